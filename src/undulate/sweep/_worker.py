"""What runs on a worker: a chunk of runs, each persisted as it finishes.

This module is imported by every worker process (local or Dask), so it keeps
its imports light and holds no state.
"""

from __future__ import annotations

import contextvars
import os
import signal
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from .. import _walltime
from ..execution import Execution, using
from ._grid import Run
from ._store import check_output, result_path, write_failure, write_result

OK = "ok"
FAILED = "failed"
EXISTS = "exists"


@dataclass(frozen=True)
class Outcome:
    """What became of one run of a chunk."""

    key: str
    status: str
    """``"ok"`` (computed and saved), ``"failed"`` (raised; recorded) or
    ``"exists"`` (already saved, e.g. by an earlier try of this chunk)."""
    error: str = ""
    seconds: float = 0.0
    physics_s: float = 0.0
    """Of ``seconds``, the time spent inside MuJoCo's stepping (``mujoco.rollout``)."""
    steps: int = 0
    """Scene-steps taken in those rollouts."""


@dataclass(frozen=True)
class Chunk:
    """Several runs sent to a worker as one task (amortises the task overhead)."""

    fn: Callable
    runs_dir: str
    runs: tuple[Run, ...]
    grid_names: tuple[str, ...]
    batched: bool = False
    provenance: tuple[tuple[str, str], ...] = ()
    """The sweep's run provenance (function call, code hash, version), stored in each run file."""
    gather: bool = False
    """Run the chunk's runs on threads whose simulations are stepped together
    (:class:`undulate.simulation.Gather`: the Warp backend's worlds)."""
    execution: Execution | None = None
    """The settings the runs step under (:func:`undulate.execution.using`, for the chunk only), those
    of the process that started the sweep (:meth:`undulate.execution.Execution.for_workers`): a local
    pool's processes serve sweeps of either backend, and a Dask worker has the environment it was
    started with, not the sweep's.  Where the worker cannot step on its engine (no gpu extra, no such
    device), every run of the chunk fails saying why.  None: the settings in effect where it runs."""


STEP_PROGRESS: contextvars.ContextVar[Callable[[float, float, int], None] | None] = contextvars.ContextVar(
    "undulate_step_progress", default=None)
"""Where a gathered batch in this process reports its stepping (``progress(done, total, worlds)``:
:meth:`undulate.sweep._progress.Progress.stepping`); set by the sweep for the chunks it runs itself."""


PARENT_POLL_S = 0.5
"""How often a local pool process checks that the process that started it is still there."""


def init_local_worker(parent_pid: int | None = None) -> None:
    """Initializer of local pool processes: Ctrl-C is the parent's to handle, and the process ends
    once ``parent_pid`` (the process whose pool it is) is gone.

    Without the second, a parent that died without stopping its pool (SIGTERM to it alone, SIGKILL,
    the out-of-memory killer) left its workers behind for good: they went on with the chunks they had,
    writing runs into a store no one then held, and then waited forever on a queue whose other end
    they themselves keep open (measured: two processes of a terminated reproduction still there
    minutes later).  A daemon thread compares ``os.getppid()`` with ``parent_pid`` every
    :data:`PARENT_POLL_S` and ends the process with ``os._exit`` (a run half-written by then is a
    temporary file the store clears when next opened; a finished run is already in place)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if parent_pid is None:
        return
    if os.getppid() != parent_pid:  # gone before this process even started
        os._exit(1)

    def watch() -> None:
        while True:
            time.sleep(PARENT_POLL_S)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, name="undulate-parent-watch", daemon=True).start()


def _timing(wall: float, physics: _walltime.Tally, share: int = 1) -> dict:
    return {"wall_s": wall / share, "physics_s": physics.seconds / share, "steps": physics.steps // share}


def run_chunk(chunk: Chunk) -> list[Outcome]:
    """Compute every run of ``chunk`` that has no result yet; save each at once.

    A run that raises is recorded (``*.failed.json``) and the chunk goes on.
    """
    runs_dir = Path(chunk.runs_dir)
    ex = chunk.execution
    if ex is not None and ex.backend != "mujoco":
        from ..simulation import backend

        try:
            ex = ex.replace(device=backend(ex.backend).resolve_device(ex.device))
        except Exception as exc:  # noqa: BLE001 - e.g. a Dask worker without the gpu extra: said per run
            return [Outcome(r.key, EXISTS) if result_path(runs_dir, r).exists()
                    else Outcome(r.key, FAILED, write_failure(runs_dir, r, exc)["error"]) for r in chunk.runs]
    with using(ex):
        return _run_chunk(chunk, runs_dir)


def _run_chunk(chunk: Chunk, runs_dir: Path) -> list[Outcome]:
    """:func:`run_chunk` under its settings."""
    todo = []
    out = []
    for run in chunk.runs:
        if result_path(runs_dir, run).exists():
            out.append(Outcome(run.key, EXISTS))
        else:
            todo.append(run)
    if chunk.batched:
        out += _run_batched(chunk, runs_dir, todo)
    elif chunk.gather and len(todo) > 1:
        out += _run_gathered(chunk, runs_dir, todo)
    else:
        for run in todo:
            out.append(_run_one(chunk, runs_dir, run, lambda r: chunk.fn(dict(r.point), r.seed)))
    return out


def _run_one(chunk: Chunk, runs_dir: Path, run: Run, compute: Callable[[Run], object]) -> Outcome:
    t0 = time.perf_counter()
    with _walltime.meter() as physics:
        try:
            ds = check_output(compute(run), chunk.grid_names)
            tm = _timing(time.perf_counter() - t0, physics)
            write_result(runs_dir, run, ds, dict(chunk.provenance), timing=tm)
        except Exception as exc:  # noqa: BLE001 - every failure is recorded, the sweep goes on
            _stop_if_disk_full(exc)
            rec = write_failure(runs_dir, run, exc)
            tm = _timing(time.perf_counter() - t0, physics)
            return Outcome(run.key, FAILED, rec["error"], tm["wall_s"], tm["physics_s"], tm["steps"])
    return Outcome(run.key, OK, "", time.perf_counter() - t0, tm["physics_s"], tm["steps"])


def _stop_if_disk_full(exc: BaseException) -> None:
    """A full disk or quota ends the sweep (re-raised: no later run's file would fit, and recording each
    run as failed would only say so thousands of times); the runs saved so far stay for a rerun."""
    from ..errors import WriteError

    if isinstance(exc, WriteError) and exc.disk_full:
        raise exc


def _run_gathered(chunk: Chunk, runs_dir: Path, runs: Sequence[Run]) -> list[Outcome]:
    """Every run on its own thread, their simulations stepped together
    (:class:`undulate.simulation.Gather`); each run saved as it finishes, as :func:`_run_one` does."""
    import threading

    from ..simulation import Gather

    sweep = Path(runs_dir).parent  # the store's folder: OUT/.sweeps/STUDY/SWEEP
    gather = Gather(len(runs), progress=STEP_PROGRESS.get(), label=f"{sweep.parent.name}/{sweep.name}")
    outcomes: list[Outcome | None] = [None] * len(runs)
    stopped: list[BaseException] = []

    def work(i: int, run: Run) -> None:
        try:
            outcomes[i] = _run_one(chunk, runs_dir, run, lambda r: chunk.fn(dict(r.point), r.seed))
        except BaseException as e:  # noqa: BLE001 - a full disk: raised below, in the chunk's process
            stopped.append(e)
        finally:
            gather.thread_done()

    threads = []
    for i, run in enumerate(runs):
        t = threading.Thread(target=contextvars.copy_context().run, args=(work, i, run), daemon=True,
                             name=f"undulate-run-{run.key}")
        t.undulate_gather = gather
        threads.append(t)
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if stopped:
        raise stopped[0]
    return [o if o is not None else Outcome(r.key, FAILED, "the run's thread ended without a result")
            for o, r in zip(outcomes, runs)]


def _run_batched(chunk: Chunk, runs_dir: Path, runs: Sequence[Run]) -> list[Outcome]:
    """``fn(points, seeds) -> list[Dataset]`` on all runs at once; on error, one by one."""
    if not runs:
        return []
    t0 = time.perf_counter()
    with _walltime.meter() as physics:
        try:
            results = list(chunk.fn([dict(r.point) for r in runs], [r.seed for r in runs]))
            if len(results) != len(runs):
                raise ValueError(f"the batched sweep function returned {len(results)} Datasets for {len(runs)} points")
            results = [check_output(ds, chunk.grid_names) for ds in results]
        except Exception:  # noqa: BLE001 - isolate the failing point(s)
            return [_run_one(chunk, runs_dir, r, lambda r: _single(chunk.fn, r)) for r in runs]
    tm = _timing(time.perf_counter() - t0, physics, share=len(runs))  # the batch's, shared evenly
    out = []
    for run, ds in zip(runs, results):
        try:
            write_result(runs_dir, run, ds, dict(chunk.provenance), timing=tm)
            out.append(Outcome(run.key, OK, "", tm["wall_s"], tm["physics_s"], tm["steps"]))
        except Exception as exc:  # noqa: BLE001
            _stop_if_disk_full(exc)
            rec = write_failure(runs_dir, run, exc)
            out.append(Outcome(run.key, FAILED, rec["error"], tm["wall_s"], tm["physics_s"], tm["steps"]))
    return out


def _single(fn: Callable, run: Run) -> object:
    results = list(fn([dict(run.point)], [run.seed]))
    if len(results) != 1:
        raise ValueError(f"the batched sweep function returned {len(results)} Datasets for 1 point")
    return results[0]
