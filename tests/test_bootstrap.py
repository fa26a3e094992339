"""The vectorised bootstrap gives the numbers of one call per resample."""

from __future__ import annotations

import itertools

import numpy as np
import pytest


def test_vectorized_bootstrap_equals_one_call_per_resample():
    """The statistics the studies bootstrap (R^2, Spearman with ties, RMS, std) are evaluated on every
    resample at once; same resamples, the same numbers as one Python call per resample (to rounding)."""
    from scipy import stats as st

    from undulate import stats

    rng = np.random.default_rng(5)
    for n in (4, 9, 30, 120):
        x = rng.normal(size=n)
        y = np.round(2 * x + rng.normal(size=n))  # ties
        y[: max(1, n // 10)] = y[0]
        pairs = [
            (lambda a, b: float(np.corrcoef(a, b)[0, 1] ** 2) if np.ptp(a) and np.ptp(b) else np.nan,
             lambda a, b, axis=-1: stats._pearson_rows(a, b, axis) ** 2, (x, y)),
            (lambda a, b: float(st.spearmanr(a, b).statistic) if np.ptp(a) and np.ptp(b) else np.nan,
             lambda a, b, axis=-1: stats._pearson_rows(st.rankdata(a, axis=axis), st.rankdata(b, axis=axis), axis),
             (x, y)),
            (lambda a: float(np.sqrt(np.mean(a * a))), lambda a, axis=-1: np.sqrt(np.mean(a * a, axis=axis)), (y,)),
            (lambda a: float(np.std(a)), lambda a, axis=-1: np.std(a, axis=axis), (y,)),
        ]
        for (one, rows, samples), method in itertools.product(pairs, stats.BOOTSTRAP_METHODS):
            ref = stats.bootstrap(one, *samples, seed=11, method=method)
            vec = stats.bootstrap(rows, *samples, seed=11, vectorized=True, method=method)
            np.testing.assert_allclose(vec, ref, rtol=1e-12, atol=1e-14, equal_nan=True)


def _scipy_bca(rows, *samples, seed):
    import warnings

    from scipy import stats as st

    from undulate import stats

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = st.bootstrap(samples, rows, paired=True, vectorized=True, n_resamples=stats.N_RESAMPLES,
                           method="BCa", rng=np.random.default_rng(seed))
    return res.standard_error, res.confidence_interval.low, res.confidence_interval.high


def test_bca_interval_is_scipys_where_every_resample_is_defined():
    """With no undefined resample the package's BCa interval (its own z0 and jackknife acceleration on
    scipy's resamples) is ``scipy.stats.bootstrap(method="BCa")``'s, for one and two paired samples,
    vectorized or not, and at another level; the percentile one is the distribution's percentiles."""
    from undulate import stats

    rng = np.random.default_rng(3)
    for n in (5, 12, 40):
        x = rng.normal(size=n)
        y = 0.8 * x + 0.6 * rng.normal(size=n)
        z = rng.lognormal(size=n)
        cases = [
            (lambda a, b, axis=-1: stats._pearson_rows(a, b, axis) ** 2,
             lambda a, b: float(np.corrcoef(a, b)[0, 1] ** 2), (x, y)),
            (lambda a, axis=-1: np.sqrt(np.mean(a * a, axis=axis)), lambda a: float(np.sqrt(np.mean(a * a))), (z,)),
            (lambda a, axis=-1: np.mean(a, axis=axis), lambda a: float(np.mean(a)), (z,)),
        ]
        for rows, one, samples in cases:
            if n == 5 and len(samples) == 2:
                continue  # a resample of 5 pairs can have no spread: scipy's interval is NaN (below)
            ref = _scipy_bca(rows, *samples, seed=11)
            np.testing.assert_allclose(stats.bootstrap(rows, *samples, seed=11, vectorized=True), ref, rtol=1e-10)
            np.testing.assert_allclose(stats.bootstrap(one, *samples, seed=11), ref, rtol=1e-10)
    with stats.at_level(0.99):
        wide = stats.bootstrap(cases[1][0], z, seed=11, vectorized=True)
    narrow = stats.bootstrap(cases[1][0], z, seed=11, vectorized=True)
    assert wide[1] < narrow[1] < narrow[2] < wide[2]
    se, lo, hi = stats.bootstrap(cases[1][0], z, seed=11, vectorized=True, method="percentile")
    assert se == pytest.approx(narrow[0]) and (lo, hi) != pytest.approx(narrow[1:])


def test_bca_interval_leaves_undefined_resamples_out():
    """R^2 of 5 points: some resamples repeat one point and have no spread (R^2 undefined). scipy's BCa
    interval is then NaN; the package's leaves those resamples out (and says NaN only when over half
    are undefined or the sample's own statistic is)."""
    from undulate import stats

    x = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    y = np.array([0.1, 0.9, 2.3, 2.8, 4.2])

    def r2(a, b, axis=-1):
        return stats._pearson_rows(a, b, axis) ** 2

    assert np.isnan(_scipy_bca(r2, x, y, seed=11)[1])
    se, lo, hi = stats.bootstrap(r2, x, y, vectorized=True)
    value = float(np.corrcoef(x, y)[0, 1] ** 2)
    assert 0 < se and lo < value <= hi <= 1.0
    fit = stats.line_fit(x, y)
    assert fit.r2.method == "bootstrap BCa" and (fit.r2.low, fit.r2.high) == pytest.approx((lo, hi))
    assert np.isnan(stats.bootstrap(r2, x, np.ones(5), vectorized=True)[1])  # R^2 of the sample undefined
    assert np.isnan(stats.bootstrap(r2, x[:2], y[:2], vectorized=True)[1])  # fewer than 3 points


def test_bootstrap_refuses_an_unknown_method():
    from undulate import stats

    with pytest.raises(ValueError, match="method must be one of BCa, percentile"):
        stats.bootstrap(np.mean, np.arange(5.0), method="basic")


def test_rms_and_std_are_scipys_bca_and_clusters_resample_design_points_together():
    """stats.rms / stats.std: scipy's BCa interval of the plain statistic (to rounding); with clusters
    of one value each, the same; with the residuals of a symmetric dphi grid, whose +dphi and -dphi
    values are one design point seen mirrored, the interval is that of the design points (each
    resampled whole), wider than the one that counts every value apart, and the value is unchanged."""
    from undulate import stats

    rng = np.random.default_rng(8)
    x = rng.normal(0.3, 1.0, 15)
    for fn, rows in ((stats.rms, lambda a, axis=-1: np.sqrt(np.mean(a * a, axis=axis))),
                     (stats.std, lambda a, axis=-1: np.std(a, axis=axis))):
        e = fn(x)
        np.testing.assert_allclose((e.stderr, e.low, e.high), _scipy_bca(rows, x, seed=stats.BOOTSTRAP_SEED),
                                   rtol=1e-10)
        one = fn(x, clusters=np.arange(x.size))
        np.testing.assert_allclose((one.value, one.low, one.high), (e.value, e.low, e.high), rtol=1e-10)
    dphi = np.linspace(-np.pi, np.pi, 17)
    half = rng.normal(0.0, 0.05, 9)  # residual at |dphi|: -r at -dphi (a mirror image), one value at 0
    res = np.where(dphi < 0, -1.0, 1.0) * half[np.round(np.abs(dphi) / (np.pi / 8)).astype(int)]
    apart, together = stats.rms(res), stats.rms(res, clusters=np.round(np.abs(dphi), 9))
    assert together.value == pytest.approx(apart.value) and together.n == apart.n == 17
    assert together.method == "bootstrap BCa over clusters"
    assert together.high - together.low > 1.2 * (apart.high - apart.low)
    assert together.low < together.value < together.high
    assert np.isnan(stats.rms(res[:4], clusters=[0, 0, 1, 1]).low)  # two clusters: no interval
    with pytest.raises(ValueError, match="one label per value"):
        stats.rms(res, clusters=[0, 1])
    with_nan = stats.rms(np.append(res, np.nan), clusters=np.append(np.round(np.abs(dphi), 9), 9.0))
    assert (with_nan.value, with_nan.low, with_nan.high) == pytest.approx((together.value, together.low, together.high))
