"""Cheap checks of a sweep's walks before any runs: is every walk a different walk, and does every axis change one?

Two walks are **the same walk** when their parsed scenarios (:func:`humanoid_sim.scenario.schema.parse_scenario`)
are equal outside ``path`` and their planned references agree to :data:`REFERENCE_TOL`.  The planned reference is
chapter 3's trajectory (:class:`humanoid_sim.references.chapter3.ReferenceTrajectory`, built from ``path`` in a
few ms), sampled at :data:`PHASE_FRACTIONS` of every phase: the phase names and durations, the hip position and
orientation, both toe points and both foot orientations.  For the zmp gait the hip's x and y are left out: the ZMP
preview plan replaces them and takes only the rest (the footholds, the swing paths, the step times, the hip height
and heading), so ``path.Vhip``, which moves only the chapter-3 hip along the path, does not make a different zmp
walk.  The zmp plan itself (seconds per walk) is not computed.

:func:`noop_axes` groups the walks of each grid axis by the values of every other axis; a group whose walks are
all the same walk is reported (``humanoid-sweep`` prints it as a warning before the walks run).  Random axes are
not checked (every sample moves all of them at once).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from typing import Any

import numpy as np

from humanoid_sim.sweep.spec import SweepSpec, Walk

REFERENCE_TOL = 1e-4
"""Two planned references agree when no sampled entry differs by more than this (m, rad, s): 0.1 mm, 0.1 mrad,
0.1 ms."""
PHASE_FRACTIONS = np.linspace(0.0, 1.0, 9)
"""Where each phase's reference is sampled, as fractions of its duration."""
_IGNORED = ("path", "source", "name", "description")
"""Scenario fields left out of the comparison: ``path`` enters through the reference; the rest is text."""


@dataclasses.dataclass(frozen=True)
class WalkPrint:
    """What decides a walk: the parsed scenario outside ``path`` (field -> value), the phase names and the
    reference samples (one row per sample: duration, hip position, hip rotation, toe points, foot rotations)."""

    rest: dict[str, Any]
    phases: tuple[str, ...]
    samples: np.ndarray


def walk_print(doc: dict) -> WalkPrint:
    """The :class:`WalkPrint` of a generated scenario document."""
    from humanoid_sim.references.chapter3 import ReferenceTrajectory
    from humanoid_sim.scenario.schema import parse_scenario

    sc = parse_scenario(doc, "<sweep walk>")
    rest = {f.name: getattr(sc, f.name) for f in dataclasses.fields(sc) if f.name not in _IGNORED}
    traj = ReferenceTrajectory(sc.path)
    zmp = bool(sc.gait.is_zmp)
    rows = []
    for ph in traj.phases:
        for frac in PHASE_FRACTIONS:
            s = traj.sample(ph.index, float(frac) * ph.duration)
            hip = np.asarray(s.hip_p, dtype=float)
            rows.append(np.concatenate([[ph.duration], hip[2:] if zmp else hip, np.ravel(s.hip_R),
                                        s.toe_R_p, s.toe_L_p, np.ravel(s.foot_R_R), np.ravel(s.foot_L_R)]))
    return WalkPrint(rest, tuple(ph.name for ph in traj.phases), np.array(rows))


def _equal(a: Any, b: Any) -> bool:
    """Deep equality of parsed scenario values (dataclasses, mappings, sequences, arrays, numbers)."""
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        return type(a) is type(b) and all(_equal(getattr(a, f.name), getattr(b, f.name))
                                          for f in dataclasses.fields(a))
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.shape(a) == np.shape(b) and bool(np.array_equal(a, b, equal_nan=True))
    if isinstance(a, (list, tuple)):
        return isinstance(b, (list, tuple)) and len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b))
    return bool(a == b)


def same_walk(a: WalkPrint, b: WalkPrint, tol: float = REFERENCE_TOL) -> bool:
    """Whether two walks are the same walk (module docstring)."""
    return (a.phases == b.phases and a.samples.shape == b.samples.shape
            and float(np.max(np.abs(a.samples - b.samples), initial=0.0)) <= tol and _equal(a.rest, b.rest))


def noop_axes(spec: SweepSpec, walks: Sequence[Walk], prints: Sequence[WalkPrint] | None = None) -> list[str]:
    """One message per grid axis that leaves every walk of some group unchanged: the axis, its values and each
    such group (the values of the other axes).  ``prints``: the walks' :func:`walk_print` (computed if None)."""
    if prints is None:
        prints = [walk_print(w.doc) for w in walks]
    out = []
    for axis in spec.grid:
        if len(axis.values) < 2:
            continue
        groups: dict[str, list[int]] = {}
        for i, w in enumerate(walks):
            others = {k: v for k, v in w.params.items() if k != axis.column}
            groups.setdefault(json.dumps(others, default=str), []).append(i)
        same = []
        for members in groups.values():
            if len(members) > 1 and all(same_walk(prints[members[0]], prints[j]) for j in members[1:]):
                w = walks[members[0]]
                same.append(", ".join(f"{k}={v}" for k, v in w.params.items() if k != axis.column) or "every walk")
        if same:
            values = ", ".join(str(v) for v in axis.values)
            out.append(f"{axis.column} changes no walk of {len(same)} group{'s' if len(same) != 1 else ''} "
                       f"(its values {values} give the same scenario and planned reference there): "
                       + "; ".join(f"[{s}]" for s in same))
    return out


def same_walk_pairs(walks: Sequence[Walk], prints: Sequence[WalkPrint] | None = None) -> list[tuple[int, int]]:
    """Every pair of walk indices that are the same walk (none in a well-designed sweep)."""
    if prints is None:
        prints = [walk_print(w.doc) for w in walks]
    return [(walks[i].index, walks[j].index) for i in range(len(walks)) for j in range(i + 1, len(walks))
            if same_walk(prints[i], prints[j])]
