"""The registry of studies: :func:`register`, :func:`names`, :func:`describe`, and a study's
:func:`identity` (what its files depend on besides its sweeps) and :func:`is_current`.
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import pkgutil
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import ParameterError, UndulateError
from ._context import _claim_verdicts

if TYPE_CHECKING:
    from ._context import StudyConfig
    from ._protocol import Study

__all__ = ["register", "names", "describe", "identity", "is_current"]

_REGISTRY: dict[str, Study] = {}


_REGISTERED: dict[str, int] = {}  # name -> its place among its module's register calls


_loaded = False


def register(study: Study) -> Study:
    """Register ``study`` under ``study.name`` (its module is recorded for the code hash)."""
    import inspect

    if study.name in _REGISTRY and _REGISTRY[study.name].dataset is not study.dataset:
        raise UndulateError(f"study {study.name!r} registered twice")
    if not study.module:
        mod = inspect.getmodule(study.dataset)
        study = dataclasses.replace(study, module=mod.__name__ if mod else "")
    if study.order is None:
        study = dataclasses.replace(study, order=_default_order(study))
    _REGISTERED.setdefault(study.name, sum(s.module == study.module for s in _REGISTRY.values()))
    _REGISTRY[study.name] = study
    return study


def _default_order(study: Study) -> float:
    """:attr:`~._protocol.Study.order` when the study declares none (see there)."""
    fig = (study.paper_figure or "").strip()
    if fig.isdigit():
        return float(fig)
    if fig:
        return 90.0
    return 200.0 if study.explanations and not study.claims else 100.0


def _load() -> None:
    """Import every public module of this package (names not starting with ``_``): each
    registers its studies.  Sorted by name, so registration order never depends on the
    file system."""
    global _loaded
    if _loaded:
        return
    package_path = sys.modules[__package__].__path__  # this package's folder(s), without an import edge to it
    for info in sorted(pkgutil.iter_modules(package_path), key=lambda m: m.name):
        if not info.name.startswith("_"):
            importlib.import_module(f"{__package__}.{info.name}")
    _loaded = True


def names() -> list[str]:
    """Registered study names, in the order of :attr:`~._protocol.Study.order` (the paper's)."""
    _load()
    # ties by module name, then register calls: not by which module some caller happened to import first
    return sorted(_REGISTRY, key=lambda name: (_REGISTRY[name].order, _REGISTRY[name].module, _REGISTERED[name]))


def describe(name: str) -> Study:
    """The :class:`~._protocol.Study` named ``name``; unknown names raise ParameterError."""
    _load()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ParameterError("study", "one of " + ", ".join(names()), name) from None


def identity(name: str, config: StudyConfig) -> dict[str, Any]:
    """What a study's files depend on besides its sweeps: mode, seed, cap on looks, package version and
    the hash of the study module's code (and every undulate module it imports); for a study that
    explains other studies' claims, also their verdicts in ``config.out_dir`` (it runs only for the
    claims that fail: :meth:`~._context.StudyContext.needs_explanation`)."""
    from .._source import code_hash
    from ..provenance import package_version
    from ..sweep import backend_identity

    info = describe(name)
    ident = {"study": name, "quick": bool(config.quick), "seed": int(config.seed),
             "undulate_version": package_version("undulate"), "code": code_hash(info.dataset, config.execution),
             "backend": backend_identity(config.execution)}
    if config.max_looks is not None:  # a capped study runs fewer looks (no key without a cap: results kept)
        ident["max_looks"] = config.max_looks
    if info.explanations:  # which explanations it runs for depends on the verdicts it explains
        known = _claim_verdicts(Path(config.out_dir), config)
        ident["explains"] = [list(t) for t in sorted({(e.study, e.claim, known.get((e.study, e.claim), "unknown"))
                                                      for e in info.explanations})]
    return ident


def is_current(name: str, config: StudyConfig) -> bool:
    """True when ``OUT/NAME.json`` was written by this code with these settings."""
    p = Path(config.out_dir) / f"{name}.json"
    try:
        doc = json.loads(p.read_text())
    except (OSError, ValueError):
        return False
    return doc.get("identity") == identity(name, config)
