"""Claims live beside their studies: pure functions of the study's summary, judged on intervals.

(Every registered study's claims are also judged on real quick runs: test_registry_suite.py.)
"""

import math

import pytest

from undulate import stats
from undulate.studies import Verdict, describe
from undulate.studies._registry import judge


def est(value, low, high):
    return stats.Estimate(value, math.nan, low, high, 9, "test").to_dict()


def pairs_summary(slope=(1.0, 0.95, 1.05), rms=(0.03, 0.02, 0.04), std0=(0.3, 0.2, 0.4)):
    row = {"slope": est(*slope), "rms_residual_over_lambda": est(*rms), "rms_residual_m": est(*(0.54 * v for v in rms)),
           "n_runs": 9, "n_steady": 9, "n_failed": 0}
    return {"per_xi": {"1": row, "0.75": dict(row), "1.5": dict(row), "0": {"dx_std": est(*std0)}}}


def verdicts(name, summary):
    return [r["verdict"] for r in judge(name, describe(name).claims, summary)]


def test_pairs_claims_are_judged_on_the_intervals():
    assert verdicts("pairs", pairs_summary()) == ["holds"] * 4
    # the value is within tolerance but the interval is not: not demonstrated
    assert verdicts("pairs", pairs_summary(slope=(1.0, 0.7, 1.3)))[:3] == ["fails"] * 3
    assert verdicts("pairs", pairs_summary(rms=(0.08, 0.05, 0.12)))[0] == "fails"
    assert verdicts("pairs", pairs_summary(std0=(0.3, 0.01, 0.5)))[-1] == "fails"


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


def test_links_claim_needs_a_fall_beyond_the_intervals():
    def summary(rms):
        per_n = {str(n): {"rms_residual_over_lambda": est(*r)} for n, r in zip((3, 5, 7, 9), rms)}
        return {"per_rule": {"fixed": {"per_n": per_n}, "curvature": {"per_n": per_n}}}

    falls = [(0.08, 0.07, 0.09), (0.06, 0.05, 0.07), (0.04, 0.03, 0.05), (0.02, 0.01, 0.03)]
    assert verdicts("links", summary(falls)) == ["holds", "holds"]
    falls[2] = (0.05, 0.01, 0.09)
    falls[3] = (0.045, 0.01, 0.085)  # falls at every step, but the last interval overlaps the first
    assert verdicts("links", summary(falls)) == ["fails", "fails"]


def test_verdicts_are_one_of_three():
    with pytest.raises(Exception):
        Verdict("maybe", "x")
    assert Verdict.none("why").verdict == "no result"
