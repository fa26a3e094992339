"""undulate.stats (uncertainties on scipy.stats) and undulate._io (the one atomic writer)."""

from __future__ import annotations

import math
import os
import stat

import numpy as np
import pytest
import xarray as xr

from undulate import stats
from undulate._io import atomic_output, remove_temporaries, write_netcdf


def test_line_fit_interval_covers_the_true_slope_at_the_stated_rate():
    rng = np.random.default_rng(1)
    x = np.linspace(0, 1, 12)
    hits = 0
    for _ in range(200):
        f = stats.line_fit(x, 1.5 * x - 0.2 + rng.normal(0, 0.1, x.size))
        hits += f.slope.low <= 1.5 <= f.slope.high
        assert f.slope.stderr > 0 and f.intercept.low < f.intercept.value < f.intercept.high
    assert 0.91 <= hits / 200 <= 0.98  # a 95 % interval


def test_line_fit_matches_least_squares_and_reports_r2():
    x = np.array([0.0, 1, 2, 3, 4, np.nan])
    y = np.array([1.0, 3.1, 4.9, 7.2, 8.8, 5.0])
    f = stats.line_fit(x, y)
    slope, icpt = np.polyfit(x[:5], y[:5], 1)
    assert f.n == 5 and f.slope.value == pytest.approx(slope) and f.intercept.value == pytest.approx(icpt)
    assert f.r2.value == pytest.approx(np.corrcoef(x[:5], y[:5])[0, 1] ** 2)
    assert f.r2.low <= f.r2.value <= f.r2.high <= 1
    assert math.isnan(stats.line_fit([1.0, 1.0], [2.0, 3.0]).slope.value)  # no spread in x


def test_rank_correlation_gives_ties_their_average_rank_and_is_seeded():
    # tied y values: spearmanr uses average ranks (argsort ranking would order them arbitrarily)
    r = stats.rank_correlation([0, 1, 2, 3, 4], [4, 2, 2, 2, 0])
    assert r.value == pytest.approx(-0.8944271909999157)  # ranks 1, 3, 3, 3, 5
    # 5! / 3! = 20 distinct orderings: the most extreme one comes by chance 1 in 20, 5 %, which no 95 %
    # interval may exclude 0 on: no interval
    assert not r.has_interval and r == stats.rank_correlation([0, 1, 2, 3, 4], [4, 2, 2, 2, 0])
    r = stats.rank_correlation([0, 1, 2, 3, 4, 5], [5, 4, 2, 2, 2, 0])
    assert r.low <= r.value <= r.high and r == stats.rank_correlation([0, 1, 2, 3, 4, 5], [5, 4, 2, 2, 2, 0])
    assert math.isnan(stats.rank_correlation([0, 1], [1, 0]).value)


def test_rms_and_estimate_judgement():
    e = stats.rms([0.1, -0.1, 0.1, -0.1, 0.1])
    assert e.value == pytest.approx(0.1) and e.low == pytest.approx(0.1) and e.high == pytest.approx(0.1)
    assert stats.Estimate(1.0, 0.05, 0.9, 1.1).inside(0.8, 1.2) is True
    assert stats.Estimate(1.0, 0.2, 0.7, 1.3).inside(0.8, 1.2) is None
    assert stats.Estimate(2.0, 0.1, 1.8, 2.2).inside(0.8, 1.2) is False
    d = stats.Estimate(1.0, 0.05, 0.9, 1.1, 7, "t").to_dict()
    assert d == {"value": 1.0, "stderr": 0.05, "ci95": [0.9, 1.1], "n": 7, "method": "t",
                 "level": 0.95, "units": 0, "dof": None}
    assert stats.Estimate.from_dict(d) == stats.Estimate(1.0, 0.05, 0.9, 1.1, 7, "t")
    # without an interval the spread is shown, unsigned whatever the value's format
    assert f"{stats.Estimate(-0.5, 0.82):+.2f}" == "-0.50 ± 0.82"
    assert f"{stats.Estimate(-0.5, 0.82, -1.0, 0.1):+.2f}" == "-0.50 [-1.00, +0.10]"


def test_atomic_output_fsyncs_sets_umask_permissions_and_cleans_up(tmp_path):
    old = os.umask(0o027)
    try:
        with atomic_output(tmp_path / "a.txt") as tmp:
            tmp.write_text("x")
            assert tmp.parent == tmp_path and tmp.name.startswith(".a.txt.")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "a.txt").stat().st_mode) == 0o640
    (tmp_path / "b.txt").write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_output(tmp_path / "b.txt") as tmp:
            tmp.write_text("half")
            raise RuntimeError("killed")
    assert (tmp_path / "b.txt").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]
    (tmp_path / ".c.nc.0123.tmp").write_text("left by a kill -9")
    (tmp_path / ".d.gif.0123.tmp.gif").write_text("left by a kill -9")
    assert remove_temporaries(tmp_path) == 2


def test_write_netcdf_round_trip(tmp_path):
    ds = xr.Dataset({"v": ("t", np.arange(4.0), {"units": "m"})})
    p = write_netcdf(ds, tmp_path / "d.nc")
    assert xr.load_dataset(p, engine="h5netcdf")["v"].attrs["units"] == "m"


def test_estimates_without_an_interval_are_equal_on_every_python():
    """NaN marks what a method does not give; two such estimates are equal and hash alike (Python 3.13's
    dataclass equality compares fields with ==, and nan != nan: an estimate differed from its own copy)."""
    import copy
    import math
    import pickle

    a = stats.Estimate(0.5, float("nan"), float("nan"), float("nan"), 3, "spearmanr")
    b = stats.Estimate(0.5, math.nan, math.nan, math.nan, 3, "spearmanr")
    assert a == b and hash(a) == hash(b) and a == copy.deepcopy(a) and a == pickle.loads(pickle.dumps(a))
    assert a == stats.Estimate.from_dict(a.to_dict())
    assert a != stats.Estimate(0.5, 0.1, math.nan, math.nan, 3, "spearmanr") and a != (0.5,)
    assert stats.Estimate(math.nan) == stats.NAN and len({a, b, stats.NAN}) == 2
    fit = stats.line_fit([0.0, 1.0, 2.0], [0.0, 1.0, 2.5])
    assert fit == copy.deepcopy(fit)  # a LineFit compares its estimates
