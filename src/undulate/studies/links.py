"""Study ``links`` (paper Fig. 5): pairs of N = 3, 5, 7, 9-link swimmers against compatibility.

The pair study at xi = 1 (L = 0.54 m, d = 0.13 m, 30 s, dx0 = 0) with more,
shorter links.  The paper does not say how the joint amplitude beta changes
with N, so two rules are run side by side:

* ``"fixed"``: beta = 45 degrees at every joint, the paper's gait Eq. (1)
  unchanged (the body bends more in total as N grows);
* ``"curvature"``: beta = 45 degrees x 3 / N, the same bending per unit
  length as the 3-link body (the same curvature wave, more finely
  discretised).

Time step: the simulator's time-step rule (:func:`undulate.scene.auto_timestep`:
2 ms for 3 links, 0.67 ms for 5, 0.5 ms for 7, 0.4 ms for 9).  Lighter,
shorter links need a shorter step: at a fixed 2 ms, 7-link pairs
interpenetrate beyond the divergence bound and 9-link pairs diverge in the
first second; with the rule's steps the steady dx/lambda agrees with a
quarter of the step to 1e-3 (docs/timestep.md).

Summary per rule and N: RMS distance of the steady dx from the nearest
compatibility branch (paper: it falls as links are added), the slope, and
how many runs were steady.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import xarray as xr

from .. import stats
from ..sweep import Grid
from ._criteria import PAIR_CHANNEL_M
from . import _analysis as C
from ._registry import Claim, Study, StudyContext, Verdict, register
from ._runners import BODY_LENGTH_M, DURATION_S, PAIR_STOP, group_point

N_LINKS = (3, 5, 7, 9)
RULES = ("fixed", "curvature")
BETA_3_LINKS_RAD = math.radians(45.0)
XI = 1.0
FULL_PHASES = 33  # step pi/16; contains the paper's nine values


def joint_amplitude(rule: str, n_links: int) -> float:
    """beta (rad) of an N-link swimmer under ``rule`` (see the module docstring)."""
    return BETA_3_LINKS_RAD if rule == "fixed" else BETA_3_LINKS_RAD * 3.0 / n_links


def timestep(n_links: int) -> float:
    """Integrator step for N links, s: the simulator's rule (module docstring)."""
    from ..params import Scene, SwimmerGeometry
    from ..scene import auto_timestep

    return auto_timestep(Scene(geometry=SwimmerGeometry(n_links=n_links)))


def _gait_point(rule: str, n: int) -> dict:
    return {"beta_rule": rule, "n_links": n, "amplitude_rad": joint_amplitude(rule, n),
            "timestep_s": timestep(n), "waves_per_body": XI}


@dataclass(frozen=True)
class Plan:
    """Every ``dphi_rad`` (rad) for every rule and N."""

    dphi_rad: tuple[float, ...]


def plan(quick: bool) -> Plan:
    """Quick: the paper's nine dphi; full: 33 over [-pi, pi] (step pi/16)."""
    return Plan(tuple(float(p) for p in (C.paper_phases() if quick else C.phase_grid(FULL_PHASES))))


def dataset(ctx: StudyContext, p: Plan) -> xr.Dataset:
    dphis = np.asarray(p.dphi_rad, float)
    gaits = [_gait_point(r, n) for r in RULES for n in N_LINKS]
    sim_points = [{**g, "dphi_rad": float(d)} for g in gaits for d in dphis]
    fn = functools.partial(group_point, n_swimmers=2, channel_width_m=PAIR_CHANNEL_M, stop=PAIR_STOP)
    sim = ctx.sweep("sim", fn, Grid(points=sim_points, seed=ctx.config.seed))
    amp = np.array([float(ctx.lone_swimmer(amplitude_rad=g["amplitude_rad"], n_links=g["n_links"],
                                           waves_per_body=XI)["amplitude_m"]) for g in gaits])
    return links_dataset(sim, amp, dphis)


def links_dataset(sim: xr.Dataset, amplitude_m: np.ndarray, dphis: np.ndarray) -> xr.Dataset:
    """Study dataset (dims rule, n_links, dphi, time) from the merged explicit-point sweeps.

    The sweep points are ordered rule, N, dphi (see :func:`run`).
    """
    nr, nn, nd = len(RULES), len(N_LINKS), len(dphis)
    lam = BODY_LENGTH_M / XI
    A = np.asarray(amplitude_m, float).reshape(nr, nn)
    failed = sim["run_failed"].isel(replicate=0).values.astype(bool).reshape(nr, nn, nd)
    dims = ("rule", "n_links", "dphi")

    def runs(idx):
        r, n, j = idx
        return sim.isel(point=(r * nn + n) * nd + j, replicate=0)

    variables, dx_t = C.collect_pairs(runs, failed, dphis[None, None, :], lam, A[:, :, None], dims)
    time = sim["time"].values
    if dx_t is None:
        dx_t = np.full(failed.shape + time.shape, np.nan)
    beta = np.array([[joint_amplitude(r, n) for n in N_LINKS] for r in RULES])
    return xr.Dataset(
        {
            **variables,
            "dx": (dims + ("time",), dx_t, {"units": "m", "long_name": "longitudinal offset x_1 - x_0 "
                                                                  "over time (= x_upper - x_lower up to "
                                                                  "reflection)"}),
            "amplitude": (("rule", "n_links"), A, {"units": "m", "long_name": "gait amplitude A of a free "
                                                                           "swimmer"}),
            "joint_amplitude": (("rule", "n_links"), beta, {"units": "rad", "long_name": "joint amplitude beta"}),
            "timestep": ("n_links", [timestep(n) for n in N_LINKS], {"units": "s",
                                                                     "long_name": "integrator time step"}),
        },
        coords={
            "rule": ("rule", list(RULES), {"long_name": "joint amplitude rule: fixed = 45 deg per joint; "
                                                       "curvature = 45 deg x 3/N"}),
            "n_links": ("n_links", np.array(N_LINKS), {"units": "1", "long_name": "links per swimmer N"}),
            "dphi": ("dphi", dphis, {"units": "rad", "long_name": "phase difference phi_1 - phi_0"}),
            "time": ("time", time, {"units": "s", "long_name": "time"}),
        },
        attrs={
            "title": "pairs with N = 3, 5, 7, 9 links: steady dx/lambda vs dphi (paper Fig. 5)",
            "conventions": "dx = x_upper - x_lower, dphi = phi_upper - phi_lower; compatibility "
                           "dx = lambda (dphi/2pi + n)",
            "waves_per_body": XI,
            "wavelength_m": lam,
            "channel_width_m": PAIR_CHANNEL_M,
            "body_length_m": BODY_LENGTH_M,
            "duration_s": DURATION_S,
            "steady_rule": C.STEADY_RULE,
            "slope_method": C.SLOPE_METHOD,
        },
    )


def summary(ds: xr.Dataset) -> dict:
    """Pure: per rule and N, the RMS residual (bootstrap interval) and the slope (standard error)."""
    lam = float(ds.attrs["wavelength_m"])
    dphi = ds["dphi"].values
    open_ = np.abs(dphi) < np.pi - 1e-9
    per_rule = {}
    for rule in ds["rule"].values:
        rows = {}
        for n in ds["n_links"].values:
            d = ds.sel(rule=rule, n_links=n)
            ok = ~d["run_failed"].values
            res = d["residual_over_lambda"].values
            fit = C.compatibility_fit(d["dx_steady_over_lambda"].values, dphi)
            rows[str(int(n))] = {
                "n_links": int(n),
                "joint_amplitude_deg": math.degrees(float(d["joint_amplitude"])),
                "amplitude_m": float(d["amplitude"]),
                "timestep_s": float(d["timestep"]),
                "rms_residual_over_lambda": C.rms(res).to_dict(),
                "rms_residual_over_lambda_open_interval": C.rms(res[open_]).to_dict(),
                "max_abs_residual_over_lambda": float(np.nanmax(np.abs(res))) if ok.any() else None,
                "slope": fit.slope.to_dict(),
                "intercept": fit.intercept.to_dict(),
                "rms_band_excess_over_lambda": C.rms(d["band_excess"].values / lam).to_dict(),
                "n_runs": int(ok.size),
                "n_failed": int((~ok).sum()),
                "n_steady": int(d["steady"].values[ok].sum()),
                "max_penetration_m": float(np.nanmax(d["penetration_max"].values)) if ok.any() else None,
            }
        falls = C.falls_with_links([E(rows[k]["rms_residual_over_lambda"]) for k in sorted(rows, key=int)])
        per_rule[str(rule)] = {
            "per_n": rows,
            "rms_falls_with_n": falls,  # the claim's criterion (C.FALLS_RULE); None without intervals
        }
    ok = ~ds["run_failed"].values
    return {
        "per_rule": per_rule,
        "n_runs": int(ok.size),
        "n_failed": int((~ok).sum()),
        "n_steady": int(ds["steady"].values[ok].sum()),
        "n_dphi": int(ds.sizes["dphi"]),
        "rules": {"fixed": "beta = 45 deg at every joint (paper Eq. 1 unchanged)",
                  "curvature": "beta = 45 deg x 3/N (same bending per length as 3 links)"},
        "residual": "RMS over dphi of theory.compatibility_residual / lambda (nearest branch); "
                    "'open_interval' leaves out dphi = +-pi (one physical state, the unstable "
                    "point between branches)",
        "steady_rule": C.STEADY_RULE,
        "slope_method": C.SLOPE_METHOD,
    }


E = stats.Estimate.from_dict


def _falls(rule: str) -> Callable[[dict], Verdict]:
    def judge(s: dict) -> Verdict:
        per_n = s["per_rule"][rule]["per_n"]
        ns = sorted(per_n, key=int)
        rms = [E(per_n[n]["rms_residual_over_lambda"]) for n in ns]
        measured = "RMS residual / lambda for N = " + ", ".join(f"{n}: {r:.3f}" for n, r in zip(ns, rms))
        value = {n: per_n[n]["rms_residual_over_lambda"] for n in ns}
        if not all(r.has_interval for r in rms):
            return Verdict.none("an RMS residual without an interval (too few runs with a result)", measured, value)
        return Verdict.judged(C.falls_with_links(rms), measured, value)
    return judge


CLAIMS = tuple(
    Claim(f"error from compatibility falls as links are added ({text})",
          "the RMS error between simulation and Eq. (2) decreased with increasing link number (values withheld)",
          C.FALLS_RULE, _falls(rule))
    for rule, text in (("fixed", "joint amplitude 45 deg at every N"),
                       ("curvature", "joint amplitude 45 deg x 3/N"))
)


def figure(ds: xr.Dataset):
    from ..plotting.links import plot_links

    return plot_links(ds)


register(Study(
    name="links", paper_figure="5", plan=plan, dataset=dataset, summary=summary, claims=CLAIMS, figure=figure,
    description="Pairs of N = 3, 5, 7, 9-link swimmers at xi = 1 (d = 0.13 m): steady dx/lambda vs "
                "dphi with the compatibility line, and the RMS error per N (two joint-amplitude rules)."))
