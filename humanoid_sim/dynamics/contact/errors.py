"""Exceptions of the contact / impact code.  Every message carries the offending value."""

from __future__ import annotations

from humanoid_sim.errors import SimulationError


class ContactError(SimulationError, ValueError):
    """Base class of every error raised by :mod:`humanoid_sim.dynamics.contact` and
    :mod:`humanoid_sim.engines.impact`."""


class ContactSetError(ContactError):
    """A contact set names a frame or joint the model does not have, or a joint that is not 1-DOF."""


class ContactInputError(ContactError):
    """A state, torque or weight vector of the wrong shape, or a non-zero force on the unactuated base."""


class SingularConstraintError(ContactError):
    """The constraint Jacobian (or a KKT / Schur matrix built from it) is rank deficient at this state."""


class AnchorError(ContactError):
    """A welded frame or locked joint has no recorded anchor (world placement / joint angle)."""
