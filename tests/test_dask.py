"""xarray imports Dask only for Dask data: a NumPy-only simulation never loads it
(undulate._xrcompat), and Dask arrays still work once Dask is imported."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest


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
