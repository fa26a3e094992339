"""Staged plans: the nested grids a study's stages run (:attr:`._registry.Study.stages`).

A stage's grid is the next stage's thinned, so every run of an earlier stage is a run of the later
one (the sweep stores key runs by content and reuse them).  Thinning by index, not by recomputing a
coarser ``linspace``, keeps the shared values bitwise equal.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

__all__ = ["thinned", "QUICK_STRIDES", "FULL_STRIDES", "strides", "kept_plan", "frozen_parts"]

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


def kept_plan(looks: Sequence[Any], decided_at: dict[Any, int], key: Any, current: Any) -> Any:
    """The plan the runs of ``key`` (a claim's share of a study: a rule, a group size) follow at a look on
    ``current``: the plan of the look that decided it (``decided_at[key]``, 1-based into ``looks``, the
    study's stages), else ``current``.  A decided claim is never reopened, so its runs stay those made."""
    return looks[decided_at[key] - 1] if key in decided_at else current


def frozen_parts(reading: Mapping[Any, Iterable[str]], frozen: Mapping[str, int]) -> dict[Any, int]:
    """``part -> look`` for the parts of a study's runs (an xi, a sweep) every claim reading which is final
    (``reading``: part -> the claims that read it; ``frozen``: claim -> look,
    :attr:`~._registry.StudyContext.frozen_claims`), each with the latest such look; a part no claim
    reads is never frozen."""
    out = {}
    for part, claims in reading.items():
        at = [frozen.get(c) for c in claims]
        if at and all(k is not None for k in at):
            out[part] = max(at)
    return out
