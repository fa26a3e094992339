"""Two engines, one physics: the pair scene in MuJoCo and in pymunk (Chipmunk2D).

The pymunk model (tests/pymunk_pair.py) is written from the model's equations;
agreement of the steady offset of a pair is the strongest check that it is
not an artefact of one solver's settings.  The comparison table lives in
docs/cross_engine.md.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("pymunk")

from pymunk_pair import DPHIS, PymunkPair, mujoco_dx_over_lambda, steady_dx_over_lambda  # noqa: E402

from undulate import Channel, Scene  # noqa: E402


def test_pymunk_model_tracks_its_gait_and_drifts_at_F_over_total_drag():
    # the second engine's own physics checks: unobstructed servo tracking, and a constant force F
    # gives the drift velocity F / (N c) of a body on viscous ground
    F = 0.3
    sc = Scene(phases_rad=(0.3,), channel=Channel(width_m=2.0), forces_N=(F,))
    tr = PymunkPair(sc, 0.0005).run(4.0)
    t = tr["time"]
    cmd = sc.gait.joint_angles(t, sc.phases_rad, 3)[:, 0]
    rms = float(np.sqrt(np.mean((tr["alpha"][t >= 2.0, 0] - cmd[t >= 2.0]) ** 2)))
    x = tr["x"][:, 0]
    v = (x[t >= 4.0 - 1e-9][0] - x[t >= 2.0 - 1e-9][0]) / 2.0  # over one whole gait period
    print(f"pymunk lone swimmer: RMS joint error {rms * 1e3:.2f} mrad, drift {v * 1e3:.2f} mm/s "
          f"(F / N c = {F / 6 * 1e3:.2f})")
    assert rms < 0.02
    assert v == pytest.approx(F / (3 * sc.ground.drag_N_s_per_m), rel=0.02)


@pytest.mark.slow
@pytest.mark.parametrize("dphi", DPHIS)
def test_pair_offset_agrees_between_mujoco_and_pymunk(dphi):
    sc = Scene(phases_rad=(0.0, dphi))
    mj = mujoco_dx_over_lambda(sc)
    pm = steady_dx_over_lambda(PymunkPair(sc, 0.00025).run(30.0), sc)
    print(f"dphi = {dphi / math.pi:+.2f} pi: MuJoCo {mj:+.4f}, pymunk {pm:+.4f}")
    if abs(abs(dphi) - math.pi) < 1e-9 and abs(abs(mj - pm) - 1.0) < 0.02:
        pytest.fail(f"the engines chose different compatibility branches at dphi = pi ({mj:+.3f}, {pm:+.3f})")
    assert abs(mj - pm) < 0.02
