"""Observables are pure functions of a trajectory: checked on synthetic data with known answers."""

from __future__ import annotations


import numpy as np
import pytest
import xarray as xr

from undulate.errors import ParameterError
from undulate.observables import (
    centreline_points,
    contact_impulse,
    gait_amplitude,
    lateral_order,
    mean_contact_force,
    neighbour_offsets,
    period_average,
    period_average_groupby,
    steady_state,
)
from undulate.studies._analysis import final_neighbours


def synthetic(x, y, phases, dt=0.1, forces=None):
    t = np.arange(x.shape[0]) * dt
    n = x.shape[1]
    ds = xr.Dataset(
        {
            "x": (("time", "swimmer"), x, {"units": "m"}),
            "y": (("time", "swimmer"), y, {"units": "m"}),
            "contact_force_pair": (("time", "pair"), np.zeros((len(t), n - 1)) if forces is None else forces),
            "contact_force_wall": (("time", "wall"), np.zeros((len(t), 2))),
        },
        coords={"time": t, "phase": ("swimmer", np.asarray(phases, dtype=float))},
        attrs={"wavelength": 0.54, "sample_interval": dt, "period": 2.0},
    )
    return ds


def test_neighbours_follow_lateral_order_even_after_a_swap():
    """One rule (lateral_ranks), two windows: sample by sample (neighbour_offsets) and at the end
    of a run (final_neighbours): both follow swimmers 0 and 1 swapping lateral places for good."""
    T = 300  # 30 s at 0.1 s, 15 gait periods; the swap at 10 s
    x = np.tile([0.0, 0.1, 0.3], (T, 1))
    y = np.tile([-0.02, 0.0, 0.02], (T, 1))
    y[T // 3:, 0], y[T // 3:, 1] = 0.0, -0.02  # swimmers 0 and 1 swap lateral places at 10 s
    ds = synthetic(x, y, phases=[0.0, 1.0, 2.5])
    off = neighbour_offsets(ds)
    before, after = off.isel(time=0), off.isel(time=-1)
    assert list(before["lower"].values) == [0, 1] and list(before["upper"].values) == [1, 2]
    assert list(after["lower"].values) == [1, 0] and list(after["upper"].values) == [0, 2]
    np.testing.assert_allclose(before["dx"].values, [0.1, 0.2])
    np.testing.assert_allclose(after["dx"].values, [-0.1, 0.3])
    np.testing.assert_allclose(after["dphi"].values, [-1.0, 2.5])
    np.testing.assert_allclose(after["dy"].values, [0.02, 0.02])
    pairs, stable = final_neighbours(ds)
    assert pairs == [(1, 0), (0, 2)] and stable
    assert lateral_order(ds).values[-1].tolist() == [1, 0, 2]
    # still changing places inside the steady window: the final order is flagged unstable
    late = y.copy()
    late[-45:, 0], late[-45:, 1] = -0.02, 0.0  # back again 4.5 s before the end
    assert final_neighbours(synthetic(x, late, phases=[0.0, 1.0, 2.5]))[1] is False


def test_period_average_of_a_sinusoid_plus_ramp_is_the_ramp_at_mid_period():
    t = np.arange(0, 20.0 + 1e-9, 0.05)
    sig = xr.DataArray(0.3 * t + np.sin(2 * np.pi * t / 2.0), dims="time", coords={"time": t})
    pa = period_average(sig, 2.0)
    assert pa.sizes["time"] == 10
    np.testing.assert_allclose(pa["time"].values, np.arange(10) * 2.0 + 1.0)
    # the mean of a sampled sinusoid over a whole period vanishes; the ramp averages to its midpoint value
    np.testing.assert_allclose(pa.values, 0.3 * pa["time"].values + 0.3 * 0.025, atol=1e-9)


def test_period_average_is_bitwise_xarrays_groupby_mean_on_a_simulated_pair():
    from undulate import Scene, SimOptions, simulate

    ds = simulate(Scene(phases_rad=(0.0, 2.0), dx0_m=0.05), SimOptions(duration_s=5.0))
    off = neighbour_offsets(ds)
    joint = ds["joint_angle"].copy()
    joint[3:17, 0, 1] = np.nan  # a gap inside the first period, and one whole period missing
    joint[41:61, 1, 0] = np.nan
    cases = [ds["x"], ds["x"].isel(swimmer=0), ds["x"].transpose("swimmer", "time"), off["dx"], off["dy"],
             joint, ds["x"].mean("swimmer"), (ds["x"] > 0).astype(int)]
    for da in cases:
        for period in (1.0, 2.0, 0.7):
            fast, ref = period_average(da, period), period_average_groupby(da, period)
            xr.testing.assert_identical(fast, ref)
            np.testing.assert_array_equal(fast.values, ref.values)


def test_steady_state_rule_on_an_exponential_approach():
    t = np.arange(0, 60.0 + 1e-9, 0.1)
    tau = 4.0
    sig = xr.DataArray(0.25 * (1 - np.exp(-t / tau)), dims="time", coords={"time": t})
    res = steady_state(sig, period_s=2.0, tol=0.01, window=3)
    assert bool(res["steady"])
    assert float(res["value"]) == pytest.approx(0.25, abs=0.01)
    # settled once the window spread is below tol: after a few time constants
    assert tau < float(res["settle_time"]) < 6 * tau
    # a still-drifting signal is flagged
    drift = xr.DataArray(0.02 * t, dims="time", coords={"time": t})
    assert not bool(steady_state(drift, period_s=2.0, tol=0.01)["steady"])


def test_contact_impulse_is_the_exact_sum_of_interval_means():
    T = 21
    f = np.zeros((T, 1))
    f[1:11, 0] = 2.0  # 2 N over the first 10 intervals of 0.1 s
    ds = synthetic(np.zeros((T, 2)), np.tile([0.0, 0.015], (T, 1)), [0, 0], forces=f)
    imp = contact_impulse(ds)
    assert float(imp["pair"].values[0]) == pytest.approx(2.0)  # N s
    assert float(contact_impulse(ds, 0.0, 0.5)["pair"].values[0]) == pytest.approx(1.0)


def test_interleaving_centres_within_a_cycle_keep_their_lateral_order():
    # two bodies whose centres of mass cross in y twice per period while their mean places stay
    t = np.arange(0, 20.0, 0.1)
    y = np.stack([-0.002 + 0.01 * np.sin(np.pi * t), 0.002 - 0.01 * np.sin(np.pi * t)], axis=1)
    x = np.tile([0.0, 0.1], (len(t), 1))
    ds = synthetic(x, y, phases=[0.0, 1.0])
    off = neighbour_offsets(ds)
    assert set(off["lower"].values[:, 0]) == {0}
    np.testing.assert_allclose(off["dx"].values, 0.1)
    # instantaneous ordering flickers, as documented
    assert set(neighbour_offsets(ds, window_s=0)["lower"].values[:, 0]) == {0, 1}
    # the end-of-run order ranks the same bodies by their mean y over the steady window
    assert final_neighbours(ds) == ([(0, 1)], True)


def _pair_like(T=60, dt=0.1):
    """A two-swimmer record over 6 s (3 gait periods) with centre lines and headings, as simulate() gives."""
    ds = synthetic(np.tile([0.0, 0.1], (T, 1)), np.tile([-0.02, 0.02], (T, 1)), phases=[0.0, 1.0], dt=dt)
    nodes = np.zeros((T, 2, 4))
    nodes[:] = np.linspace(0.0, 0.3, 4)
    return ds.assign(node_x=(("time", "swimmer", "node"), nodes),
                     node_y=(("time", "swimmer", "node"), np.zeros((T, 2, 4)) + ds["y"].values[..., None]),
                     heading=(("time", "swimmer"), np.zeros((T, 2))))


@pytest.mark.parametrize("call, name, allowed", [
    (lambda ds: period_average(ds["x"], 0.0), "period_s", "> 0 s"),
    (lambda ds: period_average(ds["x"], float("nan")), "period_s", "a finite number"),
    (lambda ds: period_average(ds["x"].values, 2.0), "da", "an xarray.DataArray"),
    (lambda ds: period_average(ds["x"].isel(time=0), 2.0), "da", "data over a 'time' coordinate"),
    (lambda ds: period_average(ds["x"].isel(time=[1, 0, 2, 3]), 2.0), "da", "strictly increasing times"),
    (lambda ds: steady_state(ds["x"], 2.0, tol=-0.1), "tol", ">= 0"),
    (lambda ds: steady_state(ds["x"], 2.0, tol=0.1, window=0), "window", "an integer >= 1"),
    (lambda ds: steady_state(ds["x"], 2.0, tol=0.1, window=2.5), "window", "an integer >= 1"),
    (lambda ds: lateral_order(ds, -1.0), "window_s", ">= 0 s"),
    (lambda ds: neighbour_offsets(ds["x"]), "ds", "a recorded trajectory"),
    (lambda ds: neighbour_offsets(ds.drop_vars("phase")), "ds", "it lacks phase"),
    (lambda ds: gait_amplitude(ds, swimmer=2), "swimmer", "an integer in [0, 1]"),
    (lambda ds: gait_amplitude(ds, swimmer=-1), "swimmer", "an integer in [0, 1]"),
    (lambda ds: gait_amplitude(ds, swimmer=True), "swimmer", "an integer in [0, 1]"),
    (lambda ds: gait_amplitude(ds, periods=0), "periods", "an integer >= 1"),
    (lambda ds: centreline_points(ds, per_link=0), "per_link", "an integer >= 1"),
    (lambda ds: contact_impulse(ds, float("nan")), "t_from", "a finite number"),
    (lambda ds: contact_impulse(ds, 9.0), "t_from", "<= the record's last time, 5.9 s"),
    (lambda ds: contact_impulse(ds, 2.0, 1.0), "t_to", ">= t_from = 2 s"),
    (lambda ds: mean_contact_force(ds, 1.0, 1.0), "t_to", "> t_from = 1 s"),
    (lambda ds: mean_contact_force(ds, 5.9), "t_from", "< the record's last time, 5.9 s"),
])
def test_observables_refuse_bad_input_naming_the_parameter(call, name, allowed):
    """A bad argument to a public observable is one ParameterError naming it and what is allowed, where
    numpy's errors (an OverflowError from a zero period, an IndexError from a swimmer out of range) or a
    silent answer (a mean force over no time divided by zero: inf, a window of -1 s) used to come."""
    with pytest.raises(ParameterError) as err:
        call(_pair_like())
    assert err.value.name == name and allowed in str(err.value)
    assert "\n" not in str(err.value)


def test_observables_accept_what_the_checks_allow():
    """The edges the checks allow still answer: an interval of no time integrates to 0 N s, a window of
    one period is steady by itself, a window of 0 s orders by the instantaneous y, whole numbers as floats."""
    ds = _pair_like()
    assert float(contact_impulse(ds, 1.0, 1.0)["pair"].sum()) == 0.0
    assert bool(steady_state(ds["x"], 2.0, tol=0.0, window=1)["steady"].all())
    assert lateral_order(ds, 0.0).values[0].tolist() == [0, 1]
    assert gait_amplitude(ds, swimmer=1.0, periods=2.0) == pytest.approx(0.0, abs=1e-12)
    assert centreline_points(ds, per_link=2)[0].shape == (60, 2, 7)
    assert neighbour_offsets(ds.isel(time=[0]))["dx"].values.tolist() == [[pytest.approx(0.1)]]
