"""Three-valued verdicts of the closed-loop (PRX 2021) claims and the sensitivity study's explanations,
on constructed summaries: an interval inside its region holds, one wholly outside fails, one that
straddles a bound is undecided (never fails); counts of runs are exact."""

from __future__ import annotations

import math

import numpy as np
import pytest
import xarray as xr

from undulate import stats
from undulate.studies import phase_interaction as P
from undulate.studies import sensitivity as S
from undulate.studies import _sensitivity_summary as SS
from undulate.studies import synchronization as Y
from undulate.studies._explanations import impulse, links, swimming, xi32
from undulate.studies._explanations._protocol import all_of, negate


def E(v, lo=math.nan, hi=math.nan, n=12):
    return stats.Estimate(v, math.nan, lo, hi, n, "test")


def _claim(claims, controller: str, words: str):
    (c,) = [c for c in claims if c.claim.startswith(f"{controller}: ") and words in c.claim]
    return c


def _pair_entry(**over):
    v = {"force_ratio": E(0.08, 0.03, 0.12).to_dict(), "n_held": 12, "n_free": 12, "held_colliding": 8,
         "held_synchronized": 8, "held_colliding_in_phase": 8, "held_colliding_anti_phase": 0,
         "held_in_phase": 12, "held_anti_phase": 0, "free_anti_phase": 0, "free_in_phase": 12,
         "median_force_ratio": 0.08, "median_lock_time_s": 5.0}
    v.update(over)
    return {"per_controller": {"relay": v}, "n_failed": 0}


# ------------------------------------------------------------------ synchronization-pairs
@pytest.mark.parametrize("ratio, verdict", [
    ((0.08, 0.03, 0.12), "holds"),       # inside: below 0.5
    ((0.75, 0.6, 0.85), "fails"),        # wholly above 0.5
    ((0.88, 0.35, 0.99), "undecided"),   # straddles 0.5: the quick self-oscillating number, not a failure
    ((0.45, 0.3, 0.5), "holds"),         # the bound itself counts as inside
])
def test_force_ratio_claim_is_judged_on_its_interval(ratio, verdict):
    c = _claim(Y.PAIR_CLAIMS, "relay", "interaction force")
    v = c.judge(_pair_entry(force_ratio=E(*ratio).to_dict()))
    assert v.verdict == verdict, v
    assert f"{ratio[0]:.2f} [{ratio[1]:.2f}, {ratio[2]:.2f}]" in v.measured
    if verdict == "undecided":
        assert "0.5" in v.reason and v.runs_needed and v.runs_needed > 12


def test_force_ratio_without_a_number_or_an_interval_is_no_result():
    c = _claim(Y.PAIR_CLAIMS, "relay", "interaction force")
    assert c.judge(_pair_entry(force_ratio=E(math.nan).to_dict())).verdict == "no result"
    v = c.judge(_pair_entry(force_ratio=E(0.2).to_dict()))  # two colliding runs: a median, no interval
    assert v.verdict == "no result" and "no interval" in v.reason


def test_held_lock_counts_only_colliding_runs_in_its_text():
    """The quick relay run: 8 held runs collided, none synchronized; the 4 in phase never collided.
    The text once read "0/8 colliding ... (in phase 4, anti-phase 0)" (in phase over all held runs)."""
    c = _claim(Y.PAIR_CLAIMS, "relay", "lock in phase")
    v = c.judge(_pair_entry(held_synchronized=0, held_colliding_in_phase=0, held_colliding_anti_phase=0,
                            held_in_phase=4, held_anti_phase=0))
    assert v.verdict == "fails"
    assert v.measured.startswith("0/8 colliding held runs end within 30 deg of 0 or pi (in phase 0, anti-phase 0)")
    assert "the 4 held runs that never collided: in phase 4, anti-phase 0" in v.measured
    assert c.judge(_pair_entry()).verdict == "holds"
    assert c.judge(_pair_entry(held_colliding=0)).verdict == "no result"


def _pairs_dataset(finals_deg, force_start):
    """A synchronization-pairs-shaped dataset: one controller, held then free runs."""
    n = len(finals_deg)
    final = np.radians(np.array([finals_deg, finals_deg], float))[None, :, :, None]
    fs = np.array([force_start, force_start], float)[None, :, :, None]
    dims = ("controller", "hold_x", "dphi0_rad", "replicate")
    return xr.Dataset({"dphi_final": (dims, final), "force_start": (dims, fs), "force_end": (dims, 0.5 * fs),
                       "lock_time": (dims, np.full(final.shape, 3.0)),
                       "run_failed": (dims, np.zeros(final.shape, bool))},
                      coords={"controller": ["relay"], "hold_x": [True, False],
                              "dphi0_rad": np.linspace(-np.pi, np.pi, n, endpoint=False), "replicate": [0]})


def test_pair_summary_counts_in_and_anti_phase_among_the_colliding_runs():
    # the quick relay held runs: the four that end in phase are the four that never collided
    finals = [-43.2, -82.8, -40.2, -19.8, -12.6, -3.6, 47.4, 10.8, 75.6, 79.2, -82.8, 79.2]
    fs = [0.463, 3.938, 0.114, 0.022, 0.012, 0.003, 0.199, 0.014, 2.924, 3.482, 3.286, 3.353]
    v = Y.pair_summary(_pairs_dataset(finals, fs))["per_controller"]["relay"]
    assert (v["n_held"], v["held_colliding"], v["held_synchronized"]) == (12, 8, 0)
    assert (v["held_colliding_in_phase"], v["held_in_phase"]) == (0, 4)
    text = _claim(Y.PAIR_CLAIMS, "relay", "lock in phase").judge({"per_controller": {"relay": v}}).measured
    assert text.startswith("0/8 colliding held runs") and "(in phase 0, anti-phase 0)" in text


@pytest.mark.parametrize("held, free, verdict", [(5, 1, "holds"), (5, 5, "fails"), (0, 2, "fails")])
def test_anti_phase_claim_is_a_count(held, free, verdict):
    c = _claim(Y.PAIR_CLAIMS, "relay", "anti-phase locking disappears")
    v = c.judge(_pair_entry(held_anti_phase=held, free_anti_phase=free))
    assert v.verdict == verdict and f"{free}/12" in v.measured
    assert ("premise" in v.measured) == (held == 0)


# ------------------------------------------------------------------ synchronization-groups
@pytest.mark.parametrize("both, verdict", [(5, "holds"), (4, "fails")])
def test_groups_end_both_is_a_count(both, verdict):
    v = {"n_runs": 8, "both": both, "phase_locked": 8, "compatible": both, "median_R_final": 0.4,
         "median_collective_frequency_hz": 0.5, "free_frequency_hz": 0.5}
    c = _claim(Y.GROUP_CLAIMS, "relay", "end phase-locked")
    r = c.judge({"per_controller": {"relay": v}})
    assert r.verdict == verdict and r.measured.startswith(f"{both}/8 runs both, 8/8 phase-locked, {both}/8 compatible")


# ------------------------------------------------------------------ phase-interaction
def _h_entry(k, n=10, zeros=()):
    bins = [{"centre": c, "H": E(0.1, 0.05, 0.15).to_dict()} for c in np.linspace(-3, 3, 12)]
    drift = [0.0] * (n - 2) + [0.5, -0.5]
    return {"per_controller": {"relay": {"held": {
        "n_runs": n, "n_predicted": k, "all_neutral": False, "stable_zeros": list(zeros), "neutral_bins": [1, 2],
        "bins": bins, "predicted": [True] * k + [False] * (n - k), "drift_rad_s": drift,
        "n_locked": n - 2, "finals_rad": [0.0] * n}}}}


@pytest.mark.parametrize("k, verdict", [(8, "holds"), (7, "fails")])
def test_phase_interaction_claim_is_a_count_and_its_text_adds_up(k, verdict):
    c = _claim(P.CLAIMS, "relay", "held pairs lock")
    v = c.judge(_h_entry(k))
    assert v.verdict == verdict
    assert v.measured.startswith(f"{k}/10 runs end at a state H predicts: {min(k, 8)}/8 locked runs")
    assert f"{k - min(k, 8)}/2 still drifting" in v.measured and "2/12 bins neutral" in v.measured


def test_a_stable_zero_near_pi_is_shown_with_its_interval_around_it():
    # the zero is wrapped into (-pi, pi], its interval is not: -178 deg with [175, 189] deg unwrapped
    z = {"zero_rad": math.radians(-178.0), "ci95": [math.radians(175.0), math.radians(189.0)],
         "slope_per_s": -1.0, "bins": [11, 0]}
    v = _claim(P.CLAIMS, "relay", "held pairs lock").judge(_h_entry(8, zeros=[z]))
    assert "-178 deg [-185, -171]" in v.measured, v.measured


# ------------------------------------------------------------------ sensitivity and its explanations
INSIDE = (E(1.0, 0.9, 1.1), E(0.03, 0.02, 0.05))
OUTSIDE = (E(0.4, 0.3, 0.5), E(0.3, 0.25, 0.35))
STRADDLES = (E(1.0, 0.7, 1.3), E(0.03, 0.02, 0.05))  # the slope's interval straddles 0.8 and 1.2
MISSING = (E(1.0), E(0.03))


def test_the_sensitivity_line_criterion_is_three_valued():
    assert [S.follows_line(*x) for x in (INSIDE, OUTSIDE, STRADDLES, MISSING)] == [True, False, None, None]
    assert [S.line_verdict(*x) for x in (INSIDE, OUTSIDE, STRADDLES, MISSING)] == [
        "holds", "fails", "undecided", "no result"]


def test_the_impulse_linearity_criterion_is_three_valued():
    x = np.abs(np.linspace(-np.pi, np.pi, 9))
    rng = np.random.default_rng(0)
    _, ok, verdict = SS._linear(x, 0.3 * x + 0.001 * rng.standard_normal(x.size))
    assert (ok, verdict) == (True, "holds")
    _, ok, verdict = SS._linear(x, rng.standard_normal(x.size))
    assert ok is not True and verdict in ("fails", "undecided")
    _, ok, verdict = SS._linear(x[:2], x[:2])
    assert (ok, verdict) == (None, "no result")


def _case(cid, fit):
    slope, rms = fit
    return {"case_id": str(cid), "claim": cid.case_set.value, "n_links": dict(cid.levels).get("n_links", 3),
            "follows_line": S.follows_line(slope, rms), "follows_line_verdict": S.line_verdict(slope, rms),
            "slope": slope.to_dict(), "rms_residual_over_lambda": rms.to_dict()}


@pytest.mark.parametrize("n3, n8, shown", [
    (OUTSIDE, INSIDE, True),
    (OUTSIDE, OUTSIDE, False),     # N = 8 fails: refuted
    (INSIDE, STRADDLES, False),    # N = 3 holds: refuted, whatever N = 8 says
    (OUTSIDE, STRADDLES, None),    # N = 8 straddles: undecided
    (STRADDLES, INSIDE, None),
    (OUTSIDE, MISSING, None),      # N = 8 has no interval yet: undecided, its text says "no result"
])
def test_xi32_explanation_is_three_valued(n3, n8, shown):
    (e,) = xi32.EXPLANATIONS
    ok, measured, value = e.check({"cases": {"a": _case(xi32.N3, n3), "b": _case(xi32.N8, n8)}})
    assert ok is shown, measured
    if n8 is STRADDLES:
        assert "(criterion: undecided)" in measured
    if n8 is MISSING:
        assert "(criterion: no result)" in measured


@pytest.mark.parametrize("default, strong, shown", [
    (OUTSIDE, INSIDE, True),       # the ellipsoid fluid model fails the criterion: the finding is shown
    (OUTSIDE, STRADDLES, True),    # the stronger drag is reported beside it, not judged
    (STRADDLES, INSIDE, None),
    (INSIDE, INSIDE, False),       # it holds there too: nothing rests on the model
])
def test_swimming_finding_is_three_valued(default, strong, shown):
    (e,) = swimming.EXPLANATIONS
    s = {"cases": {"a": _case(swimming.DEFAULT, default), "b": _case(swimming.STRONG_DRAG, strong)},
         "swim_drag_pair_speed_m_s": 3e-3}
    assert e.check(s)[0] is shown
    assert e.check({**s, "swim_drag_pair_speed_m_s": None})[0] is shown  # a speed lost in a JSON round trip


def _drag_row(c, linear, escape=0.1):
    est = E(0.9, 0.85, 0.99).to_dict()
    return {"case_id": str(S.impulse_case(c)), "drag_N_s_per_m": c, "default": c == S.IMPULSE_DRAG_DEFAULT,
            "slope_Ns_per_rad": est, "r2": est, "linear": linear, "phi0_spread_large_dphi": 2.0,
            "first_period_dx_large_dphi": escape}


@pytest.mark.parametrize("default, ok8, ok16, shown", [
    (False, True, True, True), (False, None, True, None), (None, True, True, None), (False, None, False, False)])
def test_impulse_explanation_is_three_valued(default, ok8, ok16, shown):
    rows = [_drag_row(1.0, False, 0.2), _drag_row(S.IMPULSE_DRAG_DEFAULT, default, 0.15),
            _drag_row(8.0, ok8, 0.07), _drag_row(16.0, ok16, 0.04)]
    (e,) = impulse.EXPLANATIONS
    assert e.check({"impulse": {"by_drag": rows}})[0] is shown


_RMS = {True: ([0.009, 0.003, 0.0007, 0.001], [(0.007, 0.011), (0.002, 0.004), (0.0004, 0.0009), (0.0008, 0.0012)]),
        False: ([0.03, 0.035, 0.04, 0.05], [(0.028, 0.032), (0.033, 0.037), (0.038, 0.042), (0.048, 0.052)]),
        None: ([0.03, 0.035, 0.03, 0.035], [(0.02, 0.04)] * 4)}  # falling (holds), rising (fails), flat


def _links_set(claim, falls):
    values, intervals = _RMS[falls]
    rms = [stats.Estimate(v, math.nan, lo, hi) for v, (lo, hi) in zip(values, intervals)]
    assert S.analysis.falls_with_links(rms) is falls
    return {"label": S.LINK_SETS[claim], "n_links": [3, 5, 7, 9], "amplitude_m": [0.05] * 4,
            "wavelength_over_L": [0.93] * 4, "rms_residual_over_lambda": [e.to_dict() for e in rms], "falls": falls}


@pytest.mark.parametrize("guided_x, others, shown", [
    (True, False, True), (None, False, None), (False, None, False), (True, True, False),
    (True, None, True)])  # flat controls: decided by their fall against the two-change set's, not left undecided
def test_links_explanation_is_three_valued(guided_x, others, shown):
    sets = {k: _links_set(k, others) for k in ("links", "links-x", "links-guided")}
    sets["links-guided-x"] = _links_set("links-guided-x", guided_x)
    assert links.EXPLANATIONS[0].check({"links_sets": sets})[0] is shown


def test_three_valued_logic_of_the_conditions():
    assert all_of(True, True) is True and all_of(True, None) is None and all_of(None, False) is False
    assert all_of(np.bool_(True)) is True
    assert negate(None) is None and negate(True) is False
