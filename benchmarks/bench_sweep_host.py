"""The host's share of a sweep run: everything but the stepping, per run (measured, never asserted).

    python benchmarks/bench_sweep_host.py [--runs 256] [--duration 0.2] [--backend warp|mujoco]
                                          [--device cpu|cuda] [--repeat 3] [--processes 1] [--workers 1]
                                          [--dask 0]

A sweep of ``--runs`` pair runs (the pairs study's runner, ``group_point``; ``--duration`` s each, no
stopping rule) through :func:`undulate.sweep.run_sweep` into a fresh store, end to end: on the Warp
backend (Warp's CPU device unless ``--device cuda``) its runs are gathered into one batch, each on
its own thread, as a study's are (``--processes`` P: ``UNDULATE_WARP_PROCESSES``, P processes of a
warm pool, one batch each); on the MuJoCo backend on ``--workers`` processes (1: this one, one run
after another).  ``--dask N``: on a Dask ``LocalCluster`` of N worker processes (one thread each)
instead, each Warp task one batch on its worker.  Short runs on purpose: what is measured is what a run costs besides its steps,
which on a GPU is most of a large sweep (a 10 s pair at 8 192 worlds costs the H200 ~1.3 ms of
device time per run; docs/gpu.md, "The host's share of a sweep").

Per repeat (after one that starts processes, compiles or loads kernels and is not shown) it prints
the wall time and runs per second.  In one process it also prints the time inside the engine's
rollout calls (``step``: on Warp, the launches and their waits, on the CPU device the stepping
itself), and the parts of the rest: the gathered batch's simulate call outside its steps (models,
control tables, Datasets), merging the run files, and what is left (the runner's own code, writing
the run files -- given as their threads' CPU time --, threads, the sweep's identity).  ``host/run``
is (wall - step) / runs, the figure that matters.  The last line, ``json {...}``, has the best
repeat (the machine is shared) for scripts (the GPU check's ``sweep`` step).
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import math
import os
import tempfile
import time

import numpy as np


def _timed(obj, name: str, acc: dict, key: str, clock=time.perf_counter) -> None:
    """Wrap ``obj.name`` so that its time on ``clock`` adds to ``acc[key]``: wall time for calls that
    do not overlap, the calling thread's CPU time (``time.thread_time``) for calls made by many
    threads at once (their wall times would count each other's turns on the GIL)."""
    f = getattr(obj, name)

    def g(*a, **k):
        t = clock()
        try:
            return f(*a, **k)
        finally:
            acc[key] = acc.get(key, 0.0) + clock() - t

    setattr(obj, name, g)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=256)
    p.add_argument("--duration", type=float, default=0.2)
    p.add_argument("--backend", choices=("warp", "mujoco"), default="warp")
    p.add_argument("--device", default="cpu")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--processes", type=int, default=1,
                   help="UNDULATE_WARP_PROCESSES: processes a Warp sweep splits its runs over")
    p.add_argument("--workers", type=int, default=1, help="local processes of a MuJoCo sweep")
    p.add_argument("--dask", type=int, default=0, help="worker processes of a Dask LocalCluster (0: none)")
    a = p.parse_args()
    if a.backend == "mujoco":
        a.processes = 1
    os.environ["UNDULATE_WARP_PROCESSES"] = str(a.processes)

    import undulate.simulation._run as sim  # where simulate_batch steps a batch now
    import undulate.sweep._sweep as sweep_mod
    import undulate.sweep._worker as worker
    from undulate.simulation import use_backend
    from undulate.studies._runners import group_point
    from undulate.sweep import warm_workers

    use_backend(a.backend, a.device if a.backend == "warp" else None)
    acc: dict[str, float] = {}
    if a.backend == "warp":
        from undulate.simulation import _warp

        _timed(_warp.WarpRollout, "rollout", acc, "step")
        _timed(_warp.WarpRollout, "rollout_samples", acc, "step")
    else:
        from undulate.simulation import _mujoco

        _timed(_mujoco._WarmRollout, "rollout", acc, "step")
    _timed(sim, "_simulate_batch_now", acc, "batch")
    _timed(worker, "write_result", acc, "write", clock=time.thread_time)
    _timed(sweep_mod, "merge", acc, "merge")
    fn = functools.partial(group_point, n_swimmers=2, duration_s=a.duration)
    print(f"{a.runs} pair runs of {a.duration} s, backend {a.backend}"
          f"{f' on {a.device}, {a.processes} process(es)' if a.backend == 'warp' else f', {a.workers} worker(s)'}",
          flush=True)
    with contextlib.ExitStack() as stack:
        pool = max(a.processes, a.workers)
        a.scheduler = None
        if a.dask > 0:  # the workers start on the MuJoCo backend: each task names the sweep's
            from distributed import LocalCluster

            cluster = stack.enter_context(LocalCluster(n_workers=a.dask, threads_per_worker=1, processes=True,
                                                       dashboard_address=None))
            a.scheduler, pool = cluster.scheduler_address, a.dask
        elif pool > 1:  # started once, as in a study or reproduction (the first repeat starts them)
            stack.enter_context(warm_workers(pool))
        walls = _repeats(a, fn, acc)
    best = min(walls)
    print("json " + json.dumps({"runs": a.runs, "duration_s": a.duration, "backend": a.backend,
                                "device": a.device if a.backend == "warp" else "cpu", "processes": pool,
                                "dask": a.dask > 0, "best_wall_s": best, "runs_per_s": a.runs / best, "walls_s": walls}), flush=True)


def _repeats(a, fn, acc: dict) -> list[float]:
    """The repeats' wall times (s), each printed with its parts where this process saw them."""
    from undulate.sweep import Grid, run_sweep

    walls = []
    for rep in range(a.repeat + 1):  # the first: kernels compiled or loaded, imports (not printed)
        acc.clear()
        dphi = np.linspace(0.0, 2 * math.pi, a.runs, endpoint=False) + 1e-3 * rep
        grid = Grid(axes={"dphi_rad": [float(x) for x in dphi]}, seed=0)
        with tempfile.TemporaryDirectory() as d:
            t = time.perf_counter()
            r = run_sweep(fn, grid, d, progress=False, workers=a.workers if a.backend == "mujoco" else None,
                          scheduler=a.scheduler)
            wall = time.perf_counter() - t
        if r.failures:
            raise SystemExit(f"{len(r.failures)} runs failed: {next(iter(r.failures.values()))}")
        if rep == 0:
            continue
        walls.append(wall)
        if a.processes > 1 or a.workers > 1 or a.scheduler:  # the parts ran in the pool's processes, out of this one's sight
            print(f"repeat {rep}: wall {wall:.2f} s, {a.runs / wall:.1f} runs/s, {wall / a.runs * 1e3:.1f} ms a run "
                  "end to end", flush=True)
            continue
        step = acc.get("step", 0.0)
        batch_host = acc.get("batch", 0.0) - step
        rest = wall - acc.get("batch", 0.0) - acc.get("merge", 0.0)
        print(f"repeat {rep}: wall {wall:.2f} s, {a.runs / wall:.1f} runs/s, step {step:.2f} s, host/run "
              f"{(wall - step) / a.runs * 1e3:.1f} ms (batch outside its steps {batch_host / a.runs * 1e3:.1f}, "
              f"merge {acc.get('merge', 0.0) / a.runs * 1e3:.1f}, rest {rest / a.runs * 1e3:.1f}, of it writing "
              f"run files {acc.get('write', 0.0) / a.runs * 1e3:.1f} ms CPU)", flush=True)
    return walls

if __name__ == "__main__":
    main()
