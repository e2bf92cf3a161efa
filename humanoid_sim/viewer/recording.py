"""The offline recording: ``playback.html``, a self-contained meshcat animation of a run."""

from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import meshcat
import numpy as np
import umsgpack
from meshcat.animation import Animation
from meshcat.servers.tree import SceneTree, find_node, walk

from humanoid_sim.viewer.frames import (
    DISPLAY_FPS,
    FORCE_SCALE,
    PHASE_HEX,
    PlaybackFrames,
    ViewerError,
    build_frames,
)
from humanoid_sim.viewer.scene import setup_scene

if TYPE_CHECKING:  # pragma: no cover
    from humanoid_sim.model import HumanoidModel
    from humanoid_sim.trajectory import ReferenceTrajectory


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
