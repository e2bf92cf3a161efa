"""Compiled twin of ``Actuators.thesis_torques`` (:mod:`humanoid_sim.robot.actuators`, numba): the thesis actuator
torques T of eq. 4.69 from the joint torques, the shoulders' from the arm's Newton-Euler equation (what RNEA's
joint force of a leaf body is).  The tables come from :func:`humanoid_sim.kernel.support.actuator_tables` in an
:class:`humanoid_sim.kernel.records.ActuatorTables`.  Compared with the reference in ``tests/test_kernel.py``.
"""

from __future__ import annotations

import numpy as np

from humanoid_sim.jit import njit
from humanoid_sim.kernel.linalg import cross, mm, mtv, mv, solve3


@njit
def thesis_torques(J, dJ, v, a, tau, R, p, support, act) -> np.ndarray:
    """T (26,, T-bar order) (``Actuators.thesis_torques``) of the joint torques ``tau`` at accelerations ``a``; R, p
    the joint placements, support the tree's support table, ``act`` a ``records.ActuatorTables``: g1 (n1, 5) int: T
    row, v index, sign (+-1),
    higher-joint slot, component of the one-component groups; g3 (n3, 10) int: 3 T rows, 3 v indices, 3 signs,
    higher-joint slot; gs (2, 6) int: 2 T rows, 2 components, tree joint, higher-joint slot of the shoulders,
    with ``arm_mass`` (2,), ``arm_lever`` (2, 3), ``arm_I`` (2, 3, 3) (inertia about the CoM, joint frame);
    hj: joint ids of the higher bodies (slots)."""
    g1, g3, gs, hj = act.g1, act.g3, act.gs, act.hj
    arm_mass, arm_lever, arm_I, gravity = act.arm_mass, act.arm_lever, act.arm_I, act.gravity
    T = np.zeros(26)
    for i in range(g1.shape[0]):
        row, vi, sg, slot, comp = g1[i, 0], g1[i, 1], g1[i, 2], g1[i, 3], g1[i, 4]
        Rh = R[hj[slot]]
        b = sg * (J[3, vi] * Rh[0, comp] + J[4, vi] * Rh[1, comp] + J[5, vi] * Rh[2, comp])
        T[row] = tau[vi] / b
    B = np.empty((3, 3))
    rhs = np.empty(3)
    for i in range(g3.shape[0]):
        Rh = R[hj[g3[i, 9]]]
        for k in range(3):
            vi, sg = g3[i, 3 + k], g3[i, 6 + k]
            for c in range(3):
                B[k, c] = sg * (J[3, vi] * Rh[0, c] + J[4, vi] * Rh[1, c] + J[5, vi] * Rh[2, c])
            rhs[k] = tau[vi]
        x = solve3(B, rhs)
        for k in range(3):
            T[g3[i, k]] = x[k]
    for i in range(gs.shape[0]):  # the arm (a leaf body): its Newton-Euler wrench about the shoulder point
        tj, slot = gs[i, 4], gs[i, 5]
        Rt, pt = R[tj], p[tj]
        V = np.zeros(6)
        A = np.zeros(6)
        for c in range(v.size):
            if support[tj, c]:
                for k in range(6):
                    V[k] += J[k, c] * v[c]
                    A[k] += J[k, c] * a[c] + dJ[k, c] * v[c]
        w, alpha = V[3:], A[3:]
        com = pt + mv(Rt, arm_lever[i])
        vc = V[:3] + cross(w, com)
        ac = A[:3] + cross(alpha, com) + cross(w, vc)
        f = arm_mass[i] * (ac - gravity)
        Iw = mm(mm(Rt, arm_I[i]), Rt.T)
        n = mv(Iw, alpha) + cross(w, mv(Iw, w)) + cross(com - pt, f)  # moment on the arm from the trunk, about pt
        m = mtv(R[hj[slot]], n)
        T[gs[i, 0]] = m[gs[i, 2]]
        T[gs[i, 1]] = m[gs[i, 3]]
    return T
