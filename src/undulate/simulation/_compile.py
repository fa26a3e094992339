"""A scene's model as the runner needs it: the resolved options (time step, backend) and the
compiled scene with the chosen solver and integrator."""

from __future__ import annotations

import copy
import dataclasses
import functools

import mujoco
import numpy as np

from ..errors import ParameterError
from ..params import Scene, SimOptions
from ..scene import CompiledScene, auto_timestep, build, servo_damping_rate_per_s, snap_timestep
from ._backend import check_backend, lone_swimmers_backend

RK4_DAMPING_STEP = 1.0
"""``rate dt`` allowed for the servo damping under ``rk4`` (its real-axis stability limit is 2.79)."""


def resolve_options(scene: Scene, options: SimOptions) -> SimOptions:
    """``options`` with a concrete time step (the explicit one, or the
    time-step rule's, :func:`undulate.scene.auto_timestep`, for ``scene``) and
    a concrete backend and device (:func:`default_backend` where left out).  A scene of one swimmer
    asked of the Warp backend steps where :func:`lone_swimmers_backend` says (on a GPU: MuJoCo)."""
    options = check_backend(options)
    if (options.backend == "warp" and scene.n_swimmers == 1
            and lone_swimmers_backend(options.device) == "mujoco"):
        options = dataclasses.replace(options, backend="mujoco", device=None)
    if options.timestep_s is not None:
        return options
    dt = auto_timestep(scene)
    if options.integrator == "rk4":  # explicit in the servo damping too: resolve its decay
        dt = min(dt, snap_timestep(RK4_DAMPING_STEP / servo_damping_rate_per_s(scene)))
    try:
        return options.with_timestep(dt)
    except ParameterError as e:  # e.g. a sample rate above 1/dt
        raise ParameterError(e.name, f"{e.allowed} (automatic time step for this scene: {dt:g} s)",
                             e.got) from None


def compile_scene(scene: Scene, options: SimOptions, *, push: bool | None = None,
                  loads: bool | None = None, servo: str = "pid") -> CompiledScene:
    """Build the model for ``scene`` with the solver settings the runner needs
    (``options.timestep_s`` must be resolved: :func:`resolve_options`).
    ``push``: include the perturbation-force actuators (default: only if
    ``scene.forces_N`` is set; see :func:`undulate.scene.swimmer_spec`);
    ``loads``: servo-torque sensors for a closed-loop controller (default: if
    the scene's controller is closed-loop); ``servo``: how the servos are expressed
    (:data:`undulate.scene.SERVO_MODELS`; the Warp backend steps ``"affine"``).

    A scene's model does not depend on its gait phases (they enter only its controls), so scenes
    that differ only in them -- a sweep over phase lags -- compile once a process (the last
    :data:`MODEL_CACHE_SIZE` models); each call gets its own copy of the model (~0.2 ms against ~0.9
    ms for a pair's compile), which it may change (``tests/test_simulation.py``)."""
    options = resolve_options(scene, options)
    push = scene.forces_N is not None if push is None else push
    loads = scene.controller.closed_loop if loads is None else loads
    args = (options.timestep_s, "contact_force_pair" in options.recorded, push, loads, servo, options.solver,
            options.integrator)
    try:
        model, index = _cached_model(dataclasses.replace(scene, phases_rad=(0.0,) * scene.n_swimmers), *args)
    except TypeError:  # a scene that does not hash: compiled as it is
        model, index = _model(scene, *args)
    return CompiledScene(model=copy.copy(model), index=index, scene=scene)


MODEL_CACHE_SIZE = 64
"""Compiled models :func:`compile_scene` keeps per process (each in the solver settings asked for)."""


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
