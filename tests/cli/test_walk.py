"""walk.py end to end: bad input (exit 2, one message, nothing written), failing runs (exit 1, partial results
kept), Ctrl-C (exit 1, partial results kept), and the contact audit of a short Simulation-1 run in
summary.json and contact_audit.png.

Subprocess runs cost ~1 s of imports each; they are kept to a representative handful, the rest of the
validation is tested through parse_scenario in tests/scenario/test_schema.py.
"""

from __future__ import annotations

import copy
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from humanoid_sim.cli.walk import main
from humanoid_sim.interfaces.log import load_results

ROOT = Path(__file__).resolve().parents[2]
WALK = ROOT / "scripts" / "walk.py"
SIM1 = ROOT / "scripts" / "params" / "sim1.yaml"
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def walk(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(WALK), *args], capture_output=True, text=True, env=ENV,
                          timeout=timeout, cwd=ROOT)


def sim1_variant(tmp_path: Path, name: str, edit) -> Path:
    doc = yaml.safe_load(SIM1.read_text())
    doc = copy.deepcopy(doc)
    edit(doc)
    doc["name"] = name
    p = tmp_path / f"{name}.yaml"
    p.write_text(yaml.safe_dump(doc, sort_keys=False))
    return p


def check_partial(out: Path, reason_start: str | tuple[str, ...]) -> tuple[dict, dict]:
    """results.npz and summary.json exist, load, and say the run did not complete."""
    summary = json.loads((out / "summary.json").read_text())
    res = load_results(out / "results.npz")
    assert summary["completed"] is False
    assert summary["reason"].startswith(reason_start), summary["reason"]
    assert summary["steps"] == len(res["t"])
    assert not list(out.glob(".*.tmp"))  # atomic writes leave no temporaries
    return summary, res


# --------------------------------------------------------------------------------------------- bad input
BAD_INPUT = [
    ("not-yaml", "path: [1, 2\n", "not valid YAML at line"),
    ("empty", "", "the file is empty"),
    ("unknown-key", None, "controler: unknown key; did you mean 'controller'?"),
    ("wrong-length", None, "path.Vhip: expected 2n-1 = 17 speeds for n = 9 waypoints"),
    ("impossible-arc", None, "path.R[0]: arc cannot exist"),
]


def _bad_text(case: str, text: str | None) -> str:
    if text is not None:
        return text
    doc = yaml.safe_load(SIM1.read_text())
    if case == "unknown-key":
        doc["controler"] = doc.pop("controller")
    elif case == "wrong-length":
        doc["path"]["Vhip"] = doc["path"]["Vhip"][:-1]
    elif case == "impossible-arc":
        doc["path"]["R"][0] = 0.05
    return yaml.safe_dump(doc, sort_keys=False)


@pytest.mark.parametrize("case, text, needle", BAD_INPUT, ids=[c[0] for c in BAD_INPUT])
def test_bad_scenario_exits_2_and_writes_nothing(tmp_path, case, text, needle):
    scen = tmp_path / f"{case}.yaml"
    scen.write_text(_bad_text(case, text))
    out = tmp_path / "out"
    r = walk(str(scen), "--out", str(out), "--quiet")
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith(f"walk.py: error: {scen}: ") and needle in r.stderr, r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert r.stdout == ""
    assert not out.exists()


def test_missing_file_and_object_tag_exit_2_without_running_code(tmp_path):
    out = tmp_path / "out"
    r = walk(str(tmp_path / "nope.yaml"), "--out", str(out))
    assert r.returncode == 2 and "no such scenario file" in r.stderr and "Traceback" not in r.stderr
    marker = tmp_path / "pwned"
    scen = tmp_path / "evil.yaml"
    scen.write_text(f"name: !!python/object/apply:os.system ['touch {marker}']\n")
    r = walk(str(scen), "--out", str(out))
    assert r.returncode == 2, r.stderr
    assert "tags that construct objects are refused" in r.stderr and "Traceback" not in r.stderr
    assert not marker.exists() and not out.exists()


def test_bad_until_exits_2():
    assert main(["--until", "-1", "--out", "/nonexistent/never"]) == 2


# --------------------------------------------------------------------------------------------- failing runs
@pytest.mark.slow
def test_unstable_scenario_exits_1_with_partial_results(tmp_path):
    """Zero weights on every hip (Body-17) tracking term: only the joint-deviation terms hold the posture, and
    the motion diverges at the first touchdown (joint rates beyond the divergence limit, or the hip CoM below
    the fall height, whichever the step shows first)."""
    def no_hip_task(doc: dict) -> None:
        for k, v in doc["controller"].items():
            if k.startswith(("Wp_fa_", "Wv_fa_", "Wor_fa_")):
                doc["controller"][k] = [0] * len(v)
    scen = sim1_variant(tmp_path, "nohip", no_hip_task)
    out = tmp_path / "out"
    r = walk(str(scen), "--out", str(out), "--quiet", "--no-html", "--no-plots", "--until", "3")
    assert r.returncode == 1, (r.stdout, r.stderr)
    assert "Traceback" not in r.stderr
    summary, res = check_partial(out, ("diverged at t = ", "fall: hip CoM height"))
    assert f"FAILED -- {summary['reason']}" in r.stdout
    assert len(res["t"]) > 10  # it walked a little before failing
    # the log ends with the last step started before the failure: the reason's time is one step later
    t_fail = float(summary["reason"].rsplit("at t = ", 1)[1].split(" s")[0])
    assert t_fail == pytest.approx(res["t"][-1] + 0.01, abs=1e-3)  # 1e-3: the reason prints t with 3 decimals
    assert summary["sim_time_s"] == pytest.approx(t_fail, abs=1e-3)
    assert "contact" in summary and summary["contact"]["steps"] == len(res["t"])


def test_phase_overtime_exits_1(tmp_path):
    """A phase may last at most max_phase_overtime x its nominal duration; 1.01 is exceeded within the walk."""
    scen = sim1_variant(tmp_path, "overtime",
                        lambda d: d["simulation"].__setitem__("max_phase_overtime", 1.01))
    out = tmp_path / "out"
    assert main([str(scen), "--out", str(out), "--quiet", "--no-html", "--no-plots", "--until", "3"]) == 1
    summary, res = check_partial(out, "phase ")
    assert "more than 1.01 x its nominal" in summary["reason"]


def test_singular_controller_exits_1_even_with_an_empty_log(tmp_path):
    """All controller weights zero: the command-acceleration system is singular at the very first stage."""
    def zero(doc: dict) -> None:
        for k, v in doc["controller"].items():
            if not k.startswith("Delta"):
                doc["controller"][k] = [0] * len(v) if isinstance(v, list) else 0
    scen = sim1_variant(tmp_path, "zero", zero)
    out = tmp_path / "out"
    assert main([str(scen), "--out", str(out), "--quiet", "--no-html"]) == 1
    summary, res = check_partial(out, "CommandError at t = 0.000 s in phase 1 (LFFSSP): LFFSSP step 1 (Body 17): "
                                      "the cost's normal matrix is singular")
    assert summary["steps"] == 0 and summary["contact"]["steps"] == 0
    assert not (out / "contact_audit.png").exists()  # nothing to plot


@pytest.mark.parametrize("fault, reason_start", [("nan", "non-finite"),
                                                 ("singular", "SingularConstraintError at t = ")])
def test_injected_runtime_faults_exit_1(tmp_path, monkeypatch, fault, reason_start):
    """Fault injection into the weld engine's dynamics after 60 healthy evaluations: a NaN acceleration
    (a diverging motion) or a rank-deficient constraint system.  The run stops with exit 1, the one-line
    reason, and the steps before the fault on disk."""
    from humanoid_sim.dynamics.contact import SingularConstraintError
    from humanoid_sim.engines import weld

    original = weld.WeldEngine._motion
    calls = {"n": 0}

    def motion(self, *args, **kwargs):
        calls["n"] += 1
        a, lam = original(self, *args, **kwargs)
        if calls["n"] > 60:
            if fault == "singular":
                raise SingularConstraintError("injected: constraint Jacobian rank 12 < 13 rows")
            a = np.full_like(a, np.nan)
        return a, lam

    monkeypatch.setattr(weld.WeldEngine, "_motion", motion)
    out = tmp_path / "out"
    assert main([str(SIM1), "--out", str(out), "--quiet", "--no-html", "--no-plots", "--until", "1"]) == 1
    summary, res = check_partial(out, reason_start)
    assert "\n" not in summary["reason"]
    assert 0 < len(res["t"]) < 60 and np.all(np.isfinite(res["q"]))  # the healthy steps, nothing after


SIGINT_EXIT_S = 2.0
"""s: the longest a walk may take to exit after Ctrl-C, its log saved."""


@pytest.mark.slow
def test_sigint_keeps_partial_results_and_exits_at_once(tmp_path):
    """Ctrl-C mid-walk: results.npz and summary.json written, the figures and playback (which were asked for)
    skipped, the process gone within SIGINT_EXIT_S."""
    # sim1 with a 2 ms step: five times the work of the default walk (~5-10 s wall), so that the interrupt lands
    # in the stepping loop however fast the simulator becomes
    scen = sim1_variant(tmp_path, "fine", lambda d: d["simulation"].__setitem__("step_s", 0.002))
    out = tmp_path / "out"
    # the child gets SIGINT's default disposition back: a test run started in the background by a
    # non-interactive shell inherits "ignore SIGINT", and Python then never raises KeyboardInterrupt
    proc = subprocess.Popen([sys.executable, str(WALK), str(scen), "--out", str(out), "--quiet", "--figures", "all"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV,
                            cwd=ROOT, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 60
        while not out.exists():  # walk.py creates the folder just before the simulation starts
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "walk.py did not start simulating within 60 s"
            time.sleep(0.02)
        time.sleep(0.5)  # a fraction of the walk: it takes several seconds of wall time
        proc.send_signal(signal.SIGINT)
        sent = time.monotonic()
        stdout, stderr = proc.communicate(timeout=60)
        exit_s = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1, (stdout, stderr)
    assert "Traceback" not in stderr
    assert exit_s <= SIGINT_EXIT_S, f"walk.py took {exit_s:.2f} s to exit after SIGINT"
    summary, res = check_partial(out, "interrupted by the user at t = ")
    assert summary["status"] == "interrupted"
    assert 0 < len(res["t"]) and summary["phases_completed"] < summary["phases_planned"]
    assert np.all(np.diff(res["t"]) > 0)
    assert not list(out.glob("*.png")) and not (out / "playback.html").exists()
    assert "INTERRUPTED (stopped on request" in stdout and "figures and playback skipped" in stderr


# --------------------------------------------------------------------------------------------- the audit
def test_short_sim1_run_reports_the_contact_audit(tmp_path, hm, monkeypatch):
    import humanoid_sim.outputs.plots.thesis

    # the other figures (humanoid_sim/outputs/plots/thesis.py, ~5 s) are not under test here: only contact_audit.png
    monkeypatch.setattr(humanoid_sim.outputs.plots.thesis, "figure_stems", lambda r=None: ["contact_audit"])
    monkeypatch.setattr(humanoid_sim.outputs.plots.thesis, "reference_figures", lambda *a, **k: {})
    out = tmp_path / "out"
    assert main([str(SIM1), "--out", str(out), "--quiet", "--no-html", "--until", "0.9"]) == 0
    png = out / "contact_audit.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    c = json.loads((out / "summary.json").read_text())["contact"]
    r = load_results(out / "results.npz")
    assert c["friction_coefficient"] == 0.8 and c["steps"] == len(r["t"])
    # independent recomputation from the logged per-foot world wrenches
    for i, foot in enumerate("RL"):
        on = r["in_contact"][:, i]
        assert c["contact_steps"][foot] == int(on.sum()) > 0
        f = r["foot_wrench"][on, i, :3]
        assert c["min_normal_force_N"][foot] == pytest.approx(f[:, 2].min(), rel=1e-12)  # same numbers
        assert c["max_friction_ratio"][foot] == pytest.approx(np.max(np.hypot(f[:, 0], f[:, 1]) / f[:, 2]),
                                                              rel=1e-12)
        for key in ("cop_outside_fraction", "friction_exceeded_fraction", "pulling_fraction"):
            assert 0.0 <= c[key][foot] <= 1.0
    # per phase: LFFSSP (right foot in the air), then RFFDSP; the step counts add up
    assert list(c["per_phase"])[:2] == ["LFFSSP", "RFFDSP"]
    assert c["per_phase"]["LFFSSP"]["contact_steps"]["R"] == 0
    assert sum(p["steps"] for p in c["per_phase"].values()) == len(r["t"])
    # CoP outside the flat left sole during LFFSSP, recomputed another way: the logged CoP taken into the foot
    # frame O_4 and compared with the rectangle of models/thesis_humanoid.yaml
    sole = {k: v["value"] for k, v in yaml.safe_load((ROOT / "models" / "thesis_humanoid.yaml").read_text())
            ["foot_sole"].items()}
    data = hm.model.createData()
    rows = np.flatnonzero(r["basic_phase"] == 0)
    outside = 0
    for k in rows:
        pin.framesForwardKinematics(hm.model, data, r["q"][k])
        M = data.oMf[hm.model.getFrameId("O_4")]
        # the ground point seen along the foot's z axis: intersect the vertical through the CoP with the sole
        # plane is not needed, the foot is flat to ~1e-5 rad (weld drift), so compare x, y in the foot frame
        x, y, _ = M.actInv(r["cop"][k, 1])
        outside += not (sole["heel_back_x"] <= x <= sole["toe_front_x"] and abs(y) <= sole["width"] / 2)
    assert c["per_phase"]["LFFSSP"]["cop_outside_fraction"]["L"] == pytest.approx(outside / len(rows), abs=1e-12)
    assert 0.0 <= c["zmp_outside_fraction"] <= 1.0


def test_no_kernel_runs_every_stage_on_the_reference_path(tmp_path):
    """--no-kernel: summary.json counts 0 compiled stages; the default run compiles the single-support stages
    (when numba is installed) and both give the same walk (hip path within 1e-9 m: round-off only)."""
    from humanoid_sim import kernel

    runs = {}
    for flag in ([], ["--no-kernel"]):
        out = tmp_path / ("ref" if flag else "default")
        assert main([str(SIM1), "--out", str(out), "--quiet", "--no-html", "--no-plots", "--until", "0.5"] + flag) == 0
        runs[bool(flag)] = (json.loads((out / "summary.json").read_text()), load_results(out / "results.npz"))
    s_ref, r_ref = runs[True]
    assert s_ref["compiled_stages"] == 0 and s_ref["reference_stages"] == 3 * s_ref["steps"]
    s_def, r_def = runs[False]
    assert kernel.AVAILABLE  # numba is a required dependency: the default run is compiled
    assert s_def["compiled_stages"] > 0.9 * 3 * s_def["steps"]
    assert np.abs(r_def["hip_p"] - r_ref["hip_p"]).max() < 1e-9


# --------------------------------------------------------------------------------------------- outputs
@pytest.mark.slow
@pytest.mark.parametrize("umask", [0o022, 0o027], ids=["umask-022", "umask-027"])
def test_outputs_get_the_mode_open_would_give(tmp_path, umask):
    """Every output (also those written through a temporary file and a rename) has mode 0666 less the umask, as
    a plain open() would give it: 0644 under the usual umask 022, so results can be shared."""
    out = tmp_path / "out"
    old = os.umask(umask)
    try:
        assert main([str(SIM1), "--out", str(out), "--quiet", "--until", "0.3", "--figures", "all"]) == 0
    finally:
        os.umask(old)
    files = sorted(out.iterdir())
    names = {p.name for p in files}
    assert {"results.npz", "summary.json", "playback.html", "contact_audit.png", "task_hip.png"} <= names
    for p in files:
        assert (p.stat().st_mode & 0o777) == (0o666 & ~umask), f"{p.name}: {oct(p.stat().st_mode & 0o777)}"


def test_no_stale_outputs_beside_a_new_run(tmp_path, capsys):
    """A run with --no-plots --no-html removes the figures and playback an earlier run left in its folder (also
    the names earlier versions used) and says which outputs there are; other files stay."""
    from humanoid_sim.outputs.plots.thesis import FIGURES

    out = tmp_path / "out"
    out.mkdir()
    stale = [f"{stem}.png" for stem in FIGURES] + ["joints_theta15-17l.png", "playback.html"]
    for name in stale:
        (out / name).write_bytes(b"from an earlier run")
    (out / "my_notes.txt").write_text("mine")
    assert main([str(SIM1), "--out", str(out), "--until", "0.3", "--no-plots", "--no-html", "--quiet"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["design.csv", "fatigue.csv", "load_cases.json", "my_notes.txt",
                                                     "results.npz", "summary.json"]
    printed = capsys.readouterr().out
    assert ("results.npz, summary.json, design.csv, fatigue.csv, load_cases.json, no figures (--no-plots), "
            "no playback.html (--no-html)") in printed
    assert f"removed {len(stale)} outputs of an earlier run" in printed


# --------------------------------------------------------------------------------------------- terminal
@pytest.mark.slow
@pytest.mark.parametrize("until", [None, "1.0"], ids=["whole-walk", "until"])
def test_progress_bar_reaches_100_percent_without_warnings(tmp_path, until):
    """The bar ends at 100 % (the whole walk, and --until), with no stray comma before the phase and no tqdm
    warning (--until once clamped a fraction above 1 and showed a negative remaining time)."""
    args = [str(SIM1), "--out", str(tmp_path / "out"), "--no-plots", "--no-html"] + (["--until", until] if until
                                                                                     else [])
    r = walk(*args)
    assert r.returncode == 0, r.stderr
    last = r.stderr.replace("\r", "\n").strip().splitlines()[-1]
    total = "1.00" if until else "6.88"
    assert last.startswith("100%|") and f"{total}/{total} sim s" in last, last
    assert "] phase" in last and "] , phase" not in last and ", phase" not in r.stderr, last
    assert "Warning" not in r.stderr and "clamping" not in r.stderr and "<-" not in r.stderr, r.stderr


# --------------------------------------------------------------------------------------------- first run
@pytest.mark.slow
def test_first_run_gives_the_same_bits_with_or_without_the_kernel_cache(tmp_path):
    """The first run after an install builds the kernel cache in two child processes (humanoid_sim/sim/builds.py,
    callees not re-optimised); its walk is bit for bit the walk of a kernel compiled the ordinary way in-process
    (HUMANOID_SIM_KERNEL_BUILD=0), and so is the next run, which loads the cache.  Each cold compile is tens of
    seconds: this is the slowest test of the file."""
    def run(name: str, cache: Path, **env) -> dict:
        out = tmp_path / name
        r = subprocess.run([sys.executable, str(WALK), str(SIM1), "--out", str(out), "--until", "1.0", "--no-plots",
                            "--no-html", "--quiet"], capture_output=True, text=True, cwd=ROOT, timeout=600,
                           env={**ENV, "NUMBA_CACHE_DIR": str(cache), **env})
        assert r.returncode == 0, r.stderr
        summary = json.loads((out / "summary.json").read_text())
        assert summary["compiled_stages"] > 0.9 * 3 * summary["steps"]  # the kernel ran, in both phase kinds
        return load_results(out / "results.npz")

    ordinary = run("ordinary", tmp_path / "cache-ordinary", HUMANOID_SIM_KERNEL_BUILD="0")
    built = run("built", tmp_path / "cache-built")
    assert any((tmp_path / "cache-built").rglob("*.nbi")), "the build wrote no cache"
    cached = run("cached", tmp_path / "cache-built")
    for other in (built, cached):
        assert set(other) == set(ordinary)
        for k, v in ordinary.items():
            assert v.tobytes() == other[k].tobytes(), k  # bit for bit
    assert set(np.unique(ordinary["basic_phase"])) >= {0, 1, 2}  # single and double support both ran
    # the build stores callees as LLVM bitcode without machine code: another process that calls one from Python
    # (StageKernel.split calls the two halves of ssp_stage) loads it from the cache (no compile) and gets the bits of
    # the entry point that has it linked in
    r = subprocess.run([sys.executable, "-c", SPLIT_FROM_CACHE, str(SIM1)], capture_output=True, text=True, cwd=ROOT,
                       timeout=600, env={**ENV, "NUMBA_CACHE_DIR": str(tmp_path / "cache-built")})
    assert r.returncode == 0 and r.stdout.strip() == "same bits, loaded from the cache", r.stdout + r.stderr


SPLIT_FROM_CACHE = """
import sys
from pathlib import Path
from humanoid_sim.controllers.thesis import compiled
from humanoid_sim.sim import builds as build
from humanoid_sim.robot.phases import Phase
kern, stage_args, *_ = build.sample_stage(Path(sys.argv[1]))
fused = kern.stage(Phase.LFFSSP, *stage_args(Phase.LFFSSP))
kern.split = True
split = kern.stage(Phase.LFFSSP, *stage_args(Phase.LFFSSP))
for name in ("a", "lam", "thdd_c", "T_cmd", "tau", "log"):
    a, b = getattr(fused, name), getattr(split, name)
    assert a.tobytes() == b.tobytes(), (name, a, b)
for disp in (compiled.ssp_stage, compiled.ssp_controller, compiled.ssp_dynamics):
    hits, misses = sum(disp.stats.cache_hits.values()), sum(disp.stats.cache_misses.values())
    assert hits == 1 and misses == 0, (disp, disp.stats)
print("same bits, loaded from the cache")
"""


def test_kernel_build_children_compile_the_loaded_package(tmp_path, monkeypatch):
    """``python -m`` puts the working directory first on sys.path: a build started from another checkout's folder
    compiled that checkout's compiled.py, and the walk then compiled its own in-process (a 75 s first run, measured).
    The children run from the root of the package this process loaded, with the scenario path made absolute."""
    from humanoid_sim.sim import builds as build

    seen = []

    class FakePopen:
        def __init__(self, cmd, **kw):
            seen.append((cmd, kw))

        def poll(self):
            return 0

    monkeypatch.setattr(build.subprocess, "Popen", FakePopen)
    monkeypatch.chdir(tmp_path)
    running = build.KernelBuild("scripts/params/sim1.yaml").start()
    running.stop()
    assert len(seen) == len(build.PARTS)
    package_root = Path(build.__file__).resolve().parents[2]
    for cmd, kw in seen:
        assert Path(kw["cwd"]) == package_root
        assert Path(cmd[-1]).is_absolute() and Path(cmd[-1]) == tmp_path / "scripts/params/sim1.yaml"


def test_the_kernel_build_compiles_what_the_walks_controller_calls(monkeypatch):
    """A zmp_preview walk driven by the balance controller builds the support and balance parts (not the thesis
    controller's stages it never calls); with gait.controller: thesis, or a user's controller, the thesis parts.
    The balance part's representative call runs (here from the cache the other tests filled)."""
    from humanoid_sim.scenario.schema import load_scenario
    from humanoid_sim.sim import builds as build

    zmp = load_scenario(ROOT / "scripts" / "params" / "sim3_zmp.yaml")
    assert build.parts_for(zmp) == build.BALANCE_PARTS == ("support", "balance")
    assert build.parts_for(load_scenario(ROOT / "scripts" / "params" / "sim3.yaml")) == build.PARTS
    thesis_exec = copy.deepcopy(zmp)
    object.__setattr__(thesis_exec.gait, "controller", "thesis")
    assert build.parts_for(thesis_exec) == build.PARTS
    names = {n for part in build.BALANCE_PARTS for n in build.PLAN[part]}
    assert {"balance_stage", "balance_finish", "project_on_support", "advance_on_support"} == names
    called = []
    from humanoid_sim.controllers.balance import compiled

    real = compiled.balance_stage
    monkeypatch.setattr("humanoid_sim.controllers.balance.controller.balance_stage",
                        lambda *a: called.append(1) or real(*a))
    build._compile_balance(ROOT / "scripts" / "params" / "sim3_zmp.yaml")
    assert called == [1]


# --------------------------------------------------------------------------------------------- what the results say
@pytest.fixture(scope="module")
def stopped_run(tmp_path_factory) -> tuple[int, str, Path]:
    """A 0.2 s --until run of Simulation 1 with the default figures: (exit status, console, output folder)."""
    import contextlib
    import io

    out = tmp_path_factory.mktemp("stopped") / "out"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main([str(SIM1), "--out", str(out), "--quiet", "--no-html", "--until", "0.2"])
    return rc, buf.getvalue(), out


def test_until_run_exits_0_and_says_it_stopped_as_requested(stopped_run):
    rc, printed, out = stopped_run
    assert rc == 0
    assert "sim1 on pinocchio (welded feet): stopped at t = 0.200 s (requested)" in printed
    assert json.loads((out / "summary.json").read_text())["status"] == "stopped"


def test_default_figures_are_the_quick_set(stopped_run):
    from humanoid_sim.outputs.plots.thesis import FIGURES, QUICK_FIGURES

    _, printed, out = stopped_run
    assert {p.stem for p in out.glob("*.png")} == set(QUICK_FIGURES)
    assert set(QUICK_FIGURES) < set(FIGURES) and len(FIGURES) == 27
    assert f"{len(QUICK_FIGURES)} figures (*.png, --figures all for the full set)" in printed


def test_summary_records_the_provenance(stopped_run):
    import humanoid_sim

    s = json.loads((stopped_run[2] / "summary.json").read_text())["provenance"]
    assert set(s) == {"version", "git_commit", "packages", "date", "command"}
    assert s["version"] == humanoid_sim.__version__
    assert s["git_commit"] is None or (isinstance(s["git_commit"], str) and len(s["git_commit"]) == 40)
    assert set(s["packages"]) == {"pin", "mujoco", "numpy", "numba", "scipy"}
    assert s["packages"]["numpy"] == np.__version__
    assert all(v is None or isinstance(v, str) for v in s["packages"].values())
    from datetime import datetime, timezone
    date = datetime.fromisoformat(s["date"])
    assert date.tzinfo is not None and date.utcoffset().total_seconds() == 0
    assert abs((datetime.now(timezone.utc) - date).total_seconds()) < 3600
    assert s["command"] == ["walk.py", str(SIM1), "--out", str(stopped_run[2]), "--quiet", "--no-html", "--until",
                            "0.2"]


def test_results_name_the_joints_and_actuators(stopped_run, hm):
    from humanoid_sim.robot.actuators import T_NAMES
    from humanoid_sim.robot.model import THETA_NAMES

    r = load_results(stopped_run[2] / "results.npz")
    assert list(r["theta_names"]) == list(THETA_NAMES) and len(THETA_NAMES) == r["theta"].shape[1]
    assert list(r["T_names"]) == list(T_NAMES) and len(T_NAMES) == r["T"].shape[1]
    assert len(r["q_names"]) == r["q"].shape[1] and len(r["v_names"]) == r["v"].shape[1]
    j = hm.model.getJointId("theta9")
    assert r["q_names"][hm.model.joints[j].idx_q] == "theta9" and r["v_names"][hm.model.joints[j].idx_v] == "theta9"
    assert str(r["engine"]) == "pinocchio"


def test_default_output_folder_is_keyed_by_scenario_and_engine():
    from humanoid_sim.cli.walk import default_out

    assert default_out("sim1_zmp", "pinocchio") == Path("results/sim1_zmp/pinocchio")
    assert default_out("sim1_zmp", "mujoco") != default_out("sim1_zmp", "pinocchio")


@pytest.mark.slow
def test_two_engines_leave_two_output_folders_and_mujoco_speaks_of_real_contact(tmp_path, monkeypatch, capsys):
    """sim1 without --out on the welds, then on MuJoCo (where it falls at once): both folders stay, each with its
    engine's summary; the MuJoCo console names the ground figures and never the welds."""
    monkeypatch.chdir(tmp_path)
    assert main([str(SIM1), "--until", "0.1", "--quiet", "--no-html", "--figures", "none"]) == 0
    weld = capsys.readouterr().out
    assert main([str(SIM1), "--until", "0.1", "--quiet", "--no-html", "--figures", "none", "--engine", "mujoco"]) == 1
    mj = capsys.readouterr().out
    for engine in ("pinocchio", "mujoco"):
        s = json.loads((tmp_path / "results" / "sim1" / engine / "summary.json").read_text())
        assert s["engine"] == engine
    assert "weld drift max" in weld and "welded feet" in weld   # the check below can fail
    assert "weld" not in mj.lower() and "held" not in mj
    assert "sim1 on mujoco (real contact): FELL -- " in mj
    for words in ("on the ground: FELL at t = ", "foot slip max", "stance foot tilt max", "penetration max",
                  "contact forces of real unilateral contact (mujoco)"):
        assert words in mj, (words, mj)


def test_figures_all_none_and_no_plots(tmp_path, monkeypatch):
    import humanoid_sim.outputs.plots.thesis as thesis

    drawn = []
    monkeypatch.setattr(thesis, "plot_all", lambda *a, stems=None, **k: drawn.append(tuple(stems)) or [])
    for flags in (["--figures", "all"], ["--figures", "none"], ["--no-plots"], []):
        assert main([str(SIM1), "--out", str(tmp_path / "o"), "--quiet", "--no-html", "--until", "0.1"] + flags) == 0
    assert drawn == [thesis.FIGURES, thesis.QUICK_FIGURES]
    assert main([str(SIM1), "--out", str(tmp_path / "o"), "--no-plots", "--figures", "all"]) == 2


def test_a_run_that_ends_before_its_first_step_draws_no_figures(tmp_path, capsys):
    """All controller weights zero: the first stage fails, the log is empty; no figure is drawn, and the console
    says why."""
    def zero(doc: dict) -> None:
        for k, v in doc["controller"].items():
            if not k.startswith("Delta"):
                doc["controller"][k] = [0] * len(v) if isinstance(v, list) else 0
    scen = sim1_variant(tmp_path, "zero", zero)
    out = tmp_path / "out"
    assert main([str(scen), "--out", str(out), "--quiet", "--no-html", "--figures", "all"]) == 1
    assert json.loads((out / "summary.json").read_text())["steps"] == 0
    assert not list(out.glob("*.png"))
    assert "no figures (the run ended before its first step: nothing to plot)" in capsys.readouterr().out


@pytest.mark.slow
def test_zmp_planning_says_how_long_it_took(tmp_path):
    r = walk(str(ROOT / "scripts" / "params" / "sim3_fast_zmp.yaml"), "--out", str(tmp_path / "o"), "--until",
             "0.05", "--figures", "none", "--no-html")
    assert r.returncode == 0, r.stderr
    assert "walk.py: planning the zmp_preview gait" in r.stderr
    line = next(x for x in r.stderr.splitlines() if x.startswith("walk.py: planned the gait"))
    assert float(line.rsplit(" in ", 1)[1].split(" s")[0]) > 0


# --------------------------------------------------------------------------------------------- from Python
def test_run_walk_says_when_it_compiles_and_records_the_call(monkeypatch, capsys):
    import humanoid_sim as hs
    from humanoid_sim import jit

    monkeypatch.setattr(jit, "cache_present", lambda: False)   # as on the first run after an install
    run = hs.run_walk("sim1", until=0.05)
    assert "humanoid_sim: compiling the simulation kernel" in capsys.readouterr().err
    assert run.summary["provenance"]["command"] == "python API: run_walk('sim1', engine='pinocchio', until=0.05)"
    hs.run_walk("sim1", until=0.05, verbose=False)
    assert capsys.readouterr().err == ""


@pytest.mark.slow
def test_run_walk_says_it_plans_a_zmp_gait_and_how_long_it_took(capsys):
    import humanoid_sim as hs

    hs.run_walk("sim3_fast_zmp", until=0.05)
    err = capsys.readouterr().err
    assert "humanoid_sim: planning the zmp_preview gait" in err
    assert "humanoid_sim: planned the gait and set up the walk in " in err
