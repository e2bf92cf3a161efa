"""GroundReactionLog.batch (the vectorised ground-reaction pass over many logged steps) against the per-step
paths: the independent object-based ``ground_reactions`` and the old one-instant ``GroundReactionLog.__call__``.

States: a 2 s run of simulation 1 (all four phases, both weld layouts: single support = one weld + the toe
lock, 7 rows; double support = main weld + the other foot's toe weld + the lock, 13 rows).  For every logged
step (q, v, applied tau, phase) the constrained forward dynamics is solved again with anchors recorded at q,
which gives a consistent (q, v, a, lambda) of the walk's magnitudes without reaching into the simulator's
logging internals.

Tolerance 1e-9 (N, N m, m, absolute): the paths evaluate the same formulas in different orders (pinocchio
object arithmetic vs stacked NumPy products), so they differ by round-off only: forces of ~1e3 N and moments
about the world origin of ~1e3 N m times a relative ~1e-12 (a few dozen double operations).  Observed: ~1e-13.
"""

from __future__ import annotations

import numpy as np
import pytest

from humanoid_sim.dynamics.contact import (
    ContactDynamics,
    ContactInputError,
    ContactSet,
    ground_reactions,
    record_anchors,
)
from humanoid_sim.dynamics.contact.wrenches import MIN_NORMAL_FORCE, GroundReactionLog
from humanoid_sim.engines.weld import BASIC, BODY_FRAMES, FEET
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.robot.phases import Phase
from humanoid_sim.scenario.schema import load_scenario
from humanoid_sim.sim.simulate import Simulator

TOL = 1e-9
PHASE_OF_BASIC = {i: p for p, i in BASIC.items()}


@pytest.fixture(scope="module")
def walk_states(hm: HumanoidModel) -> dict:
    """Per logged step of a 2 s sim-1 walk: Q, V, A (n x nq / nv), contacts and lams (lists)."""
    res = Simulator(hm, load_scenario("scripts/params/sim1.yaml")).run(t_end=2.0)
    log = res.log.arrays()
    dyn = ContactDynamics(hm.model)
    A, contacts, lams = [], [], []
    for q, v, tau, b in zip(log["q"], log["v"], log["tau"], log["basic_phase"]):
        cs = PHASE_OF_BASIC[int(b)].contacts  # the same object for every step of a phase
        out = dyn.forward(cs, record_anchors(hm.model, q, cs), q, v, tau)
        A.append(out.a)
        contacts.append(cs)
        lams.append(out.lam.copy())
    return {"Q": log["q"], "V": log["v"], "A": np.array(A), "contacts": contacts, "lams": lams}


def _per_step_call(rlog: GroundReactionLog, Q, V, A, contacts, lams) -> tuple[np.ndarray, ...]:
    """The old path: one ``__call__`` per step into rows initialised like batch's outputs."""
    n = len(Q)
    bf, bm = np.zeros((n, len(BODY_FRAMES), 3)), np.zeros((n, len(BODY_FRAMES), 3))
    fw, cop = np.zeros((n, len(FEET), 6)), np.full((n, len(FEET), 3), np.nan)
    for i in range(n):
        rlog(Q[i], V[i], A[i], contacts[i], lams[i], bf[i], bm[i], fw[i], cop[i])
    return bf, bm, fw, cop


def _per_step_objects(hm: HumanoidModel, Q, V, A, contacts, lams) -> tuple[np.ndarray, ...]:
    """The independent path: ``ground_reactions`` objects laid out as batch's arrays."""
    n = len(Q)
    bf, bm = np.zeros((n, len(BODY_FRAMES), 3)), np.zeros((n, len(BODY_FRAMES), 3))
    fw, cop = np.zeros((n, len(FEET), 6)), np.full((n, len(FEET), 3), np.nan)
    for i in range(n):
        gr = ground_reactions(hm.model, Q[i], V[i], A[i], contacts[i], lams[i], FEET)
        for r, frame in enumerate(BODY_FRAMES):
            if frame in gr.bodies:
                bf[i, r], bm[i, r] = gr.bodies[frame].force, gr.bodies[frame].moment
        for k, foot in enumerate(FEET):
            w = gr.feet[foot.name]
            fw[i, k] = np.concatenate([w.force, w.moment])
            cop[i, k] = w.cop
    return bf, bm, fw, cop


def _max_dev(x: np.ndarray, y: np.ndarray) -> float:
    """Largest absolute difference, NaNs required at the same places."""
    assert np.array_equal(np.isnan(x), np.isnan(y))
    ok = ~np.isnan(x)
    return float(np.max(np.abs(x[ok] - y[ok]), initial=0.0))


def test_batch_equals_per_step_paths_on_a_walk(hm: HumanoidModel, walk_states: dict) -> None:
    s = walk_states
    names = {cs.name for cs in s["contacts"]}
    assert names == {p.value for p in Phase}  # all four phases ...
    assert {cs.n_rows for cs in s["contacts"]} == {7, 13}  # ... and both weld layouts
    rlog = GroundReactionLog(hm.model, FEET, BODY_FRAMES)
    got = rlog.batch(s["Q"], s["V"], s["A"], s["contacts"], s["lams"])
    n = len(s["Q"])
    assert [x.shape for x in got] == [(n, 4, 3), (n, 4, 3), (n, 2, 6), (n, 2, 3)]
    fz = got[2][:, :, 2]
    assert 300.0 < np.max(fz.sum(axis=1)) < 3000.0  # plausible magnitudes: the robot's weight order, in N
    old = _per_step_call(GroundReactionLog(hm.model, FEET, BODY_FRAMES), s["Q"], s["V"], s["A"], s["contacts"],
                         s["lams"])
    ref = _per_step_objects(hm, s["Q"], s["V"], s["A"], s["contacts"], s["lams"])
    devs = {}
    for name, x, y, z in zip(("bf", "bm", "fw", "cop"), got, old, ref):
        devs[name] = (_max_dev(x, y), _max_dev(x, z))
    print("max |batch - __call__|, |batch - ground_reactions|:", devs)
    for name, (d_old, d_ref) in devs.items():
        assert d_old < TOL and d_ref < TOL, name
    # in single support the swing foot has neither wrench nor CoP; its bodies' rows stay exactly zero
    for i, cs in enumerate(s["contacts"]):
        if cs.n_rows == 7:
            k = 1 if cs.welds[0] == "O_3" else 0  # support R (O_3) -> swing L is foot 1
            assert not np.any(got[2][i, k]) and np.all(np.isnan(got[3][i, k]))
            rows = [BODY_FRAMES.index(f) for f in (FEET[k].main_frame, FEET[k].toe_frame)]
            assert not np.any(got[0][i, rows]) and not np.any(got[1][i, rows])


def test_batch_does_not_depend_on_step_order_or_contact_set_identity(hm: HumanoidModel, walk_states: dict) -> None:
    """Grouping by contact set is internal: shuffled steps, and equal sets given as distinct objects, give the
    same rows (bit for bit: the same operations on the same numbers)."""
    s = walk_states
    rlog = GroundReactionLog(hm.model, FEET, BODY_FRAMES)
    base = rlog.batch(s["Q"], s["V"], s["A"], s["contacts"], s["lams"])
    perm = np.random.default_rng(5).permutation(len(s["Q"]))
    copies = [ContactSet(cs.welds, cs.locks, cs.name) if i % 2 else cs for i, cs in enumerate(s["contacts"])]
    shuffled = rlog.batch(s["Q"][perm], s["V"][perm], s["A"][perm], [copies[i] for i in perm],
                          [s["lams"][i] for i in perm])
    for x, y in zip(base, shuffled):
        np.testing.assert_array_equal(x[perm], y)


def test_unloaded_foot_has_nan_cop(hm: HumanoidModel, walk_states: dict) -> None:
    """A foot whose vertical ground force is <= MIN_NORMAL_FORCE (weld force zero, or pulling) has a NaN CoP,
    while its bodies still carry the K-10 split (the toe's own Newton-Euler wrench); batch agrees with both
    per-step paths, NaNs included."""
    s = walk_states
    ssp = next(i for i, cs in enumerate(s["contacts"]) if cs.n_rows == 7)
    dsp = next(i for i, cs in enumerate(s["contacts"]) if cs.n_rows == 13)
    rows, lams = [], []
    for scale in (0.0, -1.0, 1e-15):  # zero, pulling, and a vertical force far below MIN_NORMAL_FORCE
        lam = s["lams"][ssp].copy()
        lam[:6] *= scale  # the support foot's weld: the foot's whole ground wrench
        rows.append(ssp)
        lams.append(lam)
    lam = s["lams"][dsp].copy()
    lam[6:12] *= -1.0  # the trailing toe's weld pulls the toe down
    rows.append(dsp)
    lams.append(lam)
    Q, V, A = s["Q"][rows], s["V"][rows], s["A"][rows]
    contacts = [s["contacts"][i] for i in rows]
    got = GroundReactionLog(hm.model, FEET, BODY_FRAMES).batch(Q, V, A, contacts, lams)
    bf, fw, cop = got[0], got[2], got[3]
    support = [1 if cs.welds[0] == "O_4" else 0 for cs in contacts]  # foot index of the support foot (L = 1)
    for r in range(3):
        k = support[r]
        assert not fw[r, k, 2] > MIN_NORMAL_FORCE and np.all(np.isnan(cop[r, k]))
        assert np.any(bf[r, BODY_FRAMES.index(FEET[k].toe_frame)])  # the toe still carries its own wrench
    k_trail = 1 - support[3]
    assert fw[3, k_trail, 2] < 0.0 and np.all(np.isnan(cop[3, k_trail]))
    assert np.all(np.isfinite(cop[3, support[3]]))  # the support foot of that step stays loaded
    old = _per_step_call(GroundReactionLog(hm.model, FEET, BODY_FRAMES), Q, V, A, contacts, lams)
    ref = _per_step_objects(hm, Q, V, A, contacts, lams)
    for x, y, z in zip(got, old, ref):
        assert _max_dev(x, y) < TOL and _max_dev(x, z) < TOL


def test_batch_input_checks_and_empty(hm: HumanoidModel, walk_states: dict) -> None:
    s = walk_states
    rlog = GroundReactionLog(hm.model, FEET, BODY_FRAMES)
    Q, V, A, cs, lams = s["Q"][:3], s["V"][:3], s["A"][:3], s["contacts"][:3], s["lams"][:3]
    with pytest.raises(ContactInputError, match=r"lams\[1\] must have shape"):
        rlog.batch(Q, V, A, cs, [lams[0], lams[1][:-1], lams[2]])
    with pytest.raises(ContactInputError, match="one entry per row"):
        rlog.batch(Q, V, A, cs[:2], lams)
    with pytest.raises(ContactInputError, match="must have shapes"):
        rlog.batch(Q, V[:, :-1], A, cs, lams)
    out = rlog.batch(Q[:0], V[:0], A[:0], [], [])
    assert [x.shape for x in out] == [(0, 4, 3), (0, 4, 3), (0, 2, 6), (0, 2, 3)]


def test_driven_toe_torque_goes_to_the_ground_under_the_toe_box(hm: HumanoidModel, walk_states: dict) -> None:
    """A controller that drives a locked toe joint (the balance controller does): given the applied torques, the
    toe body's ground wrench carries the couple -tau_toe about the toe axis and the main body's +tau_toe.  The three
    paths agree (TOL, as above); each foot's total is the one without torques (round-off of adding and removing the
    couple: 1e-9); and Pinocchio's inverse dynamics with these body wrenches returns the applied toe torque
    (1e-6 N m: the forward dynamics' own residual, ~1e-11, is far below)."""
    import pinocchio as pin

    s = walk_states
    rng = np.random.default_rng(3)
    n, model = len(s["Q"]), hm.model
    taus = rng.uniform(-20.0, 20.0, (n, model.nv))  # N m: the balance controller's toe torques reach ~22 N m
    rlog = GroundReactionLog(model, FEET, BODY_FRAMES)
    got = rlog.batch(s["Q"], s["V"], s["A"], s["contacts"], s["lams"], taus)
    plain = rlog.batch(s["Q"], s["V"], s["A"], s["contacts"], s["lams"])
    assert _max_dev(got[2], plain[2]) < TOL
    assert _max_dev(got[1], plain[1]) > 1.0  # the couple moved between the foot's bodies
    bf, bm = np.zeros_like(got[0]), np.zeros_like(got[1])
    fw, cop = np.zeros_like(got[2]), np.full_like(got[3], np.nan)
    for i in range(n):
        rlog(s["Q"][i], s["V"][i], s["A"][i], s["contacts"][i], s["lams"][i], bf[i], bm[i], fw[i], cop[i], taus[i])
    for x, y in zip(got, (bf, bm, fw, cop)):
        assert _max_dev(x, y) < TOL
    data = model.createData()
    worst = 0.0
    for i in range(0, n, 7):
        gr = ground_reactions(model, s["Q"][i], s["V"][i], s["A"][i], s["contacts"][i], s["lams"][i], FEET,
                              tau=taus[i])
        pin.forwardKinematics(model, data, s["Q"][i])
        pin.updateFramePlacements(model, data)
        fext = [pin.Force.Zero() for _ in range(model.njoints)]
        for frame, w in gr.bodies.items():
            jid = model.frames[model.getFrameId(frame)].parentJoint
            f_w = w.rotation @ w.force
            world = pin.Force(f_w, w.rotation @ w.moment + np.cross(w.com, f_w))  # about the world origin
            fext[jid] = fext[jid] + data.oMi[jid].actInv(world)
        tau_id = pin.rnea(model, data, s["Q"][i], s["V"][i], s["A"][i], fext)
        for foot in FEET:
            if foot.toe_joint in s["contacts"][i].locks:
                iv = model.joints[model.getJointId(foot.toe_joint)].idx_v
                worst = max(worst, abs(tau_id[iv] - taus[i, iv]))
    print("toe joint: max |rnea - applied| =", worst)
    assert worst < 1e-6
