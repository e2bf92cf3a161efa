"""Ground reactions from MuJoCo's contact forces (issue 15): Newton-Euler checks against Pinocchio's centroidal
dynamics, finite differences, the centre of pressure and the slip / tilt measures."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.analysis.audit import convex_hull, signed_distance
from humanoid_sim.engines.mujoco import MujocoSettings, MujocoSim
from humanoid_sim.engines.mujoco.contact import SlipMeter, foot_contacts, sole_corners, sole_tilt
from humanoid_sim.engines.mujoco.standing import StandingController
from humanoid_sim.references.initial import initial_configuration
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.scenario.schema import load_scenario

G = np.array([0.0, 0.0, -9.81])
H = 1e-3  # MuJoCo timestep of the default settings, s


@pytest.fixture(scope="module")
def q0(hm: HumanoidModel) -> np.ndarray:
    return initial_configuration(hm, load_scenario("scripts/params/sim1.yaml").path)


@pytest.fixture(scope="module")
def drop_and_push(hm: HumanoidModel, q0: np.ndarray) -> list[dict]:
    """0.4 s: the initial posture released 5 mm above the ground under the standing PD (an impact on both feet),
    then from 0.2 s a 20 N forward push on the trunk.  Per step, the quantities MuJoCo integrates over that step:
    the controls are set, ``mj_forward`` evaluated, then ``mj_step`` (which recomputes the same forward)."""
    sim = MujocoSim(hm, MujocoSettings())
    ctrl = StandingController(hm, q0, H)
    m, d, smap = sim.model, sim.data, sim.map
    model, data = hm.model, hm.model.createData()
    q = q0.copy()
    q[2] += 0.005
    sim.set_state(q, np.zeros(model.nv))
    base = sim.mm.base_body
    rows = []
    for k in range(400):
        push = np.array([0.0, 20.0, 0.0]) if k >= 200 else np.zeros(3)
        d.xfrc_applied[base, :3] = push
        q, v = sim.state()
        d.ctrl[:] = smap.ctrl_from_tau(ctrl(q, v))
        mujoco.mj_forward(m, d)
        fw = foot_contacts(sim.mm, d)
        a = smap.a_from_qacc(q, v, d.qacc)
        pin.centerOfMass(model, data, q, v, a)
        com, vcom, acom = data.com[0].copy(), data.vcom[0].copy(), data.acom[0].copy()
        pin.computeCentroidalMomentumTimeVariation(model, data, q, v, a)
        rows.append({"fw": fw, "push": push, "push_at": d.xipos[base].copy(), "com": com, "vcom": vcom,
                     "acom": acom, "dhg_ang": data.dhg.angular.copy(), "v": v, "a": a})
        mujoco.mj_step(m, d)
    return rows


def test_newton_euler_exact_through_impact_and_push(hm: HumanoidModel, drop_and_push: list[dict]) -> None:
    """Sum of MuJoCo's foot wrenches (mj_contactForce, turned to the world frame) + gravity + push equals the
    rate of change of Pinocchio's centroidal momentum at MuJoCo's (q, v, qacc), every step."""
    mass = pin.computeTotalMass(hm.model)
    assert max(np.linalg.norm(r["fw"]["R"].force + r["fw"]["L"].force) for r in drop_and_push) > 1000  # impact
    for r in drop_and_push:
        F = r["fw"]["R"].force + r["fw"]["L"].force
        # 1e-8 N on forces up to ~1500 N: MuJoCo's qacc and constraint forces satisfy its equations to round-off,
        # Pinocchio's CoM acceleration agrees with its mass matrix to ~1e-13 (measured 3e-10 N).
        np.testing.assert_allclose(F + r["push"] + mass * G, mass * r["acom"], atol=1e-8, rtol=0)
        # Moments about the world origin: sum of moments = d/dt (angular momentum about O)
        #   = m c x a_c + dh_G/dt (angular momentum about the CoM).
        M = (r["fw"]["R"].moment + r["fw"]["L"].moment + np.cross(r["push_at"], r["push"])
             + np.cross(r["com"], mass * G))
        np.testing.assert_allclose(M, np.cross(r["com"], mass * r["acom"]) + r["dhg_ang"], atol=1e-8, rtol=0)


def test_newton_finite_differences(hm: HumanoidModel, drop_and_push: list[dict]) -> None:
    """m (vcom[k+1] - vcom[k]) / h = sum of forces at step k, with the CoM velocity from the states alone, through
    the impact and the push."""
    mass = pin.computeTotalMass(hm.model)
    # Bound: MuJoCo's semi-implicit Euler makes v[k+1] = v[k] + h a[k] exactly, and vcom = J_c(q) v.  Expanding
    # c(q) to second order, the forward difference differs from a_c[k] by
    #   d2c[v + h a, v + h a] - d2c[v, v] = 2 h d2c[v, a] + h^2 d2c[a, a],
    # with |d2c| <= L, the mass-weighted lever of the bodies about the joints, below 1 m for a 1.6 m robot:
    #   |residual| <= m L h (2 |v| |a| + h |a|^2),  L = 1 m.   (Measured at most 0.1 of it.)
    for k in range(len(drop_and_push) - 1):
        r, r1 = drop_and_push[k], drop_and_push[k + 1]
        F = r["fw"]["R"].force + r["fw"]["L"].force + r["push"] + mass * G
        nv, na = np.linalg.norm(r["v"]), np.linalg.norm(r["a"])
        bound = mass * 1.0 * H * (2 * nv * na + H * na**2) + 1e-8  # + the exact identity's round-off
        assert np.abs(mass * (r1["vcom"] - r["vcom"]) / H - F).max() <= bound, k


def test_cop_and_support_polygon(drop_and_push: list[dict]) -> None:
    """Each foot's CoP (from its moment about the origin) is the normal-force-weighted mean of its contact points,
    inside its sole; the whole CoP is inside the support polygon."""
    for r in drop_and_push[100:]:
        F = np.zeros(3)
        Mo = np.zeros(3)
        corners = []
        for foot in "RL":
            c = r["fw"][foot]
            assert c.normal > 0 and len(c.points) >= 4
            mean = (c.point_normal[:, None] * c.points).sum(axis=0) / c.point_normal.sum()
            # Contact points lie ~0.15 mm below z = 0 (half the penetration) and carry tangential forces of at
            # most 5 % of the normal: 1e-5 m covers the resulting CoP offset.
            np.testing.assert_allclose(c.cop[:2], mean[:2], atol=1e-5)
            F += c.force
            Mo += c.moment
            corners.append(c.points[:, :2])
        cop = np.array([-Mo[1] / F[2], Mo[0] / F[2]])
        hull = convex_hull(np.vstack(corners))
        assert signed_distance(cop, hull) > 0.01  # inside, by more than a centimetre
        for foot in "RL":
            own = convex_hull(r["fw"][foot].points[:, :2])
            assert signed_distance(r["fw"][foot].cop, own) > -1e-9  # 1e-9 m: round-off on the hull edge


def test_normal_forces_per_geom(drop_and_push: list[dict]) -> None:
    """Normal force per sole box: toe + main body = the foot's normal; the main body carries most of it."""
    for r in drop_and_push[100:200]:
        for foot in "RL":
            c = r["fw"][foot]
            assert c.normal_main > 5 * c.normal_toe >= 0
            # 1e-9 N: a sum of the same numbers in two orders; the contact frame's normal is +z on flat ground.
            assert abs(c.normal - c.force[2]) < 1e-9
            assert 0 < c.penetration < 1e-3


def test_no_contact_in_the_air(hm: HumanoidModel, q0: np.ndarray) -> None:
    sim = MujocoSim(hm)
    q = q0.copy()
    q[2] += 0.1
    sim.set_state(q, np.zeros(hm.model.nv))
    fw = sim.foot_wrenches()
    for foot in "RL":
        assert fw[foot].normal == 0.0 and np.all(fw[foot].force == 0.0) and np.all(np.isnan(fw[foot].cop))
        assert len(fw[foot].points) == 0


def test_slip_meter_and_tilt(hm: HumanoidModel, q0: np.ndarray) -> None:
    """SlipMeter against a known motion: the whole robot translated by 3 mm and turned by 0.01 rad about z."""
    sim = MujocoSim(hm)
    sim.set_state(q0, np.zeros(hm.model.nv))
    meter = SlipMeter()
    start = {f: sole_corners(sim.mm, sim.data, f) for f in "RL"}
    for f in "RL":
        meter.update(f, True, start[f])
        assert sole_tilt(sim.mm, sim.data, f) < 1e-12  # flat feet at the initial posture
    q = q0.copy()
    q[0] += 0.003
    R = pin.rpy.rpyToMatrix(0.0, 0.0, 0.01)
    M = pin.SE3(R, np.zeros(3)) * pin.XYZQUATToSE3(q[:7])
    q[:7] = pin.SE3ToXYZQUAT(M)
    sim.set_state(q, np.zeros(hm.model.nv))
    for f in "RL":
        corners = sole_corners(sim.mm, sim.data, f)
        # Translated by 3 mm along x, then turned about the world z axis (through the origin).
        expect = np.max(np.linalg.norm(((start[f] + [0.003, 0, 0]) @ R.T - start[f])[:, :2], axis=1))
        assert abs(meter.update(f, True, corners) - expect) < 1e-12
        assert meter.max_slip[f] == pytest.approx(expect, abs=1e-12)
        assert meter.update(f, False, corners) == 0.0 and meter.max_slip[f] == pytest.approx(expect, abs=1e-12)
    # Tilt: the robot pitched by 0.02 rad about x tilts both soles by 0.02 rad.
    q = q0.copy()
    M = pin.SE3(pin.rpy.rpyToMatrix(0.02, 0.0, 0.0), np.zeros(3)) * pin.XYZQUATToSE3(q[:7])
    q[:7] = pin.SE3ToXYZQUAT(M)
    sim.set_state(q, np.zeros(hm.model.nv))
    for f in "RL":
        assert sole_tilt(sim.mm, sim.data, f) == pytest.approx(0.02, abs=1e-12)


def test_sole_cop_names_the_edge(hm: HumanoidModel, q0: np.ndarray) -> None:
    """The robot rolled by 0.03 rad about the right sole's outer edge (world x = 0.205 m), sunk 0.1 mm: only that
    edge touches, and the CoP lies on it.  Flat on both feet, the CoP is inside, away from every edge."""
    from humanoid_sim.engines.mujoco.contact import sole_cop

    sim = MujocoSim(hm)
    pivot = np.array([0.16 + 0.045, 0.0, 0.0])
    R = pin.rpy.rpyToMatrix(0.0, 0.03, 0.0)
    M = pin.SE3(R, pivot - R @ pivot + [0.0, 0.0, -1e-4]) * pin.XYZQUATToSE3(q0[:7])
    q = q0.copy()
    q[:7] = pin.SE3ToXYZQUAT(M)
    sim.set_state(q, np.zeros(hm.model.nv))
    fw = sim.foot_wrenches()
    assert fw["L"].normal == 0.0 and sole_cop(sim.mm, sim.data, fw["L"]) is None
    np.testing.assert_allclose(fw["R"].points[:, 0], 0.205, atol=1e-6)  # all on the edge line (1 um: the sink)
    cop = sole_cop(sim.mm, sim.data, fw["R"])
    assert cop.edges == ("outer",) and abs(cop.margin) < 1e-4 and cop.xy[1] == pytest.approx(-0.045, abs=1e-4)
    sim.set_state(q0, np.zeros(hm.model.nv))
    sim.step(np.zeros(hm.model.nv), 0.002)
    for foot in "RL":
        cop = sole_cop(sim.mm, sim.data, sim.foot_wrenches()[foot])
        assert cop.edges == () and cop.margin > 0.01


# ---------------------------------------------------------------------------------------- the vectorised reads
def _dropped(hm: HumanoidModel, q0: np.ndarray, steps: int, cone: str = "elliptic") -> MujocoSim:
    """Sim 1's initial posture released 5 mm above the ground under the standing PD, after ``steps`` MuJoCo steps
    (the feet land at ~32 ms: step 35 is the impact, 60 its end, 300 standing)."""
    sim = MujocoSim(hm, MujocoSettings(cone=cone))
    ctrl = StandingController(hm, q0, H)
    q = q0.copy()
    q[2] += 0.005
    sim.set_state(q, np.zeros(hm.model.nv))
    for _ in range(steps):
        sim.step(ctrl(*sim.state()), H)
    sim.forward()
    return sim


def _per_contact(sim: MujocoSim) -> dict[str, dict]:
    """An independent read of the feet's ground reactions: per contact, mj_contactForce turned to the world frame
    with a matrix product and np.cross, in MuJoCo's contact order; per foot and box, the lists of normals."""
    m, d, mm = sim.model, sim.data, sim.mm
    out = {f: {"force": np.zeros(3), "moment": np.zeros(3), "normal": ([], []), "points": [], "pen": [],
               "point_normal": [], "point_geom": []} for f in "RL"}
    for i in range(d.ncon):
        c = d.contact[i]
        f6 = np.zeros(6)
        mujoco.mj_contactForce(m, d, i, f6)
        g1, g2 = (int(g) for g in c.geom)
        [(foot, box, g)] = [(f, b, g) for f in "RL" for b, g in enumerate(mm.sole_geoms[f]) if g in (g1, g2)]
        assert {g1, g2} == {g, mm.floor_geom}
        sign = 1.0 if g2 == g else -1.0        # the contact force acts on geom2
        R = c.frame.reshape(3, 3)              # rows: normal, tangents
        F = sign * (R.T @ f6[:3])
        o = out[foot]
        if o["points"]:
            o["force"] = o["force"] + F
            o["moment"] = o["moment"] + np.cross(c.pos, F) + sign * (R.T @ f6[3:])
        else:
            o["force"], o["moment"] = F, np.cross(c.pos, F) + sign * (R.T @ f6[3:])
        o["normal"][box].append(f6[0])
        o["point_normal"].append(f6[0])
        o["point_geom"].append(box)
        o["points"].append(c.pos.copy())
        o["pen"].append(-c.dist)
    return out


@pytest.mark.parametrize("cone", ["elliptic", "pyramidal"])
def test_contact_forces_are_mj_contactForce(hm: HumanoidModel, q0: np.ndarray, cone: str) -> None:
    """contact_forces (one gather from efc_force for an elliptic cone) = mj_contactForce per contact, to the bit,
    through the impact and standing, for all contacts and for a subset in another order."""
    from humanoid_sim.engines.mujoco.contact import contact_forces

    for steps in (35, 60, 300):
        sim = _dropped(hm, q0, steps, cone)
        m, d = sim.model, sim.data
        assert d.ncon >= 8
        expect = np.zeros((d.ncon, 6))
        for i in range(d.ncon):
            mujoco.mj_contactForce(m, d, i, expect[i])
        assert np.all(expect[:, 0] > 0) and np.any(expect[:, 1:3] != 0)   # loaded, with friction
        np.testing.assert_array_equal(contact_forces(m, d, np.arange(d.ncon)), expect)
        ids = np.array([d.ncon - 1, 0, 3])
        np.testing.assert_array_equal(contact_forces(m, d, ids), expect[ids])
        assert contact_forces(m, d, np.zeros(0, dtype=int)).shape == (0, 6)
    with pytest.raises(IndexError, match=r"expected indices in \[0, ncon"):
        contact_forces(m, d, np.array([d.ncon]))
    with pytest.raises(TypeError, match="1-d integer array"):
        contact_forces(m, d, np.array([0.0]))


@pytest.mark.parametrize("cone", ["elliptic", "pyramidal"])
def test_foot_contacts_and_loads_against_per_contact_reads(hm: HumanoidModel, q0: np.ndarray, cone: str) -> None:
    """foot_contacts against the per-contact read (_per_contact); foot_loads = foot_contacts' loads to the bit."""
    from humanoid_sim.engines.mujoco.contact import foot_loads

    for steps in (35, 60, 300):
        sim = _dropped(hm, q0, steps, cone)
        fw, loads, ref = foot_contacts(sim.mm, sim.data), foot_loads(sim.mm, sim.data), _per_contact(sim)
        for foot in "RL":
            c, r = fw[foot], ref[foot]
            # 1e-9 N and N m on forces and moments up to ~2000: the same terms summed in the same order; a matrix
            # product and np.cross may round the last bit differently from the vectorised rotation (1e-16 relative)
            np.testing.assert_allclose(c.force, r["force"], atol=1e-9, rtol=0)
            np.testing.assert_allclose(c.moment, r["moment"], atol=1e-9, rtol=0)
            np.testing.assert_array_equal(c.points, np.array(r["points"]))              # copies
            np.testing.assert_array_equal(c.point_normal, r["point_normal"])
            np.testing.assert_array_equal(c.point_geom, r["point_geom"])
            # each box's normal force: the same numbers in MuJoCo's order, summed left to right; numpy's sum of
            # fewer than 8 numbers (a box on a plane has at most 4 contacts) does the same, to the bit
            assert all(len(x) <= 4 for x in r["normal"])
            assert c.normal_toe == np.sum(r["normal"][0]) and c.normal_main == np.sum(r["normal"][1])
            assert c.penetration == max(0.0, max(r["pen"]))
            assert c.normal > 0 and c.penetration > 0
            load = loads[foot]
            assert (load.normal_toe, load.normal_main, load.penetration) == (c.normal_toe, c.normal_main,
                                                                              c.penetration)


def test_foot_contacts_with_the_sole_as_geom1(hm: HumanoidModel, q0: np.ndarray) -> None:
    """A sole-floor contact listed sole first (geom1; MuJoCo puts the plane first) acts on the foot with the
    opposite sign: with the pair and the contact frame both flipped, the feet's wrenches are unchanged."""
    sim = _dropped(hm, q0, 60)
    d = sim.data
    before = foot_contacts(sim.mm, d)
    flip = np.arange(0, d.ncon, 2)
    con = d.contact
    con.geom[flip] = con.geom[flip][:, ::-1].copy()
    con.frame[flip] = -con.frame[flip]
    after = foot_contacts(sim.mm, d)
    for foot in "RL":
        np.testing.assert_array_equal(after[foot].force, before[foot].force)      # -(-x): exact
        np.testing.assert_array_equal(after[foot].moment, before[foot].moment)
        np.testing.assert_array_equal(after[foot].point_normal, before[foot].point_normal)
        assert after[foot].normal == before[foot].normal


def test_cross_is_np_cross() -> None:
    """The row-wise cross product: the same products and differences as np.cross, to the bit."""
    from humanoid_sim.engines.mujoco.contact import _cross

    rng = np.random.default_rng(7)
    for k in (1, 4, 16):
        a, b = rng.normal(size=(k, 3)) * 100, rng.normal(size=(k, 3))
        np.testing.assert_array_equal(_cross(a, b), np.cross(a, b))


def test_slip_meter_is_the_norm_of_the_corner_travel() -> None:
    """SlipMeter's slip (in Python floats) is numpy's np.max(np.linalg.norm(travel[:, :2], axis=1)), to the bit:
    the same differences, squares, sum of two and square root."""
    rng = np.random.default_rng(11)
    meter = SlipMeter()
    start = rng.normal(size=(4, 3)) * 0.1
    meter.update("R", True, start)
    for scale in (1e-6, 1e-3, 1e-1):
        corners = start + rng.normal(size=(4, 3)) * scale
        assert meter.update("R", True, corners) == np.max(np.linalg.norm(corners[:, :2] - start[:, :2], axis=1))
