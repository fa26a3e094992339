"""Why xi = 3/2 pairs of three-link swimmers cannot follow the compatibility line: a symmetry.

With N links the joint phase offsets are 2 pi xi i / N (i = 0..N-2).  For N = 3 and
xi = 3/2 they are 0 and pi: the two joints move in exact antiphase, alpha_1 = -alpha_0,
so the body's shape at time t + T/2 is the mirror image of its shape at t and the wave
has no direction -- there is no travelling wave whose phase a neighbour could match.  A
body with N = 4 links (offsets 0, 3 pi/4, 3 pi/2) carries a travelling wave at the same xi.
"""

from __future__ import annotations

import numpy as np

from undulate import Gait


def _joint_phase_offsets(gait: Gait, n_links: int) -> np.ndarray:
    """Each joint's phase offset (rad) read off the set-points themselves: alpha_i(t) =
    beta sin(offset_i - 2 pi f t)  ->  offset_i = angle of the complex amplitude over a period."""
    t = np.linspace(0, gait.period_s, 400, endpoint=False)
    a = gait.joint_angles(t, [0.0], n_links)[:, 0, :]  # (T, joints)
    z = (a * np.exp(1j * 2 * np.pi * gait.frequency_hz * t)[:, None]).mean(axis=0)  # ~ (beta / 2i) e^{i offset}
    return np.angle(z * 2j / gait.amplitude_rad)


def test_three_links_at_xi_three_halves_move_their_joints_in_exact_antiphase():
    g = Gait(waves_per_body=1.5)
    t = np.linspace(0, 4, 1001)
    a = g.joint_angles(t, [0.3], 3)[:, 0, :]
    np.testing.assert_allclose(a[:, 1], -a[:, 0], atol=1e-12)  # alpha_1 = -alpha_0: a standing wave
    off = _joint_phase_offsets(g, 3)
    np.testing.assert_allclose(np.abs(np.angle(np.exp(1j * (off[1] - off[0])))), np.pi, atol=1e-9)


def test_the_same_wave_travels_on_four_links():
    g = Gait(waves_per_body=1.5)
    off = _joint_phase_offsets(g, 4)
    steps = np.angle(np.exp(1j * np.diff(off)))
    np.testing.assert_allclose(np.abs(steps), 3 * np.pi / 4, atol=1e-9)  # neither 0 nor pi: a direction
    a = g.joint_angles(np.linspace(0, 4, 1001), [0.0], 4)[:, 0, :]
    assert not np.allclose(a[:, 1], -a[:, 0], atol=1e-3) and not np.allclose(a[:, 1], a[:, 0], atol=1e-3)


def test_xi_one_on_three_links_is_a_travelling_wave():
    off = _joint_phase_offsets(Gait(waves_per_body=1.0), 3)
    np.testing.assert_allclose(np.abs(np.angle(np.exp(1j * (off[1] - off[0])))), 2 * np.pi / 3, atol=1e-9)


def test_eight_links_carry_a_travelling_wave_at_xi_three_halves():
    """The N the sensitivity study uses to show the cause: joint steps 2 pi xi / N = 3 pi / 8,
    neither 0 nor pi, and no joint is the mirror (or copy) of its neighbour."""
    g = Gait(waves_per_body=1.5)
    off = _joint_phase_offsets(g, 8)
    steps = np.angle(np.exp(1j * np.diff(off)))
    np.testing.assert_allclose(np.abs(steps), 3 * np.pi / 8, atol=1e-9)
    a = g.joint_angles(np.linspace(0, 4, 1001), [0.0], 8)[:, 0, :]
    for i in range(a.shape[1] - 1):
        assert not np.allclose(a[:, i + 1], -a[:, i], atol=1e-3) and not np.allclose(a[:, i + 1], a[:, i], atol=1e-3)
