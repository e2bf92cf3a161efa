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
(:mod:`.steps`) shifts p_ref and xi_ref by the LIPM response to its moved footholds (:meth:`ZmpShift.at`).  On
real ground an estimated external force f (:mod:`.force`) leans the plan by b = f / (m omega^2): the error is
measured against xi_ref - b, so the command becomes c_ddot_ref + omega^2 (c - c_ref) - omega (omega + k)
(xi - xi_ref + b), which holds the ZMP at p_ref under c_ddot = omega^2 (c - p) + f / m.
Units: SI; world frame (x lateral, y forward, z up).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from humanoid_sim.controllers.balance.force import lean_offset

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

    def at(self, t: float, skip: ZmpWindow | None = None) -> tuple[tuple[float, float], tuple[float, float]]:
        """(dp, dxi) as (x, y) pairs, m: the ZMP offset and the DCM reference offset at plan time t, without
        ``skip``.  Scalar arithmetic (the controller's per-call path: a walk ends with a window per step, and a
        2-vector numpy operation costs ~0.5 us); windows that moved nothing are skipped."""
        px = py = xx = xy = 0.0
        om = self.omega
        for w in self.windows:
            if w is skip or t >= w.t1:
                continue
            dx, dy = float(w.d[0]), float(w.d[1])
            if dx == 0.0 and dy == 0.0:
                continue
            if t >= w.t0:
                px += dx
                py += dy
            e = math.exp(-om * max(w.t0 - t, 0.0)) - math.exp(-om * min(w.t1 - t, 700.0))
            xx += dx * e
            xy += dy * e
        return (px, py), (xx, xy)


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
        """The last call's measured DCM minus its reference (shifted by the moved footholds and the lean), m."""
        self.force: Any = None
        """The external force estimate (:class:`.force.ForceEstimate`) the CoM leans against, or None."""
        self.lean_max = 0.0
        """The largest lean, m (:func:`.force.lean_offset`)."""
        self.lean = (0.0, 0.0)
        """The last call's lean b (x, y), m: the plan's CoM and DCM are followed at minus b."""

    def measure(self, q: np.ndarray, v: np.ndarray, data: pin.Data | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Measure the whole-body CoM (``c``, ``c_dot``, ``xi``) at (q, v); returns the Body-17 CoM's position (3,)
        m and linear velocity (3,) m/s, world frame.  ``data``: a Data of the same model whose forward kinematics
        at (q, v) to the velocity level are already computed (the controller's compiled path computes them for the
        QP), else this feedback's own data runs them."""
        model = self.model
        if data is None:
            d = self.data
            pin.centerOfMass(model, d, q, v, False)      # forward kinematics to the velocity level, then the CoM
        else:
            d = data
            pin.centerOfMass(model, d, pin.KinematicLevel.VELOCITY, False)
        c, cd = self.c, self.c_dot = d.com[0], d.vcom[0]
        om = self.omega
        # capture_point's arithmetic in floats (the same numbers; this runs at every call)
        self.xi = np.array((float(c[0]) + float(cd[0]) / om, float(c[1]) + float(cd[1]) / om))
        f = self.hip_frame
        pin.updateFramePlacement(model, d, f)
        return d.oMf[f].translation, pin.getFrameVelocity(model, d, f, LWA).linear

    def hip_targets(self, hip: tuple, com_ref: tuple, k: int, t: float, q: np.ndarray, v: np.ndarray,
                    data: pin.Data | None = None, sensed: tuple[float, Any] | None = None) -> tuple:
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
            data: forward kinematics at (q, v) already computed (:meth:`measure`), or None.
            sensed: (the call's time, s; the feet's measured wrenches, ``Observation.foot_wrenches``) for the
                external force estimate (:attr:`force`), or None (no lean).
        """
        p_ref, v6_ref, R_ref, a6_ref = hip
        c_ref, cd_ref, a_ref, _ = com_ref
        p_hip, v_hip = self.measure(q, v, data)
        om = self.omega
        # scalar arithmetic, the same law as dcm_acceleration (a 2-vector numpy operation costs ~0.5 us)
        crx, cry = float(c_ref[0]), float(c_ref[1])
        xpx, xpy = crx + float(cd_ref[0]) / om, cry + float(cd_ref[1]) / om       # the plan's DCM
        xi = self.xi
        bx = by = 0.0
        if self.force is not None and sensed is not None:
            # an external force the model does not know: follow the plan leaned against it (force.py)
            f = self.force.update(sensed[0], self.c_dot, sensed[1])
            bx, by = self.lean = lean_offset(f, self.force.mass, om, self.lean_max)
        xix, xiy = float(xi[0]) + bx, float(xi[1]) + by
        st = self.steps
        if st is not None:     # the error against the plan with the earlier moved footholds, not this step's own
            _, (d0x, d0y) = self.shift.at(t, skip=st.window if st.k == k else None)
            st.update(k, t, (xix - xpx - d0x, xiy - xpy - d0y), om, R_ref, (xix, xiy))
        (dpx, dpy), (dxx, dxy) = self.shift.at(t)
        ex, ey = xix - (xpx + dxx), xiy - (xpy + dxy)
        self.xi_err = np.array((ex, ey))
        # the moved footholds shift the LIPM ZMP: c_ddot_ref + omega^2 (c - c_ref) becomes that minus omega^2 dp
        w2, wk = om * om, om * (om + self.gain)
        c = self.c
        dax = w2 * (float(c[0]) - (crx + dpx)) - wk * ex       # the law's deviation from the plan's acceleration
        day = w2 * (float(c[1]) - (cry + dpy)) - wk * ey
        p = p_ref.copy()
        p[0], p[1] = p_hip[0], p_hip[1]
        v6 = v6_ref.copy()
        v6[0], v6[1] = v_hip[0], v_hip[1]
        a6 = a6_ref.copy()
        a6[0] += dax
        a6[1] += day
        return p, v6, R_ref, a6
