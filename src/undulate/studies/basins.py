"""Study ``basins`` (paper Fig. 8): where pairs end up from a given start.

Two swimmers, ``d = 0.13 m``, ``xi = 1``, started straight and laterally in
contact at an offset ``dx0`` (``Scene.dx0_m``), run for 15 periods (30 s).

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
  leaves two bodies of width ``w`` and stroke ``A`` (``max(0, d - 2A -
  2w)``, see :mod:`undulate.studies.potential`; 0 at ``d = 0.13 m``).

This module also holds the pair runner the other pair studies share:
:func:`pair_scene` and :func:`pair_point`.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from .. import theory
from ..params import Channel, Gait, Ground, Scene, SimOptions, SwimmerGeometry
from ._registry import StudyConfig, StudyResult, register
from .packing import measure_lone_swimmers, round_amplitude, study_sweep

__all__ = [
    "PAIR_WIDTH_M",
    "RETURN_TOL",
    "pair_scene",
    "pair_point",
    "BasinsPlan",
    "plan",
    "returns_to_zero",
    "bracket_threshold",
    "compute",
]

PAIR_WIDTH_M = 0.13
"""Channel width of the pair studies, m (paper: 13 cm)."""
DURATION_S = 30.0
"""Pair runs last 15 gait periods, s (the paper's experiments)."""
RECORD_HZ = 5.0
"""Rate at which dx(t) is kept in the study data, Hz."""
STEADY_TOL = 0.01
"""Steady-state rule for dx/lambda (observables.steady_state): last 3 period means within this."""
RETURN_TOL = 0.05
"""A dphi = 0 start 'returns to the compatible state' when its final |dx/lambda| < RETURN_TOL."""

_PAIR_KEYS = ("dx0_over_lambda", "dphi_rad", "phi0_rad", "channel_width_m", "d_over_2A", "amplitude_m",
              "amplitude_rad", "force_N", "ground", "waves_per_body")


def pair_scene(point: dict, *, amplitude_m: float | None = None, force_onset_s: float = 0.0) -> Scene:
    """The pair scene of a sweep point.

    Keys (all optional): ``dx0_over_lambda`` (initial x_b - x_a over lambda;
    0), ``dphi_rad`` (phi_b - phi_a, rad; 0), ``phi0_rad`` (phase of swimmer
    a, rad; 0), ``channel_width_m`` (d, m; 0.13) or ``d_over_2A`` (d over
    twice the gait amplitude, given by the key ``amplitude_m`` (m) or else the
    keyword ``amplitude_m``),
    ``amplitude_rad`` (beta, rad; 45 degrees), ``waves_per_body`` (xi; 1),
    ``force_N`` (dF, N: swimmer a is pushed toward -x and b toward +x, from
    ``force_onset_s``; 0), ``ground`` (``"viscous"`` or ``"swimming"``).
    """
    unknown = set(point) - set(_PAIR_KEYS)
    if unknown:
        from ..errors import ParameterError

        raise ParameterError("point", f"keys among {_PAIR_KEYS}", sorted(unknown))
    gait = Gait(amplitude_rad=float(point.get("amplitude_rad", Gait().amplitude_rad)),
                waves_per_body=float(point.get("waves_per_body", 1.0)))
    geo = SwimmerGeometry()
    lam = gait.wavelength_m(geo.length_m)
    if "d_over_2A" in point:
        amp = point.get("amplitude_m", amplitude_m)
        if amp is None:
            raise ValueError("d_over_2A needs amplitude_m")
        width = float(point["d_over_2A"]) * 2.0 * float(amp)
    else:
        width = float(point.get("channel_width_m", PAIR_WIDTH_M))
    ground = Ground.swimming() if point.get("ground", "viscous") == "swimming" else Ground()
    f = float(point.get("force_N", 0.0))
    return Scene(
        phases_rad=(float(point.get("phi0_rad", 0.0)),
                    float(point.get("phi0_rad", 0.0)) + float(point.get("dphi_rad", 0.0))),
        gait=gait,
        geometry=geo,
        ground=ground,
        channel=Channel(width_m=width),
        dx0_m=float(point.get("dx0_over_lambda", 0.0)) * lam,
        forces_N=(-f, f) if f else None,
        force_onset_s=float(force_onset_s) if f else 0.0,
    )


def pair_point(point: dict, seed: int, *, duration_s: float = DURATION_S,
               amplitude_m: float | None = None, force_onset_s: float = 0.0,
               record_hz: float = RECORD_HZ):
    """One pair run (sweep function): the offsets over time and their summary.

    ``point``: see :func:`pair_scene`.  Returns (``dx = x_1 - x_0``, swimmer
    1 the one that starts above, with phase ``dphi``; ``swapped_sides`` flags
    a run in which the two changed lateral order at some time, which in the
    lateral-order convention flips the signs of dx and dphi together):
    ``dx_over_lambda(time)`` at ``record_hz``;
    ``dx_period_over_lambda(period_time)`` (whole-period means);
    ``dx_final_over_lambda`` (mean of the last 3 periods), ``steady``
    (``observables.steady_state``, tolerance :data:`STEADY_TOL`),
    ``settle_time_s``; ``dy_final_m``; ``impulse_2T_Ns`` (swimmer-swimmer
    contact impulse over the first two periods); ``mean_joint_error_rad``
    (t >= one period); ``speed_m_s`` (the pair's mean speed toward -x over
    the last 3 periods); ``max_penetration_m``.  ``seed`` is unused.
    """
    import xarray as xr

    from ..observables import contact_impulse, neighbour_offsets, period_average, steady_state
    from ..simulation import simulate

    scene = pair_scene(point, amplitude_m=amplitude_m, force_onset_s=force_onset_s)
    ds = simulate(scene, SimOptions(duration_s=duration_s))
    lam = scene.wavelength_m
    T = scene.gait.period_s
    # dx = x_1 - x_0 and dy = y_1 - y_0 in the initial labels (swimmer 1 starts above
    # swimmer 0 and has phase dphi): the lateral-order convention as long as the two
    # do not swap sides, and the same physics (dx, dphi -> -dx, -dphi) if they do.
    off = neighbour_offsets(ds).isel(pair=0)
    sign = xr.where(off["lower"] == 0, 1.0, -1.0)
    swapped = bool((sign < 0).any())
    off = off.assign(dx=off["dx"] * sign, dy=off["dy"] * sign)
    dxl = off["dx"] / lam
    pa = period_average(dxl, T)
    st = steady_state(dxl, T, tol=STEADY_TOL)
    dy = period_average(off["dy"], T)
    xc = period_average(ds["x"].mean("swimmer"), T).values
    every = max(1, int(round(1.0 / (record_hz * float(ds.attrs["sample_interval"])))))
    rec = dxl.isel(time=slice(0, None, every))
    imp = float(contact_impulse(ds, 0.0, 2 * T)["pair"].isel(pair=0))
    je = float(ds["joint_error"].where(ds["time"] >= T).mean())
    one = {"units": "1"}
    return xr.Dataset(
        {
            "dx_over_lambda": (("time",), rec.values, {**one, "long_name": "dx / lambda"}),
            "dx_period_over_lambda": (("period_time",), pa.values, {**one, "long_name": "period mean of dx / lambda"}),
            "dx_final_over_lambda": ((), float(st["value"]), {**one, "long_name": "final dx / lambda (last 3 periods)"}),
            "steady": ((), bool(st["steady"])),
            "settle_time_s": ((), float(st["settle_time"]), {"units": "s"}),
            "dy_final_m": ((), float(dy.values[-3:].mean()), {"units": "m", "long_name": "final dy"}),
            "impulse_2T_Ns": ((), imp, {"units": "N s", "long_name": "pair contact impulse over the first 2 periods"}),
            "mean_joint_error_rad": ((), je, {"units": "rad"}),
            "speed_m_s": ((), float((xc[-4] - xc[-1]) / (3 * T)) if xc.size >= 4 else float("nan"),
                          {"units": "m/s", "long_name": "pair speed toward -x, last 3 periods"}),
            "max_penetration_m": ((), float(ds["penetration"].max()), {"units": "m"}),
            "swapped_sides": ((), swapped),
        },
        coords={
            "time": ("time", rec["time"].values, {"units": "s"}),
            "period_time": ("period_time", pa["time"].values, {"units": "s"}),
        },
    )


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


def _scan(config, name, part, starts, duration_s, progress=True):
    from ..sweep import Grid

    fn = functools.partial(pair_point, duration_s=duration_s)
    grid = Grid(axes={"dx0_over_lambda": sorted(set(round(v, 12) for v in starts))}, seed=config.seed)
    return study_sweep(config, name, part, fn, grid, progress=progress)


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


def compute(config: StudyConfig, p: BasinsPlan) -> StudyResult:
    """Run the basins study on plan ``p`` (used by :func:`run` and the tests)."""
    import xarray as xr

    from ..plotting.basins import plot_basins
    from ..sweep import Grid

    geo = SwimmerGeometry()
    lam = Gait().wavelength_m(geo.length_m)
    lone = measure_lone_swimmers(config, "basins", [Gait().amplitude_rad])
    amp = round_amplitude(float(lone["amplitude_m"].item()))

    # 8a: coarse scan at dphi = 0, then refine each side's bracket
    scan = _scan(config, "basins", "scan", p.scan_dx0, p.duration_s)
    s0 = scan.dataset.isel(replicate=0)
    extra = _refinement(s0["dx0_over_lambda"].values, s0["dx_final_over_lambda"].values, p.refine)
    failures = list(scan.failures)
    if extra:
        ref = _scan(config, "basins", "refine", extra, p.duration_s)
        failures += ref.failures
        s0 = xr.concat([s0, ref.dataset.isel(replicate=0)], dim="dx0_over_lambda").sortby("dx0_over_lambda")
    x0 = s0["dx0_over_lambda"].values
    xf = s0["dx_final_over_lambda"].values
    ret = returns_to_zero(xf) & np.isfinite(xf)
    sides = {}
    for label, side in (("positive", x0 > 0), ("negative", x0 < 0)):
        inner, outer = bracket_threshold(x0[side], ret[side])
        sides[label] = (inner, outer)

    # 8b: the (dx0, dphi) grid
    fn = functools.partial(pair_point, duration_s=p.duration_s)
    grid = Grid(axes={"dx0_over_lambda": p.grid_dx0, "dphi_rad": p.grid_dphi}, seed=config.seed)
    gres = study_sweep(config, "basins", "grid", fn, grid)
    failures += gres.failures
    g = gres.dataset.isel(replicate=0)
    X0, P = np.meshgrid(g["dx0_over_lambda"].values, g["dphi_rad"].values, indexing="ij")
    clearance = theory.lateral_clearance_m(PAIR_WIDTH_M, amp, geo.width_m)
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
            "channel_width_m": PAIR_WIDTH_M,
            "duration_s": p.duration_s,
            "return_tol": RETURN_TOL,
            "theory_dy_m": clearance,
            "threshold_positive": list(sides["positive"]),
            "threshold_negative": list(sides["negative"]),
        },
    )
    summary = _summary(ds, sides, failures, [scan, gres])
    return StudyResult(dataset=ds, figure=plot_basins(ds), summary=summary)


def _summary(ds, sides, failures, results) -> dict[str, Any]:
    sim = ds["grid_displacement_over_lambda"].values
    th = ds["theory_displacement_over_lambda"].values
    ok = np.isfinite(sim)
    big = ok & (np.abs(th) > 0.02)
    agree = float(np.mean(np.sign(sim[big]) == np.sign(th[big]))) if big.any() else float("nan")
    corr = float(np.corrcoef(sim[ok].ravel(), th[ok].ravel())[0, 1]) if ok.sum() > 2 else float("nan")
    thr = {}
    for label, (inner, outer) in sides.items():
        mid = 0.5 * (inner + outer) if np.isfinite(inner) and np.isfinite(outer) else float("nan")
        thr[label] = {"last_returning_dx0_over_lambda": inner, "first_pushed_dx0_over_lambda": outer,
                      "threshold_dx0_over_lambda": mid,
                      "resolution": abs(outer - inner) / 2 if np.isfinite(mid) else None}
    ret = ds["scan_returned"].values
    far = ~ret & np.isfinite(ds["scan_dx_final_over_lambda"].values)
    x0 = ds["start"].values
    xf = ds["scan_dx_final_over_lambda"].values
    pushed_away = far & (np.abs(xf) > np.abs(x0))
    return {
        "amplitude_m": float(ds["amplitude"]),
        "return_threshold": thr,
        "n_starts_dphi0": int(x0.size),
        "n_returned": int(ret.sum()),
        "n_pushed_away_from_zero": int(pushed_away.sum()),
        "n_neither": int((far & ~pushed_away).sum()),
        "grid_shape": list(sim.shape),
        "grid_sign_agreement_with_theory": agree,
        "grid_correlation_with_theory": corr,
        "grid_not_steady": int((~ds["grid_steady"].values).sum()),
        "n_failed": len(failures),
        "failures": [str(f) for f in failures[:20]],
        "sweep_elapsed_s": float(sum(r.elapsed_s for r in results)),
        "rule": f"returned: final |dx/lambda| < {RETURN_TOL} (mean of the last 3 of 15 periods)",
    }


@register("basins", paper_figure="8",
          description="Pairs at d = 0.13 m from a range of initial offsets: dx(t) at dphi = 0 and "
                      "its return threshold; the map of dx_f - dx0 over (dx0/lambda, dphi) beside "
                      "the sinusoidal basin model.")
def run(config: StudyConfig) -> StudyResult:
    return compute(config, plan(config.quick))
