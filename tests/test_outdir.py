"""One process at a time writes an output folder (``undulate._outdir.writing_to``).

A second ``reproduce`` or ``study`` into a folder another process is writing stops at once: one line
naming ``--out`` and the process holding it, exit code 2, no traceback, nothing written.  Real
processes: the holder is a separate Python process, and a holder killed with SIGKILL frees the folder.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import pytest

from undulate._outdir import LOCK_NAME, writing_to
from undulate.errors import ParameterError

HOLDER = textwrap.dedent("""
    import sys, time
    from undulate._outdir import writing_to
    with writing_to(sys.argv[1]):
        print("held", flush=True)
        sys.stdin.read()  # until the test closes it
""")


@pytest.fixture
def held(tmp_path):
    """A folder another process is writing to; yields (folder, that process)."""
    folder = tmp_path / "repro"
    p = subprocess.Popen([sys.executable, "-c", HOLDER, str(folder)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                         text=True)
    assert p.stdout.readline().strip() == "held"
    yield folder, p
    if p.poll() is None:
        p.stdin.close()
        p.wait(timeout=30)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "undulate", *args], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "MPLBACKEND": "Agg"})


@pytest.mark.parametrize("command", [["reproduce", "--quick", "--only", "compatibility"], ["study", "compatibility"]])
def test_a_second_writer_stops_at_once_naming_the_folder_and_its_holder(held, command):
    folder, holder = held
    r = _cli(*command, "--out", str(folder))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr
    assert lines[0].startswith("error: invalid --out: must be a folder no other running reproduction or study is "
                               "writing to")
    assert f"process {holder.pid} is" in lines[0] and str(folder) in lines[0]
    assert sorted(p.name for p in folder.iterdir()) == [LOCK_NAME]  # nothing else written


def test_the_library_calls_refuse_too(held):
    from undulate.reproduce import reproduce
    from undulate.studies import run_study

    folder, _ = held
    with pytest.raises(ParameterError, match="invalid out_dir: must be a folder no other running"):
        reproduce(folder, studies=["compatibility"], log=lambda m: None)
    with pytest.raises(ParameterError, match="invalid out_dir"):
        run_study("compatibility", folder, quick=True, progress=False)
    assert sorted(p.name for p in folder.iterdir()) == [LOCK_NAME]


def test_a_killed_writer_frees_the_folder(held):
    folder, holder = held
    with pytest.raises(ParameterError):
        with writing_to(folder):
            pass
    holder.send_signal(signal.SIGKILL)
    holder.wait(timeout=30)
    assert (folder / LOCK_NAME).exists()  # a killed writer leaves its file, not its lock
    with writing_to(folder) as root:  # the kernel dropped the dead process's lock
        assert (root / LOCK_NAME).read_text().strip() == str(os.getpid())
    assert list(folder.iterdir()) == []  # released: the folder as it was


def test_one_process_may_hold_a_folder_from_several_threads_and_depths(tmp_path):
    folder = tmp_path / "out"
    errors = []

    def inner():
        try:
            with writing_to(folder), writing_to(folder):
                pass
        except Exception as e:  # noqa: BLE001
            errors.append(e)

    with writing_to(folder):
        threads = [threading.Thread(target=inner) for _ in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        # still held here after the threads' releases: another process is refused
        r = subprocess.run([sys.executable, "-c", HOLDER, str(folder)], input="", capture_output=True, text=True,
                           timeout=60)
        assert r.returncode != 0 and "no other running reproduction" in r.stderr
    assert not errors
    r = subprocess.run([sys.executable, "-c", HOLDER, str(folder)], input="", capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.strip() == "held"  # released once the last holder left
    assert list(folder.iterdir()) == []


def test_a_reproduction_leaves_no_lock_behind(tmp_path):
    r = _cli("reproduce", "--quick", "--only", "compatibility", "--animation-s", "0.3", "--out", str(tmp_path / "r"))
    assert r.returncode == 0, r.stderr
    assert not (tmp_path / "r" / LOCK_NAME).exists() and (tmp_path / "r" / "index.html").exists()


def test_racing_writers_never_both_hold_a_folder(tmp_path):
    """Eight processes taking and releasing one folder 40 times each: while one holds it no other does
    (each holder checks that it alone is in the folder's marker set), and every refusal is the one line."""
    script = textwrap.dedent("""
        import os, sys, time
        from pathlib import Path
        from undulate._outdir import writing_to
        from undulate.errors import ParameterError
        folder, won = Path(sys.argv[1]), 0
        for _ in range(40):
            try:
                with writing_to(folder):
                    mark = folder / f"holder-{os.getpid()}"
                    mark.touch()
                    others = [p.name for p in folder.glob("holder-*") if p != mark]
                    time.sleep(0.002)
                    mark.unlink()
                    assert not others, others
                    won += 1
            except ParameterError as e:
                assert "no other running reproduction or study" in str(e)
        print(won)
    """)
    folder = tmp_path / "contested"
    folder.mkdir()
    procs = [subprocess.Popen([sys.executable, "-c", script, str(folder)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for _ in range(8)]
    outs = [p.communicate(timeout=120) for p in procs]
    assert all(p.returncode == 0 for p in procs), [e for _, e in outs]
    assert sum(int(o) for o, _ in outs) > 0


def test_a_sweep_store_another_process_holds_is_refused(tmp_path):
    """The sweep stores take the same pid lock (``flock_pid``) on their ``.lock``: a sweep into a store
    another process holds is a ParameterError naming out_dir, and the holder's file is left as it was."""
    sys.path.insert(0, str(Path(__file__).parent))
    import sweep_funcs

    from undulate.sweep import Grid, run_sweep

    store = tmp_path / "s"
    store.mkdir()
    hold = textwrap.dedent("""
        import sys
        from pathlib import Path
        from undulate._outdir import flock_pid
        fd = flock_pid(Path(sys.argv[1]) / ".lock")
        print("held" if fd is not None else "refused", flush=True)
        sys.stdin.read()
    """)
    p = subprocess.Popen([sys.executable, "-c", hold, str(store)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                         text=True)
    try:
        assert p.stdout.readline().strip() == "held"
        grid = Grid(axes={"damping_Nms": [0.1], "length_m": [0.5]}, seed=0)
        with pytest.raises(ParameterError, match="invalid out_dir: must be a directory that no other running sweep"):
            run_sweep(sweep_funcs.pendulum, grid, store, workers=1, progress=False)
        assert (store / ".lock").read_text().strip() == str(p.pid)
    finally:
        p.stdin.close()
        p.wait(timeout=30)
