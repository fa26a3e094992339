"""Tracking overhead video against ground truth, and experiment versus simulation.

Real components throughout: MuJoCo runs are the ground truth, the renderer
films them (tags at the middle links' true poses, a textured table, the four
calibration tags) through a tilted, distorting lens with blur, uneven
lighting, sensor noise and H.264 compression, and the real OpenCV ArUco
detector tracks the video.  The default suite uses one 720p pair video
(every degradation at once, dropped frames and a passing hand); the 1080p
validation of every degradation, for pairs and four robots, is ``slow``.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

cv2 = pytest.importorskip("cv2")

from undulate import Channel, Scene, SimOptions, simulate  # noqa: E402
from undulate.cli import main  # noqa: E402
from undulate.compare import experiment_offsets, steady_offset  # noqa: E402
from undulate.params import SwimmerGeometry  # noqa: E402
from undulate.observables import middle_link_pose  # noqa: E402
from undulate.track import TrackCalibration  # noqa: E402
from undulate.track.render import DEGRADATIONS, CameraSetup, Occluder, render_video  # noqa: E402

ROBOT_WIDTH_M = 0.04  # an AX-12A robot's link: a 30 mm tag on a 40 mm white plate fits on it


def _scene(n: int) -> Scene:
    phases = {2: (0.0, math.pi / 2), 4: (0.0, math.pi / 2, math.pi, 1.5 * math.pi)}[n]
    return Scene(phases_rad=phases, geometry=SwimmerGeometry(width_m=ROBOT_WIDTH_M),
                 channel=Channel(width_m=0.13 if n == 2 else 0.2))


def _calibration_file(path: Path, truth: xr.Dataset) -> Path:
    """The lab's calibration: the default layout plus the lens (as OpenCV's calibrateCamera gives it)."""
    cal = TrackCalibration(camera_matrix=np.reshape(truth.attrs["camera_matrix"], (3, 3)),
                           distortion=tuple(truth.attrs["distortion"]))
    path.write_text(cal.to_toml())
    return path


def _errors(ex: xr.Dataset, truth: xr.Dataset) -> dict:
    """Centre (m) and heading (rad) errors on tracked samples; identity swaps."""
    ok = ex["tracked"].values
    dx = ex["x"].values - truth["x"].values
    dy = ex["y"].values - truth["y"].values
    dh = (ex["heading"].values - truth["heading"].values + np.pi) % (2 * np.pi) - np.pi
    # identity: each tracked point lies nearest its own robot's true point
    d = np.hypot(ex["x"].values[:, :, None] - truth["x"].values[:, None, :],
                 ex["y"].values[:, :, None] - truth["y"].values[:, None, :])
    nearest = np.argmin(np.where(np.isfinite(d), d, np.inf), axis=2)
    swaps = int((ok & (nearest != np.arange(ok.shape[1])[None, :])).sum())
    return {"rms_m": float(np.sqrt(np.mean((dx[ok] ** 2 + dy[ok] ** 2)))),
            "max_m": float(np.sqrt(dx[ok] ** 2 + dy[ok] ** 2).max()),
            "heading_rms_rad": float(np.sqrt(np.mean(dh[ok] ** 2))), "swaps": swaps,
            "tracked": float(ok.mean())}


def _steady_dx(ds: xr.Dataset, lam: float, period: float) -> np.ndarray:
    off = experiment_offsets(ds)
    return np.array([steady_offset(off["dx"].isel(pair=p) / lam, period)["value"] for p in range(off.sizes["pair"])])


def _sim_body_point(run: xr.Dataset, truth: xr.Dataset) -> xr.Dataset:
    """The simulation at the tracker's body point (middle link), on the video's frames."""
    x, y, h = middle_link_pose(run)
    sel = np.isin(run["time"].values, truth["time"].values)
    return run.isel(time=sel).assign(x=(("time", "swimmer"), x[sel]), y=(("time", "swimmer"), y[sel]),
                                     heading=(("time", "swimmer"), h[sel]))


# ------------------------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """A 20 s pair run filmed at 720p with every degradation, 3 dropped frames and a hand over robot 1."""
    d = tmp_path_factory.mktemp("track")
    scene = _scene(2)
    run = simulate(scene, SimOptions(duration_s=20.0, sample_rate_hz=10.0))
    cam_kw, deg = DEGRADATIONS["all"]
    x1, y1, _ = middle_link_pose(run.sel(time=12.0, method="nearest").expand_dims("time"))
    hand = Occluder(11.95, 13.05, float(x1[0, 1]) + 0.5, float(y1[0, 1]) + 0.125, 0.07)
    t0 = time.perf_counter()
    truth = render_video(run, d / "pair.mp4", camera=CameraSetup(width_px=1280, height_px=720, **cam_kw),
                         degradation=deg, drop_frames=(30, 31, 77), occluders=(hand,), seed=1)
    render_s = time.perf_counter() - t0
    cal = _calibration_file(d / "cal.toml", truth)
    t0 = time.perf_counter()
    rc = main(["track", str(d / "pair.mp4"), "--robots", "2", "--out", str(d / "exp.nc"), "--calibration", str(cal),
               "--phases", "0,90", "--width", str(ROBOT_WIDTH_M), "--quiet"])
    track_s = time.perf_counter() - t0
    assert rc == 0
    return {"dir": d, "scene": scene, "run": run, "truth": truth, "hand": hand, "exp": xr.load_dataset(d / "exp.nc"),
            "render_s": render_s, "track_s": track_s}


# ---------------------------------------------------------------------------------------------- tests
def test_tracked_pair_matches_ground_truth(pair):
    ex, truth = pair["exp"], pair["truth"]
    err = _errors(ex, truth)
    print(f"720p, every degradation: {err}, render {pair['render_s']:.1f} s, track {pair['track_s']:.1f} s")
    assert err["rms_m"] <= 0.002 and err["heading_rms_rad"] <= math.radians(2.0)
    assert err["swaps"] == 0
    # the simulation's schema: names, dims, units; frame times from the video's timestamps
    for v, unit in (("x", "m"), ("y", "m"), ("heading", "rad")):
        assert ex[v].dims == ("time", "swimmer") and ex[v].attrs["units"] == unit
    assert ex["time"].attrs["units"] == "s"
    np.testing.assert_allclose(ex["time"].values, truth["time"].values - truth["time"].values[0], atol=1e-6)
    # dropped frames: rows of their own, flagged, never filled
    tr = ex["tracked"].values
    assert list(np.flatnonzero(ex["frame"].values < 0)) == [30, 31, 77] == list(np.flatnonzero(truth["dropped"]))
    assert not tr[[30, 31, 77]].any() and np.isnan(ex["x"].values[[30, 31, 77]]).all()
    # the hand: robot 1 untracked while it covers the whole tag, robot 0 unaffected; untracked = NaN
    hand = pair["hand"]
    t = truth["time"].values
    covered = ((t >= hand.t_start_s) & (t <= hand.t_end_s)
               & (np.hypot(truth["x"].values[:, 1] - hand.x_m, truth["y"].values[:, 1] - hand.y_m)
                  < hand.radius_m - 0.04 / math.sqrt(2)))
    assert covered.sum() >= 4 and not tr[covered, 1].any()
    assert not truth["occluded"].values[:, 0].any()
    assert np.isnan(ex["x"].values[~tr]).all() and np.isfinite(ex["x"].values[tr]).all()
    visible = ~truth["dropped"].values[:, None] & ~truth["occluded"].values
    assert tr[visible].mean() >= 0.95
    # steady dx/lambda at the tracked point vs the simulation's at the same point: within 0.01
    lam, period = pair["scene"].wavelength_m, pair["scene"].gait.period_s
    sim = _sim_body_point(pair["run"], truth).assign_coords(time=ex["time"].values)
    assert abs(_steady_dx(ex, lam, period)[0] - _steady_dx(sim, lam, period)[0]) <= 0.01


def test_compare_pair_reproduces_its_simulation(pair, capsys):
    d = pair["dir"]
    assert main(["compare", str(d / "exp.nc"), "--out", str(d / "cmp")]) == 0
    out = capsys.readouterr().out
    assert "robots 0-1" in out
    for f in ("compare.png", "compare.pdf", "compare.json", "exp_dx.png", "exp_sim.nc"):
        assert (d / "cmp" / f).stat().st_size > 0
    res = json.loads((d / "cmp" / "compare.json").read_text())
    (e,) = res["experiments"][0]["pairs"]
    assert e["dphi_rad"] == pytest.approx(math.pi / 2)
    # the video is of this very simulation: experiment minus simulation is tracking error only
    d_es = e["experiment_minus_simulation"]
    assert abs(d_es["value"]) <= 0.01 and d_es["ci"][0] <= d_es["value"] <= d_es["ci"][1]
    assert e["timeseries_rms_experiment_minus_simulation"] <= 0.01
    assert e["theory"]["value"] == pytest.approx(0.25)
    assert e["experiment_minus_theory"]["value"] == pytest.approx(e["experiment"]["value"] - 0.25)
    sim = xr.load_dataset(d / "cmp" / "exp_sim.nc")
    assert "middle link" in sim["x"].attrs["long_name"] and sim["x"].attrs["units"] == "m"


def test_compare_an_experiment_without_a_whole_tracked_period(pair, tmp_path, capsys):
    """A video shorter than a gait period (or occluded in every one) has no steady value: ``compare`` once
    died on it (ValueError: NaN to int, the compatibility branch); now that pair's entry has nulls and the
    summary line says why."""
    short = tmp_path / "short.nc"
    exp = pair["exp"]
    period = float(exp.attrs["period"])
    exp.isel(time=exp["time"].values - float(exp["time"].values[0]) < 0.75 * period).to_netcdf(short)
    assert main(["compare", str(short), "--out", str(tmp_path / "cmp")]) == 0
    assert "experiment: no whole gait period with every frame tracked" in capsys.readouterr().out
    (e,) = json.loads((tmp_path / "cmp" / "compare.json").read_text())["experiments"][0]["pairs"]
    assert e["experiment"]["n_periods"] == 0 and e["experiment"]["value"] is None
    assert e["theory"] == {"value": None, "branch": None}
    assert e["experiment_minus_simulation"]["value"] is None


@pytest.fixture(scope="module")
def tracked_again(pair):
    """The same video tracked again, without the gait (no ``--phases``): ``again.nc``."""
    d = pair["dir"]
    assert main(["track", str(d / "pair.mp4"), "--robots", "2", "--out", str(d / "again.nc"), "--calibration",
                 str(d / "cal.toml"), "--quiet"]) == 0
    return d / "again.nc"


def test_tracking_is_deterministic(pair, tracked_again):
    """Tracked again (the gait only labels the result), every tracked number is the same."""
    again = xr.load_dataset(tracked_again)
    for v in ("x", "y", "heading", "tracked", "frame"):
        np.testing.assert_array_equal(again[v].values, pair["exp"][v].values)


def test_gait_from_merges_the_robot_log(pair, tmp_path):
    from undulate.robot.runner import RobotConfig, dry_run

    log = dry_run(RobotConfig(scene=pair["scene"], ids=(1, 2, 3, 4), duration_s=2.0))
    log.to_netcdf(tmp_path / "log.nc", engine="h5netcdf")
    out = tmp_path / "merged.nc"
    assert main(["track", str(pair["dir"] / "pair.mp4"), "--robots", "2", "--out", str(out), "--calibration",
                 str(pair["dir"] / "cal.toml"), "--gait-from", str(tmp_path / "log.nc"), "--quiet"]) == 0
    ds = xr.load_dataset(out)
    assert ds["joint_command"].dims == ("log_time", "swimmer", "joint")
    np.testing.assert_array_equal(ds["joint_command"].values, log["joint_command"].values)
    np.testing.assert_allclose(ds["phase"].values, pair["scene"].phases_rad)
    assert json.loads(ds.attrs["config"])["scene"]["phases_rad"] == list(pair["scene"].phases_rad)
    np.testing.assert_array_equal(ds["x"].values, pair["exp"]["x"].values)


def test_marker_sheet_prints_detectable_tags_at_true_size(tmp_path):
    from undulate.track.markers import sheet_figure
    from undulate.track.tracker import make_detector

    assert main(["track", "markers", "--robots", "4", "--out", str(tmp_path / "m.pdf")]) == 0
    assert (tmp_path / "m.pdf").read_bytes()[:5] == b"%PDF-"
    (fig,), pos = sheet_figure(4)
    dpi = 200
    fig.savefig(tmp_path / "m.png", dpi=dpi)
    img = cv2.imread(str(tmp_path / "m.png"), cv2.IMREAD_GRAYSCALE)
    assert np.allclose(img.shape, (0.297 / 0.0254 * dpi, 0.210 / 0.0254 * dpi), atol=1)  # A4 at true size
    corners, ids, _ = make_detector().detectMarkers(img)
    assert sorted(ids.ravel().tolist()) == [0, 1, 2, 3, 46, 47, 48, 49]
    c = np.asarray(corners)[:, 0]
    side_m = np.linalg.norm(np.roll(c, -1, axis=1) - c, axis=-1).mean() / dpi * 0.0254
    assert side_m == pytest.approx(0.03, rel=0.02)
    # robot tags read upright: first -> second corner along +x of the page
    for k, i in enumerate(ids.ravel()):
        e = c[k, 1] - c[k, 0]
        assert abs(math.atan2(e[1], e[0])) < 0.02, i


def _run_cli(args: list[str]) -> tuple[int, str]:
    p = subprocess.run([sys.executable, "-m", "undulate.cli", *args], capture_output=True, text=True, timeout=120)
    return p.returncode, p.stderr


def _blank_video(path: Path, frames: int = 40) -> None:
    import imageio_ffmpeg

    subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "gray",
                    "-s", "160x120", "-r", "10", "-i", "-", "-c:v", "libx264", "-pix_fmt", "yuv420p", str(path)],
                   input=np.full((frames, 120, 160), 180, np.uint8).tobytes(), check=True)


def test_bad_input_one_line_exit_2_nothing_written(pair, tracked_again, tmp_path, capfd):
    out = tmp_path / "exp.nc"
    bad = tmp_path / "bad.mp4"
    bad.write_text("not a video")
    blank = tmp_path / "blank.mp4"
    _blank_video(blank)
    toml = tmp_path / "cal.toml"
    toml.write_text("[markers]\n46 = [0.0, 0.0]\n47 = [1.0, 0.0]\nsize_m = 0.03\n")
    video = str(pair["dir"] / "pair.mp4")
    cases = [
        (["track", str(bad), "--robots", "2", "--out", str(out)], "VIDEO"),
        (["track", str(tmp_path / "missing.mp4"), "--robots", "2", "--out", str(out)], "VIDEO"),
        (["track", str(blank), "--robots", "2", "--out", str(out)], "calibration tags 46-49"),
        (["track", video, "--robots", "3", "--out", str(out), "--calibration", str(pair["dir"] / "cal.toml")],
         "--robots"),
        (["track", video, "--out", str(out)], "--robots"),
        (["track", video, "--robots", "2", "--out", str(out), "--calibration", str(toml)], "calibration [markers]"),
        (["track", video, "--robots", "2", "--out", str(out), "--phases", "0"], "--phases"),
        (["track", video, "--robots", "2", "--out", str(tmp_path / "exp.txt")], "--out"),
        # named as typed: these once said --width, calibration_s and "--phases: must be 0 values"
        (["track", video, "--robots", "2", "--out", str(out), "--phases", "0,90", "--channel-width", "-1"],
         "--channel-width"),
        (["track", video, "--robots", "2", "--out", str(out), "--calibration-window", "0"], "--calibration-window"),
        (["track", video, "--robots", "0", "--out", str(out), "--phases", "0,90"], "--robots"),
        (["track", video, "--robots", "2", "--out", str(out), "--start-time", "1e300"], "--start-time"),  # was
        # accepted: every frame's time 1e300
        (["compare", str(tmp_path / "missing.nc"), "--out", str(tmp_path / "cmp")], "EXP"),
        (["compare", str(pair["dir"] / "exp.nc"), "--out", "/proc/undulate-cmp"], "--out"),  # was a traceback
    ]
    rc, err = _run_cli(cases[0][0])  # as a user meets it: a fresh process, no traceback
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "VIDEO" in err, err
    capfd.readouterr()
    for args, name in cases:
        rc = main(args)
        err = capfd.readouterr().err  # file-descriptor level: FFmpeg's own messages would show here
        lines = err.strip().splitlines()
        assert rc == 2 and len(lines) == 1 and name in lines[0] and "Traceback" not in err, (args, err)
        assert not out.exists() and not (tmp_path / "cmp").exists()
    # an experiment tracked without its gait cannot be simulated: refused before anything is written
    capfd.readouterr()
    rc, err = main(["compare", str(tracked_again), "--out", str(tmp_path / "cmp")]), capfd.readouterr().err
    assert rc == 2 and "EXP" in err and len(err.strip().splitlines()) == 1 and not (tmp_path / "cmp").exists()
    assert not list(tmp_path.glob(".*"))  # no temporary left behind


def test_cli_does_not_import_opencv():
    code = "import sys, undulate.cli; sys.exit(1 if 'cv2' in sys.modules else 0)"
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


def test_renderer_is_deterministic(tmp_path):
    run = simulate(_scene(2), SimOptions(duration_s=0.5, sample_rate_hz=10.0))
    cam = CameraSetup(width_px=320, height_px=180)
    _, deg = DEGRADATIONS["noise"]
    a = render_video(run, tmp_path / "a.mp4", camera=cam, degradation=deg, seed=3)
    render_video(run, tmp_path / "b.mp4", camera=cam, degradation=deg, seed=3)
    assert (tmp_path / "a.mp4").read_bytes() == (tmp_path / "b.mp4").read_bytes()
    assert a.sizes["time"] == 6


# -------------------------------------------------------------------------- slow: 1080p, 1 m channel
@pytest.mark.slow
@pytest.mark.parametrize("n", [2, 4])
@pytest.mark.parametrize("case", list(DEGRADATIONS))
def test_1080p_tracking_accuracy(tmp_path, n, case):
    """Every degradation alone and all at once, for a pair and four robots, filmed at 1920 x 1080
    over the 1 m channel: RMS centre <= 2 mm, heading <= 2 deg, no identity swap, steady dx/lambda
    within 0.01 of the simulation's (same body point)."""
    scene = _scene(n)
    run = simulate(scene, SimOptions(duration_s=20.0, sample_rate_hz=15.0))
    cam_kw, deg = DEGRADATIONS[case]
    truth = render_video(run, tmp_path / "v.mp4", camera=CameraSetup(**cam_kw), degradation=deg, seed=2)
    cal = TrackCalibration(camera_matrix=np.reshape(truth.attrs["camera_matrix"], (3, 3)),
                           distortion=tuple(truth.attrs["distortion"]))
    from undulate.track import track_video

    t0 = time.perf_counter()
    ex = track_video(tmp_path / "v.mp4", n, cal, scene=scene, progress=False)
    fps = ex.sizes["time"] / (time.perf_counter() - t0)
    err = _errors(ex, truth)
    lam, period = scene.wavelength_m, scene.gait.period_s
    sim = _sim_body_point(run, truth).assign_coords(time=ex["time"].values)
    dsteady = np.abs(_steady_dx(ex, lam, period) - _steady_dx(sim, lam, period))
    print(f"\n{n} robots, {case:12s}: centre RMS {1e3 * err['rms_m']:.3f} mm (max {1e3 * err['max_m']:.3f}), "
          f"heading RMS {math.degrees(err['heading_rms_rad']):.3f} deg, tracked {100 * err['tracked']:.1f} %, "
          f"swaps {err['swaps']}, |steady dx/lambda - sim| max {dsteady.max():.4f}, "
          f"{truth.attrs['px_per_m']:.0f} px/m, tracking {fps:.1f} frames/s")
    assert err["rms_m"] <= 0.002 and err["heading_rms_rad"] <= math.radians(2.0)
    assert err["swaps"] == 0 and err["tracked"] >= 0.98
    assert dsteady.max() <= 0.01


def _terminated(args: list[str], ready) -> tuple[int, str]:
    """Run ``undulate ARGS`` in a fresh process, SIGTERM it once ``ready(proc)`` says it is at work, and
    return its exit code and stderr."""
    import signal

    def start():  # SIGTERM as a plain process has it, whatever this test process inherited
        signal.signal(signal.SIGTERM, signal.SIG_DFL)

    proc = subprocess.Popen([sys.executable, "-m", "undulate.cli", *args], stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=start)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None and not ready(proc):
            time.sleep(0.02)
        assert proc.poll() is None, "ended before it was signalled: " + proc.stderr.read()
        os.kill(proc.pid, signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
        return proc.returncode, err
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def _has_open(proc, path: Path) -> bool:
    try:
        return any(os.readlink(fd) == str(path) for fd in Path(f"/proc/{proc.pid}/fd").iterdir())
    except (FileNotFoundError, ProcessLookupError, PermissionError):
        return False



@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads a process's open files from /proc")
def test_a_terminated_track_or_compare_exits_143_and_leaves_no_temporary(pair, tmp_path):
    """``kill PID`` while tracking (the video open) or while comparing (simulating): the command unwinds as
    on Ctrl-C, exits 128 + SIGTERM, and leaves neither its output nor a temporary file (before: killed
    outright, exit -15, a half-written temporary possible)."""
    d = pair["dir"]
    video, out = d / "pair.mp4", tmp_path / "exp.nc"
    rc, err = _terminated(["track", str(video), "--robots", "2", "--out", str(out), "--calibration",
                           str(d / "cal.toml"), "--quiet"], lambda p: _has_open(p, video))
    assert rc == 143 and "Traceback" not in err, err
    assert list(tmp_path.iterdir()) == []
    cmp = tmp_path / "cmp"
    lines: list[str] = []
    rc, err = _terminated(["compare", str(d / "exp.nc"), "--out", str(cmp)],
                          lambda p: lines.append(p.stderr.readline()) or "simulating" in lines[-1])
    assert rc == 143 and "Traceback" not in err, "".join(lines) + err
    assert not list(tmp_path.rglob(".*")) and not list(tmp_path.rglob("*.nc"))
