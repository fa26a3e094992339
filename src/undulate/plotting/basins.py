"""Paper Fig. 8: dx(t) from a range of starts, and the displacement maps."""

from __future__ import annotations

import numpy as np

from . import new_figure, phase_axis
from .packing import _edges

__all__ = ["plot_basins"]


def plot_basins(ds):
    """Figure from the ``basins`` study dataset.

    (a) ``dx/lambda`` over time for every ``dphi = 0`` start, coloured by
    outcome (returned to 0: blue; pushed away: red), with the measured
    thresholds; (b) the map of ``(dx_f - dx0)/lambda`` over ``(dphi,
    dx0/lambda)`` for the simulation (crosses: runs whose pair never touched) and (c) for the sinusoid
    basin model, with the compatibility lines dashed.
    """
    fig = new_figure(14.0, 4.6)
    gs = fig.add_gridspec(1, 3, width_ratios=[1.0, 1.0, 1.0])

    ax = fig.add_subplot(gs[0, 0])
    t = ds["time"].values
    ret = ds["scan_returned"].values
    for x, r, series in zip(ds["start"].values, ret, ds["scan_dx_over_lambda"].values):
        ax.plot(t, series, color="tab:blue" if r else "tab:red", lw=0.8, alpha=0.8)
    ax.plot([], [], color="tab:blue", label="returns to 0")
    ax.plot([], [], color="tab:red", label="pushed away")
    for key in ("threshold_positive", "threshold_negative"):
        inner, outer = ds.attrs[key]
        if np.isfinite(inner) and np.isfinite(outer):
            ax.axhspan(min(inner, outer), max(inner, outer), color="0.6", alpha=0.4, lw=0)
    ax.set_xlabel("time (s)")
    ax.set_ylabel(r"$\Delta x/\lambda$")
    ax.set_title(r"(a) $\Delta\phi = 0$; grey: threshold bracket", fontsize=10)
    if "channel_width_m" in ds.attrs:
        conf = ds.attrs.get("confinement_d_over_2A")
        fig.suptitle(f"Pairs in a W = {100 * float(ds.attrs['channel_width_m']):g} cm channel"
                     + ("" if conf is None else f" (d/2A = {float(conf):.2f}, d per swimmer)"), fontsize=11)
    ax.legend(fontsize=8, loc="upper left")
    ax.set_xlim(t[0], t[-1])

    dphi = ds["dphi"].values
    dx0 = ds["dx0"].values
    sim = ds["grid_displacement_over_lambda"].values
    th = ds["theory_displacement_over_lambda"].values
    vmax = float(np.nanmax(np.abs(np.concatenate([sim.ravel(), th.ravel()])))) or 1.0
    for j, (data, title) in enumerate(((sim, "(b) three-link swimmers"), (th, "(c) sinusoidal swimmers"))):
        ax = fig.add_subplot(gs[0, j + 1])
        mesh = ax.pcolormesh(_edges(dphi), _edges(dx0), np.ma.masked_invalid(data), cmap="RdBu_r",
                             vmin=-vmax, vmax=vmax, shading="flat")
        for n in range(-2, 3):
            ax.plot(dphi, dphi / (2 * np.pi) + n, "k--", lw=0.7)
        ax.set_xlim(_edges(dphi)[0], _edges(dphi)[-1])
        ax.set_ylim(_edges(dx0)[0], _edges(dx0)[-1])
        phase_axis(ax.xaxis)
        ax.set_xlabel(r"$\Delta\phi$ (rad)")
        ax.set_ylabel(r"$\Delta x_0/\lambda$")
        if j == 0 and "grid_touched" in ds:  # runs whose pair never touched: left out of the clusters claim
            P, X = np.meshgrid(dphi, dx0)
            apart = ~ds["grid_touched"].values.astype(bool)
            if apart.any():
                ax.plot(P[apart], X[apart], "x", color="k", ms=6, label="never touched")
                ax.legend(fontsize=8, loc="lower right")
        ax.set_title(title, fontsize=10)
    cb = fig.colorbar(mesh, ax=fig.axes[-2:], shrink=0.9)
    cb.set_label(r"$(\Delta x_f - \Delta x_0)/\lambda$")
    return fig
