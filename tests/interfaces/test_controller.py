"""What a controller may return (humanoid_sim.interfaces.controller.as_command): the accepted forms and the
messages for everything else, checked against the shapes and values written out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from humanoid_sim.errors import ControllerError
from humanoid_sim.interfaces.controller import Command, as_command

NV = 32


def test_joint_torques_get_zero_base_rows() -> None:
    cmd = as_command(np.arange(26.0), NV, "c")
    assert isinstance(cmd, Command) and cmd.tau.dtype == np.float64
    np.testing.assert_array_equal(cmd.tau, np.r_[np.zeros(6), np.arange(26.0)])


def test_lists_and_integers_are_numbers_too() -> None:
    np.testing.assert_array_equal(as_command(list(range(26)), NV, "c").tau, np.r_[np.zeros(6), np.arange(26.0)])
    assert as_command(np.arange(26), NV, "c").tau.dtype == np.float64


def test_base_round_off_is_cleared_but_a_base_force_is_refused() -> None:
    tau = np.r_[np.full(6, 1e-12), np.ones(26)]
    out = as_command(tau, NV, "c").tau
    np.testing.assert_array_equal(out[:6], 0.0)
    assert tau[0] == 1e-12                                 # the caller's array is left alone
    with pytest.raises(ControllerError, match=r"controller 'pusher' returned forces on the unactuated base rows"):
        as_command(np.r_[1.0, np.zeros(5), np.ones(26)], NV, "pusher")


@pytest.mark.parametrize("out, message", [
    (np.zeros(25), r"controller 'c' returned torques of shape \(25,\), expected \(26,\) joint torques"),
    (np.zeros((2, 26)), r"shape \(2, 26\)"),
    ("torques", r"controller 'c' returned str, expected an array of 26 joint torques \(or 32 generalized forces\)"),
    (None, r"returned torques of shape \(\)"),
])
def test_wrong_forms_are_named(out, message) -> None:
    with pytest.raises(ControllerError, match=message):
        as_command(out, NV, "c")


def test_non_finite_torques_name_their_entries() -> None:
    tau = np.zeros(26)
    tau[3], tau[7] = np.nan, np.inf
    with pytest.raises(ControllerError, match=r"non-finite torques: entry 9 = nan, entry 13 = inf "
                                              r"\(entries \[9, 13\] of the v-ordered vector"):
        as_command(tau, NV, "c")   # joint entry j is v entry 6 + j


def test_a_command_with_thesis_torques_only_is_passed_on() -> None:
    cmd = Command(tau=None, T=np.ones(26))
    assert as_command(cmd, NV, "c") is cmd and cmd.tau is None   # the engine maps T to tau
    with pytest.raises(ControllerError, match="thesis torques T that are not 26 finite numbers"):
        as_command(Command(tau=None, T=np.r_[np.ones(25), np.nan]), NV, "c")


def test_non_finite_torques_and_wrong_shapes_name_the_joints(hm) -> None:
    from humanoid_sim.interfaces.selector import CoordinateNames

    names = CoordinateNames.of(hm)
    tau = np.zeros(26)
    i9 = int(hm.theta_v_idx[list(hm.spec.theta_order).index("theta9")]) - 6  # its row among the joint torques
    tau[i9] = np.nan
    with pytest.raises(ControllerError, match=r"non-finite torques: theta9 \(right shank, body 9\) = nan"):
        as_command(tau, NV, "c", names)
    with pytest.raises(ControllerError, match=r"shape \(25,\), expected \(26,\) joint torques in Pinocchio's joint "
                                              r"order \(theta17l, theta16, .*, theta27\)"):
        as_command(np.zeros(25), NV, "c", names)
    f = np.zeros(NV)
    f[2] = 5.0
    with pytest.raises(ControllerError, match=r"base rows .*base linear velocity z"):
        as_command(f, NV, "c", names)
