"""The vectorised bootstrap gives the numbers of one call per resample."""

from __future__ import annotations

import numpy as np


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
        for one, rows, samples in pairs:
            ref = stats.bootstrap(one, *samples, seed=11)
            vec = stats.bootstrap(rows, *samples, seed=11, vectorized=True)
            np.testing.assert_allclose(vec, ref, rtol=1e-12, atol=1e-14, equal_nan=True)
