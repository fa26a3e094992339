"""Typed sweep points: every runner refuses an unknown or mistyped key with one line naming it."""

import math

import pytest

from undulate.errors import ParameterError
from undulate.studies._points import GroupPoint, LonePoint, PackingPoint, PairPoint, SyncPoint
from undulate.studies._runners import group_point, lone_swimmer, pair_point, pair_scene
from undulate.studies.packing import packing_point
from undulate.studies.synchronization import free_frequency, pair_run


@pytest.mark.parametrize("runner, point", [
    (lambda p: group_point(p, 0, duration_s=0.1), {"dphi": 0.5}),  # a typo of dphi_rad
    (lambda p: pair_point(p, 0, duration_s=0.1), {"dx0": 0.1}),
    (lambda p: lone_swimmer(p, 0, duration_s=0.1), {"beta": 0.5}),
    (lambda p: packing_point(p, 0, amplitude_m=0.05, base_seed=0, duration_s=0.1), {"phi_max_rad": 1.0, "rho_tilde": 2.0,
                                                                        "draw": 0, "seed": 1}),
    (lambda p: pair_run(p, 0, duration_s=0.1), {"controller": "phase-oscillator", "dphi0": 1.0}),
    (lambda p: free_frequency(p, 0, duration_s=0.1), {"controller": "phase-oscillator", "n": 2}),
])
def test_every_runner_refuses_an_unknown_key_before_simulating(runner, point):
    with pytest.raises(ParameterError) as e:
        runner(point)
    assert e.value.name == "point"
    assert str(sorted(set(point) - {"phi_max_rad", "rho_tilde", "draw", "controller"})) in str(e.value)


def test_values_are_converted_and_checked_by_type():
    p = GroupPoint.of({"n_links": 5.0, "heading_guide": True, "dphi_rad": 1})
    assert (p.n_links, p.heading_guide, p.dphi_rad) == (5, True, 1.0)
    assert isinstance(p.dphi_rad, float) and isinstance(p.n_links, int)
    with pytest.raises(ParameterError, match="n_links"):
        GroupPoint.of({"n_links": 2.5})
    with pytest.raises(ParameterError, match="heading_guide"):
        GroupPoint.of({"heading_guide": "yes"})
    with pytest.raises(ParameterError, match="ground"):
        PairPoint.of({"ground": "mud"})
    with pytest.raises(ParameterError, match="drag_N_s_per_m"):
        PairPoint.of({"ground": "swimming", "drag_N_s_per_m": 1.0})
    with pytest.raises(ParameterError, match="rho_tilde"):
        PackingPoint.of({"phi_max_rad": 1.0, "rho_tilde": 0.0, "draw": 0})
    with pytest.raises(TypeError):  # a required field missing
        SyncPoint.of({})
    assert LonePoint.of({}).gait().amplitude_rad == pytest.approx(math.radians(45.0))


def test_points_build_the_same_scene_as_the_mapping_describes():
    sc = pair_scene({"d_over_2A": 1.2, "amplitude_m": 0.05, "dphi_rad": 0.5, "phi0_rad": 0.25,
                     "dx0_over_lambda": 0.1, "force_N": 0.2})
    assert sc.channel.width_m == pytest.approx(0.24)  # d per swimmer: W = 2 (d/2A) 2A
    assert sc.phases_rad == (0.25, 0.75)
    assert sc.dx0_m == pytest.approx((0.1 * sc.wavelength_m,))
    assert sc.forces_N == (-0.2, 0.2)
    with pytest.raises(ParameterError, match="d_over_2A"):
        pair_scene({"d_over_2A": 1.2})  # no amplitude anywhere
    parts = GroupPoint.of({"kp_Nm_per_rad": 3.0, "contact_timeconst_s": 0.01, "drag_N_s_per_m": 2.0}).model_parts()
    assert parts["servo"].kp_Nm_per_rad == 3.0
    assert parts["contact"].timeconst_s == 0.01
    assert parts["ground"].drag_N_s_per_m == 2.0
    assert GroupPoint.of({"contact_timeconst_s": 0.0}).model_parts() == {}  # 0: the default contact
