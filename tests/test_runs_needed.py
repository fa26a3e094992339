"""How many runs would decide an undecided interval (``stats.runs_needed``).

The half-width of a t interval (and of a bootstrap interval at the expanded levels) narrows as
``t_dof / sqrt(n)``: on few units its quantile falls steeply as runs are added, which a plain
1/sqrt(n) rule ignores.  Asserted here: the closed form against scipy's t, the large-sample limit
(the plain rule), calibration by simulation against the runs a known spread needs, the level of the
look the runs would be judged at, the units each fit records, and the registry's use of the cap's
level for its futility stop.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats as st

from undulate import stats
from undulate.stats import Check, Estimate


def t_estimate(value, half, units, dof, level=0.99, n=None):
    """An estimate whose interval is ``value -+ half``, a t interval on ``dof`` at ``level``."""
    q = st.t.ppf((1 + level) / 2, dof)
    return Estimate(value, half / q, value - half, value + half, units if n is None else n, "t", level, units, dof)


def test_runs_needed_is_the_least_growth_whose_t_interval_clears_the_boundary():
    # a mean of 5 points at 99 % (t on 4 dof), half-width 3x its distance from the boundary
    e = t_estimate(1.0, 0.6, 5, 4)
    n = stats.runs_needed(e, 0.8)
    spread = 0.6 / st.t.ppf(0.995, 4) * math.sqrt(5)  # the sample's s

    def half(m):
        return st.t.ppf(0.995, m - 1) * spread / math.sqrt(m)

    assert half(n) <= 0.2 < half(n - 1)
    assert n < 5 * 3 ** 2  # the 1/sqrt(n) rule's 45, which keeps t on 4 dof


def test_few_mirror_pairs_no_longer_need_thousands_of_runs():
    """The docstring's example: a slope on 2 mirror pairs (4 rows, t on 1 dof at 99 %) whose
    half-width is 40 times its distance from the boundary: ~9 pairs (18 rows), not 2 x 40^2 pairs."""
    e = t_estimate(0.0, 40.0, 2, 1, n=4)
    assert stats.runs_needed(e, 1.0) == 18
    assert stats.half_width_at(e, 40.0, 18 / 4) <= 1.0 < stats.half_width_at(e, 40.0, 17 / 4)


def test_many_units_give_the_plain_rule():
    e = t_estimate(1.0, 0.3, 2000, 1998, level=0.95)
    plain = 2000 * (0.3 / 0.2) ** 2
    assert stats.runs_needed(e, 0.8) == pytest.approx(plain, rel=2e-3)
    # an estimate that records no dof keeps the plain rule exactly (its quantile's shape is the normal's)
    assert Estimate(0.955, 0.08, 0.782, 1.129, 9).within(0.8, 1.2).runs_needed == math.ceil(9 * (0.173 / 0.155) ** 2)


def test_runs_needed_is_calibrated_where_the_plain_rule_is_not():
    """Normal samples of 3 points, a mean at 99 %: the true value 1 at distance 0.5 from the boundary 0.5
    and spread 1.  The runs that would decide it on average are those at which the expected half-width
    (the true spread) reaches 0.5.  Over 2000 seeded samples whose interval straddles the boundary, the
    median estimate lies within a factor 2 of them; the plain 1/sqrt(n) rule's is over 5 times too many."""
    rng = np.random.default_rng(7)
    sigma, gap = 1.0, 0.5
    truth = next(m for m in range(2, 10_000) if st.t.ppf(0.995, m - 1) * sigma / math.sqrt(m) <= gap)
    ours, plain = [], []
    with stats.at_level(0.99):
        while len(ours) < 2000:
            e = stats.mean(rng.normal(1.0, sigma, 3))
            if not e.low <= 0.5 <= e.high:
                continue
            ours.append(stats.runs_needed(e, 0.5))
            plain.append(math.ceil(3 * ((e.value - e.low) / (e.value - 0.5)) ** 2) if e.value > 0.5 else math.inf)
    assert truth / 2 <= np.median(ours) <= 2 * truth
    assert np.median(plain) > 5 * truth


def test_the_runs_are_counted_at_the_level_they_would_be_judged_at():
    e = t_estimate(1.0, 0.6, 9, 8, level=0.995)
    at_own = stats.runs_needed(e, 0.8)
    with stats.at_level(0.995, plan_at=0.97):  # a quick study's first of three looks: the cap's look at 97 %
        at_cap = stats.runs_needed(e, 0.8)
        assert stats.plan_level() == 0.97
    assert stats.plan_level() is None
    assert at_cap < at_own
    # no dof recorded: the normal quantiles' ratio alone, squared
    legacy = Estimate(1.0, 0.1, 0.4, 1.6, 9, "x", 0.995)
    with stats.at_level(0.995, plan_at=0.97):
        ratio = st.norm.ppf(0.985) / st.norm.ppf(0.9975)
        assert stats.runs_needed(legacy, 0.8) == math.ceil(9 * (0.6 * ratio / 0.2) ** 2)
    # the same runs may already decide it at the cap's level: no more runs needed than it has
    close = t_estimate(1.0, 0.205, 30, 29, level=0.995)
    with stats.at_level(0.995, plan_at=0.97):
        assert stats.runs_needed(close, 0.8) == 30
    with pytest.raises(ValueError, match="plan_at"):
        with stats.at_level(0.99, plan_at=1.5):
            pass


def test_two_intervals_apart_need_both_half_widths_narrowed():
    a, b = t_estimate(1.0, 0.5, 4, 3), t_estimate(0.2, 0.6, 6, 5)
    c = Check.apart(a, b, "a > b")
    assert c.state is None
    g = c.growth_needed
    assert c.runs_needed == math.ceil(4 * g - 1e-9)
    facing = stats.half_width_at(a, 0.5, g) + stats.half_width_at(b, 0.6, g)
    assert facing == pytest.approx(0.8, rel=1e-6)
    assert g < ((0.5 + 0.6) / 0.8) ** 2  # fewer than the plain rule's: both t quantiles fall with the dof


def test_every_fit_records_the_units_and_dof_of_its_interval():
    rng = np.random.default_rng(3)
    x = np.linspace(-1, 1, 9)
    y = x + rng.normal(0, 0.1, 9)
    fit = stats.line_fit(x, y)
    assert (fit.slope.units, fit.slope.dof) == (9, 7) and (fit.r2.units, fit.r2.dof) == (9, 8)
    mfit = stats.mirrored_line_fit(x, y)  # 4 mirror pairs and a row at 0
    assert (mfit.slope.units, mfit.slope.dof) == (4, 3) and mfit.slope.n == 9
    assert (stats.mean(y).units, stats.mean(y).dof) == (9, 8)
    r = stats.rms(y, clusters=np.r_[np.arange(4), 4, np.arange(4)[::-1]])  # each pair one cluster
    assert (r.units, r.dof, r.n) == (5, 4, 9)
    rho = stats.rank_correlation(x, y)
    assert (rho.units, rho.dof) == (9, 8)
    # carried through the study JSON's dicts
    d = fit.slope.to_dict()
    assert d["units"] == 9 and d["dof"] == 7
    assert Estimate.from_dict(d) == fit.slope
    old = {k: v for k, v in d.items() if k not in ("units", "dof")}  # a dict written before they were
    assert (Estimate.from_dict(old).units, math.isnan(Estimate.from_dict(old).dof)) == (0, True)


def test_a_staged_study_counts_the_runs_needed_at_its_last_looks_level(tmp_path, monkeypatch):
    """The futility stop of quick mode's first look asks whether the cap's runs, judged at the cap's
    level, would decide the claim: the row's runs_needed is the first look's estimate extrapolated to
    the last look's level (``staged_study.py``: a real MuJoCo pendulum)."""
    import json
    import sys
    from pathlib import Path

    from undulate.studies import _registry, run_study

    sys.path.insert(0, str(Path(__file__).parent))
    import staged_study as staged

    monkeypatch.setattr(staged, "REGION", (0.0, 5.0))
    monkeypatch.setattr(staged, "STAGE_POINTS", (6, 12))
    try:
        run_study("_staged", tmp_path, quick=True, workers=1, progress=False)
    finally:
        for name in ("_staged", "_whole"):
            _registry._REGISTRY.pop(name, None)
        sys.modules.pop("staged_study", None)
    doc = json.loads((tmp_path / "_staged.json").read_text())
    claim = doc["claims"][0]
    est = Estimate.from_dict(claim["value"]["mean_start_angle"])
    first, last = stats.look_levels(2)
    assert est.level == first and est.dof == est.units - 1 > 0
    with stats.at_level(first, plan_at=last):
        assert claim["runs_needed"] == stats.runs_needed(est, 0.0)
    assert claim["runs_needed"] < stats.runs_needed(est, 0.0)  # at the first look's own level: more


def test_a_groups_claim_counts_the_runs_it_needs_not_its_neighbour_pairs():
    """A group's estimates rest on neighbour pairs, two or three a run: "about N runs would decide it"
    counts runs (the growth needed times the runs), where it counted neighbour pairs until 2026-12-02."""
    from undulate.studies import groups

    rng = np.random.default_rng(4)
    runs = np.repeat(np.arange(9), 2)  # nine runs of three swimmers, two neighbour pairs each
    dphi = np.repeat(np.linspace(-2.5, 2.5, 9), 2)
    dx = dphi / (2 * np.pi) * 0.8 + rng.normal(0, 0.05, 9)[runs]  # a slope near 0.8: undecided
    with stats.at_level(0.95):
        slope = stats.clustered_line_fit(dphi / (2 * np.pi), dx, runs).slope
        rms = stats.rms(rng.normal(0, 0.1, 18))
        pair = stats.rms(rng.normal(0, 0.03, 9))
    summary = {"per_group_size": {"3": {"slope": slope.to_dict(), "rms_residual_over_lambda": rms.to_dict(),
                                        "n_neighbour_pairs": 18, "n_runs": 10, "n_failed": 1},
                                  "2": {"rms_residual_over_lambda": pair.to_dict()}}}
    v = groups._group_follows("3")(summary)
    assert v.verdict == "undecided", v.reason
    assert v.runs_needed == math.ceil(9 * v.growth_needed - 1e-9)  # 9 runs with a result, not 18 pairs
    assert f"about {v.runs_needed} runs would decide it" in v.reason
