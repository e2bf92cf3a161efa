#!/usr/bin/env python
"""Speed of the simulator, measured side by side with the thesis oracle.

    python scripts/bench.py [--repeats 7] [--oracle-window 0.3] [--scenario scripts/params/sim1.yaml]

Prints one JSON object:

- ``real_time_factor``: simulated seconds per wall second of the fast engine on the whole scenario (default
  Simulation 1: ode3, h = 0.01 s, controller at every stage), median of ``--repeats`` runs of the stepping loop
  (``Simulator.run``: integration, controller, dynamics, phase logic and per-step logging);
- ``step_ms_median``: wall milliseconds per integration step (same runs);
- ``oracle_real_time_factor``: the same for ``--engine thesis`` over the first ``--oracle-window`` seconds;
- ``speedup_vs_oracle``: their ratio, both measured in this one process;
- ``compiled_kernel``: whether the fast engine ran its compiled stage (numba installed), and
  ``reference_path_real_time_factor``: the same walk on the NumPy reference path (``Simulator(compiled=False)``,
  median of half the repeats), for comparison;
- ``setup_s``: imports and model/scenario loading, reported separately; ``kernel_load_s``: the first simulator
  construction and a 0.05 s warm-up run (loading the compiled kernel from numba's disk cache and its start-up check;
  the very first run after an install compiles it, up to a minute);
- ``breakdown``: fraction of the fast run's stepping time per part (trajectory, controller, dynamics, integrator,
  logging, other), from a cProfile run (profiling inflates the absolute time, not much the proportions);
- ``mujoco``: the MuJoCo engine (``--engine mujoco``, thesis controller at its control rate) on the same scenario:
  ``real_time_factor`` (median of the repeats, in this same process), the simulated time and how the run ended (the
  thesis gait falls within milliseconds, so this is a start-up figure), and the raw costs behind a sustained walk:
  ``controller_us_per_call`` (the thesis controller, compiled, at the scenario's initial state, median of 500
  calls), ``mj_step_us`` (one MuJoCo step standing in double support, median of 1000), ``engine_us_per_update``
  (the engine's own work per control update: state map, contact forces, ground measures; from a 2 s standing run
  minus its controller and MuJoCo steps) and ``projected_real_time_factor`` = 1 / (rate x (controller + engine) +
  1000 steps x mj_step) for a walk that does not fall; ``zmp_preview``: the scenario's zmp gait (below) walked on
  MuJoCo by its balance controller (median of up to 3 runs): the real-time factor of a walk that stands;
- ``gaits``: the same scenario with ``gait: {hip_reference: zmp_preview}`` added on the fast engine:
  its ``real_time_factor`` (median of the repeats, in this same process, planning excluded), ``plan_s`` (building
  the trajectory: ZMP preview and multibody correction, median), the simulated time and how it ended, and
  ``ratio_to_thesis`` = its real-time factor / the thesis gait's (``real_time_factor`` above);
  ``zmp_preview_thesis_controller``: the same plan executed by chapter 5's controller (``gait.controller: thesis``)
  in the compiled kernel, for comparison: about as fast as the thesis gait, but its centre of pressure leaves the
  soles (the balance controller, the default, is what keeps the ground reactions feasible).
"""

from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import statistics
import sys
import time
from pathlib import Path

t_import0 = time.perf_counter()
from humanoid_sim.robot.model import load_model  # noqa: E402
from humanoid_sim.scenario.schema import load_scenario  # noqa: E402
from humanoid_sim.sim.simulate import Simulator  # noqa: E402

IMPORT_S = time.perf_counter() - t_import0
ROOT = Path(__file__).resolve().parents[1]

# Profile attribution: the cumulative time of these functions (none of them calls another one of the list,
# except the logging step, which samples the trajectory for the logged references: those samples count twice,
# under "trajectory" and "logging"; "other" is the rest of the loop: phase logic, the touchdown reset, glue).
# Logging = the per-step record taken at the first stage plus the post-loop pass that derives the logged signals
# (ground reactions, thesis coordinates, unwrapped yaws) in the engine's build_log.
PARTS = {
    "trajectory": [("humanoid_sim/references/chapter3/generator.py", "sample_global"),
                   ("humanoid_sim/references/chapter3/generator.py", "hip_reference"),
                   ("humanoid_sim/references/chapter3/generator.py", "toe_reference")],
    "controller": [("humanoid_sim/controllers/thesis/command.py", "compute"),
                   ("humanoid_sim/controllers/thesis/stage.py", "controller")],
    "dynamics": [("humanoid_sim/dynamics/contact/forward.py", "prepare"),
                 ("humanoid_sim/dynamics/contact/forward.py", "inverse_prepared"),
                 ("humanoid_sim/dynamics/contact/forward.py", "forward_prepared"),
                 ("humanoid_sim/robot/actuators.py", "thesis_torques"),
                 ("humanoid_sim/robot/actuators.py", "torque_map"),
                 ("humanoid_sim/controllers/thesis/controller.py", "_dynamics_pass"),
                 ("humanoid_sim/controllers/thesis/stage.py", "dynamics"),
                 # double-support stages (~1.5 % of them) are one compiled call, controller included
                 ("humanoid_sim/controllers/thesis/stage.py", "double_support")],
    "integrator": [("humanoid_sim/engines/weld.py", "project_on_support"),
                   ("humanoid_sim/controllers/thesis/stage.py", "project"),
                   ("humanoid_sim/controllers/thesis/stage.py", "advance"), ("pinocchio", "integrate")],
    "logging": [("humanoid_sim/engines/weld.py", "_stage0_record"), ("humanoid_sim/engines/weld.py", "build_log")],
}


def _cumtime(stats: pstats.Stats, file_part: str, func: str) -> float:
    total = 0.0
    for (fname, _, fn), (_, _, _, ct, _) in stats.stats.items():  # type: ignore[attr-defined]
        if fn == func and file_part in fname:
            total += ct
        elif file_part == "pinocchio" and fn.endswith(func) and "pinocchio" in fn:
            total += ct
    return total


def breakdown(hm, scenario, t_end: float | None) -> dict[str, float]:
    sim = Simulator(hm, scenario)
    if sim.kernel is not None:
        sim.kernel.split = True  # controller and dynamics halves of the compiled stage as two calls, timed apart
    prof = cProfile.Profile()
    prof.enable()
    sim.run(t_end=t_end)
    prof.disable()
    stats = pstats.Stats(prof)
    total = _cumtime(stats, "humanoid_sim/sim/loop.py", "run")
    parts = {k: sum(_cumtime(stats, f, fn) for f, fn in v) for k, v in PARTS.items()}
    parts["other"] = max(total - sum(parts.values()), 0.0)
    return {k: round(v / total, 3) for k, v in parts.items()}


def mujoco_bench(hm, scenario, repeats: int) -> dict:
    """The MuJoCo engine's speed (see the module docstring)."""
    import numpy as np

    from humanoid_sim.engines.mujoco.standing import StandingController
    from humanoid_sim.interfaces.controller import Observation
    from humanoid_sim.robot.phases import Phase

    walls, res = [], None
    for _ in range(repeats):
        sim = Simulator(hm, scenario, engine="mujoco")
        w0 = time.perf_counter()
        res = sim.run()
        walls.append(time.perf_counter() - w0)
    wall = statistics.median(walls)
    eng, ctrl = sim.engine, sim.controller
    period = eng.settings.control_period_s
    # raw costs: the thesis controller at the initial state (its first phase), one MuJoCo step standing
    eng.start(sim.q0, Phase(sim.traj.phases[0].name))
    obs = Observation(0.0, 0, eng.phase, eng.q, eng.v, eng.anchors, 0)
    calls = []
    for _ in range(500):
        c0 = time.perf_counter()
        ctrl(obs)
        calls.append(time.perf_counter() - c0)
    ctrl_us = 1e6 * statistics.median(calls)
    stand = StandingController(hm, sim.q0, period)
    mj = eng.sim
    mj.set_state(sim.q0, np.zeros(hm.model.nv))
    steps = []
    for _ in range(1000):
        tau = stand(*mj.state())
        c0 = time.perf_counter()
        mj.step(tau, mj.timestep)
        steps.append(time.perf_counter() - c0)
    step_us = 1e6 * statistics.median(steps)
    # the engine's own work per control update: a 2 s standing run through the engine and the loop
    from humanoid_sim.sim.loop import run as loop_run

    class Stand:
        name = "standing"

        def setup(self, ctx) -> None:
            pass

        def __call__(self, o):
            return stand(o.q, o.v)

    seng = type(eng)(hm, scenario)
    w0 = time.perf_counter()
    sres = loop_run(seng, Stand(), sim.traj, scenario, sim.q0, t_end=2.0, hold=Phase.RFFDSP)
    swall = time.perf_counter() - w0
    updates = sres.stage_evaluations
    stand_us = []
    q, v = seng.q, seng.v
    for _ in range(200):
        c0 = time.perf_counter()
        stand(q, v)
        stand_us.append(time.perf_counter() - c0)
    engine_us = max(0.0, (swall - updates * statistics.median(stand_us)
                          - 2.0 / mj.timestep * step_us * 1e-6) / updates * 1e6)
    rate = 1.0 / period
    per_s = rate * (ctrl_us + engine_us) * 1e-6 + (1.0 / mj.timestep) * step_us * 1e-6
    return {"sim_time_s": round(res.sim_time, 4), "reason": res.reason, "repeats": repeats,
            "wall_time_s_median": round(wall, 5), "real_time_factor": round(res.sim_time / wall, 2),
            "control_period_s": period, "timestep_s": mj.timestep,
            "controller_us_per_call": round(ctrl_us, 1), "controller_compiled": sim.kernel is not None,
            "mj_step_us": round(step_us, 1), "engine_us_per_update": round(engine_us, 1),
            "standing_2s_real_time_factor": round(sres.sim_time / swall, 2),
            "projected_real_time_factor": round(1.0 / per_s, 2),
            "projected_seconds_per_sim_second": {"controller": round(rate * ctrl_us * 1e-6, 4),
                                                 "mj_step": round(step_us * 1e-3, 4),
                                                 "engine": round(rate * engine_us * 1e-6, 4)}}


def gait_bench(hm, scenario_path: Path, repeats: int, thesis_rtf: float, engine: str = "pinocchio",
               controller: str | None = None) -> dict:
    """The zmp-preview gait of the scenario (its file plus ``gait: {hip_reference: zmp_preview}``) on ``engine``;
    ``controller``: the gait's executor (``gait.controller``; None = its default, the balance controller)."""
    import yaml

    from humanoid_sim.scenario.schema import parse_scenario

    doc = yaml.safe_load(scenario_path.read_text())
    doc["gait"] = {"hip_reference": "zmp_preview"}
    if controller is not None:
        doc["gait"]["controller"] = controller
    doc["name"] = f"{doc.get('name', scenario_path.stem)}_zmp"
    scenario = parse_scenario(doc, str(scenario_path))
    plans, walls = [], []
    res = None
    for _ in range(repeats):
        w0 = time.perf_counter()
        sim = Simulator(hm, scenario, engine=engine)
        plans.append(time.perf_counter() - w0)
        w0 = time.perf_counter()
        res = sim.run()
        walls.append(time.perf_counter() - w0)
    rtf = res.sim_time / statistics.median(walls)
    return {"scenario": scenario.name, "engine": engine, "real_time_factor": round(rtf, 2),
            "plan_s": round(statistics.median(plans), 3), "sim_time_s": round(res.sim_time, 6),
            "completed": bool(res.completed), "reason": res.reason, "ratio_to_thesis": round(rtf / thesis_rtf, 3)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", type=Path, default=ROOT / "scripts" / "params" / "sim1.yaml")
    p.add_argument("--repeats", type=int, default=7, help="timed runs of the fast engine (median reported)")
    p.add_argument("--oracle-window", type=float, default=0.3, help="simulated seconds run on the oracle")
    args = p.parse_args(argv)
    if args.repeats < 1 or not args.oracle_window > 0:
        print("bench.py: error: --repeats must be >= 1 and --oracle-window > 0", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    hm = load_model()
    scenario = load_scenario(args.scenario)
    setup_s = IMPORT_S + time.perf_counter() - t0
    t0 = time.perf_counter()
    # the first construction loads the compiled kernel from numba's disk cache (compiling it the very first time)
    # and checks it against the reference path; it also builds the trajectory and the initial posture (IK)
    Simulator(hm, scenario).run(t_end=0.05)
    kernel_s = time.perf_counter() - t0

    walls, steps, sim_time, completed = [], [], 0.0, True
    for _ in range(args.repeats):
        sim = Simulator(hm, scenario)
        w0 = time.perf_counter()
        res = sim.run()
        walls.append(time.perf_counter() - w0)
        steps.append(res.steps)
        sim_time = res.sim_time
        completed = completed and res.completed
    wall = statistics.median(walls)
    rtf = sim_time / wall

    ref_walls = []
    for _ in range(max(1, args.repeats // 2)):
        sim = Simulator(hm, scenario, compiled=False)
        w0 = time.perf_counter()
        ref_res = sim.run()
        ref_walls.append(time.perf_counter() - w0)
    ref_rtf = ref_res.sim_time / statistics.median(ref_walls)

    osim = Simulator(hm, load_scenario(args.scenario), engine="thesis")
    w0 = time.perf_counter()
    ores = osim.run(t_end=args.oracle_window)
    owall = time.perf_counter() - w0
    ortf = ores.sim_time / owall

    out = {
        "scenario": scenario.name,
        "completed": completed,
        "sim_time_s": round(sim_time, 6),
        "steps": steps[0],
        "repeats": args.repeats,
        "wall_time_s_median": round(wall, 4),
        "wall_time_s_all": [round(w, 4) for w in walls],
        "real_time_factor": round(rtf, 2),
        "step_ms_median": round(1000 * wall / steps[0], 4),
        "oracle_window_s": args.oracle_window,
        "oracle_wall_time_s": round(owall, 3),
        "oracle_real_time_factor": round(ortf, 4),
        "speedup_vs_oracle": round(rtf / ortf, 1),
        "compiled_kernel": bool(Simulator(hm, scenario).kernel is not None),
        "reference_path_real_time_factor": round(ref_rtf, 2),
        "setup_s": round(setup_s, 3),
        "kernel_load_s": round(kernel_s, 3),
        "breakdown": breakdown(hm, scenario, None),
    }
    out["gaits"] = {"thesis": {"real_time_factor": round(rtf, 2)},
                    "zmp_preview": gait_bench(hm, args.scenario, args.repeats, rtf),
                    # the same plan executed by chapter 5's controller in the compiled kernel: as fast, but its
                    # ground reactions are not feasible (docs/getting-started.md, "The thesis walk and the feasible
                    # walk"); for the speed comparison only
                    "zmp_preview_thesis_controller": gait_bench(hm, args.scenario, args.repeats, rtf,
                                                                controller="thesis")}
    out["mujoco"] = mujoco_bench(hm, scenario, args.repeats)
    out["mujoco"]["zmp_preview"] = gait_bench(hm, args.scenario, max(1, min(3, args.repeats)), rtf, engine="mujoco")
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
