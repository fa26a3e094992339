"""Study ``confinement`` (paper Fig. 9): the central state against wall spacing.

Pairs with ``dphi = 0`` start laterally in contact at ``dx0 / lambda``
across ``[-1, 1]`` in channels of confinement ``d / 2A`` (``A`` the
measured gait amplitude of a free swimmer) from 0.6 to 1.2, the paper's
range, and on to 1.5 (quick) or 1.6 (full) to show where the walls stop
holding the pair together.  ``d`` is the paper's wall distance per swimmer:
the pair's channel is ``W = 2 d`` wall to wall
(:func:`undulate.theory.channel_width_m`; 125-251 mm over the paper's range
for ``2A = 104.5 mm``), the reading under which an in-phase pair is
obstructed below ``d/2A`` about 0.5 and a detuned pair pushes itself apart
above about 1, as the paper says (docs/confinement_d.md).  The final ``dx / lambda`` (mean of the last 3 of 20
periods) is plotted against the start, per confinement.

The *central state* of one confinement is the set of final offsets of the
starts that end near 0 (``|dx_f / lambda| < 0.5``, i.e. not pushed to a
neighbouring branch ``+-lambda``).  Its width is the range ``max - min`` of
those final offsets (:func:`central_state`); a pair that always returns to
exactly 0 has width 0.  The compatibility model predicts a band of
half-width ``(1 / pi) arcsin(dy / 2A)`` (in lambda) for a lateral clearance
``dy`` (see :mod:`undulate.studies.potential` for the clearance the walls
leave in the channel ``W``, :func:`undulate.theory.neutral_offset_m`): the model widths are
stored beside the measured ones.  The width is a range of final offsets,
not a fitted number: its resolution is set by the time the runs settle,
not by sampling, so it carries no interval.

The claim ("the central compatibility state broadened" as the wall distance
grew) is judged as a trend over the paper's range 0.6-1.2
(:data:`~._criteria.CONFINEMENT_TREND_RULE`): the least-squares slope of
the widths against ``d/2A`` there, with its Student-t interval
(:func:`broadening_trend`).  The quick plan has four confinements in the
range (0.6, 0.8, 1.0, 1.2) so that the slope has an interval on 2 degrees
of freedom, and 1.5 beyond it; the full plan thirteen (steps of 0.05: the
slope's interval narrows with confinements in the range, not with starts;
:func:`plan`).  The claim's earlier
criterion, step by step (no width narrower than the one before by more
than :data:`~._criteria.WIDTH_TOL`, over every confinement run), is judged
beside it (:attr:`~._protocol.Claim.superseded`).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from .. import stats
from ..errors import ParameterError
from ..params import Gait, SwimmerGeometry
from ..stats import Check
from ..theory import channel_width_m, neutral_offset_m
from ._criteria import CENTRAL, CONFINEMENT_TREND_RULE, WIDTH_TOL
from ._context import StudyContext
from ._protocol import Claim, Study, SupersededCriterion, Verdict
from ._registry import register
from ._stages import strides
from ._runners import PAIR_STOP, pair_point

__all__ = ["ConfinementPlan", "plan", "central_state", "broadening_trend", "dataset", "summary", "CLAIMS",
           "PAPER_RANGE"]

DURATION_S = 40.0
"""20 gait periods, s: long enough for the widest channels' central state to settle."""
PAPER_RANGE = (0.6, 1.2)


class ConfinementPlan:
    """Grid: ``d_over_2A`` x ``dx0_over_lambda``."""

    def __init__(self, d_over_2A, dx0_over_lambda, duration_s: float = DURATION_S):
        self.d_over_2A = [float(v) for v in d_over_2A]
        self.dx0_over_lambda = [float(v) for v in dx0_over_lambda]
        self.duration_s = float(duration_s)


def plan(quick: bool) -> ConfinementPlan:
    """Full: d/2A 0.6 to 1.2 in steps of 0.05 (13, the paper's range) and 1.3 to 1.6 in 0.1 (4) x 21
    starts = 357 runs; quick: d/2A 0.6, 0.8, 1.0, 1.2, 1.5 x 11 starts = 55.

    The claim is a slope over the paper's range, and its interval is set by the number of confinements in
    that range, not by the starts: the width at one confinement is a range of final offsets, with no
    replicate noise, so its scatter about the line is the trend's own shape, which no number of starts
    averages away.  Hence 13 confinements in the range (11 degrees of freedom; the 0.1 grid's 7 left 5, and
    its 41 starts a look bought nothing toward deciding it) and 21 starts (0.1 lambda apart).  Quick's four
    confinements in the range give the slope an interval on 2 degrees of freedom (three would leave 1: a
    t quantile of 12.7); 1.5 shows where the walls stop holding the pair together."""
    if quick:
        return ConfinementPlan([0.6, 0.8, 1.0, 1.2, 1.5], np.linspace(-1, 1, 11))
    d = np.round(np.r_[np.arange(0.6, 1.2001, 0.05), np.arange(1.3, 1.6001, 0.1)], 10)
    return ConfinementPlan(d, np.linspace(-1, 1, 21))


def central_state(dx0, dx_final) -> dict[str, float]:
    """Width and extent of the central state along one confinement.

    ``dx0``, ``dx_final``: starts and final offsets, in lambda.  Returns
    ``width`` (max - min of the final offsets with ``|dx_f| < CENTRAL``),
    ``lo``/``hi`` (their extremes), ``basin_lo``/``basin_hi`` (the extreme
    starts that ended there) and ``n`` (how many did); NaN when none did.
    """
    x0 = np.asarray(dx0, float)
    xf = np.asarray(dx_final, float)
    c = np.isfinite(xf) & (np.abs(xf) < CENTRAL)
    if not c.any():
        nan = float("nan")
        return {"width": nan, "lo": nan, "hi": nan, "basin_lo": nan, "basin_hi": nan, "n": 0}
    return {"width": float(xf[c].max() - xf[c].min()), "lo": float(xf[c].min()), "hi": float(xf[c].max()),
            "basin_lo": float(x0[c].min()), "basin_hi": float(x0[c].max()), "n": int(c.sum())}


def _in_paper_range(d_over_2A) -> np.ndarray:
    r = np.asarray(d_over_2A, float)
    return (r >= PAPER_RANGE[0] - 1e-9) & (r <= PAPER_RANGE[1] + 1e-9)


def broadening_trend(d_over_2A, width_over_lambda) -> stats.LineFit:
    """The claim's trend (:data:`~._criteria.CONFINEMENT_TREND_RULE`): the least-squares line of the
    central state's width (lambda) on ``d/2A`` over the paper's range :data:`PAPER_RANGE`, the
    confinements with a central state only (finite widths), by :func:`undulate.stats.line_fit`
    (``scipy.stats.linregress``; Student-t intervals on ``n - 2`` degrees of freedom at the look's
    level).  Its slope is in lambda per unit ``d/2A``; no interval with fewer than 3 widths in the range.
    Equal widths (a state closed, width 0, throughout the range) lie exactly on a flat line: slope 0,
    interval [0, 0]."""
    r = np.asarray(d_over_2A, float)
    w = np.asarray(width_over_lambda, float)
    if r.ndim != 1 or r.shape != w.shape:
        raise ParameterError("width_over_lambda", f"one width per d/2A ({r.size} values, 1-D)", w.shape)
    keep = _in_paper_range(r) & np.isfinite(w)
    return stats.line_fit(r[keep], w[keep])


def dataset(ctx: StudyContext, p: ConfinementPlan):
    """Run the confinement study on plan ``p``: the free swimmer's A sets every d, then the grid."""
    import xarray as xr

    from ..sweep import Grid

    model_dx0_m = neutral_offset_m
    geo = SwimmerGeometry()
    lam = Gait().wavelength_m(geo.length_m)
    amp = float(ctx.lone_swimmer()["amplitude_m"])
    fn = functools.partial(pair_point, duration_s=p.duration_s, amplitude_m=amp, stop=PAIR_STOP)
    grid = Grid(axes={"d_over_2A": p.d_over_2A, "dx0_over_lambda": p.dx0_over_lambda}, seed=ctx.seed)
    g = ctx.sweep("grid", fn, grid).isel(replicate=0)
    xf = g["dx_final_over_lambda"].values
    x0 = g["dx0_over_lambda"].values
    stats = [central_state(x0, xf[i]) for i in range(xf.shape[0])]
    r = np.asarray(p.d_over_2A)
    width = channel_width_m(r, amp, n_swimmers=2)
    one = {"units": "1"}
    failed = g["run_failed"].values.astype(bool)
    ds = xr.Dataset(
        {
            "dx_final_over_lambda": (("d_over_2A", "dx0"), xf, {**one, "long_name": "final dx / lambda"}),
            "dx_over_lambda": (("d_over_2A", "dx0", "time"), g["dx_over_lambda"].values, {
                **one, "long_name": "dx / lambda over time"}),
            "steady": (("d_over_2A", "dx0"), np.where(failed, False, g["steady"].values == 1), {
                "long_name": "steady by the end"}),
            "run_failed": (("d_over_2A", "dx0"), failed, {}),
            "mean_joint_error": (("d_over_2A", "dx0"), g["mean_joint_error_rad"].values, {"units": "rad"}),
            "central_width": (("d_over_2A",), [s["width"] for s in stats], {
                **one, "long_name": "range of final dx / lambda in the central state"}),
            "central_lo": (("d_over_2A",), [s["lo"] for s in stats], {**one}),
            "central_hi": (("d_over_2A",), [s["hi"] for s in stats], {**one}),
            "basin_lo": (("d_over_2A",), [s["basin_lo"] for s in stats], {
                **one, "long_name": "most negative start ending in the central state"}),
            "basin_hi": (("d_over_2A",), [s["basin_hi"] for s in stats], {
                **one, "long_name": "most positive start ending in the central state"}),
            "model_width_thin": (("d_over_2A",), 2 * model_dx0_m(width, amp, lam) / lam, {
                **one, "long_name": "compatibility band width, sinusoids (clearance W - 2A)"}),
            "model_width_bodies": (("d_over_2A",), 2 * model_dx0_m(width, amp, lam, geo.width_m) / lam, {
                **one, "long_name": "compatibility band width, bodies of width w (clearance W - 2A - 2w)"}),
            "amplitude": ((), amp, {"units": "m", "long_name": "gait amplitude A of a free swimmer"}),
        },
        coords={
            "d_over_2A": ("d_over_2A", r, {**one, "long_name": "wall distance per swimmer over peak-to-peak "
                                                                "amplitude"}),
            "dx0": ("dx0", x0, {**one, "long_name": "initial dx0 / lambda"}),
            "time": ("time", g["time"].values, {"units": "s"}),
            "channel_width": ("d_over_2A", width, {"units": "m", "long_name": "channel width W = 2 d, wall to wall "
                                                                               "(undulate.theory.channel_width_m)"}),
        },
        attrs={"title": "final offset against start per confinement, dphi = 0 (paper Fig. 9)",
               "duration_s": p.duration_s, "paper_range_d_over_2A": list(PAPER_RANGE)},
    )
    return ds


def summary(ds) -> dict[str, Any]:
    """Pure: the central state's width per confinement, the model's, its trend over the paper's range
    (:func:`broadening_trend`: ``broadening_slope_per_d_over_2A``, the claim's) and whether it ever
    shrinks from one confinement to the next (``width_never_shrinks_with_d``, the superseded criterion's)."""
    r = ds["d_over_2A"].values
    w = ds["central_width"].values
    in_paper = _in_paper_range(r)
    trend = broadening_trend(r, w)
    ok = np.isfinite(w)
    grows = bool(np.all(np.diff(w[ok]) >= -WIDTH_TOL)) if ok.sum() > 1 else None
    broad = r[ok & (w > WIDTH_TOL)]
    return {
        "amplitude_m": float(ds["amplitude"]),
        "d_over_2A": r,
        "channel_width_m": ds["channel_width"].values,
        "central_width_over_lambda": w,
        "central_range_over_lambda": np.stack([ds["central_lo"].values, ds["central_hi"].values], axis=-1),
        "basin_of_central_state_dx0_over_lambda": np.stack([ds["basin_lo"].values, ds["basin_hi"].values], axis=-1),
        "model_width_thin_over_lambda": ds["model_width_thin"].values,
        "model_width_bodies_over_lambda": ds["model_width_bodies"].values,
        # the claim's criterion (CONFINEMENT_TREND_RULE): lambda per unit d/2A, over the paper's range
        "broadening_slope_per_d_over_2A": trend.slope.to_dict(),
        "broadening_intercept_over_lambda": trend.intercept.to_dict(),
        "n_runs_in_broadening_fit": int(trend.n * ds.sizes["dx0"]),
        # the superseded step-by-step criterion's: True, False, or None with fewer than 2 widths
        "width_never_shrinks_with_d": grows,
        "smallest_d_over_2A_with_width_above_0.01": float(broad.min()) if broad.size else None,
        "max_width_in_paper_range": float(np.nanmax(w[in_paper])) if np.any(in_paper & ok) else None,
        "n_runs": int(ds["run_failed"].size),
        "n_failed": int(ds["run_failed"].values.sum()),
        "n_not_steady": int((~ds["steady"].values & ~ds["run_failed"].values).sum()),
        "rule": f"central state: final |dx/lambda| < {CENTRAL}; final = mean of the last 3 periods",
    }


def _widths_text(d, w) -> str:
    return ("width of the central state / lambda at d/2A = "
            + ", ".join(f"{a:.2f}: {'n/a' if x is None or not np.isfinite(x) else format(x, '.3f')}"
                        for a, x in zip(d, w)))


def _numbers(xs) -> list[float | None]:
    """Plain floats for ``claims.json`` (None where there is no width)."""
    return [float(x) if x is not None and np.isfinite(x) else None for x in xs]


def _slope_check(slope: stats.Estimate, what: str) -> Check:
    """:data:`~._criteria.CONFINEMENT_TREND_RULE` on the slope's interval: its lower end above 0 holds;
    its upper end at or below 0 fails (a state closed throughout the range, 0 [0, 0], too: it never
    broadened); else undecided, with about how many confinements would decide it."""
    if slope.low > 0:
        return Check(True, f"{what} {slope:.3g}: lower end above 0")
    if slope.high <= 0:
        return Check(False, f"{what} {slope:.3g}: upper end at or below 0")
    n = stats.runs_needed(slope, 0.0)
    return Check(None, f"{what} {slope:.3g} straddles 0", n, None if n is None else n / slope.n)


def _broadens(s: dict) -> Verdict:
    """The claim's judge: :data:`~._criteria.CONFINEMENT_TREND_RULE` on ``broadening_slope_per_d_over_2A``."""
    d, w = s["d_over_2A"], s["central_width_over_lambda"]
    slope = stats.Estimate.from_dict(s["broadening_slope_per_d_over_2A"])
    lo, hi = PAPER_RANGE
    measured = (f"slope of the central state's width against d/2A over {lo:g}-{hi:g}: {slope:.3g} lambda per unit "
                f"d/2A from {slope.n} confinements ({stats.interval_note(slope.level)}); " + _widths_text(d, w))
    value = {"broadening_slope_per_d_over_2A": s["broadening_slope_per_d_over_2A"],
             "broadening_intercept_over_lambda": s["broadening_intercept_over_lambda"],
             "d_over_2A": _numbers(d), "central_width_over_lambda": _numbers(w),
             "paper_range_d_over_2A": list(PAPER_RANGE)}
    if not slope.has_interval:
        return Verdict.none(f"no interval for the slope: {slope.n} confinements with a central state within the "
                            f"paper's range {lo:g}-{hi:g} (at least 3 needed)", measured, value)
    return Verdict.of([_slope_check(slope, "slope of the width against d/2A (lambda per unit d/2A)")], measured,
                      value, runs=s["n_runs_in_broadening_fit"])


def _never_shrinks(s: dict) -> Verdict:
    """The superseded judge: step by step over every confinement run, and open within the paper's range."""
    d, w = s["d_over_2A"], s["central_width_over_lambda"]
    inside = s["max_width_in_paper_range"]
    measured = _widths_text(d, w)
    value = {"d_over_2A": _numbers(d), "central_width_over_lambda": _numbers(w)}
    if inside is None or s["width_never_shrinks_with_d"] is None:
        return Verdict.none("no start ended in the central state within the paper's range", measured, value)
    # the width is a range of final offsets, with no interval (module docstring): exact, never undecided
    return Verdict.of([Check.exact(inside > WIDTH_TOL, f"largest width within d/2A <= {PAPER_RANGE[1]}: "
                                                       f"{inside:.3f} lambda (> {WIDTH_TOL} needed)"),
                       Check.exact(s["width_never_shrinks_with_d"] is True,
                                   f"the width never shrinks by more than {WIDTH_TOL} lambda per step")],
                      measured, value)


def _evidence(row: dict):
    """The claim's evidence figure (:attr:`~._protocol.Claim.evidence`):
    :func:`undulate.plotting.confinement.plot_broadening_evidence` of its ``claims.json`` row."""
    from ..plotting.confinement import plot_broadening_evidence

    return plot_broadening_evidence(row)


CLAIMS = (
    Claim("the central (dx = 0) state broadens as the confinement d/2A grows (over 0.6-1.2)",
          "increasing the wall distance increased the range of final spacings; the central state broadened",
          CONFINEMENT_TREND_RULE, _broadens,
          superseded=(SupersededCriterion(
              f"the width never shrinks by more than {WIDTH_TOL} lambda from one d/2A to the next and exceeds "
              f"{WIDTH_TOL} lambda within d/2A <= 1.2 (the width is a range of final offsets with no interval: "
              "holds or fails, never undecided)", _never_shrinks,
              why="it judged a trend step by step: one step narrower by more than 0.01 lambda decided it, "
                  "whatever the whole range showed, and it read the confinements beyond the paper's range "
                  "(d/2A above 1.2) too; the paper's words are a trend over 0.6-1.2"),),
          evidence=_evidence,
          quote=(r"Increasing the confinement wall distance increased the range of final longitudinal spacing "
                 r"observed between two swimmers (Fig.~\ref{fig:spacing_basins}). The central compatibility state "
                 r"broadened indicating that swimmers could compatibly move within a range of longitudinal "
                 r"separations without contact."),
          where="Sec. III.F, Fig. 9", bands={"broadening_slope_per_d_over_2A": (0.0, None)}),
)


def figure(ds):
    from ..plotting.confinement import plot_confinement

    return plot_confinement(ds)


def stages(quick: bool) -> tuple[ConfinementPlan, ...]:
    """The plan in looks (:mod:`._stages`): in full mode the confinements thinned (5: 0.6, 0.8, 1.0, 1.2
    and 1.6; 9: 0.6 to 1.2 in 0.1, 1.4 and 1.6; all 17), every look on all 21 starts; quick mode one look,
    its whole plan (its four confinements in the range are the fewest that give the slope an interval).

    The starts are not thinned: they set the width's resolution (a pair that never touches keeps its
    start, so the width is then the spread of the starts within the central band), so a look on fewer
    starts would measure another quantity, not the same one less precisely; the confinements in the range
    are what narrows the slope's interval (:func:`plan`)."""
    p = plan(quick)
    if quick:
        return (p,)
    return tuple(ConfinementPlan(p.d_over_2A[::k], p.dx0_over_lambda, p.duration_s) for k in strides(False))


register(Study(
    name="confinement", paper_figure="9", plan=plan, stages=stages, dataset=dataset, summary=summary, claims=CLAIMS,
    figure=figure,
    description="dphi = 0 pairs from dx0/lambda in [-1, 1] in channels of d/2A = 0.6 to 1.2 "
                "(and wider): final dx/lambda against the start; width of the central state."))
