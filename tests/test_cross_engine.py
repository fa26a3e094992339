"""Two engines, one physics: the pair scene in MuJoCo and in pymunk (Chipmunk2D).

The pymunk model (tests/pymunk_pair.py) is written from the model's
equations: maximal coordinates, hard iterative-impulse contacts, the servo,
drag and slew limit in Python.  Agreement of a pair's steady offset between
the two engines shows the offset is physics, not an artefact of one solver's
settings.  The measured table and the side-by-side model are in
docs/cross_engine.md.

Fast tests: the pymunk model alone (servo tracking, still centre, drift
under a force) and its sign conventions against MuJoCo (a lone swimmer's
centre-line nodes).  Slow tests (``-m slow``, ~1 min): the steady offset of
the pair for dphi in {0, pi/2, -pi/2, pi}.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pymunk")

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

from pymunk_pair import (  # noqa: E402
    DPHIS,
    mujoco_steady_dx_over_lambda,
    pair_scene,
    run_pair,
    steady_dx_over_lambda,
)

from undulate import Channel, Scene, SimOptions, simulate  # noqa: E402

TOL = 0.02
"""|dx/lambda (MuJoCo) - dx/lambda (pymunk)| allowed."""


def test_pymunk_lone_swimmer_tracks_its_gait_stays_put_and_drifts_at_F_over_N_c():
    # A lone swimmer away from the walls (2 m channel): no contact.  Internal forces (pivots, servo
    # torques) sum to zero and the drag is linear in each link's velocity, so the centre of mass obeys
    # M dV/dt = F - N c V exactly: it must not move before the force is on, and must drift at F / (N c)
    # once the transient (M / (N c) = 0.05 s) has died out.  A wrong drag, mass, force split or a servo
    # torque that is not equal and opposite breaks this; a wrong servo sign or gain breaks the tracking.
    F, on = 0.3, 1.0
    sc = Scene(phases_rad=(0.3,), channel=Channel(width_m=2.0), forces_N=(F,), force_onset_s=on)
    tr = run_pair(sc, 4.0, timestep_s=0.0005, sample_rate_hz=20.0)
    t, x, y = tr["time"], tr["x"][:, 0], tr["y"][:, 0]
    n, c = sc.geometry.n_links, sc.ground.drag_N_s_per_m

    cmd = sc.gait.joint_angles(t, sc.phases_rad, n)[:, 0]
    late = t >= 2.0 - 1e-9
    rms = float(np.sqrt(np.mean((tr["alpha"][late, 0] - cmd[late]) ** 2)))
    before = t <= on + 1e-9
    still = float(np.max(np.hypot(x[before] - x[0], y[before] - y[0])))
    i0, i1 = np.searchsorted(t, [2.0 - 1e-9, 4.0 - 1e-9])  # one whole gait period, long after the onset
    v = (x[i1] - x[i0]) / (t[i1] - t[i0])
    print(f"pymunk lone swimmer: RMS joint error {rms * 1e3:.2f} mrad, centre moved {still * 1e6:.3f} um "
          f"before the force, drift {v * 1e3:.4f} mm/s (F / N c = {F / (n * c) * 1e3:.4f}), "
          f"lateral {abs(y[-1] - y[0]) * 1e6:.3f} um")
    assert rms < 0.003  # MuJoCo: 0.9 mrad (README); pymunk measures 0.9 mrad
    assert still < 1e-6
    assert v == pytest.approx(F / (n * c), rel=1e-6)  # measured: 5e-11
    assert abs(y[-1] - y[0]) < 1e-6


def test_pymunk_and_mujoco_share_the_conventions():
    # Same lone swimmer, no force, in both engines: the centre-line nodes (head tip .. tail tip) must
    # coincide.  A flipped joint-angle sign, a head at +x or a phase error would put them centimetres
    # apart; the measured difference is 0.6 mm (MuJoCo's own 2 ms step against pymunk's 0.5 ms).
    sc = Scene(phases_rad=(0.3,), channel=Channel(width_m=2.0))
    tr = run_pair(sc, 4.0, timestep_s=0.0005, sample_rate_hz=20.0)
    ds = simulate(sc, SimOptions(duration_s=4.0, sample_rate_hz=20.0, record=("x", "y", "node_x", "node_y")))
    assert np.allclose(ds["time"].values, tr["time"])
    d = np.hypot(ds["node_x"].values - tr["node_x"], ds["node_y"].values - tr["node_y"])
    print(f"lone swimmer, MuJoCo vs pymunk: node distance max {d.max() * 1e3:.2f} mm")
    assert d.max() < 0.002


@pytest.mark.slow
@pytest.mark.parametrize("dphi", DPHIS, ids=lambda p: f"dphi={p / math.pi:+.2f}pi")
def test_pair_offset_agrees_between_mujoco_and_pymunk(dphi):
    sc = pair_scene(dphi)
    mj, dt = mujoco_steady_dx_over_lambda(sc)  # the package's current default step
    pm = steady_dx_over_lambda(run_pair(sc, 30.0), sc)
    print(f"dphi = {dphi / math.pi:+.2f} pi: MuJoCo {mj:+.4f} (dt {dt * 1e3:.3g} ms), pymunk {pm:+.4f}")
    if abs(abs(dphi) - math.pi) < 1e-9:
        # Mirror symmetry: reflecting y -> -y turns phase phi into phi + pi, so the (0, pi) pair started
        # straight at dx0 = 0 maps onto itself with dx -> -dx.  dx = +lambda/2 and -lambda/2 are mirror
        # images; rounding alone breaks the tie, and either engine may take either branch (both do,
        # depending on the step: docs/cross_engine.md).  Compare |dx| and require both on a branch.
        assert min(abs(mj), abs(pm)) > 0.4, "not on a +-lambda/2 branch"
        assert abs(abs(mj) - abs(pm)) < TOL
    else:
        assert abs(mj - pm) < TOL


@pytest.mark.slow
@pytest.mark.parametrize("sign", (+1, -1))
def test_antiphase_branch_follows_the_initial_offset_in_both_engines(sign):
    # The same dphi = pi pair with the symmetry broken by the start (dx0 = +-lambda/100, 5.4 mm): both
    # engines must then take the branch of the sign of dx0 and agree signed.
    sc = Scene(phases_rad=(0.0, math.pi), dx0_m=sign * 0.01 * pair_scene(0.0).wavelength_m)
    mj, _ = mujoco_steady_dx_over_lambda(sc)
    pm = steady_dx_over_lambda(run_pair(sc, 30.0), sc)
    print(f"dphi = pi, dx0 = {sign:+d} lambda/100: MuJoCo {mj:+.4f}, pymunk {pm:+.4f}")
    assert np.sign(mj) == np.sign(pm) == sign
    assert abs(mj - pm) < TOL
