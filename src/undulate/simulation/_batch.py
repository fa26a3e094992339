"""A batch planned for stepping: its scenes checked, its time step resolved, its scenes compiled by
the engine that steps them, and its chunk length chosen (:class:`_Batch`, :func:`_plan_batch`)."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from ..control import Controller, make_controller
from ..errors import DivergenceError, ParameterError
from ..params import Scene, SimOptions
from ..scene import CompiledScene
from ._backend import on_cores
from ._engines import backend
from ._record import _check_chunk_fits, _check_fits, _outs
from ._resolve import resolve_options

_HUGE = 1e6  # |state entry| beyond this (m, rad, m/s, rad/s) means the integration blew up


def _check_same_structure(compiled: Sequence[CompiledScene]) -> None:
    ref = compiled[0].model
    for c in compiled[1:]:
        m = c.model
        if (m.nq, m.nv, m.nu, m.na, m.nsensordata, m.ngeom) != (ref.nq, ref.nv, ref.nu, ref.na, ref.nsensordata, ref.ngeom):
            raise ParameterError(
                "scenes", "of one structure in a batch (same swimmers, links and walls)", None
            )


def _diagnose(cs: CompiledScene, options: SimOptions, t: float, what: str) -> DivergenceError:
    tc = cs.model.geom_solref[0, 0]
    return DivergenceError(
        f"simulation diverged at t = {t:.3f} s: {what}. Likely cause: the time step "
        f"({options.timestep_s:g} s) is too large for the contact stiffness "
        f"(time constant {tc:g} s) or servo gains, or the constraint solver failed to converge; "
        f"try a smaller --timestep, a softer contact (larger timeconst_s) or another solver "
        f"(SimOptions.solver = 'cg' or 'pgs')."
    )


class _Clock:
    """Physics time of one :func:`simulate_batch` call: wall seconds inside ``mujoco.rollout`` and
    scene-steps taken there (reported to the open meters, :func:`undulate._walltime.report`, when the
    call ends)."""

    def __init__(self):
        self.seconds, self.steps = 0.0, 0

    def rollout(self, runner, nb: int, n_steps: int, *args, **kwargs):
        t0 = time.perf_counter()
        out = runner.rollout(*args, **kwargs)
        self.seconds += time.perf_counter() - t0
        active = kwargs.get("active")
        self.steps += (nb if active is None else int(active.sum())) * n_steps
        return out


@dataclass
class _Batch:
    """A batch of compiled scenes and everything resolved about how to step and record them."""

    compiled: list
    options: SimOptions
    requested: SimOptions
    outs: list | None
    ctl: Controller | None
    tick: int
    chunk: int
    n_samples: int

    @property
    def m0(self) -> mujoco.MjModel:
        return self.compiled[0].model

    @property
    def nb(self) -> int:
        return len(self.compiled)

    @property
    def dt(self) -> float:
        return self.options.timestep_s

    @property
    def sps(self) -> int:
        return self.options.steps_per_sample


def _check_scenes(scenes, options) -> None:
    """Refuse a batch that is not a non-empty sequence of Scene, or options that are not SimOptions."""
    if options is not None and not isinstance(options, SimOptions):
        raise ParameterError("options", "a SimOptions or None", type(options).__name__)
    if isinstance(scenes, (Scene, str, bytes)) or not isinstance(scenes, Sequence):
        raise ParameterError("scenes", "a non-empty sequence of Scene", type(scenes).__name__)
    if len(scenes) == 0:
        raise ParameterError("scenes", "a non-empty sequence of Scene", scenes)
    wrong = [type(s).__name__ for s in scenes if not isinstance(s, Scene)]
    if wrong:
        raise ParameterError("scenes", "a non-empty sequence of Scene", f"an item of type {wrong[0]}")


def _plan_batch(scenes: Sequence[Scene], options: SimOptions | None, out, controller,
                compiled: dict[int, tuple] | None = None) -> _Batch:
    """Validate a batch, resolve its time step and engine, compile its scenes the engine's way
    (:meth:`undulate.simulation._engines.Backend.compile`, once each) and choose its chunk length.
    ``compiled``: ``{index: (push, CompiledScene)}`` of scenes already compiled by the same rule (a
    gathered batch's grouping, :func:`undulate.simulation._gather._gather_groups`), used where their
    ``push`` is the batch's and the batch is open-loop (closed-loop batches compile servo-load sensors).
    ``scenes`` and ``options`` are :func:`simulate_batch`'s, checked there (:func:`_check_scenes`)."""
    options = options or SimOptions()
    requested = options
    resolved = [resolve_options(s, options) for s in scenes]
    if len({o.timestep_s for o in resolved}) > 1:
        raise ParameterError("scenes", "of one time step in a batch (same links and servo, or an "
                             "explicit SimOptions.timestep_s)", sorted({o.timestep_s for o in resolved}))
    options = on_cores(resolved[0], n_scenes=len(scenes))  # a small batch asked of Warp: the cores
    engine = backend(options.backend)
    outs = _outs(out, len(scenes))
    push = any(s.forces_N is not None for s in scenes)  # one structure: all or none carry them
    closed = controller is not None or scenes[0].controller.closed_loop
    if closed and any((s.gait, s.controller, s.geometry.n_links) != (scenes[0].gait, scenes[0].controller,
                                                                   scenes[0].geometry.n_links) for s in scenes):
        raise ParameterError("scenes", "of one gait, controller and link count in a closed-loop batch", None)
    done = {} if closed or compiled is None else {i: cs for i, (p, cs) in compiled.items() if p == push}
    compiled = [done.get(i) or engine.compile(s, options, push=push, loads=closed) for i, s in enumerate(scenes)]
    _check_same_structure(compiled)
    dt, sps = options.timestep_s, options.steps_per_sample
    n_samples = options.n_steps // sps
    if n_samples < 1:
        raise ParameterError("duration_s", f">= one sample interval ({sps * dt:g} s)", options.duration_s)
    _check_fits(compiled, options.recorded, n_samples, outs)
    ctl, tick = None, 0
    if closed:
        ctl = controller if controller is not None else make_controller(scenes[0])
        ctl.reset(np.stack([np.asarray(sc.phases_rad) for sc in scenes]))
        tick = max(1, int(round(1.0 / (ctl.rate_hz * dt))))  # integrator steps per control period
        unit = sps * tick // math.gcd(sps, tick)
        chunk = unit * max(1, options.chunk_steps // unit)
    else:
        chunk = sps * max(1, options.chunk_steps // sps)
    if chunk > options.chunk_steps:  # a chunk as long as a sample interval (or control period) longer
        _check_chunk_fits(compiled, chunk, dt, engine.reduces_on_device(ctl is not None),
                          requested.timestep_s is None)
    return _Batch(compiled, options, requested, outs, ctl, tick, chunk, n_samples)
