"""Fitted numbers with their uncertainty, on :mod:`scipy.stats`.

Every number a study fits (a slope, an RMS residual, a threshold, a
stiffness, an R^2, a rank correlation) is an :class:`Estimate`: the value,
its standard error where one is defined, and a 95 % interval with the method
that gave it.  Bootstrap intervals are seeded (:data:`BOOTSTRAP_SEED` unless
given), so the same data give the same interval.

* :func:`line_fit` -- least squares ``y = slope x + intercept``
  (``scipy.stats.linregress``: standard errors of slope and intercept; the
  interval is Student's t with ``n - 2`` degrees of freedom; R^2 with a
  paired bootstrap interval).
* :func:`rank_correlation` -- Spearman's rho (``scipy.stats.spearmanr``:
  tied values get their average rank) with a paired bootstrap interval.
* :func:`rms` -- root mean square with a bootstrap interval.
* :func:`mean` -- mean with its standard error (t interval).
* :func:`bootstrap` -- any statistic of one or more paired samples.

Intervals that cannot be formed (too few points, a degenerate resample) are
NaN; :meth:`Estimate.to_dict` turns NaN into ``None`` for JSON.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Estimate", "LineFit", "line_fit", "rank_correlation", "rms", "std", "mean", "bootstrap",
           "BOOTSTRAP_SEED", "N_RESAMPLES", "CONFIDENCE"]

CONFIDENCE = 0.95
BOOTSTRAP_SEED = 20240601
"""Seed of every bootstrap unless the caller gives one (results are reproducible)."""
N_RESAMPLES = 2000


def _f(v: Any) -> float:
    try:
        v = float(v)
    except (TypeError, ValueError):
        return math.nan
    return v


@dataclass(frozen=True)
class Estimate:
    """A fitted number with its uncertainty.

    ``value``; ``stderr`` (NaN where the method gives none); ``low``, ``high``:
    the 95 % interval; ``n``: data points used; ``method``: how the interval
    was made (``"t"``, ``"bootstrap percentile"``, ...).
    """

    value: float
    stderr: float = math.nan
    low: float = math.nan
    high: float = math.nan
    n: int = 0
    method: str = ""

    @property
    def finite(self) -> bool:
        return math.isfinite(self.value)

    @property
    def has_interval(self) -> bool:
        return math.isfinite(self.low) and math.isfinite(self.high)

    def scaled(self, factor: float) -> Estimate:
        """The same estimate in other units (``factor > 0``)."""
        return Estimate(self.value * factor, self.stderr * factor, self.low * factor, self.high * factor,
                        self.n, self.method)

    def inside(self, lo: float = -math.inf, hi: float = math.inf) -> bool | None:
        """True if the whole interval lies in ``[lo, hi]``, False if it lies wholly outside,
        None when it straddles a bound or there is no interval."""
        if not self.has_interval:
            return None
        if lo <= self.low and self.high <= hi:
            return True
        if self.high < lo or self.low > hi:
            return False
        return None

    def to_dict(self) -> dict[str, Any]:
        def j(v: float) -> float | None:
            return float(v) if math.isfinite(v) else None

        return {"value": j(self.value), "stderr": j(self.stderr), "ci95": [j(self.low), j(self.high)],
                "n": int(self.n), "method": self.method}

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> Estimate:
        """Inverse of :meth:`to_dict` (``None`` -> NaN); a missing dict gives a NaN estimate."""
        if not isinstance(d, dict):
            return cls(math.nan)
        lo, hi = (d.get("ci95") or [None, None])[:2]
        return cls(_f(d.get("value")), _f(d.get("stderr")), _f(lo), _f(hi), int(d.get("n") or 0),
                   str(d.get("method", "")))

    def __format__(self, spec: str) -> str:
        spec = spec or ".3g"
        if not self.finite:
            return "n/a"
        s = format(self.value, spec)
        if self.has_interval:
            s += f" [{format(self.low, spec)}, {format(self.high, spec)}]"
        elif math.isfinite(self.stderr):
            s += f" ± {format(self.stderr, spec)}"
        return s

    def __str__(self) -> str:
        return format(self, "")


NAN = Estimate(math.nan)


def _clean(*arrays) -> tuple[np.ndarray, ...]:
    arrs = [np.asarray(a, float).ravel() for a in arrays]
    ok = np.ones(arrs[0].shape, bool)
    for a in arrs:
        ok &= np.isfinite(a)
    return tuple(a[ok] for a in arrs)


def bootstrap(statistic: Callable[..., float], *samples, seed: int | None = None,
              n_resamples: int = N_RESAMPLES, vectorized: bool = False) -> tuple[float, float, float]:
    """Paired bootstrap (``scipy.stats.bootstrap``, percentile) of ``statistic(*samples)``.

    ``samples``: equally long 1-D arrays resampled together.  Returns
    ``(stderr, low, high)`` (the standard deviation of the bootstrap
    distribution and its 2.5 / 97.5 % percentiles); NaNs with fewer than 3
    points or when the resamples give no finite values.  ``vectorized``:
    ``statistic(*xs, axis=-1)`` takes every resample at once (rows of 2-D
    arrays); the resamples are the same as without it (scipy draws them
    before evaluating), only evaluated in one NumPy call instead of one
    Python call each.
    """
    from scipy import stats as st

    samples = tuple(np.asarray(s, float) for s in samples)
    if samples[0].size < 3:
        return math.nan, math.nan, math.nan

    if vectorized:
        def stat(*xs, axis=-1):
            with np.errstate(all="ignore"):
                return statistic(*xs, axis=axis)
    else:
        def stat(*xs):
            with np.errstate(all="ignore"):
                return statistic(*xs)

    import warnings

    rng = np.random.default_rng(BOOTSTRAP_SEED if seed is None else seed)
    with warnings.catch_warnings():  # degenerate resamples are handled below
        warnings.simplefilter("ignore")
        res = st.bootstrap(samples, stat, paired=True, vectorized=vectorized, n_resamples=n_resamples,
                           confidence_level=CONFIDENCE, method="percentile", rng=rng)
    dist = np.asarray(res.bootstrap_distribution, float)
    dist = dist[np.isfinite(dist)]
    if dist.size < n_resamples // 2:  # too many degenerate resamples: no honest interval
        return math.nan, math.nan, math.nan
    lo, hi = np.percentile(dist, [100 * (1 - CONFIDENCE) / 2, 100 * (1 + CONFIDENCE) / 2])
    return float(dist.std(ddof=1)), float(lo), float(hi)


@dataclass(frozen=True)
class LineFit:
    """``y = slope x + intercept`` with uncertainties; ``r2``: coefficient of determination."""

    slope: Estimate
    intercept: Estimate
    r2: Estimate
    n: int

    def to_dict(self) -> dict[str, Any]:
        return {"slope": self.slope.to_dict(), "intercept": self.intercept.to_dict(),
                "r2": self.r2.to_dict(), "n": self.n}


def _pearson_rows(a, b, axis=-1):
    """Pearson's r along ``axis`` (every resample at once); NaN where either has no spread."""
    a = np.moveaxis(np.asarray(a, float), axis, -1)
    b = np.moveaxis(np.asarray(b, float), axis, -1)
    ac = a - a.mean(axis=-1, keepdims=True)
    bc = b - b.mean(axis=-1, keepdims=True)
    with np.errstate(all="ignore"):
        r = np.clip((ac * bc).sum(axis=-1) / np.sqrt((ac * ac).sum(axis=-1) * (bc * bc).sum(axis=-1)), -1.0, 1.0)
    flat = (np.ptp(a, axis=-1) == 0) | (np.ptp(b, axis=-1) == 0)
    return np.where(flat, np.nan, r)


def line_fit(x, y, *, seed: int | None = None) -> LineFit:
    """Least squares of ``y`` on ``x`` (NaNs dropped): ``scipy.stats.linregress``.

    Slope and intercept: standard errors from linregress and Student-t 95 %
    intervals (``n - 2`` degrees of freedom); R^2: paired bootstrap interval.
    NaN estimates with fewer than 2 points or no spread in ``x``.
    """
    from scipy import stats as st

    x, y = _clean(x, y)
    n = int(x.size)
    if n < 2 or np.ptp(x) == 0:
        return LineFit(Estimate(math.nan, n=n), Estimate(math.nan, n=n), Estimate(math.nan, n=n), n)
    r = st.linregress(x, y)
    dof = n - 2
    q = float(st.t.ppf((1 + CONFIDENCE) / 2, dof)) if dof > 0 else math.nan
    se_s = float(r.stderr) if dof > 0 else math.nan
    se_i = float(r.intercept_stderr) if dof > 0 else math.nan
    slope = Estimate(float(r.slope), se_s, r.slope - q * se_s, r.slope + q * se_s, n, "linregress, t interval")
    icpt = Estimate(float(r.intercept), se_i, r.intercept - q * se_i, r.intercept + q * se_i, n,
                    "linregress, t interval")

    def r2_of(a, b, axis=-1):
        return _pearson_rows(a, b, axis) ** 2

    r2v = float(r.rvalue ** 2) if np.ptp(y) > 0 else math.nan
    se, lo, hi = bootstrap(r2_of, x, y, seed=seed, vectorized=True)
    return LineFit(slope, icpt, Estimate(r2v, se, lo, hi, n, "bootstrap percentile"), n)


def rank_correlation(x, y, *, seed: int | None = None) -> Estimate:
    """Spearman's rho of ``y`` against ``x`` (ties get average ranks), with a paired
    bootstrap 95 % interval; NaNs dropped; NaN with fewer than 3 points."""
    from scipy import stats as st

    x, y = _clean(x, y)
    n = int(x.size)
    if n < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return Estimate(math.nan, n=n, method="spearmanr")

    def rho_rows(a, b, axis=-1):  # spearmanr of every resample: Pearson's r of the (tie-averaged) ranks
        return _pearson_rows(st.rankdata(a, axis=axis), st.rankdata(b, axis=axis), axis)

    se, lo, hi = bootstrap(rho_rows, x, y, seed=seed, vectorized=True)
    return Estimate(float(st.spearmanr(x, y).statistic), se, lo, hi, n, "spearmanr, bootstrap percentile")


def rms(values, *, seed: int | None = None) -> Estimate:
    """Root mean square of the finite ``values``, with a bootstrap 95 % interval."""
    (v,) = _clean(values)
    if v.size == 0:
        return Estimate(math.nan, method="bootstrap percentile")

    def f(a, axis=-1):
        return np.sqrt(np.mean(a * a, axis=axis))

    se, lo, hi = bootstrap(f, v, seed=seed, vectorized=True)
    return Estimate(float(f(v)), se, lo, hi, int(v.size), "bootstrap percentile")


def std(values, *, seed: int | None = None) -> Estimate:
    """Standard deviation (ddof = 0) of the finite ``values``, with a bootstrap 95 % interval."""
    (v,) = _clean(values)
    if v.size == 0:
        return Estimate(math.nan, method="bootstrap percentile")
    se, lo, hi = bootstrap(lambda a, axis=-1: np.std(a, axis=axis), v, seed=seed, vectorized=True)
    return Estimate(float(np.std(v)), se, lo, hi, int(v.size), "bootstrap percentile")


def mean(values) -> Estimate:
    """Mean of the finite ``values`` with its standard error and a t 95 % interval."""
    from scipy import stats as st

    (v,) = _clean(values)
    n = int(v.size)
    if n == 0:
        return Estimate(math.nan, method="t interval")
    m = float(v.mean())
    if n < 2:
        return Estimate(m, n=n, method="t interval")
    se = float(v.std(ddof=1) / math.sqrt(n))
    q = float(st.t.ppf((1 + CONFIDENCE) / 2, n - 1))
    return Estimate(m, se, m - q * se, m + q * se, n, "t interval")


def estimates(values: Sequence[Estimate]) -> list[dict[str, Any]]:
    """``[e.to_dict() for e in values]``."""
    return [e.to_dict() for e in values]
