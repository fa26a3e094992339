"""A wall-time meter for stepping: the wall seconds spent inside the engines' rollouts ("physics time")
and the scene-steps taken there.

:func:`undulate.simulation.simulate_batch` measures its own cost (its
Datasets' ``physics_time`` and ``physics_steps`` attrs) and, once when it
ends, reports it here (:func:`report`) to every open :func:`meter`.  Code
that runs other code it cannot see into (a sweep worker around a sweep
function, a study around its dataset) opens a meter around it and reads
what the meter collected.  Never read by the physics.

Light: imports neither MuJoCo nor the simulator (sweep workers that never
simulate do not pay for them).  The open meters are a context variable: a
meter collects what its own thread simulates, and what threads started in a
copy of its context do (:func:`undulate.reproduce.reproduce` runs studies
side by side that way: each study's meter sees its own physics, a meter
around the whole reproduction sees all of it).
"""

from __future__ import annotations

import contextlib
import contextvars
import threading
from collections.abc import Iterator

__all__ = ["Tally", "meter", "report"]


class Tally:
    """Physics seconds and scene-steps collected (a batch of 4 scenes stepped 1000 times: 4000 steps)."""

    def __init__(self) -> None:
        self.seconds, self.steps = 0.0, 0
        self._lock = threading.Lock()  # threads of one context report to the same tallies

    def add(self, seconds: float, steps: int) -> None:
        with self._lock:
            self.seconds += seconds
            self.steps += steps

    def read(self) -> tuple[float, int]:
        """``(seconds, steps)``."""
        return self.seconds, self.steps


_OPEN: contextvars.ContextVar[tuple[Tally, ...]] = contextvars.ContextVar("undulate_physics_meters", default=())


@contextlib.contextmanager
def meter() -> Iterator[Tally]:
    """A :class:`Tally` of the physics this context simulates while the ``with`` block runs (nested
    meters each count it)."""
    tally = Tally()
    token = _OPEN.set(_OPEN.get() + (tally,))
    try:
        yield tally
    finally:
        _OPEN.reset(token)


def report(seconds: float, steps: int) -> None:
    """Add one simulation's physics time to every meter open in this context."""
    for tally in _OPEN.get():
        tally.add(seconds, steps)

