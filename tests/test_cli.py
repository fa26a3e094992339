"""The command line, run as a real subprocess: contract options, output, and bad input (each bad input
also through the entry point in this process)."""

from __future__ import annotations

import subprocess
import sys

import pytest
import xarray as xr

CLI = [sys.executable, "-m", "undulate.cli"]


def run(*args: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, cwd=cwd, timeout=300)


def test_simulate_writes_netcdf_with_contract_fields_and_prints_summary(tmp_path):
    out = tmp_path / "run.nc"
    r = run("simulate", "--phases", "0,90", "--links", "3", "--waves-per-body", "1", "--amplitude", "45",
            "--frequency", "0.5", "--channel-width", "0.13", "--dx0", "0", "--separating-force", "0",
            "--duration", "10", "--timestep", "0.002", "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "compatibility dx/lambda = +0.250" in r.stdout
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        assert ds["x"].dims == ("time", "swimmer") and ds["y"].dims == ("time", "swimmer")
        assert ds["x"].attrs["units"] == "m"
        assert ds.attrs["wavelength"] == pytest.approx(0.54)
        assert "mujoco_version" in "".join(ds.attrs)
        assert float(ds["time"][-1]) == pytest.approx(10.0)


def test_separating_force_pushes_the_second_swimmer_forward(tmp_path):
    out0, out1 = tmp_path / "a.nc", tmp_path / "b.nc"
    assert run("simulate", "--phases", "0,0", "--duration", "6", "--out", str(out0)).returncode == 0
    assert run("simulate", "--phases", "0,0", "--duration", "6", "--separating-force", "0.05",
               "--out", str(out1)).returncode == 0
    with xr.open_dataset(out0, engine="h5netcdf") as a, xr.open_dataset(out1, engine="h5netcdf") as b:
        dxa = float(a["x"][-1, 1] - a["x"][-1, 0])
        dxb = float(b["x"][-1, 1] - b["x"][-1, 0])
    assert dxb > dxa + 1e-3


BAD = [
    (["--phases", "0,abc"], "--phases"),
    (["--phases", "0,nan"], "--phases"),
    (["--phases", ""], "--phases"),
    (["--links", "1"], "--links"),
    (["--links", "abc"], "--links"),
    (["--amplitude", "0"], "--amplitude"),
    (["--amplitude", "120"], "--amplitude"),
    (["--frequency", "-1"], "--frequency"),
    (["--waves-per-body", "-0.5"], "--waves-per-body"),
    (["--channel-width", "0"], "--channel-width"),
    (["--channel-width", "0.02"], "--channel-width"),  # two 15 mm swimmers cannot fit
    (["--phases", "0,0,0,0,0,0,0,0,0"], "--channel-width"),
    (["--width", "-0.01"], "--width"),
    (["--body-length", "0"], "--body-length"),
    (["--duration", "0"], "--duration"),
    (["--duration", "-5"], "--duration"),
    (["--duration", "inf"], "--duration"),
    (["--timestep", "0.05"], "--timestep"),
    (["--timestep", "0"], "--timestep"),
    (["--dx0", "nan"], "--dx0"),
    (["--separating-force", "inf"], "--separating-force"),
    (["--controller", "cpg"], "--controller"),
    (["--controller", "phase-oscillator", "--coupling", "-1"], "--coupling"),
    (["--coupling", "2"], "--coupling"),  # coupling needs the phase oscillator
    (["--controller", "self-oscillating", "--control-rate", "0"], "--control-rate"),
]


BAD_IDS = [" ".join(a) for a, _ in BAD]


def _bad_args(args: list[str], folder) -> list[str]:
    dur = ["--duration", "1"] if "--duration" not in args else ["--quiet"]
    return ["simulate", *args, *dur, "--out", str(folder / "bad.nc")]


def _one_line_error(rc: int, err: str, param: str) -> None:
    assert rc == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error:") and param in lines[0]
    assert "Traceback" not in err


@pytest.mark.parametrize("args, param", BAD, ids=BAD_IDS)
def test_bad_input_one_line_exit_2_no_file(tmp_path, capfd, args, param):
    """The command's own entry point, in this process (stderr read at the file-descriptor level)."""
    from undulate.cli import main

    rc = main(_bad_args(args, tmp_path))
    _one_line_error(rc, capfd.readouterr().err, param)
    assert list(tmp_path.iterdir()) == []  # no output, no partial file


def test_bad_input_as_a_user_meets_it(tmp_path_factory):
    """A value error, an unparsable value and a non-finite one, each in a fresh process as a user runs
    the command: the same one line, exit code 2, nothing written."""
    from concurrent.futures import ThreadPoolExecutor

    cases = [c for c in BAD if " ".join(c[0]) in ("--phases 0,abc", "--links abc", "--duration inf")]
    assert len(cases) == 3
    folders = [tmp_path_factory.mktemp("bad") for _ in cases]
    with ThreadPoolExecutor(len(cases)) as pool:
        done = list(pool.map(lambda c, f: run(*_bad_args(c[0], f)), cases, folders))
    for (_, param), r, folder in zip(cases, done, folders):
        _one_line_error(r.returncode, r.stderr, param)
        assert list(folder.iterdir()) == []


def test_unwritable_output_path(tmp_path):
    r = run("simulate", "--duration", "1", "--out", str(tmp_path / "missing" / "run.nc"))
    assert r.returncode == 2 and "--out" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = run("simulate", "--duration", "1", "--out", str(tmp_path))
    assert r.returncode == 2 and "--out" in r.stderr


def test_cli_simulates_a_lone_swimmer(tmp_path):
    from typer.testing import CliRunner

    from undulate.cli import app

    res = CliRunner().invoke(app, ["simulate", "--phases", "0", "--duration", "2", "--out", str(tmp_path / "one.nc")])
    assert res.exit_code == 0, res.output
    assert "one swimmer" in res.output


def test_closed_loop_controller_from_the_command_line(tmp_path):
    out = tmp_path / "cl.nc"
    r = run("simulate", "--phases", "0,60", "--controller", "phase-oscillator", "--coupling", "1.0",
            "--control-rate", "100", "--hold-x", "--duration", "4", "--out", str(out))
    assert r.returncode == 0, r.stderr
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        assert ds["gait_phase"].dims == ("time", "swimmer") and ds["gait_phase"].attrs["units"] == "rad"
        assert ds.attrs["controller"] == "phase-oscillator" and ds.attrs["control_rate"] == pytest.approx(100.0)
        mid = 0.5 * (ds["node_x"].isel(node=1) + ds["node_x"].isel(node=2))
        assert float(abs(mid - mid.isel(time=0)).max()) < 1e-9  # --hold-x
        # load feedback changed the phases' rates away from the open-loop 2 pi f
        rate = (ds["gait_phase"].isel(time=-1) - ds["gait_phase"].isel(time=0)) / float(ds["time"][-1])
        assert float(abs(rate - 3.14159265).max()) > 1e-3


def test_option_defaults_come_from_the_parameter_types():
    import inspect
    import math

    from undulate import cli
    from undulate.params import Channel, ControllerParams, Gait, SimOptions, SwimmerGeometry

    d = {k: v.default.default for k, v in inspect.signature(cli.simulate).parameters.items()}
    assert d["links"] == SwimmerGeometry().n_links and d["body_length"] == SwimmerGeometry().length_m
    assert d["width"] == SwimmerGeometry().width_m and d["channel_width"] == Channel().width_m
    assert math.radians(d["amplitude"]) == pytest.approx(Gait().amplitude_rad)
    assert d["waves_per_body"] == Gait().waves_per_body and d["frequency"] == Gait().frequency_hz
    assert d["duration"] == SimOptions().duration_s and d["sample_rate"] == SimOptions().sample_rate_hz
    assert d["controller"] == ControllerParams().kind and d["control_rate"] == ControllerParams().control_rate_hz


def _help_texts(command, path=("undulate",)):
    """(where, text) for the help of ``command``, its options and arguments and every sub-command."""
    yield " ".join(path), command.help or ""
    for p in command.params:
        yield f"{' '.join(path)} {p.name}", getattr(p, "help", None) or ""
    for name, sub in getattr(command, "commands", {}).items():  # a group: every sub-command
        yield from _help_texts(sub, (*path, name))


def test_every_help_text_survives_the_rich_markup_typer_renders_it_with():
    """Typer reads help as Rich markup, so an unescaped ``[gpu]`` in ``pip install 'undulate[gpu]'`` vanished
    from ``--help``.  Every command's and option's help must render to exactly its text (``\\[`` being the
    escape for a literal bracket)."""
    import typer
    from rich.text import Text
    from typer.testing import CliRunner

    from undulate.cli import app

    assert app.rich_markup_mode == "rich"  # if this changes, so does what the check below must compare
    texts = list(_help_texts(typer.main.get_command(app)))
    assert {"undulate reproduce backend", "undulate robot run ids", "undulate track video"} <= {w for w, _ in texts}
    eaten = {w: t for w, t in texts if Text.from_markup(t).plain != t.replace("\\[", "[")}
    assert not eaten, eaten
    assert any("\\[gpu]" in t for _, t in texts)  # the one that was eaten
    shown = CliRunner().invoke(app, ["reproduce", "--help"], env={"COLUMNS": "200"}, terminal_width=200).output
    assert "pip install 'undulate[gpu]'" in shown, shown


def test_python_dash_m_undulate_lists_the_studies_in_one_column():
    """``python -m undulate`` is the command line; ``studies`` starts every description in one column
    (the longest name sets it)."""
    from undulate import studies

    out = subprocess.run([sys.executable, "-m", "undulate", "studies"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    names = studies.names()
    assert [ln.split()[0] for ln in lines] == names
    starts = {ln.index(studies.describe(n).description[:20]) for ln, n in zip(lines, names)}
    assert starts == {max(map(len, names)) + 2}
    bad = subprocess.run([sys.executable, "-m", "undulate", "simulate", "--duration", "-1"], capture_output=True,
                         text=True, timeout=120)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "--duration" in bad.stderr
