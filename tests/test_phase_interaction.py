"""The relay oscillator and the phase-interaction function H(dphi) measured from contact."""

from __future__ import annotations

import math

import numpy as np
import pytest
import xarray as xr

from undulate import Channel, Scene, SimOptions, simulate, stats
from undulate.control import make_controller
from undulate.params import ControllerParams
from undulate.phases import gait_frequency, gait_phase
from undulate.studies import phase_interaction as P

RELAY = ControllerParams(kind="relay")


def test_uncoupled_relay_oscillator_keeps_its_free_frequency_and_amplitude():
    sc = Scene(phases_rad=(0.0,), channel=Channel(width_m=2.0), controller=RELAY)
    ctl = make_controller(sc)
    ds = simulate(sc, SimOptions(duration_s=20.0, record=("gait_phase", "joint_angle")), controller=ctl)
    f = float(gait_frequency(gait_phase(ds), t_from=10.0)[0])
    assert f == pytest.approx(sc.gait.frequency_hz, rel=1e-3)
    peak = np.abs(ds["joint_angle"].values[ds["time"].values >= 10.0]).max(axis=0)
    np.testing.assert_allclose(peak, sc.gait.amplitude_rad, rtol=0.05)
    # the joints start straight, behind the first command: the only early reversals are in the first period
    first = make_controller(sc)
    simulate(sc, SimOptions(duration_s=sc.gait.period_s, record=("gait_phase",)), controller=first)
    assert int(ctl.reversals.sum()) == int(first.reversals.sum()) <= 2


def test_relay_drive_reverses_only_where_a_joint_is_blocked():
    sc = Scene(phases_rad=(0.0,), controller=RELAY)
    ctl = make_controller(sc)
    psi = np.array([[0.3]])
    cmd = sc.gait.amplitude_rad * np.sin(ctl.offsets_rad - psi[..., None])
    w = 2 * math.pi * sc.gait.frequency_hz
    zero = np.zeros_like(cmd)
    assert ctl.phase_velocity(psi, cmd, zero, zero)[0, 0] == pytest.approx(w)  # tracking: 2 pi f
    # joint 0 moves towards -beta at psi = 0.3 (d alpha/d psi = -beta cos(-psi) < 0): lagging above it blocks it
    blocked = cmd.copy()
    blocked[..., 0] += 0.2
    assert ctl.phase_velocity(psi, blocked, zero, zero)[0, 0] == pytest.approx(RELAY.reverse_rate_factor * w)
    ahead = cmd.copy()
    ahead[..., 0] -= 0.2  # ahead of the command in its direction of motion: not blocked
    assert ctl.phase_velocity(psi, ahead, zero, zero)[0, 0] == pytest.approx(w)


@pytest.mark.parametrize("law", ["phase-oscillator", "relay"])
def test_measured_h_is_antisymmetric_for_identical_bodies(law):
    """Mirroring the channel (y -> -y) swaps the two identical bodies: H(-d) = -H(d)."""
    d = math.radians(120.0)
    hp, hm = (P.probe_run({"dphi_rad": s * d, "hold_x": True}, 0, duration_s=8.0)["H"].sel(law=law).values
              for s in (1, -1))
    assert abs(hp.mean()) > 0.1  # contact: a real interaction
    total = stats.mean(hp + hm)
    scale = abs(hp.mean())
    assert abs(total.value) < 0.1 * scale and total.low < 0.1 * scale and total.high > -0.1 * scale


def test_probes_stepped_as_one_batch_are_each_their_run_alone():
    """The H probe's batched sweep function (the study's): points of both ``hold_x`` interleaved come
    back in their order, each bitwise the probe run on its own."""
    pts = [{"dphi_rad": d, "hold_x": h} for d, h in ((-2.0, True), (0.5, False), (1.5, True), (2.5, False))]
    batch = P.probe_runs(pts, [0] * len(pts), duration_s=4.0)
    assert len(batch) == len(pts)
    for p, got in zip(pts, batch):
        xr.testing.assert_identical(got, P.probe_run(p, 0, duration_s=4.0))
    assert not np.allclose(batch[0]["H"], batch[2]["H"])  # the points' own runs, not one repeated


def _grid_summary(controller: str, dphi0, dphi, duration_s: float):
    """The study's judgement on the closed-loop pairs it shares with synchronization-pairs (each
    ending once its lock is decided) against H measured on ``dphi``."""
    from undulate.studies._closed_loop_pairs import closed_loop_pairs_sweep

    fn, _ = closed_loop_pairs_sweep(dphi0, duration_s, 0)
    runs = fn([{"controller": controller, "hold_x": True, "dphi0_rad": d} for d in dphi0], [0] * len(dphi0))
    v = xr.concat([r[["dphi"]] for r in runs], dim="dphi0_rad")
    probes = P.probe_runs([{"dphi_rad": d, "hold_x": True} for d in dphi], [0] * len(dphi))  # as the study does
    h = xr.concat([r["H"].sel(law=controller) for r in probes], dim=xr.DataArray(dphi, dims="dphi_rad", name="dphi_rad"))
    return P._one(v, h)


def test_relay_held_pairs_lock_where_the_measured_h_predicts_on_a_small_grid():
    dphi = list(np.linspace(-np.pi, np.pi, 12, endpoint=False) + np.pi / 12)
    s = _grid_summary("relay", [-2.4, -0.8, 0.8, 2.4], dphi, 30.0)
    assert s["n_runs"] == 4
    assert s["n_predicted"] == s["n_runs"], s


@pytest.mark.slow
@pytest.mark.parametrize("controller", ["relay", "phase-oscillator"])
def test_held_pairs_lock_where_the_measured_h_predicts_on_the_full_grid(controller):
    p = P.plan(quick=False)
    s = _grid_summary(controller, p["dphi0_rad"], p["dphi_rad"], p["duration_s"])
    assert s["n_predicted"] >= P.PREDICTED_FRACTION * s["n_runs"], s


def test_relay_parameters_are_validated():
    from undulate.errors import ParameterError

    for bad in ({"reverse_error_rad": 0.0}, {"reverse_rate_factor": 1.0}, {"reverse_rate_factor": float("nan")}):
        with pytest.raises(ParameterError):
            ControllerParams(kind="relay", **bad)
