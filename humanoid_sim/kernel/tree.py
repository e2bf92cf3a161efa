"""Constant arrays of a Pinocchio model for the compiled kinematics (:mod:`humanoid_sim.kernel.kinematics`)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from humanoid_sim.kernel.kinematics import FREE_FLYER
from humanoid_sim.kernel.records import Tree, Work


class TreeConstants:
    """The constant arrays of a Pinocchio model that the compiled kinematics needs.

    parents (nj,), axis (nj,) (FREE_FLYER or 0/1/2; -2 for the universe), idx_q / idx_v (nj,), joint placements
    jR (nj, 3, 3) / jp (nj, 3), support (nj, nv) bool: the velocity columns of joint j and its ancestors.
    Frames are registered by name: fparent, fR, fp (placement of the frame in its parent joint's frame).
    """

    _AXES = {"JointModelRX": 0, "JointModelRY": 1, "JointModelRZ": 2, "JointModelFreeFlyer": FREE_FLYER}

    def __init__(self, model: pin.Model, frames: list[str]) -> None:
        nj, nv = model.njoints, model.nv
        self.parents = np.array(model.parents, dtype=np.int64)
        self.axis = np.full(nj, -2, dtype=np.int64)
        self.idx_q = np.zeros(nj, dtype=np.int64)
        self.idx_v = np.zeros(nj, dtype=np.int64)
        self.jR = np.zeros((nj, 3, 3))
        self.jp = np.zeros((nj, 3))
        self.support = np.zeros((nj, nv), dtype=np.bool_)
        self.jR[0] = np.eye(3)
        for j in range(1, nj):
            name = model.joints[j].shortname()
            if name not in self._AXES:
                raise ValueError(f"joint {model.names[j]!r}: the compiled kinematics handles the free flyer and "
                                 f"JointModelRX/RY/RZ, got {name}")
            if (name == "JointModelFreeFlyer") != (j == 1):
                raise ValueError(f"joint {model.names[j]!r}: the free flyer must be joint 1, the root")
            self.axis[j] = self._AXES[name]
            self.idx_q[j] = model.idx_qs[j]
            self.idx_v[j] = model.idx_vs[j]
            M = model.jointPlacements[j]
            self.jR[j] = M.rotation
            self.jp[j] = M.translation
            k = j
            while k > 0:
                s, n = model.idx_vs[k], model.nvs[k]
                self.support[j, s:s + n] = True
                k = model.parents[k]
        self.frames = list(frames)
        self.frame_index = {name: i for i, name in enumerate(frames)}
        fids = [model.getFrameId(name) for name in frames]
        for name, fid in zip(frames, fids):
            if fid >= model.nframes:
                raise ValueError(f"unknown frame {name!r}")
        self.fparent = np.array([model.frames[f].parentJoint for f in fids], dtype=np.int64)
        self.fR = np.array([model.frames[f].placement.rotation for f in fids])
        self.fp = np.array([model.frames[f].placement.translation for f in fids])
        self.nj, self.nv, self.nq = nj, nv, model.nq
        self.record = Tree(self.parents, self.axis, self.idx_q, self.idx_v, self.jR, self.jp, self.support,
                           self.fparent, self.fR, self.fp)
        """The tables as the compiled functions take them (:class:`humanoid_sim.kernel.records.Tree`)."""

    def work(self) -> Work:
        """Fresh work buffers of one stage for this tree and its frames (:class:`humanoid_sim.kernel.records.Work`)."""
        nf = len(self.frames)
        return Work(np.empty((self.nj, 3, 3)), np.empty((self.nj, 3)), np.empty((nf, 3, 3)), np.empty((nf, 3)),
                    np.empty((nf, 6, self.nv + 1)), np.empty((nf, 6)))
