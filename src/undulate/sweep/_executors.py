"""Where chunks of runs execute: in-process, a local process pool, or Dask.

Every executor calls ``on_done(chunk, outcomes)`` as each chunk finishes and
``on_lost(chunk, why)`` for a chunk whose worker died too often; results are
already on disk by then (the worker writes them), so the parent only counts.
"""

from __future__ import annotations

import atexit
import contextlib
import multiprocessing
import os
import threading
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..errors import ParameterError, UndulateError
from ..execution import MAX_WORKERS_PER_CORE, check_scheduler, check_workers, usable_cpus  # noqa: F401 - used here and by run_sweep
from ._worker import Chunk, Outcome, _stop_if_disk_full, init_local_worker, run_chunk

OnDone = Callable[[Chunk, list[Outcome]], None]
OnLost = Callable[[Chunk, str], None]

#: A chunk whose worker process dies this many times is given up (recorded as
#: failed).  Mirrors Dask's ``distributed.scheduler.allowed-failures`` (3).
MAX_ATTEMPTS = 3


def default_workers() -> int:
    """Cores this process may use (:func:`undulate.execution.usable_cpus`)."""
    return usable_cpus()


def run_serial(chunks: Sequence[Chunk], on_done: OnDone, on_lost: OnLost) -> None:
    """In this process, one chunk after the other: the reference executor."""
    for chunk in chunks:
        _check_stop()
        on_done(chunk, run_chunk(chunk))


def run_local(chunks: Sequence[Chunk], on_done: OnDone, on_lost: OnLost, *, workers: int) -> None:
    """A pool of ``workers`` fresh ("spawn") processes.

    Spawned, never forked: a forked child would inherit whatever the parent
    holds (a GL context, MuJoCo's thread pools, open HDF5 handles).  At most
    ``2 * workers`` chunks are queued at a time, so Ctrl-C stops promptly and
    a dead worker takes few chunks down with it.

    When a worker process dies (killed, out of memory, a crash in C) the pool
    breaks, and every chunk in flight with it.  Their unsaved runs are then
    *quarantined*: run one at a time in a one-process pool, so the run that
    kills its process is the one identified (and moved to the back of the
    queue to try the others first).  A run that kills its process
    :data:`MAX_ATTEMPTS` times is given up and reported; the others go on in
    a fresh pool.  If processes die :data:`MAX_ATTEMPTS` times in a row
    before any task ever finished, the workers cannot work at all (cannot
    import the function, a script without a ``__main__`` guard): raise.
    """
    ctx = multiprocessing.get_context("spawn")
    health = _Health()
    pending: deque[Chunk] = deque(chunks)
    while pending:
        _check_stop()
        suspects = _run_pool(ctx, workers, pending, on_done, health)
        if suspects:
            _quarantine(ctx, suspects, on_done, on_lost, health)


class _Health:
    """Tells a worker that died on one run from workers that cannot run anything."""

    def __init__(self):
        self.any_done = False
        self.breaks_in_a_row = 0

    def done(self) -> None:
        self.any_done = True
        self.breaks_in_a_row = 0

    def broke(self) -> None:
        self.breaks_in_a_row += 1
        if self.breaks_in_a_row >= MAX_ATTEMPTS and not self.any_done:
            raise UndulateError(
                f"the local worker processes died {self.breaks_in_a_row} times in a row without finishing a "
                "task. Can they import the sweep function? Does the script that calls run_sweep guard it "
                "with `if __name__ == \"__main__\":` (new processes import that script)? Finished runs "
                "are saved; rerun to resume, or use workers=1 to see errors in this process"
            )


def _new_pool(ctx, workers: int) -> ProcessPoolExecutor:
    return ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=init_local_worker,
                               initargs=(os.getpid(),))


# ---- one warm pool for a series of sweeps --------------------------------
_WARM: dict[str, Any] = {"depth": 0, "pool": None, "workers": 0, "users": 0, "size": 0}
_WARM_LOCK = threading.RLock()  # sweeps of studies run side by side (threads) share the warm pool
_STOP = threading.Event()


def stop_sweeps() -> None:
    """Make every local sweep in flight in this process stop at its next chunk (raising
    KeyboardInterrupt there) and stop the warm pool's processes: a reproduction interrupted while
    studies run side by side on threads (:func:`undulate.reproduce.reproduce`)."""
    _STOP.set()
    with _WARM_LOCK:
        pool = _WARM["pool"]
    if pool is not None:
        _stop_now(pool)


def _check_stop() -> None:
    if _STOP.is_set():
        raise KeyboardInterrupt("the sweeps were stopped")


@contextlib.contextmanager
def warm_workers(workers: int | None = None) -> Iterator[None]:
    """Inside this context, local sweeps share one pool of worker processes, of ``workers``
    processes (None: every core this process may use) or more if a sweep asks for more.

    Outside it every :func:`run_local` call starts its own pool and shuts it
    down at the end (each process pays ~1.5 s of imports, and the first run in
    a process ~0.8 s more).  A study or a reproduction runs many sweeps one
    after the other, so :func:`undulate.studies.run_study` and
    :func:`undulate.reproduce.reproduce` enter this context: the processes
    start once and stay warm until it exits.  The code cannot change under
    them in between (it is one call of this process, whose own modules are
    fixed too).  A pool that breaks (a worker died) is dropped and the next
    sweep starts a fresh one; nesting is allowed (the outermost exit stops
    the pool).

    The pool has its size from the start, not that of the first sweep: the pool grows only while no
    sweep holds it, and studies side by side (a reproduction on many cores) always hold it, so a
    small first sweep would keep it small for the rest of the run.  Processes start when first
    needed (spawned on demand), so a pool larger than the sweeps need costs nothing.
    """
    with _WARM_LOCK:
        _WARM["depth"] += 1
        if _WARM["depth"] == 1:
            _STOP.clear()
            _WARM["size"] = int(workers or default_workers())
    try:
        yield
    finally:
        with _WARM_LOCK:
            _WARM["depth"] -= 1
            last = _WARM["depth"] == 0
        if last:
            _drop_warm(wait=True)
            _STOP.clear()


def warm_pool_running() -> bool:
    """Whether the warm pool of :func:`warm_workers` is up now (its processes started by an earlier
    sweep): a small sweep sent there pays no start (:func:`undulate.execution.runs_here`)."""
    with _WARM_LOCK:
        pool = _WARM["pool"]
        return _WARM["depth"] > 0 and pool is not None and not getattr(pool, "_broken", False)


def _drop_warm(wait: bool = False) -> None:
    with _WARM_LOCK:  # "users" stays: the sweeps holding the old pool still release it
        pool, _WARM["pool"], _WARM["workers"] = _WARM["pool"], None, 0
    if pool is not None:
        pool.shutdown(wait=wait, cancel_futures=True)


atexit.register(_drop_warm)


def _acquire_pool(ctx, workers: int) -> tuple[ProcessPoolExecutor, bool]:
    """A pool of at least ``workers`` processes and whether it is the shared warm one."""
    with _WARM_LOCK:
        if _WARM["depth"] == 0:
            return _new_pool(ctx, workers), False
        pool = _WARM["pool"]
        dead = pool is not None and (getattr(pool, "_broken", False) or getattr(pool, "_shutdown_thread", False))
        # more processes are wanted now: grow the pool, unless a sweep of another thread holds it (then
        # this sweep runs on the processes there are: results never depend on the number of workers)
        if dead or (pool is not None and _WARM["workers"] < workers and _WARM["users"] == 0):
            _drop_warm()
            pool = None
        if pool is None:
            workers = max(workers, _WARM["size"])
            pool = _new_pool(ctx, workers)
            _WARM["pool"], _WARM["workers"] = pool, workers
        _WARM["users"] += 1
        return pool, True


@contextlib.contextmanager
def _held_pool(ctx, workers: int) -> Iterator[tuple[ProcessPoolExecutor, dict]]:
    """Hold a pool (the warm one, else a fresh one) for a block: yields ``(pool, state)``;
    set ``state["broken"]`` when the block saw the pool break.  On an exception the pool's
    processes are stopped at once (and the warm pool forgotten); on exit a fresh pool is
    shut down, a broken warm pool forgotten."""
    pool, warm = _acquire_pool(ctx, workers)
    state = {"broken": False}
    try:
        yield pool, state
    except BaseException:
        _stop_now(pool)
        if warm:
            _drop_warm()
        raise
    finally:
        if not warm:
            pool.shutdown(wait=not state["broken"], cancel_futures=True)
        else:
            with _WARM_LOCK:
                _WARM["users"] -= 1
                if (state["broken"] or getattr(pool, "_broken", False)) and _WARM["pool"] is pool:
                    _drop_warm()


@contextlib.contextmanager
def local_pool(workers: int) -> Iterator[ProcessPoolExecutor]:
    """A process pool for other work than sweeps (e.g. a reproduction's animations): the
    warm one inside :func:`warm_workers`, else a fresh one stopped on exit."""
    with _held_pool(multiprocessing.get_context("spawn"), workers) as (pool, _):
        yield pool


def _run_pool(ctx, workers: int, pending: deque[Chunk], on_done: OnDone, health: _Health) -> list[Chunk]:
    """Run ``pending`` on one pool until it is empty or the pool breaks; return the chunks lost in a break."""
    with _held_pool(ctx, workers) as (pool, state):
        broken = _drain(pool, workers, pending, on_done, health)
        state["broken"] = bool(broken)
        return broken


def _drain(pool, workers: int, pending: deque[Chunk], on_done: OnDone, health: _Health) -> list[Chunk]:
    """Submit ``pending`` (at most two chunks a worker in flight) and hand each outcome to
    ``on_done``; stop at the first broken-pool error and return every chunk lost with it."""
    inflight: dict[Future, Chunk] = {}
    broken: list[Chunk] = []
    while (pending or inflight) and not broken:
        _check_stop()
        while pending and len(inflight) < 2 * workers:
            chunk = pending.popleft()
            inflight[pool.submit(run_chunk, chunk)] = chunk
        done, _ = wait(inflight, return_when=FIRST_COMPLETED)
        for fut in done:
            chunk = inflight.pop(fut)
            try:
                outcomes = fut.result()
            except BrokenProcessPool:
                broken.append(chunk)
                continue
            health.done()
            on_done(chunk, outcomes)
    if broken:
        health.broke()
        for fut, chunk in inflight.items():  # the rest of the pool's chunks fail with it
            try:
                outcomes = fut.result()
            except BrokenProcessPool:
                broken.append(chunk)
                continue
            on_done(chunk, outcomes)
    return broken


def _quarantine(ctx, chunks: list[Chunk], on_done: OnDone, on_lost: OnLost, health: _Health) -> None:
    """Run the runs of ``chunks`` one by one, alone, to find the one that kills its process."""
    queue: deque[Chunk] = deque(replace(c, runs=(r,)) for c in chunks for r in c.runs)
    deaths: dict[str, int] = {}
    while queue:
        _check_stop()
        pool = _new_pool(ctx, 1)
        try:
            while queue:
                single = queue.popleft()
                try:
                    outcomes = pool.submit(run_chunk, single).result()
                except BrokenProcessPool:
                    key = single.runs[0].key
                    deaths[key] = deaths.get(key, 0) + 1
                    health.broke()
                    if deaths[key] >= MAX_ATTEMPTS:
                        on_lost(single, f"its worker process died {deaths[key]} times running it")
                    else:
                        queue.append(single)
                    break  # a new pool for the rest
                health.done()
                on_done(single, outcomes)
        except BaseException:
            _stop_now(pool)
            raise
        finally:
            pool.shutdown(wait=False, cancel_futures=True)


def _stop_now(pool: ProcessPoolExecutor) -> None:
    """Stop the workers without waiting for their current chunk (Ctrl-C)."""
    terminate = getattr(pool, "terminate_workers", None)  # Python >= 3.14
    if terminate is not None:
        terminate()
        return
    for p in list((getattr(pool, "_processes", None) or {}).values()):
        try:
            p.terminate()
        except Exception:  # noqa: BLE001 - already gone
            pass


def connect(scheduler: Any):
    """A ``distributed.Client`` for ``scheduler`` and whether we own it.

    ``scheduler`` is a ``tcp://HOST:PORT`` address (any address Dask accepts),
    the path of a scheduler file (``dask scheduler --scheduler-file``,
    dask-jobqueue, ``dask-mpi``), or an existing ``Client`` (:func:`check_scheduler`).
    """
    import distributed

    kind = check_scheduler(scheduler)
    if kind == "client":
        return scheduler, False
    if kind == "file":
        return distributed.Client(scheduler_file=str(Path(scheduler).expanduser())), True
    try:
        return distributed.Client(scheduler, timeout="30s"), True
    except OSError as e:
        raise ParameterError("scheduler", f"the address of a running Dask scheduler ({e})", scheduler) from None


def dask_threads(client) -> int:
    """Worker threads the cluster has now (0 while workers are still starting)."""
    return sum(client.nthreads().values())


def check_shared_dir(client, runs_dir: str) -> None:
    """Every worker writes run files itself, so it must see ``runs_dir``."""
    if not client.nthreads():
        return  # no workers yet (e.g. jobqueue jobs still queued): nothing to check
    seen = client.run(os.path.isdir, runs_dir)
    blind = sorted(w for w, ok in seen.items() if not ok)
    if blind:
        raise ParameterError(
            "out_dir",
            f"a directory every Dask worker can see (a shared filesystem); {len(blind)} worker(s) cannot, e.g. {blind[0]}",
            runs_dir,
        )


def run_dask(chunks: Sequence[Chunk], on_done: OnDone, on_lost: OnLost, *, client) -> None:
    """Every chunk as one Dask task; Dask retries tasks whose worker is lost.

    A chunk that still fails (``KilledWorker`` after Dask's allowed failures,
    or a task that cannot be deserialised on the workers) is reported through
    ``on_lost`` with the error.
    """
    from distributed import as_completed

    futures = {client.submit(run_chunk, chunk, pure=False): chunk for chunk in chunks}
    try:
        for fut in as_completed(list(futures)):
            chunk = futures[fut]
            try:
                outcomes = fut.result()
            except Exception as exc:  # noqa: BLE001 - KilledWorker, unpickling errors...
                _stop_if_disk_full(exc)  # a full disk ends the sweep, as on local processes
                on_lost(chunk, f"{type(exc).__name__}: {exc}")
                continue
            on_done(chunk, outcomes)
    except BaseException:
        client.cancel(list(futures))
        raise
