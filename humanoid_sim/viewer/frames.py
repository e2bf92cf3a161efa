"""Viewer data: constants, and the node poses of every displayed frame sampled from the log at the display rate."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from humanoid_sim.model import HumanoidModel
    from humanoid_sim.trajectory import ReferenceTrajectory


DISPLAY_FPS = 30.0
"""Default display rate of playback, frames per second."""
FORCE_SCALE = 1.0e-3
"""Ground-reaction arrow length per newton, m/N (the robot's weight, about 540 N, draws 0.54 m)."""
MIN_FORCE = 1.0
"""Below this force magnitude (N) a foot's arrow is hidden."""
LOOPBACK = "127.0.0.1"
"""The only address the live server binds."""

#: thesis L4219-4221 phase colours (as humanoid_sim.plots.PHASE_COLOURS), RGB hex
PHASE_HEX = {"LFFSSP": 0xFF0000, "RFFDSP": 0x0000FF, "RFFSSP": 0xFF00FF, "LFFDSP": 0x00FFFF}
TOE_HEX = {"R": 0x00A000, "L": 0x000000}
ARROW_HEX = 0xFF9900
LABEL_HEIGHT = 1.75  # m, height of the phase label above the ground
CAMERA_OFFSET = np.array([1.3, -2.4, 0.5])  # m, camera position relative to the view target (world)


class ViewerError(RuntimeError):
    """A playback could not be produced or the live server could not start."""


# ============================================================================================ scene data
@dataclass
class PlaybackFrames:
    """Everything animated, sampled at the display rate.

    t: (n,) simulation time of each frame, s.  step: (n,) index of the logged step shown.
    transforms: node path -> (n, 4, 4) world pose of that node (rigid, no scale).
    scales: node path -> (n, 3) scale of that node (only nodes that stretch).
    visible: node path -> (n,) bool visibility (only nodes that appear and disappear).
    phase: (n,) phase index of each frame; phase_names: name of every phase of the schedule.
    """

    t: np.ndarray
    step: np.ndarray
    transforms: dict[str, np.ndarray] = field(default_factory=dict)
    scales: dict[str, np.ndarray] = field(default_factory=dict)
    visible: dict[str, np.ndarray] = field(default_factory=dict)
    phase: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    phase_names: tuple[str, ...] = ()

    def __len__(self) -> int:
        return len(self.t)


def _sample_steps(t_log: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Frame times t0 + k / fps over the log and the nearest logged step of each (s, index)."""
    if not (fps > 0):
        raise ViewerError(f"fps must be positive, got {fps}")
    if t_log.ndim != 1 or len(t_log) == 0:
        raise ViewerError(f"the log has no steps (t has shape {t_log.shape})")
    n = int(np.floor((t_log[-1] - t_log[0]) * fps + 1e-9)) + 1
    t = t_log[0] + np.arange(n) / fps
    idx = np.clip(np.searchsorted(t_log, t), 0, len(t_log) - 1)
    prev = np.clip(idx - 1, 0, len(t_log) - 1)
    nearer_prev = np.abs(t_log[prev] - t) <= np.abs(t_log[idx] - t)
    return t, np.where(nearer_prev, prev, idx)


def _homogeneous(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(..., 4, 4) poses from rotations (..., 3, 3) and positions (..., 3)."""
    R = np.asarray(R, dtype=float)
    p = np.asarray(p, dtype=float)
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def _rot_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _y_to(d: np.ndarray) -> np.ndarray:
    """A rotation whose y axis is the unit vector ``d`` (meshcat cylinders and cones lie along y)."""
    d = d / np.linalg.norm(d)
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(d, helper)
    x /= np.linalg.norm(x)
    z = np.cross(x, d)
    return np.column_stack([x, d, z])


#: meshcat cylinders lie along their local y, coal (URDF) cylinders along z: pose = oMg @ this
_CYLINDER_FIX = _homogeneous(_rot_x(np.pi / 2), np.zeros(3))


def visual_model(hm: "HumanoidModel"):
    """The URDF's VISUAL geometry model, on the joint tree of ``hm.model`` (same free-flyer root)."""
    import pinocchio as pin

    vis = pin.buildGeomFromUrdf(hm.model, str(hm.urdf_path), pin.GeometryType.VISUAL)
    if len(vis.geometryObjects) == 0:
        raise ViewerError(f"{hm.urdf_path} has no visual geometry")
    return vis


def _geometry_kind(go: Any) -> str:
    kind = type(go.geometry).__name__
    if kind not in ("Box", "Cylinder", "Sphere"):
        raise ViewerError(f"visual {go.name!r}: unsupported geometry {kind} (expected Box, Cylinder or Sphere)")
    return kind


def build_frames(results: dict[str, np.ndarray], hm: "HumanoidModel", traj: "ReferenceTrajectory | None" = None,
                 fps: float = DISPLAY_FPS, force_scale: float = FORCE_SCALE) -> PlaybackFrames:
    """Sample a run (a :func:`humanoid_sim.results.load_results` dict) at ``fps`` and pose every node.

    Robot bodies: pinocchio geometry placements of the logged ``q``.  Ghost frames: the reference of the
    trajectory generator at (t, phase) when ``traj`` is given (as the simulator evaluates it), else the logged
    ``hip_R_ref``/``hip_p_ref`` and, for the feet, the logged toe-point references with the actual foot
    orientation.  Arrows: ``foot_wrench`` force at ``cop``, length ``force_scale`` m/N.
    """
    import pinocchio as pin

    t_frames, steps = _sample_steps(np.asarray(results["t"], dtype=float), fps)
    names = tuple(str(s) for s in results["phase_names"])
    phase = np.asarray(results["phase"], dtype=int)[steps]
    fr = PlaybackFrames(t=t_frames, step=steps, phase=phase, phase_names=names)
    q = np.asarray(results["q"], dtype=float)[steps]
    if q.shape[1] != hm.model.nq:
        raise ViewerError(f"results q has {q.shape[1]} coordinates, the model has nq = {hm.model.nq}")
    n = len(steps)

    # robot
    vmodel = visual_model(hm)
    vdata = vmodel.createData()
    data = hm.model.createData()
    poses = {go.name: np.zeros((n, 4, 4)) for go in vmodel.geometryObjects}
    for i in range(n):
        pin.forwardKinematics(hm.model, data, q[i])
        pin.updateGeometryPlacements(hm.model, data, vmodel, vdata)
        for go, oMg in zip(vmodel.geometryObjects, vdata.oMg):
            T = oMg.homogeneous
            poses[go.name][i] = T @ _CYLINDER_FIX if _geometry_kind(go) == "Cylinder" else T
    for name, T in poses.items():
        fr.transforms[f"robot/{name}"] = T

    # reference ghosts
    if traj is not None:
        samples = [traj.sample_global(float(tt), phase=int(k)) for tt, k in zip(results["t"][steps], phase)]
        hip = _homogeneous(np.array([s.hip_R for s in samples]), np.array([s.hip_p for s in samples]))
        foot_R = _homogeneous(np.array([s.foot_R_R for s in samples]), np.array([s.toe_R_p for s in samples]))
        foot_L = _homogeneous(np.array([s.foot_L_R for s in samples]), np.array([s.toe_L_p for s in samples]))
    else:
        hip = _homogeneous(results["hip_R_ref"][steps], results["hip_p_ref"][steps])
        foot_R = _homogeneous(results["foot_R_R"][steps], results["toe_R_p_ref"][steps])
        foot_L = _homogeneous(results["foot_L_R"][steps], results["toe_L_p_ref"][steps])
    fr.transforms.update({"ghost/hip": hip, "ghost/foot_R": foot_R, "ghost/foot_L": foot_L})

    # ground reaction arrows
    wrench = np.asarray(results["foot_wrench"], dtype=float)[steps]
    cop = np.asarray(results["cop"], dtype=float)[steps]
    contact = np.asarray(results["in_contact"], dtype=bool)[steps]
    for f, foot in enumerate(("R", "L")):
        F = wrench[:, f, :3]
        mag = np.linalg.norm(F, axis=1)
        on = contact[:, f] & np.all(np.isfinite(cop[:, f]), axis=1) & (mag > MIN_FORCE)
        T = np.repeat(np.eye(4)[None], n, axis=0)
        length = np.where(on, mag * force_scale, 1e-6)
        for i in np.flatnonzero(on):
            T[i] = _homogeneous(_y_to(F[i]), cop[i, f])
        fr.transforms[f"grf/{foot}"] = T
        fr.visible[f"grf/{foot}"] = on
        shaft = np.repeat(np.eye(4)[None], n, axis=0)
        shaft[:, 1, 3] = length / 2
        head = np.repeat(np.eye(4)[None], n, axis=0)
        head[:, 1, 3] = length + _HEAD_LEN / 2
        fr.transforms[f"grf/{foot}/shaft"] = shaft
        fr.scales[f"grf/{foot}/shaft"] = np.column_stack([np.ones(n), length, np.ones(n)])
        fr.transforms[f"grf/{foot}/head"] = head

    # phase labels follow the reference hip, above the head, facing the camera
    yaw = np.arctan2(CAMERA_OFFSET[1], CAMERA_OFFSET[0]) + np.pi / 2  # plane normal (local z) to the camera
    R_label = _rot_z(yaw) @ _rot_x(np.pi / 2)
    label_p = np.column_stack([hip[:, 0, 3], hip[:, 1, 3], np.full(n, LABEL_HEIGHT)])
    label_T = _homogeneous(np.repeat(R_label[None], n, axis=0), label_p)
    for k in np.unique(phase):
        fr.transforms[f"phase/{k}"] = label_T
        fr.visible[f"phase/{k}"] = phase == k
    return fr


# ============================================================================================ static scene
_HEAD_LEN = 0.05  # m, arrow head length
_SHAFT_RADIUS = 0.008  # m
_HEAD_RADIUS = 0.022  # m
