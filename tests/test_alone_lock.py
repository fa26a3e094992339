"""The lock that keeps wall-clock tests alone under pytest-xdist (``alone_lock``), between real
processes: an exclusive holder waits for the shared ones to end, and once it waits no new shared
holder starts before it."""

from __future__ import annotations

import multiprocessing as mp
import time

from alone_lock import beside_others


def _hold(folder, alone, ready, release, log):
    """Take the lock (shared, or exclusive when ``alone``), log entry and exit, hold it until ``release``."""
    ready.set()
    with beside_others(folder, alone):
        log.put(("in", alone, time.monotonic()))
        release.wait(60)
        log.put(("out", alone, time.monotonic()))


def _start(ctx, folder, alone, log, release):
    ready = ctx.Event()
    p = ctx.Process(target=_hold, args=(folder, alone, ready, release, log))
    p.start()
    assert ready.wait(60)
    time.sleep(0.3)  # now at the lock (waiting, or in)
    return p


def _events(log, n):
    return [(kind, a) for kind, a, _ in sorted((log.get(timeout=30) for _ in range(n)), key=lambda e: e[2])]


def test_an_alone_test_waits_for_the_test_beside_it_and_then_runs_before_the_next(tmp_path):
    ctx = mp.get_context("spawn")
    log, first, others = ctx.Queue(), ctx.Event(), ctx.Event()
    others.set()  # the alone test and the later one leave as soon as they are in
    beside = _start(ctx, tmp_path, False, log, first)
    alone = _start(ctx, tmp_path, True, log, others)  # waits for `beside`
    later = _start(ctx, tmp_path, False, log, others)  # arrives while the alone test waits
    first.set()
    for p in (beside, alone, later):
        p.join(60)
        assert p.exitcode == 0
    assert _events(log, 6) == [("in", False), ("out", False), ("in", True), ("out", True),
                               ("in", False), ("out", False)]


def test_tests_not_alone_run_side_by_side(tmp_path):
    ctx = mp.get_context("spawn")
    log, release = ctx.Queue(), ctx.Event()
    a = _start(ctx, tmp_path, False, log, release)
    b = _start(ctx, tmp_path, False, log, release)
    time.sleep(0.3)
    release.set()
    for p in (a, b):
        p.join(60)
        assert p.exitcode == 0
    assert _events(log, 4) == [("in", False), ("in", False), ("out", False), ("out", False)]
