"""Resumable parameter sweeps on local cores or a Dask cluster.

>>> from undulate.sweep import Grid, run_sweep
>>> grid = Grid(axes={"dphi_rad": [0.0, 0.5, 1.0], "waves_per_body": [0.75, 1.0]}, replicates=2, seed=0)
>>> result = run_sweep(my_fn, grid, "out/pairs")          # doctest: +SKIP
>>> result.dataset                                          # doctest: +SKIP
>>> result.raise_if_failed()                                # doctest: +SKIP

See docs/sweeps.md for the store layout, resuming, Dask and SLURM.
"""

from ._grid import Grid, Run
from ._executors import local_pool, stop_sweeps, warm_pool_running, warm_workers
from ._store import backend_identity
from ._sweep import (RunFailure, SweepFailed, SweepResult, batched_sweep_function, is_batched_sweep_function,
                     load_sweep, run_sweep)

__all__ = ["Grid", "Run", "RunFailure", "SweepFailed", "SweepResult", "batched_sweep_function",
           "is_batched_sweep_function", "load_sweep", "run_sweep", "warm_workers", "warm_pool_running", "local_pool",
           "stop_sweeps", "backend_identity"]
