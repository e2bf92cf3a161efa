"""How a run ended, as a typed status rather than a reason string."""

from __future__ import annotations

from enum import Enum


class RunStatus(str, Enum):
    """How a run ended.

    Attributes:
        COMPLETED: every planned phase completed.
        STOPPED: the requested stop time was reached (``until``, or the scenario's ``simulation.t_end_s``).
        INTERRUPTED: stopped by the user (Ctrl-C or SIGTERM); the log up to that point is kept.
        FELL: the robot fell (:class:`humanoid_sim.errors.FallError`).
        FAILED: the simulation or the controller failed otherwise (diverged, singular contact system, a controller
            that raised); the reason says why and the log up to that point is kept.
    """

    COMPLETED = "completed"
    STOPPED = "stopped"
    INTERRUPTED = "interrupted"
    FELL = "fell"
    FAILED = "failed"

    @property
    def reached_end(self) -> bool:
        """Whether the run reached the end it was asked for (every phase, or the requested stop time)."""
        return self in (RunStatus.COMPLETED, RunStatus.STOPPED)


__all__ = ["RunStatus"]
