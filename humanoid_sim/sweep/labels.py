"""Axis labels of the sweep figures in physical units, derived from the scenario schema.

The rule (also in ``docs/design-studies.md``, "Axis labels"):

- **What and unit.**  The quantity and its unit come from the scenario schema's description of the swept key
  (:data:`humanoid_sim.scenario.schema.PATH_SEGMENT`, the hip speeds, waypoints and toe points of ``path``), else
  from the key's unit suffix (``_s`` seconds, ``_m`` metres, ``_Nm``, ``_rad``); a key with neither is labelled
  "no unit".  The label reads ``"<what> <key> (<unit>)"``, e.g. ``single-support duration t_SSP (s)``.
- **A factor (``{scale: [...]}``) is shown as the value it gives**: the factor times the base scenario's value,
  with the factor below each tick (``0.56`` / ``x0.8``).  When the base holds several values (a per-segment list),
  the value shown is the one most of its entries share (the cruise speed of ``path.Vhip``: "most entries"); the
  waypoint coordinates ``path.Phip[*][0]`` / ``[1]`` are shown as the waypoint spacing they give (the step length);
  a list without a common value is shown as its factor, ``"x base"``.
- **Shared axes** are labelled by their first path; the others are named on a second line, scaled (or set) alike.
- **Text axes** (a choice of gait) are not a map axis: the figures draw one panel per value.
"""

from __future__ import annotations

import math
import re
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

from humanoid_sim.sweep.spec import ALL, Axis, DottedPath, values_at

_SUFFIX_UNITS = (("_Nm", "N m"), ("_rad", "rad"), ("_m", "m"), ("_s", "s"), ("_N", "N"))
_WHAT = re.compile(r"^(?:an? )?(?P<what>.*?)(?: in (?P<unit>[^\s(,]+))?(?: \(.*\))?$")
_COORDS = ("x", "y", "z")


@dataclass(frozen=True)
class AxisUnits:
    """How one sweep axis is labelled: ``label`` (what, key, unit); for a factor, ``base`` is the base scenario's
    value a factor multiplies (NaN: shown as the factor itself)."""

    axis: Axis
    label: str
    base: float = math.nan

    def value(self, v: Any) -> Any:
        """The physical value a cell of the axis stands for (a factor times :attr:`base`)."""
        if self.axis.mode == "scale" and math.isfinite(self.base):
            return float(v) * self.base
        return v

    def tick(self, v: Any) -> str:
        """Tick label of a cell: the value, and for a factor the factor below it."""
        if self.axis.mode == "scale":
            return f"{self.value(v):.3g}\nx{float(v):g}" if math.isfinite(self.base) else f"x{float(v):g}"
        if isinstance(v, float):
            return f"{v:.4g}"
        s = str(v)
        return s if len(s) <= 18 else s[:15] + "..."


def _schema_num(path: DottedPath) -> tuple[str, str] | None:
    """(what, unit) of the key at ``path`` from the scenario schema, or None."""
    from humanoid_sim.scenario.schema import COORD, HIP_HEIGHT, PATH_SEGMENT, SPEED

    keys = [t for t in path.tokens if isinstance(t, str) and t != ALL]
    if len(keys) < 2 or keys[0] != "path":
        return None
    key = keys[1]
    idx = [t for t in path.tokens if not isinstance(t, str) or t == ALL]
    if key in PATH_SEGMENT:
        num = PATH_SEGMENT[key]
    elif key == "Vhip":
        num = SPEED
    elif key == "Phip" and len(idx) == 2 and isinstance(idx[1], int):
        return ("hip height", "m") if idx[1] == 2 else (f"waypoint {_COORDS[idx[1]]}", "m")
    elif key == "Phip":
        num = HIP_HEIGHT if idx[-1:] == [2] else COORD
    elif key.startswith("toe_"):
        num = COORD
    else:
        return None
    m = _WHAT.match(num.what)
    what = m.group("what") if m else num.what
    if key == "Vhip":
        what = "hip speed"
    elif key == "t_SSP":
        what = "single-support time"
    return what, (m.group("unit") if m and m.group("unit") else "")


def _suffix_unit(path: DottedPath) -> str:
    key = next((t for t in reversed(path.tokens) if isinstance(t, str) and t != ALL), "")
    for suffix, unit in _SUFFIX_UNITS:
        if key.endswith(suffix):
            return unit
    return ""


def _key_text(path: DottedPath) -> str:
    """The path without its section: ``t_SSP``, ``Phip[*][1]``, ``hip_reference``."""
    return path.text.split(".", 1)[1] if "." in path.text else path.text


def _common(values: list[float]) -> tuple[float, bool]:
    """The value most entries share and whether every entry has it (NaN when none has a majority)."""
    if not values:
        return math.nan, False
    v, count = Counter(values).most_common(1)[0]
    if count == len(values):
        return float(v), True
    return (float(v), False) if 2 * count >= len(values) else (math.nan, False)


def axis_units(axis: Axis, base_doc: dict | None) -> AxisUnits:
    """The label of ``axis`` by the module's rule; ``base_doc``: the sweep's base scenario document."""
    first = axis.paths[0]
    key = _key_text(first)
    found = _schema_num(first)
    what, unit = found if found is not None else ("", _suffix_unit(first))
    others = [p.text for p in axis.paths[1:]]
    alike = f"\n{', '.join(_key_text(DottedPath(o, ())) for o in others)} " \
            f"{'scaled' if axis.mode == 'scale' else 'set'} alike" if others else ""
    name = f"{what} {key}" if what else first.text
    unit_text = unit or "no unit"
    if axis.mode != "scale":
        if axis.values and all(isinstance(v, str) for v in axis.values):
            return AxisUnits(axis, f"{name}{alike}")
        return AxisUnits(axis, f"{name} ({unit_text}){alike}")
    base_vals = [float(v) for v in values_at(base_doc or {}, first)
                 if isinstance(v, (int, float)) and not isinstance(v, bool)]
    toks = first.tokens
    if (len(toks) >= 4 and toks[:2] == ("path", "Phip") and toks[2] == ALL and toks[3] in (0, 1)
            and len(base_vals) >= 2):
        spacing = float(np.mean(np.abs(np.diff(base_vals))))
        return AxisUnits(axis, f"step length (waypoint spacing along {_COORDS[int(toks[3])]}) {key} "
                         f"({unit_text}){alike}", spacing)
    value, every = _common(base_vals)
    if not math.isfinite(value) or value == 0.0:
        return AxisUnits(axis, f"{name} (x base{', ' + unit_text if unit else ''}){alike}")
    note = "" if every else ", most entries"
    return AxisUnits(axis, f"{name} ({unit_text}{note}){alike}", value)
