"""Exception of the gait planner package."""

from __future__ import annotations


class GaitError(ValueError):
    """Bad input to a gait planner function; the message names the argument, its value and what was expected."""
