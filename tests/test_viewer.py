"""The meshcat viewer (humanoid_sim.viewer): node poses from the log, the offline recording (rendered in headless
Chromium), and the live server's loopback-only binding."""

from __future__ import annotations

import ipaddress
import re
import shutil
import socket
import subprocess
import urllib.request
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from PIL import Image

from humanoid_sim.model import HumanoidModel
from humanoid_sim.results import load_results
from humanoid_sim.viewer import FORCE_SCALE, LiveServer, build_frames, play_live, write_playback

REPO = Path(__file__).resolve().parents[1]
SIM1 = REPO / "scripts" / "params" / "sim1.yaml"
RUN_UNTIL = 0.3  # s of Simulation 1 (LFFSSP: the robot on its left foot)
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.fixture(scope="module")
def run(hm: HumanoidModel, tmp_path_factory: pytest.TempPathFactory):
    """A 0.3 s run of Simulation 1 saved as walk.py saves it: (results.npz path, reference trajectory)."""
    from humanoid_sim.scenario import load_scenario
    from humanoid_sim.simulate import Simulator

    sim = Simulator(hm, load_scenario(SIM1))
    result = sim.run(t_end=RUN_UNTIL)
    out = tmp_path_factory.mktemp("run") / "results.npz"
    result.log.save(out, [p.name for p in sim.traj.phases])
    return out, sim.traj


def _urdf_visual(link: str) -> ET.Element:
    root = ET.parse(REPO / "models" / "thesis_humanoid.urdf").getroot()
    return root.find(f"./link[@name='{link}']/visual")


# ---------------------------------------------------------------------------------------------- frames
def test_frames_sample_the_log_at_the_display_rate(run, hm: HumanoidModel) -> None:
    npz, traj = run
    r = load_results(npz)
    fr = build_frames(r, hm, traj, fps=30.0)
    span = r["t"][-1] - r["t"][0]
    assert len(fr) == int(np.floor(span * 30.0 + 1e-9)) + 1
    np.testing.assert_allclose(np.diff(fr.t), 1 / 30.0, rtol=1e-12)  # 1e-12: float rounding of k / fps
    # each frame shows the logged step nearest to its time; the log step is h = 0.01 s, so within h / 2
    assert np.all(np.abs(r["t"][fr.step] - fr.t) <= 0.005 + 1e-12)
    np.testing.assert_array_equal(fr.phase, r["phase"][fr.step])


def test_robot_geometry_follows_the_kinematics(run, hm: HumanoidModel) -> None:
    npz, traj = run
    r = load_results(npz)
    fr = build_frames(r, hm, traj)
    data = hm.model.createData()
    # right thigh: a URDF cylinder from the hip (O_11) to the knee (O_9); meshcat cylinders lie along local y
    half = float(_urdf_visual("right_thigh").find("geometry/cylinder").get("length")) / 2
    for i in (0, len(fr) // 2, len(fr) - 1):
        pin.framesForwardKinematics(hm.model, data, r["q"][fr.step[i]])
        T = fr.transforms["robot/right_thigh_0"][i]
        top, bottom = T[:3, 3] + half * T[:3, 1], T[:3, 3] - half * T[:3, 1]
        hip, knee = data.oMf[hm.frame_id("O_11")].translation, data.oMf[hm.frame_id("O_9")].translation
        # 1e-9 m: both are the same rigid transforms composed in double precision
        assert min(np.linalg.norm(top - hip), np.linalg.norm(top - knee)) < 1e-9
        assert min(np.linalg.norm(bottom - hip), np.linalg.norm(bottom - knee)) < 1e-9
        assert np.linalg.norm(top - bottom) == pytest.approx(2 * half, abs=1e-12)
    # at t = 0 (thesis initial posture) both feet lie flat: the soles of the foot and toe boxes are on z = 0
    for link in ("right_foot", "right_toe", "left_foot", "left_toe"):
        size = np.array(_urdf_visual(link).find("geometry/box").get("size").split(), dtype=float)
        T = fr.transforms[f"robot/{link}_0"][0]
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * size / 2
        z = (T[:3, :3] @ corners.T).T[:, 2] + T[2, 3]
        assert z.min() == pytest.approx(0.0, abs=1e-9), link  # 1e-9 m: exact posture, float rounding only


def test_ground_reaction_arrows(run, hm: HumanoidModel) -> None:
    npz, traj = run
    r = load_results(npz)
    fr = build_frames(r, hm, traj)
    shown = 0
    for f, foot in enumerate(("R", "L")):
        for i, k in enumerate(fr.step):
            F = r["foot_wrench"][k, f, :3]
            if not r["in_contact"][k, f]:
                assert not fr.visible[f"grf/{foot}"][i]
                continue
            assert fr.visible[f"grf/{foot}"][i]
            shown += 1
            T = fr.transforms[f"grf/{foot}"][i]
            np.testing.assert_allclose(T[:3, 3], r["cop"][k, f], atol=1e-12)  # the arrow starts at the CoP
            np.testing.assert_allclose(T[:3, 1], F / np.linalg.norm(F), atol=1e-12)  # and points along F
            length = fr.scales[f"grf/{foot}/shaft"][i, 1]
            assert length == pytest.approx(np.linalg.norm(F) * FORCE_SCALE, rel=1e-12)
    assert shown >= len(fr), "the left foot carries the robot during the whole run"


# ---------------------------------------------------------------------------------------------- recording
def test_playback_is_self_contained_and_small(run, hm: HumanoidModel, tmp_path: Path) -> None:
    npz, _ = run
    r = load_results(npz)
    # a 7 s log (the length of Simulation 1) made by repeating the short run's rows at h = 0.01 s
    n = int(round(7.0 / 0.01)) + 1
    rows = np.arange(n) % len(r["t"])
    long = {k: (v[rows] if k not in ("phase_names", "signal_units") else v) for k, v in r.items()}
    long["t"] = np.arange(n) * 0.01
    long_npz = tmp_path / "long" / "results.npz"
    long_npz.parent.mkdir()
    np.savez(long_npz, **long)
    html = write_playback(long_npz, tmp_path / "playback.html", hm=hm)
    size = html.stat().st_size
    assert size < 20e6, f"{size / 1e6:.1f} MB"
    text = html.read_text(encoding="utf-8")
    assert not re.search(r"<(script|link|img)[^>]+(src|href)\s*=", text), "the recording loads an external file"


def _chromium(html: Path, tmp_path: Path, budget_ms: int = 1500) -> tuple[np.ndarray, list[str]]:
    """Screenshot (H x W x 3 uint8) and console messages of ``html`` rendered by headless Chromium."""
    shot = tmp_path / f"{html.stem}.png"
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
           "--disable-quic", "--no-first-run", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", f"--user-data-dir={tmp_path / 'chromium-profile'}", "--enable-logging=stderr",
           "--v=0", "--window-size=1024,768", f"--virtual-time-budget={budget_ms}", f"--screenshot={shot}",
           html.resolve().as_uri()]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=90)
    assert shot.is_file(), f"no screenshot; chromium exited {proc.returncode}: {proc.stderr[-2000:]}"
    console = [line for line in proc.stderr.splitlines() if ":CONSOLE" in line]
    with Image.open(shot) as im:
        return np.asarray(im.convert("RGB")), console


def _console_problems(console: list[str]) -> list[str]:
    # the software rasterizer's WebGL performance notes are the only console output a healthy page makes
    return [line for line in console if "GL Driver Message" not in line]


def _pixels_of(img: np.ndarray, rgb: tuple[float, float, float]) -> int:
    """Pixels whose colour is a shade of ``rgb`` (Lambert shading scales a colour; angle under 2.6 deg) and
    not near black."""
    a = img.astype(float)
    c = np.asarray(rgb) / np.linalg.norm(rgb)
    norm = np.linalg.norm(a, axis=2)
    cos = (a @ c) / np.maximum(norm, 1e-9)
    return int(((cos > 0.999) & (norm > 40)).sum())


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (Debian: apt-get install chromium)")
def test_playback_renders_in_headless_chromium(run, hm: HumanoidModel, tmp_path: Path) -> None:
    npz, traj = run
    html = write_playback(npz, tmp_path / "playback.html", hm=hm, traj=traj)
    img, console = _chromium(html, tmp_path)
    assert img.std() > 10, "blank screenshot"
    assert not _console_problems(console), _console_problems(console)
    root = ET.parse(REPO / "models" / "thesis_humanoid.urdf").getroot()
    colours = {m.get("name"): tuple(float(x) for x in m.find("color").get("rgba").split()[:3])
               for m in root.findall("./material")}
    # 1000 pixels: the robot's right / left side covers about 5000 / 2800 at 1024 x 768 from the default camera;
    # the same scene with the robot hidden has under 50 (anti-aliased label text on the red phase bar)
    for side in ("right", "left"):
        assert _pixels_of(img, colours[side]) > 1000, f"the {side} side of the robot is not on screen"


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (Debian: apt-get install chromium)")
def test_console_check_catches_page_errors(tmp_path: Path) -> None:
    """The console scan above is not vacuous: a page with a script error fails it."""
    bad = tmp_path / "bad.html"
    bad.write_text("<html><body><script>undefined_function();</script></body></html>")
    _, console = _chromium(bad, tmp_path, budget_ms=200)
    assert any("Uncaught ReferenceError" in line for line in _console_problems(console))


# ---------------------------------------------------------------------------------------------- live
def _non_loopback_ipv4() -> str | None:
    """An IPv4 address of this machine outside 127.0.0.0/8 (no packet is sent)."""
    candidates = []
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect(("192.0.2.254", 9))  # TEST-NET address: only selects the outgoing interface
            candidates.append(s.getsockname()[0])
    except OSError:
        pass
    try:
        candidates += socket.gethostbyname_ex(socket.gethostname())[2]
    except OSError:
        pass
    for addr in candidates:
        if not ipaddress.ip_address(addr).is_loopback:
            return addr
    return None


def _connects(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host, port), timeout=2.0):
            return True
    except ConnectionRefusedError:
        return False


def test_live_server_listens_on_loopback_only(run, hm: HumanoidModel) -> None:
    npz, traj = run
    other = _non_loopback_ipv4()
    if other is None:
        pytest.skip("this machine has no non-loopback IPv4 address to probe")
    server = LiveServer()
    try:
        for port in (server.web_port, server.zmq_port):
            assert _connects("127.0.0.1", port), f"port {port} not reachable on 127.0.0.1"
            assert not _connects(other, port), f"port {port} accepts connections on {other}"
        assert server.web_url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(server.web_url, timeout=5) as resp:
            assert resp.status == 200 and b"meshcat" in resp.read().lower()
        # stream the run into the server (no browser attached; 50x real time keeps the test short)
        shown = play_live(npz, hm=hm, traj=traj, server=server, wait_for_browser=False, hold=False, speed=50.0)
        assert shown == len(build_frames(load_results(npz), hm, traj))
        scene = server.visualizer().static_html()
        assert scene.count("fetch(") > 20, "the server holds no scene"
    finally:
        server.close()
    assert server.proc.poll() is not None, "the server process is still running"
    assert not _connects("127.0.0.1", server.web_port)
