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
                                  ["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"]])
def test_workers_option_is_validated(tmp_path, command, args):
    out = tmp_path / "out"
    r = subprocess.run([*CLI, *command, "--out", str(out), *args], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "--workers" in lines[0]
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
