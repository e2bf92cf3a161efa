"""NumPy transcription of the thesis's chapter 4 and section 5.2: the regression oracle for the fast path.

Modules, one concept each:

- :mod:`params`      body scalars, masses, inertias as the formulas use them
- :mod:`frames`      4.1.1 / 4.1.3 / 4.1.5: C^(0,k), w_k, alpha_k per phase
- :mod:`kinematics`  4.1.2 / 4.1.4 / 4.1.6: positions, velocities, accelerations of mass centres and toe points
- :mod:`jacobians`   4.2: unit-rate Jacobians, C_diag Jacobians, eq. 4.34 time derivatives
- :mod:`forces`      eq. 4.68 F layout, eq. 4.69 phi, phase selectors, W_act
- :mod:`dynamics`    4.3 / 4.4: Newton-Euler of the 13 bodies, M, B, K, the 122 x 122 solution
- :mod:`torque`      5.2: computed torque (SSP exact, DSP weighted minimum norm)
- :mod:`impact`      4.5: touchdown velocity reset
- :mod:`joint_space` Cartesian joint moments <-> generalized forces (not in the thesis; the bridge to pinocchio)
- :mod:`engine`      :class:`ThesisEngine`, the bundle ``walk.py --engine thesis`` uses
"""

from humanoid_sim.thesis.engine import ThesisEngine
from humanoid_sim.thesis.frames import PHASES, THETA_NAMES
from humanoid_sim.thesis.kinematics import FootState

__all__ = ["PHASES", "THETA_NAMES", "FootState", "ThesisEngine"]
