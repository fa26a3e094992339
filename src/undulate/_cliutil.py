"""Input helpers shared by the command lines (``undulate.cli``, ``undulate.robot.cli``)."""

from __future__ import annotations

import math
import os
from pathlib import Path

from .errors import ParameterError

__all__ = ["check_writable", "_parse_floats"]


def _parse_floats(name: str, text: str) -> tuple[float, ...]:
    parts = [p.strip() for p in text.split(",")]
    if not parts or any(p == "" for p in parts):
        raise ParameterError(name, "a comma-separated list of numbers", text)
    out = []
    for p in parts:
        try:
            v = float(p)
        except ValueError:
            raise ParameterError(name, "a comma-separated list of numbers", text) from None
        if not math.isfinite(v):
            raise ParameterError(name, "finite numbers", text)
        out.append(v)
    return tuple(out)


def check_writable(name: str, path: Path) -> Path:
    """Validate that ``path`` can be created (its folder exists and is writable)."""
    path = Path(path)
    parent = path.resolve().parent
    if path.exists() and path.is_dir():
        raise ParameterError(name, "a file path, not a directory", str(path))
    if not parent.is_dir():
        raise ParameterError(name, "a path in an existing directory", str(path))
    if not os.access(parent, os.W_OK):
        raise ParameterError(name, "a path in a writable directory", str(path))
    return path
