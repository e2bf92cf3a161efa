"""The thesis humanoid as a Pinocchio model with a free-flyer root at the lower trunk (body 17).

This module is the one place that maps between the thesis's 26 joint coordinates (eq. 4.1 order, Table 2.6
signs) and Pinocchio's configuration ``q`` (nq = 33) and velocity ``v`` (nv = 32):

- ``q[:7]`` = placement of frame O_17 (waist joint, lower-trunk thesis frame) in the world:
  position (m) and quaternion (x, y, z, w); ``v[:6]`` = its twist in the base frame (LOCAL).
- theta_i = sign_i * q[theta_q_idx[i]], with sign -1 on the leg joints (the thesis defines them foot-to-hip,
  the tree here is hip-to-foot) and +1 on the upper body.

Named frames: ``O_k`` (k = 1..27, every thesis body frame, virtual ones included), ``Pc_k`` (CoM of each real
body), ``P_tpR`` / ``P_tpL`` (toe points).  World frame = thesis frame 0 (x lateral, y forward, z up).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from humanoid_sim.errors import InputError
from humanoid_sim.paths import MODELS_DIR
from urdf_gen.spec import RobotSpec, load_spec

DEFAULT_URDF = MODELS_DIR / "thesis_humanoid.urdf"
DEFAULT_SPEC = MODELS_DIR / "thesis_humanoid.yaml"

THETA_NAMES: tuple[str, ...] = (
    "theta3", "theta4", "theta5", "theta6", "theta7", "theta8", "theta9", "theta10", "theta11", "theta12",
    "theta13", "theta14", "theta15", "theta16", "theta17r", "theta17l", "theta18", "theta19", "theta20",
    "theta21", "theta22", "theta23", "theta24", "theta25", "theta26", "theta27",
)
"""The joint-space vector q of eq. 4.1 (L2489), in order."""

REAL_BODIES: tuple[int, ...] = (1, 2, 3, 4, 9, 10, 11, 12, 17, 20, 23, 24, 27)
TOE_BODY = {"R": 1, "L": 2}
FOOT_BODY = {"R": 3, "L": 4}
TOE_POINT = {"R": "P_tpR", "L": "P_tpL"}
TOE_JOINT = {"R": "theta3", "L": "theta4"}


class ModelError(InputError):
    """Inconsistent model file or bad argument to the model helpers."""


@dataclass
class HumanoidModel:
    """Pinocchio model + data of the thesis humanoid and the thesis <-> pinocchio coordinate maps."""

    model: pin.Model
    data: pin.Data
    spec: RobotSpec
    theta_q_idx: np.ndarray  # (26,) index into q of each theta (eq. 4.1 order)
    theta_v_idx: np.ndarray  # (26,) index into v of each theta
    theta_sign: np.ndarray   # (26,) q = sign * theta
    urdf_path: Path

    # ------------------------------------------------------------------ frames
    def frame_id(self, name: str) -> int:
        """Index of a named frame (``O_3``, ``Pc_17``, ``P_tpR``, ...); raises with the known names."""
        if not self.model.existFrame(name):
            raise ModelError(f"unknown frame {name!r}; frames are O_1..O_27, Pc_k of real bodies, P_tpR, P_tpL")
        return self.model.getFrameId(name)

    def theta_index(self, name: str) -> int:
        """Position of a thesis joint variable (e.g. ``theta17r``) in the eq. 4.1 vector."""
        try:
            return THETA_NAMES.index(name)
        except ValueError:
            raise ModelError(f"unknown joint variable {name!r}; expected one of {THETA_NAMES}") from None

    # ------------------------------------------------------------------ coordinate maps
    def q_from_theta(self, theta: np.ndarray, base: pin.SE3 | None = None) -> np.ndarray:
        """Configuration from thesis angles (rad, eq. 4.1 order) and the world placement of frame O_17."""
        theta = np.asarray(theta, dtype=float)
        if theta.shape != (26,):
            raise ModelError(f"theta must have shape (26,), got {theta.shape}")
        base = self.initial_base() if base is None else base
        q = np.zeros(self.model.nq)
        q[:7] = pin.SE3ToXYZQUAT(base)
        q[self.theta_q_idx] = self.theta_sign * theta
        return q

    def theta_from_q(self, q: np.ndarray) -> np.ndarray:
        """Thesis angles (rad, eq. 4.1 order) from a configuration."""
        return self.theta_sign * np.asarray(q)[self.theta_q_idx]

    def base_from_q(self, q: np.ndarray) -> pin.SE3:
        """World placement of the lower-trunk frame O_17."""
        return pin.XYZQUATToSE3(np.asarray(q)[:7])

    def v_from_theta_dot(self, theta_dot: np.ndarray, base_twist: np.ndarray | None = None) -> np.ndarray:
        """Velocity from thesis joint rates (rad/s) and the base twist [v; w] of O_17 in its own frame."""
        theta_dot = np.asarray(theta_dot, dtype=float)
        if theta_dot.shape != (26,):
            raise ModelError(f"theta_dot must have shape (26,), got {theta_dot.shape}")
        v = np.zeros(self.model.nv)
        if base_twist is not None:
            v[:6] = base_twist
        v[self.theta_v_idx] = self.theta_sign * theta_dot
        return v

    def theta_dot_from_v(self, v: np.ndarray) -> np.ndarray:
        """Thesis joint rates (or accelerations) from a pinocchio velocity (or acceleration) vector."""
        return self.theta_sign * np.asarray(v)[self.theta_v_idx]

    def tau_from_joint_torques(self, tau_theta: np.ndarray) -> np.ndarray:
        """Generalized force vector (nv,) from torques conjugate to the thesis angles (N m, eq. 4.1 order)."""
        tau = np.zeros(self.model.nv)
        tau[self.theta_v_idx] = self.theta_sign * np.asarray(tau_theta)
        return tau

    # ------------------------------------------------------------------ postures
    def initial_base(self) -> pin.SE3:
        """Placement of O_17 at the thesis initial posture: C0 = Rz(+90 deg), O_17 above the origin."""
        # Feet flat on z = 0 with all theta = 0: O_17 height = toe-point height 0.015 + l3z + l9 + l11 + l17z.
        d = self.spec.dims
        height = 0.015 + d["l3z"] + d["l9"] + d["l11"] + d["l17z"]
        return pin.SE3(self.spec.C0.copy(), np.array([0.0, 0.0, height]))

    def initial_q(self) -> np.ndarray:
        """The thesis initial posture (Appendix B: all theta = 0, C^(0,k) = Rz(+90 deg), feet flat on z = 0)."""
        return self.q_from_theta(np.zeros(26), self.initial_base())

    def q_on_foot(self, theta: np.ndarray, foot: str, toe_point: np.ndarray, R_toe: np.ndarray) -> np.ndarray:
        """Configuration with the given angles whose toe body (1 for ``R``, 2 for ``L``) has world rotation
        ``R_toe`` and its toe point at ``toe_point`` (m): the thesis's SSP root data C^(0,1), P_tpR."""
        if foot not in TOE_BODY:
            raise ModelError(f"foot must be 'R' or 'L', got {foot!r}")
        q = self.q_from_theta(theta, pin.SE3.Identity())
        pin.framesForwardKinematics(self.model, self.data, q)
        M_toe_in_base = self.data.oMf[self.frame_id(TOE_POINT[foot])]  # toe-point frame, orientation of body 1/2
        target = pin.SE3(np.asarray(R_toe, dtype=float), np.asarray(toe_point, dtype=float))
        return self.q_from_theta(theta, target * M_toe_in_base.inverse())

    def copy_data(self) -> pin.Data:
        """A fresh pinocchio Data for this model (one per thread or per independent computation)."""
        return self.model.createData()


def load_model(urdf_path: str | Path | None = None, spec_path: str | Path | None = None) -> HumanoidModel:
    """Load the URDF with a free-flyer root and build the thesis <-> pinocchio maps from the model YAML."""
    urdf_path = Path(urdf_path) if urdf_path else DEFAULT_URDF
    spec = load_spec(spec_path if spec_path else DEFAULT_SPEC)
    if not urdf_path.is_file():
        raise ModelError(f"URDF not found: {urdf_path} (generate it with python -m urdf_gen)")
    model = pin.buildModelFromUrdf(str(urdf_path), pin.JointModelFreeFlyer())
    model.gravity = pin.Motion(np.array([0.0, 0.0, -spec.gravity, 0.0, 0.0, 0.0]))
    signs = {j.theta: j.sign for j in spec.joints}
    q_idx, v_idx, sign = [], [], []
    for name in THETA_NAMES:
        if not model.existJointName(name):
            raise ModelError(f"{urdf_path}: joint {name!r} missing")
        jid = model.getJointId(name)
        if model.nqs[jid] != 1 or model.nvs[jid] != 1:
            raise ModelError(f"{urdf_path}: joint {name!r} is not a 1-DOF revolute joint")
        q_idx.append(model.idx_qs[jid])
        v_idx.append(model.idx_vs[jid])
        sign.append(signs[name])
    if list(spec.theta_order) != list(THETA_NAMES):
        raise ModelError(f"model YAML theta_order differs from eq. 4.1: {spec.theta_order}")
    return HumanoidModel(model=model, data=model.createData(), spec=spec, theta_q_idx=np.array(q_idx),
                         theta_v_idx=np.array(v_idx), theta_sign=np.array(sign, dtype=float),
                         urdf_path=urdf_path)
