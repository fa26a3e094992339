"""``undulate robot run`` and ``undulate robot ping``: a thin layer over :mod:`undulate.robot`.

Bad input prints one line ``error: invalid <option>: must be ...`` and exits
with code 2 before any port is opened (nothing is sent to any servo).  A run
that fails on the bus exits 1; one ended by SIGINT / SIGTERM / SIGHUP exits
130 / 143 / 129.  In every case torque is switched off first and the log so
far is written; the last line says what happened to torque.
"""

from __future__ import annotations

import math
import os
import stat
from pathlib import Path
from typing import Optional

import typer

from .._cliutil import said
from ..errors import ParameterError
from ..params import INERTIA_FIELDS

robot_app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Run gaits on Dynamixel servo robots (needs the optional robot extra, dynamixel-sdk).",
    pretty_exceptions_enable=False,
)


def _fail(msg: str, code: int) -> None:
    typer.echo(f"error: {msg}", err=True)
    raise typer.Exit(said(code))  # this line says why (a Ctrl-C: what happened to torque); no other follows


def _parse_ids(text: str) -> tuple[int, ...]:
    parts = [p.strip() for p in text.split(",")]
    try:
        ids = tuple(int(p) for p in parts)
    except ValueError:
        raise ParameterError("--ids", "comma-separated integer servo ids", text) from None
    return ids


def _check_port(port: Optional[str]) -> str:
    if port is None:
        raise ParameterError("--port", "a serial device (e.g. /dev/ttyUSB0), or --dry-run")
    try:
        st = os.stat(port)
    except OSError:
        raise ParameterError("--port", "an existing serial device", port) from None
    if not stat.S_ISCHR(st.st_mode):
        raise ParameterError("--port", "a serial (character) device", port)
    if not os.access(port, os.R_OK | os.W_OK):
        raise ParameterError("--port", "a serial device this user may read and write (dialout group?)", port)
    try:  # a character device that is no terminal (/dev/null, /dev/zero) fails only as pyserial configures it
        fd = os.open(port, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError as e:
        raise ParameterError("--port", f"a serial device that opens ({e.strerror})", port) from None
    try:
        if not os.isatty(fd):
            raise ParameterError("--port", "a serial device (a terminal device such as /dev/ttyUSB0)", port)
    finally:
        os.close(fd)
    return port


_NAMES = {"ids": "--ids", "protocol": "--protocol", "baudrate": "--baudrate", "servo": "--servo",
          "duration_s": "--duration (s)", "amplitude_rad": "--amplitude (degrees)", "frequency_hz": "--frequency (Hz)",
          "control_rate_hz": "--control-rate (Hz)", "waves_per_body": "--waves-per-body", "n_links": "--links",
          "length_m": "--body-length (m)", "width_m": "--channel-width (m)", "channel width": "--channel-width (m)",
          "controller": "--controller", "coupling": "--coupling (rad/s per N m)", "phases_rad": "--phases (degrees)",
          INERTIA_FIELDS: "--body-length (m)"}


def _relabel(e: ParameterError) -> ParameterError:
    return ParameterError(_NAMES.get(e.name, e.name), e.allowed, e.got)


@robot_app.command("run")
def run(
    port: Optional[str] = typer.Option(None, help="Serial device of the bus (USB2Dynamixel / U2D2), e.g. /dev/ttyUSB0."),
    protocol: int = typer.Option(1, help="Dynamixel protocol: 1 (AX-12A, AX-18A) or 2 (XL430-W250)."),
    baudrate: int = typer.Option(1_000_000, help="Bus speed, bit/s."),
    ids: str = typer.Option(..., help="Servo ids robot by robot, head joint first (robot 0's joints, then robot 1's ...); count = robots x (links - 1)."),
    phases: str = typer.Option("0,90", help="Gait phase of each robot, DEGREES, comma-separated; their count is the number of robots."),
    links: int = typer.Option(3, help="Links per robot (>= 2)."),
    waves_per_body: float = typer.Option(1.0, help="xi = L/lambda, body waves per body length (0 = standing wave)."),
    amplitude: float = typer.Option(45.0, help="Joint amplitude beta, DEGREES (0, 90]."),
    frequency: float = typer.Option(0.5, help="Gait frequency f, Hz."),
    controller: str = typer.Option("open-loop", help="Gait controller: open-loop, self-oscillating, phase-oscillator or relay (undulate.control)."),
    coupling: float = typer.Option(0.0, help="phase-oscillator load-feedback strength sigma, rad/s per N m (>= 0)."),
    control_rate: float = typer.Option(50.0, help="Control rate: one sync write of goals (and one round of reads) per tick, Hz."),
    calibration: Optional[Path] = typer.Option(None, help="Calibration TOML (offsets, signs, limits, maximum speed): see docs/robots.md."),
    servo: Optional[str] = typer.Option(None, help="Servo model: AX-12A, AX-18A, XL430-W250 (default: the calibration's, else AX-12A on protocol 1, XL430-W250 on 2)."),
    body_length: float = typer.Option(0.54, help="Robot length L, m (recorded; sets lambda = L/xi in the log)."),
    channel_width: float = typer.Option(0.13, help="Channel width d, m (recorded with the run)."),
    duration: float = typer.Option(30.0, help="Gait duration, s."),
    out: Path = typer.Option(Path("run.nc"), "--out", "-o", help="Log, netCDF (.nc): the simulation's schema."),
    dry_run: bool = typer.Option(False, "--dry-run", help="Print the schedule and write the commanded trajectory; open no port."),
) -> None:
    """Drive the robots' servos with the gait and log the run."""
    from .._cliutil import check_writable

    try:
        from .._cliutil import _parse_floats
        from . import load_calibration
        from .runner import RobotConfig

        phases_deg = _parse_floats("--phases", phases)
        servo_ids = _parse_ids(ids)
        if links < 2:
            raise ParameterError("--links", "an integer >= 2", links)
        if coupling != 0.0 and controller != "phase-oscillator":
            raise ParameterError("--coupling", "0 unless --controller phase-oscillator", coupling)
        try:
            scene = _scene(phases_deg, links, waves_per_body, amplitude, frequency, controller, coupling,
                           control_rate, body_length, channel_width)
            cal = load_calibration(calibration)
            cfg = RobotConfig(scene=scene, ids=servo_ids, protocol=protocol, port=port, baudrate=baudrate,
                              duration_s=duration, calibration=cal, servo=servo)
        except ParameterError as e:
            raise _relabel(e) from None
        check_writable("--out", out)
        if out.suffix.lower() != ".nc":
            raise ParameterError("--out", "a path ending in .nc (netCDF)", str(out))
        if not dry_run:
            _check_port(port)
    except ParameterError as e:
        _fail(str(e), 2)

    from .runner import dry_run as plan, schedule_text

    if dry_run:
        ds = plan(cfg, out)
        typer.echo(schedule_text(cfg, ds))
        typer.echo(f"wrote {out} (commanded trajectory, {ds.sizes['time']} ticks; no port opened)")
        return
    _drive(cfg, out)


def _scene(phases_deg, links: int, waves_per_body: float, amplitude: float, frequency: float, controller: str,
           coupling: float, control_rate: float, body_length: float, channel_width: float):
    """The :class:`~undulate.params.Scene` of ``run``'s options (angles in degrees)."""
    from ..params import Channel, ControllerParams, Gait, Scene, SwimmerGeometry

    return Scene(phases_rad=tuple(math.radians(p) for p in phases_deg),
                 gait=Gait(amplitude_rad=math.radians(amplitude), waves_per_body=waves_per_body,
                           frequency_hz=frequency),
                 geometry=SwimmerGeometry(n_links=links, length_m=body_length),
                 channel=Channel(width_m=channel_width),
                 controller=ControllerParams(kind=controller, coupling=coupling, control_rate_hz=control_rate))


def _drive(cfg, out: Path) -> None:
    """Run the robots (warnings and the schedule first); report the log written, or fail saying what
    happened to torque and the log."""
    from .bus import BusError
    from .runner import Interrupted, run_robot, schedule_text

    for w in cfg.clipped_joints():
        typer.echo(f"warning: {w}", err=True)
    typer.echo(schedule_text(cfg))
    try:
        ds = run_robot(cfg, out, log=lambda m: typer.echo(m, err=True))
    except Interrupted as e:
        _fail(f"{_end(e)}; torque {e.torque_off}{_logged(e, out)}", 128 + e.signum)
    except BusError as e:
        _fail(f"{e}; torque {e.torque_off}{_logged(e, out)}", 1)
    except Exception as e:  # noqa: BLE001 - a bug must still say what happened to torque and the log
        _fail(f"{type(e).__name__}: {e}; torque {getattr(e, 'torque_off', 'unknown')}{_logged(e, out)}", 1)
    a = ds.attrs
    typer.echo(f"wrote {out} ({ds.sizes['time']} ticks, {float(ds['time'].values[-1]):g} s): control rate "
               f"{a['control_rate_achieved']:.2f} Hz (nominal {a['control_rate']:g}), tick lateness rms "
               f"{1e3 * a['tick_lateness_rms']:.2f} ms, max {1e3 * a['tick_lateness_max']:.2f} ms, "
               f"{a['ticks_skipped']} skipped, {a['read_timeouts']} read time-outs; torque {a['torque_off']}")


def _end(e) -> str:
    import signal

    return f"interrupted by {signal.Signals(e.signum).name}"


def _logged(e, out: Path) -> str:
    ds = getattr(e, "dataset", None)
    return f"; log of {ds.sizes['time']} ticks: {out}" if ds is not None else "; nothing logged"


@robot_app.command("ping")
def ping_cmd(
    port: Optional[str] = typer.Option(None, help="Serial device of the bus, e.g. /dev/ttyUSB0."),
    protocol: int = typer.Option(1, help="Dynamixel protocol: 1 or 2."),
    baudrate: int = typer.Option(1_000_000, help="Bus speed, bit/s."),
    ids: Optional[str] = typer.Option(None, help="Ids to ping, comma-separated (default: all; protocol 2 uses one broadcast ping, protocol 1 pings 0..253 in about 9 s)."),
) -> None:
    """List the servos that answer on the bus."""
    try:
        from .runner import BAUDRATES

        if protocol not in (1, 2):
            raise ParameterError("--protocol", "1 or 2", protocol)
        if baudrate not in BAUDRATES:
            raise ParameterError("--baudrate", "one of " + ", ".join(map(str, BAUDRATES)) + " bit/s", baudrate)
        id_list = None
        if ids is not None:
            id_list = _parse_ids(ids)
            if any(not 0 <= i <= 253 for i in id_list):
                raise ParameterError("--ids", "integers in [0, 253]", ids)
        _check_port(port)
    except ParameterError as e:
        _fail(str(e), 2)
    from .bus import BusError
    from .runner import ping

    try:
        found = ping(port, protocol, baudrate, id_list)
    except BusError as e:
        _fail(str(e), 1)
    if not found:
        _fail(f"no servos answered on {port} (protocol {protocol}, {baudrate} bit/s)", 1)
    for i, name in found.items():
        typer.echo(f"id {i:3d}: {name}")
