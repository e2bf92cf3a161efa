"""The initial configuration of a walk: feet where the scenario puts them, Body-17 CoM at the first waypoint.

The thesis starts every simulation at the zero posture (all theta = 0, Appendix B), with the first hip
waypoint P_1 equal to the zero-posture CoM height (0.9588 m).  A scenario may ask for another hip height (a
crouched start); then the legs are bent by inverse kinematics: both toe bodies at their scenario placements
(toe points toe_R0/toe_L0, orientations foot_R0/foot_L0), Body 17 at its zero-posture orientation C0 with its
CoM at Phip[0], toe joints and upper body at 0; among the solutions, the Gauss-Newton iteration from the zero
posture with minimum-norm steps picks the one closest to it.  For the thesis's own data it returns the zero
posture exactly (the residual is zero at the start).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from humanoid_sim.errors import InputError
from humanoid_sim.references.chapter3 import PathParams
from humanoid_sim.robot.model import HumanoidModel

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
LEG_THETAS = ("theta5", "theta7", "theta9", "theta11", "theta13", "theta15", "theta17r",
              "theta6", "theta8", "theta10", "theta12", "theta14", "theta16", "theta17l")


class InitialPostureError(InputError):
    """No configuration reaches the requested initial hip position with the feet where they are."""


def initial_configuration(hm: HumanoidModel, path: PathParams, tol: float = 1e-12, max_iter: int = 50) -> np.ndarray:
    """Configuration q (nq,) of the start of the walk (see the module docstring)."""
    model, data = hm.model, hm.model.createData()
    q = hm.initial_q()
    pin.framesForwardKinematics(model, data, q)
    drop = data.oMf[hm.frame_id("Pc_17")].translation[2] - float(path.Phip[0][2])
    if drop > 1e-9:
        # Straight legs are a singular configuration for lowering the hip: seed the iteration with bent knees
        # (thesis signs: ankle pitch theta5/6 > 0 tilts the shank forward, knee flexion theta11/12 < 0, hip
        # pitch theta13/14 > 0 keeps the trunk upright), the bend sized from the requested drop.
        d = hm.spec.dims
        leg = d["l9"] + d["l11"]
        phi = float(np.arccos(np.clip(1.0 - drop / leg, -1.0, 1.0)))
        theta = np.zeros(26)
        for name, sign in (("theta5", 1), ("theta6", 1), ("theta11", -2), ("theta12", -2), ("theta13", 1),
                           ("theta14", 1)):
            theta[hm.theta_index(name)] = sign * phi
        q = hm.q_on_foot(theta, "R", np.asarray(path.toe_R0), np.asarray(path.foot_R0))
    targets = [("O_1", pin.SE3(np.asarray(path.foot_R0), np.zeros(3)), "P_tpR", np.asarray(path.toe_R0)),
               ("O_2", pin.SE3(np.asarray(path.foot_L0), np.zeros(3)), "P_tpL", np.asarray(path.toe_L0))]
    hip_target = np.asarray(path.Phip[0], dtype=float)
    R17 = hm.spec.C0
    cols = list(range(6)) + [int(hm.theta_v_idx[hm.theta_index(n)]) for n in LEG_THETAS]
    fid = hm.frame_id
    err = np.inf
    for _ in range(max_iter):
        pin.framesForwardKinematics(model, data, q)
        pin.computeJointJacobians(model, data, q)
        res, rows = [], []
        for body, M, point, p in targets:
            Rb = data.oMf[fid(body)].rotation
            res.append(data.oMf[fid(point)].translation - p)
            rows.append(pin.getFrameJacobian(model, data, fid(point), LWA)[:3])
            res.append(pin.log3(M.rotation.T @ Rb))
            rows.append(pin.getFrameJacobian(model, data, fid(body), pin.ReferenceFrame.LOCAL)[3:])
        res.append(data.oMf[fid("Pc_17")].translation - hip_target)
        rows.append(pin.getFrameJacobian(model, data, fid("Pc_17"), LWA)[:3])
        res.append(pin.log3(R17.T @ data.oMf[fid("O_17")].rotation))
        rows.append(pin.getFrameJacobian(model, data, fid("O_17"), pin.ReferenceFrame.LOCAL)[3:])
        r = np.concatenate(res)
        err = float(np.max(np.abs(r)))
        if err < tol:
            return q
        J = np.vstack(rows)[:, cols]
        dx = -np.linalg.lstsq(J, r, rcond=None)[0]
        dv = np.zeros(model.nv)
        dv[cols] = dx
        q = pin.integrate(model, q, dv)
    if err < 1e-9:
        return q
    raise InitialPostureError(
        f"path.Phip[0] = {hip_target.tolist()}: no leg configuration puts the Body-17 CoM there with the feet at "
        f"toe_R0/toe_L0 (residual {err:.2e} after {max_iter} iterations); lower the hip or move the feet")
