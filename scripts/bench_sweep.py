#!/usr/bin/env python
"""Throughput of a sweep on Dask against the same walks run one after another in one process.

    python scripts/bench_sweep.py [SWEEP.yaml] [--workers 2] [--repeats 3] [--engine pinocchio]

Default sweep: scripts/sweeps/speed_step.yaml (32 walks of sim 3: 16 per gait).  Prints one JSON object:

- ``serial_walks_s``: the walks run one after another in this process with the model and the kernel already
  loaded (:func:`humanoid_sim.sweep.walk.walk_row`, the task body; median of ``--repeats``);
  ``serial_setup_s``: that process's one-time model load and kernel load (first simulator);
- ``sweep_walks_s``: the same walks as Dask tasks on a LocalCluster of ``--workers`` processes that is already up
  and warm (first submission to last row, rows recorded as in a sweep; median);
  ``cluster_start_s``: starting that cluster and loading the model and kernel on its workers; ``cluster_stop_s``;
- ``walks_ratio`` = sweep_walks_s / serial_walks_s: the throughput figure of a sweep (parallel walks against serial ones
  on 2 cores);
  ``sweep_task_wall_sum_s``: the walks' own wall times in the workers, summed (against serial_walks_s: how much
  slower a walk runs when both cores are busy); ``client_process_cpu_s``: CPU time of this process meanwhile
  (the client, the local scheduler and the nannies run here);
- ``end_to_end_s``: the whole command (``humanoid-sweep --workers N --quiet --no-plots``, in this process: validation,
  cluster start, walks, table, cluster stop; median) and ``end_to_end_ratio`` = end_to_end_s / (serial_setup_s +
  serial_walks_s): what a user waits for, cluster start included;
- ``cores``, ``load_average`` (the machine may be shared: read the ratios with it).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("sweep", nargs="?", type=Path, default=ROOT / "scripts" / "sweeps" / "speed_step.yaml")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--engine", default="pinocchio")
    args = p.parse_args()

    from humanoid_sim.sweep import cli, runner
    from humanoid_sim.sweep.spec import load_sweep
    from humanoid_sim.sweep.table import TableSink
    from humanoid_sim.sweep.walk import walk_row, warm_up

    walks = load_sweep(args.sweep).expand()
    t0 = time.perf_counter()
    warm_up(args.engine, walks[0].doc)
    serial_setup = time.perf_counter() - t0
    serial = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        for w in walks:
            walk_row(w.doc, args.engine)
        serial.append(time.perf_counter() - t0)

    t0 = time.perf_counter()
    with runner.dask_client(workers=args.workers) as client:
        runner.setup_workers(client, args.engine, walks[0].doc)
        cluster_start = time.perf_counter() - t0
        swept, task_sums, client_cpu = [], [], []
        for _ in range(args.repeats):
            with tempfile.TemporaryDirectory() as d:
                sink = TableSink(Path(d), [], [], {(w.scenario_hash, args.engine) for w in walks})
                cpu0 = time.process_time()
                stats = runner.execute(client, walks, args.engine, str(args.sweep), Path(d), sink)
                client_cpu.append(time.process_time() - cpu0)
                assert stats.recorded == len(walks), stats
                swept.append(stats.walks_s)
                task_sums.append(sum(r["task_wall_time_s"] for r in sink.rows))
        t1 = time.perf_counter()
    cluster_stop = time.perf_counter() - t1

    end_to_end = []
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            assert cli.main([str(args.sweep), "--out", d, "--workers", str(args.workers), "--engine", args.engine,
                             "--quiet", "--no-plots"]) == 0
            end_to_end.append(time.perf_counter() - t0)

    serial_walks, sweep_walks, e2e = (statistics.median(x) for x in (serial, swept, end_to_end))
    print(json.dumps({
        "sweep": str(args.sweep), "walks": len(walks), "workers": args.workers, "engine": args.engine,
        "serial_setup_s": round(serial_setup, 3), "serial_walks_s": round(serial_walks, 3),
        "cluster_start_s": round(cluster_start, 3), "sweep_walks_s": round(sweep_walks, 3),
        "cluster_stop_s": round(cluster_stop, 3),
        "walks_ratio": round(sweep_walks / serial_walks, 3),
        "sweep_task_wall_sum_s": round(statistics.median(task_sums), 3),
        "client_process_cpu_s": round(statistics.median(client_cpu), 3),
        "end_to_end_s": round(e2e, 3), "end_to_end_ratio": round(e2e / (serial_setup + serial_walks), 3),
        "runs": {"serial_walks_s": [round(x, 3) for x in serial], "sweep_walks_s": [round(x, 3) for x in swept],
                 "end_to_end_s": [round(x, 3) for x in end_to_end]},
        "cores": len(os.sched_getaffinity(0)), "load_average": [round(x, 2) for x in os.getloadavg()],
    }, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
