"""The Python side of the compiled support-foot projection and of the tables the compiled stages share:
:class:`SupportKernel` (the weld engine's projection and Runge-Kutta advance, :mod:`.projection`),
:func:`actuator_tables` (:mod:`.actuators`) and :class:`StageOutput` (what a compiled stage returns).  Independent
of any controller: the weld engine and both controllers use it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from humanoid_sim.dynamics.contact.constraints import Anchors, record_anchors
from humanoid_sim.kernel.log import LOG_SIZE, StageLog
from humanoid_sim.kernel.projection import advance_on_support, project_on_support
from humanoid_sim.kernel.records import ActuatorTables, Anchor, SupportFoot
from humanoid_sim.kernel.tree import TreeConstants
from humanoid_sim.robot.actuators import Actuators
from humanoid_sim.robot.frames import TASK_FRAMES
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.robot.phases import FOOT_SPECS, Phase

FRAMES = list(TASK_FRAMES)
"""Frames the kernel evaluates: the task frames (Pc_17, O_17, P_tpR, P_tpL, O_1, O_2, O_3, O_4), in the row order
of ``kernel.kinematics.F_PC17 ... F_O4``."""
__all__ = ["FRAMES", "LOG_SIZE", "StageOutput", "SupportKernel", "actuator_tables"]


@dataclass
class StageOutput:
    """What one compiled stage returns (SI units; see ``ThesisController.evaluate``): the accelerations a (nv,),
    multipliers lam (m,), command accelerations thdd_c (26,), thesis torques T_cmd (26,), joint torques tau (nv,)
    and the log vector (layout :mod:`humanoid_sim.kernel.log`; :attr:`record` reads it by name)."""

    a: np.ndarray
    lam: np.ndarray
    thdd_c: np.ndarray
    T_cmd: np.ndarray
    tau: np.ndarray
    log: np.ndarray

    @property
    def record(self) -> StageLog:
        return StageLog(self.log)

    @property
    def status(self) -> float:
        """0: a regular stage; > 0: an actuator saturates; < 0: a singular normal matrix or KKT system."""
        return self.record.status

    @property
    def saturated(self) -> bool:
        return self.record.status > 0.0

    @property
    def failed(self) -> bool:
        """A normal matrix or KKT system was singular (the reference path then raises its error)."""
        return self.record.status < 0.0


def check_contacts(phase: Phase) -> None:
    """The compiled stages expect the support foot's weld first and one toe lock."""
    contacts = phase.contacts
    if len(contacts.locks) != 1 or contacts.welds[0] != FOOT_SPECS[phase.support_foot].main_frame:
        raise ValueError(f"{phase.value}: the kernel expects the support foot's weld first and one toe lock")


class SupportKernel:
    """The compiled projection onto the support foot and the compiled Runge-Kutta advance of the weld engine
    (``WeldEngine.project_on_support``), independent of any controller."""

    def __init__(self, hm: HumanoidModel, tree: TreeConstants | None = None) -> None:
        model = hm.model
        self.hm = hm
        self.tree = tree if tree is not None else TreeConstants(model, FRAMES)
        tr = self.tree
        fi = tr.frame_index
        self._frames: dict[Phase, tuple] = {}
        self._feet: dict[Phase, SupportFoot] = {}
        for ph in Phase:
            check_contacts(ph)
            contacts = ph.contacts
            jid = model.getJointId(contacts.locks[0])
            w0 = fi[contacts.welds[0]]
            self._frames[ph] = (contacts.welds, contacts.locks[0])
            self._feet[ph] = SupportFoot(int(model.idx_qs[jid]), int(model.idx_vs[jid]), tr.fparent[w0], tr.fR[w0],
                                         tr.fp[w0])
        self._anchor_cache: dict[Phase, tuple] = {}
        self._coeff_cache: dict = {}
        self._n_rates = 0
        """Stage rates :meth:`advance` passes to the compiled call (set by :meth:`warm_up`; fewer are padded)."""

    def anchor(self, phase: Phase, anchors: Anchors) -> Anchor:
        """The phase's weld anchors and lock anchor as arrays (:class:`~humanoid_sim.kernel.records.Anchor`), re-read
        whenever the Anchors object, one of its placement entries or its toe angle is not the one last read for this
        phase (the simulator replaces anchors at phase changes; an SE3 modified in place would not be noticed)."""
        frames, toe = self._frames[phase]
        placements = anchors.placements
        angle = anchors.joint_positions[toe]
        hit = self._anchor_cache.get(phase)
        if hit is not None and hit[0] is anchors and hit[2] == angle:
            for f, M in zip(frames, hit[1]):   # (a loop, not any() over a generator: this runs at every stage)
                if placements[f] is not M:
                    break
            else:
                return hit[3]
        Ms = tuple(placements[f] for f in frames)
        val = Anchor(np.array([M.rotation for M in Ms]), np.array([M.translation for M in Ms]), float(angle))
        self._anchor_cache[phase] = (anchors, Ms, angle, val)
        return val

    def project(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The compiled ``WeldEngine.project_on_support`` for the support foot of ``phase``."""
        q_out, v_out = np.empty_like(q), np.empty_like(v)
        project_on_support(q, v, self.anchor(phase, anchors), self._feet[phase], self.tree.record, q_out, v_out)
        return q_out, v_out

    def advance(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray, coeffs: tuple[float, ...],
                vs: list[np.ndarray], accs: list[np.ndarray], h: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`project` of (q integrated by h sum c_j vs_j, v + h sum c_j accs_j): the integrator's stage and
        step-end states (``RungeKutta.step``'s ``advance``)."""
        anchor = self.anchor(phase, anchors)
        q_out, v_out = np.empty_like(q), np.empty_like(v)
        n = len(vs)
        if n < self._n_rates:  # one compiled variant: pad with zero coefficients, which the sum skips (same bits)
            pad = self._n_rates - n
            vs, accs = list(vs) + [v] * pad, list(accs) + [v] * pad
        advance_on_support(q, v, self._coeffs(coeffs, n), tuple(vs), tuple(accs), h, anchor, self._feet[phase],
                           self.tree.record, q_out, v_out)
        return q_out, v_out

    def warm_up(self, q: np.ndarray, n_stages: int) -> None:
        """Compile (or load from numba's cache) every entry point a run will call, before it starts: the projection
        and the advance, so that no compilation lands inside a timed run.  ``n_stages``: the integrator's stage
        count; :meth:`advance` passes that many rates whatever the stage (padding with zero coefficients), so that
        one compiled variant serves them all."""
        self._n_rates = max(self._n_rates, int(n_stages))
        phase = Phase.LFFSSP
        anchors = record_anchors(self.hm.model, q, phase.contacts)
        v = np.zeros(self.tree.nv)
        self.project(phase, anchors, q, v)
        n = self._n_rates
        self.advance(phase, anchors, q, v, (1.0,) * n, [v] * n, [v] * n, 0.0)

    def _coeffs(self, coeffs: tuple[float, ...], n: int) -> np.ndarray:
        """The first n Runge-Kutta coefficients as a float array, zero-padded to the :meth:`advance` rate count
        (cached per tableau row)."""
        key = (coeffs, n, self._n_rates)
        arr = self._coeff_cache.get(key)
        if arr is None:
            arr = np.zeros(max(n, self._n_rates))
            arr[:n] = coeffs[:n]
            self._coeff_cache[key] = arr
        return arr


def actuator_tables(model: pin.Model, act: Actuators, limits: np.ndarray) -> ActuatorTables:
    """The actuator groups of ``act`` (``Actuators._groups``) as the flat tables ``kernel.actuators.thesis_torques``
    reads, with the saturation limits ``limits`` (26,, N m) of T (see :class:`~humanoid_sim.kernel.records.
    ActuatorTables`)."""
    g1, g3, gs = [], [], []
    hj = np.array(act._hj_unique, dtype=np.int64)
    for gi, (rows, comps, hjid, sl, tj, higher_is_parent) in enumerate(act._groups):
        slot = act._hj_unique.index(hjid)
        vidx = act._vidx[sl]
        sg = act._signs[sl].astype(np.int64)
        if len(rows) == 1:
            g1.append([rows[0], vidx[0], sg[0], slot, comps[0]])
        elif len(rows) == 3:
            if list(comps) != [0, 1, 2]:
                raise ValueError(f"actuator group {gi}: three components must be x, y, z")
            g3.append(list(rows) + list(vidx) + list(sg) + [slot])
        else:
            if higher_is_parent:
                raise ValueError(f"actuator group {gi}: the two-component (universal) joint must carry a "
                                 "leaf body on its child side")
            gs.append(list(rows) + list(comps) + [tj, slot])
    for g in gs:
        if any(model.parents[j] == g[4] for j in range(model.njoints)):
            raise ValueError(f"joint {model.names[g[4]]!r} of a universal actuator is not a leaf")
    return ActuatorTables(np.array(g1, dtype=np.int64), np.array(g3, dtype=np.int64), np.array(gs, dtype=np.int64),
                          hj, np.array([model.inertias[g[4]].mass for g in gs], dtype=float),
                          np.array([model.inertias[g[4]].lever for g in gs], dtype=float),
                          np.array([model.inertias[g[4]].inertia for g in gs], dtype=float),
                          np.array(model.gravity.linear, dtype=float), limits)
