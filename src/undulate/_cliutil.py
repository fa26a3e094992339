"""Input helpers shared by the command lines (``undulate.cli``, ``undulate.robot.cli``)."""

from __future__ import annotations

import math
import os
from pathlib import Path

from .errors import ParameterError

__all__ = ["check_writable", "load_netcdf", "write_netcdf_atomic", "_parse_floats", "_fail", "_cli_name",
           "unwind_on_signals", "SignalExit", "exit_on_termination", "signalled", "stop_if_signalled"]


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


_SIGNALLED: list[int] = []  # the termination signals this process has received, in order
_RAISES: list[type] = []  # the exception each raised


def signalled() -> int | None:
    """The first termination signal handled by :func:`unwind_on_signals` in this process, or None.

    The exception the handler raises can reach the command's top as another one: raised inside C code
    that calls back into Python (matplotlib's Agg renderer asking a transform for its matrix), it comes
    out as that code's own error ("ValueError: Invalid affine transformation matrix", seen when
    ``animate`` was terminated).  The cleanup ran all the same (it is ``finally`` blocks), so
    :func:`undulate.cli.main` judges the command by this record, not by the exception it sees."""
    return _SIGNALLED[0] if _SIGNALLED else None


def stop_if_signalled() -> None:
    """Raise again the exception of a termination signal already handled.  For loops that call into C
    code which calls back into Python (matplotlib drawing a frame): an exception raised there may be
    dropped by that code, and the loop would run on to write a file the command then calls terminated."""
    if _SIGNALLED:
        raise _RAISES[0](_SIGNALLED[0])


def unwind_on_signals(signals, exception) -> None:
    """From here on each of ``signals`` raises ``exception(signum)`` in the main thread, so the command
    unwinds as on Ctrl-C (temporary files removed, sweeps and worker processes stopped).  A signal this
    process was started ignoring (``nohup``'s SIGHUP) stays ignored.

    Python runs a signal handler at the next bytecode of the main thread, which may be inside a
    finalizer or a weakref callback: an exception raised there is printed as "Exception ignored" and
    dropped, and the command went on as if never signalled (seen on Python 3.13: a terminated
    ``simulate`` ran to its end and exited 0).  So an exception of ``exception`` that reaches
    :data:`sys.unraisablehook` delivers the signal again (``_thread.interrupt_main``, from a thread 10 ms
    later: called in the hook, the handler would raise inside the finalizer again)."""
    import _thread
    import signal
    import sys
    import threading

    def handler(signum, _frame):
        if signum not in _SIGNALLED:
            _SIGNALLED.append(signum)
            _RAISES.append(exception)
        raise exception(signum)

    for sig in signals:
        if signal.getsignal(sig) is signal.SIG_DFL:
            signal.signal(sig, handler)
    previous = sys.unraisablehook
    if getattr(previous, "undulate_redelivers", None) is exception:
        return

    def hook(unraisable):
        e = unraisable.exc_value
        if isinstance(e, exception):  # again from another thread, once this finalizer has returned
            again = threading.Timer(0.01, _thread.interrupt_main, args=(e.signum,))
            again.daemon = True
            again.start()
            return
        previous(unraisable)

    hook.undulate_redelivers = exception
    sys.unraisablehook = hook


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
