"""Stepping a planned batch chunk by chunk on its engine and turning each chunk into recorded sample
blocks (:class:`_Stepper`), with the divergence checks shared by every engine."""

from __future__ import annotations

import time

import numpy as np

from ._batch import _HUGE, _Batch, _Clock, _diagnose
from ._checkpoint import Checkpoint
from ._compile import controls
from ._control_loop import _closed_loop_chunk, _feed_forward_chunk
from ._engines import Reduction, backend
from ._mujoco import _initial_state, _state_layout
from ._record import _sample_vars

def _force_mag(sd: np.ndarray, adr: np.ndarray) -> np.ndarray:
    cols = adr[..., None] + np.arange(3)
    return np.linalg.norm(sd[..., cols], axis=-1)


def _depth_of(sd: np.ndarray, md: np.ndarray) -> np.ndarray:
    return np.where(sd[..., md] > 0, np.maximum(0.0, -sd[..., md + 1]), 0.0)


def _check_divergence(bt: _Batch, st: np.ndarray, depth: np.ndarray, done: int, active: np.ndarray) -> None:
    """Raise :class:`DivergenceError` for a chunk's states ``st`` (nb, k, nstate) of the ``active``
    scenes that blew up: huge or non-finite, a MuJoCo reset (it restarts the data after bad
    accelerations: the state's clock jumps back), or deep interpenetration."""
    k, dt = st.shape[1], bt.dt
    t_expected = (done + 1 + np.arange(k)) * dt
    huge = ~(np.abs(st) < _HUGE).all(axis=2)
    reset = np.abs(st[..., 0] - t_expected) > 0.5 * dt
    deep = depth > max(c.scene.contact.max_penetration_m for c in bt.compiled)
    bad = (huge | reset | deep) & active[:, None]
    if not bad.any():
        return
    b = int(np.flatnonzero(bad.any(axis=1))[0])
    step = int(np.argmax(bad[b]))
    if huge[b, step]:
        what = "non-finite or huge state (NaN, inf or > 1e6)"
    elif reset[b, step]:
        what = "MuJoCo found bad accelerations (solver failure) and reset the state"
    else:
        what = (f"interpenetration {depth[b, step] * 1e3:.2f} mm exceeds the "
                f"{bt.compiled[b].scene.contact.max_penetration_m * 1e3:g} mm bound")
    raise _diagnose(bt.compiled[b], bt.options, float(t_expected[step]), what)


class _Stepper:
    """Steps a batch chunk by chunk on its engine (open loop: one rollout per chunk, or reduced where
    the engine steps, :class:`undulate.simulation._engines.SampledRollout`; closed loop:
    :func:`_closed_loop_chunk`) and turns each chunk into recorded sample blocks."""

    def __init__(self, bt: _Batch, nthread: int, clock: _Clock, starts: list[Checkpoint] | None = None):
        self.bt, self.clock = bt, clock
        m0, nb = bt.m0, bt.nb
        self.q0, self.nstate = _state_layout(m0)
        ix = bt.compiled[0].index
        self.pair_adr, self.wall_adr, self.md = ix.sens_pair, ix.sens_wall, ix.sens_mindist
        engine = backend(bt.options.backend)
        self.reduce = engine.reduces_on_device(bt.ctl is not None)
        red = Reduction(bt.sps, self.pair_adr, self.wall_adr, self.md,
                        tuple(c.scene.contact.max_penetration_m for c in bt.compiled)) if self.reduce else None
        self.runner = engine.prepare(bt.compiled, bt.options, nthread=nthread, reduce=red)
        state0, sens0 = np.empty((nb, self.nstate)), np.empty((nb, m0.nsensordata))
        for b, cs in enumerate(bt.compiled):
            state0[b], sens0[b] = _initial_state(cs.model)
        self.state0, self.sens0 = state0, sens0
        self.cur, self.last_sens = state0.copy(), sens0.copy()
        self.bufs = self._buffers(bt.chunk)
        self.done = 0  # integrator steps taken
        if starts is not None:  # go on from checkpoints: their states, warm starts and step count
            self.cur = np.stack([c.state for c in starts])
            self.runner.warm[:] = np.stack([c.warmstart for c in starts])
            self.done = int(round(starts[0].time_s / (bt.sps * bt.dt))) * bt.sps

    def _buffers(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every step's states, sensors and controls of a chunk of ``k`` steps (reduced on the device:
        the controls only; the states and sensors come back one row per sample interval)."""
        nb, m0 = self.bt.nb, self.bt.m0
        n = 0 if self.reduce else k
        return np.empty((nb, n, self.nstate)), np.empty((nb, n, m0.nsensordata)), np.empty((nb, k, m0.nu))

    def _forces(self, sd: np.ndarray, ns: int):
        """Interval means of the pair and wall forces and the interval's deepest penetration."""
        bt = self.bt
        nb, sps, npair = bt.nb, bt.sps, len(self.pair_adr)
        fp = _force_mag(sd, self.pair_adr).reshape(nb, ns, sps, npair).mean(axis=2) if npair \
            else np.zeros((nb, ns, 0))
        fw = _force_mag(sd, self.wall_adr)
        fw = fw.reshape(nb, ns, sps, *fw.shape[2:]).mean(axis=2)
        return fp, fw

    def initial_blocks(self) -> list[dict]:
        """The samples at t = 0, one block per scene."""
        bt, q0 = self.bt, self.q0
        cmd0 = phase0 = None
        if bt.ctl is not None:
            cmd0, _ = bt.ctl.commands(np.zeros(1))
            phase0 = bt.ctl.gait_phase(np.zeros(1))
        s0 = self.sens0
        fp = _force_mag(s0[:, None], self.pair_adr) if len(self.pair_adr) else np.zeros((bt.nb, 1, 0))
        fw, pn = _force_mag(s0[:, None], self.wall_adr), _depth_of(s0[:, None], self.md)
        return [self._block(b, 0, self.state0[b:b + 1, q0:q0 + bt.m0.nq], s0[b:b + 1], fp[b], fw[b], pn[b],
                            None if cmd0 is None else cmd0[:, b], None if phase0 is None else phase0[:, b])
                for b in range(bt.nb)]

    def _block(self, b, i0, qpos, sens, fp, fw, pn, cmd=None, phase=None) -> dict:
        bt = self.bt
        t = np.round((i0 + np.arange(len(qpos))) * (bt.sps * bt.dt), 12)  # s; equal rates, equal clocks
        return _sample_vars(bt.compiled[b], t, qpos, sens, fp, fw, pn, bt.options.recorded, cmd=cmd, phase=phase)

    def _rollout(self, k: int, active: np.ndarray | None):
        """Step ``k`` integrator steps from the current state: states, sensors, commands and phases at
        the recorded rows (None for the open-loop gait)."""
        bt, dt, sps = self.bt, self.bt.dt, self.bt.sps
        if self.bufs[2].shape[1] != k:  # last, shorter chunk: contiguous buffers of its size
            self.bufs = self._buffers(k)
        state_buf, sens_buf, ctrl_buf = self.bufs
        t = (self.done + np.arange(k)) * dt
        if bt.ctl is None:
            for b in (range(bt.nb) if active is None else np.flatnonzero(active)):
                ctrl_buf[b] = controls(bt.compiled[b], t)
            st, sd = self.clock.rollout(self.runner, bt.nb, k, self.cur, ctrl_buf, state_buf, sens_buf, k,
                                        active=active)
            return st, sd, None, None
        rows = np.arange(sps - 1, k, sps)
        t_rows = np.round((self.done // sps + 1 + np.arange(k // sps)) * (sps * dt), 12)  # as _block stamps them
        chunk = _feed_forward_chunk if bt.ctl.feed_forward else _closed_loop_chunk
        st, sd, cmd_rows, phase_rows = chunk(
            bt.ctl, bt.compiled, self.runner, self.cur, self.last_sens, t, bt.tick, rows,
            t_rows, state_buf, sens_buf, ctrl_buf, self.q0, self.clock, active)
        self.last_sens = sd[:, k - 1].copy()
        return st, sd, cmd_rows, phase_rows

    def _step_chunk_reduced(self, k: int, stepping: np.ndarray) -> list[dict | None]:
        """:meth:`step_chunk` on an engine that reduces where it steps (Warp, open loop): the device keeps each sample
        interval's last state and sensors, deepest penetration, mean forces and the first bad step
        (:meth:`undulate.simulation._engines.SampledRollout.rollout_samples`), so only those cross to the
        host; the same blocks and the same divergence diagnoses as from every step."""
        bt, q0, sps = self.bt, self.q0, self.bt.sps
        active = None if stepping.all() else stepping
        if self.bufs[2].shape[1] != k:
            self.bufs = self._buffers(k)
        ctrl_buf = self.bufs[2]
        t = (self.done + np.arange(k)) * bt.dt
        for b in (range(bt.nb) if active is None else np.flatnonzero(active)):
            ctrl_buf[b] = controls(bt.compiled[b], t)
        t0 = time.perf_counter()
        st, sd, pn, fp, fw, bad_step, bad_kind = self.runner.rollout_samples(self.cur, ctrl_buf, k, active)
        self.clock.seconds += time.perf_counter() - t0
        self.clock.steps += int(stepping.sum()) * k
        bad = np.flatnonzero((bad_step >= 0) & stepping)
        if bad.size:
            b = int(bad[0])
            step = int(bad_step[b])
            t_bad = float((self.done + 1 + step) * bt.dt)
            if bad_kind[b] == 1:
                what = "non-finite or huge state (NaN, inf or > 1e6)"
            else:
                what = (f"interpenetration beyond the "
                        f"{bt.compiled[b].scene.contact.max_penetration_m * 1e3:g} mm bound")
            raise _diagnose(bt.compiled[b], bt.options, t_bad, what)
        self.cur = st[:, -1].copy()
        self.last_sens = sd[:, -1].copy()
        blocks = [self._block(b, self.done // sps + 1, st[b, :, q0:q0 + bt.m0.nq], sd[b], fp[b], fw[b], pn[b])
                  if stepping[b] else None for b in range(bt.nb)]
        self.done += k
        return blocks

    def step_chunk(self, k: int, stepping: np.ndarray) -> list[dict | None]:
        """Step the scenes of mask ``stepping`` one chunk of ``k`` steps (a multiple of the sample
        interval); their sample blocks (None for a scene not stepped: it stays where it is)."""
        if self.reduce:
            return self._step_chunk_reduced(k, stepping)
        bt, q0, sps = self.bt, self.q0, self.bt.sps
        st, sd, cmd_rows, phase_rows = self._rollout(k, None if stepping.all() else stepping)
        depth = _depth_of(sd, self.md)
        self.cur = st[:, k - 1].copy()
        _check_divergence(bt, st, depth, self.done, stepping)
        ns, rows = k // sps, np.arange(sps - 1, k, sps)
        fp, fw = self._forces(sd, ns)
        pn = depth.reshape(bt.nb, ns, sps).max(axis=2)
        blocks = [self._block(b, self.done // sps + 1, st[b, rows, q0:q0 + bt.m0.nq], sd[b, rows], fp[b], fw[b],
                              pn[b], None if cmd_rows is None else cmd_rows[:, b],
                              None if phase_rows is None else phase_rows[:, b]) if stepping[b] else None
                  for b in range(bt.nb)]
        self.done += k
        return blocks

    def checkpoint(self, b: int) -> Checkpoint:
        """Where scene ``b`` is now (a scene that stopped stays where its rule ended it)."""
        return Checkpoint(self.cur[b].copy(), self.runner.warm[b].copy())

    def close(self) -> None:
        self.runner.close()
