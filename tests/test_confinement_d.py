"""The paper's confinement d/2A as physics (docs/confinement_d.md, explorations/d_thresholds.py).

The paper: "d/2A < 0.5 are not possible because the undulatory gait is obstructed" and "when d/2A > 1
swimmers through initial contact can push each other away".  With ``d`` the wall distance per swimmer
(:func:`undulate.theory.channel_width_m`: a pair's channel is ``W = 2 d``) the default 3-link pair
meets both, allowing for its 15 mm body: an in-phase pair is obstructed below W = 100.6-101.3 mm
(d/2A = 0.48) and free above; a pair side by side pushes itself apart, for every dphi tested, above
W = 224.4-225.0 mm (d/2A = 1.08).  Each test runs a few millimetres either side of a measured threshold,
so it fails if the model's obstruction or push-apart moves by more than that margin.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from undulate import SimOptions
from undulate.simulation import simulate
from undulate.studies._runners import LONE_SKIP_S, lone_swimmer, pair_scene
from undulate.studies.packing import THRESHOLD_RAD
from undulate.theory import channel_width_m

OBSTRUCT_S, PUSH_S, LATE_PERIODS = 20.0, 40.0, 3


@pytest.fixture(scope="module")
def lone():
    ds = lone_swimmer({}, 0)
    return float(ds["amplitude_m"]), float(ds["mean_joint_error_rad"])


def _excess(width_m: float, lone_err: float) -> float:
    """Mean joint error (t >= 2 s) of an in-phase pair started in contact, above the lone swimmer's, rad."""
    ds = simulate(pair_scene({"channel_width_m": width_m}), SimOptions(duration_s=OBSTRUCT_S, sample_rate_hz=20.0))
    return float(ds["joint_error"].where(ds["time"] >= LONE_SKIP_S).mean()) - lone_err


def _late_force(width_m: float, dphi_rad: float) -> float:
    """Largest swimmer-swimmer contact force over the last 3 periods of a pair started side by side, N."""
    ds = simulate(pair_scene({"channel_width_m": width_m, "dphi_rad": dphi_rad}),
                  SimOptions(duration_s=PUSH_S, sample_rate_hz=20.0))
    t = ds["time"].values
    late = t >= t[-1] - LATE_PERIODS * float(ds.attrs["period"])
    return float(np.abs(ds["contact_force_pair"].values[late, 0]).max())


def test_an_in_phase_pair_is_obstructed_below_d_over_2A_one_half_and_free_above(lone):
    amp, err = lone
    assert 2 * amp == pytest.approx(0.1045, abs=0.001)  # the amplitude the thresholds were measured with
    below, above = float(channel_width_m(0.46, amp, 2)), float(channel_width_m(0.50, amp, 2))  # 96, 104.5 mm
    assert _excess(below, err) > THRESHOLD_RAD
    assert _excess(above, err) < THRESHOLD_RAD


def test_an_antiphase_pair_pushes_itself_apart_only_above_d_over_2A_one(lone):
    amp, _ = lone
    below, above = float(channel_width_m(1.03, amp, 2)), float(channel_width_m(1.12, amp, 2))  # 215, 234 mm
    assert _late_force(below, math.pi) > 0.0  # still touching after 20 periods
    assert _late_force(above, math.pi) == 0.0  # apart: no contact over the last 3 periods


@pytest.mark.slow
@pytest.mark.parametrize("dphi, touching_m, free_m", [
    (math.pi / 4, 0.160, 0.170), (math.pi / 2, 0.190, 0.200), (3 * math.pi / 4, 0.210, 0.220),
    (math.pi, 0.220, 0.230)])
def test_every_detuned_pair_pushes_itself_apart_above_its_measured_width(dphi, touching_m, free_m):
    """The coarse widths either side of each dphi's threshold (explorations/results/d_thresholds.json):
    the wider the detuning the wider the channel it needs, all of them free by 225 mm (d/2A = 1.08)."""
    assert _late_force(touching_m, dphi) > 0.0
    assert _late_force(free_m, dphi) == 0.0


@pytest.mark.slow
@pytest.mark.parametrize("dx0_over_lambda", [0.1, -0.1])
def test_the_obstruction_does_not_depend_on_the_start(lone, dx0_over_lambda):
    """From dx0 = +-0.1 lambda the wedged pair snaps to dx = 0 and is obstructed exactly as from 0."""
    _, err = lone
    for w, obstructed in ((0.0995, True), (0.1025, False)):
        ds = simulate(pair_scene({"channel_width_m": w, "dx0_over_lambda": dx0_over_lambda}),
                      SimOptions(duration_s=OBSTRUCT_S, sample_rate_hz=20.0))
        excess = float(ds["joint_error"].where(ds["time"] >= LONE_SKIP_S).mean()) - err
        assert (excess > THRESHOLD_RAD) == obstructed
