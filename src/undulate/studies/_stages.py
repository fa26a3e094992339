"""Staged plans: the nested grids a study's stages run (:attr:`._protocol.Study.stages`).

A stage's grid is the next stage's thinned, so every run of an earlier stage is a run of the later
one (the sweep stores key runs by content and reuse them).  Thinning by index, not by recomputing a
coarser ``linspace``, keeps the shared values bitwise equal.  Which part of a plan a later look keeps on an
earlier look's plan is the staging engine's to decide, from the parts each claim reads.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

__all__ = ["thinned", "QUICK_STRIDES", "FULL_STRIDES", "strides"]

QUICK_STRIDES = (2, 1)
"""Quick mode: two looks, at every second value of the mode's grid, then all of it."""
FULL_STRIDES = (4, 2, 1)
"""Full mode: three looks, at every fourth value, every second, all."""


def strides(quick: bool) -> tuple[int, ...]:
    """The mode's strides (:data:`QUICK_STRIDES` or :data:`FULL_STRIDES`)."""
    return QUICK_STRIDES if quick else FULL_STRIDES


def thinned(values: Sequence[Any], steps: Sequence[int]) -> list[tuple[Any, ...]]:
    """``values[::s]`` for each stride ``s`` (descending strides give nested, growing grids; a grid of
    ``k * s + 1`` values keeps both ends)."""
    vals = list(values)
    return [tuple(vals[::int(s)]) for s in steps]
