"""Closed-loop synchronization: pairs (final vs initial phase difference, forces) and groups (R(t))."""

from __future__ import annotations

import numpy as np

from . import new_figure, phase_axis

__all__ = ["plot_sync_pairs", "plot_sync_groups", "plot_phase_interaction"]

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


def plot_sync_groups(ds, summary=None):
    """Top: order parameter R(t) of every run, one panel per controller, coloured by group size.
    Bottom (with ``summary``): the neighbour pairs' final (dphi, dx / lambda) against the compatible
    branches (dashed) and the stable zeros of H measured with positions free (blue) and held (red)."""
    ctrls = [str(c) for c in ds["controller"].values]
    rows = 1 if summary is None else 2
    fig = new_figure(5.2 * len(ctrls), 4.2 * rows)
    t = ds["time"].values
    sizes = [int(n) for n in ds["n_swimmers"].values]
    cmap = {n: col for n, col in zip(sizes, ("tab:green", "tab:orange", "tab:purple", "tab:brown"))}
    for j, c in enumerate(ctrls):
        ax = fig.add_subplot(rows, len(ctrls), j + 1)
        v = ds.sel(controller=c)
        if summary is not None:
            _plane(fig.add_subplot(rows, len(ctrls), len(ctrls) + j + 1), summary["per_controller"][c], c)
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


def _plane(ax, v, c):
    x = np.linspace(-np.pi, np.pi, 50)
    for k in (-1, 0, 1):
        ax.plot(x, x / (2 * np.pi) + k, "k--", lw=0.8)
    ax.plot(v["neighbour_dphi_rad"], v["neighbour_dx_lambda"], "o", color="tab:gray", mec="k", mew=0.5, ms=4,
            label="final neighbour pairs")
    for cond, held in (("H_free", False), ("H_held", True)):
        col, _, label = _HOLD[held]
        for z in v[cond]["stable_zeros"]:
            ax.axvspan(z["ci95"][0], z["ci95"][1], color=col, alpha=0.2)
            ax.axvline(z["zero_rad"], color=col, lw=1, label=f"stable zero of H, {label}")
    ax.set_ylim(-0.6, 0.6)
    phase_axis(ax.xaxis)
    ax.set_xlabel(r"final $\Delta\phi$ (rad)")
    ax.set_ylabel(r"final $\Delta x / \lambda$")
    ax.set_title(f"{c}: end states vs compatible branches (dashed)", fontsize=9)
    ax.legend(fontsize=7)


def plot_phase_interaction(ds, summary):
    """Per controller: H(dphi) per bin (mean, 95 % t interval; held and free), its stable zeros
    (intervals shaded) and the closed-loop runs' final dphi (ticks on the zero line)."""
    ctrls = [str(c) for c in ds["controller"].values]
    fig = new_figure(5.2 * len(ctrls), 4.4)
    for j, c in enumerate(ctrls):
        ax = fig.add_subplot(1, len(ctrls), j + 1)
        for cond, held in (("held", True), ("free", False)):
            col, mk, label = _HOLD[held]
            v = summary["per_controller"][c][cond]
            x = np.array([b["centre"] for b in v["bins"]])
            h = np.array([np.nan if b["H"]["value"] is None else b["H"]["value"] for b in v["bins"]])
            lo = np.array([np.nan if b["H"]["ci95"][0] is None else b["H"]["ci95"][0] for b in v["bins"]])
            hi = np.array([np.nan if b["H"]["ci95"][1] is None else b["H"]["ci95"][1] for b in v["bins"]])
            ax.errorbar(x, h, yerr=[h - lo, hi - h], fmt=mk + "-", color=col, ms=4, lw=1, capsize=2,
                        label=f"H, {label}")
            for z in v["stable_zeros"]:
                ax.axvspan(z["ci95"][0], z["ci95"][1], color=col, alpha=0.15)
            off = 0.02 if held else -0.02
            ax.plot(v["finals_rad"], np.full(len(v["finals_rad"]), off), "|", color=col, ms=14, mew=2,
                    label=f"final states, {label}")
        ax.axhline(0, color="k", lw=0.6)
        phase_axis(ax.xaxis)
        ax.set_xlabel(r"$\Delta\phi$ (rad)")
        ax.set_ylabel(r"$H = \langle d\Delta\phi/dt \rangle$ (rad/s)")
        ax.set_title(c, fontsize=10)
        ax.legend(fontsize=7)
    return fig
