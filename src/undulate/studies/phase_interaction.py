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
zeros (a + to - sign change between neighbouring bins whose intervals
exclude zero, located by a straight-line fit through the bins either side,
zero = -a/b with the fit's t interval propagated) and the neutral bins.
Each run's observed final ``dphi`` (circular mean over the last :data:`TAIL_S`)
is predicted when it lies within :data:`MATCH_TOL_RAD` of a stable zero's
interval or inside a neutral bin.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from .. import stats
from ..params import Channel, Scene, SimOptions
from ._registry import Claim, Study, StudyContext, Verdict, register
from .synchronization import CONTROLLERS, PAIR_CHANNEL_M, _label

__all__ = ["phase_run", "plan", "dataset", "summary", "binned_h", "stable_zeros", "predicted", "CLAIMS"]

WINDOW_PERIODS = 1
N_BINS = 24
TAIL_S = 4.0
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


def window_samples(t: np.ndarray, dphi: np.ndarray, window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Pure: per whole window of ``window_s``, (circular mean of dphi, rad; its mean rate, rad/s)."""
    u = np.unwrap(dphi)
    edges = np.arange(t[0], t[-1] + 1e-9, window_s)
    idx = np.searchsorted(t, edges - 1e-9)
    at, rate = [], []
    for a, b in zip(idx[:-1], idx[1:]):
        at.append(np.angle(np.exp(1j * dphi[a:b + 1]).mean()))
        rate.append((u[b] - u[a]) / (t[b] - t[a]))
    return np.asarray(at), np.asarray(rate)


def binned_h(at: np.ndarray, rate: np.ndarray, n_bins: int = N_BINS) -> list[dict[str, Any]]:
    """Pure: H per bin of dphi over [-pi, pi): centre (rad) and the mean rate (t interval)."""
    edges = np.linspace(-np.pi, np.pi, n_bins + 1)
    k = np.clip(np.searchsorted(edges, np.angle(np.exp(1j * at)), side="right") - 1, 0, n_bins - 1)
    return [{"centre": float((edges[i] + edges[i + 1]) / 2), "H": stats.mean(rate[k == i]).to_dict()}
            for i in range(n_bins)]


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
    n = 8 if quick else 24
    return {"dphi0_rad": list(np.linspace(-np.pi, np.pi, n, endpoint=False) + np.pi / n),
            "duration_s": 20.0 if quick else 40.0}


def dataset(ctx: StudyContext, p: dict[str, Any]):
    from ..sweep import Grid

    grid = Grid(axes={"controller": list(CONTROLLERS), "hold_x": [True, False], "dphi0_rad": p["dphi0_rad"]},
                seed=ctx.config.seed)
    ds = _label(ctx.sweep("runs", functools.partial(phase_run, duration_s=p["duration_s"]), grid))
    ds["dphi0_rad"].attrs.update(units="rad", long_name="initial phase difference phi_1 - phi_0")
    ds.attrs.update(title="phase-interaction function H(dphi) of closed-loop pairs", channel_width_m=PAIR_CHANNEL_M,
                    duration_s=p["duration_s"], window_periods=WINDOW_PERIODS,
                    period_s=Scene().gait.period_s)
    return ds


def _one(v, period_s: float) -> dict[str, Any]:
    """H, its stable zeros and the observed finals for one controller and hold condition."""
    t = v["time"].values
    ats, rates, finals = [], [], []
    for k in range(v.sizes["dphi0_rad"]):
        d = v["dphi"].isel(dphi0_rad=k).values
        if not np.isfinite(d).all():
            continue
        a, r = window_samples(t, d, WINDOW_PERIODS * period_s)
        ats.append(a)
        rates.append(r)
        tail = t >= t[-1] - TAIL_S
        finals.append(float(np.angle(np.exp(1j * d[tail]).mean())))
    bins = binned_h(np.concatenate(ats), np.concatenate(rates)) if ats else []
    zeros = stable_zeros(bins) if bins else []
    ok = [predicted(f, zeros, bins) for f in finals]
    return {"bins": bins, "stable_zeros": zeros, "neutral_bins": _neutral(bins) if bins else [],
            "finals_rad": finals, "predicted": [bool(o) for o in ok], "n_predicted": int(sum(ok)),
            "n_runs": len(finals)}


def summary(ds) -> dict[str, Any]:
    """Pure: per controller and hold condition, binned H with intervals, stable zeros, and how
    many closed-loop runs end where H predicts; the antisymmetry residual of H."""
    period = float(ds.attrs["period_s"])
    out: dict[str, Any] = {"per_controller": {}, "n_failed": int(ds["run_failed"].values.sum())}
    for c in ds["controller"].values:
        per = {}
        for h in ds["hold_x"].values:
            v = ds.sel(controller=c, hold_x=h).isel(replicate=0)
            per["held" if bool(h) else "free"] = _one(v, period)
        out["per_controller"][str(c)] = per
    return out


def _predicts(c: str, cond: str):
    def judge(s: dict) -> Verdict:
        v = s["per_controller"][c][cond]
        n, k = v["n_runs"], v["n_predicted"]
        if n == 0:
            return Verdict.none("no run has a result")
        zs = ", ".join(f"{math.degrees(z['zero_rad']):.0f} deg [{math.degrees(z['ci95'][0]):.0f}, "
                       f"{math.degrees(z['ci95'][1]):.0f}]" for z in v["stable_zeros"]) or "none"
        return Verdict.judged(k >= PREDICTED_FRACTION * n,
                              f"{k}/{n} runs end at a state H predicts (stable zeros {zs}; "
                              f"{len(v['neutral_bins'])} neutral bins)", {"predicted": k, "n_runs": n})
    return judge


CLAIMS = tuple(
    Claim(f"{c}: H(dphi) measured from contact predicts where {cond} pairs lock",
          "PRX 2021: a phase-oscillator model describes the stability of the in-phase and anti-phase modes",
          f"at least {PREDICTED_FRACTION:.0%} of closed-loop runs end within {math.degrees(MATCH_TOL_RAD):.0f} deg "
          "of a stable zero's 95 % interval (H falling through 0) or in a neutral bin", _predicts(c, cond))
    for c in CONTROLLERS for cond in ("held", "free"))


def _plot(ds):
    from ..plotting.synchronization import plot_phase_interaction

    return plot_phase_interaction(ds, summary(ds))


register(Study(
    name="phase-interaction", plan=plan, dataset=dataset, summary=summary, claims=CLAIMS, figure=_plot,
    description="Phase-interaction function H(dphi) = <d dphi/dt> of closed-loop pairs measured from contact "
                "(held and free positions, each controller), its stable zeros against the runs' final states."))
