"""Physics and engineering invariants of the core simulator (real MuJoCo runs)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import xarray as xr

from undulate import (
    Channel,
    ContactModel,
    DivergenceError,
    Gait,
    Scene,
    SimOptions,
    SwimmerGeometry,
    gait_amplitude,
    neighbour_offsets,
    simulate,
    simulate_batch,
)
from undulate.observables import period_average
from undulate.params import ControllerParams
from undulate.scene import build, root_link
from undulate.simulation import compile_scene, controls, resolve_options

WIDE = Channel(width_m=2.0)


def _data_vars_identical(a: xr.Dataset, b: xr.Dataset) -> None:
    for name in a.data_vars:
        np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


def test_lone_swimmer_tracks_gait_and_its_centre_does_not_drift():
    ds = simulate(Scene(phases_rad=(0.3,), channel=WIDE), SimOptions(duration_s=10.0, sample_rate_hz=50))
    # tracking: after the start-up ramp the servo follows the gait closely
    err = ds["joint_error"].sel(time=slice(2.0, None))
    rms = float(np.sqrt((err**2).mean()))
    print(f"lone swimmer RMS joint error {rms:.2e} rad")
    assert rms < 5e-3
    # internal torques + equal isotropic drag on equal links: the centre of mass only wobbles
    drift = float(np.hypot(ds["x"] - ds["x"][0], ds["y"] - ds["y"][0]).max())
    print(f"lone swimmer centre excursion over 10 s: {drift * 1e3:.3f} mm")
    assert drift < 1e-3
    # no contact anywhere
    assert float(ds["contact_force_wall"].max()) == 0.0
    assert float(ds["penetration"].max()) == 0.0


def _drift_rate(dt, integrator="implicitfast", n_links=3) -> float:
    """Speed of the period-averaged centre of mass of a lone swimmer over 20 s, m/s."""
    sc = Scene(phases_rad=(0.3,), channel=WIDE, geometry=SwimmerGeometry(n_links=n_links))
    ds = simulate(sc, SimOptions(duration_s=20.0, timestep_s=dt, integrator=integrator, sample_rate_hz=50))
    px = period_average(ds["x"].isel(swimmer=0), sc.gait.period_s).values
    py = period_average(ds["y"].isel(swimmer=0), sc.gait.period_s).values
    return float(np.hypot(px[-1] - px[0], py[-1] - py[0]) / (sc.gait.period_s * (len(px) - 1)))


def test_lone_swimmer_centre_stays_still_at_the_defaults():
    # internal torques + equal isotropic drag cannot move the centre of mass. Rooted at its head, the
    # first-order position update crept 0.28 mm/s at 2 ms (O(dt)); rooted at the middle link it must not
    v2, v1 = _drift_rate(None), _drift_rate(0.001)
    rk = _drift_rate(None, "rk4")  # the rule's step for rk4 (it resolves the servo damping)
    print(f"lone swimmer drift: 2 ms {v2 * 1e3:.4f} mm/s, 1 ms {v1 * 1e3:.4f} mm/s, rk4 {rk * 1e3:.4f} mm/s")
    assert v2 <= 0.05e-3
    assert v1 <= 0.05e-3 and rk <= 0.05e-3
    for n in (2, 4, 5, 12):  # the root at the body's midpoint: a link's centre (odd N) or a joint (even N)
        assert _drift_rate(None, n_links=n) <= 0.05e-3


def test_recorded_nodes_are_mujocos_links():
    # the centre line reconstructed from (root pose, joint angles) puts every link's midpoint where
    # MuJoCo has the link's centre of mass, for a body rooted at its middle link (4 links: root link 1)
    sc = Scene(phases_rad=(0.0, 2.0), dx0_m=0.05, geometry=SwimmerGeometry(n_links=4))
    opt = resolve_options(sc, SimOptions(duration_s=1.0, sample_rate_hz=50))
    ds = simulate(sc, opt)
    nx, ny = ds["node_x"].values, ds["node_y"].values
    L = sc.geometry.length_m
    np.testing.assert_allclose(nx[0, :, 0], sc.initial_x_m() - L / 2, atol=1e-12)  # head tips at the start
    np.testing.assert_allclose(np.hypot(np.diff(nx, axis=-1), np.diff(ny, axis=-1)), L / 4, atol=1e-12)
    cs = compile_scene(sc, opt)
    m, d = cs.model, mujoco.MjData(cs.model)
    mujoco.mj_forward(m, d)
    links = [[m.body(f"s{j}_link{k}").id for k in range(4)] for j in range(2)]
    u = controls(cs, np.arange(opt.n_steps) * opt.timestep_s)
    for k in range(opt.n_steps):
        d.ctrl[:] = u[k]
        mujoco.mj_step(m, d)
    mujoco.mj_kinematics(m, d)
    mid_x, mid_y = 0.5 * (nx[-1, :, 1:] + nx[-1, :, :-1]), 0.5 * (ny[-1, :, 1:] + ny[-1, :, :-1])
    np.testing.assert_allclose(mid_x, d.xipos[links, 0], atol=1e-12)
    np.testing.assert_allclose(mid_y, d.xipos[links, 1], atol=1e-12)


def test_constant_force_gives_drift_velocity_F_over_total_drag():
    F = 0.3  # N
    sc = Scene(phases_rad=(0.0,), channel=WIDE, forces_N=(F,))
    ds = simulate(sc, SimOptions(duration_s=6.0, integrator="rk4"))
    pa = period_average(ds["x"].isel(swimmer=0), sc.gait.period_s).values
    v = (pa[-1] - pa[-2]) / sc.gait.period_s  # velocity, long after the 0.05 s relaxation
    expected = F / (sc.geometry.n_links * sc.ground.drag_N_s_per_m)
    assert v == pytest.approx(expected, rel=1e-3)
    # spread equally over the links, the force translates the body without turning it
    turn = period_average(ds["heading"].isel(swimmer=0), sc.gait.period_s).values
    assert abs(turn[-1] - turn[0]) < 0.01  # rad over the run (applied at the head tip it turned ~1 rad)


def test_contact_forces_vanish_while_swimmers_are_apart():
    sc = Scene(phases_rad=(0.0, math.pi), channel=WIDE, lateral_gap_m=0.4)
    ds = simulate(sc, SimOptions(duration_s=6.0))
    assert float(ds["contact_force_pair"].max()) == 0.0
    assert float(ds["penetration"].max()) == 0.0
    # and they stay where they were, laterally
    assert float(np.abs(ds["y"] - ds["y"][0]).max()) < 1e-3  # O(dt) creep only


def test_walls_keep_every_swimmer_inside_and_contact_is_shallow():
    sc = Scene(phases_rad=(0.0, math.pi / 2))
    ds = simulate(sc, SimOptions(duration_s=30.0))
    # centre lines stay inside the walls, centres of mass at least half a width away
    assert float(np.abs(ds["node_y"]).max()) < sc.channel.width_m / 2
    assert float(np.abs(ds["y"]).max()) < sc.channel.width_m / 2 - sc.geometry.width_m / 2
    steady = ds["penetration"].sel(time=slice(10, None))
    startup = ds["penetration"].sel(time=slice(0, 2))
    print(f"penetration: start-up max {float(startup.max()) * 1e3:.2f} mm, steady max {float(steady.max()) * 1e3:.3f} mm")
    assert float(steady.max()) < 1e-3
    assert float(startup.max()) < 5e-3
    # they touch each other and the walls
    assert float(ds["contact_force_pair"].max()) > 0
    assert float(ds["contact_force_wall"].max()) > 0


def test_rollout_path_equals_plain_mj_step_loop_exactly():
    sc = Scene(phases_rad=(0.0, 2.0), dx0_m=0.05)
    opt = SimOptions(duration_s=1.5, sample_rate_hz=100, chunk_steps=137)  # chunks not aligned with anything
    ds = simulate(sc, opt)
    opt = resolve_options(sc, opt)
    cs = compile_scene(sc, opt)
    m, d = cs.model, mujoco.MjData(cs.model)
    mujoco.mj_forward(m, d)
    sps = opt.steps_per_sample
    n = (len(ds["time"]) - 1) * sps
    u = controls(cs, np.arange(n) * opt.timestep_s)
    joints = [d.qpos[cs.index.qpos_joint].copy()]
    root = [cs.model.body(f"s{j}_link{root_link(sc.geometry.n_links)}").id for j in range(sc.n_swimmers)]

    def com_now():  # subtree centre of mass at the current state (after the step)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        return d.subtree_com[root, :2].copy()

    coms = [com_now()]
    for k in range(n):
        d.ctrl[:] = u[k]
        mujoco.mj_step(m, d)
        if (k + 1) % sps == 0:
            joints.append(d.qpos[cs.index.qpos_joint].copy())
            coms.append(com_now())
    np.testing.assert_array_equal(ds["joint_angle"].values, np.array(joints))
    np.testing.assert_allclose(ds["x"].values, np.array(coms)[..., 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ds["y"].values, np.array(coms)[..., 1], rtol=0, atol=1e-12)


def test_identical_inputs_give_identical_output_and_batch_equals_single():
    a = Scene(phases_rad=(0.0, 1.0))
    b = Scene(phases_rad=(0.0, -2.0), dx0_m=0.1)
    opt = SimOptions(duration_s=3.0)
    one, two = simulate(a, opt), simulate(a, opt)
    _data_vars_identical(one, two)
    assert one.attrs["config"] == two.attrs["config"]
    batch = simulate_batch([a, b], opt, nthread=2)
    _data_vars_identical(batch[0], one)
    _data_vars_identical(batch[1], simulate(b, opt))
    # a batch mixing scenes with and without perturbation forces compiles all of them with the
    # push actuators (one structure); unused ones carry zero force and change nothing
    c = Scene(phases_rad=(0.0, 1.0), forces_N=(-0.05, 0.05), force_onset_s=1.0)
    mixed = simulate_batch([a, c], opt)
    _data_vars_identical(mixed[0], one)
    _data_vars_identical(mixed[1], simulate(c, opt))
    assert float(np.abs(mixed[1]["x"] - one["x"]).max()) > 1e-3  # the force did act


def _final_dx_over_lambda(dt: float) -> float:
    sc = Scene(phases_rad=(0.0, math.pi / 2), gait=Gait(waves_per_body=1.0), channel=Channel(width_m=0.13))
    ds = simulate(sc, SimOptions(duration_s=30.0, timestep_s=dt))
    off = neighbour_offsets(ds)
    last = ds["time"] >= ds["time"][-1] - sc.gait.period_s
    return float(off["dx"].where(last).mean()) / sc.wavelength_m


def test_pair_at_quarter_phase_ends_near_compatibility_and_converges_in_dt():
    r2, r1 = _final_dx_over_lambda(0.002), _final_dx_over_lambda(0.001)
    print(f"dx/lambda at dt=2 ms: {r2:.4f}; 1 ms: {r1:.4f}; compatibility 0.25")
    assert abs(r1 - 0.25) < 0.06  # positive slope, near the line (3-link shape error ~0.035)
    assert abs(r2 - r1) < 0.005


@pytest.mark.slow
def test_pair_converges_as_time_step_halves_three_levels():
    r = [_final_dx_over_lambda(dt) for dt in (0.002, 0.001, 0.0005)]
    print("dx/lambda vs dt 2, 1, 0.5 ms:", r)
    assert abs(r[2] - r[1]) <= abs(r[1] - r[0]) + 1e-4
    assert abs(r[2] - r[1]) < 0.003


def test_divergence_stops_with_a_diagnosis():
    sc = Scene(phases_rad=(0.0, math.pi), contact=ContactModel(max_penetration_m=1e-5))
    with pytest.raises(DivergenceError, match="time step"):
        simulate(sc, SimOptions(duration_s=5.0))


def test_gait_amplitude_of_a_free_swimmer_grows_with_beta():
    amps = []
    for beta in (30, 45, 60):
        sc = Scene(phases_rad=(0.0,), channel=WIDE, gait=Gait(amplitude_rad=math.radians(beta)))
        amps.append(gait_amplitude(simulate(sc, SimOptions(duration_s=6.0, sample_rate_hz=100))))
    print("A(beta=30,45,60) =", amps)
    assert 0 < amps[0] < amps[1] < amps[2] < 0.27


def _lone_speed(ground) -> float:
    sc = Scene(phases_rad=(0.0,), channel=WIDE, ground=ground)
    ds = simulate(sc, SimOptions(duration_s=12.0))
    pa = period_average(ds["x"].isel(swimmer=0), sc.gait.period_s).values
    return float((pa[-1] - pa[-4]) / (3 * sc.gait.period_s))


def test_swimming_mode_advances_head_first_default_mode_does_not():
    from undulate import Ground

    swim, still = _lone_speed(Ground.swimming()), _lone_speed(Ground())
    print(f"lone swimmer speed: swimming {swim * 1e3:.2f} mm/s, viscous ground {still * 1e3:.3f} mm/s")
    assert swim < -5e-3  # heads point to -x: head first is -x, at > 5 mm/s
    assert abs(still) < 5e-5  # the centre of mass stays put
    assert abs(swim) > 10 * abs(still)


def test_jammed_fifty_swimmer_pack_runs_without_solver_blow_up():
    # phi_max = 2 pi at rho~ = 3: far above the packing threshold (MuJoCo's sparse Newton blew up here)
    rng = np.random.default_rng(0)
    n, A = 50, 0.0525
    Y = 2 * A * n / 3.0
    sc = Scene(phases_rad=tuple(rng.uniform(0, 2 * np.pi, n)), channel=Channel(width_m=Y, end_walls_m=1.1 * 0.54),
               lateral_gap_m=Y / n - 0.015 * (1 + 1e-6))
    ds = simulate(sc, SimOptions(duration_s=4.0, sample_rate_hz=5))
    assert float(ds["joint_error"].mean()) > 0.01  # jammed: the servos are held off their gait
    pen = float(ds["penetration"].sel(time=slice(1, None)).max())
    print(f"jammed pack: mean joint error {float(ds['joint_error'].mean()):.3f} rad, penetration {pen * 1e3:.1f} mm")
    assert pen < sc.contact.max_penetration_m  # soft contact yields under the squeeze, but holds


def test_top_level_simulate_is_the_function_even_after_importing_the_module():
    import importlib

    importlib.import_module("undulate.simulation")
    import undulate

    assert callable(undulate.simulate) and undulate.simulate.__name__ == "simulate"


def test_scene_round_trips_through_a_dict_and_rejects_unknown_keys():
    from undulate.errors import ParameterError
    from undulate.params import ControllerParams, Scene

    sc = Scene(phases_rad=(0.0, 1.0, 2.0), controller=ControllerParams(kind="phase-oscillator"))
    assert Scene.from_dict(sc.to_dict()) == sc
    d = sc.to_dict()
    d["gait"]["wavelength_m"] = 0.3  # a misspelt or foreign field must not be dropped silently
    with pytest.raises(ParameterError, match="Gait.wavelength_m"):
        Scene.from_dict(d)


@pytest.mark.parametrize("kw", [
    {},
    {"dx0_m": (0.01, -0.02), "lateral_gap_m": 0.001},
    {"heading_guide": True},
    {"hold_x": True},
    {"forces_N": (0.1, 0.0, -0.1), "force_onset_s": 1.0},
    {"controller": ControllerParams(kind="phase-oscillator", coupling=1.0)},
    {"gait": Gait(waves_per_body=1.5), "geometry": SwimmerGeometry(n_links=6)},
])
@pytest.mark.parametrize("servo", ["pid", "affine"])
def test_a_scenes_model_does_not_depend_on_its_gait_phases(kw, servo):
    """What compile_scene's model cache rests on: scenes that differ only in their phases have the
    same model (the phases enter only the controls), in every kind of scene; and each call gets its
    own copy, with a read-only index, whose changes never reach the next call's model."""
    from undulate.scene import scene_spec

    a, b = (Scene(phases_rad=p, **kw) for p in ((0.0, 1.0, 2.5), (0.3, -2.0, 6.0)))
    assert scene_spec(a, 1e-3, servo=servo)[0].to_xml() == scene_spec(b, 1e-3, servo=servo)[0].to_xml()
    opt = resolve_options(a, SimOptions(duration_s=0.2))
    ca = compile_scene(a, opt, servo=servo)
    ca.model.opt.timestep = 0.5
    ca.model.geom_size[:] = 1.0
    cb = compile_scene(b, opt, servo=servo)
    assert cb.scene is b and cb.model is not ca.model
    fresh = build(b, opt.timestep_s, servo=servo)
    assert cb.model.opt.timestep == opt.timestep_s
    np.testing.assert_array_equal(cb.model.geom_size, fresh.model.geom_size)
    with pytest.raises(ValueError):
        cb.index.ctrl_pos[...] = 0
    np.testing.assert_array_equal(cb.controls(np.arange(3) * 0.05), fresh.controls(np.arange(3) * 0.05))


def test_runs_with_cached_models_are_bitwise_those_compiled_afresh():
    """A sweep over phase lags in one process: every run after the first takes the cached model, and
    each is bitwise the run of a model compiled for it alone."""
    from undulate.simulation._compile import clear_model_cache

    opt = SimOptions(duration_s=0.5, sample_rate_hz=20.0)
    warm = [simulate(Scene(phases_rad=(0.0, d)), opt) for d in (0.4, 1.1, 2.9)]
    for d, w in zip((0.4, 1.1, 2.9), warm):
        clear_model_cache()
        cold = simulate(Scene(phases_rad=(0.0, d)), opt)
        for v in ("x", "y", "joint_angle", "contact_force_pair", "penetration"):
            np.testing.assert_array_equal(w[v].values, cold[v].values)
