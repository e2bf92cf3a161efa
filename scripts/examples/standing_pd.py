"""Template of a user's controller: joint-space PD with gravity compensation, holding the robot standing.

    python scripts/examples/standing_pd.py [--engine pinocchio|mujoco|thesis] [--kp 200] [--kd 20] [--out DIR]

Copy this file, change ``StandingPD.__call__``, and run it on any engine.  A controller is a class with a ``name``,
``setup(ctx)`` (called once: ctx.hm = the robot, ctx.q0 = the initial posture, ctx.traj = the references,
ctx.settings = the scenario's ``controller_settings``) and ``__call__(obs)`` returning 26 joint torques (N m,
Pinocchio's joint order, obs.q[7:] / obs.v[6:]) -- see docs/controllers.md.  It can also be named in a scenario:
``controller_class: module:Class``, with ``controller_settings: {kp: 200, kd: 20}``.  The script exits 1 when the
run fails (a divergence, a fall, the controller's error).
"""

import argparse
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin

from humanoid_sim.robot.model import load_model
from humanoid_sim.robot.phases import Phase
from humanoid_sim.scenario.schema import load_scenario
from humanoid_sim.sim.simulate import Simulator
from humanoid_sim.sim.status import RunStatus

ROOT = Path(__file__).resolve().parents[2]
KP = 200.0  # N m/rad
KD = 20.0   # N m s/rad
FLAT_FEET = ("O_3", "O_4")  # the two feet's main bodies


class StandingPD:
    """tau = gravity compensation with the feet on the ground carrying the weight + kp (q0 - q) - kd v on the 26
    joints.

    The feet that carry the weight are the phase's welds on an engine that welds them (``ctx.constraints`` given:
    in RFFDSP the right main body and the left toe body), else both feet's main bodies, flat on real ground.

    Args:
        kp: joint stiffness, N m/rad; None = ``ctx.settings["kp"]``, else 200.
        kd: joint damping, N m s/rad; None = ``ctx.settings["kd"]``, else 20.
    """

    name = "standing_pd"

    def __init__(self, kp: float | None = None, kd: float | None = None) -> None:
        self.kp, self.kd = kp, kd

    def setup(self, ctx):
        settings = ctx.settings or {}
        self.kp = float(settings.get("kp", KP) if self.kp is None else self.kp)
        self.kd = float(settings.get("kd", KD) if self.kd is None else self.kd)
        self.model, self.q_ref = ctx.hm.model, ctx.q0.copy()
        self.data = self.model.createData()
        self.fid = ctx.hm.frame_id
        self.flat = ctx.constraints is None  # real ground: nothing welds the feet

    def __call__(self, obs):
        model, data, q = self.model, self.data, obs.q
        g = pin.computeGeneralizedGravity(model, data, q)
        feet = FLAT_FEET if self.flat else obs.phase.contacts.welds  # e.g. ("O_3", "O_2") in RFFDSP
        J = np.vstack([pin.computeFrameJacobian(model, data, q, self.fid(f), pin.LOCAL_WORLD_ALIGNED) for f in feet])
        lam = np.linalg.lstsq(J[:, :6].T, g[:6], rcond=None)[0]  # ground wrenches that carry the weight
        tau = g[6:] - J[:, 6:].T @ lam                              # joint torques that hold it, statically
        return tau + self.kp * pin.difference(model, q, self.q_ref)[6:] - self.kd * obs.v[6:]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--engine", default="pinocchio", help="pinocchio (default), mujoco or thesis")
    p.add_argument("--kp", type=float, default=None, help=f"joint stiffness, N m/rad (default {KP:g})")
    p.add_argument("--kd", type=float, default=None, help=f"joint damping, N m s/rad (default {KD:g})")
    p.add_argument("--out", type=Path, default=Path("results") / "standing_pd")
    p.add_argument("--seconds", type=float, default=3.0)
    args = p.parse_args()
    hm = load_model()
    sim = Simulator(hm, load_scenario(ROOT / "scripts" / "params" / "sim1.yaml"), engine=args.engine,
                    controller=StandingPD(args.kp, args.kd))
    result = sim.run(t_end=args.seconds, hold=Phase.RFFDSP)  # double support for the whole run
    hip = result.log.arrays().get("hip_p")
    drift = np.linalg.norm(hip - hip[0], axis=1).max() if hip is not None and len(hip) else float("nan")
    print(f"{result.reason}; hip drift max {drift * 1000:.3g} mm over {result.sim_time:.3f} s")
    if result.status is not RunStatus.STOPPED:
        if result.traceback:
            print(result.traceback, file=sys.stderr)
        print(f"standing_pd: the run failed: {result.reason}", file=sys.stderr)
        return 1
    args.out.mkdir(parents=True, exist_ok=True)
    result.log.save(args.out / "results.npz", result.phase_names)
    from humanoid_sim.outputs.viewer import write_playback

    write_playback(args.out / "results.npz", args.out / "playback.html", hm=hm, traj=sim.traj)
    print(f"playback: {args.out / 'playback.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
