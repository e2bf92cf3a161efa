"""The MuJoCo engine's compiled ground reads and trace rows (humanoid_sim.engines.mujoco.compiled, .ground, .trace)
against the NumPy reference path (humanoid_sim.engines.mujoco.contact, .ground.sole_friction, .trace.contact_record,
.state.StateMap), to rounding (ROUNDING) or to the bit, at every control update of a real walk on MuJoCo's ground,
and the engine's compiled and reference paths against each other (log, summary, falls)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import mujoco  # noqa: E402,F401
import numba  # noqa: E402,F401
import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.engines.mujoco import compiled as mjc  # noqa: E402
from humanoid_sim.engines.mujoco.contact import _tables, foot_loads, sole_tilt  # noqa: E402
from humanoid_sim.engines.mujoco.engine import MujocoEngine  # noqa: E402
from humanoid_sim.engines.mujoco.ground import (  # noqa: E402
    GroundMeter,
    ReferenceGroundMeter,
    end_loads,
    sole_friction,
    trunk_tilt,
)
from humanoid_sim.engines.mujoco.trace import TraceRecorder, contact_record  # noqa: E402
from humanoid_sim.robot.model import HumanoidModel  # noqa: E402
from humanoid_sim.robot.phases import Phase  # noqa: E402
from humanoid_sim.scenario.schema import load_scenario  # noqa: E402
from humanoid_sim.sim.simulate import Simulator  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def _zmp_scenario(name: str = "sim3_fast_zmp"):
    return load_scenario(ROOT / "scripts" / "params" / f"{name}.yaml")


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """The same shape and bits (NaN in the same places, +0.0 and -0.0 told apart)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


ROUNDING = 64 * np.finfo(float).eps
"""How far the compiled reads may differ from the NumPy path, relative to the largest entry of the arrays compared.
Both compute the same formulas; NumPy's vectorised products sum their terms in an order that depends on the NumPy
build (SIMD width), the compiled loops in the written order.  A sum of n terms reordered differs by at most ~n eps
of its largest term; the sums here have up to ~30 terms (64 eps).  A wrong formula, index or frame differs by
orders of magnitude more (the smallest such error is a whole term, >= 1e-9 of the scale)."""


def _close(a: np.ndarray, b: np.ndarray, scale: float = 0.0) -> bool:
    """The same shape and NaNs, and every other entry within :data:`ROUNDING` of the arrays' largest magnitude (or of
    ``scale``, when larger: the magnitude of the terms a small difference like a residual is made of)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.shape != b.shape or not np.array_equal(np.isnan(a), np.isnan(b)):
        return False
    ok = ~np.isnan(a)
    if not ok.any():
        return True
    scale = max(float(np.max(np.abs(a[ok]))), float(np.max(np.abs(b[ok]))), scale, np.finfo(float).tiny)
    return bool(np.all(np.abs(a[ok] - b[ok]) <= ROUNDING * scale))


def _split(w: np.ndarray) -> tuple[np.ndarray, ...]:
    """compiled.contact_wrenches' flat output as (fw, cop, bf, bm)."""
    return w[:12].reshape(2, 6), w[12:18].reshape(2, 3), w[18:30].reshape(4, 3), w[30:].reshape(4, 3)


def _wrenches(eng: MujocoEngine, compiled: bool) -> tuple[np.ndarray, ...]:
    """The record's (fw, cop, bf, bm) at the engine's current MuJoCo data, by the kernel or the NumPy path."""
    d = eng.sim.data
    if compiled:
        con, w = d.contact, np.full(mjc.WRENCH_FLOATS, 7.0)
        assert mjc.contact_wrenches(con.geom, con.pos, con.frame, con.dim, con.efc_address, d.efc_force,
                                    _tables(eng.mm).pair_array, eng.mm.floor_geom, eng.recorder.bodies, d.xipos,
                                    d.xmat, w)
        return _split(w)
    out = (np.full((2, 6), 7.0), np.full((2, 3), 7.0), np.full((4, 3), 7.0), np.full((4, 3), 7.0))
    contact_record(eng.mm, d, *out)
    return out


def _friction(eng: MujocoEngine) -> np.ndarray:
    """compiled.sole_friction at the engine's current MuJoCo data, (2, 3)."""
    d, con, out = eng.sim.data, eng.sim.data.contact, np.full(6, 7.0)
    assert mjc.sole_friction(con.geom, con.dim, con.efc_address, con.friction, d.efc_force, d.efc_vel,
                             _tables(eng.mm).pair_array, out, 0)
    return out.reshape(2, 3)


@pytest.fixture(scope="module")
def walk_reads(hm: HumanoidModel) -> dict:
    """The first 1.6 s of the 1.5x zmp walk on MuJoCo (lead-in, a double support, single supports, touchdowns:
    ~800 control updates), comparing at every control update the compiled reads with the NumPy ones; two
    compiled meters (a chunk of 7 updates, so that supports span chunks, and the default) and the reference meter
    read the same states.  Returns what the comparisons found."""
    sc = _zmp_scenario()
    sim = Simulator(hm, sc, engine="mujoco")
    eng = sim.engine
    assert eng.compiled
    meters = {"chunk7": GroundMeter(eng.mm, eng.settings.contact_force_N, chunk=7),
              "default": GroundMeter(eng.mm, eng.settings.contact_force_N)}
    ref = ReferenceGroundMeter(eng.mm, eng.settings.contact_force_N)
    pdata = hm.model.createData()
    found = {"updates": 0, "wrench_mismatch": [], "load_mismatch": [], "meter_mismatch": [], "tilt_gap": 0.0,
             "state_mismatch": [], "friction_mismatch": [],
             "mid_run": [], "loaded": set(), "stance": set(), "supports": 0, "sliding": 0}
    # trace rows of the same MuJoCo steps by the compiled writer and by NumPy (one control update: zero torques)
    recorders = {flag: TraceRecorder(eng.sim, eng.act, flag, flag) for flag in (True, False)}
    for r in recorders.values():
        r.control(np.zeros(hm.model.nv), None, None, None)
    found["recorders"] = recorders
    measure = eng._measure

    def checked(t: float) -> bool:
        d = eng.sim.data
        found["updates"] += 1
        if not all(_close(a, b) for a, b in zip(_wrenches(eng, True), _wrenches(eng, False))):
            found["wrench_mismatch"].append(t)
        loads, ref_loads = np.zeros(6), np.zeros(6)
        end_loads(eng.mm, d, loads, True)
        end_loads(eng.mm, d, ref_loads, False)
        if not _close(loads, ref_loads):
            found["load_mismatch"].append(t)
        friction = np.array(sole_friction(eng.mm, d))
        if not _same(_friction(eng), friction):
            found["friction_mismatch"].append(t)
        found["sliding"] += int(any(fn >= 20.0 and use >= 1 - 1e-4 for fn, use, _ in friction))
        for r in recorders.values():
            r.row(t, found["updates"], 3)
        smap = eng.map
        q, v = mjc.pin_state(d.qpos, d.qvel, smap.q_gather, smap.v_gather)
        qpos = d.qpos.copy()
        a = smap.a_from_qacc(q, v, d.qacc)
        tau = smap.tau_from_ctrl(d.ctrl)
        rnea = pin.rnea(hm.model, pdata, q, v, a)
        if not (_close(q, smap.q_from_qpos(qpos)) and _close(v, smap.v_from_qvel(qpos, d.qvel))
                and _close(mjc.pin_acceleration(q, v, d.qacc, smap.v_gather), a)
                and _close(mjc.dynamics_residual(rnea, tau, q, d.qfrc_constraint, smap.v_gather),
                           float(np.max(np.abs(rnea - tau - smap.tau_from_qfrc(q, d.qfrc_constraint)))),
                           float(np.max(np.abs(rnea))))):
            found["state_mismatch"].append(t)
        stance = {None: -1, "R": 0, "L": 1}[eng.phase.support_foot]
        r = ref.update(d, stance)
        for m in meters.values():
            if m.update(d, stance) & 3 != r & 3 or not _close(m.out[:7], ref.out[:7]) or m.out[10] != ref.out[10] \
                    or not _same(m.out[11:], ref.out[11:]):
                found["meter_mismatch"].append(t)
            found["tilt_gap"] = max(found["tilt_gap"], float(np.max(np.abs(m.out[7:10] - ref.out[7:10]))))
        found["loaded"].add(r & 3)
        found["stance"].add(stance)
        if found["updates"] % 101 == 0:      # read the maxima mid-run too (a reduction of a partial chunk)
            found["mid_run"].append([(m.slip_max, m.tilt_max, m.stance_tilt_max, m.penetration_max)
                                     for m in meters.values()]
                                    + [(ref.slip_max, ref.tilt_max, ref.stance_tilt_max, ref.penetration_max)])
        return measure(t)

    eng._measure = checked
    res = sim.run(t_end=1.6)
    assert res.reason.startswith("stopped at t = 1.600"), res.reason
    found["final"] = [(m.slip_max, m.tilt_max, m.stance_tilt_max, m.penetration_max) for m in meters.values()] \
        + [(ref.slip_max, ref.tilt_max, ref.stance_tilt_max, ref.penetration_max)]
    found["supports"] = sum(len(m.max_slip) for f in "RL" for m in ref.slip[f])
    return found


def test_contact_wrenches_are_the_numpy_path_to_rounding(walk_reads: dict) -> None:
    """compiled.contact_wrenches = foot_contacts + _body_wrenches (foot wrench, CoP, body force and moment), and
    compiled.contact_loads = foot_loads, to rounding (:data:`ROUNDING`) at every control update of the walk."""
    assert walk_reads["updates"] > 700
    assert walk_reads["wrench_mismatch"] == [] and walk_reads["load_mismatch"] == []


def test_friction_is_sole_friction(walk_reads: dict) -> None:
    """compiled.sole_friction = ground.sole_friction (per foot: normal force, cone use, slip speed) to the bit at every
    control update of the walk, sliding updates among them (their slip speeds feed the summary's sliding events)."""
    assert walk_reads["friction_mismatch"] == []
    assert walk_reads["sliding"] > 0


def test_trace_rows_are_the_numpy_rows(walk_reads: dict) -> None:
    """compiled.trace_row = TraceRecorder's NumPy row at every control update of the walk: the time, indices and
    MuJoCo's state and acceleration to the bit, the wrenches to rounding (:data:`ROUNDING`); and the built traces
    (compiled.pin_trajectory against StateMap's maps row by row) to rounding, the torques to the bit."""
    rec = walk_reads["recorders"]
    fast, ref = rec[True]._rows.array(), rec[False]._rows.array()
    assert len(fast) == walk_reads["updates"] and fast.shape == ref.shape
    w = rec[True].cols["fw"].start
    assert _same(fast[:, :w], ref[:, :w])
    assert all(_close(a, b) for a, b in zip(fast[:, w:], ref[:, w:]))
    tf, tr = rec[True].build(), rec[False].build()
    assert tf is not None and tr is not None and sorted(tf.columns) == sorted(tr.columns)
    for k in ("q", "v", "a", "foot_wrench", "cop", "body_force", "body_moment", "zmp"):
        assert all(_close(a, b) for a, b in zip(tf.columns[k], tr.columns[k])), k
    for k in ("t", "phase", "basic_phase", "tau", "saturated", "in_contact"):
        assert _same(tf.columns[k], tr.columns[k]), k


def test_pin_trajectory_is_pin_state_and_acceleration(hm: HumanoidModel) -> None:
    """compiled.pin_trajectory over rows = pin_state then pin_acceleration row by row, to the bit (random unit
    quaternions, velocities and accelerations, zeros of both signs among them), on a row block with other columns
    around the state's."""
    from humanoid_sim.engines.mujoco import MujocoSim

    smap = MujocoSim(hm).map
    rng = np.random.default_rng(11)
    n, at = 300, 4
    rows = rng.normal(size=(n, at + smap.nq + 2 * smap.nv + 5))
    quat = rng.normal(size=(n, 4))
    rows[:, at + 3:at + 7] = quat / np.linalg.norm(quat, axis=1)[:, None]
    rows[::7, at + smap.nq:] = -0.0
    Q, V, A = mjc.pin_trajectory(rows, at, at + smap.nq, at + smap.nq + smap.nv, smap.nq, smap.nv, smap.q_gather,
                                 smap.v_gather)
    for i in range(n):
        qpos, qvel = rows[i, at:at + smap.nq], rows[i, at + smap.nq:at + smap.nq + smap.nv]
        q, v = mjc.pin_state(qpos, qvel, smap.q_gather, smap.v_gather)
        a = mjc.pin_acceleration(q, v, rows[i, at + smap.nq + smap.nv:at + smap.nq + 2 * smap.nv], smap.v_gather)
        assert _same(Q[i], q) and _same(V[i], v) and _same(A[i], a)


def test_py_hypot_is_math_hypot() -> None:
    """compiled.py_hypot = Python's math.hypot to the bit: random pairs over the whole range of magnitudes and
    ratios (subnormals included), zeros of both signs, infinities and NaN."""
    rng = np.random.default_rng(7)
    pairs = []
    for scale in (1e-310, 1e-300, 1e-160, 1e-8, 1e-3, 1.0, 1e3, 1e150, 1e300):
        x = rng.normal(size=4000) * scale
        y = x * rng.choice([1.0, 0.5, 1e-3, 1e-9, 1e-17, 1e-30], size=4000) * rng.normal(size=4000)
        pairs += list(zip(x.tolist(), y.tolist()))
    special = [0.0, -0.0, 1.0, -2.5, math.inf, -math.inf, math.nan, 5e-324, 1.7976931348623157e308]
    pairs += [(a, b) for a in special for b in special]
    for x, y in pairs:
        got, want = mjc.py_hypot(x, y), math.hypot(x, y)
        assert got == want or (math.isnan(got) and math.isnan(want)), (x, y, got, want)


def test_state_maps_are_the_numpy_path_to_rounding(walk_reads: dict) -> None:
    """compiled.pin_state = StateMap.q_from_qpos / v_from_qvel, pin_acceleration = a_from_qacc, dynamics_residual =
    NumPy's max |rnea - tau - tau_from_qfrc|, to rounding (:data:`ROUNDING`) at every control update of the walk."""
    assert walk_reads["state_mismatch"] == []


def test_state_maps_at_random_states(hm: HumanoidModel) -> None:
    """The compiled state maps against StateMap's at random base orientations (unit quaternions scaled by up to
    1e-9, as MuJoCo's normalised ones are) and velocities, zero and negative-zero velocities included (their
    signs of zero too); put_ctrl = ctrl_from_tau, and it refuses a non-finite torque without writing."""
    from humanoid_sim.engines.mujoco import MujocoSim

    smap = MujocoSim(hm).map
    rng = np.random.default_rng(5)
    for k in range(2000):
        quat = rng.normal(size=4)
        quat *= (1.0 + rng.uniform(-1e-9, 1e-9)) / np.linalg.norm(quat)
        qpos, qvel, qacc, qfrc = (rng.normal(size=n) for n in (smap.nq, smap.nv, smap.nv, smap.nv))
        qpos[3:7] = quat
        if k % 3 == 0:
            qvel[:] = -0.0 if k % 2 else 0.0
        q, v = mjc.pin_state(qpos, qvel, smap.q_gather, smap.v_gather)
        # equal to rounding (see ROUNDING)
        assert _close(q, smap.q_from_qpos(qpos)) and _close(v, smap.v_from_qvel(qpos, qvel))
        assert _close(mjc.pin_acceleration(q, v, qacc, smap.v_gather), smap.a_from_qacc(q, v, qacc))
        rnea, tau = rng.normal(size=smap.nv), rng.normal(size=smap.nv)
        assert _close(mjc.dynamics_residual(rnea, tau, q, qfrc, smap.v_gather),
                     float(np.max(np.abs(rnea - tau - smap.tau_from_qfrc(q, qfrc)))))
        ctrl = np.full(smap.nu, 7.0)
        assert mjc.put_ctrl(tau, smap.ctrl_gather, ctrl) and _same(ctrl, smap.ctrl_from_tau(tau))
    tau[10] = np.nan
    ctrl = np.full(smap.nu, 7.0)
    assert not mjc.put_ctrl(tau, smap.ctrl_gather, ctrl) and (ctrl == 7.0).all()
    assert not mjc.all_finite(tau) and mjc.all_finite(ctrl)
    rnea[4] = np.nan
    assert math.isnan(mjc.dynamics_residual(rnea, tau, q, qfrc, smap.v_gather))


def test_ground_meter_is_the_reference_meter(walk_reads: dict) -> None:
    """GroundMeter (compiled reads, maxima reduced in batches) = ReferenceGroundMeter (NumPy at every update): the
    loaded feet, loads and penetration at every update, and the slip / tilt / penetration maxima, read mid-run
    and at the end, to the bit, whatever the batch size.  The fall tests' tilts are libm's: within 1e-15 rad of
    NumPy's (both are within an ulp or two of the true angle; 1e-15 is ~10 ulp at the trunk's ~0.1 rad)."""
    w = walk_reads
    assert w["meter_mismatch"] == []
    assert w["tilt_gap"] <= 1e-15, w["tilt_gap"]
    for row in w["mid_run"] + [w["final"]]:
        assert row[0] == row[1] == row[2], row
    slip, tilt, stance_tilt, pen = w["final"][-1]
    assert slip > 0 and tilt > 0 and stance_tilt > 0 and pen > 0       # every measure was exercised
    # the walk had both feet alone and together on the ground, and a stance foot each side
    assert {1, 2, 3} <= w["loaded"] and {0, 1} <= w["stance"]


def test_slip_reduce_is_slip_meter() -> None:
    """compiled.slip_reduce over buffers of random sizes = one SlipMeter per box fed row by row, to the bit: random
    supports (single rows, gaps, supports running across buffers, a buffer without any) and corner travels."""
    from humanoid_sim.engines.mujoco.contact import SlipMeter

    rng = np.random.default_rng(3)
    meters = [SlipMeter() for _ in range(4)]
    last, anchor, slip = np.full(4, -2, dtype=np.intp), np.zeros((4, 4, 3)), np.zeros(4)
    for size in rng.integers(1, 12, 60):
        on = rng.random((size, 4)) < rng.choice([0.0, 0.5, 0.9])
        corners = rng.normal(size=(size, 4, 4, 3)) * rng.choice([1e-6, 1e-3, 0.1])
        for r in range(size):
            for b in range(4):
                meters[b].update("R", bool(on[r, b]), corners[r, b])
        row, box = np.nonzero(on)
        mjc.slip_reduce(corners[row, box], row, box, int(size), last, anchor, slip)
        assert slip.tolist() == [m.max_slip["R"] for m in meters]
    assert (slip > 0).all()


def test_contact_wrenches_with_the_sole_as_geom1_and_fallback(hm: HumanoidModel) -> None:
    """A sole-floor contact listed sole first acts on the foot with the opposite sign (the kernel = the NumPy path
    to the bit, as contact.foot_contacts' own test flips them); contacts the kernel does not read (no constraint
    rows, or mixed dims) make it return False and write nothing."""
    sc = load_scenario(ROOT / "scripts" / "params" / "sim1.yaml")
    eng = MujocoEngine(hm, sc)
    eng.start(Simulator(hm, sc, engine="mujoco").q0, Phase.RFFDSP)
    for _ in range(60):
        eng.sim.hold(np.zeros(32))
        eng.sim.advance(1)
    d = eng.sim.data
    assert d.ncon >= 4
    con = d.contact
    flip = np.arange(0, d.ncon, 2)
    con.geom[flip] = con.geom[flip][:, ::-1].copy()
    con.frame[flip] = -con.frame[flip]
    for a, b in zip(_wrenches(eng, True), _wrenches(eng, False)):
        assert _close(a, b)
    w = np.full(mjc.WRENCH_FLOATS, 7.0)
    args = lambda adr, dim: (con.geom, con.pos, con.frame, dim, adr, d.efc_force,  # noqa: E731
                             _tables(eng.mm).pair_array, eng.mm.floor_geom, eng.recorder.bodies, d.xipos, d.xmat)
    adr = con.efc_address.copy()
    adr[1] = -1
    assert not mjc.contact_wrenches(*args(adr, con.dim), w)
    dim = con.dim.copy()
    dim[1] = 1
    assert not mjc.contact_wrenches(*args(con.efc_address, dim), w)
    assert (w == 7.0).all()
    # the friction reader declines the contacts it does not read (another dim, no positive coefficient) the same way
    out = np.full(6, 7.0)
    dim = con.dim.copy()
    dim[1] = 4
    assert not mjc.sole_friction(con.geom, dim, con.efc_address, con.friction, d.efc_force, d.efc_vel,
                                 _tables(eng.mm).pair_array, out, 0)
    mu = con.friction.copy()
    mu[1, 0] = 0.0
    assert not mjc.sole_friction(con.geom, con.dim, con.efc_address, mu, d.efc_force, d.efc_vel,
                                 _tables(eng.mm).pair_array, out, 0)
    assert (out == 7.0).all()


@pytest.mark.slow
def test_engine_paths_give_the_same_walk(hm: HumanoidModel) -> None:
    """The engine's compiled path and its NumPy reference path: the same log and the same ground summary over 1.2 s
    of the 1.5x zmp walk.  The state maps differ in the last bit (Eigen's and NumPy's rounding, see
    :data:`ROUNDING`), and the controller and MuJoCo's contact solver carry such a difference on: under the DCM
    feedback (the balance controller's default) it grows to ~5e-9 of an array's largest magnitude over the 1.2 s
    (measured), so each array is compared to 1e-7 of its own largest magnitude: a formula difference (a wrong sign,
    index or threshold) shows at 1e-3 and more."""
    sc = _zmp_scenario()
    runs = {}
    for flag in (None, False):
        sim = Simulator(hm, sc, engine="mujoco")
        sim.engine = MujocoEngine(hm, sc, sim.traj, compiled=flag)
        runs[flag] = (sim.run(t_end=1.2), sim.engine)
    (r1, e1), (r0, e0) = runs[None], runs[False]
    assert e1.compiled and not e0.compiled
    a1, a0 = r1.log.arrays(), r0.log.arrays()
    assert sorted(a1) == sorted(a0)
    def close(x, y, scale: float | None = None) -> bool:
        x, y = np.asarray(x), np.asarray(y)
        if x.dtype.kind not in "fc":
            return np.array_equal(x, y)
        if scale is None:
            scale = float(np.nanmax(np.abs(y))) if np.isfinite(y).any() else 0.0
        return x.shape == y.shape and bool(np.allclose(x, y, rtol=0, atol=1e-7 * max(scale, 1e-300), equal_nan=True))

    # the dynamics residual is a difference of joint torques (|rnea - tau - J^T f|): judged on the torques' scale
    scales = {"dynamics_residual": float(np.max(np.abs(a0["tau"])))}
    assert [k for k in a1 if not close(a1[k], a0[k], scales.get(k))] == []
    g1, g0 = r1.extra["ground"], r0.extra["ground"]

    def same(x, y) -> bool:   # the ground report nests mappings and lists (settling, sliding events)
        if isinstance(y, dict):
            return isinstance(x, dict) and sorted(x) == sorted(y) and all(same(x[k], y[k]) for k in y)
        if isinstance(y, list):
            return isinstance(x, list) and len(x) == len(y) and all(same(a, b) for a, b in zip(x, y))
        return close(x, y) if isinstance(y, float) else x == y

    assert same(g1, g0)


def test_pyramidal_cone_takes_the_reference_path(hm: HumanoidModel) -> None:
    """The kernels read an elliptic cone's normal forces; with a pyramidal cone the engine reads the NumPy way."""
    from humanoid_sim.engines.mujoco import MujocoSettings

    sc = load_scenario(ROOT / "scripts" / "params" / "sim1.yaml")
    eng = MujocoEngine(hm, sc, contact=replace(MujocoSettings.from_scenario(sc), cone="pyramidal"))
    assert not eng.compiled and isinstance(eng.ground, ReferenceGroundMeter)
    with pytest.raises(ValueError, match="elliptic"):
        GroundMeter(eng.mm, 20.0)


class _Limp:
    """A controller that applies no torque: the robot collapses."""

    name = "limp"

    def setup(self, ctx) -> None:
        self.nv = ctx.hm.model.nv

    def __call__(self, obs):
        return np.zeros(self.nv)


def test_trunk_fall_is_the_same_on_both_paths(hm: HumanoidModel) -> None:
    """A limp robot dropped onto both feet sags; with a 0.05 rad trunk limit its trunk tilts too far before its hip
    sinks below the fall height.  Both paths find the fall at the same control update with the same message (the
    compiled path's libm tilt is checked again with NumPy near the threshold)."""
    from humanoid_sim.sim.loop import run

    sc = load_scenario(ROOT / "scripts" / "params" / "sim1.yaml")
    found = {}
    for flag in (None, False):
        sim = Simulator(hm, sc, engine="mujoco", controller=_Limp())
        eng = MujocoEngine(hm, sc, sim.traj, compiled=flag, trunk_tilt_fall_rad=0.05)
        r = run(eng, sim.controller, sim.traj, sc, sim.q0, t_end=2.0, hold=Phase.RFFDSP)
        found[flag] = (r.reason, r.extra["ground"])
    assert found[None] == found[False]
    assert "lower trunk tilted" in found[None][0] and found[None][1]["fell"], found[None]


@pytest.mark.parametrize("compiled", [None, False])
def test_fall_thresholds(hm: HumanoidModel, compiled: bool | None) -> None:
    """At a state of the sagging limp robot, the fall tests decide at their thresholds as NumPy's numbers say: the
    trunk's tilt (trunk_tilt: a limit at its value is not a fall, one ulp below it is, also where libm's tilt of
    the compiled path differs in the last bit) and the hip CoM height (a fall height at it is not a fall, one ulp
    above it is)."""
    sc = load_scenario(ROOT / "scripts" / "params" / "sim1.yaml")
    sim = Simulator(hm, sc, engine="mujoco", controller=_Limp())
    eng = MujocoEngine(hm, sc, sim.traj, compiled=compiled)
    eng.start(sim.q0, Phase.RFFDSP)
    for _ in range(150):                  # the limp robot sags: its trunk tilts
        eng.sim.hold(np.zeros(32))
        eng.sim.advance(1)
    d = eng.sim.data
    tilt, hip_z = trunk_tilt(eng.mm, d), float(d.xipos[eng.mm.base_body][2])
    assert 1e-4 < tilt < math.pi / 4

    def falls(fall_height: float, trunk_limit: float) -> bool:
        """_measure at this state with these thresholds (the engine reads them when a run starts)."""
        eng.sc = replace(sc, simulation=replace(sc.simulation, fall_height_m=fall_height))
        eng.settings = replace(eng.settings, trunk_tilt_fall_rad=trunk_limit)
        eng._reset_measures()
        return eng._measure(0.15)

    assert not falls(0.0, tilt)
    assert falls(0.0, math.nextafter(tilt, 0.0)) and "lower trunk tilted" in eng.fall[1]
    assert not falls(hip_z, math.pi / 4)
    assert falls(math.nextafter(hip_z, 1.0), math.pi / 4) and f"hip CoM height {hip_z:.3f} m below" in eng.fall[1]
    # the feet's tilts the edge test reads: NumPy's sole_tilt, or libm's within 1e-15 rad of it
    for i, f in enumerate("RL"):
        assert abs(eng.ground.out[7 + i] - sole_tilt(eng.mm, d, f)) <= 1e-15
    assert foot_loads(eng.mm, d)["R"].normal == eng.ground.out[0] + eng.ground.out[1]


def test_build_compiles_both_contact_layouts(hm: HumanoidModel) -> None:
    """``build`` (walk.py and sweeps call it before a MuJoCo run when the cache is missing) leaves every entry point
    compiled, the contact readers for both layouts MuJoCo's contact fields come in (strided views with two contacts
    or more, C-contiguous with one or none): no walk compiles in the middle of its run."""
    from numba import types

    from humanoid_sim.sim.builds import build_mujoco_reads

    build_mujoco_reads(hm, _zmp_scenario("sim3_zmp"))
    assert mjc.cache_ready()
    for name in mjc.CONTACT_ENTRY_POINTS:
        layouts = {tuple(a.layout for a in sig if isinstance(a, types.Array) and a.dtype == types.int32)
                   for sig in getattr(mjc, name).signatures}
        assert ("C",) * 2 in {lay[:2] for lay in layouts} and ("A",) * 2 in {lay[:2] for lay in layouts}, layouts
