"""The colours of every figure and of the 3-D view, defined once (hex RGB strings, as matplotlib takes them).

- Phases: the thesis's legend (L4219-4221): LFFSSP red, RFFDSP blue, RFFSSP magenta, LFFDSP cyan.
- Sides: right green, left purple, in every figure and in the 3-D view.  Every line, marker or outline that belongs
  to one foot (toe paths, ground reactions, centre of pressure, sole outlines, contact flags) has its foot's colour,
  and so does every part of the robot on that side in the 3-D view (leg, arm: :func:`body_colour`); nothing else
  uses these two colours.  Right green is the thesis's toe-path colour (Figs. 6.51-6.53); its left toe path is
  black, which a shaded 3-D body cannot show (a black surface stays black under any light), hence purple, a hue
  apart from the four phase colours, the ZMP and the references.
- The whole-body ZMP orange; a point outside its sole or support polygon red; references grey and dashed.
"""

from __future__ import annotations

PHASE_COLOURS = {"LFFSSP": "#ff0000", "RFFDSP": "#0000ff", "RFFSSP": "#ff00ff", "LFFDSP": "#00ffff"}
FOOT_COLOURS = {"R": "#008000", "L": "#7b2cbf"}
"""The colour of each side: its foot in every figure, its foot and limbs in the 3-D view."""
FOOT_NAMES = {"R": "right foot", "L": "left foot"}
BODY_COLOUR = "#b3b3b3"
"""Parts of the robot on neither side (trunk, head) in the 3-D view."""
ZMP_COLOUR = "#ff7f0e"
OUTSIDE_COLOUR = "#e41a1c"
SIGNAL_COLOUR = "#1f77b4"
"""Simulated signals that belong to no foot (joint angles, hip, torques)."""
REFERENCE_COLOUR = "#707070"
LIMIT_COLOUR = "#d62728"
WAYPOINT_COLOUR = "#8c564b"


def hex_int(colour: str) -> int:
    """``"#rrggbb"`` -> 0xRRGGBB (meshcat's colour form)."""
    if not (isinstance(colour, str) and len(colour) == 7 and colour[0] == "#"):
        raise ValueError(f"colour: expected '#rrggbb', got {colour!r}")
    return int(colour[1:], 16)


def side_of(name: str) -> str | None:
    """"R" for a part named ``right_...``, "L" for ``left_...``, else None (a body or geometry name)."""
    return "R" if name.startswith("right_") else "L" if name.startswith("left_") else None


def body_colour(name: str) -> str:
    """The 3-D colour of the robot part ``name``: its side's :data:`FOOT_COLOURS`, else :data:`BODY_COLOUR`."""
    side = side_of(name)
    return FOOT_COLOURS[side] if side is not None else BODY_COLOUR
