"""Generate the URDF of the thesis humanoid from its body-parameter YAML.

``python -m urdf_gen models/thesis_humanoid.yaml -o models/thesis_humanoid.urdf``

Dependency-light on purpose (numpy + pyyaml): the model data is the single source of truth, the URDF is a
deterministic rendering of it.
"""

from urdf_gen.emit import emit_urdf
from urdf_gen.spec import BodySpec, JointSpec, RobotSpec, SpecError, load_spec

__all__ = ["BodySpec", "JointSpec", "RobotSpec", "SpecError", "load_spec", "emit_urdf"]
