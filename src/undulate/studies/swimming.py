"""Study ``swimming`` (paper Methods): the pair study with swimmers that swim.

The paper reports that making the simulated swimmers locomote (viscous
drag that propels them) changed nothing qualitative in their spatial
dynamics.  Here the swimming variant is :meth:`Ground.swimming` (MuJoCo's
ellipsoid fluid model in water plus a weak linear drag; a lone swimmer
advances head first, toward -x).  The study

1. measures the lone swimmer's steady speed (:func:`~undulate.studies.packing.lone_swimmer_point`);
2. repeats the pair study (``d = 0.13 m``, ``xi = 1``, ``dphi`` in
   ``{-1, -3/4, ..., 1} pi``, and a finer set in full mode; 15 periods)
   in swimming mode and in the default (viscous, non-locomoting) mode;
3. compares the steady ``dx / lambda`` against ``dphi / 2 pi`` with the
   compatibility line: per mode, the slope of the pair study
   (``_common.slope_fit``: least squares after moving each point onto the
   branch nearest the n = 0 line) and the RMS distance to the nearest
   compatible branch (``theory.compatibility_residual``).
"""

from __future__ import annotations

import functools
import json
from typing import Any

import numpy as np

from .. import theory
from ..params import Gait, SwimmerGeometry
from ._common import SLOPE_METHOD, rms, slope_fit
from ._registry import StudyConfig, StudyResult, register
from .basins import pair_point
from .packing import measure_lone_swimmers, study_sweep

__all__ = ["SwimmingPlan", "plan", "slope_and_rms", "compute", "MODES"]

MODES = ("viscous", "swimming")
DURATION_S = 30.0
LONE_DURATION_S = 30.0


class SwimmingPlan:
    def __init__(self, dphi, duration_s: float = DURATION_S):
        self.dphi = sorted(float(v) for v in dphi)
        self.duration_s = float(duration_s)


def plan(quick: bool) -> SwimmingPlan:
    """The nine paper phases (quick); those and every pi/16 (33, full)."""
    n = 9 if quick else 33
    return SwimmingPlan(np.linspace(-np.pi, np.pi, n))


def slope_and_rms(dphi_rad, dx_over_lambda) -> tuple[float, float, float]:
    """``(slope, intercept, rms)`` of ``dx/lambda`` against ``dphi/2pi``, as the pair
    study computes them (``_common.slope_fit``: least squares after moving each point
    by whole wavelengths onto the branch nearest the n = 0 line), and the RMS distance
    (in lambda) of each point from its nearest compatible branch."""
    fit = slope_fit(dx_over_lambda, dphi_rad)
    r = theory.compatibility_residual(np.asarray(dx_over_lambda, float), np.asarray(dphi_rad, float), 1.0)
    return fit.slope, fit.intercept, rms(r)


def compute(config: StudyConfig, p: SwimmingPlan) -> StudyResult:
    """Run the swimming study on plan ``p`` (used by :func:`run` and the tests)."""
    import xarray as xr

    from ..plotting.swimming import plot_swimming
    from ..sweep import Grid

    lone = measure_lone_swimmers(config, "swimming", [Gait().amplitude_rad], duration_s=LONE_DURATION_S,
                                 ground="swimming")
    speed = float(lone["speed_m_s"].item())
    lone_v = measure_lone_swimmers(config, "swimming", [Gait().amplitude_rad], duration_s=LONE_DURATION_S)
    speed_v = float(lone_v["speed_m_s"].item())

    fn = functools.partial(pair_point, duration_s=p.duration_s)
    grid = Grid(axes={"ground": list(MODES), "dphi_rad": p.dphi}, seed=config.seed)
    res = study_sweep(config, "swimming", "pairs", fn, grid)
    g = res.dataset.isel(replicate=0)
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
        attrs={"title": "pairs swimming vs not (paper Methods remark)", "channel_width_m": 0.13,
               "duration_s": p.duration_s, "wavelength_m": lam},
    )
    fits = {}
    for m in MODES:
        s, c, rms_l = slope_and_rms(ds["dphi"].values, ds["dx_final_over_lambda"].sel(mode=m).values)
        fits[m] = {"slope": s, "intercept": c, "rms_residual_over_lambda": rms_l,
                   "dx_final_over_lambda": ds["dx_final_over_lambda"].sel(mode=m).values,
                   "n_steady": int(ds["steady"].sel(mode=m).sum()),
                   "n_swapped_sides": int(ds["swapped_sides"].sel(mode=m).sum()),
                   "n_no_longer_overlapping": int((np.abs(ds["dx_final_over_lambda"].sel(mode=m).values) * lam
                                                   >= SwimmerGeometry().length_m).sum()),
                   "median_pair_speed_m_s": float(np.nanmedian(ds["pair_speed"].sel(mode=m).values))}
    ds.attrs["fits_json"] = json.dumps({m: [fits[m]["slope"], fits[m]["intercept"],
                                            fits[m]["rms_residual_over_lambda"]] for m in MODES})
    summary: dict[str, Any] = {
        "lone_swimmer_speed_m_s": speed,
        "lone_swimmer_speed_body_lengths_per_period": speed * Gait().period_s / SwimmerGeometry().length_m,
        "lone_viscous_speed_m_s": speed_v,
        "dphi_rad": ds["dphi"].values,
        "modes": fits,
        "n_failed": len(res.failures),
        "failures": [str(f) for f in res.failures[:20]],
        "sweep_elapsed_s": float(res.elapsed_s),
        "slope_method": SLOPE_METHOD,
        "rms_method": "RMS over runs of the distance of dx/lambda to the nearest compatible branch",
    }
    return StudyResult(dataset=ds, figure=plot_swimming(ds), summary=summary)


@register("swimming", paper_figure="Methods",
          description="The pair study (d = 0.13 m, xi = 1) with swimming drag and without: steady "
                      "dx/lambda vs dphi with the compatibility line; the lone swimmer's speed.")
def run(config: StudyConfig) -> StudyResult:
    return compute(config, plan(config.quick))
