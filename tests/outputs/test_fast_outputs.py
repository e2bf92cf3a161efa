"""The default walk's outputs, made faster without changing them: the playback packed by the C msgpack (the bytes of
meshcat's umsgpack), its animation built a node at a time (meshcat's per-frame calls' clips, keys and values), the
figure modules importable without matplotlib, and the figure workers started ahead (the same files, and a walk's own
process that never loads matplotlib)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import umsgpack

from humanoid_sim.robot.model import HumanoidModel

REPO = Path(__file__).resolve().parents[2]
SIM1 = REPO / "scripts" / "params" / "sim1.yaml"


@pytest.fixture(scope="module")
def run(hm: HumanoidModel, tmp_path_factory: pytest.TempPathFactory):
    """A 0.5 s run of Simulation 1 saved as walk.py saves it, with its reference and audit: (results.npz, traj,
    report)."""
    from humanoid_sim.interfaces.log import load_results
    from humanoid_sim.outputs.plots.thesis import audit_of
    from humanoid_sim.scenario.schema import load_scenario
    from humanoid_sim.sim.simulate import Simulator

    sim = Simulator(hm, load_scenario(SIM1))
    result = sim.run(t_end=0.5)
    out = tmp_path_factory.mktemp("run") / "results.npz"
    result.log.save(out, [p.name for p in sim.traj.phases])
    return out, sim.traj, audit_of(load_results(out), 0.8, hm)


def _meshcat_animation(vis, fr, fps):
    """The animation as meshcat builds it, frame by frame (the code the fast one replaced)."""
    from meshcat.animation import Animation

    from humanoid_sim.outputs.viewer.recording import prune_keys

    anim = Animation(default_framerate=fps)
    for i in range(len(fr)):
        with anim.at_frame(vis, i) as frame:
            for path, T in fr.transforms.items():
                frame[path].set_transform(T[i])
            for path, s in fr.scales.items():
                frame[path].set_property("scale", "vector3", [float(x) for x in s[i]])
            for path, v in fr.visible.items():
                frame[path].set_property("visible", "boolean", bool(v[i]))
    prune_keys(anim)
    return anim


def test_the_animation_is_meshcats_and_packs_to_the_same_bytes(run, hm: HumanoidModel) -> None:
    """_animation gives meshcat's frame-by-frame animation: the same clips in the same order, the same tracks, keys
    and values (types included), and the same packed command (umsgpack, single floats)."""
    import meshcat
    from meshcat.commands import SetAnimation

    from humanoid_sim.interfaces.log import load_results
    from humanoid_sim.outputs.viewer.frames import build_frames
    from humanoid_sim.outputs.viewer.recording import _animation, _RecordingWindow, packb

    path, traj, report = run
    fr = build_frames(load_results(path), hm, traj, fps=30.0, report=report)
    vis = meshcat.Visualizer(window=_RecordingWindow())
    fast, ref = _animation(vis, fr, 30.0), _meshcat_animation(vis, fr, 30.0)
    assert list(fast.clips) == list(ref.clips) and len(ref.clips) > 10
    for key, clip in ref.clips.items():
        other = fast.clips[key]
        assert list(other.tracks) == list(clip.tracks), key.lower()
        for name, track in clip.tracks.items():
            t = other.tracks[name]
            assert (t.name, t.jstype, t.frames) == (track.name, track.jstype, track.frames), (key.lower(), name)
            assert [[type(x) for x in v] if isinstance(v, list) else type(v) for v in t.values] == \
                [[type(x) for x in v] if isinstance(v, list) else type(v) for v in track.values]
            assert t.values == track.values, (key.lower(), name)
    cmd_fast = SetAnimation(fast, play=True, repetitions=1).lower()
    cmd_ref = SetAnimation(ref, play=True, repetitions=1).lower()
    assert packb(cmd_fast, single=True) == umsgpack.packb(cmd_ref, force_float_precision="single")


def test_quaternions_are_meshcats_bit_for_bit() -> None:
    """The batched quaternions equal meshcat's quaternion_from_matrix per matrix, bit for bit: random rotations,
    rotations by pi (two equal eigenvalues), the identity and w close to 0."""
    from meshcat import transformations as tf

    from humanoid_sim.outputs.viewer.recording import quaternions

    rng = np.random.default_rng(7)
    Ts = [tf.random_rotation_matrix(rng.random(3)) for _ in range(300)]
    Ts += [tf.rotation_matrix(np.pi, d) for d in ([1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0])]
    Ts += [np.eye(4), tf.rotation_matrix(np.pi - 1e-9, [0, 0, 1]), tf.rotation_matrix(1e-12, [1, 0, 0])]
    for T in Ts:
        T[:3, 3] = rng.normal(size=3)
    T = np.array(Ts)
    q = quaternions(T)
    for i in range(len(T)):
        assert q[i].tobytes() == tf.quaternion_from_matrix(T[i]).tobytes(), i


def test_msgpack_packs_every_command_as_umsgpack(run, hm: HumanoidModel) -> None:
    """Every command of a recording (objects with their typed arrays, transforms, properties, the animation) packs
    to umsgpack's bytes, in double and in single precision."""
    from humanoid_sim.outputs.viewer import recording

    if recording.msgpack is None:  # pragma: no cover
        pytest.skip("msgpack is not installed: the recording packs with umsgpack itself")
    path, traj, report = run
    sent = []

    class Keep(recording._RecordingWindow):
        def send(self, command) -> None:
            sent.append(command.lower())
            super().send(command)

    real = recording._RecordingWindow
    recording._RecordingWindow = Keep
    try:
        recording.record(path, hm, traj, report=report)
    finally:
        recording._RecordingWindow = real
    kinds = {c["type"] for c in sent}
    assert {"set_object", "set_transform", "set_property", "set_animation"} <= kinds

    def exts(x) -> int:
        if isinstance(x, umsgpack.Ext):
            return 1
        if isinstance(x, dict):
            return sum(exts(v) for v in x.values())
        if isinstance(x, (list, tuple)):
            return sum(exts(v) for v in x)
        return 0

    assert sum(exts(c) for c in sent) > 0   # meshcat's typed arrays (vertex buffers) are among them
    for c in sent:
        for single in (False, True):
            expect = umsgpack.packb(c, force_float_precision="single") if single else umsgpack.packb(c)
            assert recording.packb(c, single=single) == expect, c["type"]


def test_the_figure_modules_import_without_matplotlib() -> None:
    """Importing the figure modules (the catalogue of figures, plot_all) loads no matplotlib: a walk's own process
    loads it only if it draws a figure itself."""
    code = ("import sys; import humanoid_sim.outputs.plots.thesis, humanoid_sim.outputs.plots.audit, "
            "humanoid_sim.outputs.plots.pool; print('matplotlib' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "False"


def test_figures_drawn_by_workers_started_ahead_are_the_same(run, tmp_path: Path) -> None:
    """plot_all on the workers pool.start started (forked before the figures, warmed up) writes the files plot_all
    writes with its own workers, pixel for pixel."""
    from PIL import Image

    from humanoid_sim.outputs.plots import pool
    from humanoid_sim.outputs.plots.thesis import QUICK_FIGURES, plot_all, warm_up

    path, traj, report = run
    own = plot_all(path, tmp_path / "own", traj, report=report, stems=QUICK_FIGURES, title="sim1")
    assert pool.running() is None
    started = pool.start(len(QUICK_FIGURES), warm_up)
    try:
        ahead = plot_all(path, tmp_path / "ahead", traj, report=report, stems=QUICK_FIGURES, title="sim1")
        assert pool.running() is not None and (started is None or pool.running()[0] is started)
    finally:
        pool.stop()
    assert pool.running() is None
    assert [p.name for p in own] == [p.name for p in ahead] == [f"{s}.png" for s in QUICK_FIGURES]
    for a, b in zip(own, ahead):
        np.testing.assert_array_equal(np.asarray(Image.open(a)), np.asarray(Image.open(b)), err_msg=a.name)


def test_a_walk_with_figures_never_loads_matplotlib_itself(tmp_path: Path) -> None:
    """walk.py's default (quick figures, playback): the figures are drawn by the workers started before the walk,
    and its own process never imports matplotlib (the ~0.35 s import stays off the walk's critical path)."""
    code = ("import sys; from humanoid_sim.cli.walk import main; "
            f"rc = main([{str(SIM1)!r}, '--out', {str(tmp_path / 'out')!r}, '--quiet', '--until', '0.3']); "
            "print(rc, 'matplotlib' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines()[-1] == "0 False", r.stdout
    assert sorted(p.name for p in (tmp_path / "out").glob("*.png")) == sorted(
        ["phases.png", "torques_right_toe_ankle.png", "torques_right_knee_hip.png", "contact_world.png",
         "contact_audit.png"])
    assert (tmp_path / "out" / "playback.html").is_file()


def _die() -> None:
    import os

    os._exit(3)


def test_plot_all_draws_with_its_own_workers_when_the_ones_started_ahead_died(run, tmp_path: Path) -> None:
    """A worker started ahead that dies while it warms up (killed, say) breaks that pool: plot_all then draws with
    workers of its own, the same figures."""
    import time

    from humanoid_sim.outputs.plots import pool
    from humanoid_sim.outputs.plots.thesis import plot_all

    path, traj, report = run
    if pool.start(2, _die) is None:  # pragma: no cover - one CPU, or no fork: plot_all draws in its own process
        pytest.skip("no workers started ahead on this machine")
    try:
        time.sleep(0.5)
        written = plot_all(path, tmp_path, traj, report=report, stems=("phases", "contact_audit"), title="sim1")
    finally:
        pool.stop()
    assert [p.name for p in written] == ["phases.png", "contact_audit.png"]
    assert all(p.stat().st_size > 1000 for p in written)
