"""Body parameters in the form the thesis's chapter-4 formulas use them.

The formulas of chapter 4 are written with scalar dimensions (l1, c1, l3x, ..., thesis L936-992) rather than with
vectors, so this module exposes exactly those scalars plus the masses m_k, the inertia tensors J_c,k^(k) (about
the CoM of body k, resolved in frame k, kg m^2, Table 2.5 L826-834) and g (m/s^2).

Left and right dimensions are equal in the thesis (Appendix B lists "L1 = L2", "C3x = C4x", ...; L4966-4978),
so the left-side symbols (l2, c2, l4x, l4z, c4x, c4z, l10, c10, l12, c12, c24, l24y, l24z) are aliases of the
right-side ones.  The corrected foot values c3x = 0.0286 and c3z = 0.0429 (errata A-6) come from the model YAML.

Source of the numbers: ``models/thesis_humanoid.yaml`` (parsed by ``urdf_gen.spec``), never re-typed here.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from humanoid_sim.errors import InputError

REAL_BODIES: tuple[int, ...] = (1, 3, 9, 11, 2, 4, 10, 12, 17, 20, 23, 24, 27)
"""The 13 real bodies in the order of Z and K (eqs. 4.70/4.71, L2763)."""

# Left-side scalar -> the right-side scalar it equals (Appendix B "L1 = L2", ..., L4966-4978).
_ALIASES = {
    "l2": "l1", "c2": "c1", "l4x": "l3x", "l4z": "l3z", "c4x": "c3x", "c4z": "c3z",
    "l10": "l9", "c10": "c9", "l12": "l11", "c12": "c11", "c24": "c23", "l24y": "l23y", "l24z": "l23z",
}


class ThesisParamError(InputError):
    """Missing or inconsistent body parameter."""


@dataclass(frozen=True)
class ThesisParams:
    """Scalars, masses and inertias of the thesis humanoid.

    Attributes:
        d: scalar dimensions by thesis symbol (m), left aliases included.
        mass: m_k by real body number (kg).
        inertia: J_c,k^(k) by real body number (3x3, kg m^2, about CoM k, frame k).
        g: gravitational acceleration magnitude (m/s^2), acting along -u3 of frame 0.
        C0: C^(0,k) of every body at the zero posture (3x3).
    """

    d: dict[str, float]
    mass: dict[int, float]
    inertia: dict[int, np.ndarray]
    g: float
    C0: np.ndarray

    def __getitem__(self, name: str) -> float:
        try:
            return self.d[name]
        except KeyError:
            raise ThesisParamError(f"unknown thesis dimension {name!r}; known: {sorted(self.d)}") from None


def params_from_spec(spec) -> ThesisParams:
    """Build :class:`ThesisParams` from a ``urdf_gen.spec.RobotSpec`` (duck-typed: dims, bodies, gravity, C0)."""
    d = {k: float(v) for k, v in spec.dims.items()}
    for left, right in _ALIASES.items():
        if right not in d:
            raise ThesisParamError(f"dimension {right!r} (needed for {left!r}) missing from the spec")
        d.setdefault(left, d[right])
    mass, inertia = {}, {}
    for k in REAL_BODIES:
        if k not in spec.bodies:
            raise ThesisParamError(f"real body {k} missing from the spec")
        b = spec.bodies[k]
        if b.virtual or b.mass <= 0.0:
            raise ThesisParamError(f"body {k} must be a real body with positive mass, got mass {b.mass!r}")
        mass[k] = float(b.mass)
        inertia[k] = np.array(b.inertia, dtype=float).reshape(3, 3)
    return ThesisParams(d=d, mass=mass, inertia=inertia, g=float(spec.gravity), C0=np.array(spec.C0, float))


def load_params(path: str | Path | None = None) -> ThesisParams:
    """Parse the model YAML (default ``models/thesis_humanoid.yaml``) and build :class:`ThesisParams`."""
    from urdf_gen.spec import load_spec  # local import: keep this module importable without the package

    if path is None:
        from humanoid_sim.paths import MODELS_DIR

        path = MODELS_DIR / "thesis_humanoid.yaml"
    return params_from_spec(load_spec(path))
