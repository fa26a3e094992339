"""Atomic file output: every file ``undulate`` writes appears whole, or not at all.

One helper, :func:`atomic_output`, used by every writer (studies, sweeps,
report, reproduction state, animations, CLI outputs):

1. the content goes to a unique temporary name beside the target
   (``.NAME.<random>.tmp``, or ``.tmp.SUFFIX`` for writers that choose a
   format by extension; same folder, so the rename is atomic);
2. the temporary file is flushed to disk (``fsync``) and given the
   permissions a plainly created file would have (``0o666`` less the umask;
   ``mkstemp`` would leave ``0o600``);
3. it is renamed onto the target (``os.replace``);
4. on any exception (or ``KeyboardInterrupt``) the temporary file is removed
   and the target is left as it was.

A process killed between 1 and 3 leaves at most a ``.*.tmp`` file;
:func:`remove_temporaries` clears them (the sweep store does so on open).
:func:`write_netcdf` is the one netCDF writer (h5netcdf engine, compressed
numeric variables); :func:`hdf5_writes` guards every HDF5 write to a path.
"""

from __future__ import annotations

import contextlib
import errno
import os
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from ._signals import deferred

if TYPE_CHECKING:
    import xarray as xr

__all__ = ["atomic_output", "temporary_path", "commit", "discard", "atomic_write", "atomic_write_bytes", "atomic_write_text", "write_netcdf",
           "remove_temporaries", "TMP_GLOB", "hdf5_writes", "netcdf_bytes", "write_bytes"]

TMP_GLOB = ".*.tmp*"
"""Glob of the temporary names :func:`atomic_output` uses."""


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _tmp_name(path: Path, keep_suffix: bool = False) -> Path:
    tail = f".tmp{path.suffix}" if keep_suffix else ".tmp"
    return path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}{tail}")


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike, *, keep_suffix: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; when the block succeeds, move it into place.

    Write the content to the yielded path (any writer that takes a path);
    ``keep_suffix``: the temporary name ends with ``path``'s suffix too, for
    writers that choose a format by extension (matplotlib's animation
    writers); otherwise it ends with ``.tmp``, so a glob for finished files
    (``*.nc``) never sees a half-written one.
    On success it is fsync-ed, given umask permissions and renamed to
    ``path``; on any exception it is removed and ``path`` is untouched.
    """
    path = Path(path)
    tmp = temporary_path(path, keep_suffix=keep_suffix)
    try:
        yield tmp
        if not tmp.exists():  # the writer wrote nothing: an empty file, as open(path, "w") would
            tmp.touch()
        commit(tmp, path)
    except OSError as e:
        from .errors import WriteError

        discard(tmp)
        if e.errno in _FULL_ERRNOS and not isinstance(e, WriteError):  # a full disk, quota or file-size limit
            raise WriteError(path, _as_oserror(e)) from e
        raise
    except BaseException:
        discard(tmp)
        raise


_FULL_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
"""The errors of a write that no longer fits (only writes raise them)."""


def temporary_path(path: str | os.PathLike, *, keep_suffix: bool = False) -> Path:
    """A fresh temporary name beside ``path`` (step 1), for writers that must hold the
    file open across calls (the streaming recorder) and so cannot use :func:`atomic_output`'s
    ``with`` block; finish with :func:`commit` or :func:`discard`."""
    return _tmp_name(Path(path), keep_suffix)


def commit(tmp: str | os.PathLike, path: str | os.PathLike) -> None:
    """Steps 2-3: fsync ``tmp``, give it umask permissions and rename it onto ``path``."""
    tmp = Path(tmp)
    _fsync(tmp)
    os.chmod(tmp, 0o666 & ~_umask())
    os.replace(tmp, path)


def discard(tmp: str | os.PathLike) -> None:
    """Step 4: remove a temporary file (no error if it is already gone).  It is emptied first: a writer
    that failed may still hold it open (HDF5 after a failed write), which would keep its space in use
    on a full disk until the process ends."""
    with contextlib.suppress(OSError):
        os.truncate(tmp, 0)
    with contextlib.suppress(OSError):
        Path(tmp).unlink()


_FAILED_HDF5: set[str] = set()
"""Files whose HDF5 writes failed (:func:`hdf5_writes`): h5py's errors in finalizers about them are
not printed."""
_WATCHED_HDF5: dict[str, BaseException | None] = {}
"""Files being written under :func:`hdf5_writes`: the first error h5py raised about each in a finalizer."""


@contextlib.contextmanager
def hdf5_writes(tmp: str | os.PathLike, target: str | os.PathLike | None = None) -> Iterator[None]:
    """Around HDF5 (h5netcdf) writes to the file ``tmp``: a failed write (a full disk, a quota, an I/O
    error) leaves no file and raises :class:`~undulate.errors.WriteError` naming ``target``.

    HDF5 writes a dataset's chunks when its handle is released, and h5py reports a failure there only
    as "Exception ignored" in a finalizer: a disk that filled mid-run printed a page of tracebacks, the
    run went on, its corrupt file was renamed into place as if whole, and h5netcdf's own finalizer
    (a flush through the failed file) then killed the process with a segmentation fault.  Here errors
    about ``tmp`` in finalizers are caught and raised at the end of the block, every h5netcdf file on
    ``tmp`` is marked closed (its finalizer then does nothing), and ``tmp`` is emptied and removed."""
    name = os.path.abspath(tmp)
    _install_hdf5_hook()
    outer = name in _WATCHED_HDF5
    if not outer:
        _WATCHED_HDF5[name] = None
    try:
        yield
        seen = _WATCHED_HDF5.get(name)
        if seen is not None:
            raise _as_oserror(seen) from seen
    except (OSError, RuntimeError) as e:
        from .errors import WriteError

        if isinstance(e, WriteError) or (isinstance(e, RuntimeError) and not _is_write_failure(e)):
            raise
        _give_up_hdf5(tmp)
        raise WriteError(target if target is not None else tmp, _as_oserror(e)) from e
    finally:
        if not outer:
            _WATCHED_HDF5.pop(name, None)


def _is_write_failure(e: BaseException) -> bool:
    """Whether h5py's RuntimeError is HDF5 failing to write (it raises those from flushes)."""
    text = str(e)
    return "write failed" in text or "errno =" in text


def _as_oserror(e: BaseException) -> OSError:
    """h5py's error text as an OSError: its errno where HDF5 named one (``errno = 28``)."""
    import re

    if isinstance(e, OSError) and e.errno is not None:  # HDF5's own text runs over lines: the system's words
        return OSError(e.errno, os.strerror(e.errno))
    text = str(e)
    m = re.search(r"errno = (\d+)", text)
    if m:
        num = int(m.group(1))
        return OSError(num, os.strerror(num))
    return OSError(text.splitlines()[0] if text else type(e).__name__)


def _install_hdf5_hook() -> None:
    import sys

    if getattr(sys.unraisablehook, "undulate_hdf5", False):
        return
    previous = sys.unraisablehook

    def hook(unraisable):
        e = unraisable.exc_value
        if not _about_hdf5_failure(e):
            previous(unraisable)

    hook.undulate_hdf5 = True
    sys.unraisablehook = hook
    # Cython prints a finalizer's error through sys.excepthook first (its full traceback), then reports it
    # unraisable: both are dropped for these files
    previous_except = sys.excepthook

    def excepthook(kind, value, tb):
        if not _about_hdf5_failure(value):
            previous_except(kind, value, tb)

    sys.excepthook = excepthook


def _about_hdf5_failure(e: BaseException | None) -> bool:
    """Whether h5py's error ``e`` in a finalizer is about a file being written under :func:`hdf5_writes`
    (then kept, once, for the block to raise) or one already given up (HDF5 may not name it then)."""
    text = str(e) if e is not None else ""
    for f in _WATCHED_HDF5:
        if f in text:
            if _WATCHED_HDF5[f] is None:
                _WATCHED_HDF5[f] = e
            return True
    return bool(_FAILED_HDF5) and (any(f in text for f in _FAILED_HDF5)
                                   or text.startswith("Can't decrement id ref count"))


def _give_up_hdf5(tmp: str | os.PathLike) -> None:
    """Stop every use of the failed HDF5 file ``tmp`` and remove it (see :func:`hdf5_writes`)."""
    import gc

    import h5netcdf

    name = os.path.abspath(tmp)
    _install_hdf5_hook()
    _FAILED_HDF5.add(name)
    handles = []
    for obj in gc.get_objects():
        if isinstance(obj, h5netcdf.File) and not getattr(obj, "_closed", True) and \
                os.path.abspath(getattr(obj, "_filename", "")) == name:
            handles.append(getattr(obj, "_File__h5file", None))
            obj._closed = True  # h5netcdf's __del__ is close(): a flush through the failed file, a segfault
    for h in handles:  # HDF5's last writes go to /dev/null: they succeed, so the file closes whole
        _to_devnull(h)
    discard(tmp)
    for h in handles:  # closed now, not by HDF5 at exit (where a failing close crashed the process)
        with contextlib.suppress(Exception):
            if h is not None:
                h.close()
    del handles
    gc.collect()  # h5py's remaining handles on it released now, their errors dropped


def _to_devnull(h5file) -> None:
    """Put /dev/null under the file descriptor HDF5 writes ``h5file`` through (its default driver).

    HDF5 cannot close a file whose writes fail: it tries again in every release of a handle and at
    exit, and its failure paths there corrupt its memory (a segmentation fault or an aborted malloc at
    exit: seen with h5py 3.16 / HDF5 2.0 on a full disk and past a file-size limit, where freeing
    space does not help).  Written to /dev/null, what HDF5 still has to write succeeds and is lost
    with the file being given up anyway."""
    if h5file is None:
        return
    try:
        fd = h5file.id.get_vfd_handle()
    except Exception:  # noqa: BLE001 - another driver, or closed already
        return
    if not isinstance(fd, int) or fd < 0:
        return
    null = os.open(os.devnull, os.O_RDWR)
    try:
        os.dup2(null, fd)
    finally:
        os.close(null)


def make_folder(path: str | os.PathLike, name: str) -> Path:
    """``path`` as a folder, created with its parents if missing; one that cannot be (a read-only or
    pseudo file system, a file in the way, no space) is a :class:`~undulate.errors.ParameterError`
    naming ``name``, the parameter as the user knows it, where ``mkdir``'s OSError was a traceback."""
    from .errors import ParameterError

    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ParameterError(name, f"a folder that can be created ({e.strerror or e})", str(path)) from None
    return path


def atomic_write(path: str | os.PathLike, write: Callable[[Path], object]) -> None:
    """Call ``write(tmp)`` and move ``tmp`` onto ``path`` atomically (:func:`atomic_output`)."""
    with atomic_output(path) as tmp:
        write(tmp)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically; a failed write (a full disk, a quota) raises
    :class:`~undulate.errors.WriteError` naming ``path``, and leaves nothing."""
    def write(tmp: Path) -> None:
        write_bytes(tmp, data, path)

    atomic_write(path, write)


def write_bytes(tmp: str | os.PathLike, data: bytes, target: str | os.PathLike | None = None) -> None:
    """``tmp.write_bytes(data)``; a failed write raises :class:`~undulate.errors.WriteError` naming
    ``target`` (the file the user asked for) after removing ``tmp``."""
    try:
        Path(tmp).write_bytes(data)
    except OSError as e:
        from .errors import WriteError

        discard(tmp)
        raise WriteError(target if target is not None else tmp, _as_oserror(e)) from e


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def write_netcdf(ds: xr.Dataset, path: str | os.PathLike, *, compress: bool = True) -> Path:
    """Write ``ds`` to ``path`` (netCDF-4, h5netcdf engine) atomically; returns the path.

    ``compress``: zlib level 4 on every numeric variable with dimensions.
    """
    atomic_write_bytes(path, netcdf_bytes(ds, compress=compress))
    return Path(path)


def netcdf_bytes(ds: xr.Dataset, *, compress: bool = True, **kwargs) -> bytes:
    """``ds`` as a netCDF-4 file (h5netcdf engine), built in memory.

    Files are built in memory and written as bytes, so HDF5 never meets a full disk itself: there its
    failure paths corrupt its memory (a crash at exit, seen with h5py 3.16 / HDF5 2.0), and the plain
    write fails cleanly instead.  ``compress``: zlib level 4 on every numeric variable with dimensions;
    ``kwargs`` go to ``to_netcdf`` (``encoding`` there is added to the compression's)."""
    encoding = {k: {"zlib": True, "complevel": 4} for k, v in ds.data_vars.items()
                if v.dtype.kind in "biufc" and v.ndim > 0} if compress else {}
    for name, enc in (kwargs.pop("encoding", None) or {}).items():
        encoding[name] = {**encoding.get(name, {}), **enc}
    with deferred():  # a SIGTERM halfway through would leave a half-built h5netcdf File to fail at exit
        return bytes(ds.to_netcdf(engine="h5netcdf", encoding=encoding or None, **kwargs))


def remove_temporaries(folder: str | os.PathLike) -> int:
    """Remove the temporary files a killed writer left in ``folder``; returns how many."""
    n = 0
    for p in Path(folder).glob(TMP_GLOB):
        with contextlib.suppress(OSError):
            p.unlink()
            n += 1
    return n
