"""A walk planner beyond the thesis: ZMP preview control of the whole-body centre of mass (Kajita et al. 2003).

Modules: ``preview`` (the cart-table servo preview controller), ``zmp_reference`` (the ZMP reference from support
intervals and sole points), ``multibody`` (the multibody ZMP of a sampled motion and Kajita's second pass that
turns the cart-table plan into a Body-17 CoM path), ``posture`` (the whole-body inverse kinematics that pass
needs).  World frame (x lateral, y forward, z up), SI units.
"""

from .errors import GaitError
from .multibody import HipCorrection, correct_hip, manifold_derivatives, match_com, multibody_zmp, whole_body_com
from .posture import WalkPosture, thesis_free_toes
from .preview import CartTablePreview, PreviewResult
from .zmp_reference import SupportInterval, intervals_from_trajectory, sample, sole_centre, toe_part_centre

__all__ = [
    "CartTablePreview", "GaitError", "HipCorrection", "PreviewResult", "SupportInterval", "WalkPosture",
    "correct_hip", "intervals_from_trajectory", "manifold_derivatives", "match_com", "multibody_zmp", "sample",
    "sole_centre", "thesis_free_toes", "toe_part_centre", "whole_body_com",
]
