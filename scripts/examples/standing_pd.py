"""Template of a user's controller: joint-space PD with gravity compensation, holding the robot standing.

    python scripts/examples/standing_pd.py [--engine pinocchio|thesis] [--out DIR]

Copy this file, change ``StandingPD.__call__``, and run it on any engine.  A controller is a class with a ``name``,
``setup(ctx)`` (called once: ctx.hm = the robot, ctx.q0 = the initial posture, ctx.traj = the references) and
``__call__(obs)`` returning 26 joint torques (N m, Pinocchio's joint order, obs.q[7:] / obs.v[6:]) -- see
docs/controllers.md.  It can also be named in a scenario: ``controller_class: module:Class``.
"""

import argparse
from pathlib import Path

import numpy as np
import pinocchio as pin

from humanoid_sim.robot.model import load_model
from humanoid_sim.robot.phases import Phase
from humanoid_sim.scenario.schema import load_scenario
from humanoid_sim.sim.simulate import Simulator

ROOT = Path(__file__).resolve().parents[2]


class StandingPD:
    """tau = gravity compensation with the feet on the ground carrying the weight + M_j (w^2 (q0 - q) - 2 w v) on
    the 26 joints (M_j: the joints' block of the mass matrix, so that every joint motion responds at w rad/s,
    critically damped; one uniform stiff gain would make the light toes and wrists too fast for a 10 ms step)."""

    name = "standing_pd"
    w = 4.0  # rad/s; with the 10 ms ode3 step, 10 rad/s diverged within 0.2 s here (stable with a 2 ms step)

    def setup(self, ctx):
        self.model, self.q_ref = ctx.hm.model, ctx.q0.copy()
        self.data = self.model.createData()
        self.fid = ctx.hm.frame_id

    def __call__(self, obs):
        model, data, q = self.model, self.data, obs.q
        g = pin.computeGeneralizedGravity(model, data, q)
        feet = obs.phase.contacts.welds  # the bodies held on the ground in this phase, e.g. ("O_3", "O_2")
        J = np.vstack([pin.computeFrameJacobian(model, data, q, self.fid(f), pin.LOCAL_WORLD_ALIGNED) for f in feet])
        lam = np.linalg.lstsq(J[:, :6].T, g[:6], rcond=None)[0]  # ground wrenches that carry the weight
        tau = g[6:] - J[:, 6:].T @ lam                              # joint torques that hold it, statically
        M = pin.crba(model, data, q)[6:, 6:]                        # joint inertia (upper triangle filled)
        M = np.triu(M) + np.triu(M, 1).T
        return tau + M @ (self.w ** 2 * pin.difference(model, q, self.q_ref)[6:] - 2.0 * self.w * obs.v[6:])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--engine", default="pinocchio", help="pinocchio (default) or thesis")
    p.add_argument("--out", type=Path, default=Path("results") / "standing_pd")
    p.add_argument("--seconds", type=float, default=3.0)
    args = p.parse_args()
    hm = load_model()
    sim = Simulator(hm, load_scenario(ROOT / "scripts" / "params" / "sim1.yaml"), engine=args.engine,
                    controller=StandingPD())
    result = sim.run(t_end=args.seconds, hold=Phase.RFFDSP)  # double support for the whole run
    hip = result.log.arrays()["hip_p"]
    drift = np.linalg.norm(hip - hip[0], axis=1).max()
    print(f"{result.reason}; hip drift max {drift * 1000:.3g} mm over {result.sim_time:.2f} s")
    args.out.mkdir(parents=True, exist_ok=True)
    result.log.save(args.out / "results.npz", result.phase_names)
    from humanoid_sim.outputs.viewer import write_playback

    write_playback(args.out / "results.npz", args.out / "playback.html", hm=hm, traj=sim.traj)
    print(f"playback: {args.out / 'playback.html'}")


if __name__ == "__main__":
    main()
