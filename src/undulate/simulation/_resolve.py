"""A scene's options resolved for a run (time step, backend, device), and its model compiled under
them (:func:`compile_scene`, the public entry; the engines compile through
:func:`undulate.simulation._compile.compiled_model`)."""

from __future__ import annotations

from ..errors import ParameterError
from ..params import Scene, SimOptions
from ..scene import CompiledScene, auto_timestep, servo_damping_rate_per_s, snap_timestep
from ._backend import check_backend, on_cores
from ._compile import compiled_model

__all__ = ["resolve_options", "compile_scene", "RK4_DAMPING_STEP"]

RK4_DAMPING_STEP = 1.0
"""``rate dt`` allowed for the servo damping under ``rk4`` (its real-axis stability limit is 2.79)."""


def resolve_options(scene: Scene, options: SimOptions) -> SimOptions:
    """``options`` with a concrete time step (the explicit one, or the
    time-step rule's, :func:`undulate.scene.auto_timestep`, for ``scene``) and
    a concrete backend and device (:func:`default_backend` where left out).  A scene of one swimmer
    asked of the Warp backend steps where :func:`undulate.execution.lone_swimmers_engine` says (on a GPU: MuJoCo)."""
    options = on_cores(check_backend(options), n_swimmers=scene.n_swimmers)
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
    (``options`` resolved here: :func:`resolve_options`).
    ``push``: include the perturbation-force actuators (default: only if
    ``scene.forces_N`` is set; see :func:`undulate.scene.swimmer_spec`);
    ``loads``: servo-torque sensors for a closed-loop controller (default: if
    the scene's controller is closed-loop); ``servo``: how the servos are expressed
    (:data:`undulate.scene.SERVO_MODELS`; the Warp backend's device model steps ``"affine"``).
    Models are kept per process: :func:`undulate.simulation._compile.compiled_model`."""
    options = resolve_options(scene, options)
    push = scene.forces_N is not None if push is None else push
    loads = scene.controller.closed_loop if loads is None else loads
    return compiled_model(scene, options, push=push, loads=loads, servo=servo)
