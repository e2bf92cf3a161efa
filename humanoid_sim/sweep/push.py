"""The push-recovery benchmark: the largest impulse a walk survives, per direction and instant of single support.

For a zmp-gait scenario on MuJoCo, each *cell* is a push direction (heading frame: 0 deg forward, 90 deg left, every
``360 / n`` deg from forward), a single-support phase (numbered from 1 as ``summary.json``'s ``phase_log``) and an
instant in it (a fraction of the phase's nominal window: 0.2 early, 0.5 mid, 0.8 late).  Per cell a
:class:`Bisection` on the impulse magnitude J in [0, ``max_impulse_Ns``] finds the largest J survived to
``resolution_Ns``; each probe is a whole walk with one push of J over :data:`PUSH_DURATION_S` on the pelvis (body
17, at its CoM), and it survives when the walk completes its path (``completed`` of
:func:`humanoid_sim.sweep.walk.walk_row`; a fall, a divergence or any other failure does not).  The unpushed walk
(J = 0) is assumed to survive and is walked once per controller as a check.

Bisection assumes survival is monotone in J (every impulse below one survived is survived).  A real walk need not
be: a push can be survived at one magnitude and not at a smaller one when it changes which step the robot lands.
The table reports what the bisection saw: the largest impulse survived among its probes below the smallest failed.

All cells' bisections run at once on a Dask cluster (:func:`run`): a cell's next probe is submitted when its
previous one returns, with as many walks in flight as the cluster has worker threads.  Every probe's row is kept in
``probes/<scenario hash>.json`` as it arrives; a probe whose file is there is not walked again (resume).

Every probe replans the zmp gait (a few seconds of a ~10 s walk) although the plan does not depend on the pushes:
:func:`cached_plan`, the simulator's ``planner``, keeps per worker process the trajectory
:func:`humanoid_sim.references.zmp.zmp_walk.make_trajectory` planned for a scenario without its ``disturbances``
and hands each walk a deep copy (a walk may move its trajectory's clock).

Robot mass: delta-v = J / m with m the walking robot's mass in the walk's summary (``impulse_Ns / delta_v_mps`` of
its push record), so it includes a ``robot`` variant's or a compared scenario's mass.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import json
import math
import pickle
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import yaml

from humanoid_sim.errors import InputError
from humanoid_sim.interfaces.log import atomic_write_text
from humanoid_sim.robot.phases import other_foot
from humanoid_sim.sweep.spec import DottedPath, apply, scenario_hash
from humanoid_sim.sweep.walk import walk_row

ENGINE = "mujoco"
"""Pushes need real ground (:func:`humanoid_sim.sim.disturbances.check_engine`)."""
PUSH_BODY = 17
"""The pushed body: the lower trunk (the pelvis), at its centre of mass."""
PUSH_DURATION_S = 0.1
INSTANTS = {"early": 0.2, "mid": 0.5, "late": 0.8}
"""Instant name -> fraction of the single support's nominal window."""
DEFAULT_MAX_IMPULSE_NS = 60.0
"""~1.1 m/s on the 55 kg robot: above every target (0.8 m/s is Atlas's level), so the bracket holds the answer."""
DEFAULT_RESOLUTION_NS = 1.0
"""~0.02 m/s on the 55 kg robot, finer than the targets' 0.1 m/s steps."""
STEADY_AFTER_S = 2.0
"""The default pushed phase is the first single support starting this long after the lead-in: a steady gait."""
TARGETS_MPS = {"toward the stance foot": 0.3, "toward the swing foot": 0.5, "forward": 0.5, "backward": 0.7}
"""Whole-body delta-v to survive at mid single support (sim3_zmp on MuJoCo, a 0.1 s push on the pelvis)."""
BASE_LABEL = "scenario"
"""The controller label of the scenario as given (the compared one is labelled by its overrides)."""
PROBES_DIR = "probes"
_ANGLE_TOL_DEG = 1e-6   # a direction typed as an integer of degrees; float noise of 360 * i / n stays far below
_COMPASS = {0: "forward", 45: "forward-left", 90: "left", 135: "backward-left", 180: "backward",
            225: "backward-right", 270: "right", 315: "forward-right"}


class PushError(InputError):
    """Bad benchmark input: the message names the option or field, the value and what was expected."""


# --------------------------------------------------------------------------------------------- bisection
@dataclass
class Bisection:
    """The largest impulse survived in [0, ``max_impulse``], bracketed to ``resolution`` (N s).

    ``survived`` is the largest impulse known survived (0: the unpushed walk), ``failed`` the smallest known failed
    (None: none yet).  :meth:`next_impulse` halves the bracket [survived, failed or max] until it is at most
    ``resolution`` wide: ``ceil(log2(max_impulse / resolution))`` probes.  When every probe survived the maximum
    itself is probed once more (None of them bracketed a failure yet), so a cell survives ``max_impulse`` only if a
    walk did.
    """

    max_impulse: float
    resolution: float
    survived: float = 0.0
    failed: float | None = None
    probes: list[tuple[float, bool]] = field(default_factory=list)
    failed_reason: str | None = None

    def __post_init__(self) -> None:
        if not (self.max_impulse > 0 and 0 < self.resolution <= self.max_impulse):
            raise PushError(f"bisection: expected 0 < resolution <= max impulse, got resolution {self.resolution!r}, "
                            f"max impulse {self.max_impulse!r} N s")

    @property
    def steps(self) -> int:
        """Probes that halve the bracket to the resolution: ceil(log2(max / resolution))."""
        # the ratio is rounded to 9 digits so that 64 / 1 gives 6 steps, not 7 from a ratio of 64.00000000000001
        return max(0, math.ceil(math.log2(round(self.max_impulse / self.resolution, 9))))

    def next_impulse(self) -> float | None:
        """The impulse to probe next, N s, or None when done."""
        upper = self.max_impulse if self.failed is None else self.failed
        # relative slack: after `steps` halvings the width is max / 2**steps, which may equal the resolution exactly
        if upper - self.survived <= self.resolution * (1 + 1e-9):
            if self.failed is None and self.survived < self.max_impulse:
                return self.max_impulse
            return None
        return (self.survived + upper) / 2

    def record(self, impulse: float, survived: bool, reason: str | None = None) -> None:
        """Record a probe at ``impulse`` (N s); ``reason`` is the failure's, kept for the smallest failed."""
        self.probes.append((impulse, survived))
        if survived:
            self.survived = max(self.survived, impulse)
        elif self.failed is None or impulse < self.failed:
            self.failed, self.failed_reason = impulse, reason

    @property
    def done(self) -> bool:
        return self.next_impulse() is None


def bisect(survives: Callable[[float], bool], max_impulse: float = DEFAULT_MAX_IMPULSE_NS,
           resolution: float = DEFAULT_RESOLUTION_NS) -> Bisection:
    """Run a :class:`Bisection` serially with ``survives(impulse_Ns) -> bool``."""
    b = Bisection(max_impulse, resolution)
    while (j := b.next_impulse()) is not None:
        b.record(j, survives(j))
    return b


# --------------------------------------------------------------------------------------------- labels
def swing_foot(phase_name: str) -> str:
    """The swing foot, "L" or "R", of a single-support phase: ``LFFSSP`` stands on the left foot (Left Foot Fixed),
    so the right swings.

    Raises:
        PushError: not a single-support phase name.
    """
    if len(phase_name) != 6 or phase_name[0] not in "LR" or phase_name[1:] != "FFSSP":
        raise PushError(f"phase: {phase_name!r} is not a single support (expected LFFSSP or RFFSSP)")
    return other_foot(phase_name[0])


def side_of(direction_deg: float, phase_name: str) -> str:
    """Which foot a push along ``direction_deg`` (heading frame: 0 forward, 90 left) leans toward in the single
    support ``phase_name``: "swing", "stance", or "" for a push along the heading (no sideways component)."""
    lateral = math.sin(math.radians(direction_deg))   # > 0: toward the robot's left
    if abs(lateral) < math.sin(math.radians(_ANGLE_TOL_DEG)):
        return ""
    return "swing" if (lateral > 0) == (swing_foot(phase_name) == "L") else "stance"


def direction_label(direction_deg: float, phase_name: str) -> str:
    """E.g. "forward", "left, toward the swing foot", "backward-right, toward the stance foot"."""
    d = direction_deg % 360.0
    near = round(d)
    name = _COMPASS.get(near % 360, f"{d:g} deg") if abs(d - near) < _ANGLE_TOL_DEG else f"{d:g} deg"
    side = side_of(d, phase_name)
    return f"{name}, toward the {side} foot" if side else name


def target_mps(direction_deg: float, phase_name: str) -> float | None:
    """The delta-v target (:data:`TARGETS_MPS`) of a push straight forward, backward or sideways, else None."""
    d = direction_deg % 360.0
    for angle, key in ((0.0, "forward"), (180.0, "backward"), (360.0, "forward")):
        if abs(d - angle) < _ANGLE_TOL_DEG:
            return TARGETS_MPS[key]
    for angle in (90.0, 270.0):
        if abs(d - angle) < _ANGLE_TOL_DEG:
            return TARGETS_MPS[f"toward the {side_of(d, phase_name)} foot"]
    return None


# --------------------------------------------------------------------------------------------- the benchmark
@dataclass(frozen=True)
class Cell:
    """One bisection: a controller (label), a single-support phase (number from 1 and name), an instant in it
    (name and fraction of its nominal window) and a push direction (heading frame, deg)."""

    controller: str
    phase: int
    phase_name: str
    instant: str
    fraction: float
    direction_deg: float


@dataclass
class Benchmark:
    """What to run: the scenario documents per controller label (the scenario as given first), the cells, the
    bisection bracket (N s)."""

    name: str
    source: str
    docs: dict[str, dict]
    cells: list[Cell]
    max_impulse_Ns: float = DEFAULT_MAX_IMPULSE_NS
    resolution_Ns: float = DEFAULT_RESOLUTION_NS


def load_document(scenario: str | Path) -> tuple[dict, str, Any]:
    """The scenario document of a shipped name or a YAML path (``base:`` resolved), its source text and the parsed
    :class:`~humanoid_sim.scenario.schema.Scenario`.  Raises PushError naming ``scenario``."""
    from humanoid_sim.paths import scenario_path
    from humanoid_sim.scenario.schema import parse_scenario, read_scenario_doc

    try:
        path = scenario_path(scenario)
        doc = read_scenario_doc(path)
        sc = parse_scenario(doc, str(path))
    except InputError as exc:
        msg = str(exc)
        raise PushError(msg if msg.startswith("scenario") else f"scenario: {msg}") from None
    if not sc.gait.is_zmp:
        raise PushError(f"scenario: {path}: gait.hip_reference is {sc.gait.hip_reference!r}; the push benchmark "
                        "needs the zmp gait (gait.hip_reference: zmp_preview), whose walks run on MuJoCo")
    return doc, str(path), sc


def with_overrides(doc: dict, overrides: list[str], source: str) -> tuple[dict, str]:
    """``doc`` with ``KEY=VALUE`` overrides (dotted paths, :class:`humanoid_sim.sweep.spec.DottedPath`; the value
    read as YAML: ``pd``, ``8.0``, ``true``), validated, and the label ``"KEY=VALUE, ..."``.  Raises PushError naming
    ``--compare``."""
    from humanoid_sim.scenario.schema import parse_scenario

    out = copy.deepcopy(doc)
    for text in overrides:
        key, eq, raw = text.partition("=")
        if not eq or not key.strip():
            raise PushError(f"--compare: expected KEY=VALUE with KEY a dotted path (e.g. balance.feedback=pd), got "
                            f"{text!r}")
        try:
            value = yaml.safe_load(raw)
            apply(out, DottedPath.parse(key, f"--compare {text}"), value, "set")
        except yaml.YAMLError as exc:
            raise PushError(f"--compare {text}: the value is not YAML: {exc}") from None
        except InputError as exc:
            raise PushError(f"--compare {text}: {exc}") from None
    try:
        parse_scenario(out, f"{source} with {', '.join(overrides)}")
    except InputError as exc:
        raise PushError(f"--compare {' '.join(overrides)}: {exc}") from None
    return out, ", ".join(t.strip() for t in overrides)


def single_supports(sc: Any) -> list[tuple[int, str, float]]:
    """The scenario's single-support phases: (number from 1, name, nominal start in s), from its reference
    trajectory without planning the hip (cheap)."""
    from humanoid_sim.references.chapter3 import ReferenceTrajectory
    from humanoid_sim.references.zmp.zmp_walk import ZmpPreviewTrajectory

    traj = ZmpPreviewTrajectory(ReferenceTrajectory(sc.path), sc.gait.lead_in_s, 0.0)
    return [(i + 1, ph.name, float(ph.t_start)) for i, ph in enumerate(traj.phases) if ph.is_ssp]


def default_phase(sc: Any) -> int:
    """The first single support starting :data:`STEADY_AFTER_S` after the lead-in (a steady gait).  Raises
    PushError naming ``--phase`` when the walk is shorter."""
    ssp = single_supports(sc)
    for k, _, t0 in ssp:
        if t0 >= sc.gait.lead_in_s + STEADY_AFTER_S - 1e-9:   # schedule times are sums of floats
            return k
    raise PushError(f"--phase: the walk has no single support starting {STEADY_AFTER_S:g} s after its "
                    f"{sc.gait.lead_in_s:g} s lead-in; name one of its single supports "
                    f"({', '.join(f'{k} {n}' for k, n, _ in ssp)})")


def make_benchmark(scenario: str | Path, phases: list[int] | None = None, directions: int = 8,
                   instants: list[str] | None = None, compare: list[str] | None = None,
                   max_impulse_Ns: float = DEFAULT_MAX_IMPULSE_NS,
                   resolution_Ns: float = DEFAULT_RESOLUTION_NS) -> Benchmark:
    """Validate the input and list the cells: controllers x phases x instants x directions.

    Args:
        scenario: a shipped scenario's name or a YAML path; a zmp gait.
        phases: single-support phase numbers (from 1), or None for :func:`default_phase`.
        directions: how many push directions, every 360 / n deg from forward (heading frame).
        instants: names of :data:`INSTANTS`, or None for all three.
        compare: ``KEY=VALUE`` overrides of a second controller run alongside, or None.
        max_impulse_Ns: the top of the bisection's bracket, N s.
        resolution_Ns: the bracket's final width, N s.

    Raises:
        PushError: naming the option or field.
    """
    from humanoid_sim.scenario.disturbances import IMPULSE_MAG

    if isinstance(directions, bool) or not isinstance(directions, int) or not 1 <= directions <= 360:
        raise PushError(f"--directions: expected a number of directions in [1, 360], got {directions!r}")
    if not (isinstance(max_impulse_Ns, (int, float)) and 0 < max_impulse_Ns <= IMPULSE_MAG.hi):
        raise PushError(f"--max-impulse: expected an impulse in (0, {IMPULSE_MAG.hi:g}] N s, got {max_impulse_Ns!r}")
    if not (isinstance(resolution_Ns, (int, float)) and 0 < resolution_Ns <= max_impulse_Ns):
        raise PushError(f"--resolution: expected an impulse in (0, {max_impulse_Ns:g}] N s (the maximum), got "
                        f"{resolution_Ns!r}")
    names = list(INSTANTS) if not instants else list(dict.fromkeys(instants))
    for n in names:
        if n not in INSTANTS:
            raise PushError(f"--instants: expected some of {', '.join(INSTANTS)}, got {n!r}")
    doc, source, sc = load_document(scenario)
    ssp = {k: name for k, name, _ in single_supports(sc)}
    chosen = list(dict.fromkeys(phases)) if phases else [default_phase(sc)]
    for k in chosen:
        if k not in ssp:
            raise PushError(f"--phase: {k} is not a single support of {sc.name}; expected one of "
                            f"{', '.join(f'{i} ({n})' for i, n in ssp.items())}")
    docs = {BASE_LABEL: doc}
    if compare:
        other, label = with_overrides(doc, compare, source)
        if scenario_hash(other) == scenario_hash(doc):
            raise PushError(f"--compare {' '.join(compare)}: the overrides leave the scenario unchanged")
        docs[label] = other
    cells = [Cell(c, k, ssp[k], n, INSTANTS[n], 360.0 * i / directions)
             for c in docs for k in chosen for n in names for i in range(directions)]
    return Benchmark(sc.name, source, docs, cells, float(max_impulse_Ns), float(resolution_Ns))


def probe_document(doc: dict, cell: Cell, impulse_Ns: float) -> dict:
    """``doc`` with its pushes replaced by the cell's push of ``impulse_Ns`` (none at 0: the unpushed walk).  The
    scenario's other disturbances (terrain, sensing, model) are kept."""
    out = copy.deepcopy(doc)
    dist = dict(out.get("disturbances") or {})
    dist.pop("pushes", None)
    if impulse_Ns > 0:
        dist["pushes"] = [{"body": PUSH_BODY, "impulse_Ns": float(impulse_Ns), "direction_deg": cell.direction_deg,
                           "frame": "heading", "start": {"phase": cell.phase, "fraction": cell.fraction},
                           "duration_s": PUSH_DURATION_S}]
    if dist:
        out["disturbances"] = dist
    else:
        out.pop("disturbances", None)
    return out


# --------------------------------------------------------------------------------------------- one probe (worker)
_PLANS: dict[str, Any] = {}
_PLAN_LOCK = threading.Lock()
PLAN_CACHE_SIZE = 4
"""Plans kept per worker process (a benchmark needs one per controller; a plan is a few hundred kB)."""


def _plan_key(scenario: Any, q0: Any) -> str:
    """What the planner reads: the scenario without disturbances and its labels, and the start configuration."""
    bare = replace(scenario, disturbances=None, source="", name="", description="")
    return hashlib.sha256(pickle.dumps((bare, q0.tobytes()))).hexdigest()


def cached_plan(hm: Any, scenario: Any, q0: Any) -> Any:
    """The walk's plan (:func:`humanoid_sim.references.zmp.zmp_walk.make_trajectory`'s, passed to the simulator as
    its ``planner``), kept per worker process for a scenario without its disturbances; each walk gets a deep copy
    (a walk may move its trajectory's clock)."""
    from humanoid_sim.references.zmp.zmp_walk import make_trajectory

    key = _plan_key(scenario, q0)
    with _PLAN_LOCK:
        hit = _PLANS.get(key)
    if hit is not None:
        return copy.deepcopy(hit)
    traj = make_trajectory(hm, scenario, q0)
    with _PLAN_LOCK:
        while len(_PLANS) >= PLAN_CACHE_SIZE:
            _PLANS.pop(next(iter(_PLANS)))
        _PLANS[key] = copy.deepcopy(traj)   # before the walk can touch it
    return traj


def probe_task(doc: dict, source: str, cache: bool = True) -> dict[str, Any]:
    """The Dask task of one probe: :func:`humanoid_sim.sweep.walk.walk_row`'s row (its plan from
    :func:`cached_plan` when ``cache``) plus the push as the walk applied it: ``push_applied``,
    ``push_impulse_Ns``, ``push_delta_v_mps`` and ``push_start_s`` (None without a push)."""
    res = walk_row(doc, ENGINE, source, planner=cached_plan if cache else None)
    if res.get("interrupted"):
        return {"completed": False, "status": "interrupted", "failure_kind": "interrupted",
                "reason": "interrupted on the worker"}
    row = dict(res["row"])
    pushes = ((res.get("summary") or {}).get("disturbances") or {}).get("pushes") or []
    p = pushes[0] if pushes else {}
    row.update(push_applied=p.get("applied"), push_impulse_Ns=p.get("impulse_Ns"),
               push_delta_v_mps=p.get("delta_v_mps"), push_start_s=p.get("start_s"))
    return row


# --------------------------------------------------------------------------------------------- running
RERUN_KINDS = ("exception", "worker_lost", "interrupted")
"""Recorded probes walked again on resume: failures of the machinery, not of the walk."""


@dataclass
class Outcome:
    """What :func:`run` did: the bisections per cell, the unpushed walk's row per controller, the robot mass per
    controller (kg, None when no walk reported a push), probes walked and resumed, wall time (s), and the reasons of
    probes that failed in the machinery (:data:`RERUN_KINDS`: not a fall, yet counted as not survived)."""

    bisections: dict[Cell, Bisection]
    nominal: dict[str, dict]
    mass_kg: dict[str, float | None]
    walked: int = 0
    resumed: int = 0
    wall_s: float = 0.0
    machinery: list[str] = field(default_factory=list)


def probe_file(out: Path, doc: dict) -> Path:
    """``out/probes/<scenario hash>.json``: one probe's row."""
    return Path(out) / PROBES_DIR / f"{scenario_hash(doc)}.json"


def _recorded(path: Path) -> dict | None:
    try:
        row = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return None if row.get("failure_kind") in RERUN_KINDS else row


def run(client: Any, bench: Benchmark, out: Path, on_probe: Callable[[dict], None] | None = None,
        resume: bool = True) -> Outcome:
    """Run every cell's bisection and each controller's unpushed walk on ``client``'s cluster, recording each probe
    in ``out/probes/``.  ``on_probe(row)`` after each probe (progress).  On KeyboardInterrupt the walks in flight
    are cancelled and the interrupt propagates (the recorded probes stay: the next run resumes from them)."""
    import time

    from distributed import as_completed

    t0 = time.perf_counter()
    result = Outcome({c: Bisection(bench.max_impulse_Ns, bench.resolution_Ns) for c in bench.cells}, {},
                     dict.fromkeys(bench.docs))
    nominal = {c: Cell(c, 0, "", "", 0.0, 0.0) for c in bench.docs}
    ready: deque[Cell] = deque(list(nominal.values()) + bench.cells)
    futures: dict[Any, tuple[Cell, float, dict]] = {}
    slots = max(1, sum(client.nthreads().values()))
    pending = as_completed()

    def finish(cell: Cell, impulse: float, row: dict) -> None:
        if row.get("failure_kind") in RERUN_KINDS:
            result.machinery.append(str(row.get("reason")))
        if result.mass_kg[cell.controller] is None and row.get("push_delta_v_mps"):
            result.mass_kg[cell.controller] = row["push_impulse_Ns"] / row["push_delta_v_mps"]
        if cell.phase == 0:
            result.nominal[cell.controller] = row
        else:
            result.bisections[cell].record(impulse, bool(row["completed"]), row.get("reason"))
            if not result.bisections[cell].done:
                ready.append(cell)
        if on_probe is not None:
            on_probe(row)

    def fill() -> None:
        while ready and len(futures) < slots:
            cell = ready.popleft()
            impulse = 0.0 if cell.phase == 0 else result.bisections[cell].next_impulse()
            assert impulse is not None   # a cell is queued only while its bisection needs a probe
            doc = probe_document(bench.docs[cell.controller], cell, impulse)
            path = probe_file(out, doc)
            row = _recorded(path) if resume else None
            if row is not None:
                result.resumed += 1
                finish(cell, impulse, row)
                continue
            source = (f"humanoid-push {bench.name} [{cell.controller}]: " + (
                "unpushed" if cell.phase == 0 else f"phase {cell.phase} at {cell.fraction:g}, "
                f"{cell.direction_deg:g} deg, {impulse:g} N s"))
            f = client.submit(probe_task, doc, source, pure=False)
            futures[f] = (cell, impulse, doc)
            pending.add(f)

    try:
        fill()
        while futures:
            f = next(pending)
            cell, impulse, doc = futures.pop(f)
            try:
                row = f.result()
            except Exception as exc:  # noqa: BLE001 - the worker died or Dask failed the task: a row all the same
                row = {"completed": False, "status": "failed", "failure_kind": "exception",
                       "reason": f"{type(exc).__name__}: {exc}"}
            f.release()
            result.walked += 1
            row = {**_cell_columns(bench, cell, impulse, doc), **row}
            atomic_write_text(probe_file(out, doc), json.dumps(row, indent=1, default=str) + "\n")
            finish(cell, impulse, row)
            fill()
    except KeyboardInterrupt:
        with contextlib.suppress(Exception):
            client.cancel(list(futures))
        raise
    finally:
        result.wall_s = time.perf_counter() - t0
    return result


def _cell_columns(bench: Benchmark, cell: Cell, impulse: float, doc: dict) -> dict[str, Any]:
    """A probe's first columns: what was walked (the unpushed walk has no phase, instant or direction)."""
    return {"scenario": bench.name, "controller": cell.controller, "phase": cell.phase or None,
            "phase_name": cell.phase_name or None, "instant": cell.instant or None,
            "fraction": cell.fraction if cell.phase else None,
            "direction_deg": cell.direction_deg if cell.phase else None, "impulse_Ns": impulse,
            "scenario_hash": scenario_hash(doc)}
