"""The lock that keeps wall-clock tests alone under pytest-xdist (``alone_lock``), between real
processes: an exclusive holder waits for the shared ones to end, and once it waits no new shared
holder starts before it."""

from __future__ import annotations

import multiprocessing as mp
import time

from alone_lock import beside_others


def _hold(folder, alone, started, hold_s, log):
    with beside_others(folder, alone):
        log.put(("in", alone, time.monotonic()))
        started.set()
        time.sleep(hold_s)
        log.put(("out", alone, time.monotonic()))


def test_an_alone_test_waits_for_the_test_beside_it_and_then_runs_before_the_next(tmp_path):
    ctx = mp.get_context("spawn")
    log, s1, s2, s3 = ctx.Queue(), ctx.Event(), ctx.Event(), ctx.Event()
    beside = ctx.Process(target=_hold, args=(tmp_path, False, s1, 1.0, log))
    beside.start()
    assert s1.wait(30)
    alone = ctx.Process(target=_hold, args=(tmp_path, True, s2, 0.5, log))
    alone.start()
    time.sleep(0.3)  # the alone test is waiting now; a test arriving after it starts after it
    later = ctx.Process(target=_hold, args=(tmp_path, False, s3, 0.0, log))
    later.start()
    for p in (beside, alone, later):
        p.join(30)
        assert p.exitcode == 0
    events = sorted((log.get(timeout=5) for _ in range(6)), key=lambda e: e[2])
    assert [(kind, a) for kind, a, _ in events] == [("in", False), ("out", False), ("in", True), ("out", True),
                                                    ("in", False), ("out", False)]


def test_tests_not_alone_run_side_by_side(tmp_path):
    ctx = mp.get_context("spawn")
    log, s1, s2 = ctx.Queue(), ctx.Event(), ctx.Event()
    a = ctx.Process(target=_hold, args=(tmp_path, False, s1, 1.5, log))
    a.start()
    assert s1.wait(30)
    b = ctx.Process(target=_hold, args=(tmp_path, False, s2, 0.0, log))
    b.start()
    assert s2.wait(30)  # while the first still holds it
    for p in (a, b):
        p.join(30)
        assert p.exitcode == 0
    events = sorted((log.get(timeout=5) for _ in range(4)), key=lambda e: e[2])
    assert [kind for kind, _, _ in events] == ["in", "in", "out", "out"]
