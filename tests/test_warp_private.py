"""MuJoCo Warp's and Warp's private modules are reached through one adapter
(:func:`undulate.simulation._warp_private.private_api`).  These tests import exactly what it reads, so a
release that moves any of it fails here, by name, before a run does; and they check that no other
module of the package imports a ``_src`` module."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parent.parent / "src" / "undulate"


def test_the_private_names_the_adapter_reads_are_where_it_reads_them():
    pytest.importorskip("warp", reason="the gpu extra (mujoco-warp, warp-lang) is not installed")
    pytest.importorskip("mujoco_warp")
    from mujoco_warp._src import types
    from warp._src import context
    from warp._src.context import _normalize_launch_dim, _resolve_launch_block_dim

    from undulate.simulation._warp_device import resolve_device

    resolve_device("cpu")  # wp.init(): Warp's runtime is made
    runtime = context.runtime
    assert callable(_normalize_launch_dim) and callable(_resolve_launch_block_dim)
    for name in ("wp_cuda_stream_synchronize", "wp_cuda_context_get_current", "wp_cuda_context_set_current"):
        assert hasattr(runtime.core, name), name
    assert callable(runtime.get_error_string)
    for cls in (types.Model, types.Option):  # dataclasses whose array specs mark per-world fields with "*"
        shapes = [tuple(getattr(f.type, "shape", None) or ()) for f in dataclasses.fields(cls)]
        assert any(s[:1] == ("*",) for s in shapes), cls.__name__


def test_the_adapter_names_the_fields_mujoco_warp_batches_per_world():
    """What world grouping relies on (:func:`undulate.simulation._warp_worlds.plan_worlds`): the fields
    our scenes differ in across a sweep (the channel's walls, drag, gains, contact stiffness, the
    viscosity) are carried and batchable per world, and a field MuJoCo Warp fixes per model is not."""
    pytest.importorskip("warp", reason="the gpu extra (mujoco-warp, warp-lang) is not installed")
    pytest.importorskip("mujoco_warp")
    from undulate.simulation._warp_private import private_api

    api = private_api()
    per_world = {"geom_pos", "geom_solref", "actuator_gainprm", "actuator_biasprm", "body_mass"}
    assert per_world <= api.per_world_model_fields <= api.model_fields
    assert "viscosity" in api.per_world_option_fields
    assert "nq" in api.model_fields and "nq" not in api.per_world_model_fields
    assert private_api() is api  # read once a process
    from undulate.simulation._warp_device import resolve_device

    resolve_device("cpu")
    assert api.runtime is not None  # Warp's runtime, read when asked for (made by wp.init())


def _private_imports(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                 else [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
        found += [n for n in names if n.split(".")[0] in ("warp", "mujoco_warp") and "._src" in "." + n]
    return found


def test_only_the_adapter_imports_private_modules_of_warp():
    """``warp._src`` and ``mujoco_warp._src`` are imported in ``simulation/_warp_private.py`` alone."""
    where = {p.relative_to(SRC).as_posix(): _private_imports(p) for p in sorted(SRC.rglob("*.py"))}
    where = {p: names for p, names in where.items() if names}
    assert set(where) == {"simulation/_warp_private.py"}, where
    assert sorted(where["simulation/_warp_private.py"]) == ["mujoco_warp._src", "warp._src", "warp._src.context"]
