"""The claims added to pairs, groups and packing (paper Sec. III.A, III.D, III.E and the conclusions), on
constructed data: each criterion holds, fails or stays undecided on the intervals it is given, and the
summaries that feed them compute what their docstrings say (the physics of a settling pair: a decelerating
approach is fast first and slow last, a run pushed into compatibility sheds its contact force).

No simulation: the studies' quick runs judge the claims on real runs (tests/test_registry_suite.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import xarray as xr

from undulate import stats, theory
from undulate.studies import groups, packing, pairs
from undulate.studies._protocol import FAILS, HOLDS, NO_RESULT, UNDECIDED, judge

T = pairs.PERIOD_S
LAM = 0.3


def est(value, low, high, n=16):
    return stats.Estimate(value, math.nan, low, high, n, "test", units=n, dof=n - 1).to_dict()


def claim(study, words):
    (c,) = [c for c in study.CLAIMS if words in c.claim]
    return c


# ------------------------------------------------------------------ pairs: the helpers
def test_early_mean_is_over_the_first_two_periods_after_the_start():
    t = np.round(np.arange(0, 30.01, 0.1), 10)
    f = np.where(t <= 2 * T, 3.0, 0.5)
    f[0] = 100.0  # the start's sample is not in the window (0 < t <= 2T)
    assert pairs.early_mean(f, t) == pytest.approx(3.0)
    assert pairs.early_mean(f, t, periods=4) == pytest.approx((20 * 3.0 + 20 * 0.5) / 40)
    assert math.isnan(pairs.early_mean(np.full(t.size, np.nan), t))


def test_period_means_stop_at_a_stopped_runs_nan():
    t = np.round(np.arange(0, 30.01, 0.1), 10)
    x = np.sin(2 * np.pi * t / T) + 0.1 * np.floor((t - 1e-9) / T)  # a whole period of the wave averages to 0
    x[t > 13.05] = np.nan  # stopped at 13 s: six whole periods
    p = pairs.period_means(x, t)
    assert p.size == 6
    np.testing.assert_allclose(p, 0.1 * np.arange(6), atol=1e-9)


def _approach(kind, t, dx_end=0.25 * LAM, tau=2.5):
    """dx(t) of a pair settling to ``dx_end``: decelerating (exponential), at a constant rate (a ramp that
    stops), or late (a sudden jump after 16 s), plus the gait's own wiggle (a whole period averages it out)."""
    wiggle = 0.02 * LAM * np.sin(2 * np.pi * t / T)
    if kind == "decelerating":
        return dx_end * (1 - np.exp(-t / tau)) + wiggle
    if kind == "ramp":
        return dx_end * np.clip(t / 30.0, 0, 1) + wiggle
    return dx_end * (t > 16.0) + wiggle


def test_a_decelerating_approach_is_fast_first_and_slow_last():
    t = np.round(np.arange(0, 30.01, 0.1), 10)
    first, late = pairs.separation_rates(_approach("decelerating", t), t, LAM)
    assert first > 10 * late > 0
    # a constant rate: the same at both ends; a late jump: slower first than last
    first, late = pairs.separation_rates(_approach("ramp", t), t, LAM)
    assert first == pytest.approx(late, rel=1e-9)
    first, late = pairs.separation_rates(_approach("late", t)[:181], t[:181], LAM)  # ends 18 s: jump in window
    assert first < late
    # too short for two windows that share no period: no rates
    assert all(math.isnan(v) for v in pairs.separation_rates(_approach("decelerating", t)[:101], t[:101], LAM))


def test_quantile_estimate_is_the_order_statistic_interval():
    from scipy import stats as st

    v = np.linspace(0.0, 1.5, 16)
    e = pairs.quantile_estimate(v, 0.5)
    ci = st.quantile_test(v, p=0.5).confidence_interval(0.95)
    assert (e.low, e.high) == (ci.low, ci.high) and e.low <= e.value <= e.high
    some = pairs.quantile_estimate(v, 1 / 8)
    assert some.low == 0.0  # no order statistic of 16 bounds the 1/8 quantile from below: the domain's end
    assert some.high == pytest.approx(v[5])  # the sixth smallest
    assert math.isnan(pairs.quantile_estimate(v[:1], 1 / 8).high)  # one value: no upper bound
    assert math.isnan(pairs.quantile_estimate([], 0.5).value)


def _pair_slice(late, early, steady=None, kind="decelerating"):
    """One xi's slice of a pairs dataset over ``len(late)`` dphi in [-pi, pi] (33: quick's), with the given
    forces per dphi."""
    dphi = np.linspace(-np.pi, np.pi, len(late))
    t = np.round(np.arange(0, 30.01, 0.1), 10)
    n = dphi.size
    steady = np.ones(n, bool) if steady is None else steady
    dx = np.array([_approach(kind, t, dx_end=LAM * d / (2 * np.pi)) for d in dphi])
    return xr.Dataset(
        {"run_failed": ("dphi", np.zeros(n, bool)), "run_made": ("dphi", np.ones(n, bool)),
         "steady": ("dphi", steady), "contact_force_mean": ("dphi", np.asarray(late, float)),
         "contact_force_early": ("dphi", np.asarray(early, float)), "wavelength": ((), LAM),
         "dx": (("dphi", "time"), dx)},
        coords={"dphi": dphi, "time": t})


def test_contact_summary_takes_the_runs_pushed_out_of_an_incompatible_start():
    dphi = np.linspace(-np.pi, np.pi, 33)
    early = 0.8 * np.abs(dphi)  # the initial force grows with the detuning (paper Fig. 10a); 0 at dphi = 0
    late = np.where(np.abs(dphi) < 1.6, 0.0, 0.3 * early)  # none left near dphi = 0, some at large |dphi|
    steady = np.ones(33, bool)
    steady[3] = False
    s = pairs.contact_summary(_pair_slice(late, early, steady))
    assert s["n_runs_used"] == 31  # dphi = 0 (a compatible start) and the unsteady run left out
    assert s["n_not_steady"] == 1 and s["n_no_initial_contact"] == 0
    assert s["n_configurations"] == 16  # +dphi and -dphi one configuration (pi and -pi too)
    assert s["n_zero_steady_force"] == 16  # 0 < |dphi| <= pi/2: eight a side
    med, some = (stats.Estimate.from_dict(s[k]) for k in ("ratio_median", "ratio_some_quantile"))
    assert some.value == 0.0 and some.high == 0.0  # the smallest six configurations carry no force
    assert med.high < 1.0
    row = {"per_xi": {"1": {"contact": s}}}
    assert claim(pairs, "contact force is lower").judge(row).verdict == HOLDS
    assert claim(pairs, "small or zero").judge(row).verdict == HOLDS


def test_contact_forces_that_stay_at_half_fail_small_and_hold_reduced():
    """Every steady force half the initial one: reduced, but small for no configuration.  On 32
    configurations (65 dphi) the 1/8 quantile's interval has a lower end, the smallest ratio; on quick's 16
    no order statistic bounds it from below at 95 % ((7/8)^16 > 2.5 %), so there the claim cannot fail."""
    dphi = np.linspace(-np.pi, np.pi, 65)
    early = 1.0 + np.abs(dphi)
    s = pairs.contact_summary(_pair_slice(0.5 * early, early))
    row = {"per_xi": {"1": {"contact": s}}}
    assert claim(pairs, "contact force is lower").judge(row).verdict == HOLDS
    assert claim(pairs, "small or zero").judge(row).verdict == FAILS
    d33 = np.linspace(-np.pi, np.pi, 33)
    s33 = pairs.contact_summary(_pair_slice(0.5 * (1 + np.abs(d33)), 1 + np.abs(d33)))
    assert claim(pairs, "small or zero").judge({"per_xi": {"1": {"contact": s33}}}).verdict == UNDECIDED
    # a force that grows: the reduction fails
    s = pairs.contact_summary(_pair_slice(2.0 * early, early))
    assert claim(pairs, "contact force is lower").judge({"per_xi": {"1": {"contact": s}}}).verdict == FAILS


def test_no_run_with_initial_contact_is_no_result():
    s = pairs.contact_summary(_pair_slice(np.zeros(33), np.zeros(33)))
    assert s["n_runs_used"] == 0 and s["n_no_initial_contact"] == 32
    row = {"per_xi": {"1": {"contact": s}}}
    assert claim(pairs, "contact force is lower").judge(row).verdict == NO_RESULT
    assert claim(pairs, "small or zero").judge(row).verdict == NO_RESULT


def _contact(median=(0.3, 0.1, 0.6), some=(0.02, 0.0, 0.08)):
    return {"n_configurations": 16, "n_runs_used": 32, "n_not_steady": 0, "n_no_initial_contact": 0,
            "n_zero_steady_force": 4, "n_small_ratio": 8, "some_share": pairs.SOME_SHARE,
            "ratio_median": est(*median), "ratio_some_quantile": est(*some)}


@pytest.mark.parametrize("median, verdict", [
    ((0.3, 0.1, 0.6), HOLDS), ((1.5, 1.2, 2.0), FAILS), ((0.9, 0.5, 1.3), UNDECIDED),
    ((1.4, 1.1, math.nan), FAILS),      # no upper bound, the lower above 1: wholly above
    ((0.9, 0.5, math.nan), UNDECIDED),  # no upper bound, the lower below 1
])
def test_force_reduced_is_three_valued(median, verdict):
    v = claim(pairs, "contact force is lower").judge({"per_xi": {"1": {"contact": _contact(median=median)}}})
    assert v.verdict == verdict
    if verdict == UNDECIDED:
        assert "1" in v.reason


@pytest.mark.parametrize("some, verdict", [
    ((0.02, 0.0, 0.08), HOLDS), ((0.3, 0.2, 0.5), FAILS), ((0.05, 0.0, 0.2), UNDECIDED)])
def test_force_small_for_some_is_three_valued(some, verdict):
    v = claim(pairs, "small or zero").judge({"per_xi": {"1": {"contact": _contact(some=some)}}})
    assert v.verdict == verdict
    if verdict == UNDECIDED:
        assert f"straddles {pairs.SMALL_FORCE_FRACTION:g}" in v.reason


def test_approach_summary_and_claim_on_constructed_runs():
    dphi = np.linspace(-np.pi, np.pi, 33)
    force = np.abs(dphi)
    a = pairs.approach_summary(_pair_slice(force, force))
    assert a["n_runs_used"] == 32 and a["n_configurations"] == 16 and a["n_runs_slowing"] == 32
    assert stats.Estimate.from_dict(a["rate_drop_over_lambda_per_period"]).low > 0
    assert claim(pairs, "fast at first").judge({"per_xi": {"1": {"approach": a}}}).verdict == HOLDS
    # a pair that sits still and then jumps (dx changes late): the drop is negative, the claim fails
    d = _pair_slice(force, force, kind="late")
    d["dx"] = d["dx"].where(d["time"] <= 18.0)  # each run stopped at 18 s, just after its jump
    a = pairs.approach_summary(d)
    assert claim(pairs, "fast at first").judge({"per_xi": {"1": {"approach": a}}}).verdict == FAILS


def _approach_row(drop):
    return {"per_xi": {"1": {"approach": {
        "n_runs_used": 32, "n_configurations": 16, "n_runs_slowing": 20,
        "initial_rate_over_lambda_per_period": est(0.05, 0.04, 0.06),
        "late_rate_over_lambda_per_period": est(0.01, 0.0, 0.02),
        "rate_drop_over_lambda_per_period": est(*drop)}}}}


@pytest.mark.parametrize("drop, verdict", [
    ((0.04, 0.03, 0.05), HOLDS), ((-0.02, -0.03, -0.01), FAILS), ((0.01, -0.01, 0.03), UNDECIDED),
    ((0.01, math.nan, math.nan), NO_RESULT)])
def test_approach_slows_is_three_valued(drop, verdict):
    v = claim(pairs, "fast at first").judge(_approach_row(drop))
    assert v.verdict == verdict
    if verdict == UNDECIDED:
        assert "straddles 0" in v.reason and v.runs_needed is not None


def test_the_new_pairs_claims_read_xi_one_only_and_quote_the_paper():
    from undulate.claims import quote_text

    with _paper() as f:
        paper = quote_text(f.read())
    for words in ("contact force is lower", "small or zero", "fast at first"):
        c = claim(pairs, words)
        assert quote_text(c.quote) in paper and c.where.startswith("Sec. III.A")
        assert c.reads == (pairs.part(1.0),)  # the runs at xi = 1 only


def _paper():
    from pathlib import Path

    for p in (Path(__file__).resolve().parents[1] / "shared" / "paper.tex", Path("/work/shared/paper.tex")):
        if p.exists():
            return open(p)
    pytest.skip("paper.tex not found")


def test_xi_three_halves_verdict_says_the_papers_setup_cannot_give_it():
    from undulate._report_claim_sections import first_sentence
    from undulate.studies._explanations import xi32

    assert first_sentence(xi32.CAUSE).startswith("The paper's stated setup cannot give this claim")
    row = {"slope": est(0.4, 0.1, 0.7), "rms_residual_over_lambda": est(0.2, 0.15, 0.25), "n_runs": 33,
           "n_steady": 30, "n_failed": 0}
    v = claim(pairs, "xi = 3/2").judge({"per_xi": {"1.5": row}})
    assert v.verdict == FAILS and "this setup cannot give the claim" in v.measured
    assert "cannot give" not in claim(pairs, "xi = 1: contact").judge({"per_xi": {"1": row}}).measured


# ------------------------------------------------------------------ groups
def test_unexplained_share_is_the_squared_deviation_outside_the_band():
    rng = np.random.default_rng(1)
    res = rng.normal(0, 0.05, 40)
    clusters = np.repeat(np.arange(20), 2)
    inside = groups.unexplained_share(res, np.zeros(40), clusters)
    assert inside.value == 0.0 and inside.high == 0.0  # every deviation inside the band
    outside = groups.unexplained_share(res, np.abs(res), clusters)
    assert outside.value == pytest.approx(1.0) and outside.low == pytest.approx(1.0)
    half = groups.unexplained_share(res, np.abs(res) * np.tile([1.0, 0.0], 20), clusters)
    assert half.low <= half.value <= half.high and 0 <= half.low and half.high <= 1
    assert half.value == pytest.approx(np.sum(res[::2] ** 2) / np.sum(res ** 2))
    assert not groups.unexplained_share(res[:4], res[:4], [0, 0, 1, 1]).has_interval  # two clusters


def _groups_ds(dy_pairs=0.55, dy3=0.8, dy4=0.9, band=0.2):
    """Neighbour rows of pairs (9 runs), groups of three (9 runs, 2 rows each) and four (8 runs, 3 each):
    dy/2A around the given means, residuals of 0.05 lambda, band excess ``band`` times the residual."""
    rng = np.random.default_rng(2)
    rows, dphi9 = [], np.linspace(-np.pi, np.pi, 9)
    run = 0
    for size, runs, per, dy in ((2, 9, 1, dy_pairs), (3, 9, 2, dy3), (4, 8, 3, dy4)):
        for r in range(runs):
            d = dphi9[r] if size < 4 else rng.uniform(-np.pi, np.pi)
            for _ in range(per):
                res = rng.normal(0, 0.05 * LAM)
                rows.append((size, run, d, (dy + rng.normal(0, 0.02)) * 2 * 0.05, res, band * abs(res)))
            run += 1
    size, run_i, dphi, dy, res, exc = (np.array(c) for c in zip(*rows))
    return xr.Dataset({"group_size": ("neighbour", size), "run_index": ("neighbour", run_i),
                       "dphi": ("neighbour", dphi), "dy_steady": ("neighbour", dy),
                       "residual": ("neighbour", res), "band_excess": ("neighbour", exc)},
                      attrs={"amplitude_m": 0.05})


def _groups_summary(ds):
    per = {str(n): {"n_runs": int(np.unique(ds["run_index"].values[ds["group_size"].values == n]).size),
                    "n_failed": 0} for n in (2, 3, 4)}
    return {"per_group_size": per, "lateral_spacing": groups.spacing_summary(ds)}


def test_spacing_summary_and_claim_on_constructed_groups():
    s = _groups_summary(_groups_ds())
    dy = {n: stats.Estimate.from_dict(s["lateral_spacing"]["mean_dy_over_2A"][n]) for n in ("2", "3", "4")}
    assert dy["2"].value == pytest.approx(0.55, abs=0.02) and dy["4"].value == pytest.approx(0.9, abs=0.02)
    assert dy["3"].n == 5  # clusters: the runs at +dphi and -dphi of the nine dphi together
    c = claim(groups, "lateral spacing")
    assert c.judge(s).verdict == HOLDS
    assert c.judge(_groups_summary(_groups_ds(dy3=0.3))).verdict == FAILS         # groups of 3 closer than pairs
    assert c.judge(_groups_summary(_groups_ds(band=0.95))).verdict == FAILS       # the band explains little
    assert c.judge(_groups_summary(_groups_ds(dy3=0.555))).verdict == UNDECIDED   # spacings overlap


def _spacing_row(dy3=(0.8, 0.75, 0.85), share=(0.2, 0.1, 0.3)):
    return {"per_group_size": {n: {"n_runs": 9, "n_failed": 0} for n in ("2", "3", "4")},
            "lateral_spacing": {"n_neighbour_pairs_groups": 42, "unexplained_share": est(*share),
                                "mean_dy_over_2A": {"2": est(0.55, 0.5, 0.6), "3": est(*dy3),
                                                    "4": est(0.9, 0.85, 0.95)}}}


@pytest.mark.parametrize("kw, verdict", [
    ({}, HOLDS),
    ({"dy3": (0.4, 0.35, 0.45)}, FAILS),            # groups of 3 wholly below the pairs' spacing
    ({"share": (0.7, 0.6, 0.8)}, FAILS),            # the band leaves most of the deviation
    ({"dy3": (0.6, 0.55, 0.65)}, UNDECIDED),        # overlapping spacings
    ({"share": (0.45, 0.3, 0.6)}, UNDECIDED),       # the share straddles 1/2
    ({"share": (0.2, math.nan, math.nan)}, NO_RESULT),
])
def test_spacing_claim_is_three_valued(kw, verdict):
    v = claim(groups, "lateral spacing").judge(_spacing_row(**kw))
    assert v.verdict == verdict
    if verdict == UNDECIDED:
        assert "overlaps" in v.reason or "straddles 0.5" in v.reason


def test_the_groups_spacing_claim_reads_every_size():
    c = claim(groups, "lateral spacing").claim
    from undulate.studies._registry import describe
    from undulate.studies._staging import part_plans, stage_plans

    others = {x.claim: 1 for x in groups.CLAIMS if x.claim != c}
    info = describe("groups")

    def frozen(final):
        return part_plans(info, stage_plans(info, False), final, {}, lambda study, claim: True).frozen_at

    assert frozen(others) == {}  # the spacing claim still open: no size frozen
    assert frozen({**others, c: 2}) == {groups.part(n): 2 for n in (2, 3, 4)}


# ------------------------------------------------------------------ packing
def _packing_summary(ratios=(1.0, 1.05, 0.95), above_first=True, grid_max=6.5):
    phi = [0.0, math.pi / 2, math.pi, 2 * math.pi]
    cf = [float(v) for v in theory.packing_density(phi, 0.15)]
    thr = [stats.Estimate(math.nan).to_dict() if above_first else est(cf[0], 0.95 * cf[0], 1.05 * cf[0])]
    thr += [est(r * c, (r - 0.1) * c, (r + 0.1) * c, n=3) for r, c in zip(ratios, cf[1:])]
    s = {"threshold_rho_tilde": thr, "phi_max_rad": phi, "closed_form_rho_tilde": cf,
         "closed_form_walls_rho_tilde": [0.9 * c for c in cf], "threshold_above_grid": [above_first] + [False] * 3}
    s.update(packing.closed_form_ratios(s, grid_max))
    return s


def test_closed_form_ratios_scale_the_summarys_threshold_interval():
    s = _packing_summary(ratios=(1.5, 1.6, 1.7))
    r = [stats.Estimate.from_dict(d) for d in s["threshold_over_closed_form"]]
    assert not r[0].finite
    assert (r[2].value, r[2].low, r[2].high) == pytest.approx((1.6, 1.5, 1.7))
    w = stats.Estimate.from_dict(s["threshold_over_closed_form_walls"][2])
    assert w.value == pytest.approx(1.6 / 0.9)


@pytest.mark.parametrize("kw, verdict", [
    ({"above_first": False}, HOLDS),
    ({}, UNDECIDED),                                  # phi_max = 0 above a grid ending at 0.975 x the closed form
    ({"ratios": (1.45, 1.6, 1.9)}, FAILS),            # 1.45-1.9 times denser than the closed form
    ({"ratios": (1.0, 1.15, 0.95), "above_first": False}, UNDECIDED),  # [1.05, 1.25] straddles 1.2
    ({"grid_max": 9.0}, FAILS),                       # above a grid reaching 9: more than 1.2 x the 2A/w ~ 6.7
])
def test_threshold_near_closed_form_is_three_valued(kw, verdict):
    v = claim(packing, "collision threshold agrees").judge(_packing_summary(**kw))
    assert v.verdict == verdict
    if verdict == UNDECIDED:
        assert "straddles 1.2" in v.reason or "above the density grid" in v.reason


def test_the_packing_summary_reports_the_ratio_to_the_closed_form():
    """packing.summary on a synthetic dataset whose every draw crosses at 1.5 times the closed form."""
    phi = np.array([0.0, np.pi, 2 * np.pi])
    rho = np.round(np.arange(1.0, 6.01, 0.25), 10)
    w2a, draws = 0.15, 3
    cf = theory.packing_density(phi, w2a)
    thr = np.array([[np.nan] * draws] + [[1.5 * c + 0.05 * k for k in range(draws)] for c in cf[1:]])
    lo = np.floor(thr * 4) / 4
    hi = lo + 0.25
    phi_fine = np.linspace(0, 2 * np.pi, 181)
    cf_fine = theory.packing_density(phi_fine, w2a)
    shape = (phi.size, rho.size, draws)
    ds = xr.Dataset(
        {"threshold_rho_tilde": (("phi_max", "draw"), thr), "threshold_lo": (("phi_max", "draw"), lo),
         "threshold_hi": (("phi_max", "draw"), hi), "run_failed": (("phi_max", "rho_tilde", "draw"), np.zeros(shape, bool)),
         "evaluated": (("phi_max", "rho_tilde", "draw"), np.ones(shape, bool)),
         "diverged": (("phi_max", "rho_tilde", "draw"), np.zeros(shape, bool)),
         "rho_closed_form": ("phi_fine", cf_fine), "rho_monte_carlo": ("phi_fine", cf_fine * 1.001),
         "rho_monte_carlo_stderr": ("phi_fine", cf_fine * 0.001), "amplitude": ((), 0.05),
         "lone_mean_joint_error": ((), 0.002)},
        coords={"phi_max": phi, "rho_tilde": rho, "draw": np.arange(draws), "phi_fine": phi_fine},
        attrs={"n_swimmers": 50, "w_over_2A": w2a})
    ds["threshold_lo"][0] = np.nan
    ds["threshold_hi"][0] = np.nan
    s = packing.summary(ds)
    r = [stats.Estimate.from_dict(d) for d in s["threshold_over_closed_form"]]
    assert s["rho_tilde_grid_max"] == 6.0 and not r[0].finite
    for e, t, c in zip(r[1:], s["threshold_rho_tilde"][1:], cf[1:]):
        t = stats.Estimate.from_dict(t)
        assert (e.value, e.low, e.high) == pytest.approx((t.value / c, t.low / c, t.high / c))
        assert e.low <= e.value <= e.high and 1.4 < e.value < 1.6
    (row,) = [x for x in judge("packing", packing.CLAIMS, s) if "collision threshold agrees" in x["claim"]]
    assert row["verdict"] == FAILS and "above the grid" in row["measured"]
