"""Fixed-step explicit Runge-Kutta integration of (q, v) on the configuration manifold.

``ode3`` is Simulink's fixed-step ode3, the Bogacki-Shampine third-order pair used without its error
estimate (thesis L3904).  Stages use pinocchio's ``integrate`` for the configuration (the free-flyer part lives
on SE(3); never q + h v, design.md section 3): stage i evaluates the dynamics at
q_i = q (+) h sum_j a_ij v_j, v_i = v + h sum_j a_ij a_j, and the step ends at q (+) h sum_i b_i v_i.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin


@dataclass(frozen=True)
class Tableau:
    """Butcher tableau of an explicit method: stage times c, coefficients a (lower triangular), weights b."""

    name: str
    c: tuple[float, ...]
    a: tuple[tuple[float, ...], ...]
    b: tuple[float, ...]


TABLEAUS = {
    "euler": Tableau("euler", (0.0,), ((),), (1.0,)),
    # Bogacki & Shampine (1989), the 3rd-order solution of the ode23 pair: Simulink ode3.
    "ode3": Tableau("ode3", (0.0, 0.5, 0.75), ((), (0.5,), (0.0, 0.75)), (2 / 9, 1 / 3, 4 / 9)),
    "rk4": Tableau("rk4", (0.0, 0.5, 0.5, 1.0), ((), (0.5,), (0.0, 0.5), (0.0, 0.0, 1.0)),
                   (1 / 6, 1 / 3, 1 / 3, 1 / 6)),
}

Dynamics = Callable[[float, np.ndarray, np.ndarray, int], np.ndarray]
"""f(t, q, v, stage) -> generalized acceleration (nv,)."""

Projection = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
"""project(q, v) -> (q, v) on a constraint manifold (applied to every stage state and to the step's end)."""

Advance = Callable[[np.ndarray, np.ndarray, tuple, list, list, float], tuple[np.ndarray, np.ndarray]]
"""advance(q, v, coeffs, vs, accs, h) -> project(integrate(q, h dq), v + h dv) with dq = sum_j coeffs[j] vs[j] and
dv = sum_j coeffs[j] accs[j] over the stages so far, computed in one go."""


class RungeKutta:
    """One fixed step of an explicit RK method on (q, v)."""

    def __init__(self, model: pin.Model, method: str = "ode3") -> None:
        if method not in TABLEAUS:
            raise ValueError(f"integrator method: expected one of {sorted(TABLEAUS)}, got {method!r}")
        self.model = model
        self.tab = TABLEAUS[method]

    def step(self, f: Dynamics, t: float, q: np.ndarray, v: np.ndarray, h: float,
             project: Projection | None = None, advance: Advance | None = None) -> tuple[np.ndarray, np.ndarray]:
        """One step of size h (s) from (q, v) at time t; ``project`` (optional) maps every stage state and the
        result onto a constraint manifold (coordinate projection).  ``advance`` (optional) replaces both: it returns
        the projection of (q integrated by h dq, v + h dv) itself (the compiled kernel's fused version)."""
        tab = self.tab
        vs: list[np.ndarray] = []
        accs: list[np.ndarray] = []
        for i, ci in enumerate(tab.c):
            if i == 0:
                qi, vi = q, v
            else:
                qi, vi = self._advance(q, v, tab.a[i], vs, accs, h, project, advance)
            vs.append(vi)
            accs.append(f(t + ci * h, qi, vi, i))
        return self._advance(q, v, tab.b, vs, accs, h, project, advance)

    def _advance(self, q: np.ndarray, v: np.ndarray, coeffs: tuple[float, ...], vs: list[np.ndarray],
                 accs: list[np.ndarray], h: float, project: Projection | None, advance: Advance | None
                 ) -> tuple[np.ndarray, np.ndarray]:
        """The (projected) state at q integrated by h sum c_j vs_j, v + h sum c_j accs_j."""
        if advance is not None:
            return advance(q, v, coeffs, vs, accs, h)
        qi = pin.integrate(self.model, q, h * _combine(coeffs, vs))
        vi = v + h * _combine(coeffs, accs)
        return (qi, vi) if project is None else project(qi, vi)


def _combine(coeffs: tuple[float, ...], xs: list[np.ndarray]) -> np.ndarray:
    """sum_j c_j x_j over the non-zero coefficients, accumulated left to right (the rounding of Python's
    ``sum``, without its generator overhead)."""
    out = None
    for c, x in zip(coeffs, xs):
        if c != 0.0:
            out = c * x if out is None else out + c * x
    return 0.0 * xs[0] if out is None else out
