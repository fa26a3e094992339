"""``undulate track`` and ``undulate compare`` (registered by :mod:`undulate.cli`).

Bad input: one line naming the parameter, exit code 2, nothing written.
OpenCV loads only when a video is tracked or a sheet drawn.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import List, Optional

import typer

from ..errors import ParameterError

_NO_CV = "the track extra: pip install 'undulate[track]' (OpenCV)"


def _need_cv2() -> None:
    try:
        import cv2  # noqa: F401
    except ImportError:
        raise ParameterError("installation", _NO_CV, None) from None


def _scene_from_options(n: int, phases, links, waves_per_body, amplitude, frequency, channel_width, body_length,
                        width):
    """The experiment's Scene from the command line (None when no --phases)."""
    from .._cliutil import _cli_name, _parse_floats
    from ..params import INERTIA_FIELDS, Channel, Gait, Scene, SwimmerGeometry

    if phases is None:
        return None
    ph = _parse_floats("--phases", phases)
    if len(ph) != n:
        raise ParameterError("--phases", f"{n} values (degrees), one per robot (--robots {n})", phases)
    try:
        gait = Gait(amplitude_rad=math.radians(amplitude), waves_per_body=waves_per_body, frequency_hz=frequency)
        geometry = SwimmerGeometry(n_links=links, length_m=body_length, width_m=width)
        try:
            channel = Channel(width_m=channel_width)
        except ParameterError as e:  # its width_m is --channel-width, not the robots' --width
            raise _cli_name(e, {"width_m": "--channel-width (m)"}) from None
        # robots tracked side by side need not start in contact: only the channel must hold them
        return Scene(phases_rad=tuple(math.radians(p) for p in ph), gait=gait, geometry=geometry, channel=channel)
    except ParameterError as e:
        raise _cli_name(e, {"amplitude_rad": "--amplitude (degrees, (0, 90])", "waves_per_body": "--waves-per-body",
                            "frequency_hz": "--frequency (Hz)", "n_links": "--links", "length_m": "--body-length (m)",
                            "width_m": "--width (m)", "channel width": "--channel-width (m)",
                            INERTIA_FIELDS: "--body-length / --width (m)"}) from None


def _load_log(path: Path, n: int):
    from .._cliutil import load_netcdf
    from ..params import Scene

    log = load_netcdf(path, "--gait-from", "an existing robot log (.nc from undulate robot run)")
    try:
        scene = Scene.from_dict(json.loads(log.attrs["config"])["scene"])
    except (KeyError, TypeError, ValueError, ParameterError):
        raise ParameterError("--gait-from", "a robot log recording its scene (attr config)", str(path)) from None
    if scene.n_swimmers != n:
        raise ParameterError("--gait-from", f"a log of {n} robots (--robots {n})", f"{path}: {scene.n_swimmers} robots")
    return log, scene


def merge_log(exp, log, log_name: str):
    """``exp`` with the robot log's variables on their own time axis ``log_time``
    (the log's gait time, s; nothing interpolated) and its attrs as JSON."""
    import xarray as xr

    keep = {k: v for k, v in log.data_vars.items() if "time" in v.dims}
    part = xr.Dataset(keep).drop_vars([c for c in ("phase",) if c in keep]).rename({"time": "log_time"})
    part["log_time"].attrs = {"units": "s", "long_name": "robot log time (gait time of each control tick)"}
    for name in list(part.data_vars):
        if name in exp:
            part = part.rename({name: f"log_{name}"})
    if "servo_id" in log.coords:
        part = part.assign_coords(servo_id=log["servo_id"])
    out = xr.merge([exp, part], compat="override", combine_attrs="override")
    attrs = {k: (v if isinstance(v, (str, int, float)) else str(v)) for k, v in log.attrs.items()}
    out.attrs["robot_log"] = log_name
    out.attrs["robot_log_attrs"] = json.dumps(attrs)
    return out


def track(
    video: str = typer.Argument(..., help="The overhead video, or the word `markers` to print the marker sheet."),
    robots: Optional[int] = typer.Option(None, "--robots", "-n", help="Number of robots: tag ids 0 .. N-1 (markers: default 4)."),
    out: Path = typer.Option(..., "--out", "-o", help="Output: the tracked experiment (.nc), or the sheet (.pdf) for `markers`."),
    calibration: Optional[Path] = typer.Option(None, "--calibration", help="TOML calibration: a markers table (fixed tag id = x, y of its centre, m), size_m, and optionally the camera lens (docs/tracking.md). Default: the layout printed on the marker sheet."),
    gait_from: Optional[Path] = typer.Option(None, "--gait-from", help="The robot log (.nc from `undulate robot run`) to merge: gait, phases, commands, servo load."),
    start_time: float = typer.Option(0.0, "--start-time", help="Gait time (the robot log's time) of the video's first frame, s."),
    calibration_window: float = typer.Option(2.0, "--calibration-window", help="The four table tags must all be seen within this many seconds from the start, s."),
    phases: Optional[str] = typer.Option(None, help="Without --gait-from: each robot's gait phase, DEGREES, comma-separated (recorded for `undulate compare`)."),
    links: int = typer.Option(3, help="Without --gait-from: links per robot."),
    waves_per_body: float = typer.Option(1.0, help="Without --gait-from: xi = L/lambda."),
    amplitude: float = typer.Option(45.0, help="Without --gait-from: joint amplitude, DEGREES."),
    frequency: float = typer.Option(0.5, help="Without --gait-from: gait frequency, Hz."),
    channel_width: float = typer.Option(0.13, help="Without --gait-from: channel width, m."),
    body_length: float = typer.Option(0.54, help="Without --gait-from: body length L, m."),
    width: float = typer.Option(0.015, help="Without --gait-from: link width w, m."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar or summary."),
) -> None:
    """Track ArUco-tagged robots in an overhead video -> the simulation's trajectory dataset.

    `undulate track markers --out markers.pdf` writes the printable marker sheet instead.
    """
    from .._cliutil import _cli_name, _fail, check_writable, exit_on_termination

    try:
        _need_cv2()
        exit_on_termination()  # a terminated command unwinds: no temporary file left
        from .calibration import TrackCalibration

        cal = TrackCalibration.from_toml(calibration) if calibration is not None else TrackCalibration()
        check_writable("--out", out)
        if video == "markers":
            from .markers import marker_sheet

            pages = marker_sheet(out, 4 if robots is None else robots, cal)
            typer.echo(f"wrote {out} ({pages} page{'s' if pages > 1 else ''}; tag side {1000 * cal.size_m:g} mm: print at 100 %)")
            return
        if robots is None:
            raise ParameterError("--robots", "given: the number of robots (tag ids 0 .. N-1)", None)
        if out.suffix.lower() != ".nc":
            raise ParameterError("--out", "a path ending in .nc (netCDF)", str(out))
        from .tracker import _check_arguments, track_video

        try:  # the video and the counts first: --phases is checked against --robots
            _check_arguments(Path(video), robots, calibration_window, start_time)
        except ParameterError as e:
            raise _cli_name(e, {"calibration_s": "--calibration-window (s)"}) from None
        log = None
        if gait_from is not None:
            if phases is not None:
                raise ParameterError("--phases", "omitted with --gait-from (the robot log holds the gait)", phases)
            log, scene = _load_log(gait_from, robots)
        else:
            scene = _scene_from_options(robots, phases, links, waves_per_body, amplitude, frequency, channel_width,
                                        body_length, width)
        ds = track_video(Path(video), robots, cal, calibration_s=calibration_window, start_time_s=start_time,
                         scene=scene, progress=None if not quiet else False)
        if log is not None:
            ds = merge_log(ds, log, gait_from.name)
    except ParameterError as e:
        _fail(str(e), 2)
    from .._cliutil import write_netcdf_atomic

    write_netcdf_atomic(ds, out)
    if quiet:
        return
    import numpy as np

    tr = ds["tracked"].values
    lines = [f"wrote {out}  ({ds.sizes['time']} frames, {ds.attrs['frames_missing']} missing from the video, "
             f"calibration residual {1000 * ds.attrs['calibration_residual_rms']:.2f} mm RMS)"]
    for j in range(tr.shape[1]):
        lines.append(f"robot {j}: tracked in {100 * tr[:, j].mean():.1f} % of frames")
    h = ds["heading"].values[tr]
    if h.size and np.median(np.cos(h)) < 0:
        lines.append("warning: the robots' heads point toward +x in the table frame; the simulation's convention is "
                     "heads toward -x (number the table tags so that x runs head -> tail: docs/tracking.md)")
    if scene is None:
        lines.append("note: no --phases or --gait-from: `undulate compare` needs the gait to simulate")
    typer.echo("\n".join(lines))


def compare(
    experiments: List[Path] = typer.Argument(..., help="Tracked experiments (.nc from `undulate track`)."),
    out: Path = typer.Option(..., "--out", "-o", help="Output folder (created): compare.png/.pdf, NAME_dx.png, NAME_sim.nc, compare.json."),
    periods: int = typer.Option(5, help="Whole gait periods at the end that make the steady value."),
) -> None:
    """Simulate each experiment's gait, phases and channel and compare: steady dx/lambda vs dphi, dx(t), residuals."""
    from .._cliutil import _fail, exit_on_termination
    from ..compare import compare as run

    from ..errors import UndulateError

    exit_on_termination()  # a terminated comparison unwinds: no temporary file left
    try:
        summary = run(experiments, out, periods=periods, log=lambda m: typer.echo(m, err=True))
    except ParameterError as e:
        _fail(str(e), 2)
    except UndulateError as e:  # a matching simulation that diverged: its diagnosis
        _fail(str(e), 1)
    lines = [f"wrote {out}/compare.png, compare.pdf, compare.json"]
    for r in summary["experiments"]:
        for e in r["pairs"]:
            u = "/lambda" if e["unit"] == "lambda" else " m"
            d = e["experiment_minus_simulation"]
            line = (f"{r['experiment']} robots {e['lower']}-{e['upper']} dphi = {math.degrees(e['dphi_rad']):.0f} deg: "
                    f"dx{u} experiment {e['experiment']['value']:+.3f}, simulation {e['simulation']['value']:+.3f}, "
                    f"difference {d['value']:+.3f} [{d['ci'][0]:+.3f}, {d['ci'][1]:+.3f}]")
            if "theory" in e:
                line += f", compatibility {e['theory']['value']:+.3f}"
            for who in ("experiment", "simulation"):
                if e[who]["n_periods"] == 0:  # a short or much occluded video: no steady value to compare
                    line += (f" ({who}: no whole gait period with every frame tracked, {e[who]['n_skipped']} "
                             f"incomplete)")
            lines.append(line)
    typer.echo("\n".join(lines))
