"""Studies side by side: :func:`undulate.reproduce.reproduce` runs two studies at a time on threads
that share one pool of worker processes.  What must hold: an explaining study starts only after the
studies it explains; studies that share a sweep store compute each run once; each study's physics
meter sees its own physics only; an interrupt stops the sweeps in flight; and the results are the
same as one study at a time (real MuJoCo runs, real worker processes)."""

from __future__ import annotations

import contextvars
import functools
import json
import sys
import threading
import time
from pathlib import Path

import pytest
import xarray as xr

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import sweep_funcs  # noqa: E402

from undulate import _walltime, studies  # noqa: E402
from undulate.reproduce import _dependencies, _side_by_side, reproduce  # noqa: E402
from undulate import execution  # noqa: E402
from undulate.execution import Execution, runs_wide  # noqa: E402
from undulate.studies import _registry  # noqa: E402
from undulate.sweep import Grid  # noqa: E402


# ---- the scheduler -------------------------------------------------------------------------
def test_jobs_wait_for_their_dependencies_and_never_exceed_the_limit():
    lock, events, now = threading.Lock(), [], {"running": 0, "most": 0}

    def one(name):
        with lock:
            now["running"] += 1
            now["most"] = max(now["most"], now["running"])
            events.append(("start", name))
        time.sleep(0.05 if name != "slow" else 0.2)
        with lock:
            now["running"] -= 1
            events.append(("end", name))
        return name.upper()

    got = []
    deps = {"explains": {"slow", "a"}, "a": set(), "slow": set(), "b": set(), "c": set()}
    _side_by_side(["a", "b", "c", "slow", "explains"], deps, one,
                  lambda name, result: got.append((name, result, threading.current_thread() is threading.main_thread())),
                  at_once=2)
    assert now["most"] == 2
    assert sorted(got) == sorted((n, n.upper(), True) for n in deps)  # each reported once, in this thread
    start = events.index(("start", "explains"))
    assert events.index(("end", "slow")) < start and events.index(("end", "a")) < start
    # a study the explaining one waits for goes before the others ready at the same time
    assert events.index(("start", "slow")) < events.index(("start", "b"))


def test_one_at_a_time_keeps_the_order():
    seen = []
    _side_by_side(["x", "y", "z"], {}, lambda n: n, lambda n, r: seen.append(n), at_once=1)
    assert seen == ["x", "y", "z"]


def test_an_interrupt_in_one_job_is_raised_and_nothing_more_starts():
    started = []

    def one(name):
        started.append(name)
        if name == "bad":
            raise KeyboardInterrupt
        time.sleep(0.1)
        return name

    with pytest.raises(KeyboardInterrupt):
        _side_by_side(["bad", "ok", "later1", "later2"], {}, one, lambda n, r: None, at_once=2)
    assert "later2" not in started


def test_dependencies_are_the_explained_studies():
    class Reg:
        @staticmethod
        def describe(name):
            ex = [studies.Explanation(study=s, claim="c", cause="x", check=lambda s: (None, "", None))
                  for s in {"explainer": ("p", "q", "absent"), "p": (), "q": ()}[name]]
            return type("S", (), {"explanations": tuple(ex)})

    assert _dependencies(Reg, ["p", "q", "explainer"]) == {"p": set(), "q": set(), "explainer": {"p", "q"}}


# ---- physics meters per context ---------------------------------------------------------------
def test_a_meter_sees_its_own_thread_and_the_threads_started_in_its_context():
    with _walltime.meter() as outer:
        mine = {}

        def study(name, seconds):
            with _walltime.meter() as own:
                _walltime.report(seconds, 10)
                time.sleep(0.05)  # both meters open at once
            mine[name] = own.read()

        threads = [threading.Thread(target=contextvars.copy_context().run, args=(study, n, s))
                   for n, s in (("a", 1.0), ("b", 2.0))]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        stranger = threading.Thread(target=_walltime.report, args=(100.0, 1))  # a fresh context: not ours
        stranger.start()
        stranger.join()
    assert mine == {"a": (1.0, 10), "b": (2.0, 10)}
    assert outer.read() == (3.0, 20)


# ---- real studies side by side ---------------------------------------------------------------
RAN_AFTER: dict[str, bool] = {}


def _swing_dataset(ctx, plan, *, shared: bool):
    grid = Grid(axes={"damping_Nms": [0.1, 0.2], "length_m": [0.5]}, replicates=2, seed=ctx.config.seed)
    fn = functools.partial(sweep_funcs.pendulum)
    ds = ctx.shared_sweep("swing", fn, grid) if shared else ctx.sweep("own", fn, grid)
    return xr.Dataset({"final_angle": (("damping", "draw"), ds["final_angle"].isel(length_m=0).values, {"units": "rad"})},
                      coords={"damping": ("damping", [0.1, 0.2], {"units": "N m s/rad"}),
                              "draw": ("draw", [0, 1], {"units": "1"})})


class _Fig:
    def savefig(self, path, **kw):
        Path(path).write_bytes(b"%PDF-1.4 figure" if kw.get("format") == "pdf" else b"\x89PNG\r\n\x1a\n")


def _summary(ds):
    return {"mean_final_angle_rad": float(ds["final_angle"].mean())}


def _explainer_dataset(ctx, plan):
    RAN_AFTER[str(ctx.config.out_dir)] = (Path(ctx.config.out_dir) / "_swing_a.json").is_file() and \
        (Path(ctx.config.out_dir) / "_swing_b.json").is_file()
    return _swing_dataset(ctx, plan, shared=True)


CLAIM = studies.Claim(claim="the pendulum swings back", paper="-", criterion="mean final angle below 10 rad",
                      judge=lambda s: studies.Verdict.judged(abs(s["mean_final_angle_rad"]) < 10.0, "measured"))


@pytest.fixture
def swing_studies():
    names = ("_swing_a", "_swing_b", "_swing_c", "_swing_explainer")
    for name, shared in (("_swing_a", True), ("_swing_b", True), ("_swing_c", False)):
        studies.register(studies.Study(
            name=name, description="test: damped pendulum", plan=lambda quick: None,
            dataset=functools.partial(_swing_dataset, shared=shared), summary=_summary, claims=(CLAIM,),
            figure=lambda ds: _Fig()))
    studies.register(studies.Study(
        name="_swing_explainer", description="test: explains", plan=lambda quick: None, dataset=_explainer_dataset,
        summary=_summary, figure=lambda ds: _Fig(), order=200.0,
        explanations=tuple(studies.Explanation(study=s, claim=CLAIM.claim, cause="damping",
                                               check=lambda summ: (True, "shown", None))
                           for s in ("_swing_a", "_swing_b"))))
    yield names
    for n in names:
        _registry._REGISTRY.pop(n, None)


def _results(out: Path, names) -> dict:
    return {n: {k: json.loads((out / f"{n}.json").read_text())[k] for k in ("summary", "claims", "explanations")}
            for n in names}


def test_side_by_side_gives_the_results_of_one_at_a_time(tmp_path, swing_studies):
    names = list(swing_studies)
    one, two = tmp_path / "one", tmp_path / "two"
    reproduce(one, quick=True, studies=names, log=lambda m: None, animation_s=0.3, workers=2, side_by_side=1)
    reproduce(two, quick=True, studies=names, log=lambda m: None, animation_s=0.3, workers=2, side_by_side=2)
    assert _results(one, names) == _results(two, names)
    assert RAN_AFTER == {str(one): True, str(two): True}  # the explaining study waited for both
    # the shared store is computed once in all (the studies sharing it took turns)
    computed = sum(s["n_computed"] for n in ("_swing_a", "_swing_b", "_swing_explainer")
                   for s in json.loads((two / f"{n}.json").read_text())["sweeps"] if s["part"] == "swing")
    assert computed == 4
    state = json.loads((two / "reproduce.json").read_text())
    assert state["wall_s"] > 0 and set(state["studies"]) == set(names)
    claims = json.loads((two / "claims.json").read_text())
    assert claims["counts"]["holds"] == 3


@pytest.mark.slow  # ~20 s; runs ahead on MuJoCo: test_on_many_workers_every_study_runs_at_once_with_its_runs_ahead (default run)
def test_on_the_warp_backend_an_explaining_study_makes_its_runs_ahead(tmp_path, swing_studies, monkeypatch):
    """With runs ahead (the Warp backend's way), the explaining study's runs are made beside the studies
    it explains (:func:`undulate.studies.run_ahead`: every explanation taken as needed); the study itself
    still starts after them, finds its runs made, and every result is that of one study at a time."""
    import undulate.reproduce as rp

    names = list(swing_studies)
    one, ahead = tmp_path / "one", tmp_path / "ahead"
    reproduce(one, quick=True, studies=names, log=lambda m: None, animation_s=0.3, workers=2, side_by_side=1)
    monkeypatch.setattr(rp, "runs_ahead", lambda execution: True)
    log: list[str] = []
    reproduce(ahead, quick=True, studies=names, log=log.append, animation_s=0.3, workers=2, side_by_side=2)
    assert _results(one, names) == _results(ahead, names)
    assert [m for m in log if "made ahead" in m and "_swing_explainer" in m]
    assert RAN_AFTER[str(ahead)]  # the study itself waited for the studies it explains
    mine = json.loads((ahead / "_swing_explainer.json").read_text())["sweeps"]
    assert mine and sum(s["n_computed"] for s in mine) == 0  # its runs were there
    state = json.loads((ahead / "reproduce.json").read_text())
    assert set(state["studies"]) == set(names)  # the job ahead is not a study of the report


def test_on_many_workers_every_study_runs_at_once_with_its_runs_ahead(tmp_path, swing_studies, monkeypatch):
    """From :data:`WIDE_WORKERS` local workers on (here lowered to 2) the MuJoCo backend's
    reproduction runs wide, as the Warp backend's: every study at once and the explaining study's runs
    made ahead; below it, two at a time and nothing ahead; with a Dask scheduler, as few cores.  The
    results are those of one study at a time."""
    import undulate.reproduce as rp

    monkeypatch.delenv("UNDULATE_BACKEND", raising=False)
    names = list(swing_studies)
    assert not runs_wide(Execution(workers=2)) and not runs_wide(Execution(scheduler="tcp://x:1"))
    assert runs_wide(Execution(workers=execution.WIDE_WORKERS))
    one, wide = tmp_path / "one", tmp_path / "wide"
    reproduce(one, quick=True, studies=names, log=lambda m: None, animation_s=0.3, workers=2, side_by_side=1)
    at_once: list[int] = []
    real = rp._side_by_side
    monkeypatch.setattr(rp, "_side_by_side", lambda todo, deps, one, finished, n: at_once.append(n)
                        or real(todo, deps, one, finished, n))
    monkeypatch.setattr(execution, "WIDE_WORKERS", 2)
    log: list[str] = []
    reproduce(wide, quick=True, studies=names, log=log.append, animation_s=0.3, workers=2)
    assert at_once == [len(names) + 1 + 1]  # every study, the animations and the job ahead
    assert [m for m in log if "made ahead" in m and "_swing_explainer" in m]
    assert _results(one, names) == _results(wide, names)


# ---- which studies a reproduction runs ------------------------------------------------------
@pytest.mark.parametrize("quick,beyond,expect_prx", [(True, None, False), (False, None, False), (True, True, True),
                                                     (False, True, True), (False, False, False)])
def test_a_reproduction_is_the_papers_and_beyond_paper_adds_the_prx_studies(monkeypatch, tmp_path, quick, beyond,
                                                                            expect_prx):
    import undulate.reproduce as rp

    calls = []
    monkeypatch.setattr(rp, "_reproduce", lambda registry, out, q, sch, seed, names, *a: calls.append(names))
    rp.reproduce(tmp_path, quick=quick, beyond_paper=beyond, log=lambda m: None)
    prx = [n for n in studies.names() if studies.describe(n).reference == "prx2021"]
    assert prx and all((n in calls[0]) == expect_prx for n in prx)
    assert [n for n in calls[0] if n not in prx] == [n for n in studies.names() if n not in prx]
    # naming the studies overrides it
    rp.reproduce(tmp_path, quick=quick, beyond_paper=beyond, studies=[prx[0]], log=lambda m: None)
    assert calls[1] == [prx[0]]


def test_the_page_says_which_studies_beyond_the_paper_were_not_run(tmp_path):
    from undulate.report import write_report

    path = write_report(tmp_path, [], mode="quick")
    text = path.read_text()
    assert "Not run here, beyond the paper" in text and "synchronization-groups" in text and "--beyond-paper" in text


@pytest.mark.slow  # ~70 s; Ctrl-C of one study and its workers: test_termination (default run)
def test_ctrl_c_stops_studies_running_side_by_side_promptly_and_the_rerun_resumes(tmp_path):
    """SIGINT while two studies run, after a third has finished: the sweeps in flight stop at their next
    chunk, the command exits 130 within seconds, no worker process is left, the state file says which
    study finished, and the same command then finishes the job without redoing the finished study."""
    import os
    import signal
    import subprocess

    out = tmp_path / "r"
    cmd = [sys.executable, "-m", "undulate.cli", "reproduce", "--out", str(out), "--only",
           "compatibility,groups,swimming", "--workers", "2", "--animation-s", "0.3"]
    # SIGINT as a terminal delivers it, even where this test runs as a background job (which starts
    # with SIGINT ignored, and Python then never raises KeyboardInterrupt)
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    lines, deadline = [], time.time() + 240
    while time.time() < deadline:  # compatibility done; groups and swimming side by side, swimming's pairs
        line = proc.stdout.readline()  # handed to the workers
        if not line:
            break
        lines.append(line)
        if "/swimming/pairs-quick-seed0" in line and "to compute on 2 local processes" in line:
            break
    assert proc.poll() is None, "".join(lines)
    assert any("compatibility: done" in x for x in lines) and not any("groups: done" in x for x in lines)
    first = (out / "compatibility.json").stat().st_mtime_ns
    t0 = time.time()
    os.kill(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C reaches the command
    rest, _ = proc.communicate(timeout=60)
    assert proc.returncode == 130, "".join(lines) + rest
    assert time.time() - t0 < 30
    assert "sweep interrupted" in rest  # the sweep in flight stopped and said how to resume
    # no process of its session is left (the worker pool was stopped)
    for _ in range(50):  # the worker processes see their parent gone and end within moments
        left = subprocess.run(["ps", "-o", "pid=,args=", "-s", str(proc.pid)], capture_output=True, text=True).stdout
        if not left.strip():
            break
        time.sleep(0.1)
    assert not left.strip(), left
    state = json.loads((out / "reproduce.json").read_text())["studies"]
    assert state["compatibility"]["ok"] and not state.get("swimming", {}).get("ok")
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "compatibility: done earlier" in r.stdout
    assert (out / "compatibility.json").stat().st_mtime_ns == first  # not recomputed
    assert (out / "groups.json").exists() and (out / "swimming.json").exists() and (out / "index.html").exists()
