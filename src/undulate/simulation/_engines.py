"""The engines that step a batch, behind one interface: :class:`Backend`.

A backend is looked up once by name (:func:`backend`, ``SimOptions.backend``) and the stepper
(:class:`undulate.simulation._stepper._Stepper`) only calls its methods: it compiles each scene once
for the host (:meth:`Backend.compile`: the layout the controls, the recorder and the checkpoints
read), then prepares the compiled batch once (:meth:`Backend.prepare`: the engine's own models --
MuJoCo steps the host's, Warp derives its affine-servo device models from them without compiling
again) and gets a :class:`Rollout`, which steps every scene of the batch from FULLPHYSICS states
under per-step controls.  The recorder, the stopping rules, the divergence checks
and the checkpoints are the stepper's, shared by every engine.

As in MuJoCo Warp's ``put_model`` / ``put_data`` / ``step``, the caller says what runs where: the host
``MjModel`` of each scene is the source of truth, and the engine holds only what it steps.

* ``"mujoco"`` (:class:`undulate.simulation._mujoco.MujocoBackend`): ``mujoco.rollout`` in C, float64,
  each scene's solver warm start carried across calls (bitwise a plain ``mj_step`` loop).
* ``"warp"`` (:class:`undulate.simulation._warp.WarpBackend`): every scene one world of a MuJoCo
  Warp model, float32, on a GPU or Warp's CPU device; open-loop chunks reduced on the device
  (:class:`SampledRollout`).  Imported only when asked for (the ``gpu`` extra).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from ..errors import ParameterError

if TYPE_CHECKING:
    from ..params import Scene, SimOptions
    from ..scene import CompiledScene

__all__ = ["Backend", "Rollout", "SampledRollout", "Reduction", "backend", "BACKEND_NAMES"]


@dataclass(frozen=True)
class Reduction:
    """What an engine that reduces a chunk where it steps keeps of each sample interval
    (:meth:`SampledRollout.rollout_samples`): ``steps_per_sample`` integrator steps an interval, the
    sensordata addresses of the pair and wall force 3-vectors and of the deepest contact's (found,
    distance) pair, and each scene's penetration bound (m) beyond which a step is bad."""

    steps_per_sample: int
    pair_adr: np.ndarray
    wall_adr: np.ndarray
    mindist_adr: int
    max_penetration_m: tuple[float, ...]


@runtime_checkable
class Rollout(Protocol):
    """A prepared batch: steps every scene from FULLPHYSICS states (MuJoCo's layout).

    ``warm``: (nb, nv) each scene's constraint-solver warm start (m/s^2 or rad/s^2), carried from one
    call to the next and settable (checkpoints)."""

    warm: np.ndarray

    def rollout(self, cur: np.ndarray, u: np.ndarray, st: np.ndarray, sd: np.ndarray, nstep: int,
                active: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Step every scene ``nstep`` steps from ``cur`` (nb x nstate) under controls ``u``
        (nb x >= nstep x nu), into ``st`` (nb x nstep x nstate) and ``sd`` (nb x nstep x
        nsensordata); returns ``(st, sd)``.  Scenes outside the mask ``active`` (None: all) stay at
        ``cur``, their sensor rows zero."""

    def close(self) -> None:
        """Free what the engine holds (threads, device memory)."""


@runtime_checkable
class SampledRollout(Rollout, Protocol):
    """A :class:`Rollout` that can also reduce a chunk where it steps (:class:`Reduction`)."""

    def rollout_samples(self, cur: np.ndarray, u: np.ndarray, nstep: int, active: np.ndarray | None = None):
        """Step ``nstep`` steps (a multiple of the sample interval) and return per sample interval:
        the FULLPHYSICS states (nb x ns x nstate) and sensors (nb x ns x nsensordata) at its last step,
        its deepest penetration (nb x ns, m), mean pair and wall force magnitudes (nb x ns x npair,
        nb x ns x nwall; N), then per scene the first bad step (-1: none) and what was bad there (1
        huge or non-finite state, 2 interpenetration beyond the bound)."""


class Backend(Protocol):
    """An engine that steps batches of compiled scenes (see the module docstring)."""

    name: str
    """``SimOptions.backend``'s value for this engine."""

    def resolve_device(self, device: str | None) -> str | None:
        """``device`` checked against this machine (None where the engine has no choice of device)."""

    def attrs(self, options: SimOptions) -> dict[str, str]:
        """What stepped a run (resolved ``options``): ``backend``, ``device``, ``precision``, ... (Dataset
        attrs, sweep identity)."""

    def compile(self, scene: Scene, options: SimOptions, *, push: bool, loads: bool) -> CompiledScene:
        """``scene``'s model as the host records it (``options`` resolved; ``push``: the perturbation
        force actuators; ``loads``: servo-torque sensors)."""

    def reduces_on_device(self, closed_loop: bool) -> bool:
        """Whether :meth:`prepare` gets a :class:`Reduction` (the rollout is then a
        :class:`SampledRollout`, and the host holds a chunk's controls only)."""

    def prepare(self, compiled: Sequence[CompiledScene], options: SimOptions, *, nthread: int = 0,
                reduce: Reduction | None = None) -> Rollout:
        """The batch ``compiled`` (one structure, one time step) ready to step (``nthread``: threads
        for engines that step scenes on the CPU; 0: the calling thread)."""


def _mujoco() -> Backend:
    from ._mujoco import MujocoBackend

    return MujocoBackend()


def _warp() -> Backend:
    from ._warp import WarpBackend  # the gpu extra's modules load only here

    return WarpBackend()


_REGISTRY: dict[str, Callable[[], Backend]] = {"mujoco": _mujoco, "warp": _warp}
BACKEND_NAMES = tuple(_REGISTRY)
"""The engines :func:`backend` knows (``SimOptions.BACKENDS``)."""


@functools.lru_cache(maxsize=None)
def backend(name: str | None) -> Backend:
    """The engine named ``name`` (None: ``"mujoco"``), made once a process."""
    try:
        load = _REGISTRY[name or "mujoco"]
    except (KeyError, TypeError):
        raise ParameterError("backend", " or ".join(repr(n) for n in BACKEND_NAMES), name) from None
    return load()
