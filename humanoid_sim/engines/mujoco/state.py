"""The one explicit map between Pinocchio's and MuJoCo's state and generalized forces.

Pinocchio (humanoid_sim.robot.model):
    q (33,)  = [p (3) of O_17 in world, quaternion (x, y, z, w) of O_17, 26 joint angles in Pinocchio order];
    v (32,)  = [linear velocity of O_17's origin in the base frame (LOCAL), angular velocity in the base frame,
               26 joint rates];
    tau (32,) conjugate to v (power tau . v): [force in the base frame, moment in the base frame, joint torques].
MuJoCo (humanoid_sim.engines.mujoco.model):
    qpos (33,) = [p (3), quaternion (w, x, y, z), joint angles in MuJoCo order (right leg first)];
    qvel (32,) = [linear velocity of the body origin in the WORLD frame, angular velocity in the BODY frame,
                 joint rates in MuJoCo order];
    qfrc (32,) conjugate to qvel: [world force, body-frame moment, joint torques]; ctrl (26,) one motor per joint
    (gear 1), in the actuators' order.

So with R the base rotation (world <- base) and P the joint permutation:
    qvel = T v,  T = diag(R, I3, P);   qfrc = T^-T tau = diag(R, I3, P) tau (R orthogonal, P a permutation);
    qacc = T a + Tdot v,  Tdot v = [R (w x v_lin), 0, 0].
Joints are matched by name, never by position.  Both joint coordinates are the URDF's, so no sign changes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
import pinocchio as pin

from humanoid_sim.engines.mujoco.model import MujocoModelError
from humanoid_sim.robot.model import HumanoidModel


def _rotation_xyzw(quat_xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrix (world <- base) of a unit quaternion given as (x, y, z, w); normalised first."""
    x, y, z, w = np.asarray(quat_xyzw, dtype=float).tolist()
    return pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()


def _rotation_wxyz(quat_wxyz: np.ndarray) -> np.ndarray:
    """:func:`_rotation_xyzw` of a quaternion given as (w, x, y, z) (MuJoCo's order)."""
    w, x, y, z = np.asarray(quat_wxyz, dtype=float).tolist()
    return pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()


@dataclass(frozen=True)
class StateMap:
    """Index maps between a Pinocchio model and a MuJoCo model of the same URDF (see the module docstring).

    ``pin_q``/``mj_q``: joint coordinate indices (pin_q[i] in q <-> mj_q[i] in qpos); ``pin_v``/``mj_v`` the same
    for velocities; ``pin_u``/``mj_u``: v index of the joint each actuator drives <-> actuator index.

    Derived from them, each map as one gather: ``q = qpos[q_gather]`` (base position, quaternion reordered,
    joints), ``v[3:] = qvel[v_gather][3:]`` (the base linear rows need the rotation), ``ctrl = tau[ctrl_gather]``.
    """

    nq: int
    nv: int
    nu: int
    pin_q: np.ndarray
    mj_q: np.ndarray
    pin_v: np.ndarray
    mj_v: np.ndarray
    pin_u: np.ndarray
    mj_u: np.ndarray
    q_gather: np.ndarray = field(init=False, repr=False, compare=False)
    v_gather: np.ndarray = field(init=False, repr=False, compare=False)
    ctrl_gather: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        q_gather = np.full(self.nq, -1, dtype=np.intp)
        q_gather[:7] = (0, 1, 2, 4, 5, 6, 3)          # p; quaternion (x, y, z, w) from MuJoCo's (w, x, y, z)
        q_gather[self.pin_q] = self.mj_q
        v_gather = np.full(self.nv, -1, dtype=np.intp)
        v_gather[:6] = np.arange(6)                   # rows 0:3 are overwritten by the rotated base velocity
        v_gather[self.pin_v] = self.mj_v
        ctrl_gather = np.full(self.nu, -1, dtype=np.intp)
        ctrl_gather[self.mj_u] = self.pin_u
        for name, g, n in (("q", q_gather, self.nq), ("v", v_gather, self.nv)):
            if sorted(g.tolist()) != list(range(n)):
                raise MujocoModelError(f"StateMap: the {name} index maps are not a one-to-one map of {n} entries")
        if ctrl_gather.min() < 0:
            raise MujocoModelError(f"StateMap: the actuator map does not cover the {self.nu} actuators")
        object.__setattr__(self, "q_gather", q_gather)
        object.__setattr__(self, "v_gather", v_gather)
        object.__setattr__(self, "ctrl_gather", ctrl_gather)

    @classmethod
    def from_models(cls, hm: HumanoidModel, mj: mujoco.MjModel) -> StateMap:
        """Match every Pinocchio revolute joint with the MuJoCo hinge and the motor of the same name."""
        model = hm.model
        if mj.njnt < 1 or mj.jnt_type[0] != mujoco.mjtJoint.mjJNT_FREE or mj.jnt_qposadr[0] != 0:
            raise MujocoModelError("MuJoCo model: expected a free joint first (qpos[0:7], qvel[0:6])")
        if (mj.nq, mj.nv) != (model.nq, model.nv):
            raise MujocoModelError(f"MuJoCo model has nq, nv = {mj.nq}, {mj.nv}; Pinocchio has {model.nq}, {model.nv}")
        pin_q, mj_q, pin_v, mj_v = [], [], [], []
        dof_of_joint = {}
        for jid in range(2, model.njoints):
            name = model.names[jid]
            mid = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, name)
            if mid < 0:
                raise MujocoModelError(f"MuJoCo model: no joint named {name!r} (Pinocchio joint {jid})")
            if mj.jnt_type[mid] != mujoco.mjtJoint.mjJNT_HINGE or model.nqs[jid] != 1 or model.nvs[jid] != 1:
                raise MujocoModelError(f"joint {name!r}: expected a 1-DOF revolute joint in both models")
            pin_q.append(model.idx_qs[jid])
            mj_q.append(mj.jnt_qposadr[mid])
            pin_v.append(model.idx_vs[jid])
            mj_v.append(mj.jnt_dofadr[mid])
            dof_of_joint[mid] = model.idx_vs[jid]
        if len(set(mj_q)) != model.nq - 7 or len(set(mj_v)) != model.nv - 6:
            raise MujocoModelError("MuJoCo model: the joint match is not one-to-one")
        pin_u, mj_u = [], []
        for a in range(mj.nu):
            if mj.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT or mj.actuator_trnid[a, 0] not in dof_of_joint:
                raise MujocoModelError(f"actuator {mj.actuator(a).name!r}: expected a joint transmission on a hinge")
            if mj.actuator_gear[a, 0] != 1.0 or mj.actuator_biastype[a] != 0 or mj.actuator_gainprm[a, 0] != 1.0:
                raise MujocoModelError(f"actuator {mj.actuator(a).name!r}: expected a motor with gear 1")
            pin_u.append(dof_of_joint[mj.actuator_trnid[a, 0]])
            mj_u.append(a)
        if sorted(pin_u) != sorted(pin_v):
            raise MujocoModelError(f"MuJoCo model: {mj.nu} actuators do not drive each of the {len(pin_v)} joints once")
        arr = lambda x: np.asarray(x, dtype=np.intp)  # noqa: E731
        return cls(model.nq, model.nv, mj.nu, arr(pin_q), arr(mj_q), arr(pin_v), arr(mj_v), arr(pin_u), arr(mj_u))

    # ------------------------------------------------------------------ configuration
    def qpos_from_q(self, q: np.ndarray) -> np.ndarray:
        """MuJoCo qpos from Pinocchio q (quaternion xyzw -> wxyz, joints by name)."""
        q = self._check(q, self.nq, "q")
        qpos = np.empty(self.nq)
        qpos[:3] = q[:3]
        qpos[3] = q[6]
        qpos[4:7] = q[3:6]
        qpos[self.mj_q] = q[self.pin_q]
        return qpos

    def q_from_qpos(self, qpos: np.ndarray) -> np.ndarray:
        """Pinocchio q from MuJoCo qpos."""
        return self._check(qpos, self.nq, "qpos")[self.q_gather]

    # ------------------------------------------------------------------ velocity
    def qvel_from_v(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """MuJoCo qvel from Pinocchio (q, v): base linear velocity rotated to the world frame."""
        R = _rotation_xyzw(self._check(q, self.nq, "q")[3:7])
        v = self._check(v, self.nv, "v")
        qvel = np.empty(self.nv)
        qvel[:3] = R @ v[:3]
        qvel[3:6] = v[3:6]
        qvel[self.mj_v] = v[self.pin_v]
        return qvel

    def v_from_qvel(self, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
        """Pinocchio v from MuJoCo (qpos, qvel): base linear velocity rotated into the base frame."""
        qpos = self._check(qpos, self.nq, "qpos")
        R = _rotation_wxyz(qpos[3:7])
        qvel = self._check(qvel, self.nv, "qvel")
        v = qvel[self.v_gather]
        v[:3] = R.T @ qvel[:3]
        return v

    def a_from_qacc(self, q: np.ndarray, v: np.ndarray, qacc: np.ndarray) -> np.ndarray:
        """Pinocchio acceleration a = dv/dt from MuJoCo qacc: a = T^-1 (qacc - Tdot v)."""
        R = _rotation_xyzw(self._check(q, self.nq, "q")[3:7])
        v = self._check(v, self.nv, "v")
        qacc = self._check(qacc, self.nv, "qacc")
        a = qacc[self.v_gather]
        w, u = v[3:6], v[:3]
        a[:3] = R.T @ qacc[:3] - (w[1] * u[2] - w[2] * u[1], w[2] * u[0] - w[0] * u[2], w[0] * u[1] - w[1] * u[0])
        return a

    # ------------------------------------------------------------------ generalized forces
    def qfrc_from_tau(self, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """MuJoCo generalized force (e.g. for ``qfrc_applied``) with the same power as Pinocchio's tau."""
        R = _rotation_xyzw(self._check(q, self.nq, "q")[3:7])
        tau = self._check(tau, self.nv, "tau")
        f = np.empty(self.nv)
        f[:3] = R @ tau[:3]
        f[3:6] = tau[3:6]
        f[self.mj_v] = tau[self.pin_v]
        return f

    def tau_from_qfrc(self, q: np.ndarray, qfrc: np.ndarray) -> np.ndarray:
        """Pinocchio generalized force from a MuJoCo one (e.g. ``qfrc_bias``, ``qfrc_constraint``)."""
        R = _rotation_xyzw(self._check(q, self.nq, "q")[3:7])
        qfrc = self._check(qfrc, self.nv, "qfrc")
        tau = qfrc[self.v_gather]
        tau[:3] = R.T @ qfrc[:3]
        return tau

    def ctrl_from_tau(self, tau: np.ndarray) -> np.ndarray:
        """Motor controls (N m) from the joint rows of Pinocchio's tau; the base rows (0:6) are ignored."""
        return self._check(tau, self.nv, "tau")[self.ctrl_gather]

    def tau_from_ctrl(self, ctrl: np.ndarray) -> np.ndarray:
        """Pinocchio generalized force (base rows 0) of the motor controls."""
        ctrl = self._check(ctrl, self.nu, "ctrl")
        tau = np.zeros(self.nv)
        tau[self.pin_u] = ctrl[self.mj_u]
        return tau

    @staticmethod
    def _check(x: np.ndarray, n: int, name: str) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if x.shape != (n,):
            raise MujocoModelError(f"{name}: expected shape ({n},), got {x.shape}")
        return x
