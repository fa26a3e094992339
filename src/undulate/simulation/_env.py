"""Integer settings read from the environment (the Warp backend's ``UNDULATE_WARP_*``): one rule for
all of them, in a module that imports neither backend; and the CPUs this process may use."""

from __future__ import annotations

import os

from ..errors import ParameterError


def env_count(name: str, default: int, most: int = 10**6) -> int:
    """The integer environment setting ``name`` (1 to ``most``), or ``default`` where it is unset."""
    raw = os.environ.get(name)
    if not raw:
        return default
    try:
        n = int(raw)
    except ValueError:
        n = 0
    if not 1 <= n <= most:
        raise ParameterError(name, f"an integer from 1 to {most}", raw)
    return n


def usable_cpus() -> int:
    """The CPUs this process may use (its affinity where the platform has one)."""
    if hasattr(os, "process_cpu_count"):  # Python >= 3.13
        return os.process_cpu_count() or 1
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - macOS, Windows
        return os.cpu_count() or 1
