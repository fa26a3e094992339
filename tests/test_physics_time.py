"""Physics time is measured where it happens: every sweep run file records its own
``mujoco.rollout`` seconds and scene-steps, and the sweep adds them up (serial or in
worker processes); timing is never part of a result (no timing is asserted)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import xarray as xr

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import sweep_funcs  # noqa: E402

from undulate.sweep import Grid, run_sweep  # noqa: E402
from undulate.sweep._store import read_run_file  # noqa: E402


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
    xr.testing.assert_identical(sweep_funcs.result_data(ser.dataset), sweep_funcs.result_data(res.dataset))  # timing is not part of the result
