"""Where a run ended, to go on from (:class:`Checkpoint`), and the checks of a batch's checkpoints."""

from __future__ import annotations

from typing import TYPE_CHECKING

from dataclasses import dataclass

import numpy as np
import xarray as xr

from ..errors import ParameterError
from ._mujoco import _state_layout

if TYPE_CHECKING:
    from ._batch import _Batch

@dataclass(frozen=True, eq=False)
class Checkpoint:
    """Where a run ended, to go on from: MuJoCo's whole physical state there
    (``mjSTATE_FULLPHYSICS``, time first: s, then positions, velocities,
    actuator states) and the constraint solver's warm start
    (``qacc_warmstart``).  Every Dataset of :func:`simulate` carries them in
    its attrs ``end_state`` and ``end_warmstart`` (:meth:`of`);
    ``simulate(scene, options, start=checkpoint)`` then steps on from there to
    ``options.duration_s`` and records the samples after it: bitwise the rest
    of the uninterrupted run (each step depends on the state and the warm
    start alone; open-loop gaits only)."""

    state: np.ndarray
    warmstart: np.ndarray

    @classmethod
    def of(cls, ds: xr.Dataset) -> "Checkpoint":
        """The end of the run ``ds`` (a Dataset :func:`simulate` returned)."""
        if "end_state" not in ds.attrs or "end_warmstart" not in ds.attrs:
            raise ParameterError("ds", "a Dataset simulate() returned (attrs end_state and end_warmstart)",
                                 sorted(ds.attrs)[:5])
        return cls(np.asarray(ds.attrs["end_state"], dtype=float), np.asarray(ds.attrs["end_warmstart"], dtype=float))

    @property
    def time_s(self) -> float:
        """The simulated time at the checkpoint, s."""
        return float(self.state[0])


def as_list(start) -> list | None:
    """A call's ``start`` as a list (one Checkpoint, or one per scene; None: from rest), not yet validated."""
    if start is None:
        return None
    return [start] if isinstance(start, Checkpoint) else list(start)


def _starts(bt: "_Batch", start) -> list[Checkpoint] | None:
    """The batch's checkpoints, one per scene (None: every scene from rest), validated."""
    starts = as_list(start)
    if starts is None:
        return None
    if len(starts) != bt.nb or not all(isinstance(c, Checkpoint) for c in starts):
        raise ParameterError("start", f"a Checkpoint, or one per scene ({bt.nb})", start)
    if bt.ctl is not None:
        raise ParameterError("start", "open-loop scenes only (a closed-loop controller's own state is "
                             "not in a Checkpoint)", bt.ctl.kind)
    _, nstate = _state_layout(bt.m0)
    interval = bt.sps * bt.dt
    for c in starts:
        if c.state.shape != (nstate,) or c.warmstart.shape != (bt.m0.nv,):
            raise ParameterError("start", f"a Checkpoint of this scene's model ({nstate} state values, "
                                 f"{bt.m0.nv} warm-start values)", (c.state.shape, c.warmstart.shape))
        k = c.time_s / interval
        if abs(k - round(k)) > 1e-6 or not 0 <= round(k) < bt.n_samples:
            raise ParameterError("start", f"a Checkpoint at a sample time ({interval:g} s apart) before "
                                 f"duration_s", c.time_s)
    if len({round(c.time_s / interval) for c in starts}) > 1:
        raise ParameterError("start", "checkpoints of one time in a batch", sorted(c.time_s for c in starts))
    return starts
