"""Termination signals (SIGTERM, SIGHUP) turned into exceptions that unwind a command, and the record
of them its entry point judges it by (:func:`undulate.cli.main`).

Python runs a signal handler between two bytecodes of the main thread, wherever they are: inside a
finalizer, inside C code that calls back into Python (matplotlib, h5py), halfway through building an
object.  What it raises there may be dropped, reported as another error, or leave a half-built HDF5
file whose finalizer fails later ("Exception ignored in: <function File.close>").  Each case is met
here: dropped exceptions are delivered again, the record says the command was terminated whatever
exception came out, and :func:`deferred` holds the exception back while a file is opened or closed.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

__all__ = ["unwind_on_signals", "signalled", "stop_if_signalled", "deferred", "record_interrupts", "interrupted",
           "cancel_redeliveries", "forget_unhandled_interrupt"]

_DEFERRING = [0]  # how deep the main thread is in deferred() blocks
_PENDING: list[BaseException] = []  # what the signals handled meanwhile raise, as the last block ends


_INTERRUPTED = [False]  # whether Ctrl-C reached this process since record_interrupts()
_REDELIVERIES: list = []  # the threading.Timer of each Ctrl-C delivered again (record_interrupts)


def _interrupt(_signum, _frame) -> None:
    """Ctrl-C, recorded: then Python's own KeyboardInterrupt."""
    _INTERRUPTED[0] = True
    raise KeyboardInterrupt


def _hold_interrupt(_signum, _frame) -> None:
    """Ctrl-C inside :func:`deferred`: recorded, its KeyboardInterrupt held to the block's end."""
    _INTERRUPTED[0] = True
    _PENDING.append(KeyboardInterrupt())


def record_interrupts() -> None:
    """From here on Ctrl-C (SIGINT) raises KeyboardInterrupt as Python's own handler does, and is
    recorded for :func:`interrupted`; a SIGINT this process was started ignoring (a background job)
    stays ignored.

    A KeyboardInterrupt raised inside C code that calls back into Python can come out as that code's
    own error: Ctrl-C as a command imports MuJoCo turned into pybind11's "ImportError: initialization
    failed", a traceback and exit 1 (once in 30 Ctrl-C sent to ``study`` at random times in its first
    8 s, measured).  Outside the main thread (where Python runs no signal handler) it does nothing.
    :func:`undulate.cli.main` judges the command by this record, as it does terminations by
    :func:`signalled`.

    A KeyboardInterrupt raised inside a finalizer or a weakref callback is printed as "Exception
    ignored" and dropped, and the command ran on to exit 0 (seen once in a full test run: Ctrl-C to
    ``simulate`` landing in a ``WeakValueDictionary`` callback).  As for terminations
    (:func:`unwind_on_signals`), one that reaches :data:`sys.unraisablehook` is delivered again from a
    thread 10 ms later, once the finalizer has returned, and not printed."""
    import signal
    import threading

    _INTERRUPTED[0] = False
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        return
    signal.signal(signal.SIGINT, _interrupt)
    _redeliver_dropped()


_TERMINATIONS: list[type] = []  # the exceptions unwind_on_signals' handlers raise


def _redeliver_dropped() -> None:
    """Once per process: a :data:`sys.unraisablehook` that delivers again, and does not print, the
    exception of a signal a finalizer dropped: a termination's (:func:`unwind_on_signals`), or Ctrl-C's
    KeyboardInterrupt while :func:`record_interrupts`' handler is in place."""
    import signal
    import sys

    previous = sys.unraisablehook
    if getattr(previous, "undulate_redelivers", False):
        return

    def hook(unraisable):
        e = unraisable.exc_value
        if isinstance(e, tuple(_TERMINATIONS)):
            _deliver_again(e.signum)
        elif isinstance(e, KeyboardInterrupt) and _INTERRUPTED[0] and signal.getsignal(signal.SIGINT) is _interrupt:
            _deliver_again(signal.SIGINT)
        else:
            previous(unraisable)

    hook.undulate_redelivers = True
    sys.unraisablehook = hook


def _deliver_again(signum: int) -> None:
    """Deliver ``signum`` to the main thread again, from a thread 10 ms later: for a signal whose
    exception a finalizer dropped (called in the finalizer, the handler would raise there again)."""
    import _thread
    import threading

    again = threading.Timer(0.01, _thread.interrupt_main, args=(signum,))
    again.daemon = True
    _REDELIVERIES.append(again)
    again.start()


def cancel_redeliveries() -> None:
    """Cancel the deliveries :func:`record_interrupts` and :func:`unwind_on_signals` have scheduled and
    not yet made: for an entry point about to put back the handlers it found (a Ctrl-C delivered after
    that would raise Python's KeyboardInterrupt wherever the process then is).  :func:`interrupted` and
    :func:`signalled` still say the signal came."""
    while _REDELIVERIES:
        _REDELIVERIES.pop().cancel()


def forget_unhandled_interrupt() -> None:
    """Clear CPython's record that a KeyboardInterrupt went unhandled, for an entry point that has
    handled the Ctrl-C itself.

    ``exec`` or ``eval`` of a string (how dataclasses and namedtuples are made, in every import) that a
    KeyboardInterrupt leaves sets that record (``_Py_UnhandledKeyboardInterrupt``; on 3.12 in
    ``_PyRuntime``), and under ``python -m`` the interpreter then ends by killing itself with SIGINT
    whatever exit code was asked for: a Ctrl-C'd ``study`` printed its one line and exited -2, not 130
    (1 in 30 Ctrl-C in its first 1.4 s, measured; the record read at exit through ``ctypes``).  Every
    ``exec`` of a string clears it as it starts and sets it only if interrupted, so one that runs
    through clears it."""
    exec("pass")  # noqa: S102 - a constant string: its only effect is the record's reset


def interrupted() -> bool:
    """Whether Ctrl-C reached this process since :func:`record_interrupts` (in the main thread, or
    held by :func:`deferred`)."""
    return _INTERRUPTED[0]


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """A block a signal does not interrupt: what it raises (the termination's exception of
    :func:`unwind_on_signals`, Ctrl-C's KeyboardInterrupt) is raised as the block ends.

    For opening and closing HDF5 files: interrupted there, h5netcdf leaves a ``File`` without its
    ``_closed`` attribute, or one half closed, and its finalizer's error is printed at exit after the
    command's own line (seen once in ~30 terminated ``simulate`` runs on a loaded machine).  The signal
    waits as long as the block takes: milliseconds to open or close a file, as long as building a file
    in memory takes for :func:`undulate._io.netcdf_bytes` (~30 MB/s compressed, measured);
    a long read or a run's appends are not in such a block.  Outside the main thread (where Python
    never runs a signal handler) it does nothing; Ctrl-C is held only where Python's own handler would
    raise it."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    outermost = not _DEFERRING[0]
    previous = signal.getsignal(signal.SIGINT)
    hold = outermost and previous in (signal.default_int_handler, _interrupt)
    if hold:
        signal.signal(signal.SIGINT, _hold_interrupt)
    _DEFERRING[0] += 1
    try:
        yield
    finally:
        _DEFERRING[0] -= 1
        if hold:
            signal.signal(signal.SIGINT, previous)
        if outermost and _PENDING:
            e = _PENDING[0]
            _PENDING.clear()
            raise e


_SIGNALLED: list[tuple[int, type]] = []  # the termination signals this process has received, in order,
# each with the exception it raised


def signalled() -> int | None:
    """The first termination signal handled by :func:`unwind_on_signals` in this process, or None.

    The exception the handler raises can reach the command's top as another one: raised inside C code
    that calls back into Python (matplotlib's Agg renderer asking a transform for its matrix), it comes
    out as that code's own error ("ValueError: Invalid affine transformation matrix", seen when
    ``animate`` was terminated).  The cleanup ran all the same (it is ``finally`` blocks), so
    :func:`undulate.cli.main` judges the command by this record, not by the exception it sees."""
    return _SIGNALLED[0][0] if _SIGNALLED else None


def stop_if_signalled() -> None:
    """Raise again the exception of a termination signal already handled.  For loops that call into C
    code which calls back into Python (matplotlib drawing a frame): an exception raised there may be
    dropped by that code, and the loop would run on to write a file the command then calls terminated."""
    if _SIGNALLED:
        signum, exception = _SIGNALLED[0]
        raise exception(signum)


def unwind_on_signals(signals, exception) -> None:
    """From here on each of ``signals`` raises ``exception(signum)`` in the main thread, so the command
    unwinds as on Ctrl-C (temporary files removed, sweeps and worker processes stopped).  A signal this
    process was started ignoring (``nohup``'s SIGHUP) stays ignored.  Inside :func:`deferred` the
    exception is raised as the block ends.

    Python runs a signal handler at the next bytecode of the main thread, which may be inside a
    finalizer or a weakref callback: an exception raised there is printed as "Exception ignored" and
    dropped, and the command went on as if never signalled (seen on Python 3.13: a terminated
    ``simulate`` ran to its end and exited 0).  So an exception of ``exception`` that reaches
    :data:`sys.unraisablehook` delivers the signal again (``_thread.interrupt_main``, from a thread 10 ms
    later: called in the hook, the handler would raise inside the finalizer again)."""
    import signal

    def handler(signum, _frame):
        if all(signum != seen for seen, _ in _SIGNALLED):
            _SIGNALLED.append((signum, exception))
        if _DEFERRING[0]:  # the main thread is building or closing a file: raised when it is done
            _PENDING.append(exception(signum))
            return
        raise exception(signum)

    for sig in signals:
        if signal.getsignal(sig) is signal.SIG_DFL:
            signal.signal(sig, handler)
    if exception not in _TERMINATIONS:
        _TERMINATIONS.append(exception)
    _redeliver_dropped()
