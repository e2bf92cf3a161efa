"""Phases as data (design.md s. 4, errata 6.1) and the switching rules of thesis section 6.1.1 (errata 6.2)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg as sla

from humanoid_sim.engines.impact import constraint_jacobian
from humanoid_sim.robot.model import THETA_NAMES, HumanoidModel
from humanoid_sim.robot.phases import (
    FOOT_SPECS,
    Phase,
    SwitchThresholds,
    dsp_should_end,
    next_phase,
    ssp_should_end,
    touchdown_contacts,
)

# Thesis L1725-1730: bodies held fixed in each phase; the others (of bodies 1-4) move.
HELD_FIXED = {Phase.RFFSSP: {1, 3}, Phase.LFFSSP: {2, 4}, Phase.RFFDSP: {1, 2, 3}, Phase.LFFDSP: {1, 2, 4}}


def _random_q(hm: HumanoidModel, rng: np.random.Generator, scale: float = 0.3) -> np.ndarray:
    return pin.integrate(hm.model, hm.initial_q(), scale * rng.standard_normal(hm.model.nv))


def test_cycle_and_roles() -> None:
    order = [Phase.LFFSSP, Phase.RFFDSP, Phase.RFFSSP, Phase.LFFDSP]
    for i, p in enumerate(order):
        assert next_phase(p) is order[(i + 1) % 4] and p.next is order[(i + 1) % 4]
    assert [p.is_double_support for p in order] == [False, True, False, True]
    assert [p.support_foot for p in order] == ["L", "R", "R", "L"]
    assert [p.swing_foot for p in order] == ["R", None, "L", None]
    assert [p.landing_foot for p in order] == ["R", None, "L", None]
    assert [p.trailing_toe for p in order] == [None, "L", None, "R"]
    # The foot that lands at the end of an SSP is the support foot of the next DSP (s. 4.5).
    for p in (Phase.LFFSSP, Phase.RFFSSP):
        assert p.next.support_foot == p.landing_foot
        # ... and the previous support foot becomes the trailing toe.
        assert p.next.trailing_toe == p.support_foot


def test_contact_sets_match_design_table() -> None:
    expected = {
        Phase.LFFSSP: (("O_4",), ("theta4",), 7),
        Phase.RFFDSP: (("O_3", "O_2"), ("theta3",), 13),
        Phase.RFFSSP: (("O_3",), ("theta3",), 7),
        Phase.LFFDSP: (("O_4", "O_1"), ("theta4",), 13),
    }
    for p, (welds, locks, rows) in expected.items():
        assert p.contacts.welds == welds and p.contacts.locks == locks
        assert p.n_constraint_rows == rows == p.contacts.n_rows


def test_free_dof_equals_thesis_count(hm: HumanoidModel) -> None:
    """nv - rank(J) at random postures equals the thesis's count: 26 joints (eq. 4.1) - 1 toe lock
    (eq. 4.80/4.84/4.90) - 6 closed-chain rows in double support (eqs. 4.85-4.86/4.91-4.92)."""
    rng = np.random.default_rng(11)
    data = hm.model.createData()
    thesis = {Phase.LFFSSP: len(THETA_NAMES) - 1, Phase.RFFSSP: len(THETA_NAMES) - 1,
              Phase.RFFDSP: len(THETA_NAMES) - 1 - 6, Phase.LFFDSP: len(THETA_NAMES) - 1 - 6}
    assert set(thesis.values()) == {25, 19}
    for _ in range(3):
        q = _random_q(hm, rng)
        for p in Phase:
            J = constraint_jacobian(hm.model, data, q, p.contacts)
            assert hm.model.nv - np.linalg.matrix_rank(J) == thesis[p] == p.thesis_free_dof


def test_contact_sets_hold_exactly_the_thesis_bodies(hm: HumanoidModel) -> None:
    """Any velocity satisfying a phase's constraints leaves the thesis's fixed bodies (L1725-1730) at rest
    and lets the other foot bodies move."""
    rng = np.random.default_rng(12)
    model, data = hm.model, hm.model.createData()
    q = _random_q(hm, rng)
    for p in Phase:
        N = sla.null_space(constraint_jacobian(model, data, q, p.contacts))
        v = N @ rng.standard_normal(N.shape[1])
        pin.forwardKinematics(model, data, q, v)
        for k in (1, 2, 3, 4):
            twist = pin.getFrameVelocity(model, data, hm.frame_id(f"O_{k}"), pin.LOCAL).vector
            if k in HELD_FIXED[p]:
                # round-off of a null-space basis applied to an O(1) random vector
                assert np.max(np.abs(twist)) < 1e-12, (p, k, twist)
            else:
                assert np.max(np.abs(twist)) > 1e-3, (p, k, twist)


def test_touchdown_contacts() -> None:
    cs = touchdown_contacts(Phase.RFFSSP)
    assert set(cs.welds) == {"O_3", "O_4"} and set(cs.locks) == {"theta3", "theta4"} and cs.n_rows == 14
    cs = touchdown_contacts(Phase.LFFSSP)
    assert set(cs.welds) == {"O_3", "O_4"} and cs.welds[0] == "O_4"
    with pytest.raises(ValueError, match="RFFDSP"):
        touchdown_contacts(Phase.RFFDSP)
    assert FOOT_SPECS["R"].toe_joint == "theta3" and FOOT_SPECS["L"].main_frame == "O_4"


def test_switch_thresholds_defaults() -> None:
    t = SwitchThresholds()
    # thesis L3986-3990 and L4034-4037
    assert (t.toe_flat_height, t.touchdown_tolerance, t.min_horizontal_progress_fraction, t.dsp_hip_distance,
            t.dsp_overtime_fraction) == (0.015, 0.001, 0.3, 0.05, 0.1)


def test_ssp_should_end() -> None:
    start = np.array([0.16, 0.10, 0.015])
    end = np.array([0.16, 0.50, 0.015])          # 0.4 m planned horizontal travel -> 0.12 m threshold
    assert ssp_should_end([0.16, 0.30, 0.0155], start, end)             # low, 0.2 m > 0.12 m
    assert not ssp_should_end([0.16, 0.30, 0.0165], start, end)         # 0.0015 above flat: not < 0.001
    assert not ssp_should_end([0.16, 0.21, 0.0155], start, end)         # 0.11 m < 0.12 m: too early
    assert ssp_should_end([0.16 + 0.1, 0.10 + 0.1, 0.010], start, end)  # 0.141 m in xy, any direction
    # Only the horizontal distance counts (z is excluded): a high start point does not add progress.
    assert not ssp_should_end([0.16, 0.21, 0.0155], start + [0, 0, 0.5], end)
    with pytest.raises(ValueError, match="shape"):
        ssp_should_end([0.0, 0.0], start, end)


def test_dsp_should_end() -> None:
    ref = np.array([0.0, 0.5, 0.95])
    assert dsp_should_end(ref + [0.03, 0.03, 0.0], ref, elapsed=0.0, t_dsp=0.2)    # 0.042 m < 0.05 m
    assert not dsp_should_end(ref + [0.04, 0.04, 0.0], ref, elapsed=0.1, t_dsp=0.2)  # 0.057 m, not late
    assert dsp_should_end(ref + [0.0, 0.0, 0.2], ref, elapsed=0.221, t_dsp=0.2)   # lasted > 1.1 t_DSP
    assert not dsp_should_end(ref + [0.0, 0.0, 0.2], ref, elapsed=0.219, t_dsp=0.2)
    with pytest.raises(ValueError, match="t_dsp"):
        dsp_should_end(ref, ref, elapsed=0.0, t_dsp=0.0)
    with pytest.raises(ValueError, match="elapsed"):
        dsp_should_end(ref, ref, elapsed=-1.0, t_dsp=0.2)
