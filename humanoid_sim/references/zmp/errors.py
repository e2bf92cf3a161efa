"""The gait planner package's exception, and the one check of a sample time its planners share."""

from __future__ import annotations

from humanoid_sim.errors import InputError


class GaitError(InputError):
    """Bad input to a gait planner function; the message names the argument, its value and what was expected."""


def sample_time(T: object) -> float:
    """T as a float, the planners' sample time in s; :class:`GaitError` naming ``T`` unless it is a finite number
    > 0."""
    import math

    try:
        v = float(T)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise GaitError(f"T: expected a sample time in s, got {T!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise GaitError(f"T: expected a finite sample time > 0 s, got {v!r}")
    return v
