"""Step scenes in C with ``mujoco.rollout`` and record an ``xarray.Dataset``.

The per-step loop runs entirely inside MuJoCo's C rollout.  Python only
prepares the open-loop controls of a chunk of steps (the gait's set-points
and the perturbation forces), hands the chunk to ``rollout`` and decimates
its output to the recording rate.  Chunks bound memory for long runs and
large groups.

The constraint solver is warm-started from the previous step's
accelerations, as in a plain ``mj_step`` loop, and each scene's warm start is
carried from one ``rollout`` call to the next (:class:`_WarmRollout`): results
are bitwise independent of the chunk size and of batching, and equal to a
plain ``mj_step`` loop from a fresh ``MjData`` (``tests/test_simulation.py``).

Two engines step the scenes (``SimOptions.backend``): MuJoCo's C engine
(the default; everything above holds bitwise) and MuJoCo Warp
(:mod:`undulate.simulation._warp`: every scene of a batch one world of one model, on a
GPU or Warp's CPU device, float32; agreement with the default engine is
measured in docs/gpu.md, not bitwise).  :class:`Gather` lets the runs of a
sweep, each on its own thread, reach Warp as one batch.

Recorded variables: :mod:`undulate.schema` (names, dims, units, long
names; shared with the robot logger and the tracker).

Forces are interval means: ``sum(F * sample_interval)`` is the exact
time-integral over the run (every step contributes).
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
import xarray as xr

from .. import _physics
from ..errors import DivergenceError, ParameterError
from ..params import Scene, SimOptions
from ..control import Controller, make_controller
from ..schema import scene_attrs, variable  # noqa: F401  (importable from here as before)
from ..scene import CompiledScene, auto_timestep, build, servo_damping_rate_per_s, snap_timestep
from .._xrcompat import install as _lazy_dask
from ._backend import (BACKEND_ENV, DEVICE_ENV, backend_attrs, check_backend,  # noqa: F401
                       cores_up_to, default_backend, use_backend, warp_processes)
from ._checkpoint import Checkpoint, _starts
from ._compile import RK4_DAMPING_STEP, compile_scene, controls, resolve_options  # noqa: F401
from ._env import usable_cpus
from ._gather import Gather, _gathering
from ._mujoco import _WarmRollout, _initial_state, _log_mujoco_warning, _state_layout  # noqa: F401
from ._record import (RECORDABLE, _check_chunk_fits, _check_fits, _link_angles, _MemoryRecorder, _NetCDFRecorder,  # noqa: F401
                      _outs, _Recorders, _sample_vars, _to_dataset)

_lazy_dask()  # no Dask import for NumPy-only data (undulate._xrcompat)

__all__ = ["simulate", "simulate_batch", "Checkpoint", "compile_scene", "controls", "resolve_options", "RECORDABLE",
           "use_backend", "default_backend", "Gather"]


_HUGE = 1e6  # |state entry| beyond this (m, rad, m/s, rad/s) means the integration blew up


def _check_same_structure(compiled: Sequence[CompiledScene]) -> None:
    ref = compiled[0].model
    for c in compiled[1:]:
        m = c.model
        if (m.nq, m.nv, m.nu, m.na, m.nsensordata, m.ngeom) != (ref.nq, ref.nv, ref.nu, ref.na, ref.nsensordata, ref.ngeom):
            raise ParameterError(
                "scenes", "of one structure in a batch (same swimmers, links and walls)", None
            )


def _diagnose(cs: CompiledScene, options: SimOptions, t: float, what: str) -> DivergenceError:
    tc = cs.model.geom_solref[0, 0]
    return DivergenceError(
        f"simulation diverged at t = {t:.3f} s: {what}. Likely cause: the time step "
        f"({options.timestep_s:g} s) is too large for the contact stiffness "
        f"(time constant {tc:g} s) or servo gains, or the constraint solver failed to converge; "
        f"try a smaller --timestep, a softer contact (larger timeconst_s) or another solver "
        f"(SimOptions.solver = 'cg' or 'pgs')."
    )


class _Clock:
    """Physics time of one :func:`simulate_batch` call: wall seconds inside ``mujoco.rollout`` and
    scene-steps taken there (reported to the open meters, :func:`undulate._physics.report`, when the
    call ends)."""

    def __init__(self):
        self.seconds, self.steps = 0.0, 0

    def rollout(self, runner, nb: int, n_steps: int, *args, **kwargs):
        t0 = time.perf_counter()
        out = runner.rollout(*args, **kwargs)
        self.seconds += time.perf_counter() - t0
        active = kwargs.get("active")
        self.steps += (nb if active is None else int(active.sum())) * n_steps
        return out


@dataclass
class _Batch:
    """A batch of compiled scenes and everything resolved about how to step and record them."""

    compiled: list
    options: SimOptions
    requested: SimOptions
    outs: list | None
    ctl: Controller | None
    tick: int
    chunk: int
    n_samples: int

    @property
    def m0(self) -> mujoco.MjModel:
        return self.compiled[0].model

    @property
    def nb(self) -> int:
        return len(self.compiled)

    @property
    def dt(self) -> float:
        return self.options.timestep_s

    @property
    def sps(self) -> int:
        return self.options.steps_per_sample


def _check_scenes(scenes, options) -> None:
    """Refuse a batch that is not a non-empty sequence of Scene, or options that are not SimOptions."""
    if options is not None and not isinstance(options, SimOptions):
        raise ParameterError("options", "a SimOptions or None", type(options).__name__)
    if isinstance(scenes, (Scene, str, bytes)) or not isinstance(scenes, Sequence):
        raise ParameterError("scenes", "a non-empty sequence of Scene", type(scenes).__name__)
    if len(scenes) == 0:
        raise ParameterError("scenes", "a non-empty sequence of Scene", scenes)
    wrong = [type(s).__name__ for s in scenes if not isinstance(s, Scene)]
    if wrong:
        raise ParameterError("scenes", "a non-empty sequence of Scene", f"an item of type {wrong[0]}")


def _plan_batch(scenes: Sequence[Scene], options: SimOptions | None, out, controller,
                compiled: dict[int, tuple] | None = None) -> _Batch:
    """Validate a batch, resolve its time step, compile its scenes and choose its chunk length.
    ``compiled``: ``{index: (push, CompiledScene)}`` of scenes already compiled by the same rule (a
    gathered batch's grouping, :func:`undulate.simulation._gather._gather_groups`), used where their
    ``push`` is the batch's and the batch is open-loop (closed-loop batches compile servo-load sensors).
    ``scenes`` and ``options`` are :func:`simulate_batch`'s, checked there (:func:`_check_scenes`)."""
    options = options or SimOptions()
    requested = options
    resolved = [resolve_options(s, options) for s in scenes]
    if len({o.timestep_s for o in resolved}) > 1:
        raise ParameterError("scenes", "of one time step in a batch (same links and servo, or an "
                             "explicit SimOptions.timestep_s)", sorted({o.timestep_s for o in resolved}))
    options = resolved[0]
    if options.backend == "warp" and len(scenes) <= cores_up_to(options.device):  # a small batch: the cores
        options = dataclasses.replace(options, backend="mujoco", device=None)
    outs = _outs(out, len(scenes))
    push = any(s.forces_N is not None for s in scenes)  # one structure: all or none carry them
    closed = controller is not None or scenes[0].controller.closed_loop
    if closed and any((s.gait, s.controller, s.geometry.n_links) != (scenes[0].gait, scenes[0].controller,
                                                                   scenes[0].geometry.n_links) for s in scenes):
        raise ParameterError("scenes", "of one gait, controller and link count in a closed-loop batch", None)
    done = {} if closed or compiled is None else {i: cs for i, (p, cs) in compiled.items() if p == push}
    compiled = [done.get(i) or compile_scene(s, options, push=push, loads=closed) for i, s in enumerate(scenes)]
    _check_same_structure(compiled)
    dt, sps = options.timestep_s, options.steps_per_sample
    n_samples = options.n_steps // sps
    if n_samples < 1:
        raise ParameterError("duration_s", f">= one sample interval ({sps * dt:g} s)", options.duration_s)
    _check_fits(compiled, options.recorded, n_samples, outs)
    ctl, tick = None, 0
    if closed:
        ctl = controller if controller is not None else make_controller(scenes[0])
        ctl.reset(np.stack([np.asarray(sc.phases_rad) for sc in scenes]))
        tick = max(1, int(round(1.0 / (ctl.rate_hz * dt))))  # integrator steps per control period
        unit = sps * tick // math.gcd(sps, tick)
        chunk = unit * max(1, options.chunk_steps // unit)
    else:
        chunk = sps * max(1, options.chunk_steps // sps)
    if chunk > options.chunk_steps:  # a chunk as long as a sample interval (or control period) longer
        _check_chunk_fits(compiled, chunk, dt, _reduced_on_device(options, ctl), requested.timestep_s is None)
    return _Batch(compiled, options, requested, outs, ctl, tick, chunk, n_samples)


def _reduced_on_device(options: SimOptions, ctl) -> bool:
    """Whether a batch's samples are reduced on the device (the Warp backend in open loop): the host
    then holds a chunk's controls only, not its every-step states and sensors."""
    return options.backend == "warp" and ctl is None and os.environ.get("UNDULATE_WARP_REDUCE", "1") != "0"


def _force_mag(sd: np.ndarray, adr: np.ndarray) -> np.ndarray:
    cols = adr[..., None] + np.arange(3)
    return np.linalg.norm(sd[..., cols], axis=-1)


def _depth_of(sd: np.ndarray, md: np.ndarray) -> np.ndarray:
    return np.where(sd[..., md] > 0, np.maximum(0.0, -sd[..., md + 1]), 0.0)


def _check_divergence(bt: _Batch, st: np.ndarray, depth: np.ndarray, done: int, active: np.ndarray) -> None:
    """Raise :class:`DivergenceError` for a chunk's states ``st`` (nb, k, nstate) of the ``active``
    scenes that blew up: huge or non-finite, a MuJoCo reset (it restarts the data after bad
    accelerations: the state's clock jumps back), or deep interpenetration."""
    k, dt = st.shape[1], bt.dt
    t_expected = (done + 1 + np.arange(k)) * dt
    huge = ~(np.abs(st) < _HUGE).all(axis=2)
    reset = np.abs(st[..., 0] - t_expected) > 0.5 * dt
    deep = depth > max(c.scene.contact.max_penetration_m for c in bt.compiled)
    bad = (huge | reset | deep) & active[:, None]
    if not bad.any():
        return
    b = int(np.flatnonzero(bad.any(axis=1))[0])
    step = int(np.argmax(bad[b]))
    if huge[b, step]:
        what = "non-finite or huge state (NaN, inf or > 1e6)"
    elif reset[b, step]:
        what = "MuJoCo found bad accelerations (solver failure) and reset the state"
    else:
        what = (f"interpenetration {depth[b, step] * 1e3:.2f} mm exceeds the "
                f"{bt.compiled[b].scene.contact.max_penetration_m * 1e3:g} mm bound")
    raise _diagnose(bt.compiled[b], bt.options, float(t_expected[step]), what)


class _Stepper:
    """Steps a batch chunk by chunk in C (open loop: one rollout per chunk; closed loop:
    :func:`_closed_loop_chunk`) and turns each chunk into recorded sample blocks."""

    def __init__(self, bt: _Batch, nthread: int, clock: _Clock, starts: list[Checkpoint] | None = None):
        self.bt, self.clock = bt, clock
        m0, nb = bt.m0, bt.nb
        self.q0, self.nstate = _state_layout(m0)
        ix = bt.compiled[0].index
        self.pair_adr, self.wall_adr, self.md = ix.sens_pair, ix.sens_wall, ix.sens_mindist
        if bt.options.backend == "warp":
            from . import _warp

            affine = [compile_scene(c.scene, bt.options, push=c.index.ctrl_push.size > 0,
                                    loads=c.index.sens_load.size > 0, servo="affine") for c in bt.compiled]
            self.reduce = _reduced_on_device(bt.options, bt.ctl)
            red = _warp._Reduction(bt.sps, self.pair_adr, self.wall_adr, self.md,
                                   [c.scene.contact.max_penetration_m for c in bt.compiled]) if self.reduce else None
            self.runner = _warp.WarpRollout(bt.compiled, affine, bt.options, bt.options.device, reduce=red)
        else:
            self.reduce = False
            self.runner = _WarmRollout([c.model for c in bt.compiled], nthread)
        state0, sens0 = np.empty((nb, self.nstate)), np.empty((nb, m0.nsensordata))
        for b, cs in enumerate(bt.compiled):
            state0[b], sens0[b] = _initial_state(cs.model)
        self.state0, self.sens0 = state0, sens0
        self.cur, self.last_sens = state0.copy(), sens0.copy()
        self.bufs = self._buffers(bt.chunk)
        self.done = 0  # integrator steps taken
        if starts is not None:  # go on from checkpoints: their states, warm starts and step count
            self.cur = np.stack([c.state for c in starts])
            self.runner.warm[:] = np.stack([c.warmstart for c in starts])
            self.done = int(round(starts[0].time_s / (bt.sps * bt.dt))) * bt.sps

    def _buffers(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every step's states, sensors and controls of a chunk of ``k`` steps (reduced on the device:
        the controls only; the states and sensors come back one row per sample interval)."""
        nb, m0 = self.bt.nb, self.bt.m0
        n = 0 if self.reduce else k
        return np.empty((nb, n, self.nstate)), np.empty((nb, n, m0.nsensordata)), np.empty((nb, k, m0.nu))

    def _forces(self, sd: np.ndarray, ns: int):
        """Interval means of the pair and wall forces and the interval's deepest penetration."""
        bt = self.bt
        nb, sps, npair = bt.nb, bt.sps, len(self.pair_adr)
        fp = _force_mag(sd, self.pair_adr).reshape(nb, ns, sps, npair).mean(axis=2) if npair \
            else np.zeros((nb, ns, 0))
        fw = _force_mag(sd, self.wall_adr)
        fw = fw.reshape(nb, ns, sps, *fw.shape[2:]).mean(axis=2)
        return fp, fw

    def initial_blocks(self) -> list[dict]:
        """The samples at t = 0, one block per scene."""
        bt, q0 = self.bt, self.q0
        cmd0 = phase0 = None
        if bt.ctl is not None:
            cmd0, _ = bt.ctl.commands(np.zeros(1))
            phase0 = bt.ctl.gait_phase(np.zeros(1))
        s0 = self.sens0
        fp = _force_mag(s0[:, None], self.pair_adr) if len(self.pair_adr) else np.zeros((bt.nb, 1, 0))
        fw, pn = _force_mag(s0[:, None], self.wall_adr), _depth_of(s0[:, None], self.md)
        return [self._block(b, 0, self.state0[b:b + 1, q0:q0 + bt.m0.nq], s0[b:b + 1], fp[b], fw[b], pn[b],
                            None if cmd0 is None else cmd0[:, b], None if phase0 is None else phase0[:, b])
                for b in range(bt.nb)]

    def _block(self, b, i0, qpos, sens, fp, fw, pn, cmd=None, phase=None) -> dict:
        bt = self.bt
        t = np.round((i0 + np.arange(len(qpos))) * (bt.sps * bt.dt), 12)  # s; equal rates, equal clocks
        return _sample_vars(bt.compiled[b], t, qpos, sens, fp, fw, pn, bt.options.recorded, cmd=cmd, phase=phase)

    def _rollout(self, k: int, active: np.ndarray | None):
        """Step ``k`` integrator steps from the current state: states, sensors, commands and phases at
        the recorded rows (None for the open-loop gait)."""
        bt, dt, sps = self.bt, self.bt.dt, self.bt.sps
        if self.bufs[2].shape[1] != k:  # last, shorter chunk: contiguous buffers of its size
            self.bufs = self._buffers(k)
        state_buf, sens_buf, ctrl_buf = self.bufs
        t = (self.done + np.arange(k)) * dt
        if bt.ctl is None:
            for b in (range(bt.nb) if active is None else np.flatnonzero(active)):
                ctrl_buf[b] = controls(bt.compiled[b], t)
            st, sd = self.clock.rollout(self.runner, bt.nb, k, self.cur, ctrl_buf, state_buf, sens_buf, k,
                                        active=active)
            return st, sd, None, None
        rows = np.arange(sps - 1, k, sps)
        t_rows = np.round((self.done // sps + 1 + np.arange(k // sps)) * (sps * dt), 12)  # as _block stamps them
        chunk = _feed_forward_chunk if bt.ctl.feed_forward else _closed_loop_chunk
        st, sd, cmd_rows, phase_rows = chunk(
            bt.ctl, bt.compiled, self.runner, self.cur, self.last_sens, t, bt.tick, rows,
            t_rows, state_buf, sens_buf, ctrl_buf, self.q0, self.clock, active)
        self.last_sens = sd[:, k - 1].copy()
        return st, sd, cmd_rows, phase_rows

    def _step_chunk_reduced(self, k: int, stepping: np.ndarray) -> list[dict | None]:
        """:meth:`step_chunk` on the Warp backend in open loop: the device keeps each sample
        interval's last state and sensors, deepest penetration, mean forces and the first bad step
        (:meth:`undulate.simulation._warp.WarpRollout.rollout_samples`), so only those cross to the
        host; the same blocks and the same divergence diagnoses as from every step."""
        bt, q0, sps = self.bt, self.q0, self.bt.sps
        active = None if stepping.all() else stepping
        if self.bufs[2].shape[1] != k:
            self.bufs = self._buffers(k)
        ctrl_buf = self.bufs[2]
        t = (self.done + np.arange(k)) * bt.dt
        for b in (range(bt.nb) if active is None else np.flatnonzero(active)):
            ctrl_buf[b] = controls(bt.compiled[b], t)
        t0 = time.perf_counter()
        st, sd, pn, fp, fw, bad_step, bad_kind = self.runner.rollout_samples(self.cur, ctrl_buf, k, active)
        self.clock.seconds += time.perf_counter() - t0
        self.clock.steps += int(stepping.sum()) * k
        bad = np.flatnonzero((bad_step >= 0) & stepping)
        if bad.size:
            b = int(bad[0])
            step = int(bad_step[b])
            t_bad = float((self.done + 1 + step) * bt.dt)
            if bad_kind[b] == 1:
                what = "non-finite or huge state (NaN, inf or > 1e6)"
            else:
                what = (f"interpenetration beyond the "
                        f"{bt.compiled[b].scene.contact.max_penetration_m * 1e3:g} mm bound")
            raise _diagnose(bt.compiled[b], bt.options, t_bad, what)
        self.cur = st[:, -1].copy()
        self.last_sens = sd[:, -1].copy()
        blocks = [self._block(b, self.done // sps + 1, st[b, :, q0:q0 + bt.m0.nq], sd[b], fp[b], fw[b], pn[b])
                  if stepping[b] else None for b in range(bt.nb)]
        self.done += k
        return blocks

    def step_chunk(self, k: int, stepping: np.ndarray) -> list[dict | None]:
        """Step the scenes of mask ``stepping`` one chunk of ``k`` steps (a multiple of the sample
        interval); their sample blocks (None for a scene not stepped: it stays where it is)."""
        if self.reduce:
            return self._step_chunk_reduced(k, stepping)
        bt, q0, sps = self.bt, self.q0, self.bt.sps
        st, sd, cmd_rows, phase_rows = self._rollout(k, None if stepping.all() else stepping)
        depth = _depth_of(sd, self.md)
        self.cur = st[:, k - 1].copy()
        _check_divergence(bt, st, depth, self.done, stepping)
        ns, rows = k // sps, np.arange(sps - 1, k, sps)
        fp, fw = self._forces(sd, ns)
        pn = depth.reshape(bt.nb, ns, sps).max(axis=2)
        blocks = [self._block(b, self.done // sps + 1, st[b, rows, q0:q0 + bt.m0.nq], sd[b, rows], fp[b], fw[b],
                              pn[b], None if cmd_rows is None else cmd_rows[:, b],
                              None if phase_rows is None else phase_rows[:, b]) if stepping[b] else None
                  for b in range(bt.nb)]
        self.done += k
        return blocks

    def checkpoint(self, b: int) -> Checkpoint:
        """Where scene ``b`` is now (a scene that stopped stays where its rule ended it)."""
        return Checkpoint(self.cur[b].copy(), self.runner.warm[b].copy())

    def close(self) -> None:
        self.runner.close()


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
    (:func:`undulate._physics.meter`).
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
    if nthread == 0 and bt.nb > 1 and bt.options.backend == "mujoco" and check_backend(bt.requested).backend == "warp":
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
        _physics.report(clock.seconds, clock.steps)
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


def _push_controls(ctrl_buf: np.ndarray, compiled, t: np.ndarray) -> None:
    """Zero a closed-loop chunk's controls, then the perturbation forces from each scene's own controls."""
    ctrl_buf[:] = 0.0
    if compiled[0].index.ctrl_push.size:
        for b, cs in enumerate(compiled):
            ctrl_buf[b] = controls(cs, t)


def _set_points(u: np.ndarray, ang: np.ndarray, vel: np.ndarray, lead: float, pos_cols, vel_cols) -> None:
    """Servo set-points into controls ``u`` (nb, T, nu) from commands (T, nb, ...): the angle plus the
    back-EMF lead ``b omega / kp``, and the velocity."""
    n_t, nb = ang.shape[:2]
    u[:, :, pos_cols] = (ang + lead * vel).reshape(n_t, nb, -1).transpose(1, 0, 2)
    u[:, :, vel_cols] = vel.reshape(n_t, nb, -1).transpose(1, 0, 2)


def _closed_loop_chunk(ctl: Controller, compiled, runner: _WarmRollout, cur, last_sens, t, tick, rows, t_rows,
                       state_buf, sens_buf, ctrl_buf, q0, clock: _Clock, active=None):
    """Step one chunk a control period at a time: sense, command, roll out in C.

    ``cur`` (the state at the chunk's start) is updated in place.  Returns the
    chunk's states, sensor data, and the commanded joint angles and gait phases
    at the recorded ``rows`` (each ``(len(rows), nb, n, nj)`` / ``(len(rows), nb, n)``).
    ``active``: a mask of the scenes to step (None: all); the others stay where they are.
    """
    nb, k = state_buf.shape[:2]
    cs0 = compiled[0]
    ix, m0 = cs0.index, cs0.model
    sc = cs0.scene
    qv0 = q0 + m0.nq
    lead = sc.servo.back_emf_Nms_per_rad / sc.servo.kp_Nm_per_rad
    qpos_j, qvel_j, load_j = ix.qpos_joint, ix.qvel_joint, ix.sens_load
    pos_cols, vel_cols = ix.ctrl_pos, ix.ctrl_vel
    n_rows = len(rows)
    cmd_rows = np.empty((n_rows, nb) + qpos_j.shape)
    phase_rows = np.empty((n_rows, nb, qpos_j.shape[0]))
    _push_controls(ctrl_buf, compiled, t)
    pos_flat, vel_flat = pos_cols.ravel(), vel_cols.ravel()
    # the sensed joints: views of the current state and of the last step's sensors
    sens = last_sens
    one = nb == 1  # one scene: the chunk buffers' slices are contiguous, roll out straight into them
    if not one:
        u_t = np.empty((nb, tick, m0.nu))
        st_t = np.empty((nb, tick, state_buf.shape[2]))
        sd_t = np.empty((nb, tick, sens_buf.shape[2]))
    a = 0
    while a < k:
        e = min(k, a + tick)
        n_t = e - a
        ang, vel = ctl.commands(t[a:e], cur[:, q0 + qpos_j], cur[:, qv0 + qvel_j], sens[:, load_j])
        # set-points for these steps: angle (+ the back-EMF lead b omega / kp) and velocity
        if one:
            u, st, sd = ctrl_buf[:, a:e], state_buf[:, a:e], sens_buf[:, a:e]
        else:
            u = ctrl_buf[:, a:e].copy() if n_t != tick else u_t
            if n_t == tick:
                u[:] = ctrl_buf[:, a:e]
            st = st_t if n_t == tick else np.empty((nb, n_t, state_buf.shape[2]))
            sd = sd_t if n_t == tick else np.empty((nb, n_t, sens_buf.shape[2]))
        _set_points(u, ang, vel, lead, pos_flat, vel_flat)
        # what is recorded at the samples inside this period (states after step r, at time t[r] + dt)
        sel = (rows >= a) & (rows < e)
        if sel.any():
            tr = t_rows[sel]
            cmd_rows[sel] = ctl.commands(tr)[0]
            phase_rows[sel] = ctl.gait_phase(tr)
        clock.rollout(runner, nb, n_t, cur, u, st, sd, n_t, active=active)
        if not one:
            ctrl_buf[:, a:e], state_buf[:, a:e], sens_buf[:, a:e] = u, st, sd
        cur[:] = st[:, -1]
        sens = sd[:, -1]
        a = e
    return state_buf, sens_buf, cmd_rows, phase_rows


def _feed_forward_chunk(ctl: Controller, compiled, runner: _WarmRollout, cur, last_sens, t, tick, rows, t_rows,
                        state_buf, sens_buf, ctrl_buf, q0, clock: _Clock, active=None):
    """:func:`_closed_loop_chunk` for a controller whose commands do not depend on what it senses
    (``Controller.feed_forward``): the whole chunk in one rollout, then what was sensed at each
    control update (the state after the step before it, that step's sensors) handed to
    ``ctl.sense``.  Bitwise the states, sensor data and senses of stepping period by period."""
    nb, k = state_buf.shape[:2]
    ix, m0, sv = compiled[0].index, compiled[0].model, compiled[0].scene.servo
    qpos_j, qvel_j, load_j = q0 + ix.qpos_joint, q0 + m0.nq + ix.qvel_joint, ix.sens_load
    _push_controls(ctrl_buf, compiled, t)
    ang, vel = ctl.commands(t)
    _set_points(ctrl_buf, ang, vel, sv.back_emf_Nms_per_rad / sv.kp_Nm_per_rad, ix.ctrl_pos.ravel(),
                ix.ctrl_vel.ravel())
    clock.rollout(runner, nb, k, cur, ctrl_buf, state_buf, sens_buf, k, active=active)
    for a in range(0, k, tick):
        st, sd = (cur, last_sens) if a == 0 else (state_buf[:, a - 1], sens_buf[:, a - 1])
        ctl.sense(float(t[a]), st[:, qpos_j], st[:, qvel_j], sd[:, load_j])
    cur[:] = state_buf[:, -1]
    return state_buf, sens_buf, ctl.commands(t_rows)[0], ctl.gait_phase(t_rows)


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
