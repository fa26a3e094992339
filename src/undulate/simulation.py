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
(:mod:`undulate._warp`: every scene of a batch one world of one model, on a
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
import functools
import json
import logging
import math
import os
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import xarray as xr
from mujoco import rollout as _rollout

from . import _physics
from .errors import DivergenceError, ParameterError
from .params import Scene, SimOptions
from .control import Controller, make_controller
from .schema import scene_attrs, variable  # noqa: F401  (scene_attrs: importable from here as before)
from .scene import CompiledScene, auto_timestep, build, root_link, root_offset_m, servo_damping_rate_per_s, snap_timestep
from ._xrcompat import install as _lazy_dask

_lazy_dask()  # no Dask import for NumPy-only data (undulate._xrcompat)

__all__ = ["simulate", "simulate_batch", "Checkpoint", "compile_scene", "controls", "resolve_options", "RECORDABLE"]


RK4_DAMPING_STEP = 1.0
"""``rate dt`` allowed for the servo damping under ``rk4`` (its real-axis stability limit is 2.79)."""


BACKEND_ENV, DEVICE_ENV = "UNDULATE_BACKEND", "UNDULATE_DEVICE"


def use_backend(backend: str | None, device: str | None = None) -> None:
    """Make ``backend`` (``"mujoco"`` or ``"warp"``; None: back to ``"mujoco"``) and ``device`` the
    default of every :class:`SimOptions` that leaves them out, in this process and the worker
    processes it starts (it sets the environment variables ``UNDULATE_BACKEND`` and
    ``UNDULATE_DEVICE``).  The ``warp`` backend is checked here: its extra must be installed and
    the device present."""
    SimOptions(backend=backend, device=device)  # validated as options are
    if backend == "warp":
        from . import _warp

        device = _warp.resolve_device(device)
    for var, value in ((BACKEND_ENV, backend), (DEVICE_ENV, device)):
        if value is None:
            os.environ.pop(var, None)
        else:
            os.environ[var] = value


def default_backend() -> tuple[str, str | None]:
    """The session's default ``(backend, device)`` (:func:`use_backend`)."""
    backend = os.environ.get(BACKEND_ENV) or "mujoco"
    if backend not in SimOptions.BACKENDS:
        raise ParameterError(BACKEND_ENV, "'mujoco' or 'warp' (environment variable)", backend)
    return backend, (os.environ.get(DEVICE_ENV) or None) if backend == "warp" else None


def check_backend(options: SimOptions) -> SimOptions:
    """``options`` with a concrete backend and device (:func:`default_backend` where left out); a
    ParameterError if the Warp backend's extra or device is missing."""
    return _resolve_backend(options)


def _resolve_backend(options: SimOptions) -> SimOptions:
    if options.backend is not None and (options.backend == "mujoco" or options.device is not None):
        if options.backend == "warp":
            from . import _warp

            _warp.resolve_device(options.device)  # the extra and the device are there
        return options
    backend, device = (options.backend, options.device) if options.backend is not None else default_backend()
    if backend == "warp":
        from . import _warp

        device = _warp.resolve_device(options.device or device)
    return dataclasses.replace(options, backend=backend, device=device)


def backend_attrs(options: SimOptions) -> dict[str, str]:
    """What stepped a run (resolved ``options``): ``backend``, ``device``, ``precision`` and, for
    Warp, the versions of mujoco-warp and warp-lang (Dataset attrs, sweep identity)."""
    if options.backend != "warp":
        return {"backend": "mujoco", "device": "cpu", "precision": "float64"}
    from . import _warp

    return {"backend": "warp", "device": options.device or "", "precision": _warp.PRECISION,
            "backend_versions": _warp.versions()}


def resolve_options(scene: Scene, options: SimOptions) -> SimOptions:
    """``options`` with a concrete time step (the explicit one, or the
    time-step rule's, :func:`undulate.scene.auto_timestep`, for ``scene``) and
    a concrete backend and device (:func:`default_backend` where left out)."""
    options = _resolve_backend(options)
    if options.timestep_s is not None:
        return options
    dt = auto_timestep(scene)
    if options.integrator == "rk4":  # explicit in the servo damping too: resolve its decay
        dt = min(dt, snap_timestep(RK4_DAMPING_STEP / servo_damping_rate_per_s(scene)))
    try:
        return options.with_timestep(dt)
    except ParameterError as e:  # e.g. a sample rate above 1/dt
        raise ParameterError(e.name, f"{e.allowed} (automatic time step for this scene: {dt:g} s)",
                             e.got) from None


def compile_scene(scene: Scene, options: SimOptions, *, push: bool | None = None,
                  loads: bool | None = None, servo: str = "pid") -> CompiledScene:
    """Build the model for ``scene`` with the solver settings the runner needs
    (``options.timestep_s`` must be resolved: :func:`resolve_options`).
    ``push``: include the perturbation-force actuators (default: only if
    ``scene.forces_N`` is set; see :func:`undulate.scene.swimmer_spec`);
    ``loads``: servo-torque sensors for a closed-loop controller (default: if
    the scene's controller is closed-loop); ``servo``: how the servos are expressed
    (:data:`undulate.scene.SERVO_MODELS`; the Warp backend steps ``"affine"``)."""
    options = resolve_options(scene, options)
    cs = build(scene, options.timestep_s, pair_sensors="contact_force_pair" in options.recorded, push=push,
               loads=loads, servo=servo)
    m = cs.model
    solver = options.solver
    if solver == "auto":  # Newton at any size: MuJoCo 3.17's sparse Newton is correct (docs/contact.md §5)
        solver = "newton"
    m.opt.solver = {"newton": mujoco.mjtSolver.mjSOL_NEWTON, "cg": mujoco.mjtSolver.mjSOL_CG,
                    "pgs": mujoco.mjtSolver.mjSOL_PGS}[solver]
    cs.model.opt.integrator = {
        "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
        "rk4": mujoco.mjtIntegrator.mjINT_RK4,
    }[options.integrator]
    return cs


def controls(cs: CompiledScene, t_s: np.ndarray) -> np.ndarray:
    """Open-loop control vectors at times ``t_s`` -> ``T x nu`` (see
    :meth:`~undulate.scene.CompiledScene.controls`)."""
    return cs.controls(t_s)


def _state_layout(m: mujoco.MjModel) -> tuple[int, int]:
    """Offsets of qpos in a FULLPHYSICS state vector: (qpos_start, nstate)."""
    n_time = mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_TIME)
    return n_time, mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS)


def _initial_state(m: mujoco.MjModel) -> np.ndarray:
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    s = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(m, d, s, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    return s, d.sensordata.copy()


_log = logging.getLogger(__name__)


def _log_mujoco_warning(msg: str) -> None:
    _log.debug("MuJoCo: %s", msg)


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


RECORDABLE = SimOptions.RECORDABLE
"""Variables a run can record (``SimOptions.record``)."""


def _per_sample_bytes(cs: CompiledScene, record: Sequence[str]) -> int:
    """Bytes one recorded sample of one scene takes (float64), time included."""
    sc = cs.scene
    n, nj, nn = sc.n_swimmers, sc.geometry.n_links - 1, sc.geometry.n_links + 1
    size = {"x": n, "y": n, "heading": n, "node_x": n * nn, "node_y": n * nn, "joint_angle": n * nj,
            "joint_command": n * nj, "joint_error": n * nj, "contact_force_pair": max(0, n - 1),
            "contact_force_wall": len(cs.index.wall_names), "penetration": 1, "gait_phase": n}
    return 8 * (1 + sum(size[v] for v in record))


def _memory_available_bytes() -> int:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def _check_fits(compiled: Sequence[CompiledScene], record: Sequence[str], n_samples: int,
                outs: Sequence[Path] | None) -> None:
    """Refuse, before stepping, a recording that cannot fit in memory or on disk."""
    need = sum(_per_sample_bytes(c, record) for c in compiled) * (n_samples + 1)
    gib = 2.0**30
    if outs is None:
        have = _memory_available_bytes()
        if 2 * need > have:  # the samples plus the Dataset built from them
            raise ParameterError(
                "duration_s / sample_rate_hz (--duration / --sample-rate)",
                f"small enough for the recording to fit in memory: it needs {2 * need / gib:.3g} GiB, "
                f"{have / gib:.3g} GiB is available (stream it to a file with out=, or record fewer "
                f"variables with SimOptions.record)", None)
    else:
        for path in outs:
            free = shutil.disk_usage(Path(path).resolve().parent).free
            if need > free:
                raise ParameterError(
                    "duration_s / sample_rate_hz (--duration / --sample-rate)",
                    f"small enough for the recording to fit on disk: it needs {need / gib:.3g} GiB, "
                    f"{free / gib:.3g} GiB is free at {Path(path).resolve().parent}", None)


class _MemoryRecorder:
    """Collects each chunk's samples; the Dataset is built once at the end."""

    def __init__(self):
        self.blocks: list[dict] = []

    def add(self, block: dict) -> None:
        self.blocks.append(block)

    def finish(self, build) -> xr.Dataset:
        merged = {k: np.concatenate([b[k] for b in self.blocks]) for k in self.blocks[0]}
        self.blocks = []
        return build(merged)


class _NetCDFRecorder:
    """Writes the samples through to a netCDF file (unlimited ``time``).

    Chunks' samples are held until about :attr:`FLUSH_BYTES` have gathered and
    then appended in one write (each h5netcdf append costs ~1 ms per variable:
    appending every rollout chunk took a third of a long pair run), so memory
    stays bounded by that much plus one chunk.  The file is written to a
    temporary path beside ``path`` (:func:`undulate._io.temporary_path`) and
    fsync-ed and renamed into place by :meth:`finish`; :meth:`abort` removes it.
    """

    FLUSH_BYTES = 1 << 20

    def __init__(self, path: Path):
        from . import _io

        self.path = Path(path)
        self.tmp = _io.temporary_path(self.path)
        self.file = None
        self.pending: list[dict] = []
        self.pending_bytes = 0

    def add(self, block: dict, build) -> None:
        if self.file is None:  # the first block defines the file: variables, attrs, coordinates
            import h5netcdf

            ds = build(block)
            # HDF5 chunks of ~1 MiB along time: chunking by the first block's shape would make one
            # chunk per few samples, and HDF5's chunk index (held in memory) would grow with the run
            enc = {name: {"chunksizes": (max(1, 2**17 // max(1, int(np.prod(v.shape[1:])))),
                                         *(max(1, n) for n in v.shape[1:]))}  # HDF5: no empty chunk sides
                   for name, v in ds.variables.items() if v.dims[:1] == ("time",)}
            ds.to_netcdf(self.tmp, engine="h5netcdf", unlimited_dims=["time"], encoding=enc)
            self.file = h5netcdf.File(self.tmp, "a")  # kept open: reopening per chunk leaks memory
            self.appended = [n for n, v in self.file.variables.items() if v.dimensions[:1] == ("time",)]
            return
        self.pending.append(block)
        self.pending_bytes += sum(np.asarray(block[n]).nbytes for n in self.appended)
        if self.pending_bytes >= self.FLUSH_BYTES:
            self._flush()

    def _flush(self) -> None:
        if not self.pending:
            return
        f = self.file
        n0 = f.dimensions["time"].size
        k = sum(len(b["time"]) for b in self.pending)
        f.resize_dimension("time", n0 + k)
        for name in self.appended:
            f.variables[name][n0:n0 + k, ...] = np.concatenate([np.asarray(b[name]) for b in self.pending])
        self.pending, self.pending_bytes = [], 0

    def _close(self) -> None:
        if self.file is not None:
            self.file.close()
            self.file = None

    def finish(self) -> xr.Dataset:
        if self.file is not None:
            self._flush()
        self._close()
        from . import _io

        _io.commit(self.tmp, self.path)
        return xr.open_dataset(self.path, engine="h5netcdf")

    def abort(self) -> None:
        self.pending = []
        self._close()
        from . import _io

        _io.discard(self.tmp)


def _outs(out, nb: int) -> list[Path] | None:
    if out is None:
        return None
    paths = [Path(out)] if isinstance(out, (str, os.PathLike)) else [Path(p) for p in out]
    if len(paths) != nb:
        raise ParameterError("out", f"{nb} path(s), one per scene", out)
    for p_ in paths:
        if p_.suffix.lower() != ".nc":
            raise ParameterError("out", "a path ending in .nc (netCDF)", str(p_))
        if not p_.resolve().parent.is_dir():
            raise ParameterError("out", "a path in an existing directory", str(p_))
    return paths


@dataclass(frozen=True, eq=False)
class Checkpoint:
    """Where a run ended, to go on from: MuJoCo's whole physical state there
    (``mjSTATE_FULLPHYSICS``, time first: s, then positions, velocities,
    actuator states) and the constraint solver's warm start
    (``qacc_warmstart``).  Every Dataset of :func:`simulate` carries them in
    its attrs ``end_state`` and ``end_warmstart`` (:meth:`of`);
    ``simulate(scene, options, start=checkpoint)`` then steps on from there to
    ``options.duration_s`` and records the samples after it: bitwise the rest
    of the uninterrupted run (each step depends on the state and the warm
    start alone; open-loop gaits only)."""

    state: np.ndarray
    warmstart: np.ndarray

    @classmethod
    def of(cls, ds: xr.Dataset) -> "Checkpoint":
        """The end of the run ``ds`` (a Dataset :func:`simulate` returned)."""
        if "end_state" not in ds.attrs or "end_warmstart" not in ds.attrs:
            raise ParameterError("ds", "a Dataset simulate() returned (attrs end_state and end_warmstart)",
                                 sorted(ds.attrs)[:5])
        return cls(np.asarray(ds.attrs["end_state"], dtype=float), np.asarray(ds.attrs["end_warmstart"], dtype=float))

    @property
    def time_s(self) -> float:
        """The simulated time at the checkpoint, s."""
        return float(self.state[0])


def _starts(bt: "_Batch", start) -> list[Checkpoint] | None:
    """The batch's checkpoints, one per scene (None: every scene from rest), validated."""
    if start is None:
        return None
    starts = [start] if isinstance(start, Checkpoint) else list(start)
    if len(starts) != bt.nb or not all(isinstance(c, Checkpoint) for c in starts):
        raise ParameterError("start", f"a Checkpoint, or one per scene ({bt.nb})", start)
    if bt.ctl is not None:
        raise ParameterError("start", "open-loop scenes only (a closed-loop controller's own state is "
                             "not in a Checkpoint)", bt.ctl.kind)
    _, nstate = _state_layout(bt.m0)
    interval = bt.sps * bt.dt
    for c in starts:
        if c.state.shape != (nstate,) or c.warmstart.shape != (bt.m0.nv,):
            raise ParameterError("start", f"a Checkpoint of this scene's model ({nstate} state values, "
                                 f"{bt.m0.nv} warm-start values)", (c.state.shape, c.warmstart.shape))
        k = c.time_s / interval
        if abs(k - round(k)) > 1e-6 or not 0 <= round(k) < bt.n_samples:
            raise ParameterError("start", f"a Checkpoint at a sample time ({interval:g} s apart) before "
                                 f"duration_s", c.time_s)
    if len({round(c.time_s / interval) for c in starts}) > 1:
        raise ParameterError("start", "checkpoints of one time in a batch", sorted(c.time_s for c in starts))
    return starts


class _WarmRollout:
    """Rolls each scene out in C, its solver warm start carried across calls.

    ``mujoco.rollout`` starts every call's constraint solver from
    ``initial_warmstart`` (zero if not given), while ``mj_step`` starts each
    step from the previous step's accelerations.  Passing each scene's last
    ``qacc_warmstart`` on makes a run rolled out in pieces (chunks, control
    periods) bitwise equal to one ``mj_step`` loop.  The warm start of a
    scene is read from the ``MjData`` that stepped it, so every scene has its
    own; ``nthread > 0`` steps the scenes of a batch on that many threads
    (MuJoCo releases the GIL while it steps).
    """

    def __init__(self, models: Sequence[mujoco.MjModel], nthread: int = 0):
        self.models = list(models)
        self.datas = [mujoco.MjData(m) for m in self.models]
        self.warm = np.zeros((len(self.models), self.models[0].nv))
        self.pool = None
        if nthread > 0 and len(self.models) > 1:
            from concurrent.futures import ThreadPoolExecutor
            self.pool = ThreadPoolExecutor(nthread)
        self.runners = [_rollout.Rollout(nthread=0) for _ in (self.models if self.pool else self.models[:1])]

    def _one(self, b: int, cur, u, st, sd, nstep: int) -> None:
        runner = self.runners[b if self.pool else 0]
        args = (cur[b:b + 1], u[b:b + 1], self.warm[b:b + 1], st[b:b + 1], sd[b:b + 1])
        if u.shape[1] == st.shape[1] == sd.shape[1] == nstep and all(
                a.flags.c_contiguous and a.dtype == np.float64 for a in args):
            # every array already has rollout's exact shape: skip its per-call checks and tiling
            # (~50 us a call, which a closed-loop run pays once per control period); same C call
            runner.rollout([self.models[b]], [self.datas[b]], args[0], args[1], skip_checks=True,
                           nstep=nstep, initial_warmstart=args[2], state=args[3], sensordata=args[4])
        else:
            runner.rollout(self.models[b], self.datas[b], args[0], args[1], nstep=nstep,
                           initial_warmstart=args[2], state=args[3], sensordata=args[4])
        self.warm[b] = self.datas[b].qacc_warmstart

    def rollout(self, cur: np.ndarray, u: np.ndarray, st: np.ndarray, sd: np.ndarray, nstep: int,
                active: np.ndarray | None = None):
        """Step every scene ``nstep`` steps from ``cur`` under controls ``u``, into ``st`` and ``sd``.
        ``active``: a mask of the scenes to step (None: all); the others stay at ``cur`` (their
        sensor rows zero)."""
        idx = range(len(self.models))
        if active is not None:
            idx = np.flatnonzero(active)
            st[~active], sd[~active] = cur[~active, None], 0.0
        if self.pool is None:
            for b in idx:
                self._one(b, cur, u, st, sd, nstep)
        else:
            list(self.pool.map(lambda b: self._one(b, cur, u, st, sd, nstep), idx))
        return st, sd

    def close(self) -> None:
        for r in self.runners:
            r.close()
        if self.pool is not None:
            self.pool.shutdown()


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


def _plan_batch(scenes: Sequence[Scene], options: SimOptions | None, out, controller) -> _Batch:
    """Validate a batch, resolve its time step, compile its scenes and choose its chunk length."""
    options = options or SimOptions()
    if len(scenes) == 0:
        raise ParameterError("scenes", "a non-empty sequence of Scene", scenes)
    requested = options
    resolved = [resolve_options(s, options) for s in scenes]
    if len({o.timestep_s for o in resolved}) > 1:
        raise ParameterError("scenes", "of one time step in a batch (same links and servo, or an "
                             "explicit SimOptions.timestep_s)", sorted({o.timestep_s for o in resolved}))
    options = resolved[0]
    outs = _outs(out, len(scenes))
    push = any(s.forces_N is not None for s in scenes)  # one structure: all or none carry them
    closed = controller is not None or scenes[0].controller.closed_loop
    if closed and any((s.gait, s.controller, s.geometry.n_links) != (scenes[0].gait, scenes[0].controller,
                                                                   scenes[0].geometry.n_links) for s in scenes):
        raise ParameterError("scenes", "of one gait, controller and link count in a closed-loop batch", None)
    compiled = [compile_scene(s, options, push=push, loads=closed) for s in scenes]
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
    return _Batch(compiled, options, requested, outs, ctl, tick, chunk, n_samples)


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
            self.runner = _warp.WarpRollout(bt.compiled, affine, bt.options, bt.options.device)
        else:
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
        nb, m0 = self.bt.nb, self.bt.m0
        return np.empty((nb, k, self.nstate)), np.empty((nb, k, m0.nsensordata)), np.empty((nb, k, m0.nu))

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
        if self.bufs[0].shape[1] != k:  # last, shorter chunk: contiguous buffers of its size
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

    def step_chunk(self, k: int, stepping: np.ndarray) -> list[dict | None]:
        """Step the scenes of mask ``stepping`` one chunk of ``k`` steps (a multiple of the sample
        interval); their sample blocks (None for a scene not stepped: it stays where it is)."""
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
    g = _gathering()
    if g is not None and out is None and controller is None and progress is None and start is None and (
            stop is None or not callable(stop) or len(scenes) == 1):
        return g.submit(list(scenes), options, stop)
    return _simulate_batch_now(scenes, options, nthread=nthread, out=out, controller=controller, stop=stop,
                               progress=progress, start=start)


def _simulate_batch_now(scenes, options, *, nthread=0, out=None, controller=None, stop=None, progress=None,
                        start=None):
    """:func:`simulate_batch` in this call, never gathered."""
    bt = _plan_batch(scenes, options, out, controller)
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


class _Recorders:
    """One recorder per scene of a batch (in memory, or streamed to its ``out`` file) and the stopping
    rule that sees every block recorded (one for the batch, or one per scene)."""

    def __init__(self, bt: _Batch, stop):
        self.bt, self.stop = bt, stop
        self.per_scene = stop is not None and not callable(stop)
        if self.per_scene:
            self.stop = list(stop)
            if len(self.stop) != bt.nb or not all(callable(r) for r in self.stop):
                raise ParameterError("stop", f"a stopping rule, or one per scene ({bt.nb} callables)", stop)
        self.reasons: list[str | None] = [None] * bt.nb
        self.recorders = [_MemoryRecorder() for _ in range(bt.nb)] if bt.outs is None else \
            [_NetCDFRecorder(p_) for p_ in bt.outs]
        self.builders = [functools.partial(_to_dataset, cs, bt.options, record=bt.options.recorded,
                                           timestep_auto=bt.requested.timestep_s is None,
                                           control_rate_hz=None if bt.ctl is None else 1.0 / (bt.tick * bt.dt),
                                           controller_kind=None if bt.ctl is None else bt.ctl.kind)
                         for cs in bt.compiled]

    def rule(self, b: int) -> str:
        """The stopping rule of scene ``b``, as text ("" without one)."""
        r = self.stop[b] if self.per_scene else self.stop
        return "" if r is None else str(getattr(r, "rule", repr(r)))

    def record(self, blocks: list[dict | None]) -> bool:
        """Record one block per scene still stepped (None: a scene that has stopped); whether every
        scene has now stopped (its reason in :attr:`reasons`)."""
        for b, block in enumerate(blocks):
            if block is not None:
                self.recorders[b].add(block) if self.bt.outs is None else self.recorders[b].add(block, self.builders[b])
        if self.stop is None:
            return False
        if not self.per_scene:
            reason = self.stop(blocks)
            self.reasons = [reason] * len(blocks)
            return bool(reason)
        for b, block in enumerate(blocks):
            if block is not None and self.reasons[b] is None:
                self.reasons[b] = self.stop[b]([block]) or None
        return all(r is not None for r in self.reasons)

    def finish(self) -> list[xr.Dataset]:
        """One Dataset per scene (built in memory, or opened from its file)."""
        return [r.finish(self.builders[b]) if self.bt.outs is None else r.finish()
                for b, r in enumerate(self.recorders)]

    def abort(self) -> None:
        """After a failure: remove the files being streamed (nothing to do in memory)."""
        if self.bt.outs is not None:
            for r in self.recorders:
                r.abort()


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
    return simulate_batch([scene], options, out=out, controller=controller, stop=stop, progress=progress,
                          start=start)[0]


def _link_angles(yaw: np.ndarray, joints: np.ndarray, root: int) -> np.ndarray:
    """World orientation of each link's body axis (head->tail), rad.

    ``yaw``: (..., ) orientation of the root link ``root``; ``joints``:
    (..., N-1) -> (..., N).
    """
    c = np.concatenate([np.zeros_like(joints[..., :1]), np.cumsum(joints, axis=-1)], axis=-1)
    return yaw[..., None] + c - c[..., root:root + 1]


def _sample_vars(cs: CompiledScene, t, qpos, sens, fpair, fwall, pen, record, cmd=None, phase=None) -> dict:
    """The recorded variables of a block of samples (leading axis: time) as arrays.

    ``cmd``, ``phase``: the commanded joint angles and gait phases at the samples
    (closed-loop controllers); None: the open-loop gait's."""
    sc, ix = cs.scene, cs.index
    g = sc.geometry
    out = {"time": t}
    rl = root_link(g.n_links)
    xs0, ys0 = sc.initial_x_m() - g.length_m / 2 + root_offset_m(sc), sc.initial_y_m()
    root = qpos[:, ix.qpos_root]  # (T, n, 3): the body's midpoint and root-link orientation, plus the offset
    if sc.hold_x:  # no x joint (Scene.hold_x): the midpoint stays at its initial x
        root = root.copy()
        root[..., 0] = 0.0
    alpha = qpos[:, ix.qpos_joint]  # (T, n, nj)
    theta = _link_angles(root[..., 2], alpha, rl)  # (T, n, N)
    l = g.link_length_m
    # the head tip: back from the root frame (the body's midpoint) along the root link and the head-side links
    cx, cy = np.cos(theta), np.sin(theta)
    a = root_offset_m(sc) - rl * l  # the root frame's distance behind the root link's head end
    rx = root[..., 0] + xs0 - a * cx[..., rl] - l * cx[..., :rl].sum(axis=-1)
    ry = root[..., 1] + ys0 - a * cy[..., rl] - l * cy[..., :rl].sum(axis=-1)
    if "x" in record or "y" in record:
        # centre of mass of equal links = mean of the link midpoints, at the recorded state itself (the
        # subtree-COM sensor would read the state one step earlier)
        hx = rx[..., None] + l * (np.cumsum(cx, axis=-1) - cx / 2)
        hy = ry[..., None] + l * (np.cumsum(cy, axis=-1) - cy / 2)
        out["x"], out["y"] = hx.mean(axis=-1), hy.mean(axis=-1)
    if "heading" in record:
        out["heading"] = theta.mean(axis=-1)
    if "node_x" in record:
        out["node_x"] = np.concatenate([rx[..., None], rx[..., None] + l * np.cumsum(cx, axis=-1)], axis=-1)
    if "node_y" in record:
        out["node_y"] = np.concatenate([ry[..., None], ry[..., None] + l * np.cumsum(cy, axis=-1)], axis=-1)
    if cmd is None:
        cmd = sc.gait.joint_angles(t, sc.phases_rad, g.n_links)
    if phase is None:  # the open-loop gait: psi = 2 pi f t - phi (undulate.control)
        phase = (2 * np.pi * sc.gait.frequency_hz) * np.asarray(t, dtype=float)[:, None] - np.asarray(sc.phases_rad)[None]
    out["joint_angle"], out["joint_command"], out["joint_error"] = alpha, cmd, np.abs(alpha - cmd)
    out["gait_phase"] = phase
    out["contact_force_pair"], out["contact_force_wall"], out["penetration"] = fpair, fwall, pen
    return {k: v for k, v in out.items() if k == "time" or k in record}


def _to_dataset(cs: CompiledScene, options: SimOptions, block: dict, *, record=RECORDABLE,
                timestep_auto: bool = False, control_rate_hz: float | None = None,
                controller_kind: str | None = None) -> xr.Dataset:
    from .provenance import provenance

    sc, ix = cs.scene, cs.index
    g = sc.geometry
    n, nj = sc.n_swimmers, g.n_links - 1
    sps = options.steps_per_sample

    config = {"scene": sc.to_dict(), "options": options.to_dict(), "timestep_auto": timestep_auto}
    ds = xr.Dataset(
        {name: variable(name, block[name]) for name in RECORDABLE if name in record},
        coords={
            "time": ("time", block["time"], {"units": "s", "long_name": "time"}),
            "swimmer": ("swimmer", np.arange(n)),
            "joint": ("joint", np.arange(nj)),
            "node": ("node", np.arange(g.n_links + 1)),
            "pair": ("pair", np.arange(max(0, n - 1))),
            "wall": ("wall", list(ix.wall_names)),
            "phase": ("swimmer", np.asarray(sc.phases_rad), {"units": "rad", "long_name": "gait phase phi"}),
        },
        attrs={
            "title": "undulate simulation",
            **scene_attrs(sc),
            "timestep": options.timestep_s,
            "timestep_units": "s",
            "timestep_source": "auto (undulate.scene.auto_timestep)" if timestep_auto else "explicit",
            "sample_interval": sps * options.timestep_s,
            "controller": controller_kind or cs.scene.controller.kind,
            "control_rate": control_rate_hz if control_rate_hz is not None else 0.0,
            "control_rate_units": "Hz (0: open loop, set-points at every step)",
            "conventions": "heads toward -x; body wave travels +x; dx = x_upper - x_lower, "
                           "dphi = phi_upper - phi_lower; compatibility dx = lambda dphi / 2pi",
            "config": json.dumps(config),
            **backend_attrs(options),
            **{f"provenance_{k}": v for k, v in provenance().items()},
        },
    )
    return ds


class _NoStop:
    """The stopping rule of a scene that has none, in a gathered batch (it never ends a run)."""

    rule = ""

    def __call__(self, blocks):
        return None


class _Request:
    def __init__(self, scenes, options, stop):
        self.scenes, self.options, self.stop = scenes, options, stop
        self.result = self.error = None
        self.done = False
        self.physics = (0.0, 0)

    def rules(self) -> list:
        if self.stop is None:
            return [_NoStop() for _ in self.scenes]
        return [self.stop] if callable(self.stop) else list(self.stop)


class Gather:
    """Runs the simulations of several threads as one batch: every thread's
    :func:`simulate_batch` call waits until each live thread has either called it or finished,
    then the calls are stepped together, one batch per structure and options (on the Warp
    backend: one world per scene).  Each call returns its own Datasets, each bitwise what the
    same batch would give (:func:`simulate_batch`: a scene's run does not depend on the others,
    on the MuJoCo backend bitwise, on Warp to float32 rounding of the solver's reductions).

    Used by the sweep runner for the Warp backend (:func:`undulate.sweep.run_sweep`): a study's
    runs, each in its own thread, reach the GPU together.  Calls with ``out``, ``controller``,
    ``progress`` or ``start`` run at once, alone.  If a gathered batch fails (one scene diverges),
    its calls are run again one at a time so that only the failing one raises."""

    def __init__(self, n_threads: int):
        import threading

        self.live = int(n_threads)
        self.pending: list[_Request] = []
        self.cond = threading.Condition()
        self.batches: list[int] = []  # scenes per batch stepped (for reports and tests)

    def submit(self, scenes, options, stop) -> list[xr.Dataset]:
        req = _Request(scenes, options or SimOptions(), stop)
        with self.cond:
            self.pending.append(req)
            if len(self.pending) < self.live:
                while not req.done:
                    self.cond.wait()
                flush = None
            else:
                flush, self.pending = self.pending, []
        if flush is not None:
            self._run(flush)
        if req.error is not None:
            raise req.error
        _physics.report(*req.physics)
        return req.result

    def thread_done(self) -> None:
        """A thread leaves: its calls are all made (call once per thread, also when it raised)."""
        with self.cond:
            self.live -= 1
            flush = None
            if self.pending and len(self.pending) >= self.live:
                flush, self.pending = self.pending, []
        if flush is not None:
            self._run(flush)

    def _run(self, reqs: list[_Request]) -> None:
        import contextvars

        try:
            for group in _gather_groups(reqs):
                scenes = [sc for r in group for sc in r.scenes]
                rules = [rule for r in group for rule in r.rules()]
                self.batches.append(len(scenes))
                try:
                    with _physics.meter() as tally:  # this batch's physics, shared among its calls
                        dss = contextvars.Context().run(_simulate_batch_now, scenes, group[0].options, stop=rules)
                except Exception:  # noqa: BLE001 - isolate the failing call
                    for r in group:
                        try:
                            with _physics.meter() as tally:
                                r.result = contextvars.Context().run(_simulate_batch_now, r.scenes, r.options,
                                                                     stop=r.stop)
                            r.physics = tally.read()
                        except Exception as e:  # noqa: BLE001
                            r.error = e
                    continue
                sec, steps = tally.read()
                i = 0
                for r in group:
                    n = len(r.scenes)
                    r.result, i = dss[i:i + n], i + n
                    r.physics = (sec * n / len(scenes), steps * n // len(scenes))
        except BaseException as e:  # noqa: BLE001 - every waiting thread must learn of it
            for r in reqs:
                if r.result is None and r.error is None:
                    r.error = e
        finally:
            with self.cond:
                for r in reqs:
                    r.done = True
                self.cond.notify_all()


def _gather_groups(reqs: list[_Request]) -> list[list[_Request]]:
    """Calls that can be stepped as one batch: same resolved options and one structure (the
    compiled models' sizes), and for closed-loop scenes one gait, controller and link count."""
    keys = []
    for r in reqs:
        opts = [resolve_options(sc, r.options) for sc in r.scenes]
        o = opts[0]
        cs = compile_scene(r.scenes[0], o, push=any(sc.forces_N is not None for sc in r.scenes))
        m = cs.model
        closed = r.scenes[0].controller.closed_loop
        keys.append((json.dumps(o.to_dict(), sort_keys=True, default=str), len({x.timestep_s for x in opts}) == 1,
                     (m.nq, m.nv, m.nu, m.na, m.nsensordata, m.ngeom), r.scenes[0].forces_N is not None,
                     repr((r.scenes[0].gait, r.scenes[0].controller, r.scenes[0].geometry.n_links)) if closed else ""))
    out = []
    for key in dict.fromkeys(keys):
        group = [r for r, k in zip(reqs, keys) if k == key]
        if not key[1]:  # a call whose own scenes need different time steps: alone (it raises there)
            out += [[r] for r in group]
        else:
            out.append(group)
    return out



def _gathering() -> "Gather | None":
    import threading

    return getattr(threading.current_thread(), "undulate_gather", None)
