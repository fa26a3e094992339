"""What the speed work must not change, and what it must record (no timing is asserted).

* physics time is measured where it happens: every run file records its own
  rollout seconds and steps, and the sweep adds them up;
* one warm pool of worker processes serves the sweeps of a study or a
  reproduction (the same processes), gives the serial results, and is
  replaced when one of its processes dies;
* xarray no longer imports Dask for NumPy-only data, and Dask arrays still work;
* ``--workers`` is validated.
"""

from __future__ import annotations

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
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import sweep_funcs  # noqa: E402

from undulate.sweep import Grid, run_sweep, warm_workers  # noqa: E402
from undulate.sweep import _executors  # noqa: E402
from undulate.sweep._store import read_run_file  # noqa: E402

CLI = [sys.executable, "-m", "undulate.cli"]


def _data(ds: xr.Dataset) -> xr.Dataset:
    ds = ds.copy()
    ds.attrs = {k: v for k, v in ds.attrs.items() if not k.startswith("provenance_")}
    return ds


def test_physics_time_is_recorded_per_run_and_summed(tmp_path):
    from undulate.params import Scene, SimOptions
    from undulate.simulation import resolve_options

    grid = Grid(axes={"dphi_rad": [0.0, 1.0, 2.0], "duration_s": [1.0]})
    res = run_sweep(sweep_funcs.swimmer_pair, grid, tmp_path / "s", workers=2, batch=1, progress=False)
    assert res.ok
    n_steps = resolve_options(Scene(phases_rad=(0.0, 1.0)), SimOptions(duration_s=1.0)).n_steps
    timings = [read_run_file(p)[1]["timing"] for p in sorted((tmp_path / "s" / "runs").glob("*.nc"))]
    assert len(timings) == 3
    for t in timings:
        assert t["steps"] == n_steps  # one scene stepped n_steps times, counted in the worker
        assert 0 < t["physics_s"] <= t["wall_s"]
    assert res.timing["executor"] == "local" and res.timing["steps"] == 3 * n_steps
    assert res.timing["physics_s"] == pytest.approx(sum(t["physics_s"] for t in timings))
    # in this process (serial) the same counts
    ser = run_sweep(sweep_funcs.swimmer_pair, grid, tmp_path / "ser", workers=1, progress=False)
    assert ser.timing["executor"] == "serial" and ser.timing["steps"] == 3 * n_steps
    xr.testing.assert_identical(_data(ser.dataset), _data(res.dataset))  # timing is not part of the result


def _pids(res) -> set[int]:
    return set(int(p) for p in np.ravel(res.dataset["pid"].values))


def test_warm_workers_serve_every_sweep_with_the_same_processes(tmp_path):
    grid_a = Grid(axes={"k": list(range(8))})
    grid_b = Grid(axes={"k": list(range(8, 16))})
    with warm_workers():
        a = run_sweep(sweep_funcs.worker_pid, grid_a, tmp_path / "a", workers=2, batch=1, progress=False)
        b = run_sweep(sweep_funcs.worker_pid, grid_b, tmp_path / "b", workers=2, batch=1, progress=False)
        assert a.ok and b.ok and os.getpid() not in _pids(a)
        assert len(_pids(a) | _pids(b)) <= 2  # one pool of two processes served both
        pool = _executors._WARM["pool"]
        assert pool is not None
    assert _executors._WARM["pool"] is None  # stopped when the context exits
    # outside the context every sweep starts (and stops) its own processes
    c = run_sweep(sweep_funcs.worker_pid, grid_a, tmp_path / "c", workers=2, batch=1, progress=False)
    d = run_sweep(sweep_funcs.worker_pid, grid_b, tmp_path / "d", workers=2, batch=1, progress=False)
    assert not (_pids(c) & _pids(d)) and not (_pids(c) & (_pids(a) | _pids(b)))


def test_warm_pool_gives_the_serial_results_and_resumes(tmp_path):
    grid = Grid(axes={"damping_Nms": [0.05, 0.1, 0.2], "length_m": [0.3, 0.5]}, replicates=2, seed=7)
    ref = run_sweep(sweep_funcs.pendulum, grid, tmp_path / "serial", workers=1, progress=False)
    with warm_workers():
        warm = run_sweep(sweep_funcs.pendulum, grid, tmp_path / "warm", workers=2, batch=2, progress=False)
        again = run_sweep(sweep_funcs.pendulum, grid, tmp_path / "warm", workers=2, batch=2, progress=False)
    xr.testing.assert_identical(_data(warm.dataset), _data(ref.dataset))
    assert again.n_computed == 0 and again.n_reused == grid.n_runs


def test_warm_pool_replaced_when_a_waiting_worker_dies(tmp_path):
    grid = Grid(axes={"k": list(range(6))})
    with warm_workers():
        first = run_sweep(sweep_funcs.worker_pid, grid, tmp_path / "a", workers=2, batch=1, progress=False)
        victim = min(_pids(first))
        os.kill(victim, signal.SIGKILL)  # dies while the pool waits between sweeps
        for _ in range(100):  # the pool's manager thread notices
            if getattr(_executors._WARM["pool"], "_broken", False):
                break
            time.sleep(0.05)
        second = run_sweep(sweep_funcs.worker_pid, Grid(axes={"k": list(range(6, 12))}), tmp_path / "b",
                           workers=2, batch=1, progress=False)
    assert second.ok and second.n_computed == 6 and victim not in _pids(second)


def test_a_crash_inside_a_warm_pool_is_isolated_as_without_it(tmp_path):
    grid = Grid(axes={"damping_Nms": [0.1, 0.2, -1.0, 0.3, 0.4, 0.5], "length_m": [0.5]})
    with warm_workers():
        res = run_sweep(sweep_funcs.pendulum_or_crash, grid, tmp_path / "crash", workers=2, batch=2, progress=False)
        after = run_sweep(sweep_funcs.worker_pid, Grid(axes={"k": [1, 2, 3, 4]}), tmp_path / "after",
                          workers=2, batch=1, progress=False)
    (f,) = res.failures
    assert f.point["damping_Nms"] == -1.0 and f.error.startswith("WorkerLost")
    assert res.n_computed == 5 and after.ok


def test_no_dask_import_for_numpy_data_and_dask_arrays_still_work():
    pytest.importorskip("dask")
    code = textwrap.dedent("""
        import sys
        from undulate import Scene, SimOptions, simulate
        ds = simulate(Scene(phases_rad=(0.0, 1.0)), SimOptions(duration_s=0.5))
        ds.to_netcdf(sys.argv[1], engine="h5netcdf")
        print("dask" in sys.modules, "dask.array" in sys.modules, "distributed" in sys.modules)
        import dask.array as da
        import xarray as xr
        from xarray.namedarray.pycompat import array_type, is_duck_dask_array
        a = xr.DataArray(da.arange(6, chunks=3), dims="x")
        assert is_duck_dask_array(a.data) and a.chunks == ((3, 3),) and array_type("dask") == (da.Array,)
        b = ds["x"].chunk({"time": 10})
        assert is_duck_dask_array(b.data) and abs(float(b.sum().compute()) - float(ds["x"].sum())) < 1e-12
        print("ok")
    """)
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        r = subprocess.run([sys.executable, "-c", code, str(Path(d) / "r.nc")], capture_output=True, text=True,
                           timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["False", "False", "False", "ok"]


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


def test_vectorized_bootstrap_equals_one_call_per_resample():
    """The statistics the studies bootstrap (R^2, Spearman with ties, RMS, std) are evaluated on every
    resample at once; same resamples, the same numbers as one Python call per resample (to rounding)."""
    from scipy import stats as st

    from undulate import stats

    rng = np.random.default_rng(5)
    for n in (4, 9, 30, 120):
        x = rng.normal(size=n)
        y = np.round(2 * x + rng.normal(size=n))  # ties
        y[: max(1, n // 10)] = y[0]
        pairs = [
            (lambda a, b: float(np.corrcoef(a, b)[0, 1] ** 2) if np.ptp(a) and np.ptp(b) else np.nan,
             lambda a, b, axis=-1: stats._pearson_rows(a, b, axis) ** 2, (x, y)),
            (lambda a, b: float(st.spearmanr(a, b).statistic) if np.ptp(a) and np.ptp(b) else np.nan,
             lambda a, b, axis=-1: stats._pearson_rows(st.rankdata(a, axis=axis), st.rankdata(b, axis=axis), axis),
             (x, y)),
            (lambda a: float(np.sqrt(np.mean(a * a))), lambda a, axis=-1: np.sqrt(np.mean(a * a, axis=axis)), (y,)),
            (lambda a: float(np.std(a)), lambda a, axis=-1: np.std(a, axis=axis), (y,)),
        ]
        for one, rows, samples in pairs:
            ref = stats.bootstrap(one, *samples, seed=11)
            vec = stats.bootstrap(rows, *samples, seed=11, vectorized=True)
            np.testing.assert_allclose(vec, ref, rtol=1e-12, atol=1e-14, equal_nan=True)


def _search(column_above, failed_at=(), known=()):
    """Run bisection_probes to the end on a synthetic column; the indices it ran."""
    from undulate.studies.packing import bisection_probes

    m = len(column_above)
    ran = {j: (None if j in failed_at else bool(column_above[j])) for j in known}
    while True:
        nxt = bisection_probes(ran, m)
        if not nxt:
            return ran
        assert not (set(nxt) & set(ran))
        for j in nxt:
            ran[j] = None if j in failed_at else bool(column_above[j])


def test_bisection_finds_the_whole_columns_threshold():
    from undulate.studies.packing import density_threshold

    rng = np.random.default_rng(0)
    rho = np.round(np.r_[0.5, np.arange(1.0, 4.01, 0.25), np.arange(4.5, 6.51, 0.5)], 10)
    m = rho.size
    for trial in range(300):
        first = int(rng.integers(0, m + 1))  # m: never above
        excess = np.sort(rng.normal(size=m)) - 10.0
        excess[first:] = np.abs(excess[first:]) + 1e-3  # monotone sign: below, then above
        known = tuple(rng.choice(m, size=int(rng.integers(0, 6)), replace=False))
        failed_at = (int(rng.integers(0, m)),) if trial % 5 == 0 else ()
        ran = _search(excess > 0, failed_at, known)
        e = np.full(m, np.nan)
        bad = np.zeros(m, bool)
        for j, v in ran.items():
            e[j] = np.nan if v is None else excess[j]
            bad[j] = v is None
        whole_bad = np.zeros(m, bool)
        whole_bad[list(failed_at)] = True
        whole = density_threshold(rho, np.where(whole_bad, np.nan, excess), whole_bad)
        assert density_threshold(rho, e, bad) == pytest.approx(whole, nan_ok=True)
        if not failed_at:
            assert len(ran) <= len(known) + int(np.ceil(np.log2(m + 1))) + 1
    # a column that is not monotone is searched whole
    col = np.array([False, True, False, True, True])
    assert set(_search(col, known=(0, 1, 2))) == set(range(5))


def test_packing_threshold_by_bisection_equals_the_whole_grid(tmp_path):
    """Real runs (10 swimmers, 2 s): the thresholds found by bisection with a coarse heatmap are
    the whole grid's, from fewer runs."""
    from undulate import studies
    from undulate.studies import packing

    kw = dict(draws=2, n_swimmers=10, duration_s=2.5)
    phi, rho = [0.0, 2 * np.pi], [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]

    def run(out, plan):
        ctx = studies.StudyContext(studies.StudyConfig(out_dir=out, quick=True), "packing", progress=False)
        return packing.dataset(ctx, plan)

    whole = run(tmp_path / "whole", packing.PackingPlan(phi, rho, **kw))
    bis = run(tmp_path / "bisect", packing.PackingPlan(phi, rho, heatmap_rho=[1.0, 6.0], heatmap_draws=1, **kw))
    assert bool(whole["evaluated"].all()) and whole.attrs["bisection_rounds"] == 0
    assert int(bis["evaluated"].sum()) < int(whole["evaluated"].sum()) and bis.attrs["bisection_rounds"] >= 1
    for v in ("threshold_rho_tilde", "threshold_lo", "threshold_hi"):
        np.testing.assert_array_equal(bis[v].values, whole[v].values)
    assert np.isfinite(whole["threshold_rho_tilde"].values).any()
    # every run the bisection did is the whole grid's run, bit for bit
    ev = bis["evaluated"].values
    np.testing.assert_array_equal(bis["mean_joint_error"].values[ev], whole["mean_joint_error"].values[ev])
    packing.summary(bis)
    packing.figure(bis).savefig(tmp_path / "packing.png")
