"""The MuJoCo Warp backend: every scene of a batch is one world of a Warp model.

:class:`WarpBackend` is the engine (:class:`undulate.simulation._engines.Backend`) and
:class:`WarpRollout` its prepared batch (:class:`undulate.simulation._engines.SampledRollout`: step
every scene ``nstep`` steps from the given FULLPHYSICS states under the given controls, into per-step
state and sensor arrays, or reduced per sample interval), so the recorder, the stopping rules, the
divergence checks and the checkpoints of :mod:`undulate.simulation` are shared by both backends.  Each call uploads the
states and the chunk's control table, steps the worlds on the device (one captured graph per step,
on a GPU and on Warp's CPU device, each Warp model on its own stream on a GPU) and downloads the
chunk once.  Open-loop chunks are reduced on the device (:meth:`WarpRollout.rollout_samples`: each
sample interval's last state and sensors, deepest penetration, mean contact forces and the first
bad step), closed-loop ones record every step (their controllers sense at the control rate).

What differs from the MuJoCo (CPU) backend, and why the results still agree
(tests/test_warp.py, docs/gpu.md):

* **Servos.**  MuJoCo Warp 4.0 has no ``pid`` actuator.  The Warp model expresses each servo as
  an affine position servo (:data:`undulate.scene.SERVO_MODELS`; derived from the scene's host
  model as compiled, :func:`._warp_servo.device_model`, so each scene is compiled once), and the
  set-point slew limit that MuJoCo's ``pid`` applies inside the step (``Servo.max_speed_rad_s``) is applied here to the
  set-point stream, step by step, with the same rule: the slew state moves toward the command by
  at most ``slewmax dt`` per step.  On the CPU the two expressions agree to 1e-16 m over 3000
  steps; the slew state is carried in the FULLPHYSICS ``act`` slots as MuJoCo's is.
  Servos with an integral term (``ki > 0``) are refused.
* **DIAGEXACT** (exact constraint regularisation) is not in MuJoCo Warp 4.0: the Warp model steps
  without it.
* **Precision**: float32 on the device; the clock is kept in float64 on the host.
* **Capacities**: contacts and constraint rows per world, and the contact sensors' match
  buffer, are sized from the scene (:func:`capacities`); an overflow raises
  :class:`~undulate.errors.CapacityError` naming the capacity instead of a per-step print.
* **Per-world parameters**: scenes of one structure that differ in a parameter MuJoCo Warp can
  batch (channel width, drag, gains, contact stiffness, ...) share one Warp model with that field
  given per world; scenes that differ in anything else are stepped as separate Warp models.

Where the parts live: :mod:`._warp_device` (the extra, the device, capacities, a model's settings),
:mod:`._warp_worlds` (world grouping), :mod:`._warp_servo` (the affine servos and their slew),
:mod:`._warp_group` (one Warp model: put on the device, compiled, captured, stepped),
:mod:`._warp_timeline` (the timeline), :mod:`._warp_kernels` (the control-table and recording
kernels) and :mod:`._warp_private` (the one door into MuJoCo Warp's and Warp's private modules).
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..errors import ParameterError
from ..execution import current
from ._compile import compiled_model
from ._warp_device import (_DEVICE_LOCK, DEVICES, PRECISION, STEPS_PER_GRAPH, CapacityError, available, capacities,
                           compile_workers, determinism, device_name, require, resolve_device, steps_per_graph,
                           versions)
from ._warp_group import _Group, _Reduction
from ._warp_servo import AffineServoTable, _cols, _idle_controls, device_model
from ._warp_worlds import plan_worlds

__all__ = ["WarpBackend", "WarpRollout", "available", "require", "resolve_device", "device_name", "versions",
           "capacities", "CapacityError", "determinism", "steps_per_graph", "compile_workers", "DEVICES", "PRECISION",
           "STEPS_PER_GRAPH"]

_OVERFLOW_NAMES = {"NEFC": "njmax (constraint rows per world)", "NJMAX_NNZ": "njmax_nnz",
                   "BROADPHASE": "nconmax (broadphase pairs)", "NARROWPHASE": "nconmax (contacts per world)",
                   "CONTACT_MATCH": "contact_sensor_maxmatch (contacts a contact sensor may match)",
                   "CCD": "ccd iterations", "NVMAX": "nvmax", "EPA_HORIZON": "EPA horizon"}


class WarpRollout:
    """Steps a batch's scenes as the worlds of MuJoCo Warp models
    (:class:`undulate.simulation._engines.SampledRollout`: ``rollout``, ``rollout_samples``, ``warm``,
    ``close``)."""

    def __init__(self, compiled, options, device: str, reduce: "_Reduction | None" = None):
        """``compiled``: the batch's scenes as the host compiled them (each one's Warp model is derived
        from its model, :func:`undulate.simulation._warp_servo.device_model`: no scene is compiled
        again); ``reduce``: reduce each chunk on the device (:meth:`rollout_samples`) instead of
        recording every step (:meth:`rollout`)."""
        require()
        self.device = device
        self.reduce = reduce
        cpu0 = compiled[0].model
        self.nq, self.nv, self.na = cpu0.nq, cpu0.nv, cpu0.na
        nstate = mujoco.mj_stateSize(cpu0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        if nstate != 1 + cpu0.nq + cpu0.nv + cpu0.na:
            raise ParameterError("backend", "'mujoco' for this scene (its state has parts the Warp backend "
                                 "does not carry)", "warp")
        models = []
        for c in compiled:
            mjm = device_model(c.model)
            mjm.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_DIAGEXACT)
            models.append(mjm)
        self.servos = AffineServoTable(cpu0, models[0], options.timestep_s, [c.model for c in compiled])
        with _DEVICE_LOCK:
            self.groups = [_Group(models[idx[0]], idx, per_world, device, [models[i] for i in idx], reduce)
                           for idx, per_world in plan_worlds(models)]
        self.warm = np.zeros((len(compiled), cpu0.nv))
        self._dt = float(options.timestep_s)

    def _control_table(self, cur: np.ndarray, u: np.ndarray, active: np.ndarray | None, nstep: int):
        """The device's control table for ``nstep`` steps of ``u`` from ``cur`` (the servos' slew from
        their states there; scenes outside ``active`` under zero controls) and the slewed set-points
        (:meth:`AffineServoTable.table`)."""
        a0, act_idx = 1 + self.nq + self.nv, self.servos.act
        act0 = np.where(act_idx >= 0, cur[:, a0 + np.maximum(act_idx, 0)] if self.na else 0.0, np.nan)
        return self.servos.table(_idle_controls(u, active, nstep), act0)

    def _step_groups(self, cur: np.ndarray, table: np.ndarray, nstep: int):
        """Step every group ``nstep`` steps from ``cur`` under ``table``: all of them launched first,
        so that on a GPU a batch's Warp models step side by side on their streams, then each one's
        chunk collected (``[(group, what :meth:`_Group.collect` returns)]``, in order)."""
        nq, nv = self.nq, self.nv
        for g in self.groups:
            idx = _cols(g.idx)  # a slice where the group's worlds are evenly spaced (no gathers; the
            # table itself, uncopied, where one group holds every world in order)
            g.launch(cur[idx, 1:1 + nq], cur[idx, 1 + nq:1 + nq + nv], self.warm[idx],
                     np.ascontiguousarray(table[:, idx]), nstep)
        return [(g, g.collect()) for g in self.groups]

    def rollout(self, cur: np.ndarray, u: np.ndarray, st: np.ndarray, sd: np.ndarray, nstep: int,
                active: np.ndarray | None = None):
        """Step every scene ``nstep`` steps from ``cur`` (nb, nstate FULLPHYSICS) under controls ``u``
        (nb, nstep, nu), into ``st`` (nb, nstep, nstate) and ``sd`` (nb, nstep, nsensordata).
        Scenes outside ``active`` stay at ``cur`` (their sensor rows zero)."""
        nq, nv, na = self.nq, self.nv, self.na
        q0, v0, a0 = 1, 1 + nq, 1 + nq + nv
        act_idx = self.servos.act
        table, slewed = self._control_table(cur, u, active, nstep)
        t0 = cur[:, :1]  # the clock stays float64 on the host
        for g, (q, v, s, warm, overflow) in self._step_groups(cur, table, nstep):
            idx = _cols(g.idx)
            if overflow.any():
                self._overflow(g.idx, overflow)
            st[idx, :nstep, q0:q0 + nq] = q
            st[idx, :nstep, v0:v0 + nv] = v
            sd[idx, :nstep] = s
            self.warm[idx] = warm
        if na:
            st[:, :nstep, a0:] = cur[:, None, a0:]
            has = act_idx >= 0
            st[:, :nstep, _cols(a0 + act_idx[has])] = slewed[:, :, _cols(np.flatnonzero(has))]
        st[:, :nstep, 0] = t0 + self._dt * (1 + np.arange(nstep))[None]
        if active is not None:
            st[~active], sd[~active] = cur[~active, None], 0.0
        return st, sd

    def rollout_samples(self, cur: np.ndarray, u: np.ndarray, nstep: int, active: np.ndarray | None = None):
        """Step every scene ``nstep`` steps (a multiple of the sample interval) from ``cur`` under
        controls ``u``, reduced on the device: only what the recorder keeps comes back.  Returns the
        FULLPHYSICS states (nb, ns, nstate) and sensors (nb, ns, nsensordata) at each interval's last
        step, the interval's deepest penetration (nb, ns), mean pair and wall force magnitudes
        (nb, ns, npair) and (nb, ns, nwall), and per scene the first bad step (-1: none) and what
        was bad there (1 huge or non-finite state, 2 interpenetration beyond the bound).  Scenes
        outside ``active`` stay at ``cur`` (their sensor rows zero, nothing bad)."""
        r = self.reduce
        sps = r.sps
        nq, nv, na = self.nq, self.nv, self.na
        q0, v0, a0 = 1, 1 + nq, 1 + nq + nv
        nb, ns = cur.shape[0], nstep // sps
        act_idx = self.servos.act
        table, slewed = self._control_table(cur, u, active, nstep)
        st = np.empty((nb, ns, cur.shape[1]))
        sd = np.empty((nb, ns, self.groups[0].ns))
        pn = np.empty((nb, ns))
        fp, fw = np.empty((nb, ns, len(r.pair_adr))), np.empty((nb, ns, len(r.wall_adr)))
        code = np.zeros(nb, dtype=np.int64)
        for g, (q, v, s, p, f_pair, f_wall, bad, warm, overflow) in self._step_groups(cur, table, nstep):
            idx = _cols(g.idx)
            if overflow.any():
                self._overflow(g.idx, overflow)
            st[idx, :, q0:q0 + nq], st[idx, :, v0:v0 + nv], sd[idx] = q, v, s
            pn[idx], fp[idx], fw[idx], code[idx] = p, f_pair, f_wall, bad
            self.warm[idx] = warm
        rows = np.arange(sps - 1, nstep, sps)
        if na:
            st[:, :, a0:] = cur[:, None, a0:]
            has = act_idx >= 0
            st[:, :, a0 + act_idx[has]] = slewed[:, rows][:, :, has]
        st[:, :, 0] = cur[:, :1] + self._dt * (1 + rows)[None]
        if active is not None:
            st[~active], sd[~active], pn[~active], code[~active] = cur[~active, None], 0.0, 0.0, 0
            fp[~active], fw[~active] = 0.0, 0.0
        return st, sd, pn, fp, fw, np.where(code > 0, code // 4 - 1, -1), code % 4

    def _overflow(self, idx, overflow) -> None:
        _, mjw = require()
        OverflowType = mjw.OverflowType
        w = int(np.flatnonzero(overflow)[0])
        bits = int(overflow[w])
        names = [_OVERFLOW_NAMES.get(f.name, f.name) for f in OverflowType
                 if f.name not in ("NONE", "ALL") and bits & int(f) and f.value]
        cap = self.groups[0].cap
        raise CapacityError(
            f"MuJoCo Warp world {int(idx[w])} overflowed: {', '.join(names)} "
            f"(allocated per world: nconmax {cap['nconmax']}, njmax {cap['njmax']}, "
            f"contact_sensor_maxmatch {cap['contact_sensor_maxmatch']}); the results would be wrong, "
            f"so the run stops (undulate.simulation._warp.capacities sizes them from the scene)")

    def close(self) -> None:
        for g in self.groups:
            g.timeline.flush()
        self.groups = []


class WarpBackend:
    """MuJoCo Warp (:class:`undulate.simulation._engines.Backend`): every scene of a batch one world of
    a Warp model, float32, on a GPU or Warp's CPU device (see the module docstring)."""

    name = "warp"

    def resolve_device(self, device: str | None) -> str:
        """``device`` checked against what this machine has (None: ``cuda`` if present, else ``cpu``)."""
        return resolve_device(device)

    def attrs(self, options) -> dict[str, str]:
        return {"backend": "warp", "device": options.device or "", "precision": PRECISION,
                "backend_versions": versions(), "warp_determinism": "all" if determinism(options.device) else "none"}

    def compile(self, scene, options, *, push: bool, loads: bool):
        """The scene as the host records it: the ``pid`` servos' layout (controls, FULLPHYSICS states with
        the slew states in ``act``), which :meth:`prepare` maps onto the device's affine servos."""
        return compiled_model(scene, options, push=push, loads=loads)

    def reduces_on_device(self, closed_loop: bool) -> bool:
        """Open-loop chunks are reduced on the device unless ``UNDULATE_WARP_REDUCE=0`` (closed-loop
        controllers sense at the control rate: every step comes back)."""
        return not closed_loop and current().reduce_on_device

    def prepare(self, compiled, options, *, nthread: int = 0, reduce=None) -> WarpRollout:
        """The device models (each scene's host model with affine servos, derived without compiling it
        again: :func:`undulate.simulation._warp_servo.device_model`), their worlds grouped
        (:func:`undulate.simulation._warp_worlds.plan_worlds`) and put on ``options.device``.
        ``nthread`` is the CPU engine's: the device steps every world at once."""
        red = None if reduce is None else _Reduction(reduce.steps_per_sample, reduce.pair_adr, reduce.wall_adr,
                                                     reduce.mindist_adr, list(reduce.max_penetration_m))
        return WarpRollout(compiled, options, options.device, reduce=red)
