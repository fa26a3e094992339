"""The ``undulate`` command line (typer): a thin layer over the Python API.

Bad input prints one line ``error: invalid <parameter>: must be ...`` on
stderr and exits with code 2, before anything is written.  A diverged
simulation exits with code 1 and a diagnosis.  Heavy imports (MuJoCo,
xarray, matplotlib, Dask) happen inside the commands, so ``--help`` is fast.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Optional

import typer

from ._cliutil import _cli_name, _fail, _parse_floats, check_writable, exit_on_termination, load_netcdf, unwind_on_signals, write_netcdf_atomic  # noqa: F401 - shared with robot.cli, track.cli
from ._source import SourceChangedError
from .errors import DivergenceError, ParameterError, UndulateError, WriteError
from .params import Channel as _Channel
from .params import ControllerParams as _ControllerParams
from .params import Gait as _Gait
from .params import SimOptions as _SimOptions
from .params import SwimmerGeometry as _SwimmerGeometry

# Option defaults come from the parameter types themselves (one source of truth; SI -> the
# CLI's units where an option says DEGREES).
_GAIT, _GEO, _CHAN, _SIM, _CTRL = _Gait(), _SwimmerGeometry(), _Channel(), _SimOptions(), _ControllerParams()

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Simulate and analyse active undulatory collectives (contact-coupled multi-link swimmers).",
    pretty_exceptions_enable=False,
)


# Typer renders help as Rich markup: "\\[" keeps a literal "[" (tests/test_cli.py checks every help text)
_BACKEND_HELP = ("Physics engine: mujoco (MuJoCo's C engine on the CPU, float64) or warp (MuJoCo Warp: a "
                 "study's runs become the worlds of one GPU model, float32; needs pip install 'undulate\\[gpu]'). "
                 "On a GPU, scenes of one swimmer and batches of at most one scene per core step on the cores, "
                 "where they are faster (each run's attrs say which engine; UNDULATE_WARP_LONE_SWIMMERS=warp and "
                 "UNDULATE_WARP_CORES_UP_TO=0 keep them on Warp).")
_DEVICE_HELP = "The warp backend's device: cuda or cpu (default: cuda if present). Only with --backend warp."


@app.command()
def simulate(
    phases: str = typer.Option("0,90", help="Gait phase of each swimmer, DEGREES, comma-separated; their count is the number of swimmers (side by side, laterally in contact)."),
    links: int = typer.Option(_GEO.n_links, help="Links per swimmer (>= 2)."),
    waves_per_body: float = typer.Option(_GAIT.waves_per_body, help="xi = L/lambda, body waves per body length (0 = standing wave)."),
    amplitude: float = typer.Option(round(math.degrees(_GAIT.amplitude_rad), 9), help="Joint amplitude beta, DEGREES (0, 90]."),
    frequency: float = typer.Option(_GAIT.frequency_hz, help="Gait frequency f, Hz."),
    channel_width: float = typer.Option(_CHAN.width_m, help="Wall-to-wall channel width W, m (a pair's W = 2 d; "
                                               "undulate.theory.channel_width_m)."),
    dx0: float = typer.Option(0.0, help="Initial longitudinal offset of each swimmer from the previous one, m."),
    separating_force: float = typer.Option(0.0, help="Longitudinal force, N: +F on the second swimmer and -F on the first."),
    duration: float = typer.Option(_SIM.duration_s, help="Simulated time, s."),
    timestep: Optional[float] = typer.Option(None, help="Integrator time step, s (<= 0.004); default: the step the model needs (2 ms for 3 links, shorter for more links; see README)."),
    sample_rate: float = typer.Option(_SIM.sample_rate_hz, help="Recording rate, Hz."),
    body_length: float = typer.Option(_GEO.length_m, help="Total body length L, m."),
    width: float = typer.Option(_GEO.width_m, help="Link width w, m."),
    controller: str = typer.Option(_CTRL.kind, help="Gait controller: open-loop (the paper's travelling wave), self-oscillating (joints gated by their sensed turning points) phase-oscillator (load feedback) or relay (drive reverses where contact blocks a joint); see undulate.control."),
    coupling: float = typer.Option(_CTRL.coupling, help="phase-oscillator load-feedback strength sigma, rad/s per N m (>= 0)."),
    control_rate: float = typer.Option(_CTRL.control_rate_hz, help="Closed-loop control (servo-bus) rate, Hz."),
    hold_x: bool = typer.Option(False, "--hold-x", help="Lock each swimmer's longitudinal position (lateral motion and rotation stay free)."),
    heading_guide: bool = typer.Option(False, "--heading-guide", help="Remove the yaw recoil: a stiff actuator holds each swimmer's commanded head-to-tail chord along the channel (open-loop controller only; see Scene.heading_guide)."),
    out: Path = typer.Option(Path("run.nc"), "--out", "-o", help="Output netCDF file."),
    estimate: bool = typer.Option(False, "--estimate", help="Only print the estimated compute time (measured on about a second of this run's first steps, extrapolated to --duration) and exit; writes nothing."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Do not print the summary or the progress bar."),
    backend: str = typer.Option("mujoco", "--backend", help=_BACKEND_HELP),
    device: Optional[str] = typer.Option(None, "--device", help=_DEVICE_HELP),
) -> None:
    """Simulate swimmers side by side in a channel and write a netCDF trajectory.

    A run estimated to take over a minute first prints its estimated compute
    time on stderr (about a second into it), and one over 20 s shows a progress bar there.
    """
    try:
        scene = _scene(phases=phases, links=links, waves_per_body=waves_per_body, amplitude=amplitude,
                       frequency=frequency, channel_width=channel_width, dx0=dx0, separating_force=separating_force,
                       body_length=body_length, width=width, controller=controller, coupling=coupling,
                       control_rate=control_rate, hold_x=hold_x, heading_guide=heading_guide)
        options = _sim_options(duration=duration, timestep=timestep, sample_rate=sample_rate, backend=backend,
                               device=device)
        check_writable("--out", out)
        if out.suffix.lower() != ".nc":
            raise ParameterError("--out", "a path ending in .nc (netCDF)", str(out))
    except ParameterError as e:
        _fail(str(e), 2)
    exit_on_termination()  # a terminated run unwinds like Ctrl-C: its half-written temporary file is removed
    if estimate:
        _print_estimate(scene, options, out)
        return
    ds = _run_streamed(scene, options, out, bar=not quiet)
    with ds:
        if not quiet:
            typer.echo(_summary(ds, out))


def _scene(*, phases: str, links: int, waves_per_body: float, amplitude: float, frequency: float,
           channel_width: float, dx0: float, separating_force: float, body_length: float, width: float,
           controller: str, coupling: float, control_rate: float, hold_x: bool, heading_guide: bool):
    """``simulate``'s scene from its options (ParameterError naming the option)."""
    from .params import INERTIA_FIELDS, Channel, ControllerParams, Gait, Scene, SwimmerGeometry

    phases_deg = _parse_floats("--phases", phases)
    if links < 2:
        raise ParameterError("--links", "an integer >= 2", links)
    try:
        gait = Gait(amplitude_rad=math.radians(amplitude), waves_per_body=waves_per_body, frequency_hz=frequency)
    except ParameterError as e:
        raise _cli_name(e, {"amplitude_rad": "--amplitude (degrees, (0, 90])", "waves_per_body": "--waves-per-body",
                            "frequency_hz": "--frequency (Hz)"}) from None
    try:
        geometry = SwimmerGeometry(n_links=links, length_m=body_length, width_m=width)
    except ParameterError as e:
        raise _cli_name(e, {"n_links": "--links", "length_m": "--body-length (m)", "width_m": "--width (m)",
                            INERTIA_FIELDS: "--body-length / --width (m)"}) from None
    try:
        channel = Channel(width_m=channel_width)
    except ParameterError as e:
        raise _cli_name(e, {"width_m": "--channel-width (m)"}) from None
    forces = _separating_forces(separating_force, len(phases_deg))
    try:
        ctl = ControllerParams(kind=controller, coupling=coupling, control_rate_hz=control_rate)
    except ParameterError as e:
        raise _cli_name(e, {"controller": "--controller", "coupling": "--coupling (rad/s per N m)",
                            "control_rate_hz": "--control-rate (Hz)"}) from None
    if coupling != 0.0 and controller != "phase-oscillator":
        raise ParameterError("--coupling", "0 unless --controller phase-oscillator", coupling)
    try:
        return Scene(phases_rad=tuple(math.radians(p) for p in phases_deg), gait=gait, geometry=geometry,
                     channel=channel, dx0_m=dx0, forces_N=forces, controller=ctl, hold_x=hold_x,
                     heading_guide=heading_guide)
    except ParameterError as e:
        raise _cli_name(e, {"channel width": "--channel-width (m)", "dx0_m": "--dx0 (m)",
                            "phases_rad": "--phases (degrees)", "heading_guide": "--heading-guide"}) from None


def _separating_forces(separating_force: float, n: int) -> tuple[float, ...] | None:
    """``--separating-force``: -F on the first swimmer, +F on the second, none on the others."""
    if not math.isfinite(separating_force):
        raise ParameterError("--separating-force", "a finite number (N)", separating_force)
    if separating_force == 0.0:
        return None
    if n < 2:
        raise ParameterError("--separating-force", "0 unless there are at least 2 swimmers", separating_force)
    return (-separating_force, separating_force) + (0.0,) * (n - 2)


def _sim_options(*, duration: float, timestep: float | None, sample_rate: float, backend: str = "mujoco",
                 device: str | None = None):
    from .params import SimOptions
    from .simulation import check_backend

    _check_backend(backend, device)
    try:
        options = SimOptions(duration_s=duration, timestep_s=timestep, sample_rate_hz=sample_rate,
                             backend=backend, device=device)
        check_backend(options)  # the warp extra and the device, checked before anything is written
        return options
    except ParameterError as e:
        raise _cli_name(e, _RUN_OPTIONS) from None


# ``simulate``'s run options by the SimOptions field they set: a ParameterError raised once the scene is
# known (the sample rate against the scene's automatic time step) names the option the user typed too
_RUN_OPTIONS = {"duration_s": "--duration (s)", "timestep_s": "--timestep (s)", "sample_rate_hz": "--sample-rate (Hz)",
                "backend": "--backend", "device": "--device"}


def _check_backend(backend: str, device: str | None) -> None:
    """``--backend`` and ``--device``, validated (ParameterError naming the option)."""
    if backend not in ("mujoco", "warp"):
        raise ParameterError("--backend", "mujoco or warp", backend)
    if device is not None and device not in ("cpu", "cuda"):
        raise ParameterError("--device", "cuda or cpu", device)
    if device is not None and backend != "warp":
        raise ParameterError("--device", "given only with --backend warp (mujoco steps on the CPU)", device)


def _execution(backend: str, device: str | None, workers: int | None, scheduler: str | None):
    """``study``'s and ``reproduce``'s settings, built once (:class:`undulate.execution.Execution`):
    ``--backend``, ``--device``, ``--workers`` and ``--scheduler`` over the environment's
    (:meth:`~undulate.execution.Execution.from_environment`), the Warp extra and device checked, errors
    named as the options, before anything is written."""
    from .execution import settings
    from .simulation import backend as engine

    _check_backend(backend, device)
    try:
        if backend != "mujoco":  # the engine checks its extra and device
            device = engine(backend).resolve_device(device)
        return settings(workers=workers, scheduler=scheduler).replace(backend=backend, device=device)
    except ParameterError as e:
        raise _cli_name(e, {"backend": "--backend", "device": "--device", "workers": "--workers",
                            "scheduler": "--scheduler"}) from None


def _print_estimate(scene, options, out: Path) -> None:
    """``--estimate``: time the run's first chunks (to a temporary file beside ``out``, on the run's
    disk), print the extrapolation."""
    from ._progress import estimate_compute_time

    try:
        typer.echo(estimate_compute_time(scene, options, dir=out.resolve().parent).line())
    except DivergenceError as e:
        _fail(str(e), 1)
    except ParameterError as e:
        _fail(str(_cli_name(e, _RUN_OPTIONS)), 2)


def _run_streamed(scene, options, out: Path, *, bar: bool):
    """Simulate to ``out`` chunk by chunk (memory stays flat for any duration), announcing a long
    run's compute time and showing its progress on stderr; the Dataset opened lazily from ``out``."""
    from ._progress import RunMonitor
    from .simulation import simulate as run

    with RunMonitor(bar=bar) as monitor:
        try:
            return run(scene, options, out=out, progress=monitor)
        except DivergenceError as e:
            _fail(str(e), 1)
        except ParameterError as e:  # a recording that cannot fit on disk: refused before any step
            _fail(str(_cli_name(e, _RUN_OPTIONS)), 2)


def _summary(ds, out: Path) -> str:
    from . import theory
    from .observables import neighbour_offsets

    lam = float(ds.attrs["wavelength"])
    period = float(ds.attrs["period"])
    t_all = ds["time"].values
    n_total, t_end = len(t_all), float(t_all[-1])
    # read only the last two gait periods from the (possibly huge, lazily opened) file
    ds = ds.sel(time=slice(t_end - 2 * period - 1e-9, None)).load()
    off = neighbour_offsets(ds)
    t = ds["time"].values
    last = t >= t[-1] - period + 1e-9  # average over the last gait period
    lines = [f"wrote {out}  ({n_total} samples, {t_end:g} s, lambda = {lam:.4g} m)"]
    if off.sizes["pair"] == 0:
        lines.append("one swimmer: no neighbouring pairs")
    for p in range(off.sizes["pair"]):
        dx = float(off["dx"].values[last, p].mean())
        dphi = float(off["dphi"].values[-1, p])
        if ds.attrs.get("controller", "open-loop") != "open-loop":  # phases move: the final difference
            from .phases import neighbour_phase_differences

            dphi = float(neighbour_phase_differences(ds).values[-1, p])
        lo, hi = int(off["lower"].values[-1, p]), int(off["upper"].values[-1, p])
        if math.isfinite(lam):
            res = float(theory.compatibility_residual(dx, dphi, lam))
            pred = dx - res
            lines.append(
                f"pair {lo}-{hi}: dphi = {math.degrees(dphi):7.1f} deg   final dx/lambda = {dx / lam:+.3f}   "
                f"compatibility dx/lambda = {pred / lam:+.3f} (nearest branch)   residual = {res / lam:+.3f}"
            )
        else:
            lines.append(f"pair {lo}-{hi}: dphi = {math.degrees(dphi):7.1f} deg   final dx = {dx:+.4f} m   "
                         "(standing wave: no compatibility prediction)")
    return "\n".join(lines)


@app.command()
def animate(
    run: Path = typer.Argument(..., help="A netCDF file written by `undulate simulate`."),
    out: Path = typer.Option(..., "--out", "-o", help="Output animation, .mp4 or .gif."),
    stride: int = typer.Option(1, help="Draw every STRIDE-th recorded sample."),
    fps: Optional[float] = typer.Option(None, help="Frames per second (default: real time)."),
) -> None:
    """Draw a simulated run from above: links as bodies, contacts in red, a clock."""
    try:
        if not run.is_file():
            raise ParameterError("RUN", "an existing netCDF file", str(run))
        check_writable("--out", out)
        if out.suffix.lower() not in (".gif", ".mp4"):
            raise ParameterError("--out", "a path ending in .gif or .mp4", str(out))
        ds = load_netcdf(run, "RUN")
        from .animation import animate as draw

        exit_on_termination()  # a terminated animation unwinds: ffmpeg stopped, no temporary file left
        n = draw(ds, out, stride=stride, fps=fps)
    except ParameterError as e:
        _fail(str(_cli_name(e, {"run file": "RUN", "output file": "--out"})), 2)
    typer.echo(f"wrote {out} ({n} frames)")


@app.command("studies")
def list_studies() -> None:
    """List the registered studies."""
    from . import studies

    names = studies.names()
    width = max(map(len, names), default=0)
    for name in names:
        typer.echo(f"{name:{width}s}  {studies.describe(name)}")


_WORKERS_HELP = ("Local worker processes (default: the cores this process may use); results do not depend "
                 "on it. Not with --scheduler.")


def _check_config(workers: int | None, scheduler: str | None, seed: int, looks: int | None = None) -> None:
    """``--workers``, ``--scheduler`` (its form; the connection is made by the first sweep), ``--seed`` and
    ``--looks`` by :class:`~undulate.studies.StudyConfig`'s own rules, named as the CLI options, before
    anything is written."""
    from .studies import StudyConfig

    try:
        StudyConfig(out_dir=Path("."), scheduler=scheduler, workers=workers, seed=seed, max_looks=looks)
    except ParameterError as e:
        raise _cli_name(e, {"workers": "--workers", "seed": "--seed", "scheduler": "--scheduler",
                            "max_looks": "--looks"}) from None


_LOOKS_HELP = ("Stop every study after at most this many looks (an integer >= 1; default: every look while "
               "a claim is undecided). Fewer runs, more undecided verdicts; each judged at the level of that "
               "many looks.")


class _Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP (a scheduler's cancel, ``kill``, a closed terminal) during ``study`` or
    ``reproduce``: unwound as Ctrl-C is, so the sweeps in flight stop, the worker processes are stopped,
    finished runs stay saved for a rerun to resume, and the command exits ``128 + signal``."""

    def __init__(self, signum: int):
        import signal

        self.signum = int(signum)
        super().__init__(signal.Signals(signum).name)


def _stop_on_termination() -> None:
    """SIGTERM and SIGHUP raise :class:`_Terminated` in the main thread from here on (where they would
    end the process: a signal ignored, as ``nohup`` ignores SIGHUP, stays ignored)."""
    import signal

    unwind_on_signals((signal.SIGTERM, signal.SIGHUP), _Terminated)


@app.command("claims-table")
def claims_table(
    claims_json: Path = typer.Argument(..., help="A claims.json written by `undulate reproduce`."),
) -> None:
    """Print a reproduction's claims table as Markdown: the paper's counts apart from the PRX 2021 ones, then
    every claim with its verdict, measured value and the paper's sentence it tests (what
    docs/full_reproduction.md opens with)."""
    from .claims import claims_table_markdown

    try:
        if not claims_json.is_file():
            raise ParameterError("CLAIMS_JSON", "an existing claims.json", str(claims_json))
        try:
            text = claims_table_markdown(claims_json)
        except (ValueError, AttributeError, TypeError) as e:
            raise ParameterError("CLAIMS_JSON", "a claims.json written by `undulate reproduce`",
                                 f"{claims_json} ({type(e).__name__})") from None
    except ParameterError as e:
        _fail(str(e), 2)
    typer.echo(text, nl=False)


@app.command()
def study(
    name: str = typer.Argument(..., help="Study name (see `undulate studies`)."),
    out: Path = typer.Option(Path("results"), "--out", "-o", help="Output folder (created if missing)."),
    quick: bool = typer.Option(True, "--quick/--full", help="Quick mode (reduced resolution, minutes) or the paper's full resolution."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Dask scheduler address tcp://HOST:PORT or scheduler-file path (default: local processes)."),
    seed: int = typer.Option(0, help="Base random seed (an integer >= 0)."),
    workers: Optional[int] = typer.Option(None, "--workers", help=_WORKERS_HELP),
    backend: str = typer.Option("mujoco", "--backend", help=_BACKEND_HELP),
    device: Optional[str] = typer.Option(None, "--device", help=_DEVICE_HELP),
    looks: Optional[int] = typer.Option(None, "--looks", help=_LOOKS_HELP),
) -> None:
    """Run one study: writes OUT/NAME.nc, OUT/NAME.png (+ .pdf) and OUT/NAME.json."""
    from . import studies

    try:
        _check_config(workers, scheduler, seed, looks)
        execution = _execution(backend, device, workers, scheduler)
        out_path = Path(out)
        if out_path.exists() and not out_path.is_dir():
            raise ParameterError("--out", "a directory", str(out))
        _stop_on_termination()
        path = studies.run_study(name, out_path, quick=quick, seed=seed, execution=execution, max_looks=looks)
    except ParameterError as e:
        _fail(str(_cli_name(e, {"out_dir": "--out"})), 2)  # another process writing to it
    except UndulateError as e:
        _fail(str(e), 1)
    typer.echo(f"wrote {path}")


@app.command()
def reproduce(
    out: Path = typer.Option(Path("reproduction"), "--out", "-o", help="Output folder (created if missing); re-running continues."),
    quick: bool = typer.Option(True, "--quick/--full", help="Quick mode (minutes) or the paper's full resolution."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Dask scheduler address tcp://HOST:PORT or scheduler-file path (default: local processes)."),
    seed: int = typer.Option(0, help="Base random seed (an integer >= 0)."),
    only: Optional[str] = typer.Option(None, "--only", help="Comma-separated study names (default: all)."),
    workers: Optional[int] = typer.Option(None, "--workers", help=_WORKERS_HELP),
    beyond_paper: bool = typer.Option(
        False, "--beyond-paper/--paper-only",
        help="Also run the studies beyond the paper (the PRX 2021 synchronization comparisons). "
             "Default: the paper's studies only."),
    backend: str = typer.Option("mujoco", "--backend", help=_BACKEND_HELP),
    device: Optional[str] = typer.Option(None, "--device", help=_DEVICE_HELP),
    animation_s: Optional[float] = typer.Option(
        None, "--animation-s", help="Simulated seconds of each animation, 0.2 to 600 (default: each its own, "
                                    "16-24 s). The studies and their claims do not depend on it."),
    looks: Optional[int] = typer.Option(None, "--looks", help=_LOOKS_HELP),
) -> None:
    """Reproduce the paper: every study, animations, and OUT/index.html."""
    from . import studies as registry
    from .reproduce import check_animation_s, reproduce as run_all

    try:
        _check_config(workers, scheduler, seed, looks)
        check_animation_s(animation_s, "--animation-s")
        execution = _execution(backend, device, workers, scheduler)
        if out.exists() and not out.is_dir():
            raise ParameterError("--out", "a directory", str(out))
        names = None
        if only is not None:
            names = [n.strip() for n in only.split(",") if n.strip()]
            if not names:
                raise ParameterError("--only", "one or more study names from: " + ", ".join(registry.names()), only)
            for n in names:
                if n not in registry.names():
                    raise ParameterError("--only", "study names from: " + ", ".join(registry.names()), n)
    except ParameterError as e:
        _fail(str(e), 2)
    _stop_on_termination()
    try:
        path, statuses = run_all(out, quick=quick, seed=seed, studies=names, log=lambda m: typer.echo(m),
                                 beyond_paper=beyond_paper, animation_s=animation_s, execution=execution,
                                 max_looks=looks)
    except ParameterError as e:  # another process writing to --out: refused before anything is written
        _fail(str(_cli_name(e, {"out_dir": "--out"})), 2)
    except SourceChangedError as e:
        _fail(str(e), 1)
    failed = [s["name"] for s in statuses if not s["ok"]]
    if failed:
        _fail(f"{len(failed)} stud{'y' if len(failed) == 1 else 'ies'} failed: {', '.join(failed)} (see {path})", 1)


from .robot.cli import robot_app  # noqa: E402 - `undulate robot run|ping` (the SDK loads only when a port opens)

app.add_typer(robot_app, name="robot")

from .track import cli as _track_cli  # noqa: E402 - `undulate track` and `undulate compare` (OpenCV loads when used)

app.command("track")(_track_cli.track)
app.command("compare")(_track_cli.compare)


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the app, turning click's usage errors into one line + exit 2.

    Ctrl-C exits 130 with one line, ``interrupted`` (``study`` and ``reproduce`` add that finished runs
    are saved and the same command resumes).

    A command ended by SIGTERM or SIGHUP exits ``128 + signal`` with one line, whatever exception its
    unwinding reached here as (typer's Exit(130), SystemExit, or the error of C code the signal
    interrupted: see :func:`undulate._signals.signalled`).  Ctrl-C is judged the same way: whatever
    exception it comes out as (:func:`undulate._signals.record_interrupts`), the command exits 130 with
    its one line."""
    import signal

    from . import _cliutil
    from ._signals import cancel_redeliveries, forget_unhandled_interrupt, interrupted, record_interrupts, signalled

    _no_mujoco_gl()
    before = signal.getsignal(signal.SIGINT)
    record_interrupts()
    try:
        rv = _run(argv)
        cancel_redeliveries()
        if rv == 0 and interrupted() and signalled() is None:  # Ctrl-C raised in a finalizer, and the
            # command ended before it was delivered again (record_interrupts)
            if not _cliutil._SAID:
                typer.echo(f"interrupted{_resumes(argv)}", err=True)
            return 130
    except BaseException:
        if signalled() is None and not interrupted():
            raise
        rv = None
        if signalled() is None:  # Ctrl-C, come out as another error
            if not _cliutil._SAID:
                typer.echo(f"interrupted{_resumes(argv)}", err=True)
            return 130
    finally:
        cancel_redeliveries()
        if signal.getsignal(signal.SIGINT) is not before:  # only the main thread's handler was changed
            signal.signal(signal.SIGINT, before)
        if interrupted():  # judged here: not an unhandled KeyboardInterrupt that ends the process by SIGINT
            forget_unhandled_interrupt()
    signum = signalled()
    if signum is not None:
        typer.echo(f"terminated ({signal.Signals(signum).name}){_resumes(argv)}", err=True)
        return 128 + signum
    return rv


def _no_mujoco_gl() -> None:
    """``MUJOCO_GL=disable`` for this command and the worker processes it starts, where the user has not
    chosen an OpenGL backend (:func:`undulate.execution.headless_mujoco`, which says why)."""
    from .execution import headless_mujoco

    headless_mujoco()


def _resumes(argv: list[str] | None) -> str:
    """What a stopped ``study`` or ``reproduce`` keeps, for the line that says it stopped."""
    words = sys.argv[1:] if argv is None else list(argv)
    return "; finished runs are saved: the same command resumes" if words[:1] in (["study"], ["reproduce"]) else ""


def _run(argv: list[str] | None) -> int:
    """The app under ``argv``, its outcome as an exit code."""
    from . import _cliutil
    from ._signals import signalled

    _cliutil._SAID.clear()
    try:
        rv = app(args=argv, standalone_mode=False)  # typer returns 130 for a KeyboardInterrupt in a command
    except typer.Exit as e:
        rv = e.exit_code
    except typer.Abort:  # end of input at a prompt
        if signalled() is None:
            typer.echo("aborted", err=True)
        return 130
    except KeyboardInterrupt:
        rv = 130
    except WriteError as e:  # a full disk or quota under any command: one line, nothing half-written left
        typer.echo(f"error: {e}{_resumes(argv)}", err=True)
        return 1
    except typer.TyperException as e:  # click usage errors: unparsable values, unknown options
        msg = e.format_message() if hasattr(e, "format_message") else str(e)
        if type(e).__name__ == "NoArgsIsHelpError":
            typer.echo(msg)
        else:
            typer.echo(f"error: {msg.splitlines()[0] if msg else e}", err=True)
        return getattr(e, "exit_code", 2)
    if rv == 130 and signalled() is None and not _cliutil._SAID:  # Ctrl-C; a termination says so in main
        typer.echo(f"interrupted{_resumes(argv)}", err=True)
    return rv if isinstance(rv, int) else 0


def _console() -> None:  # pragma: no cover - console script
    sys.exit(main())


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
