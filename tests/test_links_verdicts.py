"""The links claim ("the error falls as links are added") is three-valued, and a wide interval is a finding.

Constructed summaries give holds / fails / undecided; constructed datasets check that the outlier finder
(:mod:`undulate.studies._outliers`, used by ``links.summary``) names the runs that widen an N's interval
and why, and reports none where no interval is wide.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import xarray as xr

from undulate import stats
from undulate.studies import _analysis as C
from undulate.studies import _criteria as C_
from undulate.studies import _outliers as O
from undulate.studies import describe, links
from undulate.studies._protocol import judge

LAM = 0.54


def est(value, low, high, n=9, units=0):
    return stats.Estimate(value, math.nan, low, high, n, "test", units=units)


FALLING_SLOPE = (-4e-4, -6e-4, -2e-4)
"""A trend's slope (lambda^2 per link) whose interval lies below 0."""


def summary(rms, per_n_extra=None, slope=FALLING_SLOPE):
    per_n = {str(n): {"rms_residual_over_lambda": est(*r).to_dict(), **(per_n_extra or {}).get(n, {})}
             for n, r in zip((3, 5, 7, 9), rms)}
    rule = {"per_n": per_n, "squared_residual_slope_per_link": est(*slope, n=36, units=5).to_dict()}
    return {"per_rule": {"fixed": rule, "curvature": rule}}


def rows(rms, per_n_extra=None, slope=FALLING_SLOPE):
    describe("links")
    return judge("links", links.CLAIMS, summary(rms, per_n_extra, slope))


FALLS = [(0.08, 0.07, 0.09), (0.06, 0.05, 0.07), (0.04, 0.03, 0.05), (0.02, 0.01, 0.03)]
ONE_STEP_RISES = [FALLS[0], (0.03, 0.02, 0.04), (0.07, 0.06, 0.08), (0.02, 0.01, 0.03)]  # 5 -> 7 rises


# ------------------------------------------------------------------ the trend criterion (LINKS_TREND_RULE)
def test_the_trend_holds_fails_or_is_undecided_on_its_slopes_interval():
    assert [r["verdict"] for r in rows(FALLS)] == ["holds", "holds"]
    assert [r["verdict"] for r in rows(FALLS, slope=(3e-4, 1e-4, 5e-4))] == ["fails", "fails"]
    r = rows(FALLS, slope=(-1e-4, -3e-4, 1e-4))[0]
    assert r["verdict"] == "undecided" and "straddles 0" in r["reason"]
    assert "slope of the squared residual against N" in r["measured"] and "5 design points" in r["measured"]
    assert rows(FALLS, slope=(-1e-4, math.nan, math.nan))[0]["verdict"] == "no result"


def test_one_noisy_step_no_longer_decides_but_the_old_criterion_is_shown_beside():
    """The superseded step-by-step criterion fails on a rise at one step; the trend, read over the whole
    range, holds; the row shows both."""
    r = rows(ONE_STEP_RISES)[0]
    assert r["verdict"] == "holds" and r["criterion"] == C_.LINKS_TREND_RULE
    (old,) = r["superseded"]
    assert old["criterion"] == C.FALLS_RULE and old["verdict"] == "fails" and "step by step" in old["why"]
    assert rows(FALLS)[0]["superseded"][0]["verdict"] == "holds"


def _residuals(per_n_scale, noise=0.0, seed=0):
    """(N = 3, 5, 7, 9) x (the paper's nine dphi) residuals / lambda: a design point's own error (its
    |dphi|, the same at +-dphi) times the N's scale, plus independent noise."""
    rng = np.random.default_rng(seed)
    base = 0.02 + 0.04 * np.abs(DPHI) / np.pi
    return np.asarray(per_n_scale, float)[:, None] * base[None, :] + noise * rng.normal(size=(4, DPHI.size))


@pytest.mark.parametrize("scale, expected", [((1.0, 0.8, 0.6, 0.4), "holds"), ((0.4, 0.6, 0.8, 1.0), "fails"),
                                             ((1.0, 1.0, 1.0, 1.0), "undecided")])
def test_error_trend_on_constructed_runs(scale, expected):
    """Per-run residuals whose error falls, rises or stays with N: the claim's verdict on the slope that
    :func:`links.error_trend` fits (design points as clusters)."""
    res = _residuals(scale, noise=0.004)
    slope = links.error_trend(res, [3, 5, 7, 9], DPHI)
    assert slope.n == 36 and slope.units == 5 and slope.dof == 4  # 5 |dphi|: t on 4
    got = rows(FALLS, slope=(slope.value, slope.low, slope.high))[0]["verdict"]
    assert got == expected, slope


def test_error_trend_is_the_slope_of_the_per_n_mean_squares():
    """In the balanced design the pooled slope equals the least-squares slope of the per-N mean squares."""
    res = _residuals((1.0, 0.7, 0.9, 0.5), noise=0.01, seed=3)
    n = np.array([3, 5, 7, 9])
    expected = np.polyfit(n, np.mean(res ** 2, axis=1), 1)[0]
    assert links.error_trend(res, n, DPHI).value == pytest.approx(expected, rel=1e-12)
    with pytest.raises(ValueError):
        links.error_trend(res[:, :5], n, DPHI)


def test_the_design_can_decide_the_trend_and_four_rms_values_cannot():
    """Every look of both modes gives the trend an interval (at least 3 design points), while the four
    per-N RMS values never could give a rank correlation one at 95 % (4! = 24 orderings < 40)."""
    for quick in (True, False):
        for p in links.stages(quick):
            assert np.unique(C.abs_dphi_keys(p.dphi_rad)).size >= 3
    assert np.unique(C.abs_dphi_keys(links.plan(True).dphi_rad)).size == 5
    assert np.unique(C.abs_dphi_keys(links.plan(False).dphi_rad)).size == 17
    assert not stats.rank_correlation([3, 5, 7, 9], [0.08, 0.06, 0.04, 0.02]).has_interval
    assert stats.rank_correlation_points() > len(links.N_LINKS)


# ------------------------------------------------------------------ the superseded step-by-step criterion
def test_holds_when_every_step_stays_and_the_last_interval_lies_below_the_first():
    assert C.falls_with_links([est(*v) for v in FALLS]) is True
    # a point rise inside overlapping intervals is no rise
    flat_tail = FALLS[:3] + [(0.045, 0.035, 0.055)]
    assert C.falls_with_links([est(*v) for v in flat_tail]) is True


def test_fails_on_a_rise_beyond_the_intervals_or_a_last_interval_above_the_first():
    assert C.falls_with_links([est(*v) for v in ONE_STEP_RISES]) is False
    creep = [(0.02, 0.015, 0.025), (0.025, 0.018, 0.03), (0.03, 0.022, 0.035), (0.035, 0.028, 0.04)]
    assert C.falls_with_links([est(*v) for v in creep]) is False  # no step rises beyond, but 9 above 3


def test_undecided_when_the_last_interval_overlaps_the_first():
    wide = FALLS[:2] + [(0.05, 0.01, 0.09), (0.045, 0.01, 0.085)]  # falls at every step, last overlaps first
    old = rows(wide)[0]["superseded"][0]
    assert old["verdict"] == "undecided"
    assert "N = 3 above N = 9" in old["reason"] and "overlaps" in old["reason"]
    assert C.falls_with_links([est(*v) for v in wide]) is None
    assert C.falls_with_links([est(0.04, math.nan, math.nan), est(0.01, 0.0, 0.02)]) is None  # no interval


def test_the_checks_name_each_step_and_the_overall_fall():
    checks = C.falls_with_links_checks([est(*v) for v in FALLS], [3, 5, 7, 9])
    assert [c.text.split(":")[0] for c in checks] == ["RMS at N = 3 -> 5", "RMS at N = 5 -> 7", "RMS at N = 7 -> 9",
                                                      "RMS at N = 3 above N = 9"]
    assert stats.decide(checks) is True


def test_a_missing_rms_interval_is_no_result_for_the_old_criterion():
    r = rows(FALLS[:3] + [(0.02, math.nan, math.nan)])[0]
    assert r["verdict"] == "holds" and r["superseded"][0]["verdict"] == "no result"


def test_the_measured_text_mentions_outliers_when_an_interval_is_wide():
    out = [{"dphi_over_pi": s, "class": O.OTHER_STATE, "arrangement": "end to end"} for s in (-1.0, 1.0)]
    r = rows(FALLS, {7: {"wide_interval": True, "outliers": out}})[0]
    assert "outliers: N = 7, 2 run(s): another steady state (end to end) at dphi = -1, +1 pi" in r["measured"]
    assert "outliers" not in rows(FALLS)[0]["measured"]


# ------------------------------------------------------------------ outlier finder on constructed data
DPHI = np.arange(-4, 5) * (np.pi / 4)
TIME = np.arange(0.0, 30.0 + 1e-9, 0.1)


def dataset(residual, *, steady=None, settle=None, extent=None, excess=None, dx_shift=None) -> xr.Dataset:
    """A links-like dataset, one rule and N = 3, 5, 7, 9: ``residual`` (4, 9) in lambda; keyword arrays
    (4, 9) override the defaults (steady, settled at 4 s, extent 0.46 m, inside the band, no wrap)."""
    res = np.asarray(residual, float)
    shape = (1,) + res.shape
    dxl = DPHI / (2 * np.pi) + res + (0 if dx_shift is None else np.asarray(dx_shift, float))
    full = {"steady": np.ones(res.shape, bool) if steady is None else np.asarray(steady, bool),
            "settle": np.full(res.shape, 4.0) if settle is None else np.asarray(settle, float),
            "extent": np.full(res.shape, 0.46) if extent is None else np.asarray(extent, float),
            "excess": np.zeros(res.shape) if excess is None else np.asarray(excess, float)}
    dims = ("rule", "n_links", "dphi")
    v = lambda a: (dims, np.asarray(a).reshape(shape))  # noqa: E731
    return xr.Dataset(
        {"residual_over_lambda": v(res), "dx_steady_over_lambda": v(dxl), "dx_steady": v(dxl * LAM),
         "dy_steady": v(np.full(res.shape, 0.02)), "steady": v(full["steady"]), "settle_time": v(full["settle"]),
         "steady_spread": v(np.zeros(res.shape)), "extent_x": v(full["extent"]),
         "band_excess": v(full["excess"] * LAM), "contact_force_mean": v(np.full(res.shape, 1.0)),
         "penetration_max": v(np.full(res.shape, 1e-4)), "run_failed": v(np.zeros(res.shape, bool)),
         "dx": (dims + ("time",), np.broadcast_to((dxl * LAM)[None, :, :, None], shape + TIME.shape).copy()),
         "amplitude": (("rule", "n_links"), np.full((1, 4), 0.05)),
         "joint_amplitude": (("rule", "n_links"), np.full((1, 4), math.radians(45))),
         "timestep": ("n_links", [2e-3, 6.7e-4, 5e-4, 4e-4])},
        coords={"rule": ["fixed"], "n_links": [3, 5, 7, 9], "dphi": DPHI, "time": TIME},
        attrs={"wavelength_m": LAM})


NOISE = np.array([0.004, 0.03, -0.02, 0.025, 0.0, -0.025, 0.02, -0.03, -0.004])


def base_residuals():
    return np.stack([NOISE, NOISE * 1.2, NOISE, NOISE * 1.1])


def test_a_wide_group_names_its_two_off_branch_runs_and_their_states():
    res = base_residuals()
    res[2, 2], res[2, 6] = -0.3, 0.3  # N = 7, dphi = -pi/2 and +pi/2: steady, off every branch
    extent = np.full(res.shape, 0.46)
    extent[2, 6] = 0.35  # |dx| = 0.55 lambda = 0.30 m: 0.85 of the extent, end to end
    excess = np.zeros(res.shape)
    excess[2, 2] = 0.1  # side by side, 0.1 lambda outside the band
    s = links.summary(dataset(res, extent=extent, excess=excess))
    per_n = s["per_rule"]["fixed"]["per_n"]
    assert [per_n[n]["wide_interval"] for n in ("3", "5", "7", "9")] == [False, False, True, False]
    found = per_n["7"]["outliers"]
    assert [o["dphi_over_pi"] for o in found] == [-0.5, 0.5]
    assert [o["residual_over_lambda"] for o in found] == pytest.approx([-0.3, 0.3])
    assert {o["class"] for o in found} == {O.OTHER_STATE}
    assert [o["arrangement"] for o in found] == ["side by side, pressed", "end to end"]
    assert all(per_n[n]["outliers"] == [] for n in ("3", "5", "9"))
    note = s["per_rule"]["fixed"]["outlier_note"]
    assert note.startswith("N = 7's RMS interval is") and "2 run(s) differ" in note
    import json
    json.dumps(s)  # the finding is JSON-able


def test_a_group_without_a_wide_interval_reports_no_outliers():
    s = links.summary(dataset(base_residuals()))
    fixed = s["per_rule"]["fixed"]
    assert fixed["outlier_note"] is None
    assert all(not r["wide_interval"] and r["outliers"] == [] for r in fixed["per_n"].values())
    mask, _ = O.outlying(NOISE)
    assert not mask.any()


def test_a_run_still_settling_is_drifting_and_a_branch_change_is_listed():
    res = base_residuals()
    res[2, 2], res[2, 6] = -0.3, 0.3
    steady = np.ones(res.shape, bool)
    steady[2, 2] = False
    settle = np.full(res.shape, 4.0)
    settle[2, 6] = 24.0  # steady only over the last window of a 30 s run
    shift = np.zeros(res.shape)
    shift[1, 7] = -1.0  # N = 5, dphi = 3 pi/4: settled one wavelength down, on branch n = -1
    s = links.summary(dataset(res, steady=steady, settle=settle, dx_shift=shift))
    per_n = s["per_rule"]["fixed"]["per_n"]
    assert [o["class"] for o in per_n["7"]["outliers"]] == [O.DRIFTING, O.DRIFTING]
    [moved] = per_n["5"]["runs_on_another_branch"]
    assert moved["dphi_over_pi"] == 0.75 and moved["branch"] == -1 and moved["start_branches"] == [0]


def test_outlier_helpers():
    assert O.width_ratios({"a": 1.0, "b": 1.0, "c": 6.0}) == {"a": pytest.approx(1 / 3.5), "b": pytest.approx(1 / 3.5),
                                                              "c": 6.0}
    mask, thr = O.outlying([0.01, -0.02, 0.015, 0.3, -0.01, 0.02, 0.0])
    assert mask.tolist() == [False, False, False, True, False, False, False] and 0.02 < thr < 0.3
    assert O.start_branches(np.pi) == (-1, 0) and O.start_branches(np.pi / 2) == (0,)
    # dphi = pi: dx = -lambda/2 is on a start branch (a tie), dphi = 3 pi/4 at -0.625 lambda is not
    moved = O.branch_changes([-0.5, -0.625, 0.375], [np.pi, 3 * np.pi / 4, 3 * np.pi / 4])
    assert moved.tolist() == [False, True, False]
    assert O.classify(True, True) == O.DRIFTING
    assert O.classify(False, True) == O.OTHER_BRANCH
    assert O.classify(False, False) == O.OTHER_STATE


class _RecordingContext:
    """A context whose sweep records the points asked for and answers with failed runs (no simulation)."""

    def __init__(self, decided):
        from undulate.studies._context import StudyConfig, StudyContext
        from undulate.studies._registry import describe
        from undulate.studies._staging import part_plans, stage_plans

        info = describe("links")
        staged = StudyContext(StudyConfig(out_dir="unused", workers=1), "links", progress=False)
        staged.parts = part_plans(info, stage_plans(info, False), decided, {}, lambda study, claim: True)
        self.plan_for = staged.plan_for  # the staging engine's answer: claim decided -> its rule's plan kept
        self.frozen_at = staged.parts.frozen_at
        self.seed = 0
        self.points = []

    def sweep(self, part, fn, grid):
        self.points = list(grid.points())
        n = len(self.points)
        return xr.Dataset({"run_failed": (("point", "replicate"), np.ones((n, 1), bool)),
                           "extent_x": (("point", "replicate", "swimmer"), np.full((n, 1, 2), np.nan))},
                          coords={"time": np.arange(3.0)})

    def together(self, *calls):  # StudyContext.together on the MuJoCo backend: one after another
        return [call() for call in calls]

    def lone_swimmer(self, **kw):
        return {"amplitude_m": 0.05}


@pytest.mark.parametrize("decided_rule", [None, "curvature"])
def test_a_rule_whose_claim_is_decided_keeps_its_looks_runs(decided_rule):
    """Full mode's second look with the 45 deg x 3/N claim decided at the first: that rule's runs stay on
    the first look's dphi (made already), the other rule's grow; the dataset marks the runs not made
    (NaN, not failed) and the summary counts only the runs made."""
    first, second = links.stages(False)[:2]
    claim = dict(zip(links.RULES, links.CLAIMS))
    ctx = _RecordingContext({claim[decided_rule].claim: 1} if decided_rule else {})
    ds = links.dataset(ctx, second)
    per_rule = {r: sorted({round(p["dphi_rad"], 9) for p in ctx.points if p["beta_rule"] == r}) for r in links.RULES}
    for r in links.RULES:
        want = first if r == decided_rule else second
        assert per_rule[r] == sorted(round(d, 9) for d in want.dphi_rad)
    assert len(ctx.points) == sum(len(v) for v in per_rule.values()) * len(links.N_LINKS)
    made = ds["run_made"].values
    for i, r in enumerate(links.RULES):
        ran = np.isin(np.round(ds["dphi"].values, 9), per_rule[r])
        assert (made[i] == ran[None, :]).all()
    assert ds["run_failed"].values.sum() == made.sum()  # every run made failed here; none not made
    assert ctx.frozen_at == ({decided_rule: 1} if decided_rule else {})
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = links.summary(ds)
    assert s["n_runs"] == int(made.sum()) == s["n_failed"]

