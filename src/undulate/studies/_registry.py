"""The study registry: one decorator, one way to run and save every study.

A study module defines ``run(config: StudyConfig) -> StudyResult`` and
registers it::

    @register("compatibility", description="...", paper_figure="4")
    def run(config: StudyConfig) -> StudyResult: ...

:func:`run_study` runs it and writes, atomically, into ``out_dir``::

    NAME.nc    the dataset (netCDF, h5netcdf engine; units and provenance in attrs)
    NAME.png   the figure
    NAME.pdf   the figure, vector
    NAME.json  the summary, the configuration and the provenance

Study modules are imported on first use, from the list
:data:`undulate.studies.STUDY_MODULES`.
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from ..errors import ParameterError, UndulateError
from ..provenance import provenance

if TYPE_CHECKING:  # heavy imports stay lazy
    import xarray as xr
    from matplotlib.figure import Figure

__all__ = [
    "StudyConfig",
    "StudyResult",
    "StudyInfo",
    "register",
    "names",
    "describe",
    "run_study",
]


@dataclass(frozen=True)
class StudyConfig:
    """How to run a study.

    ``out_dir``: where the study's files go (studies may keep resumable
    sweep state there); ``quick``: a reduced version that runs in minutes;
    ``scheduler``: a Dask scheduler address, or None for local processes;
    ``seed``: the root seed of every random draw.
    """

    out_dir: Path
    quick: bool = False
    scheduler: str | None = None
    seed: int = 0

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["out_dir"] = str(self.out_dir)
        return d


@dataclass
class StudyResult:
    """What a study returns: data, one figure, and a few headline numbers.

    ``dataset``: every numeric variable and coordinate carries a ``units``
    attribute (``"1"`` when dimensionless); ``figure``: a matplotlib Figure
    (made without pyplot); ``summary``: JSON-able numbers and strings.
    """

    dataset: xr.Dataset
    figure: Figure
    summary: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class StudyInfo:
    """A registered study: its name, what it shows, and how to run it."""

    name: str
    description: str
    needs_simulation: bool
    paper_figure: str | None
    run: Callable[[StudyConfig], StudyResult] = field(repr=False, compare=False)

    def __str__(self) -> str:
        tags = [f"paper Fig. {self.paper_figure}"] if self.paper_figure else []
        tags.append("simulation" if self.needs_simulation else "theory only")
        return f"{self.description} [{'; '.join(tags)}]"


#: Study modules imported (in this order) when the registry is first used.
STUDY_MODULES: tuple[str, ...] = (
    "pairs",
    "compatibility",
    "links",
    "groups",
    "packing",
    "basins",
    "confinement",
    "potential",
    "swimming",
    "synchronization",
)

_REGISTRY: dict[str, StudyInfo] = {}
_loaded = False


def register(name: str, *, description: str, needs_simulation: bool = True,
             paper_figure: str | None = None):
    """Decorator registering ``run(config) -> StudyResult`` as study ``name``."""

    def deco(func: Callable[[StudyConfig], StudyResult]):
        if name in _REGISTRY and _REGISTRY[name].run is not func:
            raise UndulateError(f"study {name!r} registered twice")
        _REGISTRY[name] = StudyInfo(name, description, needs_simulation, paper_figure, func)
        return func

    return deco


def _load() -> None:
    global _loaded
    if _loaded:
        return
    for mod in STUDY_MODULES:
        importlib.import_module(f"{__package__}.{mod}")
    _loaded = True


def names() -> list[str]:
    """Registered study names, in the order of :data:`STUDY_MODULES` (the paper's)."""
    _load()
    return list(_REGISTRY)


def describe(name: str) -> StudyInfo:
    """The :class:`StudyInfo` of study ``name``; unknown names raise ParameterError."""
    _load()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ParameterError("study", "one of " + ", ".join(_REGISTRY), name) from None


# ------------------------------------------------------------------- writing
def _jsonable(obj: Any) -> Any:
    """Plain JSON types; numpy scalars and arrays unwrapped, non-finite floats -> None."""
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    if obj is None or isinstance(obj, (bool, int, float, str)):
        return obj
    raise UndulateError(f"summary value {obj!r} ({type(obj).__name__}) is not JSON-able")


def _check_units(name: str, ds: xr.Dataset) -> None:
    missing = [str(k) for k, v in {**ds.coords, **ds.data_vars}.items()
               if v.dtype.kind in "iufc" and "units" not in v.attrs]
    if missing:
        raise UndulateError(f"study {name!r}: variables without a 'units' attribute: {missing}")


def _write_all(name: str, result: StudyResult, config: StudyConfig) -> Path:
    """Write every file through :func:`undulate._io.atomic_output`; they are moved into
    place only when all of them were written, the JSON last (its presence marks completion)."""
    import contextlib

    from .._io import atomic_output

    out_dir = Path(config.out_dir)
    prov = provenance()
    config_json = json.dumps(config.to_dict(), sort_keys=True)
    ds = result.dataset.copy()
    ds.attrs.update({"study": name, "study_config": config_json, **prov})
    doc = {
        "study": name,
        "summary": result.summary,
        "config": config.to_dict(),
        "provenance": prov,
        "files": [f"{name}.{ext}" for ext in ("nc", "png", "pdf")],
    }
    text = json.dumps(_jsonable(doc), indent=2, allow_nan=False) + "\n"
    encoding = {k: {"zlib": True, "complevel": 4} for k, v in ds.data_vars.items()
                if v.dtype.kind in "biufc" and v.ndim > 0}
    with contextlib.ExitStack() as stack:  # exits (renames) in reverse order: the json last
        tmp_json = stack.enter_context(atomic_output(out_dir / f"{name}.json"))
        tmp_nc = stack.enter_context(atomic_output(out_dir / f"{name}.nc"))
        ds.to_netcdf(tmp_nc, engine="h5netcdf", encoding=encoding)
        for ext in ("png", "pdf"):
            tmp = stack.enter_context(atomic_output(out_dir / f"{name}.{ext}"))
            result.figure.savefig(tmp, format=ext, dpi=150 if ext == "png" else None)
        tmp_json.write_text(text)
    return out_dir / f"{name}.nc"


def run_study(name: str, out_dir: str | os.PathLike, quick: bool = False,
              scheduler: str | None = None, seed: int = 0) -> Path:
    """Run study ``name`` and write its files into ``out_dir`` (created if needed).

    Returns the path of the netCDF file ``out_dir/NAME.nc``; beside it are
    ``NAME.png``, ``NAME.pdf`` and ``NAME.json``.  Each file appears whole or
    not at all (written under a temporary name, then renamed).  An unknown
    ``name`` raises :class:`~undulate.errors.ParameterError` listing the
    known studies.
    """
    info = describe(name)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    config = StudyConfig(out_dir=out, quick=bool(quick), scheduler=scheduler, seed=int(seed))
    result = info.run(config)
    if not isinstance(result, StudyResult):
        raise UndulateError(f"study {name!r} returned {type(result).__name__}, not StudyResult")
    _check_units(name, result.dataset)
    return _write_all(name, result, config)
