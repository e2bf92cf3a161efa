"""The constant arguments of the balance controller's compiled calls (:mod:`.compiled`: ``balance_stage``,
``balance_finish``), built once per set-up controller as the records of :mod:`humanoid_sim.kernel.records`."""

from __future__ import annotations

from typing import Any

import numpy as np

from humanoid_sim.kernel.records import Contact, Coords
from humanoid_sim.kernel.support import FRAMES, SupportKernel, actuator_tables
from humanoid_sim.kernel.tree import TreeConstants
from humanoid_sim.robot.phases import FOOT_SPECS, TOE_POINT_FRAME, Phase, other_foot

FOOT_OF_MAIN = {spec.main_frame: foot for foot, spec in FOOT_SPECS.items()}   # O_3 -> R, O_4 -> L


class CompiledStage:
    """The constant arguments of ``balance_stage`` / ``balance_finish`` for a set-up controller: the tree
    (``tree.record``), thesis coordinates (``coords``), work buffers (``work``), per phase the contact rows
    (``contacts``) and the flat feet's toe frames (``split_toe``), per task mode the frame rows and the frames read
    (``swing_frames``, ``heel_frames``, ``need``), the actuator tables and the T components the QP bounds."""

    def __init__(self, ctl: Any) -> None:
        """``ctl``: a set-up ``BalanceController`` (its model, theta0, contact gains, actuators and bounded T)."""
        hm, model = ctl.hm, ctl.model
        self.tree = tr = TreeConstants(model, FRAMES)
        fi = tr.frame_index
        nf = len(FRAMES)
        self.work = tr.work()
        self.coords = Coords(np.asarray(hm.theta_v_idx, dtype=np.int64), np.asarray(hm.theta_sign, dtype=float),
                             np.asarray(hm.theta_q_idx, dtype=np.int64), np.ascontiguousarray(ctl.theta0, dtype=float))
        self.support = SupportKernel(hm, tr)
        kp, kd = float(ctl.dyn.gains.kp), float(ctl.dyn.gains.kd)
        self.contacts: dict[Phase, Contact] = {}
        self.split_toe: dict[Phase, np.ndarray] = {}
        for ph in Phase:
            c = ph.contacts
            jid = model.getJointId(c.locks[0])
            self.contacts[ph] = Contact(np.array([fi[f] for f in c.welds], dtype=np.int64), int(model.idx_qs[jid]),
                                        int(model.idx_vs[jid]), kp, kd)
            self.split_toe[ph] = np.array([fi[FOOT_SPECS[FOOT_OF_MAIN[f]].toe_frame] if f in FOOT_OF_MAIN else -1
                                           for f in c.welds], dtype=np.int64)
        # a double support with its trailing foot held flat on its main body, without its toe lock (flat_trail)
        self.flat_contacts: dict[Phase, Contact] = {}
        self.flat_split_toe: dict[Phase, np.ndarray] = {}
        for ph in Phase:
            if not ph.is_double_support:
                continue
            c = ph.contacts
            trail = FOOT_SPECS[other_foot(ph.support_foot)]
            jid = model.getJointId(c.locks[0])
            self.flat_contacts[ph] = Contact(np.array([fi[c.welds[0]], fi[trail.main_frame]], dtype=np.int64),
                                             int(model.idx_qs[jid]), int(model.idx_vs[jid]), kp, kd)
            self.flat_split_toe[ph] = np.array([fi[FOOT_SPECS[ph.support_foot].toe_frame], -1], dtype=np.int64)
        self.swing_frames = {f: np.array([fi[TOE_POINT_FRAME[f]], fi[FOOT_SPECS[f].toe_frame],
                                          fi[FOOT_SPECS[f].main_frame]], dtype=np.int64) for f in ("R", "L")}
        self.heel_frames = {f: np.array([fi[FOOT_SPECS[f].toe_frame], fi[FOOT_SPECS[f].main_frame], 0],
                                        dtype=np.int64) for f in ("R", "L")}
        self.no_frames = np.zeros(3, dtype=np.int64)

        def need(*frames: str) -> np.ndarray:      # the frames whose [J | drift] and velocity the call reads
            out = np.zeros(nf, dtype=np.bool_)
            out[[fi[f] for f in ("Pc_17", "O_17") + frames]] = True
            return out

        self.need = {(0, None): need()}
        for f in ("R", "L"):
            self.need[(1, f)] = need(TOE_POINT_FRAME[f], FOOT_SPECS[f].toe_frame, FOOT_SPECS[f].main_frame)
            self.need[(2, f)] = need(FOOT_SPECS[f].main_frame)
        self.act_tables = actuator_tables(model, ctl.act, ctl.act.limits)
        self.bounded = np.flatnonzero(ctl._exact).astype(np.int64)  # the T components the QP bounds linearly

    def actuators(self, limits: np.ndarray):
        """The actuator tables with the saturation limits ``limits`` (the controller's ``Actuators.limits``, which
        may have been replaced since set-up)."""
        if self.act_tables.limits is not limits:
            self.act_tables = self.act_tables._replace(limits=limits)
        return self.act_tables
