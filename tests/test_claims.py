"""Claim judgements are pure functions of summaries: checked on hand-made summaries."""

from undulate.claims import evaluate


def pairs_summary(slope1=1.0, rms1=0.03, std0=0.3):
    per = {
        "1": {"slope": slope1, "rms_residual_over_lambda": rms1, "rms_residual_m": rms1 * 0.54, "n_runs": 9, "n_steady": 9},
        "0.75": {"slope": 0.95, "rms_residual_over_lambda": 0.06, "n_runs": 9, "n_steady": 9},
        "1.5": {"slope": 0.04, "rms_residual_over_lambda": 0.3, "n_runs": 9, "n_steady": 9},
        "0": {"dx_std_m": std0},
    }
    return {"per_xi": per}


def test_pairs_claims_follow_their_stated_criteria():
    rows = evaluate("pairs", {"pairs": pairs_summary()})
    assert [r["holds"] for r in rows] == [True, True, False, True]
    rows = evaluate("pairs", {"pairs": pairs_summary(slope1=0.5, std0=0.01)})
    assert rows[0]["holds"] is False and rows[-1]["holds"] is False


def test_links_claim_needs_a_monotone_fall_and_missing_data_is_not_a_verdict():
    per_n = {str(n): {"rms_residual_over_lambda": r} for n, r in zip((3, 5, 7, 9), (0.04, 0.03, 0.02, 0.01))}
    rows = evaluate("links", {"links": {"per_rule": {"fixed": {"per_n": per_n}}}})
    assert rows[0]["holds"] is True and rows[1]["holds"] is None
    per_n["7"]["rms_residual_over_lambda"] = 0.05
    assert evaluate("links", {"links": {"per_rule": {"fixed": {"per_n": per_n}}}})[0]["holds"] is False


def test_groups_claim_compares_with_pairs():
    g = {"per_group_size": {s: {"slope": 0.97, "rms_residual_over_lambda": 0.1} for s in ("3", "4")}}
    assert [r["holds"] for r in evaluate("groups", {"groups": g, "pairs": pairs_summary(rms1=0.03)})] == [True, True]
    assert [r["holds"] for r in evaluate("groups", {"groups": g, "pairs": pairs_summary(rms1=0.2)})] == [False, False]
    assert evaluate("unknown-study", {}) == []


def test_every_claim_gives_no_verdict_without_data():
    from undulate.claims import CLAIMS

    for name in CLAIMS:
        rows = evaluate(name, {})
        assert rows and all(r["holds"] is None and r["measured"] == "no result" for r in rows), name


def test_confinement_and_potential_claims():
    c = {"d_over_2A": [0.6, 1.2], "central_width_over_lambda": [0.0, 0.05], "max_width_in_paper_range": 0.05,
         "width_never_shrinks_with_d": True}
    assert evaluate("confinement", {"confinement": c})[0]["holds"] is True
    c["max_width_in_paper_range"] = 0.0
    assert evaluate("confinement", {"confinement": c})[0]["holds"] is False
    p = {"impulse_fit": {"r2": 0.95, "slope_Ns_per_rad": 4.0}, "median_fit_r2": 0.97,
         "per_beta": {"45": {"spearman_k_vs_d": -1.0}, "60": {"spearman_k_vs_d": 0.5}},
         "collapse_rms_log10k_vs_d_over_2A": 0.1, "collapse_rms_log10k_vs_d_m": 0.5}
    assert [r["holds"] for r in evaluate("potential", {"potential": p})] == [True, True, False, True]
