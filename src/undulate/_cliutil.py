"""Input helpers shared by the command lines (``undulate.cli``, ``undulate.robot.cli``)."""

from __future__ import annotations

import math
import os
from pathlib import Path

from .errors import ParameterError

__all__ = ["check_writable", "load_netcdf", "write_netcdf_atomic", "_parse_floats", "_fail", "_cli_name"]


def _fail(msg: str, code: int) -> None:
    """Print ``error: msg`` on stderr and exit with ``code`` (2: bad input)."""
    import typer

    typer.echo(f"error: {msg}", err=True)
    raise typer.Exit(code)


def _cli_name(e: ParameterError, names: dict[str, str]) -> ParameterError:
    """Re-label a parameter error with the CLI option the user typed."""
    return ParameterError(names.get(e.name, e.name), e.allowed, e.got)


def load_netcdf(path: Path, name: str, what: str = "an existing netCDF file"):
    """Load a user-given netCDF file into memory, or raise a one-line :class:`ParameterError`
    naming the option or argument ``name``: ``what`` when the file does not exist, "a readable
    netCDF file" (with the error's type) when it cannot be read."""
    import xarray as xr

    path = Path(path)
    if not path.is_file():
        raise ParameterError(name, what, str(path))
    try:
        return xr.load_dataset(path, engine="h5netcdf")
    except Exception as e:  # unreadable file: say so in one line
        raise ParameterError(name, "a readable netCDF file", f"{path} ({type(e).__name__})") from None


def write_netcdf_atomic(ds, path: Path) -> None:
    """Write ``ds`` to ``path`` atomically (:func:`undulate._io.write_netcdf`, uncompressed)."""
    from ._io import write_netcdf

    write_netcdf(ds, path, compress=False)


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
