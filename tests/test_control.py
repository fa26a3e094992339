"""Closed-loop controllers: limit cycles, exact open-loop equivalence, convergence in the control rate."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from undulate import Channel, Scene, SimOptions, simulate
from undulate.control import OpenLoop, SelfOscillating, make_controller
from undulate.errors import ParameterError
from undulate.params import ControllerParams
from undulate.phases import (gait_frequency, gait_phase, kinematic_phase, neighbour_phase_differences,
                             order_parameter, phase_offsets, time_to_lock)

WIDE = Channel(width_m=2.0)
PAIR = Channel(width_m=0.13)


def _data_vars_identical(a, b):
    assert set(a.data_vars) == set(b.data_vars)
    for v in a.data_vars:
        np.testing.assert_array_equal(a[v].values, b[v].values, err_msg=v)


def test_open_loop_controller_through_the_closed_loop_path_is_bitwise_the_open_loop_run():
    sc = Scene(phases_rad=(0.0, math.pi / 2), channel=PAIR)
    opt = SimOptions(duration_s=6.0)
    ref = simulate(sc, opt)
    new = simulate(sc, opt, controller=OpenLoop(sc.gait, sc.geometry.n_links, 100.0))
    _data_vars_identical(ref, new)
    assert new.attrs["control_rate"] == pytest.approx(100.0)
    # the default scene records the open-loop gait phase psi = 2 pi f t - phi
    psi = ref["gait_phase"].values
    t = ref["time"].values
    np.testing.assert_allclose(psi, 2 * np.pi * 0.5 * t[:, None] - np.array([0.0, math.pi / 2]), atol=1e-12)


def test_a_sensing_open_loop_steps_whole_chunks_bitwise_as_period_by_period():
    """A feed-forward controller (commands independent of what it senses) is rolled out a chunk at a
    time and told afterwards what it sensed at each control update: the run and every sensed value
    are bitwise those of stepping one control period at a time."""
    from undulate import simulate_batch
    from undulate.control import SensingOpenLoop

    scenes = [Scene(phases_rad=(0.0, 2.0), channel=PAIR), Scene(phases_rad=(0.0, -0.7), channel=PAIR)]
    opt = SimOptions(duration_s=3.0, record=("x", "joint_angle", "joint_command", "gait_phase"))

    class PeriodByPeriod(SensingOpenLoop):
        feed_forward = False

    runs, sensed = [], []
    for cls in (SensingOpenLoop, PeriodByPeriod):
        ctl = cls(scenes[0].gait, scenes[0].geometry.n_links, 100.0)
        runs.append(simulate_batch(scenes, opt, controller=ctl))
        sensed.append(ctl.sensed)
    for a, b in zip(*runs):
        _data_vars_identical(a, b)
    assert len(sensed[0]) == len(sensed[1]) == 300  # 3 s at 100 Hz
    for sa, sb in zip(*sensed):
        for x, y in zip(sa, sb):
            np.testing.assert_array_equal(x, y)
    # the loads were sensed while the pair touched (else the test would compare zeros)
    assert max(np.abs(s[4]).max() for s in sensed[0]) > 0.01


def test_phase_oscillator_without_coupling_keeps_its_frequency_exactly():
    sc = Scene(phases_rad=(0.3, -1.0), channel=PAIR, controller=ControllerParams(kind="phase-oscillator", coupling=0.0))
    ds = simulate(sc, SimOptions(duration_s=10.0))
    psi = gait_phase(ds).values
    t = ds["time"].values
    np.testing.assert_allclose(psi, 2 * np.pi * 0.5 * t[:, None] - np.array([0.3, -1.0]), atol=1e-9)
    # and it drives the same motion as the open-loop gait (set-points equal to rounding)
    ref = simulate(Scene(phases_rad=(0.3, -1.0), channel=PAIR), SimOptions(duration_s=10.0))
    np.testing.assert_allclose(ds["joint_angle"].values, ref["joint_angle"].values, atol=1e-6)


def test_phase_oscillator_with_load_feedback_slows_a_resisted_swimmer():
    """Drag resists every joint's motion: with sigma > 0 the phase runs slower than f."""
    sc = Scene(phases_rad=(0.0,), channel=WIDE, controller=ControllerParams(kind="phase-oscillator", coupling=0.5))
    ds = simulate(sc, SimOptions(duration_s=8.0))
    f = float(gait_frequency(gait_phase(ds), t_from=2.0)[0])
    assert 0.3 < f < 0.5


class _HeldHead(SelfOscillating):
    """A self-oscillating swimmer whose head joint is held straight for a while: a perturbation
    of the body (what an obstruction does), its own controller state left alone."""

    window = (4.1, 4.6)

    def commands(self, t_steps_s, angle_rad=None, velocity_rad_s=None, load_Nm=None):
        ang, vel = super().commands(t_steps_s, angle_rad, velocity_rad_s, load_Nm)
        t = np.asarray(t_steps_s)
        held = (t >= self.window[0]) & (t < self.window[1])
        ang[held, ..., 0] = 0.0
        vel[held, ..., 0] = 0.0
        return ang, vel


def _amplitude_and_frequency(ds, t_from, t_to):
    sel = (ds["time"] >= t_from) & (ds["time"] <= t_to)
    a = ds["joint_angle"].where(sel, drop=True).values[:, 0, :]
    amp = 0.5 * (a.max(axis=0) - a.min(axis=0))
    f = float(gait_frequency(kinematic_phase(ds, trim_periods=1.0), t_from=t_from, t_to=t_to)[0])
    return amp, f


def test_self_oscillating_swimmer_settles_on_its_limit_cycle_and_returns_after_a_perturbation():
    p = ControllerParams(kind="self-oscillating")
    sc = Scene(phases_rad=(0.0,), channel=WIDE, controller=p)
    opt = SimOptions(duration_s=16.0, sample_rate_hz=100.0)
    free = simulate(sc, opt)
    beta, f0 = sc.gait.amplitude_rad, sc.gait.frequency_hz
    amp, f = _amplitude_and_frequency(free, 2.0, 14.0)
    print(f"free: amplitude {np.degrees(amp)} deg, frequency {f:.4f} Hz")
    assert np.all(np.abs(amp / beta - 1) < 0.05)
    assert abs(f / f0 - 1) < 0.05
    ctl = _HeldHead(sc.gait, sc.geometry.n_links, p.control_rate_hz)
    pert = simulate(sc, opt, controller=ctl)
    amp2, f2 = _amplitude_and_frequency(pert, 8.0, 14.0)
    print(f"after the perturbation: amplitude {np.degrees(amp2)} deg, frequency {f2:.4f} Hz")
    assert np.all(np.abs(amp2 / beta - 1) < 0.05)
    assert abs(f2 / f0 - 1) < 0.05
    # the held joint fell behind: the perturbed swimmer's phase lags the free one's for good
    lag = float(gait_phase(free).values[-1, 0] - gait_phase(pert).values[-1, 0])
    print(f"phase lag after the hold: {lag:.3f} rad")
    assert 0.2 < lag < 2 * np.pi * f0 * 0.6 + 0.2


def test_kinematic_phase_estimator_recovers_the_commanded_phase():
    sc = Scene(phases_rad=(0.0, 2.0), channel=WIDE, lateral_gap_m=0.5)
    ds = simulate(sc, SimOptions(duration_s=12.0, sample_rate_hz=50.0))
    est = kinematic_phase(ds)
    ref = gait_phase(ds).sel(time=est["time"])
    err = np.angle(np.exp(1j * (est.values - ref.values)))
    print(f"kinematic phase error: max {np.abs(err).max():.3f} rad (servo lag included)")
    assert np.abs(err).max() < 0.1
    phi = phase_offsets(ds)
    np.testing.assert_allclose(phi.values[-1], [0.0, 2.0], atol=1e-9)
    d = neighbour_phase_differences(ds)
    np.testing.assert_allclose(np.abs(d.values[-1]), 2.0, atol=1e-9)
    r = order_parameter(gait_phase(ds))
    np.testing.assert_allclose(r.values, abs(math.cos(1.0)), atol=1e-9)  # |e^{i0} + e^{-2i}| / 2
    lock = time_to_lock(d)
    assert float(lock[0]) == ds["time"].values[0]  # open loop: locked from the start


def test_closed_loop_pair_converges_as_the_control_rate_rises():
    """A load-coupled pair in the channel: the phase difference after 8 s at 100, 200 and
    400 Hz control (0.5 ms steps: whole periods of 20, 10 and 5 steps)."""
    out = []
    for rate in (100.0, 200.0, 400.0):
        sc = Scene(phases_rad=(0.0, 1.2), channel=PAIR,
                   controller=ControllerParams(kind="phase-oscillator", coupling=1.0, control_rate_hz=rate))
        ds = simulate(sc, SimOptions(duration_s=8.0, timestep_s=0.0005))
        assert ds.attrs["control_rate"] == pytest.approx(rate)
        out.append(float(neighbour_phase_differences(ds).values[-1, 0]))
    d1, d2 = abs(out[0] - out[1]), abs(out[1] - out[2])
    print(f"dphi at 100/200/400 Hz: {out}; differences {d1:.4f}, {d2:.4f}")
    assert d2 < 0.05 and d2 <= d1 + 1e-3


def test_hold_x_keeps_each_midpoint_in_place_while_lateral_motion_stays_free():
    sc = Scene(phases_rad=(0.0, math.pi / 2), channel=PAIR, dx0_m=0.1, hold_x=True,
               controller=ControllerParams(kind="self-oscillating"))
    opt = SimOptions(duration_s=8.0)
    ds = simulate(sc, opt)
    # 3 links: the body's midpoint is the middle link's centre, between nodes 1 and 2
    mid = 0.5 * (ds["node_x"].isel(node=1) + ds["node_x"].isel(node=2))
    np.testing.assert_allclose(mid.values, np.broadcast_to(mid.values[:1], mid.shape), rtol=0, atol=1e-9)
    free = simulate(dataclasses.replace(sc, hold_x=False), opt)
    mid_free = 0.5 * (free["node_x"].isel(node=1) + free["node_x"].isel(node=2))
    assert float(np.abs(mid_free.values - mid_free.values[:1]).max()) > 0.01  # contact moves them when free
    assert float(np.ptp(ds["y"].values)) > 1e-3  # lateral motion stays free


def test_controller_parameters_are_validated():
    with pytest.raises(ParameterError, match="controller"):
        ControllerParams(kind="cpg")
    with pytest.raises(ParameterError, match="control_rate_hz"):
        ControllerParams(control_rate_hz=0)
    with pytest.raises(ParameterError, match="coupling"):
        ControllerParams(kind="phase-oscillator", coupling=-1)
    with pytest.raises(ParameterError, match="hold_x"):
        Scene(hold_x="yes")
    c = make_controller(Scene(phases_rad=(0.0, 1.0), controller=ControllerParams(kind="self-oscillating")))
    assert c.kind == "self-oscillating" and c.psi.shape == (2,)


def test_closed_loop_batch_equals_single_runs():
    """The controller is vectorised over a batch: two scenes stepped together give each one's run."""
    from undulate import simulate_batch

    p = ControllerParams(kind="phase-oscillator", coupling=1.0)
    a = Scene(phases_rad=(0.0, 2.5), channel=PAIR, controller=p)
    b = Scene(phases_rad=(0.0, -1.0), channel=PAIR, controller=p, hold_x=False)
    opt = SimOptions(duration_s=5.0)
    both = simulate_batch([a, b], opt, nthread=2)
    _data_vars_identical(both[0], simulate(a, opt))
    _data_vars_identical(both[1], simulate(b, opt))
    with pytest.raises(ParameterError, match="scenes"):
        simulate_batch([a, Scene(phases_rad=(0.0, 1.0), channel=PAIR,
                                 controller=ControllerParams(kind="self-oscillating"))], opt)
