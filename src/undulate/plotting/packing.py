"""Paper Fig. 7b: joint error over phase spread and density, with the packing curves."""

from __future__ import annotations

import numpy as np

from . import new_figure

__all__ = ["plot_packing"]


def _edges(c: np.ndarray) -> np.ndarray:
    """Cell edges around centres ``c`` (midpoints, ends extended by half a step)."""
    c = np.asarray(c, float)
    if c.size == 1:
        return np.array([c[0] - 0.5, c[0] + 0.5])
    mid = 0.5 * (c[1:] + c[:-1])
    return np.concatenate([[2 * c[0] - mid[0]], mid, [2 * c[-1] - mid[-1]]])


def plot_packing(ds):
    """Figure from the ``packing`` study dataset.

    Heatmap: the mean joint error (log colour scale) averaged over the
    heatmap's phase draws, over ``(phi_max, rho~)`` on the heatmap's grid; cells where every draw failed are grey,
    cells with some failed draws carry an ``x``.  Blue circles: the simulated
    threshold (mean, error bars the standard deviation over draws).  Red:
    Monte-Carlo density; green dashed: closed form; green dotted: closed form
    with the side walls' room.
    """
    from matplotlib.colors import LogNorm

    phi = ds["phi_max"].values
    if "heatmap_joint_error" in ds:  # the heatmap's own grid (the threshold grid may be searched by bisection)
        rho = ds["rho_heatmap"].values
        mean = ds["heatmap_joint_error"].mean("heatmap_draw", skipna=True).values  # (phi, rho)
        failed = ds["heatmap_failed"].values
    else:
        rho = ds["rho_tilde"].values
        mean = ds["mean_joint_error"].mean("draw", skipna=True).values
        failed = ds["run_failed"].values
    n_fail = failed.sum(axis=-1)
    n_draw = failed.shape[-1]

    fig = new_figure(7.0, 5.0)
    ax = fig.add_subplot(1, 1, 1)
    ax.set_facecolor("0.75")
    finite = mean[np.isfinite(mean)]
    vmin = max(float(finite.min()) if finite.size else 1e-4, 1e-4)
    vmax = max(float(finite.max()) if finite.size else 1.0, vmin * 10)
    mesh = ax.pcolormesh(_edges(phi), _edges(rho), np.ma.masked_invalid(mean.T), shading="flat",
                         cmap="magma", norm=LogNorm(vmin=vmin, vmax=vmax))
    cb = fig.colorbar(mesh, ax=ax)
    cb.set_label("mean joint error (rad)")
    pi_, ri_ = np.nonzero((n_fail > 0) & (n_fail < n_draw))
    if pi_.size:
        ax.plot(phi[pi_], rho[ri_], "x", color="w", ms=5, mew=1, label="some runs diverged")
    if np.any(n_fail == n_draw):
        ax.plot([], [], "s", color="0.75", mec="k", label="all runs diverged")

    thr = ds["threshold_rho_tilde"]
    m, s = thr.mean("draw", skipna=True).values, thr.std("draw", skipna=True).values
    ok = np.isfinite(m)
    ax.errorbar(phi[ok], m[ok], yerr=np.nan_to_num(s[ok]), fmt="o", color="tab:blue", mec="w",
                ms=7, capsize=3, label="simulated threshold")
    pf = ds["phi_fine"].values
    ax.plot(pf, ds["rho_monte_carlo"].values, "-", color="tab:red", lw=2, label="Monte Carlo")
    ax.plot(pf, ds["rho_closed_form"].values, "--", color="tab:green", lw=2, label="closed form")
    ax.plot(pf, ds["rho_closed_form_walls"].values, ":", color="tab:green", lw=1.5,
            label="closed form, side walls' room")
    ax.set_xlim(_edges(phi)[0], _edges(phi)[-1])
    ax.set_ylim(_edges(rho)[0], _edges(rho)[-1])
    ax.set_xticks(np.pi * np.array([0, 0.5, 1, 1.5, 2]), ["0", r"$\pi/2$", r"$\pi$", r"$3\pi/2$", r"$2\pi$"])
    ax.set_xlabel(r"phase spread $\phi_{max}$ (rad)")
    ax.set_ylabel(r"normalised density $\tilde\rho = 2AN/Y$")
    ax.set_title(f"{int(ds.attrs['n_swimmers'])} swimmers, short channel; threshold: "
                 f"{float(ds.attrs['threshold_rad']):g} rad above a lone swimmer", fontsize=10)
    ax.legend(fontsize=8, loc="upper right", framealpha=0.85)
    return fig
