"""The meshcat viewer (humanoid_sim.outputs.viewer): node poses from the log, the offline recording (rendered in
headless Chromium), and the live server's loopback-only binding."""

from __future__ import annotations

import base64
import io
import ipaddress
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
import urllib.request
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import umsgpack
import yaml
from PIL import Image

from humanoid_sim.interfaces.log import load_results
from humanoid_sim.outputs.viewer import FORCE_SCALE, LiveServer, build_frames, play_live, record, write_playback
from humanoid_sim.robot.model import HumanoidModel
from tests.conftest import CHROMIUM, needs_chromium

REPO = Path(__file__).resolve().parents[2]
SIM1 = REPO / "scripts" / "params" / "sim1.yaml"
SIM2 = REPO / "scripts" / "params" / "sim2.yaml"
WALK = REPO / "scripts" / "walk.py"
RUN_UNTIL = 0.3  # s of Simulation 1 (LFFSSP: the robot on its left foot)
#: thesis L4219-4221 phase colours, written out here (not taken from the code under test)
THESIS_PHASE_RGB = {"LFFSSP": (255, 0, 0), "RFFDSP": (0, 0, 255), "RFFSSP": (255, 0, 255), "LFFDSP": (0, 255, 255)}


def _simulate(hm: HumanoidModel, scenario: Path, out: Path, t_end: float | None = None):
    from humanoid_sim.scenario.schema import load_scenario
    from humanoid_sim.sim.simulate import Simulator

    sim = Simulator(hm, load_scenario(scenario))
    result = sim.run(t_end=t_end)
    out.parent.mkdir(parents=True, exist_ok=True)
    result.log.save(out, [p.name for p in sim.traj.phases])
    return out, sim.traj


@pytest.fixture(scope="module")
def run(hm: HumanoidModel, tmp_path_factory: pytest.TempPathFactory):
    """A 0.3 s run of Simulation 1 saved as walk.py saves it: (results.npz path, reference trajectory)."""
    return _simulate(hm, SIM1, tmp_path_factory.mktemp("run") / "results.npz", RUN_UNTIL)


@pytest.fixture(scope="module")
def walks(hm: HumanoidModel, tmp_path_factory: pytest.TempPathFactory):
    """Whole walks of Simulations 1 and 2 (with their 10-30 ms double supports): name -> (results.npz, traj)."""
    return {name: _simulate(hm, sc, tmp_path_factory.mktemp(name) / "results.npz")
            for name, sc in (("sim1", SIM1), ("sim2", SIM2))}


def _urdf_visual(link: str) -> ET.Element:
    root = ET.parse(REPO / "models" / "thesis_humanoid.urdf").getroot()
    return root.find(f"./link[@name='{link}']/visual")


# ---------------------------------------------------------------------------------------------- frames
def test_frames_sample_the_log_at_the_display_rate(run, hm: HumanoidModel) -> None:
    npz, traj = run
    r = load_results(npz)
    fr = build_frames(r, hm, traj, fps=30.0)
    span = r["t"][-1] - r["t"][0]
    assert len(fr) == int(np.ceil(span * 30.0 - 1e-9)) + 1  # up to the first frame at or past the last step
    np.testing.assert_allclose(np.diff(fr.t), 1 / 30.0, rtol=1e-12)  # 1e-12: float rounding of k / fps
    # one phase in 0.3 s: each frame shows the logged step nearest to its time; the log step is h = 0.01 s
    assert np.all(np.abs(r["t"][fr.step] - fr.t)[:-1] <= 0.005 + 1e-12)
    assert fr.step[-1] == len(r["t"]) - 1, "the last frame shows the last step"
    assert 0.0 <= fr.t[-1] - r["t"][-1] < 1 / 30.0  # the last frame is the first at or after the last step
    np.testing.assert_array_equal(fr.phase, r["phase"][fr.step])
    np.testing.assert_array_equal(fr.step_t, r["t"][fr.step])


def test_label_track_shows_phases_shorter_than_a_frame() -> None:
    """A synthetic log at h = 0.01 s: phase 1 lasts one step (10 ms, a third of a frame at 30 fps) and falls
    between two frames; phase 3 is the one-step last phase.  Nearest-step sampling misses both; the label track
    gives each a frame, shows one of its own steps there, keeps every other phase and stays in time order."""
    from humanoid_sim.outputs.viewer.frames import _sample_steps, label_track

    t = np.arange(0, 1.01, 0.01)
    phase = np.zeros(len(t), dtype=int)
    phase[52] = 1              # t = 0.52 s: frames sit at 0.5 and 0.5333 (steps 50 and 53)
    phase[53:] = 2
    phase[-1] = 3              # t = 1.00 s, the very last step
    t_frames, nearest = _sample_steps(t, 30.0)
    assert set(phase[nearest]) == {0, 2, 3}  # the premise: plain sampling never shows phase 1
    steps = label_track(t_frames, nearest, t, phase)
    assert set(phase[steps]) == {0, 1, 2, 3}
    j = int(np.flatnonzero(phase[steps] == 1)[0])
    assert steps[j] == 52 and abs(t_frames[j] - 0.52) < 1 / 30  # its own step, on the frame nearest to it
    assert np.all(np.diff(steps) >= 0)
    changed = np.flatnonzero(steps != nearest)
    assert len(changed) == 1  # only that frame moved


@pytest.mark.slow
def test_every_phase_of_the_walks_is_in_the_label_track(walks, hm: HumanoidModel) -> None:
    """Sims 1 and 2 have double supports of 10-30 ms and end on a short one: each phase of the log has a label that
    the recording makes visible in at least one frame (read back from the recorded animation's tracks)."""
    for name, (npz, traj) in walks.items():
        r = load_results(npz)
        window, fr = record(npz, hm, traj)
        shown = set()
        for cmd in (umsgpack.unpackb(c) for c in window.commands()):
            if cmd["type"] != "set_animation":
                continue
            for anim in cmd["animations"]:
                m = re.fullmatch(r"/meshcat/follow/phase/(\d+)", anim["path"])
                if not m:
                    continue
                for track in anim["clip"]["tracks"]:
                    if track["name"] == ".visible" and any(key["value"] for key in track["keys"]):
                        shown.add(int(m.group(1)))
        logged = set(np.unique(r["phase"]).tolist())
        assert len(logged) == len(r["phase_names"]), f"{name}: the walk did not complete"
        short = [k for k in logged if np.count_nonzero(r["phase"] == k) * 0.01 < 1 / 30]
        assert short, f"{name}: no phase shorter than a frame: the test would not test the label track"
        assert shown == logged, f"{name}: phases without a label frame: {sorted(logged - shown)}"
        assert r["phase"][fr.step[-1]] == r["phase"][-1]  # the playback ends on the last phase


def _recorded_static_poses(window) -> tuple[dict[str, np.ndarray], list[tuple[str, dict]]]:
    """(path -> static 4x4 transform, [(path, object JSON)]) of a recorded scene, decoded from its commands."""
    transforms, objects = {}, []
    for cmd in (umsgpack.unpackb(c) for c in window.commands()):
        if cmd["type"] == "set_transform":
            transforms[cmd["path"]] = np.array(cmd["matrix"], dtype=float).reshape(4, 4).T  # column-major
        elif cmd["type"] == "set_object":
            objects.append((cmd["path"], cmd["object"]))
    return transforms, objects


def test_the_robot_sides_have_the_feet_colours_of_every_figure(run, hm: HumanoidModel) -> None:
    """Every robot part named right_... / left_... is drawn in that foot's colour of outputs.colours (the colour of
    the right / left foot in every 2-D figure, and of the toe paths, arrows and soles here); the rest in the body
    colour; and the two side colours are none of the phase colours."""
    from humanoid_sim.outputs.colours import BODY_COLOUR, FOOT_COLOURS, PHASE_COLOURS, hex_int

    npz, traj = run
    window, _ = record(npz, hm, traj)
    _, objects = _recorded_static_poses(window)
    robot = {path.rsplit("/", 1)[-1]: obj for path, obj in objects if "/robot/" in path}
    sides = {"R": 0, "L": 0}
    for name, obj in robot.items():
        colour = obj["materials"][0]["color"]
        side = "R" if name.startswith("right_") else "L" if name.startswith("left_") else None
        assert colour == hex_int(FOOT_COLOURS[side] if side else BODY_COLOUR), name
        if side:
            sides[side] += 1
    assert sides == {"R": 5, "L": 5}   # thigh, shank, foot, toe, arm
    for foot in ("R", "L"):
        paths = [obj for path, obj in objects if path.endswith(f"/reference/toe_{foot}")]
        assert paths and paths[0]["materials"][0]["color"] == hex_int(FOOT_COLOURS[foot])
    assert not set(FOOT_COLOURS.values()) & set(PHASE_COLOURS.values())


def test_no_text_lies_at_the_origin(walks, hm: HumanoidModel) -> None:
    """Every text object of the recording is a phase label: upright, 1.5 m or more above the ground in the frame it
    hangs from, and inside a node the animation shows and hides (so an unused label cannot lie on the ground at the
    start point, as the label of a phase with no frame once did)."""
    npz, traj = walks["sim1"]
    window, _ = record(npz, hm, traj)
    transforms, objects = _recorded_static_poses(window)
    animated = set()
    for cmd in (umsgpack.unpackb(c) for c in window.commands()):
        if cmd["type"] == "set_animation":
            animated |= {a["path"] for a in cmd["animations"]}
    texts = [(path, obj) for path, obj in objects if any(t.get("type") == "_text" for t in obj.get("textures", []))]
    assert texts, "no phase label at all"
    for path, _ in texts:
        parts = path.strip("/").split("/")
        T = np.eye(4)
        for i in range(1, len(parts) + 1):  # static poses from the root down (animated nodes: their first frame)
            T = T @ transforms.get("/" + "/".join(parts[:i]), np.eye(4))
        scene = transforms.get("/meshcat", np.eye(4))
        local = np.linalg.inv(scene) @ T  # in the world of the walk (the scene node only moves the view)
        assert local[2, 3] >= 1.5, f"{path}: {local[2, 3]:.2f} m above the ground"
        assert abs(local[2, 2]) < 0.1, f"{path}: lies flat (normal {local[:3, 2]})"
        assert any(path.startswith(a + "/") for a in animated), f"{path}: not in an animated node"


def test_soles_cop_and_zmp_are_drawn(walks, hm: HumanoidModel) -> None:
    """The soles of the supporting feet are the model's sole rectangle (models/thesis_humanoid.yaml) carried by the
    foot body at the phase's first step; the CoP markers sit at the logged CoP; the ZMP marker at the point where the
    summed foot wrenches have no horizontal moment; each marker shows its "outside" variant exactly when the point
    is outside its polygon (checked here in the foot frame, or against the hull of the sole corners)."""
    npz, traj = walks["sim1"]
    r = load_results(npz)
    fr = build_frames(r, hm, traj)
    sole = {k: v["value"] for k, v in yaml.safe_load((REPO / "models" / "thesis_humanoid.yaml").read_text())
            ["foot_sole"].items()}
    data = hm.model.createData()
    corners = np.array([[sole["heel_back_x"], -sole["width"] / 2, sole["sole_z"]],
                        [sole["toe_front_x"], -sole["width"] / 2, sole["sole_z"]],
                        [sole["toe_front_x"], sole["width"] / 2, sole["sole_z"]],
                        [sole["heel_back_x"], sole["width"] / 2, sole["sole_z"]]])
    names = [str(n) for n in r["phase_names"]]
    for k in (0, 2):  # LFFSSP on the left foot (O_4), RFFSSP on the right foot (O_3)
        foot, frame = ("L", "O_4") if names[k] == "LFFSSP" else ("R", "O_3")
        first = int(np.flatnonzero(r["phase"] == k)[0])
        pin.framesForwardKinematics(hm.model, data, r["q"][first])
        M = data.oMf[hm.frame_id(frame)]
        world = (corners @ M.rotation.T + M.translation)[:, :2]
        drawn = fr.supports[k][foot][:-1]
        # 1e-9 m: both are the same rigid transform of the same corners (the audit only orders them)
        for c in world:
            assert np.min(np.linalg.norm(drawn - c, axis=1)) < 1e-9
        assert set(fr.supports[k]) == {foot}  # single support: one sole, no support polygon
    assert any("support" in outlines for outlines in fr.supports.values())  # double supports have one
    f = 1 if names[0] == "LFFSSP" else 0
    for i, step in enumerate(fr.step):
        if r["phase"][step] != 0:
            continue
        p = fr.transforms[f"feasibility/cop_{'RL'[f]}"][i][:3, 3]
        np.testing.assert_allclose(p[:2], r["cop"][step, f, :2], atol=1e-12)  # exactly the logged CoP
        pin.framesForwardKinematics(hm.model, data, r["q"][step])
        x, y, _ = data.oMf[hm.frame_id("O_4")].actInv(np.append(r["cop"][step, f, :2], 0.0))
        # the foot is flat to ~1e-5 rad (weld drift), so x, y in the foot frame decide inside / outside
        inside = sole["heel_back_x"] <= x <= sole["toe_front_x"] and abs(y) <= sole["width"] / 2
        assert fr.visible[f"feasibility/cop_{'RL'[f]}/inside"][i] == inside
        assert fr.visible[f"feasibility/cop_{'RL'[f]}/outside"][i] == (not inside)
        W = r["foot_wrench"][step].sum(axis=0)  # both feet's [force; moment about the world origin]
        zmp = np.array([-W[4] / W[2], W[3] / W[2]])
        np.testing.assert_allclose(fr.transforms["feasibility/zmp"][i][:2, 3], zmp, atol=1e-9)  # round-off
        assert fr.visible["feasibility/zmp/inside"][i] != fr.visible["feasibility/zmp/outside"][i]


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
    assert size < 2e6, f"{size / 1e6:.1f} MB"
    text = html.read_text(encoding="utf-8")
    assert not re.search(r"<(script|link|img)[^>]+(src|href)\s*=", text), "the recording loads an external file"


def test_playback_rate_keeps_long_walks_to_the_frame_bound() -> None:
    from humanoid_sim.outputs.viewer.recording import MAX_FRAMES, playback_fps

    assert playback_fps(7.0) == 30.0                            # a thesis walk: the display rate
    assert playback_fps((MAX_FRAMES - 1) / 30.0) == 30.0        # exactly the bound
    fps = playback_fps(63.0)
    assert fps == pytest.approx((MAX_FRAMES - 1) / 63.0) and 15.0 < fps < 16.0
    assert int(np.ceil(63.0 * fps - 1e-9)) + 1 <= MAX_FRAMES    # build_frames' count at that rate
    with pytest.raises(Exception, match="fps must be positive"):
        playback_fps(1.0, 0.0)


def test_pruned_keys_give_every_frame_its_value() -> None:
    """Keys whose value equals both neighbours' go; linear interpolation (vectors) and holding (booleans) of the
    keys left give back every frame's value exactly; the first and last keys stay."""
    from meshcat.animation import Animation, AnimationClip, AnimationTrack

    from humanoid_sim.outputs.viewer.recording import prune_keys

    rng = np.random.default_rng(3)
    n = 200
    pos = np.repeat(rng.normal(size=(8, 3)), 25, axis=0)        # at rest for 25 frames at a time
    pos[100:110] = rng.normal(size=(10, 3))                     # then moving
    vis = (np.arange(n) // 37) % 2 == 0
    full = {"position": [list(p) for p in pos], "visible": [bool(v) for v in vis]}
    clip = AnimationClip(tracks={k: AnimationTrack(k, "vector3" if k == "position" else "boolean", list(range(n)),
                                                   list(v)) for k, v in full.items()})
    anim = Animation(clips={"node": clip})
    dropped = prune_keys(anim)
    assert dropped > 150
    t_pos, t_vis = clip.tracks["position"], clip.tracks["visible"]
    for track in (t_pos, t_vis):
        assert track.frames[0] == 0 and track.frames[-1] == n - 1
    keys = np.array(t_pos.frames)
    vals = np.array(t_pos.values)
    again = np.column_stack([np.interp(np.arange(n), keys, vals[:, j]) for j in range(3)])
    np.testing.assert_array_equal(again, pos)                   # between equal keys the interpolation is exact
    held = np.array(t_vis.values)[np.searchsorted(t_vis.frames, np.arange(n), side="right") - 1]
    np.testing.assert_array_equal(held, vis)
    assert len(t_vis.frames) == 2 * (n // 37 + 1)               # a change of visibility keeps two keys


@pytest.mark.slow
def test_a_long_walks_playback_stays_under_5_mb(walks, hm: HumanoidModel, tmp_path: Path) -> None:
    """A 63 s walk (Simulation 1's whole walk repeated, its phases and all, every step at h = 0.01 s): at most
    MAX_FRAMES frames, under 5 MB."""
    from humanoid_sim.outputs.viewer.recording import MAX_FRAMES, _fps

    npz, _ = walks["sim1"]
    r = load_results(npz)
    n = int(round(63.0 / 0.01)) + 1
    rows = np.arange(n) % len(r["t"])
    long = {k: (v[rows] if k not in ("phase_names", "signal_units") else v) for k, v in r.items()}
    long["t"] = np.arange(n) * 0.01
    long_npz = tmp_path / "long" / "results.npz"
    long_npz.parent.mkdir()
    np.savez(long_npz, **long)
    window, fr = record(long_npz, hm)
    assert len(fr) <= MAX_FRAMES and _fps(fr) < 16.0
    assert len(set(np.asarray(r["phase"]).tolist())) > 5         # the walk's many phases, each with its label
    html = write_playback(long_npz, tmp_path / "playback.html", hm=hm)
    size = html.stat().st_size
    assert size < 5e6, f"{size / 1e6:.2f} MB"


def _chromium(url: str | Path, tmp_path: Path, budget_ms: int = 1500) -> tuple[np.ndarray, list[str]]:
    """Screenshot (H x W x 3 uint8) and console messages of a page (a file, or a URL) rendered by headless
    Chromium in a 1024 x 768 window after ``budget_ms`` of virtual time."""
    shot = tmp_path / "shot.png"
    shot.unlink(missing_ok=True)
    target = url.resolve().as_uri() if isinstance(url, Path) else url
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
           "--disable-quic", "--no-first-run", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", f"--user-data-dir={tmp_path / 'chromium-profile'}", "--enable-logging=stderr",
           "--v=0", "--window-size=1024,768", f"--virtual-time-budget={budget_ms}", f"--screenshot={shot}", target]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=90)
    assert shot.is_file(), f"no screenshot; chromium exited {proc.returncode}: {proc.stderr[-2000:]}"
    console = [line for line in proc.stderr.splitlines() if ":CONSOLE" in line]
    with Image.open(shot) as im:
        return np.asarray(im.convert("RGB")), console


def _console_problems(console: list[str]) -> list[str]:
    # the software rasterizer's WebGL performance notes are the only console output a healthy page makes
    return [line for line in console if "GL Driver Message" not in line]


def _mask_of(img: np.ndarray, rgb: tuple[float, float, float]) -> np.ndarray:
    """Pixels whose colour is a shade of ``rgb`` (Lambert shading scales a colour; angle under 2.6 deg) and not
    near black."""
    a = img.astype(float)
    c = np.asarray(rgb) / np.linalg.norm(rgb)
    norm = np.linalg.norm(a, axis=2)
    cos = (a @ c) / np.maximum(norm, 1e-9)
    return (cos > 0.999) & (norm > 40)


def _pixels_of(img: np.ndarray, rgb: tuple[float, float, float]) -> int:
    return int(_mask_of(img, rgb).sum())


def _robot_colours() -> dict[str, tuple[float, ...]]:
    """RGB in [0, 1] of the robot's right and left side: the feet's colours of every figure."""
    from humanoid_sim.outputs.colours import FOOT_COLOURS

    return {side: tuple(int(FOOT_COLOURS[f][i:i + 2], 16) / 255 for i in (1, 3, 5))
            for side, f in (("right", "R"), ("left", "L"))}


def _thick(mask: np.ndarray, steps: int = 2) -> np.ndarray:
    """``mask`` eroded by a 3 x 3 square ``steps`` times: the robot's limbs stay, the 1-2 px lines drawn in the same
    side colours (toe paths, sole outlines) go."""
    m = mask.copy()
    for _ in range(steps):
        p = np.pad(m, 1)
        m = np.logical_and.reduce([p[1 + di:p.shape[0] - 1 + di, 1 + dj:p.shape[1] - 1 + dj]
                                   for di in (-1, 0, 1) for dj in (-1, 0, 1)])
    return m


def _bbox(mask: np.ndarray) -> tuple[int, int, int, int]:
    """(row min, row max, column min, column max) of a non-empty mask."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    return int(rows[0]), int(rows[-1]), int(cols[0]), int(cols[-1])


@needs_chromium
def test_playback_renders_in_headless_chromium(run, hm: HumanoidModel, tmp_path: Path) -> None:
    npz, traj = run
    html = write_playback(npz, tmp_path / "playback.html", hm=hm, traj=traj)
    img, console = _chromium(html, tmp_path)
    assert img.std() > 10, "blank screenshot"
    assert not _console_problems(console), _console_problems(console)
    colours = _robot_colours()
    # 1000 pixels: the robot's right / left side covers about 5000 / 2800 at 1024 x 768 from the camera; the same
    # scene with the robot hidden has under 50 (anti-aliased label text)
    for side in ("right", "left"):
        assert _pixels_of(img, colours[side]) > 1000, f"the {side} side of the robot is not on screen"


@needs_chromium
@pytest.mark.parametrize("name", ["sim1", "sim2"])
def test_camera_keeps_the_robot_and_the_label_in_the_frame(walks, hm: HumanoidModel, tmp_path: Path, name) -> None:
    """playback.html#t=... opens paused at a time: at the first, middle and last second of sims 1 and 2 the robot
    and the phase label are wholly inside the 1024 x 768 frame, the label clear of meshcat's "Open Controls" bar, and
    the label's bar has the colour of the phase at that time (the thesis legend)."""
    npz, traj = walks[name]
    r = load_results(npz)
    html = write_playback(npz, tmp_path / "playback.html", hm=hm, traj=traj)
    colours = _robot_colours()
    end = float(r["t"][-1])
    for t in (0.5, round(end / 2, 2), round(end - 0.5, 2)):
        img, console = _chromium(f"{html.resolve().as_uri()}#t={t}", tmp_path, budget_ms=2500)
        assert not _console_problems(console), _console_problems(console)
        h, w, _ = img.shape
        robot = _mask_of(img, colours["right"]) | _mask_of(img, colours["left"])
        # 1000 pixels: the robot's two coloured sides cover several thousand at this distance
        assert robot.sum() > 1000, f"{name} t = {t}: the robot is not on screen"
        top, bottom, left, right = _bbox(_thick(robot))   # the body, not the toe paths in its side's colour
        assert top > 5 and left > 5 and bottom < h - 6 and right < w - 6, (name, t, (top, bottom, left, right))
        k = int(r["phase"][np.argmin(np.abs(r["t"] - t))])
        rgb = np.array(THESIS_PHASE_RGB[str(r["phase_names"][k])])
        bar = np.all(np.abs(img.astype(int) - rgb) <= 8, axis=2)  # unlit: the exact colour, 8 for rounding
        # 600 pixels: the bar is about 140 x 12 px; a reference-path line of that colour has a few hundred at most
        assert bar.sum() > 600, f"{name} t = {t}: no label bar of the phase colour ({int(bar.sum())} px)"
        top, bottom, left, right = _bbox(bar)
        assert top > 25 and left > 5 and bottom < h - 6 and right < w - 6, (name, t, (top, bottom, left, right))


@needs_chromium
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
        # load the run into the server (no browser attached)
        shown = play_live(npz, hm=hm, traj=traj, server=server, wait_for_browser=False, hold=False)
        assert shown == len(build_frames(load_results(npz), hm, traj))
        scene = server.visualizer().static_html()
        assert scene.count("fetch(") > 20, "the server holds no scene"
        assert server.browsers_connected() == 0
    finally:
        server.close()
    assert server.proc.poll() is not None, "the server process is still running"
    assert not _connects("127.0.0.1", server.web_port)


# ---------------------------------------------------------------------------------------------- walk.py --view
def _process_alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie (Linux /proc)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False
    return state != "Z"


def _wait_until(predicate, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, f"timed out after {timeout} s waiting for {what}"
        time.sleep(0.05)


class _LiveWalk:
    """``walk.py --view`` of a short Simulation-1 run in a child process (SIGINT at its default, as a terminal's
    Ctrl-C finds it), its output in a file; :attr:`url` and :attr:`server_pid` as it prints them."""

    def __init__(self, tmp_path: Path, until: float) -> None:
        import os

        self.log = tmp_path / "walk.log"
        env = {**os.environ, "PYTHONPATH": str(REPO)}
        with self.log.open("w") as fh:
            self.proc = subprocess.Popen(
                [sys.executable, str(WALK), str(SIM1), "--until", str(until), "--no-plots", "--no-html", "--quiet",
                 "--view", "--out", str(tmp_path / "out")], stdout=fh, stderr=subprocess.STDOUT, env=env, cwd=REPO,
                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        _wait_until(lambda: "waiting for a browser" in self.text() or self.proc.poll() is not None, 120,
                    "walk.py to start its server")
        text = self.text()
        assert self.proc.poll() is None, text
        self.url = re.search(r"^(http://127\.0\.0\.1:\d+/static/)$", text, re.M).group(1)
        self.server_pid = int(re.search(r"meshcat server: process (\d+)", text).group(1))
        assert _process_alive(self.server_pid)

    def text(self) -> str:
        return self.log.read_text()

    def stop(self) -> None:
        for pid in (self.proc.pid, getattr(self, "server_pid", None)):
            if pid is not None and _process_alive(pid):
                os.kill(pid, signal.SIGKILL)
        self.proc.wait()


class _DevTools:
    """Headless Chromium driven over the DevTools protocol (tornado's websocket client: tornado comes with
    meshcat), one page of 1024 x 768."""

    def __init__(self, tmp_path: Path) -> None:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        self.proc = subprocess.Popen(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--remote-debugging-port={port}", f"--user-data-dir={tmp_path / 'devtools-profile'}",
             "--window-size=1024,768", "about:blank"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.page = None

        def page_listed() -> bool:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=2) as resp:
                    pages = [p for p in json.load(resp) if p["type"] == "page"]
            except OSError:
                return False
            self.page = pages[0]["webSocketDebuggerUrl"] if pages else None
            return self.page is not None

        _wait_until(page_listed, 30, "chromium's DevTools endpoint")
        self._ids = iter(range(1, 1 << 30))

    async def connect(self) -> None:
        from tornado.websocket import websocket_connect

        self.ws = await websocket_connect(self.page, max_message_size=1 << 28)

    async def call(self, method: str, **params) -> dict:
        i = next(self._ids)
        await self.ws.write_message(json.dumps({"id": i, "method": method, "params": params}))
        while True:
            msg = json.loads(await self.ws.read_message())
            if msg.get("id") == i:
                assert "error" not in msg, msg
                return msg["result"]

    async def screenshot(self) -> np.ndarray:
        data = (await self.call("Page.captureScreenshot", format="png"))["data"]
        with Image.open(io.BytesIO(base64.b64decode(data))) as im:
            return np.asarray(im.convert("RGB"))

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


@needs_chromium
def test_walk_view_plays_in_a_browser_and_sigterm_stops_the_server(tmp_path: Path) -> None:
    """``walk.py --view`` prints the URL and waits; a headless Chromium opens it; the robot moves: its pixels
    differ between two screenshots taken a second apart.  Then SIGTERM ends walk.py and its meshcat server
    (checked by process id)."""
    import asyncio

    walk = _LiveWalk(tmp_path, until=3.0)
    browser = _DevTools(tmp_path)
    colours = _robot_colours()

    def robot(img: np.ndarray) -> np.ndarray:
        return _mask_of(img, colours["right"]) | _mask_of(img, colours["left"])

    async def watch() -> tuple[np.ndarray, np.ndarray]:
        await browser.connect()
        await browser.call("Page.enable")
        await browser.call("Page.navigate", url=walk.url)
        while "playing in the browser" not in walk.text():  # walk.py saw the browser and sent the animation
            assert walk.proc.poll() is None, walk.text()
            await asyncio.sleep(0.05)
        await asyncio.sleep(0.5)
        first = await browser.screenshot()
        await asyncio.sleep(1.0)
        return first, await browser.screenshot()

    try:
        first, second = asyncio.run(asyncio.wait_for(watch(), 120))
        a, b = robot(first), robot(second)
        # 1000 pixels: the robot covers several thousand; 300 changed pixels: a second of walking moves the legs
        # and arms far more (a still robot changes none: the page only re-renders the same frame)
        assert a.sum() > 1000 and b.sum() > 1000, "the robot is not on screen"
        assert np.count_nonzero(a ^ b) > 300, "the robot did not move in one second"
        walk.proc.send_signal(signal.SIGTERM)
        walk.proc.wait(timeout=30)
        _wait_until(lambda: not _process_alive(walk.server_pid), 10, "the meshcat server to stop")
        assert walk.proc.returncode == 1 and "terminated (SIGTERM)" in walk.text(), walk.text()
        assert "Traceback" not in walk.text()
    finally:
        browser.close()
        walk.stop()


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_ctrl_c_and_sigterm_stop_the_meshcat_server(tmp_path: Path, sig) -> None:
    """While ``walk.py --view`` waits for a browser, Ctrl-C (SIGINT) or SIGTERM ends it and its meshcat server."""
    walk = _LiveWalk(tmp_path, until=0.3)
    try:
        walk.proc.send_signal(sig)
        walk.proc.wait(timeout=30)
        _wait_until(lambda: not _process_alive(walk.server_pid), 10, "the meshcat server to stop")
        assert walk.proc.returncode == 1, walk.text()
        assert "Traceback" not in walk.text(), walk.text()
    finally:
        walk.stop()


@pytest.mark.slow
def test_meshcat_server_exits_when_walk_is_killed(tmp_path: Path) -> None:
    """Even SIGKILL, which walk.py cannot handle, leaves no server behind: the server exits when its parent's end
    of its stdin pipe closes."""
    walk = _LiveWalk(tmp_path, until=0.3)
    try:
        walk.proc.kill()
        walk.proc.wait(timeout=30)
        _wait_until(lambda: not _process_alive(walk.server_pid), 10, "the meshcat server to stop")
    finally:
        walk.stop()
