"""StudyContext.together: a study's independent calls side by side on the Warp backend (their runs reach
the device at once), one after another on the MuJoCo backend; sweeps recorded in the calls' order."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
import xarray as xr

from undulate import _walltime, studies
from undulate import execution
from undulate.studies import _context, _registry
from undulate.sweep import Grid


def toy(point: dict, seed: int) -> xr.Dataset:
    """A sweep function that simulates nothing: its point's value, and the physics it reports."""
    _walltime.report(0.5, 7)
    return xr.Dataset({"v": ((), float(point["v"]), {"units": "1"})})


def _ctx(tmp_path, workers=None):
    return studies.StudyContext(studies.StudyConfig(out_dir=tmp_path, quick=True, seed=0, workers=workers), "toy",
                                progress=False)


def test_on_the_mujoco_backend_and_a_few_cores_the_calls_run_here_one_after_another(tmp_path, monkeypatch):
    monkeypatch.delenv("UNDULATE_BACKEND", raising=False)
    ctx, seen = _ctx(tmp_path, workers=2), []
    out = ctx.together(*(lambda i=i: seen.append((i, threading.get_ident())) or i for i in range(3)))
    assert out == [0, 1, 2] and seen == [(i, threading.get_ident()) for i in range(3)]


def test_on_the_mujoco_backend_and_many_workers_the_calls_run_side_by_side(tmp_path, monkeypatch):
    """From :data:`undulate.execution.WIDE_WORKERS` local workers on, a few stages of 10-20
    runs would leave most of the pool idle: the calls run side by side there too (two calls that
    each wait for the other)."""
    monkeypatch.delenv("UNDULATE_BACKEND", raising=False)
    ctx = _ctx(tmp_path, workers=execution.WIDE_WORKERS)
    both = threading.Barrier(2, timeout=10)  # one after another, the first call would time out
    assert ctx.together(lambda: (both.wait(), "a")[1], lambda: (both.wait(), "b")[1]) == ["a", "b"]


def test_on_the_warp_backend_the_calls_run_side_by_side_and_record_in_their_order(tmp_path, monkeypatch):
    """Two calls that each wait for the other (one after another they would time out), the first
    finishing last: their results, sweeps and failures come back in the calls' order, and the study's
    physics meter counts what both simulated; a nested ``together`` keeps its calls' order too."""
    monkeypatch.setattr(_context, "runs_wide", lambda execution: True)  # as on the Warp backend
    ctx = _ctx(tmp_path)
    both = threading.Barrier(2, timeout=30)

    def call(part: str, value: float, delay: float):
        both.wait()
        time.sleep(delay)
        return float(ctx.sweep(part, toy, Grid(points=[{"v": value}], seed=0))["v"].item())

    with _walltime.meter() as tally:
        got = ctx.together(lambda: call("a", 1.0, 0.5), lambda: call("b", 2.0, 0.0))
    assert got == [1.0, 2.0]
    assert [s["part"] for s in ctx.sweeps] == ["a", "b"]
    assert tally.read() == (1.0, 14)

    def pair(tag: str):
        return ctx.together(lambda: ctx.sweep(tag + "1", toy, Grid(points=[{"v": 3.0}], seed=0)),
                            lambda: ctx.sweep(tag + "2", toy, Grid(points=[{"v": 4.0}], seed=0)))

    ctx.together(lambda: pair("x"), lambda: pair("y"))
    assert [s["part"] for s in ctx.sweeps] == ["a", "b", "x1", "x2", "y1", "y2"]


def test_the_first_failing_call_raises_once_all_have_ended(tmp_path, monkeypatch):
    monkeypatch.setattr(_context, "runs_wide", lambda execution: True)  # as on the Warp backend
    ctx = _ctx(tmp_path)
    ended = []

    def bad(msg: str):
        raise ValueError(msg)

    def slow():
        time.sleep(0.3)
        ctx.sweep("slow", toy, Grid(points=[{"v": 1.0}], seed=0))
        ended.append("slow")

    with pytest.raises(ValueError, match="first"):
        ctx.together(lambda: bad("first"), slow, lambda: bad("second"))
    assert ended == ["slow"] and [s["part"] for s in ctx.sweeps] == ["slow"]


def test_a_study_on_threads_gives_the_same_dataset(tmp_path, monkeypatch):
    """The swimming study's dataset (a reduced plan) with its three calls side by side equals the one
    made one call after another, value for value."""
    from undulate.studies import swimming

    plan = swimming.SwimmingPlan(dphi=[0.0, np.pi / 2], duration_s=4.0)
    seq = swimming.dataset(_ctx(tmp_path / "seq"), plan)
    monkeypatch.setattr(_context, "runs_wide", lambda execution: True)  # as on the Warp backend
    ctx = _ctx(tmp_path / "threads")
    par = swimming.dataset(ctx, plan)
    xr.testing.assert_equal(seq, par)
    assert [s["part"] for s in ctx.sweeps][-1] == "pairs"


def test_a_sweep_of_a_few_runs_steps_them_in_the_warm_pool_once_its_processes_are_up(tmp_path, monkeypatch):
    """Sweeps of fewer than SERIAL_BELOW runs run here, where starting worker processes would cost
    more than the runs, but once the warm pool is up (a reproduction's later sweeps) 2 or 3 runs go
    there, side by side; one run stays here."""
    from undulate.sweep import warm_workers

    monkeypatch.delenv("UNDULATE_BACKEND", raising=False)
    ctx = _ctx(tmp_path, workers=2)

    def grid(*vs):
        return Grid(points=[{"v": float(v)} for v in vs], seed=0)

    with warm_workers(2):
        ctx.sweep("cold", toy, grid(1, 2))  # no pool yet
        ctx.sweep("big", toy, grid(*range(10, 10 + execution.SERIAL_BELOW)))  # starts it
        ctx.sweep("small", toy, grid(3, 4, 5))
        ctx.sweep("one", toy, grid(6))
    assert [s["timing"]["executor"] for s in ctx.sweeps] == ["serial", "local", "local", "serial"]
