"""A study or reproduction ended by a signal leaves no process behind (``undulate.sweep._worker.
init_local_worker``, ``undulate.cli._stop_on_termination``): real processes, real signals.

Found by terminating a reproduction with ``kill PID`` (SIGTERM to it alone, as a script or a scheduler
may): its two pool processes went on for minutes, writing runs into the folder, then waited forever."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
import xarray as xr

pytestmark = pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads process states from /proc")


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, exited but not yet reaped by whoever adopted it, does not)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False
    return state not in ("Z", "X")


def _session(pid: int) -> list[int]:
    """Every running process of the session led by ``pid`` (the command and its workers)."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (FileNotFoundError, ProcessLookupError):
            continue
        if int(fields[3]) == pid and fields[0] not in ("Z", "X"):  # fields[3]: the session id
            out.append(int(stat.parent.name))
    return out


def _gone_within(pids, seconds: float) -> list[int]:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        left = [p for p in pids if _alive(p)]
        if not left:
            return []
        time.sleep(0.1)
    return [p for p in pids if _alive(p)]


_PARENT = """
import multiprocessing, sys, time
from undulate.sweep import _executors
if __name__ == "__main__":
    pool = _executors._new_pool(multiprocessing.get_context("spawn"), 2)
    futures = [pool.submit(time.sleep, 120) for _ in range(2)]
    while len(pool._processes) < 2 or not all(p.is_alive() for p in pool._processes.values()):
        time.sleep(0.05)
    time.sleep(1.0)  # both busy in their task
    print(" ".join(str(p) for p in pool._processes), flush=True)
    time.sleep(300)
"""


def test_pool_processes_end_when_their_parent_is_killed():
    """SIGKILL to the parent alone (no handler can run): its busy workers end within a few polls."""
    proc = subprocess.Popen([sys.executable, "-c", textwrap.dedent(_PARENT)], stdout=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        workers = [int(p) for p in proc.stdout.readline().split()]
        assert len(workers) == 2 and all(_alive(p) for p in workers)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
        assert _gone_within(workers, 10) == []
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


@contextlib.contextmanager
def _study_mid_sweep(out: Path, start):
    """``undulate study pairs --quick`` on 2 pool processes, started with ``start`` as its preexec, once
    its workers are busy in the sweep and a run is saved: (the process, its lines so far, the sweep's
    run store, the pool processes); its process group killed at the end."""
    cmd = [sys.executable, "-m", "undulate.cli", "study", "pairs", "--quick", "--workers", "2", "--out", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
                            preexec_fn=start)
    try:
        lines, deadline = [], time.monotonic() + 180
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
            if "sim-quick-seed0" in line and "to compute on 2 local processes" in line:
                break
        assert proc.poll() is None, "".join(lines)
        store = out / ".sweeps" / "pairs" / "sim-quick-seed0" / "runs"
        while time.monotonic() < deadline and not list(store.glob("*.nc")):  # the workers busy in the sweep
            time.sleep(0.05)
        workers = [p for p in _session(proc.pid) if p != proc.pid]
        assert workers, "".join(lines)
        yield proc, lines, store, workers
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def test_sigterm_stops_a_study_and_its_workers_and_sighup_ignored_stays_ignored(tmp_path):
    """``kill PID`` mid-sweep: the command exits 143 within seconds saying what happened, the sweep says
    how to resume, finished runs are saved whole (a run cut short is at most a temporary file, which the
    store clears when next opened), and no process of it is left.  A SIGHUP it was started
    ignoring (``nohup``) does not end it."""
    def start():  # SIGHUP ignored, as under nohup; SIGTERM as a plain process has it
        signal.signal(signal.SIGHUP, signal.SIG_IGN)

    with _study_mid_sweep(tmp_path / "s", start) as (proc, lines, store, workers):
        os.kill(proc.pid, signal.SIGHUP)
        time.sleep(0.5)
        assert proc.poll() is None  # ignored
        t0 = time.monotonic()
        os.kill(proc.pid, signal.SIGTERM)  # to the command alone, not its process group
        rest, _ = proc.communicate(timeout=60)
        assert proc.returncode == 143, "".join(lines) + rest
        assert time.monotonic() - t0 < 30
        assert "sweep interrupted" in rest and "run the same sweep again to resume" in rest
        assert rest.rstrip().splitlines()[-1] == ("terminated (SIGTERM); finished runs are saved: "
                                                  "the same command resumes")
        assert _gone_within(workers, 10) == []
        assert _session(proc.pid) == []
        finished = list(store.glob("*.nc"))
        assert finished, "finished runs are kept"
        for run in finished:  # each whole (a run cut by its worker's stop is a temporary the store clears)
            xr.load_dataset(run)


def test_ctrl_c_stops_a_study_and_its_workers_with_one_line(tmp_path):
    """Ctrl-C at a terminal (SIGINT to the whole foreground process group: the command and its pool
    processes): exit 130, the sweep says how many runs are saved, the last line says what happened and
    that the same command resumes (until 2026-12-02 typer ended it with 130 and no line), and no process
    of it is left."""
    def start():  # Python's own Ctrl-C handler, whatever this test process inherited (a background shell
        signal.signal(signal.SIGINT, signal.SIG_DFL)  # starts SIGINT ignored, and Python then keeps it so)

    with _study_mid_sweep(tmp_path / "s", start) as (proc, lines, store, workers):
        os.killpg(proc.pid, signal.SIGINT)  # as a terminal sends it
        rest, _ = proc.communicate(timeout=60)
        assert proc.returncode == 130, "".join(lines) + rest
        assert "sweep interrupted" in rest and "Traceback" not in rest, rest
        assert rest.rstrip().splitlines()[-1] == "interrupted; finished runs are saved: the same command resumes"
        assert _gone_within(workers, 10) == []
        assert list(store.glob("*.nc")), "finished runs are kept"


_CTRL_C_AS_ANOTHER_ERROR = """
import os, signal, sys
signal.signal(signal.SIGINT, signal.default_int_handler)  # a background job's shell starts it ignored
from undulate import cli
from undulate import execution

def usable_cpus():  # imports MuJoCo: Ctrl-C there came out of pybind11 as its ImportError
    try:
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(10**6):
            pass
    except KeyboardInterrupt:
        raise ImportError("initialization failed") from None
    return 1

execution.usable_cpus = usable_cpus
sys.exit(cli.main(["study", "pairs", "--quick", "--workers", "1", "--out", sys.argv[1]]))
"""


def test_ctrl_c_that_c_code_turns_into_another_error_still_ends_with_one_line(tmp_path):
    """Ctrl-C early in ``study`` (found sending it at random times in a study's first 8 s: once in 30,
    as MuJoCo's module imported) landed inside C code that calls back into Python, and came out as
    that code's error: pybind11's "ImportError: initialization failed", a traceback, exit 1.  The
    entry point judges the command by the Ctrl-C it received, whatever error it came out as: exit 130,
    one line, nothing written."""
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-c", _CTRL_C_AS_ANOTHER_ERROR, str(out)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 130, r.stderr
    assert r.stderr.strip() == "interrupted; finished runs are saved: the same command resumes", r.stderr
    assert not out.exists()


_GLFW_PROBE = """
import multiprocessing, os, sys
probes = []
sys.addaudithook(lambda event, args: probes.append(args) if event == "subprocess.Popen" and
                 any("glfwGetVersion" in str(a) for a in args[1]) else None)
from undulate import cli
from undulate.sweep import _executors
if __name__ == "__main__":
    rc = cli.main(["simulate", "--duration", "0.05", "-q", "--out", sys.argv[1]])
    pool = _executors._new_pool(multiprocessing.get_context("spawn"), 1)  # a worker it would start
    in_worker = pool.submit(eval, "__import__('mujoco') and 'glfw' in __import__('sys').modules").result()
    pool.shutdown()
    print(rc, len(probes), "glfw" in sys.modules, in_worker)
"""


def test_commands_and_their_workers_start_no_glfw_probe(tmp_path):
    """``import mujoco`` with ``MUJOCO_GL`` unset loads glfw, whose library search runs a ``python -c``
    child reading stdin and printing on stdout, its stderr the command's: Ctrl-C to a study while a
    worker imported MuJoCo left that child's "File "<string>", line 36: BrokenPipeError" after the
    command's last line (in CI; line 28, EOFError, here).  No command draws with MuJoCo's OpenGL, so
    the commands and the workers they start never load glfw."""
    r = subprocess.run([sys.executable, "-c", _GLFW_PROBE, str(tmp_path / "run.nc")], capture_output=True,
                       text=True, timeout=120, env={k: v for k, v in os.environ.items() if k != "MUJOCO_GL"})
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["0", "0", "False", "False"], r.stdout + r.stderr


def test_a_users_mujoco_gl_is_kept(monkeypatch):
    from undulate import cli

    monkeypatch.setenv("MUJOCO_GL", "egl")
    cli._no_mujoco_gl()
    assert os.environ["MUJOCO_GL"] == "egl"
    monkeypatch.delenv("MUJOCO_GL")
    cli._no_mujoco_gl()
    assert os.environ["MUJOCO_GL"] == "disable"


def test_ctrl_c_ends_simulate_with_one_line_and_no_file(tmp_path):
    out = tmp_path / "run.nc"
    proc = subprocess.Popen([sys.executable, "-m", "undulate.cli", "simulate", "--duration", "3000", "-q",
                             "--out", str(out)], stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None and not list(tmp_path.glob(".*.tmp*")):
            time.sleep(0.05)
        assert proc.poll() is None, proc.stderr.read()
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 130, err
        assert err.strip() == "interrupted", err
        assert list(tmp_path.iterdir()) == []
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_a_terminated_simulate_leaves_no_file(tmp_path, sig):
    """``undulate simulate`` ended by SIGTERM or SIGHUP mid-run: exit 128 + signal, and neither the output
    nor its temporary file is left.

    Both signals start at their defaults in the command, whatever this test process inherited: run under
    ``nohup``, SIGHUP comes ignored, so the command rightly ignored it and ran to its end with exit 0 (once
    taken for a lost signal seen "under load": the suite was then run with ``nohup``)."""
    out = tmp_path / "run.nc"

    def start():
        for s in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(s, signal.SIG_DFL)

    proc = subprocess.Popen([sys.executable, "-m", "undulate.cli", "simulate", "--duration", "3000", "-q",
                             "--out", str(out)], stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=start)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None and not list(tmp_path.glob(".*.tmp*")):
            time.sleep(0.05)
        assert proc.poll() is None, proc.stderr.read()
        os.kill(proc.pid, sig)
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 128 + sig, err
        assert "Traceback" not in err
        assert list(tmp_path.iterdir()) == []
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


_IN_A_FINALIZER = """
import os, signal, sys, time
from undulate._cliutil import unwind_on_signals

class Stop(SystemExit):
    def __init__(self, signum):
        self.signum = signum
        super().__init__(100 + signum)

unwind_on_signals((signal.SIGTERM,), Stop)

class Finalized:
    def __del__(self):
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(200000):
            pass  # the handler runs here, inside the finalizer, where Python drops what it raises

x = Finalized()
del x
for _ in range(200):
    time.sleep(0.01)
print("went on")
"""


def test_a_signal_that_lands_in_a_finalizer_still_ends_the_command():
    """Python drops an exception raised in a finalizer ("Exception ignored"): a SIGTERM handled there
    was lost, and a terminated ``simulate`` ran on to exit 0 (seen on Python 3.13).  The signal is
    delivered again once the finalizer has returned."""
    r = subprocess.run([sys.executable, "-c", textwrap.dedent(_IN_A_FINALIZER)], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 100 + signal.SIGTERM and "went on" not in r.stdout, (r.stdout, r.stderr)
    assert "Exception ignored" not in r.stderr


_CTRL_C_IN_A_FINALIZER = """
import os, signal, sys, time
from undulate._signals import record_interrupts

signal.signal(signal.SIGINT, signal.default_int_handler)  # a background job's shell starts it ignored
record_interrupts()

class Finalized:
    def __del__(self):
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(200000):
            pass  # the handler runs here, inside the finalizer, where Python drops what it raises

try:
    x = Finalized()
    del x
    for _ in range(200):
        time.sleep(0.01)
    print("went on")
except KeyboardInterrupt:
    sys.exit(130)
"""

_CTRL_C_IN_A_FINALIZER_AS_THE_COMMAND_ENDS = """
import os, signal, sys
from undulate import cli

signal.signal(signal.SIGINT, signal.default_int_handler)  # a background job's shell starts it ignored

class Finalized:
    def __del__(self):
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(200000):
            pass

def run(argv):  # a command whose last step runs a finalizer that Ctrl-C lands in
    x = Finalized()
    del x
    return 0

cli._run = run
rv = cli.main(["simulate"])
print("handler put back:", signal.getsignal(signal.SIGINT) is signal.default_int_handler)
sys.exit(rv)
"""


def test_a_ctrl_c_that_lands_in_a_finalizer_still_stops_the_command():
    """Ctrl-C to ``simulate`` landed in a ``WeakValueDictionary`` callback: Python printed "Exception
    ignored ... KeyboardInterrupt", dropped it, and the command ran on to exit 0 with its file (seen
    once in a full test run).  It is delivered again once the finalizer has returned."""
    r = subprocess.run([sys.executable, "-c", textwrap.dedent(_CTRL_C_IN_A_FINALIZER)], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 130 and "went on" not in r.stdout, (r.stdout, r.stderr)
    assert "Exception ignored" not in r.stderr, r.stderr


def test_a_ctrl_c_dropped_as_the_command_ends_still_ends_it_with_one_line():
    """The command's last step ran the finalizer Ctrl-C landed in, before it could be delivered again:
    exit 130 and ``interrupted``, not 0, and no delivery after the entry point put Python's handler
    back (a KeyboardInterrupt traceback wherever the process then was)."""
    r = subprocess.run([sys.executable, "-c", textwrap.dedent(_CTRL_C_IN_A_FINALIZER_AS_THE_COMMAND_ENDS)],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 130, (r.stdout, r.stderr)
    assert r.stderr.strip().splitlines() == ["interrupted"], r.stderr
    assert "handler put back: True" in r.stdout


def test_a_terminated_animation_stops_ffmpeg_and_leaves_no_file(tmp_path):
    """``undulate animate`` ended by SIGTERM while ffmpeg writes the mp4: exit 143, the half-written
    temporary removed, and ffmpeg ended (before: killed outright, the temporary left for good)."""
    from undulate import Scene, SimOptions, simulate

    run = tmp_path / "run.nc"
    simulate(Scene(phases_rad=(0.0, 1.0)), SimOptions(duration_s=60.0), out=run)
    film = tmp_path / "film"
    film.mkdir()

    def start():
        signal.signal(signal.SIGTERM, signal.SIG_DFL)

    proc = subprocess.Popen([sys.executable, "-m", "undulate.cli", "animate", str(run), "-o", str(film / "run.mp4")],
                            stderr=subprocess.PIPE, text=True, start_new_session=True, preexec_fn=start)
    try:
        deadline, helpers = time.monotonic() + 120, []
        while time.monotonic() < deadline and proc.poll() is None and not (list(film.glob(".*.tmp*")) and helpers):
            time.sleep(0.05)  # the temporary is made before ffmpeg starts (a film that cannot be written
            helpers = [p for p in _session(proc.pid) if p != proc.pid]  # fails first): wait for ffmpeg too
        assert proc.poll() is None, proc.stderr.read()
        os.kill(proc.pid, signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 143 and "Traceback" not in err, err
        assert list(film.iterdir()) == []
        assert helpers and _gone_within(helpers, 10) == []
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


_IN_C_CODE = """
import importlib, os, signal, sys
signal.signal(signal.SIGTERM, signal.SIG_DFL)
from undulate import cli
from undulate._cliutil import SignalExit
anim = importlib.import_module("undulate.animation")  # the module; the package's `animate` is its function

frames = [0]
real = anim._Blitter.frame

def frame(self):  # as C code that calls back into Python and handles the error its own way
    frames[0] += 1
    if frames[0] == 3:
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(200000):
                pass  # the handler raises SignalExit here
        except SignalExit:
            if sys.argv[3] == "converted":
                raise ValueError("Invalid affine transformation matrix")  # matplotlib's Agg renderer
            # "dropped": the error cleared, drawing goes on
    return real(self)

anim._Blitter.frame = frame
sys.exit(cli.main(["animate", sys.argv[1], "-o", sys.argv[2]]))
"""


@pytest.mark.parametrize("fate", ["converted", "dropped"])
def test_a_signal_whose_exception_c_code_converts_or_drops_still_ends_the_animation(tmp_path, fate):
    """A SIGTERM handled inside C code that calls back into Python: the exception the handler raises
    came out as that code's error (CI: ``ValueError: Invalid affine transformation matrix`` from
    matplotlib, a traceback and exit 1 for a terminated ``animate``), or could be dropped there and the
    animation run on to its end.  Either way: exit 143, one line, no traceback, no file."""
    from undulate import Scene, SimOptions, simulate

    run = tmp_path / "run.nc"
    simulate(Scene(phases_rad=(0.0, 1.0)), SimOptions(duration_s=2.0), out=run)
    film = tmp_path / "film"
    film.mkdir()
    r = subprocess.run([sys.executable, "-c", _IN_C_CODE, str(run), str(film / "run.gif"), fate],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 128 + signal.SIGTERM, (r.stdout, r.stderr)
    assert r.stderr.strip() == "terminated (SIGTERM)" and "wrote" not in r.stdout, (r.stdout, r.stderr)
    assert list(film.iterdir()) == []


def test_a_reproduction_whose_signal_came_out_as_a_study_error_stops(tmp_path, monkeypatch):
    """A SIGTERM reported by C code as its own error inside a study (see the animation test above) is
    not a failed study: the reproduction stops there, as on the signal, and starts no other study."""
    from undulate import _signals, studies
    from undulate.cli import _Terminated
    from undulate.reproduce import reproduce

    started = []

    def run_study(name, *args, **kwargs):
        started.append(name)
        monkeypatch.setattr(_signals, "_SIGNALLED", [(signal.SIGTERM, _Terminated)])  # as the handler records it
        raise ValueError("Invalid affine transformation matrix")

    monkeypatch.setattr(studies, "run_study", run_study)
    with pytest.raises(_Terminated):
        reproduce(tmp_path / "out", studies=["compatibility", "pairs"], workers=1, log=lambda m: None,
                  animation_s=2.0)
    assert started == ["compatibility"]


_IN_AN_HDF5_FILE = """
import os, signal, sys
for s in (signal.SIGTERM, signal.SIGHUP):
    signal.signal(s, signal.SIG_DFL)
signal.signal(signal.SIGINT, signal.default_int_handler)  # a background job's shell starts it ignored
import h5netcdf
from undulate import cli

where, sent = sys.argv[2], []

def hit():  # the signal lands here, before h5netcdf's own code of the call has run
    if not sent:
        sent.append(1)
        os.kill(os.getpid(), signal.SIGINT if where == "read" else signal.SIGTERM)
        for _ in range(200000):
            pass

real_init, real_flush = h5netcdf.File.__init__, h5netcdf.File.flush

def init(self, path, mode="r", *args, **kwargs):
    if (where, mode) in (("open", "a"), ("read", "r")):  # the recorder's temporary file; animate's input
        hit()
    real_init(self, path, mode, *args, **kwargs)

def flush(self):  # called by close(), once it has found the file open
    if where == "close" and ".tmp" in str(getattr(self, "_filename", "")):
        hit()
    real_flush(self)

if where == "read":
    from undulate import Scene, SimOptions, simulate
    simulate(Scene(phases_rad=(0.0, 1.0)), SimOptions(duration_s=1.0), out=sys.argv[1])
h5netcdf.File.__init__, h5netcdf.File.flush = init, flush
if where == "read":  # Ctrl-C as animate opens its input (before it handles SIGTERM); the input removed after
    rc = cli.main(["animate", sys.argv[1], "-o", sys.argv[1] + ".gif"])
    os.remove(sys.argv[1])
    sys.exit(rc)
sys.exit(cli.main(["simulate", "--duration", "1", "-q", "--out", sys.argv[1]]))
"""


@pytest.mark.parametrize("where", ["open", "close", "read"])
def test_a_signal_while_a_file_opens_or_closes_waits_for_it(tmp_path, where):
    """A SIGTERM that lands while h5netcdf builds or closes the run's file.  Seen on a loaded machine
    (about once in 30 terminated ``simulate`` runs): the half-built File (no ``_closed`` yet; "open"
    here makes it every time) or a half-closed one (a failing flush; "close" here lands inside close's
    flush, which then went through unharmed; "read": Ctrl-C as ``animate`` opens its input) failed in
    its finalizer at exit, "Exception ignored in: <function File.close>" and a traceback after the
    command's own line.  Now the signal waits for the file, then ends the command: exit 143 with one
    line (130 and ``interrupted`` for Ctrl-C), no file."""
    r = subprocess.run([sys.executable, "-c", _IN_AN_HDF5_FILE, str(tmp_path / "run.nc"), where],
                       capture_output=True, text=True, timeout=120)
    sig, line = (signal.SIGINT, "interrupted") if where == "read" else (signal.SIGTERM, "terminated (SIGTERM)")
    assert r.returncode == 128 + sig, (r.stdout, r.stderr)
    assert r.stderr.strip() == line, r.stderr
    assert list(tmp_path.iterdir()) == []


_DEFERRED = """
import os, signal, sys
from undulate._signals import deferred, signalled, unwind_on_signals

class Stop(Exception):
    def __init__(self, signum):
        self.signum = signum

unwind_on_signals((signal.SIGTERM,), Stop)
ran = []
try:
    with deferred():
        with deferred():
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(200000):
                pass
            ran.append("inner")
        ran.append("outer")  # the inner block's end is not the last: still held
    ran.append("after")
except Stop as e:
    print(ran, e.signum, signalled())
"""


def test_a_deferred_signal_is_raised_as_the_outermost_block_ends():
    r = subprocess.run([sys.executable, "-c", _DEFERRED], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == f"['inner', 'outer'] {int(signal.SIGTERM)} {int(signal.SIGTERM)}", r.stdout


_CTRL_C_DEFERRED = """
import os, signal
from undulate._signals import deferred

signal.signal(signal.SIGINT, signal.default_int_handler)  # a background job's shell starts it ignored

ran = []
try:
    with deferred():
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(200000):
            pass
        ran.append("block")
except KeyboardInterrupt:
    print(ran, signal.getsignal(signal.SIGINT) is signal.default_int_handler)
"""


def test_ctrl_c_inside_a_deferred_block_is_raised_as_it_ends():
    """Ctrl-C is held as termination signals are (a KeyboardInterrupt halfway through building an
    h5netcdf File leaves the same failing finalizer), and Python's own handler is back afterwards."""
    r = subprocess.run([sys.executable, "-c", _CTRL_C_DEFERRED], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "['block'] True", r.stdout



_CTRL_C_IN_CODE_RUN_FROM_A_STRING = """
import os, signal, sys, threading
from undulate import cli

signal.signal(signal.SIGINT, signal.default_int_handler)  # a background job's shell starts it ignored


def run(argv):  # a command that Ctrl-C stops inside code made from a string (a dataclass's __init__ as
    threading.Timer(0.05, os.kill, args=(os.getpid(), signal.SIGINT)).start()  # its class is made)
    eval("[0 for _ in range(10 ** 9)]")
    return 0


cli._run = run
sys.exit(cli.main(["study", "pairs"]))
"""


def test_ctrl_c_in_code_run_from_a_string_still_exits_130(tmp_path):
    """A KeyboardInterrupt out of ``exec``/``eval`` of a string (dataclasses and namedtuples are made so,
    in every import) sets CPython's record of an unhandled KeyboardInterrupt, and the interpreter then
    ends by killing itself with SIGINT whatever exit code was asked for: a Ctrl-C'd ``study`` printed its
    line and exited -2 (1 in 30 Ctrl-C in its first 1.4 s, measured).  The entry point clears the record
    once it has judged the Ctrl-C."""
    (tmp_path / "stopped_in_a_string.py").write_text(textwrap.dedent(_CTRL_C_IN_CODE_RUN_FROM_A_STRING))
    r = subprocess.run([sys.executable, "-m", "stopped_in_a_string"], capture_output=True, text=True, timeout=60,
                       cwd=tmp_path)  # -m as the record is read (runpy's module, like python -m undulate)
    assert r.returncode == 130, (r.returncode, r.stderr)
    assert r.stderr.strip().splitlines() == ["interrupted; finished runs are saved: the same command resumes"], r.stderr
