"""The confinement claim ("the central state broadens as d/2A grows") judged as a trend.

:data:`undulate.studies._criteria.CONFINEMENT_TREND_RULE`: the least-squares slope of the central state's
width against d/2A over the paper's range 0.6-1.2, with its Student-t interval.  Constructed widths, run
through the study's own ``summary`` (no simulation): rising widths hold, falling ones fail, flat noisy
ones stay undecided, too few give no result; the step-by-step criterion it replaced is judged beside it;
the claim's evidence figure is drawn from its row.
"""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
import xarray as xr
from scipy import stats as st

from undulate import stats
from undulate.studies import confinement, describe
from undulate.studies._criteria import CONFINEMENT_TREND_RULE
from undulate.studies._protocol import FAILS, HOLDS, NO_RESULT, UNDECIDED, judge

QUICK_D = (0.6, 0.8, 1.0, 1.2, 1.5)
STARTS = 11
NOISE = (0.01, -0.01, -0.01, 0.01)
"""Scatter about a line at the four quick confinements in the range: a V, as far from linear as four
points go (least-squares slope of the scatter alone: 0)."""


def dataset(widths, d=QUICK_D) -> xr.Dataset:
    """A confinement dataset shaped like :func:`confinement.dataset`'s, with these central widths (lambda;
    NaN: no start ended in the central state); the runs themselves are not needed by ``summary``."""
    d = np.asarray(d, float)
    w = np.asarray(widths, float)
    x0 = np.linspace(-1, 1, STARTS)
    runs = ("d_over_2A", "dx0")
    one = np.ones((d.size, STARTS))
    return xr.Dataset(
        {"central_width": ("d_over_2A", w), "central_lo": ("d_over_2A", -w / 2), "central_hi": ("d_over_2A", w / 2),
         "basin_lo": ("d_over_2A", np.full(d.size, -0.3)), "basin_hi": ("d_over_2A", np.full(d.size, 0.3)),
         "model_width_thin": ("d_over_2A", np.zeros(d.size)), "model_width_bodies": ("d_over_2A", np.zeros(d.size)),
         "run_failed": (runs, np.zeros_like(one, bool)), "steady": (runs, one.astype(bool)),
         "amplitude": ((), 0.05225)},
        coords={"d_over_2A": d, "dx0": x0, "channel_width": ("d_over_2A", 2 * d * 2 * 0.05225)})


def row(widths, d=QUICK_D) -> dict:
    """The claim's ``claims.json``-shaped row for these widths, through the study's summary and judge."""
    s = confinement.summary(dataset(widths, d))
    (r,) = judge("confinement", describe("confinement").claims, s)
    return r


def rising(slope=0.4):
    return [slope * (x - 0.6) + e for x, e in zip(QUICK_D[:4], NOISE)] + [0.05]


# ------------------------------------------------------------------ the statistic
def test_the_slope_is_the_least_squares_slope_over_the_papers_range_with_its_t_interval():
    w = rising()
    s = confinement.summary(dataset(w))
    slope = stats.Estimate.from_dict(s["broadening_slope_per_d_over_2A"])
    ref = st.linregress(QUICK_D[:4], w[:4])  # 1.5 lies beyond the paper's range: not fitted
    half = st.t.ppf(0.975, 4 - 2) * ref.stderr
    assert slope.value == pytest.approx(ref.slope, rel=1e-12)
    assert (slope.low, slope.high) == pytest.approx((ref.slope - half, ref.slope + half), rel=1e-12)
    assert slope.n == 4 and s["n_runs_in_broadening_fit"] == 4 * STARTS
    # what lies beyond the range does not move it
    other = confinement.summary(dataset(w[:4] + [0.9]))["broadening_slope_per_d_over_2A"]
    assert other == s["broadening_slope_per_d_over_2A"]


def test_a_confinement_without_a_central_state_is_left_out_of_the_fit():
    w = rising()
    w[1] = np.nan
    slope = stats.Estimate.from_dict(confinement.summary(dataset(w))["broadening_slope_per_d_over_2A"])
    ref = st.linregress([0.6, 1.0, 1.2], [w[0], w[2], w[3]])
    assert slope.n == 3 and slope.value == pytest.approx(ref.slope, rel=1e-12)
    assert slope.high - slope.low == pytest.approx(2 * st.t.ppf(0.975, 1) * ref.stderr, rel=1e-12)


def test_the_slope_may_be_negative_inside_the_summarys_domains():
    """A falling width gives a negative slope: its key names no quantity with a sign (a width's is >= 0)."""
    s = confinement.summary(dataset([0.5, 0.35, 0.2, 0.05, 0.0]))
    assert stats.Estimate.from_dict(s["broadening_slope_per_d_over_2A"]).high < 0
    assert stats.domain_violations(s) == []
    assert stats.domain_violations(row([0.5, 0.35, 0.2, 0.05, 0.0])["value"]) == []


# ------------------------------------------------------------------ the verdicts
def test_widths_rising_over_the_range_hold():
    r = row(rising())
    assert r["verdict"] == HOLDS and r["criterion"] == CONFINEMENT_TREND_RULE
    assert "lambda per unit d/2A from 4 confinements" in r["measured"]


def test_widths_falling_over_the_range_fail():
    assert row([0.5 - 0.4 * (x - 0.6) + e for x, e in zip(QUICK_D[:4], NOISE)] + [0.5])["verdict"] == FAILS


def test_a_state_closed_throughout_the_range_fails():
    """Width 0 at every confinement in the range lies exactly on a flat line: slope 0 [0, 0], whose upper
    end is not above 0 (linregress alone gives no standard error without spread in the widths)."""
    r = row([0.0, 0.0, 0.0, 0.0, 0.4])
    slope = stats.Estimate.from_dict(r["value"]["broadening_slope_per_d_over_2A"])
    assert (slope.value, slope.low, slope.high) == (0.0, 0.0, 0.0)
    assert r["verdict"] == FAILS


def test_flat_noisy_widths_are_undecided_with_the_boundary_named():
    r = row([0.3 + e for e in NOISE] + [0.3])
    assert r["verdict"] == UNDECIDED
    assert "straddles 0" in r["reason"]
    r = row([0.3 + 0.02 * (x - 0.6) + e for x, e in zip(QUICK_D[:4], NOISE)] + [0.3])
    assert r["verdict"] == UNDECIDED and r["runs_needed"] > 4 * STARTS


def test_fewer_than_three_widths_in_the_range_give_no_result():
    r = row([np.nan, np.nan, 0.2, 0.3, 0.4])
    assert r["verdict"] == NO_RESULT and "at least 3" in r["reason"]
    # the old quick plan's three confinements in the range: an interval on 1 degree of freedom
    r = row([0.0, 0.3, 0.35, 0.4], d=(0.6, 0.9, 1.2, 1.5))
    assert r["value"]["broadening_slope_per_d_over_2A"]["dof"] == 1


# ------------------------------------------------------------------ the superseded criterion, beside it
def test_the_step_by_step_criterion_is_judged_beside_the_trend():
    """A width that rises over the range but narrows from 1.2 to 1.5 (beyond it): the trend holds, the
    old criterion, which read every step, fails; both verdicts are in the row and its JSON."""
    r = row(rising()[:4] + [0.0])
    assert r["verdict"] == HOLDS
    (old,) = r["superseded"]
    assert old["verdict"] == FAILS and "never shrinks" in old["criterion"] and old["why"]
    assert "1.50: 0.000" in old["measured"]
    json.dumps(r)
    # one narrower step inside the range (0.8 -> 1.0 by 0.06 lambda) fails the old rule, not the trend
    r = row([0.0, 0.4, 0.34, 0.6, 0.7])
    assert r["superseded"][0]["verdict"] == FAILS and r["verdict"] != FAILS
    assert row([0.0, 0.1, 0.2, 0.3, 0.4])["superseded"][0]["verdict"] == HOLDS


# ------------------------------------------------------------------ the design can decide it
def test_the_plans_give_the_slope_degrees_of_freedom():
    def in_range(d):
        return [x for x in d if 0.6 - 1e-9 <= x <= 1.2 + 1e-9]

    quick, full = confinement.plan(True), confinement.plan(False)
    assert len(in_range(quick.d_over_2A)) == 4 and max(quick.d_over_2A) > 1.2
    assert len(in_range(full.d_over_2A)) == 13 and len(full.dx0_over_lambda) == 21  # the slope needs confinements
    for mode in (True, False):
        looks = confinement.stages(mode)
        assert looks[-1].d_over_2A == confinement.plan(mode).d_over_2A
        assert all(len(in_range(p.d_over_2A)) >= 4 for p in looks)  # every look can give an interval
        # every look measures the same width: the starts (its resolution) are the plan's at every look
        assert all(p.dx0_over_lambda == confinement.plan(mode).dx0_over_lambda for p in looks)


# ------------------------------------------------------------------ the evidence figure
def test_the_claims_evidence_figure_draws_the_widths_and_the_fitted_line():
    (claim,) = describe("confinement").claims
    assert claim.evidence is not None
    r = row(rising())
    fig = claim.evidence(r)
    assert tuple(fig.get_size_inches() * 100) == pytest.approx((560, fig.get_size_inches()[1] * 100))
    ax = fig.axes[0]
    slope = stats.Estimate.from_dict(r["value"]["broadening_slope_per_d_over_2A"])
    icpt = r["value"]["broadening_intercept_over_lambda"]["value"]
    fitted = [ln for ln in ax.lines if ln.get_label() == "least-squares line"]
    assert len(fitted) == 1
    x, y = fitted[0].get_data()
    assert list(x) == [0.6, 1.2] and list(y) == pytest.approx([icpt + slope.value * v for v in x])
    assert "holds" in ax.get_title() and "per unit d/2A" in ax.get_title()
    assert any("Increasing the confinement wall distance" in t.get_text() for t in fig.texts)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    assert buf.getvalue()[:4] == b"\x89PNG"
    # a row with no slope still gets a figure, saying so
    fig = claim.evidence(row([np.nan, np.nan, np.nan, 0.3, 0.4]))
    assert "no slope" in fig.axes[0].get_title()
