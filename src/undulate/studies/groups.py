"""Study ``groups`` (paper Fig. 6): nearest neighbours in groups of three and four swimmers.

Three 3-link swimmers in a channel d = 0.19 m with phases ``(0, dphi,
2 dphi)`` in their initial lateral stack (neighbours differ by dphi) at the
paper's nine dphi (full mode: 33 values over [-pi, pi]); four swimmers in
d = 0.22 m with every phase drawn uniformly from [0, 2 pi) (each draw seeded
from ``config.seed`` through the sweep's per-run seeds; quick: 8 draws,
full: 40).  xi = 1, 30 s, start straight, laterally in contact, dx0 = 0.

Neighbours are identified by **lateral order** at the end of the run (the
order of the swimmers' mean y over the steady-state window,
``_analysis.final_neighbours``): for each neighbouring pair ``dx = x_upper -
x_lower`` and ``dphi = wrap(phi_upper - phi_lower)`` into (-pi, pi].  The
steady dx is compared with the compatibility branches ``lambda (dphi/2pi +
n)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import xarray as xr

from .. import stats
from ._criteria import GROUP_CHANNEL_M, GROUP_RMS_TOL, GROUP_SLOPE_TOL, PAIR_CHANNEL_M
from . import _analysis as analysis
from ._analysis import group_records
from ._context import StudyContext
from ._protocol import Claim, Study, Verdict
from ._registry import register
from ._stages import strides, thinned
from ._runners import BODY_LENGTH_M, DURATION_S
from ._shared import group_part, group_sweep

XI = 1.0
SIZES = (3, 4)
"""The group sizes with a claim each (:data:`CLAIMS`, in this order)."""

NEIGHBOUR_FIELDS = {
    "group_size": ("1", "swimmers in the group"),
    "run_index": ("1", "run of the pair (coordinate 'run' of the trajectories)"),
    "rank": ("1", "lateral rank of the lower swimmer of the pair (0 = lowest)"),
    "lower": ("1", "id of the lower swimmer (initial stack order)"),
    "upper": ("1", "id of the upper swimmer"),
    "dphi": ("rad", "phase difference phi_upper - phi_lower, wrapped into (-pi, pi]"),
    "dx_steady": ("m", "steady longitudinal offset x_upper - x_lower"),
    "dx_steady_over_lambda": ("1", "dx_steady / lambda"),
    "dy_steady": ("m", "lateral offset y_upper - y_lower over the steady-state window"),
    "residual": ("m", "signed distance of dx_steady from the nearest compatibility branch"),
    "residual_over_lambda": ("1", "residual / lambda"),
    "band_excess": ("m", "distance outside the full compatibility band at dy_steady and the free "
                         "swimmer's A (0 = inside)"),
    "settle_time": ("s", "start of the steady state (NaN if not steady)"),
}
NEIGHBOUR_FLAGS = {
    "steady": "steady by the rule in attrs['steady_rule']",
    "order_stable": "the group's lateral order was the same in every period of the steady window",
    "order_changed": "the group's final lateral order differs from the initial stack",
}


@dataclass(frozen=True)
class Plan:
    """``dphi_rad`` (rad) of the groups of three; ``draws`` of four; ``pair_dphi_rad`` (rad) of the
    reference pairs (None: the groups' ``dphi_rad``)."""

    dphi_rad: tuple[float, ...]
    draws: int
    pair_dphi_rad: tuple[float, ...] | None = None

    @property
    def pairs(self) -> tuple[float, ...]:
        """dphi (rad) of the reference pairs."""
        return self.dphi_rad if self.pair_dphi_rad is None else self.pair_dphi_rad


FULL_STRIDES = (48, 12, 3, 1)
"""Full mode's looks over :func:`._analysis.group_cap_phases` (385 dphi): 9, 33, 129 and 385 dphi."""
FULL_DRAWS = (10, 40, 80, analysis.GROUP_CAP_DRAWS)
"""Full mode's draws of four at each look."""


def plan(quick: bool) -> Plan:
    """The mode's cap.  Quick: the paper's nine dphi, 8 draws of four.  Full: 385 dphi (step pi/192), 120
    draws, and the reference pairs at 33 dphi (step pi/16): they are compared with the groups on the RMS
    residual only, and their 33 decide that comparison by a wide margin (0.035 [0.026, 0.044] lambda
    against the groups' 0.12-0.14)."""
    if quick:
        return Plan(tuple(float(p) for p in analysis.group_phases(True)), analysis.GROUP_DRAWS[True])
    return Plan(tuple(float(p) for p in analysis.group_cap_phases()), analysis.GROUP_CAP_DRAWS,
                tuple(float(p) for p in analysis.group_phases(False)))


def part(n: int) -> str:
    """The plan part of the runs of groups of ``n`` (2: the reference pairs), what a claim ``reads``."""
    return f"size {int(n)}"


def dataset(ctx: StudyContext, p: Plan) -> xr.Dataset:
    """Groups of three and four, and pairs over the same dphi range (the scatter they are compared with);
    each size on the plan its part follows (:meth:`~._context.StudyContext.plan_for`: the reference
    pairs feed every claim, a size of three or four its own and the spacing claim)."""
    seed = ctx.seed
    plans = {n: ctx.plan_for(part(n), p) for n in (2, *SIZES)}

    def size(n: int) -> xr.Dataset:
        return ctx.shared_sweep(group_part(n), *group_sweep(n, plans[n].pairs if n == 2 else plans[n].dphi_rad,
                                                             plans[n].draws, seed))

    two, three, four, lone = ctx.together(lambda: size(2), lambda: size(3), lambda: size(4),
                                          lambda: ctx.lone_swimmer(waves_per_body=XI))
    return groups_dataset({2: two, 3: three, 4: four}, float(lone["amplitude_m"]))


def groups_dataset(sweeps: dict[int, xr.Dataset], amplitude_m: float) -> xr.Dataset:
    """Study dataset: one row per nearest-neighbour pair, and the trajectories per run."""
    lam = BODY_LENGTH_M / XI
    rows: list[dict] = []
    run_size, run_failed, xs, ys, phs = [], [], [], [], []
    time = next(iter(sweeps.values()))["time"].values
    nmax = max(sweeps)
    for n, sweep in sweeps.items():
        for r in analysis.sweep_runs(sweep):
            k = len(run_size)
            run_size.append(n)
            run_failed.append(r is None)
            pad = np.full((time.size, nmax), np.nan)
            x, y, ph = pad.copy(), pad.copy(), np.full(nmax, np.nan)
            if r is not None:
                x[:, :n], y[:, :n] = r["x"].values, r["y"].values
                ph[:n] = r["phase"].values
                traj = analysis.trajectory(r, lam)
                for rec in group_records(traj, amplitude_m):
                    rows.append({"group_size": n, "run_index": k, **rec})
            xs.append(x)
            ys.append(y)
            phs.append(ph)

    def col(name, dtype=float):
        return np.array([row[name] for row in rows], dtype=dtype)

    nb = ("neighbour",)
    data = {}
    for name, (units, long_name) in NEIGHBOUR_FIELDS.items():
        dtype = int if units == "1" and name not in ("dx_steady_over_lambda", "residual_over_lambda") else float
        data[name] = (nb, col(name, dtype), {"units": units, "long_name": long_name})
    for name, long_name in NEIGHBOUR_FLAGS.items():
        data[name] = (nb, col(name, bool), {"long_name": long_name})
    data.update({
        "x": (("run", "time", "swimmer"), np.array(xs), {"units": "m", "long_name": "centre of mass x "
                                                                               "(NaN: no such swimmer)"}),
        "y": (("run", "time", "swimmer"), np.array(ys), {"units": "m", "long_name": "centre of mass y"}),
        "phase": (("run", "swimmer"), np.array(phs), {"units": "rad", "long_name": "gait phase phi"}),
        "run_group_size": ("run", np.array(run_size), {"units": "1", "long_name": "swimmers in the run"}),
        "run_failed": ("run", np.array(run_failed, bool), {"long_name": "the simulation failed"}),
    })
    return xr.Dataset(
        data,
        coords={
            "neighbour": ("neighbour", np.arange(len(rows)), {"units": "1"}),
            "run": ("run", np.arange(len(run_size)), {"units": "1"}),
            "swimmer": ("swimmer", np.arange(nmax), {"units": "1", "long_name": "swimmer id (initial stack, "
                                                                              "bottom to top)"}),
            "time": ("time", time, {"units": "s", "long_name": "time"}),
        },
        attrs={
            "title": "groups of 3 and 4 swimmers: nearest-neighbour dx vs dphi (paper Fig. 6)",
            "conventions": "neighbours by lateral order (mean y over the steady window); dx = x_upper - "
                           "x_lower, dphi = wrap(phi_upper - phi_lower); compatibility dx = lambda (dphi/2pi + n)",
            "waves_per_body": XI,
            "wavelength_m": lam,
            "amplitude_m": amplitude_m,
            "channel_width_3_m": GROUP_CHANNEL_M[3],
            "channel_width_4_m": GROUP_CHANNEL_M[4],
            "phases_3": "(0, dphi, 2 dphi) bottom to top",
            "phases_4": "each uniform in [0, 2 pi), numpy default_rng(run seed)",
            "duration_s": DURATION_S,
            "steady_rule": analysis.STEADY_RULE,
            "slope_method": analysis.SLOPE_METHOD,
        },
    )


def summary(ds: xr.Dataset) -> dict:
    """Pure: per group size (2 = the reference pairs) slope (standard error) and RMS residual
    (bootstrap interval) over nearest-neighbour pairs."""
    per = {}
    for n in (2, 3, 4):
        sel = ds["group_size"].values == n
        runs = ds["run_group_size"].values == n
        res = ds["residual_over_lambda"].values[sel]
        dphi = ds["dphi"].values[sel]  # +dphi and -dphi: one design point mirrored (resampled together)
        run_of = ds["run_index"].values[sel]  # a run's neighbour pairs share their errors: one cluster
        fit = analysis.compatibility_fit(ds["dx_steady_over_lambda"].values[sel], dphi, runs=run_of)
        changed = [bool(ds["order_changed"].values[sel][run_of == r][0]) for r in np.unique(run_of)]
        per[str(n)] = {
            "group_size": n,
            "channel_width_m": GROUP_CHANNEL_M.get(n, PAIR_CHANNEL_M),
            "n_runs": int(runs.sum()),
            "n_failed": int(ds["run_failed"].values[runs].sum()),
            "n_neighbour_pairs": int(sel.sum()),
            "n_steady": int(ds["steady"].values[sel].sum()),
            "n_runs_lateral_order_changed": int(np.sum(changed)),
            "slope": fit.slope.to_dict(),
            "intercept": fit.intercept.to_dict(),
            "rms_residual_over_lambda": analysis.rms(res, dphi, run_of).to_dict(),
            "rms_residual_m": analysis.rms(ds["residual"].values[sel], dphi, run_of).to_dict(),
            "max_abs_residual_over_lambda": float(np.max(np.abs(res))) if res.size else None,
            "rms_band_excess_over_lambda": analysis.rms(ds["band_excess"].values[sel] / ds.attrs["wavelength_m"],
                                                 dphi, run_of).to_dict(),
            "mean_dy_steady_over_2A": float(np.mean(ds["dy_steady"].values[sel]) / (2 * ds.attrs["amplitude_m"]))
            if sel.any() else None,
        }
    return {
        "per_group_size": per,
        "lateral_spacing": spacing_summary(ds),
        "n_neighbour_pairs": int(ds.sizes["neighbour"]),
        "n_steady": int(ds["steady"].values.sum()),
        "neighbours": "by lateral order: mean y over the steady-state window at the end of the run",
        "residual": "RMS of theory.compatibility_residual / lambda over nearest-neighbour pairs",
        "steady_rule": analysis.STEADY_RULE,
        "slope_method": analysis.SLOPE_METHOD,
    }


PRINCIPAL_SHARE = 0.5
""""The principle influence of this variance ... is the larger lateral spacing": the full compatibility band
at each neighbour pair's measured lateral spacing (paper Eq. fullcompatibility, the range of compatible
phases the spacing allows) leaves less than this share of the groups' mean squared deviation from the
compatibility line unaccounted for, i.e. the spacing accounts for more than half of it, the largest share."""


def _cluster_mean(values: np.ndarray, clusters: np.ndarray) -> stats.Estimate:
    """Mean of the per-cluster means of the finite ``values`` (a run's neighbour pairs, and the runs at
    +dphi and -dphi, one cluster: :func:`._analysis.run_clusters`), with a t interval over the clusters."""
    ok = np.isfinite(values)
    v, c = values[ok], clusters[ok]
    return stats.mean(np.array([v[c == k].mean() for k in np.unique(c)], float))


def unexplained_share(residual, excess, clusters) -> stats.Estimate:
    """``sum(excess**2) / sum(residual**2)``: the share of the mean squared deviation from the
    compatibility line that lies outside the full band at the measured lateral spacing (``excess``:
    ``band_excess``, never larger than ``|residual|``; 0 when the spacing allows every deviation),
    with a BCa bootstrap interval over ``clusters`` (:func:`undulate.stats.bootstrap` on the clusters'
    sums, at the expanded levels).  NaN with no deviation; no interval with fewer than 3 clusters."""
    r, e, c = (np.asarray(a, float).ravel() for a in (residual, excess, clusters))
    ok = np.isfinite(r) & np.isfinite(e)
    r, e, c = r[ok], e[ok], c[ok]
    method = "bootstrap BCa over clusters (ratio of sums)"
    if r.size == 0 or not np.any(r != 0):
        return stats.Estimate(math.nan, n=int(r.size), method=method)
    value = float(np.sum(e * e) / np.sum(r * r))
    _, which = np.unique(c, return_inverse=True)
    k = int(which.max()) + 1
    if k < 3:
        return stats.Estimate(value, n=int(r.size), method=method)
    rr, ee = (np.bincount(which, w, minlength=k) for w in (r * r, e * e))

    def share(a, b, axis=-1):
        return np.sum(b, axis=axis) / np.sum(a, axis=axis)

    se, lo, hi = stats.bootstrap(share, rr, ee, vectorized=True)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return stats.Estimate(value, n=int(r.size), method=method)
    return stats.Estimate(value, se, lo, hi, int(r.size), method, stats.level(), k, k - 1)


def spacing_summary(ds: xr.Dataset) -> dict:
    """Lateral spacing and the deviation it allows: per group size the mean lateral spacing dy/2A of its
    neighbour pairs (t interval over clusters: a run's pairs, and the runs at +dphi and -dphi); over the
    groups of three and four together, the share of their mean squared deviation from the compatibility
    line left outside the band their measured spacing allows (:func:`unexplained_share`)."""
    two_a = 2 * float(ds.attrs["amplitude_m"])
    size = ds["group_size"].values
    keys = analysis.run_clusters(ds["run_index"].values, ds["dphi"].values)
    dy = ds["dy_steady"].values / two_a
    out = {"mean_dy_over_2A": {str(n): _cluster_mean(dy[size == n], keys[size == n]).to_dict() for n in (2, *SIZES)}}
    big = size > 2
    out["unexplained_share"] = unexplained_share(ds["residual"].values[big], ds["band_excess"].values[big],
                                                 keys[big]).to_dict()
    out["n_neighbour_pairs_groups"] = int(big.sum())
    out["note"] = ("dy: centre-to-centre lateral offset of neighbours over the steady window, over 2A (the free "
                   "swimmer's peak-to-peak amplitude); unexplained share: sum of band_excess^2 over sum of "
                   "residual^2 over the groups' neighbour pairs")
    return out


E = stats.Estimate.from_dict


def _spacing_explains(s: dict) -> Verdict:
    sp = s["lateral_spacing"]
    dy = {n: E(sp["mean_dy_over_2A"][n]) for n in ("2", "3", "4")}
    share = E(sp["unexplained_share"])
    measured = (f"mean dy/2A: pairs {dy['2']:.3g}, groups of 3 {dy['3']:.3g}, of 4 {dy['4']:.3g}; share of the "
                f"groups' squared deviation outside the band their spacing allows {share:.3g} "
                f"({sp['n_neighbour_pairs_groups']} neighbour pairs; {stats.interval_note(share.level)})")
    value = {"mean_dy_over_2A": sp["mean_dy_over_2A"], "unexplained_share": sp["unexplained_share"]}
    if not all(e.has_interval for e in (*dy.values(), share)):
        return Verdict.none("a mean spacing or the unexplained share without an interval (too few runs)",
                            measured, value)
    runs = sum(s["per_group_size"][n]["n_runs"] - s["per_group_size"][n]["n_failed"] for n in ("3", "4"))
    return Verdict.of([stats.Check.apart(dy["3"], dy["2"], "mean dy/2A, groups of 3 vs pairs"),
                       stats.Check.apart(dy["4"], dy["2"], "mean dy/2A, groups of 4 vs pairs"),
                       share.below(PRINCIPAL_SHARE, "share of squared deviation outside the band")],
                      measured, value, runs=runs)


def _group_follows(size: str) -> Callable[[dict], Verdict]:
    def judge(s: dict) -> Verdict:
        g, pair = s["per_group_size"][size], s["per_group_size"]["2"]
        slope, rms, rms2 = E(g["slope"]), E(g["rms_residual_over_lambda"]), E(pair["rms_residual_over_lambda"])
        measured = (f"slope {slope:.3f}, RMS residual {rms:.3f} lambda vs {rms2:.3f} lambda for pairs over the "
                    f"same dphi range ({g['n_neighbour_pairs']} neighbour pairs; {stats.interval_note(slope.level)})")
        value = {"slope": g["slope"], "rms_residual_over_lambda": g["rms_residual_over_lambda"],
                 "pairs_rms_residual_over_lambda": pair["rms_residual_over_lambda"]}
        if not (slope.has_interval and rms.has_interval and rms2.has_interval):
            return Verdict.none("a slope or RMS without an interval (too few neighbour pairs)", measured, value)
        return Verdict.of(analysis.group_follows_line_checks(slope, rms, rms2), measured, value,
                          runs=g["n_runs"] - g["n_failed"])  # "runs" in runs, not neighbour pairs
    return judge


CLAIMS = tuple(
    Claim(f"groups of {size} follow the compatibility line with more scatter than pairs",
          "nearest-neighbour dx agrees with compatibility; the variation is larger than in pair experiments",
          f"the 95 % interval of the slope lies within 1 +- {GROUP_SLOPE_TOL}, that of the RMS residual below "
          f"{GROUP_RMS_TOL} lambda and wholly above the pairs' (same xi and dphi range, d = {PAIR_CHANNEL_M} m); "
          "fails if an interval lies wholly outside its region or the RMS interval wholly below the pairs', "
          "undecided if one straddles its bound or the two RMS intervals overlap",
          _group_follows(str(size)),
          quote=(r"Examining the nearest neighbor $\Delta x_{i,i+1}$ versus $\Delta \phi_{i,i+1}$ we observe good "
                 r"agreement with the compatibility predictions (Fig.~\ref{fig:robotgroups}b). The variation in the "
                 r"longitudinal position was larger in the group experiments compared with the robot pair experiments "
                 r"suggesting potential collective effects present in the three and four robot experiments that were "
                 r"not captured in the pair experiments."),
          where="Sec. III.D, Fig. 6b", reads=(part(size), part(2)),
          bands={"slope": (1 - GROUP_SLOPE_TOL, 1 + GROUP_SLOPE_TOL), "rms_residual_over_lambda": (None, GROUP_RMS_TOL)})
    for size in SIZES) + (
    Claim("the groups' larger scatter comes mainly from the larger lateral spacing they are afforded",
          "the principal influence of the groups' variance from the compatibility prediction is their larger "
          "lateral spacing, which widens the range of compatible phases (Eq. fullcompatibility)",
          "the 95 % t interval of the mean neighbour spacing dy/2A of the groups of 3 and that of the groups of 4 "
          f"each lie wholly above the pairs' (d = {PAIR_CHANNEL_M} m; clusters: a run's neighbour pairs and the runs "
          "at +dphi and -dphi), and the 95 % bootstrap interval of the share of the groups' mean squared deviation "
          "from the line that lies outside the full compatibility band at each pair's measured dy is below "
          f"{PRINCIPAL_SHARE:g} (the spacing accounts for most of it); fails if a group's spacing interval lies "
          f"wholly below the pairs' or the share's wholly above {PRINCIPAL_SHARE:g}; undecided if spacing intervals "
          "overlap or the share's straddles", _spacing_explains,
          quote=(r"The principle influence of this variance from the compatibility prediction is the larger lateral "
                 r"spacing afforded to the larger robot groups."),
          where="Sec. III.D, Fig. 6b", reads=tuple(part(n) for n in (2, *SIZES)),
          bands={"unexplained_share": (None, PRINCIPAL_SHARE)}),
)


def figure(ds: xr.Dataset):
    from ..plotting.groups import plot_groups

    return plot_groups(_groups_only(ds))


def _groups_only(ds: xr.Dataset) -> xr.Dataset:
    """The dataset without the reference pairs (the figure shows groups of three and four)."""
    keep_nb = np.flatnonzero(ds["group_size"].values > 2)
    keep_run = np.flatnonzero(ds["run_group_size"].values > 2)
    return ds.isel(neighbour=keep_nb, run=keep_run)


def stages(quick: bool) -> tuple[Plan, ...]:
    """The plan in looks (:mod:`._stages`).  Quick: the dphi thinned and the draws of four in proportion
    (5 dphi, 4 draws; 9, 8).  Full: 9 dphi and 10 draws; 33, 40; 129, 80; 385, 120 (:data:`FULL_STRIDES`,
    :data:`FULL_DRAWS`), the reference pairs on the groups' dphi up to 33.  Full mode's cap is set by the
    runs the straddling slopes needed at a cap of 33 dphi and 40 draws (groups of three: ~640
    neighbour pairs at 97 %, ~690 at the fourth look's 97.5 %, so 385 dphi give 770; four: ~160 at
    97.5 %, 120 draws give 360), not by where their estimates may go."""
    p = plan(quick)
    if quick:
        s = strides(quick)
        return tuple(Plan(d, max(1, p.draws // k)) for d, k in zip(thinned(p.dphi_rad, s), s))
    return tuple(Plan(d, draws, d if len(d) <= len(p.pairs) else p.pairs)
                 for d, draws in zip(thinned(p.dphi_rad, FULL_STRIDES), FULL_DRAWS))


register(Study(
    name="groups", paper_figure="6", plan=plan, stages=stages, dataset=dataset, summary=summary, claims=CLAIMS, figure=figure,
    description="Groups of 3 (d = 0.19 m, nine dphi) and 4 swimmers (d = 0.22 m, random phases), "
                "xi = 1: nearest-neighbour steady dx vs dphi with the compatibility line, against pairs."))
