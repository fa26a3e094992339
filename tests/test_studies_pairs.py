"""The pair, link-number and group studies (paper Figs. 3, 5, 6): real quick runs, no mocks (links: a
reduced plan by default, its whole quick plan under the ``slow`` marker)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import xarray as xr

from undulate.studies import names, run_study
from undulate.studies import _analysis as C
from undulate.studies._analysis import group_records

pytestmark = pytest.mark.usefixtures("whole_plans", "warm_pool")  # the physics of the whole quick plan, in one look


def _run(tmp_path_factory, name):
    out = tmp_path_factory.mktemp(name)
    path = run_study(name, out, quick=True)
    return out, path


@pytest.fixture(scope="module")
def pairs_run(tmp_path_factory):
    return _run(tmp_path_factory, "pairs")


@pytest.fixture(scope="module")
def links_run(tmp_path_factory):
    return _run(tmp_path_factory, "links")


@pytest.fixture(scope="module")
def groups_run(tmp_path_factory):
    return _run(tmp_path_factory, "groups")


def _check_files(out, name):
    for ext in ("nc", "png", "pdf", "json"):
        assert (out / f"{name}.{ext}").stat().st_size > 0
    ds = xr.load_dataset(out / f"{name}.nc", engine="h5netcdf")
    for k, v in {**ds.coords, **ds.data_vars}.items():
        if v.dtype.kind in "iuf":
            assert "units" in v.attrs, k
    assert ds.attrs["study"] == name and "undulate_version" in ds.attrs
    doc = json.loads((out / f"{name}.json").read_text())
    assert doc["study"] == name
    return ds, doc["summary"]


def test_registered():
    assert {"pairs", "links", "groups"} <= set(names())


def test_pairs_quick(pairs_run):
    out, path = pairs_run
    assert path == out / "pairs.nc"
    ds, summary = _check_files(out, "pairs")
    assert ds.sizes["dphi"] == 33 and list(ds["xi"].values) == [0.0, 0.75, 1.0, 1.5]  # the quick cap
    assert np.isin(np.round(C.paper_phases(), 12), np.round(ds["dphi"].values, 12)).all()
    assert ds["dx_steady"].attrs["units"] == "m" and ds["dx"].dims == ("xi", "dphi", "time")
    assert summary["n_runs"] == 132 and summary["n_failed"] == 0
    doc = json.loads((out / "pairs.json").read_text())
    assert doc["n_failed"] == 0 and {c["verdict"] for c in doc["claims"]} <= {"holds", "fails", "undecided"}
    assert 0 <= summary["n_steady"] <= 132 and "steady_rule" in summary and "slope_method" in summary
    per = summary["per_xi"]
    assert set(per) == {"0", "0.75", "1", "1.5"}
    for key in ("0.75", "1", "1.5"):
        for field in ("slope", "intercept", "rms_residual_over_lambda", "rms_residual_m", "n_steady"):
            assert per[key][field] is not None, (key, field)
    assert per["0"]["slope"] is None and per["0"]["dx_std_m"] >= 0
    # Under the project's conventions the compatibility slope is +1: the xi = 1 pair follows it,
    # and its 95 % interval says so too
    slope = per["1"]["slope"]
    assert 0.75 < slope["value"] < 1.25 and slope["stderr"] > 0 and 0.75 < slope["ci95"][0] < slope["ci95"][1] < 1.25
    assert per["1"]["rms_residual_over_lambda"]["ci95"][1] < 0.1
    # the standing wave has no wavelength: dx/lambda is undefined there
    assert np.isnan(ds["dx_steady_over_lambda"].sel(xi=0.0)).all()


@pytest.mark.slow  # ~15 s; a killed sweep's resume stays in the default run (test_sweep)
def test_pairs_resume(pairs_run):
    """A second call reuses every stored run and gives the same numbers."""
    out, _ = pairs_run
    before = json.loads((out / "pairs.json").read_text())["summary"]
    store = out / ".sweeps" / "pairs" / "sim-quick-seed0"
    n_files = len(list((store / "runs").glob("*.nc")))
    assert n_files == 132
    run_study("pairs", out, quick=True)
    after = json.loads((out / "pairs.json").read_text())["summary"]
    assert after["per_xi"]["1"] == before["per_xi"]["1"]
    assert len(list((store / "runs").glob("*.nc"))) == n_files
    assert json.loads((out / "pairs.json").read_text())["n_computed"] == 0


@pytest.mark.slow
def test_links_quick(links_run):
    """The whole quick plan (72 runs, about 2 minutes on 2 cores); test_links_reduced runs by default."""
    out, _ = links_run
    ds, summary = _check_files(out, "links")
    _check_links(ds, summary)


def test_links_reduced(tmp_path):
    """A reduced real links run: every rule and N at three phase differences (24 runs, of 72 quick), three
    design points (+dphi and -dphi would be one: the RMS residual resamples them together)."""
    from undulate import studies
    from undulate.studies import links
    from undulate.studies._staging import _check_units

    ctx = studies.StudyContext(studies.StudyConfig(out_dir=tmp_path, quick=True, seed=0), "links", progress=False)
    ds = links.dataset(ctx, links.Plan((0.0, math.pi / 4, math.pi / 2)))
    _check_units("links", ds)
    _check_links(ds, links.summary(ds))
    assert ds.sizes["dphi"] == 3
    links.figure(ds).savefig(tmp_path / "links.png")


def _check_links(ds, summary):
    assert list(ds["n_links"].values) == [3, 5, 7, 9]
    for rule in ("fixed", "curvature"):
        per_n = summary["per_rule"][rule]["per_n"]
        assert set(per_n) == {"3", "5", "7", "9"}
        rms = []
        for n, row in per_n.items():
            assert row["n_failed"] == 0
            est = row["rms_residual_over_lambda"]
            res = ds["residual_over_lambda"].sel(rule=rule, n_links=int(n)).values
            assert est["value"] == pytest.approx(float(np.sqrt(np.nanmean(res ** 2))), rel=1e-12)
            assert est["ci95"][0] <= est["value"] <= est["ci95"][1]
            rms.append(est)
        # the claim's criterion, restated on the intervals: a step wholly above the previous one fails;
        # else the last wholly below the first holds, wholly above fails, overlapping is undecided
        rms = [rms[i] for i in np.argsort([int(n) for n in per_n])]
        assert all(None not in r["ci95"] for r in rms)  # with intervals, the criterion has a verdict
        rise = any(b["ci95"][0] > a["ci95"][1] for a, b in zip(rms, rms[1:]))
        first, last = rms[0]["ci95"], rms[-1]["ci95"]
        expected = False if rise or last[0] > first[1] else (True if last[1] < first[0] else None)
        assert summary["per_rule"][rule]["rms_falls_with_n"] is expected
    # both rules share the 3-link gait, so they agree there exactly
    a = ds["dx_steady"].sel(n_links=3)
    np.testing.assert_allclose(a.sel(rule="fixed"), a.sel(rule="curvature"))


def test_groups_quick(groups_run):
    out, _ = groups_run
    ds, summary = _check_files(out, "groups")
    per = summary["per_group_size"]
    assert per["3"]["n_runs"] == 9 and per["3"]["n_neighbour_pairs"] == 18
    assert per["4"]["n_runs"] == 8 and per["4"]["n_neighbour_pairs"] == 24
    assert per["2"]["n_runs"] == 9 and per["2"]["n_neighbour_pairs"] == 9  # the reference pairs
    for row in per.values():
        assert row["n_failed"] == 0 and row["rms_residual_over_lambda"] is not None
    # neighbours are adjacent in the final lateral order and dphi is wrapped
    assert (np.abs(ds["dphi"]) <= math.pi + 1e-12).all()
    # random 4-swimmer phases differ between draws
    fours = ds["phase"].values[ds["run_group_size"].values == 4]
    assert len({tuple(np.round(p, 9)) for p in fours}) == len(fours)


def _swap_dataset():
    """Three swimmers; 0 and 1 swap lateral places at t = 10 s, and stay swapped."""
    t = np.arange(0.0, 30.0 + 1e-9, 0.1)
    y0 = np.where(t < 10.0, -0.05, 0.0)
    y1 = np.where(t < 10.0, 0.0, -0.05)
    y2 = np.full_like(t, 0.05)
    x = np.stack([np.full_like(t, 0.10), np.full_like(t, -0.02), np.full_like(t, 0.30)], axis=1)
    y = np.stack([y0, y1, y2], axis=1)
    ds = xr.Dataset(
        {"x": (("time", "swimmer"), x, {"units": "m"}), "y": (("time", "swimmer"), y, {"units": "m"})},
        coords={"time": t, "swimmer": [0, 1, 2], "phase": ("swimmer", [0.0, 1.0, 3.0])},
        attrs={"wavelength": 0.54, "period": 2.0},
    )
    return ds


def test_group_records_follow_the_final_lateral_order_after_a_swap():
    # the lateral order itself (sample by sample and at the end): tests/test_observables.py
    ds = _swap_dataset()
    recs = group_records(ds, amplitude_m=0.05)
    assert [(r["lower"], r["upper"]) for r in recs] == [(1, 0), (0, 2)]
    assert all(r["order_changed"] for r in recs)
    np.testing.assert_allclose([r["dx_steady"] for r in recs], [0.12, 0.20])
    np.testing.assert_allclose([r["dphi"] for r in recs], [-1.0, 3.0])
    assert all(r["steady"] for r in recs)


def test_slope_fit_unwraps_the_pi_ends():
    dphi = C.paper_phases()
    y = dphi / (2 * np.pi)
    y[0] = 0.5  # dphi = -pi landed on the other branch: the same physical state
    fit = C.compatibility_fit(y, dphi)
    assert fit.slope.value == pytest.approx(1.0) and fit.intercept.value == pytest.approx(0.0, abs=1e-12)
    raw = np.polyfit(dphi / (2 * np.pi), y, 1)[0]
    assert raw < 0.9  # what a naive fit would give
