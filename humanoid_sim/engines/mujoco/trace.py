"""The MuJoCo engine's full-rate trace (:mod:`humanoid_sim.interfaces.trace`): a row per MuJoCo step.

:class:`TraceRecorder` keeps, right after each MuJoCo step (``MujocoSim.advance(1)``), the state at the step's start
(MuJoCo's qpos and qvel), its acceleration (``qacc``), the ground's wrenches on the feet and on the foot bodies
(those of that state), the step's time, loop step, basic phase and the index of the control update whose torques
it held; and per control update its torques.  :meth:`TraceRecorder.build` turns the rows into a
:class:`humanoid_sim.interfaces.trace.Trace` in Pinocchio's conventions after the run.

A row is one compiled call (:func:`humanoid_sim.engines.mujoco.compiled.trace_row`) when the engine is compiled;
:func:`contact_record` is the NumPy reference of its wrenches, and the path taken for contacts the compiled reader
does not read (a pyramidal cone, terrain geoms, contacts without constraint rows or of mixed ``dim``).
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from humanoid_sim.engines.mujoco import compiled as mjc
from humanoid_sim.engines.mujoco.contact import FootContact, _cross, _tables, foot_contacts
from humanoid_sim.engines.mujoco.model import FEET, MujocoModel
from humanoid_sim.engines.mujoco.sim import MujocoSim
from humanoid_sim.engines.weld import BASIC
from humanoid_sim.interfaces.trace import RowBuffer, Trace
from humanoid_sim.robot.actuators import Actuators
from humanoid_sim.robot.model import FOOT_BODY, TOE_BODY

_PHASE_OF_BASIC = sorted(BASIC, key=BASIC.__getitem__)  # basic phase index -> Phase

_NO_GEOM = np.zeros((0, 2), dtype=np.int32)
_NO_POS = np.zeros((0, 3))
_NO_FRAME = np.zeros((0, 9))
_NO_INT = np.zeros(0, dtype=np.int32)
_NO_FLOAT = np.zeros(0)
"""Empty contact arrays for :func:`humanoid_sim.engines.mujoco.compiled.trace_row` when it writes no wrenches."""


def trace_layout(nq: int, nv: int) -> dict[str, Any]:
    """Columns of a trace row: 4 scalars (t in s, loop step, basic phase, control update), then MuJoCo's qpos (nq),
    qvel and qacc (nv), the feet's wrenches (2 x 6) and centres of pressure (2 x 3), the foot bodies' forces and
    moments (4 x 3 each): the order :func:`humanoid_sim.engines.mujoco.compiled.trace_row` writes."""
    cols: dict[str, Any] = {}
    at = 4
    for name, size in (("qpos", nq), ("qvel", nv), ("qacc", nv), ("fw", 12), ("cop", 6), ("bf", 12), ("bm", 12)):
        cols[name] = slice(at, at + size)
        at += size
    cols["width"] = at
    return cols


def foot_body_ids(mm: MujocoModel) -> dict[int, int]:
    """MuJoCo body id of each thesis foot body (1, 2: toes R, L; 3, 4: main bodies R, L)."""
    ids = {TOE_BODY[f]: mm.foot_bodies[f][0] for f in FEET}
    ids.update({FOOT_BODY[f]: mm.foot_bodies[f][1] for f in FEET})
    return ids


def body_wrenches(mm: MujocoModel, data: mujoco.MjData, foot: str, c: FootContact, bf: np.ndarray,
                  bm: np.ndarray) -> None:
    """Write into rows ``body - 1`` of bf / bm (4, 3) the ground's force on each of the foot's loaded bodies (toe,
    main) and its moment about the body's CoM, in the body frame (N, N m), from its contacts ``c``: per body, the
    sums over its contacts (MuJoCo's order) of the force and of arm x force, then rotated."""
    boxes = c.point_geom
    bodies = (TOE_BODY[foot], FOOT_BODY[foot])
    ids = [mm.foot_bodies[foot][0], mm.foot_bodies[foot][1]]
    arm = c.points - data.xipos[ids][boxes]              # each contact from its body's CoM, world frame
    g = np.empty((len(boxes), 6))
    g[:, :3] = c.point_force
    g[:, 3:] = _cross(arm, c.point_force)
    present = set(boxes.tolist())
    for box, body in enumerate(bodies):
        if box not in present:
            continue
        total = g[boxes == box].sum(axis=0)
        Rt = data.xmat[ids[box]].reshape(3, 3).T
        bf[body - 1] = Rt @ total[:3]
        bm[body - 1] = Rt @ total[3:]


def contact_record(mm: MujocoModel, data: mujoco.MjData, fw: np.ndarray, cop: np.ndarray, bf: np.ndarray,
                   bm: np.ndarray) -> None:
    """The ground's wrenches at the current MuJoCo data by :func:`.contact.foot_contacts` and :func:`body_wrenches`
    (the reference of :func:`humanoid_sim.engines.mujoco.compiled.contact_wrenches`): ``fw`` (2, 6) per foot (R, L)
    the force (N, world frame) and its moment about the world origin (N m), ``cop`` (2, 3) the centres of pressure
    (m, NaN without normal force), ``bf`` / ``bm`` (4, 3) per foot body (row body - 1) force and moment about its
    CoM in the body frame (N, N m)."""
    feet = foot_contacts(mm, data)
    bf[:] = 0.0
    bm[:] = 0.0
    for i, f in enumerate(FEET):
        c = feet[f]
        fw[i, :3], fw[i, 3:] = c.force, c.moment
        cop[i] = c.cop                                   # NaN without normal force
        if len(c.points):
            body_wrenches(mm, data, f, c, bf, bm)


class TraceRecorder:
    """The rows of a run's full-rate trace (module docstring).

    Args:
        sim: the engine's MuJoCo simulation (its data and its state before the last step are read).
        act: the actuator map (thesis torques of a controller that gives joint torques only).
        compiled: rows by the compiled writer (else NumPy); ``wrench_kernel``: its wrenches too (else
            :func:`contact_record`).
    """

    def __init__(self, sim: MujocoSim, act: Actuators, compiled: bool, wrench_kernel: bool) -> None:
        self.sim = sim
        self.mm = sim.mm
        self.act = act
        self.compiled = compiled
        self.wrench_kernel = compiled and wrench_kernel
        self.cols = trace_layout(self.mm.model.nq, self.mm.model.nv)
        data = sim.data
        self._data = data
        # MjData's fixed-size arrays do not move, nor does the simulation's copy of the state before a step: taken once
        self._fixed = (data.xipos, data.xmat, data.qacc)
        self._before = sim.state_before_step()
        self._group = _tables(self.mm).pair_array
        body = foot_body_ids(self.mm)
        self.bodies = np.array([body[b] for b in (1, 2, 3, 4)], dtype=np.intp)   # log rows: thesis bodies 1-4
        self._wrench_at = self.cols["fw"].start
        self._no_sat = np.zeros(26, dtype=bool)
        self.start()

    def start(self) -> None:
        """Forget the rows and control updates (a new run)."""
        self._rows = RowBuffer(self.cols["width"])
        self._block: np.ndarray | None = None
        self._i = -1
        self.updates: list[tuple[np.ndarray, Any, Any, Any]] = []   # per control update: tau, T, saturated, T_cmd
        self._update = -1                                            # the last one's index

    def control(self, tau: np.ndarray, T: Any, saturated: Any, T_cmd: Any) -> None:
        """A control update starts: its generalized torques (copied) and thesis torques (None when not given)."""
        self.updates.append((tau.copy(), T, saturated, T_cmd))
        self._update += 1

    def row(self, t: float, k: int, basic: int) -> None:
        """Record the MuJoCo step just taken at time ``t`` (s) of loop step ``k`` in basic phase ``basic``: the state
        at its start, its acceleration and the ground's wrenches (those of that state), and the last control
        update (whose torques it held)."""
        block, i = self._rows.next_slot()
        self._block, self._i = block, i
        data = self._data
        qpos, qvel = self._before
        xipos, xmat, qacc = self._fixed
        if self.compiled:
            if self.wrench_kernel:
                con = data.contact
                if mjc.trace_row(con.geom, con.pos, con.frame, con.dim, con.efc_address, data.efc_force, self._group,
                                 self.mm.floor_geom, self.bodies, xipos, xmat, qpos, qvel, qacc, t, k, basic,
                                 self._update, True, block, i):
                    return
            else:
                # the wrenches are the NumPy path's: no contact arrays to hand over (empty stand-ins)
                mjc.trace_row(_NO_GEOM, _NO_POS, _NO_FRAME, _NO_INT, _NO_INT, _NO_FLOAT, self._group,
                              self.mm.floor_geom, self.bodies, xipos, xmat, qpos, qvel, qacc, t, k, basic,
                              self._update, False, block, i)
        else:
            c, row = self.cols, block[i]
            row[0], row[1], row[2], row[3] = t, k, basic, self._update
            row[c["qpos"]] = qpos
            row[c["qvel"]] = qvel
            row[c["qacc"]] = qacc
        self._write_wrenches(block[i])

    def _write_wrenches(self, row: np.ndarray) -> None:
        c = self.cols
        contact_record(self.mm, self._data, row[c["fw"]].reshape(2, 6), row[c["cop"]].reshape(2, 3),
                       row[c["bf"]].reshape(4, 3), row[c["bm"]].reshape(4, 3))

    def last_wrenches(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The last row's ground wrenches (copies): foot wrenches (2, 6), centres of pressure (2, 3), body forces and
        moments (4, 3) (:func:`contact_record`'s layout)."""
        assert self._block is not None, "no row recorded yet"
        w = self._block[self._i, self._wrench_at:self._wrench_at + mjc.WRENCH_FLOATS]
        return w[:12].reshape(2, 6).copy(), w[12:18].reshape(2, 3).copy(), w[18:30].reshape(4, 3).copy(), \
            w[30:].reshape(4, 3).copy()

    def foot_wrenches(self) -> np.ndarray:
        """The last row's foot wrenches (2, 6), a view into the trace (copy it to keep it): per foot (R, L) the
        ground's force (N, world frame) and its moment about the world origin (N m)."""
        assert self._block is not None, "no row recorded yet"
        return self._block[self._i, self._wrench_at:self._wrench_at + 12].reshape(2, 6)

    def build(self) -> Trace | None:
        """The run's trace, in Pinocchio's conventions (None before any row): the state maps of
        :class:`humanoid_sim.engines.mujoco.state.StateMap` on every row (the compiled path in one call).  Torques
        are those of the control update each step held; the thesis torques of a controller that gives joint torques
        only are derived at every step's state."""
        R = self._rows.array()
        n = len(R)
        if n == 0:
            return None
        c, smap = self.cols, self.sim.map
        nq, nv = self.mm.model.nq, self.mm.model.nv
        if self.compiled:
            Q, V, A = mjc.pin_trajectory(R, c["qpos"].start, c["qvel"].start, c["qacc"].start, nq, nv,
                                         smap.q_gather, smap.v_gather)
        else:
            Q, V, A = np.empty((n, smap.q_gather.size)), np.empty((n, smap.nv)), np.empty((n, smap.nv))
            qpos, qvel, qacc = R[:, c["qpos"]], R[:, c["qvel"]], R[:, c["qacc"]]
            for i in range(n):
                Q[i], V[i] = smap.q_from_qpos(qpos[i]), smap.v_from_qvel(qpos[i], qvel[i])
                A[i] = smap.a_from_qacc(Q[i], V[i], qacc[i])
        upd = R[:, 3].astype(np.intp)
        updates = self.updates
        TAU = np.array([u[0] for u in updates])[upd]
        if all(u[1] is not None for u in updates):
            T = np.array([u[1] for u in updates])[upd]
            T_cmd = np.array([u[3] if u[3] is not None else u[1] for u in updates])[upd]
            sat = np.array([u[2] if u[2] is not None else self._no_sat for u in updates])[upd]
        else:
            T = T_cmd = np.array([self.act.thesis_torques(Q[i], V[i], A[i], TAU[i]) for i in range(n)])
            sat = np.zeros((n, 26), dtype=bool)
        fw = R[:, c["fw"]].reshape(n, 2, 6)
        ftot, mtot = fw[:, :, :3].sum(axis=1), fw[:, :, 3:].sum(axis=1)
        zmp = np.full((n, 3), np.nan)
        ok = ftot[:, 2] > 1e-9
        zmp[ok] = np.stack([-mtot[ok, 1] / ftot[ok, 2], mtot[ok, 0] / ftot[ok, 2], np.zeros(ok.sum())], axis=1)
        basic = R[:, 2].astype(int)
        stance = np.array([[f in ph.stance_feet for f in FEET] for ph in _PHASE_OF_BASIC])
        cols = {"t": R[:, 0].copy(), "phase": R[:, 1].astype(int), "basic_phase": basic, "q": Q, "v": V, "a": A,
                "tau": TAU, "T": T, "T_cmd": T_cmd, "saturated": sat, "body_force": R[:, c["bf"]].reshape(n, 4, 3),
                "body_moment": R[:, c["bm"]].reshape(n, 4, 3), "foot_wrench": fw,
                "cop": R[:, c["cop"]].reshape(n, 2, 3), "zmp": zmp, "in_contact": stance[basic]}
        return Trace(cols, self.sim.timestep, "engine")


__all__ = ["TraceRecorder", "body_wrenches", "contact_record", "foot_body_ids", "trace_layout"]
