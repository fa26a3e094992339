"""A printable sheet of the tracking markers, at true size (matplotlib PDF).

Robot tags ``0 .. n_robots - 1`` and the four fixed table tags 46-49, each
with its white quiet zone and a cut line, labelled with its id, the tag size
and which way the robot's head goes; the default table layout is printed
below.  Print at 100 % ("actual size", no fit-to-page) and check the
printed scale bar.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from .calibration import DEFAULT_MARKERS_M, DICTIONARY, FIXED_IDS, MAX_ROBOTS, TrackCalibration

__all__ = ["marker_sheet", "sheet_figure", "A4_M"]

A4_M = (0.210, 0.297)
"""Page size, m (A4 portrait; a US-letter printer prints it unscaled with small margins)."""
_MARGIN_M = 0.012


def _tag_bitmap(tag_id: int) -> np.ndarray:
    """The tag as cells: (6, 6) with black border, 0 = black, 255 = white."""
    import cv2

    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, DICTIONARY))
    return cv2.aruco.generateImageMarker(d, int(tag_id), 6)


def sheet_figure(n_robots: int, calibration: TrackCalibration | None = None):
    """The marker sheet as one or more matplotlib Figures of A4 size (true scale).

    Returns ``(figures, positions)``: ``positions[id]`` is the tag's centre on
    its page, m from the page's lower-left corner (for checking the print).
    """
    from ..plotting import new_figure

    cal = calibration or TrackCalibration()
    n = int(n_robots)
    if n != n_robots or not 1 <= n <= MAX_ROBOTS:
        raise ParameterError("--robots", f"an integer in [1, {MAX_ROBOTS}]", n_robots)
    s = cal.size_m
    plate = s * 8 / 6  # tag + one white cell all round (the quiet zone the detector needs)
    pitch_x, pitch_y = plate + 0.016, plate + 0.014
    pw, ph = A4_M
    cols = max(1, int((pw - 2 * _MARGIN_M + 0.016) // pitch_x))
    ids = list(range(n)) + list(FIXED_IDS)
    figures, positions = [], {}
    top_reserved = 0.030
    bottom_reserved = 0.070
    rows_per_page = max(1, int((ph - top_reserved - bottom_reserved - _MARGIN_M) // pitch_y))
    per_page = cols * rows_per_page
    for page in range(0, len(ids), per_page):
        fig = new_figure(pw / 0.0254, ph / 0.0254)
        fig.set_layout_engine(None)
        ax = fig.add_axes((0, 0, 1, 1))
        ax.set_xlim(0, pw)
        ax.set_ylim(0, ph)
        ax.set_axis_off()
        ax.text(_MARGIN_M, ph - _MARGIN_M - 0.004,
                f"undulate tracking markers  -  ArUco {DICTIONARY}  -  tag side {1000 * s:g} mm "
                f"(black square)  -  print at 100 %", fontsize=8.5, va="top")
        ax.text(_MARGIN_M, ph - _MARGIN_M - 0.011,
                "robot tags: id = robot index, on the middle link, read upright with the robot's head on the LEFT; "
                "table tags 46-49: upright, top toward +y", fontsize=6.2, va="top")
        for k, tag_id in enumerate(ids[page:page + per_page]):
            r, c = divmod(k, cols)
            cx = _MARGIN_M + plate / 2 + c * pitch_x
            cy = ph - top_reserved - _MARGIN_M - plate / 2 - r * pitch_y
            positions[tag_id] = (cx, cy)
            ax.add_patch(_rect(cx, cy, plate, fc="white", ec="0.6", lw=0.4, ls=(0, (2, 2))))  # cut line
            cells = _tag_bitmap(tag_id)
            ax.imshow(cells, cmap="gray", vmin=0, vmax=255, interpolation="nearest",
                      extent=(cx - s / 2, cx + s / 2, cy - s / 2, cy + s / 2), zorder=2)
            label = f"robot {tag_id}" if tag_id < MAX_ROBOTS else f"table {tag_id}"
            ax.text(cx, cy - plate / 2 - 0.0015, label, ha="center", va="top", fontsize=6)
            if tag_id < MAX_ROBOTS:
                ax.text(cx - plate / 2 - 0.0008, cy, "head", rotation=90, ha="right", va="center", fontsize=4.5,
                        color="0.35")
        _layout_note(ax, cal, s)
        figures.append(fig)
    return figures, positions


def _rect(cx, cy, side, **kw):
    from matplotlib.patches import Rectangle

    return Rectangle((cx - side / 2, cy - side / 2), side, side, **kw)


def _layout_note(ax, cal: TrackCalibration, s: float) -> None:
    """The table layout of the fixed tags and a 100 mm scale bar, at the page bottom."""
    y0 = _MARGIN_M + 0.008
    ax.plot([_MARGIN_M, _MARGIN_M + 0.100], [y0, y0], color="k", lw=1.2)
    for x in (_MARGIN_M, _MARGIN_M + 0.100):
        ax.plot([x, x], [y0 - 0.002, y0 + 0.002], color="k", lw=1.0)
    ax.text(_MARGIN_M + 0.050, y0 + 0.003, "100 mm (check the print)", ha="center", va="bottom", fontsize=6)
    default = cal.markers_m == {k: tuple(v) for k, v in DEFAULT_MARKERS_M.items()}
    lines = [("default table layout" if default else "table layout") + " (tag centres, m; x along the channel, "
             "heads toward -x):"]
    lines.append("   ".join(f"{i} = [{x:g}, {y:g}]" for i, (x, y) in sorted(cal.markers_m.items())))
    lines.append(f"calibration file (TOML): [markers] with these lines and size_m = {s:g}")
    for k, line in enumerate(lines):
        ax.text(_MARGIN_M, _MARGIN_M + 0.050 - 0.0065 * k, line, fontsize=6.5, va="top",
                family="monospace" if k == 1 else None)


def marker_sheet(out: str | os.PathLike, n_robots: int, calibration: TrackCalibration | None = None) -> int:
    """Write the marker sheet to ``out`` (``.pdf``: one page per A4 sheet).  Returns the page count."""
    from matplotlib.backends.backend_pdf import PdfPages

    from .._io import atomic_output

    out = Path(out)
    if out.suffix.lower() != ".pdf":
        raise ParameterError("--out", "a path ending in .pdf", str(out))
    figures, _ = sheet_figure(n_robots, calibration)
    with atomic_output(out) as tmp:
        with PdfPages(tmp, metadata={"Title": "undulate tracking markers", "Creator": "undulate"}) as pdf:
            for fig in figures:
                pdf.savefig(fig)
    return len(figures)
