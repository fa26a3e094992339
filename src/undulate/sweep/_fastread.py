"""Reading a sweep's run files for the merge without building a Dataset per run.

A merge reads every run file.  Through xarray (:func:`undulate.sweep._store.read_run_file`) a small
run file costs ~2 ms, most of it building the Dataset (CF decoding, indexes, alignment); SciPy's
netCDF-3 reader gives the same file's arrays in ~0.3 ms.  The merge reads its first run both ways
and uses the raw arrays for the others only where that is provably the same:

* every variable of the first run is *plain*: a float or integer whose decoding by xarray cannot
  depend on its values (no scale, offset, missing value, dtype or time encoding; a float's
  ``_FillValue`` only NaN, an integer none);
* each of its stacked variables, decoded raw (the run record's dtypes restored, as
  :func:`~undulate.sweep._store.read_run_file` does), equals xarray's: dims, dtype and values;
* every later run file has the first's layout byte for byte: the same variables, dims, shapes,
  dtypes, variable attributes, dtype record and ``coordinates`` attribute, and the same index
  coordinate values.

A file that fits none of this (another layout, a netCDF-4 file) is read through xarray as before.
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

RUN_ATTR = "sweep_run"
"""The run file's attribute that holds its run record (written by :func:`undulate.sweep._store.write_result`)."""
_VALUE_DEPENDENT = frozenset({"scale_factor", "add_offset", "missing_value", "dtype", "_Unsigned", "calendar",
                              "_Encoding", "valid_range", "valid_min", "valid_max", "compress"})
_MISSING = object()


@dataclass(frozen=True)
class RawRun:
    """One run file as SciPy reads it: ``variables`` ``{name: (dims, array, attrs)}``, the global
    ``attrs`` (without the run record) and the run record's ``dtypes``."""

    variables: dict[str, tuple[tuple[str, ...], np.ndarray, dict[str, Any]]]
    attrs: dict[str, Any]
    dtypes: dict[str, str]

    def decoded(self, name: str) -> np.ndarray:
        """Variable ``name``'s values with its recorded dtype restored (netCDF-3 stores int64 as int32)."""
        arr = self.variables[name][1]
        dt = self.dtypes.get(name)
        if dt is not None and np.dtype(dt).kind in "biuf" and arr.dtype != np.dtype(dt):
            return arr.astype(dt)
        return arr

    def layout(self) -> tuple:
        """What must be the same, byte for byte, for two files to decode the same way."""
        return (tuple((name, dims, arr.dtype.str, arr.shape, _attrs_key(a))
                      for name, (dims, arr, a) in sorted(self.variables.items())),
                tuple(sorted(self.dtypes.items())), _key(self.attrs.get("coordinates", _MISSING)))


def read_raw(path: Path) -> tuple[RawRun | None, dict[str, Any] | None, bytes]:
    """``(run, run record, file bytes)``; ``(None, None, bytes)`` for a file SciPy does not read
    (netCDF-4: the first bytes are not ``CDF``)."""
    import scipy.io

    data = path.read_bytes()
    if data[:3] != b"CDF":
        return None, None, data
    with scipy.io.netcdf_file(io.BytesIO(data), mmap=False) as nc:
        variables = {str(k): (tuple(v.dimensions), v.data, dict(v._attributes)) for k, v in nc.variables.items()}
        attrs = dict(nc._attributes)
    meta = json.loads(attrs.pop(RUN_ATTR, b"{}") or b"{}")
    return RawRun(variables, attrs, dict(meta.get("dtypes", {}))), meta, data


def _key(value: Any) -> Any:
    if isinstance(value, np.ndarray | np.generic):
        return value.dtype.str, value.shape, value.tobytes()
    return value


def _attrs_key(attrs: dict[str, Any]) -> tuple:
    return tuple((k, _key(v)) for k, v in sorted(attrs.items()))


def _plain(arr: np.ndarray, attrs: dict[str, Any]) -> bool:
    """Whether xarray's decoding of this variable cannot depend on its values."""
    if arr.dtype.kind not in "fiu" or _VALUE_DEPENDENT.intersection(attrs):
        return False
    units = attrs.get("units", b"")
    if b" since " in (units if isinstance(units, bytes) else str(units).encode()):
        return False
    if "_FillValue" in attrs:
        return arr.dtype.kind == "f" and bool(np.all(np.isnan(attrs["_FillValue"])))
    return True


class FastLayout:
    """The first run's layout, against which later run files are read raw (:meth:`of`)."""

    def __init__(self, raw: RawRun, names: list[str], indexes: list[str], attr_names: list[str]):
        self.layout = raw.layout()
        self.names = names
        self.indexes = {k: raw.variables[k][1] for k in indexes}
        self.attrs = {k: raw.attrs.get(k, _MISSING) for k in attr_names}

    @classmethod
    def of(cls, template: xr.Dataset, raw: RawRun | None, names: list[str]) -> FastLayout | None:
        """The layout of the first run (``template`` as xarray read it, ``raw`` as SciPy did;
        ``names``: its stacked variables), or None where raw reading would not give xarray's values."""
        if (raw is None or set(raw.variables) != {str(k) for k in template.variables}
                or not set(template.attrs) <= set(raw.attrs)):
            return None
        if not all(_plain(arr, a) for _, arr, a in raw.variables.values()):
            return None
        for name in [*names, *template.indexes]:
            var, dims = template[name].variable, raw.variables[name][0]
            val = raw.decoded(name)
            if (dims != var.dims or val.shape != var.shape
                    or val.dtype.newbyteorder("=") != var.dtype.newbyteorder("=")
                    or not np.array_equal(val, var.values, equal_nan=val.dtype.kind == "f")):
                return None
        return cls(raw, list(names), list(template.indexes), list(template.attrs))

    def fits(self, raw: RawRun | None) -> bool:
        """Whether ``raw`` decodes as the first run did and has its index coordinates."""
        return (raw is not None and raw.layout() == self.layout
                and all(np.array_equal(raw.variables[k][1], v) for k, v in self.indexes.items()))

    def stack(self, raw: RawRun, stacked: dict[str, np.ndarray], j: int, attrs: dict[str, Any]) -> None:
        """Row ``j`` of every stacked variable from ``raw``; drops from ``attrs`` those on which
        ``raw`` disagrees with the first run (compared as stored, as the merge compares them decoded)."""
        for name in self.names:
            stacked[name][j] = raw.decoded(name)
        for k in list(attrs):
            first, mine = self.attrs.get(k, _MISSING), raw.attrs.get(k, _MISSING)
            if first is _MISSING or mine is _MISSING or not same_attr(first, mine):
                del attrs[k]


def same_attr(a: Any, b: Any) -> bool:
    """Whether two attribute values are equal (arrays element-wise; NaN never equals NaN)."""
    try:
        return bool(np.array_equal(a, b)) if isinstance(a, np.ndarray) or isinstance(b, np.ndarray) else bool(a == b)
    except Exception:  # noqa: BLE001 - values that cannot be compared differ
        return False
