"""The same contact / impact code on a third-party humanoid: Unitree G1 (29 DOF) from example-robot-data.

Nothing here is specific to the thesis model: contact sets are lists of welded frames (two soles).  The
sole frames are added 0.035 m below / 0.035 m ahead of the ankle-roll link origin, where the URDF's
collision spheres (radius 0.005 at z = -0.03) touch the ground.
"""

from __future__ import annotations

import importlib.metadata as md
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg as sla

from humanoid_sim.dynamics.contact import (
    Baumgarte,
    ContactDynamics,
    ContactSet,
    FootSpec,
    centre_of_pressure,
    ground_reactions,
    record_anchors,
)
from humanoid_sim.dynamics.contact.oracle import kkt_forward, kkt_impulse
from humanoid_sim.engines.impact import constraint_jacobian, inelastic_impact, least_change_reset

STAND = ContactSet(("left_sole", "right_sole"), name="G1 double support")
LEFT = ContactSet(("left_sole",), name="G1 left support")
FEET = [FootSpec("L", "left_sole"), FootSpec("R", "right_sole")]
LEG_JOINTS = tuple(f"{s}_{j}_joint" for s in ("left", "right")
                   for j in ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch", "ankle_roll"))
TOL = 1e-9  # same agreement tolerance as on the thesis model (round-off x KKT conditioning)


def _g1_urdf() -> Path:
    # example-robot-data is a test dependency (pip install -e '.[test]'): a missing package or URDF is an error.
    for f in md.files("example-robot-data") or []:
        if str(f).endswith("g1_description/urdf/g1_29dof_rev_1_0.urdf"):
            return Path(f.locate())
    raise FileNotFoundError("example-robot-data has no g1_description/urdf/g1_29dof_rev_1_0.urdf")


@pytest.fixture(scope="module")
def g1() -> tuple[pin.Model, np.ndarray]:
    """G1 with sole frames, and a standing configuration with both soles flat on z = 0."""
    model = pin.buildModelFromUrdf(str(_g1_urdf()), pin.JointModelFreeFlyer())
    for side in ("left", "right"):
        parent = model.getFrameId(f"{side}_ankle_roll_link")
        fr = model.frames[parent]
        placement = fr.placement * pin.SE3(np.eye(3), np.array([0.035, 0.0, -0.035]))
        model.addFrame(pin.Frame(f"{side}_sole", fr.parentJoint, parent, placement, pin.FrameType.OP_FRAME))
    q = pin.neutral(model)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        for joint, val in (("hip_pitch", -0.3), ("knee", 0.6), ("ankle_pitch", -0.3), ("shoulder_roll", 0.3 * sign),
                           ("elbow", 0.5)):
            q[model.idx_qs[model.getJointId(f"{side}_{joint}_joint")]] = val
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    q[2] -= data.oMf[model.getFrameId("left_sole")].translation[2]
    pin.framesForwardKinematics(model, data, q)
    for s in ("left_sole", "right_sole"):  # both soles flat on the ground (symmetric posture): round-off
        assert abs(data.oMf[model.getFrameId(s)].translation[2]) < 1e-12
        np.testing.assert_allclose(data.oMf[model.getFrameId(s)].rotation, np.eye(3), atol=1e-12)
    return model, q


def _perturbed(model: pin.Model, q: np.ndarray, rng: np.random.Generator, scale: float) -> np.ndarray:
    dq = scale * rng.standard_normal(model.nv)
    dq[:6] = 0.0
    return pin.integrate(model, q, dq)


def test_static_check_and_ground_reactions(g1) -> None:
    model, q_stand = g1
    rng = np.random.default_rng(1)
    dyn = ContactDynamics(model)
    v = np.zeros(model.nv)
    mass = sum(I.mass for I in model.inertias)
    for trial in range(3):
        q = q_stand if trial == 0 else _perturbed(model, q_stand, rng, 0.1)
        anchors = record_anchors(model, q, STAND)
        inv = dyn.inverse(STAND, anchors, q, v, np.zeros(model.nv))
        assert inv.null_space.shape[1] == 6  # internal wrench between the two welded soles
        res = dyn.forward(STAND, anchors, q, v, inv.tau)
        assert np.max(np.abs(res.a)) < TOL
        gr = ground_reactions(model, q, v, res.a, STAND, res.lam, FEET)
        f = gr.feet["L"].force + gr.feet["R"].force
        n = gr.feet["L"].moment + gr.feet["R"].moment
        # Static: the ground carries the weight; the combined CoP is below the CoM.  1e-9: round-off.
        np.testing.assert_allclose(f, [0.0, 0.0, mass * 9.81], atol=1e-9)
        cop, _ = centre_of_pressure(f, n)
        com = pin.centerOfMass(model, model.createData(), q)
        np.testing.assert_allclose(cop[:2], com[:2], atol=1e-9)


def test_forward_agrees_with_oracles(g1) -> None:
    """Random states with position errors and inconsistent velocities: fast path vs NumPy KKT and vs
    pin.constraintDynamics with the same Baumgarte corrector."""
    model, q_stand = g1
    rng = np.random.default_rng(2)
    gains = Baumgarte(20.0, 1.0)
    dyn = ContactDynamics(model, gains)
    for _ in range(3):
        q0 = _perturbed(model, q_stand, rng, 0.2)
        anchors = record_anchors(model, q0, STAND)
        q = pin.integrate(model, q0, 1e-3 * rng.standard_normal(model.nv))
        v = rng.standard_normal(model.nv)
        tau = np.zeros(model.nv)
        tau[6:] = 10.0 * rng.standard_normal(model.nv - 6)
        res = dyn.forward(STAND, anchors, q, v, tau)
        a_o, lam_o = kkt_forward(model, STAND, anchors, q, v, tau, gains)
        scale_a, scale_l = max(1.0, np.max(np.abs(a_o))), max(1.0, np.max(np.abs(lam_o)))
        assert np.max(np.abs(res.a - a_o)) < TOL * scale_a and np.max(np.abs(res.lam - lam_o)) < TOL * scale_l
        cms = []
        for f in STAND.welds:
            fr = model.frames[model.getFrameId(f)]
            cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_6D, model, fr.parentJoint, fr.placement, 0,
                                          anchors.placements[f], pin.ReferenceFrame.LOCAL)
            cm.m_baumgarte_parameters.Kp = gains.kp
            cm.m_baumgarte_parameters.Kd = gains.kd
            cms.append(cm)
        cds = [c.createData() for c in cms]
        data = model.createData()
        pin.initConstraintDynamics(model, data, cms, cds)
        a_cd = pin.constraintDynamics(model, data, q, v, tau, cms, cds)
        assert np.max(np.abs(res.a - a_cd)) < TOL * scale_a


def test_touchdown(g1) -> None:
    """Left-foot support, right foot moving; both laws put the right sole at rest and keep the left one."""
    model, q_stand = g1
    rng = np.random.default_rng(3)
    data = model.createData()
    upper = np.array([model.idx_vs[j] for j in range(2, model.njoints)
                      if model.names[j] not in LEG_JOINTS], dtype=int)
    for _ in range(3):
        q = _perturbed(model, q_stand, rng, 0.1)
        N = sla.null_space(constraint_jacobian(model, data, q, LEFT))
        v = N @ rng.standard_normal(N.shape[1])

        def sole_twists(vv):
            pin.forwardKinematics(model, data, q, vv)
            return [pin.getFrameVelocity(model, data, model.getFrameId(s), pin.LOCAL).vector
                    for s in ("left_sole", "right_sole")]

        assert np.linalg.norm(sole_twists(v)[1]) > 0.1
        thesis_like = least_change_reset(model, q, v, STAND, LEG_JOINTS, np.ones(len(LEG_JOINTS)))
        for twist in sole_twists(thesis_like.v_plus):
            assert np.max(np.abs(twist)) < 1e-10  # round-off on O(1) velocities
        assert np.array_equal(thesis_like.v_plus[upper], v[upper])  # waist, arms unchanged
        inel = inelastic_impact(model, q, v, STAND)
        for twist in sole_twists(inel.v_plus):
            assert np.max(np.abs(twist)) < 1e-10
        v_o, _ = kkt_impulse(model, STAND, q, v)
        assert np.max(np.abs(inel.v_plus - v_o)) < 1e-10
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        assert inel.energy_change <= 0.0
        assert -inel.energy_change == pytest.approx(0.5 * inel.delta_v @ M @ inel.delta_v, rel=1e-9)  # Carnot
