"""The on-disk store of a sweep: one file per finished run, merged at the end.

Layout of ``out_dir``::

    manifest.json              what sweep this is (function, grid); checked on resume
    runs/p3f9c0a1b2d4e5f60_r000.nc           a finished run (the fn's Dataset + its point and seed)
    runs/p0b1e77c24a9d3e81_r000.failed.json  a run that raised: point, seed, error, traceback
    sweep.nc                   the merged Dataset (rewritten at the end of every call)
    .lock                      held (flock) by the process running the sweep

Every file is written to a unique temporary name in the same folder and
``os.replace``-d into place, so a name that exists is complete: the rename is
the completion marker.  A process killed at any moment leaves at most a
temporary file, which the next call removes.

Runs are keyed by their point's content (:attr:`Run.key`), so a store's grid
may change between calls: a grid that grows (a later stage of a staged plan,
a refined axis) reuses every run it shares with the grid before it, and runs
the current grid does not name stay on disk unmerged.  The manifest records
the last grid.  What may not change is the function, the grid's parameters
and the base seed (they decide what a key's run is); points and replicates may.
"""

from __future__ import annotations

import contextlib
import functools
import io
import json
import os
import traceback
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from .._io import atomic_write_bytes, atomic_write_text, make_folder, remove_temporaries, write_netcdf
from ..errors import ParameterError
from ..execution import Execution
from ._fastread import RUN_ATTR, FastLayout, read_raw, same_attr
from ._fastwrite import run_file_bytes
from ._grid import RESERVED, Grid, Run
from .._xrcompat import install as _lazy_dask

_lazy_dask()  # no Dask import for NumPy-only data (undulate._xrcompat)

FORMAT = "undulate-sweep/2"  # 2: runs keyed by point content (1: by position)
#: The merged file: netCDF-4 (HDF5).
ENGINE = "h5netcdf"
MERGED = "sweep.nc"


# ---- atomic files (one helper for the whole package: undulate._io) -------
def atomic_write_netcdf(path: Path, ds: xr.Dataset) -> None:
    """The merged file: :func:`undulate._io.write_netcdf` (uncompressed: merges are rewritten often)."""
    write_netcdf(ds, path, compress=False)


def _run_file_bytes(ds: xr.Dataset) -> bytes:
    """A run's netCDF file, serialised in memory.

    NetCDF-3 (SciPy): ~20x faster to write and read than netCDF-4/HDF5 for a
    small Dataset, which matters at 0.05-1 s per run.  What netCDF-3 cannot
    hold (integers beyond int32, ...) falls back to netCDF-4; readers tell
    them apart by their first bytes.  Serialising to bytes, not to a path,
    also keeps xarray from taking a cluster-wide write lock through the Dask
    scheduler (a round trip per file) when this runs on a Dask worker.
    """
    try:
        return bytes(ds.to_netcdf(engine="scipy", format="NETCDF3_64BIT"))
    except (ValueError, TypeError, OverflowError):
        return bytes(ds.to_netcdf(engine=ENGINE))


def read_run_file(path: Path, data: bytes | None = None) -> tuple[xr.Dataset, dict[str, Any]]:
    """A run file's Dataset, with its variables' original dtypes restored, and its run record
    (``data``: the file's bytes, where already read)."""
    data = path.read_bytes() if data is None else data
    ds = xr.load_dataset(io.BytesIO(data), engine="scipy" if data[:3] == b"CDF" else ENGINE)
    meta = json.loads(ds.attrs.pop(RUN_ATTR, "{}"))
    for name, dt in meta.get("dtypes", {}).items():
        if name in ds.variables and np.dtype(dt).kind in "biuf" and ds[name].dtype != np.dtype(dt):
            ds[name] = ds[name].astype(dt)  # netCDF-3 stores int64 as int32
    return ds, meta


# ---- identity of a sweep -------------------------------------------------
def unwrapped(fn: Callable) -> Callable:
    """The function under any ``functools.partial`` layers of ``fn`` (``fn`` itself if none)."""
    while isinstance(fn, functools.partial):
        fn = fn.func
    return fn


def function_name(fn: Callable) -> str:
    """``module.qualname`` of the function under any ``functools.partial`` layers."""
    fn = unwrapped(fn)
    module = getattr(fn, "__module__", None) or type(fn).__module__
    name = getattr(fn, "__qualname__", None) or type(fn).__qualname__
    return f"{module}.{name}"


def bound_arguments(fn: Callable) -> dict[str, str]:
    """Every argument a run gets besides ``(point, seed)``, defaults included, as ``repr``.

    ``functools.partial(f, scale=2.0)`` of ``f(point, seed, *, scale=1.0,
    n=3)`` gives ``{"scale": "2.0", "n": "3"}``; editing a default changes
    it.  Bound values need a stable ``repr`` (numbers, strings, tuples,
    dataclasses have one).
    """
    import inspect

    args: tuple = ()
    kw: dict[str, Any] = {}
    inner = fn
    while isinstance(inner, functools.partial):  # the outer partial's arguments win
        args = inner.args + args
        kw = {**inner.keywords, **kw}
        inner = inner.func
    try:
        params = list(inspect.signature(inner).parameters.values())
    except (TypeError, ValueError):  # no signature: what was bound is all we know
        return {**{f"arg{i}": repr(a) for i, a in enumerate(args)}, **{k: repr(v) for k, v in sorted(kw.items())}}
    out: dict[str, str] = {}
    positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    for p, a in zip(positional, args):  # partial(f, x): x binds f's first parameter
        out[p.name] = repr(a)
    rest = [p for p in params if p.name not in out]
    skip = 2 - len(out) if len(out) < 2 else 0  # the two run arguments (point, seed)
    for p in rest:
        if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            continue
        if skip and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) and p.name not in kw:
            skip -= 1
            continue
        if p.name in kw:
            out[p.name] = repr(kw[p.name])
        elif p.default is not p.empty:
            out[p.name] = repr(p.default)
    for k in sorted(set(kw) - set(out)):  # into **kwargs
        out[k] = repr(kw[k])
    return out


def function_id(fn: Callable) -> str:
    """The fully bound call: ``"pkg.mod.fn(a=1, scale=2.0)"`` (:func:`bound_arguments`)."""
    args = bound_arguments(fn)
    return f"{function_name(fn)}({', '.join(f'{k}={v}' for k, v in args.items())})"


def backend_identity(execution: Execution | None = None) -> str:
    """The stepping backend of ``execution`` (None: the settings in effect,
    :func:`undulate.execution.current`) as a sweep's identity records it: ``"mujoco"``, or
    ``"warp DEVICE float32 (mujoco-warp X, warp-lang Y)"``, with `` nondeterministic`` after the
    precision where MuJoCo Warp's determinism is off, then ``, lone swimmers on mujoco`` where scenes of
    one swimmer step on the cores (:func:`undulate.execution.lone_swimmers_engine`) and
    ``, batches of up to N on mujoco`` where batches of at most N scenes do
    (:func:`undulate.execution.cores_up_to`).  Runs of one backend, or of one rule for lone
    swimmers or small batches, are never served for another."""
    from ..execution import cores_up_to, current, lone_swimmers_engine, using
    from ..params import SimOptions
    from ..simulation import backend, backend_attrs

    ex = execution or current()
    if ex.backend == "mujoco":
        return "mujoco"
    with using(ex):  # the engine's attrs read its switches (determinism) from the settings in effect
        a = backend_attrs(SimOptions(backend=ex.backend, device=backend(ex.backend).resolve_device(ex.device)))
    nondet = " nondeterministic" if a["warp_determinism"] == "none" else ""
    lone = ", lone swimmers on mujoco" if lone_swimmers_engine(a["device"], ex) == "mujoco" else ""
    small = cores_up_to(a["device"], ex)
    lone += f", batches of up to {small} on mujoco" if small else ""
    return f"warp {a['device']} {a['precision']}{nondet}{lone} ({a['backend_versions']})"


def make_manifest(fn: Callable, grid: Grid, batched: bool, execution: Execution | None = None) -> dict[str, Any]:
    """What a sweep is: the function (fully bound call), the hash of the code that
    computes a run (:func:`undulate._source.code_hash`), the backend that steps it under ``execution``
    (:func:`backend_identity`), the package version, the grid."""
    from .._source import code_hash
    from ..provenance import package_version

    return {
        "format": FORMAT,
        "function": function_id(fn),
        "function_name": function_name(fn),
        "code": code_hash(fn, execution),
        "backend": backend_identity(execution),
        "undulate_version": package_version("undulate"),
        "batched": bool(batched),
        "grid": grid.to_dict(),
    }


#: Manifest keys whose change makes the stored runs stale (recomputed, not refused).
RESULT_KEYS = ("format", "function", "code", "backend", "undulate_version")


def _stale(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    """What makes the runs in a store with manifest ``old`` stale for sweep ``new``."""
    out = []
    for key in RESULT_KEYS:
        if old.get(key) != new.get(key):
            out.append(f"{key} {old.get(key)!r} -> {new.get(key)!r}")
    return out


def _differences(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    """What makes ``old`` a different sweep (refused): anything but :data:`RESULT_KEYS`."""
    out = []
    old_name = old.get("function_name") or str(old.get("function", "")).split("(")[0]
    if old_name != new.get("function_name"):
        out.append(f"function {old_name!r} != {new.get('function_name')!r}")
    for key in ("batched",):
        if old.get(key) != new.get(key):
            out.append(f"{key} {old.get(key)!r} != {new.get(key)!r}")
    og, ng = old.get("grid", {}), new.get("grid", {})
    for key in ("seed",):  # points and replicates may change: runs are keyed by point and replicate
        if og.get(key) != ng.get(key):
            out.append(f"grid {key} {og.get(key)!r} != {ng.get(key)!r}")
    if ("axes" in og) != ("axes" in ng):
        out.append("grid kind differs (axes vs explicit points)")
    elif _names(og) != _names(ng):
        out.append(f"grid parameters {_names(og)} != {_names(ng)}")
    return out


def _names(grid: dict[str, Any]) -> list[str]:
    """The parameter names of a grid's dict (:meth:`Grid.to_dict`)."""
    if grid.get("axes") is not None:
        return list(grid["axes"])
    pts = grid.get("points") or [{}]
    return sorted(pts[0])


# ---- the store -----------------------------------------------------------
class Store:
    """An open sweep directory, locked against a second concurrent sweep."""

    def __init__(self, root: Path):
        self.root = root
        self.runs_dir = root / "runs"
        self.merged_path = root / MERGED
        self._lock_fd: int | None = None
        self.stale: list[str] = []
        """Why the runs found on open were discarded (empty: nothing was)."""
        self.grown = False
        """The grid differs from the last call's (runs shared with it are reused by key)."""
        self.manifest: dict[str, Any] = {}

    @classmethod
    @contextlib.contextmanager
    def open(cls, root: str | os.PathLike, manifest: dict[str, Any]) -> Iterator[Store]:
        """Create or reopen ``root`` for the sweep described by ``manifest``.

        Raises :class:`ParameterError` when ``root`` holds a different sweep,
        something that is not a sweep, or a sweep another process is running.
        """
        root = Path(root).absolute()
        if root.exists() and not root.is_dir():
            raise ParameterError("out_dir", "a directory", str(root))
        store = cls(root)
        mpath = root / "manifest.json"
        manifest = json.loads(json.dumps(manifest))  # normalise (tuples -> lists)
        if mpath.exists():
            try:
                old = json.loads(mpath.read_text(encoding="utf-8"))
            except (OSError, ValueError) as e:
                raise ParameterError("out_dir", f"a sweep directory with a readable manifest.json ({e})", str(root)) from None
            diff = _differences(old, manifest)
            if diff:
                raise ParameterError(
                    "out_dir",
                    "a new directory or one holding this same sweep; it holds a different one: " + "; ".join(diff),
                    str(root),
                )
            store.stale = _stale(old, manifest)
            store.grown = old.get("grid") != manifest.get("grid")
        elif root.exists() and any(p.name != ".lock" for p in root.iterdir()):
            raise ParameterError("out_dir", "a new or empty directory, or one made by run_sweep (no manifest.json found)", str(root))
        make_folder(store.runs_dir, "out_dir")
        store._lock()
        try:
            if store.stale:  # computed by other code or arguments: never reused
                store._discard_runs()
                atomic_write_text(mpath, json.dumps(manifest, indent=1) + "\n")
            elif store.grown:  # another grid of the same sweep: its shared runs are reused by key
                atomic_write_text(mpath, json.dumps(manifest, indent=1) + "\n")
            if not mpath.exists():
                atomic_write_text(mpath, json.dumps(manifest, indent=1) + "\n")
            store.manifest = manifest
            store._remove_temporaries()
            yield store
        finally:
            store._unlock()

    def _lock(self) -> None:
        try:
            import fcntl  # noqa: F401
        except ImportError:  # pragma: no cover - Windows: no advisory lock
            return
        from .._outdir import flock_pid

        fd = flock_pid(self.root / ".lock")
        if fd is None:
            raise ParameterError("out_dir", "a directory that no other running sweep is using", str(self.root))
        self._lock_fd = fd

    def _unlock(self) -> None:
        if self._lock_fd is not None:
            os.close(self._lock_fd)  # releases the flock
            self._lock_fd = None

    def _remove_temporaries(self) -> None:
        for d in (self.root, self.runs_dir):
            remove_temporaries(d)

    def _discard_runs(self) -> None:
        """Remove every run result, failure record and the merged file (the manifest is
        rewritten after this, so a kill in between discards them again on the next open)."""
        for p in [*self.runs_dir.glob("p*_r*.nc"), *self.runs_dir.glob("p*_r*.failed.json"), self.merged_path]:
            with contextlib.suppress(FileNotFoundError):
                p.unlink()

    def done_keys(self) -> set[str]:
        """Keys of the runs whose result file exists."""
        return {p.name[: -len(".nc")] for p in self.runs_dir.glob("p*_r*.nc")}

    def failure(self, run: Run) -> dict[str, Any] | None:
        """The failure record of a run without a result, if one was written."""
        p = failure_path(self.runs_dir, run)
        try:
            return json.loads(p.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None


def result_path(runs_dir: Path, run: Run) -> Path:
    return runs_dir / f"{run.key}.nc"


def failure_path(runs_dir: Path, run: Run) -> Path:
    return runs_dir / f"{run.key}.failed.json"


def _run_meta(run: Run) -> dict[str, Any]:
    return {"key": run.key, "index": run.index, "replicate": run.replicate, "point": run.point, "seed": run.seed}


def run_provenance(manifest: dict[str, Any]) -> dict[str, Any]:
    """What each run file records about the code that computed it (with host and time added
    when it is written)."""
    return {k: manifest.get(k) for k in ("function", "code", "backend", "undulate_version")}


def check_output(ds: Any, grid_names: Sequence[str]) -> xr.Dataset:
    """The contract of a sweep function's return value; raises TypeError/ValueError."""
    if not isinstance(ds, xr.Dataset):
        raise TypeError(f"the sweep function must return an xarray.Dataset, not {type(ds).__name__}")
    taken = (set(ds.dims) | set(ds.variables)) & (set(grid_names) | RESERVED)
    if taken:
        raise ValueError(
            f"the sweep function's Dataset uses names the sweep needs for its own dimensions: {sorted(taken)}"
        )
    return ds


def write_result(runs_dir: Path, run: Run, ds: xr.Dataset, provenance: dict[str, Any] | None = None,
                 timing: dict[str, Any] | None = None) -> None:
    """Persist a finished run atomically, then drop any failure record of an earlier try.

    ``provenance``: the sweep's :func:`run_provenance`; the file records it with
    the host and the UTC time of writing (attribute ``sweep_run``).  ``timing``:
    where the run's time went (``wall_s``, ``physics_s`` inside ``mujoco.rollout``,
    ``steps``), recorded beside it (benchmarks read it; nothing else does).
    """
    import socket
    from datetime import datetime, timezone

    meta = _run_meta(run)
    meta["provenance"] = {**(provenance or {}), "hostname": socket.gethostname(),
                          "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds")}
    meta["dtypes"] = {str(k): v.dtype.str for k, v in ds.variables.items()}
    if timing is not None:
        meta["timing"] = dict(timing)
    ds = ds.copy(deep=False)
    ds.attrs = {**ds.attrs, RUN_ATTR: json.dumps(meta)}
    data = run_file_bytes(ds, _run_file_bytes)  # xarray's bytes, written without xarray where plain
    atomic_write_bytes(result_path(runs_dir, run), data)
    with contextlib.suppress(FileNotFoundError):
        failure_path(runs_dir, run).unlink()


def write_failure(runs_dir: Path, run: Run, exc: BaseException | None, message: str | None = None) -> dict[str, Any]:
    """Record why a run has no result (an exception, or ``message``)."""
    rec = _run_meta(run)
    if exc is not None:
        rec["error"] = f"{type(exc).__name__}: {exc}"
        rec["traceback"] = "".join(traceback.format_exception(exc))
    else:
        rec["error"] = message or "unknown error"
        rec["traceback"] = ""
    atomic_write_text(failure_path(runs_dir, run), json.dumps(rec, indent=1) + "\n")
    return rec


# ---- merging -------------------------------------------------------------
def _missing_fill(dtype: np.dtype) -> tuple[np.dtype, Any]:
    """dtype and fill value for a variable some of whose runs have no result."""
    if dtype.kind in "fc":
        return dtype, np.nan
    if dtype.kind in "iub":
        return np.dtype("float64"), np.nan
    if dtype.kind in "mM":
        return dtype, np.array("NaT", dtype=dtype)
    return dtype, ""  # strings (h5netcdf reads them as objects)


def merge(grid: Grid, runs: Sequence[Run], runs_dir: Path, code: str | None = None) -> xr.Dataset:
    """Stack every finished run file into one Dataset over the grid.

    Dimensions: ``grid.dims + ("replicate",)`` then the function's own.
    Data variables are stacked; so are non-index coordinates that differ
    between runs (one that is the same in every run stays as it is).  Index
    coordinates (``time``...) must be the same in every run.  Runs without a
    result are filled with NaN (integers and booleans become floats; strings
    get "") and flagged by ``run_failed``.  Attributes on which every run
    agrees are kept; the others are dropped (they stay in the run files).
    """
    runs_shape = (*grid.shape, grid.replicates)
    dims = (*grid.dims, "replicate")
    have = np.array([result_path(runs_dir, r).exists() for r in runs], dtype=bool)
    read = _stack_runs(runs, runs_dir, code, have)
    if read is None:  # a run file was unreadable or stale and was removed: start over without it
        return merge(grid, runs, runs_dir, code)
    template, stacked, attrs = read
    coords = _grid_coords(grid, runs, dims, runs_shape)
    variables: dict[str, Any] = {}
    if template is not None:
        variables = _stacked_variables(template, stacked, have, coords, dims, runs_shape)
    variables["run_failed"] = xr.Variable(
        dims, ~have.reshape(runs_shape), attrs={"long_name": "run raised or never finished (its values are NaN)"}
    )
    out = xr.Dataset(variables, coords=coords, attrs=attrs)
    out["seed"].attrs["long_name"] = "seed passed to the sweep function for this run"
    return out


def _stack_runs(runs: Sequence[Run], runs_dir: Path, code: str | None, have: np.ndarray):
    """Read the finished runs (``have``) into stacked arrays, one row per run: ``(template, stacked,
    attrs)`` (the first run read, its stackable variables, the attributes every run agrees on), or
    None when a run file was removed (corrupt or stale).  Runs after the first are read raw where
    that gives what xarray would (:mod:`undulate.sweep._fastread`)."""
    n = len(runs)
    complete = bool(have.all())
    template: xr.Dataset | None = None
    fast: FastLayout | None = None
    stacked: dict[str, np.ndarray] = {}
    attrs: dict[str, Any] = {}
    for j, run in enumerate(runs):
        if not have[j]:
            continue
        path = result_path(runs_dir, run)
        got = _read_checked(runs_dir, run, path, code)
        if got is None:
            return None
        raw, data, ds = got
        if fast is not None and fast.fits(raw):
            fast.stack(raw, stacked, j, attrs)
            continue
        ds = ds if ds is not None else _dataset(runs_dir, run, path, data)
        if ds is None:
            return None
        if template is None:
            template = ds
            attrs = dict(ds.attrs)
            stacked = _empty_stack(ds, n, complete)
            fast = FastLayout.of(template, raw, list(stacked))
        else:
            _check_like(template, ds, path)
            for k in list(attrs):
                if k not in ds.attrs or not same_attr(attrs[k], ds.attrs[k]):
                    del attrs[k]
        for name, arr in stacked.items():
            value = ds[name].values
            arr[j] = value[()] if value.ndim == 0 else value  # a 0-d object array's element, not the array
    return template, stacked, attrs


def _dataset(runs_dir: Path, run: Run, path: Path, data: bytes) -> xr.Dataset | None:
    """A run file's Dataset from its bytes, as :func:`read_run_file` gives it; None where xarray
    cannot read it (removed, as :func:`_read_checked` does)."""
    try:
        return read_run_file(path, data)[0]
    except Exception as exc:  # noqa: BLE001
        _corrupt(runs_dir, run, path, exc)
        return None


def _corrupt(runs_dir: Path, run: Run, path: Path, exc: BaseException) -> None:
    """Remove an unreadable run file and record why (the sweep computes the run again)."""
    path.unlink(missing_ok=True)
    write_failure(runs_dir, run, None, f"CorruptResult: {path.name} could not be read ({exc}); "
                  "it was removed, run the sweep again to recompute it")


def _read_checked(runs_dir: Path, run: Run, path: Path, code: str | None):
    """The run file of ``run`` at ``path`` as ``(raw, its bytes, None)``
    (:func:`undulate.sweep._fastread.read_raw`), or for a netCDF-4 file ``(None, its bytes, its
    Dataset)``; None if the file was unreadable or computed by other code (it is then removed and
    recorded as a failure).  A file of another run is refused."""
    ds = None
    try:
        raw, meta, data = read_raw(path)
        if meta is None:  # not netCDF-3: read through xarray
            ds, meta = read_run_file(path, data)
    except Exception as exc:  # noqa: BLE001 - e.g. truncated by a power cut despite fsync
        _corrupt(runs_dir, run, path, exc)
        return None
    if code is not None and (meta.get("provenance") or {}).get("code") != code:
        path.unlink(missing_ok=True)  # computed by other code: never presented
        write_failure(runs_dir, run, None, f"StaleResult: {path.name} was computed by other code "
                      f"({(meta.get('provenance') or {}).get('code')!r}, not {code!r}); it was removed, "
                      "run the sweep again to recompute it")
        return None
    if meta.get("seed") != run.seed or meta.get("point") != json.loads(json.dumps(run.point)):
        raise ParameterError(
            "out_dir", f"a store whose run files match its manifest ({path.name} is for another run)",
            str(runs_dir.parent),
        )
    return raw, data, ds


def _empty_stack(ds: xr.Dataset, n: int, complete: bool) -> dict[str, np.ndarray]:
    """Arrays for ``n`` runs of each stackable variable of ``ds`` (pre-filled with the missing value
    unless every run finished)."""
    stacked = {}
    for name in _stackable(ds):
        var = ds[name].variable
        dtype, fill = (var.dtype, None) if complete else _missing_fill(var.dtype)
        arr = np.empty((n, *var.shape), dtype=dtype)
        if not complete:
            arr[...] = fill
        stacked[name] = arr
    return stacked


def _grid_coords(grid: Grid, runs: Sequence[Run], dims: tuple, runs_shape: tuple) -> dict[str, Any]:
    """Coordinates of the grid's axes (or its points), the replicates and every run's seed."""
    coords: dict[str, Any] = {}
    if grid.is_product:
        for name, values in grid.axes.items():
            coords[name] = (name, np.asarray(values))
    else:
        coords["point"] = ("point", np.arange(grid.n_points))
        for name, values in grid.axes.items():
            coords[name] = ("point", np.asarray(values))
    coords["replicate"] = ("replicate", np.arange(grid.replicates))
    coords["seed"] = (dims, np.array([r.seed for r in runs], dtype=np.int64).reshape(runs_shape))
    return coords


def _stacked_variables(template: xr.Dataset, stacked: dict[str, np.ndarray], have: np.ndarray,
                       coords: dict[str, Any], dims: tuple, runs_shape: tuple) -> dict[str, Any]:
    """The runs' data variables over the grid; adds the runs' coordinates to ``coords`` (stacked
    where they differ between runs)."""
    first = int(np.argmax(have))
    for name, c in template.coords.items():
        if name in stacked:
            arr = stacked[name]
            if all(np.array_equal(arr[first], arr[j]) for j in np.flatnonzero(have)):
                coords[name] = c.variable  # the same in every run: keep as is
            else:
                coords[name] = xr.Variable((*dims, *c.dims), arr.reshape(*runs_shape, *c.shape), attrs=dict(c.attrs))
        else:
            coords[name] = c.variable
    return {name: xr.Variable((*dims, *var.dims), stacked[name].reshape(*runs_shape, *var.shape),
                              attrs=dict(var.attrs))
            for name, var in template.data_vars.items()}


def _stackable(ds: xr.Dataset) -> list[str]:
    """Data variables and non-index coordinates."""
    return [*ds.data_vars, *(c for c in ds.coords if c not in ds.indexes)]


def _check_like(template: xr.Dataset, ds: xr.Dataset, path: Path) -> None:
    def fail(what: str):
        raise ParameterError(
            "fn",
            "a function whose Datasets all have the same variables, dimensions and index coordinates "
            f"({path.name}: {what})",
        )

    if set(ds.data_vars) != set(template.data_vars) or set(ds.coords) != set(template.coords):
        fail(f"variables {sorted(ds.variables)} != {sorted(template.variables)}")
    for name in _stackable(template):
        var, other = template[name], ds[name]
        if other.dims != var.dims or other.shape != var.shape:
            fail(f"{name} has dims {dict(other.sizes)} not {dict(var.sizes)}")
    for name in template.indexes:
        if name not in ds.indexes or not np.array_equal(ds[name].values, template[name].values):
            fail(f"index coordinate {name!r} differs; return per-run values as data variables")
