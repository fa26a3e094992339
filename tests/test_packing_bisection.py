"""The packing study's bisection finds the whole grid's thresholds from fewer runs:
on synthetic columns (every case) and on real runs."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.usefixtures("warm_pool")  # the sweeps of this module share one pool of worker processes


def _search(column_above, failed_at=(), known=()):
    """Run bisection_probes to the end on a synthetic column; the indices it ran."""
    from undulate.studies.packing import bisection_probes

    m = len(column_above)
    ran = {j: (None if j in failed_at else bool(column_above[j])) for j in known}
    while True:
        nxt = bisection_probes(ran, m)
        if not nxt:
            return ran
        assert not (set(nxt) & set(ran))
        for j in nxt:
            ran[j] = None if j in failed_at else bool(column_above[j])


def test_bisection_finds_the_whole_columns_threshold():
    from undulate.studies.packing import density_threshold

    rng = np.random.default_rng(0)
    rho = np.round(np.r_[0.5, np.arange(1.0, 4.01, 0.25), np.arange(4.5, 6.51, 0.5)], 10)
    m = rho.size
    for trial in range(300):
        first = int(rng.integers(0, m + 1))  # m: never above
        excess = np.sort(rng.normal(size=m)) - 10.0
        excess[first:] = np.abs(excess[first:]) + 1e-3  # monotone sign: below, then above
        known = tuple(rng.choice(m, size=int(rng.integers(0, 6)), replace=False))
        failed_at = (int(rng.integers(0, m)),) if trial % 5 == 0 else ()
        ran = _search(excess > 0, failed_at, known)
        e = np.full(m, np.nan)
        bad = np.zeros(m, bool)
        for j, v in ran.items():
            e[j] = np.nan if v is None else excess[j]
            bad[j] = v is None
        whole_bad = np.zeros(m, bool)
        whole_bad[list(failed_at)] = True
        whole = density_threshold(rho, np.where(whole_bad, np.nan, excess), whole_bad)
        assert density_threshold(rho, e, bad) == pytest.approx(whole, nan_ok=True)
        if not failed_at:
            assert len(ran) <= len(known) + int(np.ceil(np.log2(m + 1))) + 1
    # a column that is not monotone is searched whole
    col = np.array([False, True, False, True, True])
    assert set(_search(col, known=(0, 1, 2))) == set(range(5))


@pytest.mark.slow  # ~27 s; the continued brackets' equality stays in the default run
def test_packing_threshold_by_bisection_equals_the_whole_grid(tmp_path):
    """Real runs (10 swimmers, 2 s): the thresholds found by bisection with a coarse heatmap are
    the whole grid's, from fewer runs."""
    from undulate import studies
    from undulate.studies import packing

    kw = dict(draws=2, n_swimmers=10, duration_s=2.5)
    phi, rho = [0.0, 2 * np.pi], [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]

    def run(out, plan):
        ctx = studies.StudyContext(studies.StudyConfig(out_dir=out, quick=True), "packing", progress=False)
        return packing.dataset(ctx, plan)

    whole = run(tmp_path / "whole", packing.PackingPlan(phi, rho, **kw))
    bis = run(tmp_path / "bisect", packing.PackingPlan(phi, rho, heatmap_rho=[1.0, 6.0], heatmap_draws=1, **kw))
    assert bool(whole["evaluated"].all()) and whole.attrs["bisection_rounds"] == 0
    assert int(bis["evaluated"].sum()) < int(whole["evaluated"].sum()) and bis.attrs["bisection_rounds"] >= 1
    for v in ("threshold_rho_tilde", "threshold_lo", "threshold_hi"):
        np.testing.assert_array_equal(bis[v].values, whole[v].values)
    assert np.isfinite(whole["threshold_rho_tilde"].values).any()
    # every run the bisection did is the whole grid's run, bit for bit
    ev = bis["evaluated"].values
    np.testing.assert_array_equal(bis["mean_joint_error"].values[ev], whole["mean_joint_error"].values[ev])
    # the study's numbers do not depend on how the thresholds were found
    sb, sw = packing.summary(bis), packing.summary(whole)
    assert sb["threshold_rho_tilde"] == sw["threshold_rho_tilde"]
    np.testing.assert_array_equal(sb["threshold_rho_tilde_mean"], sw["threshold_rho_tilde_mean"])
    assert sb["spearman_threshold_vs_phi_max"] == sw["spearman_threshold_vs_phi_max"]
    assert sb["threshold_above_grid"] == sw["threshold_above_grid"]
    packing.figure(bis).savefig(tmp_path / "packing.png")
    assert (tmp_path / "packing.png").stat().st_size > 0


def test_brackets_continued_from_their_stop_give_the_unstopped_thresholds(tmp_path, monkeypatch):
    """Real runs (8 swimmers, 6 s): probes far from the threshold stop at 5.2 s; the two that bracket
    each threshold are then continued from their stop to 6 s, and the thresholds and the bracket runs'
    means are bit for bit those of the same study with no stopping rule."""
    from undulate import studies
    from undulate.studies import packing

    plan = packing.PackingPlan([np.pi], [1.0, 6.0], draws=2, n_swimmers=8, duration_s=6.0)

    def run(out):
        ctx = studies.StudyContext(studies.StudyConfig(out_dir=out, quick=True), "packing", progress=False)
        return packing.dataset(ctx, plan)

    stopped = run(tmp_path / "stopped")
    monkeypatch.setattr(packing, "PACKING_STOP", None)
    whole = run(tmp_path / "whole")
    assert stopped.attrs["bracket_runs_continued"] == 4 and stopped.attrs["bracket_reruns"] == 1
    assert stopped.attrs["runs_stopped_early"] == whole.attrs["runs_stopped_early"] == 0
    assert whole.attrs["bracket_runs_continued"] == 0
    assert np.isfinite(whole["threshold_rho_tilde"].values).all()
    for v in ("threshold_rho_tilde", "mean_joint_error", "max_penetration"):
        np.testing.assert_array_equal(stopped[v].values, whole[v].values, err_msg=v)
