"""Divergent component of motion (DCM, capture point) feedback on the whole-body centre of mass.

Linear inverted pendulum (LIPM) of height z_c: omega = sqrt(g / z_c), xi = c + c_dot / omega (horizontal, world
frame), xi_dot = omega (xi - p) with p the ZMP.  Englsberger et al. (2015) close the loop on xi alone:

    p_cmd = p_ref + (1 + k / omega) (xi - xi_ref),    c_ddot_cmd = omega^2 (c - p_cmd),

so that the DCM error decays at rate k (1/s) while c follows xi (c_dot = omega (xi - c) is stable).  The plan's
whole-body CoM (:meth:`ZmpPreviewTrajectory.com_targets`) gives xi_ref; its ZMP in the LIPM sense is taken as
p_ref = c_ref - c_ddot_ref / omega^2 (the multibody plan's CoM does not obey the LIPM exactly with the ZMP reference;
this p_ref makes the law return the plan's acceleration on the plan).  The command is then

    c_ddot_cmd = c_ddot_ref + omega^2 (c - c_ref) - omega (omega + k) (xi - xi_ref),

a PD on the whole-body CoM error with stiffness k omega and damping omega + k.  The QP realises it through the
Body-17 CoM task (its horizontal PD is cancelled: the target is the measured hip, the acceleration the plan's plus
the command's deviation from the plan's), and keeps every foot's CoP inside its sole.  Step adjustment
(:mod:`.steps`) shifts p_ref and xi_ref by the LIPM response to its moved footholds (:meth:`ZmpShift.at`).
Units: SI; world frame (x lateral, y forward, z up).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

G = 9.81
"""Gravity, m/s^2 (the design's)."""
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def lipm_omega(z_c: float) -> float:
    """The LIPM's natural frequency sqrt(g / z_c), rad/s, for a CoM height ``z_c`` > 0 (m)."""
    if not (math.isfinite(z_c) and z_c > 0.0):
        raise ValueError(f"z_c = {z_c!r}: expected a CoM height > 0 m")
    return math.sqrt(G / z_c)


def capture_point(c: np.ndarray, c_dot: np.ndarray, omega: float) -> np.ndarray:
    """The DCM xi = c + c_dot / omega (2,) of a horizontal CoM position (m) and velocity (m/s), m."""
    return np.asarray(c, dtype=float)[:2] + np.asarray(c_dot, dtype=float)[:2] / omega


def dcm_acceleration(c: np.ndarray, xi: np.ndarray, c_ref: np.ndarray, xi_ref: np.ndarray, a_ref: np.ndarray,
                     omega: float, k: float) -> np.ndarray:
    """The commanded horizontal CoM acceleration (2,) m/s^2 of the DCM law (module docstring): the plan's a_ref plus
    omega^2 (c - c_ref) - omega (omega + k) (xi - xi_ref)."""
    return a_ref + omega * omega * (c - c_ref) - omega * (omega + k) * (xi - xi_ref)


@dataclass
class ZmpWindow:
    """A constant ZMP offset ``d`` (2,) m of the plan over [t0, t1] (plan's clock, s): a moved foothold's stance."""

    t0: float
    t1: float
    d: np.ndarray


class ZmpShift:
    """The change of the plan's ZMP reference by moved footholds, and the LIPM's DCM and CoM response to it.

    A window of constant offset d over [t0, t1] moves the DCM reference by the backward recursion
    xi(t) = int_t^inf omega e^{-omega (s - t)} p(s) ds:  d (e^{-omega max(t0 - t, 0)} - e^{-omega (t1 - t)}) for
    t < t1, zero after.  The windows add."""

    def __init__(self, omega: float) -> None:
        self.omega = float(omega)
        self.windows: list[ZmpWindow] = []

    def at(self, t: float, skip: ZmpWindow | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(dp, dxi) (2,) each, m: the ZMP offset and the DCM reference offset at plan time t, without ``skip``."""
        dp = np.zeros(2)
        dxi = np.zeros(2)
        om = self.omega
        for w in self.windows:
            if w is skip or t >= w.t1:
                continue
            if t >= w.t0:
                dp += w.d
            e = math.exp(-om * max(w.t0 - t, 0.0)) - math.exp(-om * min(w.t1 - t, 700.0))
            dxi += w.d * e
        return dp, dxi


class DcmFeedback:
    """The DCM law of the module docstring on a Pinocchio model: measures the whole-body CoM and the Body-17 CoM
    (frame ``hip_frame``) and returns the hip task's targets.

    Args:
        model: the controller's Pinocchio model (free-flyer root).
        hip_frame: the id of the Body-17 CoM frame (Pc_17).
        z_c: the plan's CoM height, m.
        gain: k, the DCM error's decay rate, 1/s.
    """

    def __init__(self, model: pin.Model, hip_frame: int, z_c: float, gain: float) -> None:
        self.model = model
        self.data = model.createData()
        self.hip_frame = int(hip_frame)
        self.omega = lipm_omega(z_c)
        self.gain = float(gain)
        self.shift = ZmpShift(self.omega)
        self.steps: Any = None
        """The step adjustment (:class:`.steps.StepAdjuster`) that moves footholds and fills ``shift``, or None."""
        self.c = np.zeros(3)
        self.c_dot = np.zeros(3)
        self.xi = np.zeros(2)
        self.xi_err = np.zeros(2)
        """The last call's measured DCM minus its reference (shifted by the moved footholds), m."""

    def measure(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measure the whole-body CoM (``c``, ``c_dot``, ``xi``) at (q, v); returns the Body-17 CoM's position (3,)
        m and linear velocity (3,) m/s, world frame."""
        model, d = self.model, self.data
        pin.centerOfMass(model, d, q, v, False)      # forward kinematics to the velocity level, then the CoM
        self.c, self.c_dot = d.com[0], d.vcom[0]
        self.xi = capture_point(self.c, self.c_dot, self.omega)
        f = self.hip_frame
        pin.updateFramePlacement(model, d, f)
        return d.oMf[f].translation, pin.getFrameVelocity(model, d, f, LWA).linear

    def hip_targets(self, hip: tuple, com_ref: tuple, k: int, t: float, q: np.ndarray, v: np.ndarray) -> tuple:
        """The Body-17 CoM task's (position, velocity (6,), orientation, acceleration (6,)) that realise the DCM law:
        horizontally the measured hip (no PD error) and the plan's hip acceleration plus the law's deviation from the
        plan's CoM acceleration; vertically and in orientation the plan's ``hip`` unchanged.

        Args:
            hip: the plan's hip targets (``traj.hip_targets``).
            com_ref: the plan's whole-body CoM (position, velocity, acceleration, ZMP), (2,) each
                (``traj.com_targets``).
            k: the phase index (the step adjustment's single support).
            t: the plan's time, s (for the moved footholds' offsets).
            q, v: the state.
        """
        p_ref, v6_ref, R_ref, a6_ref = hip
        c_ref, cd_ref, a_ref, _ = com_ref
        p_hip, v_hip = self.measure(q, v)
        om = self.omega
        xi_plan = c_ref + cd_ref / om
        st = self.steps
        if st is not None:     # the error against the plan with the earlier moved footholds, not this step's own
            _, dxi0 = self.shift.at(t, skip=st.window if st.k == k else None)
            st.update(k, t, self.xi - xi_plan - dxi0, om, R_ref)
        dp, dxi = self.shift.at(t)
        xi_ref = xi_plan + dxi
        # the moved footholds shift the LIPM ZMP: c_ddot_ref + omega^2 (c - c_ref) becomes that minus omega^2 dp
        c = self.c[:2]
        self.xi_err = self.xi - xi_ref
        acc = dcm_acceleration(c, self.xi, c_ref + dp, xi_ref, a_ref, om, self.gain)
        p = p_ref.copy()
        p[:2] = p_hip[:2]
        v6 = v6_ref.copy()
        v6[:2] = v_hip[:2]
        a6 = a6_ref.copy()
        a6[:2] += acc - a_ref
        return p, v6, R_ref, a6

