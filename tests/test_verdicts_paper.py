"""Three-valued verdicts of the paper's claims (groups, swimming, basins, confinement, potential, packing).

Constructed summaries, shaped like each study's ``summary``: an interval inside its accepted region
holds, one wholly outside fails, one that straddles a boundary leaves the claim undecided (with the
boundary named in the reason).  Criteria on counts or numbers without an interval are never undecided.
"""

from __future__ import annotations

import math

import pytest

from undulate import stats
from undulate.studies import describe
from undulate.studies import _analysis as C
from undulate.studies._protocol import FAILS, HOLDS, NO_RESULT, UNDECIDED, judge


def est(value, low, high, n=9):
    return stats.Estimate(value, math.nan, low, high, n, "test").to_dict()


def rows(name, summary):
    return judge(name, describe(name).claims, summary)


def verdicts(name, summary):
    return [r["verdict"] for r in rows(name, summary)]


# ------------------------------------------------------------------ groups
def groups_summary(slope=(1.0, 0.9, 1.1), rms=(0.1, 0.08, 0.12), pair_rms=(0.03, 0.02, 0.04)):
    def group(size, slope_, rms_):
        return {"group_size": size, "n_neighbour_pairs": 18, "n_runs": 9, "n_failed": 0, "slope": est(*slope_),
                "rms_residual_over_lambda": est(*rms_)}

    spacing = {"n_neighbour_pairs_groups": 42, "unexplained_share": est(0.2, 0.1, 0.3),  # holds: its own tests
               "mean_dy_over_2A": {"2": est(0.55, 0.5, 0.6), "3": est(0.8, 0.75, 0.85), "4": est(0.9, 0.85, 0.95)}}
    return {"per_group_size": {"2": group(2, (1.0, 0.95, 1.05), pair_rms), "3": group(3, slope, rms),
                               "4": group(4, slope, rms)}, "lateral_spacing": spacing}


@pytest.mark.parametrize("kw, verdict", [
    ({}, HOLDS),
    ({"slope": (0.6, 0.5, 0.7)}, FAILS),             # slope wholly below 1 - 0.2
    ({"slope": (0.76, 0.62, 0.9)}, UNDECIDED),       # slope straddles 0.8
    ({"rms": (0.3, 0.25, 0.35)}, FAILS),             # RMS wholly above 0.2
    ({"rms": (0.17, 0.12, 0.22)}, UNDECIDED),        # RMS straddles 0.2
    ({"rms": (0.01, 0.005, 0.015)}, FAILS),          # RMS wholly below the pairs'
    ({"rms": (0.05, 0.03, 0.07)}, UNDECIDED),        # RMS overlaps the pairs'
    ({"slope": (0.6, 0.5, 0.7), "rms": (0.17, 0.12, 0.22)}, FAILS),  # one fails: fails
])
def test_groups(kw, verdict):
    r = rows("groups", groups_summary(**kw))[:2]  # the lateral-spacing claim: test_new_claims_*
    assert [x["verdict"] for x in r] == [verdict] * 2
    if verdict == UNDECIDED:
        assert "straddles" in r[0]["reason"] or "overlaps" in r[0]["reason"]


def test_groups_missing_interval_is_no_result():
    s = groups_summary()
    s["per_group_size"]["2"]["rms_residual_over_lambda"] = stats.Estimate(math.nan).to_dict()
    assert verdicts("groups", s)[:2] == [NO_RESULT] * 2


def test_group_follows_line_is_three_valued():
    E = stats.Estimate
    pair = E(0.03, math.nan, 0.02, 0.04, 9)
    assert C.group_follows_line(E(1.0, math.nan, 0.9, 1.1, 9), E(0.1, math.nan, 0.08, 0.12, 9), pair) is True
    assert C.group_follows_line(E(0.6, math.nan, 0.5, 0.7, 9), E(0.1, math.nan, 0.08, 0.12, 9), pair) is False
    assert C.group_follows_line(E(0.76, math.nan, 0.62, 0.9, 9), E(0.1, math.nan, 0.08, 0.12, 9), pair) is None
    assert C.group_follows_line(E(1.0), E(0.1, math.nan, 0.08, 0.12, 9), pair) is None  # no interval
    checks = C.group_follows_line_checks(E(0.76, math.nan, 0.62, 0.9, 9), E(0.1, math.nan, 0.08, 0.12, 9), pair)
    assert [c.state for c in checks] == [None, True, True] and "0.8" in checks[0].text


# ------------------------------------------------------------------ swimming
def swimming_summary(slope=(1.0, 0.9, 1.1), rms=(0.04, 0.03, 0.05)):
    line = {"slope": est(1.0, 0.95, 1.05), "rms_residual_over_lambda": est(0.03, 0.02, 0.04)}
    return {"lone_swimmer_speed_m_s": 0.0085,
            "lone_swimmer_speed_body_lengths_per_period": 0.0085 * 2.0 / 0.54,
            "modes": {"viscous": line, "resistive": {"slope": est(*slope), "rms_residual_over_lambda": est(*rms)}}}


@pytest.mark.parametrize("kw, verdict", [
    ({}, HOLDS),
    ({"slope": (1.5, 1.3, 1.7)}, FAILS),
    ({"slope": (0.92, 0.24, 1.6)}, UNDECIDED),   # straddles both 0.8 and 1.2
    ({"rms": (0.26, 0.11, 0.36)}, FAILS),        # wholly above 0.1
    ({"rms": (0.09, 0.06, 0.12)}, UNDECIDED),    # straddles 0.1
])
def test_swimming(kw, verdict):
    r = rows("swimming", swimming_summary(**kw))
    assert r[0]["verdict"] == verdict
    if verdict == UNDECIDED:
        assert "straddles" in r[0]["reason"]


def test_swimming_missing_interval_is_no_result():
    s = swimming_summary()
    s["modes"]["resistive"]["slope"] = stats.Estimate(math.nan).to_dict()
    assert verdicts("swimming", s) == [NO_RESULT]


# ------------------------------------------------------------------ basins (counts: exact)
def basins_summary(returned=11, pushed=16, negative=(-0.33, -0.34, -0.32)):
    nan = stats.Estimate(math.nan).to_dict()
    treads = {"tread_share": est(0.75, 0.6, 0.9), "line_distance": est(0.11, 0.08, 0.14),  # holds: its own tests
              "n_pairs": 72, "n_treads": 54, "n_offsets": 81, "n_starts": 9, "n_phases": 9}
    return {"n_returned": returned, "n_pushed_away_from_zero": pushed, "n_starts_dphi0": 29,
            "return_threshold": {"positive": {"threshold_dx0_over_lambda": est(0.29, 0.28, 0.30)},
                                 "negative": {"threshold_dx0_over_lambda": est(*negative) if negative else nan}},
            "stair_steps": treads, "stair_steps_sinusoid": {**treads, "tread_share": est(0.0, 0.0, 0.0)},
            # the superseded every-start reading (judged beside the current one)
            "stair_steps_all_starts": treads,
            "stair_steps_sinusoid_all_starts": {**treads, "tread_share": est(0.0, 0.0, 0.0)}}


def test_basins_is_exact():
    assert verdicts("basins", basins_summary()) == [HOLDS] * 2
    assert verdicts("basins", basins_summary(pushed=0))[0] == FAILS
    assert verdicts("basins", basins_summary(returned=0))[0] == FAILS
    assert verdicts("basins", basins_summary(negative=None))[0] == FAILS  # not bracketed on one side


# ------------------------------------------------------------------ confinement (a trend: test_confinement_trend.py)
def confinement_summary(widths=(0.0, 0.02, 0.05, 0.08, 0.18), never_shrinks=True):
    from undulate.studies import confinement

    d = [0.6, 0.8, 1.0, 1.2, 1.5]
    fit = confinement.broadening_trend(d, widths)
    inside = max(w for a, w in zip(d, widths) if a <= 1.2)
    return {"d_over_2A": d, "central_width_over_lambda": list(widths), "max_width_in_paper_range": inside,
            "width_never_shrinks_with_d": never_shrinks, "broadening_slope_per_d_over_2A": fit.slope.to_dict(),
            "broadening_intercept_over_lambda": fit.intercept.to_dict(), "n_runs_in_broadening_fit": 11 * fit.n}


def test_confinement_is_a_trend_with_its_step_by_step_criterion_beside_it():
    def both(s):
        (r,) = rows("confinement", s)
        return r["verdict"], r["superseded"][0]["verdict"]

    assert both(confinement_summary()) == (HOLDS, HOLDS)
    assert both(confinement_summary((0.0, 0.0, 0.0, 0.0, 0.18))) == (FAILS, FAILS)  # opens only beyond 1.2
    assert both(confinement_summary(never_shrinks=False)) == (HOLDS, FAILS)
    s = confinement_summary()
    s["max_width_in_paper_range"] = None
    assert both(s) == (HOLDS, NO_RESULT)


# ------------------------------------------------------------------ potential
def potential_summary(r2=(0.95, 0.92, 0.99), a=(4.0, 2.5, 5.5), fit_r2=(0.99, 0.978, 1.0),
                      rho=((-1.0, -1.0, -1.0),) * 3, collapse=((0.2, 0.1, 0.3), (0.6, 0.45, 0.75)),
                      amp_ratio=((0.5, 0.2, 0.8),) * 3, impulse_steps=((0.01, 0.005, 0.015),) * 2):
    return {"impulse_fit": {"slope_Ns_per_rad": est(*a), "r2": est(*r2), "r2_without_phase_scatter": est(*r2)},
            "median_fit_r2": fit_r2[0], "fit_r2_ci95_low_median": fit_r2[1], "fit_r2_ci95_high_median": fit_r2[2],
            "n_fits": 9, "n_fit_points": 45, "fit_r2_level": stats.CONFIDENCE, "d_over_2A": [0.5, 0.6, 0.7],
            "per_beta": {b: {"spearman_k_vs_d": est(*r, n=3), "channel_width_m": [0.1, 0.12, 0.14],
                             "stiffness_N_per_m": [est(3.0, 2.0, 4.0), est(2.0, 1.5, 2.5), est(1.0, 0.5, 1.5)]}
                         for b, r in zip(("30", "45", "60"), rho)},
            "impulse_by_amplitude": {"n_starts": 32, "mean_impulse_Ns": {b: est(0.02 * (i + 1), 0.01, 0.07, n=32)
                                                                         for i, b in enumerate(("30", "45", "60"))},
                                     "steps": {k: {"increase_Ns": est(*e, n=32)} for k, e in
                                               zip(("30-45", "45-60"), impulse_steps)}},
            "collapse_rms_log10k_vs_d_over_2A": est(*collapse[0]), "collapse_rms_log10k_vs_d_m": est(*collapse[1]),
            "k_by_amplitude_at_width": {
                key: {"beta_low_deg": float(key.split("-")[0]), "beta_high_deg": float(key.split("-")[1]),
                      "at_channel_widths_m": [0.13, 0.14], "log_k_ratio": est(*r, n=4)}
                for key, r in zip(("30-45", "30-60", "45-60"), amp_ratio)},
            # the dx0 and release claims hold here (their own tests: tests/test_new_claims_potential_basins.py)
            "dx0_vs_model": {"n_fits": 9, "n_below": 9, "n_above": 0, "n_unresolved": 0,
                             "share_below": est(1.0, 0.66, 1.0), "share_not_above": est(1.0, 0.66, 1.0),
                             "mean_difference_over_lambda": est(-0.1, -0.12, -0.08)},
            "release": {"sustain_frac": 0.1, "runs": [
                {"beta_deg": 45.0, "d_over_2A": 0.8, "force_N": 0.02, "failed": False,
                 "separation": est(0.04, 0.039, 0.041), "drift_3T": est(0.0, -0.001, 0.001),
                 "back": est(0.035, 0.03, 0.04)}]}}


def test_potential_holds():
    assert verdicts("potential", potential_summary()) == [HOLDS] * 8


@pytest.mark.parametrize("kw, index, verdict", [
    ({"r2": (0.8, 0.7, 0.88)}, 0, FAILS),             # R^2 wholly below 0.9
    ({"r2": (0.85, 0.74, 0.98)}, 0, UNDECIDED),       # straddles 0.9
    ({"a": (-1.0, -2.0, -0.5)}, 0, FAILS),            # slope wholly below 0
    ({"a": (0.5, -0.5, 1.5)}, 0, UNDECIDED),          # slope straddles 0
    ({"fit_r2": (0.8, 0.7, 0.85)}, 1, FAILS),         # the median upper bound below 0.9
    ({"fit_r2": (0.93, 0.85, 1.0)}, 1, UNDECIDED),    # median bounds straddle 0.9
    ({"rho": ((0.5, 0.2, 1.0),) + ((-1.0, -1.0, -1.0),) * 2}, 2, FAILS),
    ({"rho": ((-0.5, -1.0, 1.0),) + ((-1.0, -1.0, -1.0),) * 2}, 2, UNDECIDED),  # 3 widths: straddles 0
    ({"collapse": ((0.6, 0.45, 0.75), (0.2, 0.1, 0.3))}, 3, FAILS),   # wholly larger against d/2A
    ({"collapse": ((0.37, 0.02, 0.46), (0.6, 0.14, 0.74))}, 3, UNDECIDED),  # intervals overlap
    ({"amp_ratio": ((0.5, 0.2, 0.8), (-0.4, -0.7, -0.1), (0.5, 0.2, 0.8))}, 4, FAILS),  # larger A softer
    ({"amp_ratio": ((0.5, 0.2, 0.8), (0.1, -0.2, 0.4), (0.5, 0.2, 0.8))}, 4, UNDECIDED),  # straddles 0
    ({"impulse_steps": ((0.01, 0.005, 0.015), (-0.01, -0.015, -0.005))}, 7, FAILS),  # the larger beta less
    ({"impulse_steps": ((0.01, -0.005, 0.025), (0.01, 0.005, 0.015))}, 7, UNDECIDED),  # straddles 0
])
def test_potential(kw, index, verdict):
    r = rows("potential", potential_summary(**kw))
    assert r[index]["verdict"] == verdict
    assert all(x["verdict"] == HOLDS for k, x in enumerate(r) if k != index)
    if verdict == UNDECIDED:
        assert "straddles" in r[index]["reason"] or "overlaps" in r[index]["reason"]


def test_harmonic_runs_needed_count_the_fits_points_not_the_fits():
    """Each dF = k (dx - dx0) fit's R^2 interval rests on its own forces, so more fits do not narrow the
    median bounds; the runs that would decide it scale the fits' points (13 forces x 27 fits here), and
    each fit's quantile is t on its 13 points less one."""
    from scipy import stats as st

    s = potential_summary(fit_r2=(0.958, 0.897, 0.998))
    s.update(n_fits=27, n_fit_points=351, fit_r2_level=0.97)
    r = rows("potential", s)[1]
    assert r["verdict"] == UNDECIDED
    gap, half = 0.958 - 0.9, 0.958 - 0.897
    g = r["runs_needed"] / 351  # the least growth of the points per fit whose half-width clears the gap

    def half_at(growth):
        return half * st.t.ppf(0.985, 13 * growth - 1) / st.t.ppf(0.985, 12) / math.sqrt(growth)

    assert half_at(g) <= gap < half_at((r["runs_needed"] - 1) / 351)
    assert r["runs_needed"] < math.ceil(351 * (half / gap) ** 2)  # the plain 1/sqrt(n) rule's
    assert "97 % intervals, 95 % over the looks" in r["measured"]


def test_potential_missing_numbers_are_no_result():
    s = potential_summary()
    s["impulse_fit"]["r2"] = stats.Estimate(math.nan).to_dict()
    s["per_beta"]["30"]["spearman_k_vs_d"] = stats.Estimate(math.nan).to_dict()
    s["collapse_rms_log10k_vs_d_m"] = stats.Estimate(math.nan).to_dict()
    s["impulse_by_amplitude"]["steps"]["45-60"]["increase_Ns"] = stats.Estimate(math.nan).to_dict()
    assert verdicts("potential", s) == [NO_RESULT, HOLDS, NO_RESULT, NO_RESULT, HOLDS, HOLDS, HOLDS, NO_RESULT]


# ------------------------------------------------------------------ packing
def packing_summary(rho=(-0.96, -1.0, -0.71), thresholds=((3.66, 3.54, 3.78), (2.69, 2.36, 3.01), (2.09, 1.86, 2.31)),
                    above_first=True, rel=0.0009):
    thr = [stats.Estimate(math.nan).to_dict() if above_first else est(5.0, 4.8, 5.2, n=2)]
    thr += [est(*t, n=2) for t in thresholds]
    means = ([] if above_first else [5.0]) + [t[0] for t in thresholds]  # the summary's: above the grid is larger
    from undulate.studies import packing

    cf = [6.67, 2.52, 1.65, 1.28]  # the closed form (quick's last three); ratio claim: test_new_claims_*
    ratios = packing.closed_form_ratios({"threshold_rho_tilde": thr, "closed_form_rho_tilde": cf,
                                         "closed_form_walls_rho_tilde": cf}, 6.5)
    return {**ratios, "closed_form_rho_tilde": cf, "spearman_threshold_vs_phi_max": est(*rho, n=6),
            "largest_rise_of_threshold_between_neighbouring_phi_max": max(b - a for a, b in zip(means, means[1:])),
            "threshold_rho_tilde": thr, "phi_max_rad": [0.0, math.pi / 2, math.pi, 2 * math.pi],
            "threshold_above_grid": [above_first, False, False, False], "n_diverged": 0, "n_runs": 40,
            "max_rel_diff_closed_form_vs_monte_carlo": rel, "monte_carlo_rel_stderr_at_max_diff": 0.0011}


def test_packing_holds():
    assert verdicts("packing", packing_summary())[:2] == [HOLDS, HOLDS]
    assert verdicts("packing", packing_summary(above_first=False))[:2] == [HOLDS, HOLDS]


@pytest.mark.parametrize("kw, verdict, words", [
    ({"rho": (0.5, 0.2, 0.8)}, FAILS, ""),                      # rho wholly above 0
    ({"rho": (-0.4, -0.9, 0.3)}, UNDECIDED, "straddles"),       # rho straddles 0
    # a rise beyond the intervals: fails
    ({"thresholds": ((2.0, 1.9, 2.1), (2.69, 2.5, 2.9), (2.09, 1.86, 2.31))}, FAILS, ""),
    # the mean rises inside overlapping intervals: undecided
    ({"thresholds": ((2.6, 2.3, 2.9), (2.69, 2.36, 3.01), (2.09, 1.86, 2.31))}, UNDECIDED, "rises inside"),
])
def test_packing_threshold_falls(kw, verdict, words):
    r = rows("packing", packing_summary(**kw))
    assert r[0]["verdict"] == verdict and r[1]["verdict"] == HOLDS
    assert words in r[0]["reason"]


def test_packing_rise_above_the_grid_fails():
    s = packing_summary(above_first=False)
    s["threshold_rho_tilde"][-1] = stats.Estimate(math.nan).to_dict()
    s["threshold_above_grid"][-1] = True
    assert verdicts("packing", s)[0] == FAILS


def test_packing_closed_form_is_exact():
    assert verdicts("packing", packing_summary(rel=0.02))[1] == FAILS
    assert verdicts("packing", packing_summary(rel=0.0099))[1] == HOLDS
