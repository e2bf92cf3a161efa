"""The colour table (humanoid_sim.outputs.colours) against the thesis's legend and the hex notation."""

from __future__ import annotations

import re

import numpy as np
import pytest

from humanoid_sim.outputs import colours
from humanoid_sim.robot.phases import Phase


def test_hex_int_reads_the_three_bytes() -> None:
    # by hand: 0xff7f0e = 255 * 65536 + 127 * 256 + 14
    assert colours.hex_int("#ff7f0e") == 255 * 65536 + 127 * 256 + 14
    assert colours.hex_int("#000000") == 0
    assert colours.hex_int("#FFFFFF") == 2 ** 24 - 1


@pytest.mark.parametrize("bad", ["ff7f0e", "#ff7f0", "#ff7f0e0", 0xff7f0e, None, "#gg0000"])
def test_hex_int_refuses_other_notations(bad) -> None:
    with pytest.raises(ValueError):
        colours.hex_int(bad)


def test_phase_colours_are_the_thesis_legend() -> None:
    # thesis legend: LFFSSP red, RFFDSP blue, RFFSSP magenta, LFFDSP cyan (one per contact phase)
    rgb = {"red": (255, 0, 0), "blue": (0, 0, 255), "magenta": (255, 0, 255), "cyan": (0, 255, 255)}
    expected = {"LFFSSP": "red", "RFFDSP": "blue", "RFFSSP": "magenta", "LFFDSP": "cyan"}
    assert set(colours.PHASE_COLOURS) == {p.value for p in Phase}
    for phase, name in expected.items():
        c = colours.PHASE_COLOURS[phase]
        assert tuple(int(c[i:i + 2], 16) for i in (1, 3, 5)) == rgb[name], phase


def test_every_colour_is_rrggbb_and_the_feet_own_theirs() -> None:
    singles = {n: getattr(colours, n) for n in dir(colours) if n.endswith("_COLOUR")}
    every = [*singles.values(), *colours.PHASE_COLOURS.values(), *colours.FOOT_COLOURS.values()]
    assert all(re.fullmatch(r"#[0-9a-f]{6}", c) for c in every), every
    # right green (the thesis's right toe path), left purple; nothing else uses them
    assert colours.FOOT_COLOURS == {"R": "#008000", "L": "#7b2cbf"}
    others = [*singles.values(), *colours.PHASE_COLOURS.values()]
    assert not set(colours.FOOT_COLOURS.values()) & set(others)
    assert set(colours.FOOT_NAMES) == set(colours.FOOT_COLOURS)


def test_robot_parts_take_their_sides_colour() -> None:
    assert colours.body_colour("right_thigh_0") == colours.FOOT_COLOURS["R"]
    assert colours.body_colour("left_arm_0") == colours.FOOT_COLOURS["L"]
    assert colours.body_colour("upper_trunk_0") == colours.body_colour("head_0") == colours.BODY_COLOUR
    assert colours.side_of("rightmost") is None


def test_side_colours_are_lit_and_far_from_every_other_colour() -> None:
    """A shaded 3-D body shows a hue, not black: each side colour has a channel above 0x60; and every other named
    colour is at least 80 apart (RGB distance, 0-255 channels) from both sides."""
    def rgb(c: str) -> np.ndarray:
        return np.array([int(c[i:i + 2], 16) for i in (1, 3, 5)], dtype=float)

    others = [*(getattr(colours, n) for n in dir(colours) if n.endswith("_COLOUR")), *colours.PHASE_COLOURS.values()]
    for side in colours.FOOT_COLOURS.values():
        assert rgb(side).max() > 0x60, side
        assert min(np.linalg.norm(rgb(side) - rgb(o)) for o in others) > 80, side
