"""urdf_gen: deterministic output, validation errors, and agreement with third-party URDF consumers."""

from __future__ import annotations

import copy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from humanoid_sim.robot.model import DEFAULT_SPEC, DEFAULT_URDF, HumanoidModel
from urdf_gen import SpecError, emit_urdf, load_spec
from urdf_gen.spec import parse_spec

ROOT = Path(__file__).resolve().parents[2]


def test_committed_urdf_is_regenerated_byte_for_byte(tmp_path: Path) -> None:
    out = tmp_path / "thesis_humanoid.urdf"
    subprocess.run([sys.executable, "-m", "urdf_gen", str(DEFAULT_SPEC), "-o", str(out)], check=True, cwd=ROOT,
                   capture_output=True)
    assert out.read_bytes() == DEFAULT_URDF.read_bytes(), \
        ("models/thesis_humanoid.urdf is stale: run python -m urdf_gen models/thesis_humanoid.yaml "
         "-o models/thesis_humanoid.urdf")
    assert emit_urdf(load_spec(DEFAULT_SPEC)) == emit_urdf(load_spec(DEFAULT_SPEC))


def _doc() -> dict:
    return yaml.safe_load(DEFAULT_SPEC.read_text())


def _body(doc: dict, name: str) -> dict:
    return next(b for b in doc["bodies"] if b["name"] == name)


@pytest.mark.parametrize(
    "mutate, pattern",
    [
        (lambda d: _body(d, "right_thigh").__setitem__("mass", {"value": -5.213}),
         r"body right_thigh: mass must be a positive number of kg, got -5.213"),
        (lambda d: _body(d, "head").__setitem__("inertia", {"value": [0.023, -0.023, 0.015, 0, 0, 0]}),
         r"body head: inertia is not positive definite"),
        # B.2's misprint Jzz = 0.0012 (errata A-7) violates Jzz <= Jxx + Jyy = 0.00014.
        (lambda d: _body(d, "left_toe").__setitem__("inertia", {"value": [7e-5, 7e-5, 0.0012, 0, 0, 0]}),
         r"body left_toe: inertia violates the triangle inequality: principal moment 0.0012"),
        (lambda d: d["joints"][3].__setitem__("parent", "right_femur"),
         r"joints\[3\] \(theta11\): unknown parent 'right_femur'"),
        (lambda d: _body(d, "left_arm").__setitem__("name", "right_arm"),
         r"body right_arm \(id 24\): duplicate body name 'right_arm'"),
        (lambda d: _body(d, "right_foot").__setitem__("com", {"value": ["c3x", 0, "-c3q"]}),
         r"body right_foot \(id 3\): com\[2\]: unknown dimension 'c3q'"),
        (lambda d: d["joints"][0].__setitem__("axis", "w"), r"theta17r\): axis must be one of x, y, z, got 'w'"),
        (lambda d: d["actuators"]["neck"].__setitem__("limit", 0), r"actuators.neck.limit: expected a positive"),
    ],
)
def test_invalid_body_data_is_named(mutate, pattern: str) -> None:
    doc = copy.deepcopy(_doc())
    mutate(doc)
    with pytest.raises(SpecError, match=pattern):
        parse_spec(doc, "model.yaml")


def test_cli_reports_bad_input_with_exit_2(tmp_path: Path) -> None:
    doc = _doc()
    _body(doc, "head")["mass"] = {"value": -1.0}
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(doc))
    out = tmp_path / "out.urdf"
    r = subprocess.run([sys.executable, "-m", "urdf_gen", str(bad), "-o", str(out)], cwd=ROOT,
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert "body head: mass must be a positive number of kg, got -1.0" in r.stderr
    assert "Traceback" not in r.stderr
    assert not out.exists() and list(tmp_path.iterdir()) == [bad]  # nothing half-written


def test_yourdfpy_agrees_with_pinocchio(hm: HumanoidModel) -> None:
    import yourdfpy
    robot = yourdfpy.URDF.load(str(DEFAULT_URDF), load_meshes=False, build_scene_graph=False)
    model = hm.model
    for link in robot.robot.links:
        if link.inertial is None:
            continue
        fid = model.getFrameId(link.name, pin.FrameType.BODY)
        inertia = model.inertias[model.frames[fid].parentJoint]
        # A link with mass is the only massive body on its joint here, so masses match exactly.
        assert inertia.mass == pytest.approx(link.inertial.mass, abs=1e-15), link.name
        np.testing.assert_allclose(inertia.lever, link.inertial.origin[:3, 3], atol=1e-15, err_msg=link.name)
    n = 0
    for joint in robot.robot.joints:
        if joint.type != "revolute":
            continue
        jid = model.getJointId(joint.name)
        # Pinocchio's joint placement relative to its parent joint = URDF origin (composed through any fixed
        # parents; there are none between revolute joints here).
        np.testing.assert_allclose(model.jointPlacements[jid].homogeneous, joint.origin, atol=1e-15,
                                   err_msg=joint.name)
        assert model.joints[jid].shortname()[-1].lower() == "xyz"[int(np.argmax(joint.axis))]
        np.testing.assert_allclose(np.sort(joint.axis), [0, 0, 1], atol=0)  # a positive unit axis
        n += 1
    assert n == 26


def _mujoco_model():
    import mujoco
    spec = mujoco.MjSpec.from_file(str(DEFAULT_URDF))
    # The 14 virtual bodies are massless; MuJoCo refuses massless moving bodies, so it bounds them to a tiny
    # mass/inertia.  The pinocchio side is given exactly the same values for the comparison below.
    spec.compiler.boundmass = 1e-13
    spec.compiler.boundinertia = 1e-13
    spec.body("lower_trunk").add_freejoint()
    return mujoco, spec.compile()


def test_mass_matrix_and_bias_agree_with_mujoco(hm: HumanoidModel) -> None:
    mujoco, mj = _mujoco_model()
    md = mujoco.MjData(mj)
    model = hm.model.copy()
    # Same inertial data in both engines: copy MuJoCo's bounded virtual-body inertias into pinocchio, and check
    # the real bodies' inertias agree as loaded.
    for b in range(1, mj.nbody):
        name = mj.body(b).name
        fid = model.getFrameId(name, pin.FrameType.BODY)
        jid = model.frames[fid].parentJoint
        R = pin.Quaternion(*mj.body_iquat[b]).toRotationMatrix()  # MuJoCo quaternion is (w, x, y, z)
        I_mj = pin.Inertia(float(mj.body_mass[b]), mj.body_ipos[b].copy(), R @ np.diag(mj.body_inertia[b]) @ R.T)
        placement = model.frames[fid].placement
        I_local = placement.act(I_mj)
        if mj.body_mass[b] > 1e-6:
            # Same numbers from the same file: only round-off in MuJoCo's principal-axes decomposition differs.
            np.testing.assert_allclose(I_local.toDynamicParameters(), model.inertias[jid].toDynamicParameters(),
                                       atol=1e-15, err_msg=name)
        else:
            model.inertias[jid] = I_local
    data = model.createData()
    # Joint index maps: MuJoCo dofs by joint name.
    rng = np.random.default_rng(3)
    for _trial in range(5):
        q = pin.randomConfiguration(model, -np.pi * np.ones(model.nq), np.pi * np.ones(model.nq))
        q[:3] = rng.normal(size=3)
        v = rng.normal(size=model.nv)
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        # MuJoCo free joint: qpos = [p, (w,x,y,z)], qvel = [world linear velocity, local angular velocity].
        qpos = np.zeros(mj.nq)
        qvel = np.zeros(mj.nv)
        qpos[:3], qpos[3:7] = q[:3], [q[6], q[3], q[4], q[5]]
        T = np.eye(model.nv)  # v_mj = T v_pin
        T[:3, :3] = R
        perm = np.zeros(model.nv, dtype=int)
        perm[:6] = np.arange(6)
        for jid in range(2, model.njoints):
            mj_j = mj.joint(model.names[jid])
            qpos[mj_j.qposadr[0]] = q[model.idx_qs[jid]]
            perm[mj_j.dofadr[0]] = model.idx_vs[jid]
        P = np.eye(model.nv)[perm]  # rows: MuJoCo dof order
        Tfull = P @ T
        qvel = Tfull @ v
        md.qpos[:], md.qvel[:] = qpos, qvel
        mujoco.mj_forward(mj, md)
        M_mj = np.zeros((mj.nv, mj.nv))
        mujoco.mj_fullM(mj, md, M_mj)
        M_pin = pin.crba(model, data, q)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        M_from_mj = Tfull.T @ M_mj @ Tfull
        # 1e-8 relative to the largest entry: both engines are exact up to double round-off (~1e-13); this leaves
        # margin for the 1e-13 kg bounded virtual masses' different inertia frames.
        scale = np.abs(M_pin).max()
        np.testing.assert_allclose(M_from_mj, M_pin, atol=1e-8 * scale, rtol=0)
        # Bias: h_pin = T^T (h_mj + M_mj Tdot v), Tdot v = R (w x v_lin) on the linear base rows.
        Tdot_v = np.zeros(mj.nv)
        Tdot_v[:3] = R @ np.cross(v[3:6], v[:3])
        h_from_mj = Tfull.T @ (md.qfrc_bias + M_mj @ (P @ np.concatenate([Tdot_v[:6], np.zeros(model.nv - 6)])))
        h_pin = pin.rnea(model, data, q, v, np.zeros(model.nv))
        hscale = np.abs(h_pin).max()
        np.testing.assert_allclose(h_from_mj, h_pin, atol=1e-8 * hscale, rtol=0)
