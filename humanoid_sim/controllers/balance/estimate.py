"""The base twist the balance controller acts on: the sensed twist filtered against the controller's own prediction.

A sensed base twist carries noise that no PD, DCM law or contact row of the QP should see: the welds' velocity
terms (Baumgarte's ``kd J v``, kd = 40 1/s) turn 0.02 m/s of white noise into ~1 m/s^2 of commanded foot
acceleration against the ground, the DCM law multiplies its velocity error by omega + k ~ 24 1/s, and the swing
foot's damping (2 x 25 1/s) sees the base's angular noise times the leg's length.  The filter predicts the twist
with the base acceleration the controller's last QP solved for, then corrects it toward the measurement (an
observer with a constant gain, the steady state of a Kalman filter on an integrator):

    z_pred = z + a_base dt,    z = z_pred + a (v_meas - z_pred),    a = 1 - e^{-2 pi f dt},

which is a first-order low-pass filter of cut-off f (Hz) on the prediction's error.  It leaves a white noise of
standard deviation sigma, sampled every dt, at sigma sqrt(a / (2 - a)) (30 Hz at 2 ms: 43 %); a motion the
controller commanded passes without the low-pass's lag of ~1 / (2 pi f) (16 ms at 10 Hz), which on the nominal
MuJoCo walk tripled the hip's tracking error.  A push, which the prediction does not know, is still lagged: a
lower cut-off costs push recovery (docs/controllers.md).  The joint rates are not filtered: they are measured by
encoders, and a lag on them would lag every task.

The twist of the legs' kinematics with the held feet still (-X_bf J_f qdot, the legged estimators' odometry) is no
substitute on MuJoCo's soft contact: the soles move by mm at every touchdown and at the start, and that estimate
swings by up to 0.9 m/s there; blended with the sensed twist (kinematics above 1-20 Hz) the nominal walk fell within
0.3 s.  Frames: ``v[:6]`` is the base's [linear; angular] velocity in the base frame (Pinocchio's free flyer); SI
units.
"""

from __future__ import annotations

import math

import numpy as np


def low_pass_gain(dt: float, cutoff_hz: float) -> float:
    """The update gain a = 1 - e^{-2 pi f dt} of a first-order low-pass filter of cut-off ``cutoff_hz`` (Hz) over a
    step ``dt`` (s; <= 0: no update, 0)."""
    if dt <= 0.0:
        return 0.0
    return 1.0 - math.exp(-2.0 * math.pi * cutoff_hz * dt)


class TwistFilter:
    """The base twist low-passed at ``cutoff_hz`` (module docstring).

    Args:
        cutoff_hz: the filter's cut-off frequency, Hz (> 0).
    """

    def __init__(self, cutoff_hz: float) -> None:
        if not (math.isfinite(cutoff_hz) and cutoff_hz > 0.0):
            raise ValueError(f"cutoff_hz = {cutoff_hz!r}: expected a frequency > 0 Hz")
        self.cutoff_hz = float(cutoff_hz)
        self.z = np.zeros(6)
        """The filtered base twist, base frame, [m/s; rad/s]."""
        self.t_last: float | None = None
        self.acc = np.zeros(6)
        """The base acceleration (6,) of the controller's last command (``a[:6]``, base frame), m/s^2 and rad/s^2:
        the prediction (set by the controller after each solve)."""

    def __call__(self, t: float, v: np.ndarray) -> np.ndarray:
        """``v`` with its base twist ``v[:6]`` replaced by the filtered one (a new array).  ``t``: the call's time,
        s; a repeated or earlier time (an engine's integration stage) does not advance the filter."""
        if self.t_last is None:
            self.z[:] = v[:6]
            self.t_last = t
        else:
            dt = t - self.t_last
            a = low_pass_gain(dt, self.cutoff_hz)
            if a > 0.0:
                self.z += self.acc * dt
                self.z += a * (v[:6] - self.z)
                self.t_last = t
        out = v.copy()
        out[:6] = self.z
        return out
