"""Settings read from the environment (the Warp backend's ``UNDULATE_WARP_*``): one rule for the
integers and one for the switches, in a module that imports neither backend; which devices are Warp's
CPU device; the CPUs this process may use; and the label of the gathered batch stepping in this context."""

from __future__ import annotations

import contextvars
import os

from ..errors import ParameterError

BATCH_LABEL: contextvars.ContextVar[str] = contextvars.ContextVar("undulate_batch_label", default="")
"""What a gathered batch steps for (its sweep: ``STUDY/SWEEP``, :attr:`undulate.simulation.Gather.label`),
set while it steps; the Warp backend's timeline names its models by it
(:class:`undulate.simulation._warp_timeline.Timeline`)."""


def env_count(name: str, default: int, most: int = 10**6, least: int = 1) -> int:
    """The integer environment setting ``name`` (``least`` to ``most``), or ``default`` where it is unset."""
    raw = os.environ.get(name)
    if not raw:
        return default
    try:
        n = int(raw)
    except ValueError:
        n = least - 1
    if not least <= n <= most:
        raise ParameterError(name, f"an integer from {least} to {most}", raw)
    return n


def env_switch(name: str, default: bool) -> bool:
    """The on/off environment setting ``name`` (``1`` or ``0``), or ``default`` where it is unset."""
    raw = os.environ.get(name)
    if not raw:
        return default
    if raw not in ("0", "1"):
        raise ParameterError(name, "'1' or '0' (environment variable)", raw)
    return raw == "1"


def is_cpu_device(device: str | None) -> bool:
    """Whether ``device`` (``cpu``, ``cuda``, ``cuda:1``...) is Warp's CPU device."""
    return str(device or "").split(":")[0] == "cpu"


def usable_cpus() -> int:
    """The CPUs this process may use (its affinity where the platform has one)."""
    if hasattr(os, "process_cpu_count"):  # Python >= 3.13
        return os.process_cpu_count() or 1
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - macOS, Windows
        return os.cpu_count() or 1
