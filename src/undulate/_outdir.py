"""One process at a time writes a reproduction's or a study's output folder.

Two ``undulate reproduce --out X`` (or a reproduction and an ``undulate study NAME --out X``) at
once would step on each other: their sweeps refuse to share a store only once both reach it,
minutes in, and each overwrites the other's study files and page.  :func:`writing_to` takes an
advisory lock (``flock``) on ``X/.writer.lock`` for as long as the command runs (and removes the
file when it ends), so the second command stops at once with one line naming the folder and the
process holding it.  A process killed while it writes leaves the file, but not the lock: the kernel
drops it.

The lock is the process's, not a thread's: studies side by side in one reproduction, and a study
run inside a reproduction, share it (a count per folder).  The sweep stores' own locks
(:mod:`undulate.sweep._store`) still guard each store against any other writer.  Where ``fcntl`` is
missing (Windows) there is no lock, as for the stores.
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Iterator
from pathlib import Path

from ._io import make_folder
from .errors import ParameterError

__all__ = ["writing_to", "flock_pid", "LOCK_NAME"]

LOCK_NAME = ".writer.lock"
"""The lock file in an output folder (it holds the pid of the process writing the folder)."""

_HELD: dict[Path, list[int]] = {}  # folder -> [fd, count] held by this process
_GUARD = threading.Lock()


def _holder(path: Path) -> str:
    try:
        pid = path.read_text().strip()
    except OSError:
        return ""
    return f"; process {pid} is" if pid.isdigit() else ""


@contextlib.contextmanager
def writing_to(folder: str | os.PathLike, name: str = "out_dir") -> Iterator[Path]:
    """Hold ``folder`` (created if missing) for this process while the block runs.

    Raises :class:`~undulate.errors.ParameterError` naming ``name`` (the parameter as the user knows
    it: ``--out``, ``out_dir``) when another process holds it; nothing in the folder but the lock file
    is touched before that.  Re-entrant within the process."""
    root = Path(folder).resolve()
    try:
        import fcntl  # noqa: F401
    except ImportError:  # pragma: no cover - Windows: no advisory lock
        yield root
        return
    with _GUARD:
        held = _HELD.get(root)
        if held is not None:
            held[1] += 1
        else:
            make_folder(root, name)
            _HELD[root] = [_acquire(root / LOCK_NAME, name, folder), 1]
    try:
        yield root
    finally:
        with _GUARD:
            held = _HELD[root]
            held[1] -= 1
            if held[1] == 0:
                del _HELD[root]
                with contextlib.suppress(OSError):
                    os.unlink(root / LOCK_NAME)  # while still held: the folder is left as it was
                os.close(held[0])  # releases the flock


def flock_pid(path: Path) -> int | None:
    """An fd holding an exclusive ``flock`` on ``path`` (created if missing), which then names this
    process; None when another process holds it.  Closing the fd releases it (the kernel does, too,
    when the process dies).  The sweep stores' lock (:mod:`undulate.sweep._store`) and
    :func:`writing_to`'s."""
    import fcntl

    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())
    return fd


def _acquire(lock: Path, name: str, folder) -> int:
    """An fd holding ``lock``'s flock (:func:`flock_pid`).  A holder removes the file before it lets go,
    so a lock won on a file no longer at ``lock`` (opened just before that removal) is dropped and tried
    again on the file there now: only one process ever holds the path's lock."""
    while True:
        fd = flock_pid(lock)
        if fd is None:
            raise ParameterError(name, "a folder no other running reproduction or study is writing to"
                                 + _holder(lock), str(folder))
        try:
            if os.path.samestat(os.fstat(fd), os.stat(lock)):
                return fd
        except FileNotFoundError:
            pass
        os.close(fd)
