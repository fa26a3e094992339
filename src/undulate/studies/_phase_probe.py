"""The closed-loop studies' controllers and their phase-interaction probe, H(dphi).

Not the phase observables of a trajectory: those are :mod:`undulate.phases`.

:func:`probe_run` (:func:`probe_runs` in batches) measures ``H(dphi)`` by phase reduction (see
:mod:`undulate.studies.phase_interaction`); :func:`stable_zeros`,
:func:`predicted` read the locked states it predicts.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from .. import stats
from ..params import Channel, ControllerParams, Scene, SimOptions
from ..sweep import batched_sweep_function
from ._criteria import PAIR_CHANNEL_M

PAIR_COUPLING = 2.0
"""phase-oscillator load feedback sigma in these studies, rad/s per N m."""
CONTROLLERS = {"self-oscillating": ControllerParams(kind="self-oscillating"),
               "phase-oscillator": ControllerParams(kind="phase-oscillator", coupling=PAIR_COUPLING),
               "relay": ControllerParams(kind="relay")}
PROBE_S = 10.0
"""Duration of a phase-reduction probe run, s (the first period is left out)."""
MATCH_TOL_RAD = math.radians(15.0)
"""An observed final dphi this close to a predicted stable zero's interval counts as predicted."""
NEUTRAL_RATE_RAD_S = 0.01
"""A bin whose mean |H| and interval lie within this is neutral (no interaction), rad/s."""


def _label(ds):
    """Units on the sweep's bookkeeping variables (run index and seed: dimensionless)."""
    for v in ("replicate", "seed", "run_failed"):
        if v in ds.variables:
            ds[v].attrs.setdefault("units", "1")
    return ds


def probe_run(point: dict, seed: int, *, duration_s: float = PROBE_S):
    """Phase reduction at a held phase difference (sweep function): the pair runs the open-loop gait
    at ``point["dphi_rad"]`` (``hold_x`` as given); at every control update each closed-loop law of
    :data:`CONTROLLERS` is evaluated on what the servos sensed (``phase_velocity``); per gait period
    after the first, ``H = -(<dpsi_1/dt> - <dpsi_0/dt>)`` (rad/s; dphi = phi_1 - phi_0, phi = 2 pi f t - psi).
    One point of :func:`probe_runs`."""
    return probe_runs([point], [seed], duration_s=duration_s)[0]


@batched_sweep_function
def probe_runs(points: list[dict], seeds: list[int], *, duration_s: float = PROBE_S) -> list:
    """:func:`probe_run` on several points (batched sweep function): the probes of one ``hold_x`` are
    stepped together as one batch (on the Warp backend the worlds of one model), each bitwise its run
    alone (a scene's run does not depend on the others, and the open-loop commands not on what the
    probe senses)."""
    from ._runners import _in_batches

    return _in_batches([bool(p["hold_x"]) for p in points],
                       lambda hold_x, idx: _probe_batch([float(points[i]["dphi_rad"]) for i in idx], hold_x,
                                                        duration_s))


def _probe_batch(dphi_rad: list[float], hold_x: bool, duration_s: float) -> list:
    """The probes at held phase differences ``dphi_rad`` (rad), positions held or not, in one batch."""
    import xarray as xr

    from ..control import SensingOpenLoop, make_controller
    from ..simulation import simulate_batch

    scenes = [Scene(phases_rad=(0.0, d), channel=Channel(width_m=PAIR_CHANNEL_M), hold_x=hold_x) for d in dphi_rad]
    sc = scenes[0]  # gait, geometry and controller settings: the batch's
    probe = SensingOpenLoop(sc.gait, sc.geometry.n_links, CONTROLLERS["relay"].control_rate_hz)
    simulate_batch(scenes, SimOptions(duration_s=duration_s, record=("x",)), controller=probe)
    t, psi, angle, vel, load = (np.array([s[k] for s in probe.sensed]) for k in range(5))  # time, scene, ...
    period = sc.gait.period_s
    k = np.floor(t / period + 1e-9).astype(int)
    periods = np.arange(1, int(duration_s / period + 1e-9))
    laws = [make_controller(dataclasses.replace(sc, controller=p)) for p in CONTROLLERS.values()]
    out = []
    for b in range(len(scenes)):
        h = np.full((len(CONTROLLERS), periods.size), np.nan)
        for i, law in enumerate(laws):
            w = law.phase_velocity(psi[:, b], angle[:, b], vel[:, b], load[:, b])
            dh = -(w[:, 1] - w[:, 0])
            h[i] = [dh[k == j].mean() for j in periods]
        attrs = {"units": "rad/s", "long_name": "period-mean d dphi/dt the law would command"}
        out.append(xr.Dataset({"H": (("law", "period"), h, attrs)},
                              coords={"law": ("law", list(CONTROLLERS)), "period": ("period", periods, {"units": "1"})}))
    return out


def _sign(h: stats.Estimate) -> int:
    return 0 if not h.has_interval or h.low <= 0 <= h.high else (1 if h.value > 0 else -1)


def stable_zeros(bins: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Pure: zeros where H falls through zero (+ then -, intervals excluding 0, circular; neutral
    or empty bins in between allowed), each with the line fit through the bins either side:
    the zero and the slope with their t intervals."""
    n, out = len(bins), []
    est = [stats.Estimate.from_dict(b["H"]) for b in bins]
    c = np.array([b["centre"] for b in bins])
    signed = [i for i in range(n) if _sign(est[i]) != 0]
    for a, b in zip(signed, signed[1:] + signed[:1]):
        if not (_sign(est[a]) > 0 and _sign(est[b]) < 0):
            continue
        xa, xb = c[a], c[b] + (2 * np.pi if b <= a else 0.0)
        x, y = np.array([xa, xb]), np.array([est[a].value, est[b].value])
        slope = (y[1] - y[0]) / (x[1] - x[0])
        z = x[0] - y[0] / slope
        # interval: the zero moves with each bin's mean within its interval (worst corners)
        zs = []
        for ya in (est[a].low, est[a].high):
            for yb in (est[b].low, est[b].high):
                s = (yb - ya) / (x[1] - x[0])
                zs.append(x[0] - ya / s if s < 0 else np.nan)
        zs = np.asarray(zs)
        lo, hi = (np.nanmin(zs), np.nanmax(zs)) if np.isfinite(zs).any() else (xa, xb)
        out.append({"zero_rad": float(np.angle(np.exp(1j * z))), "ci95": [float(lo), float(hi)],
                    "slope_per_s": float(slope), "bins": [int(a), int(b)]})
    return out


def _neutral(bins) -> list[int]:
    out = []
    for i, b in enumerate(bins):
        e = stats.Estimate.from_dict(b["H"])
        if e.has_interval and max(abs(e.low), abs(e.high)) < NEUTRAL_RATE_RAD_S:
            out.append(i)
    return out


def predicted(final: float, zeros: list[dict[str, Any]], bins: list[dict[str, Any]]) -> bool:
    """Pure: is a run's final dphi (rad) one of the states H predicts?"""
    for z in zeros:
        lo, hi = z["ci95"]
        for shift in (-2 * np.pi, 0.0, 2 * np.pi):
            if lo - MATCH_TOL_RAD <= final + shift <= hi + MATCH_TOL_RAD:
                return True
    w = 2 * np.pi / len(bins)
    return any(abs(np.angle(np.exp(1j * (final - bins[i]["centre"])))) <= w / 2 + 1e-9 for i in _neutral(bins))


