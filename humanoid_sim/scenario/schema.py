"""Scenario files (YAML): the typed :class:`Scenario` the simulator runs, and its validation.

Sections:

- ``path``: the locomotion parameters of thesis 3.1 (waypoints, speeds, arcs, step timing);
- ``gait``: which hip reference the walk follows (chapter 3's, or the feasible ZMP-preview plan) and who executes it;
- ``controller``: the thesis controller's Appendix B weights (:mod:`.thesis_controller`); required only when the
  thesis controller runs;
- ``balance``: the balance controller's settings (:mod:`.balance`); optional, documented defaults;
- ``actuators``: a motor and gearbox per joint from a sourced catalogue (:mod:`.actuators`); optional: without it
  every joint is the thesis's torque source;
- ``robot``: the body as a design variable (segment lengths, masses, sole, payload; :mod:`.robot`); optional:
  without it the walk runs on the thesis robot;
- ``controller_class`` and ``controller_settings``: a user's controller (``package.module:ClassName``) and its own
  settings, passed to its ``setup`` as ``ControlContext.settings``;
- ``reset``: the touchdown weights W_adj of eqs. 4.97/4.100; required only when the thesis impact law is used;
- ``simulation``, ``phase_switch``, ``contact``: integrator and run settings, the 6.1.1 thresholds, the friction
  coefficient.

A file may start from another with ``base: other.yaml`` (a path relative to the file) and override any key:
mappings merge key by key, anything else replaces (:func:`load_scenario`).

Files are read with a safe YAML loader (no code execution, no duplicate keys). This module checks the *form* of
every field: the key exists and is spelled right (an unknown key gets the closest valid name suggested), its type,
its length and its unit range, element by element. The cross-field geometry is then checked by
:meth:`humanoid_sim.references.chapter3.PathParams.from_dict`. Every error is a :class:`ScenarioError` whose
message names the file, the field path with its index (``path.R[3]``), the value and what was expected.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from humanoid_sim.references.chapter3 import PathParamError, PathParams
from humanoid_sim.robot.variant import RobotVariant
from humanoid_sim.scenario.actuators import ActuatorChoice, parse_actuators
from humanoid_sim.scenario.balance import BalanceSettings, parse_balance
from humanoid_sim.scenario.disturbances import Disturbances, parse_disturbances
from humanoid_sim.scenario.fields import (
    Num,
    ScenarioError,
    check_keys,
    flat_section,
    mapping_of,
    number,
    show,
    type_hint,
    vector,
)
from humanoid_sim.scenario.robot import parse_robot
from humanoid_sim.scenario.thesis_controller import ControllerParams, parse_controller
from humanoid_sim.scenario.yamlio import read_yaml

SECTIONS = ("name", "description", "base", "path", "gait", "controller", "balance", "actuators", "robot",
            "controller_class", "controller_settings", "reset", "simulation", "phase_switch", "contact",
            "disturbances")
REQUIRED = ("path",)
RESET_KEYS = ("Wadj_qdot_LFFSSP_to_RFFDSP", "Wadj_qdot_RFFSSP_to_LFFDSP")
METHODS = ("ode3", "rk4", "euler")
IMPACT_LAWS = ("thesis", "inelastic")
FIRST_PHASES = ("LFFSSP", "RFFSSP")
DOTTED_CLASS = re.compile(r"^[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*:[A-Za-z_][\w]*$")
"""The form of ``controller_class``: ``package.module:ClassName``."""


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
    planned by ZMP preview control (Kajita et al. 2003, ``humanoid_sim.references.zmp``): a standing ``lead_in_s``
    double
    support first (the weight shift onto the first stance foot), ``horizon_s`` of preview (which sees a stop of
    ``lead_out_s`` after the last phase: the ZMP moving to the midpoint of both soles; 0 = none), ``passes`` multibody
    corrections of the cart-table plan, planned on a ``sample_s`` grid; the ZMP reference moves between the sole
    centres with a ``transfer`` profile.  In this gait a double support lasts its planned duration and touchdown
    uses the inelastic impact law unless ``simulation.impact_law`` says otherwise, and the whole walk (the initial
    stance included) runs ``hip_lowering_m`` below the path's ``Phip`` heights: a hip that sways over the stance
    foot needs more reach of the legs (at sim 1's 0.93 m the planner cannot reach the feet on its first, 40 deg
    turning step; 0.02 m lower it can).  It starts from a ready stance (:mod:`humanoid_sim.references.zmp.stance`): Body
    17
    moved so the whole-body CoM is ``ready_margin_m`` inside the lead-in's support polygon (0 = chapter 3's
    initial stance).  The thesis gait ignores both.  ``controller``: what executes the zmp gait when the scenario
    names no ``controller_class``: ``balance`` (:class:`humanoid_sim.controllers.balance.controller.BalanceController`,
    a QP
    that keeps every ground reaction inside its sole and friction cone) or ``thesis`` (5.1/5.2, compiled)."""

    hip_reference: str = "thesis"
    horizon_s: float = 1.6
    lead_in_s: float = 1.0
    lead_out_s: float = 1.0
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
    """A validated scenario.

    Attributes:
        name: the walk's name (the default output folder).
        description: free text.
        path: the locomotion parameters (thesis 3.1), with the zmp gait's hip lowering applied.
        controller: the thesis controller's weights, or None when the scenario does not run the thesis controller
            and gives no ``controller`` section.
        W_adj: the touchdown weights of the thesis impact law per transition (14 each), empty when not given.
        simulation: integrator and run settings.
        switch: the phase-switching thresholds of 6.1.1.
        contact: the friction coefficient.
        source: the file the scenario came from.
        controller_class: ``package.module:ClassName`` of a user's controller, or None.
        gait: the hip reference and who executes the zmp gait.
        balance: the balance controller's settings.
        controller_settings: a user controller's own section, passed to its ``setup`` as ``ControlContext.settings``.
        actuators: a motor and gearbox per joint (:mod:`.actuators`), or None for the thesis's torque sources.
        robot: the body's variant (:mod:`.robot`), or None for the thesis robot.
        disturbances: pushes, terrain, sensing noise and actuation delay (:mod:`.disturbances`), or None.
    """

    name: str
    description: str
    path: PathParams
    controller: ControllerParams | None
    W_adj: dict[str, np.ndarray]
    simulation: SimulationSettings = field(default_factory=SimulationSettings)
    switch: SwitchThresholds = field(default_factory=SwitchThresholds)
    contact: ContactSettings = field(default_factory=ContactSettings)
    source: str = "<dict>"
    controller_class: str | None = None
    gait: GaitSettings = field(default_factory=GaitSettings)
    balance: BalanceSettings = field(default_factory=BalanceSettings)
    controller_settings: dict[str, Any] = field(default_factory=dict)
    actuators: ActuatorChoice | None = None
    robot: RobotVariant | None = None
    disturbances: Disturbances | None = None

    @property
    def runs_thesis_controller(self) -> bool:
        """Whether the thesis controller executes this walk (no user controller, and the thesis gait or the zmp gait
        with ``gait.controller: thesis``)."""
        return self.controller_class is None and (not self.gait.is_zmp or self.gait.controller == "thesis")


def _lowered(src: str, path: PathParams, dz: float) -> PathParams:
    """``path`` with every hip waypoint ``dz`` m lower (the zmp gait's ``gait.hip_lowering_m``; a robot variant's
    legs, ``robot.hip_height``)."""
    Phip = np.array(path.Phip, dtype=float)
    Phip[:, 2] -= dz
    if Phip[:, 2].min() <= HIP_HEIGHT.lo:
        raise ScenarioError(f"{src}: gait.hip_lowering_m: {dz} m puts the hip at {Phip[:, 2].min():.3f} m, below "
                            "the ground")
    return replace(path, Phip=Phip)




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
RESET_WEIGHT = Num("a weight", 0.0, lo_open=True)


# --------------------------------------------------------------------------------------------- sections
def _check_path(src: str, raw: Any) -> dict[str, Any]:
    """Form of the ``path`` block: keys, types, lengths, element ranges.  Returns it unchanged."""
    d = mapping_of(src, "path", raw)
    check_keys(src, "path", d, PATH_KEYS)
    for k in PATH_KEYS:
        if k != "first_phase" and k not in d:
            raise ScenarioError(f"{src}: path.{k}: missing (required keys: {', '.join(PATH_KEYS[:-1])})")
    P = d["Phip"]
    if not isinstance(P, list) or len(P) < 2:
        raise ScenarioError(f"{src}: path.Phip: expected a list of n >= 2 waypoints [x, y, z] in m, got "
                            f"{show(P)}{'' if isinstance(P, list) else type_hint(P)}")
    for i, p in enumerate(P):
        if not isinstance(p, list) or len(p) != 3:
            raise ScenarioError(f"{src}: path.Phip[{i}]: expected a waypoint [x, y, z] in m, got {show(p)}")
        number(src, f"path.Phip[{i}][0]", p[0], COORD)
        number(src, f"path.Phip[{i}][1]", p[1], COORD)
        number(src, f"path.Phip[{i}][2]", p[2], HIP_HEIGHT)
    n = len(P)
    V = d["Vhip"]
    if isinstance(V, list) and len(V) != 2 * n - 1:
        raise ScenarioError(f"{src}: path.Vhip: expected 2n-1 = {2 * n - 1} speeds for n = {n} waypoints "
                            f"(V_1, V_12, V_2, ..., V_n), got {len(V)}")
    vector(src, "path.Vhip", V, 2 * n - 1, SPEED, "speeds in m/s")
    for k, rng in PATH_SEGMENT.items():
        v = d[k]
        if isinstance(v, list) and len(v) != n - 1:
            raise ScenarioError(f"{src}: path.{k}: expected n-1 = {n - 1} entries, one per segment for n = {n} "
                                f"waypoints, got {len(v)}")
        vector(src, f"path.{k}", v, n - 1, rng, "one per segment")
    for k in ("toe_R0", "toe_L0"):
        v = vector(src, f"path.{k}", d[k], 3, COORD, "a toe point [x, y, z] in m")
        number(src, f"path.{k}[2]", v[2], TOE_HEIGHT)
    for k in ("foot_R0", "foot_L0"):
        M = d[k]
        if not isinstance(M, list) or len(M) != 3:
            raise ScenarioError(f"{src}: path.{k}: expected a 3x3 rotation matrix (3 rows of 3), got {show(M)}")
        for i, row in enumerate(M):
            vector(src, f"path.{k}[{i}]", row, 3, ROT_ENTRY, "a rotation-matrix row")
    if "first_phase" in d and d["first_phase"] not in FIRST_PHASES:
        raise ScenarioError(f"{src}: path.first_phase: expected one of {', '.join(FIRST_PHASES)}, got "
                            f"{show(d['first_phase'])}")
    return d


def _check_reset(src: str, raw: Any) -> dict[str, np.ndarray]:
    reset = mapping_of(src, "reset", raw)
    check_keys(src, "reset", reset, RESET_KEYS)
    W_adj = {}
    for k in RESET_KEYS:
        if k not in reset:
            raise ScenarioError(f"{src}: reset.{k}: missing (expected 14 positive weights, eq. 4.97/4.100)")
        W_adj[k] = np.array(vector(src, f"reset.{k}", reset[k], 14, RESET_WEIGHT,
                                    "weights of the lower-body joints without the toes, errata K-11"))
    return W_adj


# --------------------------------------------------------------------------------------------- entry points
def _user_controller(src: str, doc: dict) -> tuple[str | None, dict[str, Any]]:
    """``controller_class`` and ``controller_settings``: the class's dotted name (form checked here, imported when the
    walk is assembled) and its own settings (any mapping; the controller validates it in ``setup``)."""
    cc = doc.get("controller_class")
    if cc is not None and (not isinstance(cc, str) or not DOTTED_CLASS.match(cc)):
        raise ScenarioError(f"{src}: controller_class: expected 'package.module:ClassName' (a controller class "
                            f"importable from PYTHONPATH), got {show(cc)}")
    settings = doc.get("controller_settings")
    if settings is None:
        return cc, {}
    if cc is None:
        raise ScenarioError(f"{src}: controller_settings: given without a controller_class to receive them; the "
                            "shipped controllers have their own sections (controller, balance)")
    return cc, dict(mapping_of(src, "controller_settings", settings))


def parse_scenario(doc: Any, source: str = "<dict>") -> Scenario:
    """Validate a parsed YAML document and build a :class:`Scenario`.

    Args:
        doc: the document (a mapping of sections; a ``base:`` key must have been resolved, see
            :func:`read_scenario_doc`).
        source: the file's name, for messages and for the default ``name``.

    Raises:
        ScenarioError: the message names the file, the field, the value and what was expected.
    """
    src = source
    if doc is None:
        raise ScenarioError(f"{src}: the file is empty; expected a mapping with sections {', '.join(REQUIRED)}")
    doc = mapping_of(src, "top level", doc)
    check_keys(src, "", doc, SECTIONS)
    if "base" in doc:
        raise ScenarioError(f"{src}: base: {show(doc['base'])} must be resolved before parsing; load the file with "
                            "load_scenario or read_scenario_doc")
    for sec in REQUIRED:
        if sec not in doc:
            raise ScenarioError(f"{src}: {sec}: missing section (required: {', '.join(REQUIRED)})")
    name = doc.get("name", Path(source).stem)
    if not isinstance(name, str) or not name.strip() or any(c in name for c in "/\\\0") or name in (".", ".."):
        raise ScenarioError(f"{src}: name: expected a non-empty string usable as a folder name, got {show(name)}")
    desc = doc.get("description", "")
    if not isinstance(desc, str):
        raise ScenarioError(f"{src}: description: expected a string, got {show(desc)}")
    path_raw = _check_path(src, doc["path"])
    try:
        path = PathParams.from_dict(path_raw, where="path")
    except PathParamError as exc:
        raise ScenarioError(f"{src}: {exc}") from None
    sim = flat_section(src, "simulation", doc.get("simulation"), SimulationSettings, {
        "method": METHODS, "step_s": Num("a step in s", 1e-5, 0.05),
        "t_end_s": ("optional", Num("a stop time in s", 0.0, 1e4, lo_open=True)),
        "impact_law": IMPACT_LAWS, "fall_height_m": Num("a height in m", 0.0, 2.0),
        "max_phase_overtime": Num("a ratio to the nominal phase duration", 1.0, 100.0, lo_open=True)})
    sw = flat_section(src, "phase_switch", doc.get("phase_switch"), SwitchThresholds, {
        "toe_flat_height_m": Num("a height in m", 0.0, 0.1),
        "touchdown_tolerance_m": Num("a tolerance in m", 0.0, 0.05, lo_open=True),
        "min_horizontal_progress_fraction": Num("a fraction", 0.0, 1.0),
        "dsp_hip_distance_m": Num("a distance in m", 0.0, 1.0, lo_open=True),
        "dsp_overtime_fraction": Num("a fraction", 0.0, 10.0)})
    ct = flat_section(src, "contact", doc.get("contact"), ContactSettings, {
        "friction_coefficient": Num("a friction coefficient", 0.0, 5.0, lo_open=True)})
    gait = flat_section(src, "gait", doc.get("gait"), GaitSettings, {
        "hip_reference": HIP_REFERENCES, "horizon_s": Num("a preview horizon in s", 0.05, 5.0),
        "lead_in_s": Num("a standing double support in s", 0.2, 5.0),
        "lead_out_s": Num("a planned stop after the last phase in s", 0.0, 5.0),
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
    cc, user_settings = _user_controller(src, doc)
    thesis_runs = cc is None and (not gait.is_zmp or gait.controller == "thesis")
    if "controller" in doc or thesis_runs:
        if "controller" not in doc:
            raise ScenarioError(f"{src}: controller: missing section: the thesis controller runs this walk "
                                f"({'the thesis gait' if not gait.is_zmp else 'gait.controller: thesis'}) and needs "
                                "its Appendix B weights")
        controller: ControllerParams | None = parse_controller(src, doc["controller"])
    else:
        controller = None
    if "reset" in doc or sim.impact_law == "thesis":
        if "reset" not in doc:
            raise ScenarioError(f"{src}: reset: missing section: the thesis impact law (simulation.impact_law: "
                                "thesis) needs its touchdown weights W_adj")
        W_adj = _check_reset(src, doc["reset"])
    else:
        W_adj = {}
    balance = parse_balance(src, doc.get("balance"))
    folder = Path(source).parent if source and not source.startswith("<") else None
    section = parse_robot(src, doc.get("robot"))
    robot, robot_actuators = (None, None) if section is None else (section.variant, section.actuators)
    if section is not None and section.hip_rise_m != 0.0:   # the walk keeps the thesis robot's knee bend
        path = _lowered(src, path, -section.hip_rise_m)
    if robot_actuators is not None and doc.get("actuators") is not None:
        raise ScenarioError(f"{src}: robot.actuators: given with an actuators section too; expected one of them")
    actuators = parse_actuators(src, doc.get("actuators") if robot_actuators is None else robot_actuators, folder)
    return Scenario(name=name, description=desc, path=path, controller=controller, W_adj=W_adj, simulation=sim,
                    switch=sw, contact=ct, source=source, controller_class=cc, gait=gait, balance=balance,
                    controller_settings=user_settings, actuators=actuators, robot=robot,
                    disturbances=parse_disturbances(src, doc.get("disturbances")))


NOT_INHERITED = ("name", "description")
"""Keys a file does not take from its ``base``: they describe the file itself."""


def merge(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    """``override`` laid over ``base``: mappings merge key by key, recursively; any other value replaces."""
    out = dict(base)
    for k, v in override.items():
        out[k] = merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def read_scenario_doc(path: str | Path, _seen: tuple[Path, ...] = ()) -> Any:
    """The YAML document of a scenario file with its ``base:`` chain resolved.

    ``base:`` names another scenario file, relative to this file's folder; this file's keys are laid over it
    (:func:`merge`), except ``name`` and ``description``, which are never inherited.

    Raises:
        ScenarioError: an unreadable file, a ``base`` that is not a string or does not exist, or a cycle of bases.
    """
    p = Path(path)
    doc = read_yaml(p)
    if not isinstance(doc, dict) or "base" not in doc:
        return doc
    base = doc.pop("base")
    if not isinstance(base, str) or not base.strip():
        raise ScenarioError(f"{p}: base: expected the path of a scenario file, relative to this file, got {show(base)}")
    base_path = (p.parent / base).resolve()
    if base_path in _seen or base_path == p.resolve():
        raise ScenarioError(f"{p}: base: {base!r} leads back to {base_path.name}: a cycle of base files")
    if not base_path.is_file():
        raise ScenarioError(f"{p}: base: {base!r}: no such file ({base_path})")
    parent = read_scenario_doc(base_path, _seen + (p.resolve(),))
    if not isinstance(parent, dict):
        raise ScenarioError(f"{base_path}: expected a mapping of sections (the base of {p.name})")
    parent = {k: v for k, v in parent.items() if k not in NOT_INHERITED}
    return merge(parent, doc)


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file, its ``base:`` chain resolved.

    Args:
        path: the YAML file.

    Raises:
        ScenarioError: the message names the file, the field, the value and what was expected.
    """
    return parse_scenario(read_scenario_doc(path), str(Path(path)))
