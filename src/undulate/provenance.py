"""Provenance: which code, on which machine, made a result.

:func:`provenance` returns flat ``str -> str`` entries, ready to be stored as
netCDF attributes or in a JSON summary.  Versions come from package metadata
(no heavy imports); the git commit is included only when the package runs
from its own source checkout.
"""

from __future__ import annotations

import functools
import platform
import socket
import subprocess
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path

__all__ = ["provenance", "package_version"]


def package_version(dist: str, fallback: str = "0+unknown") -> str:
    """Installed version of distribution ``dist``, or ``fallback``."""
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return fallback


def _git(args: list[str], cwd: Path) -> str | None:
    try:
        out = subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True,
                             timeout=5, check=True)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip()


@functools.lru_cache(maxsize=1)
def _git_state() -> dict[str, str]:
    """Commit (and dirtiness) of the checkout this package runs from, if any."""
    pkg = Path(__file__).resolve().parent
    top = _git(["rev-parse", "--show-toplevel"], pkg)
    # Only our own checkout counts, not some repository that happens to hold the venv.
    if not top or (Path(top).resolve() / "src" / "undulate") != pkg:
        return {}
    commit = _git(["rev-parse", "HEAD"], pkg)
    if not commit:
        return {}
    state = {"git_commit": commit}
    status = _git(["status", "--porcelain", "--untracked-files=no"], pkg)
    if status is not None:
        state["git_dirty"] = "true" if status else "false"
    return state


def provenance() -> dict[str, str]:
    """Versions, git commit (when available), UTC time and host, as strings.

    Keys: ``undulate_version``, ``mujoco_version``, ``numpy_version``,
    ``xarray_version``, ``python_version``, ``git_commit`` and ``git_dirty``
    (only in a source checkout), ``created_utc`` (ISO 8601), ``hostname``.
    """
    out = dict(_static())
    out["created_utc"] = datetime.now(timezone.utc).isoformat(timespec="seconds")
    return out


@functools.lru_cache(maxsize=1)
def _static() -> tuple[tuple[str, str], ...]:
    """The parts that cannot change while a process runs (read once: ~20 ms)."""
    out = {
        "undulate_version": package_version("undulate"),
        "mujoco_version": package_version("mujoco", "not installed"),
        "numpy_version": package_version("numpy", "not installed"),
        "xarray_version": package_version("xarray", "not installed"),
        "python_version": platform.python_version(),
    }
    out.update(_git_state())
    out["hostname"] = socket.gethostname()
    return tuple(out.items())
