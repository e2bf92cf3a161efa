"""Thesis chapter 3: reference trajectory generation (hip CoM/orientation, toe points, feet).

Modules: ``params`` (locomotion parameters of 3.1, validated), ``geometry`` (arc centres and local
frames of 3.2.1-3.2.2), ``polynomials`` (the boundary-value systems of 3.2.3), ``generator`` (the
precomputed generator queried by phase or global time).
"""

from .generator import PhaseInfo, PhaseTargets, ReferenceTrajectory, RefSample, TrajectoryError
from .params import TOE_FLAT_HEIGHT, PathParamError, PathParams

__all__ = [
    "PathParams",
    "PathParamError",
    "PhaseInfo",
    "PhaseTargets",
    "RefSample",
    "ReferenceTrajectory",
    "TrajectoryError",
    "TOE_FLAT_HEIGHT",
]
