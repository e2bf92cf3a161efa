"""The thesis humanoid in MuJoCo: an independent physics engine with unilateral, frictional foot contact.

- :mod:`.model` builds the MjModel at run time from the generated URDF (free joint at the lower trunk, ground
  plane, sole boxes, motor actuators) and documents every contact and integration setting;
- :mod:`.state` is the one explicit map between Pinocchio's (q, v, tau) and MuJoCo's (qpos, qvel, qfrc / ctrl).
"""

from humanoid_sim.mujoco.model import MujocoModel, MujocoModelError, MujocoSettings, build_model
from humanoid_sim.mujoco.state import StateMap

__all__ = ["MujocoModel", "MujocoModelError", "MujocoSettings", "build_model", "StateMap"]
