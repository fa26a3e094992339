"""A scene's model as the runner needs it: the resolved options (time step, backend) and the
compiled scene with the chosen solver and integrator."""

from __future__ import annotations

import mujoco
import numpy as np

from ..errors import ParameterError
from ..params import Scene, SimOptions
from ..scene import CompiledScene, auto_timestep, build, servo_damping_rate_per_s, snap_timestep
from ._backend import check_backend

RK4_DAMPING_STEP = 1.0
"""``rate dt`` allowed for the servo damping under ``rk4`` (its real-axis stability limit is 2.79)."""


def resolve_options(scene: Scene, options: SimOptions) -> SimOptions:
    """``options`` with a concrete time step (the explicit one, or the
    time-step rule's, :func:`undulate.scene.auto_timestep`, for ``scene``) and
    a concrete backend and device (:func:`default_backend` where left out)."""
    options = check_backend(options)
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
    (:data:`undulate.scene.SERVO_MODELS`; the Warp backend steps ``"affine"``)."""
    options = resolve_options(scene, options)
    cs = build(scene, options.timestep_s, pair_sensors="contact_force_pair" in options.recorded, push=push,
               loads=loads, servo=servo)
    m = cs.model
    solver = options.solver
    if solver == "auto":  # Newton at any size: MuJoCo 3.17's sparse Newton is correct (docs/contact.md §5)
        solver = "newton"
    m.opt.solver = {"newton": mujoco.mjtSolver.mjSOL_NEWTON, "cg": mujoco.mjtSolver.mjSOL_CG,
                    "pgs": mujoco.mjtSolver.mjSOL_PGS}[solver]
    cs.model.opt.integrator = {
        "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
        "rk4": mujoco.mjtIntegrator.mjINT_RK4,
    }[options.integrator]
    return cs


def controls(cs: CompiledScene, t_s: np.ndarray) -> np.ndarray:
    """Open-loop control vectors at times ``t_s`` -> ``T x nu`` (see
    :meth:`~undulate.scene.CompiledScene.controls`)."""
    return cs.controls(t_s)
