"""The grouped arguments of the compiled twins: NamedTuples of arrays and scalars (numba passes them as typed
tuples), built once on the Python side (:class:`humanoid_sim.kernel.tree.TreeConstants`,
:class:`humanoid_sim.kernel.support.SupportKernel`, :class:`humanoid_sim.controllers.thesis.stage.StageKernel`, the
balance controller) except :class:`State`, :class:`Anchor` and :class:`StageBuffers`, which change per call or
per phase.  All arrays float64 unless stated, C-contiguous; SI units.

Python passes the records themselves; they cross into numba as plain tuples in ``_fields`` order (numba types a
NamedTuple argument about three times slower than the same values in a plain tuple), and each entry point
rebuilds them on its first line: see :func:`humanoid_sim.jit.entry`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Tree(NamedTuple):
    """Constant tables of the kinematic tree (``TreeConstants``): per joint its parent, axis code (FREE_FLYER or
    0/1/2, -2 the universe), first q and v index (int64), placement in its parent (jR (nj, 3, 3), jp (nj, 3)), the
    velocity columns of it and its ancestors (support (nj, nv) bool); per task frame its parent joint (int64) and
    placement in it (fR (nf, 3, 3), fp (nf, 3))."""

    parents: np.ndarray
    axis: np.ndarray
    idx_q: np.ndarray
    idx_v: np.ndarray
    jR: np.ndarray
    jp: np.ndarray
    support: np.ndarray
    fparent: np.ndarray
    fR: np.ndarray
    fp: np.ndarray


class Coords(NamedTuple):
    """The thesis joint coordinates (26, T-bar order): their v columns ``jcols`` and q indices ``theta_q`` (int64),
    signs ``jsign`` (q = sign * theta) and the initial angles ``theta0`` (rad) the controllers measure from."""

    jcols: np.ndarray
    jsign: np.ndarray
    theta_q: np.ndarray
    theta0: np.ndarray


class Work(NamedTuple):
    """Work buffers a stage fills and its second half reads: joint placements R (nj, 3, 3), p (nj, 3); task-frame
    placements fR (nf, 3, 3), fpos (nf, 3); LOCAL_WORLD_ALIGNED [J | drift] ``motion`` (nf, 6, nv + 1) and velocities
    ``vel`` (nf, 6) of the frames a phase reads."""

    R: np.ndarray
    p: np.ndarray
    fR: np.ndarray
    fpos: np.ndarray
    motion: np.ndarray
    vel: np.ndarray


class State(NamedTuple):
    """One call's state (q (nq,), v (nv,)) and Pinocchio's terms at it: WORLD joint Jacobians J, dJ (6, nv)
    (``computeJointJacobiansTimeVariation``), ``M_upper`` (crba's upper triangle), ``h`` (nonLinearEffects)."""

    q: np.ndarray
    v: np.ndarray
    J: np.ndarray
    dJ: np.ndarray
    M_upper: np.ndarray
    h: np.ndarray


class Anchor(NamedTuple):
    """A phase's contact anchors: the welds' world placements R (n_w, 3, 3), p (n_w, 3) and the toe lock's angle
    (rad)."""

    R: np.ndarray
    p: np.ndarray
    lock: float


class Contact(NamedTuple):
    """A phase's constraint rows: the weld frames' rows (int64, support foot first), the toe lock's q and v index,
    the Baumgarte gains kp (1/s^2), kd (1/s)."""

    welds: np.ndarray
    lock_q: int
    lock_v: int
    kp: float
    kd: float


class SupportFoot(NamedTuple):
    """A phase's support foot for the projection: the toe lock's q and v index and the foot frame's parent joint and
    placement in it."""

    lock_q: int
    lock_v: int
    f_parent: int
    f_R: np.ndarray
    f_p: np.ndarray


class ActuatorTables(NamedTuple):
    """The actuator groups as flat tables (``support.actuator_tables``): g1 (n1, 5), g3 (n3, 10), gs (2, 6) int64
    (see ``kernel.actuators.thesis_torques``), hj (int64: joint ids of the higher bodies), the arms' mass (2,),
    lever (2, 3), inertia (2, 3, 3), gravity (3,), and the saturation limits of T (26,, N m)."""

    g1: np.ndarray
    g3: np.ndarray
    gs: np.ndarray
    hj: np.ndarray
    arm_mass: np.ndarray
    arm_lever: np.ndarray
    arm_I: np.ndarray
    gravity: np.ndarray
    limits: np.ndarray


class StageBuffers(NamedTuple):
    """A stage's outputs: theta_ddot_c (26,), a (nv,), lam (m,), T_cmd (26,), tau (nv,), log (``kernel.log``)."""

    qdd: np.ndarray
    a: np.ndarray
    lam: np.ndarray
    T: np.ndarray
    tau: np.ndarray
    log: np.ndarray
