"""Animations of a recorded run, seen from above (matplotlib; no GL needed).

Links are drawn to scale as ``w``-wide bodies along the recorded centre-line
nodes; a swimmer in contact with a neighbour is drawn in red, a wall that is
being pushed flashes red; a clock runs in the corner.  ``.gif`` files are
written with Pillow, ``.mp4`` with the ffmpeg binary shipped by
``imageio-ffmpeg``.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

import numpy as np

from ._signals import deferred, stop_if_signalled
from ._io import _as_oserror, atomic_output
from .errors import ParameterError, WriteError

__all__ = ["animate", "count_frames", "FORMATS"]

FORMATS = (".gif", ".mp4")
FPS_RANGE = {".gif": (1 / 655.35, 100.0), ".mp4": (1e-4, 1000.0)}
"""Frame rates each format keeps, frames per second: a GIF's frame delay is 0.01-655.35 s (16 bits of
centiseconds); the H.264 MP4s ffmpeg writes lose their frames' timing below 1e-4 fps (a muxing error)
and above ~1000 fps (every frame at time 0), measured with imageio-ffmpeg's ffmpeg 9.0.2."""
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

    out = Path(out)
    _check_request(ds, out, stride)
    run = _Recording(ds, stride)
    given = fps is not None
    fps = float(fps) if given else 1.0 / (run.sample * stride)
    if not np.isfinite(fps) or fps <= 0:
        raise ParameterError("--fps", "> 0 frames per second", fps)
    lo, hi = FPS_RANGE[out.suffix.lower()]
    if not lo <= fps <= hi:
        raise ParameterError("--fps" if given else "--stride (real time: --fps = the sample rate / stride)",
                             f"a frame rate in [{lo:.3g}, {hi:g}] frames per second for a {out.suffix.lower()} "
                             f"file", fps if given else int(stride))
    fig, ax, wall_lines = _stage(ds, run, dpi, title)
    frame = _Frame(ax, run, wall_lines)
    blit = _Blitter(fig, frame.redrawn())
    if out.suffix.lower() == ".gif":
        _check_gif_fits(len(run.times), blit.size, stride)
    try:
        with atomic_output(out, keep_suffix=True) as tmp:  # the sink picks its format by extension
            with _sink(Path(tmp), fps, blit.size) as put:
                for i in range(len(run.times)):
                    frame.draw(i)
                    put(blit.frame())
                    stop_if_signalled()  # a SIGTERM matplotlib's C code dropped still ends the animation
    except OSError as e:  # the file could not be written (a pseudo or read-only file system): one line
        if isinstance(e, WriteError):
            raise
        raise WriteError(out, _as_oserror(e)) from e
    return len(run.times)


class _Blitter:
    """Frames drawn by blitting: the still parts (axes, ticks, labels, title) are drawn once, and
    each frame restores them and draws only the moving artists over them, in their z-order, as a
    full draw would (pixel-identical to it, tested).  Redrawing the axes every frame was two
    thirds of an animation's time."""

    def __init__(self, fig, moving):
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        self.fig, self.canvas = fig, FigureCanvasAgg(fig)
        self.moving = sorted(moving, key=lambda a: a.get_zorder())  # stable: ties keep the axes' order
        for a in self.moving:
            a.set_animated(True)
        self.canvas.draw()
        self.background = self.canvas.copy_from_bbox(fig.bbox)
        self.size = self.canvas.get_width_height()  # (width, height) px

    def frame(self) -> np.ndarray:
        """The current frame, RGBA (height, width, 4), a copy."""
        self.canvas.restore_region(self.background)
        for a in self.moving:
            self.fig.draw_artist(a)
        return np.asarray(self.canvas.buffer_rgba()).copy()


def _check_request(ds, out: Path, stride: int) -> None:
    """Refuse an output format, a run file or a stride that cannot be animated."""
    if out.suffix.lower() not in FORMATS:
        raise ParameterError("output file", "a path ending in .gif or .mp4", str(out))
    import xarray as xr

    if not isinstance(ds, xr.Dataset):
        raise ParameterError("run file", "a run (an xarray.Dataset from undulate.simulate)", type(ds).__name__)
    missing = [v for v in _REQUIRED if v not in ds]
    if missing:
        raise ParameterError("run file", f"an `undulate simulate` output (missing {', '.join(missing)})", None)
    if int(stride) != stride or stride < 1:
        raise ParameterError("--stride", "a positive integer", stride)


def _check_gif_fits(n_frames: int, size: tuple[int, int], stride: int) -> None:
    """Refuse a GIF whose frames cannot be held in memory: Pillow writes a GIF from all its frames at
    once (an RGB(A) image each, and its palette copy), where an MP4 streams them to ffmpeg."""
    from . import execution

    need = n_frames * size[0] * size[1] * 5  # 4 bytes a pixel (RGBA at most), 1 of its palette image
    have = execution.memory_available_bytes()
    if need > have:
        gib = 2.0**30
        raise ParameterError("--stride", f"large enough for the GIF's frames to fit in memory: {n_frames} frames of "
                             f"{size[0]}x{size[1]} px need {need / gib:.3g} GiB, {have / gib:.3g} GiB is available "
                             "(or write an .mp4, which streams its frames)", int(stride))


class _Recording:
    """The samples drawn (every ``stride``-th) and the run's sizes: link width, channel width, interval."""

    def __init__(self, ds, stride: int):
        self.times = ds["time"].values[::stride]
        self.nx = ds["node_x"].values[::stride]
        self.ny = ds["node_y"].values[::stride]
        self.fpair = ds["contact_force_pair"].values[::stride]
        self.fwall = ds["contact_force_wall"].values[::stride]
        self.walls = [str(w) for w in ds["wall"].values]
        self.w = float(ds.attrs.get("link_width", 0.015))
        self.d = float(ds.attrs.get("channel_width", 2 * np.abs(self.ny).max() + self.w))
        times = self.times
        self.sample = float(ds.attrs.get("sample_interval", times[1] - times[0] if len(times) > 1 else 0.05))


def _stage(ds, run: _Recording, dpi: int, title: str | None):
    """The figure, its axes (to scale, even pixel sizes) and the wall lines by wall name."""
    from matplotlib.figure import Figure

    d = run.d
    x_lo, x_hi = float(run.nx.min()), float(run.nx.max())
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
    end_walls = [nm for nm in run.walls if nm.startswith("wall_end")]
    if end_walls and "config" in ds.attrs:
        import json

        e = json.loads(ds.attrs["config"])["scene"]["channel"].get("end_walls_m")
        if e:
            ax.set_xlim(min(x_lo - pad, -e / 2 - pad / 2), max(x_hi + pad, e / 2 + pad / 2))
            for nm, x in (("wall_end_lo", -e / 2), ("wall_end_hi", e / 2)):
                (wall_lines[nm],) = ax.plot([x, x], [-d / 2, d / 2], color=_WALL, lw=3)
    return fig, ax, wall_lines


class _Frame:
    """The moving artists (bodies, heads, clock) and how sample ``i`` sets them and the walls' colours."""

    def __init__(self, ax, run: _Recording, wall_lines: dict):
        from matplotlib.collections import PolyCollection

        self.ax, self.run, self.wall_lines = ax, run, wall_lines
        self.bodies = PolyCollection([], closed=True, edgecolors="k", linewidths=0.4)
        ax.add_collection(self.bodies)
        self.heads = ax.scatter(run.nx[0, :, 0], run.ny[0, :, 0], s=10, c="k", zorder=3)
        self.clock = ax.text(0.995, 1.015, "", transform=ax.transAxes, fontsize=9, family="monospace", ha="right")

    def draw(self, i: int):
        run, n_sw = self.run, self.run.nx.shape[1]
        polys, colours = [], []
        touching = np.zeros(n_sw, bool)
        if run.fpair.shape[1]:
            on = run.fpair[i] > 0
            touching[:-1] |= on
            touching[1:] |= on
        for j in range(n_sw):
            pj = _link_polygons(run.nx[i, j], run.ny[i, j], run.w)
            polys.extend(pj)
            colours.extend([_CONTACT if touching[j] else _BODY] * len(pj))
        self.bodies.set_verts(polys)
        self.heads.set_offsets(np.stack([run.nx[i, :, 0], run.ny[i, :, 0]], axis=-1))
        self.bodies.set_facecolors(colours)
        for k, nm in enumerate(run.walls):
            if nm in self.wall_lines:
                self.wall_lines[nm].set_color(_CONTACT if run.fwall[i, k] > 0 else _WALL)
        self.clock.set_text(f"t = {run.times[i]:6.2f} s")

    def redrawn(self) -> list:
        """The artists drawn anew each frame: every one :meth:`draw` changes, and the axes' spines
        (z-order 2.5), which lie over the ends of the walls (2)."""
        return [self.bodies, self.heads, self.clock, *self.wall_lines.values(), *self.ax.spines.values()]


@contextlib.contextmanager
def _sink(path: Path, fps: float, size: tuple[int, int]):
    """``put(rgba)`` for each frame: Pillow for ``.gif`` (as matplotlib's PillowWriter writes it);
    ffmpeg (the ``imageio-ffmpeg`` binary) with H.264, yuv420p for ``.mp4``.  The file is made first, so
    a place that cannot be written fails before any frame is drawn (and before ffmpeg prints its own)."""
    path.touch()
    if path.suffix.lower() == ".gif":
        from PIL import Image

        frames = []
        # opaque frames go in as RGB, which Pillow turns into a better palette (matplotlib does the same)
        yield lambda rgba: frames.append(Image.fromarray(rgba if rgba[..., 3].min() < 255 else rgba[..., :3]))
        frames[0].save(path, format="GIF", save_all=True, append_images=frames[1:],
                       duration=int(1000 / fps), loop=0)
        return
    import imageio_ffmpeg

    gen = None
    try:
        # ffmpeg started with signals held: a SIGTERM or Ctrl-C between its start and the generator's
        # try block left it unmanaged, and it wrote the temporary anew after the command had removed it
        # and exited 143 (2 in 9 runs of the termination tests beside another load, 0 in 8 since)
        with deferred():
            gen = imageio_ffmpeg.write_frames(str(path), size, pix_fmt_in="rgba", pix_fmt_out="yuv420p", fps=fps,
                                              codec="libx264", quality=None, macro_block_size=1,
                                              output_params=["-f", "mp4"])  # x264's default quality
            gen.send(None)
        yield lambda rgba: gen.send(np.ascontiguousarray(rgba))
    finally:
        if gen is not None:
            gen.close()  # ffmpeg has ended when this returns


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
