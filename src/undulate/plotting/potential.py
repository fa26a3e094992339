"""Paper Fig. 10: contact impulse vs detuning, and the cohesion stiffness."""

from __future__ import annotations

import numpy as np

from . import new_figure, phase_axis

__all__ = ["plot_potential"]

_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")


def plot_potential(ds):
    """Figure from the ``potential`` study dataset.

    (a) contact impulse over the first two periods against dphi (grey: each
    common phase; black: their mean) with the fit ``a |dphi| + b``; (b)
    period means of ``dx/lambda`` over time under each force (middle beta,
    ``d/2A`` nearest 0.7), with the release run there (dashed: the force removed at the dash-dotted line); (c) ``dF`` against ``dx/lambda`` for three
    confinements (middle beta) with the fitted lines, broken pairs hollow;
    (d) stiffness k against ``d/2A`` per beta (log scale) and (e) against
    the channel width ``W = 2d`` in metres (no collapse expected); (f) fitted ``dx0/lambda`` against
    ``d/2A`` with the compatibility model (dashed: sinusoids, dotted: bodies).
    """
    fig = new_figure(14.0, 8.0)
    gs = fig.add_gridspec(2, 3)
    ib = ds.sizes["beta"] // 2
    # a confinement with a visible response that still holds (the pair touches up to d/2A ~0.8)
    ir = int(np.argmin(np.abs(ds["d_over_2A"].values - 0.7)))
    _impulse_panel(fig.add_subplot(gs[0, 0]), ds)
    _response_panel(fig.add_subplot(gs[0, 1]), ds, ib, ir)
    _force_panel(fig.add_subplot(gs[0, 2]), ds, ib)
    _stiffness_panels(fig.add_subplot(gs[1, 0]), fig.add_subplot(gs[1, 1]), fig.add_subplot(gs[1, 2]), ds)
    return fig


def _impulse_panel(ax, ds) -> None:
    """(a) contact impulse over the first two periods against dphi, with the ``a |dphi| + b`` fit."""
    dphi = ds["dphi"].values
    if "impulse_all" in ds:
        for series in ds["impulse_all"].values.T:
            ax.plot(dphi, series, ".", color="0.6", ms=4)
        ax.plot([], [], ".", color="0.6", label=r"each common phase $\phi_a$")
    ax.plot(dphi, ds["impulse"].values, "o", color="k", label="mean")
    a, b, r2 = ds.attrs["impulse_fit_abs"]
    if np.isfinite(a):
        pp = np.linspace(dphi.min(), dphi.max(), 201)
        ax.plot(pp, a * np.abs(pp) + b, "--", color="tab:red", label=rf"$a|\Delta\phi|+b$, $R^2$ = {r2:.3f}")
    ax.legend(fontsize=8)
    phase_axis(ax.xaxis)
    ax.set_xlabel(r"$\Delta\phi$ (rad)")
    ax.set_ylabel("contact impulse, first 2 periods (N s)")
    ax.set_title(r"(a) $\Delta x_0 = 0$", fontsize=10)


def _response_panel(ax, ds, ib: int, ir: int) -> None:
    """(b) period means of dx/lambda over time under each force, at beta ``ib`` and d/2A ``ir``."""
    import matplotlib as mpl

    beta, R, forces = ds["beta"].values, ds["d_over_2A"].values, ds["force"].values
    t = ds["period_time"].values
    cmap = mpl.colormaps["plasma"]
    for m, f in enumerate(forces):
        ax.plot(t, ds["dx_period"].values[ib, ir, m], ".-", color=cmap(m / max(len(forces), 1)), lw=0.9,
                label=f"{f:g} N" if m in (0, len(forces) - 1) else None)
    ax.axvline(float(ds.attrs["settle_s"]), color="0.5", ls=":")
    _release_overlay(ax, ds, beta[ib], R[ir])
    ax.set_xlabel("time (s)")
    ax.set_ylabel(r"period mean of $\Delta x/\lambda$")
    shown = ds["dx_period"].values[ib, ir]
    top = float(np.nanmax(np.where(ds["broken"].values[ib, ir][:, None], np.nan, shown))) if np.isfinite(shown).any() else 0.5
    ax.set_ylim(-0.02, min(0.6, (top if np.isfinite(top) else 0.5) + 0.05))
    ax.set_title(rf"(b) $\pm\delta F$ from t = {float(ds.attrs['settle_s']):g} s; "
                 rf"$\beta$ = {beta[ib]:g}$^\circ$, $d/2A$ = {R[ir]:g}", fontsize=10)
    ax.legend(fontsize=8)


def _release_overlay(ax, ds, beta: float, r: float) -> None:
    """(b) the release run at this (beta, d/2A), if any: dx/lambda with the force on, then removed (black,
    dashed), and the removal time (dash-dotted)."""
    if "release_dx_period" not in ds or ds.sizes.get("release", 0) == 0:
        return
    at = np.flatnonzero(np.isclose(ds["release_beta"].values, beta) & np.isclose(ds["release_d_over_2A"].values, r))
    if not at.size:
        return
    i = int(at[0])
    ax.plot(ds["release_period_time"].values, ds["release_dx_period"].values[i], "--", color="k", lw=1.2,
            label=f"{float(ds['release_force'].values[i]):g} N, removed")
    ax.axvline(float(ds.attrs["release_force_offset_s"]), color="k", ls="-.", lw=0.8)


def _force_panel(ax, ds, ib: int) -> None:
    """(c) dF against dx/lambda for three confinements at beta ``ib``, with the fitted lines."""
    lam = float(ds.attrs["wavelength_m"])
    beta, R, forces = ds["beta"].values, ds["d_over_2A"].values, ds["force"].values
    nr = ds.sizes["d_over_2A"]
    picks = sorted({0, nr // 2, nr - 1})
    for c, j in enumerate(picks):
        col = _COLOURS[c % len(_COLOURS)]
        dx = ds["dx"].values[ib, j]
        br = ds["broken"].values[ib, j]
        ax.plot(dx[~br], forces[~br], "o", color=col, label=rf"$d/2A$ = {R[j]:g}")
        ax.plot(np.clip(dx[br], None, 0.6), forces[br], "o", mfc="none", color=col)
        k, x0 = ds["stiffness"].values[ib, j], ds["dx0"].values[ib, j]
        if np.isfinite(k):
            xx = np.linspace(max(x0, 0.0), np.nanmax(np.where(br, np.nan, dx)), 20)
            ax.plot(xx, k * (xx - x0) * lam, "-", color=col, lw=1)
    ax.set_xlim(-0.01, 0.6)
    ax.set_xlabel(r"$\delta x/\lambda$")
    ax.set_ylabel(r"$\delta F$ (N)")
    ax.set_title(rf"(c) $\beta$ = {beta[ib]:g}$^\circ$; hollow: broke apart", fontsize=10)
    ax.legend(fontsize=8)


def _stiffness_panels(ax_k, ax_d, ax_0, ds) -> None:
    """(d) stiffness against d/2A (crosses on the axis: no rung held, k = 0) and (e) against the channel width
    W = 2d per beta; (f) the fitted offset with the model."""
    beta, R = ds["beta"].values, ds["d_over_2A"].values
    for i in range(ds.sizes["beta"]):
        col = _COLOURS[i % len(_COLOURS)]
        k = ds["stiffness"].values[i]
        pos = k > 0
        ax_k.plot(R[pos], k[pos], "o-", color=col, label=rf"$\beta$ = {beta[i]:g}$^\circ$")
        ax_d.plot(ds["channel_width"].values[i][pos], k[pos], "o-", color=col)
        ax_0.plot(R, ds["dx0"].values[i], "o-", color=col, label=rf"$\beta$ = {beta[i]:g}$^\circ$")
        none = ds["broken"].values[i].all(axis=-1)  # no rung held: no cohesion, k = 0 (off a log axis)
        if none.any():
            ax_k.plot(R[none], np.full(int(none.sum()), 0.03), "x", color=col, ms=8,
                      transform=ax_k.get_xaxis_transform(), clip_on=False,
                      label=r"no force held: $k = 0$" if i == 0 else None)
        if "stiffness_ci95" in ds:  # 95 % intervals (k: t interval; dx0: bootstrap)
            ci = ds["stiffness_ci95"].values[i]
            lo, hi = np.clip(k - ci[:, 0], 0, None), np.clip(ci[:, 1] - k, 0, None)
            ax_k.errorbar(R[pos], k[pos], yerr=[lo[pos], hi[pos]], fmt="none", color=col, capsize=2)
            c0, d0 = ds["dx0_ci95"].values[i], ds["dx0"].values[i]
            ax_0.errorbar(R, d0, yerr=[np.clip(d0 - c0[:, 0], 0, None), np.clip(c0[:, 1] - d0, 0, None)],
                          fmt="none", color=col, capsize=2)
        ax_0.plot(R, ds["model_dx0_bodies"].values[i], ":", color=col)
    ax_0.plot(R, ds["model_dx0_thin"].values[0], "--", color="k", label=r"model, $\Delta y = W - 2A$")
    ax_0.plot([], [], ":", color="k", label=r"model, $\Delta y = W - 2A - 2w$")
    for ax in (ax_k, ax_d):
        ax.set_yscale("log")
        ax.set_ylabel(r"stiffness $k$ (N/m)")
    ax_k.set_xlabel(r"$d/2A$ ($d$ per swimmer)")
    ax_k.set_title(r"(d) $\delta F = k(\delta x - \delta x_0)$", fontsize=10)
    ax_k.legend(fontsize=8)
    ax_d.set_xlabel(r"channel width $W = 2d$ (m)")
    ax_d.set_title("(e) the same against W", fontsize=10)
    ax_0.set_xlabel(r"$d/2A$ ($d$ per swimmer)")
    ax_0.set_ylabel(r"$\delta x_0/\lambda$")
    ax_0.set_title(r"(f) offset $\delta x_0$", fontsize=10)
    ax_0.legend(fontsize=7)
