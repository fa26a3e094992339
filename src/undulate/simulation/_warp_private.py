"""The one place that reaches into MuJoCo Warp's and Warp's private modules (:func:`private_api`).

Both are pinned by the ``gpu`` extra; a release that moves what is read here fails
``tests/test_warp_private.py``, which imports exactly these names, before any run does."""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from typing import Any

__all__ = ["WarpInternals", "private_api"]


@dataclasses.dataclass(frozen=True)
class WarpInternals:
    """What the Warp backend needs that MuJoCo Warp and Warp keep private.

    ``model_fields``: the MjModel fields a MuJoCo Warp model carries (``mujoco_warp._src.types.Model``);
    ``per_world_model_fields`` / ``per_world_option_fields``: those it may batch per world (an array
    spec whose first dimension is ``"*"``; ``Model`` and ``Option``); ``normalize_launch_dim``,
    ``resolve_launch_block_dim``: how ``wp.launch`` reads a launch's size and block size;
    ``context``: the module holding Warp's runtime (:attr:`runtime`)."""

    model_fields: frozenset[str]
    per_world_model_fields: frozenset[str]
    per_world_option_fields: frozenset[str]
    normalize_launch_dim: Callable[..., Any]
    resolve_launch_block_dim: Callable[..., Any]
    context: Any

    @property
    def runtime(self) -> Any:
        """Warp's runtime (its native stream synchronisation and CUDA context), set by ``wp.init()``:
        read when asked for, not when the adapter was made."""
        return self.context.runtime


def _per_world(field: dataclasses.Field) -> bool:
    """An array spec whose first dimension is ``"*"`` (a per-world field)."""
    return tuple(getattr(field.type, "shape", None) or ())[:1] == ("*",)


@functools.lru_cache(maxsize=1)
def private_api() -> WarpInternals:
    """:class:`WarpInternals`, read once a process (the ``gpu`` extra must be installed:
    :func:`undulate.simulation._warp_device.require`)."""
    from ._warp_device import require

    require()
    from mujoco_warp._src import types
    from warp._src import context
    from warp._src.context import _normalize_launch_dim, _resolve_launch_block_dim

    model = dataclasses.fields(types.Model)
    return WarpInternals(
        model_fields=frozenset(f.name for f in model),
        per_world_model_fields=frozenset(f.name for f in model if _per_world(f)),
        per_world_option_fields=frozenset(f.name for f in dataclasses.fields(types.Option) if _per_world(f)),
        normalize_launch_dim=_normalize_launch_dim, resolve_launch_block_dim=_resolve_launch_block_dim,
        context=context)
