"""Study ``swimming`` (paper Methods): the pair study with swimmers that swim.

The paper reports that making the simulated swimmers locomote (viscous
drag that propels them) changed nothing qualitative in their spatial
dynamics.  Here the swimming variant is :meth:`Ground.swimming` (MuJoCo's
ellipsoid fluid model in water plus a weak linear drag; a lone swimmer
advances head first, toward -x).  The study

1. measures the lone swimmer's steady speed (``StudyContext.lone_swimmer``);
2. repeats the pair study (``d = 0.13 m``, ``xi = 1``, ``dphi`` in
   ``{-1, -3/4, ..., 1} pi``, and a finer set in full mode; 15 periods)
   in swimming mode and in the default (viscous, non-locomoting) mode;
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
from ..params import Gait, SwimmerGeometry
from ._criteria import LINE_RMS_TOL, LINE_SLOPE_TOL, PAIR_CHANNEL_M
from ._analysis import SLOPE_METHOD, compatibility_fit, line_checks, rms
from ._registry import Claim, Study, StudyContext, Verdict, register
from ._stages import strides, thinned
from ._runners import PAIR_STOP, pair_point

__all__ = ["SwimmingPlan", "plan", "slope_and_rms", "dataset", "summary", "CLAIMS", "MODES"]

MODES = ("viscous", "swimming")
DURATION_S = 30.0


class SwimmingPlan:
    def __init__(self, dphi, duration_s: float = DURATION_S):
        self.dphi = sorted(float(v) for v in dphi)
        self.duration_s = float(duration_s)


def plan(quick: bool) -> SwimmingPlan:
    """The nine paper phases (quick); those and every pi/16 (33, full)."""
    n = 9 if quick else 33
    return SwimmingPlan(np.linspace(-np.pi, np.pi, n))


def slope_and_rms(dphi_rad, dx_over_lambda) -> tuple[stats.Estimate, stats.Estimate, stats.Estimate]:
    """``(slope, intercept, rms)`` of ``dx/lambda`` against ``dphi/2pi``, as the pair
    study computes them (``_analysis.compatibility_fit``: least squares after moving each
    point by whole wavelengths onto the branch nearest the n = 0 line), and the RMS
    distance (in lambda) of each point from its nearest compatible branch; with
    uncertainties."""
    fit = compatibility_fit(dx_over_lambda, dphi_rad)
    r = theory.compatibility_residual(np.asarray(dx_over_lambda, float), np.asarray(dphi_rad, float), 1.0)
    return fit.slope, fit.intercept, rms(r, dphi_rad)


def dataset(ctx: StudyContext, p: SwimmingPlan):
    """The free swimmer on both grounds, then the pair sweep in both modes."""
    import xarray as xr

    from ..sweep import Grid

    fn = functools.partial(pair_point, duration_s=p.duration_s, stop=PAIR_STOP)
    grid = Grid(axes={"ground": list(MODES), "dphi_rad": p.dphi}, seed=ctx.config.seed)
    lone, lone_v, g = ctx.together(lambda: ctx.lone_swimmer(ground="swimming"),
                                   lambda: ctx.lone_swimmer(ground="viscous"),
                                   lambda: ctx.sweep("pairs", fn, grid).isel(replicate=0))
    speed = float(lone["speed_m_s"])
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
               "duration_s": p.duration_s, "wavelength_m": lam},
    )
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
    return {
        "lone_swimmer_speed_m_s": speed,
        "lone_swimmer_speed_body_lengths_per_period": speed * Gait().period_s / SwimmerGeometry().length_m,
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
    v, w = s["modes"]["viscous"], s["modes"]["swimming"]
    sv, rv, sw, rw = E(v["slope"]), E(v["rms_residual_over_lambda"]), E(w["slope"]), E(w["rms_residual_over_lambda"])
    measured = (f"lone swimmer {s['lone_swimmer_speed_m_s'] * 1e3:.1f} mm/s head first; slope / RMS residual: "
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
    """The plan in looks (:mod:`._stages`): quick 5, 9 dphi; full 9, 17, 33."""
    return tuple(SwimmingPlan(d) for d in thinned(plan(quick).dphi, strides(quick)))


register(Study(
    name="swimming", paper_figure="Methods", plan=plan, stages=stages, dataset=dataset, summary=summary, claims=CLAIMS,
    figure=figure,
    description="The pair study (d = 0.13 m, xi = 1) with swimming drag and without: steady "
                "dx/lambda vs dphi with the compatibility line; the lone swimmer's speed."))
