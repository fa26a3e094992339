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
how many runs were steady; per rule the trend of the error over N
(:func:`error_trend`: the slope of every run's squared residual against N,
with its cluster-jackknife interval over the design points), which the
claim judges (:data:`~._criteria.LINKS_TREND_RULE`).  The claim's earlier
criterion, step by step on the per-N RMS intervals (``analysis.FALLS_RULE``), is
judged beside it (:attr:`~._protocol.Claim.superseded`).

Outliers are findings (:mod:`undulate.studies._outliers`): where one N's RMS
interval is more than :data:`~undulate.studies._outliers.WIDTH_FACTOR` times
as wide as the median of the other N's, the summary names the runs that
widen it (|residual| beyond the group's median + 3 MAD) and why: still
drifting, on another compatible branch, or in another steady state (and
then which: end to end, side by side inside the band, side by side pressed
outside it).  Runs that settled on another branch than their start's are
listed for every N (they do not widen the interval: the residual is taken
from the nearest branch).
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
from ._criteria import LINKS_TREND_RULE, PAIR_CHANNEL_M
from . import _analysis as analysis
from . import _outliers as O
from ._context import StudyContext
from ._protocol import Claim, Study, SupersededCriterion, Verdict
from ._registry import register
from ._stages import strides, thinned
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
    return Plan(tuple(float(p) for p in (analysis.paper_phases() if quick else analysis.phase_grid(FULL_PHASES))))


def dataset(ctx: StudyContext, p: Plan) -> xr.Dataset:
    """Pairs of every rule and N at every dphi; each rule on the plan its part (the rule's name, read by
    its claim) follows (:meth:`~._context.StudyContext.plan_for`)."""
    dphis = np.asarray(p.dphi_rad, float)
    plans = {rule: ctx.plan_for(rule, p) for rule in RULES}
    gaits = [_gait_point(r, n) for r in RULES for n in N_LINKS]
    sim_points = [{**g, "dphi_rad": float(d)} for g in gaits for d in plans[g["beta_rule"]].dphi_rad]
    fn = functools.partial(group_point, n_swimmers=2, channel_width_m=PAIR_CHANNEL_M, stop=PAIR_STOP)
    sim, *lone = ctx.together(lambda: ctx.sweep("sim", fn, Grid(points=sim_points, seed=ctx.seed)),
                              *(functools.partial(ctx.lone_swimmer, amplitude_rad=g["amplitude_rad"],
                                                  n_links=g["n_links"], waves_per_body=XI) for g in gaits))
    amp = np.array([float(ds["amplitude_m"]) for ds in lone])
    return links_dataset(sim, amp, dphis, [plans[r].dphi_rad for r in RULES])


def links_dataset(sim: xr.Dataset, amplitude_m: np.ndarray, dphis: np.ndarray,
                  rule_dphis: list | None = None) -> xr.Dataset:
    """Study dataset (dims rule, n_links, dphi, time) from the merged explicit-point sweeps.

    The sweep points are ordered rule, N, dphi (see :func:`dataset`), each rule over its own
    ``rule_dphis`` (default: ``dphis``; a frozen rule's, a subset of them); a
    (rule, N, dphi) without a run is NaN, ``run_made`` False (and not ``run_failed``).
    """
    nr, nn, nd = len(RULES), len(N_LINKS), len(dphis)
    lam = BODY_LENGTH_M / XI
    A = np.asarray(amplitude_m, float).reshape(nr, nn)
    rule_dphis = [dphis] * nr if rule_dphis is None else [np.asarray(d, float) for d in rule_dphis]
    index = analysis.point_index(dphis, [rule_dphis[r] for r in range(nr) for _ in range(nn)]).reshape(nr, nn, nd)
    made = index >= 0
    point_failed = sim["run_failed"].isel(replicate=0).values.astype(bool)
    failed = made & point_failed[np.where(made, index, 0)]
    dims = ("rule", "n_links", "dphi")

    def runs(idx):
        return sim.isel(point=int(index[idx]), replicate=0)

    variables, dx_t = analysis.collect_pairs(runs, failed | ~made, dphis[None, None, :], lam, A[:, :, None], dims)
    variables["run_failed"] = xr.Variable(dims, failed, variables["run_failed"].attrs)
    variables["run_made"] = xr.Variable(dims, made, {"long_name": "a run was made (False: a frozen rule's "
                                                                  "dphi its look did not run; NaN values)"})
    time = sim["time"].values
    if dx_t is None:
        dx_t = np.full(failed.shape + time.shape, np.nan)
    beta = np.array([[joint_amplitude(r, n) for n in N_LINKS] for r in RULES])
    extent = sim["extent_x"].isel(replicate=0).mean("swimmer").values[np.where(made, index, 0)]
    extent = np.where(failed | ~made, np.nan, extent)
    return xr.Dataset(
        {
            **variables,
            "dx": (dims + ("time",), dx_t, {"units": "m", "long_name": "longitudinal offset x_1 - x_0 "
                                                                  "over time (= x_upper - x_lower up to "
                                                                  "reflection)"}),
            "amplitude": (("rule", "n_links"), A, {"units": "m", "long_name": "gait amplitude A of a free "
                                                                           "swimmer"}),
            "extent_x": (dims, extent, {"units": "m", "long_name": "head-to-tail extent along x of a swimmer "
                                                                 "(mean of the two) at the end of the run"}),
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
            "steady_rule": analysis.STEADY_RULE,
            "slope_method": analysis.SLOPE_METHOD,
        },
    )


def error_trend(residual_over_lambda, n_links, dphi) -> stats.Estimate:
    """The trend of the error over N (:data:`~._criteria.LINKS_TREND_RULE`): the least-squares slope of
    every run's squared residual (lambda^2) against its N, lambda^2 per link, with the cluster-robust
    interval of :func:`undulate.stats.clustered_line_fit` (CR3 jackknife, t on G - 1) over the design
    points: a |dphi| (:func:`~._analysis.abs_dphi_keys`), its runs at every N.

    ``residual_over_lambda``: (N, dphi), one row per ``n_links``; runs without a result (NaN) are left
    out.  Where every |dphi| has a run at every N, the slope is that of the per-N mean squares on N."""
    res = np.asarray(residual_over_lambda, float)
    n = np.asarray(n_links, float)
    if res.shape != (n.size, np.size(dphi)):
        raise ValueError(f"residual_over_lambda has shape {res.shape}, not (N, dphi) = ({n.size}, {np.size(dphi)})")
    x = np.repeat(n, res.shape[1])
    keys = np.tile(analysis.abs_dphi_keys(dphi), n.size)
    return stats.clustered_line_fit(x, res.ravel() ** 2, keys).slope


def summary(ds: xr.Dataset) -> dict:
    """Pure: per rule and N, the RMS residual (bootstrap interval), the slope (standard error) and the
    outlier findings (:data:`OUTLIER_RULE`; per N ``wide_interval``, ``outliers``,
    ``runs_on_another_branch``; per rule ``outlier_note``); per rule the error's trend over N
    (:func:`error_trend`, ``squared_residual_slope_per_link``)."""
    lam = float(ds.attrs["wavelength_m"])
    dphi = ds["dphi"].values
    open_ = np.abs(dphi) < np.pi - 1e-9
    per_rule = {}
    for rule in ds["rule"].values:
        rows = {}
        for n in ds["n_links"].values:
            d = ds.sel(rule=rule, n_links=n)
            made = analysis.runs_made(d)
            ok = made & ~d["run_failed"].values
            res = d["residual_over_lambda"].values
            fit = analysis.compatibility_fit(d["dx_steady_over_lambda"].values, dphi)
            rows[str(int(n))] = {
                "n_links": int(n),
                "joint_amplitude_deg": math.degrees(float(d["joint_amplitude"])),
                "amplitude_m": float(d["amplitude"]),
                "timestep_s": float(d["timestep"]),
                "rms_residual_over_lambda": analysis.rms(res, dphi).to_dict(),
                "rms_residual_over_lambda_open_interval": analysis.rms(res[open_], dphi[open_]).to_dict(),
                "max_abs_residual_over_lambda": float(np.nanmax(np.abs(res))) if ok.any() else None,
                "slope": fit.slope.to_dict(),
                "intercept": fit.intercept.to_dict(),
                "rms_band_excess_over_lambda": analysis.rms(d["band_excess"].values / lam, dphi).to_dict(),
                "n_runs": int(made.sum()),
                "n_failed": int((made & ~ok).sum()),
                "n_steady": int(d["steady"].values[ok].sum()),
                "max_penetration_m": float(np.nanmax(d["penetration_max"].values)) if ok.any() else None,
            }
        note = _find_outliers(ds.sel(rule=rule), rows)
        falls = analysis.falls_with_links([E(rows[k]["rms_residual_over_lambda"]) for k in sorted(rows, key=int)])
        dr = ds.sel(rule=rule)
        trend = error_trend(dr["residual_over_lambda"].transpose("n_links", "dphi").values, dr["n_links"].values,
                            dphi)
        per_rule[str(rule)] = {
            "per_n": rows,
            # the claim's criterion (LINKS_TREND_RULE), lambda^2 per link
            "squared_residual_slope_per_link": trend.to_dict(),
            # the superseded step-by-step criterion (analysis.FALLS_RULE): True holds, False fails, None undecided
            "rms_falls_with_n": falls,
            "outlier_note": note,  # None when no N's interval is wide
        }
    made = analysis.runs_made(ds)
    ok = made & ~ds["run_failed"].values
    return {
        "per_rule": per_rule,
        "n_runs": int(made.sum()),
        "n_failed": int((made & ~ok).sum()),
        "n_steady": int(ds["steady"].values[ok].sum()),
        "n_dphi": int(ds.sizes["dphi"]),
        "rules": {"fixed": "beta = 45 deg at every joint (paper Eq. 1 unchanged)",
                  "curvature": "beta = 45 deg x 3/N (same bending per length as 3 links)"},
        "residual": "RMS over dphi of theory.compatibility_residual / lambda (nearest branch); "
                    "'open_interval' leaves out dphi = +-pi (one physical state, the unstable "
                    "point between branches)",
        "steady_rule": analysis.STEADY_RULE,
        "slope_method": analysis.SLOPE_METHOD,
        "outlier_rule": OUTLIER_RULE,
    }


E = stats.Estimate.from_dict


END_TO_END = 0.75
"""A pair lies end to end (in line, not side by side) when its steady |dx| is at least this fraction of a
body's extent along x: the bodies overlap along less than a quarter of their length."""
IN_BAND_OVER_LAMBDA = 1e-3
"""A steady state lies inside the full compatibility band when its band excess is below this (lambda)."""
OUTLIER_RULE = (
    f"an N's RMS interval is wide when its width exceeds {O.WIDTH_FACTOR:g} x the median width of the "
    f"other N's; its outlying runs have |residual| above the N's median + {O.MAD_K:g} x {O.MAD_SCALE} MAD; "
    f"each is 'still drifting' (not steady, or settled only within the last {analysis.STEADY_WINDOW + 1} periods "
    "of its run), 'another compatible branch' (steady, nearest a branch other than the one(s) nearest "
    "the start dx0 = 0) or 'another steady state' (steady, off every branch: end to end when "
    f"|dx| >= {END_TO_END:g} x the body's extent, else side by side inside or outside the full "
    "compatibility band); 'runs_on_another_branch' lists, for every N, the runs that settled on another "
    "branch than their start's (they do not widen the interval: the residual is taken from the nearest "
    "branch)")


def _run_end_s(dx_t: np.ndarray, time: np.ndarray) -> float:
    """Time of the last finite sample of a run's dx(t) (runs stopped once steady end early), s."""
    fin = np.flatnonzero(np.isfinite(dx_t))
    return float(time[fin[-1]]) if fin.size else math.nan


def _arrangement(dx_m: float, dy_m: float, extent_m: float, excess: float, force: float) -> tuple[str, str]:
    """``(arrangement, description)`` of one steady state off the branches."""
    if math.isfinite(extent_m) and extent_m > 0 and abs(dx_m) >= END_TO_END * extent_m:
        return "end to end", (f"end to end (in line): |dx| = {abs(dx_m) / extent_m:.2f} of the body's extent, "
                              f"dy = {dy_m * 1e3:.0f} mm, mean contact force {force:.2g} N: the bodies do not "
                              "lie side by side, so compatibility does not constrain them")
    if math.isfinite(excess) and excess <= IN_BAND_OVER_LAMBDA:
        return "side by side, in band", (f"side by side inside the full compatibility band at dy = "
                                         f"{dy_m * 1e3:.0f} mm (the lateral offset lets a phase mismatch pass)")
    return "side by side, pressed", (f"side by side {excess:.3f} lambda outside the compatibility band at dy = "
                                     f"{dy_m * 1e3:.0f} mm, pressed (mean contact force {force:.2g} N)")


def _outlier_runs(d: xr.Dataset, lam: float) -> tuple[list[dict], float]:
    """The runs of one N that widen its interval, each with its cause (:data:`OUTLIER_RULE`)."""
    res = d["residual_over_lambda"].values
    mask, thr = O.outlying(res)
    other = O.branch_changes(d["dx_steady_over_lambda"].values, d["dphi"].values)
    time = d["time"].values
    out = []
    for j in np.flatnonzero(mask):
        r = d.isel(dphi=j)
        steady, settle = bool(r["steady"]), float(r["settle_time"])
        end = _run_end_s(r["dx"].values, time)
        drifting = not steady or not (settle <= end - (analysis.STEADY_WINDOW + 1) * analysis.PERIOD_S)
        cls = O.classify(drifting, bool(other[j]))
        arr, text = _arrangement(float(r["dx_steady"]), float(r["dy_steady"]), float(r["extent_x"]),
                                 float(r["band_excess"]) / lam, float(r["contact_force_mean"]))
        if cls == O.DRIFTING:
            text = f"not settled by {end:g} s (steady: {steady}, settle time {settle:g} s)"
        elif cls == O.OTHER_BRANCH:
            text = f"settled nearest branch n = {int(O.nearest_branch(r['dx_steady_over_lambda'], r['dphi']))}"
        out.append({"dphi_rad": float(r["dphi"]), "dphi_over_pi": float(r["dphi"]) / math.pi,
                    "residual_over_lambda": float(res[j]), "dx_steady_over_lambda": float(r["dx_steady_over_lambda"]),
                    "class": cls, "arrangement": arr, "why": text, "steady": steady, "settle_time_s": settle,
                    "run_end_s": end})
    return out, thr


def _branch_changes(d: xr.Dataset) -> list[dict]:
    dxl, dphi = d["dx_steady_over_lambda"].values, d["dphi"].values
    n = O.nearest_branch(dxl, dphi)
    return [{"dphi_rad": float(dphi[j]), "dphi_over_pi": float(dphi[j]) / math.pi,
             "dx_steady_over_lambda": float(dxl[j]), "branch": int(n[j]),
             "start_branches": list(O.start_branches(dphi[j]))}
            for j in np.flatnonzero(O.branch_changes(dxl, dphi))]


def _find_outliers(dr: xr.Dataset, rows: dict[str, dict]) -> str | None:
    """Fill ``rows`` (one rule's per-N summary) with the outlier findings; return the rule's note."""
    lam = float(dr.attrs["wavelength_m"])
    widths = {}
    for k, row in rows.items():
        lo, hi = row["rms_residual_over_lambda"]["ci95"]
        widths[k] = hi - lo if lo is not None and hi is not None else math.nan
    ratios = O.width_ratios(widths)
    notes = []
    for k, row in rows.items():
        wide = bool(ratios[k] > O.WIDTH_FACTOR)
        d = dr.sel(n_links=int(k))
        runs, thr = _outlier_runs(d, lam) if wide else ([], math.nan)
        row.update({"rms_interval_width": widths[k] if math.isfinite(widths[k]) else None,
                    "width_over_others_median": ratios[k] if math.isfinite(ratios[k]) else None,
                    "wide_interval": wide, "outlier_threshold_over_lambda": thr if math.isfinite(thr) else None,
                    "outliers": runs, "runs_on_another_branch": _branch_changes(d)})
        if wide:
            notes.append(_note(k, ratios[k], runs))
    return "; ".join(notes) or None


def _note(n: str, ratio: float, runs: list[dict]) -> str:
    head = f"N = {n}'s RMS interval is {ratio:.1f} x the other N's median width"
    if not runs:
        return head + f": no single run stands out (median + {O.MAD_K:g} MAD)"
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in runs:
        groups.setdefault((r["class"], r["arrangement"] if r["class"] == O.OTHER_STATE else ""), []).append(r)
    parts = []
    for (cls, arr), rs in groups.items():
        where = ", ".join(f"{r['dphi_over_pi']:+.3g} pi (residual {r['residual_over_lambda']:+.3f})" for r in rs)
        parts.append(f"{cls}{' (' + arr + ')' if arr else ''} at dphi = {where}")
    return f"{head}: {len(runs)} run(s) differ -- " + "; ".join(parts)


def _brief_outliers(per_n: dict[str, dict]) -> str:
    """``"; outliers: N = 7, 2 runs: another steady state (end to end) at dphi = -1, +1 pi"`` for the N
    whose interval is wide (:func:`_find_outliers`); empty when none is (or the summary has no findings)."""
    parts = []
    for n, row in per_n.items():
        runs = row.get("outliers") or []
        if not row.get("wide_interval"):
            continue
        kinds = dict.fromkeys(f"{r['class']}" + (f" ({r['arrangement']})" if r["class"] == O.OTHER_STATE else "")
                              for r in runs)
        at = ", ".join(f"{r['dphi_over_pi']:+.3g}" for r in runs)
        parts.append(f"N = {n}, {len(runs)} run(s): {', '.join(kinds)} at dphi = {at} pi" if runs
                     else f"N = {n}: wide interval, no single run stands out")
    return "; outliers: " + "; ".join(parts) if parts else ""


def _rms_text(per_n: dict) -> tuple[list[str], list[stats.Estimate], str]:
    ns = sorted(per_n, key=int)
    rms = [E(per_n[n]["rms_residual_over_lambda"]) for n in ns]
    return ns, rms, "RMS residual / lambda for N = " + ", ".join(f"{n}: {r:.3f}" for n, r in zip(ns, rms))


def _trend(rule: str) -> Callable[[dict], Verdict]:
    """The claim's judge: :data:`~._criteria.LINKS_TREND_RULE` on the rule's ``squared_residual_slope_per_link``."""
    def judge(s: dict) -> Verdict:
        r = s["per_rule"][rule]
        slope = E(r["squared_residual_slope_per_link"])
        ns, rms, text = _rms_text(r["per_n"])
        measured = (f"slope of the squared residual against N {slope:.3g} lambda^2 per link over {slope.n} runs "
                    f"in {slope.units} design points ({stats.interval_note(slope.level)}); {text}"
                    + _brief_outliers(r["per_n"]))  # the outliers: a finding, not part of the criterion
        value = {"squared_residual_slope_per_link": r["squared_residual_slope_per_link"],
                 "rms_residual_over_lambda": {n: r["per_n"][n]["rms_residual_over_lambda"] for n in ns}}
        if not slope.has_interval:
            return Verdict.none("no interval for the trend's slope (fewer than 3 design points with runs)",
                                measured, value)
        return Verdict.of([slope.below(0.0, "slope of the squared residual against N")], measured, value)
    return judge


def _falls(rule: str) -> Callable[[dict], Verdict]:
    """The superseded judge: ``analysis.FALLS_RULE``, step by step on the per-N RMS intervals."""
    def judge(s: dict) -> Verdict:
        per_n = s["per_rule"][rule]["per_n"]
        ns = sorted(per_n, key=int)
        rms = [E(per_n[n]["rms_residual_over_lambda"]) for n in ns]
        measured = "RMS residual / lambda for N = " + ", ".join(f"{n}: {r:.3f}" for n, r in zip(ns, rms))
        value = {n: per_n[n]["rms_residual_over_lambda"] for n in ns}
        if not all(r.has_interval for r in rms):
            return Verdict.none("an RMS residual without an interval (too few runs with a result)", measured, value)
        measured += _brief_outliers(per_n)  # a finding, not part of the criterion
        return Verdict.of(analysis.falls_with_links_checks(rms, [int(n) for n in ns]), measured, value)
    return judge


CLAIMS = tuple(
    Claim(f"error from compatibility falls as links are added ({text})",
          "the RMS error between simulation and Eq. (2) decreased with increasing link number (values withheld)",
          LINKS_TREND_RULE, _trend(rule),
          quote=(r"The root mean square (RMS) error of the simulation compatibility separation and the prediction "
                 r"(Eqn.~\ref{eqn:compatibility}) decreased with increasing link number (values withheld)."),
          where="Sec. III.C, Fig. 5", reads=(rule,),
          superseded=(SupersededCriterion(
              analysis.FALLS_RULE, _falls(rule),
              why="it judged a trend step by step: one noisy step (an N whose interval lies wholly above the "
                  "previous one's) decided it, whatever the other steps and the whole range showed; the "
                  "paper's words are a trend over the range"),))
    for rule, text in (("fixed", "joint amplitude 45 deg at every N"),
                       ("curvature", "joint amplitude 45 deg x 3/N"))
)


def figure(ds: xr.Dataset):
    from ..plotting.links import plot_links

    return plot_links(ds)


def stages(quick: bool) -> tuple[Plan, ...]:
    """The plan in looks (:mod:`._stages`): quick 5, 9 dphi; full 9, 17, 33."""
    return tuple(Plan(d) for d in thinned(plan(quick).dphi_rad, strides(quick)))


register(Study(
    name="links", paper_figure="5", plan=plan, stages=stages, dataset=dataset, summary=summary, claims=CLAIMS, figure=figure,
    description="Pairs of N = 3, 5, 7, 9-link swimmers at xi = 1 (d = 0.13 m): steady dx/lambda vs "
                "dphi with the compatibility line, and the RMS error per N (two joint-amplitude rules)."))
