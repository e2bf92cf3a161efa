"""Whole-body inverse kinematics of a walk (humanoid_sim/references/zmp/posture.py), checked with forward kinematics of
the returned configurations and with HumanoidModel.q_on_foot (which places a toe body without any iteration)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim import PACKAGE_DIR
from humanoid_sim.references.chapter3 import ReferenceTrajectory
from humanoid_sim.references.initial import initial_configuration
from humanoid_sim.references.zmp.errors import GaitError
from humanoid_sim.references.zmp.posture import WalkPosture, thesis_free_toes
from humanoid_sim.scenario.schema import load_scenario

PARAMS = PACKAGE_DIR.parent / "scripts" / "params"
T = 0.01
IK_TOL = 1e-9   # m / rad: the solver stops at 1e-10; FK of the returned q repeats a few roundings


@pytest.fixture(scope="module")
def walk(hm):
    """Sim 3 (straight, 0.93 m hip) from a 0.5 s stand to its end, with the thesis's own hip reference."""
    path = load_scenario(PARAMS / "sim3.yaml").path
    traj = ReferenceTrajectory(path)
    q0 = initial_configuration(hm, path)
    times = -0.5 + T * np.arange(int(round((traj.duration + 0.5) / T)))
    hip = np.array([traj.positions(max(t, 0.0))[0][:2] for t in times])
    post = WalkPosture.from_trajectory(hm, traj, times, q0)
    q = post(hip)
    return traj, q0, times, hip, post, q


def test_thesis_free_toes(walk):
    traj, _, times, _, post, _ = walk
    for k in range(0, len(times), 7):
        t = times[k]
        if t < 0:
            assert not post.free_toe[k].any()
            continue
        ph = traj.phases[traj.phase_at(t)]
        foot = ph.swing_foot if ph.is_ssp else ("L" if ph.landed_foot == "R" else "R")
        assert post.free_toe[k].tolist() == [foot == "R", foot == "L"]


def test_configurations_meet_every_target(hm, walk):
    traj, q0, times, hip, post, q = walk
    data = hm.model.createData()
    fid = hm.frame_id
    for k in range(len(times)):
        s = traj.sample_global(float(times[k]))
        pin.framesForwardKinematics(hm.model, data, q[k])
        np.testing.assert_allclose(data.oMf[fid("Pc_17")].translation, [*hip[k], traj.hip_z], atol=IK_TOL)
        np.testing.assert_allclose(data.oMf[fid("O_17")].rotation, s.hip_R, atol=IK_TOL)
        np.testing.assert_allclose(data.oMf[fid("P_tpR")].translation, s.toe_R_p, atol=IK_TOL)
        np.testing.assert_allclose(data.oMf[fid("P_tpL")].translation, s.toe_L_p, atol=IK_TOL)
        np.testing.assert_allclose(data.oMf[fid("O_1")].rotation, s.foot_R_R, atol=IK_TOL)
        np.testing.assert_allclose(data.oMf[fid("O_2")].rotation, s.foot_L_R, atol=IK_TOL)
    theta = np.array([hm.theta_from_q(x) for x in q])
    toes = theta[:, [hm.theta_index("theta3"), hm.theta_index("theta4")]]
    assert np.all(toes[~post.free_toe] == 0.0)            # a foot that is not free stays flat
    assert np.abs(toes).max() > np.radians(1.0)           # the thesis hip needs the heel up (sim 3: ~4 deg)
    upper = [hm.theta_index(n) for n in ("theta18", "theta19", "theta20", "theta21", "theta22", "theta23",
                                          "theta24", "theta25", "theta26", "theta27")]
    np.testing.assert_array_equal(theta[:, upper], np.tile(hm.theta_from_q(q0)[upper], (len(q), 1)))


def test_ankle_of_a_turned_toe_joint_matches_the_model(hm, walk):
    post = walk[4]
    data = hm.model.createData()
    for f, toe, main, name in (("R", "O_1", "O_3", "theta3"), ("L", "O_2", "O_4", "theta4")):
        for angle in (-0.4, 0.25):
            q = pin.neutral(hm.model)
            q[hm.theta_q_idx[hm.theta_index(name)]] = angle
            pin.framesForwardKinematics(hm.model, data, q)
            rel = data.oMf[hm.frame_id(toe)].actInv(data.oMf[hm.frame_id(main)]).translation
            np.testing.assert_allclose(post._ankle_in_toe(f, angle), rel, atol=1e-14)


def test_needed_heel_angle_brings_the_leg_to_its_cap(hm, walk):
    """Independent placement: q_on_foot puts the toe body at its target with the needed toe angle (no iteration),
    and the hip joint comes from the base placement; their distance must be max_extension x the straight leg."""
    traj, _, times, hip, post, _ = walk
    data = hm.model.createData()
    hits = 0
    for k in np.flatnonzero(np.any(post.toe_needed != 0.0, axis=1))[::5]:
        i = int(np.flatnonzero(post.toe_needed[k])[0])
        f = "RL"[i]
        s = traj.sample_global(float(times[k]))
        theta = np.zeros(26)
        theta[hm.theta_index("theta3" if f == "R" else "theta4")] = post.toe_needed[k, i]
        p, R = (s.toe_R_p, s.foot_R_R) if f == "R" else (s.toe_L_p, s.foot_L_R)
        q = hm.q_on_foot(theta, f, p, R)
        pin.framesForwardKinematics(hm.model, data, q)
        ankle = data.oMf[hm.frame_id("O_3" if f == "R" else "O_4")].translation.copy()   # a view into data
        q_hip = walk[5][k]                      # any configuration with the base at the sample's target
        pin.framesForwardKinematics(hm.model, data, q_hip)
        hip_joint = data.oMf[hm.frame_id("O_11" if f == "R" else "O_12")].translation
        leg = hm.spec.dims["l9"] + hm.spec.dims["l11"]
        # 1e-10 m: brentq's xtol is 1e-13 rad on a ~0.2 m lever; the rest is rounding
        assert np.linalg.norm(hip_joint - ankle) == pytest.approx(post.max_extension * leg, abs=1e-10)
        hits += 1
    assert hits >= 5


def test_heel_angle_is_smooth(walk):
    """The used toe angle has no corners: its second difference stays at the level of the smoothing (the hard
    rule's corners gave ~140 rad/s^2 and 0.1-0.45 m multibody-ZMP spikes)."""
    post = walk[4]
    acc = np.abs(np.diff(post.toe_angle, 2, axis=0)) / T ** 2
    # 100 rad/s^2: a 4 deg rise over the 0.05 s ramp is ~110 rad/s^2 at a smoothstep's worst; measured 69
    assert acc.max() < 100.0


def test_posture_depends_on_the_targets_only(hm, walk):
    """The least-distance solution does not remember the warm start: a call after another path gives the same q."""
    traj, q0, times, hip, _, q = walk
    post = WalkPosture.from_trajectory(hm, traj, times, q0)
    post(hip + np.array([0.01, -0.02]))
    # 1e-8: both iterations stop within 1e-10 of the same solution of a well-conditioned problem
    np.testing.assert_allclose(post(hip), q, atol=1e-8)


def test_unreachable_hip_is_reported(hm, walk):
    traj, q0, times, hip, _, _ = walk
    post = WalkPosture.from_trajectory(hm, traj, times[:20], q0)
    with pytest.raises(GaitError, match="cannot reach"):
        post(hip[:20] + np.array([0.0, 0.5]))


def test_bad_inputs_are_named(hm, walk):
    traj, q0, times, hip, post, _ = walk
    with pytest.raises(GaitError, match=r"hip_xy: expected an \(\d+, 2\) array"):
        post(hip[:-1])
    with pytest.raises(GaitError, match="free_toe: expected an"):
        WalkPosture.from_trajectory(hm, traj, times, q0, free_toe=np.zeros((3, 2), dtype=bool))
    with pytest.raises(GaitError, match="max_extension: expected a fraction"):
        WalkPosture.from_trajectory(hm, traj, times, q0, max_extension=1.5)
    assert thesis_free_toes(traj, [-1.0]).tolist() == [[False, False]]
