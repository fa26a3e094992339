"""Long runs in bounded memory: streaming to netCDF, reduced recordings, refusals (real runs)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from undulate import ParameterError, Scene, SimOptions, simulate, simulate_batch
from undulate.cli import app
from undulate.simulation import compile_scene

PAIR = Scene(phases_rad=(0.0, 1.0), dx0_m=0.02)


@pytest.mark.parametrize("flush_bytes", [1 << 20, 3000], ids=["one-flush", "many-flushes"])
@pytest.mark.parametrize("scene", [PAIR, Scene(phases_rad=(0.0,))], ids=["pair", "lone"])
def test_streamed_file_equals_the_in_memory_run_bitwise(tmp_path, scene, flush_bytes, monkeypatch):
    from undulate.simulation import _record

    monkeypatch.setattr(_record._NetCDFRecorder, "FLUSH_BYTES", flush_bytes)  # small: many appends
    opt = SimOptions(duration_s=3.0, sample_rate_hz=100, chunk_steps=137)  # chunks not aligned with samples
    mem = simulate(scene, opt)
    with simulate(scene, opt, out=tmp_path / "run.nc") as disk:  # lone: an empty pair dimension
        assert disk["x"].encoding.get("source")  # lazily backed by the file
        for name in mem.data_vars:
            np.testing.assert_array_equal(mem[name].values, disk[name].values, err_msg=name)
            assert mem[name].attrs == disk[name].attrs
        np.testing.assert_array_equal(mem["time"].values, disk["time"].values)
        assert json.loads(disk.attrs["config"]) == json.loads(mem.attrs["config"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.nc"]  # no temporary left


def test_batch_streams_each_scene_to_its_file(tmp_path):
    b = Scene(phases_rad=(0.0, -2.0), dx0_m=0.1)
    opt = SimOptions(duration_s=1.0)
    outs = simulate_batch([PAIR, b], opt, out=[tmp_path / "a.nc", tmp_path / "b.nc"])
    for ds, sc in zip(outs, (PAIR, b)):
        np.testing.assert_array_equal(ds["joint_angle"].values, simulate(sc, opt)["joint_angle"].values)
        ds.close()
    with pytest.raises(ParameterError, match="out"):
        simulate_batch([PAIR, b], opt, out=[tmp_path / "a.nc"])


def test_a_diverging_stream_leaves_no_file(tmp_path):
    from undulate import ContactModel, DivergenceError

    sc = Scene(phases_rad=(0.0, math.pi), contact=ContactModel(max_penetration_m=1e-5))
    with pytest.raises(DivergenceError):
        simulate(sc, SimOptions(duration_s=5.0), out=tmp_path / "run.nc")
    assert list(tmp_path.iterdir()) == []


def test_reduced_recording_keeps_only_what_is_asked_and_builds_no_pair_sensors():
    opt = SimOptions(duration_s=1.0, record=("x", "y", "penetration"))
    ds = simulate(PAIR, opt)
    assert sorted(ds.data_vars) == ["penetration", "x", "y"]
    np.testing.assert_array_equal(ds["x"].values, simulate(PAIR, SimOptions(duration_s=1.0))["x"].values)
    from undulate.simulation import resolve_options

    lean = compile_scene(PAIR, resolve_options(PAIR, opt))
    full = compile_scene(PAIR, resolve_options(PAIR, SimOptions(duration_s=1.0)))
    assert len(lean.index.sens_pair) == 0 and lean.model.nsensor == full.model.nsensor - 1
    with pytest.raises(ParameterError, match="record"):
        SimOptions(record=("x", "speed"))


def test_in_memory_recording_too_large_is_refused_before_stepping():
    with pytest.raises(ParameterError, match="duration_s / sample_rate_hz.*GiB"):
        simulate(PAIR, SimOptions(duration_s=1e7))


_RSS = textwrap.dedent("""
    import resource, sys, tempfile, os
    from undulate import Scene, SimOptions, simulate
    d = tempfile.mkdtemp()
    ds = simulate(Scene(phases_rad=(0.0, 1.0)), SimOptions(duration_s=float(sys.argv[1]), sample_rate_hz=500),
                  out=os.path.join(d, "run.nc"))
    n = ds.sizes["time"]; ds.close()
    print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, n)
""")


def _peak_rss(duration_s: float) -> tuple[int, int]:
    out = subprocess.run([sys.executable, "-c", _RSS, str(duration_s)], capture_output=True, text=True, check=True)
    rss, n = out.stdout.split()
    return int(rss), int(n)


def test_streaming_memory_does_not_grow_with_duration():
    (r1, n1), (r2, n2) = _peak_rss(40.0), _peak_rss(200.0)
    extra_samples_bytes = (n2 - n1) * 8 * 39  # 39 float64 per sample for a pair
    print(f"peak RSS {r1 / 2**20:.0f} MiB ({n1} samples) vs {r2 / 2**20:.0f} MiB ({n2} samples); "
          f"in memory the extra samples alone would take {extra_samples_bytes / 2**20:.0f} MiB")
    assert r2 - r1 < 0.2 * extra_samples_bytes


def test_cli_refuses_a_non_netcdf_output_and_writes_nothing(tmp_path):
    res = CliRunner().invoke(app, ["simulate", "--duration", "1", "--out", str(tmp_path / "run.txt")])
    assert res.exit_code == 2
    assert "--out" in res.output and ".nc" in res.output and "Traceback" not in res.output
    assert list(tmp_path.iterdir()) == []


def test_cli_streams_long_runs_to_the_file_and_reads_only_the_last_period(tmp_path):
    res = CliRunner().invoke(app, ["simulate", "--duration", "8", "--out", str(tmp_path / "run.nc")])
    assert res.exit_code == 0, res.output
    assert "pair 0-1" in res.output
    with xr.open_dataset(tmp_path / "run.nc", engine="h5netcdf") as ds:
        assert float(ds["time"][-1]) == pytest.approx(8.0)
