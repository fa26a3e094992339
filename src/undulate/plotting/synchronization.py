"""Closed-loop synchronization: pairs (final vs initial phase difference, forces) and groups (R(t))."""

from __future__ import annotations

import numpy as np

from . import new_figure, phase_axis

__all__ = ["plot_sync_pairs", "plot_sync_groups"]

_HOLD = {True: ("tab:red", "o", "positions held"), False: ("tab:blue", "s", "positions free")}


def plot_sync_pairs(ds):
    """Per controller family: final against initial phase difference (held and free), and
    the contact force before against after (log-log, the diagonal dashed)."""
    ctrls = [str(c) for c in ds["controller"].values]
    fig = new_figure(5.2 * len(ctrls), 8.4)
    d0 = ds["dphi0_rad"].values
    for j, c in enumerate(ctrls):
        v = ds.sel(controller=c).isel(replicate=0)
        ax = fig.add_subplot(2, len(ctrls), j + 1)
        for h in v["hold_x"].values:
            col, mk, label = _HOLD[bool(h)]
            ax.plot(d0, v["dphi_final"].sel(hold_x=h).values, mk, color=col, mec="k", mew=0.5, label=label)
        ax.axhline(0, color="k", lw=0.6)
        for y in (-np.pi, np.pi):
            ax.axhline(y, color="k", lw=0.6, ls="--")
        phase_axis(ax.xaxis)
        phase_axis(ax.yaxis)
        ax.set_xlabel(r"initial $\Delta\phi$ (rad)")
        ax.set_ylabel(r"final $\Delta\phi$ (rad)")
        ax.set_title(c, fontsize=10)
        ax.legend(fontsize=8)
        ax = fig.add_subplot(2, len(ctrls), len(ctrls) + j + 1)
        for h in v["hold_x"].values:
            col, mk, label = _HOLD[bool(h)]
            fs = v["force_start"].sel(hold_x=h).values
            fe = v["force_end"].sel(hold_x=h).values
            ax.loglog(np.maximum(fs, 1e-4), np.maximum(fe, 1e-4), mk, color=col, mec="k", mew=0.5, label=label)
        lim = [1e-4, max(1.0, float(np.nanmax(ds["force_start"].values)) * 1.5)]
        ax.plot(lim, lim, "k--", lw=0.8)
        ax.set_xlabel("mean contact force, first 10 s (N)")
        ax.set_ylabel("mean contact force, last 10 s (N)")
    return fig


def plot_sync_groups(ds):
    """Order parameter R(t) of every run, one panel per controller, coloured by group size."""
    ctrls = [str(c) for c in ds["controller"].values]
    fig = new_figure(5.2 * len(ctrls), 4.2)
    t = ds["time"].values
    sizes = [int(n) for n in ds["n_swimmers"].values]
    cmap = {n: col for n, col in zip(sizes, ("tab:green", "tab:orange", "tab:purple", "tab:brown"))}
    for j, c in enumerate(ctrls):
        ax = fig.add_subplot(1, len(ctrls), j + 1)
        v = ds.sel(controller=c)
        for n in v["n_swimmers"].values:
            for series in v["R"].sel(n_swimmers=n).values.reshape(-1, len(t)):
                ax.plot(t, series, color=cmap[int(n)], lw=0.7, alpha=0.8)
            ax.plot([], [], color=cmap[int(n)], label=f"N = {int(n)}")
        ax.set_ylim(0, 1.02)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("order parameter R")
        ax.set_title(f"{c}: phases and positions free", fontsize=10)
        ax.legend(fontsize=8)
    return fig
