"""The MuJoCo backend (:class:`MujocoBackend`): each scene rolled out in C by ``mujoco.rollout``, its
solver warm start carried across calls (:class:`_WarmRollout`), and MuJoCo's FULLPHYSICS state layout."""

from __future__ import annotations

import logging
from collections.abc import Sequence

import mujoco
import numpy as np
from mujoco import rollout as _rollout

from ._compile import compiled_model

__all__ = ["MujocoBackend"]


def _state_layout(m: mujoco.MjModel) -> tuple[int, int]:
    """Offsets of qpos in a FULLPHYSICS state vector: (qpos_start, nstate)."""
    n_time = mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_TIME)
    return n_time, mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS)


def _initial_state(m: mujoco.MjModel) -> np.ndarray:
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    s = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(m, d, s, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    return s, d.sensordata.copy()


_log = logging.getLogger(__name__)



def _log_mujoco_warning(msg: str) -> None:
    _log.debug("MuJoCo: %s", msg)




class _WarmRollout:
    """Rolls each scene out in C, its solver warm start carried across calls.

    ``mujoco.rollout`` starts every call's constraint solver from
    ``initial_warmstart`` (zero if not given), while ``mj_step`` starts each
    step from the previous step's accelerations.  Passing each scene's last
    ``qacc_warmstart`` on makes a run rolled out in pieces (chunks, control
    periods) bitwise equal to one ``mj_step`` loop.  The warm start of a
    scene is read from the ``MjData`` that stepped it, so every scene has its
    own; ``nthread > 0`` steps the scenes of a batch on that many threads
    (MuJoCo releases the GIL while it steps).
    """

    def __init__(self, models: Sequence[mujoco.MjModel], nthread: int = 0):
        self.models = list(models)
        self.datas = [mujoco.MjData(m) for m in self.models]
        self.warm = np.zeros((len(self.models), self.models[0].nv))
        self.pool = None
        if nthread > 0 and len(self.models) > 1:
            from concurrent.futures import ThreadPoolExecutor
            self.pool = ThreadPoolExecutor(nthread)
        self.runners = [_rollout.Rollout(nthread=0) for _ in (self.models if self.pool else self.models[:1])]

    def _one(self, b: int, cur, u, st, sd, nstep: int) -> None:
        runner = self.runners[b if self.pool else 0]
        args = (cur[b:b + 1], u[b:b + 1], self.warm[b:b + 1], st[b:b + 1], sd[b:b + 1])
        if u.shape[1] == st.shape[1] == sd.shape[1] == nstep and all(
                a.flags.c_contiguous and a.dtype == np.float64 for a in args):
            # every array already has rollout's exact shape: skip its per-call checks and tiling
            # (~50 us a call, which a closed-loop run pays once per control period); same C call
            runner.rollout([self.models[b]], [self.datas[b]], args[0], args[1], skip_checks=True,
                           nstep=nstep, initial_warmstart=args[2], state=args[3], sensordata=args[4])
        else:
            runner.rollout(self.models[b], self.datas[b], args[0], args[1], nstep=nstep,
                           initial_warmstart=args[2], state=args[3], sensordata=args[4])
        self.warm[b] = self.datas[b].qacc_warmstart

    def rollout(self, cur: np.ndarray, u: np.ndarray, st: np.ndarray, sd: np.ndarray, nstep: int,
                active: np.ndarray | None = None):
        """Step every scene ``nstep`` steps from ``cur`` under controls ``u``, into ``st`` and ``sd``.
        ``active``: a mask of the scenes to step (None: all); the others stay at ``cur`` (their
        sensor rows zero)."""
        idx = range(len(self.models))
        if active is not None:
            idx = np.flatnonzero(active)
            st[~active], sd[~active] = cur[~active, None], 0.0
        if self.pool is None:
            for b in idx:
                self._one(b, cur, u, st, sd, nstep)
        else:
            list(self.pool.map(lambda b: self._one(b, cur, u, st, sd, nstep), idx))
        return st, sd

    def close(self) -> None:
        for r in self.runners:
            r.close()
        if self.pool is not None:
            self.pool.shutdown()


class MujocoBackend:
    """MuJoCo's C engine (:class:`undulate.simulation._engines.Backend`): float64 on the CPU, every
    scene its own ``MjData``, results bitwise a plain ``mj_step`` loop (``tests/test_simulation.py``)."""

    name = "mujoco"

    def resolve_device(self, device: str | None) -> None:
        """None: MuJoCo steps on this process's cores."""
        return None

    def attrs(self, options) -> dict[str, str]:
        return {"backend": "mujoco", "device": "cpu", "precision": "float64"}

    def compile(self, scene, options, *, push: bool, loads: bool):
        """The scene's model with MuJoCo's ``pid`` servos."""
        return compiled_model(scene, options, push=push, loads=loads)

    def reduces_on_device(self, closed_loop: bool) -> bool:
        return False

    def prepare(self, compiled, options, *, nthread: int = 0, reduce=None) -> _WarmRollout:
        """Each scene rolled out from its own ``MjData`` (``nthread > 0``: on that many threads)."""
        return _WarmRollout([c.model for c in compiled], nthread)
