r"""Study ``phase-interaction``: the phase analogue of ``potential`` -- H(dphi) measured from contact.

For a closed-loop pair in the 0.13 m channel, the **phase-interaction
function** ``H(dphi)`` is the phase velocity ``d dphi / dt`` averaged over a
gait period, as a function of the phase difference ``dphi = phi_1 - phi_0``
(the paper's offsets, :mod:`undulate.phases`).  Its zeros are the locked
states; a zero where ``H`` falls (``dH/d dphi < 0``) is stable; a band where
``H`` is zero within its interval (no contact: no interaction) is neutral.

Method (direct measurement; why not the phase-reduction projection is in
``docs/controllers.md``): pairs start from a grid of ``dphi0`` over
``[-pi, pi)`` and run closed loop; the record is cut into whole gait periods
(:data:`WINDOW_PERIODS`); each window gives one sample ``(circular mean of
dphi, (dphi_end - dphi_start) / window)``.  The samples of all runs are
binned in ``dphi`` (:data:`N_BINS` bins); each bin's mean carries a t 95 %
interval.  Positions held (``Scene.hold_x``) and free are measured
separately; with positions free ``H`` is the marginal over the ``dx`` the
runs visit.

Prediction against observation: the predicted final states are the stable
zeros (a + to - sign change between neighbouring grid points whose intervals
exclude zero, located by a straight-line fit through the bins either side,
zero = -a/b with the fit's t interval propagated) and the neutral bins.
Each run's observed final ``dphi`` (circular mean over the last :data:`TAIL_S`)
is predicted when it lies within :data:`MATCH_TOL_RAD` of a stable zero's
interval or inside a neutral bin.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any

import numpy as np

from .. import stats
from ..params import Channel, Scene, SimOptions
from ._registry import Claim, Study, StudyContext, Verdict, register
from .synchronization import CONTROLLERS, PAIR_CHANNEL_M, _label

__all__ = ["phase_run", "probe_run", "plan", "dataset", "summary", "stable_zeros", "predicted", "CLAIMS"]

PROBE_S = 10.0
"""Duration of a phase-reduction probe run, s (the first period is left out)."""
TAIL_S = 4.0
DRIFT_RAD_S = 0.02
"""A run whose dphi moves less than this over the last TAIL_S has locked, rad/s."""
MATCH_TOL_RAD = math.radians(15.0)
"""An observed final dphi this close to a predicted stable zero's interval counts as predicted."""
NEUTRAL_RATE_RAD_S = 0.01
"""A bin whose mean |H| and interval lie within this is neutral (no interaction), rad/s."""
PREDICTED_FRACTION = 0.8
"""Claim: at least this fraction of runs end where H predicts."""


def phase_run(point: dict, seed: int, *, duration_s: float):
    """One closed-loop pair from ``point["dphi0_rad"]`` (sweep function): ``dphi(t)`` at 20 Hz and
    the contact force.  ``controller``, ``hold_x`` as in :func:`~.synchronization.pair_run`."""
    import xarray as xr

    from ..phases import neighbour_phase_differences
    from ..simulation import simulate

    sc = Scene(phases_rad=(0.0, float(point["dphi0_rad"])), channel=Channel(width_m=PAIR_CHANNEL_M),
               hold_x=bool(point["hold_x"]), controller=CONTROLLERS[str(point["controller"])])
    ds = simulate(sc, SimOptions(duration_s=duration_s, sample_rate_hz=20.0,
                                 record=("x", "y", "gait_phase", "contact_force_pair")))
    d = neighbour_phase_differences(ds)
    return xr.Dataset({
        "dphi": (("time",), d.values[:, 0], {"units": "rad", "long_name": "phase difference phi_1 - phi_0"}),
        "force": (("time",), ds["contact_force_pair"].values[:, 0], {"units": "N", "long_name": "contact force"}),
    }, coords={"time": ("time", ds["time"].values, {"units": "s"})}, attrs={"period_s": sc.gait.period_s})


def probe_run(point: dict, seed: int, *, duration_s: float = PROBE_S):
    """Phase reduction at a held phase difference (sweep function): the pair runs the open-loop gait
    at ``point["dphi_rad"]`` (``hold_x`` as given); at every control update each closed-loop law of
    :data:`CONTROLLERS` is evaluated on what the servos sensed (``phase_velocity``); per gait period
    after the first, ``H = -(<dpsi_1/dt> - <dpsi_0/dt>)`` (rad/s; dphi = phi_1 - phi_0, phi = 2 pi f t - psi)."""
    import xarray as xr

    from ..control import SensingOpenLoop, make_controller
    from ..simulation import simulate

    sc = Scene(phases_rad=(0.0, float(point["dphi_rad"])), channel=Channel(width_m=PAIR_CHANNEL_M),
               hold_x=bool(point["hold_x"]))
    probe = SensingOpenLoop(sc.gait, sc.geometry.n_links, CONTROLLERS["relay"].control_rate_hz)
    simulate(sc, SimOptions(duration_s=duration_s, record=("x",)), controller=probe)
    t, psi, angle, vel, load = (np.array([s[k] for s in probe.sensed]) for k in range(5))
    psi, angle, vel, load = psi[:, 0], angle[:, 0], vel[:, 0], load[:, 0]  # the batch of one scene
    period = sc.gait.period_s
    k = np.floor(t / period + 1e-9).astype(int)
    periods = np.arange(1, int(duration_s / period + 1e-9))
    h = np.full((len(CONTROLLERS), periods.size), np.nan)
    for i, p in enumerate(CONTROLLERS.values()):
        w = make_controller(dataclasses.replace(sc, controller=p)).phase_velocity(psi, angle, vel, load)
        dh = -(w[:, 1] - w[:, 0])
        h[i] = [dh[k == j].mean() for j in periods]
    return xr.Dataset({"H": (("law", "period"), h, {"units": "rad/s",
                                                    "long_name": "period-mean d dphi/dt the law would command"})},
                      coords={"law": ("law", list(CONTROLLERS)), "period": ("period", periods, {"units": "1"})})


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


def plan(quick: bool) -> dict[str, Any]:
    n, m = (8, 16) if quick else (24, 36)
    return {"dphi0_rad": list(np.linspace(-np.pi, np.pi, n, endpoint=False) + np.pi / n),
            "dphi_rad": list(np.linspace(-np.pi, np.pi, m, endpoint=False) + np.pi / m),
            "duration_s": 20.0 if quick else 60.0}


def dataset(ctx: StudyContext, p: dict[str, Any]):
    from ..sweep import Grid

    grid = Grid(axes={"controller": list(CONTROLLERS), "hold_x": [True, False], "dphi0_rad": p["dphi0_rad"]},
                seed=ctx.config.seed)
    ds = _label(ctx.sweep("runs", functools.partial(phase_run, duration_s=p["duration_s"]), grid))
    ds["dphi0_rad"].attrs.update(units="rad", long_name="initial phase difference phi_1 - phi_0")
    probe = ctx.sweep("probe", probe_run, Grid(axes={"hold_x": [True, False], "dphi_rad": p["dphi_rad"]},
                                               seed=ctx.config.seed))
    ds["H"] = probe["H"].isel(replicate=0).rename(hold_x="probe_hold_x")
    ds["dphi_rad"].attrs.update(units="rad", long_name="held phase difference of the probe runs")
    ds.attrs.update(title="phase-interaction function H(dphi) of closed-loop pairs", channel_width_m=PAIR_CHANNEL_M,
                    duration_s=p["duration_s"], probe_s=PROBE_S)
    return ds


def _one(v, h) -> dict[str, Any]:
    """H (per held dphi, t interval over periods), its stable zeros and the closed-loop finals."""
    bins = [{"centre": float(d), "H": stats.mean(h.sel(dphi_rad=d).values).to_dict()} for d in h["dphi_rad"].values]
    t = v["time"].values
    tail = t >= t[-1] - TAIL_S
    runs = [d for d in v["dphi"].values if np.isfinite(d).all()]
    finals = [float(np.angle(np.exp(1j * d[tail]).mean())) for d in runs]
    drift = [float(np.angle(np.exp(1j * (d[-1] - d[tail][0])))) / TAIL_S for d in runs]
    zeros = stable_zeros(bins)
    ok = [predicted(f, zeros, bins) if abs(r) < DRIFT_RAD_S else _drifts_as_h(f, r, bins)
          for f, r in zip(finals, drift)]
    return {"bins": bins, "stable_zeros": zeros, "neutral_bins": _neutral(bins), "finals_rad": finals,
            "predicted": [bool(o) for o in ok], "n_predicted": int(sum(ok)), "n_runs": len(finals),
            "drift_rad_s": drift, "n_locked": int(sum(abs(r) < DRIFT_RAD_S for r in drift)),
            "all_neutral": len(_neutral(bins)) == len(bins),
            "antisymmetry_rad_s": _antisymmetry(bins)}


def _drifts_as_h(final: float, rate: float, bins) -> bool:
    """Pure: a run still drifting is predicted when it drifts the way H points at its dphi (the
    nearest grid point's interval excluding 0)."""
    c = np.array([b["centre"] for b in bins])
    i = int(np.argmin(np.abs(np.angle(np.exp(1j * (c - final))))))
    return _sign(stats.Estimate.from_dict(bins[i]["H"])) == np.sign(rate) != 0


def _antisymmetry(bins) -> dict[str, Any]:
    """max over the grid of |H(d) + H(-d)| and the largest |H| (rad/s), for the symmetry check."""
    c = np.array([b["centre"] for b in bins])
    h = np.array([stats.Estimate.from_dict(b["H"]).value for b in bins])
    pairs = [(i, int(np.argmin(np.abs(c + c[i])))) for i in range(c.size)]
    return {"max_sum": float(max(abs(h[i] + h[j]) for i, j in pairs)), "max_abs": float(np.nanmax(np.abs(h)))}


def summary(ds) -> dict[str, Any]:
    """Pure: per controller and hold condition, H with intervals, stable zeros, and how many
    closed-loop runs end where H predicts."""
    out: dict[str, Any] = {"per_controller": {}, "n_failed": int(ds["run_failed"].values.sum())}
    for c in ds["controller"].values:
        per = {}
        for held in (True, False):
            v = ds.sel(controller=c, hold_x=held).isel(replicate=0)
            per["held" if held else "free"] = _one(v, ds["H"].sel(law=c, probe_hold_x=held))
        out["per_controller"][str(c)] = per
    return out


def _predicts(c: str, cond: str):
    def judge(s: dict) -> Verdict:
        v = s["per_controller"][c][cond]
        n, k = v["n_runs"], v["n_predicted"]
        if n == 0:
            return Verdict.none("no run has a result")
        if v["all_neutral"]:
            return Verdict.none("H is zero within its interval at every dphi (no contact once the held-phase "
                                "pair has settled): nothing to predict")
        zs = ", ".join(f"{math.degrees(z['zero_rad']):.0f} deg [{math.degrees(z['ci95'][0]):.0f}, "
                       f"{math.degrees(z['ci95'][1]):.0f}]" for z in v["stable_zeros"]) or "none"
        return Verdict.judged(k >= PREDICTED_FRACTION * n,
                              f"{k}/{n} runs end at a state H predicts ({v['n_locked']} locked, the rest judged by the "
                              f"direction of their drift; stable zeros {zs}; "
                              f"{len(v['neutral_bins'])} neutral bins)", {"predicted": k, "n_runs": n})
    return judge


CLAIMS = tuple(
    Claim(f"{c}: H(dphi) measured from contact predicts where {cond} pairs lock",
          "PRX 2021: a phase-oscillator model describes the stability of the in-phase and anti-phase modes",
          f"at least {PREDICTED_FRACTION:.0%} of closed-loop runs end within {math.degrees(MATCH_TOL_RAD):.0f} deg "
          "of a stable zero's 95 % interval (H falling through 0) or in a neutral bin, or, still drifting, "
          "drift the way H's interval points", _predicts(c, cond))
    for c in CONTROLLERS for cond in ("held", "free"))


def _plot(ds):
    from ..plotting.synchronization import plot_phase_interaction

    return plot_phase_interaction(ds, summary(ds))


register(Study(
    name="phase-interaction", plan=plan, dataset=dataset, summary=summary, claims=CLAIMS, figure=_plot,
    description="Phase-interaction function H(dphi) = <d dphi/dt> of closed-loop pairs measured from contact "
                "(held and free positions, each controller), its stable zeros against the runs' final states."))
