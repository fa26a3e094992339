"""Claims live beside their studies: pure functions of the study's summary, judged on intervals.

(Every registered study's claims are also judged on real quick runs: test_registry_suite.py.)
"""

import math

import pytest

from undulate import stats
from undulate.studies import Verdict, describe
from undulate.studies._protocol import judge


def est(value, low, high):
    return stats.Estimate(value, math.nan, low, high, 9, "test").to_dict()


def pairs_summary(slope=(1.0, 0.95, 1.05), rms=(0.03, 0.02, 0.04), std0=(0.3, 0.2, 0.4)):
    row = {"slope": est(*slope), "rms_residual_over_lambda": est(*rms), "rms_residual_m": est(*(0.54 * v for v in rms)),
           "n_runs": 9, "n_steady": 9, "n_failed": 0}
    contact = {"n_configurations": 16, "n_runs_used": 32, "n_not_steady": 0, "n_no_initial_contact": 0,
               "n_zero_steady_force": 8, "n_small_ratio": 16, "some_share": 0.125,
               "ratio_median": est(0.05, 0.0, 0.3), "ratio_some_quantile": est(0.0, 0.0, 0.0)}
    approach = {"n_runs_used": 32, "n_configurations": 16, "n_runs_slowing": 32,
                "initial_rate_over_lambda_per_period": est(0.05, 0.04, 0.06),
                "late_rate_over_lambda_per_period": est(0.001, 0.0, 0.002),
                "rate_drop_over_lambda_per_period": est(0.049, 0.039, 0.059)}
    return {"per_xi": {"1": {**row, "contact": contact, "approach": approach}, "0.75": dict(row), "1.5": dict(row),
                       "0": {"dx_std": est(*std0)}}}


def verdicts(name, summary):
    return [r["verdict"] for r in judge(name, describe(name).claims, summary)]


def test_pairs_claims_are_judged_on_the_intervals():
    assert verdicts("pairs", pairs_summary()) == ["holds"] * 7  # the three after the standing wave: test_new_claims_*
    # the value is within tolerance but the interval straddles the bounds: undecided, not demonstrated
    assert verdicts("pairs", pairs_summary(slope=(1.0, 0.7, 1.3)))[:3] == ["undecided"] * 3
    assert verdicts("pairs", pairs_summary(rms=(0.08, 0.05, 0.12)))[0] == "undecided"
    assert verdicts("pairs", pairs_summary(std0=(0.3, 0.01, 0.5)))[3] == "undecided"
    # an interval wholly outside the accepted region fails
    assert verdicts("pairs", pairs_summary(slope=(1.5, 1.3, 1.7)))[:3] == ["fails"] * 3
    assert verdicts("pairs", pairs_summary(rms=(0.2, 0.15, 0.25)))[0] == "fails"
    assert verdicts("pairs", pairs_summary(std0=(0.01, 0.005, 0.02)))[3] == "fails"


def test_an_undecided_claim_names_the_straddled_boundary_and_the_runs_it_needs():
    row = judge("pairs", describe("pairs").claims, pairs_summary(slope=(1.0, 0.7, 1.3)))[0]
    assert row["verdict"] == "undecided" and "straddles 0.8 and 1.2" in row["reason"]
    # the half-width 0.3 must shrink to the distance 0.2 from the boundary: 9 (0.3 / 0.2)^2 = 20.25 -> 21 runs
    assert row["runs_needed"] == 21


def test_missing_interval_is_no_result_with_a_reason():
    s = pairs_summary()
    s["per_xi"]["1"]["slope"] = stats.Estimate(math.nan).to_dict()
    row = judge("pairs", describe("pairs").claims, s)[0]
    assert row["verdict"] == "no result" and "interval" in row["reason"]


def test_a_renamed_key_raises_instead_of_becoming_no_result():
    s = pairs_summary()
    s["per_xi"]["1"]["slope_renamed"] = s["per_xi"]["1"].pop("slope")
    with pytest.raises(KeyError):
        judge("pairs", describe("pairs").claims, s)


def test_links_claim_is_judged_on_the_trends_slope_and_shows_the_step_by_step_verdict_beside():
    def summary(rms, slope):
        per_n = {str(n): {"rms_residual_over_lambda": est(*r)} for n, r in zip((3, 5, 7, 9), rms)}
        rule = {"per_n": per_n, "squared_residual_slope_per_link": est(*slope)}
        return {"per_rule": {"fixed": rule, "curvature": rule}}

    def old(s):
        return [r["superseded"][0]["verdict"] for r in judge("links", describe("links").claims, s)]

    falls = [(0.08, 0.07, 0.09), (0.06, 0.05, 0.07), (0.04, 0.03, 0.05), (0.02, 0.01, 0.03)]
    down, flat, up = (-4e-4, -6e-4, -2e-4), (-1e-4, -3e-4, 1e-4), (4e-4, 2e-4, 6e-4)
    assert verdicts("links", summary(falls, down)) == ["holds", "holds"] == old(summary(falls, down))
    assert verdicts("links", summary(falls, flat)) == ["undecided", "undecided"]
    assert verdicts("links", summary(falls, up)) == ["fails", "fails"]
    falls[2] = (0.05, 0.01, 0.09)
    falls[3] = (0.045, 0.01, 0.085)  # falls at every step, but the last interval overlaps the first
    assert old(summary(falls, down)) == ["undecided", "undecided"]
    falls[3] = (0.2, 0.15, 0.25)  # the last interval wholly above the one before it: a rise
    assert old(summary(falls, down)) == ["fails", "fails"]


def test_verdicts_are_one_of_four():
    with pytest.raises(Exception):
        Verdict("maybe", "x")
    assert Verdict.none("why").verdict == "no result"


def _row(study, claim, verdict, **extra):
    return {"study": study, "claim": claim, "paper": "", "measured": "", "value": None, "verdict": verdict,
            "reason": "", "criterion": "", **extra}


def test_claims_json_counts_each_reference_apart_and_old_rows_are_the_papers(tmp_path):
    import json

    from undulate.claims import FIELDS, VERDICTS, collect, write_claims_json

    assert VERDICTS == ("holds", "explained", "undecided", "fails", "no result")
    assert "reference" in FIELDS and "runs_needed" in FIELDS
    old = [_row("alpha", "a", "holds"), _row("alpha", "b", "fails")]  # written before `reference` existed
    new = [_row("sync", "relay: c", "undecided", reference="prx2021", reason="x straddles 0.5", runs_needed=40),
           _row("sync", "relay: d", "fails", reference="prx2021"),
           _row("beta", "e", "undecided", reference="paper", reason="y straddles 1", runs_needed=None)]
    (tmp_path / "alpha.json").write_text(json.dumps({"claims": old}))
    (tmp_path / "sync.json").write_text(json.dumps({"claims": new[:2], "explanations": [
        {"study": "sync", "claim": "relay: d", "cause": "why", "shown": None, "measured": "m", "value": None,
         "evidence_study": "sync", "evidence_figure": "sync.png"}]}))
    (tmp_path / "beta.json").write_text(json.dumps({"claims": new[2:]}))
    rows = collect(tmp_path, ["alpha", "sync", "beta"])
    assert [r["reference"] for r in rows] == ["paper", "paper", "prx2021", "prx2021", "paper"]
    assert [r["runs_needed"] for r in rows] == [None, None, 40, None, None]
    d = rows[3]  # an explanation left undecided (shown null) does not explain the claim
    assert d["verdict"] == "fails" and d["explanation"] is None and d["explanations_not_shown"][0]["shown"] is None
    doc = json.loads(write_claims_json(tmp_path, rows).read_text())
    assert doc["counts"] == {"holds": 1, "explained": 0, "undecided": 2, "fails": 2, "no result": 0}
    assert doc["counts_by_reference"] == {
        "paper": {"holds": 1, "explained": 0, "undecided": 1, "fails": 1, "no result": 0},
        "prx2021": {"holds": 0, "explained": 0, "undecided": 1, "fails": 1, "no result": 0}}
    # rows handed over without `reference` (an older caller) are counted as the paper's too
    bare = [{k: v for k, v in r.items() if k != "reference"} for r in rows]
    doc = json.loads(write_claims_json(tmp_path, bare).read_text())
    assert doc["counts_by_reference"]["paper"] == doc["counts"]


def test_a_claim_decided_at_an_earlier_look_says_so_in_claims_json_and_on_its_page(tmp_path):
    import json

    from undulate._report_claim_sections import claim_section
    from undulate.claims import collect, write_claims_json

    at = {"stage": 1, "of": 4, "confidence_level": 0.995, "measured_at_stage": 1,
          "later_verdicts": ["undecided", "undecided", "fails"]}
    agreed = {**at, "measured_at_stage": 4, "later_verdicts": ["holds"] * 3}  # every later look agreed
    rows = [_row("pot", "harmonic", "holds", decided_at=at), _row("pot", "agreed", "holds", decided_at=agreed),
            _row("pot", "open", "undecided", decided_at=None)]
    (tmp_path / "pot.json").write_text(json.dumps({"claims": rows}))
    got = collect(tmp_path, ["pot"])
    assert [r["decided_at"] for r in got] == [at, agreed, None]
    assert json.loads(write_claims_json(tmp_path, got).read_text())["claims"][0]["decided_at"] == at
    page = "".join(claim_section(got[0], "a", tmp_path))
    assert "holds at stage 1 of 4 (99.5 % intervals), measured as of stage 1" in page
    assert "undecided, undecided, fails" in page
    assert "<dt>decided</dt>" not in "".join(claim_section(got[1], "b", tmp_path))  # nothing to tell
    assert "<dt>decided</dt>" not in "".join(claim_section(got[2], "c", tmp_path))
