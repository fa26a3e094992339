"""Keep xarray from importing Dask when no Dask array can exist yet.

xarray asks, whenever it builds a variable, whether the data is a Dask
array, and answers that by importing ``dask`` and ``dask.array`` whenever
Dask is installed (~1.2 s).  Every worker process and every ``undulate
simulate`` paid it, with the ``dask`` extra installed, for NumPy-only data.
No object can be a Dask collection before ``dask`` has been imported (unless
it carries the collection protocol, ``__dask_graph__``), so until then the
answer "not a Dask array" is exact.  :func:`install`

* wraps ``xarray.namedarray.utils.is_dask_collection`` (which
  ``is_duck_dask_array`` calls): ``False`` at once while ``dask`` is not
  imported and ``x`` has no ``__dask_graph__``, otherwise xarray's own answer;
* puts an entry for ``"dask"`` in xarray's duck-array cache whose array types
  are looked up at each check (empty while ``dask.array`` is not imported, the
  real ``Array`` class once it is), and whose module, version and
  availability import Dask when asked, as xarray's own entry would;
* wraps ``get_dask_scheduler`` (asked by every ``to_netcdf``; it imports
  ``dask`` and ``dask.distributed``): while ``dask`` is not imported it
  answers ``"threaded"``, what xarray's own answers with Dask installed and no
  scheduler set.  It matters only for Dask-chunked data (which imports Dask
  first) and for the kind of lock around a write of NumPy data in this one
  process, which any lock serves.  Behaviour with Dask arrays is unchanged
(``tests/test_dask.py``).  If xarray's internals differ from what this
expects, nothing is installed (only the speed-up is lost).
"""

from __future__ import annotations

import sys

__all__ = ["install"]


def install() -> bool:
    """Install the lazy ``"dask"`` entry; True if it is in place."""
    try:
        from xarray.namedarray import pycompat, utils
    except ImportError:  # pragma: no cover - another xarray layout
        return False
    real = getattr(utils, "is_dask_collection", None)
    if real is not None and not getattr(real, "_undulate_lazy", False):
        def is_dask_collection(x):
            if "dask" not in sys.modules and not hasattr(x, "__dask_graph__"):
                return False
            return real(x)

        is_dask_collection._undulate_lazy = True
        is_dask_collection.__wrapped__ = real
        utils.is_dask_collection = is_dask_collection
    _wrap_scheduler()
    cache = getattr(pycompat, "_cached_duck_array_modules", None)
    base = getattr(pycompat, "DuckArrayModule", None)
    if not isinstance(cache, dict) or base is None:  # pragma: no cover
        return False
    if "dask" in cache:
        return True  # already resolved by xarray (Dask imported): nothing to save

    class _Lazy(_LazyDask, base):  # an instance of xarray's class, for any isinstance check
        pass

    cache["dask"] = _Lazy.__new__(_Lazy)
    return True


class _LazyDask:
    """xarray's ``DuckArrayModule("dask")``, resolved only when Dask is in use."""

    _real = None

    def _resolve(self):
        if self._real is None:
            from xarray.namedarray.pycompat import DuckArrayModule

            self._real = DuckArrayModule("dask")
        return self._real

    @property
    def type(self):
        if "dask.array" not in sys.modules:
            return ()  # nothing can be a Dask array yet
        return self._resolve().type

    @property
    def module(self):
        return self._resolve().module

    @property
    def version(self):
        return self._resolve().version

    @property
    def available(self):
        return self._resolve().available


def _wrap_scheduler() -> None:
    try:
        from xarray.backends import locks, writers
    except ImportError:  # pragma: no cover - another xarray layout
        return
    real = getattr(locks, "get_dask_scheduler", None)
    if real is None or getattr(real, "_undulate_lazy", False):
        return

    import importlib.util

    try:
        installed = importlib.util.find_spec("dask") is not None
    except (ImportError, ValueError):  # pragma: no cover
        installed = False

    def get_dask_scheduler(get=None, collection=None):
        if get is None and collection is None and "dask" not in sys.modules:
            return "threaded" if installed else None  # as xarray's own, without importing Dask
        return real(get, collection)

    get_dask_scheduler._undulate_lazy = True
    get_dask_scheduler.__wrapped__ = real
    locks.get_dask_scheduler = get_dask_scheduler
    if getattr(writers, "get_dask_scheduler", None) is real:
        writers.get_dask_scheduler = get_dask_scheduler
