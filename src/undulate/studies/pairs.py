"""Study ``pairs`` (paper Fig. 3): contact drives a pair to a compatible longitudinal offset.

Two 3-link swimmers in a channel d = 0.13 m start straight, laterally in
contact, at dx0 = 0; swimmer 0 (lower) has phase 0, swimmer 1 (upper) phase
dphi.  They run 15 gait periods (30 s) at every dphi of the paper's nine
``{-1, -3/4, ..., 1} pi`` (quick mode: up to 33, full mode: up to 193 values
over [-pi, pi], which contain the nine) and every xi in {0, 3/4, 1, 3/2}; at a later look an xi whose
claims are decided or found futile keeps the runs of the look that made them final (:func:`xi_plans`).
The steady offset ``dx = x_upper - x_lower`` is compared with the compatibility branches
``dx = lambda (dphi / 2 pi + n)`` (paper Eq. (compatibility)).

Summary per xi: the slope of dx/lambda against dphi/2pi with its standard
error and 95 % interval (``_analysis.SLOPE_METHOD``), the RMS distance from
the nearest branch with a bootstrap interval, how many runs were steady;
for the standing wave xi = 0 (lambda = inf) the spread of dx in metres.

This module is the template of the study protocol (``_registry``):
``plan`` -> ``dataset`` (sweeps through the context) -> ``summary`` (pure)
-> ``CLAIMS`` (pure functions of the summary) -> ``figure``; ``register``.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import xarray as xr

from .. import stats
from ..sweep import Grid
from ._criteria import LINE_RMS_TOL, LINE_SLOPE_TOL, PAIR_CHANNEL_M
from . import _analysis as C
from ._registry import Claim, Study, StudyContext, Verdict, register
from ._stages import frozen_parts, kept_plan, strides, thinned
from ._runners import BODY_LENGTH_M, DURATION_S, PAIR_STOP, SAMPLE_RATE_HZ, TIMESTEP_S, group_point

XI_VALUES = (0.0, 0.75, 1.0, 1.5)
FULL_PHASES = 49  # step pi/24; contains the paper's nine values
FULL_REFINE = 4
"""Full mode's cap: every step of the :data:`FULL_PHASES` grid cut into this many (193 dphi, step pi/96),
its fourth look (:func:`stages`).  Sized on 2026-11-29 by the runs the xi = 3/4 claim's RMS interval
needed at the third look once +dphi and -dphi were resampled together (~102 dphi at 97 %, more at a
fourth look's 97.5 %): the next nested grid above, 193 (``explorations/pairs_cap.py``)."""


@dataclass(frozen=True)
class Plan:
    """The grid: every ``dphi_rad`` (rad) at every ``xi`` (waves per body)."""

    dphi_rad: tuple[float, ...]
    xi: tuple[float, ...] = XI_VALUES


QUICK_REFINE = 4
"""Quick mode's cap: every step of the paper's nine dphi cut into this many (33 dphi, step pi/16), its
third look (:func:`stages`).  Sized on 2026-11-29 by the runs the quick claims undecided on the nine
needed at b112001's second look (96 %): xi = 3/4 (slope 0.955 [0.771, 1.14], RMS residual 0.065 [0.020,
0.118] lambda) and the standing wave (std of dx at xi = 0 [0.002, 0.318] m against 3 x xi = 1's RMS
residual [0.029, 0.079] m) each ~21 dphi; the next nested grid above, 33.  A pair run costs ~0.1
physics core-s."""


def plan(quick: bool) -> Plan:
    """Quick: 33 over [-pi, pi] (step pi/16; the paper's nine bitwise every fourth:
    :data:`QUICK_REFINE`); full: 193 (step pi/96, containing the nine; the 49 of step pi/24 bitwise every
    fourth: :data:`FULL_REFINE`)."""
    dphis = (C.refined(C.paper_phases(), QUICK_REFINE) if quick
             else C.refined(C.phase_grid(FULL_PHASES), FULL_REFINE))
    return Plan(tuple(float(p) for p in dphis))


def _claims_reading(xi: float) -> tuple[str, ...]:
    """The claims whose judge reads the runs at ``xi``: its own line claim; the standing-wave claim reads
    xi = 0 and xi = 1 (its spread against xi = 1's RMS residual)."""
    key = f"{xi:g}"
    return tuple(c.claim for c, k in zip(CLAIMS, _CLAIM_XI) if key in k)


def frozen_xi(xi: tuple[float, ...], decided: dict[str, int]) -> dict[float, int]:
    """The xi every claim reading which an earlier look decided or found futile (``decided``:
    claim -> look, :attr:`~._registry.StudyContext.frozen_claims`), each with the latest such look."""
    return frozen_parts({float(x): _claims_reading(x) for x in xi}, decided)


def xi_plans(p: Plan, decided: dict[str, int], quick: bool) -> dict[float, tuple[float, ...]]:
    """The dphi each xi's runs follow at a look on plan ``p``: ``p``'s, or, for a frozen xi
    (:func:`frozen_xi`), the plan's of the look from which it is frozen (its runs are made, and a
    decided claim is never reopened, nor a futile one grown, so more of them would buy nothing)."""
    looks, frozen = stages(quick), frozen_xi(p.xi, decided)
    return {float(x): kept_plan(looks, frozen, float(x), p).dphi_rad for x in p.xi}


def dataset(ctx: StudyContext, p: Plan) -> xr.Dataset:
    """Run (or resume) the pair sweep and the free swimmers; assemble the study dataset.  An xi whose
    claims an earlier look decided or found futile keeps that look's runs (:func:`xi_plans`)."""
    plans = xi_plans(p, ctx.frozen_claims, bool(ctx.config.quick))
    points = [{"waves_per_body": float(x), "dphi_rad": float(d)} for x in p.xi for d in plans[float(x)]]
    fn = functools.partial(group_point, n_swimmers=2, channel_width_m=PAIR_CHANNEL_M, stop=PAIR_STOP)
    sim, *lone = ctx.together(lambda: ctx.sweep("sim", fn, Grid(points=points, seed=ctx.config.seed)),
                              *(functools.partial(ctx.lone_swimmer, waves_per_body=x) for x in p.xi))
    amp = [float(ds["amplitude_m"]) for ds in lone]
    ds = pairs_dataset(sim, np.array(amp), p.xi, p.dphi_rad, [plans[float(x)] for x in p.xi])
    ds.attrs["frozen_xi"] = json.dumps({f"{x:g}": k for x, k in frozen_xi(p.xi, ctx.frozen_claims).items()})
    return ds


def pairs_dataset(sim: xr.Dataset, amplitude_m: np.ndarray, xi, dphis, xi_dphis=None) -> xr.Dataset:
    """The study dataset (dims xi, dphi, time) from the explicit-point sweep, its points ordered xi, dphi,
    each ``xi`` over its own ``xi_dphis`` (default: ``dphis``; a frozen xi's, a subset of them:
    :func:`xi_plans`), and the free swimmers' A per xi.  An (xi, dphi) without a run is NaN,
    ``run_made`` False (and not ``run_failed``)."""
    xi, dphi = np.asarray(xi, float), np.asarray(dphis, float)
    xi_dphis = [dphi] * xi.size if xi_dphis is None else [np.asarray(d, float) for d in xi_dphis]
    lam = np.array([BODY_LENGTH_M / x if x > 0 else math.inf for x in xi])
    A = np.asarray(amplitude_m, float)
    index = C.point_index(dphi, xi_dphis)
    made = index >= 0
    failed = made & sim["run_failed"].isel(replicate=0).values.astype(bool)[np.where(made, index, 0)]
    dims = ("xi", "dphi")
    variables, dx_t = C.collect_pairs(lambda idx: sim.isel(point=int(index[idx]), replicate=0),
                                      failed | ~made, dphi[None, :], lam[:, None], A[:, None], dims)
    variables["run_failed"] = xr.Variable(dims, failed, variables["run_failed"].attrs)
    variables["run_made"] = xr.Variable(dims, made, {"long_name": "a run was made (False: a frozen xi's dphi "
                                                                  "its look did not run; NaN values)"})
    time = sim["time"].values
    if dx_t is None:
        dx_t = np.full(failed.shape + time.shape, np.nan)
    with np.errstate(invalid="ignore"):
        dxl_t = np.where(np.isfinite(lam)[:, None, None], dx_t / lam[:, None, None], np.nan)
    ds = xr.Dataset(
        {
            **variables,
            "dx": (dims + ("time",), dx_t, {
                "units": "m", "long_name": "longitudinal offset x_1 - x_0 over time (swimmer 1 has phase "
                                           "dphi; = x_upper - x_lower, reflected if the pair swapped)"}),
            "dx_over_lambda": (dims + ("time",), dxl_t, {"units": "1", "long_name": "dx / lambda over time "
                                                                               "(NaN for xi = 0)"}),
            "wavelength": ("xi", lam, {"units": "m", "long_name": "body wavelength lambda = L / xi "
                                                               "(inf for the standing wave)"}),
            "amplitude": ("xi", A, {"units": "m", "long_name": "gait amplitude A of a free swimmer"}),
        },
        coords={
            "xi": ("xi", xi, {"units": "1", "long_name": "waves per body xi = L / lambda"}),
            "dphi": ("dphi", dphi, {"units": "rad", "long_name": "phase difference phi_1 - phi_0 "
                                                            "(upper minus lower at the start)"}),
            "time": ("time", time, {"units": "s", "long_name": "time"}),
        },
        attrs={
            "title": "robot pairs: steady longitudinal offset vs phase difference (paper Fig. 3)",
            "conventions": "heads toward -x; body wave travels +x; dx = x_upper - x_lower, dphi = phi_upper - "
                           "phi_lower; compatibility dx = lambda (dphi/2pi + n)",
            "channel_width_m": PAIR_CHANNEL_M,
            "body_length_m": BODY_LENGTH_M,
            "n_links": 3,
            "duration_s": DURATION_S,
            "timestep_s": TIMESTEP_S,
            "sample_rate_hz": SAMPLE_RATE_HZ,
            "steady_rule": C.STEADY_RULE,
            "slope_method": C.SLOPE_METHOD,
        },
    )
    return ds


def _on_paper_phases(dphi: np.ndarray) -> np.ndarray:
    return np.isclose(dphi[:, None], C.paper_phases()[None, :], atol=1e-9).any(axis=1)


def xi_summary(ds: xr.Dataset, xi: float) -> dict:
    """Summary numbers of one xi (see the module docstring)."""
    d = ds.sel(xi=xi)
    dphi = d["dphi"].values
    made = C.runs_made(d)
    ok = made & ~d["run_failed"].values
    lam = float(d["wavelength"])
    out = {
        "xi": xi,
        "wavelength_m": lam if math.isfinite(lam) else None,
        "amplitude_m": float(d["amplitude"]),
        "n_runs": int(made.sum()),
        "n_failed": int((made & ~ok).sum()),
        "n_steady": int(d["steady"].values[ok].sum()),
        "n_swapped": int(d["swapped"].values[ok].sum()),
        "dx_std_m": float(np.nanstd(d["dx_steady"].values)),
        "dx_min_m": float(np.nanmin(d["dx_steady"].values)) if ok.any() else None,
        "dx_max_m": float(np.nanmax(d["dx_steady"].values)) if ok.any() else None,
        "mean_contact_force_N": float(np.nanmean(d["contact_force_mean"].values)),
    }
    if math.isfinite(lam):
        y = d["dx_steady_over_lambda"].values
        fit = C.compatibility_fit(y, dphi, unwrap=True)
        open_ = np.abs(dphi) < np.pi - 1e-9
        fit_open = C.compatibility_fit(y[open_], dphi[open_], unwrap=False)
        res = d["residual_over_lambda"].values
        paper = _on_paper_phases(dphi)
        out.update({
            "slope": fit.slope.to_dict(),
            "intercept": fit.intercept.to_dict(),
            "r2": fit.r2.to_dict(),
            "slope_open_interval": fit_open.slope.to_dict(),
            "rms_residual_over_lambda": C.rms(res, dphi).to_dict(),
            "rms_residual_m": C.rms(d["residual"].values, dphi).to_dict(),
            "max_abs_residual_over_lambda": float(np.nanmax(np.abs(res))) if ok.any() else None,
            "rms_residual_over_lambda_paper_phases": C.rms(res[paper], dphi[paper]).to_dict(),
            "rms_band_excess_over_lambda": C.rms(d["band_excess"].values / lam, dphi).to_dict(),
        })
    else:
        out.update({"slope": None, "intercept": None, "slope_open_interval": None,
                    "rms_residual_over_lambda": None, "rms_residual_m": None,
                    "dx_std": stats.std(d["dx_steady"].values, clusters=C.abs_dphi_keys(dphi)).to_dict(),
                    "note": "standing wave: lambda = inf, no compatible dx; dx in metres only"})
    return out


def summary(ds: xr.Dataset) -> dict:
    """Pure: the numbers of the study, per xi, with uncertainties (module docstring)."""
    made = C.runs_made(ds)
    ok = made & ~ds["run_failed"].values
    return {
        "per_xi": {f"{x:g}": xi_summary(ds, float(x)) for x in ds["xi"].values},
        "n_runs": int(made.sum()),
        "n_failed": int((made & ~ok).sum()),
        "n_steady": int(ds["steady"].values[ok].sum()),
        "n_dphi": int(ds.sizes["dphi"]),
        "steady_rule": C.STEADY_RULE,
        "slope_method": C.SLOPE_METHOD,
        "residual": "RMS over runs of theory.compatibility_residual (distance from the nearest branch "
                    "lambda (dphi/2pi + n)), in units of lambda and in m",
        "band_excess": "distance outside the full compatibility band |psi| <= 2 arcsin(dy/2A) at the "
                       "measured steady dy and the free swimmer's A (0 = no contact needed)",
    }


# ------------------------------------------------------------------ claims
E = stats.Estimate.from_dict


def _follows_line(key: str) -> Callable[[dict], Verdict]:
    def judge(s: dict) -> Verdict:
        v = s["per_xi"][key]
        slope, rms = E(v["slope"]), E(v["rms_residual_over_lambda"])
        measured = (f"slope {slope:.3f}, RMS residual {rms:.3f} lambda, {v['n_steady']}/{v['n_runs']} runs "
                    f"steady ({stats.interval_note(slope.level)})")
        value = {"slope": v["slope"], "rms_residual_over_lambda": v["rms_residual_over_lambda"]}
        if not (slope.has_interval and rms.has_interval):
            return Verdict.none(f"no interval for the slope or the RMS at xi = {key} "
                                f"({v['n_runs'] - v['n_failed']} runs with a result)", value=value)
        return Verdict.of(C.line_checks(slope, rms), measured, value)
    return judge


def _standing_wave_scatter(s: dict) -> Verdict:
    std0, rms1 = E(s["per_xi"]["0"]["dx_std"]), E(s["per_xi"]["1"]["rms_residual_m"])
    value = {"dx_std_xi0_m": std0.to_dict(), "rms_residual_xi1_m": rms1.to_dict()}
    if not (std0.has_interval and rms1.has_interval):
        return Verdict.none("no interval for the spread at xi = 0 or the RMS residual at xi = 1", value=value)
    return Verdict.of([stats.Check.apart(std0, rms1.scaled(3.0), "std of dx at xi = 0 vs 3 x RMS residual at xi = 1")],
                      f"std of steady dx at xi = 0: {std0:.3f} m; RMS residual at xi = 1: {rms1:.3f} m", value)


_CLAIM_XI = (("1",), ("0.75",), ("1.5",), ("0", "1"))
"""The xi (summary keys) each of :data:`CLAIMS` reads, in order (:func:`_claims_reading`)."""
_CRITERION = (f"the 95 % interval of the slope lies within 1 +- {LINE_SLOPE_TOL} and that of the RMS residual "
              f"below {LINE_RMS_TOL} lambda (fails if either lies wholly outside; undecided if one straddles)")
CLAIMS = tuple(
    Claim(f"xi = {label}: contact drives pairs to a steady dx that follows the compatibility line",
          "steady dx is approximately linear in dphi and agrees with dx = lambda dphi / 2 pi",
          _CRITERION, _follows_line(key),
          quote=(r"Similarly in simulation we find good agreement between the model and observation, with some "
                 r"systematic variation that is a result of the sinusoidal assumption for the three-link robot."),
          where="Sec. III.B, Fig. 3c")
    for key, label in (("1", "1"), ("0.75", "3/4"), ("1.5", "3/2"))
) + (
    Claim("the standing wave (xi = 0) gives large scatter in dx",
          "with a stationary body wave the robots and simulation displayed large variance in dx",
          "the lower 95 % bound of the std of steady dx at xi = 0 exceeds 3 times the upper bound of the "
          "RMS residual at xi = 1", _standing_wave_scatter,
          quote=(r"Critically, when the undulatory body wave was stationary ($\frac{\lambda}{L} = 0$) the robots and "
                 r"simulation displayed large variance in $\Delta x$."),
          where="Sec. III.B, Fig. 3c (right column)"),
)


def figure(ds: xr.Dataset):
    from ..plotting.pairs import plot_pairs

    return plot_pairs(ds)


def stages(quick: bool) -> tuple[Plan, ...]:
    """The plan in looks (:mod:`._stages`): the mode's looks on its grid and one more on the cap refined
    from it: quick 5, 9, 33 dphi (every 8th, 4th, all: :data:`QUICK_REFINE`); full 13, 25, 49, 193 (every
    16th, 8th, 4th, all: :data:`FULL_REFINE`)."""
    refine = QUICK_REFINE if quick else FULL_REFINE
    steps = tuple(refine * s for s in strides(quick)) + (1,)
    return tuple(Plan(d) for d in thinned(plan(quick).dphi_rad, steps))


register(Study(
    name="pairs", paper_figure="3", plan=plan, stages=stages, dataset=dataset, summary=summary, claims=CLAIMS, figure=figure,
    description="Pairs of 3-link swimmers (d = 0.13 m, 30 s) at the paper's nine phase differences (quick: up "
                "to 33, full: up to 193) "
                "and xi in {0, 3/4, 1, 3/2}: dx(t), steady dx vs dphi with the compatibility lines, "
                "slope and RMS error per xi."))
