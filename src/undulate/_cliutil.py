"""Input helpers shared by the command lines (``undulate.cli``, ``undulate.robot.cli``)."""

from __future__ import annotations

import math
import os
from pathlib import Path

from ._signals import deferred, unwind_on_signals  # noqa: F401 - unwind_on_signals: shared with cli
from .errors import ParameterError

__all__ = ["check_writable", "load_netcdf", "write_netcdf_atomic", "_parse_floats", "_fail", "_cli_name",
           "unwind_on_signals", "SignalExit", "exit_on_termination", "said"]


_SAID: list[int] = []
"""Exit codes whose one line the command has printed itself (:func:`said`), since ``cli._run`` began."""


def said(code: int) -> int:
    """``code``, noted as an exit whose line the command has printed: the entry point adds none (a robot
    run stopped by Ctrl-C says what happened to torque and exits 130; ``cli._run`` says ``interrupted``
    only where no command has)."""
    _SAID.append(int(code))
    return int(code)


def _fail(msg: str, code: int) -> None:
    """Print ``error: msg`` on stderr and exit with ``code`` (2: bad input)."""
    import typer

    typer.echo(f"error: {msg}", err=True)
    raise typer.Exit(said(code))


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
        with deferred():  # opened whole or not at all: a half-opened h5netcdf File fails at exit
            ds = xr.open_dataset(path, engine="h5netcdf")
        try:
            return ds.load()  # the long part (a long run's samples): Ctrl-C or kill ends it at once
        finally:
            with deferred():
                ds.close()
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


class SignalExit(SystemExit):
    """SIGTERM or SIGHUP during a command that writes files (``simulate``, ``animate``, ``track``,
    ``compare``): exit ``128 + signal`` through the ``finally`` blocks, so no temporary file is left."""

    def __init__(self, signum: int):
        self.signum = int(signum)
        super().__init__(128 + self.signum)


def exit_on_termination() -> None:
    """From here on SIGTERM and SIGHUP (``kill``, a scheduler's cancel, a closed terminal) raise
    :class:`SignalExit`, as Ctrl-C raises KeyboardInterrupt: the command unwinds, removing its
    half-written temporary files and stopping its helper processes (ffmpeg).  A signal the command
    was started ignoring (``nohup``'s SIGHUP) stays ignored."""
    import signal

    unwind_on_signals((signal.SIGTERM, signal.SIGHUP), SignalExit)
