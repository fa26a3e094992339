"""Study ``basins`` (paper Fig. 8): where pairs end up from a given start.

Two swimmers in the paper's "wall separation d = 13 cm" channel (0.13 m wall
to wall: confinement ``d/2A = 0.62`` with ``d`` the wall distance per
swimmer, :func:`undulate.theory.confinement_d_over_2A`, below the ``d/2A``
about 1 above which a detuned pair pushes itself apart, as the paper says of
it: "swimmers cannot push each other away laterally"; docs/confinement_d.md),
``xi = 1``, started straight and laterally in contact at an offset ``dx0`` (``Scene.dx0_m``), run for 15 periods (30 s).

* (8a) ``dphi = 0`` from ``dx0 / lambda`` across ``[-1, 1]``: ``dx(t)``.
  Starts near 0 return to the compatible ``dx = 0``; starts beyond a
  threshold are pushed away (toward the next branch, ``dx = +-lambda``).
  The threshold is **measured**, on each side: a coarse scan brackets the
  change of outcome, then a second sweep refines the bracket
  (:func:`returns_to_zero`, :func:`bracket_threshold`).  A start "returns"
  when its final ``|dx / lambda|`` is below :data:`RETURN_TOL`.
* (8b) the ``(dx0 / lambda, dphi)`` grid: the map of ``dx_f - dx0`` (the
  final offset is the mean of the last three periods), beside the
  sinusoidal theory :func:`undulate.theory.sinusoid_basin_displacement`
  (target ``"line"``, the paper's) with the lateral clearance the channel
  leaves two bodies of width ``w`` and stroke ``A`` (``max(0, W - 2A -
  2w)`` for the channel's whole width ``W``, :func:`undulate.theory.lateral_clearance_m`;
  0 at ``W = 0.13 m``).

Runs: :func:`._runners.pair_point`.  The threshold's uncertainty is its
bracket (the last start that returned, the first that was pushed away).

Discrete clusters (a stair-step) against the sinusoid's line (:func:`stair_steps`)
-------------------------------------------------------------------------------
The paper (Sec. III.C, explained in III.F by Fig. 8b) says the three-link equilibria form "discrete
clusters along the compatibility prediction line" where the sinusoids give a line.  On the grid's final
offsets: two neighbouring phases ``dphi_j``, ``dphi_(j+1)`` from the same start form a *tread* when their
final ``dx / lambda`` differ, modulo whole wavelengths (a start that ends on the next branch of the same
level), by less than half the line's step ``(dphi_(j+1) - dphi_j) / 2 pi`` (nearer no change than the
line's change).  A linear relation gives no treads; ``m`` levels per branch on ``J``
phases give a share of about ``1 - m / J``.  "Discrete clusters" is read as at most half as many levels
as phases: the share of treads above 1/2, and above the sinusoidal map's own share on the same grid
(its final offsets ``dx0 + (dx_f - dx0)_theory``).  "Along the line": the mean distance of the final
offsets from the nearest compatible branch, ``|psi| / 2 pi`` (:func:`undulate.theory.phase_mismatch`),
below 1/4, the mean of offsets unrelated to the line (uniform).  Intervals: bootstrap over the starts
(rows of the grid, resampled whole; BCa).

Only runs whose pair *touched* count (``grid_touched``: a swimmer-swimmer contact impulse over the first
two periods above zero, ``impulse_2T_Ns`` of :func:`._runners.pair_point`; a pair started laterally in
contact with overlapping bodies touches at once).  Starts a whole wavelength apart (``dx0 = +-lambda``,
bodies one body length apart) never touch: each run ends where it began, so every neighbouring phase
pair in such a row is a "tread" without any interaction, and its offsets sit ``|dphi| / 2 pi`` from the
line for the same reason.  A tread is therefore counted only between two runs that both touched, the
line distance only over runs that touched, and the sinusoidal map's share on the same pairs.  The first
criterion counted every start; it is kept beside the claim (:attr:`~._protocol.Claim.superseded`) with
its verdict.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from .. import stats, theory
from ..errors import ParameterError
from ..params import Gait, SwimmerGeometry
from ._criteria import PAIR_CHANNEL_M, RETURN_TOL
from ._context import StudyContext
from ._protocol import Claim, Study, SupersededCriterion, Verdict
from ._registry import register
from ._stages import strides, thinned
from ._runners import PAIR_DURATION_S, PAIR_STOP, pair_point

__all__ = [
    "RETURN_TOL",
    "BasinsPlan",
    "plan",
    "returns_to_zero",
    "bracket_threshold",
    "dataset",
    "summary",
    "CLAIMS",
]

DURATION_S = PAIR_DURATION_S


# ----------------------------------------------------------------- thresholds
def returns_to_zero(dx_final_over_lambda) -> np.ndarray:
    """True where a dphi = 0 start ended in the central state: ``|dx_f / lambda| < RETURN_TOL``."""
    return np.abs(np.asarray(dx_final_over_lambda, float)) < RETURN_TOL


def bracket_threshold(dx0, returned) -> tuple[float, float]:
    """The bracket ``(inner, outer)`` of the return threshold on one side.

    ``dx0``: starts on one side of 0 (any sign), ``returned``: their outcome.
    ``inner`` is the farthest start (from 0) that returned with every start
    nearer 0 also returning; ``outer`` the nearest one beyond it that did
    not.  ``outer`` is NaN when every start returned.
    """
    x = np.asarray(dx0, float)
    r = np.asarray(returned, bool)
    o = np.argsort(np.abs(x))
    x, r = x[o], r[o]
    if not r.any() or not r[0]:
        return float("nan"), float(x[0]) if x.size else float("nan")
    k = int(np.argmin(r)) if not r.all() else x.size
    inner = float(x[k - 1])
    outer = float(x[k]) if k < x.size else float("nan")
    return inner, outer


# --------------------------------------------------------------------- the study
class BasinsPlan:
    """Starts for 8a (coarse, then ``refine`` points inside each side's bracket)
    and the 8b grid."""

    def __init__(self, scan_dx0, refine: int, grid_dx0, grid_dphi, duration_s: float = DURATION_S):
        self.scan_dx0 = [float(v) for v in scan_dx0]
        self.refine = int(refine)
        self.grid_dx0 = [float(v) for v in grid_dx0]
        self.grid_dphi = [float(v) for v in grid_dphi]
        self.duration_s = float(duration_s)


def plan(quick: bool) -> BasinsPlan:
    """Full: 41 starts (step 0.05 lambda) + 2 x 19 refinements (bracket / 20);
    grid 41 x 41 = 1681 runs.  Quick: 21 starts + 2 x 4; grid 9 x 9."""
    if quick:
        return BasinsPlan(np.linspace(-1, 1, 21), 4, np.linspace(-1, 1, 9), np.linspace(-np.pi, np.pi, 9))
    return BasinsPlan(np.linspace(-1, 1, 41), 19, np.linspace(-1, 1, 41), np.linspace(-np.pi, np.pi, 41))


def _scan(ctx: StudyContext, part, starts, duration_s):
    from ..sweep import Grid

    fn = functools.partial(pair_point, duration_s=duration_s, stop=PAIR_STOP)
    grid = Grid(axes={"dx0_over_lambda": sorted(set(round(v, 12) for v in starts))}, seed=ctx.seed)
    return ctx.sweep(part, fn, grid)


def _refinement(scan_dx0, final, n: int) -> list[float]:
    """``n`` equally spaced starts strictly inside each side's bracket."""
    x = np.asarray(scan_dx0, float)
    ret = returns_to_zero(final)
    out: list[float] = []
    for side in (x > 0, x < 0):
        inner, outer = bracket_threshold(x[side], ret[side] & np.isfinite(final[side]))
        if n > 0 and np.isfinite(inner) and np.isfinite(outer):
            out += list(np.linspace(inner, outer, n + 2)[1:-1])
    return out


def dataset(ctx: StudyContext, p: BasinsPlan):
    """Run the basins study on plan ``p``: the dphi = 0 scan and its refinement, and the grid (side
    by side where the study runs wide, :meth:`StudyContext.together`)."""
    import xarray as xr

    from ..sweep import Grid

    geo = SwimmerGeometry()
    lam = Gait().wavelength_m(geo.length_m)
    amp = float(ctx.lone_swimmer()["amplitude_m"])

    def scan():  # 8a: coarse scan at dphi = 0, then refine each side's bracket
        s0 = _scan(ctx, "scan", p.scan_dx0, p.duration_s).isel(replicate=0)
        extra = _refinement(s0["dx0_over_lambda"].values, s0["dx_final_over_lambda"].values, p.refine)
        if extra:
            ref = _scan(ctx, "refine", extra, p.duration_s)
            s0 = xr.concat([s0, ref.isel(replicate=0)], dim="dx0_over_lambda").sortby("dx0_over_lambda")
        return s0

    def grid():  # 8b: the (dx0, dphi) grid, independent of the scan
        fn = functools.partial(pair_point, duration_s=p.duration_s, stop=PAIR_STOP)
        axes = {"dx0_over_lambda": p.grid_dx0, "dphi_rad": p.grid_dphi}
        return ctx.sweep("grid", fn, Grid(axes=axes, seed=ctx.seed)).isel(replicate=0)

    s0, g = ctx.together(scan, grid)
    x0 = s0["dx0_over_lambda"].values
    xf = s0["dx_final_over_lambda"].values
    ret = returns_to_zero(xf) & np.isfinite(xf)
    sides = {}
    for label, side in (("positive", x0 > 0), ("negative", x0 < 0)):
        inner, outer = bracket_threshold(x0[side], ret[side])
        sides[label] = (inner, outer)

    X0, P = np.meshgrid(g["dx0_over_lambda"].values, g["dphi_rad"].values, indexing="ij")
    clearance = theory.lateral_clearance_m(PAIR_CHANNEL_M, amp, geo.width_m)
    th = theory.sinusoid_basin_displacement(X0 * lam, P, amp, lam, dy_m=clearance) / lam
    sim = g["dx_final_over_lambda"].values - X0

    one = {"units": "1"}
    ds = xr.Dataset(
        {
            "scan_dx_over_lambda": (("start", "time"), s0["dx_over_lambda"].values, {
                **one, "long_name": "dx / lambda over time, dphi = 0 (Fig. 8a)"}),
            "scan_dx_final_over_lambda": (("start",), xf, {**one, "long_name": "final dx / lambda, dphi = 0"}),
            "scan_returned": (("start",), ret, {"long_name": f"ended with |dx/lambda| < {RETURN_TOL}"}),
            "scan_steady": (("start",), s0["steady"].values == 1, {"long_name": "steady by the end"}),
            "grid_dx_final_over_lambda": (("dx0", "dphi"), g["dx_final_over_lambda"].values, {
                **one, "long_name": "final dx / lambda"}),
            "grid_displacement_over_lambda": (("dx0", "dphi"), sim, {
                **one, "long_name": "simulated (dx_f - dx0) / lambda (Fig. 8b left)"}),
            "theory_displacement_over_lambda": (("dx0", "dphi"), th, {
                **one, "long_name": "sinusoid basin model (dx_f - dx0) / lambda (Fig. 8b right)"}),
            "grid_steady": (("dx0", "dphi"), g["steady"].values == 1, {"long_name": "steady by the end"}),
            "grid_run_failed": (("dx0", "dphi"), g["run_failed"].values.astype(bool), {}),
            "grid_impulse_2T_Ns": (("dx0", "dphi"), g["impulse_2T_Ns"].values, {
                "units": "N s", "long_name": "swimmer-swimmer contact impulse over the first 2 periods"}),
            "grid_touched": (("dx0", "dphi"), g["impulse_2T_Ns"].values > 0, {
                "long_name": "the pair touched (contact impulse over the first 2 periods > 0)"}),
            "amplitude": ((), amp, {"units": "m", "long_name": "gait amplitude A of a free swimmer"}),
        },
        coords={
            "start": ("start", x0, {**one, "long_name": "initial dx0 / lambda (dphi = 0)"}),
            "time": ("time", s0["time"].values, {"units": "s"}),
            "dx0": ("dx0", g["dx0_over_lambda"].values, {**one, "long_name": "initial dx0 / lambda"}),
            "dphi": ("dphi", g["dphi_rad"].values, {"units": "rad", "long_name": "phase difference phi_b - phi_a"}),
        },
        attrs={
            "title": "basins of attraction of a pair, d = 0.13 m (paper Fig. 8)",
            "channel_width_m": PAIR_CHANNEL_M,
            "confinement_d_over_2A": float(theory.confinement_d_over_2A(PAIR_CHANNEL_M, amp, 2)),
            "duration_s": p.duration_s,
            "return_tol": RETURN_TOL,
            "theory_dy_m": clearance,
            "threshold_positive": list(sides["positive"]),
            "threshold_negative": list(sides["negative"]),
        },
    )
    return ds


def _pearson(a, b) -> float:
    if np.ptp(a) == 0 or np.ptp(b) == 0:
        return math.nan
    return float(np.corrcoef(a, b)[0, 1])


def _ratio_of_sums(a, b, axis=-1):
    return np.sum(a, axis=axis) / np.sum(b, axis=axis)


def _row_share(num, den) -> stats.Estimate:
    """``sum(num) / sum(den)`` over the rows with ``den > 0``, with a BCa bootstrap over the rows."""
    num, den = np.asarray(num, float), np.asarray(den, float)
    keep = den > 0
    num, den = num[keep], den[keep]
    if not keep.any():
        return stats.Estimate(math.nan, n=0, method="bootstrap BCa over starts")
    v = float(num.sum() / den.sum())
    se, lo, hi = stats.bootstrap(_ratio_of_sums, num, den, vectorized=True)
    k = int(num.size)
    return stats.Estimate(v, se, lo, hi, int(den.sum()), "bootstrap BCa over starts", stats.level(), k, k - 1)


def stair_steps(dx_final_over_lambda, dphi_rad, touched=None) -> dict[str, Any]:
    """Treads and distance from the compatibility line of a grid of final offsets (module docstring).

    ``dx_final_over_lambda``: (start, dphi) final dx / lambda; ``dphi_rad``: the grid's phases, rad,
    ascending; ``touched``: (start, dphi) whether each run's pair touched (None: every run counts, the
    superseded reading).  Returns ``tread_share`` (share of neighbouring-phase pairs from one start, both
    runs touched, whose final offsets differ, modulo 1, by less than half the line's step) and
    ``line_distance`` (mean ``|psi| / 2 pi`` of the final offsets of runs that touched), each an Estimate
    dict with a bootstrap interval over the starts, and their counts (``n_untouched``: runs left out)."""
    x = np.asarray(dx_final_over_lambda, float)
    p = np.asarray(dphi_rad, float).ravel()
    if x.ndim != 2 or x.shape[1] != p.size:
        raise ParameterError("dx_final_over_lambda", f"a (start, dphi) grid with {p.size} phases", x.shape)
    if p.size > 1 and np.any(np.diff(p) <= 0):
        raise ParameterError("dphi_rad", "ascending phases", p)
    if touched is None:
        t = np.ones(x.shape, bool)
    else:
        t = np.asarray(touched)
        if t.shape != x.shape or t.dtype != bool:
            raise ParameterError("touched", f"a boolean (start, dphi) grid of shape {x.shape}", t.shape)
    x = np.where(t, x, np.nan)  # a run whose pair never touched tells nothing of the interaction
    step = np.diff(p) / (2 * np.pi)  # the line's change between neighbouring phases, lambda
    with np.errstate(invalid="ignore"):  # a change of branch (whole wavelengths) is no change of level
        change = np.abs((np.diff(x, axis=1) + 0.5) % 1.0 - 0.5)
        pair = np.isfinite(change)
        tread = pair & (change < step / 2)
    psi = np.abs(theory.phase_mismatch(p[None, :], x, 1.0)) / (2 * np.pi)
    fin = np.isfinite(x)
    return {"tread_share": _row_share(tread.sum(axis=1), pair.sum(axis=1)).to_dict(),
            "line_distance": _row_share(np.where(fin, psi, 0.0).sum(axis=1), fin.sum(axis=1)).to_dict(),
            "n_pairs": int(pair.sum()), "n_treads": int(tread.sum()), "n_offsets": int(fin.sum()),
            "n_untouched": int((~t).sum()), "n_starts": int(x.shape[0]), "n_phases": int(p.size)}


def summary(ds) -> dict[str, Any]:
    """Pure: return thresholds (bracket as interval), counts of outcomes, agreement of the grid
    with the sinusoid model (Pearson r with a bootstrap interval)."""
    sim = ds["grid_displacement_over_lambda"].values
    th = ds["theory_displacement_over_lambda"].values
    ok = np.isfinite(sim)
    big = ok & (np.abs(th) > 0.02)
    agree = float(np.mean(np.sign(sim[big]) == np.sign(th[big]))) if big.any() else float("nan")
    corr = _pearson(sim[ok].ravel(), th[ok].ravel()) if ok.sum() > 2 else float("nan")
    se, lo, hi = stats.bootstrap(_pearson, sim[ok].ravel(), th[ok].ravel())
    sides = {"positive": ds.attrs["threshold_positive"], "negative": ds.attrs["threshold_negative"]}
    thr = {}
    for label, (inner, outer) in sides.items():
        inner, outer = float(inner), float(outer)
        mid = 0.5 * (inner + outer) if np.isfinite(inner) and np.isfinite(outer) else float("nan")
        est = stats.Estimate(mid, math.nan, min(inner, outer), max(inner, outer), 0,
                             "bracket: last start that returned .. first pushed away") if np.isfinite(mid) \
            else stats.Estimate(math.nan, method="not bracketed")
        thr[label] = {"last_returning_dx0_over_lambda": inner, "first_pushed_dx0_over_lambda": outer,
                      "threshold_dx0_over_lambda": est.to_dict(),
                      "resolution": abs(outer - inner) / 2 if np.isfinite(mid) else None}
    ret = ds["scan_returned"].values
    far = ~ret & np.isfinite(ds["scan_dx_final_over_lambda"].values)
    x0 = ds["start"].values
    xf = ds["scan_dx_final_over_lambda"].values
    pushed_away = far & (np.abs(xf) > np.abs(x0))
    touched = np.asarray(ds["grid_touched"].values, bool)
    return {
        "amplitude_m": float(ds["amplitude"]),
        "return_threshold": thr,
        "n_starts_dphi0": int(x0.size),
        "n_returned": int(ret.sum()),
        "n_pushed_away_from_zero": int(pushed_away.sum()),
        "n_neither": int((far & ~pushed_away).sum()),
        "grid_shape": list(sim.shape),
        "grid_sign_agreement_with_theory": agree,
        "grid_correlation_with_theory": stats.Estimate(corr, se, lo, hi, int(ok.sum()),
                                                       "Pearson r, bootstrap BCa", stats.level(),
                                                       int(ok.sum()), int(ok.sum()) - 1).to_dict(),
        "grid_not_steady": int((~ds["grid_steady"].values).sum()),
        "n_grid_failed": int(ds["grid_run_failed"].values.sum()),
        "stair_steps": stair_steps(ds["grid_dx_final_over_lambda"].values, ds["dphi"].values, touched),
        "stair_steps_sinusoid": stair_steps(ds["dx0"].values[:, None] + th, ds["dphi"].values, touched),
        "stair_steps_all_starts": stair_steps(ds["grid_dx_final_over_lambda"].values, ds["dphi"].values),
        "stair_steps_sinusoid_all_starts": stair_steps(ds["dx0"].values[:, None] + th, ds["dphi"].values),
        "grid_touched": int(touched.sum()),
        "rule": f"returned: final |dx/lambda| < {RETURN_TOL} (mean of the last 3 of 15 periods)",
    }


E = stats.Estimate.from_dict


def _return_and_push(s: dict) -> Verdict:
    ret, away = s["n_returned"], s["n_pushed_away_from_zero"]
    tp = E(s["return_threshold"]["positive"]["threshold_dx0_over_lambda"])
    tn = E(s["return_threshold"]["negative"]["threshold_dx0_over_lambda"])
    measured = (f"{ret} of {s['n_starts_dphi0']} starts returned, {away} were pushed away; return threshold "
                f"dx0/lambda = {tn:+.3f} / {tp:+.3f} (bracket)")
    value = {"n_returned": ret, "n_pushed_away": away,
             "threshold_negative": tn.to_dict(), "threshold_positive": tp.to_dict()}
    # counts of outcomes and whether a bracket exists: exact, never undecided
    return Verdict.of([stats.Check.exact(ret > 0, f"{ret} starts returned"),
                       stats.Check.exact(away > 0, f"{away} starts pushed away"),
                       stats.Check.exact(tn.has_interval, "return threshold bracketed on the negative side"),
                       stats.Check.exact(tp.has_interval, "return threshold bracketed on the positive side")],
                      measured, value)


def _clusters(s: dict) -> Verdict:
    """The clusters claim on the runs whose pair touched (module docstring)."""
    return _clusters_on(s["stair_steps"], s["stair_steps_sinusoid"], "of runs whose pair touched: ")


def _clusters_all_starts(s: dict) -> Verdict:
    """The superseded reading: every start counts, those that never touched too."""
    return _clusters_on(s["stair_steps_all_starts"], s["stair_steps_sinusoid_all_starts"], "every start: ")


def _clusters_on(st: dict, sin: dict, which: str) -> Verdict:
    tread, line = E(st["tread_share"]), E(st["line_distance"])
    tread_sin = E(sin["tread_share"]).value
    left = f" ({st['n_untouched']} runs that never touched left out)" if st.get("n_untouched") else ""
    measured = (f"{which}{st['n_treads']} of {st['n_pairs']} neighbouring-phase pairs are treads{left}: share {tread:.2f} "
                f"(sinusoidal map on the same grid: {tread_sin:.2f}); mean distance from the compatibility line "
                f"{line:.3f} lambda (uniform offsets: 0.25) over {st['n_offsets']} final offsets "
                f"({stats.interval_note(tread.level)})")
    value = {"tread_share": st["tread_share"], "tread_share_sinusoid": sin["tread_share"],
             "line_distance": st["line_distance"]}
    if not (tread.finite and line.finite):
        return Verdict.none("too few final offsets on the grid", measured, value)
    return Verdict.of([tread.above(0.5, "share of treads"),
                       tread.above(tread_sin, "share of treads against the sinusoidal map's"),
                       line.below(0.25, "mean distance from the compatibility line (lambda)")], measured, value)


CLAIMS = (
    Claim("dphi = 0 pairs return to dx = 0 from nearby starts and are pushed away from far ones",
          "starts close enough to zero evolve to dx_f = 0; beyond a threshold (withheld) they are pushed away",
          "both behaviours occur and the return threshold is bracketed on both sides (counts of starts and "
          "brackets: holds or fails, never undecided)", _return_and_push,
          quote=(r"Initial separation distances that are far away from the compatible separation (beyond a "
                 r"threshold, withheld) are pushed away from the $\Delta x = 0$ compatible configuration as the "
                 r"swimmers repel each other along the longitudinal axis. However, when the initial separation "
                 r"distances are closer (within that threshold) the swimmers experience an attractive interaction "
                 r"force in the longitudinal direction and ultimately end in the compatible state for there phase "
                 r"difference."),
          where="Sec. III.F, Fig. 8a"),
    Claim("three-link equilibria form discrete clusters (a stair-step) along the compatibility line",
          "the equilibrium dx forms discrete clusters along the compatibility line, where the sinusoidal model "
          "gives a linear phase-displacement relation; the position-change map's minimum is stair-stepped",
          "on the (dx0, dphi) grid's final offsets of the runs whose pair touched (contact impulse over the "
          "first two periods > 0): the share of treads (neighbouring phases from one start, both runs touched, "
          "ending within half the line's step of each other) has its bootstrap interval above 1/2 and above "
          "the sinusoidal map's share on the same pairs, and the mean distance from the nearest compatible "
          "branch |psi|/2pi has its interval below 1/4 (that of offsets unrelated to the line).  Fails if one "
          "interval lies wholly on the wrong side; undecided if one straddles", _clusters,
          superseded=(SupersededCriterion(
              "the same on every start's final offsets, touched or not", _clusters_all_starts,
              why="starts a whole wavelength apart (dx0 = +-lambda) never touch and end where they began, so "
                  "every phase pair in their rows counted as a tread and their offsets as off the line "
                  "without any interaction: the paper's clusters are equilibria the contacts make"),),
          quote=(r"In both experiment and simulation we noticed that the equilibrium $\Delta x$ formed discrete "
                 r"clusters along the compatibility prediction line while the prediction from a sinusoidal model "
                 r"is a linear phase-displacement relationship."),
          where="Sec. III.C (Figs. 3b, 5a); explained in Sec. III.F, Fig. 8b",
          bands={"tread_share": (0.5, None), "line_distance": (None, 0.25)}),
)


def figure(ds):
    from ..plotting.basins import plot_basins

    return plot_basins(ds)


def stages(quick: bool) -> tuple[BasinsPlan, ...]:
    """The plan in looks (:mod:`._stages`): the scan of starts and the (dx0, dphi) grid thinned (quick:
    scan 11, 21; grid 5 x 5, 9 x 9.  Full: scan 11, 21, 41; grid 11 x 11, 21 x 21, 41 x 41)."""
    p, s = plan(quick), strides(quick)
    return tuple(BasinsPlan(x0, p.refine, gx, gp, p.duration_s) for x0, gx, gp in
                 zip(thinned(p.scan_dx0, s), thinned(p.grid_dx0, s), thinned(p.grid_dphi, s)))


register(Study(
    name="basins", paper_figure="8", plan=plan, stages=stages, dataset=dataset, summary=summary, claims=CLAIMS, figure=figure,
    description="Pairs at d = 0.13 m from a range of initial offsets: dx(t) at dphi = 0 and "
                "its return threshold; the map of dx_f - dx0 over (dx0/lambda, dphi) beside "
                "the sinusoidal basin model."))
