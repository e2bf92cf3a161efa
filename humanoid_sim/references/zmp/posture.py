"""Whole-body postures of a walk for :func:`humanoid_sim.references.zmp.multibody.correct_hip`: inverse kinematics per
sample.

Given, at each sample k, the toe points (world, m) and toe-body orientations of both feet (thesis P_tpR / P_tpL,
bodies 1 / 2), Body 17's orientation and the hip height, :class:`WalkPosture` maps a Body-17 CoM path hip_xy (N, 2)
to configurations q (N, nq):

- Body 17 is the free-flyer root, so its CoM target fixes the base placement directly:
  O_17 = (R_17, p_c17 - R_17 c17) with c17 the CoM of Body 17 in O_17;
- toe joints: 0 (the foot flat) unless ``free_toe`` marks the foot at that sample (the thesis's trailing foot of
  a double support, held by its toe body only, and its swing foot).  A free foot raises its heel when its leg
  would otherwise be stretched beyond ``max_extension`` times its straight length L (hip joint O_11 / O_12 to ankle
  O_3 / O_4, 0.734 m): the *needed* toe angle is the smallest that brings the ankle back to that distance (a
  scalar root; 0 where the flat foot is reachable).  The needed angle has corners where it leaves or returns to
  0, and a corner's acceleration impulse showed as 0.1-0.45 m spikes of the multibody ZMP, so the angle used is
  the needed one smoothed in time: a running maximum over +-``heel_window_s`` then a Gaussian of ``heel_sigma_s``
  (scipy.ndimage), raised to the needed angle where it dips below, then multiplied by a smoothstep from 0 to 1
  over the first ``heel_ramp_s`` after the toe is freed.  A trailing foot's leg is often near its cap at the end of
  the single support, so its needed angle is already > 0 when the toe is freed; during the ramp the heel lags the
  need and the leg uses part of its last 0.5 % of length.  The thesis walk needs the heel rise: neither its own
  hip reference nor a preview plan reaches the trailing foot flat late in the double support and early in the
  swing (sim 3: with both toe joints locked the inverse kinematics of the thesis's own hip reference fails there);
- each leg (hip yaw, roll, pitch, knee, ankle roll, yaw, pitch: 7 joints for the 6 targets of its foot) takes,
  among the configurations that meet the targets, the one closest to the seed's leg angles: Gauss-Newton on that
  constrained least-distance problem, warm-started from the previous call's solution at the same sample, else from
  the previous sample.  The postures are a function of the targets (of the whole path, through the heel
  smoothing), not of the iteration's history, which the fixed point of ``match_com`` needs;
- the upper body keeps the seed's angles (normally 0, the thesis posture).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin
from scipy.ndimage import gaussian_filter1d, maximum_filter1d
from scipy.optimize import brentq

from humanoid_sim.references.chapter3.polynomials import smoothstep
from humanoid_sim.references.initial import LEG_THETAS
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.robot.phases import other_foot

from .errors import GaitError
from .preview import _finite_array

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
LOCAL = pin.ReferenceFrame.LOCAL
MAX_NULL_STEP = 0.05
"""rad: the largest move toward the seed posture per Gauss-Newton step (inside the null space of the foot targets)."""
MAX_STEP = 0.2
"""rad: the largest joint move per Gauss-Newton step."""
FEET = ("R", "L")
_FRAMES = {"R": ("P_tpR", "O_1", "O_3", "O_11", "theta3"), "L": ("P_tpL", "O_2", "O_4", "O_12", "theta4")}
MAX_HEEL_RISE = np.radians(60.0)
"""rad: the largest toe angle :class:`WalkPosture` tries before declaring a leg too short."""


def thesis_free_toes(traj: Any, times: Sequence[float]) -> np.ndarray:
    """(N, 2) bool, right / left: the toe joints the thesis leaves free at global times t (s) of its nominal schedule:
    the trailing foot's in a double support (held by its toe body), the swing foot's in a single support.
    Before 0 (a standing lead-in) none; after the end, those of the last phase."""
    out = np.zeros((len(times), 2), dtype=bool)
    for k, t in enumerate(times):
        if t < 0:
            continue
        ph = traj.phases[traj.phase_at(float(t))]
        foot = ph.swing_foot if ph.is_ssp else other_foot(ph.landed_foot)
        out[k, FEET.index(foot)] = True
    return out


class WalkPosture:
    """Callable hip_xy (N, 2) -> q (N, nq); see the module docstring.

    toe_R, toe_L: (N, 3) toe points, m; R_R, R_L: (N, 3, 3) toe-body orientations; R_hip: (N, 3, 3) Body-17
    orientation; hip_z: Body-17 CoM height, m; q_seed: (nq,) configuration whose upper-body angles are kept and
    whose leg angles are the least-distance reference; free_toe: (N, 2) bool, right / left (default none);
    max_extension: the hip-ankle distance a free foot's leg may reach, fraction of its straight length;
    T: sample time, s; heel_window_s, heel_sigma_s, heel_ramp_s: the time smoothing of the heel angle, s (module
    docstring);
    tol: max residual (m and rad) of the foot targets and max step (rad) at convergence.
    After a call, ``residual`` (N,) holds each sample's max foot-target residual, ``iterations`` the Gauss-Newton
    steps, ``toe_angle`` (N, 2) the thesis toe angles theta3 / theta4 used and ``toe_needed`` (N, 2) the needed
    ones (rad).
    """

    def __init__(self, hm: HumanoidModel, toe_R: np.ndarray, R_R: np.ndarray, toe_L: np.ndarray, R_L: np.ndarray,
                 R_hip: np.ndarray, hip_z: float, q_seed: np.ndarray, free_toe: np.ndarray | None = None,
                 T: float = 0.01, max_extension: float = 0.995, heel_window_s: float = 0.05,
                 heel_sigma_s: float = 0.02, heel_ramp_s: float = 0.05, tol: float = 1e-10,
                 max_iter: int = 50) -> None:
        self.hm = hm
        m = hm.model
        self.toe = {"R": _finite_array("toe_R", toe_R, (None, 3), "an (N, 3) array of toe points in m")}
        n = len(self.toe["R"])
        self.toe["L"] = _finite_array("toe_L", toe_L, (n, 3), f"an ({n}, 3) array of toe points in m")
        self.rot = {"R": _finite_array("R_R", R_R, (n, 3, 3), f"an ({n}, 3, 3) array of rotations"),
                    "L": _finite_array("R_L", R_L, (n, 3, 3), f"an ({n}, 3, 3) array of rotations")}
        self.R_hip = _finite_array("R_hip", R_hip, (n, 3, 3), f"an ({n}, 3, 3) array of rotations")
        self.hip_z = float(hip_z)
        self.q_seed = _finite_array("q_seed", q_seed, (m.nq,), f"a ({m.nq},) configuration")
        free = np.zeros((n, 2), dtype=bool) if free_toe is None else np.asarray(free_toe)
        if free.shape != (n, 2) or free.dtype != bool:
            raise GaitError(f"free_toe: expected an ({n}, 2) bool array (right, left), got {free.dtype} {free.shape}")
        self.free_toe = free
        if not (isinstance(max_extension, (int, float)) and 0.5 < max_extension <= 1.0):
            raise GaitError(f"max_extension: expected a fraction in (0.5, 1], got {max_extension!r}")
        self.max_extension = float(max_extension)
        for name, v in (("T", T), ("heel_window_s", heel_window_s), ("heel_sigma_s", heel_sigma_s)):
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise GaitError(f"{name}: expected a duration > 0 s, got {v!r}")
        self.T, self.heel_window_s, self.heel_sigma_s = float(T), float(heel_window_s), float(heel_sigma_s)
        if not (isinstance(heel_ramp_s, (int, float)) and np.isfinite(heel_ramp_s) and heel_ramp_s >= 0):
            raise GaitError(f"heel_ramp_s: expected a duration >= 0 s, got {heel_ramp_s!r}")
        self.heel_ramp_s = float(heel_ramp_s)
        self._ramp = np.zeros((n, 2))   # 0 where the toe is locked, smoothstep 0 -> 1 over heel_ramp_s once freed
        for i in (0, 1):
            since = 0
            for k in range(n):
                since = since + 1 if free[k, i] else 0
                tau = 1.0 if self.heel_ramp_s == 0 else min(1.0, (since - 1) * self.T / self.heel_ramp_s)
                self._ramp[k, i] = smoothstep(tau) if since else 0.0
        self.tol, self.max_iter, self.n = float(tol), int(max_iter), n

        # constant geometry, from the model at its neutral configuration (every leg joint at 0)
        data = m.createData()
        pin.framesForwardKinematics(m, data, pin.neutral(m))
        rel = lambda a, b: data.oMf[hm.frame_id(a)].actInv(data.oMf[hm.frame_id(b)])  # noqa: E731
        self._c17 = rel("O_17", "Pc_17").translation.copy()
        self._geo: dict[str, dict[str, Any]] = {}
        for f in FEET:
            tp, toe_body, foot_body, hip, toe_joint = _FRAMES[f]
            jid = m.getJointId(toe_joint)
            axis = m.joints[jid].shortname()[-1].lower()
            if m.joints[jid].shortname() not in ("JointModelRX", "JointModelRY", "JointModelRZ"):
                raise GaitError(f"model: toe joint {toe_joint} is {m.joints[jid].shortname()}, expected a revolute "
                                "joint about a body axis")
            self._geo[f] = dict(
                tp=hm.frame_id(tp), body=hm.frame_id(toe_body),
                tp_in_toe=rel(toe_body, tp).translation.copy(),        # toe point in O_1 / O_2
                ankle_in_toe=rel(toe_body, foot_body).translation.copy(),  # O_3 / O_4 origin in O_1 / O_2 at 0
                hip_in_17=rel("O_17", hip).translation.copy(),          # hip joint centre in O_17
                axis="xyz".index(axis),
                length=float(np.linalg.norm(data.oMf[hm.frame_id(hip)].translation
                                            - data.oMf[hm.frame_id(foot_body)].translation)),
                q_idx=int(hm.theta_q_idx[hm.theta_index(toe_joint)]),
                theta_sign=float(hm.theta_sign[hm.theta_index(toe_joint)]),
            )
        for f in FEET:   # the heel-up sign of the toe coordinate: the one that raises the ankle
            g = self._geo[f]
            g["up"] = 1.0 if self._ankle_in_toe(f, 0.1)[2] > g["ankle_in_toe"][2] else -1.0
        self._cols = np.array([int(hm.theta_v_idx[hm.theta_index(t)]) for t in LEG_THETAS])
        self._leg_q = np.array([int(hm.theta_q_idx[hm.theta_index(t)]) for t in LEG_THETAS])
        self._leg_ref = self.q_seed[self._leg_q].copy()
        self._data = m.createData()
        self._cache: np.ndarray | None = None
        self.residual = np.full(n, np.nan)
        self.iterations = np.zeros(n, dtype=int)
        self.toe_angle = np.zeros((n, 2))
        self.toe_needed = np.zeros((n, 2))

    @classmethod
    def from_trajectory(cls, hm: HumanoidModel, traj: Any, times: Sequence[float], q_seed: np.ndarray,
                        **kw: Any) -> WalkPosture:
        """Foot and Body-17 orientation targets from a chapter-3 ReferenceTrajectory on its nominal schedule at the
        given global times (s), free toes from :func:`thesis_free_toes`; times before 0 or after the end take the
        clamped first / last phase."""
        times = np.asarray(times, dtype=float)
        samples = [traj.sample_global(float(t)) for t in times]
        kw.setdefault("free_toe", thesis_free_toes(traj, times))
        if len(times) > 1:
            dt = np.diff(times)
            # 1e-9 s: grids built as t0 + k T differ from uniform by rounding only
            if np.ptp(dt) > 1e-9:
                raise GaitError(f"times: expected a uniform grid, got steps from {dt.min()} to {dt.max()} s")
            kw.setdefault("T", float(dt[0]))
        return cls(hm, np.array([s.toe_R_p for s in samples]), np.array([s.foot_R_R for s in samples]),
                   np.array([s.toe_L_p for s in samples]), np.array([s.foot_L_R for s in samples]),
                   np.array([s.hip_R for s in samples]), traj.hip_z, q_seed, **kw)

    # ------------------------------------------------------------------------------------------------ heel
    def _ankle_in_toe(self, f: str, q_toe: float) -> np.ndarray:
        """Ankle (O_3 / O_4 origin) in the toe body frame for toe coordinate q_toe: the toe body turns by q_toe
        about the joint axis relative to the foot, so the foot turns by -q_toe relative to the toe."""
        g = self._geo[f]
        w = np.zeros(3)
        w[g["axis"]] = -q_toe
        return pin.exp3(w) @ g["ankle_in_toe"]

    def heel_angle(self, k: int, f: str, hip_xy: np.ndarray) -> float:
        """Needed toe coordinate q (rad, Pinocchio's) of free foot f at sample k with Body 17's CoM at hip_xy: 0 if
        the leg reaches the flat foot within max_extension of its length, else the smallest heel-up angle that does."""
        g = self._geo[f]
        R17 = self.R_hip[k]
        base_p = np.array([hip_xy[0], hip_xy[1], self.hip_z]) - R17 @ self._c17
        hip = base_p + R17 @ g["hip_in_17"]
        R_toe = self.rot[f][k]
        joint = self.toe[f][k] - R_toe @ g["tp_in_toe"]
        cap = self.max_extension * g["length"]

        def excess(a: float) -> float:
            return float(np.linalg.norm(hip - joint - R_toe @ self._ankle_in_toe(f, g["up"] * a))) - cap

        if excess(0.0) <= 0.0:
            return 0.0
        if excess(MAX_HEEL_RISE) > 0.0:
            raise GaitError(f"posture: sample {k}: the {f} leg cannot reach its foot with Body 17's CoM at "
                            f"{np.asarray(hip_xy).tolist()} even with the heel {np.degrees(MAX_HEEL_RISE):.0f} deg up")
        return g["up"] * brentq(excess, 0.0, MAX_HEEL_RISE, xtol=1e-13)

    def heel_angles(self, hip_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(used, needed): (N, 2) toe coordinates (rad, Pinocchio's) of both feet for a Body-17 CoM path; see the
        module docstring."""
        needed = np.zeros((self.n, 2))
        used = np.zeros((self.n, 2))
        size = 2 * int(round(self.heel_window_s / self.T)) + 1
        sigma = self.heel_sigma_s / self.T
        for i, f in enumerate(FEET):
            up = self._geo[f]["up"]
            for k in np.flatnonzero(self.free_toe[:, i]):
                needed[k, i] = self.heel_angle(int(k), f, hip_xy[k])
            lift = up * needed[:, i]   # >= 0
            smooth = gaussian_filter1d(maximum_filter1d(lift, size=size, mode="nearest"), sigma, mode="nearest")
            used[:, i] = up * self._ramp[:, i] * np.maximum(smooth, lift)
        return used, needed

    # ------------------------------------------------------------------------------------------------ legs
    def _solve(self, k: int, q: np.ndarray) -> tuple[np.ndarray, float, int]:
        """Legs at sample k: min |theta_leg - theta_seed|^2 subject to the 12 foot targets (Gauss-Newton: the
        minimum-norm correction of the targets plus the best move toward the seed inside their null space)."""
        m, data, cols = self.hm.model, self._data, self._cols
        err = np.inf
        for it in range(self.max_iter + 1):
            pin.computeJointJacobians(m, data, q)
            pin.updateFramePlacements(m, data)
            res, rows = [], []
            for f in FEET:
                g = self._geo[f]
                res.append(data.oMf[g["tp"]].translation - self.toe[f][k])
                rows.append(pin.getFrameJacobian(m, data, g["tp"], LWA)[:3, cols])
                res.append(pin.log3(self.rot[f][k].T @ data.oMf[g["body"]].rotation))
                rows.append(pin.getFrameJacobian(m, data, g["body"], LOCAL)[3:, cols])
            r = np.concatenate(res)
            err = float(np.max(np.abs(r)))
            U, sv, Vt = np.linalg.svd(np.vstack(rows))
            rank = int(np.sum(sv > 1e-10 * sv[0]))
            step = -Vt[:rank].T @ ((U[:, :rank].T @ r) / sv[:rank])
            Z = Vt[rank:].T
            pull = Z @ (Z.T @ (self._leg_ref - (q[self._leg_q] + step)))
            norm = float(np.linalg.norm(pull))
            if norm > MAX_NULL_STEP:   # far from the seed (e.g. a twisted stance leg): the linearization is poor
                pull *= MAX_NULL_STEP / norm
            step += pull
            norm = float(np.max(np.abs(step)))
            if norm > MAX_STEP:   # near a stretched-leg singularity the minimum-norm step blows up
                step *= MAX_STEP / norm
            if (err < self.tol and float(np.max(np.abs(step))) < self.tol) or it == self.max_iter:
                return q, err, it
            dv = np.zeros(m.nv)
            dv[cols] = step
            q = pin.integrate(m, q, dv)
        return q, err, self.max_iter

    def __call__(self, hip_xy: np.ndarray) -> np.ndarray:
        hip = _finite_array("hip_xy", hip_xy, (self.n, 2), f"an ({self.n}, 2) array of Body-17 CoM x, y in m")
        out = np.empty((self.n, self.hm.model.nq))
        used, needed = self.heel_angles(hip)
        q = self.q_seed.copy()
        for k in range(self.n):
            if self._cache is not None:
                q = self._cache[k].copy()
            for i, f in enumerate(FEET):
                g = self._geo[f]
                q[g["q_idx"]] = used[k, i]
                self.toe_angle[k, i] = g["theta_sign"] * used[k, i]
                self.toe_needed[k, i] = g["theta_sign"] * needed[k, i]
            R17 = self.R_hip[k]
            p17 = np.array([hip[k, 0], hip[k, 1], self.hip_z])
            q[:7] = pin.SE3ToXYZQUAT(pin.SE3(R17, p17 - R17 @ self._c17))
            q, err, its = self._solve(k, q)
            self.residual[k], self.iterations[k] = err, its
            out[k] = q
        self._cache = out.copy()
        worst = int(np.argmax(self.residual))
        # 1e-6 m / rad: the foot targets are met to ~1e-10 when reachable; a residual above 1e-6 is a leg that cannot
        # reach its foot (over-stretched), where the multibody ZMP of the posture would be meaningless.
        if self.residual[worst] > 1e-6:
            raise GaitError(f"posture: sample {worst}: the legs cannot reach the feet with Body 17's CoM at "
                            f"{hip[worst].tolist()} (residual {self.residual[worst]:.3g} after {self.max_iter} "
                            f"iterations)")
        return out
