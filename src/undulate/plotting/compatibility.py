"""Paper Fig. 4: the gait-compatibility region and its sections."""

from __future__ import annotations

import numpy as np

from . import new_figure, phase_axis

__all__ = ["plot_compatibility"]


def plot_compatibility(ds, sections=None):
    """Figure of the compatibility region from the ``compatibility`` study dataset.

    Left (Fig. 4b): the surface ``dy/2A = |sin(psi/2)|`` (variable
    ``min_dy_over_2A``) over (dphi, dx/lambda); compatible configurations lie
    on or above it.  Right (Fig. 4c): sections of ``compatible`` at the
    ``dy/2A`` values ``sections`` (default: the dataset's
    ``sections_dy_over_2A`` attribute), shaded where compatible, with the
    compatibility lines ``dx/lambda = dphi/2pi + n`` dashed.
    """
    if sections is None:
        sections = np.atleast_1d(ds.attrs["sections_dy_over_2A"])
    sections = [float(s) for s in sections]
    dphi = ds["dphi"].values
    dxl = ds["dx_over_lambda"].values

    fig = new_figure(11.0, 2.6 * max(len(sections), 3))
    gs = fig.add_gridspec(len(sections), 2, width_ratios=[1.35, 1])

    ax3 = fig.add_subplot(gs[:, 0], projection="3d")
    P, X = np.meshgrid(dphi, dxl, indexing="ij")
    Z = ds["min_dy_over_2A"].values
    ax3.plot_surface(P, X, Z, cmap="viridis", rcount=P.shape[0], ccount=P.shape[1], linewidth=0,
                     antialiased=True, alpha=0.85, rasterized=True)  # dense mesh: raster in PDF
    for s in sections:  # where each section plane cuts the boundary surface
        ax3.contour(P, X, Z, levels=[s], zdir="z", offset=s, colors="k", linewidths=1.0)
    ax3.set_xlabel(r"$\Delta\phi$ (rad)")
    ax3.set_ylabel(r"$\Delta x/\lambda$")
    ax3.set_zlabel(r"$\Delta y/2A$", labelpad=2)
    ax3.set_box_aspect(None, zoom=0.85)
    ax3.view_init(elev=32, azim=-60)
    phase_axis(ax3.xaxis)
    ax3.set_zlim(0, max(1.0, float(ds["dy_over_2A"].max())))
    ax3.set_title("compatible on or above the surface\n"
                  r"$\Delta y/2A = |\sin((\Delta\phi - 2\pi\Delta x/\lambda)/2)|$", fontsize=10)

    lines = np.arange(np.floor(dxl.min()) - 1, np.ceil(dxl.max()) + 2)
    for i, s in enumerate(sections):
        ax = fig.add_subplot(gs[i, 1])
        sec = ds["compatible"].sel(dy_over_2A=s, method="nearest")
        ax.contourf(dphi, dxl, sec.values.T.astype(float), levels=[0.5, 1.5], colors=["tab:blue"],
                    alpha=0.45)
        ax.contour(dphi, dxl, sec.values.T.astype(float), levels=[0.5], colors="tab:blue",
                   linewidths=1.2)
        for n in lines:
            ax.plot(dphi, dphi / (2 * np.pi) + n, "k--", lw=0.8)
        ax.set_xlim(dphi.min(), dphi.max())
        ax.set_ylim(dxl.min(), dxl.max())
        phase_axis(ax.xaxis)
        ax.set_ylabel(r"$\Delta x/\lambda$")
        frac = ds["compatible_fraction"].sel(dy_over_2A=s, method="nearest").item()
        ax.set_title(rf"$\Delta y/2A = {float(sec['dy_over_2A']):g}$: {100 * frac:.0f}% compatible",
                     fontsize=10)
        if i == len(sections) - 1:
            ax.set_xlabel(r"$\Delta\phi$ (rad)")
        else:
            ax.tick_params(labelbottom=False)
    return fig
