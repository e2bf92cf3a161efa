"""Contact-feasibility audit of a run: could real, unilateral foot contacts have produced the logged wrenches?

The simulator (like the thesis) welds the feet to the ground, so a constraint may pull on the ground, put the
centre of pressure outside the sole or need more friction than the floor has.  This module checks, for every
logged step and every foot in contact, from the results arrays alone:

1. normal force: ``f_n = f_z`` (world, N) of the foot's total ground force; ``f_n < -F_TOL`` is a weld
   *pulling* on the ground (infeasible);
2. centre of pressure: the point of the ground plane z = 0 where the foot's wrench has no horizontal moment,
   ``cop = (-M_y / f_z, M_x / f_z)`` (M about the world origin), against the sole polygon of the part of the foot
   that touches: the whole sole (heel to toe tip) for a foot held flat, the toe part only for the trailing foot
   of a double support phase (thesis: only the toe body 1 / 2 is held, the heel rises).  The polygon is the
   model's sole rectangle (``foot_sole`` of models/thesis_humanoid.yaml) carried by the logged pose of the
   welded body and projected on z = 0.  The margin is the signed distance to the polygon's edge (m; > 0 inside);
3. friction: ``|f_t| / f_n`` with ``f_t = (f_x, f_y)`` against the scenario's Coulomb coefficient mu;
4. the whole-body ZMP (the CoP of the summed foot wrenches) against the support polygon, the convex hull of the
   polygons of the feet in contact (signed distance, m).

Conventions for the counts (documented in docs/outputs.md, "The contact-feasibility audit"): a pulling foot has no
centre of pressure on its sole and violates the friction cone, so it counts as "CoP outside" and "friction
exceeded" as well; a foot whose normal force is within +-F_TOL of zero is unloaded (no CoP, no ratio) and violates
nothing; a non-finite wrench counts as a violation of every check.  A centre of pressure or ZMP counts as outside
only when it lies more than :data:`EDGE_TOL_M` outside its polygon (the margins keep the raw distance).  A step
whose feet together carry less than :data:`UNLOADED_WEIGHT_FRACTION` of the robot's weight is *unloaded* (the
robot is not standing on the ground: the first step on real ground, before any contact force): it is counted
apart and judged by no check.  All fractions are fractions of the loaded steps in which the foot (or, for the ZMP,
any foot) is in contact; the step is fixed, so they are fractions of time.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from humanoid_sim.errors import HumanoidSimError
from humanoid_sim.robot.phases import Phase
from humanoid_sim.robot.sole import (  # noqa: F401
    FEET,
    FLAT,
    NONE,
    TOE,
    SoleGeometry,
    _project,
    convex_hull,
    signed_distance,
    sole_polygons,
)

F_TOL = 1e-6
"""N: normal forces within +-F_TOL of zero are numerically zero (the constraint solver's force residuals are
orders of magnitude below; the feet carry hundreds of N)."""

FRICTION_TOL = 1e-9
"""Relative: a foot force up to mu (1 + FRICTION_TOL) times its normal force is inside the cone.  A foot sliding on
real ground sits exactly on the cone, and the ratio of its summed contact forces exceeds mu by round-off (measured
2.2e-16 relative on sim1_zmp on MuJoCo); needing more friction than the ground has misses by far more."""

EDGE_TOL_M = 1e-3
"""m: a centre of pressure or ZMP up to this far outside its polygon's edge counts as on it, in the audit's masks and
fractions and in the feasibility verdict (``analysis.summary.EDGE_VERDICT_TOL_M`` is this constant).  A foot
pivoting on an edge of real (MuJoCo's soft) ground puts its CoP just past the edge of the audit's polygon (the
sole rectangle at the logged pose, toe counted flat): measured 3-25 um on sim1_zmp and sim3_zmp.  A walk
that needs ground beyond its soles misses by centimetres: the thesis gaits on welded feet (sims 1-3) have no step
between 1e-9 m and 1 mm outside, and their CoP lies up to 0.26-1.19 m outside."""

UNLOADED_WEIGHT_FRACTION = 0.05
"""A step whose feet carry less than this fraction of the robot's weight in total (27 N for the thesis robot's 540 N)
is unloaded: the robot is not standing on the ground there (real ground's first logged step, before the soles
have taken any force: 0 N), and its CoP and ZMP are ratios of near-zero numbers.  A walking robot's feet carry
about its weight: the least measured was 0.94 of it on welded feet (sim1-3, sim1_zmp, sim3_zmp) and 0.43 on
MuJoCo's ground (sim1_zmp, a landing), so 5 % leaves a wide margin either way; 4 % is the MuJoCo engine's
per-foot touchdown threshold (20 N)."""


class AuditError(HumanoidSimError, ValueError):
    """The results arrays are inconsistent or malformed (message names the array and the problem)."""


# ------------------------------------------------------------------------------------------------ report
@dataclass
class AuditReport:
    """Per-step audit arrays (N steps; feet ordered right, left) and the totals of :meth:`summary`.

    t (N,) s; phase_name (N,) basic phase names; kind (N, 2) NONE/FLAT/TOE; f_n (N, 2) N, NaN when not in contact;
    f_t (N, 2) N; cop (N, 2, 2) m (world x, y on z = 0), NaN when unloaded; cop_margin (N, 2) m (> 0 inside the
    sole); friction_ratio (N, 2) |f_t|/f_n where f_n > F_TOL; zmp (N, 2) m; zmp_margin (N,) m (> 0 inside the
    support polygon); polygons: per step, per foot, the (k, 2) sole polygon in the world or None; edge_tol (m):
    how far outside an edge a CoP or ZMP may lie and still count as on it; unloaded (N,): the steps whose feet
    carry less than ``unloaded_below_N`` in total (judged by no check; by default none is); unloaded_below_N: that
    threshold (N), None when the audit had no weight to scale it.
    """

    mu: float
    t: np.ndarray
    phase_name: np.ndarray
    kind: np.ndarray
    f_n: np.ndarray
    f_t: np.ndarray
    cop: np.ndarray
    cop_margin: np.ndarray
    friction_ratio: np.ndarray
    zmp: np.ndarray
    zmp_margin: np.ndarray
    polygons: list[list[np.ndarray | None]]
    edge_tol: float = EDGE_TOL_M
    unloaded: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    unloaded_below_N: float | None = None

    def __post_init__(self) -> None:
        if len(self.unloaded) != len(self.t):    # the default: no step is unloaded
            if len(self.unloaded):
                raise AuditError(f"unloaded: expected {len(self.t)} steps, got {len(self.unloaded)}")
            self.unloaded = np.zeros(len(self.t), dtype=bool)

    # violation masks (N, 2) / (N,), true where the check fails; False where the foot is not in contact and at
    # the unloaded steps
    @property
    def in_contact(self) -> np.ndarray:
        return self.kind != NONE

    @property
    def judged(self) -> np.ndarray:
        """(N, 2) the feet in contact at the steps that are not unloaded: where the checks apply."""
        return self.in_contact & ~self.unloaded[:, None]

    @property
    def pulling(self) -> np.ndarray:
        return self.judged & ~(self.f_n >= -F_TOL)

    @property
    def loaded(self) -> np.ndarray:
        return self.in_contact & (self.f_n > F_TOL)

    @property
    def cop_outside(self) -> np.ndarray:
        outside = self.loaded & ~self.unloaded[:, None] & ~(self.cop_margin >= -self.edge_tol)
        return outside | self.pulling

    @property
    def friction_exceeded(self) -> np.ndarray:
        exceeded = self.loaded & ~self.unloaded[:, None] & ~(self.friction_ratio <= self.mu * (1.0 + FRICTION_TOL))
        return exceeded | self.pulling

    @property
    def any_contact(self) -> np.ndarray:
        return np.asarray(self.in_contact.any(axis=1))

    @property
    def zmp_outside(self) -> np.ndarray:
        return self.any_contact & ~self.unloaded & ~(self.zmp_margin >= -self.edge_tol)

    @property
    def feasible(self) -> np.ndarray:
        """(N,) true where every check passes at the step."""
        return ~(self.cop_outside.any(axis=1) | self.friction_exceeded.any(axis=1) | self.zmp_outside)

    def _totals(self, rows: np.ndarray) -> dict[str, Any]:
        """The totals over the steps ``rows`` (N,): every count and extremum over those that are not unloaded,
        except ``steps`` and ``contact_steps`` (all of them)."""
        def frac(mask: np.ndarray, among: np.ndarray) -> float | None:
            n = int(among.sum())
            return float(mask[among].sum()) / n if n else None

        def ext(x: np.ndarray, among: np.ndarray, fn) -> float | None:
            v = x[among]
            v = v[np.isfinite(v)]
            return float(fn(v)) if v.size else None

        out: dict[str, Any] = {
            "steps": int(rows.sum()),
            "contact_steps": {}, "min_normal_force_N": {}, "pulling_fraction": {}, "cop_outside_fraction": {},
            "min_cop_margin_m": {}, "max_friction_ratio": {}, "friction_exceeded_fraction": {},
        }
        judged = rows & ~self.unloaded
        for i, foot in enumerate(FEET):
            out["contact_steps"][foot] = int((rows & self.in_contact[:, i]).sum())
            c = judged & self.in_contact[:, i]
            out["min_normal_force_N"][foot] = ext(self.f_n[:, i], c, np.min)
            out["pulling_fraction"][foot] = frac(self.pulling[:, i], c)
            out["cop_outside_fraction"][foot] = frac(self.cop_outside[:, i], c)
            out["min_cop_margin_m"][foot] = ext(self.cop_margin[:, i], c, np.min)
            out["max_friction_ratio"][foot] = ext(self.friction_ratio[:, i], c, np.max)
            out["friction_exceeded_fraction"][foot] = frac(self.friction_exceeded[:, i], c)
        c = judged & self.any_contact
        out["zmp_outside_fraction"] = frac(self.zmp_outside, c)
        out["min_zmp_margin_m"] = ext(self.zmp_margin, c, np.min)
        out["infeasible_fraction"] = frac(~self.feasible, c)
        out["unloaded_steps"] = int((rows & self.unloaded).sum())
        return out

    def summary(self) -> dict[str, Any]:
        """The ``contact`` section of summary.json: totals over the run and per basic phase name, and the audit's
        thresholds (``edge_tolerance_m``: :data:`EDGE_TOL_M`; ``unloaded_below_N``: the unloaded steps' total
        normal force bound, None when the audit had none)."""
        out = {"friction_coefficient": float(self.mu), "force_tolerance_N": F_TOL,
               **self._totals(np.ones(len(self.t), dtype=bool))}
        out["per_phase"] = {p.value: self._totals(self.phase_name == p.value) for p in Phase
                            if np.any(self.phase_name == p.value)}
        out["edge_tolerance_m"] = float(self.edge_tol)
        out["unloaded_below_N"] = None if self.unloaded_below_N is None else float(self.unloaded_below_N)
        return out


# ------------------------------------------------------------------------------------------------ audit
def contact_kinds(phase_name: Sequence[str]) -> np.ndarray:
    """(N, 2) contact kind of the right and left foot from the basic phase names (phases.Phase)."""
    out = np.zeros((len(phase_name), 2), dtype=int)
    for k, name in enumerate(phase_name):
        try:
            ph = Phase(str(name))
        except ValueError:
            raise AuditError(f"phase name at step {k}: expected one of {[p.value for p in Phase]}, "
                             f"got {name!r}") from None
        out[k, FEET.index(ph.support_foot)] = FLAT
        if ph.trailing_toe is not None:
            out[k, FEET.index(ph.trailing_toe)] = TOE
    return out


def audit_contacts(t: np.ndarray, phase_name: Sequence[str], foot_wrench: np.ndarray, kind: np.ndarray,
                   polygons: list[list[np.ndarray | None]], mu: float,
                   unloaded_below_N: float | None = None) -> AuditReport:
    """Audit given wrenches against given sole polygons.

    t (N,) s; phase_name (N,) basic phase names (grouping only); foot_wrench (N, 2, 6) per foot [force; moment
    about the world origin], world frame, N and N m; kind (N, 2) NONE/FLAT/TOE; polygons[k][i] the (m, 2) convex
    polygon (world x, y, m) of foot i at step k, or None when it is not in contact; mu the friction coefficient;
    unloaded_below_N: the steps where both feet's normal forces (f_z, whether or not the phase holds the foot)
    sum to less than this are unloaded (module docstring), N; None: none is.
    """
    t = np.asarray(t, dtype=float)
    n = len(t)
    W = np.asarray(foot_wrench, dtype=float)
    kind = np.asarray(kind, dtype=int)
    if W.shape != (n, 2, 6):
        raise AuditError(f"foot_wrench: expected shape ({n}, 2, 6), got {W.shape}")
    if kind.shape != (n, 2):
        raise AuditError(f"contact kinds: expected shape ({n}, 2), got {kind.shape}")
    if len(phase_name) != n or len(polygons) != n:
        raise AuditError(f"phase_name / polygons: expected {n} entries, got {len(phase_name)} / {len(polygons)}")
    if not (np.isfinite(mu) and mu > 0):
        raise AuditError(f"friction coefficient: expected a positive number, got {mu!r}")
    if unloaded_below_N is not None and not (np.isfinite(unloaded_below_N) and unloaded_below_N >= 0):
        raise AuditError(f"unloaded_below_N: expected a force >= 0 N or None, got {unloaded_below_N!r}")
    polys = [[None if p is None else convex_hull(p) for p in row] for row in polygons]
    for k in range(n):
        for i in range(2):
            if (kind[k, i] != NONE) != (polys[k][i] is not None):
                raise AuditError(f"step {k}, foot {FEET[i]}: contact kind {kind[k, i]} but polygon "
                                 f"{'missing' if polys[k][i] is None else 'given'}")
    contact = kind != NONE
    f = W[:, :, :3]
    m = W[:, :, 3:]
    f_n = np.where(contact, f[:, :, 2], np.nan)
    f_t = np.where(contact, np.hypot(f[:, :, 0], f[:, :, 1]), np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        loaded = contact & (f_n > F_TOL)
        cop = np.stack([-m[:, :, 1] / f[:, :, 2], m[:, :, 0] / f[:, :, 2]], axis=-1)
        cop[~loaded] = np.nan
        ratio = np.where(loaded, f_t / f_n, np.nan)
        ftot = np.where(contact[:, :, None], f, 0.0).sum(axis=1)
        mtot = np.where(contact[:, :, None], m, 0.0).sum(axis=1)
        zmp = np.stack([-mtot[:, 1] / ftot[:, 2], mtot[:, 0] / ftot[:, 2]], axis=-1)
        zmp[~(ftot[:, 2] > F_TOL)] = np.nan
    cop_margin = np.full((n, 2), np.nan)
    zmp_margin = np.full(n, np.nan)
    for k in range(n):
        for i in range(2):
            poly = polys[k][i]
            if loaded[k, i] and poly is not None:     # (a loaded foot is in contact: it has its polygon)
                cop_margin[k, i] = signed_distance(cop[k, i], poly)
        if contact[k].any():
            hull = convex_hull(np.concatenate([polys[k][i] for i in range(2) if contact[k, i]]))
            zmp_margin[k] = signed_distance(zmp[k], hull)
    # a non-finite total is not "below" the bound: such a step stays judged (and fails its checks)
    unloaded = np.zeros(n, dtype=bool) if unloaded_below_N is None else f[:, :, 2].sum(axis=1) < unloaded_below_N
    return AuditReport(mu=float(mu), t=t, phase_name=np.asarray([str(s) for s in phase_name]), kind=kind,
                       f_n=f_n, f_t=f_t, cop=cop, cop_margin=cop_margin, friction_ratio=ratio, zmp=zmp,
                       zmp_margin=zmp_margin, polygons=polys, unloaded=unloaded,
                       unloaded_below_N=None if unloaded_below_N is None else float(unloaded_below_N))


def robot_weight(hm: Any) -> float:
    """The robot's weight, N: its total mass times the magnitude of its model's gravity."""
    return float(pin.computeTotalMass(hm.model) * np.linalg.norm(hm.model.gravity.linear))


def audit_results(results: Mapping[str, np.ndarray], hm: Any, mu: float, real_ground: bool = False) -> AuditReport:
    """Audit a run from its results arrays (``results.npz`` contents or ``SimLog.arrays()`` plus
    ``phase_names``): ``t``, ``phase``, ``q``, ``foot_wrench``, ``in_contact``, ``phase_names``.  The steps whose
    feet carry less than :data:`UNLOADED_WEIGHT_FRACTION` of the robot's weight (:func:`robot_weight`) are
    unloaded.  ``real_ground``: the run's feet stood on real (unilateral) ground, so either part of a foot in
    contact may carry load whatever the phase assumes: each foot's polygon is the hull of both parts' footprints
    (:func:`humanoid_sim.robot.sole.sole_polygons`, ``articulated``); on welded feet it is the part the phase holds."""
    for key in ("t", "phase", "q", "foot_wrench", "in_contact", "phase_names"):
        if key not in results:
            raise AuditError(f"results: missing array {key!r}")
    t = np.asarray(results["t"], dtype=float)
    n = len(t)
    below = UNLOADED_WEIGHT_FRACTION * robot_weight(hm)
    if n == 0:
        return audit_contacts(t, [], np.zeros((0, 2, 6)), np.zeros((0, 2), dtype=int), [], mu, unloaded_below_N=below)
    names = np.asarray(results["phase_names"]).astype(str)
    idx = np.asarray(results["phase"], dtype=int)
    if idx.min() < 0 or idx.max() >= len(names):
        raise AuditError(f"phase: indices {idx.min()}..{idx.max()} outside the {len(names)} phase names")
    phase_name = names[idx]
    kind = contact_kinds(phase_name)
    logged = np.asarray(results["in_contact"], dtype=bool)
    if logged.shape != kind.shape or np.any(logged != (kind != NONE)):
        bad = np.argwhere(logged != (kind != NONE))
        raise AuditError(f"in_contact disagrees with the phase's contact set at step {bad[0][0] if len(bad) else '?'}"
                         f" (shape {logged.shape})")
    polys = sole_polygons(hm, results["q"], kind, articulated=real_ground)
    return audit_contacts(t, phase_name, results["foot_wrench"], kind, polys, mu, unloaded_below_N=below)
