"""Animations decode with the expected number of frames (real files, real decoders)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from undulate import Scene, SimOptions, simulate
from undulate.animation import animate, count_frames
from undulate.errors import ParameterError


@pytest.fixture(scope="module")
def run_ds():
    return simulate(Scene(phases_rad=(0.0, 1.5)), SimOptions(duration_s=2.0, sample_rate_hz=10))


@pytest.mark.parametrize("ext, stride", [(".gif", 1), (".mp4", 2)])
def test_animation_has_expected_frames(tmp_path, run_ds, ext, stride):
    out = tmp_path / f"a{ext}"
    n = animate(run_ds, out, stride=stride, dpi=60)
    expected = len(run_ds["time"][::stride])
    assert n == expected
    assert count_frames(out) == expected
    assert [p.name for p in tmp_path.iterdir()] == [out.name]  # no temporary left behind


def test_bad_animation_requests(tmp_path, run_ds):
    with pytest.raises(ParameterError, match="gif or .mp4"):
        animate(run_ds, tmp_path / "a.avi")
    with pytest.raises(ParameterError, match="simulate"):
        animate(run_ds.drop_vars("node_x"), tmp_path / "a.gif")
    assert list(tmp_path.iterdir()) == []


def test_frame_rates_a_format_cannot_keep_are_refused(tmp_path, run_ds):
    """A GIF's frame delay is 16 bits of centiseconds (Pillow raised OverflowError past 655.35 s, and
    stored 0 below 10 ms); ffmpeg's MP4 lost its timing below 1e-4 fps.  Refused, naming the option that
    set the rate (``--stride`` where the rate is real time); the bounds themselves are written exactly."""
    from PIL import Image

    from undulate.animation import FPS_RANGE

    for out, kw, name in [("a.gif", dict(fps=101.0), "--fps"), ("a.gif", dict(fps=1e-300), "--fps"),
                          ("a.gif", dict(stride=10**21), "--stride"), ("a.mp4", dict(fps=1e-5), "--fps"),
                          ("a.mp4", dict(fps=1e4), "--fps")]:
        with pytest.raises(ParameterError, match=f"invalid {name}.*frame rate in"):
            animate(run_ds, tmp_path / out, **kw)
    assert list(tmp_path.iterdir()) == []
    lo, hi = FPS_RANGE[".gif"]
    for fps, delay_ms in [(lo, 655350), (hi, 10)]:
        animate(run_ds, tmp_path / "b.gif", fps=fps, dpi=40)
        with Image.open(tmp_path / "b.gif") as im:
            assert im.info["duration"] == delay_ms
    for fps in FPS_RANGE[".mp4"]:
        assert animate(run_ds, tmp_path / "b.mp4", fps=fps, dpi=40) == count_frames(tmp_path / "b.mp4")


def test_a_gif_too_large_for_memory_is_refused_and_an_mp4_streams(tmp_path, run_ds, monkeypatch):
    """A GIF holds all its frames until it is written: one that cannot fit in the memory available is
    refused before drawing, naming ``--stride``; an MP4 of the same frames streams and is written."""
    import undulate.execution as execution

    monkeypatch.setattr(execution, "memory_available_bytes", lambda: 10**6)  # ~1 MB left: 21 frames of ~100 kB don't fit
    with pytest.raises(ParameterError, match=r"invalid --stride: must be large enough for the GIF's frames.*\.mp4"):
        animate(run_ds, tmp_path / "a.gif", dpi=40)
    assert list(tmp_path.iterdir()) == []
    assert animate(run_ds, tmp_path / "a.mp4", dpi=40) == count_frames(tmp_path / "a.mp4") == run_ds.sizes["time"]
    assert animate(run_ds, tmp_path / "b.gif", stride=20, dpi=40) == 2  # fewer frames fit


def test_an_animation_that_cannot_be_written_is_a_write_error(run_ds):
    """On a pseudo file system (``/proc``) Pillow's FileNotFoundError came out as a traceback after every
    frame was drawn, and ffmpeg printed its own three lines: the file is made first, and any failure to
    write it is a :class:`~undulate.errors.WriteError` naming it, before a frame is drawn."""
    from undulate.errors import WriteError

    for out in ("/proc/undulate-a.gif", "/proc/undulate-a.mp4"):
        with pytest.raises(WriteError, match=f"could not write {out}"):
            animate(run_ds, out, dpi=40)


def test_cli_animate_from_a_simulate_file(tmp_path):
    nc, gif = tmp_path / "run.nc", tmp_path / "run.gif"
    cli = [sys.executable, "-m", "undulate.cli"]
    r = subprocess.run([*cli, "simulate", "--phases", "0,90,45,180", "--channel-width", "0.22", "--duration", "1",
                        "--out", str(nc), "-q"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    r = subprocess.run([*cli, "animate", str(nc), "-o", str(gif), "--stride", "2"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert count_frames(gif) == 11
    r = subprocess.run([*cli, "animate", str(tmp_path / "missing.nc"), "-o", str(gif)], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    import xarray as xr

    other = tmp_path / "other.nc"
    xr.Dataset({"dx": ("time", [0.0, 1.0])}).to_netcdf(other, engine="h5netcdf")
    r = subprocess.run([*cli, "animate", str(other), "-o", str(tmp_path / "b.gif")], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.startswith("error: invalid RUN: must be an `undulate simulate` output")
    assert r.stderr.count("\n") == 1 and not (tmp_path / "b.gif").exists()


def test_blitted_frames_are_pixel_identical_to_full_draws():
    # two swimmers in contact half of the time: bodies turn red, walls flash, the clock runs
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from undulate.animation import _Blitter, _Frame, _Recording, _stage

    ds = simulate(Scene(phases_rad=(0.0, 1.5)), SimOptions(duration_s=3.0, sample_rate_hz=10))
    run = _Recording(ds, 1)
    fig, ax, walls = _stage(ds, run, 70, "a title")
    frame = _Frame(ax, run, walls)
    blit = _Blitter(fig, frame.redrawn())
    fig2, ax2, walls2 = _stage(ds, run, 70, "a title")
    frame2, canvas2 = _Frame(ax2, run, walls2), FigureCanvasAgg(fig2)
    touching = 0
    for i in range(len(run.times)):
        frame.draw(i)
        frame2.draw(i)
        canvas2.draw()
        full = np.asarray(canvas2.buffer_rgba())
        assert blit.size == canvas2.get_width_height()
        np.testing.assert_array_equal(blit.frame(), full, err_msg=f"frame {i}")
        touching += bool((run.fpair[i] > 0).any())
    assert 0 < touching < len(run.times)  # both looks were compared
