"""User-facing inputs are validated: one line naming the parameter and what is allowed,
exit code 2, no traceback, no partial output (``--workers`` of ``study`` and
``reproduce``; :class:`undulate.studies.StudyConfig`), and the options are consistent across
commands (every quick mode is the same ``--quick/--full`` pair, quick by default)."""

from __future__ import annotations

import subprocess
import sys

import pytest

CLI = [sys.executable, "-m", "undulate.cli"]


@pytest.mark.parametrize("command", [["study", "pairs", "--quick"], ["reproduce", "--quick"]])
@pytest.mark.parametrize("args", [["--workers", "0"], ["--workers", "-2"], ["--workers", "two"],
                                  ["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], ["--seed", "-1"],
                                  ["--workers", "100000"], ["--scheduler", "notaurl"],
                                  ["--scheduler", "/no/such/scheduler.json"], ["--looks", "0"], ["--looks", "two"]])
def test_workers_and_seed_options_are_validated(tmp_path, command, args):
    """Before anything is written: a negative seed once made every study of a reproduction fail after a
    page of work (exit 1), and a study leave an empty folder; a malformed scheduler once failed the first
    study that swept, after the others had written; ``--workers 100000`` would have started a process a run."""
    out = tmp_path / "out"
    r = subprocess.run([*CLI, *command, "--out", str(out), *args], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].lower().startswith("error: invalid") and args[0] in lines[0], lines
    assert not out.exists()


def test_study_config_rejects_bad_workers(tmp_path):
    from undulate.errors import ParameterError
    from undulate.studies import StudyConfig

    for bad in (0, -1, 1.5, True):
        with pytest.raises(ParameterError, match="workers"):
            StudyConfig(out_dir=tmp_path, workers=bad)
    with pytest.raises(ParameterError, match="workers"):
        StudyConfig(out_dir=tmp_path, workers=2, scheduler="tcp://x:1")
    assert StudyConfig(out_dir=tmp_path, workers=3).workers == 3
    for bad in (-1, 1.5, True, "0", None):
        with pytest.raises(ParameterError, match="seed"):
            StudyConfig(out_dir=tmp_path, seed=bad)
    import numpy as np

    seed = StudyConfig(out_dir=tmp_path, seed=np.int64(7)).seed
    assert seed == 7 and type(seed) is int
    for bad in ("yes", 1, 0.5, None):  # bool("no") is True: a mode is asked for, not guessed
        with pytest.raises(ParameterError, match="invalid quick: must be True or False"):
            StudyConfig(out_dir=tmp_path, quick=bad)
    assert StudyConfig(out_dir=str(tmp_path), quick=np.bool_(True)).quick is True
    for bad in (None, 3, b"/tmp"):
        with pytest.raises(ParameterError, match="invalid out_dir: must be a folder's path"):
            StudyConfig(out_dir=bad)


def test_the_python_entry_points_refuse_what_is_not_their_type(tmp_path):
    """simulate, simulate_batch, build, make_controller, animate, run_study and reproduce name the argument of the wrong
    type (an AttributeError from deep inside, or a study run as quick for quick="no", came before), and
    nothing is written."""
    import importlib

    import undulate
    from undulate import Scene, SimOptions
    from undulate.control import make_controller
    from undulate.errors import ParameterError
    from undulate.reproduce import reproduce

    importlib.import_module("undulate.animation")  # its module imported first: the package's animate stays the function
    calls = [
        (lambda: undulate.simulate(None), "invalid scene: must be a Scene (got 'NoneType')"),
        (lambda: undulate.simulate(Scene(), {"duration_s": 1.0}), "invalid options: must be a SimOptions or None"),
        (lambda: undulate.simulate_batch(Scene()), "invalid scenes: must be a non-empty sequence of Scene (got 'Scene')"),
        (lambda: undulate.simulate_batch([Scene(), "pair"], SimOptions(duration_s=1.0)), "an item of type str"),
        (lambda: undulate.build(None), "invalid scene: must be a Scene"),
        (lambda: make_controller(None), "invalid scene: must be a Scene"),
        (lambda: make_controller(Scene(), "relay"), "invalid params: must be a ControllerParams or None"),
        (lambda: undulate.animate({"x": 1}, tmp_path / "a.gif"), "invalid run file: must be a run"),
        (lambda: undulate.run_study("pairs", None), "invalid out_dir"),
        (lambda: undulate.run_study("pairs", tmp_path / "s", quick="no"), "invalid quick: must be True or False"),
        (lambda: undulate.run_study("pairs", tmp_path / "s", progress="no"), "invalid progress: must be True or False"),
        (lambda: reproduce(tmp_path / "r", quick="yes"), "invalid quick: must be True or False"),
    ]
    for call, message in calls:
        with pytest.raises(ParameterError) as err:
            call()
        assert message in str(err.value), str(err.value)
    assert list(tmp_path.iterdir()) == []


def test_a_bad_seed_is_refused_before_a_study_or_reproduction_writes(tmp_path):
    from undulate.errors import ParameterError
    from undulate.reproduce import reproduce
    from undulate.studies import run_study

    with pytest.raises(ParameterError, match="seed"):
        run_study("compatibility", tmp_path / "s", seed=-3)
    with pytest.raises(ParameterError, match="seed"):
        reproduce(tmp_path / "r", seed=2.5, studies=["compatibility"])
    assert list(tmp_path.iterdir()) == []


def _commands(cmd, path=()):
    """Every leaf command of the click tree, with its path (``("robot", "run")``).  Duck-typed:
    typer >= 0.20 builds on its own copy of click."""
    if hasattr(cmd, "commands"):
        for name, sub in cmd.commands.items():
            yield from _commands(sub, (*path, name))
    else:
        yield path, cmd


def test_every_quick_mode_option_is_the_same_quick_full_pair_defaulting_to_quick():
    import typer

    from undulate.cli import app

    commands = dict(_commands(typer.main.get_command(app)))
    assert ("study",) in commands and ("reproduce",) in commands and ("robot", "run") in commands
    found = []
    for path, cmd in commands.items():
        for p in cmd.params:
            names = {o.lstrip("-") for o in (*p.opts, *p.secondary_opts)} | {p.name}
            if not names & {"quick", "full"}:
                continue
            found.append(path)
            assert p.param_type_name == "option" and p.name == "quick", (path, p.name)
            assert p.opts == ["--quick"] and p.secondary_opts == ["--full"], (path, p.opts, p.secondary_opts)
            assert p.default is True, (path, p.default)
    assert sorted(found) == [("reproduce",), ("study",)]


@pytest.mark.parametrize("args, option", [
    (["--sample-rate", "1e9"], "--sample-rate"),  # against the scene's automatic step, found once the scene is known
    (["--sample-rate", "1e9", "--estimate"], "--sample-rate"),
    (["--links", "12", "--sample-rate", "5000"], "--sample-rate"),
    (["--sample-rate", "600", "--timestep", "0.002"], "--sample-rate"),
    (["--timestep", "0.01"], "--timestep"),
    (["--duration", "1e-5", "--timestep", "0.002"], "--duration"),
    (["--channel-width", "0.02"], "--channel-width"),
    (["--dx0", "nan"], "--dx0"),
    (["--dx0", "1e20"], "--dx0"),  # was run, and stopped as diverged blaming the time step
    (["--amplitude", "95"], "--amplitude"),
    (["--width", "-0.01"], "--width"),
    (["--body-length", "0"], "--body-length"),
    (["--phases", "0,90", "--separating-force", "inf"], "--separating-force"),
    (["--coupling", "-1", "--controller", "phase-oscillator"], "--coupling"),
    (["--control-rate", "0", "--controller", "relay"], "--control-rate"),
    (["--backend", "gpu"], "--backend"),
])
def test_simulate_errors_name_the_option_typed(tmp_path, args, option):
    """Whatever raises it (the options, the scene, or the run once the scene's time step is known), a bad
    ``simulate`` input is one line naming the option as typed, exit code 2, and no file."""
    from typer.testing import CliRunner

    from undulate.cli import app

    out = tmp_path / "run.nc"
    r = CliRunner().invoke(app, ["simulate", "--duration", "0.2", *args, "--out", str(out)])
    err = r.stderr if hasattr(r, "stderr") and r.stderr else r.output
    lines = err.strip().splitlines()
    assert r.exit_code == 2, (args, r.output)
    assert len(lines) == 1 and lines[0].startswith(f"error: invalid {option}"), (args, lines)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args, names", [
    (["--width", "1e-12"], "--width"),  # MuJoCo's compiler refused the link's inertia: a traceback
    (["--timestep", "1e-300"], "--sample-rate / --timestep"),  # a sample interval of 5e298 steps: numpy's traceback
    (["--body-length", "1e20"], "--sample-rate / --timestep"),  # its automatic step, 5e-24 s, likewise
    (["--body-length", "1e300"], "--body-length"),  # a link's moment of inertia overflowed: NaN to int
])
def test_simulate_refuses_what_once_raised_a_traceback(tmp_path, args, names):
    """Inputs that passed every check and then failed inside MuJoCo or numpy (found by a sweep of
    extreme values over every ``simulate`` option) are one line naming the option, exit 2, no file."""
    out = tmp_path / "run.nc"
    r = subprocess.run([*CLI, "simulate", "--phases", "0,90", "--duration", "0.5", *args, "--out", str(out)],
                       capture_output=True, text=True, timeout=120)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert len(lines) == 1 and lines[0].startswith("error: invalid") and names in lines[0], lines
    assert "Traceback" not in r.stderr and not out.exists()


def test_a_geometry_is_accepted_exactly_when_mujoco_compiles_it():
    """:class:`SwimmerGeometry` applies MuJoCo's rules for a moving body's inertia (mass and moments at
    least mjMINVAL, any two moments at least the third in floating point): over geometries spanning
    twelve decades of width, height and mass, it refuses exactly those whose swimmer does not compile."""
    import numpy as np

    from undulate import Channel, Scene
    from undulate.errors import ParameterError
    from undulate.params import SwimmerGeometry
    from undulate.scene import swimmer_spec

    rng = np.random.default_rng(3)
    seen = {"accepted": 0, "refused": 0}
    for _ in range(400):
        n = int(rng.integers(2, 65))
        L = 10 ** rng.uniform(-4, 3)
        kw = dict(n_links=n, length_m=L, width_m=L / n * 10 ** rng.uniform(-12, -0.01),
                  height_m=L / n * 10 ** rng.uniform(-12, 1), mass_kg=10 ** rng.uniform(-14, 3))
        try:
            g = SwimmerGeometry(**kw)
            accepted = True
        except ParameterError as e:
            assert e.name in ("width_m", "height_m", "mass_kg / length_m / width_m / height_m"), e
            accepted = False
            with pytest.MonkeyPatch.context() as mp:  # the same geometry, unchecked, to ask MuJoCo
                mp.setattr(SwimmerGeometry, "_check_inertia", lambda self: None)
                g = SwimmerGeometry(**kw)
        channel = Channel(width_m=2 * L + 3 * g.width_m, length_m=max(1.0, 2 * L))
        try:
            swimmer_spec(Scene(phases_rad=(0.0,), geometry=g, channel=channel), 1e-3).compile()
            compiles = True
        except ValueError:
            compiles = False
        assert accepted == compiles, kw
        seen["accepted" if accepted else "refused"] += 1
    assert min(seen.values()) > 50, seen  # both sides of the rule were visited


def test_python_parameters_refuse_wrong_types():
    """From Python too, a wrong type is a ParameterError naming the field (a sweep of odd values over every
    field found these raising TypeError, AttributeError or OverflowError, or storing the string "1" or
    True where a number belongs, to fail later inside MuJoCo)."""
    import numpy as np

    import undulate.params as P
    from undulate.errors import ParameterError

    cases = [(P.Channel, "width_m", "1"), (P.Servo, "kp_Nm_per_rad", "10"), (P.Gait, "frequency_hz", True),
             (P.SimOptions, "duration_s", "30"), (P.ContactModel, "dampratio", np.bool_(True)),
             (P.Servo, "back_emf", "no"), (P.SwimmerGeometry, "n_links", float("inf")),
             (P.SwimmerGeometry, "collision_segments", True), (P.SimOptions, "chunk_steps", None),
             (P.SimOptions, "chunk_steps", "x"), (P.SimOptions, "record", 3)]
    for kind, name, value in cases:
        with pytest.raises(ParameterError, match=f"invalid {name}"):
            kind(**{name: value})
    for name in ("gait", "geometry", "servo", "ground", "channel", "contact", "controller"):
        with pytest.raises(ParameterError, match=f"invalid {name}: must be a "):
            P.Scene(**{name: None})
    for name, value in [("phases_rad", "0,90"), ("phases_rad", (0.0, "a")), ("phases_rad", ((0.0,), (1.0,))),
                        ("phases_rad", None), ("dx0_m", None), ("dx0_m", "0.1"), ("dx0_m", True),
                        ("dx0_m", (0.1, 0.2)), ("forces_N", 1.0), ("forces_N", (1.0, "2"))]:
        with pytest.raises(ParameterError, match=f"invalid {name}"):
            P.Scene(**{"phases_rad": (0.0, 1.0), name: value})
    s = P.Scene(phases_rad=np.array([0, 1]), dx0_m=np.float32(0.25), forces_N=[1, np.float64(-1)])
    assert s.phases_rad == (0.0, 1.0) and s.dx0_m == (0.25,) and s.forces_N == (1.0, -1.0)
    assert all(type(v) is float for v in (*s.phases_rad, *s.dx0_m, *s.forces_N))


@pytest.mark.parametrize("command", [["study", "compatibility"], ["reproduce", "--only", "compatibility"]])
def test_an_out_folder_that_cannot_be_made_is_one_line(tmp_path, command):
    """A folder under a file, or on a pseudo file system, was a FileNotFoundError traceback."""
    (tmp_path / "a_file").write_text("")
    for out in (tmp_path / "a_file" / "sub", "/proc/undulate-out"):
        r = subprocess.run([*CLI, *command, "--out", str(out)], capture_output=True, text=True, timeout=120)
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1, (out, r.stderr)
        assert lines[0].startswith("error: invalid --out: must be a folder that can be created"), lines


def test_reproduce_only_needs_a_study_name(tmp_path):
    """``--only ""`` or ``--only ,`` ran a reproduction of nothing and wrote its page."""
    for only in ("", ",", " , "):
        r = subprocess.run([*CLI, "reproduce", "--only", only, "--out", str(tmp_path / "r")], capture_output=True,
                           text=True, timeout=120)
        assert r.returncode == 2 and "invalid --only: must be one or more study names" in r.stderr, r.stderr
    assert not (tmp_path / "r").exists()
