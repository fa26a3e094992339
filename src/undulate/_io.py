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
numeric variables).
"""

from __future__ import annotations

import contextlib
import os
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import xarray as xr

__all__ = ["atomic_output", "temporary_path", "commit", "discard", "atomic_write", "atomic_write_bytes", "atomic_write_text", "write_netcdf",
           "remove_temporaries", "TMP_GLOB"]

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
    except BaseException:
        discard(tmp)
        raise


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
    """Step 4: remove a temporary file (no error if it is already gone)."""
    with contextlib.suppress(OSError):
        Path(tmp).unlink()


def atomic_write(path: str | os.PathLike, write: Callable[[Path], object]) -> None:
    """Call ``write(tmp)`` and move ``tmp`` onto ``path`` atomically (:func:`atomic_output`)."""
    with atomic_output(path) as tmp:
        write(tmp)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    atomic_write(path, lambda p: p.write_bytes(data))


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    atomic_write(path, lambda p: p.write_text(text, encoding="utf-8"))


def write_netcdf(ds: xr.Dataset, path: str | os.PathLike, *, compress: bool = True) -> Path:
    """Write ``ds`` to ``path`` (netCDF-4, h5netcdf engine) atomically; returns the path.

    ``compress``: zlib level 4 on every numeric variable with dimensions.
    """
    encoding = {k: {"zlib": True, "complevel": 4} for k, v in ds.data_vars.items()
                if v.dtype.kind in "biufc" and v.ndim > 0} if compress else None
    atomic_write(path, lambda p: ds.to_netcdf(p, engine="h5netcdf", encoding=encoding))
    return Path(path)


def remove_temporaries(folder: str | os.PathLike) -> int:
    """Remove the temporary files a killed writer left in ``folder``; returns how many."""
    n = 0
    for p in Path(folder).glob(TMP_GLOB):
        with contextlib.suppress(OSError):
            p.unlink()
            n += 1
    return n
