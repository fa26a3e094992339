"""Paper Fig. 9: final offset against the start, per confinement."""

from __future__ import annotations

import numpy as np

from . import new_figure

__all__ = ["plot_confinement", "plot_broadening_evidence"]


def plot_confinement(ds):
    """Figure from the ``confinement`` study dataset.

    Left: final ``dx/lambda`` against the start ``dx0/lambda``, one line per
    ``d/2A`` (colour; ``d`` the wall distance per swimmer, the pair's channel
    ``W = 2d``); the paper's range 0.6-1.2 solid, wider channels dashed.
    Right: width of the central state against ``d/2A`` (top axis: ``W``, mm) with the
    compatibility model's band widths (sinusoids; bodies of width w).
    """
    import matplotlib as mpl

    r = ds["d_over_2A"].values
    lo, hi = ds.attrs.get("paper_range_d_over_2A", (0.6, 1.2))
    cmap = mpl.colormaps["viridis"]
    norm = mpl.colors.Normalize(vmin=float(r.min()), vmax=float(r.max()) if r.size > 1 else float(r.min()) + 1)
    fig = new_figure(11.0, 4.4)
    ax = fig.add_subplot(1, 2, 1)
    x0 = ds["dx0"].values
    for i, ri in enumerate(r):
        inside = lo - 1e-9 <= ri <= hi + 1e-9
        ax.plot(x0, ds["dx_final_over_lambda"].values[i], "-" if inside else "--", marker="o", ms=3,
                color=cmap(norm(ri)), lw=1.2, label=f"{ri:.2g}")
    ax.plot([-1, 1], [-1, 1], ":", color="0.5", lw=0.8)
    ax.set_xlabel(r"initial $\Delta x_0/\lambda$")
    ax.set_ylabel(r"final $\Delta x_f/\lambda$")
    ax.set_title(r"$\Delta\phi = 0$; legend: $d/2A$ (dashed: beyond the paper's range)", fontsize=10)
    ax.legend(fontsize=7, ncol=2, title=r"$d/2A$", title_fontsize=8)

    ax = fig.add_subplot(1, 2, 2)
    ax.plot(r, ds["central_width"].values, "o-", color="k", label="simulation (range of final dx)")
    ax.plot(r, ds["model_width_thin"].values, "--", color="tab:green", label=r"model, sinusoids ($\Delta y = W-2A$)")
    ax.plot(r, ds["model_width_bodies"].values, ":", color="tab:green",
            label=r"model, bodies ($\Delta y = W-2A-2w$)")
    ax.axvspan(lo, hi, color="0.9", zorder=0, label="paper's range")
    ax.set_xlabel(r"$d/2A$ ($d$ per swimmer: channel $W = 2d$)")
    if "channel_width" in ds.coords:
        top = ax.secondary_xaxis("top", functions=(lambda v, k=float(ds["channel_width"].values[0] / r[0]): v * k * 1e3,
                                                    lambda v, k=float(ds["channel_width"].values[0] / r[0]): v / k / 1e3))
        top.set_xlabel("channel width W, mm", fontsize=8)
    ax.set_ylabel(r"width of the central state / $\lambda$")
    ax.legend(fontsize=8)
    return fig


def plot_broadening_evidence(row):
    """The evidence figure of the claim "the central state broadens as d/2A grows" from its
    ``claims.json`` row (:attr:`undulate.studies.Claim.evidence`).

    The central state's width (lambda) against ``d/2A``: the paper's range shaded grey; the confinements
    in it (filled) with the least-squares line fitted there, its slope, interval and the verdict in the
    title, and lines at the interval's two ends drawn through the fitted points' mean (the line of least
    squares passes through it); the confinements beyond the range hollow (not fitted).  The paper's
    sentence is written above; the legend, under the axes, and the verdict's rule below it.  5.6 in wide at 100 dpi with 10 pt labels, laid out by
    hand, as the generic evidence figure (:mod:`undulate._evidence`)."""
    import textwrap

    from .._evidence import FONT_PT, LINE_IN, WIDTH_IN, _NO, _OK, _UN, framed_figure
    from ..claims import quote_text
    from ..stats import Estimate

    v = row.get("value") or {}

    def numbers(key):
        return np.array([np.nan if x is None else float(x) for x in v.get(key) or []], float)

    d, w = numbers("d_over_2A"), numbers("central_width_over_lambda")
    lo, hi = (v.get("paper_range_d_over_2A") or (0.6, 1.2))[:2]
    slope = Estimate.from_dict(v.get("broadening_slope_per_d_over_2A"))
    icpt = Estimate.from_dict(v.get("broadening_intercept_over_lambda"))
    verdict = str(row.get("verdict") or "no result")
    color = {"holds": _OK, "fails": _NO, "undecided": _UN}.get(verdict, "0.4")

    header = textwrap.fill(f"Paper: {quote_text(row.get('quote') or '') or row.get('paper') or ''}", 72)
    footer = textwrap.fill(f"verdict: {verdict}. Holds when the slope's interval lies above 0, fails when its "
                           "upper end is at or below 0; hollow points lie beyond the paper's range and are "
                           "not fitted.", 76)
    title_in, ticks_in, panel_in, legend_in = 1.4 * LINE_IN + 0.05, 2.6 * LINE_IN + 0.05, 2.3, 3 * LINE_IN + 0.15
    fig, height, head_in, foot_in = framed_figure(header, footer, title_in + panel_in + ticks_in + legend_in)
    fig.subplots_adjust(left=0.8 / WIDTH_IN, right=1 - 0.12 / WIDTH_IN, top=1 - (head_in + title_in) / height,
                        bottom=(foot_in + legend_in + ticks_in) / height)
    ax = fig.add_subplot(1, 1, 1)
    ax.axvspan(lo, hi, color="0.9", lw=0, zorder=0, label=f"paper's range {lo:g}-{hi:g}")
    inside = (d >= lo - 1e-9) & (d <= hi + 1e-9) & np.isfinite(w)
    beyond = ~inside & np.isfinite(w) & np.isfinite(d)
    ax.plot(d[inside], w[inside], "o", color="#1f4e99", ms=6, zorder=3, label="central state's width")
    if beyond.any():
        ax.plot(d[beyond], w[beyond], "o", mfc="white", mec="#1f4e99", ms=6, zorder=3, label="beyond the range")
    if slope.finite and icpt.finite:
        xs = np.array([lo, hi])
        ax.plot(xs, icpt.value + slope.value * xs, "-", color=color, lw=1.8, zorder=2,
                label="least-squares line")
        if slope.has_interval:
            xm = float(np.mean(d[inside]))
            ym = icpt.value + slope.value * xm
            for k, b in enumerate((slope.low, slope.high)):
                ax.plot(xs, ym + b * (xs - xm), "--", color=color, lw=1.0, zorder=2,
                        label=f"slope's {100 * slope.level:.3g} % interval" if k == 0 else None)
        title = f"slope {slope:.2g} \u03bb per unit d/2A: {verdict}"
    else:
        title = f"no slope: fewer than 3 widths in {lo:g}-{hi:g} ({verdict})"
    ax.set_title(title, fontsize=FONT_PT)
    _broadening_limits(ax, d, w, slope, icpt, lo, hi)
    ax.set_xlabel("d/2A (d per swimmer: channel W = 2d)", fontsize=FONT_PT)
    ax.set_ylabel("width / \u03bb", fontsize=FONT_PT)
    ax.tick_params(labelsize=FONT_PT)
    fig.legend(*ax.get_legend_handles_labels(), fontsize=FONT_PT, ncol=2, frameon=False, loc="lower left",
               bbox_to_anchor=(0.0, foot_in / height), borderaxespad=0.2)
    return fig


def _broadening_limits(ax, d, w, slope, icpt, lo: float, hi: float) -> None:
    """Axis limits of :func:`plot_broadening_evidence`: every width, 0 and the fitted line's ends, padded;
    every confinement and the paper's range."""
    ys = [u for u in w[np.isfinite(w)]] + [0.0]
    if slope.finite and icpt.finite:
        ys += [icpt.value + slope.value * x for x in (lo, hi)]
    top, bottom = max(ys), min(ys)
    pad = 0.1 * (top - bottom) if top > bottom else 0.05
    ax.set_ylim(bottom - pad, top + pad)
    xs_all = [u for u in d[np.isfinite(d)]] + [lo, hi]
    ax.set_xlim(min(xs_all) - 0.05, max(xs_all) + 0.05)
