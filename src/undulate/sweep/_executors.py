"""Where chunks of runs execute: in-process, a local process pool, or Dask.

Every executor calls ``on_done(chunk, outcomes)`` as each chunk finishes and
``on_lost(chunk, why)`` for a chunk whose worker died too often; results are
already on disk by then (the worker writes them), so the parent only counts.
"""

from __future__ import annotations

import multiprocessing
import os
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..errors import ParameterError, UndulateError
from ._worker import Chunk, Outcome, init_local_worker, run_chunk

OnDone = Callable[[Chunk, list[Outcome]], None]
OnLost = Callable[[Chunk, str], None]

#: A chunk whose worker process dies this many times is given up (recorded as
#: failed).  Mirrors Dask's ``distributed.scheduler.allowed-failures`` (3).
MAX_ATTEMPTS = 3


def default_workers() -> int:
    """Cores this process may use."""
    if hasattr(os, "process_cpu_count"):  # Python >= 3.13
        return os.process_cpu_count() or 1
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - macOS, Windows
        return os.cpu_count() or 1


def run_serial(chunks: Sequence[Chunk], on_done: OnDone, on_lost: OnLost) -> None:
    """In this process, one chunk after the other: the reference executor."""
    for chunk in chunks:
        on_done(chunk, run_chunk(chunk))


def run_local(chunks: Sequence[Chunk], on_done: OnDone, on_lost: OnLost, *, workers: int) -> None:
    """A pool of ``workers`` fresh ("spawn") processes.

    Spawned, never forked: a forked child would inherit whatever the parent
    holds (a GL context, MuJoCo's thread pools, open HDF5 handles).  At most
    ``2 * workers`` chunks are queued at a time, so a dead worker costs at
    most those, and Ctrl-C stops promptly.  When a worker process dies (killed,
    out of memory, a crash in C), the pool is rebuilt and the chunks it was
    running are retried one run at a time; a run whose process dies
    :data:`MAX_ATTEMPTS` times is given up and reported.
    """
    ctx = multiprocessing.get_context("spawn")
    pending: deque[tuple[Chunk, int]] = deque((c, 0) for c in chunks)
    breaks_in_a_row = 0
    while pending:
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=init_local_worker)
        inflight: dict[Future, tuple[Chunk, int]] = {}
        broken: list[tuple[Chunk, int]] = []
        try:
            while (pending or inflight) and not broken:
                while pending and len(inflight) < 2 * workers:
                    chunk, attempts = pending.popleft()
                    inflight[pool.submit(run_chunk, chunk)] = (chunk, attempts)
                done, _ = wait(inflight, return_when=FIRST_COMPLETED)
                for fut in done:
                    chunk, attempts = inflight.pop(fut)
                    try:
                        outcomes = fut.result()
                    except BrokenProcessPool:
                        broken.append((chunk, attempts))
                        continue
                    breaks_in_a_row = 0
                    on_done(chunk, outcomes)
            if broken:
                breaks_in_a_row += 1
                if breaks_in_a_row >= MAX_ATTEMPTS:
                    raise UndulateError(
                        f"the local worker processes died {breaks_in_a_row} times in a row without finishing a "
                        "task. Can they import the sweep function? Does the script that calls run_sweep guard it "
                        "with `if __name__ == \"__main__\":` (new processes import that script)? Finished runs "
                        "are saved; rerun to resume, or use workers=1 to see errors in this process"
                    )
                # Every other in-flight chunk fails with the pool as well.
                for fut, (chunk, attempts) in inflight.items():
                    try:
                        on_done(chunk, fut.result())
                    except BrokenProcessPool:
                        broken.append((chunk, attempts))
                inflight.clear()
                retry = []
                for chunk, attempts in broken:
                    if attempts + 1 >= MAX_ATTEMPTS:
                        on_lost(chunk, f"worker process died {attempts + 1} times running this run")
                        continue
                    # Singles isolate a run that kills its process.
                    retry += [(replace(chunk, runs=(r,)), attempts + 1) for r in chunk.runs]
                pending.extendleft(reversed(retry))
        except BaseException:
            _stop_now(pool)
            raise
        finally:
            pool.shutdown(wait=not broken, cancel_futures=True)


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
    dask-jobqueue, ``dask-mpi``), or an existing ``Client``.
    """
    try:
        import distributed
    except ImportError:
        raise ParameterError(
            "scheduler", "usable only with Dask installed: pip install 'undulate[dask]'", scheduler
        ) from None
    if isinstance(scheduler, distributed.Client):
        return scheduler, False
    if isinstance(scheduler, os.PathLike) or (isinstance(scheduler, str) and "://" not in scheduler):
        path = Path(scheduler)
        if not path.is_file():
            raise ParameterError(
                "scheduler", "a Dask scheduler address tcp://HOST:PORT or the path of an existing scheduler file", str(scheduler)
            )
        return distributed.Client(scheduler_file=str(path)), True
    if isinstance(scheduler, str):
        try:
            return distributed.Client(scheduler, timeout="30s"), True
        except OSError as e:
            raise ParameterError("scheduler", f"the address of a running Dask scheduler ({e})", scheduler) from None
    raise ParameterError("scheduler", "a Dask scheduler address, a scheduler-file path or a distributed.Client", scheduler)


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
                on_lost(chunk, f"{type(exc).__name__}: {exc}")
                continue
            on_done(chunk, outcomes)
    except BaseException:
        client.cancel(list(futures))
        raise
