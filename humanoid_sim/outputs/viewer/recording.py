"""The offline recording: ``playback.html``, a self-contained meshcat animation of a run.

The commands are packed with the C ``msgpack`` package when it is installed (a dependency of dask's distributed):
the same bytes as meshcat's pure-Python ``umsgpack``, about ten times faster (``tests/outputs/test_fast_outputs.py``
compares them).  The animation's tracks are built a node at a time from the frames' arrays (:func:`_animation`),
with the values meshcat's per-frame calls would give.
"""

from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import meshcat
import numpy as np
import umsgpack
from meshcat.animation import Animation, AnimationClip, AnimationTrack
from meshcat.servers.tree import SceneTree, find_node, walk

try:
    import msgpack
except ImportError:  # pragma: no cover - umsgpack packs the same bytes, slower
    msgpack = None

from humanoid_sim.outputs.viewer.disturbances import add_objects, push_frames
from humanoid_sim.outputs.viewer.frames import (
    DISPLAY_FPS,
    FORCE_SCALE,
    PHASE_HEX,
    PlaybackFrames,
    ViewerError,
    build_frames,
)
from humanoid_sim.outputs.viewer.scene import setup_scene

if TYPE_CHECKING:  # pragma: no cover
    from humanoid_sim.analysis.audit import AuditReport
    from humanoid_sim.references.chapter3 import ReferenceTrajectory
    from humanoid_sim.robot.model import HumanoidModel


class _RecordingWindow:
    """A meshcat window without a server: keeps the scene tree as meshcat's ZMQ bridge does and renders
    it to the same self-contained HTML as ``Visualizer.static_html()``."""

    def __init__(self) -> None:
        self.tree = SceneTree()

    def send(self, command: Any) -> None:
        data = command.lower()
        path = [p for p in data["path"].split("/") if p]
        node = find_node(self.tree, path)
        kind = data["type"]
        # animation values as single floats: three.js holds every keyframe track in a Float32Array anyway
        packed = packb(data, single=kind == "set_animation")
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
        """Every command of the scene, animations last (an animation binds to the objects that exist when it
        loads: one created later would not move)."""
        return scene_commands(self.tree)

    def get_scene(self, title: str = "MeshCat", overlay: str = "") -> str:
        """The self-contained page.  The commands are decoded and applied one after the other, in order (meshcat's
        ``static_html`` fetches each from a data URL, which applies them in whatever order the fetches finish)."""
        js = (Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js").read_text(encoding="utf-8")
        cmds = ",\n".join(f'"{base64.b64encode(c).decode("ascii")}"' for c in self.commands())
        return (f"<!DOCTYPE html>\n<html>\n<head><meta charset=utf-8><title>{title}</title></head>\n<body>\n"
                f'<div id="meshcat-pane"></div>\n<script>\n{js}\n</script>\n<script>\n'
                f'var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));\n'
                f"for (const c of [\n{cmds}\n]) {{\n"
                "  viewer.handle_command_bytearray(Uint8Array.from(atob(c), ch => ch.charCodeAt(0)));\n"
                "}\n</script>\n"
                f"{overlay}\n<style>body {{margin: 0;}} #meshcat-pane {{width: 100vw; height: 100vh; "
                "overflow: hidden;}</style>\n</body>\n</html>\n")


def _ext(obj: Any) -> Any:
    """msgpack's hook for what it cannot pack itself: meshcat's typed arrays (``umsgpack.Ext``)."""
    if isinstance(obj, umsgpack.Ext):
        return msgpack.ExtType(obj.type, obj.data)
    raise TypeError(f"cannot pack {type(obj).__name__} in a meshcat command")


def packb(data: Any, single: bool = False) -> bytes:
    """A meshcat command packed as meshcat packs it (``umsgpack.packb``; floats as single precision with
    ``single``), by the C ``msgpack`` when installed."""
    if msgpack is None:  # pragma: no cover
        return umsgpack.packb(data, force_float_precision="single") if single else umsgpack.packb(data)
    return msgpack.packb(data, use_bin_type=True, use_single_float=single, default=_ext)


def scene_commands(tree: Any) -> list[bytes]:
    """The packed commands of a meshcat scene tree (objects, properties, transforms), then its animations."""
    out: list[bytes] = []
    animations: list[bytes] = []
    for node in walk(tree):
        if node.object is not None:
            out.append(node.object)
        out.extend(node.properties)
        if node.transform is not None:
            out.append(node.transform)
        if node.animation is not None:
            animations.append(node.animation)
    return out + animations


def _overlay(fr: PlaybackFrames) -> str:
    """A corner box showing the simulation time and phase of the frame on screen, read from the playing animation's
    clock; and the URL fragment ``#t=SECONDS`` (simulation time), which pauses the playback at that time."""
    colours = {n: f"#{PHASE_HEX.get(n, 0x808080):06x}" for n in sorted(set(fr.phase_names))}
    return (
        '<div id="hs-status" style="position:fixed;left:8px;bottom:8px;padding:4px 8px;'
        'font:14px monospace;background:rgba(255,255,255,0.85);border-left:8px solid #888"></div>\n'
        "<script>\n"
        f"const HS = {{t0: {float(fr.t[0]) if len(fr) else 0.0!r}, fps: {_fps(fr)!r}, n: {len(fr)}, "
        f"times: {json.dumps([round(float(x), 4) for x in fr.step_t])}, "
        f"phases: {json.dumps([int(k) for k in fr.phase])}, names: {json.dumps(list(fr.phase_names))}, "
        f"colours: {json.dumps(colours)}}};\n"
        "function hsFrame() {  // the frame on screen, from meshcat's animation clock (clip time, s)\n"
        "  const tau = viewer.animator ? viewer.animator.time : 0;\n"
        "  return Math.min(HS.n - 1, Math.max(0, Math.round(tau * HS.fps)));\n"
        "}\n"
        "function hsUpdate() {\n"
        "  const k = hsFrame(), ph = HS.phases[k], name = HS.names[ph];\n"
        "  const el = document.getElementById('hs-status');\n"
        "  el.textContent = 't = ' + HS.times[k].toFixed(2) + ' s   phase ' + (ph + 1) + '/' +\n"
        "    HS.names.length + ' ' + name;\n"
        "  el.style.borderLeftColor = HS.colours[name];\n"
        "  requestAnimationFrame(hsUpdate);\n"
        "}\n"
        "requestAnimationFrame(hsUpdate);\n"
        "function hsSeek() {  // #t=SECONDS: pause at that simulation time once the animation is loaded\n"
        "  const m = /[#&]t=([0-9.eE+-]+)/.exec(location.hash);\n"
        "  if (!m) return;\n"
        "  if (!viewer.animator || !(viewer.animator.duration > 0)) { setTimeout(hsSeek, 20); return; }\n"
        "  const tau = Math.max(0, Math.min(viewer.animator.duration, parseFloat(m[1]) - HS.t0));\n"
        "  viewer.animator.pause();\n"
        "  viewer.animator.seek(tau);\n"
        "  viewer.animator.display_progress(tau);\n"
        "}\n"
        "hsSeek();\n"
        "window.addEventListener('hashchange', hsSeek);\n"
        "</script>")


def _fps(fr: PlaybackFrames) -> float:
    return float(1.0 / (fr.t[1] - fr.t[0])) if len(fr) > 1 else DISPLAY_FPS


def _animation(vis: meshcat.Visualizer, fr: PlaybackFrames, fps: float) -> Animation:
    """The animation of the frames: what meshcat's per-frame calls give (``anim.at_frame(vis, i)``, then
    ``frame[path].set_transform(T[i])``, ``set_property("scale", ...)``, ``set_property("visible", ...)`` for every
    frame i; the same clips, tracks, keys and values, in the same order), built a node at a time from the frames'
    arrays, then pruned (:func:`prune_keys`)."""
    anim = Animation(default_framerate=fps)
    n = len(fr)
    if n == 0:
        return anim

    def track(path: str, name: str, jstype: str, values: list) -> None:
        key = vis.path.append(path)
        clip = anim.clips.get(key)
        if clip is None:
            clip = anim.clips[key] = AnimationClip(fps=anim.default_framerate)
        clip.tracks[name] = AnimationTrack(name, jstype, list(range(n)), values)

    for path, T in fr.transforms.items():
        T = np.asarray(T, dtype=np.float64)
        track(path, "position", "vector3", [list(p) for p in T[:, :3, 3]])     # meshcat's js_position
        q = quaternions(T)
        track(path, "quaternion", "quaternion", [[x[1], x[2], x[3], x[0]] for x in q])   # js_quaternion
    for path, s in fr.scales.items():
        track(path, "scale", "vector3", [[float(x) for x in row] for row in s])
    for path, v in fr.visible.items():
        track(path, "visible", "boolean", [bool(x) for x in v])
    prune_keys(anim)
    return anim


def quaternions(T: np.ndarray) -> np.ndarray:
    """Unit quaternions (w, x, y, z) of the rotations of the transforms T (n, 4, 4): meshcat's
    ``transformations.quaternion_from_matrix`` (the eigenvector of the largest eigenvalue of its symmetric K, the
    sign making w >= 0) for all of them in one batched ``eigh``, the same numbers (the same sums in the same order,
    and LAPACK's routine run on each matrix alike)."""
    m00, m01, m02 = T[:, 0, 0], T[:, 0, 1], T[:, 0, 2]
    m10, m11, m12 = T[:, 1, 0], T[:, 1, 1], T[:, 1, 2]
    m20, m21, m22 = T[:, 2, 0], T[:, 2, 1], T[:, 2, 2]
    K = np.zeros((len(T), 4, 4))
    K[:, 0, 0] = m00 - m11 - m22
    K[:, 1, 0], K[:, 1, 1] = m01 + m10, m11 - m00 - m22
    K[:, 2, 0], K[:, 2, 1], K[:, 2, 2] = m02 + m20, m12 + m21, m22 - m00 - m11
    K[:, 3, 0], K[:, 3, 1], K[:, 3, 2], K[:, 3, 3] = m21 - m12, m02 - m20, m10 - m01, m00 + m11 + m22
    K /= 3.0
    w, V = np.linalg.eigh(K)
    q = V[np.arange(len(T)), :, np.argmax(w, axis=1)][:, [3, 0, 1, 2]]
    np.negative(q, out=q, where=q[:, :1] < 0.0)
    return q


def prune_keys(anim: Animation) -> int:
    """Drop every key of ``anim`` whose value equals both its neighbours' (a node at rest, a visibility that does not
    change): three.js interpolates between the keys left (linearly, by slerp, or holding a boolean), so every frame
    shows exactly what it showed with every key.  The first and last keys stay (the clip keeps its length).
    Returns how many keys were dropped."""
    dropped = 0
    for clip in anim.clips.values():
        for track in clip.tracks.values():
            v, n = track.values, len(track.values)
            keep = [i for i in range(n) if i == 0 or i == n - 1 or not (v[i] == v[i - 1] == v[i + 1])]
            dropped += n - len(keep)
            track.frames = [track.frames[i] for i in keep]
            track.values = [v[i] for i in keep]
    return dropped


def _load_inputs(results_npz: str | Path, hm: HumanoidModel | None) -> tuple[dict[str, np.ndarray], Any]:
    from humanoid_sim.interfaces.log import load_results

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
        from humanoid_sim.robot.model import load_model

        hm = load_model()
    return r, hm


MAX_FRAMES = 1000
"""Most frames a recording holds: 33 s at :data:`DISPLAY_FPS`.  A longer walk is sampled at a lower rate
(:func:`playback_fps`), which keeps ``playback.html`` under about 5 MB (a 63 s walk: 16 fps)."""


def playback_fps(duration_s: float, fps: float = DISPLAY_FPS, max_frames: int = MAX_FRAMES) -> float:
    """The frame rate of a recording of ``duration_s`` seconds: ``fps``, or lower so that the recording has at
    most ``max_frames`` frames (the frames of :func:`~.frames.build_frames`: one per 1 / rate from the start, and
    one at or past the end)."""
    if not (fps > 0):
        raise ViewerError(f"fps must be positive, got {fps}")
    if duration_s * fps + 1 <= max_frames:
        return float(fps)
    return float((max_frames - 1) / duration_s)


def record(results_npz: str | Path, hm: HumanoidModel | None = None, traj: ReferenceTrajectory | None = None,
           *, fps: float = DISPLAY_FPS, force_scale: float = FORCE_SCALE,
           repetitions: int = 1, max_frames: int = MAX_FRAMES, report: AuditReport | None = None,
           disturbances: dict[str, Any] | None = None) -> tuple[_RecordingWindow, PlaybackFrames]:
    """The recorded scene of a run (every meshcat command, as the browser receives them) and its frames: sampled
    at ``fps``, or at the lower rate that keeps a long walk to ``max_frames`` frames (:func:`playback_fps`);
    ``disturbances``: summary.json's entry of a scenario's pushes and terrain, drawn too (:mod:`.disturbances`)."""
    r, hm = _load_inputs(results_npz, hm)
    t = np.asarray(r["t"], dtype=float)
    fps = playback_fps(float(t[-1] - t[0]), fps, max_frames)
    fr = build_frames(r, hm, traj, fps=fps, force_scale=force_scale, report=report)
    if disturbances is not None:
        push_frames(fr, r, hm, disturbances)
    window = _RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    setup_scene(vis, r, hm, traj, fr)
    if disturbances is not None:
        add_objects(vis, disturbances)
    vis.set_animation(_animation(vis, fr, fps), play=True, repetitions=repetitions)
    return window, fr


def write_playback(results_npz: str | Path, out_html: str | Path, hm: HumanoidModel | None = None,
                   traj: ReferenceTrajectory | None = None, *, fps: float = DISPLAY_FPS,
                   force_scale: float = FORCE_SCALE, repetitions: int = 1, max_frames: int = MAX_FRAMES,
                   report: AuditReport | None = None, disturbances: dict[str, Any] | None = None) -> Path:
    """Write ``out_html``: a self-contained meshcat recording of the run that opens offline in a browser.

    The animation (sampled at ``fps``; a walk longer than ``max_frames`` frames at the rate that fits,
    :func:`playback_fps`) plays once on load, the camera following the robot; meshcat's "Animations" panel replays
    and scrubs it, and ``playback.html#t=3.5`` opens it paused at t = 3.5 s.  A corner box shows the simulation time
    and the phase.  The size stays bounded: keys of a node at rest are dropped (:func:`prune_keys`), animation
    values are single floats, and at most ``max_frames`` frames are kept.  ``report``: the run's contact audit when
    the caller has it (else it is computed anew).  ``disturbances``: summary.json's entry of a scenario's pushes and
    terrain, drawn as arrows and boxes (:mod:`.disturbances`).  Returns the path written.
    """
    from humanoid_sim.interfaces.log import atomic_write_text

    window, fr = record(results_npz, hm, traj, fps=fps, force_scale=force_scale, repetitions=repetitions,
                        max_frames=max_frames, report=report, disturbances=disturbances)
    html = window.get_scene(title=f"humanoid_sim playback: {Path(results_npz).parent.name}", overlay=_overlay(fr))
    out = Path(out_html)
    atomic_write_text(out, html)
    return out


# ============================================================================================ live server
