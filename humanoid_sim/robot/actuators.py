"""The thesis's actuator torques T (eq. 4.69) and their relation to Pinocchio's generalized forces.

Thesis T components are Cartesian components of the moment M_{k,j} that the lower body k exerts on the
higher-numbered real body j, about the joint point, resolved in frame j (chapter 2 L1008, eq. 4.69 with the
K-2 fix).  The higher body is the lower trunk for the hips, the shank for the ankles, the thigh for the knees,
the foot main body for the toes, and the upper trunk / arm / head above the waist / shoulders / neck.

Power: M . (w_j - w_k) = sum_i (M . u_i) theta_dot_i, with u_i the world axis of thesis joint i of the group
(Table 2.6); so the generalized force conjugate to theta_i is u_i . M and, since q = sign * theta,
tau_pin_i = sign_i (u_i . R_j T_full), where T_full holds all three moment components.  For the revolute joints
(toe, knee) and the spherical joints (ankle, hip, waist, neck) the actuated components are exactly what the
joint space sees.  At the universal shoulder (T20/T21 = M_{20,23}^{(23)} x, y) the z component is a
reaction that is not workless (errata P-8); T is therefore read off the transmitted moment itself (RNEA joint
forces), and the saturation correction keeps that reaction component unchanged (exact when it does not bind).

T-bar order (eq. 4.69): [T1 T3 T5 T7 T9 T11 T13 T15 | T2 T4 T6 T8 T10 T12 T14 T16 | T17 T18 T19 | T20 T21 T22 T23 |
T24 T25 T26]; saturation limits by errata section 7 (inferred mapping of the Simulink blocks).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from humanoid_sim.robot.model import HumanoidModel


@dataclass(frozen=True)
class ActuatorGroup:
    """One joint's actuator: the thesis torques it produces and how to read the transmitted moment."""

    name: str                 # actuator group in models/thesis_humanoid.yaml
    T: tuple[str, ...]        # thesis torque names, in component order
    comps: tuple[int, ...]    # moment components (0 = x, 1 = y, 2 = z of the higher body frame)
    thetas: tuple[str, ...]   # thesis joint variables of the joint
    higher: int               # higher-numbered real body j (frame of the components)
    tree_joint: str           # pinocchio joint whose transmitted force carries M_{k,j}
    higher_is_parent: bool    # in the pelvis-rooted tree, is body j on the parent side of tree_joint?


GROUPS: tuple[ActuatorGroup, ...] = (
    ActuatorGroup("right_toe", ("T1",), (1,), ("theta3",), 3, "theta3", True),
    ActuatorGroup("right_ankle", ("T3", "T5", "T7"), (0, 1, 2), ("theta5", "theta7", "theta9"), 9, "theta9", True),
    ActuatorGroup("right_knee", ("T9",), (1,), ("theta11",), 11, "theta11", True),
    ActuatorGroup("right_hip", ("T11", "T13", "T15"), (0, 1, 2), ("theta13", "theta15", "theta17r"), 17,
                  "theta17r", True),
    ActuatorGroup("left_toe", ("T2",), (1,), ("theta4",), 4, "theta4", True),
    ActuatorGroup("left_ankle", ("T4", "T6", "T8"), (0, 1, 2), ("theta6", "theta8", "theta10"), 10, "theta10", True),
    ActuatorGroup("left_knee", ("T10",), (1,), ("theta12",), 12, "theta12", True),
    ActuatorGroup("left_hip", ("T12", "T14", "T16"), (0, 1, 2), ("theta14", "theta16", "theta17l"), 17,
                  "theta17l", True),
    ActuatorGroup("waist", ("T17", "T18", "T19"), (0, 1, 2), ("theta18", "theta19", "theta20"), 20, "theta20", False),
    ActuatorGroup("right_shoulder", ("T20", "T21"), (0, 1), ("theta21", "theta23"), 23, "theta23", False),
    ActuatorGroup("left_shoulder", ("T22", "T23"), (0, 1), ("theta22", "theta24"), 24, "theta24", False),
    ActuatorGroup("neck", ("T24", "T25", "T26"), (0, 1, 2), ("theta25", "theta26", "theta27"), 27, "theta27", False),
)
T_NAMES: tuple[str, ...] = tuple(t for g in GROUPS for t in g.T)  # eq. 4.69 T-bar order


class Actuators:
    """Maps between thesis actuator torques T (26,, T-bar order) and generalized forces tau (nv,)."""

    def __init__(self, hm: HumanoidModel) -> None:
        self.hm = hm
        self.model = hm.model
        self.data = hm.model.createData()
        spec = hm.spec
        self.limits = np.array([float(spec.actuators[g.name]["limit"]) for g in GROUPS for _ in g.T])
        model = hm.model
        # Per thesis joint (group order): v index and sign (q = sign * theta).
        vidx, signs = [], []
        self._groups = []  # (T rows, comps, higher-body joint id, slice into the joint arrays, tree joint id,
        #                    higher_is_parent)
        row = 0
        for g in GROUPS:
            rows = list(range(row, row + len(g.T)))
            row += len(g.T)
            start = len(vidx)
            for th in g.thetas:
                i = hm.theta_index(th)
                vidx.append(int(hm.theta_v_idx[i]))
                signs.append(float(hm.theta_sign[i]))
            higher_jid = model.frames[hm.frame_id(f"O_{g.higher}")].parentJoint
            self._groups.append((rows, list(g.comps), higher_jid, slice(start, len(vidx)),
                                 model.getJointId(g.tree_joint), g.higher_is_parent))
        self._vidx = np.array(vidx)
        self._signs = np.array(signs)
        # The joint axes are read from the world joint Jacobian (angular rows of a revolute joint's column = its
        # world axis), the higher bodies' rotations once per distinct body.  Revolute and spherical groups are
        # batched by components; the universal shoulders (two components) are read off the RNEA joint force.
        self._hj_unique = sorted({grp[2] for grp in self._groups})
        batches: dict[tuple[int, ...], list[int]] = {}
        self._moment_groups = []
        for gi, (rows, comps, _hj, _sl, _, _) in enumerate(self._groups):
            if len(rows) != 2:
                batches.setdefault(tuple(comps), []).append(gi)
            else:
                self._moment_groups.append(gi)
        self._batches = []  # (comps, joint positions (n_g, s), higher positions (n_g,), T rows (n_g, s), v idx)
        for comps, gis in batches.items():
            jpos = np.array([np.arange(self._groups[gi][3].start, self._groups[gi][3].stop) for gi in gis])
            hpos = np.array([self._hj_unique.index(self._groups[gi][2]) for gi in gis])
            trows = np.array([self._groups[gi][0] for gi in gis])
            self._batches.append((np.array(comps), jpos, hpos, trows, self._vidx[jpos]))
        # batches using all three moment components need no component selection
        self._batch_all_comps = [comps == (0, 1, 2) for comps in batches]
        # per universal-shoulder group, the position of its higher body in the rotations array
        self._moment_hpos = {gi: self._hj_unique.index(self._groups[gi][2]) for gi in self._moment_groups}

    def _frames(self, q: np.ndarray, data: pin.Data | None) -> tuple[np.ndarray, np.ndarray, pin.Data]:
        """World joint axes U (26, 3, thesis sign), rotations of the distinct higher bodies (n, 3, 3) and the Data
        they came from; ``data`` may hold placements and joint Jacobians at q already (then not recomputed)."""
        if data is None:
            data = self.data
            pin.forwardKinematics(self.model, data, q)
            pin.computeJointJacobians(self.model, data)
        U = data.J[3:, self._vidx].T * self._signs[:, None]
        placements = [data.oMi[j] for j in self._hj_unique]  # SE3s held while np.array copies their rotations
        Rh = np.array([M.rotation for M in placements])
        return U, Rh, data

    def _batch_blocks(self, U: np.ndarray, Rh: np.ndarray) -> list[np.ndarray]:
        """Per batch of square groups, the blocks B_g (n_g, s, s): world joint axes against the components'
        world directions, B_g[i, c] = u_i . R_j e_c."""
        return [U[jpos] @ (Rh[hpos] if all_comps else Rh[hpos][:, :, comps])
                for (comps, jpos, hpos, _, _), all_comps in zip(self._batches, self._batch_all_comps)]

    def _blocks(self, q: np.ndarray, data: pin.Data | None = None) -> list[np.ndarray]:
        """Per group, the block B_g (n_joints x n_T) of the torque map; ``data`` may hold forward kinematics
        and joint Jacobians at q already (then they are not recomputed)."""
        U, Rh, _ = self._frames(q, data)
        return [U[sl] @ Rh[self._hj_unique.index(hj)][:, comps] for (_, comps, hj, sl, _, _) in self._groups]

    def torque_map(self, q: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
        """B (nv x 26) with tau = B T for a moment made only of the actuated components (reactions held):
        tau_pin_i = sign_i u_i . R_j e_c for each component c of the group of joint i.  ``data``: optional
        pinocchio Data holding the placements and joint Jacobians of q."""
        B = np.zeros((self.model.nv, 26))
        for (rows, _, _, sl, _, _), Bg in zip(self._groups, self._blocks(q, data)):
            B[np.ix_(self._vidx[sl], rows)] = Bg
        return B

    def joint_frames(self, q: np.ndarray, data: pin.Data | None = None) -> tuple:
        """What :meth:`component_map` and :meth:`thesis_torques` both derive from the placements at q: world joint
        axes, higher-body rotations, the Data they came from and the square groups' blocks.  A caller needing both
        at one state passes it to each (``frames=``) instead of computing it twice.  ``data``: as
        :meth:`torque_map`."""
        U, Rh, kin_data = self._frames(q, data)
        return U, Rh, kin_data, self._batch_blocks(U, Rh)

    def component_map(self, q: np.ndarray, data: pin.Data | None = None, frames: tuple | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
        """(P, exact): P (26 x nv) with T = P tau for the components of the revolute and spherical groups
        (``exact`` True: T_group = B_g^-1 tau_group, as :meth:`thesis_torques` computes them); the universal
        shoulders' components are read off the moment transmitted to the arm, not tau alone (``exact`` False, rows
        of P zero).  A controller can then bound T linearly in tau.  ``data``: as :meth:`torque_map`; ``frames``:
        :meth:`joint_frames` at q (then ``data`` is not read)."""
        P = np.zeros((26, self.model.nv))
        exact = np.zeros(26, dtype=bool)
        _, _, _, blocks = frames if frames is not None else self.joint_frames(q, data)
        for (_, _, _, trows, vidx), B in zip(self._batches, blocks):
            P[trows[:, :, None], vidx[:, None, :]] = np.linalg.inv(B)   # one batched inverse per group shape
            exact[trows.ravel()] = True
        return P, exact

    def thesis_torques(self, q: np.ndarray, v: np.ndarray, a: np.ndarray, tau: np.ndarray,
                       kin_data: pin.Data | None = None, frames: tuple | None = None) -> np.ndarray:
        """T (26,, T-bar order, N m) of the motion (q, v, a) driven by generalized torques ``tau`` (nv,).

        Revolute and spherical joints: the actuated components are the whole joint-space torque, so
        T_group = (U^T R_j[:, comps])^-1 tau_group (U: the joint's world axes).  Shoulders: T20/T21 are read
        off the moment transmitted to the arm (RNEA joint force of theta23/theta24; the arm is a leaf, so no
        contact force enters it), about the shoulder point, in the arm frame (errata P-8).
        ``kin_data``: optional pinocchio Data holding the placements (forward kinematics) and the joint
        Jacobians (``computeJointJacobians``) of q; ``frames``: :meth:`joint_frames` at q (then ``kin_data`` is not
        read).
        """
        data = self.data
        pin.rnea(self.model, data, q, v, a)  # joint forces data.f (rnea does not update data.oMi)
        U, Rh, kin_data, blocks = frames if frames is not None else self.joint_frames(q, kin_data)
        T = np.zeros(26)
        for (_comps, _jpos, _hpos, trows, vidx), B in zip(self._batches, blocks):
            if B.shape[1] == 1:
                T[trows[:, 0]] = tau[vidx[:, 0]] / B[:, 0, 0]
            else:
                T[trows] = np.linalg.solve(B, tau[vidx][..., None])[..., 0]
        for gi in self._moment_groups:  # universal shoulder: x, y of the transmitted moment (z is a reaction, P-8)
            rows, comps, hj, sl, tj, higher_is_parent = self._groups[gi]
            f = data.f[tj]  # force of the parent on the child subtree, joint frame, about the joint
            oMt = kin_data.oMi[tj]  # held while its rotation is read (the array is a view into this object)
            n_world = oMt.rotation @ f.angular
            m = -n_world if higher_is_parent else n_world  # moment on the higher body from the lower one
            T[rows] = (Rh[self._moment_hpos[gi]].T @ m)[comps]
        return T

    def saturate(self, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Clip T to the saturation limits (errata section 7); returns (T_sat, mask of saturated rows)."""
        inside = np.abs(T) <= self.limits          # False for NaN, as clip's NaN != NaN
        if inside.all():                           # the usual case: nothing to clip
            return T.copy(), ~inside
        Ts = np.clip(T, -self.limits, self.limits)
        return Ts, Ts != T
