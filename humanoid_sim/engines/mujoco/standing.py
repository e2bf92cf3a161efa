"""Standing still on MuJoCo's ground: joint-space PD + gravity compensation, and the standing experiment.

The controller holds a reference configuration q_ref (the walk's initial double-support posture)::

    tau_j = tau_g,j + Kp * (q_ref - q)_j - Kd * v_j          (joint rows; the base rows are not actuated)

``tau_g`` is the gravity compensation *with the feet on the ground*: ``pin.computeGeneralizedGravity`` g(q_ref)
minus what the ground carries, g = S^T tau_g + J_c^T lambda with J_c the 6-D frame Jacobians of both feet's main
bodies (O_3, O_4, LOCAL) and lambda the minimum-norm pair of foot wrenches that balances the base rows
(g_base = J_c,base^T lambda).  It is constant (evaluated once at q_ref).  The plain joint rows of g(q_ref) would be
the torques that hold the legs up from the trunk, the opposite of standing on them.

Gains: Kp = 2000 N m/rad, Kd = 20 N m s/rad, capped per joint.  The torques are computed from the state at the
start of each control period h and held, so the PD is explicit, and the lightest subtrees (toe, ankle) would make
it diverge: uniform gains (Kp 2000, Kd 5) diverged within 1 ms at h = 1 ms.  Each joint's gains are capped by its
free-flight effective inertia I_i = 1 / (M(q_ref)^-1)_ii: Kp_i <= alpha I_i / h^2, Kd_i <= alpha I_i / h, with
alpha the largest of 1, 1/2, 1/4, ... for which one held-PD step of the free-flying robot (joint block of M^-1,
semi-implicit Euler) has spectral radius < 1 (:func:`held_pd_spectral_radius`).  At h = 1 ms, alpha = 1/2
(radius 1.69 at alpha = 1, 0.993 at 1/2), which caps the toes (Kp 64, Kd 0.065), ankle roll (Kp 400, Kd 0.40),
ankle pitch (Kp 1270, Kd 1.27), ankle yaw, hip yaw and neck damping.  The two ankles' pitch stiffness (2540 N
m/rad) stays far above the toppling stiffness of the body as an inverted pendulum on them (m g l ~ 540 N x 0.8 m
~ 430 N m/rad); the body's sway about the ankles is lightly damped (period ~1-2 s).  A standing controller, not a
balance controller.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from humanoid_sim.engines.mujoco.contact import SlipMeter, sole_corners, sole_tilt
from humanoid_sim.engines.mujoco.sim import MujocoSim
from humanoid_sim.robot.model import HumanoidModel

KP_STAND = 2000.0  # N m/rad
KD_STAND = 20.0    # N m s/rad


def held_pd_spectral_radius(W: np.ndarray, kp: np.ndarray, kd: np.ndarray, h: float) -> float:
    """Spectral radius of one step of the joint PD loop in free flight: torques -Kp x - Kd v held over h,
    accelerations W tau (W the joint block of M^-1), semi-implicit Euler (MuJoCo's): v+ = v + h a, x+ = x + h v+.
    Below 1 the held PD is stable."""
    n = len(kp)
    E = np.eye(n)
    Bp, Bd = h * W * kp, h * W * kd  # W @ diag(k), scaled by h
    A = np.block([[E - h * Bp, h * (E - Bd)], [-Bp, E - Bd]])
    return float(np.max(np.abs(np.linalg.eigvals(A))))


class StandingController:
    """Joint-space PD about ``q_ref`` plus contact-consistent gravity compensation (module docstring)."""

    def __init__(self, hm: HumanoidModel, q_ref: np.ndarray, h: float, kp: float = KP_STAND,
                 kd: float = KD_STAND) -> None:
        model = hm.model
        data = model.createData()
        self.model = model
        self.q_ref = np.asarray(q_ref, dtype=float).copy()
        if not h > 0:
            raise ValueError(f"control period h = {h!r} s: expected > 0")
        M = pin.crba(model, data, self.q_ref)
        M = np.triu(M) + np.triu(M, 1).T
        W = np.linalg.inv(M)[6:, 6:]       # joint block of M^-1: joint accelerations per joint torque, free base
        inertia = 1.0 / np.diag(W)           # free-flight effective inertia of each joint, kg m^2
        self.kp = np.zeros(model.nv)
        self.kd = np.zeros(model.nv)
        for k in range(20):
            alpha = 0.5**k
            kp_j = np.minimum(float(kp), alpha * inertia / h**2)
            kd_j = np.minimum(float(kd), alpha * inertia / h)
            if held_pd_spectral_radius(W, kp_j, kd_j, h) < 1.0:
                break
        else:  # pragma: no cover - alpha ~ 1e-6 is stable for any positive definite W
            raise ValueError("no stable PD gains found")
        self.alpha = alpha
        self.kp[6:], self.kd[6:] = kp_j, kd_j
        g = pin.computeGeneralizedGravity(model, data, self.q_ref)
        pin.computeJointJacobians(model, data, self.q_ref)
        pin.updateFramePlacements(model, data)
        Jc = np.vstack([pin.getFrameJacobian(model, data, hm.frame_id(f), pin.ReferenceFrame.LOCAL)
                        for f in ("O_3", "O_4")])
        lam = np.linalg.lstsq(Jc[:, :6].T, g[:6], rcond=None)[0]
        self.foot_wrenches_ref = lam  # (12,) [f, m] of O_3 then O_4, LOCAL frames, N / N m
        tau = g - Jc.T @ lam
        tau[:6] = 0.0
        self.tau_g = tau

    def __call__(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Generalized torques (nv,), Pinocchio v order, base rows zero."""
        tau = self.tau_g + self.kp * pin.difference(self.model, q, self.q_ref) - self.kd * np.asarray(v)
        tau[:6] = 0.0
        return tau


@dataclass
class StandingResult:
    """What the standing experiment measured (SI units)."""

    duration: float
    fell: bool
    hip_drift_max: float             # m, largest distance of the Body-17 CoM from its start
    hip_final: np.ndarray            # (3,) m, final Body-17 CoM minus its start
    slip_max: dict[str, float]       # m, per foot (SlipMeter, corners of the main-body sole)
    tilt_max: dict[str, float]       # rad, per foot
    penetration_max: float           # m
    force_final: np.ndarray          # (3,) N, summed ground force at the end
    cop_final: dict[str, np.ndarray]  # m, each foot's CoP at the end
    wall_s: float                    # s of wall time for the stepping loop
    history: dict[str, list] = field(default_factory=dict)


def run_standing(sim: MujocoSim, q0: np.ndarray, duration: float = 5.0, control_period: float | None = None,
                 kp: float = KP_STAND, kd: float = KD_STAND, fall_height: float = 0.5,
                 sample_every: int = 10) -> StandingResult:
    """Hold ``q0`` (v = 0 at the start) for ``duration`` s; the controller runs every ``control_period``
    (default: every MuJoCo step) with its torques held in between.  Measures are sampled every
    ``sample_every`` control periods and at the end."""
    hm = sim.hm
    model, data = hm.model, hm.model.createData()
    h = sim.timestep if control_period is None else float(control_period)
    ctrl = StandingController(hm, q0, h, kp, kd)
    n = int(round(duration / h))
    sim.set_state(q0, np.zeros(model.nv))
    sim.time = 0.0
    fid = hm.frame_id("Pc_17")
    pin.framesForwardKinematics(model, data, q0)
    hip0 = data.oMf[fid].translation.copy()
    slip = SlipMeter()
    tilt = {f: 0.0 for f in "RL"}
    pen, drift, fell = 0.0, 0.0, False
    hist: dict[str, list] = {"t": [], "hip": []}
    t0 = time.perf_counter()
    for k in range(n):
        q, v = sim.state()
        sim.step(ctrl(q, v), h)
        if k % sample_every == sample_every - 1 or k == n - 1:
            sim.forward()
            q, _ = sim.state()
            pin.framesForwardKinematics(model, data, q)
            hip = data.oMf[fid].translation - hip0
            drift = max(drift, float(np.linalg.norm(hip)))
            hist["t"].append(sim.time)
            hist["hip"].append(hip.copy())
            fw = sim.foot_wrenches()
            for f in "RL":
                slip.update(f, fw[f].normal > 0.0, sole_corners(sim.mm, sim.data, f))
                tilt[f] = max(tilt[f], sole_tilt(sim.mm, sim.data, f))
                pen = max(pen, fw[f].penetration)
            if data.oMf[fid].translation[2] < fall_height:
                fell = True
                break
    wall = time.perf_counter() - t0
    fw = sim.foot_wrenches()
    return StandingResult(duration=sim.time, fell=fell, hip_drift_max=drift, hip_final=hist["hip"][-1],
                          slip_max=dict(slip.max_slip), tilt_max=tilt, penetration_max=pen,
                          force_final=fw["R"].force + fw["L"].force,
                          cop_final={f: fw[f].cop for f in "RL"}, wall_s=wall, history=hist)
