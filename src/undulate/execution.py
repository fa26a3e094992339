"""How runs are executed: one frozen settings object, :class:`Execution`, and the policy of where runs go.

A study says what it measures; the caller says how it is run (the anchor: mujoco_warp's
``put_model`` / ``put_data`` / ``step``, where the caller says what runs where).  The command line and
the Python API build one :class:`Execution` and pass it down to :func:`undulate.reproduce.reproduce`,
:func:`undulate.studies.run_study` and :func:`undulate.sweep.run_sweep` (``execution=``); their
``workers=`` and ``scheduler=`` keywords are a shorthand that builds one.  Worker processes (a local
pool's, Dask's) receive the settings with each task and step under them (:func:`using`).

Settings left out come from the environment, which this module alone reads
(:meth:`Execution.from_environment`).  Every variable it reads:

| Python name          | environment variable              | CLI option      |
|----------------------|-----------------------------------|-----------------|
| ``backend``          | ``UNDULATE_BACKEND``              | ``--backend``   |
| ``device``           | ``UNDULATE_DEVICE``               | ``--device``    |
| ``workers``          | ``UNDULATE_WORKERS``              | ``--workers``   |
| ``scheduler``        | ``UNDULATE_SCHEDULER``            | ``--scheduler`` |
| ``warp_processes``   | ``UNDULATE_WARP_PROCESSES``       | -               |
| ``lone_swimmers``    | ``UNDULATE_WARP_LONE_SWIMMERS``   | -               |
| ``cores_up_to``      | ``UNDULATE_WARP_CORES_UP_TO``     | -               |
| ``prefetch``         | ``UNDULATE_WARP_PREFETCH``        | -               |
| ``reduce_on_device`` | ``UNDULATE_WARP_REDUCE``          | -               |
| ``deterministic``    | ``UNDULATE_WARP_DETERMINISTIC``   | -               |
| ``steps_per_graph``  | ``UNDULATE_WARP_STEPS_PER_GRAPH`` | -               |
| ``compile_workers``  | ``UNDULATE_WARP_COMPILE_WORKERS`` | -               |
| ``streams``          | ``UNDULATE_WARP_STREAMS``         | -               |
| ``timeline``         | ``UNDULATE_WARP_TIMELINE``        | -               |
| ``stats_file``       | ``UNDULATE_WARP_STATS``           | -               |

(:data:`SETTINGS` holds each one's meaning; docs/guide/execution.md explains them.)  Integers are
decimal, switches ``1`` or ``0``; an empty variable is unset; a bad value is a
:class:`~undulate.errors.ParameterError` naming the variable.  None in a field means "by the policy
below" (most Warp defaults depend on the device).  Process setup that is not a setting also lives
here: ``MUJOCO_GL`` (:func:`headless_mujoco`) and OpenCV's FFmpeg log level (:func:`quiet_opencv_ffmpeg`).

The policy of where runs go, with its reasons: lone swimmers and small batches asked of Warp on the
cores (:func:`lone_swimmers_engine`, :func:`cores_up_to`, :func:`engine_for`), prefetching
(:func:`prefetch`), process counts (:func:`usable_cpus`, :func:`local_workers`,
:func:`warp_processes`), width (:func:`runs_wide`), the serial threshold (:func:`runs_here`), runs
made ahead (:func:`runs_ahead`) and studies side by side (:func:`studies_side_by_side`).  None of it
changes a result: every run's result is a function of its parameters and seed on its engine, and each
Dataset says which engine stepped it (attrs ``engine``, ``engine_requested``).
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .errors import ParameterError

__all__ = ["Execution", "SETTINGS", "current", "using", "settings", "carry_into", "in_effect", "usable_cpus", "check_workers", "check_scheduler",
           "is_cpu_device", "memory_available_bytes", "local_workers", "warp_processes", "lone_swimmers_engine", "cores_up_to", "engine_for",
           "prefetch", "runs_here", "runs_wide", "runs_ahead", "studies_side_by_side", "substitution_note",
           "headless_mujoco", "quiet_opencv_ffmpeg", "BACKENDS", "DEVICES", "MAX_WORKERS_PER_CORE",
           "WARP_PROCESSES_MAX", "SERIAL_BELOW", "WIDE_WORKERS", "SIDE_BY_SIDE"]

BACKENDS = ("mujoco", "warp")
"""The engines (:attr:`undulate.params.SimOptions.BACKENDS`)."""
DEVICES = ("cuda", "cpu")
"""Warp's devices as a setting names them (:attr:`undulate.params.SimOptions.device`)."""
MAX_WORKERS_PER_CORE = 4
"""Local worker processes allowed a core: each is a process with its own interpreter and MuJoCo (~0.2 GB),
and past a few a core they only queue for the cores (``--workers 100000`` would start as many processes
as a sweep has runs)."""
WARP_PROCESSES_MAX = 256
"""Most processes a Warp sweep's host work may be split over (:func:`warp_processes`)."""
STEPS_PER_GRAPH_MAX = 1000
"""Most steps in one captured Warp graph (:attr:`Execution.steps_per_graph`)."""
COUNT_MAX = 10**6
"""Largest value of an integer setting without a bound of its own."""


@dataclass(frozen=True)
class Setting:
    """One row of :data:`SETTINGS`: a field of :class:`Execution`, its environment variable, its command-line
    option (None: environment only) and what it means."""

    name: str
    env: str
    cli: str | None
    meaning: str


SETTINGS = (
    Setting("backend", "UNDULATE_BACKEND", "--backend",
            "The engine: `mujoco` (MuJoCo's C engine, float64; default) or `warp` (MuJoCo Warp, float32)."),
    Setting("device", "UNDULATE_DEVICE", "--device",
            "Warp's device: `cuda` or `cpu` (default: `cuda` where there is one). Only with `warp`."),
    Setting("workers", "UNDULATE_WORKERS", "--workers",
            "Local worker processes (default: every core this process may use); 1 runs in this process."),
    Setting("scheduler", "UNDULATE_SCHEDULER", "--scheduler",
            "A Dask scheduler `tcp://HOST:PORT` or scheduler file (default: local processes)."),
    Setting("warp_processes", "UNDULATE_WARP_PROCESSES", None,
            "Processes a Warp sweep's host work is split over (1 to 256; default 1)."),
    Setting("lone_swimmers", "UNDULATE_WARP_LONE_SWIMMERS", None,
            "Engine of one-swimmer scenes asked of Warp (default: `mujoco` on a GPU, `warp` on Warp's CPU device)."),
    Setting("cores_up_to", "UNDULATE_WARP_CORES_UP_TO", None,
            "Largest batch asked of Warp that steps on the cores (0: none; default: the cores on a GPU, 0 on CPU)."),
    Setting("prefetch", "UNDULATE_WARP_PREFETCH", None,
            "A Warp study steps its last stage's runs before its first look (1/0; default: on a GPU)."),
    Setting("reduce_on_device", "UNDULATE_WARP_REDUCE", None,
            "Open-loop Warp chunks reduced to samples on the device (1/0; default 1)."),
    Setting("deterministic", "UNDULATE_WARP_DETERMINISTIC", None,
            "MuJoCo Warp's determinism (1/0; default: on Warp's CPU device, off on a GPU)."),
    Setting("steps_per_graph", "UNDULATE_WARP_STEPS_PER_GRAPH", None,
            "Steps in one captured Warp graph (1 to 1000; default 16 on a GPU, 1 on CPU)."),
    Setting("compile_workers", "UNDULATE_WARP_COMPILE_WORKERS", None,
            "Threads compiling a Warp model's kernels at once (default: the CPUs this process may use)."),
    Setting("streams", "UNDULATE_WARP_STREAMS", None,
            "Each Warp model on its own CUDA stream (1/0; default 1)."),
    Setting("timeline", "UNDULATE_WARP_TIMELINE", None,
            "File each Warp model appends its chunks' timing to, as JSON lines (default: none)."),
    Setting("stats_file", "UNDULATE_WARP_STATS", None,
            "File each Warp model appends its first step's time to, as JSON lines (default: none)."),
)
"""Every setting of :class:`Execution`: its field, environment variable, CLI option and meaning
(the table of the README and docs/guide/execution.md)."""


def usable_cpus() -> int:
    """The CPUs this process may use (its affinity where the platform has one)."""
    if hasattr(os, "process_cpu_count"):  # Python >= 3.13
        return os.process_cpu_count() or 1
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - macOS, Windows
        return os.cpu_count() or 1


def memory_available_bytes() -> int:
    """The memory this machine has available now, bytes (``MemAvailable`` of ``/proc/meminfo``, else the
    free pages): what a recording or a GIF held in memory must fit in."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def is_cpu_device(device: str | None) -> bool:
    """Whether ``device`` (``cpu``, ``cuda``, ``cuda:1``...) is Warp's CPU device."""
    return str(device or "").split(":")[0] == "cpu"


def check_workers(workers: Any, scheduler: Any = None) -> None:
    """``workers`` is None (every core) or an integer from 1 to :data:`MAX_WORKERS_PER_CORE` a core this
    process may use, and left out when a Dask ``scheduler`` is given; else a :class:`ParameterError`
    naming ``workers``."""
    if workers is None:
        return
    cap = MAX_WORKERS_PER_CORE * usable_cpus()
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= cap:
        raise ParameterError("workers", f"an integer in [1, {cap}] ({MAX_WORKERS_PER_CORE} a core of the "
                             f"{usable_cpus()} this process may use), or None: every core", workers)
    if scheduler is not None:
        raise ParameterError("workers", "left out when a Dask scheduler is given (the cluster sets the workers)",
                             workers)


def check_scheduler(scheduler: Any) -> str:
    """What ``scheduler`` is, without connecting: ``"client"`` (an existing ``distributed.Client``),
    ``"file"`` (the path of a scheduler file) or ``"address"`` (a string with a port, any address Dask
    accepts); anything else is a :class:`ParameterError`, raised before a study or reproduction writes."""
    try:
        import distributed
    except ImportError:
        raise ParameterError(
            "scheduler", "usable only with Dask installed: pip install 'undulate[dask]'", scheduler
        ) from None
    if isinstance(scheduler, distributed.Client):
        return "client"
    if isinstance(scheduler, str | os.PathLike):
        if Path(scheduler).expanduser().is_file():
            return "file"
        if isinstance(scheduler, str) and ":" in scheduler:
            return "address"
    raise ParameterError(
        "scheduler",
        "a Dask scheduler address tcp://HOST:PORT, the path of an existing scheduler file, or a distributed.Client",
        scheduler,
    )


def _count(name: str, value: Any, least: int, most: int) -> None:
    if value is not None and (isinstance(value, bool) or not isinstance(value, int) or not least <= value <= most):
        raise ParameterError(name, f"an integer from {least} to {most}, or None (by the device)", value)


def _switch(name: str, value: Any, optional: bool) -> None:
    if not (isinstance(value, bool) or (optional and value is None)):
        raise ParameterError(name, "True or False" + (", or None (by the device)" if optional else ""), value)


def _path(name: str, value: Any) -> None:
    if value is not None and (isinstance(value, bytes) or not isinstance(value, str | os.PathLike) or not str(value)):
        raise ParameterError(name, "a file's path, or None (none written)", value)


@dataclass(frozen=True)
class Execution:
    """How runs are executed (never what they compute): the engine and device, where the work goes,
    and the Warp backend's switches.  Frozen and validated; None in a Warp field means "by the policy
    for the device" (:func:`lone_swimmers_engine` ...).  The module's table names each field's
    environment variable and command-line option.

    >>> Execution(backend="warp", device="cpu", workers=2).backend
    'warp'
    """

    backend: str = "mujoco"
    """The engine every run that leaves it out steps on (:data:`BACKENDS`)."""
    device: str | None = None
    """Warp's device (:data:`DEVICES`; None: ``cuda`` where there is one); left out with ``mujoco``."""
    workers: int | None = None
    """Local worker processes (None: every core this process may use; 1: this process)."""
    scheduler: Any = None
    """A Dask scheduler: ``tcp://HOST:PORT``, a scheduler file's path, or a ``distributed.Client``."""
    warp_processes: int | None = None
    """Processes a Warp sweep's host work is split over (:func:`warp_processes`; None: 1)."""
    lone_swimmers: str | None = None
    """Engine of one-swimmer scenes asked of Warp (:func:`lone_swimmers_engine`; None: by device)."""
    cores_up_to: int | None = None
    """Largest batch asked of Warp that steps on the cores (:func:`cores_up_to`; None: by device)."""
    prefetch: bool | None = None
    """Whether a Warp study steps its last stage first (:func:`prefetch`; None: by device)."""
    reduce_on_device: bool = True
    """Open-loop Warp chunks reduced to samples on the device (closed loop: every step comes back)."""
    deterministic: bool | None = None
    """MuJoCo Warp's determinism (None: on Warp's CPU device, off on a GPU)."""
    steps_per_graph: int | None = None
    """Steps in one captured Warp graph (None: 16 on a GPU, 1 on Warp's CPU device)."""
    compile_workers: int | None = None
    """Threads compiling a Warp model's kernels at once (None: the CPUs this process may use)."""
    streams: bool = True
    """Each Warp model on its own CUDA stream (False: the device's current stream)."""
    timeline: str | None = None
    """File each Warp model appends its chunks' timing to (JSON lines; None: none)."""
    stats_file: str | None = None
    """File each Warp model appends its first step's time to (JSON lines; None: none)."""

    def __post_init__(self):
        if self.backend not in BACKENDS:
            raise ParameterError("backend", "'mujoco' or 'warp'", self.backend)
        if self.device not in (None, *DEVICES):
            raise ParameterError("device", "'cuda' or 'cpu' (or None: the default)", self.device)
        if self.device is not None and self.backend == "mujoco":
            raise ParameterError("device", "left out with backend 'mujoco' (it steps on the CPU)", self.device)
        check_workers(self.workers, self.scheduler)
        if self.scheduler is not None:  # its form now, before anything is written (a connection at the first sweep)
            check_scheduler(self.scheduler)
        _count("warp_processes", self.warp_processes, 1, WARP_PROCESSES_MAX)
        if self.lone_swimmers not in (None, *BACKENDS):
            raise ParameterError("lone_swimmers", "'mujoco' or 'warp', or None (by the device)", self.lone_swimmers)
        _count("cores_up_to", self.cores_up_to, 0, COUNT_MAX)
        _switch("prefetch", self.prefetch, True)
        _switch("reduce_on_device", self.reduce_on_device, False)
        _switch("deterministic", self.deterministic, True)
        _count("steps_per_graph", self.steps_per_graph, 1, STEPS_PER_GRAPH_MAX)
        _count("compile_workers", self.compile_workers, 1, COUNT_MAX)
        _switch("streams", self.streams, False)
        for name in ("timeline", "stats_file"):
            _path(name, getattr(self, name))
            if getattr(self, name) is not None:
                object.__setattr__(self, name, str(getattr(self, name)))

    def replace(self, **changes: Any) -> Execution:
        """A copy with ``changes`` (validated as a new one)."""
        return dataclasses.replace(self, **changes)

    def for_workers(self) -> Execution:
        """The settings a worker process steps under: these, without ``workers`` and ``scheduler``
        (a worker runs its task itself, and a ``distributed.Client`` does not travel)."""
        return self if self.workers is None and self.scheduler is None else self.replace(workers=None, scheduler=None)

    @classmethod
    def from_environment(cls, environ: Mapping[str, str] | None = None) -> Execution:
        """The settings the environment holds (``environ``, default ``os.environ``): every variable of
        :data:`SETTINGS`, unset or empty ones at their default.  ``UNDULATE_DEVICE`` is read only with
        ``UNDULATE_BACKEND=warp`` (MuJoCo steps on the CPU).  A bad value is a ParameterError naming
        the variable.  The one place the package reads these variables."""
        env = os.environ if environ is None else environ
        raw = {s.name: (env.get(s.env) or None) for s in SETTINGS}
        var = {s.name: s.env for s in SETTINGS}
        got: dict[str, Any] = {}
        if raw["backend"] is not None:
            if raw["backend"] not in BACKENDS:
                raise ParameterError(var["backend"], "'mujoco' or 'warp' (environment variable)", raw["backend"])
            got["backend"] = raw["backend"]
        if got.get("backend") == "warp" and raw["device"] is not None:
            if raw["device"] not in DEVICES:
                raise ParameterError(var["device"], "'cuda' or 'cpu' (environment variable)", raw["device"])
            got["device"] = raw["device"]
        for name, least, most in (("workers", 1, MAX_WORKERS_PER_CORE * usable_cpus()),
                                  ("warp_processes", 1, WARP_PROCESSES_MAX), ("cores_up_to", 0, COUNT_MAX),
                                  ("steps_per_graph", 1, STEPS_PER_GRAPH_MAX), ("compile_workers", 1, COUNT_MAX)):
            if raw[name] is not None:
                try:
                    n = int(raw[name])
                except ValueError:
                    n = least - 1
                if not least <= n <= most:
                    raise ParameterError(var[name], f"an integer from {least} to {most}", raw[name])
                got[name] = n
        for name in ("prefetch", "reduce_on_device", "deterministic", "streams"):
            if raw[name] is not None:
                if raw[name] not in ("0", "1"):
                    raise ParameterError(var[name], "'1' or '0' (environment variable)", raw[name])
                got[name] = raw[name] == "1"
        if raw["lone_swimmers"] is not None:
            if raw["lone_swimmers"] not in BACKENDS:
                raise ParameterError(var["lone_swimmers"], "'mujoco' or 'warp' (environment variable)",
                                     raw["lone_swimmers"])
            got["lone_swimmers"] = raw["lone_swimmers"]
        for name in ("scheduler", "timeline", "stats_file"):
            if raw[name] is not None:
                got[name] = raw[name]
        if "workers" in got and "scheduler" in got:
            raise ParameterError(var["workers"], f"unset when {var['scheduler']} is set (the cluster sets the "
                                 "workers)", raw["workers"])
        try:
            return cls(**got)
        except ParameterError as e:  # named as the environment names it
            raise ParameterError(var.get(e.name, e.name), f"{e.allowed} (environment variable)", e.got) from None

    def to_environment(self) -> dict[str, str]:
        """The environment variables that rebuild these settings (:meth:`from_environment`): one for
        each field not at its default.  A ``distributed.Client`` scheduler has none (a
        ParameterError)."""
        out: dict[str, str] = {}
        defaults = Execution()
        for s in SETTINGS:
            value = getattr(self, s.name)
            if value == getattr(defaults, s.name) and s.name != "scheduler" or value is None:
                continue
            if s.name == "scheduler" and not isinstance(value, str | os.PathLike):
                raise ParameterError("scheduler", "an address or a scheduler file's path to travel in the "
                                     "environment (a distributed.Client does not)", value)
            out[s.env] = ("1" if value else "0") if isinstance(value, bool) else str(value)
        return out

    def export(self) -> None:
        """Make these settings this process's default and its future child processes' (they inherit the
        environment): every variable of :data:`SETTINGS` set as :meth:`to_environment` says, the others
        removed.  :func:`undulate.simulation.use_backend` is this for the engine and device."""
        env = self.to_environment()
        for s in SETTINGS:
            if s.env in env:
                os.environ[s.env] = env[s.env]
            else:
                os.environ.pop(s.env, None)


_CURRENT: contextvars.ContextVar[Execution | None] = contextvars.ContextVar("undulate_execution", default=None)


def current() -> Execution:
    """The settings in effect here: the innermost :func:`using` of this context, else the
    environment's (:meth:`Execution.from_environment`, read again at each call)."""
    ex = _CURRENT.get()
    return ex if ex is not None else Execution.from_environment()


@contextlib.contextmanager
def using(execution: Execution | None) -> Iterator[Execution]:
    """Inside this block (this thread, and the threads started in a copy of its context), runs that
    leave the engine out step as ``execution`` says (None: as the settings in effect already)."""
    if execution is None:
        yield current()
        return
    if not isinstance(execution, Execution):
        raise ParameterError("execution", "an undulate.execution.Execution, or None", execution)
    token = _CURRENT.set(execution)
    try:
        yield execution
    finally:
        _CURRENT.reset(token)


def settings(execution: Execution | None = None, *, workers: Any = None, scheduler: Any = None) -> Execution:
    """The settings a call runs under: ``execution`` (then ``workers`` and ``scheduler`` are left out:
    they are its fields), else the settings in effect (:func:`current`) with the ``workers`` or
    ``scheduler`` given here in place of theirs (the keywords of :func:`undulate.sweep.run_sweep`,
    :func:`undulate.studies.run_study` and :func:`undulate.reproduce.reproduce`)."""
    if execution is not None:
        if not isinstance(execution, Execution):
            raise ParameterError("execution", "an undulate.execution.Execution, or None", execution)
        for name, value in (("workers", workers), ("scheduler", scheduler)):
            if value is not None:
                raise ParameterError(name, "left out when execution= is given (set it there)", value)
        return execution
    ex = current()
    if workers is None and scheduler is None:
        return ex
    check_workers(workers, scheduler)
    return ex.replace(workers=workers, scheduler=scheduler)


def carry_into(context: contextvars.Context) -> None:
    """Set in ``context`` (a fresh one, e.g. a gathered batch's) the settings a :func:`using` block set
    here, if any: runs there step as they would here."""
    ex = _CURRENT.get()
    if ex is not None:
        context.run(_CURRENT.set, ex)


def in_effect() -> Execution | None:
    """The settings a :func:`using` block set in this context (None: none; the environment's apply)."""
    return _CURRENT.get()


# ------------------------------------------------------------------ where runs go
def local_workers(execution: Execution | None = None) -> int:
    """Local worker processes a sweep may use: ``execution.workers``, else every core this process may use."""
    ex = execution or current()
    return ex.workers or usable_cpus()


def warp_processes(execution: Execution | None = None) -> int:
    """Processes a sweep on the Warp backend splits its runs over: ``warp_processes``
    (1 to :data:`WARP_PROCESSES_MAX`; default 1, every run of a task in this process).  Each process
    steps its share as the worlds of one batch on the same device, and does its share of the host's
    work (models, control tables, Datasets, run files), which on a GPU is most of a large sweep's time
    (docs/gpu.md, "The host's share of a sweep"); more processes are not yet measured on a GPU."""
    ex = execution or current()
    return ex.warp_processes or 1


def lone_swimmers_engine(device: str | None, execution: Execution | None = None) -> str:
    """The engine that steps a scene of one swimmer when the Warp backend is asked for on ``device``:
    ``lone_swimmers`` (``mujoco`` or ``warp``), else ``mujoco`` on a GPU and ``warp`` on Warp's CPU device.

    Why a GPU hands lone swimmers to the cores: a lone swimmer touches nothing but the channel
    walls, and its batches are small (a study's free swimmers, 1-36 at a time), where a GPU step
    costs the same ~0.32 ms as a model of a thousand worlds (on an H200) and one core steps a
    9-link swimmer in ~14 us (MuJoCo on a 2-core VM).  The free swimmers are also the reproduction's
    longest chain of steps that must follow one another (sensitivity's equal-A search: up to three
    30 s runs in turn).  Such runs step on MuJoCo (float64, the MuJoCo backend's results bitwise), and
    their Datasets say so (attrs ``engine``, ``engine_requested``); a sweep's identity records the rule
    (:func:`undulate.sweep.backend_identity`), so runs of one rule are never served for the other.  On
    Warp's CPU device nothing is gained, and the tests step lone swimmers on Warp there."""
    ex = execution or current()
    if ex.lone_swimmers is not None:
        return ex.lone_swimmers
    return "warp" if is_cpu_device(device) else "mujoco"


def cores_up_to(device: str | None, execution: Execution | None = None) -> int:
    """The most scenes a batch asked of the Warp backend on ``device`` may have and still step on the
    cores (MuJoCo, one scene per core): ``cores_up_to`` (0: every batch on Warp), else on a GPU the
    cores this process may use and on Warp's CPU device 0.

    Why on a GPU: a step of a small Warp model costs about the same whatever its worlds, ~0.35 ms for
    pairs and ~1.5 ms for 3-12 jammed packs in a quick reproduction on an H200, where one
    core steps a pair in ~23 us and a pack in ~0.7 ms (that machine's cores, ../shared/GPU.md).  Up to
    one scene per core, the cores step every scene 2x (packs) to 15x (pairs) faster than the device
    steps the batch, and a quick reproduction's longest chains are such batches stepped one after
    another (the links study's one-world looks: 7 x 19 500 steps, ~67 s of a 466 s run; the packing
    study's five looks of 3-12 packs).  Wide batches (sweeps of hundreds or thousands of runs) stay
    on the device, where it wins.  Such runs are the MuJoCo backend's (float64, bitwise) and their
    Datasets say so (attrs ``engine``, ``engine_requested``); a sweep's identity records the rule, so
    runs of one rule are never served for another.  On Warp's CPU device nothing is gained, and the
    tests step every batch on Warp there."""
    ex = execution or current()
    if ex.cores_up_to is not None:
        return ex.cores_up_to
    return 0 if is_cpu_device(device) else usable_cpus()


def engine_for(backend: str, device: str | None, *, n_scenes: int | None = None, n_swimmers: int | None = None,
               execution: Execution | None = None) -> tuple[str, str | None]:
    """The engine that steps a batch of ``n_scenes`` scenes or a scene of ``n_swimmers`` swimmers asked
    of ``backend`` on ``device``, and why it is another (None: it is the one asked): on the Warp
    backend a scene of one swimmer (:func:`lone_swimmers_engine`) and a batch of at most
    :func:`cores_up_to` scenes step on MuJoCo."""
    if backend != "warp":
        return backend, None
    if n_swimmers == 1 and lone_swimmers_engine(device, execution) == "mujoco":
        return "mujoco", "a lone swimmer (lone_swimmers)"
    if n_scenes is not None and n_scenes <= cores_up_to(device, execution):
        return "mujoco", f"a batch of at most {cores_up_to(device, execution)} scenes (cores_up_to)"
    return backend, None


def substitution_note(execution: Execution | None = None, device: str | None = None) -> str | None:
    """One line saying which runs asked of the Warp backend step on MuJoCo under ``execution`` on
    ``device`` (resolved), or None where none do (the MuJoCo backend; Warp's CPU device by default)."""
    ex = execution or current()
    if ex.backend != "warp":
        return None
    lone = lone_swimmers_engine(device, ex) == "mujoco"
    small = cores_up_to(device, ex)
    parts = (["scenes of one swimmer"] if lone else []) + ([f"batches of up to {small} scenes"] if small else [])
    if not parts:
        return None
    return (f"asked of warp on {device or 'the default device'}, {' and '.join(parts)} step on mujoco "
            "(float64; each run's Dataset says so: attrs engine, engine_requested)")


def prefetch(device: str | None, execution: Execution | None = None) -> bool:
    """Whether a study on the Warp backend on ``device`` (resolved: ``cuda`` or ``cpu``; None only
    where ``prefetch`` is set) steps its last stage's runs before its first look: ``prefetch``, else on
    a GPU and not on Warp's CPU device.  False on the MuJoCo backend.

    Why by device: on a GPU a step costs about the same for one world as for hundreds (an H200: ~0.32 ms
    for one world, 0.34 ms for 1 024), so stepping every stage's runs at once costs about
    the first look's time and spares the later looks' chains of steps.  On Warp's CPU device each world
    costs its own steps, so the runs no look reads are time lost: full mode's packing study would step
    its last stage's 182 jammed packs where its first look, which decides on the MuJoCo backend, reads
    28.  The looks and verdicts are the staged plan's either way (:mod:`tests.test_staged_verdicts`)."""
    ex = execution or current()
    if ex.backend != "warp":
        return False
    if ex.prefetch is not None:
        return ex.prefetch
    if device is None:
        raise ParameterError("device", "Warp's device, resolved ('cuda' or 'cpu'), where prefetch is not set", device)
    return not is_cpu_device(device)


SERIAL_BELOW = 4
"""Sweeps of fewer runs than this run in this process (starting worker processes costs more), unless
the warm pool's processes are up already (a reproduction's or a study's later sweeps): then a sweep of
2 or 3 runs steps them side by side there.  (Run here one after another, the packing study's third
bisection look, 3 jammed packs, took 14.3 s on the chain of the study that ended a 16-core quick
reproduction.)"""


def runs_here(n_runs: int, pool_warm: bool, execution: Execution | None = None) -> bool:
    """Whether a study's sweep of ``n_runs`` runs runs in this process (:data:`SERIAL_BELOW`), given
    whether the warm pool's processes are up (``pool_warm``); never with a Dask scheduler."""
    ex = execution or current()
    return ex.scheduler is None and n_runs < SERIAL_BELOW and not (n_runs > 1 and pool_warm)


WIDE_WORKERS = 8
"""Local worker processes from which a study's independent calls run side by side and a reproduction
runs every study at once, with explaining studies' runs made ahead.  On 2 cores the quick
reproduction, two studies at a time, keeps the cores 94-97 % busy: its time is its work, and running
more at once only adds runs made ahead.  On 16 cores (an H100 machine) the same schedule took 70.5 s
for ~345 core-s of work, the cores ~30 % busy: its time was its chain of sequential stages.  8 is a
judgement between those two measurements, not a measured crossover (docs/performance.md)."""


def runs_wide(execution: Execution | None = None) -> bool:
    """Whether a study or reproduction runs wide (:data:`WIDE_WORKERS`): on the Warp backend (a device
    step costs about the same for one world as for hundreds), or on at least ``WIDE_WORKERS`` local
    worker processes.  Not with a Dask scheduler (its size is the cluster's, unknown here).  Results
    never depend on it."""
    ex = execution or current()
    if ex.backend == "warp":
        return True
    if ex.scheduler is not None:
        return False
    return local_workers(ex) >= WIDE_WORKERS


def runs_ahead(execution: Execution | None = None) -> bool:
    """Whether a reproduction's explaining studies make their runs ahead, beside the studies they
    explain: where it runs wide (:func:`runs_wide`), whose time is its chain of sequential steps, not its
    work."""
    return runs_wide(execution)


SIDE_BY_SIDE = 2
"""How many studies a reproduction runs at once where it does not run wide (threads sharing one pool
of worker processes): while one study summarises, judges and draws (in this process), the other's runs
keep the workers busy."""


def studies_side_by_side(n_studies: int, execution: Execution | None = None) -> int:
    """Studies a reproduction of ``n_studies`` runs at once: every one (and its animations) where it runs
    wide (:func:`runs_wide`), else :data:`SIDE_BY_SIDE`."""
    return n_studies + 1 if runs_wide(execution) else SIDE_BY_SIDE


# ------------------------------------------------------------------ process setup
def headless_mujoco() -> None:
    """``MUJOCO_GL=disable`` for this process and the worker processes it starts (they inherit it),
    where the user has not chosen an OpenGL backend; call it before ``import mujoco``.

    No command draws with MuJoCo's OpenGL (figures and films are matplotlib's, test videos OpenCV's),
    but ``import mujoco`` with ``MUJOCO_GL`` unset loads glfw, whose library search starts a
    ``python -c`` child that reads a path on stdin and prints the library's version on stdout, its
    stderr the command's own.  Ctrl-C or a worker stopped while one ran left that child's traceback
    after the command's last line ("File "<string>", line 36: BrokenPipeError", or line 28:
    EOFError; once in ~40 Ctrl-C sent to a study as its first run is saved, and in CI), and each
    process paid ~50 ms for it."""
    os.environ.setdefault("MUJOCO_GL", "disable")


def quiet_opencv_ffmpeg() -> None:
    """FFmpeg's own messages through OpenCV off (``OPENCV_FFMPEG_LOGLEVEL=-8``): they ("moov atom not
    found") would add lines to the tracker's one-line errors.  The user's setting of this variable wins.
    Call before OpenCV opens a video."""
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
