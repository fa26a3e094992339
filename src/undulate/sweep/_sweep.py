"""run_sweep: a function over a grid, resumable, on local cores or Dask."""

from __future__ import annotations

import json
import logging
import math
import os
import pickle
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import xarray as xr

from ..errors import ParameterError, UndulateError
from ..execution import Execution, local_workers, settings, using, warp_processes
from ..params import _flag
from . import _executors, _worker
from ._grid import Grid
from ._progress import Progress
from .._source import check_unchanged
from ._store import (ENGINE, MERGED, Store, atomic_write_netcdf, function_id, function_name, make_manifest, merge,
                     run_provenance, unwrapped, write_failure)
from ._worker import EXISTS, FAILED, OK, Chunk, Outcome

log = logging.getLogger("undulate.sweep")

#: Auto chunking aims for this many chunks per worker (load balance at the
#: end of a sweep) but never more runs per chunk than MAX_AUTO_CHUNK.
CHUNKS_PER_WORKER = 8
MAX_AUTO_CHUNK = 16


@dataclass(frozen=True)
class RunFailure:
    """A run that has no result: its parameters and why."""

    key: str
    """Store key (``runs/<key>.failed.json`` holds the full record)."""
    point: dict[str, Any]
    replicate: int
    seed: int
    error: str
    """``ExceptionType: message``."""
    traceback: str = ""

    def __str__(self) -> str:
        pt = ", ".join(f"{k}={v!r}" for k, v in self.point.items())
        return f"{self.key} ({pt}, replicate={self.replicate}, seed={self.seed}): {self.error}"


class SweepFailed(UndulateError):
    """Some runs of a sweep failed; ``.failures`` lists them, ``.result`` has the rest."""

    def __init__(self, result: SweepResult):
        self.result = result
        self.failures = result.failures
        shown = "\n  ".join(str(f) for f in self.failures[:10])
        more = f"\n  ... and {len(self.failures) - 10} more" if len(self.failures) > 10 else ""
        super().__init__(
            f"{len(self.failures)} of {result.n_runs} runs failed (records in {result.out_dir / 'runs'}; "
            f"run the sweep again to retry them):\n  {shown}{more}"
        )


@dataclass
class SweepResult:
    """What :func:`run_sweep` returns."""

    dataset: xr.Dataset
    """Every run stacked: dims ``grid.dims + ("replicate",)`` then the function's own.
    Failed runs are NaN and flagged by the ``run_failed`` variable."""
    failures: list[RunFailure]
    n_computed: int
    """Runs computed (successfully) by this call."""
    n_reused: int
    """Runs found finished in ``out_dir`` (from an earlier call), not recomputed."""
    out_dir: Path
    elapsed_s: float = 0.0
    grid: Grid | None = field(default=None, repr=False)
    identity: dict[str, Any] = field(default_factory=dict)
    """The fully bound function call, code hash and package version every run was computed with."""
    stale: list[str] = field(default_factory=list)
    """Why runs found in ``out_dir`` were discarded as stale (empty: none were)."""
    timing: dict[str, Any] = field(default_factory=dict)
    """Where this call's time went: ``executor`` (``"serial"``: this process, ``"local"``,
    ``"dask"``), ``runs_wall_s`` (sum over the runs computed now of their own wall time, in
    whichever process ran them), ``physics_s`` (of that, inside ``mujoco.rollout``) and
    ``steps`` (scene-steps).  Measured, for benchmarks; never part of a result."""

    @property
    def n_runs(self) -> int:
        return int(self.dataset["run_failed"].size)

    @property
    def ok(self) -> bool:
        """True when every run has a result."""
        return not self.failures

    @property
    def path(self) -> Path:
        """The merged netCDF file."""
        return self.out_dir / MERGED

    def raise_if_failed(self) -> SweepResult:
        """Raise :class:`SweepFailed` if any run failed; else return self."""
        if self.failures:
            raise SweepFailed(self)
        return self


GATHER_MAX = 4096
"""Most runs of one task on the Warp backend (one thread each; their scenes become worlds)."""
GATHER_MIN_SPLIT = 64
"""Fewest runs a process (or Dask task) gets where ``warp_processes`` (or Dask) splits a
Warp sweep: a split pays only where the runs' host work (~20 ms a run on 2 cores) outweighs the step
latency each batch pays on the device whatever its size (0.34 ms a step on an H200: 64 runs' host
work is ~3 800 steps).  A judgement from those two figures, not a measured crossover."""


def _auto_chunk(n_todo: int, workers: int) -> int:
    return max(1, min(MAX_AUTO_CHUNK, math.ceil(n_todo / (max(workers, 1) * CHUNKS_PER_WORKER))))


def _provenance() -> dict[str, str]:
    try:
        from ..provenance import provenance
    except ImportError:  # pragma: no cover - provenance module absent
        from importlib import metadata

        def v(d):
            try:
                return metadata.version(d)
            except metadata.PackageNotFoundError:
                return "unknown"

        return {"undulate_version": v("undulate"), "mujoco_version": v("mujoco")}
    return provenance()


BATCHED_MARK = "__undulate_batched_sweep__"


def batched_sweep_function(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Mark ``fn(points: list[dict], seeds: list[int]) -> list[Dataset]`` as a batched sweep function:
    :func:`run_sweep` then hands it a task's points at once without being told (``batched=None``),
    also through a ``functools.partial`` of it.  Returns ``fn`` itself, marked."""
    setattr(fn, BATCHED_MARK, True)
    return fn


def is_batched_sweep_function(fn: Callable[..., Any]) -> bool:
    """Whether ``fn`` (or the function a ``functools.partial`` chain wraps) is marked by
    :func:`batched_sweep_function`."""
    return bool(getattr(unwrapped(fn), BATCHED_MARK, False))


def _resolve_batched(fn: Callable[..., Any], batched: bool | None) -> bool:
    """``run_sweep``'s ``batched``: None takes the function's mark; False for a marked function is
    refused (it would be called with one point where it takes a list)."""
    marked = is_batched_sweep_function(fn)
    if batched is None:
        return marked
    if not isinstance(batched, bool):
        raise ParameterError("batched", "True, False or None (None: as the function is marked)", batched)
    if marked and not batched:
        raise ParameterError("batched", f"True or None for {function_name(fn)}, a batched sweep function "
                                        "(fn(points, seeds) -> list of Datasets)", batched)
    return batched


def run_sweep(
    fn: Callable[..., Any],
    grid: Grid,
    out_dir: str | os.PathLike,
    *,
    workers: int | None = None,
    scheduler: Any = None,
    progress: bool = True,
    batch: int | None = None,
    batched: bool | None = None,
    stream: TextIO | None = None,
    execution: Execution | None = None,
) -> SweepResult:
    """Run ``fn`` on every point (and replicate) of ``grid``; resumable.

    Parameters
    ----------
    fn:
        ``fn(point: dict, seed: int) -> xarray.Dataset``; a top-level (picklable)
        function, or a ``functools.partial`` of one.  Every returned Dataset
        must have the same variables, dimensions and coordinates, and be
        writable to netCDF.  A batched sweep function (``batched=True``, or
        marked with :func:`batched_sweep_function`, which ``batched=None``
        reads): ``fn(points: list[dict], seeds: list[int]) -> list[Dataset]``
        on a chunk of runs at once.
    grid:
        The points, replicates and base seed (:class:`Grid`).
    out_dir:
        Where each finished run is saved as it finishes, and the merged
        ``sweep.nc``.  Calling again with the same ``fn`` and ``grid`` resumes:
        finished runs are reused, failed or missing ones (re)computed.  A
        directory holding a different sweep raises :class:`ParameterError`.
    workers:
        Local processes; default: every core this process may use.  ``1``
        runs in this process (serial: for debugging; the reference).
    scheduler:
        Run on a Dask cluster instead: ``"tcp://HOST:PORT"``, the path of a
        scheduler file, or a ``distributed.Client``.  ``out_dir`` must be on
        a filesystem every worker sees.
    progress:
        Show a bar (terminal) or periodic lines (logs) on ``stream``
        (default stderr), and a summary at the end.
    batch:
        Runs per task (per ``fn`` call when ``batched``).  Default: enough
        for ~8 tasks per worker, at most 16.  Serial runs use 1 unless batched.
    execution:
        How the runs are executed (:class:`undulate.execution.Execution`: engine, device,
        workers, scheduler...); ``workers`` and ``scheduler`` are then left out.  Default: the
        settings in effect (:func:`undulate.execution.current`) with ``workers`` and ``scheduler``.
        The runs step under it wherever they run (this process, a local pool, Dask).

    Returns
    -------
    SweepResult
        ``.dataset`` (also saved as ``out_dir/sweep.nc``), ``.failures``,
        ``.n_computed``, ``.n_reused``; ``.raise_if_failed()`` raises
        :class:`SweepFailed` when a run failed.

    Seeds do not depend on the executor, so serial, local and Dask runs give
    identical results.
    """
    t_start = time.monotonic()
    batched = _check_arguments(fn, grid, workers, scheduler, batch, batched, progress, stream)
    ex = settings(execution, workers=workers, scheduler=scheduler)
    workers, scheduler = ex.workers, ex.scheduler
    if scheduler is None and workers != 1:
        _check_importable(fn)
    with using(ex):  # this process's runs, the code hash and the identity: under ex
        return _run_sweep(fn, grid, out_dir, ex, progress, batch, batched, stream, t_start)


def _run_sweep(fn, grid: Grid, out_dir, ex: Execution, progress: bool, batch, batched: bool, stream,
               t_start: float) -> SweepResult:
    """:func:`run_sweep` under its settings ``ex``."""
    with Store.open(out_dir, make_manifest(fn, grid, batched, ex)) as store:
        _report_stale(store, progress, stream)
        runs = grid.runs()
        done = store.done_keys()
        todo = [r for r in runs if r.key not in done]
        n_reused = len(runs) - len(todo)
        counts, timing = _compute(fn, grid, store, runs, todo, ex, progress=progress, batch=batch,
                                  batched=batched, stream=stream)
        check_unchanged(fn)  # the runs above ran the code the manifest names
        ds = merge(grid, runs, store.runs_dir, store.manifest.get("code"))
        failures = _failures(runs, store)
        ds.attrs.update(_sweep_attrs(fn, grid, failures, store.manifest))
        atomic_write_netcdf(store.merged_path, ds)

    result = SweepResult(dataset=ds, failures=failures, n_computed=counts[OK], n_reused=n_reused + counts[EXISTS],
                         out_dir=store.root, elapsed_s=time.monotonic() - t_start, grid=grid,
                         identity=run_provenance(store.manifest), stale=list(store.stale), timing=timing)
    if progress:
        _summary(result, stream or sys.stderr)
    return result


def _check_arguments(fn, grid, workers, scheduler, batch, batched, progress=True, stream=None) -> bool:
    """:func:`run_sweep`'s arguments, validated (one ParameterError naming the first bad one);
    returns whether ``fn`` runs batched (:func:`_resolve_batched`)."""
    if not callable(fn):
        raise ParameterError("fn", "a callable fn(point, seed) -> xarray.Dataset", fn)
    if not isinstance(grid, Grid):
        raise ParameterError("grid", "an undulate.sweep.Grid", grid)
    _executors.check_workers(workers, scheduler)
    if batch is not None and (isinstance(batch, bool) or not isinstance(batch, int) or batch < 1):
        raise ParameterError("batch", "an integer >= 1 (runs per task), or None (automatic)", batch)
    _flag("progress", progress)  # "no" or 0.0 would have shown the bar, or not, by truth
    if stream is not None and not callable(getattr(stream, "write", None)):
        raise ParameterError("stream", "a text stream with write(), or None (standard error)", stream)
    return _resolve_batched(fn, batched)


def _report_stale(store: Store, progress: bool, stream: TextIO | None) -> None:
    """Say that stored runs of other code or arguments were discarded (on the stream or the log)."""
    if not store.stale:
        return
    msg = (f"sweep {store.root}: the stored runs were computed by other code or arguments "
           f"({'; '.join(store.stale)}); they were discarded and are recomputed")
    if progress:
        print(msg, file=stream or sys.stderr, flush=True)
    else:
        log.warning(msg)


def _chunks(fn, grid: Grid, store: Store, todo: list, ex: Execution, *, client, batch, batched: bool):
    """Where the ``todo`` runs go under ``ex``: ``(processes or Dask threads, runs per task, where in
    words, the tasks)``.  On the Warp backend a task's runs are gathered into one batch: one task in
    this process, or with ``warp_processes`` > 1 (:func:`undulate.execution.warp_processes`) one a
    process of the local pool, or on Dask one a worker thread (at least :data:`GATHER_MIN_SPLIT` runs
    each where split)."""
    gather = store.manifest.get("backend", "mujoco") != "mujoco"
    if client is not None:
        _executors.check_shared_dir(client, str(store.runs_dir))
        threads = _executors.dask_threads(client)
        n_workers = threads or 8  # workers still starting: assume a few for the chunk size
        where = f"Dask at {client.scheduler.address} ({threads} worker threads now)"
        if gather:  # as many batches as threads, none smaller than a split's least
            n_workers = max(1, min(n_workers, len(todo) // GATHER_MIN_SPLIT))
            where += ", each task's runs stepped together as Warp worlds"
    elif gather:  # its runs' host work shared by warp_processes processes (default 1)
        n_workers = max(1, min(warp_processes(ex), len(todo) // GATHER_MIN_SPLIT))
        where = ("this process, each task's runs stepped together as Warp worlds" if n_workers == 1 else
                 f"{n_workers} local processes, each task's runs stepped together as Warp worlds")
    else:
        n_workers = min(local_workers(ex), max(len(todo), 1))
        where = "this process" if n_workers == 1 else f"{n_workers} local processes"
    if gather:  # the runs reach the device together: one task (a process) of up to GATHER_MAX runs
        size = batch or min(GATHER_MAX, max(math.ceil(len(todo) / n_workers), 1))
    else:
        size = batch or (1 if (client is None and n_workers == 1 and not batched) else _auto_chunk(len(todo), n_workers))
    run_prov = tuple(run_provenance(store.manifest).items())
    # the workers (a local pool's processes, Dask's) step under this sweep's settings, named in every task
    chunks = [Chunk(fn, str(store.runs_dir), tuple(todo[i : i + size]), grid.names, batched, run_prov, gather,
                    ex.for_workers())
              for i in range(0, len(todo), size)]
    return n_workers, size, where, chunks


def _compute(fn, grid: Grid, store: Store, runs: list, todo: list, ex: Execution, *, progress: bool,
             batch, batched: bool, stream) -> tuple[dict, dict]:
    """Run the ``todo`` runs in chunks on the chosen executor, saving each as it finishes.

    Returns the outcome counts (``OK``, ``FAILED``, ``EXISTS``) and the timing
    (executor, the runs' own wall and physics seconds, scene-steps)."""
    client, own_client = None, False
    if ex.scheduler is not None and todo:
        client, own_client = _executors.connect(ex.scheduler)
    try:
        n_workers, size, where, chunks = _chunks(fn, grid, store, todo, ex, client=client, batch=batch,
                                                 batched=batched)
        # named by its store's folder: sweeps side by side (a reproduction's studies) print between each other;
        # the function's whole bound call is in the store's manifest (sweep_function)
        bar = Progress(len(runs), len(runs) - len(todo), enabled=progress, stream=stream,
                       label=f"sweep {Path(store.root).name}")
        if todo:
            bar.write(
                f"{bar.label}: {len(runs)} runs of {function_name(fn)}, {len(runs) - len(todo)} already in "
                f"{store.root}, {len(todo)} to compute on {where} in tasks of {size}"
            )
        executor = "dask" if client is not None else ("serial" if n_workers == 1 else "local")
        tally = _Tally(store, bar, executor)
        try:
            if not chunks:
                pass
            elif client is not None:
                _executors.run_dask(chunks, tally.on_done, tally.on_lost, client=client)
            elif n_workers == 1:  # a gathered batch here shows its stepping on the bar
                token = _worker.STEP_PROGRESS.set(bar.stepping)
                try:
                    _executors.run_serial(chunks, tally.on_done, tally.on_lost)
                finally:
                    _worker.STEP_PROGRESS.reset(token)
            else:
                _executors.run_local(chunks, tally.on_done, tally.on_lost, workers=n_workers)
        except KeyboardInterrupt:
            bar.close()
            print(
                f"\nsweep interrupted: {len(store.done_keys())}/{len(runs)} runs are saved in {store.root}; "
                "run the same sweep again to resume",
                file=stream or sys.stderr,
            )
            raise
        finally:
            bar.close()
    finally:
        if own_client:
            client.close()
    return tally.counts, tally.timing


class _Tally:
    """Counts the runs' outcomes and timing as chunks finish (or their worker is lost)."""

    def __init__(self, store: Store, bar: Progress, executor: str):
        self.store, self.bar = store, bar
        self.counts = {OK: 0, FAILED: 0, EXISTS: 0}
        self.timing = {"executor": executor, "runs_wall_s": 0.0, "physics_s": 0.0, "steps": 0}

    def on_done(self, chunk: Chunk, outcomes: list[Outcome]) -> None:
        for o in outcomes:
            self.counts[o.status] += 1
            self.timing["runs_wall_s"] += o.seconds
            self.timing["physics_s"] += o.physics_s
            self.timing["steps"] += o.steps
            if o.status == FAILED:
                log.info("run %s failed: %s", o.key, o.error)
        self.bar.update(sum(o.status != FAILED for o in outcomes), sum(o.status == FAILED for o in outcomes))

    def on_lost(self, chunk: Chunk, why: str) -> None:
        runs_dir = self.store.runs_dir
        lost = [r for r in chunk.runs if not (runs_dir / f"{r.key}.nc").exists()]
        for r in lost:
            write_failure(runs_dir, r, None, f"WorkerLost: {why}")
            log.info("run %s lost: %s", r.key, why)
        self.counts[FAILED] += len(lost)
        self.counts[OK] += len(chunk.runs) - len(lost)  # saved before the worker was lost
        self.bar.update(len(chunk.runs) - len(lost), len(lost))


def _failures(runs: list, store: Store) -> list[RunFailure]:
    """A :class:`RunFailure` for every run without a result (its failure record, if any)."""
    failures = []
    for r in runs:
        if (store.runs_dir / f"{r.key}.nc").exists():
            continue
        rec = store.failure(r) or {"error": "no result and no failure record"}
        failures.append(
            RunFailure(r.key, dict(r.point), r.replicate, r.seed, rec.get("error", ""), rec.get("traceback", ""))
        )
    return failures


def _check_importable(fn: Callable) -> None:
    """Local worker processes get ``fn`` by reference (pickle): it must be importable there."""
    try:
        pickle.dumps(fn)
    except Exception as e:  # noqa: BLE001 - lambdas, closures, bound objects that do not pickle
        raise ParameterError(
            "fn", f"a top-level function (or a functools.partial of one) that pickles, for workers > 1 ({e}); "
            "workers=1 runs anything", fn
        ) from None
    inner = fn.func if hasattr(fn, "func") else fn
    main = sys.modules.get("__main__")
    if getattr(inner, "__module__", None) == "__main__" and not getattr(main, "__file__", None):
        raise ParameterError(
            "fn", "defined in an importable module (not in an interactive session or notebook) for workers > 1; "
            "workers=1 runs it here, and a Dask scheduler= ships it by value", fn
        )


def _sweep_attrs(fn: Callable, grid: Grid, failures: list[RunFailure], manifest: dict[str, Any]) -> dict[str, Any]:
    attrs: dict[str, Any] = {
        "sweep_function": function_id(fn),
        "sweep_code_hash": str(manifest.get("code")),
        "sweep_code_rule": "sha256 of the source of the function's module and every undulate module it imports "
                           "(undulate._source.code_hash); every run file records the hash it was computed with",
        "sweep_grid": json.dumps(grid.to_dict()),
        "sweep_replicates": grid.replicates,
        "sweep_seed": grid.seed,
        "sweep_seed_rule": "SeedSequence(sweep_seed, spawn_key=(*sha256 words of the point, replicate)), first 63 bits",
        "sweep_n_failed": len(failures),
        "sweep_failures": json.dumps([{"key": f.key, "point": f.point, "replicate": f.replicate, "error": f.error}
                                      for f in failures]),
    }
    for k, v in _provenance().items():
        attrs[f"provenance_{k}"] = v  # the prefix undulate.simulate uses too
    return attrs


def _summary(result: SweepResult, stream: TextIO) -> None:
    n_ok = result.n_runs - len(result.failures)
    lines = [
        f"sweep done in {result.elapsed_s:.1f} s: {n_ok}/{result.n_runs} runs have results "
        f"({result.n_computed} computed now, {result.n_reused} reused) -> {result.path}"
    ]
    if result.failures:
        lines.append(f"{len(result.failures)} run(s) FAILED (records in {result.out_dir / 'runs'}; "
                     "run again to retry them):")
        lines += [f"  {f}" for f in result.failures[:20]]
        if len(result.failures) > 20:
            lines.append(f"  ... and {len(result.failures) - 20} more")
    print("\n".join(lines), file=stream, flush=True)


def load_sweep(out_dir: str | os.PathLike) -> xr.Dataset:
    """The merged Dataset of a finished :func:`run_sweep` call (``out_dir/sweep.nc``)."""
    path = Path(out_dir) / MERGED
    if not path.is_file():
        raise ParameterError("out_dir", f"a sweep directory with {MERGED} (run the sweep to completion first)", str(out_dir))
    return xr.load_dataset(path, engine=ENGINE)
