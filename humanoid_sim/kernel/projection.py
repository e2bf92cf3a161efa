"""Compiled twin of the weld engine's projection onto the support foot (``WeldEngine.project_on_support``,
:mod:`humanoid_sim.engines.weld`) and of one Runge-Kutta combination of :mod:`humanoid_sim.dynamics.integrator`
(``RungeKutta.step``'s ``advance``), numba.  Compared with the references in ``tests/test_kernel.py``.  The entry
points (:func:`project_on_support`, :func:`advance_on_support`) receive their records as plain tuples
(``humanoid_sim.jit.entry``) and rebuild them on their first line.
"""

from __future__ import annotations

import math

import numpy as np

from humanoid_sim.jit import entry, njit
from humanoid_sim.kernel.kinematics import action_matrix, forward_kinematics, frame_placement, quat_to_rot, rot_to_quat
from humanoid_sim.kernel.linalg import cross, mm, mtm, mtv, mv, put
from humanoid_sim.kernel.records import Anchor, SupportFoot, Tree


@njit
def _project_inplace(q, v, anchor, foot, tree) -> None:
    """Put (q, v) on the support foot in place (``WeldEngine.project_on_support``): toe lock at its anchor angle with
    zero rate, base placement re-derived from the foot's anchor (anchor * oMf^-1 * base: the base's own value
    cancels), base twist from the joint rates through the foot's LOCAL Jacobian.  ``anchor``: the phase's
    ``records.Anchor`` (its first weld is the support foot's); ``foot``: ``SupportFoot``; ``tree``: ``Tree``."""
    anchor_R, anchor_p, lock_anchor = anchor.R[0], anchor.p[0], anchor.lock
    lock_q, lock_v, f_parent, f_R, f_p = foot.lock_q, foot.lock_v, foot.f_parent, foot.f_R, foot.f_p
    parents, axis, idx_q, idx_v, jR, jp, support = (tree.parents, tree.axis, tree.idx_q, tree.idx_v, tree.jR, tree.jp,
                                                    tree.support)
    q[lock_q] = lock_anchor
    v[lock_v] = 0.0
    nj = parents.size
    R = np.empty((nj, 3, 3))
    p = np.empty((nj, 3))
    forward_kinematics(q, parents, axis, idx_q, jR, jp, R, p)
    Rf, pf = frame_placement(R, p, f_parent, f_R, f_p)
    Rb = quat_to_rot(q[3], q[4], q[5], q[6])
    pb = q[:3].copy()
    X = mm(anchor_R, Rf.T)
    Rn = mm(X, Rb)
    put(q, 0, anchor_p + mv(X, pb - pf))
    quat = np.empty(4)
    rot_to_quat(Rn, quat)
    # unit length, as Pinocchio's integrate leaves it (without this the round-off of a slightly non-unit quaternion
    # would compound from step to step, since the compiled advance does not pass through integrate)
    n = math.sqrt(quat[0] * quat[0] + quat[1] * quat[1] + quat[2] * quat[2] + quat[3] * quat[3])
    put(q, 3, quat / n)
    # LOCAL Jacobian of the foot frame times the joint rates (the joint columns do not depend on the base)
    vj = np.zeros(3)
    wj = np.zeros(3)
    for j in range(2, nj):
        iv = idx_v[j]
        if support[f_parent, iv] and v[iv] != 0.0:
            u = R[j][:, axis[j]]
            wj += u * v[iv]
            vj += cross(u, pf - p[j]) * v[iv]
    lin = mtv(Rf, vj)
    ang = mtv(Rf, wj)
    Ad = action_matrix(mtm(Rb, Rf), mtv(Rb, pf - pb))
    tw = np.empty(6)
    put(tw, 0, lin)
    put(tw, 3, ang)
    put(v, 0, -mv(Ad, tw))


@entry
def project_on_support(q, v, anchor, foot, tree, q_out, v_out) -> None:
    """(q, v) projected on the support foot (:func:`_project_inplace`) into (q_out, v_out)."""
    anchor, foot, tree = Anchor(*anchor), SupportFoot(*foot), Tree(*tree)
    put(q_out, 0, q)
    put(v_out, 0, v)
    _project_inplace(q_out, v_out, anchor, foot, tree)


@entry
def advance_on_support(q, v, coeffs, vs, accs, h, anchor, foot, tree, q_out, v_out) -> None:
    """The state at (q + h dq, v + h dv), dq = sum_j coeffs[j] vs[j] and dv = sum_j coeffs[j] accs[j] (a Runge-Kutta
    stage or step end), projected on the support foot, into (q_out, v_out): ``RungeKutta.step``'s combination,
    ``integrate`` and ``project`` in one call.  The sums run left to right over the non-zero coefficients (the
    rounding of ``integrator._combine``); revolute coordinates add (Pinocchio's integrate of a revolute joint); the
    base is not integrated, since the projection re-derives it from the foot (its input value cancels).  ``vs``,
    ``accs``: tuples of (nv,) arrays; ``anchor``, ``foot``, ``tree`` as :func:`_project_inplace`."""
    anchor, foot, tree = Anchor(*anchor), SupportFoot(*foot), Tree(*tree)
    parents, idx_q, idx_v = tree.parents, tree.idx_q, tree.idx_v
    nv = v.size
    dq = np.zeros(nv)
    dv = np.zeros(nv)
    first = True
    for j in range(len(vs)):
        c = coeffs[j]
        if c == 0.0:
            continue
        x, y = vs[j], accs[j]
        if first:
            for i in range(nv):
                dq[i] = c * x[i]
                dv[i] = c * y[i]
            first = False
        else:
            for i in range(nv):
                dq[i] = dq[i] + c * x[i]
                dv[i] = dv[i] + c * y[i]
    put(q_out, 0, q)
    for j in range(2, parents.size):
        q_out[idx_q[j]] = q[idx_q[j]] + h * dq[idx_v[j]]
    for i in range(nv):
        v_out[i] = v[i] + h * dv[i]
    _project_inplace(q_out, v_out, anchor, foot, tree)
