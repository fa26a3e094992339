"""undulate.sweep: serial, local processes and Dask agree; resume; failures.

Real components only: a MuJoCo pendulum (tests/sweep_funcs.py) as the sweep
function, real process pools, a real Dask LocalCluster, a real SIGKILL.
"""

from __future__ import annotations

import functools
import io
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:  # workers inherit sys.path, so they can import sweep_funcs
    sys.path.insert(0, str(HERE))

import sweep_funcs  # noqa: E402

from undulate.errors import ParameterError  # noqa: E402
from undulate.sweep import Grid, SweepFailed, load_sweep, run_sweep  # noqa: E402

GRID = Grid(axes={"damping_Nms": [0.05, 0.1, 0.2], "length_m": [0.3, 0.5, 0.7]}, replicates=2, seed=7)


def _data(ds: xr.Dataset) -> xr.Dataset:
    """The dataset without attributes that record when/where it was made."""
    ds = ds.copy()
    ds.attrs = {k: v for k, v in ds.attrs.items() if not k.startswith("provenance_")}
    return ds


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The reference: the grid run in this process."""
    res = run_sweep(sweep_funcs.pendulum, GRID, tmp_path_factory.mktemp("serial") / "s", workers=1, progress=False)
    assert res.ok and res.n_computed == GRID.n_runs and res.n_reused == 0
    return res


# ---- the grid and its seeds -----------------------------------------------------------------
def test_grid_shape_and_seeds():
    assert GRID.dims == ("damping_Nms", "length_m") and GRID.shape == (3, 3) and GRID.n_runs == 18
    runs = GRID.runs()
    seeds = [r.seed for r in runs]
    assert len(set(seeds)) == len(seeds) and all(0 <= s < 2**63 for s in seeds)
    # a seed depends on the point and replicate, not on the grid around it
    bigger = Grid(axes={"damping_Nms": [0.01, 0.05, 0.1, 0.2], "length_m": [0.5]}, replicates=2, seed=7)
    pick = {(r.point["damping_Nms"], r.replicate): r.seed for r in bigger.runs() if r.point["length_m"] == 0.5}
    for r in runs:
        if r.point["length_m"] == 0.5:
            assert pick[(r.point["damping_Nms"], r.replicate)] == r.seed
    assert Grid(axes={"a": [1, 2]}).runs()[0].seed == Grid(axes={"a": [1.0, 2.0]}).runs()[0].seed
    assert Grid(axes={"a": [1, 2]}, seed=1).runs()[0].seed != Grid(axes={"a": [1, 2]}, seed=2).runs()[0].seed


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"axes": {"a": []}}, "axes['a']"),
        ({"axes": {"a": [1, 1]}}, "axes['a']"),
        ({"axes": {"replicate": [1]}}, "grid axis name"),
        ({"axes": {"a": [1, "x"]}}, "axes['a']"),
        ({"axes": {"a": [1]}, "replicates": 0}, "replicates"),
        ({"points": [{"a": 1}, {"b": 2}]}, "points"),
        ({}, "Grid"),
    ],
)
def test_grid_rejects_bad_input(kwargs, name):
    with pytest.raises(ParameterError) as e:
        Grid(**kwargs)
    assert e.value.name == name


# ---- executors agree --------------------------------------------------------------------------
def test_serial_result_matches_direct_calls(serial):
    ds = serial.dataset
    assert ds["angle"].dims == ("damping_Nms", "length_m", "replicate", "time")
    assert not ds["run_failed"].any()
    one = ds.sel(damping_Nms=0.1, length_m=0.5, replicate=1)
    direct = sweep_funcs.pendulum({"damping_Nms": 0.1, "length_m": 0.5}, int(one["seed"]))
    np.testing.assert_array_equal(one["angle"].values, direct["angle"].values)
    # replicates differ (their seeds draw other release angles)
    assert not np.array_equal(ds["angle"][0, 0, 0].values, ds["angle"][0, 0, 1].values)
    # provenance and the grid are stored with the data
    saved = load_sweep(serial.out_dir)
    assert json.loads(saved.attrs["sweep_grid"]) == GRID.to_dict()
    assert saved.attrs["sweep_function"] == "sweep_funcs.pendulum()"  # the fully bound call
    assert "provenance_mujoco_version" in saved.attrs and "provenance_undulate_version" in saved.attrs
    xr.testing.assert_identical(_data(saved), _data(ds))


def test_local_pool_equals_serial(serial, tmp_path):
    res = run_sweep(sweep_funcs.pendulum, GRID, tmp_path / "local", workers=2, batch=3, progress=False)
    assert res.n_computed == GRID.n_runs
    xr.testing.assert_identical(_data(res.dataset), _data(serial.dataset))
    # batched form, explicit chunking: same numbers
    res = run_sweep(sweep_funcs.pendulum_batch, GRID, tmp_path / "batched", workers=2, batch=4, batched=True,
                    progress=False)
    xr.testing.assert_identical(res.dataset.drop_attrs(), serial.dataset.drop_attrs())


def test_a_marked_batched_sweep_function_runs_batched_without_being_told(serial, tmp_path):
    """``@batched_sweep_function`` is read by ``run_sweep`` (also through a partial): the same runs as the
    one-point function, the same sweep identity as ``batched=True``; ``batched=False`` for it is refused."""
    from undulate.sweep import is_batched_sweep_function

    fn = functools.partial(sweep_funcs.pendulum_batch_marked, scale=1.0)
    assert is_batched_sweep_function(fn) and not is_batched_sweep_function(sweep_funcs.pendulum_batch)
    res = run_sweep(fn, GRID, tmp_path / "m", workers=1, progress=False)
    assert res.n_computed == GRID.n_runs
    xr.testing.assert_identical(res.dataset.drop_attrs(), serial.dataset.drop_attrs())
    assert json.loads((tmp_path / "m" / "manifest.json").read_text())["batched"] is True
    again = run_sweep(fn, GRID, tmp_path / "m", workers=1, progress=False, batched=True)  # the same sweep
    assert again.n_reused == GRID.n_runs and again.n_computed == 0
    for bad, says in ((False, "pendulum_batch_marked, a batched sweep function"), ("yes", "True, False or None")):
        with pytest.raises(ParameterError, match=says) as e:
            run_sweep(fn, GRID, tmp_path / f"refused-{bad}", workers=1, progress=False, batched=bad)
        assert e.value.name == "batched" and not (tmp_path / f"refused-{bad}").exists()


@pytest.mark.parametrize("kwargs, name", [({"progress": "no"}, "progress"), ({"progress": 0.0}, "progress"),
                                          ({"stream": "log.txt"}, "stream")])
def test_run_sweep_refuses_a_progress_or_stream_of_the_wrong_kind(kwargs, name, tmp_path):
    """``progress="no"`` was truthy and showed the bar; a path as ``stream`` failed at the first line
    written, after runs had been made."""
    with pytest.raises(ParameterError) as e:
        run_sweep(sweep_funcs.pendulum, GRID, tmp_path / "s", workers=1, **kwargs)
    assert e.value.name == name and not (tmp_path / "s").exists()


def test_dask_local_cluster_equals_serial(serial, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None) as cl:
        res = run_sweep(sweep_funcs.pendulum, GRID, tmp_path / "dask", scheduler=cl.scheduler_address,
                        progress=False)
    assert res.n_computed == GRID.n_runs
    xr.testing.assert_identical(_data(res.dataset), _data(serial.dataset))


# ---- failures ---------------------------------------------------------------------------------
def test_failing_point_is_reported_and_retried(tmp_path):
    grid = Grid(axes={"damping_Nms": [0.1, -0.05, 0.2], "length_m": [0.5]})
    out = tmp_path / "fail"
    res = run_sweep(sweep_funcs.pendulum, grid, out, workers=1, progress=False)
    assert not res.ok and res.n_computed == 2
    (f,) = res.failures
    assert f.point == {"damping_Nms": -0.05, "length_m": 0.5}
    assert f.error.startswith("DivergenceError: pendulum swing grows")
    assert "Traceback" in f.traceback and "sweep_funcs.py" in f.traceback
    record = json.loads((out / "runs" / f"{f.key}.failed.json").read_text())
    assert record["point"] == f.point and record["seed"] == f.seed and "DivergenceError" in record["error"]
    ds = res.dataset
    assert ds["run_failed"].sel(damping_Nms=-0.05).all() and np.isnan(ds["angle"].sel(damping_Nms=-0.05)).all()
    assert np.isfinite(ds["angle"].sel(damping_Nms=[0.1, 0.2])).all()
    assert json.loads(load_sweep(out).attrs["sweep_failures"])[0]["point"] == f.point
    with pytest.raises(SweepFailed, match=r"(?s)1 of 3 runs failed.*damping_Nms=-0\.05"):
        res.raise_if_failed()
    # A CLI maps SweepFailed to a non-zero exit; resuming retries the failed run (only it).
    stamp = (out / "runs" / f"{f.key}.failed.json").stat().st_mtime_ns
    again = run_sweep(sweep_funcs.pendulum, grid, out, workers=1, progress=False)
    assert again.n_reused == 2 and again.n_computed == 0 and len(again.failures) == 1
    assert (out / "runs" / f"{f.key}.failed.json").stat().st_mtime_ns != stamp


def test_failures_in_worker_processes(tmp_path):
    grid = Grid(axes={"damping_Nms": [0.1, -0.05, 0.2, -0.1], "length_m": [0.5]})
    res = run_sweep(sweep_funcs.pendulum, grid, tmp_path / "f", workers=2, batch=2, progress=False)
    assert sorted(f.point["damping_Nms"] for f in res.failures) == [-0.1, -0.05] and res.n_computed == 2
    # batched: a failing batch is split so that only the bad points fail
    res = run_sweep(sweep_funcs.pendulum_batch, grid, tmp_path / "fb", workers=1, batch=4, batched=True,
                    progress=False)
    assert sorted(f.point["damping_Nms"] for f in res.failures) == [-0.1, -0.05] and res.n_computed == 2


def test_lost_worker_process(tmp_path):
    """A run that kills its worker process is retried, then reported; the pool is rebuilt for the rest."""
    grid = Grid(axes={"damping_Nms": [0.1, 0.2, -1.0, 0.3, 0.4, 0.5], "length_m": [0.5]})
    res = run_sweep(sweep_funcs.pendulum_or_crash, grid, tmp_path / "crash", workers=2, batch=2, progress=False)
    (f,) = res.failures
    assert f.point["damping_Nms"] == -1.0 and f.error.startswith("WorkerLost: its worker process died 3 times")
    # the 5 healthy runs all have results; one that a worker saved just before its pool broke is found on
    # disk when its chunk is re-run alone and counts as reused (a race, seen on a loaded machine)
    assert res.n_computed + res.n_reused == 5
    assert not res.dataset["run_failed"].sel(damping_Nms=[0.1, 0.2, 0.3, 0.4, 0.5]).any()


def test_progress_lines_when_not_a_terminal(tmp_path):
    log = io.StringIO()  # not a tty: plain lines (for CI logs), then the summary
    grid = Grid(axes={"damping_Nms": [0.1, -0.05, 0.2, 0.3], "length_m": [0.5]})
    run_sweep(sweep_funcs.pendulum, grid, tmp_path / "p", workers=1, stream=log)
    text = log.getvalue()
    assert "sweep p: 4 runs of sweep_funcs.pendulum, 0 already in" in text  # the start line, by its store
    assert "sweep p: 4/4 runs (100%), 1 failed" in text and "runs/s" in text and "ETA" in text  # named by its store
    assert "sweep done" in text and "1 run(s) FAILED" in text and "damping_Nms=-0.05" in text


# ---- the store refuses what it should ---------------------------------------------------------
def test_a_sweep_folder_that_cannot_be_made_is_a_parameter_error(tmp_path):
    """Under a file, or on a pseudo file system: ``mkdir``'s NotADirectoryError / FileNotFoundError was
    raised as it came; now it names ``out_dir``, and nothing is left."""
    (tmp_path / "a_file").write_text("")
    grid = Grid(axes={"damping_Nms": [0.1], "length_m": [0.5]})
    for out in (tmp_path / "a_file" / "s", Path("/proc/undulate-sweep")):
        with pytest.raises(ParameterError, match="invalid out_dir: must be a folder that can be created") as e:
            run_sweep(sweep_funcs.pendulum, grid, out, workers=1, progress=False)
        assert e.value.name == "out_dir"
    assert [p.name for p in tmp_path.iterdir()] == ["a_file"]


def test_resume_into_other_sweep_is_refused(tmp_path):
    grid = Grid(axes={"damping_Nms": [0.1], "length_m": [0.5]})
    out = tmp_path / "s"
    run_sweep(sweep_funcs.pendulum, grid, out, workers=1, progress=False)
    other = Grid(axes={"damping_Nms": [0.1], "length_m": [0.5], "duration_s": [5.0]})
    with pytest.raises(ParameterError, match="holds a different one: grid parameters") as e:
        run_sweep(sweep_funcs.pendulum, other, out, workers=1, progress=False)
    assert e.value.name == "out_dir"
    with pytest.raises(ParameterError, match="function"):
        run_sweep(sweep_funcs.pendulum_batch, grid, out, workers=1, progress=False, batched=True)
    with pytest.raises(ParameterError, match="seed"):
        run_sweep(sweep_funcs.pendulum, Grid(axes=grid.axes, seed=1), out, workers=1, progress=False)
    with pytest.raises(ParameterError) as e:
        run_sweep(sweep_funcs.pendulum, grid, tmp_path / "new", scheduler=str(tmp_path / "no-scheduler.json"))
    assert e.value.name == "scheduler"
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "notes.txt").write_text("mine")
    with pytest.raises(ParameterError, match="no manifest.json"):
        run_sweep(sweep_funcs.pendulum, grid, tmp_path / "junk", workers=1, progress=False)


def test_grown_grid_reuses_shared_runs_bitwise(tmp_path):
    """A later stage's grid (more points, in another order) reuses every run it shares with the
    earlier one (runs are keyed by content), and equals the grown grid swept from scratch."""
    out = tmp_path / "s"
    small = Grid(axes={"damping_Nms": [0.1, 0.3], "length_m": [0.5]}, seed=4)
    run_sweep(sweep_funcs.pendulum, small, out, workers=1, progress=False)
    grown = Grid(axes={"damping_Nms": [0.05, 0.1, 0.2, 0.3], "length_m": [0.5]}, seed=4)
    res = run_sweep(sweep_funcs.pendulum, grown, out, workers=1, progress=False)
    assert (res.n_reused, res.n_computed) == (2, 2)
    fresh = run_sweep(sweep_funcs.pendulum, grown, tmp_path / "fresh", workers=1, progress=False)
    xr.testing.assert_identical(res.dataset.drop_attrs(), fresh.dataset.drop_attrs())
    back = run_sweep(sweep_funcs.pendulum, small, out, workers=1, progress=False)  # the smaller look again
    assert (back.n_reused, back.n_computed) == (2, 0)
    more = Grid(axes=small.axes, replicates=3, seed=4)  # more draws of the same points
    res = run_sweep(sweep_funcs.pendulum, more, out, workers=1, progress=False)
    assert (res.n_reused, res.n_computed) == (2, 4)
    np.testing.assert_array_equal(res.dataset["final_angle"].isel(replicate=0), back.dataset["final_angle"].isel(replicate=0))


# ---- interruption -----------------------------------------------------------------------------
KILL_GRID = dict(axes={"damping_Nms": [0.05, 0.1, 0.2, 0.4], "length_m": [0.3, 0.4, 0.5, 0.6, 0.7],
                       "duration_s": [20.0]}, replicates=2, seed=3)

_SCRIPT = """
import sys
sys.path.insert(0, {here!r})
import sweep_funcs
from undulate.sweep import Grid, run_sweep
run_sweep(sweep_funcs.pendulum, Grid(**{grid!r}), {out!r}, workers=2, batch=1, progress=True)
"""


def test_sigkill_then_resume(tmp_path):
    grid = Grid(**KILL_GRID)
    out = tmp_path / "killed"
    runs = out / "runs"
    script = _SCRIPT.format(here=str(HERE), grid=KILL_GRID, out=str(out))
    proc = subprocess.Popen([sys.executable, "-c", textwrap.dedent(script)], start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            if runs.is_dir() and len(list(runs.glob("*.nc"))) >= 6:
                break
            time.sleep(0.01)
        assert proc.poll() is None, proc.stderr.read().decode()
        os.killpg(proc.pid, signal.SIGKILL)  # the sweep and its workers, as an OOM killer or scancel would
    finally:
        proc.wait(30)
    saved = {p.name: p.stat().st_mtime_ns for p in runs.glob("*.nc")}
    assert 6 <= len(saved) < grid.n_runs, "the kill should land mid-way"

    res = run_sweep(sweep_funcs.pendulum, grid, out, workers=2, progress=False)
    assert res.ok
    assert res.n_reused == len(saved) and res.n_computed == grid.n_runs - len(saved)
    assert {p.name: p.stat().st_mtime_ns for p in runs.glob("*.nc") if p.name in saved} == saved  # not redone
    assert not list(out.rglob("*.tmp*"))  # no half-written file survives
    reference = run_sweep(sweep_funcs.pendulum, grid, tmp_path / "whole", workers=1, progress=False)
    xr.testing.assert_identical(_data(res.dataset), _data(reference.dataset))


# ---- real swimmers ----------------------------------------------------------------------------
def test_swimmer_pair_sweep(tmp_path):
    pytest.importorskip("undulate.simulation")
    grid = Grid(axes={"dphi_rad": [0.0, np.pi / 2], "duration_s": [1.0]})
    res = run_sweep(sweep_funcs.swimmer_pair, grid, tmp_path / "pair", workers=1, progress=False)
    assert res.ok, "\n".join(f.traceback for f in res.failures)
    ds = res.dataset
    assert ds["x"].dims == ("dphi_rad", "duration_s", "replicate", "time", "swimmer")
    assert ds["x"].attrs["units"] == "m"
    assert np.isfinite(ds["x"]).all()
    # the per-run phase coordinate differs between points, so it is stacked over the grid
    np.testing.assert_allclose(ds["phase"].isel(swimmer=1).squeeze().values, [0.0, np.pi / 2])


# ---- results always current: a sweep's identity is the fully bound call and the code ----
_SCALED = '''
import xarray as xr


def scaled(point, seed, *, scale={scale}):
    return xr.Dataset({{"v": ((), point["x"] * scale, {{"units": "m"}})}})
'''


def _scaled_module(tmp_path, scale, name="stale_fn_mod"):
    import importlib
    import sys

    (tmp_path / f"{name}.py").write_text(_SCALED.format(scale=scale))
    sys.path.insert(0, str(tmp_path))
    try:
        sys.modules.pop(name, None)
        importlib.invalidate_caches()
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(tmp_path))


def test_editing_a_default_recomputes_instead_of_reusing(tmp_path):
    """The issue's scenario: sweep f(point, seed, *, scale=1.0) into a folder, change the
    default to 2.0, sweep again into the same folder: the values are recomputed."""
    grid = Grid(axes={"x": [1.0, 2.0, 3.0]})
    out = tmp_path / "sweep"
    mod = _scaled_module(tmp_path, 1.0)
    first = run_sweep(mod.scaled, grid, out, workers=1, progress=False)
    assert list(first.dataset["v"].values.ravel()) == [1.0, 2.0, 3.0] and first.n_computed == 3
    again = run_sweep(mod.scaled, grid, out, workers=1, progress=False)
    assert again.n_reused == 3 and again.n_computed == 0 and not again.stale

    mod = _scaled_module(tmp_path, 2.0)
    second = run_sweep(mod.scaled, grid, out, workers=1, progress=False)
    assert list(second.dataset["v"].values.ravel()) == [2.0, 4.0, 6.0]
    assert second.n_computed == 3 and second.n_reused == 0
    assert any("scale=1.0" in s and "scale=2.0" in s for s in second.stale), second.stale
    merged = load_sweep(out)
    assert list(merged["v"].values.ravel()) == [2.0, 4.0, 6.0]
    assert "scale=2.0" in merged.attrs["sweep_function"]
    # each run file records the code and call that computed it
    from undulate.sweep._store import read_run_file

    _, meta = read_run_file(next((out / "runs").glob("*.nc")))
    assert meta["provenance"]["code"] == second.identity["code"] and "scale=2.0" in meta["provenance"]["function"]


def test_editing_code_but_not_arguments_recomputes(tmp_path):
    grid = Grid(axes={"x": [1.0]})
    mod = _scaled_module(tmp_path, 1.0, "stale_fn_mod2")
    run_sweep(functools.partial(mod.scaled, scale=3.0), grid, tmp_path / "s", workers=1, progress=False)
    src = (tmp_path / "stale_fn_mod2.py").read_text().replace('"units": "m"', '"units": "m", "note": "edited"')
    (tmp_path / "stale_fn_mod2.py").write_text(src)
    import importlib
    import sys

    sys.path.insert(0, str(tmp_path))
    try:
        sys.modules.pop("stale_fn_mod2", None)
        importlib.invalidate_caches()
        mod = importlib.import_module("stale_fn_mod2")
    finally:
        sys.path.remove(str(tmp_path))
    res = run_sweep(functools.partial(mod.scaled, scale=3.0), grid, tmp_path / "s", workers=1, progress=False)
    assert res.n_computed == 1 and res.stale and res.stale[0].startswith("code")


def test_bound_arguments_include_every_default():
    from undulate.sweep._store import bound_arguments, function_id

    def f(point, seed, *, scale=1.0, n=3):
        return None

    assert bound_arguments(f) == {"scale": "1.0", "n": "3"}
    assert bound_arguments(functools.partial(f, scale=2.0)) == {"scale": "2.0", "n": "3"}
    assert function_id(functools.partial(functools.partial(f, n=4), scale=0.5)).endswith("f(scale=0.5, n=4)")


def test_grid_from_dict_round_trips_and_rejects_unknown_keys():
    g = Grid(axes={"x": [1.0, 2.0]}, replicates=2, seed=5)
    assert Grid.from_dict(g.to_dict()) == g
    with pytest.raises(ParameterError, match="seeed"):
        Grid.from_dict({**g.to_dict(), "seeed": 1})


_EDITED_DURING_RUN = r"""
import os, sys
from pathlib import Path
import undulate
from undulate._source import SourceChangedError, code_hash
from undulate.studies._runners import pair_point
from undulate.sweep import Grid, run_sweep

before = code_hash(pair_point)
theory = Path(undulate.__file__).parent / "theory.py"
theory.write_text(theory.read_text() + "\n# edited while a long run was going\n")
os.utime(theory, ns=(theory.stat().st_atime_ns, theory.stat().st_mtime_ns + 10**9))
try:
    code_hash(pair_point)
except SourceChangedError as e:
    print("hash refused:", "theory.py" in str(e))
try:
    run_sweep(pair_point, Grid(axes={"dphi_rad": [0.0]}), sys.argv[1], workers=1, progress=False)
except SourceChangedError:
    print("sweep refused:", not (Path(sys.argv[1]) / "sweep.nc").exists())
print("before", before)
"""


def test_a_source_edit_during_a_run_is_refused_not_mislabelled(tmp_path):
    """The hash names the code the process runs: a package file edited on disk after `import undulate`
    (a user editing the code during a long reproduction) makes the next hash, and a sweep about to write
    its merged result, stop with a diagnosis; a fresh process gets the new hash."""
    import shutil
    import subprocess
    import sys

    import undulate

    pkg = tmp_path / "pkg"
    shutil.copytree(Path(undulate.__file__).parent, pkg / "undulate",
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "PYTHONPATH": str(pkg)}
    script = tmp_path / "edit.py"
    script.write_text(_EDITED_DURING_RUN)
    out = subprocess.run([sys.executable, str(script), str(tmp_path / "sweep")], env=env, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "hash refused: True" in out.stdout and "sweep refused: True" in out.stdout, out.stdout
    before = out.stdout.split("before ")[1].strip()
    fresh = subprocess.run([sys.executable, "-c", "from undulate._source import code_hash; from "
                            "undulate.studies._runners import pair_point; print(code_hash(pair_point))"],
                           env=env, capture_output=True, text=True, timeout=120)
    assert fresh.returncode == 0 and len(fresh.stdout.strip()) == 16 and fresh.stdout.strip() != before


# ---- the merge reads run files raw only where that is what xarray gives ---------------------------
@pytest.mark.parametrize("fn, axes, raw_rows", [
    (sweep_funcs.mixed, {"i": [0, 1, 2, 3], "kind": [0]}, 2),  # every run after the first raw
    (sweep_funcs.mixed, {"i": [0, 1, 2, 3], "kind": [1]}, 0),  # booleans and strings: xarray's
    (sweep_funcs.mixed, {"i": [0, 1, 2, 3], "kind": [2]}, 0),  # a fill value xarray masks by value
    (sweep_funcs.mixed, {"i": [0, 1, 2, 3], "kind": [3]}, 1),  # run 2's layout differs: read by xarray
    (sweep_funcs.mixed, {"i": [0, 1, 2, 3], "kind": [4]}, 0),  # netCDF-4 run files: xarray's
    (sweep_funcs.swimmer_pair, {"dphi_rad": [0.0, 1.0, 2.0, 3.0], "duration_s": [0.1]}, 2),
])
def test_the_merge_reading_run_files_raw_gives_what_xarray_gives(tmp_path, monkeypatch, fn, axes, raw_rows):
    """Merging a store whose run files are read raw (SciPy's netCDF-3 arrays, no Dataset per run)
    is identical to merging it through xarray, values, dtypes and attributes: with a missing run, NaN,
    int64, per-run coordinates and attributes; booleans, strings and value-dependent fill values stay
    xarray's, as does a file whose layout differs from the first run's."""
    from undulate.sweep import _fastread, _store

    grid = Grid(axes=axes, seed=3)
    res = run_sweep(fn, grid, tmp_path / "s", workers=1, progress=False)
    assert res.ok
    runs = grid.runs()
    runs_dir = tmp_path / "s" / "runs"
    _store.result_path(runs_dir, runs[1]).unlink()  # a run without a result: NaN and run_failed
    rows = []
    stack = _fastread.FastLayout.stack
    monkeypatch.setattr(_fastread.FastLayout, "stack", lambda self, raw, s, j, a: (rows.append(j), stack(self, raw, s, j, a)))
    fast = _store.merge(grid, runs, runs_dir)
    assert len(rows) == raw_rows
    monkeypatch.setattr(_fastread.FastLayout, "of", classmethod(lambda cls, *a: None))
    slow = _store.merge(grid, runs, runs_dir)
    xr.testing.assert_identical(fast, slow)
    assert all(fast[k].dtype == slow[k].dtype for k in fast.variables)
    assert bool(fast["run_failed"].values.ravel()[1]) and int(fast["run_failed"].sum()) == 1
    if fn is sweep_funcs.mixed:
        big = fast["big"].values.ravel()  # int64 made float by the missing run
        assert np.isnan(big[1]) and [int(b) % 2**20 for b in big[[0, 2, 3]]] == [0, 2, 3]
        assert fast.attrs["shared"] == "same" and "own" not in fast.attrs and "nan" not in fast.attrs
    if axes.get("kind") == [1]:  # strings merge as strings (a 0-d one was stored as an array: unwritable)
        assert list(fast["name"].values.ravel()) == ["n0", "", "n2", "n3"]


def test_progress_shows_a_batchs_stepping_beside_the_bar_on_a_terminal_and_as_lines_elsewhere():
    """:meth:`Progress.stepping`: on a terminal beside the tqdm bar, otherwise a plain line (at most
    one every ``every_s`` seconds, and always the end); nothing when disabled."""
    from undulate.sweep._progress import Progress

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    tty = Terminal()
    bar = Progress(4, 0, stream=tty)
    bar.stepping(1.0, 4.0, 7)
    bar.close()
    assert "stepping 7 worlds together: 25%" in tty.getvalue()
    plain = io.StringIO()
    lines = Progress(4, 0, stream=plain, every_s=3600.0)
    for done in (1.0, 2.0, 4.0):
        lines.stepping(done, 4.0, 7)
    assert [x.split(", elapsed")[0] for x in plain.getvalue().splitlines()] == [
        "sweep: stepping 7 worlds together, 100% of their simulated time"]  # the rest within every_s
    quiet = io.StringIO()
    Progress(4, 0, stream=quiet, enabled=False).stepping(4.0, 4.0, 7)
    assert quiet.getvalue() == ""
