"""Physics time: wall seconds inside ``mujoco.rollout`` and the scene-steps taken there.

:func:`undulate.simulation.simulate_batch` measures its own cost (its
Datasets' ``physics_time`` and ``physics_steps`` attrs) and, once when it
ends, reports it here (:func:`report`) to every open :func:`meter`.  Code
that runs other code it cannot see into (a sweep worker around a sweep
function, a study around its dataset) opens a meter around it and reads
what the meter collected.  Never read by the physics.

Light: imports neither MuJoCo nor the simulator (sweep workers that never
simulate do not pay for them).  One process-wide set of meters: a meter
also collects what other threads simulate while it is open.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

__all__ = ["Tally", "meter", "report"]


class Tally:
    """Physics seconds and scene-steps collected (a batch of 4 scenes stepped 1000 times: 4000 steps)."""

    def __init__(self) -> None:
        self.seconds, self.steps = 0.0, 0

    def add(self, seconds: float, steps: int) -> None:
        self.seconds += seconds
        self.steps += steps

    def read(self) -> tuple[float, int]:
        """``(seconds, steps)``."""
        return self.seconds, self.steps


_OPEN: list[Tally] = []


@contextlib.contextmanager
def meter() -> Iterator[Tally]:
    """A :class:`Tally` of the physics simulated while the ``with`` block runs (nested meters each count it)."""
    tally = Tally()
    _OPEN.append(tally)
    try:
        yield tally
    finally:
        _OPEN.remove(tally)  # by identity (Tally has no __eq__)


def report(seconds: float, steps: int) -> None:
    """Add one simulation's physics time to every open meter."""
    for tally in _OPEN:
        tally.add(seconds, steps)

