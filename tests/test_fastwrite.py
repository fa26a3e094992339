"""The run files' fast writer: byte for byte xarray's netCDF-3 file, or nothing (undulate.sweep._fastwrite)."""

import io
import json
import logging
import string
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from undulate.sweep import _fastwrite
from undulate.sweep._fastwrite import netcdf3_bytes, run_file_bytes
from undulate.sweep._store import RUN_ATTR, _run_file_bytes, read_run_file


def _xarray(ds: xr.Dataset) -> bytes:
    return bytes(ds.to_netcdf(engine="scipy", format="NETCDF3_64BIT"))


def _random_attrs(rng: np.random.Generator) -> dict:
    pool = {
        "units": lambda: "m",
        "long_name": lambda: "".join(rng.choice(list(string.printable[:90]), rng.integers(0, 40))),
        "note": lambda: "é ≤ 1 mm",  # not ASCII: UTF-8 bytes
        "empty": lambda: "",
        "count": lambda: int(rng.integers(-2**31, 2**31 - 1)),
        "npint": lambda: np.int64(rng.integers(-1000, 1000)),
        "scale": lambda: float(rng.normal()),
        "single": lambda: np.float32(rng.normal()),
        "nan_attr": lambda: float("nan"),
        "vector": lambda: rng.normal(size=int(rng.integers(1, 6))),
        "ivector": lambda: rng.integers(-5, 5, size=int(rng.integers(1, 6))),
        "fvector32": lambda: rng.normal(size=3).astype(np.float32),
    }
    keys = rng.choice(list(pool), size=int(rng.integers(0, len(pool))), replace=False)
    return {str(k): pool[str(k)]() for k in keys}


def _random_dataset(rng: np.random.Generator) -> xr.Dataset:
    sizes = {d: int(rng.integers(0 if d == "empty" else 1, 7)) for d in ("time", "swimmer", "pair", "empty")}
    dims = list(sizes)
    rng.shuffle(dims)
    data_vars = {}
    for i in range(int(rng.integers(1, 9))):
        vd = tuple(dims[: int(rng.integers(0, 4))])
        shape = tuple(sizes[d] for d in vd)
        dtype = rng.choice(["float64", "float32", "int64", "int32"])
        if dtype.startswith("float"):
            a = rng.normal(size=shape).astype(dtype)
            if a.size:
                a.flat[0] = np.nan
                a.flat[-1] = np.inf if rng.random() < 0.5 else a.flat[-1]
        else:
            a = rng.integers(-2**31, 2**31 - 1, size=shape).astype(dtype)
        attrs = _random_attrs(rng)
        if dtype.startswith("int"):
            attrs.pop("units", None)
        data_vars[f"v{i}_{dtype}"] = (vd, a, attrs)
    coords = {}
    if rng.random() < 0.7:
        coords["time"] = ("time", np.arange(sizes["time"]) * 0.1, {"units": "s"})
    return xr.Dataset(data_vars, coords=coords, attrs=_random_attrs(rng))


def test_random_plain_datasets_are_xarrays_bytes():
    """Datasets of every plain kind (dims in any order, 0-d to 3-d, NaN and inf, int64 stored as int32,
    attributes of every kind, empty dimensions): the same bytes as xarray's SciPy engine."""
    rng = np.random.default_rng(7)
    plain = 0
    for _ in range(300):
        ds = _random_dataset(rng)
        fast = netcdf3_bytes(ds)
        if any(v.ndim and v.shape[0] == 0 for v in ds.variables.values()):
            assert fast is None  # a record variable to SciPy
            continue
        assert fast is not None
        assert fast == _xarray(ds)
        plain += 1
    assert plain > 200


def test_real_runs_are_xarrays_bytes():
    """What the runners return, stamped as write_result stamps it (the run record), and a simulation's
    series with every attribute the stepping gives them (end state, warm start, provenance, units)."""
    from undulate import Scene, SimOptions, simulate
    from undulate.studies._runners import group_point

    record = json.dumps({"point": {"dphi_rad": 0.5}, "seed": 1, "dtypes": {"x": "<f8"}})
    run = group_point({"dphi_rad": 0.5}, 1, n_swimmers=3, duration_s=0.3).assign_attrs({RUN_ATTR: record})
    sim = simulate(Scene(phases_rad=(0.0, 0.5)), SimOptions(duration_s=0.3, sample_rate_hz=20.0))
    assert netcdf3_bytes(sim) is None  # a string coordinate (wall) and a non-index one (phase)
    series = sim[["x", "y", "joint_error", "penetration"]].reset_coords(drop=True).assign_attrs({RUN_ATTR: record})
    assert {"end_state", "end_warmstart", "physics_steps"} <= set(series.attrs)
    for ds in (run, series):
        fast = netcdf3_bytes(ds)
        assert fast is not None and fast == _xarray(ds)
        back, meta = read_run_file(Path("unused"), fast)
        assert meta["seed"] == 1
        xr.testing.assert_identical(back.drop_attrs(), ds.drop_attrs())
        np.testing.assert_array_equal(back.attrs.get("end_state", 0), ds.attrs.get("end_state", 0))


@pytest.mark.parametrize("make", [
    lambda: xr.Dataset({"b": ("t", np.array([True, False]))}),  # bool: int8 with a dtype attribute
    lambda: xr.Dataset({"s": ("t", np.array(["a", "bc"]))}),  # strings: character arrays
    lambda: xr.Dataset({"i": ("t", np.array([2**40, 1]))}),  # int64 beyond int32: xarray refuses it
    lambda: xr.Dataset({"i": ("t", np.array([1, 2]), {"units": "s"})}),  # integer time units
    lambda: xr.Dataset({"x": ("t", [1.0, 2.0])}, coords={"c": ("t", [3.0, 4.0])}),  # non-index coordinate
    lambda: xr.Dataset({"x": ("t", [1.0, 2.0], {"_FillValue": -1.0})}),
    lambda: xr.Dataset({"x": ("t", np.array([1, 2], dtype=np.int16))}),  # padded types
    lambda: xr.Dataset({"x y": ("t", [1.0])}),  # a name netCDF-3 may refuse
    lambda: xr.Dataset({"x": (("t", "s"), np.zeros((0, 2)))}),  # SciPy: a record variable
    lambda: xr.Dataset({"x": ("t", [1.0])}, attrs={"flag": True}),
    lambda: xr.Dataset({"x": ("t", [1.0])}, attrs={"m": np.zeros((2, 2))}),
    lambda: xr.Dataset({"x": ("t", [1.0])}, attrs={"big": 2**40}),
    lambda: xr.Dataset({"x": ("t", [1.0])}, attrs={"l": [1.0, 2.0]}),
])
def test_what_is_not_plain_is_left_to_xarray(make):
    assert netcdf3_bytes(make()) is None


def test_encoded_variables_are_left_to_xarray():
    ds = xr.Dataset({"x": ("t", [1.0, 2.0])})
    ds["x"].encoding["dtype"] = "int16"
    assert netcdf3_bytes(ds) is None


def test_first_of_a_layout_is_compared_and_a_mismatch_sticks(monkeypatch, caplog):
    monkeypatch.setattr(_fastwrite, "_checked", {})
    ds = xr.Dataset({"x": ("t", [1.0, 2.0])}, attrs={"k": "v"})
    calls = []

    def wrong(d):  # an xarray that writes otherwise
        calls.append(d)
        return b"other"

    with caplog.at_level(logging.WARNING, logger="undulate.sweep._fastwrite"):
        assert run_file_bytes(ds, wrong) == b"other"
        assert run_file_bytes(ds.assign(x=("t", [3.0, 4.0])), wrong) == b"other"
    assert len(calls) == 2 and "written through xarray" in caplog.text
    # a layout whose first Dataset matched is then written without xarray
    ds2 = xr.Dataset({"y": ("t", [1.0, 2.0])})
    calls.clear()
    assert run_file_bytes(ds2, lambda d: (calls.append(d), _xarray(d))[1]) == _xarray(ds2)
    ds3 = ds2.assign(y=("t", [5.0, 6.0, 7.0]))  # another length, the same layout
    assert run_file_bytes(ds3, lambda d: (calls.append(d), _xarray(d))[1]) == _xarray(ds3)
    assert len(calls) == 1


def test_store_writes_what_it_read(tmp_path):
    """write_result through the fast writer: the run file reads back as the Dataset written."""
    from undulate.sweep import Grid
    from undulate.sweep._store import result_path, write_result

    run = next(iter(Grid(axes={"a": [1.0]}, seed=0).runs()))
    ds = xr.Dataset({"x": (("time", "swimmer"), np.arange(6.0).reshape(3, 2), {"units": "m"}),
                     "n": ((), np.int64(4))}, coords={"time": ("time", [0.0, 0.1, 0.2], {"units": "s"})},
                    attrs={"stop_rule": "none", "physics_steps": 300, "end_state": np.arange(4.0)})
    write_result(tmp_path, run, ds, {"code": "x"})
    data = result_path(tmp_path, run).read_bytes()
    assert data[:4] == b"CDF\x02"
    back, meta = read_run_file(result_path(tmp_path, run), data)
    assert back["n"].dtype == np.int64 and int(back["n"]) == 4
    np.testing.assert_array_equal(back["x"].values, ds["x"].values)
    np.testing.assert_array_equal(back.attrs["end_state"], np.arange(4.0))
    assert meta["provenance"]["code"] == "x"
    assert _run_file_bytes(back.assign_attrs({RUN_ATTR: json.dumps(meta)})) is not None
    assert io.BytesIO(data).read(3) == b"CDF"
