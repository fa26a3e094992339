r"""Study ``phase-interaction``: the phase analogue of ``potential`` -- H(dphi) measured from contact.

For a closed-loop pair in the 0.13 m channel, the **phase-interaction
function** ``H(dphi)`` is the phase velocity ``d dphi / dt`` averaged over a
gait period, as a function of the phase difference ``dphi = phi_1 - phi_0``
(the paper's offsets, :mod:`undulate.phases`).  Its zeros are the locked
states; a zero where ``H`` falls (``dH/d dphi < 0``) is stable; a band where
``H`` is zero within its interval (no contact: no interaction) is neutral.

Method (phase reduction; why not the direct measurement from closed-loop
runs is in ``docs/controllers.md``): the pair runs the open-loop gait with its
phase difference held at each ``dphi`` of a grid (positions held, or free);
at every control update each closed-loop law is evaluated on what the servos
sensed (``Controller.phase_velocity``, :func:`._phase_probe.probe_run`), and ``H =
-(<dpsi_1/dt> - <dpsi_0/dt>)`` is averaged per gait period after the first;
each grid point's mean carries the t 95 % interval over its periods.  The
probe is shared with ``synchronization-groups`` (:func:`._shared.h_probe_sweep`).

Prediction against observation: the predicted final states are the stable
zeros (a + to - sign change between neighbouring grid points whose intervals
exclude zero, located by a straight-line fit through the bins either side,
zero = -a/b with the fit's t interval propagated) and the neutral bins.
The closed-loop pairs give the observed states: they are
``synchronization-pairs``' own runs (:func:`._closed_loop_pairs.closed_loop_pairs_sweep`,
from a grid of ``dphi0``, each ending once its lock is decided), shared by
identity, so both studies judge one set of runs.  A run whose ``dphi`` moves
less than :data:`DRIFT_RAD_S` over the last :data:`TAIL_S` it ran has locked, and is predicted when its final ``dphi``
(circular mean over that window) lies within :data:`MATCH_TOL_RAD` of a stable
zero's interval or inside a neutral bin; a run still drifting is predicted when
it drifts the way H's interval points at its ``dphi``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .. import stats
from ._closed_loop_pairs import _tail_circmean, closed_loop_pairs_sweep, pair_plan, pair_stages
from ._shared import h_probe_phases, h_probe_sweep
from ._context import StudyContext
from ._protocol import Claim, Study, Verdict
from ._registry import register
from ._criteria import PAIR_CHANNEL_M
from ._phase_probe import (CONTROLLERS, MATCH_TOL_RAD, NEUTRAL_RATE_RAD_S, PROBE_S, _label, _neutral,  # noqa: F401
                     _sign, predicted, probe_run, probe_runs, stable_zeros)

__all__ = ["probe_run", "probe_runs", "plan", "dataset", "summary", "stable_zeros", "predicted", "CLAIMS"]

TAIL_S = 4.0
DRIFT_RAD_S = 0.02
"""A run whose dphi moves less than this over the last TAIL_S has locked, rad/s."""
PREDICTED_FRACTION = 0.8
"""Claim: at least this fraction of runs end where H predicts."""


def plan(quick: bool) -> dict[str, Any]:
    """The closed-loop pairs are ``synchronization-pairs``' own (its initial phase differences and
    duration: 12 x 60 s quick, 24 x 120 s full, each ending once locked); H on the probe's grid."""
    pairs = pair_plan(quick)
    return {"dphi0_rad": pairs["dphi0_rad"], "duration_s": pairs["duration_s"], "dphi_rad": h_probe_phases(quick)}


def stages(quick: bool) -> tuple[dict[str, Any], ...]:
    """The looks of ``synchronization-pairs``' closed-loop pairs (:func:`._closed_loop_pairs.pair_stages`),
    each judged against H on the probe's whole grid."""
    h = h_probe_phases(quick)
    return tuple({"dphi0_rad": p["dphi0_rad"], "duration_s": p["duration_s"], "dphi_rad": h}
                 for p in pair_stages(quick))


def dataset(ctx: StudyContext, p: dict[str, Any]):
    pairs, probe = ctx.together(  # independent: side by side where the study runs wide
        lambda: ctx.shared_sweep("closed-loop-pairs", *closed_loop_pairs_sweep(p["dphi0_rad"], p["duration_s"],
                                                                              ctx.seed)),
        lambda: ctx.shared_sweep("h-probe", *h_probe_sweep(p["dphi_rad"], ctx.seed)))
    ds = _label(pairs)[["dphi", "force_start", "force_end", "stopped_at_s", "run_failed"]]
    ds["dphi0_rad"].attrs.update(units="rad", long_name="initial phase difference phi_1 - phi_0")
    ds["H"] = probe["H"].isel(replicate=0).rename(hold_x="probe_hold_x")
    ds["dphi_rad"].attrs.update(units="rad", long_name="held phase difference of the probe runs")
    ds.attrs.update(title="phase-interaction function H(dphi) of closed-loop pairs", channel_width_m=PAIR_CHANNEL_M,
                    duration_s=p["duration_s"], probe_s=PROBE_S)
    return ds


def _tail(t: np.ndarray, d: np.ndarray) -> tuple[float, float]:
    """A run's final dphi (circular mean over its last TAIL_S, rad) and its drift over them (rad/s);
    ``d`` is NaN after the run's stop."""
    n = int(np.isfinite(d).sum())
    t, d = t[:n], d[:n]
    tail = t >= t[-1] - TAIL_S
    return float(_tail_circmean(d, tail)), float(np.angle(np.exp(1j * (d[-1] - d[tail][0])))) / TAIL_S


def _one(v, h) -> dict[str, Any]:
    """H (per held dphi, t interval over periods), its stable zeros and the closed-loop finals."""
    bins = [{"centre": float(d), "H": stats.mean(h.sel(dphi_rad=d).values).to_dict()} for d in h["dphi_rad"].values]
    t = v["time"].values
    runs = [d for d in v["dphi"].values if np.isfinite(d[0])]  # a failed run is NaN throughout
    finals, drift = (list(x) for x in zip(*[_tail(t, d) for d in runs])) if runs else ([], [])
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


def _zero_text(z: dict[str, Any]) -> str:
    """A stable zero in degrees, its interval shifted by the turn that puts it around the zero (the zero is
    wrapped into (-180, 180], its interval is not: a zero near pi may carry an interval beyond 180)."""
    lo, hi = z["ci95"]
    turn = 2 * np.pi * round(((lo + hi) / 2 - z["zero_rad"]) / (2 * np.pi))
    return f"{math.degrees(z['zero_rad']):.0f} deg [{math.degrees(lo - turn):.0f}, {math.degrees(hi - turn):.0f}]"


def _predicts(c: str, cond: str):
    def judge(s: dict) -> Verdict:
        v = s["per_controller"][c][cond]
        n, k = v["n_runs"], v["n_predicted"]
        if n == 0:
            return Verdict.none("no run has a result")
        if v["all_neutral"]:
            return Verdict.none("H is zero within its interval at every dphi (no contact once the held-phase "
                                "pair has settled): nothing to predict")
        zs = ", ".join(_zero_text(z) for z in v["stable_zeros"]) or "none"
        locked = [abs(r) < DRIFT_RAD_S for r in v["drift_rad_s"]]
        k_locked = sum(p for p, lk in zip(v["predicted"], locked) if lk)
        n_locked = sum(locked)
        return Verdict.of(
            [stats.Check.exact(k >= PREDICTED_FRACTION * n, f"{k}/{n} runs predicted")],
            f"{k}/{n} runs end at a state H predicts: {k_locked}/{n_locked} locked runs at a stable zero or in a "
            f"neutral bin, {k - k_locked}/{n - n_locked} still drifting the way H points (stable zeros {zs}; "
            f"{len(v['neutral_bins'])}/{len(v['bins'])} bins neutral)", {"predicted": k, "n_runs": n})
    return judge


CLAIMS = tuple(
    Claim(f"{c}: H(dphi) measured from contact predicts where {cond} pairs lock",
          "PRX 2021: a phase-oscillator model describes the stability of the in-phase and anti-phase modes",
          f"at least {PREDICTED_FRACTION:.0%} of closed-loop runs end within {math.degrees(MATCH_TOL_RAD):.0f} deg "
          "of a stable zero's 95 % interval (H falling through 0) or in a neutral bin, or, still drifting, "
          "drift the way H's interval points", _predicts(c, cond),
          quote=("Its zeros and slopes predict which locked states exist and which are stable; the closed-loop "
                 "runs must end where it says."),
          where="PRX 2021 (Zhou, Hao & Gravish, Phys. Rev. X 11, 031051), as SPEC.md §6 states it: phase reduction")
    for c in CONTROLLERS for cond in ("held", "free"))


def _plot(ds):
    from ..plotting.synchronization import plot_phase_interaction

    return plot_phase_interaction(ds, summary(ds))


register(Study(
    name="phase-interaction", plan=plan, stages=stages, dataset=dataset, summary=summary, claims=CLAIMS, figure=_plot, reference="prx2021",
    description="Phase-interaction function H(dphi) = <d dphi/dt> of closed-loop pairs measured from contact "
                "(held and free positions, each controller), its stable zeros against the runs' final states."))
