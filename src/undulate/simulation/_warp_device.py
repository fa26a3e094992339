"""MuJoCo Warp on this machine (:mod:`undulate.simulation._warp`): the ``gpu`` extra, the device, the
per-world capacities a scene needs, and the settings of a Warp model (determinism, steps per captured
graph, compile threads: ``UNDULATE_WARP_*``, read where each is used)."""

from __future__ import annotations

import functools
import os
import sys
import threading

import mujoco

from ..errors import ParameterError, UndulateError
from ..execution import current
from ._env import is_cpu_device, usable_cpus

__all__ = ["available", "require", "versions", "resolve_device", "device_name", "capacities", "CapacityError",
           "determinism", "steps_per_graph", "compile_workers", "DEVICES", "PRECISION", "STEPS_PER_GRAPH"]

DEVICES = ("cpu", "cuda")
"""Devices the Warp backend steps on (``SimOptions.device``; None: ``cuda`` if present, else ``cpu``)."""
PRECISION = "float32"
"""The Warp backend's floating-point precision (recorded in provenance)."""

EXTRA_HINT = "pip install 'undulate[gpu]' (mujoco-warp and warp-lang)"


class CapacityError(UndulateError):
    """A Warp world needed more contacts, constraint rows or sensor matches than were allocated."""


_LOCK = threading.Lock()
_DEVICE_LOCK = threading.RLock()


@functools.lru_cache(maxsize=1)
def _modules():
    import warp as wp

    wp.config.quiet = True  # before mujoco_warp's import initialises Warp: no banner, no per-module lines
    if hasattr(wp, "LOG_WARNING"):
        wp.config.log_level = wp.LOG_WARNING
    import mujoco_warp as mjw

    return wp, mjw


def available() -> bool:
    """Whether the ``gpu`` extra (mujoco-warp, warp-lang) is importable."""
    try:
        _modules()
    except ImportError:
        return False
    return True


def require():
    """``(warp, mujoco_warp)``, or a ParameterError naming the extra to install."""
    try:
        return _modules()
    except ImportError:
        raise ParameterError("backend", f"'mujoco', or 'warp' once the gpu extra is installed: {EXTRA_HINT}",
                             "warp") from None


@functools.lru_cache(maxsize=1)
def versions() -> str:
    """``"mujoco-warp X, warp-lang Y"`` (provenance; read once a process, as
    :func:`undulate.provenance.provenance`'s versions are: every run's Dataset records it, and
    reading a distribution's metadata costs ~1.5 ms, a tenth of a gathered run's host time)."""
    from ..provenance import package_version

    return f"mujoco-warp {package_version('mujoco-warp', '?')}, warp-lang {package_version('warp-lang', '?')}"


_NO_DRIVER = b"Warp CUDA warning: Could not find or load the NVIDIA CUDA driver."


@functools.lru_cache(maxsize=1)  # once a process (wp.init() does nothing after its first call)
def _init(wp) -> None:
    """``wp.init()`` without the line Warp's C library writes on stderr on a machine with no CUDA driver
    (every Warp run on the CPU device would print it; a ``cuda`` request there is refused by
    :func:`resolve_device` naming the device instead).  Everything else it writes is passed on."""
    import tempfile

    sys.stderr.flush()
    with tempfile.TemporaryFile() as caught:
        saved = os.dup(2)
        try:
            os.dup2(caught.fileno(), 2)
            try:
                wp.init()
            finally:
                os.dup2(saved, 2)
        finally:
            os.close(saved)
        caught.seek(0)
        kept = b"".join(line for line in caught.read().splitlines(keepends=True) if not line.startswith(_NO_DRIVER))
    if kept:
        os.write(2, kept)


def resolve_device(device: str | None) -> str:
    """``device`` checked against what this machine has (None: ``cuda`` if present, else ``cpu``)."""
    wp, _ = require()
    with _LOCK:
        _init(wp)
    if device is None:
        return "cuda" if wp.is_cuda_available() else "cpu"
    if device not in DEVICES:
        raise ParameterError("device", "'cpu' or 'cuda'", device)
    if device == "cuda" and not wp.is_cuda_available():
        raise ParameterError("device", "'cpu' on this machine (no CUDA device is visible to Warp)", device)
    return device


def device_name(device: str) -> str:
    """The device's own name (e.g. 'NVIDIA H100 80GB HBM3', or the CPU's)."""
    wp, _ = require()
    return str(wp.get_device(device).name)


def capacities(mjm: mujoco.MjModel) -> dict[str, int]:
    """Per-world capacities for a scene: contacts (``nconmax``), constraint rows (``njmax``) and
    the contact sensors' match buffer (``contact_sensor_maxmatch``).

    Every colliding geom of a swimmer can touch its two lateral neighbours' geoms along its
    length and a wall; capsule pairs and capsule-plane pairs make at most 2 contacts each.
    The bound used is 6 contacts per colliding geom plus 16.  Constraint rows: per contact, 1
    for a frictionless contact (condim 1), else ``2 (condim - 1)`` in a pyramidal friction cone
    or ``condim`` in an elliptic one; plus one per joint limit, per dof with friction loss and
    per equality row (6 at most each), and 16.  (A frictionless contact counted as 0 rows would let a
    group of three overflow.)"""
    colliding = int(((mjm.geom_contype != 0) | (mjm.geom_conaffinity != 0)).sum())
    nconmax = 6 * colliding + 16
    condim = max([int(mjm.geom_condim.max()) if mjm.ngeom else 3] + ([int(mjm.pair_dim.max())] if mjm.npair else []))
    pyramidal = mjm.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    rows = 1 if condim == 1 else 2 * (condim - 1) if pyramidal else condim
    other = int(mjm.njnt) + int((mjm.dof_frictionloss > 0).sum()) + 6 * int(mjm.neq)
    njmax = rows * nconmax + other + 16
    return {"nconmax": nconmax, "njmax": njmax, "contact_sensor_maxmatch": nconmax}


def determinism(device: str = "cuda") -> int:
    """MuJoCo Warp's determinism bitmask for a Warp model on ``device``: ``UNDULATE_WARP_DETERMINISTIC``
    (1: all of it, stable contact order, canonical constraint rows and order-invariant atomic sums;
    0: none), by default on Warp's CPU device and off on a GPU.

    On the CPU device it costs nothing measurable (a pair: 27.0 k against 26.5 k world-steps/s) and the
    kernels run on one thread, so the same inputs give the same results either way.  On a GPU its
    order-invariant atomics are sort-reduce launches whose workspace grows with the launch size times
    the constraint rows: on an H200 it made the pair's steps 8.9x slower at 1 024 worlds
    and 20x at 8 192, and could not allocate at 32 768 worlds nor for one jammed 50-swimmer pack
    (Warp's arrays stop at 2^31 elements).  Off, identical worlds of a jammed pack drift apart on a GPU
    (4 cm in 1 s on an H200, GPU.md): only statistics over runs are comparable there, as between the
    two engines; the Dataset attr ``warp_determinism`` and the sweep identity say which."""
    _, mjw = require()
    DeterminismType = mjw.DeterminismType

    on = current().deterministic
    on = is_cpu_device(device) if on is None else on
    return int(DeterminismType.ALL if on else DeterminismType.NONE)


STEPS_PER_GRAPH = 16
"""Steps captured in one graph on a GPU (besides the one-step graph for a chunk's remainder): a chunk of
k steps is k // 16 + k % 16 launches, each one Python call on the host (``UNDULATE_WARP_STEPS_PER_GRAPH``).
On Warp's CPU device the default is 1: there the kernels dominate a step (a pair: 70 us a step either
way) and capturing 16 steps costs each new model ~0.4 s."""


def steps_per_graph(device: str = "cuda") -> int:
    """Steps in one captured graph on ``device``: ``UNDULATE_WARP_STEPS_PER_GRAPH``, else
    :data:`STEPS_PER_GRAPH` on a GPU and 1 on Warp's CPU device."""
    n = current().steps_per_graph
    return n if n is not None else 1 if is_cpu_device(device) else STEPS_PER_GRAPH


def compile_workers() -> int:
    """Threads that compile a Warp model's kernels at once: ``UNDULATE_WARP_COMPILE_WORKERS``, or
    the CPUs this process may use (1: one module after another, as Warp's first step does)."""
    return current().compile_workers or usable_cpus()
