r"""Study ``potential`` (paper Fig. 10): contact force against detuning, and cohesion stiffness.

(a) Pairs in the 0.13 m channel start at ``dx0 = 0`` with ``dphi`` across
``[-pi, pi]``; the swimmer-swimmer contact impulse over the first two
periods (``observables.contact_impulse(ds, 0, 2T)``) is fitted by
``a |dphi| + b`` (least squares; R^2 reported).  The start from straight
bodies makes the first two periods depend on the common phase too (a
``dphi`` run and its mirror image ``-dphi`` differ by a common phase
shift), so each ``dphi`` is run at several phases ``phi0`` of the lower
swimmer and the impulse is averaged over them.

(b-d) A ``dphi = 0`` pair settles for :data:`SETTLE_S` at compatibility
(``dx = 0``), then equal and opposite longitudinal forces ``-dF`` (lower
swimmer, toward -x) and ``+dF`` (upper, toward +x) switch on
(``Scene.forces_N``, ``force_onset_s``) and stay on.  ``dx`` is the mean of
the last 3 periods minus the mean of the period before the onset.  A pair
*broke apart* when ``dx / lambda > BREAK`` or when its period means still
drift (range over the last 3 periods > ``DRIFT`` lambda); those points are
left out of the fit :func:`fit_stiffness`, ``dF = k (dx - dx0)``.  Done for
every ``d / 2A`` and ``beta`` in {30, 45, 60} degrees, with ``A`` measured
per beta on a free swimmer.

Compatibility model of ``dx0`` (:func:`model_dx0_m`)
----------------------------------------------------
Full compatibility region (paper Eq. fullcompatibility), at ``dphi = 0``:
two sinusoids of amplitude ``A`` at lateral offset ``dy`` never touch for

    |2 pi dx / lambda| <= 2 arcsin(min(dy / 2A, 1)),

a band of neutral offsets of half-width ``(lambda / pi) arcsin(dy / 2A)``
around ``dx = 0``.  The settled pair sits in the middle of that band; the
pulling forces slide it freely to the band's edge, so the model's offset
is that half-width.  The lateral room ``dy`` is what the walls leave:

* sinusoids (zero thickness): each centre line keeps ``A`` from its wall,
  so ``dy <= d - 2A``; this is the model drawn in the paper's terms
  (``dy / 2A = d / 2A - 1``): ``dx0 = (lambda / pi) arcsin(clip(d / 2A - 1, 0, 1))``;
* bodies of width ``w``: each body edge keeps ``A + w / 2`` from its wall
  and the two bodies need ``w`` between centre lines, so the clearance
  between the curves is ``d - 2A - 2w`` (:func:`lateral_clearance_m`).

Both are drawn; the measured offset is expected between or below them
(three-link bodies do not fill the sinusoid's envelope).
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from .. import theory
from ..params import Gait, SwimmerGeometry
from ._registry import StudyConfig, StudyResult, register
from .basins import PAIR_WIDTH_M, pair_point
from .packing import _spearman, measure_lone_swimmers, round_amplitude, study_sweep

__all__ = [
    "lateral_clearance_m",
    "model_dx0_m",
    "fit_stiffness",
    "fit_abs_linear",
    "PotentialPlan",
    "plan",
    "compute",
]

SETTLE_S = 6.0
"""Settling time before the forces switch on, s (3 periods)."""
DURATION_S = 50.0
BREAK = 0.45
"""dx / lambda beyond which the pair has broken apart (left its compatible state)."""
DRIFT = 0.005
"""Range of the last 3 period means (lambda) above which dx is still drifting."""
SLIDING_FROM = 1.0
"""d/2A from which the collapse of k is also measured on its own: in narrower channels
the two bodies are wedged between the walls (large joint errors; the pair barely moves
under any force) and k is large but erratic."""
IMPULSE_DURATION_S = 6.0
"""Length of the impulse runs, s (the impulse is taken over the first 2 periods)."""


lateral_clearance_m = theory.lateral_clearance_m
model_dx0_m = theory.neutral_offset_m


def fit_stiffness(dF, dx, valid=None, min_points: int = 3) -> tuple[float, float, float]:
    """Least-squares fit ``dF = k (dx - dx0)``; returns ``(k, dx0, r2)``.

    ``dF``: applied forces (N); ``dx``: steady extra separations (m, or any
    unit: ``k`` is then N per that unit and ``dx0`` in it); ``valid``: points
    to use (e.g. not broken apart); non-finite points are ignored too.
    Fits ``dF = k dx + c`` (dF regressed on dx), ``dx0 = -c / k``; ``r2`` is
    the coefficient of determination of that regression.  NaNs when fewer
    than ``min_points`` usable points or no spread in ``dx``.
    """
    f = np.asarray(dF, float).ravel()
    x = np.asarray(dx, float).ravel()
    use = np.isfinite(f) & np.isfinite(x)
    if valid is not None:
        use &= np.asarray(valid, bool).ravel()
    f, x = f[use], x[use]
    nan = (float("nan"),) * 3
    if f.size < max(2, min_points) or np.ptp(x) == 0:
        return nan
    k, c = np.polyfit(x, f, 1)
    if k == 0:
        return nan
    resid = f - (k * x + c)
    ss = np.sum((f - f.mean()) ** 2)
    r2 = 1.0 - np.sum(resid**2) / ss if ss > 0 else float("nan")
    return float(k), float(-c / k), float(r2)


def fit_abs_linear(dphi, y) -> tuple[float, float, float]:
    """Least squares ``y = a |dphi| + b``; returns ``(a, b, r2)`` (NaNs if < 3 points)."""
    p = np.abs(np.asarray(dphi, float).ravel())
    v = np.asarray(y, float).ravel()
    ok = np.isfinite(p) & np.isfinite(v)
    p, v = p[ok], v[ok]
    if p.size < 3 or np.ptp(p) == 0:
        return (float("nan"),) * 3
    a, b = np.polyfit(p, v, 1)
    ss = np.sum((v - v.mean()) ** 2)
    r2 = 1.0 - np.sum((v - a * p - b) ** 2) / ss if ss > 0 else float("nan")
    return float(a), float(b), float(r2)


class PotentialPlan:
    """Grids of the potential study."""

    def __init__(self, impulse_dphi, betas_deg, d_over_2A, forces_N, duration_s: float = DURATION_S,
                 impulse_phi0=(0.0, np.pi / 2, np.pi, 3 * np.pi / 2)):
        self.impulse_dphi = [float(v) for v in impulse_dphi]
        self.impulse_phi0 = [float(v) for v in impulse_phi0]
        self.betas_deg = [float(v) for v in betas_deg]
        self.d_over_2A = [float(v) for v in d_over_2A]
        self.forces_N = sorted(float(v) for v in forces_N)
        self.duration_s = float(duration_s)


def plan(quick: bool) -> PotentialPlan:
    """Full: 37 dphi x 8 common phases; 3 beta x 9 d/2A (0.6 to 1.4) x 13 forces (5 mN to
    0.5 N) = 351 runs.  Quick: 9 dphi x 4 phases; 3 x 3 x 5 = 45 runs."""
    if quick:
        return PotentialPlan(np.linspace(-np.pi, np.pi, 9), [30, 45, 60], [0.8, 1.0, 1.2],
                             [0.02, 0.05, 0.1, 0.2, 0.3])
    return PotentialPlan(np.linspace(-np.pi, np.pi, 37), [30, 45, 60], np.round(np.arange(0.6, 1.41, 0.1), 10),
                         [0.005, 0.01, 0.02, 0.03, 0.04, 0.06, 0.08, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5],
                         impulse_phi0=np.linspace(0, 2 * np.pi, 8, endpoint=False))


def compute(config: StudyConfig, p: PotentialPlan) -> StudyResult:
    """Run the potential study on plan ``p`` (used by :func:`run` and the tests)."""
    import xarray as xr

    from ..plotting.potential import plot_potential
    from ..sweep import Grid

    geo = SwimmerGeometry()
    gait = Gait()
    lam = gait.wavelength_m(geo.length_m)
    betas = [math.radians(b) for b in p.betas_deg]

    # (a) contact impulse over the first two periods against dphi, for several common phases
    fa = functools.partial(pair_point, duration_s=IMPULSE_DURATION_S)
    ga = Grid(axes={"dphi_rad": p.impulse_dphi, "phi0_rad": p.impulse_phi0}, seed=config.seed)
    ra = study_sweep(config, "potential", "impulse", fa, ga)
    imp_all = ra.dataset.isel(replicate=0)["impulse_2T_Ns"].values  # (dphi, phi0)
    impulse = np.nanmean(imp_all, axis=1)
    dphi = np.asarray(p.impulse_dphi)
    fit_a = fit_abs_linear(dphi, impulse)
    fit_pos = fit_abs_linear(dphi[dphi >= 0], impulse[dphi >= 0])
    fit_neg = fit_abs_linear(dphi[dphi <= 0], impulse[dphi <= 0])

    # amplitudes per beta, then every (beta, d/2A, dF) in one sweep
    lone = measure_lone_swimmers(config, "potential", betas)
    amps = np.array([round_amplitude(float(v)) for v in lone["amplitude_m"].values])
    n_b, n_r, n_f = len(betas), len(p.d_over_2A), len(p.forces_N)
    points = [{"amplitude_rad": beta, "amplitude_m": float(amp), "d_over_2A": r, "force_N": f}
              for beta, amp in zip(betas, amps) for r in p.d_over_2A for f in p.forces_N]
    fn = functools.partial(pair_point, duration_s=p.duration_s, force_onset_s=SETTLE_S)
    rf = study_sweep(config, "potential", "force", fn, Grid(points=points, seed=config.seed))
    g = rf.dataset.isel(replicate=0)
    shape = (n_b, n_r, n_f)
    pm = g["dx_period_over_lambda"].values.reshape(*shape, -1)
    pt = g["period_time"].values
    k_before = int(np.flatnonzero(pt < SETTLE_S)[-1])
    last = pm[..., -3:]
    before = pm[..., k_before]
    dxl = last.mean(axis=-1) - before
    drift = np.ptp(last, axis=-1)
    failed = g["run_failed"].values.astype(bool).reshape(shape)
    with np.errstate(invalid="ignore"):
        broken = failed | ~np.isfinite(dxl) | (dxl > BREAK) | (drift > DRIFT)
    k = np.full((n_b, n_r), np.nan)
    dx0 = np.full_like(k, np.nan)
    r2 = np.full_like(k, np.nan)
    n_used = (~broken).sum(axis=-1)
    for i in range(n_b):
        for j in range(n_r):
            k[i, j], dx0[i, j], r2[i, j] = fit_stiffness(p.forces_N, dxl[i, j] * lam, ~broken[i, j])

    R = np.asarray(p.d_over_2A)
    one = {"units": "1"}
    model_thin = np.array([model_dx0_m(R * 2 * a, a, lam) / lam for a in amps])
    model_bodies = np.array([model_dx0_m(R * 2 * a, a, lam, geo.width_m) / lam for a in amps])
    fdims = ("beta", "d_over_2A", "force")
    ds = xr.Dataset(
        {
            "impulse": (("dphi",), impulse, {
                "units": "N s", "long_name": "pair contact impulse over the first 2 periods, mean over phi0"}),
            "impulse_all": (("dphi", "phi0"), imp_all, {
                "units": "N s", "long_name": "pair contact impulse over the first 2 periods"}),
            "dx": (fdims, dxl, {**one, "long_name": "steady extra separation dx / lambda under +-dF"}),
            "dx_before": (fdims, before, {**one, "long_name": "settled dx / lambda"}),
            "drift": (fdims, drift, {**one, "long_name": "range of the last 3 period means of dx / lambda"}),
            "broken": (fdims, broken, {"long_name": f"broke apart (dx/lambda > {BREAK}, still drifting, or failed)"}),
            "run_failed": (fdims, failed, {}),
            "dx_period": ((*fdims, "period_time"), pm, {**one, "long_name": "period mean of dx / lambda"}),
            "stiffness": (("beta", "d_over_2A"), k, {"units": "N/m", "long_name": "k in dF = k (dx - dx0)"}),
            "dx0": (("beta", "d_over_2A"), dx0 / lam, {**one, "long_name": "offset dx0 / lambda of the fit"}),
            "fit_r2": (("beta", "d_over_2A"), r2, {**one, "long_name": "R^2 of the fit"}),
            "fit_n": (("beta", "d_over_2A"), n_used, {**one, "long_name": "points in the fit"}),
            "model_dx0_thin": (("beta", "d_over_2A"), model_thin, {
                **one, "long_name": "compatibility model dx0 / lambda, sinusoids (dy = d - 2A)"}),
            "model_dx0_bodies": (("beta", "d_over_2A"), model_bodies, {
                **one, "long_name": "compatibility model dx0 / lambda, bodies of width w (dy = d - 2A - 2w)"}),
            "amplitude": (("beta",), amps, {"units": "m", "long_name": "gait amplitude A of a free swimmer"}),
        },
        coords={
            "dphi": ("dphi", dphi, {"units": "rad", "long_name": "phase difference phi_b - phi_a"}),
            "phi0": ("phi0", np.asarray(p.impulse_phi0), {"units": "rad", "long_name": "phase phi_a"}),
            "beta": ("beta", np.asarray(p.betas_deg), {"units": "degree", "long_name": "joint amplitude beta"}),
            "d_over_2A": ("d_over_2A", R, {**one, "long_name": "wall spacing over peak-to-peak amplitude"}),
            "force": ("force", np.asarray(p.forces_N), {"units": "N", "long_name": "applied force dF"}),
            "period_time": ("period_time", pt, {"units": "s", "long_name": "middle of the gait period"}),
            "channel_width": (("beta", "d_over_2A"), np.outer(2 * amps, R), {"units": "m", "long_name": "d"}),
        },
        attrs={
            "title": "contact force against detuning; cohesion stiffness of the compatible state (paper Fig. 10)",
            "impulse_channel_width_m": PAIR_WIDTH_M,
            "settle_s": SETTLE_S,
            "duration_s": p.duration_s,
            "impulse_fit_abs": list(fit_a),
            "wavelength_m": lam,
        },
    )
    summary = _summary(ds, fit_a, fit_pos, fit_neg, [ra, rf])
    return StudyResult(dataset=ds, figure=plot_potential(ds), summary=summary)


def _collapse_rms(x, logk) -> float:
    """RMS of log10 k about one quadratic in ``x`` pooled over every beta."""
    x, logk = np.asarray(x, float).ravel(), np.asarray(logk, float).ravel()
    ok = np.isfinite(x) & np.isfinite(logk)
    if ok.sum() < 4 or np.unique(x[ok]).size < 3:
        return float("nan")
    u = (x[ok] - x[ok].mean()) / x[ok].std()  # centred and scaled: a well-conditioned fit
    c = np.polyfit(u, logk[ok], 2)
    return float(np.sqrt(np.mean((logk[ok] - np.polyval(c, u)) ** 2)))


def _summary(ds, fit_a, fit_pos, fit_neg, results) -> dict[str, Any]:
    k = ds["stiffness"].values
    R = ds["d_over_2A"].values
    with np.errstate(invalid="ignore", divide="ignore"):
        logk = np.where(k > 0, np.log10(k), np.nan)
    x_scaled = np.broadcast_to(R, k.shape)
    x_metres = ds["channel_width"].values
    sliding = x_scaled >= SLIDING_FROM - 1e-9
    per_beta = {}
    for i, b in enumerate(ds["beta"].values):
        ok = np.isfinite(k[i])
        per_beta[f"{b:g}"] = {
            "amplitude_m": float(ds["amplitude"].values[i]),
            "stiffness_N_per_m": k[i],
            "dx0_over_lambda": ds["dx0"].values[i],
            "fit_r2": ds["fit_r2"].values[i],
            "fit_points": ds["fit_n"].values[i],
            "spearman_k_vs_d": _spearman(R[ok], k[i][ok]),
            "model_dx0_thin_over_lambda": ds["model_dx0_thin"].values[i],
            "model_dx0_bodies_over_lambda": ds["model_dx0_bodies"].values[i],
        }
    failed = [f for r in results for f in r.failures]
    return {
        "impulse_fit": {"slope_Ns_per_rad": fit_a[0], "intercept_Ns": fit_a[1], "r2": fit_a[2],
                        "positive_dphi": list(fit_pos), "negative_dphi": list(fit_neg),
                        "form": "impulse = slope |dphi| + intercept"},
        "impulse_Ns": ds["impulse"].values,
        "dphi_rad": ds["dphi"].values,
        "d_over_2A": R,
        "per_beta": per_beta,
        "median_fit_r2": float(np.nanmedian(ds["fit_r2"].values)),
        "collapse_rms_log10k_vs_d_over_2A": _collapse_rms(x_scaled.ravel(), logk.ravel()),
        "collapse_rms_log10k_vs_d_m": _collapse_rms(x_metres.ravel(), logk.ravel()),
        "collapse_rms_log10k_vs_d_over_2A_sliding": _collapse_rms(x_scaled[sliding], logk[sliding]),
        "collapse_rms_log10k_vs_d_m_sliding": _collapse_rms(x_metres[sliding], logk[sliding]),
        "sliding_regime": f"d/2A >= {SLIDING_FROM} (below it the pair is wedged between the walls)",
        "n_points_broken": int(ds["broken"].values.sum()),
        "n_points": int(ds["broken"].size),
        "n_failed": len(failed),
        "failures": [str(f) for f in failed[:20]],
        "sweep_elapsed_s": float(sum(r.elapsed_s for r in results)),
        "rules": f"dx: mean of last 3 periods minus the period before onset ({SETTLE_S} s); broken: "
                 f"dx/lambda > {BREAK} or last-3-period range > {DRIFT} lambda; fit by least squares of dF on dx",
    }


@register("potential", paper_figure="10",
          description="Contact impulse over the first two periods against dphi; equal and opposite "
                      "forces on a settled dphi = 0 pair: dF = k (dx - dx0) per d/2A and beta, with "
                      "the compatibility model's dx0.")
def run(config: StudyConfig) -> StudyResult:
    return compute(config, plan(config.quick))
