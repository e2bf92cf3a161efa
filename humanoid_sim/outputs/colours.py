"""The colours of every figure and of the 3-D view, defined once (hex RGB strings, as matplotlib takes them).

- Phases: the thesis's legend (L4219-4221): LFFSSP red, RFFDSP blue, RFFSSP magenta, LFFDSP cyan.
- Feet: the thesis's toe-path colours (Figs. 6.51-6.53): right green, left black.  Every line, marker or outline that
  belongs to one foot (toe paths, ground reactions, centre of pressure, sole outlines, contact flags) has its foot's
  colour; nothing else uses these two colours.
- The whole-body ZMP orange; a point outside its sole or support polygon red; references grey and dashed.
"""

from __future__ import annotations

PHASE_COLOURS = {"LFFSSP": "#ff0000", "RFFDSP": "#0000ff", "RFFSSP": "#ff00ff", "LFFDSP": "#00ffff"}
FOOT_COLOURS = {"R": "#008000", "L": "#000000"}
FOOT_NAMES = {"R": "right foot", "L": "left foot"}
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
