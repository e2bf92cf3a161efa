"""A scenario's disturbances on the engines: a push's impulse against the robot's momentum, terrain boxes where they
were asked, sensing noise against its asked law, the actuation delay to the control period, and walks without the
section untouched."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from humanoid_sim.engines.mujoco.contact import sole_corners
from humanoid_sim.engines.mujoco.disturb import Pusher, terrain_boxes
from humanoid_sim.engines.mujoco.model import MujocoSettings, build_model
from humanoid_sim.engines.mujoco.sim import MujocoSim
from humanoid_sim.errors import InputError
from humanoid_sim.interfaces.controller import Command, Observation
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.robot.phases import Phase
from humanoid_sim.scenario.disturbances import Push, PushStart, Sensing, parse_disturbances
from humanoid_sim.scenario.schema import load_scenario
from humanoid_sim.sim.disturbances import Sensed
from humanoid_sim.sim.simulate import Simulator

ROOT = Path(__file__).resolve().parents[2]
SIM1 = ROOT / "scripts" / "params" / "sim1.yaml"


def _momentum(sim: MujocoSim) -> np.ndarray:
    """The whole robot's linear momentum (world, N s): total mass times the CoM velocity of the world's subtree."""
    mujoco.mj_forward(sim.model, sim.data)
    mujoco.mj_subtreeVel(sim.model, sim.data)
    return float(np.sum(sim.model.body_mass)) * sim.data.subtree_linvel[0].copy()


def _floating(hm: HumanoidModel, integrator: str) -> MujocoSim:
    """The robot 2 m above the ground, at rest, without gravity: nothing but a push changes its momentum."""
    sim = MujocoSim(hm, MujocoSettings(integrator=integrator))
    sim.model.opt.gravity[:] = 0.0
    q = hm.initial_q().copy()
    q[2] += 2.0
    sim.set_state(q, np.zeros(hm.model.nv))
    return sim


@pytest.mark.parametrize("body, start, duration", [(17, 0.0103, 0.1), ("O_17", 0.004, 0.0371), (12, 0.0, 0.05)])
def test_push_changes_the_momentum_by_its_impulse(hm: HumanoidModel, body, start, duration) -> None:
    """A push of impulse J (a window off the 2 ms control grid, at a CoM or at a point off it) changes the free
    robot's linear momentum by J: Newton's second law for the whole robot, whatever its joints do.  Integrated by
    RK4: the engine's semi-implicit Euler updates the velocities at each step's start configuration, a first-order
    momentum drift of the tumbling robot (8e-4 N s over these 0.2 s at dt = 1 ms, 2e-4 at 0.25 ms, measured) that
    would hide the push's own error."""
    sim = _floating(hm, "rk4")
    J = np.array([7.0, -4.0, 3.0])
    push = Push(body, tuple(J / duration), "world", PushStart(time_s=start), duration)
    pusher = Pusher(hm, sim.model, sim.data, [push], [], float(np.sum(sim.model.body_mass)), sim.mm.base_body)
    pusher.reset()
    p0 = _momentum(sim)
    assert np.all(np.abs(p0) < 1e-12)
    period, n_sub = 0.002, 2
    for i in range(100):                       # 0.2 s: the push and some free flight after it
        pusher.apply(i * period, period)
        sim.hold(np.zeros(hm.model.nv))
        sim.advance(n_sub)
    dp = _momentum(sim) - p0
    # 1e-9 N s: RK4's momentum error in free flight is O(dt^4), 1e-11 N s measured over these 0.2 s
    np.testing.assert_allclose(dp, J, atol=1e-9)
    rep = pusher.report()[0]
    assert rep["applied"] and rep["delta_v_mps"] == pytest.approx(np.linalg.norm(J) / 55.044, rel=1e-4)


def test_heading_push_turns_with_the_trunk(hm: HumanoidModel) -> None:
    """A heading-frame push [1, 0, 0] (forward) acts along the lower trunk's x axis projected on the ground: at the
    thesis's initial posture, world +y (the walk's forward direction)."""
    sim = _floating(hm, "euler")
    push = Push(17, (50.0, 0.0, 0.0), "heading", PushStart(time_s=0.0), 0.02)
    pusher = Pusher(hm, sim.model, sim.data, [push], [], 55.0, sim.mm.base_body)
    pusher.reset()
    pusher.apply(0.0, 0.002)
    F = sim.data.xfrc_applied[sim.mm.base_body, :3]
    R = sim.data.xmat[sim.mm.base_body].reshape(3, 3)
    fwd = np.array([R[0, 0], R[1, 0], 0.0]) / math.hypot(R[0, 0], R[1, 0])
    np.testing.assert_allclose(F, 50.0 * fwd, atol=1e-12)   # one rotation of exact numbers: round-off only
    np.testing.assert_allclose(fwd, [0.0, 1.0, 0.0], atol=1e-9)  # C0's x axis is world y (model YAML)


def test_phase_fraction_start_is_the_nominal_window(hm: HumanoidModel) -> None:
    """A push at {phase: k, fraction: f} starts at t_start + f (t_end - t_start) of the trajectory's k-th phase
    (numbered from 1), and the pushed walk reports that time and the world force."""
    sc = load_scenario(SIM1)
    dist = parse_disturbances("test", {"pushes": [
        {"impulse_Ns": 2.0, "direction_deg": 0, "start": {"phase": 2, "fraction": 0.25}, "duration_s": 0.02}]})
    sim = Simulator(hm, dataclasses.replace(sc, disturbances=dist), engine="mujoco")
    ph = sim.traj.phases[1]
    t0 = ph.t_start + 0.25 * (ph.t_end - ph.t_start)
    assert sim.engine.pusher.active[0].t0 == t0      # the same arithmetic on the same numbers: exact
    assert sim.run(t_end=0.02).extra["disturbances"]["pushes"][0] == {
        "body": 17, "frame": "heading", "given": "impulse_Ns", "start_s": t0, "duration_s": 0.02, "applied": False,
        "force_world_N": None, "impulse_world_Ns": None, "impulse_Ns": 2.0,
        "delta_v_mps": 2.0 / sim.engine.mm.total_mass}
    # the thesis gait falls within ~6 ms on real ground: a push in its first milliseconds, to see one applied
    dist = parse_disturbances("test", {"pushes": [
        {"impulse_Ns": 0.2, "direction_deg": 0, "start": {"phase": 1, "fraction": 0.001}, "duration_s": 0.002}]})
    sim = Simulator(hm, dataclasses.replace(sc, disturbances=dist), engine="mujoco")
    ph = sim.traj.phases[0]
    t0 = ph.t_start + 0.001 * (ph.t_end - ph.t_start)
    row = sim.run(t_end=0.004).extra["disturbances"]["pushes"][0]
    assert row["start_s"] == t0 and row["applied"]
    np.testing.assert_allclose(row["impulse_world_Ns"], [0.0, 0.2, 0.0], atol=1e-12)  # forward = world +y at C0


def test_phase_beyond_the_walk_is_refused(hm: HumanoidModel) -> None:
    sc = load_scenario(SIM1)
    dist = parse_disturbances("test", {"pushes": [
        {"force_N": [0, 10, 0], "start": {"phase": 99, "fraction": 0.5}, "duration_s": 0.1}]})
    with pytest.raises(InputError, match=r"pushes\[0\]\.start\.phase: expected a phase number in \[1, "):
        Simulator(hm, dataclasses.replace(sc, disturbances=dist), engine="mujoco")


@pytest.mark.parametrize("engine", ["pinocchio", "thesis"])
def test_pushes_and_terrain_refused_on_welds(hm: HumanoidModel, engine) -> None:
    sc = load_scenario(SIM1)
    for raw, key in (({"terrain": [{"kind": "tile", "centre": [0, 0.5, 0.005], "size": [0.2, 0.2, 0.01]}]},
                      "terrain"),
                     ({"pushes": [{"force_N": [0, 10, 0], "start": {"time_s": 1}, "duration_s": 0.1}]}, "pushes")):
        sc2 = dataclasses.replace(sc, disturbances=parse_disturbances("test", raw))
        with pytest.raises(InputError, match=rf"disturbances\.{key}: the '{engine}' engine welds the feet"):
            Simulator(hm, sc2, engine=engine)


def _ray_down(m: mujoco.MjModel, d: mujoco.MjData, x: float, y: float) -> tuple[float, int]:
    """Height of the first surface below (x, y, 1 m) and its geom id (mj_ray straight down)."""
    gid = np.array([-1], dtype=np.int32)
    dist = mujoco.mj_ray(m, d, np.array([x, y, 1.0]), np.array([0.0, 0.0, -1.0]), None, 1, -1, gid)
    return 1.0 - dist, int(gid[0])


def test_terrain_boxes_where_asked(hm: HumanoidModel) -> None:
    """A bar's top is where its centre and height put it; a slope's top face has the asked angle, rises along the
    asked direction and starts at the ground; both with the floor's contact parameters and their own friction."""
    dist = parse_disturbances("test", {"terrain": [
        {"kind": "bar", "centre": [0.3, 1.2, 0.005], "size": [0.6, 0.02, 0.01], "yaw_deg": 30, "friction": 0.4},
        {"kind": "slope", "centre": [2.0, 3.0], "size": [0.6, 0.8], "angle_deg": 3, "direction": "up"},
        {"kind": "slope", "centre": [-2.0, 3.0], "size": [0.6, 0.8], "angle_deg": 5, "direction": "sideways"}]})
    heading = math.pi / 2                            # the walk goes along +y
    mm = build_model(hm, terrain=terrain_boxes(dist.terrain, heading))
    m, d = mm.model, mujoco.MjData(mm.model)
    mujoco.mj_forward(m, d)
    bar, up, side = mm.terrain_geoms
    z, g = _ray_down(m, d, 0.3, 1.2)
    assert g == bar and z == pytest.approx(0.01, abs=1e-9)     # ray-box arithmetic: round-off
    z, g = _ray_down(m, d, 0.3 + 0.25 * math.cos(math.radians(30)), 1.2 + 0.25 * math.sin(math.radians(30)))
    assert g == bar        # along the bar's yawed axis, 0.25 m from its centre: still on it

    def plane(xs: list[tuple[float, float]]) -> np.ndarray:
        P = np.array([[x, y, _ray_down(m, d, x, y)[0]] for x, y in xs])
        n = np.cross(P[1] - P[0], P[2] - P[0])
        return n / n[2] * np.sign(n[2]) / np.linalg.norm(n / n[2])

    n = plane([(2.0, 2.9), (2.1, 3.1), (1.9, 3.1)])
    # 1e-9 rad: three ray hits on an exact plane, differences of 0.1 m: round-off only
    assert math.degrees(math.acos(n[2])) == pytest.approx(3.0, abs=1e-7)
    assert n[1] < 0 and abs(n[0]) < 1e-9            # rises along +y, the heading
    z_low, _ = _ray_down(m, d, 2.0, 3.0 - 0.3 + 1e-6)
    assert z_low == pytest.approx(0.0, abs=1e-6)      # its low edge at the ground (1e-6 m in from the edge)
    assert _ray_down(m, d, 2.0, 3.0)[0] == pytest.approx(0.3 * math.tan(math.radians(3)), abs=1e-9)
    n = plane([(-2.0, 2.9), (-1.9, 3.1), (-2.1, 3.1)])
    assert math.degrees(math.acos(n[2])) == pytest.approx(5.0, abs=1e-7)
    assert n[0] > 0 and abs(n[1]) < 1e-9            # rises toward the walk's left, -x when heading +y
    for gid, mu in ((bar, 0.4), (up, mm.settings.friction)):
        assert m.geom_friction[gid, 0] == mu and m.geom_priority[gid] > m.geom_priority[mm.sole_geoms["R"][0]]
        np.testing.assert_array_equal(m.geom_solref[gid], m.geom_solref[mm.floor_geom])
        np.testing.assert_array_equal(m.geom_solimp[gid], m.geom_solimp[mm.floor_geom])
        assert m.geom_conaffinity[gid] == 1 and m.geom_contype[gid] == 0


def _obs(t: float) -> Observation:
    return Observation(t, 0, Phase.RFFDSP, np.zeros(33), np.zeros(32), None, 0, 0.0)


def test_sensing_noise_has_the_asked_law_and_the_seed_reproduces() -> None:
    seen: list[Observation] = []

    def inner(obs: Observation) -> Command:
        seen.append(obs)
        return Command(np.zeros(32))

    s = Sensing(base_linear_velocity_mps=0.02, base_angular_velocity_radps=0.05, joint_position_rad=0.001,
                joint_velocity_radps=0.3, seed=7)
    n = 4000
    wrapped = Sensed(inner, s, 0.002)
    for i in range(n):
        wrapped(_obs(0.002 * i))
    V = np.array([o.v for o in seen])
    Q = np.array([o.q for o in seen])
    for x, sd in ((V[:, :3], 0.02), (V[:, 3:6], 0.05), (Q[:, 7:], 0.001), (V[:, 6:], 0.3)):
        k = x.size
        # the sample std of k Gaussian draws has relative standard error 1/sqrt(2k); 5 of them: a 1-in-1.7e6 miss
        assert np.std(x) == pytest.approx(sd, rel=5 / math.sqrt(2 * k))
        assert abs(np.mean(x)) < 5 * sd / math.sqrt(k)    # zero mean, the same 5-sigma bound
    assert np.all(Q[:, :7] == 0.0)                          # the base pose gets no noise
    again: list[Observation] = []
    w2 = Sensed(lambda o: (again.append(o), Command(np.zeros(32)))[1], s, 0.002)
    for i in range(50):
        w2(_obs(0.002 * i))
    np.testing.assert_array_equal(np.array([o.v for o in again]), V[:50])   # the same seed: the same draws


def test_foot_sensor_noise_has_the_asked_law_and_leaves_the_engines_wrench_alone() -> None:
    seen: list[Observation] = []
    s = Sensing(foot_force_N=5.0, foot_moment_Nm=0.5, seed=3)
    wrapped = Sensed(lambda o: (seen.append(o), Command(np.zeros(32)))[1], s, 0.002)
    true = np.arange(12.0).reshape(2, 6)
    n = 4000
    for i in range(n):
        wrapped(dataclasses.replace(_obs(0.002 * i), foot_wrenches=true))
    W = np.array([o.foot_wrenches for o in seen]) - true
    for x, sd in ((W[:, :, :3], 5.0), (W[:, :, 3:], 0.5)):
        k = x.size
        # as above: the sample std within 5 standard errors, the mean within 5 sigma / sqrt(k)
        assert np.std(x) == pytest.approx(sd, rel=5 / math.sqrt(2 * k))
        assert abs(np.mean(x)) < 5 * sd / math.sqrt(k)
    np.testing.assert_array_equal(true, np.arange(12.0).reshape(2, 6))     # the engine's array is not touched
    assert Sensed(lambda o: Command(np.zeros(32)), s, 0.002).observe(_obs(0.0)).foot_wrenches is None


def test_delay_lands_each_command_whole_periods_later() -> None:
    """The command applied at t is the one computed at t - d, d = delay_s rounded to control periods (0.0205 s at
    2 ms: 10 periods, 0.02 s); before that the first command."""
    def inner(obs: Observation) -> Command:
        return Command(np.full(32, obs.t))

    w = Sensed(inner, Sensing(delay_s=0.0205), 0.002)
    assert w.periods == 10
    t = 0.0
    for i in range(200):
        out = w(_obs(t))
        expected = max(i - 10, 0) * 0.002   # the command's time, computed on the same grid
        assert out.tau[0] == pytest.approx(expected, abs=1e-12), i   # times t + i h in floating point
        t += 0.002


class _TimeTorque:
    """A controller whose torque encodes its call's time: 0.01 N m per second on every joint (small: the robot
    barely moves in 0.06 s)."""

    name = "time_torque"
    control_period_s = 0.002

    def setup(self, ctx) -> None:
        self.calls: list[tuple[float, np.ndarray]] = []

    def __call__(self, obs: Observation) -> np.ndarray:
        tau = np.full(26, 0.01 * obs.t)
        self.calls.append((obs.t, tau))
        return tau


def test_delay_on_mujoco_applies_the_command_of_t_minus_d(hm: HumanoidModel) -> None:
    """On the MuJoCo engine, through the loop: the torque held at each control update t is exactly the controller's
    output at t - d (d = 5 periods of 2 ms)."""
    sc = load_scenario(SIM1)
    sc = dataclasses.replace(sc, disturbances=parse_disturbances("test", {"sensing": {"delay_s": 0.01}}))
    ctrl = _TimeTorque()
    res = Simulator(hm, sc, engine="mujoco", controller=ctrl).run(t_end=0.06)
    computed = dict((round(t, 9), tau) for t, tau in ctrl.calls)
    tr = res.trace.columns
    for t, tau in zip(tr["t"][::2], tr["tau"][::2]):       # each control update's first MuJoCo step
        src = max(round(t - 0.01, 9), 0.0)
        np.testing.assert_array_equal(tau[6:], computed[src])    # the same array: exact
    assert res.extra["disturbances"]["sensing"]["delay_periods"] == 5


def test_empty_section_leaves_the_walk_bit_for_bit(hm: HumanoidModel) -> None:
    """A ``disturbances`` section with nothing in it runs the walk the engine runs without one, to the bit; its
    summary entry lists nothing applied."""
    sc = load_scenario(SIM1)
    a = Simulator(hm, sc, engine="mujoco").run(t_end=0.2)
    b = Simulator(hm, dataclasses.replace(sc, disturbances=parse_disturbances("test", {})), engine="mujoco"
                  ).run(t_end=0.2)
    for k in ("q", "v", "tau", "foot_wrench"):
        np.testing.assert_array_equal(a.log.arrays()[k], b.log.arrays()[k])
    assert "disturbances" not in a.extra
    assert b.extra["disturbances"] == {"pushes": [], "terrain": [], "sensing": None}


def _turned_onto_slope(hm: HumanoidModel, a: float) -> tuple[MujocoSim, np.ndarray]:
    """The standing robot turned as one body by ``a`` (rad) about the world x axis, its soles pressed 1 mm into a
    slope box whose top face is the floor's plane turned the same way and lifted 0.5 m (the floor touches nothing);
    MuJoCo's forward pass done.  Returns the sim and the turn R (3 x 3)."""
    import pinocchio as pin

    R = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(a), -math.sin(a)], [0.0, math.sin(a), math.cos(a)]])
    lift = np.array([0.0, 0.0, 0.5])
    piece = parse_disturbances("test", {"terrain": [
        {"kind": "slope", "centre": [0.0, 0.0], "size": [2.0, 2.0], "angle_deg": math.degrees(a),
         "direction": "up"}]}).terrain[0]
    half = np.array([2.0, 2.0, 0.05])
    slope = dataclasses.replace(terrain_boxes([piece], 0.0)[0], centre=R @ np.array([0.0, 0.0, -half[2]]) + lift,
                                half=half, R=R)
    robot = MujocoSim(hm, MujocoSettings(), terrain=[slope])
    # the initial posture with its lowest sole corner 1 mm below the floor's plane, then turned and lifted
    q = hm.initial_q().copy()
    robot.set_state(q, np.zeros(hm.model.nv))
    mujoco.mj_forward(robot.model, robot.data)
    low = min(float(np.min(sole_corners(robot.mm, robot.data, f, box)[:, 2])) for f in "RL" for box in (0, 1))
    q[2] -= low + 0.001
    q[:3] = R @ q[:3] + lift
    x, y, z, w = q[3:7]
    turned = pin.Quaternion(R @ pin.Quaternion(w, x, y, z).toRotationMatrix())
    q[3:7] = turned.x, turned.y, turned.z, turned.w
    robot.set_state(q, np.zeros(hm.model.nv))
    mujoco.mj_forward(robot.model, robot.data)
    return robot, R


def test_a_foot_flat_on_a_slope_has_not_tipped(hm: HumanoidModel) -> None:
    """The fall test's tilt is read from the ground under the foot.  The standing robot is turned as one body by
    5 deg about the world x axis, its soles pressed 1 mm into a slope box whose top face is the floor's plane turned
    the same way: each sole is then 5 deg from the vertical (what the fall test read before: 'tipped' from 3 deg on)
    and level with the ground it stands on.  Without terrain the tilt is the vertical's, as before."""
    from humanoid_sim.engines.mujoco.contact import bearing_tilt, ground_normal, ground_slope, sole_tilt

    a = math.radians(5.0)
    robot, R = _turned_onto_slope(hm, a)
    assert ground_slope(build_model(hm)) == 0.0
    assert ground_slope(robot.mm) == pytest.approx(a, abs=1e-12)      # a unit quaternion's matrix: round-off
    mm, d = robot.mm, robot.data
    for foot in "RL":
        # the posture's soles are level to 1e-3 rad; the rest is the turn
        assert sole_tilt(mm, d, foot) == pytest.approx(a, abs=1e-3)
        np.testing.assert_allclose(ground_normal(mm, d, foot), R[:, 2], atol=1e-12)   # one geom's axis: round-off
        assert bearing_tilt(mm, d, foot, 300.0, 20.0) < 1e-3


def test_the_summary_tilts_are_read_from_the_ground_under_the_foot_on_terrain(hm: HumanoidModel) -> None:
    """summary.json's tilt maxima on terrain: a foot standing flat on a slope box has not tilted.  The robot of
    :func:`_turned_onto_slope` (5 deg) read by both ground meters with the left foot held flat: each loaded sole is
    5 deg from the vertical and both meters' maxima read under 1e-3 rad (the posture's soles are level to that), the
    compiled meter's equal to the reference's."""
    from humanoid_sim.engines.mujoco.contact import sole_tilt
    from humanoid_sim.engines.mujoco.ground import GroundMeter, ReferenceGroundMeter

    a = math.radians(5.0)
    robot, _ = _turned_onto_slope(hm, a)
    mm, d = robot.mm, robot.data
    assert all(sole_tilt(mm, d, f) == pytest.approx(a, abs=1e-3) for f in "RL")
    meters = [ReferenceGroundMeter(mm, 20.0, settling_s=0.0), GroundMeter(mm, 20.0, settling_s=0.0)]
    for m in meters:
        loaded = m.update(d, 1)
        assert loaded & 3 == 3            # both feet carry at least 20 N: both main boxes' tilts count
        assert 0.0 < m.tilt_max < 1e-3 and 0.0 < m.stance_tilt_max <= m.tilt_max
    assert meters[1].tilt_max == meters[0].tilt_max and meters[1].stance_tilt_max == meters[0].stance_tilt_max


def test_a_vector_in_the_ground_frame_keeps_its_angle_to_the_normal() -> None:
    """:func:`in_ground_frame`: the tilt form arctan2(hypot(x, y), z) of the result is the angle between the vector
    and the normal, against arccos of their dot product (well conditioned away from 0 and pi; 1e-12 rad covers
    round-off), for random unit vectors; the normal itself maps to +z."""
    from humanoid_sim.engines.mujoco.contact import in_ground_frame

    rng = np.random.default_rng(3)
    for _ in range(200):
        z, n = rng.normal(size=3), rng.normal(size=3)
        z /= np.linalg.norm(z)
        n /= np.linalg.norm(n)
        out = in_ground_frame(z, n)
        assert math.atan2(math.hypot(out[0], out[1]), out[2]) == pytest.approx(math.acos(float(z @ n)), abs=1e-12)
        np.testing.assert_allclose(in_ground_frame(n, n), [0.0, 0.0, 1.0], atol=1e-15)
