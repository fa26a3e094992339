"""A scene's model as the engines step it: compiled with the chosen solver and integrator, and kept
(scenes that differ only in their gait phases compile once a process).  The options are resolved by
the caller (:func:`undulate.simulation._resolve.resolve_options`); the engines choose how the servos
are expressed (:meth:`undulate.simulation._engines.Backend.compile`)."""

from __future__ import annotations

import copy
import dataclasses
import functools

import mujoco
import numpy as np

from ..params import Scene, SimOptions
from ..scene import CompiledScene, build

__all__ = ["compiled_model", "clear_model_cache", "controls", "MODEL_CACHE_SIZE"]


def compiled_model(scene: Scene, options: SimOptions, *, push: bool, loads: bool,
                   servo: str = "pid") -> CompiledScene:
    """The model of ``scene`` under resolved ``options`` (its time step, solver and integrator;
    ``pair_sensors`` where ``contact_force_pair`` is recorded), with the perturbation-force actuators
    if ``push``, servo-torque sensors if ``loads`` and the servos expressed as ``servo``
    (:data:`undulate.scene.SERVO_MODELS`).

    A scene's model does not depend on its gait phases (they enter only its controls), so scenes
    that differ only in them -- a sweep over phase lags -- compile once a process (the last
    :data:`MODEL_CACHE_SIZE` models); each call gets its own copy of the model (~0.2 ms against ~0.9
    ms for a pair's compile), which it may change (``tests/test_simulation.py``)."""
    args = (options.timestep_s, "contact_force_pair" in options.recorded, push, loads, servo, options.solver,
            options.integrator)
    try:
        model, index = _cached_model(dataclasses.replace(scene, phases_rad=(0.0,) * scene.n_swimmers), *args)
    except TypeError:  # a scene that does not hash: compiled as it is
        model, index = _model(scene, *args)
    return CompiledScene(model=copy.copy(model), index=index, scene=scene)


MODEL_CACHE_SIZE = 64
"""Compiled models :func:`compiled_model` keeps per process (each in the solver settings asked for)."""


def _model(scene: Scene, timestep_s: float, pair_sensors: bool, push: bool, loads: bool, servo: str,
           solver: str, integrator: str) -> tuple[mujoco.MjModel, object]:
    cs = build(scene, timestep_s, pair_sensors=pair_sensors, push=push, loads=loads, servo=servo)
    m = cs.model
    if solver == "auto":  # Newton at any size: MuJoCo 3.17's sparse Newton is correct (docs/contact.md §5)
        solver = "newton"
    m.opt.solver = {"newton": mujoco.mjtSolver.mjSOL_NEWTON, "cg": mujoco.mjtSolver.mjSOL_CG,
                    "pgs": mujoco.mjtSolver.mjSOL_PGS}[solver]
    m.opt.integrator = {
        "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
        "rk4": mujoco.mjtIntegrator.mjINT_RK4,
    }[integrator]
    return m, cs.index


def clear_model_cache() -> None:
    """Forget the models :func:`compile_scene` keeps (for code that changes how models are built at
    run time: tests that patch the model builder)."""
    _cached_model.cache_clear()


@functools.lru_cache(maxsize=MODEL_CACHE_SIZE)
def _cached_model(*args) -> tuple[mujoco.MjModel, object]:
    """:func:`_model`, kept: its model is only ever handed out as a copy, and its index (shared by
    every call) is read-only."""
    model, index = _model(*args)
    for f in dataclasses.fields(index):
        v = getattr(index, f.name)
        if isinstance(v, np.ndarray):
            v.flags.writeable = False
    return model, index


def controls(cs: CompiledScene, t_s: np.ndarray) -> np.ndarray:
    """Open-loop control vectors at times ``t_s`` -> ``T x nu`` (see
    :meth:`~undulate.scene.CompiledScene.controls`)."""
    return cs.controls(t_s)
