"""Paper Fig. 3: pairs of swimmers; and the offset-vs-phase panel the other studies share."""

from __future__ import annotations

import math

import numpy as np

from . import new_figure, phase_axis

__all__ = ["plot_pairs", "compatibility_lines", "offset_panel", "finish_offset_panel"]

XI_COLOURS = {0.0: "tab:grey", 0.75: "tab:green", 1.0: "tab:purple", 1.5: "tab:orange"}


def _xi_label(xi: float) -> str:
    return {0.0: "0", 0.75: "3/4", 1.0: "1", 1.5: "3/2"}.get(float(xi), f"{xi:g}")


def compatibility_lines(ax, scale: float = 1.0, **kw) -> None:
    """Draw every branch ``dx = scale (dphi / 2 pi + n)`` crossing the axes' current y range.

    ``scale``: lambda in the plot's y unit (1 for dx/lambda, lambda in m for
    dx in m).  Call after the limits are set.
    """
    lo, hi = ax.get_ylim()
    dphi = np.linspace(-np.pi, np.pi, 3)
    style = {"color": "k", "ls": "--", "lw": 0.9, "zorder": 1, **kw}
    for n in range(int(math.floor(lo / scale)) - 1, int(math.ceil(hi / scale)) + 2):
        ax.plot(dphi, scale * (dphi / (2 * np.pi) + n), **style)
    ax.set_ylim(lo, hi)


def offset_panel(ax, dphi, y, steady=None, *, colour="tab:purple", marker="o", label=None,
                 size: float = 28) -> None:
    """Scatter steady offsets ``y`` against ``dphi`` (rad) on ``ax``.

    Filled markers: steady by the study's rule; open: not steady; NaN
    (failed) runs are skipped.  Call :func:`finish_offset_panel` once all
    series are drawn.
    """
    dphi = np.asarray(dphi, float)
    y = np.asarray(y, float)
    steady = np.ones_like(y, bool) if steady is None else np.asarray(steady, bool)
    ok = np.isfinite(y)
    ax.scatter(dphi[ok & steady], y[ok & steady], s=size, c=colour, marker=marker, label=label, zorder=3)
    if np.any(ok & ~steady):
        ax.scatter(dphi[ok & ~steady], y[ok & ~steady], s=size, facecolors="none", edgecolors=colour,
                   marker=marker, zorder=3)


def finish_offset_panel(ax, scale: float | None = 1.0, span: float = 0.6) -> None:
    """Phase axis, y range and compatibility branches of an offset panel.

    ``scale``: lambda in the y unit (1 for dx/lambda; None: no branches, as
    for the standing wave).  The y range covers every plotted point and at
    least ``+-span * scale``.
    """
    ax.set_xlim(-np.pi * 1.08, np.pi * 1.08)
    phase_axis(ax.xaxis)
    ax.set_xlabel(r"$\Delta\phi = \phi_{upper} - \phi_{lower}$ (rad)")
    ax.grid(alpha=0.25)
    ys = np.concatenate([np.asarray(c.get_offsets(), float)[:, 1] for c in ax.collections] or [np.zeros(0)])
    m = span * (scale if scale is not None else 0.05)
    ys = np.concatenate([ys[np.isfinite(ys)], [-m, m]])
    lo, hi = ys.min(), ys.max()
    pad = 0.06 * (hi - lo)
    ax.set_ylim(lo - pad, hi + pad)
    if scale is not None:
        compatibility_lines(ax, scale)
    else:
        ax.axhline(0.0, color="k", lw=0.6, zorder=1)


def fit_line(ax, dphi, dx_over_lambda, colour="k") -> None:
    """The study's compatibility fit (each point moved onto the branch nearest the n = 0 line,
    then least squares; :mod:`undulate.stats`) drawn with its 95 % band of lines: every slope and
    intercept within their intervals.  The label gives the slope and its interval."""
    from .. import stats, theory

    x = np.asarray(dphi, float)
    y = np.asarray(dx_over_lambda, float)
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 3:
        return
    y_line = x[ok] / (2 * np.pi) + theory.compatibility_residual(y[ok], x[ok], 1.0)
    fit = stats.line_fit(x[ok] / (2 * np.pi), y_line)
    if not fit.slope.has_interval:
        return
    xx = np.linspace(-np.pi, np.pi, 50) / (2 * np.pi)
    corners = [a * xx + b for a in (fit.slope.low, fit.slope.high) for b in (fit.intercept.low, fit.intercept.high)]
    ax.fill_between(xx * 2 * np.pi, np.min(corners, axis=0), np.max(corners, axis=0), color=colour, alpha=0.15,
                    lw=0, zorder=0)
    ax.plot(xx * 2 * np.pi, fit.slope.value * xx + fit.intercept.value, "-", color=colour, lw=1, zorder=2,
            label=f"fit: slope {fit.slope:.2f} (95 %)")


def plot_pairs(ds):
    """Figure of the ``pairs`` study dataset, laid out like paper Fig. 3b,c.

    Top row: (b) dx/lambda over time at xi = 1, one curve per dphi; (c)
    steady dx/lambda against dphi at xi = 1, 3/4, 3/2 with the compatibility
    branches ``dx/lambda = dphi/2pi + n`` (dashed).  Bottom row: dx over time
    for the standing wave xi = 0, and steady dx in metres against dphi for
    xi = 0, 3/4, 3/2 (paper Fig. 3c right column; branches ``lambda (dphi/2pi
    + n)``; none for xi = 0, lambda = inf).
    """
    import matplotlib as mpl

    fig = new_figure(17.0, 7.5)
    axes = fig.subplots(2, 4)
    xis = [float(x) for x in ds["xi"].values]
    dphi = ds["dphi"].values
    cmap = mpl.colormaps["coolwarm"]
    norm = mpl.colors.Normalize(-np.pi, np.pi)
    t = ds["time"].values

    def curves(ax, xi, var, ylabel):
        if xi not in xis:
            ax.set_visible(False)
            return
        d = ds.sel(xi=xi)
        for j, p in enumerate(dphi):
            ax.plot(t, d[var].values[j], color=cmap(norm(p)), lw=1.0)
        ax.set_xlabel("time (s)")
        ax.set_ylabel(ylabel)
        ax.set_xlim(t[0], t[-1])
        ax.grid(alpha=0.25)
        sm = mpl.cm.ScalarMappable(norm=norm, cmap=cmap)
        cb = fig.colorbar(sm, ax=ax, pad=0.01, fraction=0.05)
        cb.ax.set_title(r"$\Delta\phi$", fontsize=9)
        cb.set_ticks(np.pi * np.array([-1, -0.5, 0, 0.5, 1]), labels=[r"$-\pi$", r"$-\pi/2$", "0",
                                                                       r"$\pi/2$", r"$\pi$"])

    curves(axes[0, 0], 1.0, "dx_over_lambda", r"$\Delta x/\lambda$")
    axes[0, 0].set_title(r"(b) $\Delta x(t)$, $\xi = 1$", loc="left")
    curves(axes[1, 0], 0.0, "dx", r"$\Delta x$ (m)")
    axes[1, 0].set_title(r"$\Delta x(t)$, standing wave $\xi = 0$", loc="left")

    for col, xi in zip((1, 2, 3), (1.0, 0.75, 1.5)):
        ax = axes[0, col]
        if xi not in xis:
            ax.set_visible(False)
            continue
        d = ds.sel(xi=xi)
        offset_panel(ax, dphi, d["dx_steady_over_lambda"].values, d["steady"].values,
                     colour=XI_COLOURS.get(xi, "k"))
        fit_line(ax, dphi, d["dx_steady_over_lambda"].values, colour=XI_COLOURS.get(xi, "k"))
        finish_offset_panel(ax, 1.0)
        ax.legend(fontsize=7, loc="upper left")
        ax.set_ylabel(r"steady $\Delta x/\lambda$")
        ax.set_title(rf"(c) $\xi = L/\lambda = {_xi_label(xi)}$", loc="left")
    for col, xi in zip((1, 2, 3), (0.0, 0.75, 1.5)):
        ax = axes[1, col]
        if xi not in xis:
            ax.set_visible(False)
            continue
        d = ds.sel(xi=xi)
        lam = float(d["wavelength"])
        offset_panel(ax, dphi, d["dx_steady"].values, d["steady"].values, colour=XI_COLOURS.get(xi, "k"))
        finish_offset_panel(ax, lam if math.isfinite(lam) else None)
        ax.set_ylabel(r"steady $\Delta x$ (m)")
        lam_txt = r"\infty" if not math.isfinite(lam) else f"{lam:.2f}" + r"\,\mathrm{m}"
        ax.set_title(rf"$\xi = {_xi_label(xi)}$ ($\lambda = {lam_txt}$)", loc="left")

    fig.suptitle(
        f"Pairs in a d = {ds.attrs.get('channel_width_m', 0.13):g} m channel, {ds.attrs.get('duration_s', 30):g} s: "
        r"$\Delta x = x_{upper} - x_{lower}$; dashed: compatibility $\Delta x = \lambda(\Delta\phi/2\pi + n)$; "
        "open markers: not steady", fontsize=11)
    return fig
