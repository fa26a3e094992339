"""Tests that measure wall-clock time run with no other test beside them.

The default run spreads the test modules over two pytest-xdist worker processes (``-n 2 --dist
loadfile``, ``pyproject.toml``).  A few tests measure real time: the servo bus emulator answers the
driver within the Dynamixel SDK's packet timeout (tens of milliseconds), the compute-time estimate
is compared with a measured run.  On two cores, a study's sweep on the other worker makes them
measure the machine, not the code.  They are marked ``alone``; :func:`beside_others` is a
readers-writer lock shared by the workers through two files: every test holds it shared, an
``alone`` test holds it exclusively, and a waiting ``alone`` test holds a turnstile that keeps new
tests from starting (else the other worker's stream of short tests could keep it waiting).
"""

from __future__ import annotations

import contextlib
import fcntl
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def beside_others(folder: Path, alone: bool) -> Iterator[None]:
    """Hold the lock in ``folder`` for one test: exclusively when ``alone``, else shared."""
    with open(folder / "alone.turnstile", "a") as turn, open(folder / "alone.lock", "a") as lock:
        fcntl.flock(turn, fcntl.LOCK_EX)
        try:
            fcntl.flock(lock, fcntl.LOCK_EX if alone else fcntl.LOCK_SH)
        finally:
            fcntl.flock(turn, fcntl.LOCK_UN)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
