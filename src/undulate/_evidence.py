"""Each claim's own evidence figure: the numbers that decide it, the criterion's region, the paper's words.

One generic figure serves every claim (a claim whose data needs its own picture sets
:attr:`undulate.studies.Claim.evidence`).  It reads the verdict's ``value`` as the judge left it:

- an :class:`~undulate.stats.Estimate` dict (``value``, ``ci95``) is a point with its interval;
  a number ``X`` beside ``X_low`` and ``X_high`` is one too;
- estimates are grouped by their own key (``slope``, ``rms``): one panel each, the keys above
  them (``swimming``, ``viscous``) or numeric keys (links ``3``, ``5``: a trend) along its x axis;
- equal-length lists of numbers in one dict: the first is x, the others are y (a curve);
- other numbers, counts and flags are written under the panels.

The criterion's accepted region of a number (:attr:`~undulate.studies.Claim.bands`) is shaded
green behind its panel.  An explained claim shows, side by side, the default model's numbers (left) and the
explaining runs (or a finding's, or a tested cause's: the :class:`~undulate.studies.Explanation`'s ``value``: the criterion met, not met
or undecided in each run; for a value of numbers only, the explanation's own verdict).  The paper's
statement (the claim's short paraphrase) is written above the panels.  Figures are 5.6 in wide at 100 dpi (560 px: shown at their own size beside
the claim's text at 1366 px), two panels a row, labels of at least 10 pt, laid out by hand (constrained
layout took twice as long, and a reproduction draws one figure per claim; an unchanged claim's is kept).
"""

from __future__ import annotations

import hashlib
import json
import math
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["evidence_figure", "write_evidence", "flatten"]

WIDTH_IN, DPI, FONT_PT = 5.6, 100, 10
MAX_PANELS = 5
MAX_TEXT = 5
_OK, _NO, _UN = "#2e8b57", "#c0392b", "#d99a00"


def _num(x: Any) -> float | None:
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return None
    return float(x) if math.isfinite(float(x)) else None


def _is_estimate(d: Any) -> bool:
    return isinstance(d, dict) and "value" in d and "ci95" in d


def _numeric_key(k: str) -> bool:
    try:
        float(k)
        return True
    except ValueError:
        return False


def flatten(value: Any, path: tuple[str, ...] = ()) -> tuple[list, list, list, list]:
    """(estimates, curves, scalars, flags) of a verdict's ``value``: ``(path, value, low, high)``,
    ``(path, x key, xs, y key, ys)``, ``(path, number)`` and ``(path, True/False/None)``."""
    est, curves, scalars, flags = [], [], [], []
    if _is_estimate(value):
        lo, hi = (value.get("ci95") or [None, None])[:2]
        est.append((path, _num(value.get("value")), _num(lo), _num(hi)))
        return est, curves, scalars, flags
    if isinstance(value, dict):
        keys = [str(k) for k in value]
        lists = [k for k in keys if isinstance(value[k], list) and value[k]
                 and all(_num(u) is not None or u is None for u in value[k])]
        if len(lists) >= 2 and len({len(value[k]) for k in lists}) == 1:
            for k in lists[1:]:
                curves.append((path, lists[0], value[lists[0]], k, value[k]))
        else:
            lists = []
        for k in keys:
            v = value[k]
            if k in lists:
                continue
            if (k.endswith("_low") or k.endswith("_high")) and k.rsplit("_", 1)[0] in value:
                continue
            if _num(v) is not None and f"{k}_low" in value and f"{k}_high" in value:
                est.append((path + (k,), _num(v), _num(value[f"{k}_low"]), _num(value[f"{k}_high"])))
                continue
            e, c, s, f = flatten(v, path + (k,))
            est += e
            curves += c
            scalars += s
            flags += f
        return est, curves, scalars, flags
    if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):  # one entry per run
        for i, v in enumerate(value):
            e, c, s, f = flatten(v, path + (str(i),))
            est += e
            curves += c
            scalars += s
            flags += f
        return est, curves, scalars, flags
    if isinstance(value, bool) or value is None:
        if path:
            flags.append((path, value))
        return est, curves, scalars, flags
    if _num(value) is not None:
        scalars.append((path, _num(value)))
    return est, curves, scalars, flags


def _name_and_category(path: tuple[str, ...]) -> tuple[str, str]:
    """A number's panel (its own key; for a numeric key, the key above it) and its place on the x axis."""
    if not path:
        return "value", ""
    if _numeric_key(path[-1]):
        return (path[-2] if len(path) > 1 else "value"), path[-1]
    return path[-1], "/".join(path[:-1])


def _band(bands: dict[str, Any], name: str, path: tuple[str, ...]) -> tuple[float | None, float | None] | None:
    for k in (".".join(path), name, "*"):
        if k in bands:
            lo, hi = bands[k]
            return (None if lo is None else float(lo), None if hi is None else float(hi))
    return None


def _shade(ax, band, axis: str = "y") -> None:
    if band is None:
        return
    lo, hi = band
    span = ax.axhspan if axis == "y" else ax.axvspan
    lim = ax.get_ylim() if axis == "y" else ax.get_xlim()
    a = lo if lo is not None else min(lim[0], hi if hi is not None else lim[0]) - 1e6
    b = hi if hi is not None else max(lim[1], lo if lo is not None else lim[1]) + 1e6
    span(a, b, color=_OK, alpha=0.13, lw=0, zorder=0)
    for edge in (lo, hi):
        if edge is not None:
            (ax.axhline if axis == "y" else ax.axvline)(edge, color=_OK, lw=1.2, ls="--", zorder=1)
    (ax.set_ylim if axis == "y" else ax.set_xlim)(*lim)


def _panels(value: Any, bands: dict[str, Any]) -> tuple[list[dict], list[str]]:
    """Panels to draw (estimate groups and curves) and the text lines of the other numbers."""
    est, curves, scalars, flags = flatten(value)
    groups: dict[str, dict] = {}
    for path, v, lo, hi in est:
        name, cat = _name_and_category(path)
        g = groups.setdefault(name, {"kind": "points", "name": name, "points": [], "band": _band(bands, name, path)})
        g["points"].append((cat, v, lo, hi))
    for path, v in scalars:  # a number with its own region is a point (no interval)
        name, cat = _name_and_category(path)
        if _band(bands, name, path) is not None and name not in groups:
            groups[name] = {"kind": "points", "name": name, "points": [(cat, v, None, None)],
                            "band": _band(bands, name, path)}
    for name in sorted(groups, key=len, reverse=True):  # "pairs_rms" or "rms_sinusoid" beside "rms": compared
        base = next((b for b in groups if b != name and (name.endswith("_" + b) or name.startswith(b + "_"))), None)
        if base is not None:
            tag = name[: -len(base) - 1] if name.endswith("_" + base) else name[len(base) + 1:]
            g = groups.pop(name)
            groups[base]["points"] += [((f"{c}/{tag}" if c else tag), v, lo, hi) for c, v, lo, hi in g["points"]]
    for g in groups.values():  # the x labels without what all of a panel's points share
        parts = [c.split("/") if c else [] for c, *_ in g["points"]]
        k = 0
        while len(parts) > 1 and all(len(q) > k + 1 for q in parts) and len({q[k] for q in parts}) == 1:
            k += 1
        g["points"] = [("/".join(q[k:]), v, lo, hi) for q, (_, v, lo, hi) in zip(parts, g["points"])]
    panels = list(groups.values())
    for path, xk, xs, yk, ys in curves:
        panels.append({"kind": "curve", "name": yk, "x": xk, "xs": xs, "ys": ys, "band": _band(bands, yk, path + (yk,))})
    counts = [(p, v) for p, v in scalars if float(v).is_integer() and v >= 0 and _band(bands, p[-1], p) is None]
    if not panels and len(counts) >= 2:  # counts only (runs that did what the claim says, of how many): bars
        panels.append({"kind": "counts", "name": "counts", "bars": [(".".join(p), v) for p, v in counts[:8]]})
        scalars = [(p, v) for p, v in scalars if (p, v) not in counts[:8]]
    shown = {p["name"] for p in panels}
    text = [f"{'.'.join(p)} = {v:.4g}" for p, v in scalars if _name_and_category(p)[0] not in shown]
    text += [f"{'.'.join(p)}: {'yes' if f else 'no' if f is False else 'undecided'}" for p, f in flags]
    if len(text) > MAX_TEXT:
        text = text[:MAX_TEXT] + [f"{len(text) - MAX_TEXT} more in the claim's value (claims.json)"]
    return panels[:MAX_PANELS], text


def _title(name: str) -> str:
    return textwrap.fill(name.replace("_", " "), 22)


def _draw_points(ax, p: dict) -> None:
    pts = p["points"]
    xs = list(range(len(pts)))
    for x, (cat, v, lo, hi) in zip(xs, pts):
        if v is None:
            continue
        err = None
        if lo is not None and hi is not None:
            err = [[max(v - lo, 0.0)], [max(hi - v, 0.0)]]
        ax.errorbar([x], [v], yerr=err, fmt="o", color="#1f4e99", ms=6, capsize=4, lw=1.6, zorder=3)
        if lo is None or hi is None:
            ax.plot([x], [v], "o", mfc="white", mec="#1f4e99", ms=6, zorder=4)
    named = any(c for c, *_ in pts)
    ax.set_xticks(xs, [(c if len(c) <= 12 else c[:11] + "…") or ("measured" if named else " ") for c, *_ in pts])
    ax.set_xlim(-0.6, len(pts) - 0.4)
    vals = [u for _, v, lo, hi in pts for u in (v, lo, hi) if u is not None]
    band = p["band"] or (None, None)
    vals += [u for u in band if u is not None]
    if vals:
        lo, hi = min(vals), max(vals)
        pad = 0.12 * (hi - lo) if hi > lo else 0.1 * abs(hi) + 0.05
        ax.set_ylim(lo - pad, hi + pad)
    _shade(ax, p["band"])
    ax.set_title(_title(p["name"]), fontsize=FONT_PT)


def _draw_counts(ax, p: dict) -> None:
    bars = p["bars"]
    ys = list(range(len(bars)))[::-1]
    ax.barh(ys, [v for _, v in bars], color="#1f4e99", alpha=0.8)
    ax.set_yticks(ys, [k if len(k) <= 16 else k[:15] + "…" for k, _ in bars])
    top = max(v for _, v in bars) or 1
    for y, (_, v) in zip(ys, bars):
        ax.text(v + 0.02 * top, y, f"{v:g}", va="center", fontsize=FONT_PT)
    ax.set_xlim(0, 1.15 * top)
    ax.set_title("counts", fontsize=FONT_PT)


def _draw_curve(ax, p: dict) -> None:
    pts = [(x, y) for x, y in zip(p["xs"], p["ys"]) if _num(x) is not None and _num(y) is not None]
    ax.plot([x for x, _ in pts], [y for _, y in pts], "o-", color="#1f4e99", ms=5, lw=1.4, zorder=3)
    ax.set_xlabel(p["x"], fontsize=FONT_PT)
    _shade(ax, p["band"])
    ax.set_title(_title(p["name"]), fontsize=FONT_PT)


def _draw_explanation(ax, explanation: dict[str, Any], kind: str) -> None:
    """The explaining runs: the criterion met (holds), not met (fails) or undecided in each."""
    value = explanation.get("value")
    _, _, _, flags = flatten(value if isinstance(value, dict) else {"shown": explanation.get("shown")})
    if not flags:  # numbers only (or none): the explanation's own verdict on them
        flags = [(("cause shown",), explanation.get("shown"))]
    flags = flags[:8]
    for i, (path, f) in enumerate(flags):
        y = len(flags) - 1 - i
        color, word = (_OK, "holds") if f is True else (_NO, "fails") if f is False else (_UN, "undecided")
        ax.barh([y], [1], color=color, alpha=0.85)
        label = ".".join(path)
        label = label if len(label) <= 18 else label[:17] + "…"  # with ": undecided", within the panel
        ax.text(0.03, y, f"{label}: {word}", va="center",
                ha="left", fontsize=FONT_PT, color="white" if f is not None else "black")
    ax.set_xlim(0, 1)
    ax.set_ylim(-0.6, max(len(flags), 1) - 0.4)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title({"explanation": "explaining runs\n(changed model)",
                  "finding": "a finding's runs\n(several changes)"}.get(kind, "a tested cause\n(not shown)"),
                 fontsize=FONT_PT)


LINE_IN = 1.25 * FONT_PT / 72
"""A line of text in an evidence figure, inches."""


def framed_figure(header: str, footer: str, body_in: float):
    """An evidence figure's frame, laid out by hand (not by constrained layout: three times faster, and a
    reproduction draws one per claim): :data:`WIDTH_IN` wide at :data:`DPI`, ``header`` (wrapped text: the
    paper's statement) at its top, ``footer`` (wrapped; "" for none) at its bottom, ``body_in`` inches
    between them for the panels, their titles, labels and legend.  Returns ``(fig, height_in, head_in,
    foot_in)``: the heights of the whole figure, the header's band and the footer's band, inches (from
    which the caller places its panels)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    head_in = 0.1 + LINE_IN * (header.count("\n") + 1)
    foot_in = (0.1 + LINE_IN * (footer.count("\n") + 1)) if footer else 0.05
    height = head_in + foot_in + body_in
    fig = Figure(figsize=(WIDTH_IN, height), dpi=DPI)
    FigureCanvasAgg(fig)
    fig.text(0.01, 1 - 0.05 / height, header, fontsize=FONT_PT, ha="left", va="top", color="#333")
    if footer:
        fig.text(0.01, 0.05 / height, footer, fontsize=FONT_PT, ha="left", va="bottom")
    return fig, height, head_in, foot_in


def evidence_figure(row: dict[str, Any], bands: dict[str, Any] | None = None,
                    evidence: Callable[[dict[str, Any]], Any] | None = None):
    """The evidence figure of one claim row (``claims.json``'s): ``evidence`` (the claim's own hook)
    when given, else the generic figure drawn from ``row["value"]`` with ``bands`` shaded."""
    if evidence is not None:
        return evidence(row)
    panels, text = _panels(row.get("value"), bands or {})
    kind, ex = next(((k, e) for k, e in (("explanation", row.get("explanation")),
                                         ("finding", next(iter(row.get("findings") or []), None)),
                                         ("tested", next(iter(row.get("explanations_not_shown") or []), None)))
                     if e), ("", None))
    n = len(panels) + (1 if ex else 0)
    cols = max(1, min(2, n))  # two panels a row: each about 2 in wide, its labels legible at 10 pt
    nrows = max(1, math.ceil(n / cols)) if n else 0
    if ex:  # side by side: the default model's numbers down the left, the explaining runs on the right
        nrows = max(1, len(panels))
    header = textwrap.fill(f"Paper: {row.get('paper') or ''}", 72)
    footer = textwrap.fill("; ".join(text), 80) if text else ("" if n else "no number to draw: see the measured text")
    title_in, ticks_in, panel_in = 2.2 * LINE_IN + 0.05, 2.6 * LINE_IN, 1.45  # a panel's title, x labels, box
    fig, height, head_in, foot_in = framed_figure(header, footer, nrows * (title_in + panel_in + ticks_in))
    if n:
        labels = [min(len(k), 16) for q in panels if q["kind"] == "counts" for k, _ in q["bars"]]
        left_in = max(0.72, 0.2 + 0.085 * max(labels, default=0))  # a count's name fits left of its bar
        fig.subplots_adjust(left=left_in / WIDTH_IN, right=1 - 0.08 / WIDTH_IN,
                            top=1 - (head_in + title_in) / height, bottom=(foot_in + ticks_in) / height,
                            wspace=0.35, hspace=(title_in + ticks_in) / panel_in)
        if ex:
            grid = fig.add_gridspec(nrows, 2)
            axes = [fig.add_subplot(grid[i, 0]) for i in range(len(panels))] + [fig.add_subplot(grid[:, 1])]
        else:
            axes = list(fig.subplots(nrows, cols, squeeze=False).ravel())
        for ax, p in zip(axes, panels):
            {"points": _draw_points, "curve": _draw_curve, "counts": _draw_counts}[p["kind"]](ax, p)
            ax.tick_params(labelsize=FONT_PT)
            if ex:
                ax.set_ylabel("default model", fontsize=FONT_PT)
        if ex:
            _draw_explanation(axes[-1], ex, kind)
        for ax in axes[n:]:
            ax.set_visible(False)
    return fig


def _module_hash(fn: Callable | None) -> str | None:
    """sha1 of the source file of the module defining ``fn`` (a claim's own evidence hook), so that its
    figure is drawn again when the hook's code changes; None without a hook or a file."""
    import inspect

    if fn is None:
        return None
    try:
        return hashlib.sha1(Path(inspect.getfile(fn)).read_bytes()).hexdigest()
    except (TypeError, OSError):
        return None


def write_evidence(row: dict[str, Any], out_dir: Path, stem: str, bands: dict[str, Any] | None = None,
                   evidence: Callable[[dict[str, Any]], Any] | None = None) -> str:
    """Write ``out_dir/evidence/STEM-HASH.png`` (HASH: of what the figure is drawn from, so an unchanged
    claim's figure is not drawn again) and return its path relative to ``out_dir``."""
    from ._io import atomic_output

    key = json.dumps({"row": {k: row.get(k) for k in ("claim", "paper", "value", "verdict", "explanation",
                                                      "findings", "explanations_not_shown")},
                      "bands": bands or {}, "hook": getattr(evidence, "__qualname__", None),
                      "code": hashlib.sha1(Path(__file__).read_bytes()).hexdigest(),
                      "hook_code": _module_hash(evidence)},
                     sort_keys=True, default=str)
    rel = f"evidence/{stem}-{hashlib.sha1(key.encode()).hexdigest()[:8]}.png"
    path = Path(out_dir) / rel
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        fig = evidence_figure(row, bands, evidence)
        with atomic_output(path) as tmp:
            fig.savefig(tmp, format="png", dpi=DPI)
    return rel
