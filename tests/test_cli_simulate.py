"""``undulate simulate`` on long runs: the compute-time estimate, the progress bar, and that
watching a run does not change it (``undulate._progress``, ``simulate(progress=...)``)."""

from __future__ import annotations

import io
import math
import subprocess
import sys

import numpy as np
import pytest

from undulate import _progress
from undulate._progress import Estimate, RunMonitor, estimate_compute_time, format_duration
from undulate.params import Scene, SimOptions, SwimmerGeometry
from undulate.simulation import simulate

CLI = [sys.executable, "-m", "undulate.cli"]


def _same(a, b) -> None:
    assert set(a.variables) == set(b.variables)
    for name in a.variables:
        x, y = a[name].values, b[name].values
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert x.tobytes() == y.tobytes(), name  # bitwise, NaN included
    skip = {"physics_time", "provenance_created_utc"}  # wall clock: differs from run to run, progress or not
    keys = set(a.attrs) - skip
    assert keys == set(b.attrs) - skip
    for k in keys:  # the end state and warm start (arrays) bitwise too
        x, y = a.attrs[k], b.attrs[k]
        assert (np.asarray(x).tobytes() == np.asarray(y).tobytes()) if isinstance(x, np.ndarray) else x == y, k


@pytest.mark.parametrize("closed", [False, True], ids=["open-loop", "phase-oscillator"])
def test_progress_does_not_change_the_run_bitwise(tmp_path, closed):
    from undulate.params import ControllerParams

    ctl = ControllerParams(kind="phase-oscillator", coupling=1.0) if closed else ControllerParams()
    scene = Scene(phases_rad=(0.0, math.pi / 2), controller=ctl)
    opt = SimOptions(duration_s=3.0, chunk_steps=300)  # several chunks
    calls = []
    stream = io.StringIO()
    # every threshold at 0: calibrated after the first chunk, announced, a bar drawn
    with RunMonitor(calibrate_s=0.0, announce_s=0.0, bar_s=0.0, stream=stream) as mon:
        def progress(done, total):
            calls.append((done, total))
            mon(done, total)

        watched = simulate(scene, opt, progress=progress)
    plain = simulate(scene, opt)
    _same(watched, plain)
    streamed = simulate(scene, opt, out=tmp_path / "w.nc", progress=RunMonitor(calibrate_s=0.0, stream=io.StringIO()))
    with streamed:
        _same(streamed.load(), plain)
    # called at t = 0 and after each chunk, up to the run's end
    done = [d for d, _ in calls]
    assert done[0] == 0.0 and done == sorted(done) and len(done) >= 4
    assert done[-1] == pytest.approx(3.0) and all(t == pytest.approx(3.0) for _, t in calls)
    text = stream.getvalue()
    assert text.startswith("estimated compute time: ") and "simulated s" in text.splitlines()[0]
    assert "100%" in text  # the bar ran to the end
    assert mon.estimate is not None and 0 < mon.estimate.measured_on_s < 3.0


def test_monitor_announces_only_long_runs_and_bars_only_from_20_s():
    def run(rate, total):  # a fake clock: `rate` wall s per simulated s, chunks of 4 s
        now = [0.0]
        stream = io.StringIO()
        mon = RunMonitor(stream=stream, clock=lambda: now[0])
        mon(0.0, total)
        done = 0.0
        while done < total:  # 4 s chunks until calibrated, then tenths of the run (a short test)
            step = min(4.0 if mon.estimate is None else total / 10, total - done)
            now[0] += rate * step
            done += step
            mon(done, total)
            if mon._bar is not None:
                assert mon._bar.n == pytest.approx(done)
        mon.close()
        return mon, stream.getvalue()

    rate = 1 / 64  # exact in binary: 16 chunks make the 1 s of calibration
    mon, text = run(rate, 1e7)  # 43 h: announced and barred
    assert mon.estimate.seconds == pytest.approx(1e7 / 64)
    assert text.splitlines()[0] == ("estimated compute time: 1 d 19 h (0.016 s per simulated s, "
                                    "measured on the first 64 s)")
    assert "10000000/10000000 simulated s" in text
    mon, text = run(rate, 3000)  # 47 s: a bar, no estimate line
    assert mon.estimate.seconds == pytest.approx(3000 / 64) and "estimated" not in text and "3000/3000" in text
    mon, text = run(rate, 500)  # 8 s: silent
    assert text == "" and mon.estimate.seconds == pytest.approx(500 / 64)
    quiet = RunMonitor(bar=False, stream=io.StringIO(), clock=iter([0.0, 2.0]).__next__)
    quiet(0.0, 1e6)
    quiet(4.0, 1e6)
    assert quiet._bar is None and quiet.stream.getvalue().startswith("estimated compute time: 5 d 19 h")


@pytest.mark.parametrize("s, text", [(0.25, "0.2 s"), (9.96, "10.0 s"), (45, "45 s"), (200, "3 min 20 s"),
                                     (2 * 3600 + 14 * 60, "2 h 14 min"), (5 * 86400 + 3 * 3600, "5 d 3 h")])
def test_format_duration(s, text):
    assert format_duration(s) == text


def test_estimate_only_prints_the_estimate_and_writes_nothing(tmp_path):
    out = tmp_path / "run.nc"
    r = subprocess.run([*CLI, "simulate", "--duration", "1e7", "--estimate", "--out", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("estimated compute time: "), r.stdout
    assert " d " in lines[0] and "s per simulated s, measured on the first" in lines[0]  # days for 1e7 s
    assert list(tmp_path.iterdir()) == []


def test_estimate_option_is_validated_like_the_run(tmp_path):
    r = subprocess.run([*CLI, "simulate", "--duration", "-1", "--estimate", "--out", str(tmp_path / "r.nc")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "--duration" in r.stderr
    assert "Traceback" not in r.stderr
    r = subprocess.run([*CLI, "simulate", "--estimate=maybe"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "--estimate" in r.stderr
    assert "Traceback" not in r.stderr


def test_a_long_run_announces_its_estimate_before_its_progress(tmp_path, monkeypatch):
    """The thresholds lowered so that a 6 s run counts as long: the estimate line comes first, on
    stderr, then the bar; stdout keeps only the summary."""
    from typer.testing import CliRunner

    from undulate.cli import app

    monkeypatch.setattr(_progress, "CALIBRATE_S", 0.0)
    monkeypatch.setattr(_progress, "ANNOUNCE_S", 0.0)
    monkeypatch.setattr(_progress, "BAR_S", 0.0)
    res = CliRunner().invoke(app, ["simulate", "--duration", "12", "--out", str(tmp_path / "r.nc")])
    assert res.exit_code == 0, res.output
    err = res.stderr
    assert err.startswith("estimated compute time: ") and "100%" in err
    assert err.index("estimated compute time") < err.index("simulated s [")
    assert res.stdout.startswith("wrote ") and "estimated" not in res.stdout
    res = CliRunner().invoke(app, ["simulate", "--duration", "12", "-q", "--out", str(tmp_path / "q.nc")])
    assert res.exit_code == 0 and res.stdout == "" and "%" not in res.stderr  # --quiet: no bar
    assert res.stderr.startswith("estimated compute time: ")


@pytest.mark.alone  # two wall times of this process, not of the other worker's test
def test_estimate_is_within_a_factor_3_of_the_measured_compute_time(tmp_path):
    """A moderate run (4 swimmers of 12 links, 8 s: a few seconds of stepping): the estimate from
    about a second of calibration against the same run's stepping time.  Loose: both are wall
    times on a machine that may be shared."""
    scene = Scene(phases_rad=(0.0, 1.0, 2.0, 3.0), geometry=SwimmerGeometry(n_links=12))
    opt = SimOptions(duration_s=8.0)
    est = estimate_compute_time(scene, opt)
    assert isinstance(est, Estimate) and est.total_s == 8.0 and est.measured_on_s < 8.0
    mon = RunMonitor(bar=False, announce_s=math.inf)
    simulate(scene, opt, out=tmp_path / "m.nc", progress=mon).close()
    ratio = est.seconds / mon.elapsed
    assert 1 / 3 < ratio < 3, (est, mon.elapsed)
    assert np.isfinite(ratio)
