"""Lone swimmers on the cores when the Warp backend is asked for (``UNDULATE_WARP_LONE_SWIMMERS``,
:func:`undulate.execution.lone_swimmers_engine`): on a GPU by default, here on Warp's CPU
device by setting it.  A routed run is the MuJoCo backend's run, bitwise, and says so; a scene of two
swimmers still steps on Warp; a sweep's identity records the rule, so its runs are never served
under the other rule."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest

from undulate import Scene, SimOptions
from undulate.errors import ParameterError
from undulate.params import Gait
from undulate.simulation import simulate, simulate_batch
from undulate.execution import cores_up_to, lone_swimmers_engine, usable_cpus

pytest.importorskip("warp", reason="the gpu extra (mujoco-warp, warp-lang) is not installed")
pytest.importorskip("mujoco_warp")

WARP = dict(backend="warp", device="cpu")
LONE_ENV, CORES_UP_TO_ENV = "UNDULATE_WARP_LONE_SWIMMERS", "UNDULATE_WARP_CORES_UP_TO"


def test_the_rule_is_the_cores_on_a_gpu_and_warp_on_its_cpu_device_unless_set(monkeypatch):
    monkeypatch.delenv(LONE_ENV, raising=False)
    assert lone_swimmers_engine("cuda") == "mujoco"
    assert lone_swimmers_engine("cpu") == "warp"
    monkeypatch.setenv(LONE_ENV, "warp")
    assert lone_swimmers_engine("cuda") == "warp"
    monkeypatch.setenv(LONE_ENV, "mujoco")
    assert lone_swimmers_engine("cpu") == "mujoco"
    monkeypatch.setenv(LONE_ENV, "gpu")
    with pytest.raises(ParameterError, match=LONE_ENV):
        lone_swimmers_engine("cpu")


def test_a_routed_lone_swimmer_is_the_mujoco_run_and_a_pair_still_steps_on_warp(monkeypatch):
    monkeypatch.setenv(LONE_ENV, "mujoco")
    opts = dict(duration_s=0.5, sample_rate_hz=50.0)
    lone = Scene(phases_rad=(0.0,))
    w, m = simulate(lone, SimOptions(**opts, **WARP)), simulate(lone, SimOptions(**opts))
    assert w.attrs["backend"] == "mujoco" and w.attrs["precision"] == "float64"
    np.testing.assert_array_equal(w["x"].values, m["x"].values)
    pair = simulate(Scene(phases_rad=(0.0, 1.0)), SimOptions(**opts, **WARP))
    assert pair.attrs["backend"] == "warp"
    monkeypatch.setenv(LONE_ENV, "warp")
    assert simulate(lone, SimOptions(**opts, **WARP)).attrs["backend"] == "warp"


def _rollout_threads(monkeypatch) -> list[int]:
    """The threads of every MuJoCo rollout made from now on (a list it fills)."""
    from undulate.simulation import _mujoco

    threads: list[int] = []
    real = _mujoco._WarmRollout.__init__

    def spy(self, models, nthread):
        threads.append(nthread)
        real(self, models, nthread)

    monkeypatch.setattr(_mujoco._WarmRollout, "__init__", spy)
    return threads


def test_a_routed_batch_steps_on_every_core_and_each_run_is_its_run_alone(monkeypatch):
    monkeypatch.setenv(LONE_ENV, "mujoco")
    threads = _rollout_threads(monkeypatch)
    scenes = [Scene(phases_rad=(0.0,), gait=dataclasses.replace(Gait(), amplitude_rad=a)) for a in (0.5, 0.8, 1.1)]
    opts = SimOptions(duration_s=0.5, sample_rate_hz=50.0)
    batch = simulate_batch(scenes, dataclasses.replace(opts, **WARP))
    assert threads == [min(3, usable_cpus())]
    for sc, ds in zip(scenes, batch):
        np.testing.assert_array_equal(ds["x"].values, simulate(sc, opts)["x"].values)


def test_a_sweeps_identity_records_the_rule_and_a_change_of_rule_recomputes(tmp_path, monkeypatch):
    from undulate.studies._runners import lone_swimmer
    from undulate.sweep import Grid, run_sweep

    fn = functools.partial(lone_swimmer, duration_s=6.5)  # the amplitude reads 3 periods of 2 s
    grid = Grid(points=[{"amplitude_rad": a} for a in (0.6, 0.8)], seed=0)
    monkeypatch.setenv("UNDULATE_BACKEND", "warp")
    monkeypatch.setenv("UNDULATE_DEVICE", "cpu")
    monkeypatch.delenv(LONE_ENV, raising=False)
    on_warp = run_sweep(fn, grid, tmp_path / "s", progress=False)
    assert on_warp.n_computed == 2
    assert "lone swimmers" not in on_warp.identity["backend"]
    monkeypatch.setenv(LONE_ENV, "mujoco")
    routed = run_sweep(fn, grid, tmp_path / "s", progress=False)
    assert routed.identity["backend"].startswith("warp cpu float32, lone swimmers on mujoco")
    assert routed.n_computed == 2 and routed.n_reused == 0 and routed.stale  # not the Warp runs
    monkeypatch.delenv("UNDULATE_BACKEND")
    monkeypatch.delenv("UNDULATE_DEVICE")
    on_mujoco = run_sweep(fn, grid, tmp_path / "m", workers=1, progress=False)
    for var in ("amplitude_m", "speed_m_s", "mean_joint_error_rad"):
        np.testing.assert_array_equal(routed.dataset[var].values, on_mujoco.dataset[var].values)


def test_the_small_batch_rule_is_one_scene_per_core_on_a_gpu_and_none_on_warps_cpu_device_unless_set(monkeypatch):
    monkeypatch.delenv(CORES_UP_TO_ENV, raising=False)
    assert cores_up_to("cuda") == usable_cpus() and cores_up_to("cuda:1") == usable_cpus()
    assert cores_up_to("cpu") == 0
    monkeypatch.setenv(CORES_UP_TO_ENV, "0")
    assert cores_up_to("cuda") == 0
    monkeypatch.setenv(CORES_UP_TO_ENV, "3")
    assert cores_up_to("cpu") == 3
    for bad in ("-1", "many", "2.5"):
        monkeypatch.setenv(CORES_UP_TO_ENV, bad)
        with pytest.raises(ParameterError, match=CORES_UP_TO_ENV):
            cores_up_to("cpu")


def test_a_batch_of_at_most_the_rules_scenes_is_the_mujoco_run_on_every_core_and_a_larger_one_steps_on_warp(
        monkeypatch):
    """A batch of two pairs with the rule at 2 steps on the cores (each run the MuJoCo backend's,
    bitwise, one thread per scene), a batch of three on Warp; a sweep's identity names the rule."""
    from undulate.sweep import backend_identity

    monkeypatch.setenv(CORES_UP_TO_ENV, "2")
    threads = _rollout_threads(monkeypatch)
    scenes = [Scene(phases_rad=(0.0, p)) for p in (0.5, 1.5, 2.5)]
    opts = SimOptions(duration_s=0.3, sample_rate_hz=50.0)
    two = simulate_batch(scenes[:2], dataclasses.replace(opts, **WARP))
    assert threads == [min(2, usable_cpus())]
    for sc, ds in zip(scenes, two):
        assert ds.attrs["backend"] == "mujoco"
        np.testing.assert_array_equal(ds["x"].values, simulate(sc, opts)["x"].values)
    three = simulate_batch(scenes, dataclasses.replace(opts, **WARP))
    assert {ds.attrs["backend"] for ds in three} == {"warp"}
    assert max(float(np.abs(a["x"].values - b["x"].values).max()) for a, b in zip(two, three)) < 1e-3
    monkeypatch.setenv("UNDULATE_BACKEND", "warp")
    monkeypatch.setenv("UNDULATE_DEVICE", "cpu")
    assert ", batches of up to 2 on mujoco (" in backend_identity()
    monkeypatch.setenv(CORES_UP_TO_ENV, "0")
    assert "batches of up to" not in backend_identity()
