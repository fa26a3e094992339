"""Which engine steps a run: the session's default backend and device, and what a Dataset records
about them (:mod:`undulate.simulation`)."""

from __future__ import annotations

import dataclasses

from .. import execution
from ..params import SimOptions
from ._engines import backend as engine

def use_backend(backend: str | None, device: str | None = None) -> None:
    """Make ``backend`` (``"mujoco"`` or ``"warp"``; None: back to ``"mujoco"``) and ``device`` the
    default of every :class:`SimOptions` that leaves them out, in this process and the worker
    processes it starts (:meth:`undulate.execution.Execution.export`: the environment variables
    ``UNDULATE_BACKEND`` and ``UNDULATE_DEVICE``).  The ``warp`` backend is checked here: its extra
    must be installed and the device present.  Code that runs studies or sweeps passes an
    :class:`~undulate.execution.Execution` instead (``execution=``)."""
    SimOptions(backend=backend, device=device)  # validated as options are
    if backend is not None:  # the engine checks its extra and device (MuJoCo's: none)
        device = engine(backend).resolve_device(device)
    execution.Execution.from_environment().replace(backend=backend or "mujoco",
                                                   device=device if backend == "warp" else None).export()


def default_backend() -> tuple[str, str | None]:
    """The default ``(backend, device)`` here: the settings in effect (:func:`undulate.execution.current`:
    an ``execution=`` passed down, else the environment's)."""
    ex = execution.current()
    return ex.backend, ex.device if ex.backend == "warp" else None


def warp_processes() -> int:
    """Processes a sweep on the Warp backend splits its runs over (:func:`undulate.execution.warp_processes`)."""
    return execution.warp_processes()


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
    of ``n_scenes`` scenes or a scene of ``n_swimmers`` swimmers to the cores
    (:func:`undulate.execution.engine_for`); otherwise ``options`` as they are."""
    engine_name, _ = execution.engine_for(options.backend, options.device, n_scenes=n_scenes, n_swimmers=n_swimmers)
    return options if engine_name == options.backend else dataclasses.replace(options, backend="mujoco", device=None)
