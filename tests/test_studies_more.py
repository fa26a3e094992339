"""Studies packing, basins, confinement, potential and swimming (paper Figs. 7-10, Methods).

The analysis functions are checked against synthetic data with known
answers; every study runs for real (no mocks) and the physics each one is
there to show is asserted on its result: by default on a reduced plan run
through the study's ``dataset``; under the ``slow`` marker on the whole quick
plan through the registry, with its four files (in the default run
tests/test_studies_pairs.py runs pairs and groups that way).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import xarray as xr

from undulate import studies
from undulate.studies import _runners, basins, confinement, packing, potential, swimming
from undulate.studies._staging import _check_units  # what the registry checks before it writes a file

pytestmark = pytest.mark.usefixtures("whole_plans", "warm_pool")  # the physics of the whole quick plan, in one look

MINE = ("packing", "basins", "confinement", "potential", "swimming")


# ----------------------------------------------------------------- pure helpers
def test_fit_stiffness_recovers_slope_and_offset():
    rng = np.random.default_rng(1)
    k_true, x0_true = 4.2, 0.031  # N/m, m
    dF = np.linspace(0.02, 0.3, 12)
    dx = x0_true + dF / k_true + rng.normal(0, 2e-4, dF.size)
    broken = np.zeros(dF.size, bool)
    broken[-2:] = True  # the pair broke apart: huge separations, to be ignored
    dx[-2:] = [3.0, 7.0]
    dx[3] = np.nan  # a failed run
    k, x0, r2 = potential.fit_stiffness(dF, dx, ~broken)
    assert k == pytest.approx(k_true, rel=0.02)
    assert x0 == pytest.approx(x0_true, abs=5e-4)
    assert 0.99 < r2 <= 1.0
    # exact data: exact answer; too few points: NaN
    k, x0, r2 = potential.fit_stiffness([1.0, 2.0, 3.0], [0.5, 0.75, 1.0])
    assert (k, x0, r2) == pytest.approx((4.0, 0.25, 1.0))
    assert all(math.isnan(v) for v in potential.fit_stiffness([1.0, 2.0], [0.1, 0.2]))
    assert all(math.isnan(v) for v in potential.fit_stiffness([1, 2, 3], [0.1, 0.1, 0.1]))


def test_fit_abs_linear_is_symmetric_in_dphi():
    dphi = np.linspace(-np.pi, np.pi, 9)
    a, b, r2 = potential.fit_abs_linear(dphi, 0.3 * np.abs(dphi) + 0.05)
    assert (a, b, r2) == pytest.approx((0.3, 0.05, 1.0))


def test_compatibility_model_offset():
    A, lam, w = 0.05, 0.54, 0.015
    # d = 2A leaves no room; d = 4A (dy = 2A) frees every offset up to half a wavelength
    assert potential.model_dx0_m(2 * A, A, lam) == pytest.approx(0.0)
    assert potential.model_dx0_m(4 * A, A, lam) == pytest.approx(lam / 2)
    d = 1.3 * 2 * A
    assert potential.model_dx0_m(d, A, lam) == pytest.approx(lam / np.pi * np.arcsin(0.3))
    assert potential.model_dx0_m(d, A, lam, w) == pytest.approx(lam / np.pi * np.arcsin(0.3 - w / A))
    assert potential.lateral_clearance_m(0.1, A, w) == 0.0


def test_density_threshold_rule():
    rho = [1.0, 2.0, 3.0, 4.0]
    # crossing between 2 and 3 at a quarter of the way
    assert packing.density_threshold(rho, [-0.01, -0.003, 0.009, 0.05]) == pytest.approx((2.25, 2.0, 3.0))
    # failed runs are left out, never counted as above; one inside the bracket leaves the threshold undefined
    t = packing.density_threshold(rho, [-0.01, -0.01, np.nan, np.nan], [False, False, True, True])
    assert np.isnan(t[0]) and t[1] == 2.0 and np.isnan(t[2])
    t = packing.density_threshold(rho, [-0.01, np.nan, 0.01, 0.05], [False, True, False, False])
    assert np.isnan(t[0]) and (t[1], t[2]) == (1.0, 3.0)
    t = packing.density_threshold(rho, [-0.01, -0.01, 0.01, np.nan], [False, False, False, True])
    assert t == pytest.approx((2.5, 2.0, 3.0))
    lo_all = packing.density_threshold(rho, [0.1, 0.1, 0.1, 0.1])
    assert math.isnan(lo_all[0]) and lo_all[2] == 1.0
    none = packing.density_threshold(rho, [-0.1] * 4)
    assert math.isnan(none[0]) and none[1] == 4.0


def test_walled_density_is_below_the_open_closed_form():
    from undulate import theory

    phi = np.linspace(0, 2 * np.pi, 7)
    w2a = 0.143
    walls = packing.walled_packing_density(phi, w2a, 50)
    assert np.all(walls < theory.packing_density(phi, w2a))
    assert walls[0] == pytest.approx(1 / (w2a + 1 / 50))


def test_basin_threshold_bracket():
    x0 = [0.1, 0.2, 0.3, 0.4, 0.05]
    ret = [True, True, False, False, True]
    assert basins.bracket_threshold(x0, ret) == (0.2, 0.3)
    inner, outer = basins.bracket_threshold([-0.1, -0.2], [True, True])
    assert inner == -0.2 and math.isnan(outer)
    assert math.isnan(basins.bracket_threshold([0.1, 0.2], [False, True])[0])
    assert list(basins.returns_to_zero([0.01, -0.04, 0.06, -0.9])) == [True, True, False, False]


def test_central_state_width():
    s = confinement.central_state([-1, -0.5, 0, 0.5, 1], [-0.95, -0.02, 0.0, 0.03, 0.95])
    assert s["width"] == pytest.approx(0.05) and s["n"] == 3
    assert (s["basin_lo"], s["basin_hi"]) == (-0.5, 0.5)
    assert math.isnan(confinement.central_state([0.5], [0.9])["width"])


def test_pair_scene_maps_the_point():
    s = _runners.pair_scene({"dx0_over_lambda": 0.25, "dphi_rad": 1.0, "d_over_2A": 1.1, "force_N": 0.2},
                          amplitude_m=0.05, force_onset_s=6.0)
    assert s.phases_rad == (0.0, 1.0)
    assert s.channel.width_m == pytest.approx(0.22)  # the pair's channel W = 2 d, d = 1.1 * 2A
    assert s.dx0_m == pytest.approx((0.25 * 0.54,))
    assert s.forces_N == (-0.2, 0.2) and s.force_onset_s == 6.0
    with pytest.raises(ValueError):
        _runners.pair_scene({"bogus": 1})


# ------------------------------------------------------------- the studies, real
def test_my_studies_are_registered():
    names = studies.names()
    for n in MINE:
        assert n in names and studies.describe(n).needs_simulation


@pytest.fixture(scope="module")
def quick_runs(tmp_path_factory):
    """Run a study once in quick mode (through the registry) and keep its files."""
    out = tmp_path_factory.mktemp("quick")
    done = {}

    def get(name):
        if name not in done:
            nc = studies.run_study(name, out, quick=True, seed=0)
            assert nc == out / f"{name}.nc"
            for ext in ("png", "pdf", "json"):
                assert (out / f"{name}.{ext}").stat().st_size > 0
            assert (out / f"{name}.pdf").read_bytes()[:4] == b"%PDF"
            ds = xr.load_dataset(nc, engine="h5netcdf")
            assert ds.attrs["study"] == name
            doc = json.loads((out / f"{name}.json").read_text())
            assert doc["study"] == name
            done[name] = (ds, doc["summary"], out)
        return done[name]

    return get


@pytest.mark.slow
def test_swimming_quick(quick_runs):
    """The whole quick plan (nine phases); test_swimming_reduced runs by default."""
    ds, summary, out = quick_runs("swimming")
    _check_swimming(ds, summary)
    # resuming: a second call reuses every run
    studies.run_study("swimming", out, quick=True, seed=0)
    assert "runs" in {p.name for p in (out / ".sweeps" / "swimming").rglob("runs")}


def test_swimming_reduced(tmp_path):
    """A reduced real swimming run: five of the nine quick phases in both modes (10 runs and the lone
    swimmers, of 18 and the lone swimmers quick)."""
    ds = swimming.dataset(_context(tmp_path, "swimming"), swimming.SwimmingPlan(np.linspace(-np.pi, np.pi, 5)))
    _check_units("swimming", ds)
    assert ds.sizes["dphi"] == 5
    _check_swimming(ds, swimming.summary(ds))
    swimming.figure(ds).savefig(tmp_path / "swimming.png")


def _check_swimming(ds, summary):
    # the lone swimmer advances head first (toward -x) in the resistive medium, at the inertialess RFT
    # speed of its gait (tests/test_resistive.py: 0.0146 m per period = 0.027 L); on the viscous ground
    # it only creeps (the integrator's O(dt) drift)
    assert 0.004 < summary["lone_swimmer_speed_m_s"] < 0.02
    assert summary["lone_swimmer_speed_body_lengths_per_period"] == pytest.approx(0.027, rel=0.05)
    lo, hi = summary["lone_swimmer_speed_body_lengths_per_period_range"]
    assert lo <= summary["lone_swimmer_speed_body_lengths_per_period"] * (1 + 1e-6) and hi - lo < 0.002
    assert abs(summary["lone_viscous_speed_m_s"]) < 1e-3
    vis = summary["modes"]["viscous"]
    assert 0.8 < vis["slope"]["value"] < 1.2 and vis["rms_residual_over_lambda"]["value"] < 0.08
    sw = ds["dx_final_over_lambda"].sel(mode="resistive")
    # small detuning: swimming pairs settle where non-swimming ones do
    small = np.abs(ds["dphi"]) <= np.pi / 4 + 1e-9
    assert int(small.sum()) >= 1
    np.testing.assert_allclose(sw.where(small, drop=True),
                               ds["dx_final_over_lambda"].sel(mode="viscous").where(small, drop=True), atol=0.05)


@pytest.mark.slow
def test_confinement_quick(quick_runs):
    """The whole quick plan (55 runs); test_confinement_reduced runs by default."""
    ds, summary, _ = quick_runs("confinement")
    _check_confinement(ds, summary)


def test_confinement_reduced(tmp_path):
    """A reduced real confinement run: the tightest and the widest quick channel, five starts near
    dx0 = 0 (10 runs, of 55 quick): the central state is a point at d/2A = 0.6 and broadens at 1.5."""
    ds = confinement.dataset(_context(tmp_path, "confinement"),
                             confinement.ConfinementPlan([0.6, 1.5], np.linspace(-0.4, 0.4, 5)))
    _check_units("confinement", ds)
    summary = confinement.summary(ds)
    _check_confinement(ds, summary)
    w = ds["central_width"].values
    assert w[-1] > w[0] + 0.05  # strictly broader: starts at +-0.2 lambda no longer all end at 0
    confinement.figure(ds).savefig(tmp_path / "confinement.png")


def _check_confinement(ds, summary):
    w = ds["central_width"].values
    assert np.all(np.isfinite(w))
    # the central state is at least as wide in the widest channel as in the tightest (at d/2A = 0.6 the bodies
    # leave no clearance W - 2A - 2w); whether it broadens over the paper's range is the claim's to judge
    assert w[-1] >= w[0]
    assert set(summary["broadening_slope_per_d_over_2A"]) >= {"value", "ci95"}
    # a start at dx0 = 0 stays at the compatible dx = 0
    assert np.all(np.abs(ds["dx_final_over_lambda"].sel(dx0=0.0, method="nearest")) < 0.05)


@pytest.mark.slow
def test_potential_quick(quick_runs):
    """The whole quick plan (36 impulse, 36 force and 3 release runs); test_potential_reduced runs by default."""
    ds, summary, _ = quick_runs("potential")
    _check_potential(ds, summary, min_stiffnesses=6)


def test_potential_reduced(tmp_path):
    """A reduced real potential run: 7 dphi x 2 common phases, 2 beta x 2 d/2A x 3 forces (26 runs, of 75
    quick).  d/2A = 0.5 and 0.6 (per swimmer: channels 2 (d/2A) 2A, 105 and 125 mm at beta = 45 deg), just
    above the in-phase pair's obstruction (0.48), where the settled pair touches and holds against the
    quick ladder's low rungs (docs/confinement_d.md's cohesion scan)."""
    p = potential.PotentialPlan(np.pi * np.array([-1.0, -0.5, -0.25, 0.0, 0.25, 0.5, 1.0]), [30, 60], [0.5, 0.6],
                                list(potential.FORCES_N_QUICK[:3]), impulse_phi0=(0.0, np.pi))
    ds = potential.dataset(_context(tmp_path, "potential"), p)
    _check_units("potential", ds)
    _check_potential(ds, potential.summary(ds), min_stiffnesses=4)
    potential.figure(ds).savefig(tmp_path / "potential.png")


def _check_potential(ds, summary, min_stiffnesses: int):
    imp = ds["impulse"]
    # (a) contact grows with the detuning from compatibility (on both sides)
    for sign in (1, -1):
        at = [float(imp.sel(dphi=sign * q * np.pi, method="nearest")) for q in (0, 0.25, 0.5, 1.0)]
        assert at[0] < at[1] < at[2] < at[3]
    fit = summary["impulse_fit"]
    assert 0 <= fit["r2"]["value"] <= 1 and fit["slope_Ns_per_rad"]["value"] > 0
    # the line rests on the distinct |dphi| (+-dphi pooled), not on the rows
    n_abs = np.unique(np.round(np.abs(ds["dphi"].values), 9)).size
    assert fit["r2"]["n"] == fit["slope_Ns_per_rad"]["n"] == fit["n_abs_dphi"] == n_abs < ds.sizes["dphi"]
    assert fit["slope_Ns_per_rad"]["stderr"] > 0
    # every stiffness carries its interval
    ci = ds["stiffness_ci95"].values
    ok = np.isfinite(ds["stiffness"].values)
    assert np.all(ci[ok][:, 0] <= ds["stiffness"].values[ok]) and np.all(ds["stiffness"].values[ok] <= ci[ok][:, 1])
    # (b-d) a linear, positive stiffness that falls as the walls move apart
    k = ds["stiffness"]
    assert int(np.isfinite(k).sum()) >= min_stiffnesses
    assert float(np.nanmin(k)) > 0
    for b in ds["beta"].values:
        kb = k.sel(beta=b).values
        fitted = kb[np.isfinite(kb)]
        assert fitted.size >= 2 and fitted[0] > fitted[-1]  # narrowest fitted channel stiffer than the widest
    # the narrowest channel, just above the obstruction, holds every rung (cohesion there); a width with
    # no rung held is reported with k = 0 and no fit, never the other way round
    for b, v in summary["per_beta"].items():
        coh = v["cohesion"]
        assert coh[0]["cohesive"] and coh[0]["held_N"] == [float(f) for f in ds["force"].values]
        for j, c in enumerate(coh):
            assert c["d_over_2A"] == pytest.approx(float(ds["d_over_2A"].values[j]))
            if not c["cohesive"]:
                assert c["k_N_per_m"] == 0.0 and not np.isfinite(ds["stiffness"].sel(beta=float(b)).values[j])
                assert c["d_over_2A"] in summary["no_cohesion"][b]


@pytest.mark.slow
def test_basins_quick(quick_runs):
    """The whole quick plan (29 scan and 81 grid runs); test_basins_reduced runs by default."""
    ds, summary, _ = quick_runs("basins")
    _check_basins(ds, summary)


def test_basins_reduced(tmp_path):
    """A reduced real basins run: six starts and one refinement a side, a 3 x 3 grid (17 runs, of 110
    quick)."""
    p = basins.BasinsPlan([-0.8, -0.45, -0.1, 0.1, 0.45, 0.8], 1, [-0.5, 0.0, 0.5], [-np.pi / 2, 0.0, np.pi / 2])
    ds = basins.dataset(_context(tmp_path, "basins"), p)
    _check_units("basins", ds)
    _check_basins(ds, basins.summary(ds))
    assert ds.sizes["start"] == 8  # the six starts and one refinement inside each side's bracket
    basins.figure(ds).savefig(tmp_path / "basins.png")


def _context(tmp_path, name: str):
    """A quick study's context writing under ``tmp_path`` (for a reduced plan run through ``dataset``)."""
    return studies.StudyContext(studies.StudyConfig(out_dir=tmp_path, quick=True, seed=0), name, progress=False)


@pytest.mark.slow
def test_packing_quick(quick_runs):
    ds, summary, _ = quick_runs("packing")
    _check_packing(ds, summary)


def _check_basins(ds, summary):
    start, ret = ds["start"].values, ds["scan_returned"].values
    # nearby starts return to the compatible dx = 0, far ones do not
    assert ret[np.argmin(np.abs(start - 0.1))] and ret[np.argmin(np.abs(start + 0.1))]
    assert not ret[np.argmin(np.abs(start - 0.8))] and not ret[np.argmin(np.abs(start + 0.8))]
    thr = summary["return_threshold"]
    for side in ("positive", "negative"):
        t = thr[side]["threshold_dx0_over_lambda"]
        assert t["value"] is not None and 0.05 < abs(t["value"]) < 0.8
        assert min(t["ci95"]) <= t["value"] <= max(t["ci95"])  # the bracket
    assert ds["theory_displacement_over_lambda"].shape == ds["grid_displacement_over_lambda"].shape
    # starts with overlapping bodies (|dx0| <= lambda / 2) touch at once; starts a wavelength apart never do
    x0 = ds["dx0"].values
    assert bool(ds["grid_touched"].values[np.abs(x0) <= 0.5].all())
    assert not bool(ds["grid_touched"].values[np.isclose(np.abs(x0), 1.0)].any())
    assert summary["stair_steps"]["n_untouched"] == int((~ds["grid_touched"].values).sum())


def _check_packing(ds, summary):
    n = int(ds.attrs["n_swimmers"])
    amp = float(ds["amplitude"])
    width = ds["channel_width"]
    ok = np.isfinite(width)
    assert bool(ok.any())
    # the stored widths reproduce the requested normalised densities: rho~ = 2AN/Y
    rho = (2 * amp * n / width).where(ok)
    expect = ds["rho_tilde"].broadcast_like(width).where(ok)
    np.testing.assert_allclose(rho.values[ok.values], expect.values[ok.values], rtol=1e-12)
    # the closed form matches Monte Carlo
    assert summary["max_rel_diff_closed_form_vs_monte_carlo"] < 0.01
    # contact (joint error) rises with density along the in-phase column
    col = ds["mean_joint_error"].isel(phi_max=0).mean("draw")
    assert float(col.isel(rho_tilde=0)) < packing.THRESHOLD_RAD


def test_packing_reduced(tmp_path):
    """A reduced real packing run (the quick run, 40 runs of 50 swimmers, is marked slow)."""
    plan = packing.PackingPlan([0.0, 2 * np.pi], [1.0, 3.0], draws=1, duration_s=4.0)
    ds = packing.dataset(_context(tmp_path, "packing"), plan)
    _check_units("packing", ds)
    summary = packing.summary(ds)
    _check_packing(ds, summary)
    # the in-phase group fits at rho~ = 3 without contact; a full phase spread does not
    # (its joint error crosses the threshold or the jammed run diverges)
    assert float(ds["mean_joint_error"].sel(phi_max=0.0, rho_tilde=3.0).item()) < packing.THRESHOLD_RAD
    spread = ds.sel(phi_max=2 * np.pi, rho_tilde=3.0)
    assert bool(spread["run_failed"].item()) or float(spread["mean_joint_error"].item()) > 0.01
    packing.figure(ds).savefig(tmp_path / "packing.png")


def test_the_impulse_r2_without_phase_scatter_recovers_a_noisy_lines_shape():
    """Impulses on an exact line in |dphi| plus phase scatter: the plain R^2 of the means falls with the
    scatter, the one with the scatter taken out stays near 1; on a curved shape it stays below 1."""
    from undulate import stats
    from undulate.studies.potential import impulse_r2_without_phase_scatter

    rng = np.random.default_rng(7)
    dphi = np.linspace(-np.pi, np.pi, 41)
    line = 2.0 * np.abs(dphi)[:, None] + rng.normal(0.0, 2.0, (41, 8))
    plain = stats.line_fit(np.abs(dphi), line.mean(axis=1)).r2
    clean = impulse_r2_without_phase_scatter(dphi, line)
    assert plain.value < 0.9 < clean.value <= 1.0 and clean.low < clean.value <= clean.high
    curve = 3.0 * (np.abs(dphi) > 1.0)[:, None] + rng.normal(0.0, 0.05, (41, 8))  # a step, hardly any scatter
    assert impulse_r2_without_phase_scatter(dphi, curve).value < 0.85


def test_the_impulse_r2_without_phase_scatter_leaves_an_exact_phase_average_alone():
    """On equally spaced common phases a phase dependence that averages out exactly (here 3 sin(phi0)) is
    no error of the mean: the two interpenetrating halves (+dphi, -dphi) agree, nothing is taken out, and
    the R^2 is the plain one.  var(phi0) / n, as if the phases were drawn, would call 3 sin(phi0) noise
    and lift a step's R^2 towards 1."""
    from undulate import stats
    from undulate.studies import _analysis as C
    from undulate.studies.potential import (_r2_without_scatter_value, _split_half_means,
                                            impulse_r2_without_phase_scatter)

    dphi = np.linspace(-np.pi, np.pi, 41)
    phi0 = np.linspace(0.0, 2 * np.pi, 8, endpoint=False)
    step = 3.0 * (np.abs(dphi) > 1.0)[:, None] + 3.0 * np.sin(phi0)[None, :]
    x, y, nv = _split_half_means(dphi, step)
    assert x.size == 21 and np.allclose(nv, 0.0, atol=1e-20)
    # +-dphi rows that are the same runs (a mirror shift of whole grid steps) split by even / odd phases
    same = np.array([[0.0, 1.0, 0.0, 1.0], [1.0, 0.0, 1.0, 0.0]])  # one set of runs, reordered
    xs, ys, nvs = _split_half_means([-1.0, 1.0], same)
    assert xs.tolist() == [1.0] and ys.tolist() == [0.5] and nvs.tolist() == [0.25]
    other = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 1.0, 1.0, 1.0]])  # two different halves
    assert _split_half_means([-1.0, 1.0], other)[2].tolist() == [0.25]
    # one run a half will do (quick's first look: 2 common phases; dphi = 0 has one row)
    x0, _, nv0 = _split_half_means([0.0, 1.0], np.array([[1.0, 3.0], [2.0, np.nan]]))
    assert x0.tolist() == [0.0] and nv0.tolist() == [1.0]  # |dphi| = 1: a half with no finite run, left out
    plain = stats.line_fit(x, y).r2
    clean = impulse_r2_without_phase_scatter(dphi, step)
    assert clean.value == pytest.approx(plain.value, abs=1e-9) and clean.value < 0.85
    u, pooled = C.by_abs_dphi(dphi, step)  # what the random-sampling formula would have taken out:
    naive = np.nanvar(pooled, axis=1, ddof=1) / np.isfinite(pooled).sum(axis=1)
    assert _r2_without_scatter_value(u, np.nanmean(pooled, axis=1), naive) > plain.value + 0.05


def test_the_impulse_line_counts_each_abs_dphi_once():
    """+-dphi are one design point (mirror images; +-pi one state): the line on |dphi| pools their runs,
    so its intervals rest on the distinct |dphi|, not on twice as many rows."""
    from undulate.studies import _analysis as C

    dphi = np.linspace(-np.pi, np.pi, 9)
    rows = np.abs(dphi)[:, None] + np.arange(4.0)[None, :]  # (dphi, phi0)
    u, pooled = C.by_abs_dphi(dphi, rows)
    np.testing.assert_allclose(u, np.linspace(0.0, np.pi, 5))
    assert pooled.shape == (5, 8) and np.isnan(pooled[0, 4:]).all() and np.isfinite(pooled[1:]).all()
    np.testing.assert_allclose(np.nanmean(pooled, axis=1), u + 1.5)
    u1, p1 = C.by_abs_dphi(dphi, np.abs(dphi))  # one value per dphi
    np.testing.assert_allclose(u1, u)
    np.testing.assert_allclose(np.nanmean(p1, axis=1), u)


def test_row_means_are_numpys_nanmean_and_nan_without_a_warning_for_an_empty_row():
    """The impulse line's means per |dphi| (C.row_means): np.nanmean's values bitwise, and a row with
    no run (failed, or an explanation not run) NaN without NumPy's "Mean of empty slice" warning, which
    every quick reproduction printed twice (the sensitivity study's impulse line, not run in quick)."""
    import warnings

    from undulate.studies import _analysis as C

    rng = np.random.default_rng(3)
    for _ in range(200):
        a = rng.normal(size=(int(rng.integers(1, 6)), int(rng.integers(1, 7)))) * 10 ** rng.uniform(-3, 3)
        a[rng.random(a.shape) < 0.4] = np.nan
        a[0] = np.nan  # at least one empty row
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            ref = np.nanmean(a, axis=1)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            got = C.row_means(a)
        assert np.array_equal(got, ref, equal_nan=True)
    np.testing.assert_array_equal(C.row_means([1.0, np.nan, 3.0]), [1.0, np.nan, 3.0])  # one value a row
    assert C.row_means(np.zeros((0, 0))).shape == (0,)


def test_two_period_impulse_runs_give_a_longer_runs_impulse_and_escape_bitwise():
    """The impulse runs last the two periods they read (IMPULSE_DURATION_S = 2 T): the impulse over
    [0, 2T] and the first period's mean dx of a 3-period run are the same numbers, bitwise; the short run
    has no steady window (NaN, not steady) instead of failing."""
    from undulate.studies._shared import IMPULSE_DURATION_S
    from undulate.studies._runners import PERIOD_S, pair_point

    assert IMPULSE_DURATION_S == 2 * PERIOD_S
    point = {"dphi_rad": 2.0, "phi0_rad": 0.7}
    short = pair_point(point, 0, duration_s=IMPULSE_DURATION_S)
    long = pair_point(point, 0, duration_s=3 * PERIOD_S)
    assert float(short["impulse_2T_Ns"]) == float(long["impulse_2T_Ns"]) > 0.1
    assert float(short["dx_period_over_lambda"][0]) == float(long["dx_period_over_lambda"][0])
    assert short.sizes["period_time"] == 2 and long.sizes["period_time"] == 3
    assert not bool(short["steady"]) and np.isnan(float(short["dx_final_over_lambda"]))
    assert np.isnan(float(short["settle_time_s"])) and np.isfinite(float(long["dx_final_over_lambda"]))


def test_a_pair_at_minus_dphi_is_the_mirror_image_of_the_pair_at_dphi():
    """Why +-dphi are one design point of the impulse line: reflected across the channel's centre line
    (each body's bend negated: phase + pi) and relabelled, the pair (phi0, phi0 + dphi) is the pair
    (phi0 + dphi + pi, phi0 + pi), i.e. -dphi from phi0' = phi0 + dphi + pi.  Real runs: the same contact
    impulse over the first two periods, equal to rounding (so on the common-phase grid some -dphi runs
    repeat +dphi runs: 1.6409580233630723 against ...694 N s at dphi = 2, phi0 = 1)."""
    import functools

    from undulate.studies._shared import IMPULSE_DURATION_S
    from undulate.studies._runners import pair_point

    run = functools.partial(pair_point, duration_s=IMPULSE_DURATION_S)
    for dphi, phi0 in ((3 * np.pi / 4, 0.0), (1.3, 0.4)):
        a = float(run({"dphi_rad": dphi, "phi0_rad": phi0}, 0)["impulse_2T_Ns"])
        b = float(run({"dphi_rad": -dphi, "phi0_rad": (phi0 + dphi + np.pi) % (2 * np.pi)}, 0)["impulse_2T_Ns"])
        assert a > 0.1 and b == pytest.approx(a, rel=1e-9), (dphi, phi0, a, b)  # equal to rounding
