"""Scenario files (YAML): schema, validation and the typed :class:`Scenario` the simulator runs.

A scenario has the sections ``path`` (locomotion parameters of thesis 3.1), ``controller`` (Appendix B weights
and prediction times, names verbatim), ``reset`` (touchdown weights W_adj), ``simulation`` (integrator, step,
stop time, impact law, fall height), ``phase_switch`` (section 6.1.1 thresholds) and ``contact`` (friction
coefficient for the feasibility audit).  Files are read with a safe YAML loader (no code execution).

Every error is a :class:`ScenarioError` whose message names the file, the field path (``path.R[3]``), the value
and what was expected; ``walk.py`` prints it and exits with status 2 before anything is written.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from humanoid_sim.command import ControllerParamError, ControllerParams
from humanoid_sim.trajectory import PathParamError, PathParams

SECTIONS = ("name", "description", "path", "controller", "reset", "simulation", "phase_switch", "contact")
REQUIRED = ("path", "controller", "reset")
RESET_KEYS = ("Wadj_qdot_LFFSSP_to_RFFDSP", "Wadj_qdot_RFFSSP_to_LFFDSP")
METHODS = ("ode3", "rk4", "euler")
IMPACT_LAWS = ("thesis", "inelastic")


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
    max_phase_overtime: float = 3.0  # an SSP lasting this many times its nominal duration is a failure


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

    friction_coefficient: float = 0.8


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


def _suggest(key: str, allowed: tuple[str, ...] | list[str]) -> str:
    close = difflib.get_close_matches(key, list(allowed), n=1, cutoff=0.5)
    return f"; did you mean {close[0]!r}?" if close else f"; allowed: {', '.join(allowed)}"


def _mapping(src: str, where: str, value: Any) -> dict:
    if not isinstance(value, dict):
        raise ScenarioError(f"{src}: {where}: expected a mapping of keys to values, got {type(value).__name__} "
                            f"({value!r})")
    return value


def _check_keys(src: str, where: str, d: dict, allowed: tuple[str, ...] | list[str]) -> None:
    for k in d:
        if k not in allowed:
            raise ScenarioError(f"{src}: {where + '.' if where else ''}{k}: unknown key{_suggest(str(k), allowed)}")


def _number(src: str, where: str, value: Any, lo: float | None = None, hi: float | None = None,
            lo_open: bool = False, what: str = "a number") -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise ScenarioError(f"{src}: {where}: expected {what}, got {value!r}")
    v = float(value)
    if lo is not None and (v < lo or (lo_open and v == lo)):
        raise ScenarioError(f"{src}: {where}: expected {what} {'>' if lo_open else '>='} {lo}, got {value!r}")
    if hi is not None and v > hi:
        raise ScenarioError(f"{src}: {where}: expected {what} <= {hi}, got {value!r}")
    return v


def _dataclass_section(src: str, name: str, raw: Any, cls, checks: dict[str, tuple]) -> Any:
    if raw is None:
        return cls()
    d = _mapping(src, name, raw)
    _check_keys(src, name, d, tuple(checks))
    kwargs = {}
    for k, v in d.items():
        spec = checks[k]
        if spec[0] == "choice":
            if v not in spec[1]:
                raise ScenarioError(f"{src}: {name}.{k}: expected one of {', '.join(spec[1])}, got {v!r}")
            kwargs[k] = v
        elif spec[0] == "optional_number" and v is None:
            kwargs[k] = None
        else:
            kwargs[k] = _number(src, f"{name}.{k}", v, *spec[1:])
    return cls(**kwargs)


def parse_scenario(doc: Any, source: str = "<dict>") -> Scenario:
    """Validate a parsed YAML document and build a :class:`Scenario`."""
    src = source
    if doc is None:
        raise ScenarioError(f"{src}: the file is empty; expected a mapping with sections {', '.join(REQUIRED)}")
    doc = _mapping(src, "top level", doc)
    _check_keys(src, "", doc, SECTIONS)
    for sec in REQUIRED:
        if sec not in doc:
            raise ScenarioError(f"{src}: {sec}: missing section (required: {', '.join(REQUIRED)})")
    name = doc.get("name", Path(source).stem)
    if not isinstance(name, str) or not name or any(c in name for c in "/\\\0"):
        raise ScenarioError(f"{src}: name: expected a non-empty string usable as a folder name, got {name!r}")
    desc = doc.get("description", "")
    if not isinstance(desc, str):
        raise ScenarioError(f"{src}: description: expected a string, got {desc!r}")
    try:
        path = PathParams.from_dict(_mapping(src, "path", doc["path"]), where="path")
    except PathParamError as exc:
        raise ScenarioError(f"{src}: {exc}") from None
    try:
        controller = ControllerParams.from_dict(_mapping(src, "controller", doc["controller"]), where="controller")
    except (ControllerParamError, TypeError, ValueError) as exc:
        raise ScenarioError(f"{src}: {exc}") from None
    reset = _mapping(src, "reset", doc["reset"])
    _check_keys(src, "reset", reset, RESET_KEYS)
    W_adj = {}
    for k in RESET_KEYS:
        if k not in reset:
            raise ScenarioError(f"{src}: reset.{k}: missing (expected 14 non-negative weights, eq. 4.97/4.100)")
        val = reset[k]
        if not isinstance(val, list) or len(val) != 14:
            raise ScenarioError(f"{src}: reset.{k}: expected a list of 14 weights (lower-body joints without the "
                                f"toes, errata K-11), got {val!r}")
        arr = np.array([_number(src, f"reset.{k}[{i}]", x, 0.0, lo_open=True, what="a positive weight")
                        for i, x in enumerate(val)])
        W_adj[k] = arr
    sim = _dataclass_section(src, "simulation", doc.get("simulation"), SimulationSettings, {
        "method": ("choice", METHODS), "step_s": ("number", 1e-5, 0.05, True, "a step in s"),
        "t_end_s": ("optional_number", 0.0, 1e4, True, "a stop time in s"),
        "impact_law": ("choice", IMPACT_LAWS), "fall_height_m": ("number", 0.0, 2.0, False, "a height in m"),
        "max_phase_overtime": ("number", 1.0, 100.0, True, "a ratio")})
    sw = _dataclass_section(src, "phase_switch", doc.get("phase_switch"), SwitchThresholds, {
        "toe_flat_height_m": ("number", 0.0, 0.1, False, "a height in m"),
        "touchdown_tolerance_m": ("number", 0.0, 0.05, True, "a tolerance in m"),
        "min_horizontal_progress_fraction": ("number", 0.0, 1.0, False, "a fraction"),
        "dsp_hip_distance_m": ("number", 0.0, 1.0, True, "a distance in m"),
        "dsp_overtime_fraction": ("number", 0.0, 10.0, False, "a fraction")})
    ct = _dataclass_section(src, "contact", doc.get("contact"), ContactSettings, {
        "friction_coefficient": ("number", 0.0, 5.0, True, "a friction coefficient")})
    return Scenario(name=name, description=desc, path=path, controller=controller, W_adj=W_adj, simulation=sim,
                    switch=sw, contact=ct, source=source)


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file."""
    p = Path(path)
    if not p.exists():
        raise ScenarioError(f"{p}: no such scenario file")
    if not p.is_file():
        raise ScenarioError(f"{p}: not a regular file")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{p}: cannot read: {exc}") from None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise ScenarioError(f"{p}: not valid YAML{where}: {getattr(exc, 'problem', exc)}") from None
    return parse_scenario(doc, str(p))
