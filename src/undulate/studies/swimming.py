"""Study ``swimming`` (paper Methods): the pair study with swimmers that swim.

The paper reports that making the simulated swimmers locomote ("viscous
drag forces on the swimmers to make them swim forward") changed nothing
qualitative in their spatial dynamics.  Here the viscous drag is the
resistive-force medium :meth:`Ground.resistive`: linear drag per link along
and across its own axis, ``c_par`` = 2 N s/m per link (the table's
isotropic ground drag, so the only change from the non-swimming model is
the anisotropy) and ``c_perp / c_par = 2`` (the slender-body value), with
no isotropic drag besides.  In this medium a lone swimmer advances head
first (toward -x); inertia is small (a link's drag relaxation time,
25-50 ms, is 1-3 % of the 2 s period), so it swims as an inertialess
resistive-force swimmer does (tests/test_resistive.py).  MuJoCo's
ellipsoid fluid model (:meth:`Ground.swimming`) stays available and is not
used here.  The study

1. measures the lone swimmer's steady speed (``StudyContext.lone_swimmer``),
   in m/s and in body lengths per gait period;
2. repeats the pair study (``d = 0.13 m``, ``xi = 1``, ``dphi`` in
   ``{-1, -3/4, ..., 1} pi``, and a finer set in full mode; 15 periods)
   in the resistive medium and on the default (viscous, non-locomoting) ground;
3. compares the steady ``dx / lambda`` against ``dphi / 2 pi`` with the
   compatibility line: per mode, the slope of the pair study with its
   standard error (``_analysis.compatibility_fit``: least squares after
   moving each point onto the branch nearest the n = 0 line) and the RMS
   distance to the nearest compatible branch (``theory.compatibility_residual``)
   with a bootstrap interval.
"""

from __future__ import annotations

import functools
import json
from typing import Any

import numpy as np

from .. import stats, theory
from ..params import Gait, Ground, SwimmerGeometry
from ._criteria import LINE_RMS_TOL, LINE_SLOPE_TOL, PAIR_CHANNEL_M
from ._analysis import SLOPE_METHOD, compatibility_fit, line_checks, rms
from ._context import StudyContext
from ._protocol import Claim, Study, Verdict
from ._registry import register
from ._stages import strides, thinned
from ._runners import PAIR_STOP, pair_point

__all__ = ["SwimmingPlan", "plan", "slope_and_rms", "dataset", "summary", "CLAIMS", "MODES"]

MODES = ("viscous", "resistive")
"""The grounds compared: the default (isotropic, non-locomoting) and the resistive-force medium."""
DURATION_S = 30.0


class SwimmingPlan:
    def __init__(self, dphi, duration_s: float = DURATION_S):
        self.dphi = sorted(float(v) for v in dphi)
        self.duration_s = float(duration_s)


QUICK_REFINE = 2
"""Quick mode's cap: every step of the paper's nine dphi cut in two (17 dphi, step pi/8).  The criterion
reads the slope's t interval over the mirror pairs (+dphi and -dphi are one design point): the nine give
4 units (3 degrees of freedom), and with pairs on the line (RMS residual 0.03 lambda) the slope's 96 %
interval was still 0.78-1.15, straddling 0.8; 17 give 8 units."""
FULL_REFINE = 4
"""Full mode's cap: 33 dphi (step pi/16)."""


def plan(quick: bool) -> SwimmingPlan:
    """The paper's nine phases with every step cut into :data:`QUICK_REFINE` (17, quick) or
    :data:`FULL_REFINE` (33, full); the nine are in both, bitwise."""
    from ._analysis import paper_phases, refined

    return SwimmingPlan(refined(paper_phases(), QUICK_REFINE if quick else FULL_REFINE))


def slope_and_rms(dphi_rad, dx_over_lambda) -> tuple[stats.Estimate, stats.Estimate, stats.Estimate]:
    """``(slope, intercept, rms)`` of ``dx/lambda`` against ``dphi/2pi``, as the pair
    study computes them (``_analysis.compatibility_fit``: least squares after moving each
    point by whole wavelengths onto the branch nearest the n = 0 line), and the RMS
    distance (in lambda) of each point from its nearest compatible branch; with
    uncertainties."""
    fit = compatibility_fit(dx_over_lambda, dphi_rad)
    r = theory.compatibility_residual(np.asarray(dx_over_lambda, float), np.asarray(dphi_rad, float), 1.0)
    return fit.slope, fit.intercept, rms(r, dphi_rad)


def lone_period_speeds(x_period_m) -> np.ndarray:
    """The lone swimmer's distance toward -x per gait period, in body lengths, over the second half of
    its run (the half its speed is fitted on): consecutive differences of the period-averaged centre x."""
    x = np.asarray(x_period_m, float)
    x = x[np.isfinite(x)]
    return -np.diff(x[len(x) // 2:]) / SwimmerGeometry().length_m


def dataset(ctx: StudyContext, p: SwimmingPlan):
    """The free swimmer on both grounds, then the pair sweep in both modes."""
    import xarray as xr

    from ..sweep import Grid

    fn = functools.partial(pair_point, duration_s=p.duration_s, stop=PAIR_STOP)
    grid = Grid(axes={"ground": list(MODES), "dphi_rad": p.dphi}, seed=ctx.seed)
    lone, lone_v, g = ctx.together(lambda: ctx.lone_swimmer(ground="resistive"),
                                   lambda: ctx.lone_swimmer(ground="viscous"),
                                   lambda: ctx.sweep("pairs", fn, grid).isel(replicate=0))
    speed = float(lone["speed_m_s"])
    medium = Ground.resistive()
    speed_v = float(lone_v["speed_m_s"])
    failed = g["run_failed"].values.astype(bool)
    one = {"units": "1"}
    lam = Gait().wavelength_m(SwimmerGeometry().length_m)
    ds = xr.Dataset(
        {
            "dx_final_over_lambda": (("mode", "dphi"), g["dx_final_over_lambda"].values, {
                **one, "long_name": "steady dx / lambda (mean of the last 3 periods)"}),
            "dx_over_lambda": (("mode", "dphi", "time"), g["dx_over_lambda"].values, {
                **one, "long_name": "dx / lambda over time"}),
            "steady": (("mode", "dphi"), np.where(failed, False, g["steady"].values == 1), {}),
            "run_failed": (("mode", "dphi"), failed, {}),
            "swapped_sides": (("mode", "dphi"), g["swapped_sides"].values == 1, {
                "long_name": "the two swimmers changed lateral order during the run"}),
            "pair_speed": (("mode", "dphi"), g["speed_m_s"].values, {
                "units": "m/s", "long_name": "pair speed toward -x, last 3 periods"}),
            "lone_speed": (("mode",), [speed_v, speed], {"units": "m/s", "long_name": "lone swimmer speed toward -x"}),
            "lone_x": (("mode", "period_time"), np.stack([lone_v["x_period_m"].values.ravel(), lone["x_period_m"].values.ravel()]), {
                "units": "m", "long_name": "lone swimmer period-averaged x"}),
        },
        coords={
            "mode": ("mode", list(MODES)),
            "dphi": ("dphi", np.asarray(p.dphi), {"units": "rad", "long_name": "phase difference phi_b - phi_a"}),
            "time": ("time", g["time"].values, {"units": "s"}),
            "period_time": ("period_time", lone["period_time"].values, {"units": "s"}),
        },
        attrs={"title": "pairs swimming vs not (paper Methods remark)", "channel_width_m": PAIR_CHANNEL_M,
               "duration_s": p.duration_s, "wavelength_m": lam, "body_length_m": SwimmerGeometry().length_m,
               "period_s": Gait().period_s, "medium": "resistive-force drag per link (Ground.resistive)",
               "tangential_drag_N_s_per_m": medium.drag_N_s_per_m,
               "normal_drag_N_s_per_m": medium.normal_drag_N_s_per_m, "drag_anisotropy": medium.drag_anisotropy},
    )
    per = lone_period_speeds(ds["lone_x"].sel(mode="resistive").values)
    ds.attrs["lone_speed_body_lengths_per_period"] = speed * Gait().period_s / SwimmerGeometry().length_m
    ds.attrs["lone_speed_body_lengths_per_period_range"] = [float(per.min()), float(per.max())] if per.size else []
    fits = {m: [e.value for e in slope_and_rms(ds["dphi"].values, ds["dx_final_over_lambda"].sel(mode=m).values)]
            for m in MODES}
    ds.attrs["fits_json"] = json.dumps(fits)
    return ds


def summary(ds) -> dict[str, Any]:
    """Pure: per mode slope (standard error) and RMS residual (bootstrap interval); lone speeds."""
    lam = float(ds.attrs["wavelength_m"])
    speed_v, speed = (float(v) for v in ds["lone_speed"].values)
    fits = {}
    for m in MODES:
        s, c, rms_l = slope_and_rms(ds["dphi"].values, ds["dx_final_over_lambda"].sel(mode=m).values)
        fits[m] = {"slope": s.to_dict(), "intercept": c.to_dict(), "rms_residual_over_lambda": rms_l.to_dict(),
                   "dx_final_over_lambda": ds["dx_final_over_lambda"].sel(mode=m).values,
                   "n_steady": int(ds["steady"].sel(mode=m).sum()),
                   "n_swapped_sides": int(ds["swapped_sides"].sel(mode=m).sum()),
                   "n_no_longer_overlapping": int((np.abs(ds["dx_final_over_lambda"].sel(mode=m).values) * lam
                                                   >= SwimmerGeometry().length_m).sum()),
                   "median_pair_speed_m_s": float(np.nanmedian(ds["pair_speed"].sel(mode=m).values))}
    per = lone_period_speeds(ds["lone_x"].sel(mode="resistive").values)
    return {
        "lone_swimmer_speed_m_s": speed,
        "lone_swimmer_speed_body_lengths_per_period": speed * Gait().period_s / SwimmerGeometry().length_m,
        "lone_swimmer_speed_body_lengths_per_period_range": [float(per.min()), float(per.max())] if per.size else [],
        "lone_swimmer_speed_note": "one deterministic run (no replicate varies it): the range is that of its "
                                   "per-period distances over the fitted half, not a confidence interval",
        "medium": {k: ds.attrs[k] for k in ("tangential_drag_N_s_per_m", "normal_drag_N_s_per_m", "drag_anisotropy")
                   if k in ds.attrs},
        "lone_viscous_speed_m_s": speed_v,
        "dphi_rad": ds["dphi"].values,
        "modes": fits,
        "n_failed": int(ds["run_failed"].values.sum()),
        "slope_method": SLOPE_METHOD,
        "rms_method": "RMS over runs of the distance of dx/lambda to the nearest compatible branch "
                      "(seeded bootstrap 95 % interval)",
    }


E = stats.Estimate.from_dict


def _like_viscous(s: dict) -> Verdict:
    v, w = s["modes"]["viscous"], s["modes"]["resistive"]
    sv, rv, sw, rw = E(v["slope"]), E(v["rms_residual_over_lambda"]), E(w["slope"]), E(w["rms_residual_over_lambda"])
    measured = (f"lone swimmer {s['lone_swimmer_speed_m_s'] * 1e3:.1f} mm/s = "
                f"{s['lone_swimmer_speed_body_lengths_per_period']:.4f} L per period head first (resistive-force "
                "drag, c_perp / c_par = 2); slope / RMS residual: "
                f"swimming {sw:.2f} / {rw:.3f} lambda, not swimming {sv:.2f} / {rv:.3f} lambda ({stats.interval_note(sw.level)})")
    value = {"swimming": {"slope": w["slope"], "rms": w["rms_residual_over_lambda"]},
             "viscous": {"slope": v["slope"], "rms": v["rms_residual_over_lambda"]}}
    if not (sw.has_interval and rw.has_interval):
        return Verdict.none("no interval for the swimming pairs' slope or RMS", measured, value)
    return Verdict.of(line_checks(sw, rw, "swimming pairs' "), measured, value)


CLAIMS = (
    Claim("swimming (anisotropic drag) pairs behave like non-swimming ones",
          "we found no qualitative difference in spatial dynamics between locomoting and non-locomoting simulations",
          f"swimming pairs also follow the line: the 95 % interval of their slope lies within 1 +- {LINE_SLOPE_TOL} "
          f"and that of their RMS residual below {LINE_RMS_TOL} lambda (fails if either lies wholly outside; "
          "undecided if one straddles its bound)", _like_viscous,
          quote=(r"In simulations we implemented viscous drag forces on the swimmers to make them swim forward and "
                 r"interact with each other through contact and we found no qualitative difference in spatial "
                 r"dynamics between the locomoting, and non locomoting simulations."),
          where="Sec. II.A (Methods, robotics experiments)",
          bands={"slope": (1 - LINE_SLOPE_TOL, 1 + LINE_SLOPE_TOL), "rms": (None, LINE_RMS_TOL)}),
)


def figure(ds):
    from ..plotting.swimming import plot_swimming

    return plot_swimming(ds)


def stages(quick: bool) -> tuple[SwimmingPlan, ...]:
    """The plan in looks (:mod:`._stages`): quick 9, 17 dphi; full 9, 17, 33."""
    return tuple(SwimmingPlan(d) for d in thinned(plan(quick).dphi, strides(quick)))


register(Study(
    name="swimming", paper_figure="Methods", plan=plan, stages=stages, dataset=dataset, summary=summary, claims=CLAIMS,
    figure=figure,
    description="The pair study (d = 0.13 m, xi = 1) in a resistive-force medium (swimming) and on the "
                "isotropic ground (not swimming): steady dx/lambda vs dphi with the compatibility line; the lone "
                "swimmer's speed in body lengths per period."))
