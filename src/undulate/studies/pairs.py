"""Study ``pairs`` (paper Fig. 3): contact drives a pair to a compatible longitudinal offset.

Two 3-link swimmers in a channel d = 0.13 m start straight, laterally in
contact, at dx0 = 0; swimmer 0 (lower) has phase 0, swimmer 1 (upper) phase
dphi.  They run 15 gait periods (30 s) at every dphi of the paper's nine
``{-1, -3/4, ..., 1} pi`` (full mode: 49 values over [-pi, pi], which contain
the nine) and every xi in {0, 3/4, 1, 3/2}.  The steady offset
``dx = x_upper - x_lower`` is compared with the compatibility branches
``dx = lambda (dphi / 2 pi + n)`` (paper Eq. (compatibility)).

Summary per xi: the slope of dx/lambda against dphi/2pi (see
``_common.SLOPE_METHOD``), the RMS distance from the nearest branch, how
many runs were steady; for the standing wave xi = 0 (lambda = inf) the
spread of dx in metres.
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from ..sweep import Grid
from . import _common as C
from ._registry import StudyConfig, StudyResult, register

XI_VALUES = (0.0, 0.75, 1.0, 1.5)
CHANNEL_WIDTH_M = 0.13
FULL_PHASES = 49  # step pi/24; contains the paper's nine values


def phases(quick: bool) -> np.ndarray:
    """The dphi values of a run, rad."""
    return C.paper_phases() if quick else C.phase_grid(FULL_PHASES)


def simulate_pairs(config: StudyConfig):
    """Run (or resume) the pair sweeps; returns (sim sweep, amplitude sweep) results."""
    dphis = phases(config.quick)
    grid = Grid(axes={"waves_per_body": list(XI_VALUES), "dphi_rad": [float(p) for p in dphis]},
                seed=config.seed)
    sim = C.run_points(config, "pairs", "sim",
                       C.sweep_function(n_swimmers=2, channel_width_m=CHANNEL_WIDTH_M), grid)
    amp = C.run_points(config, "pairs", "amplitude", C.free_amplitude,
                       Grid(axes={"waves_per_body": list(XI_VALUES)}, seed=config.seed))
    return sim, amp


def pairs_dataset(sim: xr.Dataset, amp: xr.Dataset) -> xr.Dataset:
    """The study dataset from the merged sweep datasets (dims xi, dphi, time)."""
    xi = sim["waves_per_body"].values.astype(float)
    dphi = sim["dphi_rad"].values.astype(float)
    lam = np.array([C.BODY_LENGTH_M / x if x > 0 else math.inf for x in xi])
    A = amp["amplitude"].isel(replicate=0).values.astype(float)
    failed = sim["run_failed"].isel(replicate=0).values.astype(bool)
    dims = ("xi", "dphi")
    variables, dx_t = C.collect_pairs(
        lambda idx: sim.isel(waves_per_body=idx[0], dphi_rad=idx[1], replicate=0),
        failed, dphi[None, :], lam[:, None], A[:, None], dims)
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
            "channel_width_m": CHANNEL_WIDTH_M,
            "body_length_m": C.BODY_LENGTH_M,
            "n_links": 3,
            "duration_s": C.DURATION_S,
            "timestep_s": C.TIMESTEP_S,
            "sample_rate_hz": C.SAMPLE_RATE_HZ,
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
    ok = ~d["run_failed"].values
    lam = float(d["wavelength"])
    out = {
        "xi": xi,
        "wavelength_m": lam if math.isfinite(lam) else None,
        "amplitude_m": float(d["amplitude"]),
        "n_runs": int(dphi.size),
        "n_failed": int((~ok).sum()),
        "n_steady": int(d["steady"].values[ok].sum()),
        "n_swapped": int(d["swapped"].values[ok].sum()),
        "dx_std_m": float(np.nanstd(d["dx_steady"].values)),
        "dx_min_m": float(np.nanmin(d["dx_steady"].values)) if ok.any() else None,
        "dx_max_m": float(np.nanmax(d["dx_steady"].values)) if ok.any() else None,
        "mean_contact_force_N": float(np.nanmean(d["contact_force_mean"].values)),
    }
    if math.isfinite(lam):
        y = d["dx_steady_over_lambda"].values
        fit = C.slope_fit(y, dphi, unwrap=True)
        open_ = np.abs(dphi) < np.pi - 1e-9
        fit_open = C.slope_fit(y[open_], dphi[open_], unwrap=False)
        res = d["residual_over_lambda"].values
        out.update({
            "slope": fit.slope,
            "intercept": fit.intercept,
            "slope_open_interval": fit_open.slope,
            "rms_residual_over_lambda": C.rms(res),
            "rms_residual_m": C.rms(d["residual"].values),
            "max_abs_residual_over_lambda": float(np.nanmax(np.abs(res))) if ok.any() else None,
            "rms_residual_over_lambda_paper_phases": C.rms(res[_on_paper_phases(dphi)]),
            "rms_band_excess_over_lambda": C.rms(d["band_excess"].values / lam),
        })
    else:
        out.update({"slope": None, "intercept": None, "slope_open_interval": None,
                    "rms_residual_over_lambda": None, "rms_residual_m": None,
                    "note": "standing wave: lambda = inf, no compatible dx; dx in metres only"})
    return out


def pairs_summary(ds: xr.Dataset) -> dict:
    ok = ~ds["run_failed"].values
    return {
        "per_xi": {f"{x:g}": xi_summary(ds, float(x)) for x in ds["xi"].values},
        "n_runs": int(ok.size),
        "n_failed": int((~ok).sum()),
        "n_steady": int(ds["steady"].values[ok].sum()),
        "n_dphi": int(ds.sizes["dphi"]),
        "steady_rule": C.STEADY_RULE,
        "slope_method": C.SLOPE_METHOD,
        "residual": "RMS over runs of theory.compatibility_residual (distance from the nearest branch "
                    "lambda (dphi/2pi + n)), in units of lambda and in m",
        "band_excess": "distance outside the full compatibility band |psi| <= 2 arcsin(dy/2A) at the "
                       "measured steady dy and the free swimmer's A (0 = no contact needed)",
    }


@register("pairs", paper_figure="3",
          description="Pairs of 3-link swimmers (d = 0.13 m, 30 s) at nine (full: 49) phase differences "
                      "and xi in {0, 3/4, 1, 3/2}: dx(t), steady dx vs dphi with the compatibility lines, "
                      "slope and RMS error per xi.")
def run(config: StudyConfig) -> StudyResult:
    from ..plotting.pairs import plot_pairs

    sim, amp = simulate_pairs(config)
    ds = pairs_dataset(sim.dataset, amp.dataset)
    return StudyResult(dataset=ds, figure=plot_pairs(ds), summary=pairs_summary(ds))
