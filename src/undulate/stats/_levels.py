"""Confidence levels of repeated looks: the level every interval of a look is formed at (:mod:`undulate.stats`)."""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Iterator

import numpy as np

from ..errors import ParameterError


CONFIDENCE = 0.95
"""The family-wise confidence of every claim's verdict: ``holds`` means 95 %."""

LOOK_SHARES = {1: (1.0,), 2: (0.2, 0.8), 3: (0.1, 0.3, 0.6), 4: (0.05, 0.15, 0.3, 0.5)}
"""How :func:`look_levels` splits ``alpha = 1 - CONFIDENCE`` over K looks: shares that sum to 1,
small early (the shape of O'Brien-Fleming's spending: an early look stops only for a clear answer)."""

_LEVEL: contextvars.ContextVar[float] = contextvars.ContextVar("undulate_confidence_level", default=CONFIDENCE)
_PLAN_LEVEL: contextvars.ContextVar[float | None] = contextvars.ContextVar("undulate_plan_level", default=None)


def level() -> float:
    """The confidence level of the intervals formed now (:data:`CONFIDENCE` outside a staged look)."""
    return _LEVEL.get()


def plan_level() -> float | None:
    """The level at which :func:`runs_needed` asks an interval to be decided: the last look's where a
    staged study set it (:func:`at_level`'s ``plan_at``), else None (each estimate's own level)."""
    return _PLAN_LEVEL.get()


def _confidence(v, name: str = "confidence") -> float:
    """A confidence level: a real number in (0, 1); else a ParameterError naming ``name``."""
    ok = isinstance(v, float | int | np.floating | np.integer) and not isinstance(v, bool | np.bool_)
    if not ok or not 0.0 < float(v) < 1.0:
        raise ParameterError(name, "a level in (0, 1)", v)
    return float(v)


@contextlib.contextmanager
def at_level(confidence: float, plan_at: float | None = None) -> Iterator[float]:
    """Form every interval inside the ``with`` block at ``confidence`` (0 < confidence < 1).

    ``plan_at``: the level of the look that more runs would be judged at (a staged study's last look,
    whose share of alpha is the largest); :func:`runs_needed` estimates the runs that would decide an
    interval there.  Default: each estimate's own level (``confidence`` for those formed in the block)."""
    _confidence(confidence)
    if plan_at is not None:
        _confidence(plan_at, "plan_at")
    token = _LEVEL.set(float(confidence))
    plan = _PLAN_LEVEL.set(None if plan_at is None else float(plan_at))
    try:
        yield float(confidence)
    finally:
        _PLAN_LEVEL.reset(plan)
        _LEVEL.reset(token)


def interval_note(at: float | None = None) -> str:
    """How a measured text names intervals formed at level ``at`` (an estimate's ``level``; default: the
    level now): "95 % intervals" for a single look, else that level with the family-wise 95 % it keeps,
    e.g. "97 % intervals, 95 % over the looks"."""
    lv = level() if at is None else float(at)
    if abs(lv - CONFIDENCE) < 1e-12:
        return f"{100 * CONFIDENCE:g} % intervals"
    return f"{100 * lv:.3g} % intervals, {100 * CONFIDENCE:g} % over the looks"


def look_levels(n_looks: int, confidence: float = CONFIDENCE) -> tuple[float, ...]:
    """The per-look confidence levels of a plan looked at ``n_looks`` times.

    Bonferroni over the looks: look k forms its intervals at ``1 - alpha_k``
    with ``sum(alpha_k) = alpha = 1 - confidence`` (shares
    :data:`LOOK_SHARES`).  By the union bound the chance that *any* look's
    interval misses the true value is at most ``alpha``, whatever the looks'
    dependence, so a verdict taken at whichever look decides it keeps the
    family-wise ``confidence`` (``holds`` means 95 %).  ``n_looks`` beyond the
    table split alpha equally.
    """
    if isinstance(n_looks, bool) or not isinstance(n_looks, int) or n_looks < 1:
        raise ParameterError("n_looks", "an integer >= 1", n_looks)
    _confidence(confidence)
    alpha = 1.0 - confidence
    shares = LOOK_SHARES.get(n_looks, (1.0 / n_looks,) * n_looks)
    return tuple(1.0 - alpha * s for s in shares)
