"""Swimming vs not: steady dx/lambda against dphi with the compatibility line."""

from __future__ import annotations

import json

import numpy as np

from . import new_figure, phase_axis

__all__ = ["plot_swimming"]

_STYLE = {"viscous": ("tab:purple", "o", "not swimming (viscous ground)"),
          "resistive": ("tab:cyan", "s", "swimming (resistive-force drag)"),
          "swimming": ("tab:cyan", "s", "swimming (ellipsoid fluid drag)")}


def plot_swimming(ds):
    """Figure from the ``swimming`` study dataset.

    Left: steady ``dx/lambda`` against ``dphi`` for both modes, with the
    compatibility branches ``dx/lambda = dphi/2pi + n`` dashed (slopes and
    RMS residuals in the legend).  Right: ``dx/lambda`` over time in both
    modes (thin lines), and the lone swimmers' positions.
    """
    fits = json.loads(ds.attrs.get("fits_json", "{}"))
    fig = new_figure(12.0, 4.6)
    ax = fig.add_subplot(1, 2, 1)
    dphi = ds["dphi"].values
    for n in (-2, -1, 0, 1, 2):
        ax.plot(dphi, dphi / (2 * np.pi) + n, "k--", lw=0.8)
    for m in ds["mode"].values:
        col, mk, label = _STYLE.get(str(m), ("k", "o", str(m)))
        if str(m) in fits:
            s, _, rms = fits[str(m)]
            label += f": slope {s:.2f}, RMS {rms:.3f}" + r"$\lambda$"
        ax.plot(dphi, ds["dx_final_over_lambda"].sel(mode=m).values, mk, color=col, ms=6, mec="k", mew=0.5,
                label=label)
    phase_axis(ax.xaxis)
    ax.set_xlim(dphi.min() - 0.2, dphi.max() + 0.2)
    vals = ds["dx_final_over_lambda"].values
    top = max(0.75, float(np.nanmax(np.abs(vals))) + 0.1) if np.isfinite(vals).any() else 0.75
    ax.set_ylim(-top, top)
    ax.set_xlabel(r"$\Delta\phi$ (rad)")
    ax.set_ylabel(r"steady $\Delta x/\lambda$")
    ax.set_title(r"$d$ = 0.13 m, $\xi$ = 1; dashed: compatibility $\Delta x/\lambda = \Delta\phi/2\pi + n$",
                 fontsize=9)
    ax.legend(fontsize=8, loc="lower right")  # the upper left holds points on the n = 1 branch

    ax = fig.add_subplot(1, 2, 2)
    t = ds["time"].values
    for m in ds["mode"].values:
        col = _STYLE.get(str(m), ("k",))[0]
        for series in ds["dx_over_lambda"].sel(mode=m).values:
            ax.plot(t, series, color=col, lw=0.7, alpha=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel(r"$\Delta x/\lambda$")
    speeds = ds["lone_speed"].values
    per_T = float(ds.attrs.get("period_s", 2.0)) / float(ds.attrs.get("body_length_m", 0.54))
    ax.set_title("lone swimmer: " + ", ".join(
        f"{m} {1e3 * v:.1f} mm/s ({v * per_T:.3f} L/period)" for m, v in zip(ds["mode"].values, speeds)), fontsize=9)
    return fig
