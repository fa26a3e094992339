"""Synchronization studies: real closed-loop runs (pair and group runners), and the studies in quick mode (slow)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from undulate.studies.synchronization import group_run, pair_run


def test_load_coupled_held_pair_synchronizes_and_its_contact_force_collapses():
    """Two phase oscillators with load feedback, positions held, starting 165 deg apart: contact
    pulls their phases together and the force falls by an order of magnitude (PRX 2021's claim 3)."""
    ds = pair_run({"controller": "phase-oscillator", "hold_x": True, "dphi0_rad": math.radians(165.0)}, 0,
                  duration_s=40.0)
    start, end = float(ds["force_start"]), float(ds["force_end"])
    final = float(ds["dphi_final"])
    print(f"force {start:.3f} -> {end:.3f} N; dphi 165 -> {math.degrees(final):.1f} deg")
    assert start > 0.5 and end < 0.1 * start
    assert abs(final) < math.radians(60.0)
    assert ds["force_start"].attrs["units"] == "N" and ds["dphi"].attrs["units"] == "rad"


def test_batched_sweep_functions_give_each_point_its_own_run_in_order():
    """The batched runners group a task's points by controller and hold_x (size for groups), step each
    group together and return the results in the points' order, bitwise each point's run alone."""
    from undulate.studies.synchronization import group_runs, pair_run, pair_runs

    pts = [{"controller": c, "hold_x": h, "dphi0_rad": d}
           for c, h, d in (("relay", True, 2.0), ("phase-oscillator", True, 1.0), ("relay", True, -1.5),
                           ("relay", False, 2.0))]
    for a, b in zip(pair_runs(pts, [0] * 4, duration_s=3.0), [pair_run(p, 0, duration_s=3.0) for p in pts]):
        for v in a.data_vars:
            np.testing.assert_array_equal(a[v].values, b[v].values, err_msg=v)
    gp = [{"controller": "relay", "n_swimmers": n, "spacing_m": w} for n, w in ((3, 0.055), (4, 0.065), (3, 0.065))]
    for a, b in zip(group_runs(gp, [0, 1, 2], duration_s=12.0), [group_run(p, s, duration_s=12.0) for p, s in zip(gp, [0, 1, 2])]):
        for v in a.data_vars:
            np.testing.assert_array_equal(a[v].values, b[v].values, err_msg=v)


def test_open_loop_pair_keeps_its_phase_difference_exactly():
    """The controller-free reference: without feedback nothing can change a phase."""
    from undulate.studies import synchronization as s
    from undulate.params import ControllerParams

    s.CONTROLLERS["_open"] = ControllerParams(kind="phase-oscillator", coupling=0.0)
    try:
        ds = pair_run({"controller": "_open", "hold_x": False, "dphi0_rad": 2.0}, 0, duration_s=12.0)
    finally:
        del s.CONTROLLERS["_open"]
    np.testing.assert_allclose(ds["dphi"].values, 2.0, atol=1e-9)


def test_group_runner_reports_order_parameter_and_final_configuration():
    ds = group_run({"controller": "self-oscillating", "n_swimmers": 3, "spacing_m": 0.065}, 7, duration_s=20.0)
    r = ds["R"].values
    assert np.all((r >= 0) & (r <= 1 + 1e-12))
    assert 0 <= float(ds["R_final"]) <= 1
    assert 0 <= float(ds["compat_rms"]) <= 0.5  # residuals from the nearest branch lie within half a wavelength
    assert int(ds["phase_locked"]) in (0, 1)
    for v in ds.data_vars:
        assert "units" in ds[v].attrs, v
    again = group_run({"controller": "self-oscillating", "n_swimmers": 3, "spacing_m": 0.065}, 7, duration_s=20.0)
    np.testing.assert_array_equal(ds["R"].values, again["R"].values)  # seeded: deterministic


@pytest.mark.slow
@pytest.mark.parametrize("name", ["synchronization-pairs", "synchronization-groups", "phase-interaction"])
def test_synchronization_studies_in_quick_mode_give_every_claim_a_verdict(tmp_path, name):
    import json

    from undulate.studies import run_study

    run_study(name, tmp_path, quick=True)
    doc = json.loads((tmp_path / f"{name}.json").read_text())
    assert doc["n_failed"] == 0
    # phase-interaction: "no result" where H is zero at every held dphi (nothing to predict); an interval
    # criterion (the contact-force ratio) may be undecided when its interval straddles the bound
    allowed = ("holds", "fails", "undecided") + (("no result",) if name == "phase-interaction" else ())
    assert doc["claims"] and all(r["verdict"] in allowed for r in doc["claims"]), doc["claims"]


def test_the_phase_tools_refuse_what_they_cannot_read_naming_the_argument():
    """order_parameter, gait_frequency and time_to_lock read (time, swimmer or rank) phases; a list, a 1-D
    record, a tolerance of no radians or a window that ends before it starts is one ParameterError naming
    it (an AttributeError or IndexError came before, and tol_rad = -1 answered NaN as if never locked)."""
    import xarray as xr

    from undulate.errors import ParameterError
    from undulate.phases import gait_frequency, order_parameter, time_to_lock

    t = np.arange(0.0, 10.0, 0.1)
    psi = xr.DataArray(np.stack([np.pi * t, np.pi * t + 0.3], axis=1), dims=("time", "swimmer"), coords={"time": t})
    dphi = xr.DataArray(0.3 * np.exp(-t)[:, None], dims=("time", "rank"), coords={"time": t})
    for call, message in [
        (lambda: order_parameter(psi.values.tolist()), "invalid psi: must be an xarray.DataArray of phases"),
        (lambda: time_to_lock(dphi[:, 0]), "invalid dphi: must be an xarray.DataArray of phases"),
        (lambda: time_to_lock(dphi, tol_rad=-1.0), "invalid tol_rad: must be > 0 rad"),
        (lambda: time_to_lock(dphi, hold_s=-1.0), "invalid hold_s: must be >= 0 s"),
        (lambda: gait_frequency(psi, t_from=5.0, t_to=4.0), "invalid t_to: must be > t_from = 5 s"),
        (lambda: gait_frequency(psi, t_from=float("nan")), "invalid t_from: must be a finite number"),
    ]:
        with pytest.raises(ParameterError) as err:
            call()
        assert message in str(err.value), str(err.value)
    # what they accept still answers: two phases 0.3 rad apart, a frequency of 0.5 Hz, a lock at ~1.1 s
    assert float(order_parameter(psi)[0]) == pytest.approx(abs(np.cos(0.15)))
    assert gait_frequency(psi).values == pytest.approx([0.5, 0.5])
    assert float(time_to_lock(dphi, tol_rad=0.1)[0]) == pytest.approx(1.1, abs=0.1)
