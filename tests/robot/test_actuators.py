"""Thesis actuator torques T <-> generalized torques: power conjugacy and the joint-moment definition."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from humanoid_sim.robot.actuators import GROUPS, T_NAMES, Actuators


def _state(hm, seed):
    rng = np.random.default_rng(seed)
    q = hm.q_from_theta(rng.uniform(-0.6, 0.6, 26), pin.SE3.Random())
    return rng, q, rng.normal(size=hm.model.nv), rng.normal(size=hm.model.nv)


def test_torque_map_is_power_conjugate(hm):
    """tau = B T: the power tau . v equals the sum over joints of the moment
    M (components T in the higher body's frame) dotted with the relative angular velocity of the higher body
    with respect to the lower one, computed independently from pinocchio's frame velocities (shoulders: the
    moment made of the actuated x, y components only)."""
    act = Actuators(hm)
    rng, q, v, _ = _state(hm, 1)
    T = rng.normal(size=26)
    B = act.torque_map(q)
    data = hm.model.createData()
    pin.forwardKinematics(hm.model, data, q, v)
    pin.updateFramePlacements(hm.model, data)
    lower = {3: 1, 9: 3, 11: 9, 17: None, 4: 2, 10: 4, 12: 10, 20: 17, 23: 20, 24: 20, 27: 20}
    power = 0.0
    row = 0
    for g in GROUPS:
        comps = np.zeros(3)
        for c in g.comps:
            comps[c] = T[row]
            row += 1
        Rj = data.oMf[hm.frame_id(f"O_{g.higher}")].rotation
        w_hi = pin.getFrameVelocity(hm.model, data, hm.frame_id(f"O_{g.higher}"),
                                    pin.ReferenceFrame.LOCAL_WORLD_ALIGNED).angular
        lo = {"right_hip": 11, "left_hip": 12}.get(g.name, lower.get(g.higher))
        w_lo = pin.getFrameVelocity(hm.model, data, hm.frame_id(f"O_{lo}"),
                                    pin.ReferenceFrame.LOCAL_WORLD_ALIGNED).angular
        power += (Rj @ comps) @ (w_hi - w_lo)
    # Round-off on sums of ~100 products of O(1) numbers.
    assert abs(B @ T @ v - power) < 1e-12
    assert len(T_NAMES) == 26 and T_NAMES[:2] == ("T1", "T3") and T_NAMES[8] == "T2"


def test_thesis_torques_invert_the_map_and_read_the_shoulder_moment(hm):
    """T from (q, v, a, tau): for revolute/spherical groups the inverse of B; for the shoulders the components of
    the moment transmitted to the arm.  Rebuild tau from T (B T, plus the shoulders' reaction component) and
    compare with the generalized torques of the same motion from RNEA."""
    act = Actuators(hm)
    rng, q, v, a = _state(hm, 2)
    tau = pin.rnea(hm.model, hm.model.createData(), q, v, a)
    T = act.thesis_torques(q, v, a, tau)
    B = act.torque_map(q)
    tau_rebuilt = B @ T
    joints = [j for g in GROUPS if g.name.endswith("shoulder") for j in g.thetas]
    others = [int(hm.theta_v_idx[hm.theta_index(n)]) for n in
              [t for g in GROUPS if not g.name.endswith("shoulder") for t in g.thetas]]
    # 1e-9 N m: solves of 3x3 systems with torques up to ~1e2 N m
    np.testing.assert_allclose(tau_rebuilt[others], tau[others], atol=1e-9)
    # theta23/theta24 (the y axis of the arm frame) see exactly T21/T23; theta21/22 also see the reaction.
    for name, row in (("theta23", T_NAMES.index("T21")), ("theta24", T_NAMES.index("T23"))):
        vi = int(hm.theta_v_idx[hm.theta_index(name)])
        assert abs(hm.theta_sign[hm.theta_index(name)] * tau[vi] - T[row]) < 1e-9
    assert joints == ["theta21", "theta23", "theta22", "theta24"]


def test_saturate_is_a_clip_to_the_limits(hm):
    """``saturate`` against numpy's clip: torques inside, on and beyond the limits, and NaN (flagged saturated, as
    clip's NaN != NaN), with and without anything to clip (the method skips the clip when nothing binds)."""
    act = Actuators(hm)
    lim = act.limits
    rng = np.random.default_rng(3)
    inside = lim * rng.uniform(-0.99, 0.99, 26)
    for T in (inside, lim * rng.uniform(-1.5, 1.5, 26), np.where(np.arange(26) == 4, np.nan, inside),
              np.where(np.arange(26) == 7, -lim, inside)):
        Ts, sat = act.saturate(T)
        ref = np.clip(T, -lim, lim)
        assert np.array_equal(Ts, ref, equal_nan=True)
        assert np.array_equal(sat, ref != T)
        assert Ts is not T
    assert not act.saturate(inside)[1].any()
