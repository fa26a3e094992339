"""The public entries :func:`simulate` and :func:`simulate_batch`: a batch planned, stepped and
recorded, its cost reported to the open wall-time meters."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence

import mujoco
import numpy as np
import xarray as xr

from .. import _walltime
from ..control import Controller
from ..errors import ParameterError
from ..params import Scene, SimOptions
from ._backend import check_backend
from ._batch import _Batch, _check_scenes, _Clock, _plan_batch
from ._checkpoint import Checkpoint, _starts
from ._env import usable_cpus
from ._gather import _gathering
from ._mujoco import _log_mujoco_warning
from ._record import _Recorders
from ._stepper import _Stepper

def simulate_batch(
    scenes: Sequence[Scene],
    options: SimOptions | None = None,
    *,
    nthread: int = 0,
    out: str | os.PathLike | Sequence[str | os.PathLike] | None = None,
    controller: Controller | None = None,
    stop: Callable[[list[dict]], str | None] | Sequence[Callable[[list[dict]], str | None]] | None = None,
    progress: Callable[[float, float], None] | None = None,
    start: Checkpoint | Sequence[Checkpoint] | None = None,
) -> list[xr.Dataset]:
    """Simulate several scenes of one structure together in one rollout.

    ``nthread = 0`` steps them on the calling thread; ``> 0`` uses MuJoCo's
    rollout thread pool.  Returns one Dataset per scene, identical to
    :func:`simulate` on each scene alone.

    ``out``: one ``.nc`` path per scene (a single path for one scene) to
    stream the samples to, chunk by chunk, so memory does not grow with the
    duration; the Datasets returned are then opened lazily from those files
    (close them when done).  Without ``out`` the recording is kept in memory,
    and a run whose recording would not fit is refused before it starts.

    ``controller``: a gait controller object (:mod:`undulate.control`) to
    drive the servos instead of the scenes' own (``Scene.controller``), reset
    to the scenes' phases (leading batch axis).  With a closed-loop
    controller (the scenes' or this one) MuJoCo steps one control period at a
    time in C and the controller senses joint angles, speeds and servo
    torques between periods, vectorised over swimmers and the batch; the
    scenes must then share their gait and controller parameters.

    ``stop``: a stopping rule (e.g. :class:`undulate.stopping.SteadyStop`'s
    monitor), called with the new samples of every scene (a list of dicts of
    arrays, ``"time"`` and the recorded variables; the t = 0 sample first)
    after each chunk of ``SimOptions.chunk_steps`` steps; it returns None to go
    on or a reason to end the run there.  The recording then ends at that
    chunk: bitwise the first samples of the full-length run (each step depends
    on the state alone).  Or a sequence of rules, one per scene, each called
    with ``[that scene's samples]``: a scene whose rule ends it is stepped no
    further while the others go on, so each scene's Dataset is bitwise its run
    alone with its own rule.  The Datasets' attrs ``stop_rule`` (the rule's
    ``rule`` attribute), ``stop_reason`` ("" when it ran to the end) and
    ``stopped_at`` (s, the last sample) record it.

    ``progress``: called as ``progress(done_s, total_s)`` (simulated seconds
    stepped so far and in all) once the t = 0 samples are recorded and after
    every chunk, between calls into C, never inside the step loop; it cannot
    change the results (e.g. :class:`undulate._progress.RunMonitor`).

    ``start``: a :class:`Checkpoint` per scene (all at one time) to go on from
    instead of from rest, e.g. where a stopping rule ended a run: every Dataset's
    attrs ``end_state`` and ``end_warmstart`` hold where its scene ended.

    Every Dataset's attrs ``physics_time`` (s, wall time inside
    ``mujoco.rollout`` for the whole batch) and ``physics_steps`` (scene-steps)
    record what the call cost; the same is reported to the open physics meters
    (:func:`undulate._walltime.meter`).
    """
    _check_scenes(scenes, options)
    g = _gathering()
    if g is not None and out is None and controller is None and progress is None and (
            stop is None or not callable(stop) or len(scenes) == 1):
        return g.submit(list(scenes), options, stop, _simulate_batch_now, start)
    return _simulate_batch_now(scenes, options, nthread=nthread, out=out, controller=controller, stop=stop,
                               progress=progress, start=start)


def _simulate_batch_now(scenes, options, *, nthread=0, out=None, controller=None, stop=None, progress=None,
                        start=None, compiled=None):
    """:func:`simulate_batch` in this call, never gathered (``compiled``: see :func:`_plan_batch`)."""
    bt = _plan_batch(scenes, options, out, controller, compiled)
    if nthread == 0 and bt.nb > 1 and bt.options.backend != check_backend(bt.requested).backend:
        nthread = min(bt.nb, usable_cpus())  # lone swimmers or a small batch handed to the cores: all of them
    starts = _starts(bt, start)
    clock = _Clock()
    recorders = _Recorders(bt, stop)
    stepper = _Stepper(bt, nthread, clock, starts)
    # MuJoCo's own warnings (printed and appended to ./MUJOCO_LOG.TXT by default) go to the
    # log instead while we step: a divergence is diagnosed from the state itself.
    previous_handler = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(_log_mujoco_warning)
    ok = False
    try:
        _step_all(bt, stepper, recorders, progress, resumed=starts is not None)
        results, ends = recorders.finish(), [stepper.checkpoint(b) for b in range(bt.nb)]
        ok = True
    finally:
        stepper.close()
        mujoco.set_mju_user_warning(previous_handler)
        _walltime.report(clock.seconds, clock.steps)
        if not ok:
            recorders.abort()
    _stamp(results, clock, recorders, ends)
    return results


def _stamp(results: list[xr.Dataset], clock: _Clock, recorders: "_Recorders", ends: list[Checkpoint]) -> None:
    """Each Dataset's attrs: what the batch cost, how its scene's run ended, and where (its checkpoint)."""
    for b, ds in enumerate(results):
        ds.attrs.update(physics_time=clock.seconds, physics_time_units="s", physics_steps=clock.steps,
                        stop_rule=recorders.rule(b), stop_reason=recorders.reasons[b] or "",
                        stopped_at=float(ds["time"].values[-1]), stopped_at_units="s",
                        end_state=ends[b].state, end_warmstart=ends[b].warmstart)


def _step_all(bt: _Batch, stepper: _Stepper, recorders: _Recorders,
              progress: Callable[[float, float], None] | None, resumed: bool = False) -> None:
    """Record the t = 0 samples (not when ``resumed`` from checkpoints), then step and record chunk by
    chunk to the end or until every scene's stopping rule has ended it (a scene that stopped is stepped
    no further)."""
    total = bt.n_samples * bt.sps
    ended = False if resumed else recorders.record(stepper.initial_blocks())
    if progress is not None:
        progress(stepper.done * bt.dt, total * bt.dt)
    while stepper.done < total and not ended:
        stepping = np.array([r is None for r in recorders.reasons])  # a scene whose rule ended it stays
        ended = recorders.record(stepper.step_chunk(min(bt.chunk, total - stepper.done), stepping))
        if progress is not None:
            progress(stepper.done * bt.dt, total * bt.dt)


def simulate(scene: Scene, options: SimOptions | None = None, *,
             out: str | os.PathLike | None = None, controller: Controller | None = None,
             stop: Callable[[list[dict]], str | None] | Sequence[Callable[[list[dict]], str | None]] | None = None,
             progress: Callable[[float, float], None] | None = None,
             start: Checkpoint | None = None) -> xr.Dataset:
    """Simulate one scene; see the module docstring for the recorded variables.

    ``out``: a ``.nc`` path to stream the samples to (memory stays flat for
    any duration); the Dataset returned is then opened lazily from it (close
    it when done).  ``controller``, ``stop``, ``progress``, ``start``: see :func:`simulate_batch`.

    >>> from undulate import Scene, SimOptions, simulate
    >>> ds = simulate(Scene(phases_rad=(0.0, 1.57)), SimOptions(duration_s=4))
    """
    if not isinstance(scene, Scene):
        raise ParameterError("scene", "a Scene", type(scene).__name__)
    return simulate_batch([scene], options, out=out, controller=controller, stop=stop, progress=progress,
                          start=start)[0]
