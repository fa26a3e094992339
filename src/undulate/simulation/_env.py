"""Integer settings read from the environment (the Warp backend's ``UNDULATE_WARP_*``): one rule for
all of them, in a module that imports neither backend."""

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
