"""The sensitivity study's figure: which claims hold where, and the three demonstrations."""

from __future__ import annotations

import textwrap

import numpy as np

from . import new_figure

__all__ = ["plot_sensitivity"]

COLOURS = {"holds": "#8fd19e", "fails": "#f3a6ae", "no result": "#dddddd"}


def plot_sensitivity(ds, s: dict):
    """(a) one row per (factor, level) of the summary's table, one column per claim, coloured by
    verdict; (b) xi = 3/2 final dx/lambda against dphi/2pi per N; (c) equal-A rule: RMS residual
    against N; (d) width of the central state against d/2A per reading of d, with the model's; (e) the
    two-period contact impulse against |dphi| per linear drag of the ground (mean over phi0, scaled by
    its largest value, so the shapes compare)."""
    rows = list(dict.fromkeys((t["factor"], t["level"]) for t in s["table"]))
    fig = new_figure(15.0, max(6.0, 0.3 * len(rows) + 1.5))
    gs = fig.add_gridspec(4, 2, width_ratios=[1.5, 1])
    _verdict_grid(fig.add_subplot(gs[:, 0]), s["table"])
    _xi32_panel(fig.add_subplot(gs[0, 1]), ds)
    _links_panel(fig.add_subplot(gs[1, 1]), s["links_sets"])
    _confinement_panel(fig.add_subplot(gs[2, 1]), s)
    _impulse_panel(fig.add_subplot(gs[3, 1]), ds, s)
    return fig


def _verdict_grid(ax, table: list[dict]) -> None:
    """(a) the summary's table as a grid of verdicts: (factor, level) rows, claim columns."""
    from matplotlib.patches import Rectangle

    claims = list(dict.fromkeys(t["claim"] for t in table))
    rows = list(dict.fromkeys((t["factor"], t["level"]) for t in table))
    for t in table:
        i, j = rows.index((t["factor"], t["level"])), claims.index(t["claim"])
        ax.add_patch(Rectangle((j, i), 1, 1, facecolor=COLOURS.get(t["verdict"], "#dddddd"), edgecolor="white"))
        ax.text(j + 0.5, i + 0.5, t["verdict"], ha="center", va="center", fontsize=7)
    ax.set_xlim(0, len(claims))
    ax.set_ylim(len(rows), 0)
    ax.set_xticks(np.arange(len(claims)) + 0.5, [textwrap.fill(c, 16) for c in claims], fontsize=7)
    ax.xaxis.tick_top()
    ax.set_yticks(np.arange(len(rows)) + 0.5, [f"{f}: {lv}" for f, lv in rows], fontsize=7)
    ax.set_title("(a) which claims hold where (one factor changed at a time)", fontsize=9)


def _xi32_panel(bx, ds) -> None:
    """(b) xi = 3/2 pairs: final dx/lambda against dphi/2pi per case (links per body, duration)."""
    dphi = ds["dphi"].values / (2 * np.pi)
    for i in range(ds.sizes["case"]):
        if str(ds["claim"].values[i]) == "xi32":
            bx.plot(dphi, ds["dx_final_over_lambda"].values[i], "o-", ms=3, label=str(ds["level"].values[i]))
    bx.plot(dphi, dphi, "k--", lw=0.8, label="compatibility")
    bx.set_xlabel("dphi / 2 pi")
    bx.set_ylabel("final dx / lambda")
    bx.set_title("(b) xi = 3/2: links per body", fontsize=9)
    bx.legend(fontsize=6)


def _links_panel(cx, sets: dict) -> None:
    """(c) the link-number sets: RMS residual (95 % interval) against N, side by side."""
    for k, L in enumerate(sets.values()):
        r = L["rms_residual_over_lambda"]
        v = np.array([np.nan if q["value"] is None else q["value"] for q in r])
        lo = np.array([np.nan if q["ci95"][0] is None else q["ci95"][0] for q in r])
        hi = np.array([np.nan if q["ci95"][1] is None else q["ci95"][1] for q in r])
        n = np.asarray(L["n_links"], float) + 0.08 * (k - 1.5)  # side by side
        cx.errorbar(n, v, yerr=[v - lo, hi - v], marker="o", ms=3, capsize=2, label=L["label"])
    if sets:
        cx.set_yscale("log")
        cx.legend(fontsize=5)
    cx.set_xlabel("links N (equal-A rule: A held at the 3-link value)")
    cx.set_ylabel("RMS residual / lambda")
    cx.set_title("(c) link-number trend at fixed d/2A (all dphi)", fontsize=9)


def _confinement_panel(dx, s: dict) -> None:
    """(d) the central state's width against d/2A per reading of d (per swimmer: W = 2d, the default;
    whole width: W = d), measured and the bodies' model in the same channels."""
    from ..theory import neutral_offset_m

    A = s["amplitude_3_links_m"]
    r = np.linspace(0.3, 1.6, 131)
    for key, c in s["confinement"].items():
        line = dx.plot(c["d_over_2A"], c["central_width_over_lambda"], "o", label=f"measured, d {key}")[0]
        scale = float(c["channel_width_m"][0]) / float(c["d_over_2A"][0])  # W per unit d/2A, m
        model = 2 * neutral_offset_m(r * scale, A, 0.54, c["body_width_m"]) / 0.54
        dx.plot(r, model, "-", color=line.get_color(), lw=0.8, label=f"model, d {key}")
    dx.axvspan(0.6, 1.2, color="0.9", zorder=0)
    dx.set_xlabel("d / 2A (centre-line A)")
    dx.set_ylabel("central state width / lambda")
    dx.set_title("(d) confinement: where the central state opens", fontsize=9)
    dx.legend(fontsize=6)


def _impulse_panel(ex, ds, s: dict) -> None:
    """(e) the two-period impulse against |dphi| per linear drag (mean over phi0, over its largest)."""
    if "impulse_drag" in ds.sizes:
        dp = np.abs(ds["impulse_dphi"].values)
        order = np.argsort(dp, kind="stable")
        r2 = {r["drag_N_s_per_m"]: r["r2"]["value"] for r in s["impulse"].get("by_drag", [])}
        for k, c in enumerate(ds["impulse_drag"].values):
            if not np.isfinite(ds["impulse_drag_all"].values[k]).any():  # no runs (failed, or not run)
                continue
            m = np.nanmean(ds["impulse_drag_all"].values[k], axis=1)
            top = np.nanmax(m)
            if np.isfinite(top) and top > 0:
                rr = r2.get(float(c))
                ex.plot(dp[order] / np.pi, m[order] / top, "o-", ms=3,
                        label=f"{c:g} N s/m" + ("" if rr is None else f", R^2 {rr:.2f}"))
        if ex.get_legend_handles_labels()[0]:
            ex.legend(fontsize=6, title="linear drag per link", title_fontsize=6)
        else:  # the impulse runs were not run (the claim they would explain does not fail) or all failed
            ex.text(0.5, 0.5, "no impulse runs", ha="center", va="center", transform=ex.transAxes, fontsize=8)
    ex.set_xlabel("|dphi| / pi")
    ex.set_ylabel("impulse over 2 periods / its largest")
    ex.set_title("(e) contact impulse against detuning, by drag (default 2)", fontsize=9)
