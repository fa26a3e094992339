"""Evidence figures of the potential study's claims (:attr:`~._protocol.Claim.evidence`): the data each is decided on.

Each is a function of the claim's row (``claims.json``'s: ``paper``, ``verdict`` and the judge's ``value``)
and draws, as the generic figure (:mod:`undulate._evidence`) does, the paper's statement above the panels,
5.6 in wide at 100 dpi (560 px, shown at its own size beside the claim's text at 1366 px), labels of
10 pt: on the left the measured curves (the cohesion stiffness k with its fit interval per beta, or the
mean contact impulse per beta with its interval), on the right the number the criterion judges with its
interval and the accepted region shaded green.
"""

from __future__ import annotations

import math
import textwrap
from typing import Any

from .._evidence import _OK, FONT_PT, LINE_IN, WIDTH_IN, framed_figure

__all__ = ["stiffness_against_confinement", "stiffness_at_fixed_width", "impulse_by_amplitude"]

_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")


def _f(v: Any) -> float:
    """A number of a row's value (None: NaN, as JSON writes it)."""
    try:
        return math.nan if v is None else float(v)
    except (TypeError, ValueError):
        return math.nan


def _estimate(d: Any) -> tuple[float, float, float]:
    """``(value, low, high)`` of an :meth:`~undulate.stats.Estimate.to_dict` dict (NaN where missing)."""
    d = d if isinstance(d, dict) else {}
    lo, hi = (d.get("ci95") or [None, None])[:2]
    return _f(d.get("value")), _f(lo), _f(hi)


def _shown(v: float, lo: float, hi: float, spec: str = "+.2f") -> str:
    if not math.isfinite(v):
        return "n/a"
    return f"{v:{spec}} [{lo:{spec}}, {hi:{spec}}]" if math.isfinite(lo) and math.isfinite(hi) else \
        f"{v:{spec}} (no interval)"


def _layout(row: dict[str, Any], legend: int, footer: list[str]):
    """``(fig, main axes, criterion axes, legend bottom in figure units)``: the paper's statement on top,
    two panels side by side (the data, 2/3; the criterion's number, 1/3), ``legend`` lines of legend under
    them and ``footer`` below it."""
    header = textwrap.fill(f"Paper: {row.get('paper') or ''}", 72)
    foot = textwrap.fill("; ".join(footer), 80) if footer else ""
    legend_in = (0.1 + LINE_IN * legend) if legend else 0.0
    panel_in, title_in, ticks_in = 2.2, 0.3, 0.6
    fig, height, head_in, foot_in = framed_figure(header, foot, title_in + panel_in + ticks_in + legend_in)
    grid = fig.add_gridspec(1, 2, width_ratios=(2.0, 1.0), left=0.8 / WIDTH_IN, right=1 - 0.1 / WIDTH_IN,
                            top=1 - (head_in + title_in) / height,
                            bottom=(foot_in + legend_in + ticks_in) / height, wspace=0.55)
    main, crit = fig.add_subplot(grid[0]), fig.add_subplot(grid[1])
    for ax in (main, crit):
        ax.tick_params(labelsize=FONT_PT)
    return fig, main, crit, (foot_in + 0.02) / height


def _criterion_panel(ax, points: list[tuple[str, float, float, float]], band: tuple[float | None, float | None],
                     title: str) -> None:
    """The judged numbers (``(label, value, low, high)``) with their intervals, the accepted region shaded."""
    xs = list(range(len(points)))
    for x, (_, v, lo, hi) in zip(xs, points):
        if not math.isfinite(v):
            continue
        err = [[max(v - lo, 0.0)], [max(hi - v, 0.0)]] if math.isfinite(lo) and math.isfinite(hi) else None
        ax.errorbar([x], [v], yerr=err, fmt="o", color="#1f4e99", ms=6, capsize=4, lw=1.6, zorder=3)
    ax.set_xticks(xs, [p[0] for p in points], rotation=30 if max((len(p[0]) for p in points), default=0) > 3 else 0)
    ax.set_xlim(-0.6, len(points) - 0.4)
    vals = [u for _, v, lo, hi in points for u in (v, lo, hi) if math.isfinite(u)] + [u for u in band if u is not None]
    lo_, hi_ = (min(vals), max(vals)) if vals else (-1.0, 1.0)
    pad = 0.12 * (hi_ - lo_) if hi_ > lo_ else 0.1 * abs(hi_) + 0.05
    ax.set_ylim(lo_ - pad, hi_ + pad)
    a, b = ax.get_ylim()
    ax.axhspan(band[0] if band[0] is not None else a - 1e6, band[1] if band[1] is not None else b + 1e6,
               color=_OK, alpha=0.14, lw=0, zorder=0)
    for edge in band:
        if edge is not None:
            ax.axhline(edge, color=_OK, lw=1.2, ls="--", zorder=1)
    ax.set_ylim(a, b)
    ax.set_title(title, fontsize=FONT_PT)


def _k_panel(ax, curves: dict[str, Any], x_key: str, x_scale: float, labels: dict[str, str]) -> list:
    """k (N/m) against ``curves[beta][x_key]`` (times ``x_scale``) per beta, the fits' intervals as error
    bars (log y when k spans a decade or more; a lower bound at or below 0 then runs to the axis' foot)."""
    rows = []
    for b, c in curves.items():
        pts = [(_f(x) * x_scale, _f(k), _f(lo), _f(hi)) for x, k, lo, hi in
               zip(c[x_key], c["k_N_per_m"], c["k_low_N_per_m"], c["k_high_N_per_m"])]
        rows.append((b, [p for p in pts if math.isfinite(p[0]) and math.isfinite(p[1]) and p[1] > 0]))
    ks = [p[1] for _, pts in rows for p in pts]
    log = bool(ks) and max(ks) >= 10 * min(ks)
    floor = min(ks) / 3 if ks else 0.0
    xs = sorted({p[0] for _, pts in rows for p in pts})
    step = min((b - a for a, b in zip(xs, xs[1:])), default=0.0)
    handles = []
    for i, (b, pts) in enumerate(rows):
        shift = 0.1 * step * (i - (len(rows) - 1) / 2)  # side by side, so the bars do not hide each other
        colour = _COLOURS[i % len(_COLOURS)]
        x = [p[0] + shift for p in pts]
        y = [p[1] for p in pts]
        lo = [p[1] - (max(p[2], floor) if log else p[2]) if math.isfinite(p[2]) else 0.0 for p in pts]
        hi = [p[3] - p[1] if math.isfinite(p[3]) else 0.0 for p in pts]
        h = ax.errorbar(x, y, yerr=[lo, hi], fmt="o-", color=colour, ms=5, lw=1.3, capsize=3,
                        label=labels.get(b, f"beta {b} deg"))
        handles.append(h)
    if log:
        ax.set_yscale("log")
        ax.set_ylim(bottom=floor)
    ax.set_ylabel("k (N/m)", fontsize=FONT_PT)
    return handles


def _stiffness(row: dict[str, Any], x_key: str, x_scale: float, x_label: str, judged: str,
               judged_label: str, band: tuple[float | None, float | None], names: dict[str, str], notes: list[str]):
    value = row.get("value") or {}
    curves = value.get("k_N_per_m") or {}
    judged_values = value.get(judged) or {}
    legend = len(curves)
    fig, main, crit, legend_y = _layout(row, legend, notes + [f"verdict: {row.get('verdict', 'n/a')}"])
    handles = _k_panel(main, curves, x_key, x_scale, names)
    main.set_xlabel(x_label, fontsize=FONT_PT)
    main.set_title("fitted k per beta (bars: fit interval)", fontsize=FONT_PT)
    if handles:
        fig.legend(handles=handles, loc="lower left", bbox_to_anchor=(0.01, legend_y), fontsize=FONT_PT,
                   frameon=False, ncol=1, handlelength=1.5, borderaxespad=0.0)
    _criterion_panel(crit, [(k, *_estimate(e)) for k, e in judged_values.items()], band, judged_label)
    return fig


def stiffness_against_confinement(row: dict[str, Any]):
    """The claim "k falls as the channel widens": k against d/2A per beta, with each beta's Spearman rho and
    its interval in the legend; on the right the rho per beta, accepted below 0."""
    rho = (row.get("value") or {}).get("spearman_rho") or {}
    names = {b: f"β = {b}°: ρ = {_shown(*_estimate(e))}" for b, e in rho.items()}
    return _stiffness(row, "d_over_2A", 1.0, "d/2A (wall distance per swimmer / 2A)", "spearman_rho",
                      "Spearman ρ\nof k with d", (None, 0.0), names,
                      ["criterion: every β's ρ interval below 0 (green)",
                       "widths without a fit (no rung held: k = 0; under 3 held) not drawn"])


def stiffness_at_fixed_width(row: dict[str, Any]):
    """The claim "at a fixed channel width k grows with amplitude": k against the channel width W (mm) per
    beta; on the right each pair of betas' mean ln(k of the larger A / k of the smaller), accepted above 0."""
    ratios = (row.get("value") or {}).get("log_k_ratio") or {}
    curves = (row.get("value") or {}).get("k_N_per_m") or {}
    names = {b: f"β = {b}°" for b in curves}
    shown = ", ".join(f"{k}: {_shown(*_estimate(e))}" for k, e in ratios.items())
    return _stiffness(row, "channel_width_m", 1e3, "channel width W (mm)", "log_k_ratio",
                      "mean ln(k_hi / k_lo)\nat common W", (0.0, None), names,
                      [f"criterion: every pair's interval above 0 (green): {shown}"])


def impulse_by_amplitude(row: dict[str, Any]):
    """The claim "the contact impulse grows with the gait amplitude": the mean impulse over the detuned starts
    per beta with its interval; on the right the mean paired increase of each step up in beta, accepted
    above 0."""
    value = row.get("value") or {}
    means = value.get("mean_impulse_Ns") or {}
    steps = value.get("steps") or {}
    fig, main, crit, _ = _layout(row, 0, [
        "criterion: every step's interval above 0 (green)",
        "the paper's 'larger projection of interaction surface' is not measured",
        f"verdict: {row.get('verdict', 'n/a')}"])
    pts = sorted((_f(b), *_estimate(e)) for b, e in means.items())
    pts = [p for p in pts if math.isfinite(p[0]) and math.isfinite(p[1])]
    scale, unit = (1e3, "mN s") if pts and max(abs(p[1]) for p in pts) < 0.1 else (1.0, "N s")
    if pts:
        lo = [p[1] - p[2] if math.isfinite(p[2]) else 0.0 for p in pts]
        hi = [p[3] - p[1] if math.isfinite(p[3]) else 0.0 for p in pts]
        main.errorbar([p[0] for p in pts], [scale * p[1] for p in pts],
                      yerr=[[scale * v for v in lo], [scale * v for v in hi]], fmt="o-", color="#1f4e99", ms=6,
                      lw=1.4, capsize=4)
        main.set_xticks([p[0] for p in pts], [f"{p[0]:g}" for p in pts])
    main.set_xlabel("joint amplitude β (degrees)", fontsize=FONT_PT)
    main.set_ylabel(f"contact impulse, 2 periods ({unit})", fontsize=FONT_PT)
    main.set_title("mean over the detuned starts (bars: interval)", fontsize=FONT_PT)
    _criterion_panel(crit, [(k, *(scale * v for v in _estimate(v_["increase_Ns"] if isinstance(v_, dict) else None)))
                            for k, v_ in steps.items()], (0.0, None), f"increase a step\nup in β ({unit})")
    return fig
