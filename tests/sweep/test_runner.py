"""Sweeps on real Dask clusters (issue #16 acceptance): a scheduler and two workers started here as separate
processes on 127.0.0.1 (``--scheduler``), and the LocalCluster default; rows equal to serial runs of the same
scenarios, every summary number bit for bit; faults (a diverging walk, a worker killed in the middle, Dask's
KilledWorker); Ctrl-C and resume.

Walks are kept short (CI has 2 cores): sim3 cut at 1 s of simulated time for the equality tests (~0.05 s of wall
time each); for the fault and interrupt tests, where a walk must still be running when the test strikes, sim3 cut
at 1.5 s with a 0.5 ms step (~1.2 s of wall time each).  Every process started here is stopped by its pid.
"""

from __future__ import annotations

import copy
import json
import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import distributed
import numpy as np
import pytest
import yaml

from humanoid_sim.analysis.summary import summary_audit_design
from humanoid_sim.cli import sweep as cli
from humanoid_sim.scenario.schema import parse_scenario
from humanoid_sim.sim.simulate import Simulator
from humanoid_sim.sweep import runner
from humanoid_sim.sweep.spec import load_sweep
from humanoid_sim.sweep.table import read_rows

pytestmark = pytest.mark.slow  # Dask sweeps: clusters, workers and whole walks

ROOT = Path(__file__).resolve().parents[2]
SWEEP_PY = ROOT / "scripts" / "sweep.py"
SIM3 = yaml.safe_load((ROOT / "scripts" / "params" / "sim3.yaml").read_text())
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
WALL = ("wall_time_s", "real_time_factor", "provenance")   # what may differ between two runs: when, how long
HIP_WEIGHTS = "controller.Wp_fa_LFFSSP, controller.Wv_fa_LFFSSP, controller.Wor_fa_LFFSSP"


def write_yaml(path: Path, doc: dict) -> Path:
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory) -> dict[str, Path]:
    """The sweep files of these tests, with their (shortened) base scenarios next to them."""
    d = tmp_path_factory.mktemp("sweeps")
    short = copy.deepcopy(SIM3)
    short["simulation"]["t_end_s"] = 1.0
    write_yaml(d / "short.yaml", short)
    slow = copy.deepcopy(SIM3)
    slow["simulation"].update(t_end_s=1.5, step_s=0.0005)
    write_yaml(d / "slow.yaml", slow)
    return {
        # 2 grid x 2 random: a scale axis and a random one
        "small": write_yaml(d / "small.yaml", {"base": "short.yaml", "grid": {"path.Vhip": {"scale": [0.9, 1.1]}},
                                               "random": {"n": 2, "seed": 7, "path.SH": {"low": 0.06, "high": 0.09}}}),
        # five healthy walks and one without the LFFSSP hip task (weights x 0): it diverges at the first touchdown
        "fault": write_yaml(d / "fault.yaml", {"base": "slow.yaml",
                                               "grid": {HIP_WEIGHTS: {"scale": [1.0, 0.99, 1.01, 0.98, 1.02, 0.0]}}}),
        "four": write_yaml(d / "four.yaml", {"base": "slow.yaml",
                                             "grid": {HIP_WEIGHTS: {"scale": [1.0, 0.99, 1.01, 0.98]}}}),
        "eight": write_yaml(d / "eight.yaml", {"base": "slow.yaml", "grid": {
            HIP_WEIGHTS: {"scale": [1.0, 0.99, 1.01, 0.98]}, "path.SH[1]": [0.08, 0.085]}}),
    }


def serial_summary(hm, doc: dict) -> dict:
    """A walk run in this process the way walk.py runs it (cli._run): simulator, summary, contact audit, design
    card; plus the RMS torques.  Independent of humanoid_sim.sweep."""
    sc = parse_scenario(doc, "serial")
    sim = Simulator(hm, sc)
    result = sim.run()
    s = summary_audit_design(result, sc, "pinocchio", hm, [p.name for p in sim.traj.phases])[0]
    T = result.log.arrays()["T"]
    s["torque_rms_Nm"] = dict(zip(s["torque_peak_Nm"], np.sqrt(np.mean(T ** 2, axis=0)).tolist()))
    return s


@pytest.fixture(scope="module")
def small_serial(sweeps, hm) -> dict[str, dict]:
    """scenario hash -> serial summary of every walk of the small sweep."""
    return {w.scenario_hash: serial_summary(hm, w.doc) for w in load_sweep(sweeps["small"]).expand()}


def listening_hosts(port: int) -> set[str] | None:
    """The local addresses listening on TCP ``port`` (from /proc/net/tcp and tcp6), None when unreadable."""
    hosts = set()
    try:
        lines = Path("/proc/net/tcp").read_text().splitlines()[1:] + Path("/proc/net/tcp6").read_text().splitlines()[1:]
    except OSError:
        return None
    for line in lines:
        local, state = line.split()[1], line.split()[3]
        addr, p = local.split(":")
        if state != "0A" or int(p, 16) != port:   # 0A = LISTEN
            continue
        if len(addr) == 8:
            hosts.add(".".join(str(int(addr[i:i + 2], 16)) for i in (6, 4, 2, 0)))
        else:
            hosts.add("127.0.0.1" if addr == "0000000000000000FFFF00000100007F" else f"ipv6:{addr}")
    return hosts


def leaves(d: dict, prefix: str = ""):
    for k, v in d.items():
        if isinstance(v, dict):
            yield from leaves(v, f"{prefix}{k}_")
        elif not isinstance(v, list):
            yield f"{prefix}{k}", v


def assert_rows_equal_serial(out: Path, sweep: Path, serial: dict[str, dict]) -> list[dict]:
    """Every walk has one row; each row's numbers and each walk's summary file equal the serial run's, bit for
    bit (==, on the doubles read back from Parquet and JSON), wall times aside."""
    walks = load_sweep(sweep).expand()
    rows = read_rows(out)
    assert sorted(r["scenario_hash"] for r in rows) == sorted(w.scenario_hash for w in walks)
    by_hash = {r["scenario_hash"]: r for r in rows}
    checked = 0
    for w in walks:
        row, s = by_hash[w.scenario_hash], serial[w.scenario_hash]
        assert row["walk"] == w.index and row["engine"] == "pinocchio"
        assert all(row[k] == v for k, v in w.params.items())
        assert row["completed"] is True and row["failure_kind"] is None
        assert row["reason"] == s["reason"] and row["all_phases_completed"] == s["completed"]
        for k, v in s.items():
            if k in WALL or k in ("scenario", "engine", "completed", "reason", "phase_log"):
                continue
            if k == "contact":
                v = {ck: cv for ck, cv in v.items() if ck != "per_phase"}
            for col, x in leaves({k: v}):
                assert row[col] == x, (w.label, col, row[col], x)
                checked += 1
        full = json.loads(runner.summary_file(out, w.scenario_hash, "pinocchio").read_text())
        assert {k: v for k, v in full.items() if k not in WALL} == \
               json.loads(json.dumps({k: v for k, v in s.items() if k not in WALL}))
    assert checked > 100 * len(walks)   # peaks, RMS, per-actuator saturation, tracking, audit...
    return rows


# --------------------------------------------------------------------------------------------- LocalCluster
def test_local_cluster_default_rows_equal_serial_runs(sweeps, small_serial, tmp_path, monkeypatch, capsys):
    seen: dict = {}
    real = runner.dask_client

    @contextmanager
    def spy(*a, **k):
        with real(*a, **k) as client:
            info = client.scheduler_info()
            seen.update(args=(a, k), scheduler=info["address"], workers=list(info["workers"]),
                        services=info.get("services", {}),
                        threads={w: i["nthreads"] for w, i in info["workers"].items()},
                        pids=client.run(os.getpid),
                        sigint=client.run(lambda: str(signal.getsignal(signal.SIGINT))))
            # the scheduler's port and its HTTP server's (health, metrics, dashboard), while they run
            ports = (int(info["address"].rsplit(":", 1)[1]), info["services"]["dashboard"])
            seen["listening"] = {port: listening_hosts(port) for port in ports}
            yield client
    monkeypatch.setattr(runner, "dask_client", spy)
    out = tmp_path / "out"
    disposition = signal.getsignal(signal.SIGINT)
    assert cli.main([str(sweeps["small"]), "--out", str(out), "--workers", "2", "--quiet"]) == 0
    assert seen["args"][1] == {"workers": 2, "scheduler": None}
    assert seen["scheduler"].startswith("tcp://127.0.0.1:")
    for port, hosts in seen["listening"].items():
        assert hosts in ({"127.0.0.1"}, None), (port, hosts)   # None: no /proc/net/tcp to read
    assert len(seen["workers"]) == 2 and all(w.startswith("tcp://127.0.0.1:") for w in seen["workers"])
    assert set(seen["threads"].values()) == {1}
    assert os.getpid() not in seen["pids"].values() and len(set(seen["pids"].values())) == 2   # processes
    # Ctrl-C is the command's to handle (keep the rows, stop the cluster), not the workers'
    assert set(seen["sigint"].values()) == {str(signal.SIG_IGN)}
    assert signal.getsignal(signal.SIGINT) is disposition   # and this process's is restored
    rows = assert_rows_equal_serial(out, sweeps["small"], small_serial)
    assert {r["worker"].rsplit(":", 1)[1] for r in rows} <= {str(p) for p in seen["pids"].values()}
    assert (out / "sweep.csv").exists() and (out / "sizing.png").stat().st_size > 10_000
    assert (out / "feasibility.png").stat().st_size > 10_000
    assert "4 of 4 walks: 4 completed, 0 failed" in capsys.readouterr().out


# --------------------------------------------------------------------------------------------- external cluster
@pytest.fixture(scope="module")
def dask_cluster(tmp_path_factory):
    """``dask scheduler`` and two ``dask worker`` processes (one thread each) on 127.0.0.1; yields a Client of
    it.  Stopped by pid at the end."""
    d = tmp_path_factory.mktemp("dask")
    sched_file = d / "scheduler.json"
    procs: list[subprocess.Popen] = []
    client = None

    def start(args: list[str], log: str) -> None:
        procs.append(subprocess.Popen([sys.executable, "-m", *args], env=ENV, cwd=d, stdout=subprocess.DEVNULL,
                                      stderr=open(d / log, "w")))

    try:
        start(["distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
               "--dashboard-address", "127.0.0.1:0", "--scheduler-file", str(sched_file)], "scheduler.log")
        deadline = time.monotonic() + 60
        while not sched_file.exists():
            assert procs[0].poll() is None, (d / "scheduler.log").read_text()
            assert time.monotonic() < deadline, "the scheduler did not start within 60 s"
            time.sleep(0.1)
        for i in range(2):
            start(["distributed.cli.dask_worker", "--scheduler-file", str(sched_file), "--nworkers", "1",
                   "--nthreads", "1", "--host", "127.0.0.1", "--no-dashboard", "--dashboard-address", "127.0.0.1:0",
                   "--name", f"w{i}"], f"worker{i}.log")
        client = distributed.Client(scheduler_file=str(sched_file), timeout="30s")
        client.wait_for_workers(2, timeout=120)
        info = client.scheduler_info()
        ports = [int(a.rsplit(":", 1)[1]) for a in [info["address"], *info["workers"]]]
        ports += [info["services"]["dashboard"]] + [w["nanny"] and int(w["nanny"].rsplit(":", 1)[1])
                                                   for w in info["workers"].values()]
        for port in ports:   # scheduler, its HTTP server, workers, nannies: loopback only
            assert listening_hosts(port) in ({"127.0.0.1"}, None), (port, listening_hosts(port))
        yield client
    finally:
        if client is not None:
            client.close()
        for p in reversed(procs):
            p.send_signal(signal.SIGTERM)
        for p in procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def sweep_cmd(*args: str, start_new_session: bool = False) -> subprocess.Popen:
    # SIGINT's default disposition back in the child (a test run started in the background by a non-interactive
    # shell inherits "ignore SIGINT", and Python then never raises KeyboardInterrupt)
    return subprocess.Popen([sys.executable, str(SWEEP_PY), *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=ENV, cwd=ROOT, start_new_session=start_new_session,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def finish(proc: subprocess.Popen, timeout: float = 240) -> tuple[str, str]:
    try:
        return proc.communicate(timeout=timeout)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def stats(client) -> dict[str, dict]:
    from humanoid_sim.sweep.walk import worker_stats

    return client.run(worker_stats)


def test_scheduler_rows_equal_serial_runs_and_one_model_per_worker(dask_cluster, sweeps, small_serial, tmp_path):
    before = stats(dask_cluster)
    out = tmp_path / "out"
    proc = sweep_cmd(str(sweeps["small"]), "--out", str(out), "--scheduler", dask_cluster.scheduler.address,
                     "--quiet", "--no-plots")
    stdout, stderr = finish(proc)
    assert proc.returncode == 0, (stdout, stderr)
    assert "Traceback" not in stderr
    rows = assert_rows_equal_serial(out, sweeps["small"], small_serial)
    after = stats(dask_cluster)
    assert sum(a["walks"] for a in after.values()) - sum(b["walks"] for b in before.values()) == 4
    for addr, a in after.items():
        assert a["model_loads"] == 1, (addr, a)   # once per worker process, however many walks it ran
    pids = {str(a["pid"]) for a in after.values()}
    assert {r["worker"].rsplit(":", 1)[1] for r in rows} <= pids   # the walks ran on the cluster's workers


def _kill_a_busy_worker(client, out: Path, proc: subprocess.Popen) -> tuple[int, int, list[int]]:
    """Once one walk has finished (its key left every worker's executing set), SIGKILL a worker running a walk
    first seen less than 0.5 s ago (polled every ~50 ms; a walk lasts ~1.2 s, so it is surely still running);
    returns its pid, the rows written before, and the walks (indices) it was running.

    The finish is observed on the workers, not in sweep.parquet: the client may write its rows after the next
    walks started, and waiting for the file then missed every fresh walk (seen once in CI)."""
    deadline = time.monotonic() + 120
    first_seen: dict[str, float] = {}
    while True:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "no walk finished and no walk starting within 120 s"
        running = client.run(lambda dask_worker: [str(ts.key) for ts in dask_worker.state.executing])
        now = time.monotonic()
        walks = {w: [k for k in keys if k.startswith("walk-")] for w, keys in running.items()}
        executing = {k for keys in walks.values() for k in keys}
        finished = set(first_seen) - executing
        for k in executing:
            first_seen.setdefault(k, now)
        fresh = {w: [k for k in keys if now - first_seen[k] < 0.5] for w, keys in walks.items()}
        busy = [w for w, keys in fresh.items() if keys]
        if finished and busy:
            addr = busy[0]
            pid = client.run(os.getpid, workers=[addr])[addr]
            n_rows = len(read_rows(out)) if (out / "sweep.parquet").exists() else 0
            os.kill(pid, signal.SIGKILL)
            return pid, n_rows, [int(k.split("-")[1]) for k in walks[addr]]
        time.sleep(0.05)


def test_fault_diverging_walk_and_killed_worker_still_give_every_row(dask_cluster, sweeps, tmp_path):
    out = tmp_path / "out"
    proc = sweep_cmd(str(sweeps["fault"]), "--out", str(out), "--scheduler", dask_cluster.scheduler.address,
                     "--quiet", "--no-plots")
    killed, n_before, hit = _kill_a_busy_worker(dask_cluster, out, proc)
    stdout, stderr = finish(proc)
    assert proc.returncode == 0, (stdout, stderr)
    assert n_before < 6   # the worker died in the middle of the sweep
    rows = read_rows(out)
    assert sorted(r["walk"] for r in rows) == list(range(6))   # every row, once
    by = {r["walk"]: r for r in rows}
    assert by[5]["completed"] is False and by[5]["failure_kind"] == "simulation"
    assert by[5]["reason"].startswith(("diverged at t = ", "fall: hip CoM height"))
    assert all(by[i]["completed"] for i in range(5))
    assert hit and all(not by[i]["worker"].endswith(f":{killed}") for i in hit)   # Dask ran it again elsewhere
    dask_cluster.wait_for_workers(2, timeout=120)   # the nanny restarts the worker
    assert killed not in [s["pid"] for s in stats(dask_cluster).values()]
    assert "6 of 6 walks: 5 completed, 1 failed (1 simulation)" in stdout


def _set_allowed_failures(client, n: int) -> int:
    def setter(dask_scheduler, n):
        old = dask_scheduler.allowed_failures
        dask_scheduler.allowed_failures = n
        return old
    return client.run_on_scheduler(setter, n=n)


def test_killed_worker_row_resume_and_retry(dask_cluster, sweeps, tmp_path):
    """With no retry allowed (allowed-failures 0), the walk of a killed worker ends in Dask's KilledWorker: a row
    with failure_kind worker_lost.  Running the sweep again runs nothing; --retry-failed runs just that walk."""
    out = tmp_path / "out"
    args = [str(sweeps["four"]), "--out", str(out), "--scheduler", dask_cluster.scheduler.address, "--quiet",
            "--no-plots"]
    old = _set_allowed_failures(dask_cluster, 0)
    try:
        proc = sweep_cmd(*args)
        killed, _, hit = _kill_a_busy_worker(dask_cluster, out, proc)
        stdout, stderr = finish(proc)
    finally:
        _set_allowed_failures(dask_cluster, old)
    assert proc.returncode == 0, (stdout, stderr)
    rows = read_rows(out)
    assert sorted(r["walk"] for r in rows) == [0, 1, 2, 3]
    lost = [r for r in rows if r["failure_kind"] == "worker_lost"]
    # the walk it was running, and any walk already queued on it
    assert hit and set(hit) <= {r["walk"] for r in lost} and all(r["completed"] is False for r in lost)
    assert all(r["reason"].startswith("worker process died while running this walk") for r in lost)
    assert all(r["completed"] for r in rows if r["failure_kind"] != "worker_lost")
    dask_cluster.wait_for_workers(2, timeout=120)

    before = stats(dask_cluster)
    proc = sweep_cmd(*args)   # resume: every walk has its row, nothing runs
    stdout, stderr = finish(proc)
    assert proc.returncode == 0, (stdout, stderr)
    assert "4 already in" in stderr and "0 to run" in stderr
    assert read_rows(out) == rows
    assert stats(dask_cluster) == before

    proc = sweep_cmd(*args, "--retry-failed")
    stdout, stderr = finish(proc)
    assert proc.returncode == 0, (stdout, stderr)
    assert f"{4 - len(lost)} already in" in stderr and f"{len(lost)} to run" in stderr
    again = {r["walk"]: r for r in read_rows(out)}
    assert all(r["completed"] for r in again.values())
    for r in rows:   # the rows done before are untouched (not re-run: same worker, same wall time)
        if r["failure_kind"] is None:
            assert again[r["walk"]] == r
    after = stats(dask_cluster)
    assert sum(a["walks"] for a in after.values()) - sum(b["walks"] for b in before.values()) == len(lost)


# --------------------------------------------------------------------------------------------- Ctrl-C, resume
def test_ctrl_c_keeps_finished_rows_and_the_next_run_resumes(sweeps, tmp_path):
    out = tmp_path / "out"
    args = [str(sweeps["eight"]), "--out", str(out), "--workers", "2", "--quiet", "--no-plots"]
    proc = sweep_cmd(*args, start_new_session=True)   # its own process group, as a terminal's foreground job
    try:
        deadline = time.monotonic() + 120
        while not ((out / "sweep.parquet").exists() and len(read_rows(out)) >= 2):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no rows within 120 s"
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGINT)   # Ctrl-C reaches the whole group: the command and its workers
        stdout, stderr = finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1, (stdout, stderr)
    assert "interrupted;" in stderr and "Traceback" not in stderr
    kept = read_rows(out)
    assert 2 <= len(kept) < 8, stderr
    assert f"interrupted; {len(kept)} of 8 walks have their row" in stderr
    assert all(r["completed"] and r["failure_kind"] is None for r in kept)   # finished walks only
    assert not list(out.glob(".*.tmp"))

    proc = sweep_cmd(*args)
    stdout, stderr = finish(proc)
    assert proc.returncode == 0, (stdout, stderr)
    assert f"{len(kept)} already in" in stderr and f"{8 - len(kept)} to run" in stderr
    rows = read_rows(out)
    assert sorted(r["walk"] for r in rows) == list(range(8)) and all(r["completed"] for r in rows)
    by = {r["walk"]: r for r in rows}
    for r in kept:
        assert by[r["walk"]] == r   # not run again


# --------------------------------------------------------------------------------------------- an edited sweep file
def test_resume_after_editing_the_sweep_file(sweeps, tmp_path, monkeypatch, capsys):
    """Rows are found by scenario: a walk both versions of the file generate is not run again and takes its new
    walk index; a walk only the old file generated keeps its row, after this sweep's rows.  (An in-process
    threads cluster: what is tested here is the bookkeeping, not the processes.)"""
    @contextmanager
    def threads(*a, **k):
        # in-process (inproc:// transport, no socket); its HTTP server on 127.0.0.1
        with distributed.Client(processes=False, n_workers=1, threads_per_worker=1,
                                dashboard_address="127.0.0.1:0") as c:
            yield c
    monkeypatch.setattr(runner, "dask_client", threads)
    out = tmp_path / "out"
    a = write_yaml(sweeps["small"].parent / "edit_a.yaml", {"base": "short.yaml", "grid": {"path.SH[1]": [0.07, 0.08]}})
    b = write_yaml(sweeps["small"].parent / "edit_b.yaml", {"base": "short.yaml", "grid": {"path.SH[1]": [0.08, 0.06]}})
    assert cli.main([str(a), "--out", str(out), "--quiet", "--no-plots"]) == 0
    first = {r["path.SH[1]"]: r for r in read_rows(out)}
    assert cli.main([str(b), "--out", str(out), "--quiet", "--no-plots"]) == 0
    assert "2 walks (2 path.SH[1]), 1 already in" in capsys.readouterr().err
    rows = read_rows(out)
    assert [(r["walk"], r["path.SH[1]"]) for r in rows] == [(0, 0.08), (1, 0.06), (0, 0.07)]
    assert {k: v for k, v in rows[0].items() if k != "walk"} == {k: v for k, v in first[0.08].items() if k != "walk"}
    assert rows[2] == first[0.07]
