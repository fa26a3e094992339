"""Paper Fig. 6: nearest neighbours in groups of three and four swimmers."""

from __future__ import annotations

import numpy as np

from . import new_figure
from .pairs import finish_offset_panel, offset_panel

__all__ = ["plot_groups"]

GROUP_STYLE = {3: ("tab:red", "s"), 4: ("tab:blue", "o")}


def plot_groups(ds, example_run: int | None = None):
    """Figure of the ``groups`` study dataset, laid out like paper Fig. 6.

    (a) One four-swimmer run (``example_run``; default the first): each
    swimmer's x/lambda (relative to the group mean) over time, and its
    lateral position y.  (b) Steady nearest-neighbour dx/lambda against
    dphi, three swimmers (red squares) and four (blue circles), with the
    compatibility branches ``dx/lambda = dphi/2pi + n`` dashed.
    """
    lam = float(ds.attrs["wavelength_m"])
    fig = new_figure(13.0, 4.6)
    gs = fig.add_gridspec(2, 2, width_ratios=[1.0, 1.15])
    ax_x, ax_y, ax = fig.add_subplot(gs[0, 0]), fig.add_subplot(gs[1, 0]), fig.add_subplot(gs[:, 1])

    fours = np.flatnonzero((ds["run_group_size"].values == 4) & ~ds["run_failed"].values)
    k = int(fours[0]) if example_run is None and fours.size else example_run
    t = ds["time"].values
    if k is not None:
        x = ds["x"].values[k]
        y = ds["y"].values[k]
        ph = ds["phase"].values[k]
        n = int(ds["run_group_size"].values[k])
        with np.errstate(invalid="ignore"):  # a run its stopping rule ended is NaN after the stop
            centre = np.where(np.isfinite(x[:, :n]).any(axis=1), np.nansum(x[:, :n], axis=1) / n, np.nan)
        for j in range(n):
            line, = ax_x.plot(t, (x[:, j] - centre) / lam, lw=1.0,
                              label=rf"swimmer {j}: $\phi$ = {np.degrees(ph[j]):.0f}$^\circ$")
            ax_y.plot(t, y[:, j], lw=0.8, color=line.get_color())
        ax_x.legend(fontsize=7, ncol=2, loc="upper left")
    ax_x.set_ylabel(r"$(x - \bar{x})/\lambda$")
    ax_x.set_title(f"(a) four swimmers, d = {ds.attrs.get('channel_width_4_m', 0.22):g} m (run {k})", loc="left")
    ax_y.set_ylabel("y (m)")
    ax_y.set_xlabel("time (s)")
    for a in (ax_x, ax_y):
        a.set_xlim(t[0], t[-1])
        a.grid(alpha=0.25)

    for n in (3, 4):
        sel = ds["group_size"].values == n
        if not sel.any():
            continue
        colour, marker = GROUP_STYLE[n]
        d = ds.attrs.get(f"channel_width_{n}_m", float("nan"))
        offset_panel(ax, ds["dphi"].values[sel], ds["dx_steady_over_lambda"].values[sel],
                     ds["steady"].values[sel], colour=colour, marker=marker, size=30,
                     label=f"{n} swimmers, d = {d:g} m")
    finish_offset_panel(ax, 1.0)
    ax.set_ylabel(r"nearest-neighbour steady $\Delta x/\lambda$")
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title(r"(b) $\Delta x = x_{upper} - x_{lower}$ vs $\Delta\phi$; dashed: compatibility", loc="left")
    fig.suptitle(rf"Groups, $\xi = {ds.attrs.get('waves_per_body', 1):g}$, neighbours by lateral order; "
                 "open markers: not steady", fontsize=11)
    return fig
