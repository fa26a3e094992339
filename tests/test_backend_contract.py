"""The rollout contract every engine keeps (:class:`undulate.simulation._engines.Backend`): MuJoCo, and
MuJoCo Warp on its CPU device, step the same scenes into Datasets of the same shapes, dtypes and time
axis, with the same physics (a lone swimmer's centre stays put under isotropic drag; a touching pair's
contact force is a non-negative magnitude that is felt), and agree with each other to the Warp
backend's float32 tolerance (tests/test_warp.py's).  Each scene runs once per engine (module fixtures):
on Warp's CPU device its kernels are compiled once per machine and cached (~/.cache/warp)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from undulate import Scene, SimOptions
from undulate.errors import ParameterError
from undulate.params import Channel
from undulate.simulation import Rollout, SampledRollout, backend, resolve_options, simulate, simulate_batch

ENGINES = {"mujoco": dict(backend="mujoco"), "warp-cpu": dict(backend="warp", device="cpu")}
PRECISION = {"mujoco": "float64", "warp-cpu": "float32"}
RATE_HZ = 50.0
PAIR = Scene(phases_rad=(0.0, math.pi / 2))
LONE = Scene(phases_rad=(0.3,), channel=Channel(width_m=1.0))  # walls far away: drag and servos only


def _engine(name: str) -> dict:
    if name == "warp-cpu":
        pytest.importorskip("warp", reason="the gpu extra (mujoco-warp, warp-lang) is not installed")
        pytest.importorskip("mujoco_warp")
    return ENGINES[name]


@pytest.fixture(scope="module", params=list(ENGINES))
def engine(request) -> str:
    return request.param


_RUNS: dict = {}


def _run(name: str, scene: Scene, duration_s: float):
    key = (name, scene, duration_s)
    if key not in _RUNS:
        _RUNS[key] = simulate(scene, SimOptions(duration_s=duration_s, sample_rate_hz=RATE_HZ, **_engine(name)))
    return _RUNS[key]


def test_a_rollout_has_the_same_shapes_dtypes_and_time_axis(engine):
    """The pair's Dataset: one sample at t = 0 and one per sample interval, every variable float64
    with the schema's dims, the clock exact multiples of the interval, and the engine named."""
    ds = _run(engine, PAIR, 0.5)
    ref = _run("mujoco", PAIR, 0.5)
    n = int(round(0.5 * RATE_HZ)) + 1
    assert ds.sizes["time"] == n and ds.sizes["swimmer"] == 2
    np.testing.assert_array_equal(ds["time"].values, np.round(np.arange(n) / RATE_HZ, 12))
    assert set(ds.data_vars) == set(ref.data_vars)
    for v in ds.data_vars:
        assert ds[v].dims == ref[v].dims and ds[v].shape == ref[v].shape, v
        assert ds[v].dtype == np.float64, v
        assert np.isfinite(ds[v].values).all(), v
    assert ds.attrs["backend"] == ENGINES[engine]["backend"] and ds.attrs["precision"] == PRECISION[engine]
    assert ds.attrs["end_state"].shape == ref.attrs["end_state"].shape
    assert ds.attrs["end_warmstart"].shape == ref.attrs["end_warmstart"].shape


def test_a_lone_swimmers_centre_stays_put_under_isotropic_drag(engine):
    """Internal torques and equal isotropic drag on equal links cannot move the centre of mass: over
    1 s (two gait periods, the start-up ramp included) it wobbles by less than 1 mm, as over 10 s on
    MuJoCo (tests/test_simulation.py), while the body itself bends through the gait."""
    ds = _run(engine, LONE, 1.0)
    assert ds.attrs["backend"] == ENGINES[engine]["backend"]  # Warp's CPU device steps lone swimmers itself
    drift = float(np.hypot(ds["x"] - ds["x"][0], ds["y"] - ds["y"][0]).max())
    assert drift < 1e-3
    assert float(np.abs(ds["joint_angle"]).max()) > 0.1  # rad: it does move
    assert float(ds["contact_force_wall"].max()) == 0.0 and float(ds["penetration"].max()) == 0.0


def test_a_touching_pairs_contact_force_is_non_negative_and_felt(engine):
    """The pair force is an interval mean of force magnitudes (N): never negative, zero at the start
    (the swimmers apart) and felt once they touch, with penetration within the contact model's 1 mm."""
    ds = _run(engine, PAIR, 1.0)
    f = ds["contact_force_pair"].values
    assert (f >= 0.0).all() and f[0].max() == 0.0
    assert f.max() > 0.1
    assert 0.0 <= float(ds["penetration"].min()) and float(ds["penetration"].max()) < 1e-3


def test_warp_on_the_cpu_agrees_with_mujoco():
    """The same pair on both engines: centres within 1 mm, joint angles within 2 mrad and contact forces
    within 5 % of their peak (float32 against float64, no DIAGEXACT on Warp: tests/test_warp.py's bounds)."""
    a, b = _run("mujoco", PAIR, 1.0), _run("warp-cpu", PAIR, 1.0)
    for v in ("x", "y"):
        assert float(np.abs(a[v].values - b[v].values).max()) < 1e-3, v
    assert float(np.abs(a["joint_angle"].values - b["joint_angle"].values).max()) < 2e-3
    fa, fb = a["contact_force_pair"].values, b["contact_force_pair"].values
    assert np.abs(fa - fb).max() < 0.05 * fa.max()


def test_engines_are_looked_up_by_name_and_prepare_rollouts():
    """One lookup by name; an unknown name is refused naming the engines; each engine prepares a
    compiled batch into a :class:`Rollout` (Warp's also reduces on the device: a SampledRollout)."""
    from undulate.simulation import compile_scene, resolve_options

    assert backend("mujoco") is backend("mujoco") and backend(None).name == "mujoco"
    with pytest.raises(ParameterError, match="backend"):
        backend("jax")
    for name in ENGINES:
        opts = resolve_options(PAIR, SimOptions(duration_s=0.1, **_engine(name)))
        eng = backend(opts.backend)
        assert eng.name == opts.backend and eng.attrs(opts)["precision"] == PRECISION[name]
        cs = eng.compile(PAIR, opts, push=False, loads=False)
        assert cs.model.nu == compile_scene(PAIR, opts).model.nu  # the host's layout: MuJoCo's servos
        runner = eng.prepare([cs, cs], opts)
        try:
            assert isinstance(runner, Rollout) and runner.warm.shape == (2, cs.model.nv)
            assert isinstance(runner, SampledRollout) == eng.reduces_on_device(closed_loop=False)
        finally:
            runner.close()


def test_each_scene_is_built_and_compiled_once(engine, monkeypatch):
    """A batch of scenes that differ in their channel (distinct models) builds and compiles each scene
    once, as its ``pid`` model (the host's layout: controls, FULLPHYSICS states with the servos' slew
    states), on either engine: Warp derives its device's affine-servo model from that compiled model
    (:func:`undulate.simulation._warp_servo.device_model`).  Planning, stepping and recording compile
    nothing more (counted at ``MjSpec.compile``, which every model comes from)."""
    import mujoco

    from undulate.simulation import _compile

    scenes = [Scene(phases_rad=(0.0, 1.0), channel=Channel(width_m=w)) for w in (0.13, 0.14)]
    opts = SimOptions(duration_s=0.1, **_engine(engine))
    _compile.clear_model_cache()
    builds: list[str] = []
    real = _compile.build
    monkeypatch.setattr(_compile, "build", lambda sc, *a, **k: (builds.append(k.get("servo", "pid")), real(sc, *a, **k))[1])
    for sc in scenes:  # the automatic time step's lone-swimmer model (kept a process) is not the scene's
        resolve_options(sc, opts)
    compiles = []
    compile_spec = mujoco.MjSpec.compile
    monkeypatch.setattr(mujoco.MjSpec, "compile", lambda spec, *a, **k: (compiles.append(1), compile_spec(spec, *a, **k))[1])
    simulate_batch(scenes, opts)
    assert builds == ["pid"] * len(scenes)
    assert len(compiles) == len(scenes)
