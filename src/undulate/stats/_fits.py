"""Fits with their intervals: lines (plain, mirrored, clustered), rank correlation, RMS, std, mean."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ParameterError
from ._bootstrap import _clean, _paired, _values, bootstrap
from ._estimate import Estimate
from ._levels import level


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
    intervals (``n - 2`` degrees of freedom); R^2: paired BCa bootstrap interval.
    NaN estimates with fewer than 2 points or no spread in ``x``.  Equal ``y`` (at least 3 points) lie
    exactly on a flat line: slope 0 and intercept ``y`` with standard error 0, as for any other exact
    line (``linregress`` leaves that one's standard errors NaN: its correlation is undefined without
    spread in ``y``); their R^2 is NaN.
    """
    from scipy import stats as st

    x, y = _clean(x, y)
    n = int(x.size)
    if n < 2 or np.ptp(x) == 0:
        return LineFit(Estimate(math.nan, n=n), Estimate(math.nan, n=n), Estimate(math.nan, n=n), n)
    r = st.linregress(x, y)
    dof = n - 2
    conf = level()
    q = float(st.t.ppf((1 + conf) / 2, dof)) if dof > 0 else math.nan
    flat = dof > 0 and np.ptp(y) == 0  # an exact flat line: no residual, so no uncertainty
    se_s = 0.0 if flat else float(r.stderr) if dof > 0 else math.nan
    se_i = 0.0 if flat else float(r.intercept_stderr) if dof > 0 else math.nan
    slope = Estimate(float(r.slope), se_s, r.slope - q * se_s, r.slope + q * se_s, n, "linregress, t interval",
                     conf, n, dof)
    icpt = Estimate(float(r.intercept), se_i, r.intercept - q * se_i, r.intercept + q * se_i, n,
                    "linregress, t interval", conf, n, dof)

    def r2_of(a, b, axis=-1):
        return _pearson_rows(a, b, axis) ** 2

    r2v = float(r.rvalue ** 2) if np.ptp(y) > 0 else math.nan
    se, lo, hi = bootstrap(r2_of, x, y, seed=seed, vectorized=True)
    return LineFit(slope, icpt, Estimate(r2v, se, lo, hi, n, "bootstrap BCa", conf, n, n - 1), n)


def is_mirror_design(x) -> bool:
    """Whether the finite ``x`` are a mirror-symmetric design: every ``x != 0`` once at ``+|x|`` and once
    at ``-|x|`` (matched to 1e-9), any number of rows at ``x = 0``."""
    x = np.asarray(x, float).ravel()
    x = x[np.isfinite(x)]
    key = np.round(np.abs(x), 9)
    return all(np.sum(x[key == k] > 0) == 1 and np.sum(x[key == k] < 0) == 1 for k in np.unique(key[key > 0]))


def mirrored_line_fit(x, y, *, seed: int | None = None) -> LineFit:
    """Least squares of ``y`` on ``x`` over a mirror-symmetric design (:func:`is_mirror_design`; a study's
    runs at +dphi and -dphi, one design point seen mirrored, their residuals nearly opposite).
    :func:`line_fit`'s t interval counts the two rows as independent and is too narrow by about sqrt(2)
    there (docs/verdicts.md, "Staged runs"); here the pairs are the units.

    Slope: the half-differences ``d = (y(x) - y(-x)) / 2`` of the G complete pairs (the intercept
    cancels) regressed on ``x`` through the origin, Student's t on ``G - 1`` degrees of freedom; the
    value is the least-squares slope of the rows used.  Intercept: the mean of the half-sums
    ``(y(x) + y(-x)) / 2`` and of the rows at ``x = 0``, t on their count less one.  R^2: the least
    squares' over the rows used, BCa bootstrap resampling each pair together (:func:`bootstrap`).  Rows
    used: the complete pairs and the rows at ``x = 0``; a pair one of whose ``y`` is NaN (a run without a
    result) is left out, ``n`` counts the rest.  No interval for the slope with fewer than 2 pairs.
    ``ValueError`` when the finite ``x`` are not a mirror-symmetric design.
    """
    from scipy import stats as st

    x, y = _paired(x, y)
    y = y[np.isfinite(x)]
    x = x[np.isfinite(x)]
    if not is_mirror_design(x):
        raise ParameterError("x", "a mirror-symmetric design: every x != 0 once at +|x| and once at -|x|")
    key = np.round(np.abs(x), 9)
    xs, d, halves, labels = [], [], [], np.full(x.size, -1)
    at_zero = np.flatnonzero((key == 0) & np.isfinite(y))
    labels[at_zero] = np.arange(at_zero.size) + x.size  # each row at x = 0 is its own unit
    for k in np.unique(key[key > 0]):
        up, down = int(np.flatnonzero((key == k) & (x > 0))[0]), int(np.flatnonzero((key == k) & (x < 0))[0])
        if np.isfinite(y[up]) and np.isfinite(y[down]):
            xs.append(float(k))
            d.append((y[up] - y[down]) / 2)
            halves.append((y[up] + y[down]) / 2)
            labels[[up, down]] = len(xs) - 1
    units = halves + [float(v) for v in y[at_zero]]  # the intercept's: half-sums and rows at x = 0
    used = labels >= 0
    xu, yu, lab = x[used], y[used], labels[used]
    xs_, d_ = np.asarray(xs), np.asarray(d)
    g, n, conf = len(xs), int(used.sum()), level()
    method = "mirror pairs: fold, t interval"
    if g == 0:
        return LineFit(Estimate(math.nan, n=n), mean(units), Estimate(math.nan, n=n), n)
    sxx = float(xs_ @ xs_)
    b = float(xs_ @ d_) / sxx
    if g >= 2:
        r = d_ - b * xs_
        se = math.sqrt(float(r @ r) / (g - 1) / sxx)
        q = float(st.t.ppf((1 + conf) / 2, g - 1))
        slope = Estimate(b, se, b - q * se, b + q * se, n, method, conf, g, g - 1)
    else:
        slope = Estimate(b, n=n, method=method)
    return LineFit(slope, mean(units), _clustered_r2(xu, yu, lab, seed), n)


def joined_clusters(*labelings) -> np.ndarray:
    """One cluster label per row (0, 1, ...) joining every labeling given: two rows share a cluster
    when any labeling gives them the same label, directly or through other rows (the connected
    components of the rows linked by each labeling; ``scipy.sparse.csgraph``).  E.g. a run's
    neighbour pairs (one run) and the runs at +dphi and -dphi (one design point mirrored)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    labs = [np.asarray(lab).ravel() for lab in labelings]
    if not labs:
        raise ParameterError("labelings", "at least one labeling")
    n = labs[0].size
    if any(lab.size != n for lab in labs):
        raise ParameterError("labelings", f"one label per row ({n}) each", [lab.size for lab in labs])
    cols = []
    for lab in labs:  # each row linked to the first row of its label
        _, first, which = np.unique(lab, return_index=True, return_inverse=True)
        cols.append(first[which.ravel()])
    rows = np.tile(np.arange(n), len(labs))
    graph = coo_matrix((np.ones(rows.size), (rows, np.concatenate(cols))), shape=(n, n))
    return connected_components(graph, directed=False)[1]


CLUSTERED_SLOPE_METHOD = "least squares, cluster jackknife CR3, t on G - 1"


def clustered_line_fit(x, y, clusters, *, seed: int | None = None) -> LineFit:
    """Least squares of ``y`` on ``x`` where the rows of a cluster may share their errors (the neighbour
    pairs of one run of a group, the runs at +dphi and -dphi of a mirrored grid): rows with a NaN ``x``
    or ``y`` dropped, ``clusters`` one label per row.

    Slope and intercept: the least-squares values, with the cluster-robust CR3 standard error (the
    delete-one-cluster jackknife ``(G - 1) / G * sum_g (b_(g) - b)^2`` about the full fit ``b``, for
    ``G`` clusters) and Student's t on ``G - 1`` degrees of freedom (MacKinnon, Nielsen & Webb 2023,
    J. Econometrics 232, 272: on few clusters CR3 with t(G - 1) keeps its level where the usual CR1
    sandwich does not).  Measured here (docs/verdicts.md): at 95 % it covered 94-95 % on 4-12
    clusters of rows sharing a run effect (the rows' t: 58-81 %, CR1: 80-91 %), of rows whose errors
    cancel (the rows' t: 99 %), and of independent rows.  ``units`` the clusters and ``dof`` ``G - 1``,
    so :func:`runs_needed` extrapolates in clusters.  R^2: the rows' value, BCa bootstrap resampling
    each cluster together.  No interval with fewer than 3 clusters or where leaving a cluster out
    leaves no spread in ``x``.
    """
    from scipy import stats as st

    x, y = _paired(x, y)
    labels = np.asarray(clusters).ravel()
    if labels.size != x.size:
        raise ParameterError("clusters", f"one label per row ({x.size})", labels.size)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y, labels = x[ok], y[ok], labels[ok]
    n = int(x.size)
    if n < 2 or np.ptp(x) == 0:
        return LineFit(Estimate(math.nan, n=n), Estimate(math.nan, n=n), Estimate(math.nan, n=n), n)
    _, which = np.unique(labels, return_inverse=True)
    g = int(which.max()) + 1

    def fit(keep: np.ndarray) -> np.ndarray:  # (intercept, slope) of the rows kept; NaN without spread
        xk, yk = x[keep], y[keep]
        if xk.size < 2 or np.ptp(xk) == 0:
            return np.full(2, np.nan)
        xm, ym = xk.mean(), yk.mean()
        b = float((xk - xm) @ (yk - ym) / ((xk - xm) @ (xk - xm)))
        return np.array([ym - b * xm, b])

    full = fit(np.ones(n, bool))
    conf = level()
    method = f"{CLUSTERED_SLOPE_METHOD}, {g} clusters"
    se = np.full(2, np.nan)
    if g >= 3:
        jack = np.array([fit(which != k) for k in range(g)])
        if np.isfinite(jack).all():
            se = np.sqrt((g - 1) / g * np.sum((jack - full) ** 2, axis=0))
    q = float(st.t.ppf((1 + conf) / 2, g - 1)) if g >= 3 else math.nan

    def est(k: int) -> Estimate:
        v = float(full[k])
        if not math.isfinite(se[k]):
            return Estimate(v, n=n, method=method)
        return Estimate(v, float(se[k]), v - q * se[k], v + q * se[k], n, method, conf, g, g - 1)

    return LineFit(est(1), est(0), _clustered_r2(x, y, which, seed, "clusters"), n)


def _clustered_r2(x: np.ndarray, y: np.ndarray, labels: np.ndarray, seed: int | None,
                  what: str = "mirror pairs") -> Estimate:
    """R^2 of ``y`` on ``x`` with a BCa bootstrap interval resampling the rows of a label together
    (per label: the count and the sums of x, y, x^2, y^2 and xy)."""
    n = int(x.size)
    if n < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return Estimate(math.nan, n=n)
    r2v = float(_pearson_rows(x, y) ** 2)
    _, which = np.unique(labels, return_inverse=True)
    k = int(which.max()) + 1
    sums = [np.bincount(which, w, minlength=k) for w in (None, x, y, x * x, y * y, x * y)]

    def r2_of(c, sx, sy, sxx, syy, sxy, axis=-1):
        m, sx, sy = np.sum(c, axis=axis), np.sum(sx, axis=axis), np.sum(sy, axis=axis)
        vx = m * np.sum(sxx, axis=axis) - sx * sx
        vy = m * np.sum(syy, axis=axis) - sy * sy
        cov = m * np.sum(sxy, axis=axis) - sx * sy
        with np.errstate(all="ignore"):  # a resample of collinear rows rounds to 1 + 2e-16: an R^2 is at most 1
            return np.where((vx > 0) & (vy > 0), np.minimum(cov * cov / (vx * vy), 1.0), np.nan)

    se, lo, hi = bootstrap(r2_of, *sums, seed=seed, vectorized=True)
    return Estimate(r2v, se, lo, hi, n, f"bootstrap BCa over {what}", level(), k, k - 1)


def _orderings_suffice(orderings: float, level_: float) -> bool:
    """Whether a rank statistic with ``orderings`` distinct orderings of its data can exclude no trend at
    ``level_``: the most extreme ordering comes by chance once in that many, so at least ``2 / (1 - level)``."""
    return orderings * (1.0 - level_) >= 2.0


def rank_correlation_points(level_: float | None = None) -> int:
    """The fewest points (without ties) for which :func:`rank_correlation` gives an interval at ``level_``
    (None: the current :func:`level`): the smallest ``n`` with ``n! (1 - level) >= 2``; 5 up to 98.3 %."""
    lv = level() if level_ is None else float(level_)
    n = 3
    while not _orderings_suffice(math.factorial(n), lv):
        n += 1
    return n


def rank_correlation(x, y, *, seed: int | None = None) -> Estimate:
    """Spearman's rho of ``y`` against ``x`` (ties get average ranks), with a paired percentile
    bootstrap 95 % interval; NaNs dropped; NaN with fewer than 3 points.

    No interval (the value and its bootstrap standard error only) while the distinct orderings of the
    data, ``n!`` over the factorials of the tie counts in ``x`` and in ``y``, are fewer than ``2 / (1 -
    level)``: with no trend the most extreme ordering comes by chance once in that many, so no data
    could exclude rho = 0 at the level (without ties: 5 points up to 98.3 %, 6 up to 99.7 %), whereas
    every resample of a monotone sample is monotone and the bootstrap's interval is [-1, -1] (three
    channel widths in a monotone order would otherwise be judged rho = -1 [-1, -1])."""
    from scipy import stats as st

    x, y = _clean(x, y)
    n = int(x.size)
    if n < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return Estimate(math.nan, n=n, method="spearmanr")

    def rho_rows(a, b, axis=-1):  # spearmanr of every resample: Pearson's r of the (tie-averaged) ranks
        return _pearson_rows(st.rankdata(a, axis=axis), st.rankdata(b, axis=axis), axis)

    # a rank statistic: BCa gains nothing on it (bivariate normal samples of 9-37 points, six rows: the
    # percentile interval misses at most 5.5 % a side, BCa 4.0 %, but BCa's misses sum to 22.9 points
    # against 17.4; explorations/interval_coverage.py --pairs)
    se, lo, hi = bootstrap(rho_rows, x, y, seed=seed, vectorized=True, method="percentile")
    rho = float(st.spearmanr(x, y).statistic)
    ties = [math.factorial(int(c)) for v in (x, y) for c in np.unique(v, return_counts=True)[1]]
    if not _orderings_suffice(math.factorial(n) / math.prod(ties), level()):
        return Estimate(rho, se, n=n, method="spearmanr; too few orderings for an interval at this level",
                        level=level())
    return Estimate(rho, se, lo, hi, n, "spearmanr, bootstrap percentile", level(), n, n - 1)


def _root_mean_square(values, centred: bool, seed: int | None, clusters=None) -> Estimate:
    """``sqrt(mean(c**2))`` of the finite ``values`` (``c``: the values, less their mean if ``centred``),
    with a bias-corrected and accelerated (BCa) bootstrap interval at the expanded levels (:func:`bootstrap`,
    :func:`expanded_z`; the levels of the design points resampled, so of the clusters where given).

    The percentile bootstrap of a root mean square undercovers on its upper side: its bound cannot
    exceed ``max |v|``, and the statistic's skew is not corrected.  Normal samples (seeded trials,
    ``explorations/interval_coverage.py``): the true RMS above the percentile interval in 7 % of
    samples of 49 points and 18 % of 9 (nominal 2.5 %); BCa corrects part of it, and more for heavy
    tails, and the expanded levels a little more (12 % at 9 with BCa, 9.5 % with both; docs/verdicts.md,
    "How an interval is formed").  A studentized bootstrap covers better on
    normal samples but is unstable on the studies' residuals (mirror pairs give equal squares, and
    near-zero spreads in resamples): tried and set aside.  ``stderr``: the bootstrap distribution's
    standard deviation.  An exact interval when every resample gives the value (all ``c**2`` equal);
    NaN with no values, no interval with fewer than 3 values or 3 clusters.

    ``clusters``: one label per value; the values of a label are resampled together (a cluster
    bootstrap), as one design point: a study's residuals at +dphi and -dphi are one pair seen mirrored,
    nearly equal in size, and resampled apart they would count each design point twice and narrow the
    interval.  The value is the same with or without clusters (every value counts once).
    """
    method = "bootstrap BCa" if clusters is None else "bootstrap BCa over clusters"
    v = _values("values", values)
    labels = np.arange(v.size) if clusters is None else np.asarray(clusters).ravel()
    if labels.shape != v.shape:
        raise ParameterError("clusters", f"one label per value ({v.size})", labels.size)
    keep = np.isfinite(v)
    v, labels = v[keep], labels[keep]
    if v.size == 0:
        return Estimate(math.nan, method=method)
    c = v - v.mean() if centred else v
    n, value = int(v.size), float(np.sqrt(np.mean(c * c)))
    _, which = np.unique(labels, return_inverse=True)
    k = int(which.max()) + 1
    if n < 3 or k < 3:
        return Estimate(value, n=n, method=method)
    if np.ptp(c * c) == 0:
        return Estimate(value, 0.0, value, value, n, method, level(), k, k - 1)
    # per cluster: the count, the sum and the sum of squares of c (c centred on the whole sample's mean:
    # a resample's variance is then a difference of small sums, with no cancellation)
    count, total, squares = (np.bincount(which, w, minlength=k) for w in (None, c, c * c))

    def f(cnt, tot, sq, axis=-1):
        m = np.sum(cnt, axis=axis)
        ms = np.sum(sq, axis=axis) / m - (np.sum(tot, axis=axis) / m) ** 2 * centred
        return np.sqrt(np.maximum(ms, 0.0))

    se, lo, hi = bootstrap(f, count, total, squares, seed=seed, vectorized=True)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return Estimate(value, n=n, method=method)
    return Estimate(value, se, lo, hi, n, method, level(), k, k - 1)


def rms(values, *, seed: int | None = None, clusters=None) -> Estimate:
    """Root mean square of the finite ``values``, with a BCa bootstrap 95 % interval
    (:func:`_root_mean_square`; ``clusters``: labels of values resampled together)."""
    return _root_mean_square(values, False, seed, clusters)


def std(values, *, seed: int | None = None, clusters=None) -> Estimate:
    """Standard deviation (ddof = 0) of the finite ``values``, with a BCa bootstrap 95 % interval
    (:func:`_root_mean_square` of the centred values; ``clusters``: labels of values resampled together)."""
    return _root_mean_square(values, True, seed, clusters)


def mean(values) -> Estimate:
    """Mean of the finite ``values`` with its standard error and a t 95 % interval."""
    from scipy import stats as st

    (v,) = _clean(values, names=("values",))
    n = int(v.size)
    if n == 0:
        return Estimate(math.nan, method="t interval")
    m = float(v.mean())
    if n < 2:
        return Estimate(m, n=n, method="t interval")
    se = float(v.std(ddof=1) / math.sqrt(n))
    conf = level()
    q = float(st.t.ppf((1 + conf) / 2, n - 1))
    return Estimate(m, se, m - q * se, m + q * se, n, "t interval", conf, n, n - 1)
