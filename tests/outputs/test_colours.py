"""The colour table (humanoid_sim.outputs.colours) against the thesis's legend and the hex notation."""

from __future__ import annotations

import re

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
    # the thesis's toe-path colours: right green, left black; nothing else uses them
    assert colours.FOOT_COLOURS == {"R": "#008000", "L": "#000000"}
    others = [*singles.values(), *colours.PHASE_COLOURS.values()]
    assert not set(colours.FOOT_COLOURS.values()) & set(others)
    assert set(colours.FOOT_NAMES) == set(colours.FOOT_COLOURS)
