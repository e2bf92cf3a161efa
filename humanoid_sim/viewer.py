"""See a run in meshcat: live playback (:func:`play_live`) and an offline recording (:func:`write_playback`).

The scene (all coordinates in the world frame of design.md section 3: x lateral, y forward, z up, metres):

- ``robot/<body>``: the URDF's visual geometry (boxes, cylinders, a sphere) posed from the logged
  configuration ``q``; right side red, left side blue, centre bodies grey (URDF materials).
- ``ground``: a 0.1 m grid on z = 0 around the walk, 1 m lines darker.
- ``reference/hip_<k>``: the planned Body-17 CoM path, one line per phase, in the thesis phase colours
  (LFFSSP red, RFFDSP blue, RFFSSP magenta, LFFDSP cyan); ``reference/toe_R`` (green) and
  ``reference/toe_L`` (black): the planned toe-point paths (thesis Figs. 6.51-6.53 colours);
  ``actual/hip``: the Body-17 CoM path the simulation produced (grey).
- ``ghost/hip``, ``ghost/foot_R``, ``ghost/foot_L``: the reference Body-17 frame (at the reference CoM) and
  the reference Body-1 / Body-2 frames (at the reference toe points) as triads (x red, y green, z blue),
  moving with the reference.
- ``grf/R``, ``grf/L``: the ground reaction force on each foot as an orange arrow from its centre of
  pressure, length :data:`FORCE_SCALE` m per N; hidden while the foot is off the ground.
- ``phase/<k>``: a label above the robot naming the current phase (``RFFDSP 2/16``) on a bar of the
  phase colour; only the current phase's label is visible.

Frames are sampled from the log at the display rate (default 30 fps, nearest logged step), so a 7 s walk
makes a recording of about 1.5 MB.  Live playback runs a meshcat server bound to 127.0.0.1 only (both its
ZeroMQ socket and its web server), so it refuses connections on every other address.
"""

from __future__ import annotations

import base64
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import meshcat
import meshcat.geometry as g
import numpy as np
import umsgpack
from meshcat.animation import Animation
from meshcat.servers.tree import SceneTree, find_node, walk

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


def _rgba_hex(rgba: np.ndarray) -> int:
    r, gg, b = (int(round(255 * float(c))) for c in rgba[:3])
    return (r << 16) | (gg << 8) | b


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


def _reference_paths(results: dict[str, np.ndarray], traj: "ReferenceTrajectory | None",
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


def setup_scene(vis: meshcat.Visualizer, results: dict[str, np.ndarray], hm: "HumanoidModel",
                traj: "ReferenceTrajectory | None" = None) -> None:
    """Create every object of the scene (module docstring) and place the camera; poses come from frames."""
    vmodel = visual_model(hm)
    for go in vmodel.geometryObjects:
        kind = _geometry_kind(go)
        if kind == "Box":
            geom = g.Box(list(2 * np.asarray(go.geometry.halfSide)))
        elif kind == "Cylinder":
            geom = g.Cylinder(2 * go.geometry.halfLength, go.geometry.radius)
        else:
            geom = g.Sphere(go.geometry.radius)
        rgba = np.asarray(go.meshColor)
        vis[f"robot/{go.name}"].set_object(geom, g.MeshLambertMaterial(color=_rgba_hex(rgba),
                                                                       opacity=float(rgba[3])))

    hips, toe_R, toe_L = _reference_paths(results, traj)
    for k, (name, pts) in enumerate(hips):
        vis[f"reference/hip_{k}"].set_object(_line(pts, PHASE_HEX.get(name, 0x808080)))
    vis["reference/toe_R"].set_object(_line(toe_R, TOE_HEX["R"]))
    vis["reference/toe_L"].set_object(_line(toe_L, TOE_HEX["L"]))
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
                                                   g.MeshBasicMaterial(color=TOE_HEX[foot], opacity=0.6,
                                                                      depthTest=False))
        # arrows run up through the leg: drawn in the transparent pass without depth test, so always seen
        arrow = g.MeshLambertMaterial(color=ARROW_HEX, opacity=0.9, depthTest=False)
        vis[f"grf/{foot}/shaft"].set_object(g.Cylinder(1.0, _SHAFT_RADIUS), arrow)
        vis[f"grf/{foot}/head"].set_object(g.Cylinder(_HEAD_LEN, radiusTop=0.0, radiusBottom=_HEAD_RADIUS), arrow)
        vis[f"grf/{foot}/base"].set_object(g.Sphere(0.015), arrow)

    names = [str(s) for s in results["phase_names"]]
    for k in np.unique(np.asarray(results["phase"], dtype=int)):
        name = names[k]
        vis[f"phase/{k}/text"].set_object(
            _Plane(0.9, 0.9), g.MeshBasicMaterial(map=_TextTexture(f"{name} {k + 1}/{len(names)}", 44),
                                                  transparent=True, depthWrite=False))
        vis[f"phase/{k}/bar"].set_object(_Plane(0.9, 0.09), g.MeshBasicMaterial(
            color=PHASE_HEX.get(name, 0x808080), opacity=0.45))
        vis[f"phase/{k}/bar"].set_transform(_homogeneous(np.eye(3), [0.0, 0.03, -0.002]))

    # a neutral grey backdrop (meshcat's default sky-blue gradient hides the blue left side)
    vis["/Background"].set_property("top_color", [0.96, 0.96, 0.96])  # RGB in [0, 1]
    vis["/Background"].set_property("bottom_color", [0.70, 0.70, 0.70])
    # camera: orbit target at the middle of the walk, 0.9 m up; meshcat's camera frame is y-up
    target = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, 0.9])
    vis["/Cameras/default"].set_transform(_homogeneous(np.eye(3), target))
    off = CAMERA_OFFSET
    vis["/Cameras/default/rotated/<object>"].set_property("position", [float(off[0]), float(off[2]),
                                                                       float(-off[1])])


# ============================================================================================ recording
class _RecordingWindow:
    """A meshcat window without a server: keeps the scene tree as meshcat's ZMQ bridge does and renders
    it to the same self-contained HTML as ``Visualizer.static_html()``."""

    def __init__(self) -> None:
        self.tree = SceneTree()

    def send(self, command: Any) -> None:
        data = command.lower()
        path = [p for p in data["path"].split("/") if p]
        node = find_node(self.tree, path)
        packed = umsgpack.packb(data)
        kind = data["type"]
        if kind == "set_object":
            node.object, node.properties = packed, []
        elif kind == "set_transform":
            node.transform = packed
        elif kind == "set_property":
            node.properties.append(packed)
        elif kind == "set_animation":
            node.animation = packed
        else:
            raise ViewerError(f"recording: unsupported meshcat command {kind!r}")

    def commands(self) -> list[bytes]:
        out: list[bytes] = []
        for node in walk(self.tree):
            if node.object is not None:
                out.append(node.object)
            out.extend(node.properties)
            for extra in (node.transform, node.animation):
                if extra is not None:
                    out.append(extra)
        return out

    def get_scene(self, title: str = "MeshCat", overlay: str = "") -> str:
        js = (Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js").read_text(encoding="utf-8")
        cmds = "".join(
            'fetch("data:application/octet-binary;base64,{}")\n'
            "    .then(res => res.arrayBuffer())\n"
            "    .then(buffer => viewer.handle_command_bytearray(new Uint8Array(buffer)));\n".format(
                base64.b64encode(c).decode("ascii")) for c in self.commands())
        return (f"<!DOCTYPE html>\n<html>\n<head><meta charset=utf-8><title>{title}</title></head>\n<body>\n"
                f'<div id="meshcat-pane"></div>\n<script>\n{js}\n</script>\n<script>\n'
                f'var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));\n{cmds}</script>\n'
                f"{overlay}\n<style>body {{margin: 0;}} #meshcat-pane {{width: 100vw; height: 100vh; "
                "overflow: hidden;}</style>\n</body>\n</html>\n")


def _overlay(fr: PlaybackFrames) -> str:
    """A corner box showing simulation time and phase, read from the playing animation's clock."""
    t0 = float(fr.t[0]) if len(fr) else 0.0
    # run-length encoding of the phase per frame: [[first frame, phase index], ...]
    changes = [[0, int(fr.phase[0])]] + [[i, int(fr.phase[i])] for i in range(1, len(fr))
                                          if fr.phase[i] != fr.phase[i - 1]]
    colours = {n: f"#{PHASE_HEX.get(n, 0x808080):06x}" for n in set(fr.phase_names)}
    return (
        '<div id="hs-status" style="position:fixed;left:8px;bottom:8px;padding:4px 8px;'
        'font:14px monospace;background:rgba(255,255,255,0.85);border-left:8px solid #888"></div>\n'
        "<script>\n"
        f"const HS = {{t0: {t0!r}, fps: {DISPLAY_FPS if not len(fr) else _fps(fr)!r}, n: {len(fr)}, "
        f"changes: {json.dumps(changes)}, names: {json.dumps(list(fr.phase_names))}, "
        f"colours: {json.dumps(colours)}}};\n"
        "function hsUpdate() {\n"
        "  const tau = viewer.animator ? viewer.animator.time : 0;  // clip time, s (meshcat's scrubber)\n"
        "  const k = Math.min(HS.n - 1, Math.max(0, Math.round(tau * HS.fps)));\n"
        "  let ph = HS.changes[0][1];\n"
        "  for (const c of HS.changes) { if (c[0] <= k) ph = c[1]; }\n"
        "  const name = HS.names[ph];\n"
        "  const el = document.getElementById('hs-status');\n"
        "  el.textContent = 't = ' + (HS.t0 + k / HS.fps).toFixed(2) + ' s   phase ' + (ph + 1) + '/' +\n"
        "    HS.names.length + ' ' + name;\n"
        "  el.style.borderLeftColor = HS.colours[name];\n"
        "  requestAnimationFrame(hsUpdate);\n"
        "}\n"
        "requestAnimationFrame(hsUpdate);\n"
        "</script>")


def _fps(fr: PlaybackFrames) -> float:
    return float(1.0 / (fr.t[1] - fr.t[0])) if len(fr) > 1 else DISPLAY_FPS


def _animation(vis: meshcat.Visualizer, fr: PlaybackFrames, fps: float) -> Animation:
    anim = Animation(default_framerate=fps)
    for i in range(len(fr)):
        with anim.at_frame(vis, i) as frame:
            for path, T in fr.transforms.items():
                frame[path].set_transform(T[i])
            for path, s in fr.scales.items():
                frame[path].set_property("scale", "vector3", [float(x) for x in s[i]])
            for path, v in fr.visible.items():
                frame[path].set_property("visible", "boolean", bool(v[i]))
    return anim


def _load_inputs(results_npz: str | Path, hm: "HumanoidModel | None") -> tuple[dict[str, np.ndarray], Any]:
    from humanoid_sim.results import load_results

    path = Path(results_npz)
    if not path.is_file():
        raise ViewerError(f"results file not found: {path}")
    r = load_results(path)
    missing = {"t", "q", "phase", "phase_names", "foot_wrench", "cop", "in_contact", "hip_p", "hip_p_ref",
               "hip_R_ref", "toe_R_p_ref", "toe_L_p_ref", "foot_R_R", "foot_L_R"} - set(r)
    if missing:
        raise ViewerError(f"{path}: missing signals {sorted(missing)}")
    if len(r["t"]) == 0:
        raise ViewerError(f"{path}: the log is empty")
    if hm is None:
        from humanoid_sim.model import load_model

        hm = load_model()
    return r, hm


def write_playback(results_npz: str | Path, out_html: str | Path, hm: "HumanoidModel | None" = None,
                   traj: "ReferenceTrajectory | None" = None, *, fps: float = DISPLAY_FPS,
                   force_scale: float = FORCE_SCALE, repetitions: int = 1) -> Path:
    """Write ``out_html``: a self-contained meshcat recording of the run that opens offline in a browser.

    The animation (sampled at ``fps``) plays once on load; meshcat's "Animations" panel replays and scrubs
    it.  A corner box shows the simulation time and the phase.  Returns the path written.
    """
    from humanoid_sim.results import atomic_write_text

    r, hm = _load_inputs(results_npz, hm)
    fr = build_frames(r, hm, traj, fps=fps, force_scale=force_scale)
    window = _RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    setup_scene(vis, r, hm, traj)
    vis.set_animation(_animation(vis, fr, fps), play=True, repetitions=repetitions)
    html = window.get_scene(title=f"humanoid_sim playback: {Path(results_npz).parent.name}", overlay=_overlay(fr))
    out = Path(out_html)
    atomic_write_text(out, html)
    return out


# ============================================================================================ live server
class LiveServer:
    """A meshcat server (ZeroMQ + web) in a child process, bound to 127.0.0.1 only.

    Use as a context manager or call :meth:`close`.  ``web_url``: the page to open; ``zmq_url``: where
    :class:`meshcat.Visualizer` connects; ``web_port`` / ``zmq_port``: their TCP ports.
    """

    def __init__(self, timeout: float = 20.0) -> None:
        env = dict(os.environ)
        root = str(Path(__file__).resolve().parent.parent)
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        self.proc = subprocess.Popen([sys.executable, "-u", "-m", "humanoid_sim.viewer", "--serve"],
                                     stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env,
                                     start_new_session=True)
        urls: dict[str, str] = {}
        deadline = time.monotonic() + timeout
        while len(urls) < 2:
            line = self.proc.stdout.readline().decode("utf-8").strip()
            if not line and self.proc.poll() is not None:
                raise ViewerError(f"the meshcat server exited with status {self.proc.returncode} before "
                                  "reporting its URLs")
            if "=" in line:
                key, value = line.split("=", 1)
                urls[key] = value
            if time.monotonic() > deadline:
                self.close()
                raise ViewerError(f"the meshcat server did not report its URLs within {timeout} s")
        self.zmq_url, self.web_url = urls["zmq_url"], urls["web_url"]
        self.zmq_port = int(self.zmq_url.rsplit(":", 1)[1])
        self.web_port = int(self.web_url.split(":")[2].split("/")[0])

    def visualizer(self) -> meshcat.Visualizer:
        """A client connected to this server (prints the URL, as meshcat does)."""
        return meshcat.Visualizer(zmq_url=self.zmq_url)

    def close(self) -> None:
        """Stop the server process (idempotent)."""
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.proc.stdout is not None:
            self.proc.stdout.close()

    def __enter__(self) -> "LiveServer":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _serve() -> None:
    """Child-process entry point: meshcat's bridge with its web server bound to 127.0.0.1 as well.

    (meshcat 0.3.2 binds its ZeroMQ socket to the given host but lets tornado listen on every interface.)"""
    from meshcat.servers.zmqserver import ZMQWebSocketBridge

    class LoopbackBridge(ZMQWebSocketBridge):
        def make_app(self):  # type: ignore[override]
            app = super().make_app()
            listen = app.listen

            def listen_loopback(port: int, **kwargs: Any) -> Any:
                kwargs["address"] = LOOPBACK
                return listen(port, **kwargs)

            app.listen = listen_loopback
            return app

    bridge = LoopbackBridge(host=LOOPBACK)
    print(f"zmq_url={bridge.zmq_url}")
    print(f"web_url={bridge.web_url}")
    try:
        bridge.run()
    except KeyboardInterrupt:
        pass


def play_live(results_npz: str | Path, hm: "HumanoidModel | None" = None,
              traj: "ReferenceTrajectory | None" = None, *, speed: float = 1.0, fps: float = DISPLAY_FPS,
              force_scale: float = FORCE_SCALE, server: LiveServer | None = None, wait_for_browser: bool = True,
              open_browser: bool = False, hold: bool = True) -> int:
    """Play the run in a meshcat server on 127.0.0.1 at ``speed`` x real time; returns the frames shown.

    Starts a :class:`LiveServer` unless ``server`` is given, prints the URL, waits for a browser to connect
    (``wait_for_browser``), streams the frames, then loads the recording as a meshcat animation (replay and
    scrub from the "Animations" panel) and, with ``hold``, keeps the server up until Ctrl-C.  A server
    started here is stopped on return.
    """
    if not (speed > 0):
        raise ViewerError(f"speed must be positive, got {speed}")
    r, hm = _load_inputs(results_npz, hm)
    fr = build_frames(r, hm, traj, fps=fps, force_scale=force_scale)
    own = server is None
    server = LiveServer() if own else server
    try:
        vis = server.visualizer()
        setup_scene(vis, r, hm, traj)
        if open_browser:
            vis.open()
        if wait_for_browser:
            print("waiting for a browser to open the URL above ...", flush=True)
            vis.wait()
        shown = _stream(vis, fr, speed)
        vis.set_animation(_animation(vis, fr, fps), play=False)
        if hold:
            print("playback done; replay it from the Animations panel. Ctrl-C stops the server.", flush=True)
            try:
                while True:
                    time.sleep(1.0)
            except KeyboardInterrupt:
                pass
        return shown
    finally:
        if own:
            server.close()


def _stream(vis: meshcat.Visualizer, fr: PlaybackFrames, speed: float) -> int:
    """Send each frame's poses at its wall-clock time (frame time / speed); returns the frames sent."""
    start = time.monotonic()
    last_visible: dict[str, bool] = {}
    for i in range(len(fr)):
        due = start + (fr.t[i] - fr.t[0]) / speed
        delay = due - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        for path, T in fr.transforms.items():
            M = T[i]
            if path in fr.scales:
                M = M @ np.diag(np.append(fr.scales[path][i], 1.0))
            vis[path].set_transform(M)
        for path, v in fr.visible.items():
            if last_visible.get(path) != bool(v[i]):
                vis[path].set_property("visible", bool(v[i]))
                last_visible[path] = bool(v[i])
    return len(fr)


if __name__ == "__main__":  # pragma: no cover - the live server's child process
    if sys.argv[1:] == ["--serve"]:
        _serve()
    else:
        sys.exit("usage: python -m humanoid_sim.viewer --serve  (starts a meshcat server on 127.0.0.1)")
