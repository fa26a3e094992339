"""The closed-loop pairs, defined once: ``synchronization-pairs`` judges the PRX claims on them and
``phase-interaction`` whether H(dphi) predicts where they end (:func:`closed_loop_pairs_sweep`, run
through :meth:`~._context.StudyContext.shared_sweep`, so both studies read one set of runs).

Two swimmers in the paper's ``d = 0.13 m`` channel, one closed-loop controller of
:data:`._phase_probe.CONTROLLERS`, longitudinal positions held (``Scene.hold_x``) or free, from an initial
phase difference ``dphi0``; run for :data:`PAIR_DURATION_S` or until :data:`PAIR_SYNC_STOP` finds
the lock decided.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from ..params import Channel, Scene, SimOptions
from ..stopping import PhaseStop
from ..sweep import Grid, batched_sweep_function
from ._criteria import PAIR_CHANNEL_M
from ._phase_probe import CONTROLLERS
from ._points import SyncPoint
from ._runners import _in_batches, _padded, _simulate_stopped_batch, _stop_vars

__all__ = ["PAIR_DURATION_S", "TAIL_S", "LOCK_TOL_RAD", "PAIR_SYNC_STOP", "RECORD", "pair_run", "pair_runs",
           "pair_plan", "closed_loop_pairs_sweep"]

PAIR_DURATION_S = 60.0
TAIL_S = 10.0
LOCK_TOL_RAD = 0.15
PAIR_SYNC_STOP = PhaseStop(tol_rad=LOCK_TOL_RAD, hold_s=TAIL_S, extra_s=TAIL_S, min_s=2 * TAIL_S)
"""The closed-loop pairs' stopping rule: the lock rule (:data:`LOCK_TOL_RAD` over :data:`TAIL_S`) held
:data:`TAIL_S` longer, no drift, and the offsets steady (:data:`._runners.PAIR_STOP`'s rule); never
before 2 :data:`TAIL_S`.  A pair that is still drifting runs the whole :data:`PAIR_DURATION_S`."""
RECORD = ("x", "y", "joint_angle", "joint_command", "joint_error", "contact_force_pair", "gait_phase")


def _tail_circmean(a: np.ndarray, sel: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * a[sel]).mean(axis=0))


def pair_run(point: dict, seed: int, *, duration_s: float = PAIR_DURATION_S, stop: PhaseStop | None = None):
    """One closed-loop pair (sweep function).  ``point``: ``controller`` (a key of
    :data:`CONTROLLERS`), ``hold_x`` (bool), ``dphi0_rad`` (initial phi_1 - phi_0).
    ``stop``: a stopping rule (:data:`PAIR_SYNC_STOP`; None: the whole ``duration_s``); the
    final values are then taken over the last :data:`TAIL_S` before the stop and ``dphi`` is
    NaN after it.  Deterministic (``seed`` unused)."""
    return pair_runs([point], [seed], duration_s=duration_s, stop=stop)[0]


@batched_sweep_function
def pair_runs(points: list[dict], seeds: list[int], *, duration_s: float = PAIR_DURATION_S,
              stop: PhaseStop | None = None):
    """:func:`pair_run` on several points (batched sweep function): the pairs of one controller and
    one ``hold_x`` are stepped together in one batch, each stopping by its own rule (bitwise its
    run alone: the controller is vectorised over the batch)."""
    pts = [SyncPoint.of(p) for p in points]
    opts = SimOptions(duration_s=duration_s, sample_rate_hz=20.0, record=RECORD)

    def run(key, idx):
        scenes = [Scene(phases_rad=(0.0, pts[i].dphi0_rad), channel=Channel(width_m=PAIR_CHANNEL_M),
                        hold_x=key[1], controller=CONTROLLERS[key[0]]) for i in idx]
        dss, n_full = _simulate_stopped_batch(scenes, opts, stop)
        return [_pair_result(ds, n_full) for ds in dss]

    return _in_batches([(p.controller, p.hold_x) for p in pts], run)


def _pair_result(ds, n_full: int):
    """A closed-loop pair's run -> its final phase difference, lock time, contact forces, dphi(t)."""
    import xarray as xr

    from ..phases import neighbour_phase_differences, time_to_lock

    t = ds["time"].values
    d = neighbour_phase_differences(ds)
    f = ds["contact_force_pair"].values[:, 0]
    head, tail = t <= t[0] + TAIL_S, t >= t[-1] - TAIL_S
    t_full = np.round(np.arange(n_full) * float(ds.attrs["sample_interval"]), 12)  # the full run's axis
    return xr.Dataset({
        "dphi_final": ((), float(_tail_circmean(d.values[:, 0], tail)),
                       {"units": "rad", "long_name": "final phase difference (circular mean, last TAIL_S)"}),
        "lock_time": ((), float(time_to_lock(d, tol_rad=LOCK_TOL_RAD, hold_s=TAIL_S)[0]),
                      {"units": "s", "long_name": "time to lock (NaN: still drifting)"}),
        "force_start": ((), float(f[head].mean()), {"units": "N", "long_name": "mean contact force, first TAIL_S"}),
        "force_end": ((), float(f[tail].mean()), {"units": "N", "long_name": "mean contact force, last TAIL_S"}),
        "dphi": (("time",), _padded(d.values[:, 0], n_full), {
            "units": "rad", "long_name": "phase difference over time (NaN after a stop)"}),
        **_stop_vars(ds),
    }, coords={"time": ("time", t_full, {"units": "s"})})


def pair_plan(quick: bool) -> dict[str, Any]:
    """Initial phase differences (12 quick, 24 full, bin centres over [-pi, pi), rad) and duration (s)."""
    n = 12 if quick else 24
    return {"dphi0_rad": list(np.linspace(-np.pi, np.pi, n, endpoint=False) + np.pi / n),
            "duration_s": PAIR_DURATION_S if quick else 2 * PAIR_DURATION_S}


def pair_stages(quick: bool) -> tuple[dict[str, Any], ...]:
    """:func:`pair_plan` in looks (:mod:`._stages`): quick 6, 12 initial phase differences; full 6, 12, 24."""
    from ._stages import strides, thinned

    p = pair_plan(quick)
    return tuple({**p, "dphi0_rad": list(d)} for d in thinned(p["dphi0_rad"], strides(quick)))


def closed_loop_pairs_sweep(dphi0_rad: Sequence[float], duration_s: float, seed: int) -> tuple[Callable, Grid]:
    """``(fn, grid)`` of the closed-loop pairs (``fn`` a batched sweep function, :func:`pair_runs`):
    :func:`pair_runs` for each controller, positions held and free, from each initial phase
    difference of ``dphi0_rad`` (rad), up to ``duration_s``, each ending once its lock is decided
    (:data:`PAIR_SYNC_STOP`)."""
    fn = functools.partial(pair_runs, duration_s=float(duration_s), stop=PAIR_SYNC_STOP)
    return fn, Grid(axes={"controller": list(CONTROLLERS), "hold_x": [True, False],
                          "dphi0_rad": [float(d) for d in dphi0_rad]}, seed=seed)
