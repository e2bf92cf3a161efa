"""Live playback in a meshcat server bound to 127.0.0.1 only (a child process serves it)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import meshcat
import numpy as np

from humanoid_sim.viewer.frames import (
    DISPLAY_FPS,
    FORCE_SCALE,
    LOOPBACK,
    PlaybackFrames,
    ViewerError,
    build_frames,
)
from humanoid_sim.viewer.recording import _animation, _load_inputs
from humanoid_sim.viewer.scene import setup_scene

if TYPE_CHECKING:  # pragma: no cover
    from humanoid_sim.model import HumanoidModel
    from humanoid_sim.trajectory import ReferenceTrajectory


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
