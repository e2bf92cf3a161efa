"""The measurements behind :class:`humanoid_sim.engines.mujoco.model.MujocoSettings` and the standing experiment.

``python -m humanoid_sim.engines.mujoco.experiments [standing|contact|timestep|speed|all]`` prints them (a few seconds
each).  All start from the initial double-support posture of ``scripts/params/sim1.yaml`` held by
:class:`humanoid_sim.engines.mujoco.standing.StandingController`.

- ``standing``: the 5 s standing experiment (no fall, sole slip, hip drift, penetration, tilt).
- ``contact``: contact settings compared by sole creep under a horizontal push and by penetration.
- ``timestep``: the hip path at timesteps 0.5, 1 and 2 ms against 0.2 ms, standing and after a 5 mm drop.
- ``speed``: the raw MuJoCo stepping rate of the model in double support.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from humanoid_sim.engines.mujoco.contact import SlipMeter, sole_corners
from humanoid_sim.engines.mujoco.model import MujocoSettings
from humanoid_sim.engines.mujoco.sim import MujocoSim
from humanoid_sim.engines.mujoco.standing import StandingController, StandingResult, run_standing
from humanoid_sim.paths import SCENARIOS_DIR
from humanoid_sim.references.initial import initial_configuration
from humanoid_sim.robot.model import HumanoidModel, load_model
from humanoid_sim.scenario.schema import Scenario, load_scenario

SIM1 = SCENARIOS_DIR / "sim1.yaml"


def _setup(scenario: str | Path | None = None) -> tuple[HumanoidModel, Scenario, np.ndarray]:
    hm = load_model()
    sc = load_scenario(scenario or SIM1)
    return hm, sc, initial_configuration(hm, sc.path)


def standing(duration: float = 5.0, **overrides: Any) -> StandingResult:
    """The standing experiment with the default settings (``overrides`` replace MujocoSettings fields)."""
    hm, sc, q0 = _setup()
    sim = MujocoSim(hm, MujocoSettings.from_scenario(sc, **overrides))
    return run_standing(sim, q0, duration=duration)


@dataclass
class HoldRun:
    """Hip (Body-17 CoM) path and contact measures of one held-posture run."""

    t: np.ndarray          # (n,) s
    hip: np.ndarray        # (n, 3) m, minus the start
    slip: float            # m, largest sole slip after ``measure_from``
    penetration: float     # m
    wall_s: float


def hold(overrides: dict[str, Any], push: float = 0.0, duration: float = 2.0, drop: float = 0.0,
         gains_period: float = 1e-3, push_from: float = 0.5, measure_from: float = 0.5) -> HoldRun:
    """Hold the initial posture with the PD of control period ``gains_period`` (applied every MuJoCo step),
    starting ``drop`` m above the ground, with a horizontal force ``push`` (N, +y, forward) on the trunk from
    ``push_from`` s; sampled every 10 ms."""
    hm, sc, q0 = _setup()
    sim = MujocoSim(hm, MujocoSettings.from_scenario(sc, **overrides))
    ctrl = StandingController(hm, q0, gains_period)
    model, data = hm.model, hm.model.createData()
    fid = hm.frame_id("Pc_17")
    pin.framesForwardKinematics(model, data, q0)
    hip0 = data.oMf[fid].translation.copy()
    q = q0.copy()
    q[2] += drop
    sim.set_state(q, np.zeros(model.nv))
    sim.time = 0.0
    h = sim.timestep
    every = max(1, int(round(0.01 / h)))
    slip, pen, ts, hips = SlipMeter(), 0.0, [], []
    t0 = time.perf_counter()
    for k in range(int(round(duration / h))):
        sim.data.xfrc_applied[sim.mm.base_body, :3] = (0.0, push, 0.0) if sim.time >= push_from else 0.0
        sim.step(ctrl(*sim.state()), h)
        if k % every == every - 1:
            fw = sim.foot_wrenches()
            for f in "RL":
                slip.update(f, fw[f].normal > 0.0 and sim.time > measure_from, sole_corners(sim.mm, sim.data, f))
                pen = max(pen, fw[f].penetration)
            pin.framesForwardKinematics(model, data, sim.state()[0])
            ts.append(sim.time)
            hips.append(data.oMf[fid].translation - hip0)
    return HoldRun(np.array(ts), np.array(hips), max(slip.max_slip.values()), pen, time.perf_counter() - t0)


CONTACT_VARIANTS: dict[str, dict[str, Any]] = {
    "chosen (elliptic, impratio 10, solref 5 ms)": {},
    "impratio 100": {"impratio": 100.0},
    "impratio 1": {"impratio": 1.0},
    "pyramidal": {"cone": "pyramidal", "impratio": 1.0},
    "solref 10 ms": {"solref": (0.01, 1.0)},
    "MuJoCo defaults (pyramidal, solref 20 ms, solimp 0.9/0.95)": {
        "cone": "pyramidal", "impratio": 1.0, "solref": (0.02, 1.0), "solimp": (0.9, 0.95, 0.001, 0.5, 2.0)},
}


def contact_table(push: float = 20.0) -> list[tuple[str, float, float, float, float]]:
    """(name, slip under ``push`` m, penetration m, hip drift after 2 s standing m, wall s) per variant."""
    rows = []
    for name, kw in CONTACT_VARIANTS.items():
        still = hold(kw)
        pushed = hold(kw, push=push)
        rows.append((name, pushed.slip, still.penetration, float(np.linalg.norm(still.hip[-1])), pushed.wall_s))
    return rows


def timestep_table(drop: float = 0.0, steps: tuple[float, ...] = (0.0005, 0.001, 0.002),
                   reference: float = 0.0002, duration: float = 1.0) -> list[tuple[float, float]]:
    """(timestep, largest hip-path difference from the ``reference`` timestep, m); PD gains of a 2 ms period
    for all, so the controller is the same at every timestep."""
    ref = hold({"timestep": reference}, duration=duration, drop=drop, gains_period=0.002)
    out = []
    for ts in steps:
        run = hold({"timestep": ts}, duration=duration, drop=drop, gains_period=0.002)
        out.append((ts, float(np.max(np.linalg.norm(run.hip - ref.hip, axis=1)))))
    return out


def stepping_rate(seconds: float = 0.2, repeats: int = 5, **overrides: Any) -> tuple[float, int]:
    """Best wall time per MuJoCo step (s) in double support (after 0.3 s of standing), and the contact count."""
    hm, sc, q0 = _setup()
    sim = MujocoSim(hm, MujocoSettings.from_scenario(sc, **overrides))
    ctrl = StandingController(hm, q0, sim.timestep)
    sim.set_state(q0, np.zeros(hm.model.nv))
    for _ in range(int(round(0.3 / sim.timestep))):
        sim.step(ctrl(*sim.state()), sim.timestep)
    qpos, qvel = sim.data.qpos.copy(), sim.data.qvel.copy()
    tau = ctrl(*sim.state())
    n = int(round(seconds / sim.timestep))
    best = np.inf
    for _ in range(repeats):
        sim.data.qpos[:], sim.data.qvel[:] = qpos, qvel
        t0 = time.perf_counter()
        sim.step(tau, n * sim.timestep)
        best = min(best, (time.perf_counter() - t0) / n)
    return float(best), int(sim.data.ncon)


def main(argv: list[str] | None = None) -> int:
    what = (argv if argv is not None else sys.argv[1:]) or ["all"]
    what = what[0]
    if what not in ("standing", "contact", "timestep", "speed", "all"):
        print(f"unknown experiment {what!r}; expected standing, contact, timestep, speed or all", file=sys.stderr)
        return 2
    if what in ("standing", "all"):
        r = standing()
        print(f"standing {r.duration:.1f} s: fell {r.fell}; hip drift max {r.hip_drift_max * 1e3:.2f} mm "
              f"(final {np.round(r.hip_final * 1e3, 2).tolist()} mm); slip R {r.slip_max['R'] * 1e3:.4f} mm, "
              f"L {r.slip_max['L'] * 1e3:.4f} mm; tilt max {np.degrees(max(r.tilt_max.values())):.3f} deg; "
              f"penetration max {r.penetration_max * 1e3:.3f} mm; "
              f"ground force {np.round(r.force_final, 2).tolist()} N; "
              f"wall {r.wall_s:.2f} s")
    if what in ("contact", "all"):
        print("contact settings: sole slip under a 20 N push (0.5-2 s), penetration and hip drift standing 2 s")
        for name, slip, pen, drift, wall in contact_table():
            print(f"  {name:60s} slip {slip * 1e3:7.4f} mm  penetration {pen * 1e3:6.3f} mm  "
                  f"drift {drift * 1e3:5.2f} mm  wall {wall:.2f} s")
    if what in ("timestep", "all"):
        for drop in (0.0, 0.005):
            rows = timestep_table(drop)
            print(f"timestep (hip path vs 0.2 ms over 1 s, {'standing' if drop == 0 else f'{drop * 1e3:g} mm drop'}): "
                  + ", ".join(f"{ts * 1e3:g} ms: {d * 1e3:.3f} mm" for ts, d in rows))
    if what in ("speed", "all"):
        for name, kw in (("chosen", {}), ("pyramidal", {"cone": "pyramidal", "impratio": 1.0}),
                         ("impratio 100", {"impratio": 100.0})):
            dt, ncon = stepping_rate(**kw)
            print(f"raw stepping ({name}): {dt * 1e6:.1f} us per 1 ms step with {ncon} contacts = "
                  f"{1e-3 / dt:.0f}x real time")
    return 0


if __name__ == "__main__":
    sys.exit(main())
