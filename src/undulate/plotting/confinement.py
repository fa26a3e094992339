"""Paper Fig. 9: final offset against the start, per confinement."""

from __future__ import annotations

from . import new_figure

__all__ = ["plot_confinement"]


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
