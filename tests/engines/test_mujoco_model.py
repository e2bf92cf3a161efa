"""The MuJoCo model built from our URDF (issue 15): what it contains, and that its dynamics are Pinocchio's."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.analysis.audit import SoleGeometry
from humanoid_sim.engines.mujoco import MujocoModelError, MujocoSettings, StateMap, build_model
from humanoid_sim.engines.mujoco.model import VIRTUAL_BOUND
from humanoid_sim.robot.model import HumanoidModel, load_model


@pytest.fixture(scope="module")
def mm(hm: HumanoidModel):
    return build_model(hm)


def test_structure(hm: HumanoidModel, mm) -> None:
    m = mm.model
    assert (m.nq, m.nv, m.nu) == (33, 32, 26)
    assert m.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE and m.body(m.jnt_bodyid[0]).name == "lower_trunk"
    assert not m.jnt_limited.any() and not m.jnt_actfrclimited.any()  # the URDF's +-pi, 150 N m are dropped
    assert not m.actuator_ctrllimited.any() and not m.actuator_forcelimited.any()
    np.testing.assert_array_equal(m.actuator_gear[:, 0], 1.0)
    assert all(m.actuator_trntype == mujoco.mjtTrn.mjTRN_JOINT)
    # One motor per revolute joint, named after it.
    assert sorted(m.actuator(a).name for a in range(m.nu)) == sorted(hm.model.names[2:])
    assert not m.dof_damping.any() and not m.dof_armature.any() and not m.dof_frictionloss.any()
    np.testing.assert_array_equal(m.opt.gravity, [0.0, 0.0, -9.81])
    assert m.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC and m.opt.timestep == 1e-3


def test_only_sole_floor_collisions(mm) -> None:
    """Geom pairs MuJoCo may collide (contype/conaffinity rule, no explicit pairs): sole boxes x floor only."""
    m = mm.model
    assert m.npair == 0 and m.nexclude == 0
    soles = {g for pair in mm.sole_geoms.values() for g in pair}
    assert len(soles) == 4 and m.ngeom == 5
    for a in range(m.ngeom):
        for b in range(a + 1, m.ngeom):
            can = bool(m.geom_contype[a] & m.geom_conaffinity[b]) or bool(m.geom_contype[b] & m.geom_conaffinity[a])
            assert can == ({a, b} - soles == {mm.floor_geom} and len({a, b} & soles) == 1), (a, b)
    for g in soles:
        assert m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX and m.geom_friction[g][0] == 0.8
        assert m.geom_condim[g] == 3


def test_sole_boxes_in_the_world(hm: HumanoidModel, mm) -> None:
    """At the zero posture the boxes' bottom faces are the sole rectangle of the model YAML, on z = 0: compared
    with Pinocchio's placement of O_3 / O_4 and the SoleGeometry corners (independent of the URDF boxes)."""
    m = mm.model
    d = mujoco.MjData(m)
    q = hm.initial_q()
    smap = StateMap.from_models(hm, m)
    d.qpos[:] = smap.qpos_from_q(q)
    mujoco.mj_kinematics(m, d)
    data = hm.model.createData()
    pin.framesForwardKinematics(hm.model, data, q)
    sole = SoleGeometry.from_model(hm)
    for foot, k in (("R", 3), ("L", 4)):
        corners = []
        for g in mm.sole_geoms[foot]:
            R = d.geom_xmat[g].reshape(3, 3)
            half = m.geom_size[g]
            signs = np.array([[sx, sy, -1.0] for sx in (-1, 1) for sy in (-1, 1)])
            corners.append(d.geom_xpos[g] + (signs * half) @ R.T)
        corners = np.vstack(corners)
        bottom = corners[np.abs(corners[:, 2]) < 1e-9]
        assert len(bottom) == 8  # 1e-9 m: float round-off of the URDF's printed numbers; every corner on z = 0
        # Sole outline: heel to toe tip, full width, from Pinocchio's O_k and the YAML sole.
        M = data.oMf[hm.frame_id(f"O_{k}")]
        expect = sole.flat_corners() @ M.rotation.T + M.translation
        lo, hi = bottom.min(axis=0), bottom.max(axis=0)
        np.testing.assert_allclose(lo, expect.min(axis=0), atol=1e-12)
        np.testing.assert_allclose(hi, expect.max(axis=0), atol=1e-12)
        # 0.226 m x 0.09 m (Table 2.3 foot length; assumed width): the world frame has the feet along y.
        np.testing.assert_allclose(hi - lo, [0.09, 0.226, 0.0], atol=1e-12)


@pytest.fixture(params=["thesis", "variant"])
def models(request, hm: HumanoidModel, mm, variant_hm: HumanoidModel):
    """The thesis robot and a robot variant (tests/conftest.py VARIANT_DOC), each with its MuJoCo model."""
    return (hm, mm) if request.param == "thesis" else (variant_hm, build_model(variant_hm))


def test_mass_and_inertias(models) -> None:
    hm, mm = models
    m = mm.model
    # Real bodies as in the URDF; 14 virtual bodies at the 1e-13 bound.  1e-11 kg covers 14 bounds + round-off.
    assert abs(m.body_mass.sum() - pin.computeTotalMass(hm.model)) < 1e-11
    for b in range(1, m.nbody):
        name = m.body(b).name
        fid = hm.model.getFrameId(name, pin.FrameType.BODY)
        jid = hm.model.frames[fid].parentJoint
        I_pin = hm.model.inertias[jid]
        if I_pin.mass == 0.0:
            assert m.body_mass[b] <= 3 * VIRTUAL_BOUND
            continue
        R = pin.Quaternion(*m.body_iquat[b]).toRotationMatrix()
        I_mj = pin.Inertia(float(m.body_mass[b]), m.body_ipos[b].copy(), R @ np.diag(m.body_inertia[b]) @ R.T)
        # Body frames coincide with the joint frames (URDF link = child of its joint): compare directly.
        assert hm.model.frames[fid].placement.isIdentity()
        # 1e-12: MuJoCo's principal-axes decomposition and its 2e-13 kg mass bound.
        np.testing.assert_allclose(I_mj.toDynamicParameters(), I_pin.toDynamicParameters(), atol=1e-12,
                                   err_msg=name)


def test_mass_matrix_and_bias_agree_with_pinocchio(models) -> None:
    """At random states, through the StateMap: M_pin = T^T M_mj T and h_pin = T^T (h_mj + M_mj Tdot v); on the
    thesis robot and on a variant (the generated URDF read by both engines)."""
    hm, mm = models
    m = mm.model
    d = mujoco.MjData(m)
    smap = StateMap.from_models(hm, m)
    model, data = hm.model, hm.model.createData()
    rng = np.random.default_rng(15)
    for _ in range(5):
        q = pin.randomConfiguration(model, -np.pi * np.ones(model.nq), np.pi * np.ones(model.nq))
        q[:3] = rng.normal(size=3) + [0, 0, 3]  # in the air: no contact
        v = rng.normal(size=model.nv)
        d.qpos[:], d.qvel[:] = smap.qpos_from_q(q), smap.qvel_from_v(q, v)
        mujoco.mj_forward(m, d)
        assert d.ncon == 0
        T = np.column_stack([smap.qvel_from_v(q, e) for e in np.eye(model.nv)])  # qvel = T v
        M_mj = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M_mj)
        M_pin = pin.crba(model, data, q)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        # 1e-12 relative to the largest entry: double round-off in two recursions plus the virtual bodies'
        # 1e-13 kg / kg m^2 bounds, which Pinocchio does not have (measured 1.3e-13).
        scale = np.abs(M_pin).max()
        np.testing.assert_allclose(T.T @ M_mj @ T, M_pin, atol=1e-12 * scale, rtol=0)
        Tdot_v = np.zeros(m.nv)
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).normalized().toRotationMatrix()
        Tdot_v[:3] = R @ np.cross(v[3:6], v[:3])
        h_pin = pin.rnea(model, data, q, v, np.zeros(model.nv))
        h_mj = T.T @ (d.qfrc_bias + M_mj @ Tdot_v)
        np.testing.assert_allclose(h_mj, h_pin, atol=1e-12 * np.abs(h_pin).max(), rtol=0)  # measured 1.1e-13


def test_settings_are_validated() -> None:
    with pytest.raises(MujocoModelError, match=r"MujocoSettings.cone = 'round': expected one of"):
        MujocoSettings(cone="round")
    with pytest.raises(MujocoModelError, match=r"timestep = 0.05: expected a step in \(0, 0.01\] s"):
        MujocoSettings(timestep=0.05)
    with pytest.raises(MujocoModelError, match=r"solref = \(0.001, 1.0\): expected a time constant >= 2 timesteps"):
        MujocoSettings(solref=(0.001, 1.0))
    with pytest.raises(MujocoModelError, match=r"friction = -1"):
        MujocoSettings(friction=-1)
    with pytest.raises(MujocoModelError, match=r"solimp"):
        MujocoSettings(solimp=(0.99, 0.9, 0.001, 0.5, 2.0))
    with pytest.raises(MujocoModelError, match=r"unknown field\(s\) \['timestpe'\]"):
        MujocoSettings.from_scenario(type("S", (), {"contact": type("C", (), {"friction_coefficient": 0.5})})(),
                                     timestpe=0.001)


def test_friction_from_scenario(hm: HumanoidModel) -> None:
    scenario = type("S", (), {"contact": type("C", (), {"friction_coefficient": 0.5})})()
    mm = build_model(hm, MujocoSettings.from_scenario(scenario))
    for g in (g for pair in mm.sole_geoms.values() for g in pair):
        assert mm.model.geom_friction[g][0] == 0.5


def test_mismatched_sole_box_is_refused(hm: HumanoidModel, tmp_path: Path) -> None:
    """A URDF whose sole box differs from the model YAML's sole: a clear error naming the link."""
    text = hm.urdf_path.read_text()
    bad = text.replace('<box size="0.1517 0.09 0.045"/>', '<box size="0.1517 0.08 0.045"/>', 1)
    assert bad != text
    path = tmp_path / "bad.urdf"
    path.write_text(bad)
    hm_bad = load_model(path)
    with pytest.raises(MujocoModelError, match=r"bottom face of the sole box of link 'right_foot'"):
        build_model(hm_bad)
