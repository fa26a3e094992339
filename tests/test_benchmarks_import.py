"""The benchmark and exploration scripts are not run by the test suite (timings and
findings are never asserted), so a renamed function would break them silently:
every ``undulate`` name they import, at top level or inside a function, must exist."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "benchmarks"
EXPLORE = ROOT / "explorations"
SCRIPTS = sorted(BENCH.glob("*.py")) + sorted(EXPLORE.glob("*.py"))


def _undulate_imports(path: Path):
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "undulate":
            for alias in node.names:
                yield node.lineno, node.module, alias.name
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "undulate":
                    yield node.lineno, alias.name, None


def test_there_are_benchmarks_and_explorations():
    assert len(list(BENCH.glob("*.py"))) >= 5
    assert len(list(EXPLORE.glob("*.py"))) >= 6


def test_benchmarks_holds_only_benchmarks():
    """``benchmarks/`` times workloads (``bench_*.py``); investigations live in ``explorations/``."""
    assert sorted(p.name for p in BENCH.glob("*.py") if not p.name.startswith("bench_")) == []


def test_the_explorations_readme_lists_every_script():
    readme = (EXPLORE / "README.md").read_text(encoding="utf-8")
    assert [p.name for p in sorted(EXPLORE.glob("*.py")) if f"`{p.name}`" not in readme] == []


@pytest.mark.parametrize("script", SCRIPTS, ids=[f"{p.parent.name}/{p.name}" for p in SCRIPTS])
def test_every_undulate_name_a_benchmark_imports_exists(script):
    missing = []
    for line, module, name in _undulate_imports(script):
        try:
            mod = importlib.import_module(module)
        except ImportError as e:
            missing.append(f"{script.name}:{line}: {module} ({e})")
            continue
        if name is not None and name != "*" and not hasattr(mod, name):
            try:  # a submodule imported by name
                importlib.import_module(f"{module}.{name}")
            except ImportError:
                missing.append(f"{script.name}:{line}: {module}.{name}")
    assert not missing, "scripts import names that no longer exist: " + "; ".join(missing)
