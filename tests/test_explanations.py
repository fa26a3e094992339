"""The `explained` verdict: a failing claim becomes `explained` only when a study's own runs
show the cause; the sensitivity study's checks, constants and explanation targets."""

from __future__ import annotations

import json
import math

import pytest

from undulate import stats
from undulate.claims import VERDICTS, apply_explanations, collect
from undulate.params import Ground, Servo
from undulate.report import write_report
from undulate.studies import describe, names
from undulate.studies import sensitivity as S
from undulate.studies import _sensitivity_summary as SS
from undulate.studies._explanations import groups, impulse, links, swimming, xi32
from undulate.studies._sensitivity_design import CaseId, CaseSet


def row(verdict, study="pairs", claim="c"):
    return {"study": study, "claim": claim, "paper": "", "measured": "m", "value": None, "verdict": verdict,
            "reason": "", "criterion": ""}


def expl(shown, study="pairs", claim="c"):
    return {"study": study, "claim": claim, "cause": "because", "shown": shown, "measured": "numbers",
            "value": None, "evidence_study": "sensitivity", "evidence_figure": "sensitivity.png"}


def test_only_a_shown_explanation_turns_fails_into_explained():
    assert "explained" in VERDICTS
    (r,) = apply_explanations([row("fails")], [expl(True)])
    assert r["verdict"] == "explained" and r["explanation"]["evidence_figure"] == "sensitivity.png"
    (r,) = apply_explanations([row("fails")], [expl(False)])
    assert r["verdict"] == "fails" and r["explanation"] is None and r["explanations_not_shown"]
    (r,) = apply_explanations([row("holds")], [expl(True)])  # a claim that holds stays `holds`
    assert r["verdict"] == "holds"
    (r,) = apply_explanations([row("no result")], [expl(True)])
    assert r["verdict"] == "no result"
    (r,) = apply_explanations([row("fails")], [expl(True, claim="another claim")])
    assert r["verdict"] == "fails"


def test_every_explanation_names_a_registered_claim():
    found = 0
    for name in names():
        for e in describe(name).explanations:
            assert e.study in names(), e
            assert e.claim in [c.claim for c in describe(e.study).claims], e
            found += 1
    assert found >= 4


def test_report_and_claims_json_show_the_cause_with_a_link_to_the_evidence(tmp_path):
    claim = describe("pairs").claims[2].claim
    (tmp_path / "pairs.json").write_text(json.dumps({"claims": [row("fails", "pairs", claim)], "files": []}))
    (tmp_path / "sensitivity.json").write_text(json.dumps(
        {"claims": [], "explanations": [expl(True, "pairs", claim)], "files": []}))
    rows = collect(tmp_path, ["pairs", "sensitivity"])
    assert [r["verdict"] for r in rows] == ["explained"]
    statuses = [{"name": n, "ok": True, "wall_s": 1.0} for n in ("pairs", "sensitivity")]
    html = write_report(tmp_path, statuses, mode="quick").read_text()
    assert "explained" in html and "href='sensitivity.png'" in html and "because" in html
    # without the evidence study the claim is reported failing
    assert [r["verdict"] for r in collect(tmp_path, ["pairs"])] == ["fails"]


def test_sensitivity_uses_the_model_defaults():
    assert S.MODEL_DEFAULTS["kp_Nm_per_rad"] == Servo().kp_Nm_per_rad
    assert S.MODEL_DEFAULTS["torque_limit_Nm"] == Servo().torque_limit_Nm
    assert S.MODEL_DEFAULTS["max_speed_rad_s"] == Servo().max_speed_rad_s
    assert S.MODEL_DEFAULTS["drag_N_s_per_m"] == Ground().drag_N_s_per_m
    for _, _, over in S.MODEL_LEVELS:  # one factor changed at a time
        assert len(over) == 1 and over != {k: S.MODEL_DEFAULTS[k] for k in over}


def E(v, lo=math.nan, hi=math.nan):
    return stats.Estimate(v, math.nan, lo, hi, 9, "test")


def test_follows_line_is_judged_on_the_intervals():
    assert S.follows_line(E(1.0, 0.9, 1.1), E(0.03, 0.02, 0.05)) is True
    # an interval straddling a bound leaves it undecided (None), one wholly outside fails
    assert S.follows_line(E(1.0, 0.7, 1.3), E(0.03, 0.02, 0.05)) is None  # slope interval straddles 0.8, 1.2
    assert S.follows_line(E(1.0, 0.9, 1.1), E(0.05, 0.02, 0.12)) is None  # RMS straddles 0.1
    assert S.follows_line(E(0.5, 0.4, 0.6), E(0.03, 0.02, 0.05)) is False
    assert S.follows_line(E(1.0, 0.9, 1.1), E(0.2, 0.15, 0.25)) is False
    assert S.follows_line(E(1.0), E(0.03, 0.02, 0.05)) is None
    # the verdict tells a straddle from a missing interval
    assert S.line_verdict(E(1.0, 0.7, 1.3), E(0.03, 0.02, 0.05)) == "undecided"
    assert S.line_verdict(E(1.0), E(0.03, 0.02, 0.05)) == "no result"
    assert S.line_verdict(E(0.5, 0.4, 0.6), E(0.03, 0.02, 0.05)) == "fails"


def _case(cid, ok):
    return {"case_id": str(cid), "claim": cid.case_set.value, "level": "any label", "n_links": cid["n_links"],
            "follows_line": ok, "slope": E(1, 0.9, 1.1).to_dict(),
            "rms_residual_over_lambda": E(0.03, 0.02, 0.04).to_dict()}


@pytest.mark.parametrize("n3, n8, shown", [(False, True, True), (False, False, False), (True, True, False)])
def test_xi_three_halves_explanation_needs_n3_failing_and_n8_holding(n3, n8, shown):
    s = {"cases": {"a": _case(xi32.N3, n3), "b": _case(xi32.N8, n8)}}
    (e,) = xi32.EXPLANATIONS
    assert e.check(s)[0] is shown
    # found by case id, not by label: the N = 8, 60 s case is another case
    s = {"cases": {"a": _case(xi32.N3, n3), "b": _case(CaseId.of(CaseSet.XI32, n_links=8, duration_s=60.0), n8)}}
    assert e.check(s)[:1] == (False,) and "no N = 3 or N = 8" in e.check(s)[1]


def test_central_state_width_and_broadening():
    assert S.central_width([0.0, 0.04, -0.05, 0.9]) == pytest.approx(0.09)  # 0.9: another branch
    assert math.isnan(S.central_width([0.8, -0.9]))
    assert SS._broadens([0.9, 1.2, 1.4], [0.0, 0.1, 0.2]) is True
    assert SS._broadens([0.9, 1.2, 1.4], [0.0, 0.0, 0.2]) is False  # opens only beyond 1.2
    assert SS._broadens([0.9, 1.2, 1.4], [0.0, 0.1, 0.05]) is False  # shrinks


def _group_ds(cases):
    """A sensitivity-shaped dataset with only the group variables: ``cases`` = (size, width, default,
    dx/lambda per neighbour as a function of dphi, residual scale, spacing m)."""
    import numpy as np
    import xarray as xr

    rng = np.random.default_rng(3)
    dphi = np.tile(np.linspace(-0.8 * np.pi, 0.8 * np.pi, 9), 4)
    rows = {k: [] for k in ("dphi", "dx", "res", "dy", "be")}
    for _, _, _, gain, scatter, dy in cases:
        noise = scatter * rng.standard_normal(dphi.size)
        dx = gain * dphi / (2 * np.pi) + noise
        rows["dphi"].append(dphi)
        rows["dx"].append(dx)
        rows["res"].append(dx - dphi / (2 * np.pi))
        rows["dy"].append(np.full(dphi.size, dy))
        rows["be"].append(np.zeros(dphi.size))
    g = ("group_case", "neighbour")
    return xr.Dataset(
        {"group_dphi": (g, np.array(rows["dphi"])), "group_dx_over_lambda": (g, np.array(rows["dx"])),
         "group_residual_over_lambda": (g, np.array(rows["res"])), "group_dy": (g, np.array(rows["dy"])),
         "group_band_excess": (g, np.array(rows["be"])),
         "group_run": (g, np.tile(np.arange(dphi.size, dtype=float), (len(cases), 1)))},  # a row a run
        coords={"group_size": ("group_case", [c[0] for c in cases]),
                "group_channel_width": ("group_case", [c[1] for c in cases]),
                "group_default": ("group_case", [c[2] for c in cases])})


@pytest.mark.parametrize("spaced_gain, spaced_scatter, shown", [
    (1.0, 0.08, True),    # at the pairs' spacing: on the line, more scatter than pairs -> the cause is shown
    (0.6, 0.08, False),   # still short of the line at the pairs' spacing: not shown
    (1.0, 0.01, None),    # on the line, scatter like the pairs': the RMS intervals overlap, undecided
    (1.0, 0.001, False),  # on the line but less scatter than pairs (wholly below): the criterion fails, not shown
])
def test_groups_explanation_needs_default_failing_and_the_pairs_spacing_meeting_the_whole_criterion(
        spaced_gain, spaced_scatter, shown):
    ds = _group_ds([(2, 0.13, True, 1.0, 0.01, 0.032), (3, 0.19, True, 0.6, 0.02, 0.040),
                    (3, S.spaced_channel_m(3), False, spaced_gain, spaced_scatter, 0.031)])
    g = SS._groups_summary(ds)
    assert g["3 in 0.19 m"]["follows_line_more_scatter"] is False
    assert g["3 in 0.19 m"]["fraction_short_of_line"] > 0.5
    three, four = groups.EXPLANATIONS
    ok, measured, _ = three.check({"groups": g})
    assert ok is shown and "0.162 m" in measured
    assert four.check({"groups": g})[0] is False  # no groups of four in this summary


@pytest.mark.parametrize("quick", [True, False])
def test_groups_cases_rerun_the_groups_studys_own_design(quick):
    """Only the channel may differ from the groups study: the same phases (and reference pairs) and the
    same number of random draws of four, in quick mode at each of its two looks the groups study's look
    (5 dphi and 4 draws, then 9 and 8), in full mode its second look (33 dphi, 40 draws; its cap grew past
    them, and the shared runs must still be found value for value)."""
    from undulate.studies import groups

    if quick:
        looks = S.stages(True)
        assert len(looks) == len(groups.stages(True)) == 2
        for p, g in zip(looks, groups.stages(True)):
            assert p.group_dphi_rad == g.dphi_rad and p.group_draws == g.draws
        assert [(len(p.group_dphi_rad), p.group_draws) for p in looks] == [(5, 4), (9, 8)]
        return
    g, p = groups.stages(False)[1], S.plan(False)
    assert p.group_dphi_rad == g.dphi_rad and p.group_draws == g.draws
    assert (len(p.group_dphi_rad), p.group_draws) == (33, 40)
    assert len(groups.plan(False).dphi_rad) > len(p.group_dphi_rad)


@pytest.mark.parametrize("quick", [True, False])
def test_impulse_cases_rerun_the_potential_studys_own_design(quick):
    """The impulse runs at the default drag are the potential study's (its dphi and common phases, quick
    and full), so the sensitivity study's default row is the claim's own number; only the drag varies.
    Quick: each look the potential study's (5 x 2, then 9 x 4); full: the potential study's third look
    (37 x 8), which its cap (73 dphi) contains bitwise."""
    from undulate.studies import potential

    pairs = (list(zip(S.stages(True), potential.stages(True))) if quick
             else [(S.plan(False), potential.stages(False)[2])])
    for p, pot in pairs:
        assert list(p.impulse_dphi_rad) == list(pot.impulse_dphi) and list(p.impulse_phi0_rad) == list(pot.impulse_phi0)
    sizes = [(len(p.impulse_dphi_rad), len(p.impulse_phi0_rad)) for p, _ in pairs]
    assert sizes == ([(5, 2), (9, 4)] if quick else [(37, 8)])


def test_spaced_channel_adds_the_pairs_spacing_per_extra_swimmer():
    assert S.spaced_channel_m(2) == S.PAIR_CHANNEL_M
    assert S.spaced_channel_m(3) == pytest.approx(0.162) and S.spaced_channel_m(4) == pytest.approx(0.194)


@pytest.mark.parametrize("default_ok, strong_ok, shown", [
    (False, True, True),    # the ellipsoid fluid model fails the criterion: the verdict rests on the model
    (False, False, True),
    (True, True, False),    # it holds there too: nothing rests on the model
    (None, True, None),     # undecided at the default
])
def test_swimming_finding_is_the_ellipsoid_model_failing_where_the_resistive_medium_is_judged(
        default_ok, strong_ok, shown):
    est = stats.Estimate(1.0, 0.01, 0.98, 1.02, 9, "t").to_dict()
    cases = {"a": {"case_id": str(swimming.DEFAULT), "claim": "swim", "follows_line": default_ok,
                   "slope": est, "rms_residual_over_lambda": est},
             "b": {"case_id": str(swimming.STRONG_DRAG), "claim": "swim",
                   "follows_line": strong_ok, "slope": est, "rms_residual_over_lambda": est}}
    (e,) = swimming.EXPLANATIONS
    assert e.finding  # never turns a failing claim into explained
    ok, measured, _ = e.check({"cases": cases, "swim_drag_pair_speed_m_s": 3.5e-3})
    assert ok is shown and "ellipsoid fluid model" in measured and "3.5 mm/s" in measured
    assert e.check({"cases": {}})[0] is False


def _drag_row(c, linear, escape):
    est = stats.Estimate(0.9, 0.02, 0.85, 0.99, 9, "t").to_dict()
    return {"case_id": str(S.impulse_case(c)), "drag_N_s_per_m": c, "default": c == S.IMPULSE_DRAG_DEFAULT, "slope_Ns_per_rad": est, "r2": est,
            "linear": linear, "phi0_spread_large_dphi": 2.0, "first_period_dx_large_dphi": escape}


@pytest.mark.parametrize("default_ok, ok8, ok16, escapes, shown", [
    (False, True, True, (0.15, 0.07, 0.04), True),
    (False, True, False, (0.15, 0.07, 0.04), False),   # must hold at every level of the scan from 8 up
    (False, True, True, (0.15, 0.16, 0.04), False),    # more drag must slow the escape (the stated cause)
    (True, True, True, (0.15, 0.07, 0.04), False),     # holds at the default: nothing to explain
])
def test_impulse_explanation_needs_the_default_failing_and_every_stronger_drag_holding(
        default_ok, ok8, ok16, escapes, shown):
    rows = [_drag_row(1.0, False, 0.19), _drag_row(S.IMPULSE_DRAG_DEFAULT, default_ok, escapes[0]),
            _drag_row(8.0, ok8, escapes[1]), _drag_row(16.0, ok16, escapes[2])]
    (e,) = impulse.EXPLANATIONS
    ok, measured, value = e.check({"impulse": {"by_drag": rows}})
    assert ok is shown and "only the drag changed" in measured and "(default)" in measured
    assert e.check({"impulse": {}})[0] is False
    assert S.IMPULSE_DRAG_DEFAULT == Ground().drag_N_s_per_m


def test_pair_scene_sets_the_viscous_drag_and_refuses_it_on_the_swimming_ground():
    from undulate.errors import ParameterError
    from undulate.studies._runners import pair_scene

    assert pair_scene({"drag_N_s_per_m": 8.0}).ground.drag_N_s_per_m == 8.0
    assert pair_scene({}).ground == Ground()
    with pytest.raises(ParameterError, match="drag_N_s_per_m"):
        pair_scene({"ground": "swimming", "drag_N_s_per_m": 8.0})


def test_more_drag_slows_the_escape_from_dx0_and_lengthens_contact():
    """Real runs (one period, dphi = 3 pi/4 from dx0 = 0): contact pushes an overdamped pair apart at
    force / drag, so with 4x the drag it has moved less after a period and collected more impulse."""
    from undulate.studies._runners import pair_point

    out = {}
    for c in (S.IMPULSE_DRAG_DEFAULT, 8.0):
        r = pair_point({"dphi_rad": 3 * math.pi / 4, "drag_N_s_per_m": c}, 0, duration_s=6.0)
        out[c] = (abs(float(r["dx_period_over_lambda"].values[0])), float(r["impulse_2T_Ns"]))
    (esc2, imp2), (esc8, imp8) = out[S.IMPULSE_DRAG_DEFAULT], out[8.0]
    assert esc8 < 0.8 * esc2 and imp8 > imp2 > 0


def _links_set(claim, values, intervals):
    return {"label": S.LINK_SETS[claim], "n_links": [3, 5, 7, 9], "amplitude_m": [0.0522] * 4,
            "wavelength_over_L": [0.93] * 4,
            "rms_residual_over_lambda": [E(v, lo, hi).to_dict() for v, (lo, hi) in zip(values, intervals)],
            "falls": S.analysis.falls_with_links([E(v, lo, hi) for v, (lo, hi) in zip(values, intervals)])}


FLAT = ([0.03, 0.035, 0.03, 0.035], [(0.02, 0.04)] * 4)  # overlapping intervals: the trend is undecided
RISING = ([0.03, 0.035, 0.04, 0.05], [(0.028, 0.032), (0.033, 0.037), (0.038, 0.042), (0.048, 0.052)])  # fails
FALLING = ([0.009, 0.003, 0.0007, 0.001], [(0.007, 0.011), (0.002, 0.004), (0.0004, 0.0009), (0.0008, 0.0012)])


WIDE_FLAT = ([0.03, 0.035, 0.03, 0.035], [(0.01, 0.09)] * 4)  # flat, too uncertain to tell from a modest fall
MODEST = ([0.03, 0.02, 0.015, 0.012], [(0.022, 0.038), (0.015, 0.025), (0.011, 0.019), (0.009, 0.015)])  # holds


@pytest.mark.parametrize("guided_x, alone, shown", [
    (FALLING, RISING, True), (RISING, RISING, False),
    (FALLING, FALLING, False),  # a partial change alone makes the trend: not this cause
    (FALLING, FLAT, True),  # a flat control: its own criterion never decides, the contrast does (fall ratio ~10)
    (MODEST, WIDE_FLAT, None),  # the contrast straddles: more runs would tell
    (FLAT, RISING, None)])
def test_links_explanation_needs_both_changes_and_neither_alone(guided_x, alone, shown):
    sets = {"links": _links_set("links", *RISING), "links-x": _links_set("links-x", *alone),
            "links-guided": _links_set("links-guided", *RISING),
            "links-guided-x": _links_set("links-guided-x", *guided_x)}
    for e in links.EXPLANATIONS:  # the two amplitude rules' claims: one cause
        assert e.check({"links_sets": sets})[0] is shown
    del sets["links-x"]
    assert links.EXPLANATIONS[0].check({"links_sets": sets})[0] is False  # a set missing: not shown


def test_links_contrast_is_a_log_ratio_test_at_the_looks_level():
    """The control's fall against the two-change set's: the difference of log(RMS_9 / RMS_3), each RMS's
    interval read as a normal interval on a log scale, decided at the look's level (a wider interval at a
    stricter level can straddle what 95 % decides)."""
    fix, flat = _links_set("links-guided-x", *FALLING), _links_set("links", *FLAT)
    state, d, lo, hi = links.weaker_fall(flat, fix)
    z = 1.959963984540054
    se = math.hypot(*(math.log(h / lo_) / (2 * z) for lo_, h in ((0.02, 0.04), (0.02, 0.04), (0.007, 0.011),
                                                                  (0.0008, 0.0012))))
    assert d == pytest.approx(math.log((0.035 / 0.03) / (0.001 / 0.009)))
    assert (lo, hi) == pytest.approx((d - z * se, d + z * se))
    assert state is True and links.weaker_fall(fix, flat)[0] is False  # the other way round: decisively less
    assert links.weaker_fall(fix, fix)[0] is None
    modest, wide = _links_set("links-guided-x", *MODEST), _links_set("links", *WIDE_FLAT)
    assert links.weaker_fall(wide, modest)[0] is None
    s_lo = links.weaker_fall(_links_set("links", [0.03, 0.035, 0.03, 0.035], [(0.02, 0.045)] * 4), modest)
    assert s_lo[0] is True  # narrower control intervals decide it at 95 % ...
    with stats.at_level(0.9999):  # ... and not at a much stricter look level
        assert links.weaker_fall(_links_set("links", [0.03, 0.035, 0.03, 0.035], [(0.02, 0.045)] * 4),
                                 modest)[0] is None


def test_the_link_number_criterion_is_judged_on_the_intervals():
    f = S.analysis.falls_with_links
    assert f([E(*v) for v in ((0.009, 0.007, 0.011), (0.003, 0.002, 0.004), (0.0007, 0.0004, 0.0009),
                              (0.001, 0.0008, 0.0012))]) is True  # the last step: a point rise inside the intervals
    assert f([E(*v) for v in ((0.009, 0.007, 0.011), (0.003, 0.002, 0.004), (0.0007, 0.0004, 0.0009),
                              (0.002, 0.0015, 0.0025))]) is False  # a rise beyond the intervals
    assert f([E(*v) for v in ((0.04, 0.03, 0.05), (0.035, 0.028, 0.045))]) is None  # overlapping: undecided
    assert f([E(*v) for v in ((0.04, 0.03, 0.05), (0.08, 0.06, 0.1))]) is False  # wholly above: fails
    assert f([E(0.04), E(0.01)]) is None


def test_a_finding_is_written_beside_the_claim_and_never_explains_it():
    """A finding (several changes together) shown by its runs leaves the failing claim `fails`, with the
    finding listed beside it; an explanation of one change beside it still explains."""
    finding = {**expl(True), "finding": True, "cause": "three changes together"}
    (r,) = apply_explanations([row("fails")], [finding])
    assert r["verdict"] == "fails" and r["explanation"] is None
    assert [f["cause"] for f in r["findings"]] == ["three changes together"] and "explanations_not_shown" not in r
    (r,) = apply_explanations([row("fails")], [{**finding, "shown": None}])
    assert r["verdict"] == "fails" and r["findings"][0]["shown"] is None
    (r,) = apply_explanations([row("fails")], [finding, {**expl(True), "finding": False}])
    assert r["verdict"] == "explained" and r["explanation"]["cause"] == "because" and len(r["findings"]) == 1
    (r,) = apply_explanations([row("holds")], [expl(True)])
    assert "findings" not in r


def test_the_report_writes_a_finding_beside_the_failing_claim(tmp_path):
    claim = describe("links").claims[0].claim
    (tmp_path / "links.json").write_text(json.dumps({"claims": [row("fails", "links", claim)], "files": []}))
    finding = {**expl(True, "links", claim), "finding": True, "cause": "three changes together recover it"}
    (tmp_path / "sensitivity.json").write_text(json.dumps({"claims": [], "explanations": [finding], "files": []}))
    rows = collect(tmp_path, ["links", "sensitivity"])
    assert [r["verdict"] for r in rows] == ["fails"] and rows[0]["findings"][0]["shown"] is True
    statuses = [{"name": n, "ok": True, "wall_s": 1.0} for n in ("links", "sensitivity")]
    html = write_report(tmp_path, statuses, mode="quick").read_text()
    assert "finding (not an explanation: the verdict stands)" in html and "three changes together" in html
