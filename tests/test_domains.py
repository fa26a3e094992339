"""No reported interval leaves its quantity's physical domain, and the packing threshold's interval comes
from its bisection brackets and its draws (:func:`undulate.studies.packing.threshold_estimate`)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from undulate import stats
from undulate.claims import collect
from undulate.errors import UndulateError
from undulate.studies import packing

GRID = np.round(np.r_[0.5, np.arange(1.0, 4.01, 0.25), np.arange(4.5, 6.51, 0.5)], 10)
"""The full plan's threshold grid (packing.plan(False).rho_tilde)."""
RHO_MAX = 1 / 0.1434
"""2A/w at the defaults (A = 52.3 mm, w = 15 mm)."""
FULL_LOOK_DRAWS = [3.38, 3.46]
"""Two draws 0.08 apart in one bracket, as at phi_max = 2.09 at the full mode's first look (99.5 %)."""


def est(value, low, high):
    return {"value": value, "stderr": None, "ci95": [low, high], "n": 5, "method": "test", "level": 0.95,
            "units": 5, "dof": 4}


def brackets(tau):
    j = np.searchsorted(GRID, tau)
    return GRID[j - 1], GRID[j]


# ------------------------------------------------------------------ the domain check
def test_the_old_packing_interval_leaves_the_density_domain_and_the_new_one_does_not():
    with stats.at_level(0.995):
        old = stats.mean(FULL_LOOK_DRAWS)  # the t interval the summary reported: [-1.6, 8.4]
        lo, hi = zip(*(brackets(t) for t in FULL_LOOK_DRAWS))
        new = packing.threshold_estimate(FULL_LOOK_DRAWS, lo, hi, RHO_MAX)
    assert old.low < 0
    bad = stats.domain_violations({"threshold_rho_tilde": [est(6.0, 6.0, 6.0), old.to_dict()]})
    assert len(bad) == 1 and bad[0].startswith("threshold_rho_tilde[1]: a density")
    assert stats.domain_violations({"threshold_rho_tilde": [est(6.0, 6.0, 6.0), new.to_dict()]}) == []
    assert 0 < new.low <= new.value <= new.high < RHO_MAX
    with pytest.raises(UndulateError, match="outside their physical domain"):
        stats.check_domains({"summary": {"threshold_rho_tilde": [old.to_dict()]}}, "study 'packing'")


@pytest.mark.parametrize("key, good, bad", [
    ("r2", est(0.9, 0.8, 1.0), est(0.9, 0.8, 1.02)),
    ("spearman_k_vs_d", est(-0.9, -1.0, -0.6), est(-0.9, -1.1, -0.6)),
    ("rms_residual_over_lambda", est(0.03, 0.0, 0.05), est(0.03, -0.01, 0.05)),
    ("dx_std", est(0.3, 0.2, 0.4), est(0.3, -0.2, 0.4)),
    ("threshold_rho_tilde", est(3.4, 0.7, 6.6), est(3.4, -2.0, 8.9)),
    ("central_width_over_lambda", 0.0, -0.01),
    ("fraction_short_of_line", 1.0, 1.2),
    ("n_runs", 0, -1),
])
def test_each_quantity_is_checked_against_its_domain(key, good, bad):
    assert stats.domain_violations({key: good}) == []
    assert len(stats.domain_violations({key: bad})) == 1
    # nested, in lists, and under number-labelled dicts ({"3": ..., "5": ...}) alike
    assert len(stats.domain_violations({"per_rule": {"fixed": {"per_n": {"3": {key: bad}}}}})) == 1
    assert len(stats.domain_violations({key: [good, bad, None]})) == 1
    assert len(stats.domain_violations({key: {"3": good, "5": bad}})) == 1


def test_quantities_without_a_domain_and_missing_numbers_are_left_alone():
    s = {"slope": est(-1.0, -2.0, -0.5), "threshold_dx0_over_lambda": est(-0.3, -0.4, -0.2),
         "intercept": est(-5, -6, -4), "rms_residual_over_lambda": est(None, None, None),
         "r2": {"value": 0.5, "ci95": [None, None]}, "spearman_x": est(-1.0, None, None), "rms_falls_with_n": True,
         "fraction_short_of_line": math.nan, "rules": {"fixed": "beta = 45 deg"}}
    assert stats.domain_violations(s) == []
    assert stats.domain_of("spearman_threshold_vs_phi_max")[:2] == (-1.0, 1.0)  # a correlation, not a density
    assert stats.domain_of("slope") is None


def test_collect_refuses_a_study_that_reports_an_interval_outside_its_domain(tmp_path):
    claim = {"study": "packing", "claim": "c", "verdict": "holds", "value": {"spearman": est(-0.9, -1.0, -0.7)}}
    doc = {"claims": [claim], "summary": {"threshold_rho_tilde": [est(3.42, -2.02, 8.86)]}}
    (tmp_path / "packing.json").write_text(json.dumps(doc))
    with pytest.raises(UndulateError, match=r"packing.*threshold_rho_tilde\[0\]: a density 3.42 \[-2.02, 8.86\]"):
        collect(tmp_path, ["packing"])
    doc["summary"]["threshold_rho_tilde"] = [est(3.42, 0.74, 6.6)]
    (tmp_path / "packing.json").write_text(json.dumps(doc))
    assert [r["verdict"] for r in collect(tmp_path, ["packing"])] == ["holds"]
    claim["value"] = {"spearman": est(-0.9, -1.2, -0.7)}  # a claim's value is checked too
    (tmp_path / "packing.json").write_text(json.dumps(doc))
    with pytest.raises(UndulateError, match="a correlation"):
        collect(tmp_path, ["packing"])


# ------------------------------------------------------------------ the packing threshold's interval
def test_the_threshold_interval_stays_in_the_domain_and_covers_the_constructed_truth():
    """Seeded draws of per-draw thresholds (normal about a true mean), bracketed on the full grid and
    interpolated exactly: the 95 % interval covers the true mean at least at its level, and always lies
    inside (0, 2A/w) with the value inside it."""
    rng = np.random.default_rng(7)
    for mu, sd, n in ((3.4, 0.05, 5), (3.0, 0.3, 5), (2.4, 0.2, 3), (5.0, 0.4, 5), (1.3, 0.2, 5)):
        cover, trials = 0, 400
        for _ in range(trials):
            tau = np.clip(rng.normal(mu, sd, n), GRID[0] + 1e-6, GRID[-1] - 1e-6)
            lo, hi = zip(*(brackets(t) for t in tau))
            e = packing.threshold_estimate(tau, lo, hi, RHO_MAX)
            assert 0 < e.low <= e.value <= e.high < RHO_MAX
            cover += e.low <= mu <= e.high
        assert cover / trials >= 0.93, (mu, sd, n, cover / trials)


def test_draws_that_agree_leave_their_bracket_and_one_draw_no_interval():
    # phi_max = 0: every draw is the same in-phase group
    e = packing.threshold_estimate([5.9, 5.9, 5.9], [5.5] * 3, [6.0] * 3, RHO_MAX)
    assert (e.low, e.high) == pytest.approx((5.5, 6.0)) and e.value == pytest.approx(5.9)
    assert e.units == 3 and e.dof == 2
    one = packing.threshold_estimate([3.4, math.nan], [3.25, math.nan], [3.5, math.nan], RHO_MAX)
    assert one.value == pytest.approx(3.4) and not one.has_interval and one.n == 1
    assert not packing.threshold_estimate([math.nan], [math.nan], [math.nan], RHO_MAX).finite
    # a bracket end outside (0, 2A/w) cannot be placed on its scale: no interval
    assert not packing.threshold_estimate([6.9, 6.95], [6.5, 6.5], [7.5, 7.5], RHO_MAX).has_interval
