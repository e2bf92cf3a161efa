"""Viewer scene: the static meshcat objects (robot visuals, ground grid, reference paths, ghosts, arrows, labels)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import meshcat
import meshcat.geometry as g
import numpy as np

from humanoid_sim.outputs.colours import body_colour, hex_int
from humanoid_sim.outputs.viewer.frames import (
    _HEAD_LEN,
    _HEAD_RADIUS,
    _SHAFT_RADIUS,
    CAMERA,
    CAMERA_OFFSET,
    FOLLOW,
    FOOT_HEX,
    GROUND_LIFT,
    OUTSIDE_HEX,
    PHASE_HEX,
    SCENE,
    SUPPORT_HEX,
    ZMP_HEX,
    PlaybackFrames,
    _geometry_kind,
    _homogeneous,
    label_pose,
    visual_model,
)

if TYPE_CHECKING:  # pragma: no cover
    from humanoid_sim.references.chapter3 import ReferenceTrajectory
    from humanoid_sim.robot.model import HumanoidModel


class _Plane(g.Geometry):
    """three.js PlaneGeometry (in the local x-y plane, normal +z)."""

    def __init__(self, width: float, height: float) -> None:
        super().__init__()
        self.width, self.height = width, height

    def lower(self, object_data: Any) -> dict[str, Any]:
        return {"uuid": self.uuid, "type": "PlaneGeometry", "width": self.width, "height": self.height}


class _TextTexture(g.Texture):
    """meshcat's ``_text`` texture: black text drawn by the browser on a 256 x 256 canvas."""

    def __init__(self, text: str, font_size: int = 40, font_face: str = "sans-serif") -> None:
        super().__init__()
        self.text, self.font_size, self.font_face = text, font_size, font_face

    def lower(self, object_data: Any) -> dict[str, Any]:
        return {"uuid": self.uuid, "type": "_text", "text": self.text, "font_size": self.font_size,
                "font_face": self.font_face}


def body_hex(name: str) -> int:
    """meshcat colour of the robot part ``name`` (:func:`humanoid_sim.outputs.colours.body_colour`: its side's foot
    colour, or the body colour), whatever colours the URDF gives its materials."""
    return hex_int(body_colour(name))


def _line(points: np.ndarray, colour: int, segments: bool = False) -> g.Object:
    geom = g.PointsGeometry(np.asarray(points, dtype=np.float32).T)
    mat = g.LineBasicMaterial(color=colour)
    return g.LineSegments(geom, mat) if segments else g.Line(geom, mat)


def _ghost_triad(scale: float) -> g.Object:
    """Axes x (red), y (green), z (blue) of length ``scale`` (m), drawn through the robot (no depth test)."""
    pts = np.array([[0, 0, 0], [scale, 0, 0], [0, 0, 0], [0, scale, 0], [0, 0, 0], [0, 0, scale]], np.float32)
    col = np.array([[1, 0, 0], [1, 0, 0], [0, 0.7, 0], [0, 0.7, 0], [0, 0, 1], [0, 0, 1]], np.float32)
    return g.LineSegments(g.PointsGeometry(pts.T, color=col.T),
                          g.LineBasicMaterial(vertexColors=True, transparent=True, depthTest=False))


def _reference_paths(results: dict[str, np.ndarray], traj: ReferenceTrajectory | None,
                     dt: float = 0.01) -> tuple[list[tuple[str, np.ndarray]], np.ndarray, np.ndarray]:
    """Planned hip path per phase [(name, (m, 3))] and toe paths (m, 3): the whole nominal schedule with
    ``traj``, else the logged references."""
    if traj is not None:
        hips, toes_R, toes_L = [], [], []
        for ph in traj.phases:
            ts = np.linspace(0.0, ph.duration, max(2, int(np.ceil(ph.duration / dt)) + 1))
            s = [traj.sample(ph.index, tt) for tt in ts]
            hips.append((ph.name, np.array([x.hip_p for x in s])))
            toes_R.append(np.array([x.toe_R_p for x in s]))
            toes_L.append(np.array([x.toe_L_p for x in s]))
        return hips, np.concatenate(toes_R), np.concatenate(toes_L)
    names = [str(s) for s in results["phase_names"]]
    phase = np.asarray(results["phase"], dtype=int)
    hips = []
    for k in np.unique(phase):
        sel = np.flatnonzero(phase == k)
        sel = np.append(sel, min(sel[-1] + 1, len(phase) - 1))  # join to the next phase's first point
        hips.append((names[k], results["hip_p_ref"][sel]))
    return hips, results["toe_R_p_ref"], results["toe_L_p_ref"]


def _ground_grid(lo: np.ndarray, hi: np.ndarray, step: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Segments (2m, 3) of a grid on z = 0 covering [lo, hi] (x, y, m): minor lines and 1 m lines."""
    x0, y0 = np.floor(lo / step) * step
    x1, y1 = np.ceil(hi / step) * step
    minor, major = [], []
    for x in np.arange(x0, x1 + step / 2, step):
        (major if abs(x - round(x)) < 1e-6 else minor).append([[x, y0, 0.0], [x, y1, 0.0]])
    for y in np.arange(y0, y1 + step / 2, step):
        (major if abs(y - round(y)) < 1e-6 else minor).append([[x0, y, 0.0], [x1, y, 0.0]])
    as_pts = (lambda segs: np.array(segs).reshape(-1, 3) if segs else np.zeros((0, 3)))
    return as_pts(minor), as_pts(major)


def setup_scene(vis: meshcat.Visualizer, results: dict[str, np.ndarray], hm: HumanoidModel,
                traj: ReferenceTrajectory | None = None, frames: PlaybackFrames | None = None) -> None:
    """Create every object of the scene (module docstring of :mod:`humanoid_sim.outputs.viewer`) and place the camera;
    poses come from ``frames`` (:func:`~humanoid_sim.outputs.viewer.frames.build_frames`), whose first frame is set here
    so that the scene is posed before any animation plays.  Without ``frames`` the phase labels, soles and
    feasibility markers are left out."""
    vmodel = visual_model(hm)
    for go in vmodel.geometryObjects:
        kind = _geometry_kind(go)
        if kind == "Box":
            geom = g.Box(list(2 * np.asarray(go.geometry.halfSide)))
        elif kind == "Cylinder":
            geom = g.Cylinder(2 * go.geometry.halfLength, go.geometry.radius)
        else:
            geom = g.Sphere(go.geometry.radius)
        opacity = float(np.asarray(go.meshColor)[3])
        vis[f"robot/{go.name}"].set_object(geom, g.MeshLambertMaterial(color=body_hex(go.name), opacity=opacity))

    hips, toe_R, toe_L = _reference_paths(results, traj)
    for k, (name, pts) in enumerate(hips):
        vis[f"reference/hip_{k}"].set_object(_line(pts, PHASE_HEX.get(name, 0x808080)))
    vis["reference/toe_R"].set_object(_line(toe_R, FOOT_HEX["R"]))
    vis["reference/toe_L"].set_object(_line(toe_L, FOOT_HEX["L"]))
    vis["actual/hip"].set_object(_line(np.asarray(results["hip_p"]), 0x606060))

    allpts = np.concatenate([p for _, p in hips] + [toe_R, toe_L, np.asarray(results["hip_p"])])
    lo, hi = allpts[:, :2].min(axis=0) - 0.6, allpts[:, :2].max(axis=0) + 0.6
    minor, major = _ground_grid(lo, hi)
    vis["/Grid"].set_property("visible", False)  # replaced by a grid sized to the walk
    if len(minor):
        vis["ground/minor"].set_object(_line(minor, 0xB0B0B0, segments=True))
    if len(major):
        vis["ground/major"].set_object(_line(major, 0x505050, segments=True))

    vis["ghost/hip"].set_object(_ghost_triad(0.25))
    vis["ghost/hip/point"].set_object(g.Sphere(0.02), g.MeshBasicMaterial(color=0xFFCC00, opacity=0.6,
                                                                      depthTest=False))
    for foot in ("R", "L"):
        vis[f"ghost/foot_{foot}"].set_object(_ghost_triad(0.12))
        vis[f"ghost/foot_{foot}/point"].set_object(g.Sphere(0.012),
                                                   g.MeshBasicMaterial(color=FOOT_HEX[foot], opacity=0.6,
                                                                      depthTest=False))
        # arrows run up through the leg: drawn in the transparent pass without depth test, so always seen
        arrow = g.MeshLambertMaterial(color=FOOT_HEX[foot], opacity=0.85, depthTest=False)
        vis[f"grf/{foot}/shaft"].set_object(g.Cylinder(1.0, _SHAFT_RADIUS), arrow)
        vis[f"grf/{foot}/head"].set_object(g.Cylinder(_HEAD_LEN, radiusTop=0.0, radiusBottom=_HEAD_RADIUS), arrow)
        vis[f"grf/{foot}/base"].set_object(g.Sphere(0.015), arrow)

    if frames is not None:
        _feasibility(vis, frames)
        _labels(vis, frames)

    # a neutral grey backdrop (meshcat's default sky-blue gradient hides the blue left side)
    vis["/Background"].set_property("top_color", [0.96, 0.96, 0.96])  # RGB in [0, 1]
    vis["/Background"].set_property("bottom_color", [0.70, 0.70, 0.70])
    # camera: looks at the world origin, where the scene node puts the robot (frames.SCENE); its frame is y-up
    if frames is None or not len(frames):  # no animation: centre the walk instead
        target = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, 0.9])
        vis[SCENE].set_transform(_homogeneous(np.eye(3), -target))
    vis[CAMERA].set_transform(np.eye(4))
    off = CAMERA_OFFSET
    vis[f"{CAMERA}/rotated/<object>"].set_property("position", [float(off[0]), float(off[2]), float(-off[1])])
    if frames is not None and len(frames):
        pose_frame(vis, frames, 0)


def _feasibility(vis: meshcat.Visualizer, fr: PlaybackFrames) -> None:
    """Soles and support polygon of each phase (``support/<k>``), CoP and ZMP markers (``feasibility/...``): drawn
    over the robot (no depth test), since they lie under the feet."""
    for k, outlines in fr.supports.items():
        for who, P in outlines.items():
            pts = np.column_stack([P[:-1], np.full(len(P) - 1, GROUND_LIFT)])
            colour = SUPPORT_HEX if who == "support" else FOOT_HEX[who]
            vis[f"support/{k}/{who}"].set_object(g.LineLoop(
                g.PointsGeometry(np.asarray(pts, dtype=np.float32).T),
                g.LineBasicMaterial(color=colour, transparent=True, depthTest=False)))
    for foot in ("R", "L"):
        vis[f"feasibility/cop_{foot}/inside"].set_object(
            g.Sphere(0.014), g.MeshBasicMaterial(color=FOOT_HEX[foot], transparent=True, depthTest=False))
        vis[f"feasibility/cop_{foot}/outside"].set_object(
            g.Sphere(0.018), g.MeshBasicMaterial(color=OUTSIDE_HEX, transparent=True, depthTest=False))
    disc = _homogeneous(np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]), np.zeros(3))  # cylinder axis y -> z
    for state, colour in (("inside", ZMP_HEX), ("outside", OUTSIDE_HEX)):
        node = vis[f"feasibility/zmp/{state}"]
        node.set_object(g.Cylinder(0.004, 0.03), g.MeshBasicMaterial(color=colour, transparent=True, opacity=0.8,
                                                                    depthTest=False))
        node.set_transform(disc)


def _labels(vis: meshcat.Visualizer, fr: PlaybackFrames) -> None:
    """One label per phase shown (``FOLLOW/phase/<k>``): the phase name and number on a panel above the robot, on
    a bar of the phase colour."""
    pose = label_pose()
    for k in np.unique(fr.phase):
        name = fr.phase_names[k]
        node = vis[f"{FOLLOW}/phase/{k}"]
        node.set_transform(pose)
        node["panel"].set_object(_Plane(0.72, 0.2), g.MeshBasicMaterial(color=0xFFFFFF, opacity=0.8,
                                                                       transparent=True))
        node["panel"].set_transform(_homogeneous(np.eye(3), [0.0, 0.0, -0.002]))
        node["text"].set_object(_Plane(0.72, 0.72), g.MeshBasicMaterial(
            map=_TextTexture(f"{name} {k + 1}/{len(fr.phase_names)}", 40), transparent=True, depthWrite=False))
        node["bar"].set_object(_Plane(0.72, 0.06), g.MeshBasicMaterial(color=PHASE_HEX.get(name, 0x808080)))
        node["bar"].set_transform(_homogeneous(np.eye(3), [0.0, -0.13, 0.0]))


def pose_frame(vis: meshcat.Visualizer, fr: PlaybackFrames, i: int) -> None:
    """Set every animated node to its pose, scale and visibility of frame ``i`` (static commands)."""
    for path, T in fr.transforms.items():
        M = T[i]
        if path in fr.scales:
            M = M @ np.diag(np.append(fr.scales[path][i], 1.0))
        vis[path].set_transform(M)
    for path, v in fr.visible.items():
        vis[path].set_property("visible", bool(v[i]))
