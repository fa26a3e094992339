"""Experiment versus simulation: the same observables on a tracked video and on
the simulation of the same gait, phases and channel.

An experiment is a dataset from :func:`undulate.track.track_video` whose
``config`` attribute holds its scene (gait, phases, swimmer geometry,
channel): given on the ``undulate track`` command line or taken from the
robot log (``--gait-from``).  :func:`matching_simulation` runs that scene
from straight bodies at gait time 0 with the experiment's first measured
longitudinal offsets and records the same body point the tracker measures,
the centre of the middle link (:func:`undulate.observables.middle_link_pose`),
so both are compared like with like.

Steady offsets: the experiment's and simulation's ``dx / lambda`` of each
lateral-neighbour pair are averaged over whole gait periods and the last
``periods`` period averages give the steady value, with a Student-t
confidence interval of their mean (``scipy.stats.t``).  Residuals between
experiment, simulation and the compatibility line (the nearest branch,
:func:`undulate.theory.compatibility_residual`) carry their intervals
(Welch's for a difference of two means).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
from pathlib import Path

import numpy as np

from .errors import ParameterError

__all__ = ["experiment_offsets", "matching_simulation", "steady_offset", "compare_experiment", "compare",
           "CONFIDENCE", "STEADY_PERIODS"]

CONFIDENCE = 0.95
"""Confidence level of every interval reported."""
STEADY_PERIODS = 5
"""Whole gait periods at the end of a run that make the steady value."""


def _scene(exp):
    from .params import Scene

    try:
        cfg = json.loads(exp.attrs["config"])["scene"]
    except (KeyError, TypeError, ValueError):
        raise ParameterError("EXP", "a tracked experiment that records its gait, phases and channel (undulate track "
                             "with --phases ... or --gait-from)", exp.attrs.get("video", "dataset")) from None
    return Scene.from_dict(cfg)


def experiment_offsets(ds):
    """Neighbour offsets of a tracked (or simulated) dataset: ``dx``, ``dy`` (m),
    ``dphi`` (rad), ``lower``, ``upper`` over (time, pair), as
    :func:`undulate.observables.neighbour_offsets`; NaN wherever either robot is
    untracked.  Gaps are bridged (linearly) only to decide the lateral order."""
    from .observables import neighbour_offsets

    y = ds["y"].values
    filled = y.copy()
    t = ds["time"].values
    for j in range(y.shape[1]):
        ok = np.isfinite(y[:, j])
        if ok.any():
            filled[:, j] = np.interp(t, t[ok], y[ok, j])
    off = neighbour_offsets(ds.assign(y=(ds["y"].dims, filled)))
    tracked = ds["tracked"].values if "tracked" in ds else np.isfinite(ds["x"].values)
    lo, hi = off["lower"].values, off["upper"].values
    both = np.take_along_axis(tracked, lo, axis=1) & np.take_along_axis(tracked, hi, axis=1)
    for v in ("dx", "dy"):
        off[v] = off[v].where(both)
    return off


def matching_simulation(exp, *, out: str | os.PathLike | None = None):
    """Simulate the experiment ``exp``'s scene and return it with the tracker's body point.

    The robots are stacked in their lateral order in the experiment's first
    frame with all robots tracked, each pair started at that frame's
    longitudinal offset (straight bodies, gait time 0); the run lasts until
    the experiment's last frame and is recorded at its frame rate.  The
    result has ``swimmer`` = robot id (as in ``exp``), ``x``, ``y`` and
    ``heading`` of the middle link (the centre of mass kept as ``x_com``,
    ``y_com``).
    """
    from .params import SimOptions
    from .simulation import simulate
    from .observables import middle_link_pose

    scene = _scene(exp)
    tracked = exp["tracked"].values
    all_in = np.flatnonzero(tracked.all(axis=1))
    if all_in.size == 0:
        raise ParameterError("EXP", "an experiment with at least one frame where every robot is tracked",
                             exp.attrs.get("video", ""))
    k = all_in[0]
    x0, y0 = exp["x"].values[k], exp["y"].values[k]
    order = np.argsort(y0, kind="stable")  # robot ids from lowest to highest y
    phases = np.asarray(scene.phases_rad)[order]
    dx0 = tuple(float(v) for v in np.diff(x0[order]))
    t = exp["time"].values
    step = float(exp.attrs.get("frame_interval", np.median(np.diff(t))))
    duration = float(t[-1])
    if not duration > 0:
        raise ParameterError("EXP", "an experiment ending after gait time 0 (its start_time)", duration)
    sc = dataclasses.replace(scene, phases_rad=tuple(phases), dx0_m=dx0)
    opts = SimOptions(duration_s=duration + 0.5 * step, sample_rate_hz=1.0 / step,
                      record=("x", "y", "heading", "node_x", "node_y", "contact_force_pair", "penetration"))
    sim = simulate(sc, opts)
    rank = np.argsort(order)  # simulated swimmer of each robot id
    sim = sim.isel(swimmer=rank).assign_coords(swimmer=np.arange(len(order)),
                                               phase=("swimmer", np.asarray(scene.phases_rad), sim["phase"].attrs))
    mx, my, mh = middle_link_pose(sim)
    dims = ("time", "swimmer")
    sim = sim.rename({"x": "x_com", "y": "y_com"}).assign(
        x=(dims, mx, {"units": "m", "long_name": "x of the middle link's centre (the robot tag's centre)"}),
        y=(dims, my, {"units": "m", "long_name": "y of the middle link's centre (the robot tag's centre)"}),
        heading=(dims, mh, {"units": "rad", "long_name": "middle-link orientation: head -> tail from +x"}))
    sim.attrs.update({"body_point": exp.attrs.get("body_point", "middle link centre"),
                      "matched_experiment": exp.attrs.get("video", ""),
                      "note": "contact_force_pair is indexed by the simulation's stacking order, not robot id"})
    if out is not None:
        from ._cliutil import write_netcdf_atomic

        write_netcdf_atomic(sim, Path(out))
    return sim


def steady_offset(series, period_s: float, periods: int = STEADY_PERIODS, confidence: float = CONFIDENCE) -> dict:
    """Steady value of one pair's offset series (a DataArray over time, NaN = missing).

    The mean of the last ``periods`` whole-period averages and its Student-t
    interval; ``steady``: the same averages all lie within 0.01 of their mean
    (the rule of :func:`undulate.observables.steady_state`).  Only periods
    with every sample present count: the offset swings through the gait
    cycle (by ~0.25 lambda at the middle link), so a period missing a few
    samples (occlusion, dropped frames) would be biased toward the phases it
    kept.  ``n_skipped``: complete periods were lacking, so that many
    incomplete ones were skipped.
    """
    from scipy import stats

    from .observables import period_average

    t = series["time"].values
    if t.size == 0 or (t[-1] - t[0]) / period_s < 1.0 - 1e-9:  # shorter than a period: none to average
        pa = cover = np.empty(0)
    else:
        pa = period_average(series, period_s).values
        cover = period_average(series.notnull().astype(float), period_s).values
    complete = pa[np.isfinite(pa) & (cover >= 1.0 - 1e-9)]
    skipped = int(np.sum(np.isfinite(pa[-periods:]) & (cover[-periods:] < 1.0 - 1e-9)))
    pa = complete[-periods:]
    n = int(pa.size)
    if n < 2:
        return {"value": float(pa[0]) if n else float("nan"), "ci": [float("nan")] * 2, "sem": float("nan"),
                "n_periods": n, "n_skipped": skipped, "steady": False}
    mean = float(pa.mean())
    sem = float(pa.std(ddof=1) / math.sqrt(n))
    lo, hi = stats.t.interval(confidence, n - 1, loc=mean, scale=sem) if sem > 0 else (mean, mean)
    return {"value": mean, "ci": [float(lo), float(hi)], "sem": sem, "n_periods": n, "n_skipped": skipped,
            "steady": bool(np.all(np.abs(pa - mean) <= 0.01))}


def _difference(a: dict, b: dict, confidence: float) -> dict:
    """a - b with Welch's interval (t with Welch-Satterthwaite degrees of freedom)."""
    from scipy import stats

    d = a["value"] - b["value"]
    va, vb = a["sem"] ** 2, b["sem"] ** 2
    se = math.sqrt(va + vb)
    if not math.isfinite(se):
        return {"value": d, "ci": [float("nan")] * 2, "sem": se}
    if se == 0:
        return {"value": d, "ci": [d, d], "sem": 0.0}
    na, nb = a["n_periods"], b["n_periods"]
    dof = (va + vb) ** 2 / ((va ** 2 / (na - 1) if va else 0.0) + (vb ** 2 / (nb - 1) if vb else 0.0))
    lo, hi = stats.t.interval(confidence, dof, loc=d, scale=se)
    return {"value": d, "ci": [float(lo), float(hi)], "sem": se, "dof": float(dof)}


def compare_experiment(exp, sim, *, periods: int = STEADY_PERIODS, confidence: float = CONFIDENCE) -> dict:
    """Residuals between the experiment ``exp``, its simulation ``sim``
    (:func:`matching_simulation`) and the compatibility line, pair by pair
    (pairs by lateral rank)."""
    from . import theory

    lam = float(exp.attrs["wavelength"])
    period = float(exp.attrs["period"])
    scale, unit = (lam, "lambda") if math.isfinite(lam) else (1.0, "m")
    eo, so = experiment_offsets(exp), experiment_offsets(sim)
    t_e = exp["time"].values
    pairs = []
    for p in range(eo.sizes["pair"]):
        ex = eo["dx"].isel(pair=p) / scale
        sx = so["dx"].isel(pair=p) / scale
        se = steady_offset(ex, period, periods, confidence)
        ss = steady_offset(sx, period, periods, confidence)
        # the experiment's pair at its last tracked frame, by robot id
        lo_id = int(eo["lower"].values[-1, p])
        hi_id = int(eo["upper"].values[-1, p])
        dphi = float(eo["dphi"].values[-1, p])
        entry = {"pair": p, "lower": lo_id, "upper": hi_id, "dphi_rad": dphi, "unit": unit,
                 "experiment": se, "simulation": ss}
        if math.isfinite(lam):
            th = float(se["value"] - theory.compatibility_residual(se["value"] * lam, dphi, lam) / lam)
            # no whole period tracked (a short or much occluded video): no steady value, no branch
            branch = int(round(th - dphi / (2 * math.pi))) if math.isfinite(th) else None
            entry["theory"] = {"value": th, "branch": branch}
            exact = {"value": th, "sem": 0.0, "n_periods": 2}
            entry["experiment_minus_theory"] = _difference(se, exact, confidence)
            entry["simulation_minus_theory"] = _difference(ss, exact, confidence)
        entry["experiment_minus_simulation"] = _difference(se, ss, confidence)
        # the time series, sample by sample: simulation interpolated onto the video's times
        s_on_e = np.interp(t_e, sim["time"].values, sx.values, left=np.nan, right=np.nan)
        diff = ex.values - s_on_e
        ok = np.isfinite(diff)
        entry["timeseries_rms_experiment_minus_simulation"] = float(np.sqrt(np.mean(diff[ok] ** 2))) if ok.any() \
            else float("nan")
        entry["timeseries_samples"] = int(ok.sum())
        pairs.append(entry)
    tracked = exp["tracked"].values
    return {"experiment": exp.attrs.get("video", ""), "wavelength_m": lam, "period_s": period,
            "channel_width_m": float(exp.attrs["channel_width"]), "tracked_fraction": float(tracked.mean()),
            "frames_missing": int(exp.attrs.get("frames_missing", 0)), "pairs": pairs}


def _fig_steady(results: list[dict]):
    from .plotting import new_figure
    from .plotting.pairs import finish_offset_panel, offset_panel

    fig = new_figure(5.2, 4.0)
    ax = fig.add_subplot()
    unit = results[0]["pairs"][0]["unit"] if results and results[0]["pairs"] else "lambda"
    for key, colour, marker, label, dx in (("experiment", "k", "s", "experiment (tracked video)", -0.03),
                                           ("simulation", "tab:purple", "o", "simulation", 0.03)):
        ph = np.array([e["dphi_rad"] for r in results for e in r["pairs"]])
        v = np.array([e[key]["value"] for r in results for e in r["pairs"]])
        ci = np.array([e[key]["ci"] for r in results for e in r["pairs"]]).reshape(-1, 2)
        st = np.array([e[key]["steady"] for r in results for e in r["pairs"]], bool)
        err = np.abs(ci - v[:, None]).T
        ax.errorbar(ph + dx, v, yerr=np.where(np.isfinite(err), err, 0), fmt="none", ecolor=colour, lw=0.9, zorder=2)
        offset_panel(ax, ph + dx, v, st, colour=colour, marker=marker, label=label)
    finish_offset_panel(ax, 1.0 if unit == "lambda" else None, span=0.3)
    ax.set_ylabel(r"steady $\Delta x/\lambda$" if unit == "lambda" else r"steady $\Delta x$ (m)")
    ax.plot([], [], "k--", lw=0.9, label=r"compatibility $\Delta x = \lambda\Delta\phi/2\pi + n\lambda$")
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title(f"experiment vs simulation (middle-link centre; {int(100 * CONFIDENCE)} % intervals)", fontsize=9)
    return fig


def _fig_timeseries(exp, sim, result: dict):
    from .plotting import new_figure

    lam = result["wavelength_m"]
    scale = lam if math.isfinite(lam) else 1.0
    eo, so = experiment_offsets(exp), experiment_offsets(sim)
    n = eo.sizes["pair"]
    fig = new_figure(6.4, 1.2 + 1.8 * max(n, 1))
    axes = fig.subplots(max(n, 1), 1, sharex=True, squeeze=False)[:, 0]
    for p in range(n):
        ax = axes[p]
        e = result["pairs"][p]
        ax.plot(so["time"].values, so["dx"].values[:, p] / scale, color="tab:purple", lw=1.0, label="simulation")
        ax.plot(eo["time"].values, eo["dx"].values[:, p] / scale, "k.", ms=2.0, label="experiment (tracked)")
        if "theory" in e:
            ax.axhline(e["theory"]["value"], color="k", ls="--", lw=0.8, label="compatibility")
        ax.set_ylabel((r"$\Delta x/\lambda$" if math.isfinite(lam) else r"$\Delta x$ (m)")
                      + f"\nrobots {e['lower']}-{e['upper']}")
        ax.set_title(rf"$\Delta\phi$ = {math.degrees(e['dphi_rad']):.0f} deg", fontsize=8, loc="left")
        ax.grid(alpha=0.25)
    axes[0].legend(fontsize=7, loc="best")
    axes[-1].set_xlabel("time (s)")
    return fig


def compare(experiments, out_dir: str | os.PathLike, *, periods: int = STEADY_PERIODS,
            confidence: float = CONFIDENCE, log=None) -> dict:
    """Compare tracked experiments (paths to ``undulate track`` outputs) with their simulations.

    Writes into ``out_dir`` (created): ``compare.png`` and ``compare.pdf``
    (steady dx/lambda against dphi: experiment, simulation, compatibility
    line), ``<name>_dx.png`` (dx(t) overlay per experiment), ``<name>_sim.nc``
    (the matching simulation) and ``compare.json`` (residuals with their
    intervals).  Every input is read and checked before anything is written.
    Returns the JSON content.
    """

    from ._io import atomic_output, make_folder
    from .provenance import provenance

    if not 0 < confidence < 1:
        raise ParameterError("confidence", "in (0, 1)", confidence)
    if int(periods) != periods or periods < 2:
        raise ParameterError("--periods", "an integer >= 2", periods)
    paths = [Path(p) for p in experiments]
    if not paths:
        raise ParameterError("EXP", "at least one tracked experiment (.nc)", None)
    stems = [p.stem for p in paths]
    if len(set(stems)) != len(stems):
        raise ParameterError("EXP", "files with distinct names (outputs are named after them)", stems)
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ParameterError("--out", "a directory", str(out_dir))
    exps = []
    from ._cliutil import load_netcdf

    for p in paths:
        ds = load_netcdf(p, "EXP", "an existing netCDF file from undulate track")
        for v in ("x", "y", "tracked"):
            if v not in ds:
                raise ParameterError("EXP", f"a tracked experiment (variable {v!r} missing)", str(p))
        _scene(ds)
        if ds.sizes["swimmer"] < 2:
            raise ParameterError("EXP", "an experiment with at least 2 robots (offsets need a pair)", str(p))
        exps.append(ds)
    created = not out_dir.exists()
    make_folder(out_dir, "--out")  # before the simulations: a folder that cannot be made is refused first
    results, sims = [], []
    try:
        for p, ds in zip(paths, exps):
            if log:
                log(f"simulating {p.name} ...")
            sim = matching_simulation(ds)
            r = compare_experiment(ds, sim, periods=periods, confidence=confidence)
            r["experiment"] = p.name
            results.append(r)
            sims.append(sim)
    except BaseException:  # a diverged simulation, a signal: leave no empty folder behind
        if created:
            with contextlib.suppress(OSError):
                out_dir.rmdir()
        raise
    summary = {
        "what": "steady dx/lambda of lateral neighbours (middle-link centres), experiment vs simulation vs the "
                "compatibility line dx = lambda (dphi/2pi + n), nearest branch",
        "steady_rule": f"mean of the last {periods} whole-period averages; interval: Student t of that mean "
                       f"(scipy.stats.t), differences: Welch",
        "confidence": confidence,
        "experiments": results,
        "provenance": provenance(),
    }
    figs = [(_fig_steady(results), ["compare.png", "compare.pdf"])]
    figs += [(_fig_timeseries(ds, sim, r), [f"{p.stem}_dx.png"]) for p, ds, sim, r in zip(paths, exps, sims, results)]
    for fig, names in figs:
        for name in names:
            with atomic_output(out_dir / name) as tmp:
                fig.savefig(tmp, dpi=150, format=Path(name).suffix[1:])
    from ._cliutil import write_netcdf_atomic

    for p, sim in zip(paths, sims):
        write_netcdf_atomic(sim, out_dir / f"{p.stem}_sim.nc")
    with atomic_output(out_dir / "compare.json") as tmp:
        tmp.write_text(json.dumps(_json_safe(summary), indent=2, allow_nan=False) + "\n")
    return summary


def _json_safe(obj):
    """NaN and infinities as null (strict JSON); numpy scalars as Python numbers."""
    if isinstance(obj, dict):
        return {k: _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    return obj
