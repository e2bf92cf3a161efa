"""Design files (YAML) of ``humanoid-optimize``: what to vary, what to minimise, what every design must meet.

::

    base: ../params/sim3_zmp_motors.yaml      # the walk every candidate walks (relative to this file, then the cwd)
    description: "gearboxes and build weight"  # optional
    engine: mujoco                            # pinocchio (welds), mujoco (real contact; the default) or thesis
    budget: {trials: 30, seed: 1}             # candidates walked (besides the baseline), the sampler's seed
    sampler: tpe                              # tpe (default), nsga2 or random (Optuna's)
    parameters:                               # dotted paths into the scenario document, as sweep axes
      robot.mass_scale.all: {low: 0.85, high: 1.0}
      "actuators.gear_ratio.theta15, actuators.gear_ratio.theta16": {low: 40, high: 160, log: true}
      actuators.joints.toe: {choices: [mini_cheetah_knee, osl_knee]}
      actuators.gear_ratio.toe: {low: 8, high: 20, step: 1}        # an integer-spaced grid
    objectives:                               # one (single-objective) or more (a Pareto front)
      - {column: design_actuators_electrical_cost_of_transport, direction: minimize}
      - {column: "design_actuators_joints_*_speed_margin", aggregate: min, direction: maximize}
    constraints: [completed, motors_pass]     # and/or {column: ..., min: ..., max: ...}
    best: 3                                   # designs written out with their URDF and sizing card

Columns are those of a sweep row (:func:`humanoid_sim.sweep.walk.flatten_summary`); a ``*`` in a column matches
many (``aggregate`` of ``min``, ``max`` or ``sum`` then combines them).  The built-in constraints:

- ``completed``: the walk reached its end without falling or failing;
- ``motors_pass``: every motor's margin (torque, speed, current, RMS current, winding temperature) is >= 0 over the
  walk, and the drive never had to cut a command after the start-up settling (``design.actuators``).

Every error is a :class:`DesignFileError` naming the file, the field, the value and what was expected; the command
prints it and exits with status 2 before anything runs.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from humanoid_sim.errors import InputError
from humanoid_sim.scenario.fields import ScenarioError, suggest_key
from humanoid_sim.scenario.schema import parse_scenario, read_scenario_doc
from humanoid_sim.scenario.yamlio import read_yaml
from humanoid_sim.sweep.spec import DottedPath, SweepError, apply

TOP_KEYS = ("base", "description", "engine", "budget", "sampler", "parameters", "objectives", "constraints", "best")
ENGINES = ("mujoco", "pinocchio", "thesis")
SAMPLERS = ("tpe", "nsga2", "random")
BUILT_IN = ("completed", "motors_pass")
AGGREGATES = ("min", "max", "sum")
MAX_TRIALS = 10_000


class DesignFileError(InputError):
    """A design file that cannot be run (the message names the file, the field and the value)."""


@dataclass(frozen=True)
class Parameter:
    """One design variable: the scenario paths it sets and its domain.

    Attributes:
        name: the key as written (the candidates' column).
        paths: where the value goes in the scenario document.
        low, high: a number's bounds (None for choices).
        log: sampled on a log scale.
        step: a grid step (None: continuous).
        choices: the values of a categorical variable (None for a number).
    """

    name: str
    paths: tuple[DottedPath, ...]
    low: float | None = None
    high: float | None = None
    log: bool = False
    step: float | None = None
    choices: tuple[Any, ...] | None = None


@dataclass(frozen=True)
class Objective:
    """A number to minimise or maximise: a row's column (or an aggregate of the columns a pattern matches)."""

    column: str
    direction: str = "minimize"
    aggregate: str | None = None

    @property
    def label(self) -> str:
        return self.column if self.aggregate is None else f"{self.aggregate}({self.column})"


@dataclass(frozen=True)
class Constraint:
    """A condition every accepted design meets: a built-in name, or a column between ``min`` and ``max``."""

    name: str
    column: str | None = None
    min: float | None = None
    max: float | None = None


@dataclass(frozen=True)
class DesignStudy:
    """A parsed design file.

    Attributes:
        source: the file.
        base: the base scenario's file.
        base_doc: the base scenario's document (its own ``base:`` chain resolved).
        description: free text.
        engine: the engine every candidate walks on.
        trials: candidates to walk (the baseline not counted).
        seed: the sampler's seed.
        sampler: ``tpe``, ``nsga2`` or ``random``.
        parameters, objectives, constraints: as the module docstring says.
        best: how many designs to write out.
    """

    source: Path
    base: Path
    base_doc: dict[str, Any]
    description: str
    engine: str
    trials: int
    seed: int
    sampler: str
    parameters: tuple[Parameter, ...]
    objectives: tuple[Objective, ...]
    constraints: tuple[Constraint, ...]
    best: int

    def candidate_doc(self, values: dict[str, Any], name: str) -> dict[str, Any]:
        """The scenario document of a candidate: the base with each parameter's value at its paths."""
        doc = copy.deepcopy(self.base_doc)
        for p in self.parameters:
            for path in p.paths:
                apply(doc, path, values[p.name], "set")
        doc["name"] = name
        return doc

    def midpoint(self) -> dict[str, Any]:
        """A value of every parameter inside its domain (the first choice, the bounds' mean)."""
        out: dict[str, Any] = {}
        for p in self.parameters:
            if p.choices is not None:
                out[p.name] = p.choices[0]
            else:
                assert p.low is not None and p.high is not None
                out[p.name] = math.sqrt(p.low * p.high) if p.log else 0.5 * (p.low + p.high)
        return out


def _number(src: str, where: str, x: Any) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
        raise DesignFileError(f"{src}: {where} = {x!r}: expected a finite number")
    return float(x)


def _parameter(src: str, key: Any, raw: Any) -> Parameter:
    where = f"parameters.{key}"
    if not isinstance(key, str):
        raise DesignFileError(f"{src}: parameters: key {key!r}: expected a dotted path into the scenario")
    try:
        paths = tuple(DottedPath.parse(part.strip(), f"{src}: {where}") for part in key.split(","))
    except SweepError as exc:
        raise DesignFileError(str(exc)) from None
    if not isinstance(raw, dict):
        raise DesignFileError(f"{src}: {where} = {raw!r}: expected {{low: .., high: ..}} (optionally log, step) or "
                              "{choices: [..]}")
    allowed = ("choices",) if "choices" in raw else ("low", "high", "log", "step")
    for k in raw:
        if k not in allowed:
            raise DesignFileError(f"{src}: {where}.{k}: unknown key{suggest_key(str(k), allowed)}")
    if "choices" in raw:
        ch = raw["choices"]
        if not isinstance(ch, list) or len(ch) < 2 or any(isinstance(c, (dict, list)) for c in ch):
            raise DesignFileError(f"{src}: {where}.choices = {ch!r}: expected a list of at least 2 plain values")
        return Parameter(key, paths, choices=tuple(ch))
    for k in ("low", "high"):
        if k not in raw:
            raise DesignFileError(f"{src}: {where}.{k}: missing; expected a number")
    low, high = _number(src, f"{where}.low", raw["low"]), _number(src, f"{where}.high", raw["high"])
    if not low < high:
        raise DesignFileError(f"{src}: {where}: low = {low:g} must be below high = {high:g}")
    log = raw.get("log", False)
    if not isinstance(log, bool):
        raise DesignFileError(f"{src}: {where}.log = {log!r}: expected true or false")
    if log and low <= 0:
        raise DesignFileError(f"{src}: {where}.low = {low:g}: a log-scaled parameter needs low > 0")
    step = None if raw.get("step") is None else _number(src, f"{where}.step", raw["step"])
    if step is not None and (step <= 0 or log):
        raise DesignFileError(f"{src}: {where}.step = {step:g}: expected a step > 0, and no step with log: true")
    return Parameter(key, paths, low, high, log, step)


def _objective(src: str, i: int, raw: Any) -> Objective:
    where = f"objectives[{i}]"
    if not isinstance(raw, dict) or "column" not in raw:
        raise DesignFileError(f"{src}: {where} = {raw!r}: expected {{column: NAME, direction: minimize|maximize}} "
                              "(and aggregate: min|max|sum for a column with *)")
    for k in raw:
        if k not in ("column", "direction", "aggregate"):
            keys = ("column", "direction", "aggregate")
            raise DesignFileError(f"{src}: {where}.{k}: unknown key{suggest_key(str(k), keys)}")
    col, direction, agg = raw["column"], raw.get("direction", "minimize"), raw.get("aggregate")
    if not isinstance(col, str) or not col:
        raise DesignFileError(f"{src}: {where}.column = {col!r}: expected a column name of the candidates' rows")
    if direction not in ("minimize", "maximize"):
        raise DesignFileError(f"{src}: {where}.direction = {direction!r}: expected minimize or maximize")
    if ("*" in col) != (agg is not None):
        raise DesignFileError(f"{src}: {where}: a column with * needs aggregate (min, max or sum), and only such a "
                              f"column takes one; got column {col!r}, aggregate {agg!r}")
    if agg is not None and agg not in AGGREGATES:
        raise DesignFileError(f"{src}: {where}.aggregate = {agg!r}: expected one of {', '.join(AGGREGATES)}")
    return Objective(col, direction, agg)


def _constraint(src: str, i: int, raw: Any) -> Constraint:
    where = f"constraints[{i}]"
    if isinstance(raw, str):
        if raw not in BUILT_IN:
            raise DesignFileError(f"{src}: {where} = {raw!r}: not a built-in constraint{suggest_key(raw, BUILT_IN)} "
                                  "(or write {column: NAME, min: X, max: Y})")
        return Constraint(raw)
    if not isinstance(raw, dict) or "column" not in raw or not ({"min", "max"} & set(raw)):
        raise DesignFileError(f"{src}: {where} = {raw!r}: expected {', '.join(BUILT_IN)} or {{column: NAME, min: X, "
                              "max: Y}} (at least one bound)")
    for k in raw:
        if k not in ("column", "min", "max"):
            raise DesignFileError(f"{src}: {where}.{k}: unknown key{suggest_key(str(k), ('column', 'min', 'max'))}")
    lo = None if raw.get("min") is None else _number(src, f"{where}.min", raw["min"])
    hi = None if raw.get("max") is None else _number(src, f"{where}.max", raw["max"])
    return Constraint(f"{raw['column']} in [{lo}, {hi}]", str(raw["column"]), lo, hi)


def load_design(path: str | Path) -> DesignStudy:
    """Read and check a design file (module docstring); every candidate's scenario is checked by the scenario
    schema at the parameters' bounds and choices before anything runs.

    Raises:
        DesignFileError: the message names the file, the field, the value and what was expected.
    """
    src = Path(path)
    doc = read_yaml(src, "design file", DesignFileError)
    if not isinstance(doc, dict):
        raise DesignFileError(f"{src}: expected a mapping with base, parameters and objectives, got {doc!r}")
    for k in doc:
        if k not in TOP_KEYS:
            raise DesignFileError(f"{src}: {k}: unknown key{suggest_key(str(k), TOP_KEYS)}")
    for k in ("base", "parameters", "objectives"):
        if k not in doc:
            raise DesignFileError(f"{src}: {k}: missing; a design file names its base scenario, its parameters "
                                  "and its objectives")
    base = Path(str(doc["base"]))
    if not base.is_absolute():
        base = src.parent / base if (src.parent / base).exists() else base
    try:
        base_doc = read_scenario_doc(base)
    except (OSError, ScenarioError) as exc:
        raise DesignFileError(f"{src}: base = {doc['base']!r}: {exc}") from None
    engine = doc.get("engine", "mujoco")
    if engine not in ENGINES:
        raise DesignFileError(f"{src}: engine = {engine!r}: expected one of {', '.join(ENGINES)}")
    budget = doc.get("budget", {})
    if not isinstance(budget, dict) or set(budget) - {"trials", "seed"}:
        raise DesignFileError(f"{src}: budget = {budget!r}: expected {{trials: N, seed: S}}")
    trials, seed = budget.get("trials", 30), budget.get("seed", 0)
    for name, v, lo in (("trials", trials, 1), ("seed", seed, 0)):
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= MAX_TRIALS * 1000:
            raise DesignFileError(f"{src}: budget.{name} = {v!r}: expected a whole number >= {lo}")
    if trials > MAX_TRIALS:
        raise DesignFileError(f"{src}: budget.trials = {trials}: expected at most {MAX_TRIALS}")
    sampler = doc.get("sampler", "tpe")
    if sampler not in SAMPLERS:
        raise DesignFileError(f"{src}: sampler = {sampler!r}: expected one of {', '.join(SAMPLERS)}")
    params = doc["parameters"]
    if not isinstance(params, dict) or not params:
        raise DesignFileError(f"{src}: parameters = {params!r}: expected a mapping of dotted paths to domains")
    parameters = tuple(_parameter(str(src), k, v) for k, v in params.items())
    objs = doc["objectives"]
    if not isinstance(objs, list) or not objs:
        raise DesignFileError(f"{src}: objectives = {objs!r}: expected a list of one or more objectives")
    objectives = tuple(_objective(str(src), i, o) for i, o in enumerate(objs))
    cons = doc.get("constraints", list(BUILT_IN))
    if not isinstance(cons, list):
        raise DesignFileError(f"{src}: constraints = {cons!r}: expected a list")
    constraints = tuple(_constraint(str(src), i, c) for i, c in enumerate(cons))
    best = doc.get("best", 3)
    if isinstance(best, bool) or not isinstance(best, int) or not 0 <= best <= 20:
        raise DesignFileError(f"{src}: best = {best!r}: expected a whole number of designs in [0, 20]")
    desc = doc.get("description", "")
    study = DesignStudy(src, base, base_doc, str(desc), engine, trials, seed, sampler, parameters, objectives,
                        constraints, best)
    _check_candidates(study)
    return study


def _check_candidates(study: DesignStudy) -> None:
    """Every corner of the domain (each parameter at its low, its high, each choice) through the scenario schema."""
    mid = study.midpoint()
    probes = [("midpoint", mid)]
    for p in study.parameters:
        for v in (p.choices if p.choices is not None else (p.low, p.high)):
            probes.append((f"parameters.{p.name} = {v!r}", {**mid, p.name: v}))
    for label, values in probes:
        try:
            parse_scenario(study.candidate_doc(values, "candidate"), f"{study.source} ({label})")
        except SweepError as exc:
            raise DesignFileError(f"{study.source}: {exc}") from None
        except ScenarioError as exc:
            raise DesignFileError(str(exc)) from None


__all__ = ["AGGREGATES", "BUILT_IN", "Constraint", "DesignFileError", "DesignStudy", "Objective", "Parameter",
           "load_design"]
