"""Contact-constrained dynamics: contact sets, forward and inverse dynamics, ground reactions.

Generic over the model (any pinocchio model with a free-flyer root): a contact set is a list of welded
frames and locked 1-DOF joints.  The thesis's phases are one instance (:mod:`humanoid_sim.robot.phases`).
"""

from humanoid_sim.dynamics.contact.constraints import (
                                              NO_STABILIZATION,
                                              Anchors,
                                              Baumgarte,
                                              ConstraintRows,
                                              ContactSet,
                                              record_anchors,
)
from humanoid_sim.dynamics.contact.errors import (
                                              AnchorError,
                                              ContactError,
                                              ContactInputError,
                                              ContactSetError,
                                              SingularConstraintError,
)
from humanoid_sim.dynamics.contact.forward import ContactDynamics, ForwardResult
from humanoid_sim.dynamics.contact.inverse import InverseResult
from humanoid_sim.dynamics.contact.wrenches import (
                                              BodyWrench,
                                              FootSpec,
                                              FootWrench,
                                              GroundReactions,
                                              centre_of_pressure,
                                              ground_reactions,
)

__all__ = [
    "AnchorError", "Anchors", "Baumgarte", "BodyWrench", "ConstraintRows", "ContactDynamics", "ContactError",
    "ContactInputError", "ContactSet", "ContactSetError", "FootSpec", "FootWrench", "ForwardResult",
    "GroundReactions", "InverseResult", "NO_STABILIZATION", "SingularConstraintError", "centre_of_pressure",
    "ground_reactions", "record_anchors",
]
