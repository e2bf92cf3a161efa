"""Viewer data: constants, and the node poses of every displayed frame sampled from the log at the display rate."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from humanoid_sim.errors import HumanoidSimError
from humanoid_sim.outputs.colours import (
    FOOT_COLOURS,
    OUTSIDE_COLOUR,
    PHASE_COLOURS,
    REFERENCE_COLOUR,
    ZMP_COLOUR,
    hex_int,
)

if TYPE_CHECKING:
    from humanoid_sim.analysis.audit import AuditReport  # pragma: no cover
    from humanoid_sim.references.chapter3 import ReferenceTrajectory
    from humanoid_sim.robot.model import HumanoidModel


DISPLAY_FPS = 30.0
"""Default display rate of playback, frames per second."""
FORCE_SCALE = 1.0e-3
"""Ground-reaction arrow length per newton, m/N (the robot's weight, about 540 N, draws 0.54 m)."""
MIN_FORCE = 1.0
"""Below this force magnitude (N) a foot's arrow is hidden."""
LOOPBACK = "127.0.0.1"
"""The only address the live server binds."""

PHASE_HEX = {name: hex_int(c) for name, c in PHASE_COLOURS.items()}
"""Thesis L4219-4221 phase colours (:mod:`humanoid_sim.outputs.colours`), RGB hex."""
FOOT_HEX = {foot: hex_int(c) for foot, c in FOOT_COLOURS.items()}
"""One colour per side, as in every figure (:data:`humanoid_sim.outputs.colours.FOOT_COLOURS`)."""
TOE_HEX = FOOT_HEX
ZMP_HEX = hex_int(ZMP_COLOUR)
OUTSIDE_HEX = hex_int(OUTSIDE_COLOUR)
SUPPORT_HEX = hex_int(REFERENCE_COLOUR)
LABEL_HEIGHT = 1.9  # m, height of the phase label above the ground (the robot is 1.6 m tall)
GROUND_LIFT = 0.003  # m, soles, CoP and ZMP markers are drawn this far above z = 0 (no z-fighting with the grid)
CAMERA_TARGET_Z = 0.95  # m, height of the point the camera looks at (the robot's middle), following the robot
CAMERA_OFFSET = np.array([1.3, -2.25, 0.45])  # m, camera position relative to the view target (world axes)
FOLLOW = "follow"
"""Node that follows the robot's hip over the ground (x, y of the Body-17 CoM smoothed over :data:`FOLLOW_WINDOW`,
z = 0); the phase labels hang on it."""
FOLLOW_WINDOW = 0.5  # s, width of the moving average of the followed point (the hip sways within each step)
SCENE = "/meshcat"
"""meshcat's root of every object.  The camera keeps looking at the world origin (meshcat's orbit controls aim at
the world origin whatever the camera node's pose), so the view follows the robot by moving the scene instead: this
node is translated by minus the followed point (at :data:`CAMERA_TARGET_Z`), which puts the robot at the origin."""
CAMERA = "/Cameras/default"


class ViewerError(HumanoidSimError, RuntimeError):
    """A playback could not be produced or the live server could not start."""


# ============================================================================================ scene data
@dataclass
class PlaybackFrames:
    """Everything animated, sampled at the display rate.

    t: (n,) time of each frame on the display grid, s.  step: (n,) index of the logged step shown (the nearest one,
    except where a phase shorter than a frame borrows the frame: see :func:`label_track`).
    transforms: node path -> (n, 4, 4) world pose of that node (rigid, no scale; for a child node, its pose in the
    parent).  scales: node path -> (n, 3) scale of that node (only nodes that stretch).
    visible: node path -> (n,) bool visibility (only nodes that appear and disappear).
    phase: (n,) phase index of the step each frame shows (the label track); phase_names: every phase of the schedule.
    supports: phase index -> {"R" / "L" / "support": closed outline (k, 2) on the ground, world x, y in m}: the soles
    the phase stands on (at its first step; the feet are welded during a phase) and, in double support, the support
    polygon.  step_t: the time of the step each frame shows.
    """

    t: np.ndarray
    step: np.ndarray
    transforms: dict[str, np.ndarray] = field(default_factory=dict)
    scales: dict[str, np.ndarray] = field(default_factory=dict)
    visible: dict[str, np.ndarray] = field(default_factory=dict)
    phase: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    phase_names: tuple[str, ...] = ()
    supports: dict[int, dict[str, np.ndarray]] = field(default_factory=dict)

    step_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """(n,) simulation time of the step each frame shows, s."""

    def __len__(self) -> int:
        return len(self.t)


def _sample_steps(t_log: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Frame times t0 + k / fps up to the first at or past the log's last step, and the nearest logged step of each
    (s, index): the last frame shows the last step."""
    if not (fps > 0):
        raise ViewerError(f"fps must be positive, got {fps}")
    if t_log.ndim != 1 or len(t_log) == 0:
        raise ViewerError(f"the log has no steps (t has shape {t_log.shape})")
    n = int(np.ceil((t_log[-1] - t_log[0]) * fps - 1e-9)) + 1
    t = t_log[0] + np.arange(n) / fps
    idx = np.clip(np.searchsorted(t_log, t), 0, len(t_log) - 1)
    prev = np.clip(idx - 1, 0, len(t_log) - 1)
    nearer_prev = np.abs(t_log[prev] - t) <= np.abs(t_log[idx] - t)
    return t, np.where(nearer_prev, prev, idx)


def label_track(t_frames: np.ndarray, steps: np.ndarray, t_log: np.ndarray, phase_log: np.ndarray) -> np.ndarray:
    """The logged step each frame shows, such that every phase of the log appears in at least one frame.

    ``steps``: the nearest step of each frame.  A phase that no frame samples (shorter than a frame: the 10-30 ms
    double supports at 30 fps) takes the frame nearest to its middle, unless that frame is the only one of its own
    phase, and shows its own step nearest to that frame's time.  Returns the new (n,) step indices (monotonic)."""
    steps = np.asarray(steps).copy()
    phase_log = np.asarray(phase_log)
    for k in np.unique(phase_log):
        if np.any(phase_log[steps] == k):
            continue
        own = np.flatnonzero(phase_log == k)
        t_mid = 0.5 * (t_log[own[0]] + t_log[own[-1]])
        for j in np.argsort(np.abs(t_frames - t_mid), kind="stable"):
            if np.count_nonzero(phase_log[steps] == phase_log[steps[j]]) >= 2:
                steps[j] = own[np.argmin(np.abs(t_log[own] - t_frames[j]))]
                break
    return steps


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


def visual_model(hm: HumanoidModel):
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


def _translation(p: np.ndarray) -> np.ndarray:
    """(n, 4, 4) pure translations to the points p (n, 3)."""
    T = np.repeat(np.eye(4)[None], len(p), axis=0)
    T[:, :3, 3] = p
    return T


def build_frames(results: dict[str, np.ndarray], hm: HumanoidModel, traj: ReferenceTrajectory | None = None,
                 fps: float = DISPLAY_FPS, force_scale: float = FORCE_SCALE,
                 report: AuditReport | None = None) -> PlaybackFrames:
    """Sample a run (a :func:`humanoid_sim.interfaces.log.load_results` dict) at ``fps`` and pose every node.

    Robot bodies: pinocchio geometry placements of the logged ``q``.  Ghost frames: the reference of the
    trajectory generator at (t, phase) when ``traj`` is given (as the simulator evaluates it), else the logged
    ``hip_R_ref``/``hip_p_ref`` and, for the feet, the logged toe-point references with the actual foot
    orientation.  Arrows: ``foot_wrench`` force at ``cop``, length ``force_scale`` m/N.  Feasibility (the contact
    audit, :mod:`humanoid_sim.analysis.audit`): each foot's CoP and the whole-body ZMP, each as an "inside" and an
    "outside"
    marker of which one is visible; the soles and support polygon of the phase shown (``supports``).  Camera and
    labels: the :data:`FOLLOW` node and the camera at the robot's hip.  ``report``: the run's contact audit when the
    caller has it (else it is computed here).
    """
    import pinocchio as pin

    from humanoid_sim.analysis.audit import AuditError, audit_results

    t_log = np.asarray(results["t"], dtype=float)
    phase_log = np.asarray(results["phase"], dtype=int)
    t_frames, steps = _sample_steps(t_log, fps)
    steps = label_track(t_frames, steps, t_log, phase_log)
    names = tuple(str(s) for s in results["phase_names"])
    phase = phase_log[steps]
    fr = PlaybackFrames(t=t_frames, step=steps, phase=phase, phase_names=names, step_t=t_log[steps])
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
        samples = [traj.sample_global(float(tt), phase=int(k)) for tt, k in zip(t_log[steps], phase)]
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

    # feasibility: CoP per foot and ZMP, inside / outside markers; soles and support polygon of each phase
    try:
        if report is None:
            report = audit_results(results, hm, 0.8)  # mu enters only the friction check, which is not drawn
    except AuditError as exc:
        raise ViewerError(f"contact audit of the run: {exc}") from None
    for key, pts, outside in ([(f"cop_{foot}", report.cop[steps, f], report.cop_outside[steps, f])
                               for f, foot in enumerate(("R", "L"))]
                              + [("zmp", report.zmp[steps], report.zmp_outside[steps])]):
        shown = np.all(np.isfinite(pts), axis=1)
        p = np.zeros((n, 3))
        # hidden frames keep the nearest earlier (else later) shown position: no marker sweeps in from the origin
        src = np.maximum.accumulate(np.where(shown, np.arange(n), -1))
        first = int(np.argmax(shown)) if shown.any() else 0
        src = np.where(src < 0, first, src)
        if shown.any():
            p[:, :2] = pts[src, :2]
        p[:, 2] = GROUND_LIFT
        fr.transforms[f"feasibility/{key}"] = _translation(p)
        fr.visible[f"feasibility/{key}/inside"] = shown & ~outside
        fr.visible[f"feasibility/{key}/outside"] = shown & outside
    for k in np.unique(phase_log):
        a = int(np.flatnonzero(phase_log == k)[0])
        polys = report.polygons[a]
        outlines = {foot: np.vstack([P, P[:1]]) for foot, P in zip(("R", "L"), polys)
                    if P is not None and np.all(np.isfinite(P))}
        if len(outlines) == 2:
            from humanoid_sim.analysis.audit import convex_hull

            H = convex_hull(np.concatenate([P[:-1] for P in outlines.values()]))
            outlines["support"] = np.vstack([H, H[:1]])
        fr.supports[int(k)] = outlines
        fr.visible[f"support/{k}"] = phase == k

    # the view and the labels follow the robot's hip over the ground
    ground = follow_points(np.asarray(results["hip_p"], dtype=float)[steps], fps)
    fr.transforms[FOLLOW] = _translation(ground)
    fr.transforms[SCENE] = _translation(-(ground + np.array([0.0, 0.0, CAMERA_TARGET_Z])))
    for k in np.unique(phase):
        fr.visible[f"{FOLLOW}/phase/{k}"] = phase == k
    return fr


def follow_points(hip_p: np.ndarray, fps: float) -> np.ndarray:
    """(n, 3) point the view follows at each frame: the hip's x, y (m, world) averaged over :data:`FOLLOW_WINDOW`
    (centred, shortened at the ends), z = 0."""
    n = len(hip_p)
    half = max(0, int(round(FOLLOW_WINDOW * fps / 2)))
    c = np.concatenate([np.zeros((1, 2)), np.cumsum(hip_p[:, :2], axis=0)])
    lo = np.clip(np.arange(n) - half, 0, n)
    hi = np.clip(np.arange(n) + half + 1, 0, n)
    return np.column_stack([(c[hi] - c[lo]) / (hi - lo)[:, None], np.zeros(n)])


def label_pose() -> np.ndarray:
    """(4, 4) pose of a phase label in the :data:`FOLLOW` node: :data:`LABEL_HEIGHT` above the ground, upright,
    facing the camera."""
    yaw = np.arctan2(CAMERA_OFFSET[1], CAMERA_OFFSET[0]) + np.pi / 2  # plane normal (local z) to the camera
    return _homogeneous(_rot_z(yaw) @ _rot_x(np.pi / 2), np.array([0.0, 0.0, LABEL_HEIGHT]))


# ============================================================================================ static scene
_HEAD_LEN = 0.05  # m, arrow head length
_SHAFT_RADIUS = 0.008  # m
_HEAD_RADIUS = 0.022  # m
