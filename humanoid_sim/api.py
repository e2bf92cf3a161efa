"""The public API: run a walk from Python and read what it did.

    import humanoid_sim as hs

    run = hs.run_walk("sim1_zmp", engine="mujoco")   # a shipped scenario, or the path of a YAML file
    print(run.status, run.summary["torque_peak_Nm"]["T3"])
    df = run.log.to_pandas()                         # one row per logged step, columns "T.T3 [N m]", ...
    run.write("results/sim1_zmp/mujoco")              # results.npz, summary.json, figures, playback.html

``walk.py`` (``humanoid-walk``) and the sweeps run their walks through `run_walk`.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from humanoid_sim.analysis.summary import provenance, summary_audit_design
from humanoid_sim.engines import ENGINE_NAMES
from humanoid_sim.errors import InputError
from humanoid_sim.interfaces.log import SIGNALS, atomic_write_text
from humanoid_sim.paths import scenario_path
from humanoid_sim.robot.actuators import T_NAMES
from humanoid_sim.robot.model import THETA_NAMES, HumanoidModel, load_model
from humanoid_sim.robot.variant import RobotVariant, variant_model
from humanoid_sim.scenario import Scenario, load_scenario
from humanoid_sim.sim.loop import SimResult
from humanoid_sim.sim.simulate import Simulator
from humanoid_sim.sim.status import RunStatus

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

    from humanoid_sim.analysis.audit import AuditReport
    from humanoid_sim.analysis.design import DesignCard
    from humanoid_sim.interfaces.controller import Controller

Engine = Literal["pinocchio", "thesis", "mujoco"]


@lru_cache(maxsize=8)
def robot(variant: RobotVariant | None = None) -> HumanoidModel:
    """The humanoid's model, loaded once per process and variant (the URDF parse takes ~0.1 s).

    Args:
        variant: a scenario's ``robot`` section (`Scenario.robot`); None (or a nominal variant) for the thesis robot.
    """
    if variant is not None and variant.is_nominal:
        return robot(None)
    return load_model() if variant is None else variant_model(variant)


def _component_labels(name: str, shape: tuple[int, ...], hm: HumanoidModel) -> list[tuple[str, str]]:
    """(label, unit) per component of one logged signal, in C order of its trailing axes."""
    unit = SIGNALS[name][0] if name in SIGNALS else "-"
    joints = [hm.model.names[j] for j in range(2, hm.model.njoints)]
    xyz = ["x", "y", "z"]
    if name in ("theta", "theta_dot", "theta_ddot", "theta_ddot_cmd"):
        return [(n, unit) for n in THETA_NAMES]
    if name in ("T", "T_cmd", "saturated"):
        return [(n, unit) for n in T_NAMES]
    if name == "q":
        return ([(f"base_{a}", "m") for a in xyz] + [(f"base_quat_{a}", "-") for a in "xyzw"]
                + [(j, "rad") for j in joints])
    if name in ("v", "tau"):
        lin, ang = ("m/s", "rad/s") if name == "v" else ("N", "N m")
        return ([(f"base_v{a}", lin) for a in xyz] + [(f"base_w{a}", ang) for a in xyz]
                + [(j, "rad/s" if name == "v" else "N m") for j in joints])
    if name == "foot_wrench":
        return [(f"{f}_{c}", "N" if c[0] == "f" else "N m") for f in "RL" for c in ("fx", "fy", "fz", "mx", "my", "mz")]
    if name in ("body_force", "body_moment"):
        return [(f"body{b}_{a}", unit) for b in (1, 2, 3, 4) for a in xyz]
    if name == "cop":
        return [(f"{f}_{a}", unit) for f in "RL" for a in xyz[:shape[-1]]]
    if name == "in_contact":
        return [(f, unit) for f in "RL"]
    if len(shape) == 2 and shape == (3, 3):
        return [(f"R{i}{j}", unit) for i in range(3) for j in range(3)]
    if len(shape) == 1 and shape[0] in (2, 3):
        return [(a, unit) for a in xyz[:shape[0]]]
    return [("_".join(map(str, ix)), unit) for ix in np.ndindex(*shape)]


@dataclass
class RunLog:
    """A run's log: every signal per logged step, with units (`SIGNALS`).

    Attributes:
        arrays: signal name -> array whose first axis is the logged step.
        phase_names: the name of each index the ``phase`` column holds.
    """

    arrays: dict[str, np.ndarray]
    phase_names: list[str]
    hm: HumanoidModel = field(repr=False)

    def __len__(self) -> int:
        return len(self.arrays.get("t", ()))

    def __getitem__(self, name: str) -> np.ndarray:
        return self.arrays[name]

    @property
    def units(self) -> dict[str, str]:
        """Signal name -> unit."""
        return {k: SIGNALS[k][0] for k in self.arrays if k in SIGNALS}

    def to_pandas(self) -> pd.DataFrame:
        """The log as a DataFrame: one row per logged step, indexed by time ``t [s]``.

        Columns are named ``"<signal>.<component> [<unit>]"``: joints by their thesis names (``"theta.theta3 [rad]"``),
        actuators by theirs (``"T.T3 [N m]"``), Pinocchio's coordinates by joint name, vectors by axis, feet by
        ``R`` and ``L``; ``"phase_name"`` holds the phase's name.

        Returns:
            The log as a DataFrame.
        """
        import pandas as pd

        cols: dict[str, np.ndarray] = {}
        n = len(self)
        for name, arr in self.arrays.items():
            if name == "t":
                continue
            a = np.asarray(arr)
            if a.ndim == 1:
                cols[f"{name} [{SIGNALS.get(name, ('-',))[0]}]"] = a
                continue
            flat = a.reshape(n, -1)
            for i, (label, unit) in enumerate(_component_labels(name, a.shape[1:], self.hm)):
                cols[f"{name}.{label} [{unit}]"] = flat[:, i]
        df = pd.DataFrame(cols, index=pd.Index(self.arrays["t"], name="t [s]"))
        if "phase" in self.arrays and self.phase_names:
            df["phase_name"] = [self.phase_names[int(k)] for k in self.arrays["phase"]]
        return df


@dataclass
class Run:
    """One walk: the scenario, how it ended, its summary and its log.

    Attributes:
        scenario: the validated scenario.
        engine: the engine's name.
        result: the stepping loop's record (phases, timings, the exception that ended the run).
        summary: the numbers ``summary.json`` holds (tracking, torques, contacts, speed; SI units).
        hm: the robot model.
        traj: the reference trajectory the walk followed.
        audit: the contact-feasibility audit behind ``summary["contact"]``, or None when it could not be made.
        design: the design numbers behind ``summary["design"]`` (:class:`humanoid_sim.analysis.design.DesignCard`:
            per joint torque, speed, power, work and loads over every integration step), or None without a step.
    """

    scenario: Scenario
    engine: str
    result: SimResult
    summary: dict[str, Any]
    hm: HumanoidModel = field(repr=False)
    traj: Any = field(repr=False)
    audit: AuditReport | None = field(default=None, repr=False)
    design: DesignCard | None = field(default=None, repr=False)

    @property
    def status(self) -> RunStatus:
        """How the run ended."""
        return self.result.status

    @property
    def log(self) -> RunLog:
        """The log's signals as arrays (and `RunLog.to_pandas`)."""
        return RunLog(self.result.log.arrays(), list(self.result.phase_names), self.hm)

    def column_names(self) -> dict[str, np.ndarray]:
        """The names of the columns of the logged arrays, as ``results.npz`` holds them: ``theta_names``
        (:data:`THETA_NAMES`, of ``theta``, ``theta_dot``, ...), ``T_names`` (:data:`T_NAMES`, of ``T``, ``T_cmd``,
        ``saturated``), ``q_names`` and ``v_names`` (Pinocchio's coordinates: the base's, then the joints by name;
        ``v_names`` also label ``tau``)."""
        hm = self.hm
        return {"theta_names": np.array(THETA_NAMES), "T_names": np.array(T_NAMES),
                "q_names": np.array([n for n, _ in _component_labels("q", (hm.model.nq,), hm)]),
                "v_names": np.array([n for n, _ in _component_labels("v", (hm.model.nv,), hm)])}

    def _joint_wrench(self) -> dict[str, np.ndarray]:
        """``{"joint_wrench": (n, 26, 6)}``: the wrench every joint transmits at the logged steps (thesis joint order;
        :mod:`humanoid_sim.dynamics.joint_loads`), empty without a logged step."""
        from humanoid_sim.dynamics.joint_loads import fext_from_body_wrenches, joint_loads

        a = self.result.log.arrays()
        if not len(self.result.log):
            return {}
        model = self.hm.model
        loads = joint_loads(model, a["q"], a["v"], a["a"], fext_from_body_wrenches(model, a["body_force"],
                                                                                   a["body_moment"]),
                            joints=list(THETA_NAMES))
        return {"joint_wrench": loads.wrench}

    def write(self, out: str | Path, *, figures: bool | str | Sequence[str] = True,
              playback: bool = True, full_rate: bool = False) -> list[Path]:
        """Write the run's outputs into the folder ``out`` (created if missing).

        ``results.npz`` holds the log, the column names (:meth:`column_names`), the ``engine`` and ``joint_wrench`` (the
        wrench every joint transmits at each logged step, :mod:`humanoid_sim.dynamics.joint_loads`); ``summary.json``
        the summary, with a ``provenance`` section (:func:`humanoid_sim.analysis.summary.provenance`; added here
        when the summary has none).  A run that ended before its first step has nothing to draw or play: it gets
        neither figures nor playback.

        Args:
            out: the output folder.
            figures: the figures (PNG) to draw: True or ``"all"`` for every one
                (:data:`humanoid_sim.outputs.plots.thesis.FIGURES`), ``"quick"`` for the few a user looks at first
                (``QUICK_FIGURES``), False or ``"none"`` for none, or a list of figure names.
            playback: also write ``playback.html`` (a self-contained 3-D recording).
            full_rate: also write ``trace.npz``, the signals at every integration step
                (:mod:`humanoid_sim.interfaces.trace`; ~1.5 MB per simulated second on MuJoCo).

        Besides, with the design numbers (:attr:`design`): ``design.csv`` (per joint: torque, speed, power, work,
        joint loads), ``fatigue.csv`` (rainflow cycles per km) and ``load_cases.json`` (per joint the worst
        wrenches with time, frame and state), and the sizing figures among ``figures``
        (:func:`humanoid_sim.outputs.design.write_design`).

        Returns:
            The paths written: ``results.npz``, ``summary.json``, the design files, then the figures and the
            playback.
        """
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        self.summary.setdefault("provenance", provenance("python API"))
        self.result.log.save(out / "results.npz", self.result.phase_names,
                             extra={**self.column_names(), "engine": np.array(self.engine),
                                    **self._joint_wrench()})
        atomic_write_text(out / "summary.json", json.dumps(self.summary, indent=2) + "\n")
        written = [out / "results.npz", out / "summary.json"]
        stems = _figure_stems(figures)
        if self.design is not None and len(self.result.log):
            from humanoid_sim.outputs.design import write_design

            written += write_design(self.design, out, trace=self.result.trace if full_rate else None,
                                    figures=[s for s in stems if s.startswith("sizing")], title=self.scenario.name,
                                    engine=self.engine,
                                    motors=None if self.scenario.actuators is None else self.scenario.actuators.motors)
            stems = tuple(s for s in stems if not s.startswith("sizing"))
        html: list[Path] = []

        def play() -> None:
            from humanoid_sim.outputs.viewer import write_playback

            html.append(write_playback(out / "results.npz", out / "playback.html", hm=self.hm, traj=self.traj,
                                       report=self.audit, disturbances=self.summary.get("disturbances")))

        play_now = play if playback and len(self.result.log) else None
        if stems and self.audit is not None and len(self.result.log):
            from humanoid_sim.outputs.plots.thesis import plot_all

            written += plot_all(out / "results.npz", out, traj=self.traj, report=self.audit,
                                mu=self.scenario.contact.friction_coefficient, title=self.scenario.name, hm=self.hm,
                                stems=stems, engine=self.engine, meanwhile=play_now)  # playback while figures draw
        elif play_now is not None:
            play_now()
        return written + html


def _figure_stems(figures: bool | str | Sequence[str]) -> tuple[str, ...]:
    """The figure names of `Run.write`'s ``figures`` argument: the thesis's figures and the sizing card's."""
    from humanoid_sim.outputs.design import SIZING_FIGURES
    from humanoid_sim.outputs.plots.thesis import FIGURE_SETS, FIGURES

    every = FIGURES + tuple(SIZING_FIGURES)
    sets = {**FIGURE_SETS, "all": every}
    if isinstance(figures, bool):
        return every if figures else ()
    if isinstance(figures, str):
        if figures not in sets:
            raise InputError(f"figures: {figures!r} is not one of {', '.join(sets)} or a list of figures")
        return sets[figures]
    unknown = [f for f in figures if f not in every]
    if unknown:
        raise InputError(f"figures: unknown figures {unknown}; the figures are {', '.join(every)}")
    return tuple(figures)


def as_scenario(scenario: str | Path | Scenario) -> Scenario:
    """A `Scenario` from a shipped scenario's name (``"sim1_zmp"``), a YAML path, or a Scenario.

    Raises:
        InputError: an unknown name, or a file that is not a valid scenario (the message names the field).
    """
    if isinstance(scenario, Scenario):
        return scenario
    return load_scenario(scenario_path(scenario))


def prepare(scenario: str | Path | Scenario, engine: Engine = "pinocchio", *, compiled: bool | None = None,
            controller: Controller | None = None, planner: Callable[..., Any] | None = None) -> Simulator:
    """The walk's `Simulator`: references planned, engine and controller set up.

    Args:
        scenario: a shipped scenario's name, a YAML path, or a `Scenario`.
        engine: ``"pinocchio"`` (welded feet, the thesis's model), ``"mujoco"`` (real, unilateral contact) or
            ``"thesis"`` (the NumPy transcription of the thesis's equations; slow).
        compiled: use the compiled kernels (None: where numba is installed; False: the NumPy reference path).
        controller: a controller object; None for the scenario's.
        planner: called as ``planner(hm, scenario, q0)`` instead of planning the references (a cache of the same
            plan: :func:`humanoid_sim.references.zmp.zmp_walk.make_trajectory`'s result for these arguments).

    Raises:
        InputError: a bad scenario or engine name, a controller that cannot be loaded, a walk the planner
            cannot make.
    """
    if engine not in ENGINE_NAMES:
        raise InputError(f"engine: {engine!r} is not one of {', '.join(ENGINE_NAMES)}")
    sc = as_scenario(scenario)
    return Simulator(robot(sc.robot), sc, compiled=compiled, engine=engine, controller=controller, planner=planner)


def finish(sim: Simulator, result: SimResult) -> Run:
    """The `Run` of a simulated walk: its summary and contact-feasibility audit."""
    summary, report, card = summary_audit_design(result, sim.sc, sim.engine.name, sim.hm, result.phase_names)
    return Run(sim.sc, sim.engine.name, result, summary, sim.hm, sim.traj, report, card)


def run_walk(scenario: str | Path | Scenario, engine: Engine = "pinocchio", *, until: float | None = None,
             compiled: bool | None = None, controller: Controller | None = None,
             progress: Callable[[float, int], None] | None = None, out: str | Path | None = None,
             figures: bool | str | Sequence[str] = False, playback: bool = False, verbose: bool = True,
             planner: Callable[..., Any] | None = None) -> Run:
    """Simulate one walk and summarise it.

    Args:
        scenario: a shipped scenario's name (``"sim1"``, ``"sim1_zmp"``, ...; ``humanoid_sim.scenario_names()``
            lists them), the path of a YAML file, or a `Scenario`.
        engine: ``"pinocchio"`` (welded feet, the thesis's model), ``"mujoco"`` (real, unilateral contact) or
            ``"thesis"`` (the NumPy transcription of the thesis's equations; slow).
        until: stop at this simulated time, s (None: when every planned phase is done).
        compiled: use the compiled kernels (None: where numba is installed; False: the NumPy reference path).
        controller: a controller object (`Controller`); None for the
            scenario's own.
        progress: called after every step with the time (s) and the phase index.
        out: also write the outputs into this folder (`Run.write`).
        figures: with ``out``, the figures to draw (`Run.write`: True or ``"all"``, ``"quick"``, a list of names).
        playback: with ``out``, write ``playback.html``.
        verbose: print a line to stderr before a wait of seconds (numba compiling the kernel when its cache is
            missing, planning a ``zmp_preview`` gait) and the planning time after it.
        planner: as `prepare`'s.

    Returns:
        The `Run`. A walk that fails or falls returns normally: ``run.status`` says how it ended and
        ``run.result.reason`` why; its log holds every step up to the failure.  A walk stopped by Ctrl-C returns
        too; with ``out`` it writes ``results.npz`` and ``summary.json`` only (no figures, no playback).
        ``run.summary["provenance"]`` records the call.

    Raises:
        InputError: bad input (the message names the field, the value and what was expected).
    """
    if until is not None and not (isinstance(until, (int, float)) and until > 0):
        raise InputError(f"until: expected a positive time in s, got {until!r}")
    call = _call_text(scenario, engine, until=until, compiled=compiled, controller=controller, out=out,
                      figures=figures, playback=playback)
    if verbose:
        sc = as_scenario(scenario)
        if _will_compile(engine, compiled):
            _say("compiling the simulation kernel (numba's cache is missing: the first run after an install or an edit "
                 "of a compiled module; up to a minute, cached for later runs)")
        if sc.gait.is_zmp:
            _say("planning the zmp_preview gait (ZMP preview control and its multibody correction: a few seconds per "
                 "10 s of walk)")
        t0 = time.perf_counter()
        sim = prepare(sc, engine, compiled=compiled, controller=controller, planner=planner)
        if sc.gait.is_zmp:
            _say(f"planned the gait and set up the walk in {time.perf_counter() - t0:.1f} s")
    else:
        sim = prepare(scenario, engine, compiled=compiled, controller=controller, planner=planner)
    run = finish(sim, sim.run(t_end=until, progress=progress))
    run.summary["provenance"] = provenance(call)
    if out is not None:
        stopped = run.status is RunStatus.INTERRUPTED   # Ctrl-C: keep the log, skip the slow outputs
        run.write(out, figures=False if stopped else figures, playback=playback and not stopped)
    return run


def _say(message: str) -> None:
    print(f"humanoid_sim: {message}", file=sys.stderr, flush=True)


def _will_compile(engine: str, compiled: bool | None) -> bool:
    """Whether this walk's first steps will wait for numba to compile the kernel (its disk cache is missing)."""
    from humanoid_sim import jit

    return engine in ("pinocchio", "mujoco") and compiled is not False and jit.AVAILABLE and not jit.cache_present()


def _call_text(scenario: str | Path | Scenario, engine: str, **kwargs: Any) -> str:
    """``"python API: run_walk(...)"``, with the arguments given other than their defaults."""
    defaults = {"until": None, "compiled": None, "out": None, "figures": False, "playback": False}
    what = f"Scenario({scenario.name!r})" if isinstance(scenario, Scenario) else repr(str(scenario))
    args = [what, f"engine={engine!r}"] + [f"{k}={repr(str(v)) if isinstance(v, Path) else repr(v)}"
                                           for k, v in kwargs.items() if k in defaults and v != defaults[k]]
    if kwargs.get("controller") is not None:
        args.append(f"controller={type(kwargs['controller']).__name__}(...)")
    return f"python API: run_walk({', '.join(args)})"


__all__ = ["Engine", "Run", "RunLog", "as_scenario", "finish", "prepare", "robot", "run_walk"]
