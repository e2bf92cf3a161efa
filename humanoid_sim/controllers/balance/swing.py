"""The swing foot's references of one balance-controller call: the plan's toe path, possibly on a faster clock.

The plan gives the swing toe point's path and orientation (``traj.toe_reference``) on the plan's clock.  Step
timing (:class:`.steps.StepAdjuster`) may run the swing on its own clock ``t_sw``, advancing ``rate`` >= 1 times
as fast as the plan's, so that the foot lands earlier: the path's shape is kept, its velocity is scaled by the rate
and its acceleration by the rate squared (the rate is constant between calls: the d rate / dt term is left out).
SI units, world frame.
"""

from __future__ import annotations

import numpy as np

from humanoid_sim.references.chapter3.polynomials import smoothstep


def swing_targets(traj, s, k: int, t: float, foot: str, real_ground: bool, own: bool, t_sw: float | None = None,
                  rate: float = 1.0) -> tuple:
    """The swing foot's task targets ``(foot, toe point (3,) m, velocity (6,), toe orientation (3x3), feed-forward
    acceleration (6,), heel-return phase (-))`` of single support k at plan time t.

    Args:
        traj: the trajectory (``toe_reference``, ``toe_velocity``, ``phases``).
        s: the :class:`BalanceSettings`.
        k: the phase index (a single support).
        t: the plan's time, s (the swing ramp and the heel return run on it).
        foot: "R" or "L", the swing foot.
        real_ground: the engine has unilateral contact (the landing's depth and search apply).
        own: ``traj`` is one of the package's trajectories (``swing_feedforward`` answers in one query).
        t_sw: the swing's clock, s (None: ``t``).
        rate: d t_sw / dt (>= 1).
    """
    info = traj.phases[k]
    ts = t if t_sw is None else t_sw
    hdt = s.ff_dt_s
    if own:
        pt, v6, Rr, a_ff = traj.swing_feedforward(k, ts, foot, hdt)
    else:
        pt, v6, Rr = traj.toe_reference(k, ts, foot)
        a_ff = (traj.toe_reference(k, ts + hdt, foot)[1] - traj.toe_reference(k, ts - hdt, foot)[1]) / (2.0 * hdt)
    if rate != 1.0:
        v6 = v6 * rate
        a_ff = a_ff * (rate * rate)
    # the thesis's toe path starts with a step in acceleration (4-5 m/s^2, 3 rad/s^2 of yaw): its feed-forward
    # is ramped in over swing_ramp_s (smoothstep), or the swing leg's reaction jolts the stance foot
    xs = (t - info.t_start) / s.swing_ramp_s
    if xs < 1.0:
        a_ff = a_ff * smoothstep(max(xs, 0.0))
    # aim the last 20 % of the swing landing_depth_m below the path (smoothstep): on real ground the sole
    # then meets the ground on time and presses it (the path ends with the sole ~0.5 mm above it)
    u = (ts - info.t_start) / info.duration
    depth = s.landing_depth_m if real_ground else 0.0
    if u > 0.8 and depth > 0.0:
        x = min(1.0, (u - 0.8) / 0.2)
        # depth times a smoothstep, written out: depth * smoothstep(x) rounds differently
        pt = pt - np.array([0.0, 0.0, depth * x * x * (3.0 - 2.0 * x)])
        v6 = v6.copy()
        v6[2] -= depth * 6.0 * x * (1.0 - x) / (0.2 * info.duration) * rate
    late = ts - info.t_end
    if late > 0.0:   # the foot has not landed on schedule (real ground): keep lowering it until it does
        pt = pt - np.array([0.0, 0.0, s.landing_search_mps * late / rate])
        v6 = v6.copy()
        v6[2] -= s.landing_search_mps
        a_ff = np.zeros(6)
    return foot, pt, v6, Rr, a_ff, (t - info.t_start) / s.heel_return_time_s
