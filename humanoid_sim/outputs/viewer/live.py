"""Live playback in a meshcat server bound to 127.0.0.1 only (a child process serves it)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import meshcat

from humanoid_sim.outputs.viewer.frames import (
    DISPLAY_FPS,
    FORCE_SCALE,
    LOOPBACK,
    ViewerError,
    build_frames,
)
from humanoid_sim.outputs.viewer.recording import _animation, _load_inputs
from humanoid_sim.outputs.viewer.scene import setup_scene

if TYPE_CHECKING:  # pragma: no cover
    from humanoid_sim.references.chapter3 import ReferenceTrajectory
    from humanoid_sim.robot.model import HumanoidModel

REPLY_TIMEOUT = 30.0
"""s: a server command not answered within this time fails instead of hanging."""
CONNECTIONS = b"humanoid_sim_connections"
"""ZeroMQ request the live server answers with the number of browser connections so far."""


class LiveServer:
    """A meshcat server (ZeroMQ + web) in a child process, bound to 127.0.0.1 only.

    Use as a context manager or call :meth:`close`.  ``web_url``: the page to open; ``zmq_url``: where
    :class:`meshcat.Visualizer` connects; ``web_port`` / ``zmq_port``: their TCP ports; ``proc``: the child process.
    The child also exits when this process dies without closing it (it watches its stdin pipe for end-of-file).
    """

    def __init__(self, timeout: float = 20.0) -> None:
        env = dict(os.environ)
        root = str(Path(__file__).resolve().parents[3])
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        self.proc = subprocess.Popen([sys.executable, "-u", "-m", "humanoid_sim.outputs.viewer", "--serve"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                     env=env, start_new_session=True)
        self._socket: Any = None
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

    def visualizer(self, timeout: float = REPLY_TIMEOUT) -> meshcat.Visualizer:
        """A client connected to this server (prints the URL, as meshcat does); a command the server does not
        answer within ``timeout`` s raises ``zmq.Again`` instead of waiting forever."""
        import zmq

        vis = meshcat.Visualizer(zmq_url=self.zmq_url)
        vis.window.zmq_socket.setsockopt(zmq.RCVTIMEO, int(timeout * 1000))
        vis.window.zmq_socket.setsockopt(zmq.LINGER, 0)
        return vis

    def browsers_connected(self, timeout: float = REPLY_TIMEOUT) -> int:
        """How many browser connections the server has accepted so far (open or since closed)."""
        import zmq

        if self._socket is None:
            self._socket = zmq.Context.instance().socket(zmq.REQ)
            self._socket.setsockopt(zmq.RCVTIMEO, int(timeout * 1000))
            self._socket.setsockopt(zmq.LINGER, 0)
            self._socket.connect(self.zmq_url)
        self._socket.send(CONNECTIONS)
        try:
            return int(self._socket.recv().decode("ascii"))
        except zmq.Again:
            raise ViewerError(f"the meshcat server (pid {self.proc.pid}) did not answer within {timeout} s") from None

    def wait_for_browser(self, poll: float = 0.2) -> None:
        """Return once a browser has opened :attr:`web_url` (polls; Ctrl-C and SIGTERM interrupt it)."""
        while self.browsers_connected() == 0:
            if self.proc.poll() is not None:
                raise ViewerError(f"the meshcat server exited with status {self.proc.returncode}")
            time.sleep(poll)

    def close(self) -> None:
        """Stop the server process (idempotent)."""
        if self._socket is not None:
            self._socket.close()
            self._socket = None
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        for pipe in (self.proc.stdin, self.proc.stdout):
            if pipe is not None and not pipe.closed:
                pipe.close()

    def __enter__(self) -> LiveServer:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _serve() -> None:
    """Child-process entry point: meshcat's bridge, made fit for a live view.

    - its web server bound to 127.0.0.1 as well (meshcat 0.3.2 binds its ZeroMQ socket to the given host but lets
      tornado listen on every interface);
    - it sends a connecting browser the scene's animations after its objects (meshcat sends the tree in order,
      and the animation of the root node first, which then moves none of the objects);
    - it counts browser connections and answers :data:`CONNECTIONS` with that count (meshcat's own ``wait`` polls
      the *open* connections every 0.1 s, so a browser that came and went in between was never seen);
    - a browser that closes no longer breaks the bridge (meshcat writes to every socket of its pool and an error on a
      closed one left the command unanswered: the client then waited forever);
    - it exits when its parent goes away (end of file on stdin), so no server outlives the walk that started it.
    """
    import threading

    from meshcat.servers.zmqserver import ZMQWebSocketBridge
    from tornado.websocket import WebSocketClosedError

    class LiveBridge(ZMQWebSocketBridge):
        connections = 0

        def make_app(self):  # type: ignore[override]
            app = super().make_app()
            listen = app.listen

            def listen_loopback(port: int, **kwargs: Any) -> Any:
                kwargs["address"] = LOOPBACK
                return listen(port, **kwargs)

            app.listen = listen_loopback
            return app

        def send_scene(self, websocket: Any) -> None:  # called when a browser connects
            from humanoid_sim.outputs.viewer.recording import scene_commands

            LiveBridge.connections += 1
            for command in scene_commands(self.tree):  # animations last, after the objects they move
                websocket.write_message(command, binary=True)

        def handle_zmq(self, frames: list[bytes]) -> None:
            if frames[0] == CONNECTIONS:
                self.zmq_socket.send(str(LiveBridge.connections).encode("ascii"))
            else:
                super().handle_zmq(frames)

        def forward_to_websockets(self, frames: list[bytes]) -> None:
            _, _, data = frames
            for websocket in list(self.websocket_pool):
                try:
                    websocket.write_message(data, binary=True)
                except WebSocketClosedError:
                    self.websocket_pool.discard(websocket)

    def exit_with_parent() -> None:
        try:
            sys.stdin.buffer.read()
        finally:
            os._exit(0)

    threading.Thread(target=exit_with_parent, daemon=True).start()
    bridge = LiveBridge(host=LOOPBACK)
    print(f"zmq_url={bridge.zmq_url}")
    print(f"web_url={bridge.web_url}", flush=True)
    devnull = os.open(os.devnull, os.O_WRONLY)  # nobody reads stdout any more: a full pipe would block the server
    os.dup2(devnull, 1)
    try:
        bridge.run()
    except KeyboardInterrupt:
        pass


def play_live(results_npz: str | Path, hm: HumanoidModel | None = None,
              traj: ReferenceTrajectory | None = None, *, speed: float = 1.0, fps: float = DISPLAY_FPS,
              force_scale: float = FORCE_SCALE, server: LiveServer | None = None, wait_for_browser: bool = True,
              open_browser: bool = False, hold: bool = True) -> int:
    """Play the run in a meshcat server on 127.0.0.1 at ``speed`` x real time; returns the frames of the animation.

    Starts a :class:`LiveServer` unless ``server`` is given, shows the robot at its first frame, prints the URL,
    waits for a browser to open it (``wait_for_browser``), then sends the recording as a meshcat animation that the
    browser plays (the camera following the robot; replay and scrub it from the "Animations" panel) and, with
    ``hold``, keeps the server up until Ctrl-C or SIGTERM.  A server started here is stopped on return, however it
    returns.
    """
    if not (speed > 0):
        raise ViewerError(f"speed must be positive, got {speed}")
    r, hm = _load_inputs(results_npz, hm)
    fr = build_frames(r, hm, traj, fps=fps, force_scale=force_scale)
    own = server is None
    server = LiveServer() if own else server
    try:
        import zmq

        vis = server.visualizer()
        print(f"(meshcat server: process {server.proc.pid}, listening on 127.0.0.1 only)", flush=True)
        try:
            setup_scene(vis, r, hm, traj, fr)
            if open_browser:
                vis.open()
            if wait_for_browser:
                print("waiting for a browser to open the URL above ...", flush=True)
                server.wait_for_browser()
            vis.set_animation(_animation(vis, fr, fps * speed), play=True)
        except zmq.Again:
            raise ViewerError(f"the meshcat server (pid {server.proc.pid}) stopped answering") from None
        if hold:
            print("playing in the browser; replay it from Open Controls -> Animations. Ctrl-C stops the server.",
                  flush=True)
            try:
                while server.proc.poll() is None:
                    time.sleep(0.5)
            except KeyboardInterrupt as exc:
                if type(exc) is not KeyboardInterrupt:  # SIGTERM (cli.Terminated): let the caller report it
                    raise
        return len(fr)
    finally:
        if own:
            server.close()
