"""Scenario files (YAML): schema, validation and the typed :class:`Scenario` the simulator runs.

A scenario has the sections ``path`` (locomotion parameters of thesis 3.1), ``controller`` (Appendix B weights
and prediction times, names verbatim), ``reset`` (touchdown weights W_adj), ``simulation`` (integrator, step,
stop time, impact law, fall height), ``phase_switch`` (section 6.1.1 thresholds) and ``contact`` (friction
coefficient for the feasibility audit).  Files are read with a safe YAML loader (no code execution: a
``!!python/...`` tag is an error) that also rejects duplicate keys.

Validation happens in two layers.  This module checks the *form* of every field: the key exists and is spelled
right (an unknown key gets the closest valid name suggested, at every level), its type (a number, not a string
or a boolean), its length (``Vhip`` has 2n-1 entries for n waypoints, the per-segment fields n-1, the controller
vectors the sizes of Appendix B / Table A.1) and its unit range, element by element.  The cross-field geometry
(constant hip height, arcs that exist, step width below the radius, rotation matrices) is then checked by
:meth:`humanoid_sim.trajectory.PathParams.from_dict`, and the controller is assembled by
:meth:`humanoid_sim.command.ControllerParams.from_dict`.

Every error is a :class:`ScenarioError` whose message names the file, the field path with its index
(``path.R[3]``), the value and what was expected; ``walk.py`` prints it and exits with status 2 before anything
is written.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import yaml

from humanoid_sim.command import ControllerParamError, ControllerParams
from humanoid_sim.trajectory import PathParamError, PathParams

SECTIONS = ("name", "description", "path", "controller", "reset", "simulation", "phase_switch", "contact",
            "controller_class", "gait")
REQUIRED = ("path", "controller", "reset")
RESET_KEYS = ("Wadj_qdot_LFFSSP_to_RFFDSP", "Wadj_qdot_RFFSSP_to_LFFDSP")
METHODS = ("ode3", "rk4", "euler")
IMPACT_LAWS = ("thesis", "inelastic")
FIRST_PHASES = ("LFFSSP", "RFFSSP")


class ScenarioError(ValueError):
    """Invalid scenario file: the message names the file, the field, the value and the expectation."""


@dataclass(frozen=True)
class SimulationSettings:
    """Integrator and run settings (SI units)."""

    method: str = "ode3"          # Simulink ode3 = Bogacki-Shampine, fixed step (thesis L3904)
    step_s: float = 0.01
    t_end_s: float | None = None  # default: the nominal schedule's end plus the allowed DSP overtime
    impact_law: str = "thesis"    # touchdown velocity reset: eqs. 4.97/4.100, or "inelastic" (impulse dynamics)
    fall_height_m: float = 0.5    # the run stops when the Body-17 CoM drops below this height
    max_phase_overtime: float = 3.0  # a phase lasting this many times its nominal duration is a failure


@dataclass(frozen=True)
class SwitchThresholds:
    """Phase-switching thresholds of thesis 6.1.1 (L3986-3988, L4036-4037)."""

    toe_flat_height_m: float = 0.015
    touchdown_tolerance_m: float = 0.001
    min_horizontal_progress_fraction: float = 0.3
    dsp_hip_distance_m: float = 0.05
    dsp_overtime_fraction: float = 0.1


@dataclass(frozen=True)
class ContactSettings:
    """Contact-feasibility audit settings."""

    friction_coefficient: float = 0.8  # Coulomb coefficient mu of the cone |f_t| <= mu f_n (assumed, not in thesis)


HIP_REFERENCES = ("thesis", "zmp_preview")
ZMP_TRANSFERS = ("smoothstep", "linear")
GAIT_CONTROLLERS = ("balance", "thesis")


@dataclass(frozen=True)
class GaitSettings:
    """Which hip reference the walk follows (the feet, footholds and timing are chapter 3's in both gaits).

    ``thesis``: chapter 3's hip (constant height, no lateral sway), unchanged.  ``zmp_preview``: the Body-17 CoM path
    planned by ZMP preview control (Kajita et al. 2003, ``humanoid_sim.gait``): a standing ``lead_in_s`` double
    support first (the weight shift onto the first stance foot), ``horizon_s`` of preview, ``passes`` multibody
    corrections of the cart-table plan, planned on a ``sample_s`` grid; the ZMP reference moves between the sole
    centres with a ``transfer`` profile.  In this gait a double support lasts its planned duration and touchdown
    uses the inelastic impact law unless ``simulation.impact_law`` says otherwise, and the whole walk (the initial
    stance included) runs ``hip_lowering_m`` below the path's ``Phip`` heights: a hip that sways over the stance
    foot needs more reach of the legs (at sim 1's 0.93 m the planner cannot reach the feet on its first, 40 deg
    turning step; 0.02 m lower it can).  It starts from a ready stance (:mod:`humanoid_sim.gait.stance`): Body 17
    moved so the whole-body CoM is ``ready_margin_m`` inside the lead-in's support polygon (0 = chapter 3's
    initial stance).  The thesis gait ignores both.  ``controller``: what executes the zmp gait when the scenario
    names no ``controller_class``: ``balance`` (:class:`humanoid_sim.controllers.balance.BalanceController`, a QP
    that keeps every ground reaction inside its sole and friction cone) or ``thesis`` (5.1/5.2, compiled)."""

    hip_reference: str = "thesis"
    horizon_s: float = 1.6
    lead_in_s: float = 1.0
    passes: int = 2
    sample_s: float = 0.01
    transfer: str = "smoothstep"
    hip_lowering_m: float = 0.02
    ready_margin_m: float = 0.03
    controller: str = "balance"

    @property
    def is_zmp(self) -> bool:
        return self.hip_reference == "zmp_preview"


@dataclass(frozen=True)
class Scenario:
    """A validated scenario."""

    name: str
    description: str
    path: PathParams
    controller: ControllerParams
    W_adj: dict[str, np.ndarray]
    simulation: SimulationSettings = field(default_factory=SimulationSettings)
    switch: SwitchThresholds = field(default_factory=SwitchThresholds)
    contact: ContactSettings = field(default_factory=ContactSettings)
    source: str = "<dict>"
    controller_class: str | None = None   # 'package.module:ClassName' of a user's controller; None = the thesis's
    gait: GaitSettings = field(default_factory=GaitSettings)


def _lowered(src: str, path: PathParams, dz: float) -> PathParams:
    """``path`` with every hip waypoint ``dz`` m lower (the zmp gait's ``gait.hip_lowering_m``)."""
    Phip = np.array(path.Phip, dtype=float)
    Phip[:, 2] -= dz
    if Phip[:, 2].min() <= HIP_HEIGHT.lo:
        raise ScenarioError(f"{src}: gait.hip_lowering_m: {dz} m puts the hip at {Phip[:, 2].min():.3f} m, below "
                            "the ground")
    return replace(path, Phip=Phip)


# --------------------------------------------------------------------------------------------- value ranges
@dataclass(frozen=True)
class Num:
    """Expected number: ``what`` (with unit) in the interval from ``lo`` to ``hi`` (open ends where asked);
    ``choices`` restricts it to a finite set."""

    what: str
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple[float, ...] | None = None

    def describe(self) -> str:
        if self.choices is not None:
            return f"{self.what}, one of {', '.join(f'{c:g}' for c in self.choices)}"
        if self.lo == -math.inf and self.hi == math.inf:
            return f"{self.what} (finite)"
        if self.hi == math.inf:
            return f"{self.what} {'>' if self.lo_open else '>='} {self.lo:g}"
        if self.lo == -math.inf:
            return f"{self.what} {'<' if self.hi_open else '<='} {self.hi:g}"
        return (f"{self.what} in {'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}"
                f"{')' if self.hi_open else ']'}")

    def accepts(self, v: float) -> bool:
        if self.choices is not None:
            return v in self.choices
        lo_ok = v > self.lo if self.lo_open else v >= self.lo
        hi_ok = v < self.hi if self.hi_open else v <= self.hi
        return lo_ok and hi_ok


#: per-segment fields of ``path`` (one entry per segment P_k -> P_k+1) and their unit ranges
PATH_SEGMENT: dict[str, Num] = {
    "R": Num("an arc radius in m", 0.0, lo_open=True),
    "T_dir": Num("a turn direction", choices=(1.0, -1.0)),
    "t_SSP": Num("a single-support duration in s", 0.0, 10.0, lo_open=True),
    "PTR": Num("a ratio t_SSP/t_DSP", 0.0, 100.0, lo_open=True),
    "SW": Num("a step width in m", 0.0, 1.0, lo_open=True),
    "SH": Num("a swing-toe height in m (above the flat-toe height 0.015 m)", 0.015, 0.5, lo_open=True),
    "k_SH": Num("a fraction of t_SSP", 0.0, 1.0, lo_open=True, hi_open=True),
    "k_Adj": Num("a ratio t_SSP/t_z", 1.0, 100.0),
    "dtheta_PLN": Num("an angle in rad", -math.pi, math.pi),
    "dtheta_ADJ": Num("an angle in rad", -math.pi, math.pi),
}
PATH_KEYS = ("Phip", "Vhip", *PATH_SEGMENT, "toe_R0", "toe_L0", "foot_R0", "foot_L0", "first_phase")
HIP_HEIGHT = Num("a hip height in m", 0.0, 2.0, lo_open=True)
COORD = Num("a coordinate in m", -1e4, 1e4)
SPEED = Num("a speed magnitude in m/s", 0.0, 5.0)
TOE_HEIGHT = Num("a toe height in m", 0.0, 0.5)
ROT_ENTRY = Num("a rotation-matrix entry", -1.0 - 1e-6, 1.0 + 1e-6)   # 1e-6: entries typed with ~7 digits
TIME = Num("a prediction time in s", 0.0, 5.0, lo_open=True)
WEIGHT = Num("a weight", 0.0)
RESET_WEIGHT = Num("a weight", 0.0, lo_open=True)


def _controller_schema() -> dict[str, tuple[int, Num, bool]]:
    """Controller key -> (size, range, required).  Sizes of Appendix B / Table A.1; Wact has len(F) = 96
    entries (eq. 4.68).  Wact_* and Delta_t2_*DSP are accepted but optional: the fast path does not read them
    (errata A-3, A-13)."""
    s: dict[str, tuple[int, Num, bool]] = {}
    for p in ("LFFSSP", "RFFSSP"):
        for j in (1, 2, 3):
            s[f"Delta_t{j}_{p}"] = (1, TIME, True)
    for p in ("LFFDSP", "RFFDSP"):
        s[f"Delta_t1_{p}"] = (1, TIME, True)
        s[f"Delta_t2_{p}"] = (1, TIME, False)
    sizes = {"Wp_fa": 3, "Wv_fa": 6, "Wa_a": 7, "Wp_fb": 3, "Wv_fb": 6, "Wa_b": 8, "Wor_fa": 3, "Wor_fb": 3}
    for w, n in sizes.items():
        for p in ("LFFSSP", "RFFSSP", "LFFDSP", "RFFDSP"):
            s[f"{w}_{p}"] = (n, WEIGHT, True)
    for k in ("Wp_Tetha3_LFFSSP", "Wv_Tetha3_LFFSSP", "Wp_Tetha4_RFFSSP", "Wv_Tetha4_RFFSSP"):
        s[k] = (1, WEIGHT, True)
    for k in ("Wact_LFFDSP", "Wact_RFFDSP"):
        s[k] = (96, WEIGHT, False)
    for k, n in (("WqL_H_LFFSSP", 7), ("WqH_R_LFFSSP", 8), ("WqR_H_RFFSSP", 7), ("WqH_L_RFFSSP", 8),
                 ("WqL_H_LFFDSP", 7), ("WqR_H_LFFDSP", 8), ("WqR_H_RFFDSP", 7), ("WqL_H_RFFDSP", 8)):
        s[k] = (n, WEIGHT, True)
    for j in range(18, 28):
        s[f"WpTetha{j}"] = (1, WEIGHT, True)
        s[f"WvTetha{j}"] = (1, WEIGHT, True)
        s[f"Delta_t{j}"] = (1, TIME, True)
    return s


CONTROLLER_SCHEMA = _controller_schema()


# --------------------------------------------------------------------------------------------- helpers
def suggest_key(key: str, allowed: Sequence[str]) -> str:
    """'; did you mean ...?' for a misspelt key, else the allowed keys (message tail)."""
    close = difflib.get_close_matches(key, list(allowed), n=1, cutoff=0.5)
    if close:
        return f"; did you mean {close[0]!r}?"
    listed = ", ".join(list(allowed)[:12]) + (", ..." if len(allowed) > 12 else "")
    return f"; allowed: {listed}"


def _mapping(src: str, where: str, value: Any) -> dict:
    if not isinstance(value, dict):
        raise ScenarioError(f"{src}: {where}: expected a mapping of keys to values, got {type(value).__name__} "
                            f"({_show(value)})")
    return value


def _check_keys(src: str, where: str, d: dict, allowed: Sequence[str]) -> None:
    for k in d:
        if not isinstance(k, str) or k not in allowed:
            raise ScenarioError(f"{src}: {where + '.' if where else ''}{k}: unknown key{suggest_key(str(k), allowed)}")


def _show(value: Any, limit: int = 80) -> str:
    """repr of a value, shortened for messages."""
    r = repr(value)
    return r if len(r) <= limit else r[:limit - 3] + "..."


def _type_hint(value: Any) -> str:
    if isinstance(value, bool):
        return " (a boolean)"
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return " (a string)"
        if "e" in value.lower():
            return " (a string: YAML 1.1 reads an exponent without a dot and a sign as text; write e.g. 1.0e+3)"
        return " (a string: write the number without quotes)"
    if value is None:
        return " (empty)"
    name = type(value).__name__
    return f" ({'an' if name[0] in 'aeiou' else 'a'} {name})"


def _number(src: str, where: str, value: Any, rng: Num) -> float:
    """A finite real number in ``rng``; booleans and numeric strings are rejected."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ScenarioError(f"{src}: {where}: expected {rng.describe()}, got {_show(value)}{_type_hint(value)}")
    v = float(value)
    if not math.isfinite(v) or not rng.accepts(v):
        raise ScenarioError(f"{src}: {where}: expected {rng.describe()}, got {_show(value)}")
    return v


def _vector(src: str, where: str, value: Any, n: int, rng: Num, what: str) -> list[float]:
    """A YAML list of exactly ``n`` numbers in ``rng``."""
    if not isinstance(value, list):
        raise ScenarioError(f"{src}: {where}: expected a list of {n} {what}, got {_show(value)}{_type_hint(value)}")
    if len(value) != n:
        raise ScenarioError(f"{src}: {where}: expected {n} entries ({what}), got {len(value)}: {_show(value)}")
    return [_number(src, f"{where}[{i}]", x, rng) for i, x in enumerate(value)]


# --------------------------------------------------------------------------------------------- sections
def _check_path(src: str, raw: Any) -> dict[str, Any]:
    """Form of the ``path`` block: keys, types, lengths, element ranges.  Returns it unchanged."""
    d = _mapping(src, "path", raw)
    _check_keys(src, "path", d, PATH_KEYS)
    for k in PATH_KEYS:
        if k != "first_phase" and k not in d:
            raise ScenarioError(f"{src}: path.{k}: missing (required keys: {', '.join(PATH_KEYS[:-1])})")
    P = d["Phip"]
    if not isinstance(P, list) or len(P) < 2:
        raise ScenarioError(f"{src}: path.Phip: expected a list of n >= 2 waypoints [x, y, z] in m, got "
                            f"{_show(P)}{'' if isinstance(P, list) else _type_hint(P)}")
    for i, p in enumerate(P):
        if not isinstance(p, list) or len(p) != 3:
            raise ScenarioError(f"{src}: path.Phip[{i}]: expected a waypoint [x, y, z] in m, got {_show(p)}")
        _number(src, f"path.Phip[{i}][0]", p[0], COORD)
        _number(src, f"path.Phip[{i}][1]", p[1], COORD)
        _number(src, f"path.Phip[{i}][2]", p[2], HIP_HEIGHT)
    n = len(P)
    V = d["Vhip"]
    if isinstance(V, list) and len(V) != 2 * n - 1:
        raise ScenarioError(f"{src}: path.Vhip: expected 2n-1 = {2 * n - 1} speeds for n = {n} waypoints "
                            f"(V_1, V_12, V_2, ..., V_n), got {len(V)}")
    _vector(src, "path.Vhip", V, 2 * n - 1, SPEED, "speeds in m/s")
    for k, rng in PATH_SEGMENT.items():
        v = d[k]
        if isinstance(v, list) and len(v) != n - 1:
            raise ScenarioError(f"{src}: path.{k}: expected n-1 = {n - 1} entries, one per segment for n = {n} "
                                f"waypoints, got {len(v)}")
        _vector(src, f"path.{k}", v, n - 1, rng, "one per segment")
    for k in ("toe_R0", "toe_L0"):
        v = _vector(src, f"path.{k}", d[k], 3, COORD, "a toe point [x, y, z] in m")
        _number(src, f"path.{k}[2]", v[2], TOE_HEIGHT)
    for k in ("foot_R0", "foot_L0"):
        M = d[k]
        if not isinstance(M, list) or len(M) != 3:
            raise ScenarioError(f"{src}: path.{k}: expected a 3x3 rotation matrix (3 rows of 3), got {_show(M)}")
        for i, row in enumerate(M):
            _vector(src, f"path.{k}[{i}]", row, 3, ROT_ENTRY, "a rotation-matrix row")
    if "first_phase" in d and d["first_phase"] not in FIRST_PHASES:
        raise ScenarioError(f"{src}: path.first_phase: expected one of {', '.join(FIRST_PHASES)}, got "
                            f"{_show(d['first_phase'])}")
    return d


def _check_controller(src: str, raw: Any) -> dict[str, Any]:
    """Form of the ``controller`` block: keys, sizes, ranges.  Returns it unchanged."""
    d = _mapping(src, "controller", raw)
    _check_keys(src, "controller", d, tuple(CONTROLLER_SCHEMA))
    for k, (n, rng, required) in CONTROLLER_SCHEMA.items():
        if k not in d:
            if required:
                raise ScenarioError(f"{src}: controller.{k}: missing (expected "
                                    f"{'1 value' if n == 1 else f'{n} values'}, {rng.describe()})")
            continue
        if n == 1:
            _number(src, f"controller.{k}", d[k], rng)
        else:
            _vector(src, f"controller.{k}", d[k], n, rng, "weights")
    return d


def _check_reset(src: str, raw: Any) -> dict[str, np.ndarray]:
    reset = _mapping(src, "reset", raw)
    _check_keys(src, "reset", reset, RESET_KEYS)
    W_adj = {}
    for k in RESET_KEYS:
        if k not in reset:
            raise ScenarioError(f"{src}: reset.{k}: missing (expected 14 positive weights, eq. 4.97/4.100)")
        W_adj[k] = np.array(_vector(src, f"reset.{k}", reset[k], 14, RESET_WEIGHT,
                                    "weights of the lower-body joints without the toes, errata K-11"))
    return W_adj


def _dataclass_section(src: str, name: str, raw: Any, cls, checks: dict[str, Any]) -> Any:
    """A flat section of scalars: each key is a :class:`Num`, a tuple of string choices, or
    ``("optional", Num)`` (``null`` allowed)."""
    if raw is None:
        return cls()
    d = _mapping(src, name, raw)
    _check_keys(src, name, d, tuple(checks))
    kwargs = {}
    for k, v in d.items():
        spec = checks[k]
        if isinstance(spec, tuple) and spec and spec[0] == "optional":
            kwargs[k] = None if v is None else _number(src, f"{name}.{k}", v, spec[1])
        elif isinstance(spec, tuple):
            if not isinstance(v, str) or v not in spec:
                raise ScenarioError(f"{src}: {name}.{k}: expected one of {', '.join(spec)}, got {_show(v)}")
            kwargs[k] = v
        else:
            kwargs[k] = _number(src, f"{name}.{k}", v, spec)
    return cls(**kwargs)


# --------------------------------------------------------------------------------------------- entry points
def parse_scenario(doc: Any, source: str = "<dict>") -> Scenario:
    """Validate a parsed YAML document and build a :class:`Scenario` (raises :class:`ScenarioError`)."""
    src = source
    if doc is None:
        raise ScenarioError(f"{src}: the file is empty; expected a mapping with sections {', '.join(REQUIRED)}")
    doc = _mapping(src, "top level", doc)
    _check_keys(src, "", doc, SECTIONS)
    for sec in REQUIRED:
        if sec not in doc:
            raise ScenarioError(f"{src}: {sec}: missing section (required: {', '.join(REQUIRED)})")
    name = doc.get("name", Path(source).stem)
    if not isinstance(name, str) or not name.strip() or any(c in name for c in "/\\\0") or name in (".", ".."):
        raise ScenarioError(f"{src}: name: expected a non-empty string usable as a folder name, got {_show(name)}")
    desc = doc.get("description", "")
    if not isinstance(desc, str):
        raise ScenarioError(f"{src}: description: expected a string, got {_show(desc)}")
    path_raw = _check_path(src, doc["path"])
    try:
        path = PathParams.from_dict(path_raw, where="path")
    except PathParamError as exc:
        raise ScenarioError(f"{src}: {exc}") from None
    ctrl_raw = _check_controller(src, doc["controller"])
    try:
        controller = ControllerParams.from_dict(ctrl_raw, where="controller")
    except (ControllerParamError, TypeError, ValueError) as exc:
        raise ScenarioError(f"{src}: {exc}") from None
    W_adj = _check_reset(src, doc["reset"])
    sim = _dataclass_section(src, "simulation", doc.get("simulation"), SimulationSettings, {
        "method": METHODS, "step_s": Num("a step in s", 1e-5, 0.05),
        "t_end_s": ("optional", Num("a stop time in s", 0.0, 1e4, lo_open=True)),
        "impact_law": IMPACT_LAWS, "fall_height_m": Num("a height in m", 0.0, 2.0),
        "max_phase_overtime": Num("a ratio to the nominal phase duration", 1.0, 100.0, lo_open=True)})
    sw = _dataclass_section(src, "phase_switch", doc.get("phase_switch"), SwitchThresholds, {
        "toe_flat_height_m": Num("a height in m", 0.0, 0.1),
        "touchdown_tolerance_m": Num("a tolerance in m", 0.0, 0.05, lo_open=True),
        "min_horizontal_progress_fraction": Num("a fraction", 0.0, 1.0),
        "dsp_hip_distance_m": Num("a distance in m", 0.0, 1.0, lo_open=True),
        "dsp_overtime_fraction": Num("a fraction", 0.0, 10.0)})
    ct = _dataclass_section(src, "contact", doc.get("contact"), ContactSettings, {
        "friction_coefficient": Num("a friction coefficient", 0.0, 5.0, lo_open=True)})
    gait = _dataclass_section(src, "gait", doc.get("gait"), GaitSettings, {
        "hip_reference": HIP_REFERENCES, "horizon_s": Num("a preview horizon in s", 0.05, 5.0),
        "lead_in_s": Num("a standing double support in s", 0.2, 5.0),
        "passes": Num("a count of multibody corrections", choices=(0, 1, 2, 3, 4, 5)),
        "sample_s": Num("a planning step in s", 0.002, 0.05), "transfer": ZMP_TRANSFERS,
        "hip_lowering_m": Num("a hip lowering in m", 0.0, 0.15),
        "ready_margin_m": Num("a CoM margin in m", 0.0, 0.1), "controller": GAIT_CONTROLLERS})
    gait = replace(gait, passes=int(gait.passes))
    if gait.is_zmp and gait.hip_lowering_m > 0.0:
        path = _lowered(src, path, gait.hip_lowering_m)
    sim_raw = doc.get("simulation")
    if gait.is_zmp and not (isinstance(sim_raw, dict) and "impact_law" in sim_raw):
        sim = replace(sim, impact_law="inelastic")   # the zmp gait's default: no momentum from nowhere
    cc = doc.get("controller_class")
    if cc is not None:
        from humanoid_sim.controllers.loading import DOTTED

        if not isinstance(cc, str) or not DOTTED.match(cc):
            raise ScenarioError(f"{src}: controller_class: expected 'package.module:ClassName' (a controller class "
                                f"importable from PYTHONPATH), got {_show(cc)}")
    return Scenario(name=name, description=desc, path=path, controller=controller, W_adj=W_adj, simulation=sim,
                    switch=sw, contact=ct, source=source, controller_class=cc, gait=gait)


class _StrictSafeLoader(yaml.SafeLoader):
    """PyYAML's safe loader (plain data only, no object construction) that also rejects duplicate keys."""


def _construct_mapping(loader: _StrictSafeLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    seen: set = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            dup = key in seen
        except TypeError:  # unhashable key: let the base constructor report it
            break
        if dup:
            raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r}", key_node.start_mark)
        seen.add(key)
    return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)


_StrictSafeLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def read_yaml(path: str | Path, what: str = "scenario file", error: type[Exception] = ScenarioError) -> Any:
    """The YAML document of a file, read strictly (plain data only, no duplicate keys); ``what`` names the file
    in messages, ``error`` is raised for a missing, unreadable or invalid file."""
    p = Path(path)
    if not p.exists():
        raise error(f"{p}: no such {what}")
    if not p.is_file():
        raise error(f"{p}: not a regular file")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{p}: cannot read as UTF-8 text: {exc}") from None
    try:
        return yaml.load(text, Loader=_StrictSafeLoader)  # noqa: S506 (a SafeLoader subclass)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        if isinstance(exc, yaml.constructor.ConstructorError) and "constructor for the tag" in problem:
            problem += " (only plain YAML data is accepted; tags that construct objects are refused)"
        raise error(f"{p}: not valid YAML{where}: {problem}") from None


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file (raises :class:`ScenarioError`)."""
    return parse_scenario(read_yaml(path), str(Path(path)))
