"""Sweeps that more than one study runs, each defined once.

The groups study's three sweeps and the potential study's contact-impulse
sweep are also the sensitivity study's default-model rows; the closed-loop
pairs' H(dphi) probe is run by both ``phase-interaction`` and
``synchronization-groups`` (the closed-loop pairs, run by both
``synchronization-pairs`` and ``phase-interaction``, are defined in
:mod:`._closed_loop_pairs`).  Both studies
build them here, with the same function, the same bound arguments and the
same grid, and request them through
:meth:`~._context.StudyContext.shared_sweep`: in one output folder they are
computed once, by whichever study runs first, and reused by the other only
while their identity (bound call, grid, code hash, package version) is the
same.  Whatever is bound here (a duration, a stopping rule) is bound for
every study that runs these sweeps.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence

import numpy as np

from ..sweep import Grid
from ._criteria import GROUP_CHANNEL_M, PAIR_CHANNEL_M
from ._runners import DURATION_S, PAIR_STOP, PERIOD_S, group_point, pair_point

__all__ = ["IMPULSE_DURATION_S", "group_sweep", "group_part", "impulse_sweep", "h_probe_phases", "h_probe_sweep"]

IMPULSE_DURATION_S = 2 * PERIOD_S
"""Length of the contact-impulse runs, s: the two periods the impulse is taken over (and the first period's
escape the sensitivity study reads), nothing after them.  A longer run gives the same numbers bitwise
(the run is its prefix) at more cost; these runs were 6 s (3 periods) until the sixth second was seen to
feed nothing (one third of their physics)."""


def group_part(size: int, channel_width_m: float | None = None) -> str:
    """The store name of :func:`group_sweep`'s runs: ``groups{size}-d{width:g}``."""
    w = {2: PAIR_CHANNEL_M, **GROUP_CHANNEL_M}[size] if channel_width_m is None else channel_width_m
    return f"groups{size}-d{w:g}"


def group_sweep(size: int, dphi_rad: Sequence[float], draws: int, seed: int,
                channel_width_m: float | None = None) -> tuple[Callable, Grid]:
    """``(fn, grid)`` of the groups study's runs of groups of ``size`` (2: its reference pairs in the
    pair channel; 3: phases ``(0, dphi, 2 dphi)`` at each of ``dphi_rad`` (rad); 4: random phases,
    ``draws`` seeded draws), :data:`._runners.DURATION_S` long with :data:`._runners.PAIR_STOP`, in their
    channel (:data:`._criteria.GROUP_CHANNEL_M`) or in ``channel_width_m`` (m) with all else the same
    (the same per-run seeds: the same phase draws)."""
    w = {2: PAIR_CHANNEL_M, **GROUP_CHANNEL_M}[size] if channel_width_m is None else float(channel_width_m)
    run = functools.partial(group_point, n_swimmers=int(size), channel_width_m=w, duration_s=DURATION_S,
                            stop=PAIR_STOP)
    if size == 4:  # random phases: one seeded draw per replicate
        return (functools.partial(run, random_phases=True),
                Grid(axes={"waves_per_body": [1.0]}, replicates=int(draws), seed=seed))
    return run, Grid(axes={"dphi_rad": [float(d) for d in dphi_rad]}, seed=seed)


def impulse_sweep(dphi_rad: Sequence[float], phi0_rad: Sequence[float], seed: int,
                  **axes: Sequence[float]) -> tuple[Callable, Grid]:
    """``(fn, grid)`` of the contact-impulse runs (pairs from dx0 = 0, :data:`IMPULSE_DURATION_S`) over
    ``dphi_rad`` x ``phi0_rad`` (rad); ``axes`` (e.g. ``drag_N_s_per_m``) go before them."""
    fn = functools.partial(pair_point, duration_s=IMPULSE_DURATION_S)
    return fn, Grid(axes={**{k: [float(x) for x in v] for k, v in axes.items()},
                          "dphi_rad": [float(v) for v in dphi_rad], "phi0_rad": [float(v) for v in phi0_rad]},
                    seed=seed)


def h_probe_phases(quick: bool) -> list[float]:
    """The held phase differences of the H(dphi) probe, rad: 16 (full: 36) bin centres over [-pi, pi)."""
    m = 16 if quick else 36
    return [float(v) for v in np.linspace(-np.pi, np.pi, m, endpoint=False) + np.pi / m]


def h_probe_sweep(dphi_rad: Sequence[float], seed: int) -> tuple[Callable, Grid]:
    """``(fn, grid)`` of the closed-loop pairs' H(dphi) probe (``fn`` a batched sweep function,
    :func:`._phase_probe.probe_runs`), positions held and free, at each held phase difference of ``dphi_rad``
    (rad)."""
    from ._phase_probe import probe_runs

    return probe_runs, Grid(axes={"hold_x": [True, False], "dphi_rad": [float(d) for d in dphi_rad]}, seed=seed)

