"""Animations of a recorded run, seen from above (matplotlib; no GL needed).

Links are drawn to scale as ``w``-wide bodies along the recorded centre-line
nodes; a swimmer in contact with a neighbour is drawn in red, a wall that is
being pushed flashes red; a clock runs in the corner.  ``.gif`` files are
written with Pillow, ``.mp4`` with the ffmpeg binary shipped by
``imageio-ffmpeg``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ._io import atomic_output
from .errors import ParameterError

__all__ = ["animate", "count_frames", "FORMATS"]

FORMATS = (".gif", ".mp4")
_REQUIRED = ("node_x", "node_y", "contact_force_pair", "contact_force_wall")
_BODY = "#d9732f"
_CONTACT = "#c0182a"
_WALL = "#7a7f87"


def _link_polygons(nx: np.ndarray, ny: np.ndarray, w: float) -> np.ndarray:
    """Rectangles of width ``w`` around each link: (n_links, 4, 2), m."""
    p0 = np.stack([nx[:-1], ny[:-1]], axis=-1)
    p1 = np.stack([nx[1:], ny[1:]], axis=-1)
    d = p1 - p0
    n = np.stack([-d[:, 1], d[:, 0]], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True) + 1e-15
    h = 0.5 * w * n
    return np.stack([p0 - h, p1 - h, p1 + h, p0 + h], axis=1)


def animate(ds, out: str | os.PathLike, *, fps: float | None = None, stride: int = 1,
            dpi: int = 100, title: str | None = None) -> int:
    """Draw the run ``ds`` (from :func:`undulate.simulate`) into ``out``.

    ``stride`` keeps every ``stride``-th sample; ``fps`` defaults to real
    time (the recording rate / stride).  Returns the number of frames.  The
    file is written under a temporary name and renamed, so it appears whole
    or not at all.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib import animation
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure

    out = Path(out)
    if out.suffix.lower() not in FORMATS:
        raise ParameterError("output file", "a path ending in .gif or .mp4", str(out))
    missing = [v for v in _REQUIRED if v not in ds]
    if missing:
        raise ParameterError("run file", f"an `undulate simulate` output (missing {', '.join(missing)})", None)
    if int(stride) != stride or stride < 1:
        raise ParameterError("--stride", "a positive integer", stride)
    times = ds["time"].values[::stride]
    nx_all = ds["node_x"].values[::stride]
    ny_all = ds["node_y"].values[::stride]
    fpair = ds["contact_force_pair"].values[::stride]
    fwall = ds["contact_force_wall"].values[::stride]
    walls = [str(w) for w in ds["wall"].values]
    w = float(ds.attrs.get("link_width", 0.015))
    d = float(ds.attrs.get("channel_width", 2 * np.abs(ny_all).max() + w))
    sample = float(ds.attrs.get("sample_interval", times[1] - times[0] if len(times) > 1 else 0.05))
    fps = float(fps) if fps is not None else 1.0 / (sample * stride)
    if not np.isfinite(fps) or fps <= 0:
        raise ParameterError("--fps", "> 0 frames per second", fps)
    n_sw = nx_all.shape[1]

    x_lo, x_hi = float(nx_all.min()), float(nx_all.max())
    pad = 0.05
    # even pixel sizes: H.264 (yuv420p) needs them
    w_px = 2 * round(8 * dpi / 2)
    h_px = 2 * round(max(2.2, 8 * (d + 2 * pad) / (x_hi - x_lo + 2 * pad)) * dpi / 2)
    fig = Figure(figsize=(w_px / dpi, h_px / dpi), dpi=dpi)
    ax = fig.add_axes([0.08, 0.2, 0.9, 0.66])
    ax.set_aspect("equal")
    ax.set_xlim(x_lo - pad, x_hi + pad)
    ax.set_ylim(-d / 2 - pad / 2, d / 2 + pad / 2)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if title:
        fig.suptitle(title, fontsize=9, y=0.99)
    wall_lines = {}
    for name, y in (("wall_lo", -d / 2), ("wall_hi", d / 2)):
        (wall_lines[name],) = ax.plot([x_lo - pad, x_hi + pad], [y, y], color=_WALL, lw=3)
    end_walls = [nm for nm in walls if nm.startswith("wall_end")]
    if end_walls and "config" in ds.attrs:
        import json

        e = json.loads(ds.attrs["config"])["scene"]["channel"].get("end_walls_m")
        if e:
            ax.set_xlim(min(x_lo - pad, -e / 2 - pad / 2), max(x_hi + pad, e / 2 + pad / 2))
            for nm, x in (("wall_end_lo", -e / 2), ("wall_end_hi", e / 2)):
                (wall_lines[nm],) = ax.plot([x, x], [-d / 2, d / 2], color=_WALL, lw=3)
    bodies = PolyCollection([], closed=True, edgecolors="k", linewidths=0.4)
    ax.add_collection(bodies)
    heads = ax.scatter(nx_all[0, :, 0], ny_all[0, :, 0], s=10, c="k", zorder=3)
    clock = ax.text(0.995, 1.015, "", transform=ax.transAxes, fontsize=9, family="monospace", ha="right")

    def draw(i: int):
        polys, colours = [], []
        touching = np.zeros(n_sw, bool)
        if fpair.shape[1]:
            on = fpair[i] > 0
            touching[:-1] |= on
            touching[1:] |= on
        for j in range(n_sw):
            pj = _link_polygons(nx_all[i, j], ny_all[i, j], w)
            polys.extend(pj)
            colours.extend([_CONTACT if touching[j] else _BODY] * len(pj))
        bodies.set_verts(polys)
        heads.set_offsets(np.stack([nx_all[i, :, 0], ny_all[i, :, 0]], axis=-1))
        bodies.set_facecolors(colours)
        for k, nm in enumerate(walls):
            if nm in wall_lines:
                wall_lines[nm].set_color(_CONTACT if fwall[i, k] > 0 else _WALL)
        clock.set_text(f"t = {times[i]:6.2f} s")
        return [bodies, heads, clock, *wall_lines.values()]

    if out.suffix.lower() == ".gif":
        writer = animation.PillowWriter(fps=fps)
    else:
        import imageio_ffmpeg
        import matplotlib as mpl

        mpl.rcParams["animation.ffmpeg_path"] = imageio_ffmpeg.get_ffmpeg_exe()
        writer = animation.FFMpegWriter(fps=fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"])
    with atomic_output(out, keep_suffix=True) as tmp:  # the writer picks its format by extension
        with writer.saving(fig, str(tmp), dpi):
            for i in range(len(times)):
                draw(i)
                writer.grab_frame()
    return len(times)


def count_frames(path: str | os.PathLike) -> int:
    """Number of frames in a written animation (decoded, not trusted from metadata)."""
    path = Path(path)
    if path.suffix.lower() == ".gif":
        from PIL import Image, ImageSequence

        with Image.open(path) as im:
            return sum(1 for _ in ImageSequence.Iterator(im))
    import imageio_ffmpeg

    n, _ = imageio_ffmpeg.count_frames_and_secs(str(path))
    return int(n)
