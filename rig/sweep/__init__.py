"""rig sweep (docs/sweeps.md): one scenario over many variations, on a local process pool or a Dask
cluster. scenarios/sweep.py reads and expands the spec; here the runs are spread (engine.py), flown
(work.py: inside a worker, pinned to a core), kept (store.py: one row per run, resumable) and shown
(reports/sweep.py)."""
