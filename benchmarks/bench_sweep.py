"""Throughput of undulate.sweep: serial vs local processes vs Dask.

A 200-point pair sweep (two swimmers, 10 s each, a grid of phase lags) run
three ways on the same grid; prints runs per second and the speed-ups, and
checks the three results are identical.  Timings are printed, never asserted.

    python benchmarks/bench_sweep.py                 # 200 points, 2 workers
    python benchmarks/bench_sweep.py --points 50 --workers 4 --duration 5

Two rates per executor:

* end to end: grid size / wall time of ``run_sweep``, including starting the
  worker processes (~1.5 s each: Python, NumPy, xarray, MuJoCo imports) and
  merging the run files -- what a user waits for;
* steady state: from the completion times of the run files (their mtimes),
  runs finished per second between the first and the last -- the throughput
  once workers are up, which long sweeps approach;
* warm pool: the same grid on worker processes already started by an earlier
  sweep (``undulate.sweep.warm_workers``: what a sweep inside ``undulate
  study`` or ``undulate reproduce`` gets).

Timings are only meaningful on an otherwise idle machine; the script prints
the load average before and after.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import xarray as xr


def pair_run(point: dict, seed: int) -> xr.Dataset:
    """One pair simulation; returns centres and contact force (what the pair study keeps)."""
    from undulate.params import Scene, SimOptions
    from undulate.simulation import simulate

    ds = simulate(Scene(phases_rad=(0.0, point["dphi_rad"])), SimOptions(duration_s=point["duration_s"]))
    return ds[["x", "y", "contact_force_pair"]]


def _timed(label: str, fn, grid, out: Path, **kw):
    from undulate.sweep import run_sweep

    t0 = time.perf_counter()
    res = run_sweep(fn, grid, out, progress=False, **kw)
    dt = time.perf_counter() - t0
    assert res.ok, res.failures
    done = sorted(p.stat().st_mtime for p in (out / "runs").glob("*.nc"))
    steady = (len(done) - 1) / (done[-1] - done[0]) if len(done) > 1 and done[-1] > done[0] else float("nan")
    print(f"{label:<28s} {dt:7.2f} s  end-to-end {grid.n_runs / dt:6.2f} runs/s  steady {steady:6.2f} runs/s",
          flush=True)
    return grid.n_runs / dt, steady, res.dataset


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=200, help="grid points (phase lags), default 200")
    ap.add_argument("--duration", type=float, default=10.0, help="simulated seconds per run, default 10")
    ap.add_argument("--workers", type=int, default=2, help="local processes and Dask workers, default 2")
    ap.add_argument("--skip-dask", action="store_true")
    ap.add_argument("--dask-profiler", choices=("on", "off"), default="on",
                    help="Dask workers' statistical profiler (on by default in Dask; costs ~10-15%% here)")
    args = ap.parse_args()

    from undulate.sweep import Grid

    grid = Grid(axes={"dphi_rad": np.linspace(-math.pi, math.pi, args.points), "duration_s": [args.duration]})
    # warm this process (imports, first rollout) so serial is not charged for it
    pair_run({"dphi_rad": 0.0, "duration_s": 0.1}, 0)
    print(f"{args.points} pair runs of {args.duration:g} s; {args.workers} workers; "
          f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        r_ser, s_ser, ref = _timed("serial (workers=1)", pair_run, grid, tmp / "serial", workers=1)
        r_loc, s_loc, local = _timed(f"local pool ({args.workers} procs)", pair_run, grid, tmp / "local",
                                     workers=args.workers)
        print(f"  speed-up local/serial: {r_loc / r_ser:.2f}x end-to-end, {s_loc / s_ser:.2f}x steady")
        xr.testing.assert_identical(_data(ref), _data(local))
        # inside a study or a reproduction the worker processes are already up (warm_workers):
        # start them with a small sweep first, then time the same grid
        from undulate.sweep import run_sweep, warm_workers

        with warm_workers():
            t0 = time.perf_counter()
            warmup = Grid(axes={"dphi_rad": [0.1 * k for k in range(2 * args.workers)], "duration_s": [0.1]})
            run_sweep(pair_run, warmup, tmp / "warmup", workers=args.workers, batch=1, progress=False)
            print(f"{'(starting the warm pool)':<28s} {time.perf_counter() - t0:7.2f} s")
            r_wrm, s_wrm, warm = _timed(f"warm pool ({args.workers} procs)", pair_run, grid, tmp / "warm",
                                        workers=args.workers)
        print(f"  speed-up warm/serial:  {r_wrm / r_ser:.2f}x end-to-end, {s_wrm / s_ser:.2f}x steady")
        xr.testing.assert_identical(_data(ref), _data(warm))
        if not args.skip_dask:
            import dask
            from distributed import LocalCluster

            t0 = time.perf_counter()
            with dask.config.set({"distributed.worker.profile.enabled": args.dask_profiler == "on"}), LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                              dashboard_address=None) as cluster:
                t_start = time.perf_counter() - t0
                r_dsk, s_dsk, dsk = _timed(f"dask LocalCluster ({args.workers})", pair_run, grid, tmp / "dask",
                                           scheduler=cluster.scheduler_address)
            print(f"  speed-up dask/serial:  {r_dsk / r_ser:.2f}x end-to-end, {s_dsk / s_ser:.2f}x steady "
                  f"(cluster start {t_start:.1f} s not included; worker profiler {args.dask_profiler})")
            xr.testing.assert_identical(_data(ref), _data(dsk))
    print(f"results identical across executors; load average now {os.getloadavg()[0]:.2f}")


def _data(ds: xr.Dataset) -> xr.Dataset:
    return ds.drop_attrs()


if __name__ == "__main__":
    main()
