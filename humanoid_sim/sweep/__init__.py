"""Parameter sweeps: many walks of one base scenario, run as Dask tasks.

- :mod:`.spec`: the sweep file (``base``, ``grid``, ``random``), its validation and its expansion into walks;
- :mod:`.walk`: one walk on a worker (model and kernel loaded once per process) and its table row;
- :mod:`.runner`: the Dask execution (LocalCluster by default, or a scheduler address), resume, faults, Ctrl-C;
- :mod:`.table`: rows -> ``sweep.parquet`` and ``sweep.csv``, written atomically;
- :mod:`.checks`: cheap checks before the walks run (is every walk distinct, does every axis change a walk);
- :mod:`.plots`: the actuator-sizing figure and the completion/feasibility map; :mod:`.labels`: their axis labels
  in physical units;
- :mod:`.design_file`, :mod:`.optimize`, :mod:`.pareto`: design searches (``humanoid-optimize``): the design file,
  the Optuna study over walks on the same cluster, its Pareto figure;
- :mod:`.push`, :mod:`.push_report`: the push-recovery benchmark (``humanoid-push``): bisections of the largest
  survived push per direction and instant, its table and polar figure;
- the commands themselves are in :mod:`humanoid_sim.cli` (``humanoid-sweep``, ``humanoid-optimize``,
  ``humanoid-push``; ``scripts/sweep.py``, ``scripts/optimize.py``, ``scripts/push_benchmark.py``).
"""
