"""Writing a run file without xarray's encoding machinery: the same bytes, a fraction of the time.

Every finished run is written once (:func:`undulate.sweep._store.write_result`).  Through xarray's
SciPy engine a small run's netCDF-3 file costs ~1 ms of Python (CF encoding, attribute checks,
SciPy's writer), which on a GPU, where a batch of a thousand runs steps in seconds, is a large part
of a sweep's host time (docs/gpu.md, "The host's share of a sweep").  :func:`netcdf3_bytes` writes
the file itself, byte for byte what ``ds.to_netcdf(engine="scipy", format="NETCDF3_64BIT")`` writes,
for the *plain* Datasets the runners return:

* variables of float64 or float32 (written with xarray's default ``_FillValue`` NaN), or of int64
  or int32 without units (int64 stored as int32, as xarray does, only where every value fits);
* no variable whose first dimension has length 0 (SciPy would write it as a record variable);
* coordinates only along their own dimension (no ``coordinates`` attribute is needed), no
  unlimited dimension, and no encoding carried over from a file;
* names of letters, digits and ``_``; attributes of str, float, int or 1-D numeric arrays
  (booleans are left to xarray, which stores them as int8).

Anything else returns None and the caller writes through xarray, as before.  The first Dataset of
each layout in a process is written both ways and compared: a layout whose bytes differ (an xarray
or SciPy release that writes otherwise) is written through xarray from then on, and says so once.
``tests/test_fastwrite.py`` compares the bytes on many Datasets.
"""

from __future__ import annotations

import logging
import re
import struct
import threading
from typing import Any

import numpy as np
import xarray as xr

log = logging.getLogger(__name__)

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_NC_CHAR, _NC_INT, _NC_FLOAT, _NC_DOUBLE = 2, 4, 5, 6
_NC_DIMENSION, _NC_VARIABLE, _NC_ATTRIBUTE = 10, 11, 12
_ABSENT = b"\x00" * 8
_NC_TYPE = {"i4": _NC_INT, "f4": _NC_FLOAT, "f8": _NC_DOUBLE}
_INT32 = np.iinfo(np.int32)

_checked: dict[tuple, bool] = {}  # layout -> its bytes equal xarray's (first Dataset of that layout)
_lock = threading.Lock()


class _NotPlain(Exception):
    """The Dataset needs xarray's encoding (or xarray would refuse it)."""


def _int32(a: np.ndarray) -> np.ndarray:
    if a.dtype == np.int32:
        return a
    if a.size and (a.min() < _INT32.min or a.max() > _INT32.max):
        raise _NotPlain  # xarray raises here; the caller falls back to netCDF-4
    return a.astype(np.int32)


def _attr(value: Any) -> tuple[int, np.ndarray]:
    """An attribute value as xarray encodes it for netCDF-3 (``encode_nc3_attr_value``): its
    netCDF type and big-endian values."""
    if isinstance(value, str):
        a = np.asarray(value.encode("utf-8"), dtype="S")
        return _NC_CHAR, a
    if isinstance(value, bool | np.bool_):
        raise _NotPlain  # int8 (NC_BYTE): left to xarray
    if isinstance(value, int | np.integer):
        a = np.atleast_1d(np.asarray(value))
    elif isinstance(value, float | np.floating):
        a = np.atleast_1d(np.asarray(value))
    elif isinstance(value, np.ndarray) and value.ndim <= 1 and value.dtype.kind in "if":
        a = np.atleast_1d(value)
    else:
        raise _NotPlain
    if a.dtype.kind == "i":
        a = _int32(a.astype(np.int64, copy=False))
    elif a.dtype not in (np.float64, np.float32):
        raise _NotPlain
    return _NC_TYPE[a.dtype.str[1:]], a.astype(a.dtype.newbyteorder(">"), copy=False)


def _variable(name: str, var: xr.Variable) -> tuple[tuple[str, ...], np.ndarray, dict[str, Any]]:
    """``(dims, big-endian data, attrs)`` of one variable as xarray writes it."""
    if not _NAME.match(name) or var.encoding or any(not _NAME.match(str(d)) for d in var.dims):
        raise _NotPlain
    attrs = dict(var.attrs)
    if any(not isinstance(k, str) or not _NAME.match(k) for k in attrs):
        raise _NotPlain
    data = np.asarray(var.values)
    kind, size = data.dtype.kind, data.dtype.itemsize
    if kind == "f" and size in (4, 8):
        if "_FillValue" in attrs or "missing_value" in attrs:
            raise _NotPlain
        attrs["_FillValue"] = data.dtype.type(np.nan)  # xarray's default for floats
    elif kind == "i" and size in (4, 8) and "units" not in attrs:  # (int "time" units: xarray's own rule)
        if "_FillValue" in attrs or "missing_value" in attrs or "dtype" in attrs:
            raise _NotPlain
        data = _int32(data)
    else:
        raise _NotPlain
    return tuple(str(d) for d in var.dims), data.astype(data.dtype.newbyteorder(">"), copy=False), attrs


def _string(out: bytearray, s: str) -> None:
    b = s.encode("latin1")
    out += struct.pack(">i", len(b)) + b + b"\x00" * (-len(b) % 4)


def _attrs(out: bytearray, attrs: dict[str, Any]) -> None:
    if not attrs:
        out += _ABSENT
        return
    out += struct.pack(">ii", _NC_ATTRIBUTE, len(attrs))
    for k, v in attrs.items():
        _string(out, k)
        nc_type, a = _attr(v)
        n = a.itemsize if nc_type == _NC_CHAR else a.size
        raw = a.tobytes()
        out += struct.pack(">ii", nc_type, n) + raw + b"\x00" * (-len(raw) % 4)


def netcdf3_bytes(ds: xr.Dataset) -> bytes | None:
    """``ds`` as xarray's SciPy engine writes it (``format="NETCDF3_64BIT"``), or None where ``ds``
    is not plain (see the module's docstring)."""
    try:
        for name, c in ds.coords.items():
            if c.dims != (name,):
                raise _NotPlain
        if any(not isinstance(k, str) or not _NAME.match(k) for k in ds.attrs):
            raise _NotPlain
        variables = {str(k): _variable(str(k), v) for k, v in ds.variables.items()}
        if any(data.ndim and data.shape[0] == 0 for _, data, _ in variables.values()):
            raise _NotPlain  # SciPy takes a first dimension of length 0 for the record dimension
        dims: dict[str, int] = {}
        for vdims, data, _ in variables.values():  # xarray's order: as the variables name them
            dims.update(zip(vdims, data.shape))
        out = bytearray(b"CDF\x02")
        out += struct.pack(">i", 0)  # no record dimension
        if dims:
            out += struct.pack(">ii", _NC_DIMENSION, len(dims))
            for d, n in dims.items():
                _string(out, d)
                out += struct.pack(">i", n)
        else:
            out += _ABSENT
        _attrs(out, dict(ds.attrs))
        if not variables:
            out += _ABSENT
            return bytes(out)
        order = sorted(variables, key=lambda k: variables[k][1].shape, reverse=True)  # SciPy's order
        dim_ids = {d: i for i, d in enumerate(dims)}
        out += struct.pack(">ii", _NC_VARIABLE, len(variables))
        begins = []
        for name in order:
            vdims, data, attrs = variables[name]
            _string(out, name)
            out += struct.pack(">i", len(vdims)) + b"".join(struct.pack(">i", dim_ids[d]) for d in vdims)
            _attrs(out, attrs)
            out += struct.pack(">ii", _NC_TYPE[data.dtype.str[1:]], data.nbytes)  # (4-byte types: no padding)
            begins.append(len(out))
            out += b"\x00" * 8
        for name, at in zip(order, begins):
            out[at:at + 8] = struct.pack(">q", len(out))
            out += variables[name][1].tobytes()
        return bytes(out)
    except _NotPlain:
        return None


def _layout(ds: xr.Dataset) -> tuple:
    """What decides how a plain Dataset is written, apart from its values and sizes (runs of one
    sweep that stop at different times share a layout)."""
    def kinds(attrs: dict) -> tuple:
        return tuple((k, type(v).__name__, getattr(v, "dtype", None), np.ndim(v)) for k, v in attrs.items())

    return (tuple((str(k), v.dims, v.dtype.str, kinds(v.attrs)) for k, v in ds.variables.items()),
            kinds(ds.attrs), tuple(ds.coords))


def run_file_bytes(ds: xr.Dataset, through_xarray) -> bytes:
    """A run file's bytes: :func:`netcdf3_bytes` where it applies and its layout has been checked
    against ``through_xarray(ds)`` (the first Dataset of each layout is written both ways);
    ``through_xarray(ds)`` otherwise."""
    fast = netcdf3_bytes(ds)
    if fast is None:
        return through_xarray(ds)
    key = _layout(ds)
    with _lock:
        ok = _checked.get(key)
    if ok is None:
        slow = through_xarray(ds)
        ok = slow == fast
        with _lock:
            _checked[key] = ok
        if not ok:
            log.warning("run files of this layout are written through xarray: the fast writer's bytes "
                        "differ from xarray's (xarray %s)", xr.__version__)
        return slow
    return fast if ok else through_xarray(ds)
