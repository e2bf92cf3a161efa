"""Parameter sweeps: many walks of one base scenario, run as Dask tasks.

- :mod:`.spec`: the sweep file (``base``, ``grid``, ``random``), its validation and its expansion into walks;
- :mod:`.walk`: one walk on a worker (model and kernel loaded once per process) and its table row;
- :mod:`.runner`: the Dask execution (LocalCluster by default, or a scheduler address), resume, faults, Ctrl-C;
- :mod:`.table`: rows -> ``sweep.parquet`` and ``sweep.csv``, written atomically;
- :mod:`.checks`: cheap checks before the walks run (is every walk distinct, does every axis change a walk);
- :mod:`.plots`: the actuator-sizing figure and the completion/feasibility map; :mod:`.labels`: their axis labels
  in physical units;
- :mod:`.cli`: the ``humanoid-sweep`` command (``scripts/sweep.py``).
"""
