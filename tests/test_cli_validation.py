"""User-facing inputs are validated: one line naming the parameter and what is allowed,
exit code 2, no traceback, no partial output (``--workers`` of ``study`` and
``reproduce``; :class:`undulate.studies.StudyConfig`)."""

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
