"""Paper Fig. 5: pairs with 3, 5, 7 and 9 links."""

from __future__ import annotations

import numpy as np

from . import new_figure
from .pairs import finish_offset_panel, offset_panel

__all__ = ["plot_links"]

RULE_STYLE = {"fixed": ("tab:purple", "o"), "curvature": ("tab:cyan", "s")}


def plot_links(ds):
    """Figure of the ``links`` study dataset, laid out like paper Fig. 5.

    One panel per link number N (left to right): steady dx/lambda against
    dphi for each joint-amplitude rule, with the compatibility branches
    ``dx/lambda = dphi/2pi + n`` dashed.  Right: the RMS distance from the
    nearest branch against N.
    """
    ns = [int(n) for n in ds["n_links"].values]
    rules = [str(r) for r in ds["rule"].values]
    fig = new_figure(4.0 * len(ns) + 3.6, 4.2)
    gs = fig.add_gridspec(1, len(ns) + 1, width_ratios=[1] * len(ns) + [0.9])
    dphi = ds["dphi"].values
    for i, n in enumerate(ns):
        ax = fig.add_subplot(gs[0, i])
        for rule in rules:
            d = ds.sel(n_links=n, rule=rule)
            colour, marker = RULE_STYLE.get(rule, ("k", "o"))
            beta = np.degrees(float(d["joint_amplitude"]))
            offset_panel(ax, dphi, d["dx_steady_over_lambda"].values, d["steady"].values, colour=colour,
                         marker=marker, size=24, label=rf"{rule}: $\beta$ = {beta:.3g}$^\circ$")
        finish_offset_panel(ax, 1.0)
        ax.set_title(f"N = {n} links", loc="left")
        ax.legend(fontsize=7, loc="upper left")
        if i == 0:
            ax.set_ylabel(r"steady $\Delta x/\lambda$")
    ax = fig.add_subplot(gs[0, -1])
    for rule in rules:
        colour, marker = RULE_STYLE.get(rule, ("k", "o"))
        rms = [float(np.sqrt(np.nanmean(ds["residual_over_lambda"].sel(rule=rule, n_links=n).values ** 2)))
               for n in ns]
        ax.plot(ns, rms, marker=marker, color=colour, label=rule)
    ax.set_xticks(ns)
    ax.set_xlabel("links per swimmer N")
    ax.set_ylabel(r"RMS distance from compatibility, $/\lambda$")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.25)
    ax.legend(fontsize=8)
    ax.set_title("RMS error vs N", loc="left")
    fig.suptitle(
        rf"Pairs with N links, $\xi = {ds.attrs.get('waves_per_body', 1):g}$, d = {ds.attrs.get('channel_width_m', 0.13):g} m: "
        r"dashed: $\Delta x/\lambda = \Delta\phi/2\pi + n$; open markers: not steady", fontsize=11)
    return fig
