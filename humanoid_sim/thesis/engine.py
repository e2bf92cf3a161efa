"""ThesisEngine: the chapter-4 / section-5.2 oracle behind one small interface (``walk.py --engine thesis``).

All inputs and outputs use the thesis's conventions: theta, theta_dot, theta_ddot (26,) in eq. 4.1 order (rad,
rad/s, rad/s^2); T (26,) in eq. 4.69 order (N m, Cartesian moment components); F (96,) in eq. 4.68 order;
``fixed`` = {"R": FootState, "L": FootState} with the stance toe bodies' C^(0,1)/C^(0,2) and toe points (only
the entries the phase uses are read).  Slow on purpose: every matrix is built as the thesis builds it.
"""

from __future__ import annotations

import numpy as np

from humanoid_sim.thesis.dynamics import DirectDynamicsResult, DynamicTerms, dynamic_terms, solve_direct
from humanoid_sim.thesis.impact import ResetResult, touchdown_reset
from humanoid_sim.thesis.jacobians import jacobian_derivatives, thesis_jacobians
from humanoid_sim.thesis.kinematics import Fixed, Kinematics, accelerations, add_velocities, kinematics, positions
from humanoid_sim.thesis.params import ThesisParams, params_from_spec
from humanoid_sim.thesis.torque import ComputedTorqueResult, computed_torque


class ThesisEngine:
    """The NumPy transcription of the thesis's kinematics, dynamics, computed torque and impact law."""

    def __init__(self, spec) -> None:
        """``spec``: a ``urdf_gen.spec.RobotSpec`` (``load_spec("models/thesis_humanoid.yaml")``) or ThesisParams."""
        self.params: ThesisParams = spec if isinstance(spec, ThesisParams) else params_from_spec(spec)

    # ------------------------------------------------------------------ section 4.1
    def kinematics(self, phase: str, theta: np.ndarray, theta_dot: np.ndarray | None, fixed: Fixed,
                   theta_ddot: np.ndarray | None = None) -> Kinematics:
        """Orientations, positions (and velocities / accelerations when their inputs are given) of every frame,
        mass centre and toe point."""
        return kinematics(phase, theta, theta_dot, theta_ddot, fixed, self.params)

    def accelerations(self, kin: Kinematics, theta_dot: np.ndarray, theta_ddot: np.ndarray,
                      fixed: Fixed) -> Kinematics:
        """Fill ``kin.alpha`` / ``kin.a`` for theta_ddot (velocities added first if missing)."""
        if kin.w is None:
            add_velocities(kin, theta_dot, fixed, self.params)
        kin.alpha, kin.a = accelerations(kin, theta_dot, theta_ddot, fixed, self.params)
        return kin

    # ------------------------------------------------------------------ section 4.2
    def jacobians(self, phase: str, theta: np.ndarray, fixed: Fixed,
                  names: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
        """The thesis Jacobians the phase needs (4.2.1), by name, e.g. "J_v,17_fR", "J_v,Cdiag0_2"."""
        return thesis_jacobians(positions(phase, theta, fixed, self.params), fixed, self.params, names)

    def jacobian_derivatives(self, phase: str, theta: np.ndarray, theta_dot: np.ndarray, fixed: Fixed, dt: float,
                             names: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
        """Eq. 4.34 forward differences with step dt (s; not given by the thesis, errata A-14)."""
        return jacobian_derivatives(phase, theta, theta_dot, fixed, self.params, dt, names)

    # ------------------------------------------------------------------ sections 4.3-4.4
    def dynamic_terms(self, phase: str, theta: np.ndarray, theta_dot: np.ndarray, fixed: Fixed) -> DynamicTerms:
        """M, B, K (and the DSP closure rows) at a state; reusable by forward_dynamics and computed_torque at the
        same state (the controller and the dynamics are evaluated at the same state in the simulation)."""
        kin = add_velocities(positions(phase, theta, fixed, self.params), theta_dot, fixed, self.params)
        return dynamic_terms(kin, theta_dot, fixed, self.params)

    def forward_dynamics(self, phase: str, theta: np.ndarray, theta_dot: np.ndarray, T: np.ndarray,
                         fixed: Fixed, terms: DynamicTerms | None = None) -> DirectDynamicsResult:
        """The 122 x 122 direct dynamic solution (eqs. 4.78 / 4.82 / 4.88 / 4.94)."""
        terms = self.dynamic_terms(phase, theta, theta_dot, fixed) if terms is None else terms
        return solve_direct(phase, terms, T)

    # ------------------------------------------------------------------ section 5.2
    def computed_torque(self, phase: str, theta: np.ndarray, theta_dot: np.ndarray, theta_ddot_cmd: np.ndarray,
                        fixed: Fixed, W_act: np.ndarray | None = None,
                        terms: DynamicTerms | None = None) -> ComputedTorqueResult:
        """T (and F) realising theta_ddot_cmd (eqs. 5.92 / 5.93 / 5.96 / 5.98)."""
        terms = self.dynamic_terms(phase, theta, theta_dot, fixed) if terms is None else terms
        return computed_torque(phase, terms, theta_ddot_cmd, W_act)

    # ------------------------------------------------------------------ section 4.5
    def touchdown_reset(self, phase_from: str, theta: np.ndarray, theta_dot: np.ndarray, fixed: Fixed,
                        W_adj: np.ndarray) -> ResetResult:
        """Velocity reset of eq. 4.97 / 4.100 at the end of ``phase_from`` (an SSP)."""
        return touchdown_reset(positions(phase_from, theta, fixed, self.params), theta_dot, fixed, self.params,
                               W_adj)
