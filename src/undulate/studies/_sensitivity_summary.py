"""The sensitivity study's summary (:mod:`.sensitivity`): per case the verdict by its claim's own
criterion and the key numbers, one ``_summary_*`` step a family of cases, and the table.

Pure functions of the dataset; the criteria are the studies' own (:mod:`._analysis`, :mod:`._criteria`).
"""

from __future__ import annotations

import json
import math
import warnings
from typing import Any

import numpy as np
import xarray as xr

from .. import stats, theory
from . import _analysis as analysis
from ._criteria import CENTRAL, LINE_RMS_TOL, LINE_SLOPE_TOL, R2_MIN, WIDTH_TOL
from ._explanations import results_by_case
from ._protocol import FAILS, HOLDS, NO_RESULT, UNDECIDED
from ._runners import BODY_LENGTH_M
from ._sensitivity_design import (
    FACTOR_GROUPS, SKIPPABLE_GROUPS, DEFAULT_BODY_M, IMPULSE_DRAG_DEFAULT, PAPER_RANGE_HIGH,
    D_READING_SCALE, PER_SWIMMER, WHOLE_WIDTH, CaseId, confinement_case, group_case,
    impulse_case)


NOT_RUN = "not run (the claim it would explain does not fail, or in quick mode only findings read it)"
"""The table's reason for the rows of a skipped factor group (verdict ``no result``)."""


def _line(y, dphi) -> dict[str, Any]:
    fit = analysis.compatibility_fit(y, dphi)
    res = theory.compatibility_residual(np.asarray(y, float), np.asarray(dphi, float), 1.0)
    return {"slope": fit.slope, "rms": analysis.rms(res, dphi)}


def line_checks(slope: stats.Estimate, rms: stats.Estimate) -> list[stats.Check]:
    """The pairs study's criterion as :class:`~undulate.stats.Check` s: the slope's interval within
    1 +- LINE_SLOPE_TOL, the RMS residual's below LINE_RMS_TOL lambda."""
    return analysis.line_checks(slope, rms)


def follows_line(slope: stats.Estimate, rms: stats.Estimate) -> bool | None:
    """The pairs study's criterion on the intervals: True when both lie inside their regions, False when
    one lies wholly outside, None when one straddles a bound -- or when one has no interval
    (:func:`line_verdict` tells the two apart, as the pairs study does)."""
    if not (slope.has_interval and rms.has_interval):
        return None
    return stats.decide(line_checks(slope, rms))


def line_verdict(slope: stats.Estimate, rms: stats.Estimate) -> str:
    """:func:`follows_line` as a verdict: ``no result`` without both intervals, else holds / fails /
    undecided."""
    return _verdict(follows_line(slope, rms), missing=not (slope.has_interval and rms.has_interval))


LINK_SETS = {
    "links": "equal-A, lambda = L",
    "links-x": "equal-A, lambda = lambda_x",
    "links-guided": "equal-A, yaw recoil removed, lambda = L",
    "links-guided-x": "equal-A, yaw recoil removed, lambda = lambda_x",
}
"""The link-number sets (:class:`~._sensitivity_design.CaseSet` value -> label): A held at the 3-link
value at every N; the compatibility line drawn with lambda = L (the links study's) or with lambda_x, the
wavelength along the channel measured in the runs; the free body, or the body whose yaw recoil a heading
guide removes (only that changed)."""

CLAIM_LABELS = {"xi1": "xi = 1 pairs follow the line", "xi32": "xi = 3/2 pairs follow the line",
                "swim": "swimming pairs follow the line"}


def _verdict(ok: bool | None, missing: bool) -> str:
    """A table verdict: ``no result`` only where a number (an interval) is ``missing``; else ``ok`` True
    holds, False fails, None undecided (an interval straddles a bound of its region)."""
    if missing:
        return NO_RESULT
    return HOLDS if ok is True else FAILS if ok is False else UNDECIDED


def central_width(dx_final) -> float:
    xf = np.asarray(dx_final, float)
    c = np.isfinite(xf) & (np.abs(xf) < CENTRAL)
    return float(xf[c].max() - xf[c].min()) if c.any() else math.nan


def _broadens(ratios, widths, high=PAPER_RANGE_HIGH) -> bool | None:
    r, w = np.asarray(ratios, float), np.asarray(widths, float)
    ok = np.isfinite(w)
    inside = ok & (r <= high + 1e-6)
    if not inside.any():
        return None
    grows = bool(np.all(np.diff(w[ok]) >= -WIDTH_TOL))
    return bool(np.nanmax(w[inside]) > WIDTH_TOL and grows)


def _summary_cases(ds: xr.Dataset, skipped: frozenset[str] = frozenset()) -> tuple[dict[str, dict], list[dict]]:
    """Per pair case (keyed by its display label): its ``case_id``, the line fit and the pairs verdict;
    the table rows of the cases judged by the pairs criterion (not the link sets; ``no result``, not run,
    for a case of a ``skipped`` factor group)."""
    dphi = ds["dphi"].values
    open_ = np.abs(dphi) < np.pi - 1e-9
    table, cases = [], {}
    for i in range(ds.sizes["case"]):
        c = ds.isel(case=i)
        cid = CaseId.parse(str(c["case_id"].values))
        claim, factor, level = str(c["claim"].values), str(c["factor"].values), str(c["level"].values)
        y = c["dx_final_over_lambda"].values
        fit = _line(y, dphi)
        entry = {"case_id": str(cid), "claim": claim, "factor": factor, "level": level,
                 "default": bool(c["is_default"]), "n_links": int(c["n_links"]),
                 "joint_amplitude_deg": math.degrees(float(c["joint_amplitude"])),
                 "amplitude_m": float(c["amplitude"]), "wavelength_m": float(c["wavelength"]),
                 "slope": fit["slope"].to_dict(),
                 "rms_residual_over_lambda": fit["rms"].to_dict(),
                 "rms_residual_over_lambda_open_interval": analysis.rms(c["residual_over_lambda"].values[open_],
                                                                 dphi[open_]).to_dict(),
                 "n_runs": int(np.isfinite(y).sum()), "n_steady": int(c["steady"].values.sum()),
                 "follows_line": follows_line(fit["slope"], fit["rms"]),
                 "follows_line_verdict": line_verdict(fit["slope"], fit["rms"])}
        cases[f"{claim}: {factor}: {level}"] = entry
        if cid.case_set.value not in LINK_SETS:
            table += _not_run([{"claim": CLAIM_LABELS[claim], "factor": factor, "level": level,
                                "verdict": entry["follows_line_verdict"],
                                "key number": f"slope {fit['slope']:.2f}, RMS {fit['rms']:.3f} lambda, "
                                              f"{entry['n_steady']}/{entry['n_runs']} steady"}],
                              FACTOR_GROUPS.get(cid.case_set) in skipped)
    return cases, table


def _not_run(rows: list[dict], skipped: bool) -> list[dict]:
    """Table ``rows`` as they stand, or, for a ``skipped`` factor group, with verdict ``no result`` and
    the reason :data:`NOT_RUN` (in ``key number`` and ``reason``)."""
    if not skipped:
        return rows
    return [{**t, "verdict": NO_RESULT, "key number": NOT_RUN, "reason": NOT_RUN} for t in rows]


def skipped_groups(ds: xr.Dataset) -> frozenset[str]:
    """The factor groups the dataset did not run (its ``skipped_factor_groups`` attribute; none if absent)."""
    return frozenset(json.loads(ds.attrs.get("skipped_factor_groups") or "[]"))


def _summary_link_sets(cases: dict[str, dict]) -> tuple[dict[str, dict], list[dict]]:
    """The links study's criterion on each set of N (equal-A rule; lambda = L or lambda_x; recoil or not)."""
    link_sets, table = {}, []
    for claim, label in LINK_SETS.items():
        links = sorted((e for e in cases.values() if CaseId.parse(e["case_id"]).case_set.value == claim),
                       key=lambda e: e["n_links"])
        if not links:
            continue
        rms = [stats.Estimate.from_dict(e["rms_residual_over_lambda"]) for e in links]
        rms_open = [stats.Estimate.from_dict(e["rms_residual_over_lambda_open_interval"]) for e in links]
        out = {"label": label, "n_links": [e["n_links"] for e in links],
               "joint_amplitude_deg": [e["joint_amplitude_deg"] for e in links],
               "amplitude_m": [e["amplitude_m"] for e in links],
               "wavelength_over_L": [e["wavelength_m"] / BODY_LENGTH_M for e in links],
               "rms_residual_over_lambda": [r.to_dict() for r in rms],
               "rms_residual_over_lambda_open_interval": [r.to_dict() for r in rms_open],
               "falls": analysis.falls_with_links(rms), "falls_open_interval": analysis.falls_with_links(rms_open)}
        out["falls_verdict"] = _verdict(out["falls"], missing=_no_trend(rms))
        out["falls_open_interval_verdict"] = _verdict(out["falls_open_interval"], missing=_no_trend(rms_open))
        link_sets[claim] = out
        rows = (((label + " (all dphi)"), rms, out["falls_verdict"]),) + (
            ((label + ", dphi = +-pi left out"), rms_open, out["falls_open_interval_verdict"]),) * (claim == "links")
        for lab, seq, verdict in rows:
            table.append({"claim": "error falls as links are added", "factor": links[0]["factor"],
                          "level": lab, "verdict": verdict,
                          "key number": "RMS / lambda at N = " + ", ".join(
                              f"{e['n_links']}: {r:.4f}" for e, r in zip(links, seq))
                          + ("" if claim in ("links", "links-guided") else "; lambda_x / L " + ", ".join(
                              f"{e['wavelength_m'] / BODY_LENGTH_M:.3f}" for e in links))})
    return link_sets, table


def _no_trend(rms_by_n) -> bool:
    """No link-number trend can be judged: fewer than two N, or an RMS without an interval."""
    seq = list(rms_by_n)
    return len(seq) < 2 or not all(r.has_interval for r in seq)


def _linear(idphi, impulse) -> tuple[stats.LineFit, bool | None, str]:
    """The potential study's criterion: the impulse's line fit against |dphi|, whether it is linear (the
    R^2 interval above R2_MIN and the slope's above 0: True, False when one lies wholly outside, None when
    one straddles or has no interval) and the verdict (``no result`` only without the intervals)."""
    u, pooled = analysis.by_abs_dphi(idphi, impulse)  # +-dphi: one design point (analysis.by_abs_dphi)
    f = stats.line_fit(u, analysis.row_means(pooled))
    missing = not (f.r2.has_interval and f.slope.has_interval)
    ok = None if missing else stats.decide([f.r2.above(R2_MIN, "R^2"), f.slope.above(0.0, "slope")])
    return f, ok, _verdict(ok, missing)


def _summary_impulse(ds: xr.Dataset) -> tuple[dict[str, Any], list[dict]]:
    """potential: impulse linear in |dphi| (on the potential study's grid) with and without dphi = +-pi,
    and per linear drag of the ground (``by_drag``, each row with its ``case_id``)."""
    imp, idphi = ds["impulse"].values, ds["impulse_dphi"].values
    pot, table = {}, []
    for label, use in (("all dphi (default)", np.ones(idphi.shape, bool)),
                       ("dphi = +-pi left out", np.abs(idphi) < np.pi - 1e-9)):
        f, ok, verdict = _linear(idphi[use], imp[use])
        pot[label] = {"slope_Ns_per_rad": f.slope.to_dict(), "r2": f.r2.to_dict(), "linear": ok,
                      "linear_verdict": verdict}
        table.append({"claim": "impulse over 2 periods linear in |dphi|", "factor": "dphi = +-pi",
                      "level": label, "verdict": verdict,
                      "key number": f"a = {f.slope:.3g} N s/rad, R^2 = {f.r2:.2f}"})
    pot_drag = []
    if "impulse_drag" in ds.sizes:
        big = np.abs(idphi) >= np.pi / 2 - 1e-9
        for k, c in enumerate(ds["impulse_drag"].values):
            allv = ds["impulse_drag_all"].values[k]
            with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN rows: failed or not run (NaN)
                f, ok, verdict = _linear(idphi, analysis.row_means(allv))
                spread = float(np.nanmedian((np.nanmax(allv, 1) / np.nanmin(allv, 1))[big]))
                esc = float(np.nanmean(ds["impulse_drag_escape"].values[k][big]))
            pot_drag.append({"case_id": str(impulse_case(float(c))), "drag_N_s_per_m": float(c),
                             "default": bool(c == IMPULSE_DRAG_DEFAULT),
                             "slope_Ns_per_rad": f.slope.to_dict(), "r2": f.r2.to_dict(), "linear": ok,
                             "linear_verdict": verdict,
                             "phi0_spread_large_dphi": spread, "first_period_dx_large_dphi": esc})
            table.append({"claim": "impulse over 2 periods linear in |dphi|", "factor": "drag (impulse runs)",
                          "level": f"{c:g} N s/m per link" + (" (default)" if c == IMPULSE_DRAG_DEFAULT else ""),
                          "verdict": verdict,
                          "key number": f"R^2 = {f.r2:.2f}; |dphi| >= pi/2: first-period |dx| {esc:.3f} lambda, "
                                        f"phi0 max/min {spread:.1f}"})
    pot["by_drag"] = pot_drag
    return pot, table


def _summary_confinement(ds: xr.Dataset) -> tuple[dict[str, dict], list[dict]]:
    """confinement: per reading of d (keyed by :data:`D_READINGS`, each with its ``case_id``) the channel
    widths, the central state's width over d/2A and whether it broadens, by centre-line A and by edge
    amplitude A + w/2; the bodies' model opens where the clearance W - 2A - 2w turns positive."""
    A = float(ds["amplitude_3_links"])
    ratios = ds["d_over_2A"].values
    w = DEFAULT_BODY_M
    conf = {}
    for ri, reading in enumerate(ds["d_reading"].values):
        reading = str(reading)
        k = D_READING_SCALE[reading]
        widths = [central_width(ds["conf_dx_final_over_lambda"].values[ri, j]) for j in range(len(ratios))]
        r_edge = ratios * A / (A + w / 2)
        conf[reading] = {
            "case_id": str(confinement_case(reading)), "d_reading": reading, "body_width_m": w,
            "d_over_2A": ratios, "d_over_2A_edge": r_edge,
            "channel_width_m": 2 * k * ratios * 2 * A,
            "central_width_over_lambda": np.asarray(widths),
            "model_opening_d_over_2A": (2 * A + 2 * w) / (2 * k * 2 * A),
            "broadens_centreline_A": _broadens(ratios, widths),
            "broadens_edge_A": _broadens(r_edge, widths)}
    table = []
    label = {PER_SWIMMER: "wall distance per swimmer, W = 2d (default)", WHOLE_WIDTH: "whole channel width, W = d"}
    for reading, v in conf.items():
        wtxt = ", ".join(f"{r:.2f} ({W * 1000:.0f} mm): {x:.3f}" for r, W, x in
                         zip(v["d_over_2A"], v["channel_width_m"], v["central_width_over_lambda"]))
        table.append({"claim": "central state broadens over d/2A 0.6-1.2", "factor": "reading of d",
                      "level": label.get(reading, reading),
                      "verdict": _verdict(v["broadens_centreline_A"], missing=v["broadens_centreline_A"] is None),
                      "key number": f"width/lambda at d/2A (W) = {wtxt}; bodies' model opens at d/2A = "
                                    f"{v['model_opening_d_over_2A']:.2f}"})
    v = conf[PER_SWIMMER]
    table.append({"claim": "central state broadens over d/2A 0.6-1.2", "factor": "definition of A",
                  "level": "edge amplitude A + w/2 (default: centre line A)",
                  "verdict": _verdict(v["broadens_edge_A"], missing=v["broadens_edge_A"] is None),
                  "key number": "width/lambda at d/2(A + w/2) = " + ", ".join(
                      f"{r:.2f}: {x:.3f}" for r, x in zip(v["d_over_2A_edge"], v["central_width_over_lambda"]))})
    return conf, table


def _finite_mean(values) -> float:
    v = np.asarray(values, float)
    return float(v[np.isfinite(v)].mean()) if np.isfinite(v).any() else math.nan


def _groups_summary(ds: xr.Dataset) -> dict[str, dict[str, Any]]:
    """Per group case (keyed ``"3 in 0.19 m"``, each with its ``case_id``): slope and RMS residual (95 %
    intervals) of the neighbours against the line, their median lateral spacing, the fractions inside the
    contact-free band and short of the line, and the groups study's verdict against the reference pairs
    (size 2)."""
    out: dict[str, dict[str, Any]] = {}
    ref_rms = None
    for i in range(ds.sizes.get("group_case", 0)):
        c = ds.isel(group_case=i)
        size, w = int(c["group_size"]), float(c["group_channel_width"])
        dphi, dx = c["group_dphi"].values, c["group_dx_over_lambda"].values
        ok = np.isfinite(dphi) & np.isfinite(dx)
        dphi, dx, run_of = dphi[ok], dx[ok], c["group_run"].values[ok]
        fit = analysis.compatibility_fit(dx, dphi, runs=run_of)  # a run's neighbour pairs: one cluster
        rms = analysis.rms(c["group_residual_over_lambda"].values[ok], dphi, run_of)
        if size == 2:
            ref_rms = rms
        entry = {"case_id": str(group_case(size, w)), "group_size": size, "channel_width_m": w,
                 "default": bool(c["group_default"]),
                 "n_neighbour_pairs": int(ok.sum()), "slope": fit.slope.to_dict(),
                 "rms_residual_over_lambda": rms.to_dict(),
                 "median_dy_m": float(np.median(c["group_dy"].values[ok])) if ok.any() else math.nan,
                 "fraction_inside_band": float(np.mean(c["group_band_excess"].values[ok] == 0)) if ok.any() else math.nan,
                 "fraction_short_of_line": float(np.mean(np.abs(dx) < np.abs(dphi) / (2 * np.pi))) if ok.any() else math.nan,
                 "follows_line_more_scatter": None, "follows_line_more_scatter_verdict": NO_RESULT}
        if size > 2 and ref_rms is not None:
            entry["follows_line_more_scatter"] = ok = analysis.group_follows_line(fit.slope, rms, ref_rms)
            entry["follows_line_more_scatter_verdict"] = _verdict(ok, missing=not (
                fit.slope.has_interval and rms.has_interval and ref_rms.has_interval))
        out[f"{size} in {w:g} m"] = entry
    return out


def _group_table(groups: dict[str, dict]) -> list[dict]:
    """The table rows of the groups of three and four (the reference pairs have none)."""
    return [{"claim": f"groups of {g['group_size']} follow the line, more scatter",
             "factor": "neighbour spacing (channel width)",
             "level": f"d = {g['channel_width_m']:g} m" + (" (default)" if g["default"] else ": the pairs' spacing"),
             "verdict": g["follows_line_more_scatter_verdict"],
             "key number": f"slope {stats.Estimate.from_dict(g['slope']):.2f}, RMS "
                           f"{stats.Estimate.from_dict(g['rms_residual_over_lambda']):.3f} lambda, "
                           f"neighbour spacing {g['median_dy_m'] * 1000:.1f} mm"}
            for g in groups.values() if g["group_size"] != 2]


def summary(ds: xr.Dataset) -> dict:
    """Pure: per case the verdict by its claim's criterion and the key numbers (the ``_summary_*`` steps,
    every per-case entry with its ``case_id``); the table (``no result``, :data:`NOT_RUN`, for the rows
    of a skipped factor group); ``skipped_factor_groups`` and the ids of their cases, ``skipped_cases``
    (whose explanations are then not judged: :data:`~._explanations._protocol.NOT_RUN`).  Which look's
    plan each group kept is the study JSON's (``stages``: ``frozen_parts``)."""
    skipped = skipped_groups(ds)
    cases, table = _summary_cases(ds, skipped)
    link_sets, link_rows = _summary_link_sets(cases)
    pot, pot_rows = _summary_impulse(ds)
    conf, conf_rows = _summary_confinement(ds)
    groups = _groups_summary(ds)
    table += (_not_run(link_rows, "links" in skipped) + _not_run(pot_rows, "impulse" in skipped)
              + _not_run(conf_rows, "confinement" in skipped) + _not_run(_group_table(groups), "groups" in skipped))
    out = {"cases": cases, "groups": groups, "confinement": conf, "impulse": pot}
    skipped_cases = sorted(str(c) for c in results_by_case(out) if FACTOR_GROUPS.get(c.case_set) in skipped)
    return {"table": table, "cases": cases,
            "links_equal_A": link_sets.get("links"), "links_sets": link_sets,
            "confinement": conf, "impulse": pot,
            "groups": groups,
            "skipped_factor_groups": [g for g in SKIPPABLE_GROUPS if g in skipped],
            "skipped_cases": skipped_cases,
            "swim_drag_pair_speed_m_s": _finite_mean(ds["swim_drag_pair_speed"].values),
            "impulse_Ns": ds["impulse"].values,
            "amplitude_3_links_m": float(ds["amplitude_3_links"]),
            "criteria": {"pairs": f"slope 95 % interval within 1 +- {LINE_SLOPE_TOL}, RMS upper bound < {LINE_RMS_TOL} "
                                  "lambda (the pairs study's)",
                         "links": "RMS falls at every step in N and the largest N's interval lies below N = 3's",
                         "confinement": f"central width > {WIDTH_TOL} lambda within d/2A <= 1.2, never "
                                        f"shrinking by more than {WIDTH_TOL}"}}
