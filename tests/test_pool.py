"""One warm pool of worker processes serves the sweeps of a study or a reproduction (the
same processes), gives the serial results, resumes, and is replaced when one of its
processes dies; a crash inside it is isolated as without it."""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import numpy as np
import xarray as xr

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import sweep_funcs  # noqa: E402

from undulate.sweep import Grid, run_sweep, warm_workers  # noqa: E402
from undulate.sweep import _executors  # noqa: E402


def _pids(res) -> set[int]:
    return set(int(p) for p in np.ravel(res.dataset["pid"].values))


def test_warm_workers_serve_every_sweep_with_the_same_processes(tmp_path):
    grid_a = Grid(axes={"k": list(range(8))})
    grid_b = Grid(axes={"k": list(range(8, 16))})
    with warm_workers(2):
        a = run_sweep(sweep_funcs.worker_pid, grid_a, tmp_path / "a", workers=2, batch=1, progress=False)
        b = run_sweep(sweep_funcs.worker_pid, grid_b, tmp_path / "b", workers=2, batch=1, progress=False)
        assert a.ok and b.ok and os.getpid() not in _pids(a)
        assert len(_pids(a) | _pids(b)) <= 2  # one pool of two processes served both
        pool = _executors._WARM["pool"]
        assert pool is not None
    assert _executors._WARM["pool"] is None  # stopped when the context exits
    # outside the context every sweep starts (and stops) its own processes
    c = run_sweep(sweep_funcs.worker_pid, grid_a, tmp_path / "c", workers=2, batch=1, progress=False)
    d = run_sweep(sweep_funcs.worker_pid, grid_b, tmp_path / "d", workers=2, batch=1, progress=False)
    assert not (_pids(c) & _pids(d)) and not (_pids(c) & (_pids(a) | _pids(b)))


def test_warm_pool_gives_the_serial_results_and_resumes(tmp_path):
    grid = Grid(axes={"damping_Nms": [0.05, 0.1, 0.2], "length_m": [0.3, 0.5]}, replicates=2, seed=7)
    ref = run_sweep(sweep_funcs.pendulum, grid, tmp_path / "serial", workers=1, progress=False)
    with warm_workers(2):
        warm = run_sweep(sweep_funcs.pendulum, grid, tmp_path / "warm", workers=2, batch=2, progress=False)
        again = run_sweep(sweep_funcs.pendulum, grid, tmp_path / "warm", workers=2, batch=2, progress=False)
    xr.testing.assert_identical(sweep_funcs.result_data(warm.dataset), sweep_funcs.result_data(ref.dataset))
    assert again.n_computed == 0 and again.n_reused == grid.n_runs


def test_warm_pool_replaced_when_a_waiting_worker_dies(tmp_path):
    grid = Grid(axes={"k": list(range(6))})
    with warm_workers(2):
        first = run_sweep(sweep_funcs.worker_pid, grid, tmp_path / "a", workers=2, batch=1, progress=False)
        victim = min(_pids(first))
        os.kill(victim, signal.SIGKILL)  # dies while the pool waits between sweeps
        for _ in range(100):  # the pool's manager thread notices
            if getattr(_executors._WARM["pool"], "_broken", False):
                break
            time.sleep(0.05)
        second = run_sweep(sweep_funcs.worker_pid, Grid(axes={"k": list(range(6, 12))}), tmp_path / "b",
                           workers=2, batch=1, progress=False)
    assert second.ok and second.n_computed == 6 and victim not in _pids(second)


def test_a_crash_inside_a_warm_pool_is_isolated_as_without_it(tmp_path):
    grid = Grid(axes={"damping_Nms": [0.1, 0.2, -1.0, 0.3, 0.4, 0.5], "length_m": [0.5]})
    with warm_workers(2):
        res = run_sweep(sweep_funcs.pendulum_or_crash, grid, tmp_path / "crash", workers=2, batch=2, progress=False)
        after = run_sweep(sweep_funcs.worker_pid, Grid(axes={"k": [1, 2, 3, 4]}), tmp_path / "after",
                          workers=2, batch=1, progress=False)
    (f,) = res.failures
    assert f.point["damping_Nms"] == -1.0 and f.error.startswith("WorkerLost")
    # every other run has its result, each computed once: a chunk that finished and wrote its runs just
    # as the crash broke the pool is found in the store when the lost chunks are rerun (reused, not
    # computed again), which happens or not with the timing of the crash
    assert res.n_computed + res.n_reused == 5 and int(res.dataset["run_failed"].sum()) == 1 and after.ok


def test_a_sweep_that_wants_more_processes_never_takes_the_pool_from_a_sweep_beside_it(tmp_path):
    """Studies side by side (threads) share the warm pool: a sweep asking for more processes than it
    has runs on the pool there is while another thread's sweep holds it (dropping it would cancel that
    sweep's runs), and grows it once nobody holds it."""
    import threading

    grid = Grid(axes={"damping_Nms": [0.05, 0.1, 0.2, 0.3], "length_m": [0.3, 0.5]}, replicates=2, seed=3)
    ref = run_sweep(sweep_funcs.pendulum, grid, tmp_path / "serial", workers=1, progress=False)
    results, errors = {}, []

    def sweep(name, workers):
        try:
            results[name] = run_sweep(sweep_funcs.pendulum, grid, tmp_path / name, workers=workers, batch=1,
                                      progress=False)
        except BaseException as e:  # noqa: BLE001 - reported below
            errors.append(e)

    with warm_workers(2):
        run_sweep(sweep_funcs.worker_pid, Grid(axes={"k": [0, 1]}), tmp_path / "w", workers=2, batch=1,
                  progress=False)  # the warm pool: two processes
        a = threading.Thread(target=sweep, args=("a", 2))
        a.start()
        while _executors._WARM["users"] == 0 and a.is_alive():
            time.sleep(0.001)
        b = threading.Thread(target=sweep, args=("b", 3))  # wants three while "a" holds the pool
        b.start()
        a.join()
        b.join()
        assert _executors._WARM["users"] == 0
        grown = run_sweep(sweep_funcs.worker_pid, Grid(axes={"k": list(range(6))}), tmp_path / "g", workers=3,
                          batch=1, progress=False)
        assert _executors._WARM["workers"] == 3 and grown.ok  # nobody held it: grown
    assert errors == []
    for name in ("a", "b"):
        assert results[name].ok
        xr.testing.assert_identical(sweep_funcs.result_data(results[name].dataset), sweep_funcs.result_data(ref.dataset))


def test_the_warm_pool_has_its_size_from_the_start_not_from_the_first_sweep(tmp_path):
    """Studies side by side hold the warm pool all the time, and a pool grows only while no sweep
    holds it: so it is made at the reproduction's size, whatever the first sweep asks for (its
    processes start when first needed)."""
    with warm_workers(3):
        run_sweep(sweep_funcs.worker_pid, Grid(axes={"k": [0, 1]}), tmp_path / "a", workers=2, batch=1,
                  progress=False)
        assert _executors._WARM["workers"] == 3
        wide = run_sweep(sweep_funcs.worker_pid, Grid(axes={"k": list(range(12))}), tmp_path / "b", workers=3,
                         batch=1, progress=False)
        assert wide.ok and len(_pids(wide)) <= 3
