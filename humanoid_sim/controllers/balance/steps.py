"""Online step adjustment: the next foothold moved to where the DCM says the robot can stop.

In single support on a fixed CoP p the DCM diverges as xi(t) = p + (xi(t_now) - p) e^{omega (t - t_now)}, so a DCM
error e (measured minus plan) grows to e e^{omega T_r} by the planned touchdown, T_r ahead.  Like IHMC's ICP
planner (the next foothold at the predicted capture point plus the nominal offset), the swing foot's landing
moves by that predicted error, less a dead band the ankles absorb (so that the nominal walk, whose DCM tracks its
plan to a few mm, keeps its footholds), clamped in the heading frame (x forward, y left, the trunk's planned yaw)
to a reach box (``step_forward_m`` ahead, ``step_backward_m`` back, ``step_outward_m`` away from the stance foot)
and to a collision bound (the feet's toe points at least ``step_min_width_m`` apart sideways: no crossing step).
The offset is frozen after ``freeze`` of the swing (a target that jumps just before touchdown lands the foot
tilted), moves at most ``max_speed`` m/s, and enters the swing foot's target ramped with the swing's progress.

Step timing (``step_timing``): when the forward foothold the DCM asks for (the robot ahead of its plan) lies
beyond the reach, the step lands earlier instead, while the error is smaller (Khadiv et al. 2016 choose a step's
position and duration together, in the same exponential of omega T).  The remaining swing time T becomes the
longest that brings the forward offset within its reach, ln((reach + dead band) / error) / omega, but:
- not under ``step_min_time_s``;
- gaining no more time than the plan needs to catch up with the robot (error / the plan's forward speed);
- only from ``step_timing_after`` of the swing on.
The swing's path then runs on its own clock, ``rate`` = (planned remaining swing) / T times as fast as the plan's
(at most ``step_max_rate``; a rate never decreases within a swing).  At the early touchdown the plan's clock moves
on toward the double support's start (:meth:`humanoid_sim.interfaces.selector.PhaseSelector.advance`) by the
amount, within the time gained and ``step_max_jump_s``, that brings the plan's lateral DCM nearest the measured one,
and waits out the rest, as for any early touchdown (:meth:`StepAdjuster.plan_jump`).  Why: the robot's lateral sway
does not wait for the plan's.  A plan whose clock moves by a fixed amount can leave its lateral DCM a lateral error
away from the robot's that the next single support cannot absorb (the robot falls sideways one or two steps
later); a plan that never moves on leaves a robot pushed forward ahead of it (the push benchmark:
``docs/notes/2026-11-27-step-timing.md`` and ``docs/notes/2026-11-27-plan-clock.md``).

A moved foothold moves the rest of the walk with it: the plan's ZMP is shifted by the offset from the middle of the
double support that follows the touchdown on, the DCM reference follows by the LIPM's backward recursion
(:class:`.dcm.ZmpShift`), and every later swing lands the offsets so far from its planned foothold, less what the
steps since have taken back: each step adds to its own offset the earlier offsets' opposite, at most
``step_return_m`` long, so that a walk knocked off its path walks back onto it over a few steps (the recovery step
is never pulled back: the return starts with the step after it, and the DCM error's move comes on top).
SI units, world frame.
"""

from __future__ import annotations

import math

import numpy as np

from humanoid_sim.controllers.balance.dcm import DcmFeedback, ZmpShift, ZmpWindow, capture_point
from humanoid_sim.robot.phases import other_foot

_NO_END = 1e9
"""A window's end, s: a moved foothold moves the rest of the walk with it."""
JUMP_CANDIDATES = 17
"""Plan-clock moves tried at an early touchdown (:meth:`StepAdjuster.plan_jump`): every 1/16 of the allowed move,
at most 19 ms apart with the default ``step_max_jump_s`` (0.3 s), in which the plan's DCM moves at most ~20 mm
(its speed stays under 1.1 m/s on the shipped zmp gaits)."""


def smoothstep(x: float) -> float:
    """3 x^2 - 2 x^3 on [0, 1], clamped."""
    x = min(max(x, 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x)


def _shrink(x: float, band: float) -> float:
    """x moved toward zero by ``band`` (>= 0), stopping at zero."""
    return x - band if x > band else x + band if x < -band else 0.0


def predicted_offset(err: np.ndarray, omega: float, t_remaining: float, deadband: float,
                     plus: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """The foothold offset (2,) m for a DCM error ``err`` (2,) m, in any horizontal frame: the error grown over
    ``t_remaining`` s by e^{omega T}, each component shrunk toward zero by ``deadband`` m, plus ``plus`` (m, the
    same frame: a move wanted whatever the error, such as the return toward the planned footholds)."""
    g = math.exp(omega * max(t_remaining, 0.0))
    return np.array([_shrink(float(err[0]) * g, deadband) + plus[0], _shrink(float(err[1]) * g, deadband) + plus[1]])


def clamp_offset(d_heading: np.ndarray, outward_sign: float, width: float, s) -> np.ndarray:
    """The heading-frame offset (forward, left) (2,) m clamped to the reach box and the collision bound.

    Args:
        d_heading: the wanted offset, m.
        outward_sign: +1 when the swing foot is the left one (away from the stance foot is +y), -1 the right.
        width: the nominal landing's lateral distance from the stance foot (toe points, heading frame), m.
        s: the :class:`BalanceSettings`.
    """
    fwd = min(max(float(d_heading[0]), -s.step_backward_m), s.step_forward_m)
    out = outward_sign * float(d_heading[1])
    out = min(max(out, min(s.step_min_width_m - width, 0.0)), s.step_outward_m)
    return np.array([fwd, outward_sign * out])


class StepAdjuster:
    """The step adjustment of the module docstring for one walk (``traj``: the zmp gait's trajectory; ``shift``:
    the DCM feedback's ZMP shift, which this fills; ``settings``: :class:`BalanceSettings`)."""

    freeze = 0.75
    """Swing progress after which the offset is frozen (-)."""
    max_speed = 1.5
    """The largest speed of the offset, m/s."""

    def __init__(self, traj, shift: ZmpShift, settings) -> None:
        self.traj = traj
        self.shift = shift
        self.s = settings
        self.k = -1                       # the single support being adjusted (phase index)
        self.window: ZmpWindow | None = None
        self.d = np.zeros(2)              # the applied offset of that single support, world, m
        self.t_last = 0.0
        self.ratio = 0.0                  # the swing's progress at the last call (-)
        self.ahead = 0.0                  # how far the swing's clock runs ahead of the plan's, s
        self.clock_rate = 1.0             # d t_sw / dt (step timing), -
        self.shortened = 0                # single supports whose swing was shortened
        self.adjusted = 0                 # single supports whose foothold moved
        self.total = np.zeros(2)          # the earlier single supports' offsets, world, m
        self._width_vec = (0.0, 0.0)      # nominal landing + earlier offsets - stance toe point, world, m
        self._end = np.zeros(3)           # the nominal landing's toe point, world, m
        self._xi: tuple[float, float] | None = None   # the last call's measured DCM, world, m
        self._ret = (0.0, 0.0)            # this step's return toward the planned footholds, world, m
        self._left = (0.0, 1.0)           # the heading frame's left axis, world

    def _start(self, k: int, t: float) -> None:
        ph = self.traj.phases
        n = len(ph)
        t0 = ph[k].t_end + (0.5 * ph[k + 1].duration if k + 1 < n else 0.0)
        self.k, self.d, self.t_last = k, np.zeros(2), t
        self.ahead, self.clock_rate = 0.0, 1.0
        self.total = sum((w.d for w in self.shift.windows), np.zeros(2))
        self.window = ZmpWindow(t0, _NO_END, self.d)
        self.shift.windows.append(self.window)
        # the nominal landing's and the stance foot's toe points, world (the stance foot stays during the swing).
        # The stance foot is where it landed, moved by the earlier offsets; the nominal landing is not: the step
        # this swing takes before its own offset is the nominal landing plus those offsets, less the stance
        swing = ph[k].swing_foot
        self._end = np.array(self.traj.phase_targets(k).swing_toe_end, dtype=float)
        stance = np.asarray(self.traj.toe_reference(k, t, other_foot(swing))[0], dtype=float)[:2]
        self._width_vec = (float(self._end[0] + self.total[0] - stance[0]),
                           float(self._end[1] + self.total[1] - stance[1]))
        # the earlier offsets, taken back by at most step_return_m a step (the foothold moves toward the plan's)
        tx, ty = float(self.total[0]), float(self.total[1])
        n = math.hypot(tx, ty)
        g = min(1.0, self.s.step_return_m / n) if n > 0.0 else 0.0
        self._ret = (-g * tx, -g * ty)

    def update(self, k: int, t: float, xi_err: np.ndarray, omega: float, R_heading: np.ndarray,
               xi: tuple[float, float] | None = None) -> None:
        """One call in single support k at plan time t: the DCM error ``xi_err`` (2,) m against the plan shifted by
        the earlier moved footholds; ``R_heading`` the trunk's planned orientation (its x axis forward); ``xi`` the
        measured DCM (x, y) m, world (leaned, as the error), kept for :meth:`plan_jump`."""
        info = self.traj.phases[k]
        if info.swing_foot is None:
            return
        self._xi = xi
        if self.k != k:
            self._start(k, t)
            moved = False
        else:
            moved = self.d[0] != 0.0 or self.d[1] != 0.0
        dt, self.t_last = max(t - self.t_last, 0.0), t
        self.ahead += dt * (self.clock_rate - 1.0)
        t_sw = t + self.ahead                                       # the swing's clock
        u = (t_sw - info.t_start) / info.duration
        self.ratio = u
        if u > self.freeze:
            return
        # scalar arithmetic: this runs at every call of a single support (a 2-vector numpy operation costs ~1 us)
        fx, fy = float(R_heading[0, 0]), float(R_heading[1, 0])
        nf = max(math.hypot(fx, fy), 1e-9)
        fx, fy = fx / nf, fy / nf                                   # forward; left is (-fy, fx)
        self._left = (-fy, fx)
        ex, ey = float(xi_err[0]), float(xi_err[1])
        e = (fx * ex + fy * ey, fx * ey - fy * ex)
        s = self.s
        left = max(info.t_end - t_sw, 0.0)                     # the planned swing still to go, s
        ret = (fx * self._ret[0] + fy * self._ret[1], fx * self._ret[1] - fy * self._ret[0])   # heading frame
        want = predicted_offset(e, omega, left / self.clock_rate, s.step_deadband_m, ret)
        width = abs(fx * self._width_vec[1] - fy * self._width_vec[0])
        sign = 1.0 if info.swing_foot == "L" else -1.0
        hf, hl = clamp_offset(want, sign, width, s)
        if s.step_timing and e[0] > 0.0 and left > 0.0 and want[0] - hf > 1e-3 and \
                u >= s.step_timing_after:
            period = info.duration + (self.traj.phases[k + 1].duration if k + 1 < len(self.traj.phases) else 0.0)
            speed = max(fx * self._width_vec[0] + fy * self._width_vec[1], 0.0) / period   # the plan's, m/s
            rate = self._timing(e, (hf, hl), omega, left, speed, s)
            if rate > self.clock_rate:
                self.clock_rate = rate
                want = predicted_offset(e, omega, left / rate, s.step_deadband_m, ret)
                hf, hl = clamp_offset(want, sign, width, s)
        sx, sy = fx * hf - fy * hl - self.d[0], fy * hf + fx * hl - self.d[1]
        n = math.hypot(sx, sy)
        if n > self.max_speed * dt:
            sx, sy = sx * self.max_speed * dt / n, sy * self.max_speed * dt / n
        self.d[0] += sx                   # in place: the window holds it
        self.d[1] += sy
        if not moved and (self.d[0] != 0.0 or self.d[1] != 0.0):
            self.adjusted += 1

    def _timing(self, e: tuple[float, float], reach: tuple[float, float], omega: float, left: float, speed: float,
                s) -> float:
        """The swing clock's rate (>= 1) that lands the foot while the forward error ``e[0]`` (m) still fits the
        forward ``reach[0]`` (m): the remaining time ln((reach + dead band) / e) / omega, at least
        ``step_min_time_s``, for ``left`` s of planned swing, at most ``step_max_rate``; and no more time gained
        than the plan needs to catch up with the robot, e / ``speed`` (the plan's mean forward speed, m/s)."""
        T = min(left / self.clock_rate, math.log(max((reach[0] + s.step_deadband_m) / e[0], 1.0)) / omega)
        T = max(T, s.step_min_time_s)
        if speed > 1e-6:        # gained so far (ahead) plus left - T: at most e / speed
            T = max(T, left - max(e[0] / speed - self.ahead, 0.0))
        rate = min(left / T, s.step_max_rate) if T > 0.0 else s.step_max_rate
        if rate > self.clock_rate and self.clock_rate == 1.0:
            self.shortened += 1
        return rate

    def landing(self, k: int) -> np.ndarray | None:
        """Single support k's landing toe point (3,) m, world: the plan's moved by the offsets so far and this
        step's; None when nothing moved it (or k is not the step being adjusted)."""
        if self.k != k or not (np.any(self.d) or np.any(self.total)):
            return None
        end = self._end.copy()
        end[:2] += self.total + self.d
        return end

    def plan_jump(self, k: int) -> float:
        """How far (s) the plan's clock moves on at the touchdown ending single support k, when step timing
        shortened that swing: of the moves in [0, the time gained] (the plan's remaining swing at touchdown, at most
        ``step_max_jump_s``), the one whose plan DCM is nearest the measured one sideways (heading frame; the
        moved footholds included; the module docstring says why).  0 for a swing step timing left alone; the rest
        of an early touchdown the plan waits for."""
        if self.k != k or self.clock_rate == 1.0:
            return 0.0
        cap = min(max(self.traj.phases[k].t_end - self.t_last, 0.0), self.s.step_max_jump_s)
        if self._xi is None:
            return cap
        (lx, ly), (x, y) = self._left, self._xi
        best, best_e = 0.0, math.inf
        for i in range(JUMP_CANDIDATES):
            tau = cap * i / (JUMP_CANDIDATES - 1)
            tc = self.t_last + tau
            c, cd, _, _ = self.traj.com_targets(k, tc)
            xp = capture_point(c, cd, self.shift.omega)          # the plan's DCM; the shift's omega is the law's
            _, (dx, dy) = self.shift.at(tc)
            e = abs(lx * (x - float(xp[0]) - dx) + ly * (y - float(xp[1]) - dy))
            if e < best_e:
                best, best_e = tau, e
        return best

    def swing_clock(self, k: int, t: float) -> tuple[float, float]:
        """(t_sw, rate): where single support k's swing is on its planned path (s, the plan's time) and how fast
        that clock runs (-); (t, 1) when the swing runs on the plan's clock."""
        if self.k != k:
            return t, 1.0
        return t + self.ahead, self.clock_rate

    def swing_target(self, k: int, swing: tuple) -> tuple:
        """Single support k's swing targets (``Targets.swing``) with the toe point moved by the offsets (the earlier
        ones and this one), ramped in over the swing's progress (smoothstep to full at ``freeze``)."""
        if self.k != k:
            return swing
        # in floats (the same numbers as the 2-vector expression; this runs at every call of a swing)
        (d0, d1), (t0, t1) = self.d.tolist(), self.total.tolist()
        if not (d0 or d1 or t0 or t1):
            return swing
        foot, pt, v6, Rr, a_ff, xr = swing
        pt = pt.copy()
        ramp = smoothstep(self.ratio / self.freeze)
        pt[0] += (t0 + d0) * ramp
        pt[1] += (t1 + d1) * ramp
        return foot, pt, v6, Rr, a_ff, xr


def dcm_feedback(settings, model, hip_frame: int, traj) -> DcmFeedback | None:
    """The balance controller's :class:`.dcm.DcmFeedback` (with a :class:`StepAdjuster` when
    ``settings.step_adjustment``) for ``settings.feedback == "dcm"`` and a trajectory with a whole-body CoM plan
    (``traj.com_plan``), else None (the hip PD)."""
    com_plan = getattr(traj, "com_plan", None)
    if settings.feedback != "dcm" or com_plan is None:
        return None
    fb = DcmFeedback(model, hip_frame, com_plan[3], settings.dcm_gain)
    if settings.step_adjustment:
        fb.steps = StepAdjuster(traj, fb.shift, settings)
    return fb
