"""The horizontal external force on the robot, estimated from the feet's force sensors and the CoM's momentum.

Newton's law on the whole robot, horizontally: m c_ddot = F_ground + f_ext, with F_ground the ground's force on the
feet (what their force-torque sensors measure) and f_ext everything else the controller's model does not know: a
slope (the ground tilted under gravity: m g sin(angle) downhill), a steady push or wind, a payload pulling the CoM
off. The estimate is the momentum observer of the robotics literature (De Luca's residual, here on the linear
momentum alone): it integrates the measured ground force and its own estimate into a predicted momentum, and reads
the estimate off the prediction's error,

    p_hat(t + T) = p_hat(t) + T (F_ground_mean + f_hat),    f_hat = L (m c_dot - p_hat),

so that f_hat is f_ext low-passed at L = 2 pi f rad/s (the cut-off ``external_force_filter_hz``), without
differentiating the CoM velocity. F_ground_mean is the sensors' mean over the control period (its impulse over the
period). The noise of the sensed velocity passes into f_hat unfiltered (times L m): the estimate the controller
uses is f_hat through a second first-order low-pass of the same cut-off (on the nominal walk with 0.02 m/s of noise
on the base twist, the lean swung by +-7 mm with one stage). A constant force is known to 95 % after ~4.7 / L
(1.5 s at 0.5 Hz). A short push of force F and duration T would peak in it at about F T L / e (a ninth of the
force of a 0.1 s push at 0.5 Hz); that lean, against a push already over, made the recovery step overshoot (on
sim3_zmp the largest backward push survived at mid single support fell from 39.4 to 34.7 N s). A slope's force is
small and stays; a push's is large and goes. So a reading that departs from the estimate by more than the lean can
answer (``lean_max_m`` m omega^2, 48 N) is a push. From then, and for ``PUSH_HOLD_S``, the observer's predicted
momentum is set at every update to the measured one less what the estimate holds, so the push's impulse is dropped
instead of spread over the next second; and the estimate goes back to where it stood when the reading last lay
within half that limit of it (a 0.1 s push of 350 N then leaves the estimate under 1 N once known, ~50 ms in; without
the step back it kept the 3.5 N that reached it before, and a 27.5 N s forward push that sim3_zmp survives without
the estimate felled it). A force that grows by more than the limit within a few tenths of a second is
taken for a push and not followed.

In the linear inverted pendulum with a constant external acceleration a = f_ext / m,
c_ddot = omega^2 (c - p) + a: the robot keeps its ZMP p where the plan puts it by leaning its CoM by
-a / omega^2 (on a 3 deg slope z_c sin(3 deg): 48 mm uphill for sim3_zmp's z_c = 0.91 m) and commanding its
model's acceleration minus a.
:class:`humanoid_sim.controllers.balance.dcm.DcmFeedback` does both through ``lean`` (the DCM error is measured
against the leaned plan), clamped to ``lean_max_m``. Units: SI; world frame (x lateral, y forward, z up).
"""

from __future__ import annotations

import math

import numpy as np

from humanoid_sim.controllers.balance.estimate import low_pass_gain

PUSH_HOLD_S = 0.25
"""How long after its reading left the estimate by more than the limit the observer keeps dropping a push's
momentum, s (longer than a push of the benchmark, 0.1 s; a longer push leaves it again)."""


class ForceEstimate:
    """The momentum observer of the module docstring, horizontally.

    Args:
        mass: the controller's model mass m, kg.
        cutoff_hz: the estimate's cut-off f, Hz (> 0).
        limit: the largest departure of the observer's reading from the estimate that is not a push, N (> 0;
            infinite: none is); a push's momentum the observer drops (module docstring).
    """

    def __init__(self, mass: float, cutoff_hz: float, limit: float = math.inf) -> None:
        if not (math.isfinite(mass) and mass > 0.0):
            raise ValueError(f"mass = {mass!r}: expected a mass > 0 kg")
        if not (math.isfinite(cutoff_hz) and cutoff_hz > 0.0):
            raise ValueError(f"cutoff_hz = {cutoff_hz!r}: expected a frequency > 0 Hz")
        if not limit > 0.0:
            raise ValueError(f"limit = {limit!r}: expected a force > 0 N")
        self.limit = float(limit)
        self.hold_until = -math.inf
        """Until when (s) a push's momentum is dropped."""
        self.quiet = (0.0, 0.0)
        """The estimate when the observer's reading last lay within half the limit of it, N."""
        self.mass = float(mass)
        self.cutoff_hz = float(cutoff_hz)
        self.gain = 2.0 * math.pi * self.cutoff_hz
        self.t_last: float | None = None
        self.p_hat = (0.0, 0.0)
        """The predicted horizontal momentum, kg m/s."""
        self.raw = (0.0, 0.0)
        """The observer's f_hat (x, y), N, world frame."""
        self.force = (0.0, 0.0)
        """The estimate: f_hat low-passed once more (x, y), N, world frame."""

    def update(self, t: float, c_dot: np.ndarray, foot_wrenches: np.ndarray | None) -> tuple[float, float]:
        """Advance to time ``t`` (s) with the measured CoM velocity ``c_dot`` (3,) m/s and the feet's mean wrenches
        over the period since the last update (``Observation.foot_wrenches``, (2, 6); None: nothing measured, the
        estimate is kept).  Returns the estimate (x, y), N.  A repeated or earlier time does not advance it."""
        m = self.mass
        px, py = m * float(c_dot[0]), m * float(c_dot[1])
        if foot_wrenches is None:
            return self.force
        fx = float(foot_wrenches[0, 0]) + float(foot_wrenches[1, 0])
        fy = float(foot_wrenches[0, 1]) + float(foot_wrenches[1, 1])
        if self.t_last is None:
            self.p_hat = (px, py)
            self.t_last = t
            return self.force
        dt = t - self.t_last
        if dt <= 0.0:
            return self.force
        self.t_last = t
        ex, ey = self.raw
        hx, hy = self.p_hat
        hx += dt * (fx + ex)
        hy += dt * (fy + ey)
        self.p_hat = (hx, hy)
        L = self.gain
        rx, ry = L * (px - hx), L * (py - hy)
        ox, oy = self.force
        dev = math.hypot(rx - ox, ry - oy)
        if dev > self.limit:
            if t > self.hold_until:      # a new push: back to the estimate from before it showed
                self.force = ox, oy = self.quiet
            self.hold_until = t + PUSH_HOLD_S
        held = t <= self.hold_until
        if held:
            # a push: drop its momentum from the prediction, the observer reads the estimate it had
            rx, ry = ox, oy
            self.p_hat = (px - rx / L, py - ry / L)
        self.raw = (rx, ry)
        a = low_pass_gain(dt, self.cutoff_hz)
        self.force = (ox + a * (rx - ox), oy + a * (ry - oy))
        if not held and dev < 0.5 * self.limit:
            self.quiet = self.force
        return self.force


def lean_offset(force: tuple[float, float], mass: float, omega: float, limit: float) -> tuple[float, float]:
    """The LIPM's CoM lean (x, y), m, that keeps the ZMP where planned under a constant horizontal ``force`` (N):
    f / (m omega^2), along the force (the CoM leans against it by this much), its length clamped to ``limit`` (m)."""
    s = 1.0 / (mass * omega * omega)
    bx, by = force[0] * s, force[1] * s
    n = math.hypot(bx, by)
    if n > limit:
        bx, by = bx * limit / n, by * limit / n
    return bx, by
