"""Which engine steps a run: the session's default backend and device, and what a Dataset records
about them (:mod:`undulate.simulation`)."""

from __future__ import annotations

import dataclasses
import os

from ..errors import ParameterError
from ..params import SimOptions
from ._engines import backend as engine
from ._env import env_count, env_switch, is_cpu_device, usable_cpus

BACKEND_ENV, DEVICE_ENV = "UNDULATE_BACKEND", "UNDULATE_DEVICE"
WARP_PROCESSES_ENV = "UNDULATE_WARP_PROCESSES"
LONE_ENV = "UNDULATE_WARP_LONE_SWIMMERS"
PREFETCH_ENV = "UNDULATE_WARP_PREFETCH"
CORES_UP_TO_ENV = "UNDULATE_WARP_CORES_UP_TO"
WARP_PROCESSES_MAX = 256


def use_backend(backend: str | None, device: str | None = None) -> None:
    """Make ``backend`` (``"mujoco"`` or ``"warp"``; None: back to ``"mujoco"``) and ``device`` the
    default of every :class:`SimOptions` that leaves them out, in this process and the worker
    processes it starts (it sets the environment variables ``UNDULATE_BACKEND`` and
    ``UNDULATE_DEVICE``).  The ``warp`` backend is checked here: its extra must be installed and
    the device present."""
    SimOptions(backend=backend, device=device)  # validated as options are
    if backend is not None:  # the engine checks its extra and device (MuJoCo's: none)
        device = engine(backend).resolve_device(device)
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


def warp_processes() -> int:
    """Processes a sweep on the Warp backend splits its runs over: ``UNDULATE_WARP_PROCESSES``
    (1 to :data:`WARP_PROCESSES_MAX`; default 1, every run of a task in this process).  Each process
    steps its share as the worlds of one batch on the same device, and does its share of the host's
    work (models, control tables, Datasets, run files), which on a GPU is most of a large sweep's time
    (docs/gpu.md, "The host's share of a sweep"); more processes are not yet measured on a GPU."""
    return env_count(WARP_PROCESSES_ENV, 1, WARP_PROCESSES_MAX)


def lone_swimmers_backend(device: str | None) -> str:
    """The engine that steps a scene of one swimmer when the Warp backend is asked for on ``device``:
    ``UNDULATE_WARP_LONE_SWIMMERS`` (``mujoco`` or ``warp``), else ``mujoco`` on a GPU and ``warp``
    on Warp's CPU device.

    Why a GPU hands lone swimmers to the cores: a lone swimmer touches nothing but the channel
    walls, and its batches are small (a study's free swimmers, 1-36 at a time), where a GPU step
    costs the same ~0.32 ms as a model of a thousand worlds (on an H200) and one core steps a
    9-link swimmer in ~14 us (MuJoCo on a 2-core VM).  The free swimmers are also the reproduction's longest chain of steps
    that must follow one another (sensitivity's equal-A search: up to three 30 s runs in turn).  Such
    runs step on MuJoCo (float64, the MuJoCo backend's results bitwise), and their Datasets say so
    (attrs ``backend``); a sweep's identity records the rule (:func:`undulate.sweep._store.backend_identity`),
    so runs of one rule are never served for the other.  On Warp's CPU device nothing is gained, and
    the tests step lone swimmers on Warp there."""
    raw = os.environ.get(LONE_ENV)
    if raw:
        if raw not in SimOptions.BACKENDS:
            raise ParameterError(LONE_ENV, "'mujoco' or 'warp' (environment variable)", raw)
        return raw
    return "warp" if is_cpu_device(device) else "mujoco"


def cores_up_to(device: str | None) -> int:
    """The most scenes a batch asked of the Warp backend on ``device`` may have and still step on the
    cores (MuJoCo, one scene per core): ``UNDULATE_WARP_CORES_UP_TO`` (0 to 10^6; 0: every batch on
    Warp), else on a GPU the cores this process may use and on Warp's CPU device 0.

    Why on a GPU: a step of a small Warp model costs about the same whatever its worlds, ~0.35 ms for
    pairs and ~1.5 ms for 3-12 jammed packs in a quick reproduction on an H200, where one
    core steps a pair in ~23 us and a pack in ~0.7 ms (that machine's cores, ../shared/GPU.md).  Up to
    one scene per core, the cores step every scene 2x (packs) to 15x (pairs) faster than the device
    steps the batch, and a quick reproduction's longest chains are such batches stepped one after
    another (the links study's one-world looks: 7 x 19 500 steps, ~67 s of a 466 s run; the packing
    study's five looks of 3-12 packs).  Wide batches (sweeps of hundreds or thousands of runs) stay
    on the device, where it wins.  Such runs are the MuJoCo backend's (float64, bitwise) and their
    Datasets say so (attrs ``backend``); a sweep's identity records the rule
    (:func:`undulate.sweep._store.backend_identity`), so runs of one rule are never served for another.
    On Warp's CPU device nothing is gained, and the tests step every batch on Warp there."""
    return env_count(CORES_UP_TO_ENV, 0 if is_cpu_device(device) else usable_cpus(), least=0)


def warp_prefetch(device: str | None) -> bool:
    """Whether a study on the Warp backend on ``device`` (None: the default, ``cuda`` where there is
    one) steps its last stage's runs before its first look (:func:`undulate.studies._registry._prefetch`):
    ``UNDULATE_WARP_PREFETCH`` (``1`` or ``0``), else on a GPU and not on Warp's CPU device.

    Why by device: on a GPU a step costs about the same for one world as for hundreds (an H200: ~0.32 ms
    for one world, 0.34 ms for 1 024), so stepping every stage's runs at once costs about
    the first look's time and spares the later looks' chains of steps.  On Warp's CPU device each world
    costs its own steps, so the runs no look reads are time lost: full mode's packing study would step
    its last stage's 182 jammed packs where its first look, which decides on the MuJoCo backend, reads
    28.  The looks and verdicts are the staged plan's either way (:mod:`tests.test_staged_verdicts`)."""
    if device is None and not os.environ.get(PREFETCH_ENV):  # the default needs the device
        from . import _warp

        device = _warp.resolve_device(None)
    return env_switch(PREFETCH_ENV, not is_cpu_device(device))


def check_backend(options: SimOptions) -> SimOptions:
    """``options`` with a concrete backend and device (:func:`default_backend` where left out); a
    ParameterError if the Warp backend's extra or device is missing."""
    backend, device = (options.backend, options.device) if options.backend is not None else default_backend()
    device = engine(backend).resolve_device(options.device or device)  # the extra and the device are there
    if (backend, device) == (options.backend, options.device):
        return options
    return dataclasses.replace(options, backend=backend, device=device)


def backend_attrs(options: SimOptions) -> dict[str, str]:
    """What stepped a run (resolved ``options``): ``backend``, ``device``, ``precision`` and, for
    Warp, the versions of mujoco-warp and warp-lang and whether MuJoCo Warp's determinism was on
    (``warp_determinism``: ``all`` or ``none``; Dataset attrs, sweep identity): the engine's
    :meth:`~undulate.simulation._engines.Backend.attrs`."""
    return engine(options.backend).attrs(options)


def on_cores(options: SimOptions, *, n_scenes: int | None = None, n_swimmers: int | None = None) -> SimOptions:
    """``options`` (backend resolved) moved to MuJoCo (device None) where the Warp backend hands a batch
    of ``n_scenes`` scenes (:func:`cores_up_to`) or a scene of ``n_swimmers`` swimmers
    (:func:`lone_swimmers_backend`) to the cores; otherwise ``options`` as they are."""
    if options.backend != "warp":
        return options
    lone = n_swimmers == 1 and lone_swimmers_backend(options.device) == "mujoco"
    small = n_scenes is not None and n_scenes <= cores_up_to(options.device)
    return dataclasses.replace(options, backend="mujoco", device=None) if lone or small else options
