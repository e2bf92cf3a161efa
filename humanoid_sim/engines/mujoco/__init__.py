"""The thesis humanoid in MuJoCo: an independent physics engine with unilateral, frictional foot contact.

- :mod:`.model` builds the MjModel at run time from the generated URDF (free joint at the lower trunk, ground
  plane, sole boxes, motor actuators) and documents every contact and integration setting;
- :mod:`.state` is the one explicit map between Pinocchio's (q, v, tau) and MuJoCo's (qpos, qvel, qfrc / ctrl);
- :mod:`.contact` reads the feet's ground wrenches, CoP, normal forces and contact points from
  ``mujoco.mj_contactForce`` and measures slip, tilt and penetration;
- :mod:`.ground` keeps those measures over a run at every control update (the engine's meters), :mod:`.compiled`
  the numba forms of the engine's per-update and per-step reads (the same numbers as :mod:`.contact`'s);
- :mod:`.sim` is :class:`MujocoSim`, the engine object (set/get state in Pinocchio's convention, zero-order-hold
  torque steps);
- :mod:`.standing` is the joint-space PD + gravity-compensation controller of the standing experiment;
- :mod:`.experiments` repeats the measurements behind the settings
  (``python -m humanoid_sim.engines.mujoco.experiments``).
"""

from humanoid_sim.engines.mujoco.contact import (
                                         FootContact,
                                         SlipMeter,
                                         SoleCop,
                                         foot_contacts,
                                         sole_cop,
                                         sole_corners,
                                         sole_tilt,
)
from humanoid_sim.engines.mujoco.model import MujocoModel, MujocoModelError, MujocoSettings, build_model
from humanoid_sim.engines.mujoco.sim import MujocoSim, MujocoSimError
from humanoid_sim.engines.mujoco.state import StateMap

__all__ = ["MujocoModel", "MujocoModelError", "MujocoSettings", "build_model", "StateMap", "FootContact",
           "SlipMeter", "SoleCop", "foot_contacts", "sole_cop", "sole_corners", "sole_tilt", "MujocoSim",
           "MujocoSimError"]
