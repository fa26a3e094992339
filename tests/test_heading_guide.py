"""Scene.heading_guide: the yaw recoil removed, so the lab-frame shape is the commanded travelling wave."""

from __future__ import annotations

import math

import numpy as np
import pytest

from undulate.errors import ParameterError
from undulate.params import Channel, ControllerParams, Gait, Scene, SimOptions, SwimmerGeometry
from undulate.scene import build, chord_heading
from undulate.simulation import simulate


def test_chord_heading_closed_forms():
    # straight body: no turn; a body bent only at one joint turns by half that joint's angle (N = 2 links)
    y, r = chord_heading(np.zeros((1, 2)), np.zeros((1, 2)), 3)
    assert y[0] == pytest.approx(0.0) and r[0] == pytest.approx(0.0)
    y, _ = chord_heading(np.array([[0.4]]), np.zeros((1, 1)), 2)
    assert y[0] == pytest.approx(0.2)  # root = link 1: its chord-relative angle is +0.4/2, so yaw -(-0.2)
    # the rate is the time derivative of the heading (central difference of a moving gait)
    g, t, h = Gait(), np.array([0.3]), 1e-6
    a, ad = g.joint_angles(t, (0.0,), 9)[:, 0], g.joint_velocities(t, (0.0,), 9)[:, 0]
    ap, am = g.joint_angles(t + h, (0.0,), 9)[:, 0], g.joint_angles(t - h, (0.0,), 9)[:, 0]
    _, rate = chord_heading(a, ad, 9)
    fd = (chord_heading(ap, ad, 9)[0] - chord_heading(am, ad, 9)[0]) / (2 * h)
    assert rate[0] == pytest.approx(fd[0], rel=1e-5, abs=1e-8)


def _lone(n_links, beta_deg, guide):
    sc = Scene(phases_rad=(0.0,), gait=Gait(amplitude_rad=math.radians(beta_deg)),
               geometry=SwimmerGeometry(n_links=n_links, length_m=0.54), channel=Channel(width_m=0.5),
               heading_guide=guide)
    ds = simulate(sc, SimOptions(duration_s=8.0, sample_rate_hz=100, record=("node_x", "node_y")))
    nx, ny = ds["node_x"].values[-200:, 0], ds["node_y"].values[-200:, 0]  # the last period
    chord = np.arctan2(ny[:, -1] - ny[:, 0], nx[:, -1] - nx[:, 0])
    return (chord.max() - chord.min()) / 2, (ny.max(0) - ny.min(0)) / 2


def test_the_guide_removes_the_recoil_and_its_standing_wave():
    swing, env = _lone(9, 17.85, False)
    assert swing > 0.1  # a free body turns back and forth as it bends (isotropic drag)
    assert env.max() / env.min() > 2  # ... so its lateral excursion varies along it: a standing wave
    swing, env = _lone(9, 17.85, True)
    assert swing < 0.02  # the chord stays along x (servo lag leaves a little)
    assert env.max() / env.min() < 1.2  # a travelling wave: the same excursion along the body
    swing, env = _lone(3, 45.0, True)
    assert swing < 0.005 and env.max() / env.min() < 1.02


def test_the_guide_is_validated_and_only_in_the_model_when_asked():
    with pytest.raises(ParameterError, match="heading_guide"):
        Scene(heading_guide="yes")
    with pytest.raises(ParameterError, match="heading_guide"):
        Scene(heading_guide=True, controller=ControllerParams(kind="phase-oscillator"))
    assert build(Scene()).index.ctrl_heading.shape == (2, 0)
    cs = build(Scene(heading_guide=True))
    assert cs.index.ctrl_heading.shape == (2, 2) and cs.model.nu == build(Scene()).model.nu + 4


def test_heading_guide_from_the_command_line(tmp_path):
    import json
    import subprocess
    import sys

    import xarray as xr

    cli = [sys.executable, "-m", "undulate.cli"]
    out = tmp_path / "g.nc"
    r = subprocess.run([*cli, "simulate", "--phases", "0", "--links", "9", "--amplitude", "23", "--channel-width",
                        "0.5", "--heading-guide", "--duration", "6", "--sample-rate", "100", "--out", str(out)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        nx, ny = ds["node_x"].values[-200:, 0], ds["node_y"].values[-200:, 0]
        assert json.loads(ds.attrs["config"])["scene"]["heading_guide"] is True  # provenance
    chord = np.arctan2(ny[:, -1] - ny[:, 0], nx[:, -1] - nx[:, 0])
    assert (chord.max() - chord.min()) / 2 < 0.02
    bad = tmp_path / "bad.nc"
    r = subprocess.run([*cli, "simulate", "--heading-guide", "--controller", "phase-oscillator", "--out", str(bad)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "--heading-guide" in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not bad.exists()
