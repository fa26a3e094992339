"""The package's own source: its import graph, and hashes of the code behind a result.

:func:`import_graph` reads every module of ``undulate`` with :mod:`ast` (no
import happens) and lists, per module, the ``undulate`` modules it imports
-- at the top or inside a function, everything but ``if TYPE_CHECKING:``
blocks.  The test suite asserts it has no cycle.

:func:`code_hash` hashes the source of a function's module and of every
``undulate`` module it reaches through that graph: the code that computes a
sweep's run.  Any edit there (a constant such as a duration or a tolerance,
a default, the simulator) changes the hash, and the sweep store then
recomputes instead of reusing (:mod:`undulate.sweep`).
"""

from __future__ import annotations

import ast
import functools
import hashlib
import sys
from collections.abc import Callable, Iterable
from pathlib import Path

__all__ = ["PACKAGE", "module_files", "import_graph", "find_cycle", "closure", "code_hash", "function_modules"]

PACKAGE = "undulate"
_ROOT = Path(__file__).resolve().parent


def module_files(root: Path = _ROOT) -> dict[str, Path]:
    """``{dotted module name: file}`` for every ``.py`` file of the package."""
    out = {}
    for p in sorted(root.rglob("*.py")):
        rel = p.relative_to(root).with_suffix("")
        parts = [PACKAGE, *rel.parts]
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def _imports(tree: ast.AST, module: str, is_package: bool, known: set[str]) -> set[str]:
    out: set[str] = set()
    base = module.split(".") if is_package else module.split(".")[:-1]

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node):
            for n in node.orelse:
                visit(n)
            return
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name == PACKAGE or a.name.startswith(PACKAGE + "."):
                    out.add(a.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                target = base[: len(base) - (node.level - 1)]
                if node.module:
                    target = [*target, *node.module.split(".")]
            elif node.module and (node.module == PACKAGE or node.module.startswith(PACKAGE + ".")):
                target = node.module.split(".")
            else:
                target = None
            if target is not None:
                name = ".".join(target)
                for a in node.names:  # `from . import theory` imports the module undulate.theory
                    sub = f"{name}.{a.name}"
                    out.add(sub if sub in known else name)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return {m for m in out if m in known and m != module}


@functools.lru_cache(maxsize=4)
def import_graph(root: Path = _ROOT) -> dict[str, frozenset[str]]:
    """``{module: undulate modules it imports}`` (AST; see the module docstring)."""
    files = module_files(root)
    known = set(files)
    graph = {}
    for mod, path in files.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        graph[mod] = frozenset(_imports(tree, mod, path.name == "__init__.py", known))
    return graph


def find_cycle(graph: dict[str, Iterable[str]]) -> list[str] | None:
    """One import cycle ``[a, b, ..., a]``, or None when the graph has none."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def dfs(u: str) -> list[str] | None:
        state[u] = 1
        stack.append(u)
        for v in sorted(graph.get(u, ())):
            if state.get(v) == 1:
                return stack[stack.index(v):] + [v]
            if v not in state:
                found = dfs(v)
                if found:
                    return found
        stack.pop()
        state[u] = 2
        return None

    for u in sorted(graph):
        if u not in state:
            found = dfs(u)
            if found:
                return found
    return None


def closure(modules: Iterable[str], graph: dict[str, Iterable[str]] | None = None) -> set[str]:
    """``modules`` and every ``undulate`` module they import, directly or not."""
    graph = import_graph() if graph is None else graph
    seen: set[str] = set()
    todo = [m for m in modules if m in graph]
    while todo:
        m = todo.pop()
        if m in seen:
            continue
        seen.add(m)
        todo.extend(graph.get(m, ()))
    return seen


def function_modules(fn: Callable) -> list[str]:
    """Modules that define ``fn`` (through ``functools.partial`` layers) and the classes
    or functions bound as its arguments."""
    mods = []
    while isinstance(fn, functools.partial):
        for v in (*fn.args, *fn.keywords.values()):
            m = getattr(type(v), "__module__", None)
            if m:
                mods.append(m)
        fn = fn.func
    mods.append(getattr(fn, "__module__", None) or type(fn).__module__)
    return mods


@functools.lru_cache(maxsize=256)
def _file_digest(path: str, mtime_ns: int, size: int) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _digest(path: Path) -> str:
    st = path.stat()
    return _file_digest(str(path), st.st_mtime_ns, st.st_size)


def code_hash(fn: Callable) -> str:
    """SHA-256 (hex, 16 characters) of the source behind ``fn``.

    The files of the modules :func:`function_modules` names and, for
    ``undulate`` modules, of every ``undulate`` module they reach
    (:func:`closure`).  A module outside the package (a test's or a user's
    sweep function) contributes its own file.
    """
    files = module_files()
    mods = function_modules(fn)
    own = closure([m for m in mods if m in files])
    paths: dict[str, Path] = {m: files[m] for m in own}
    for m in mods:
        if m not in files:
            f = getattr(sys.modules.get(m), "__file__", None)
            if f:
                paths[m] = Path(f)
    h = hashlib.sha256()
    for m in sorted(paths):
        h.update(m.encode() + b"\0" + _digest(paths[m]).encode() + b"\0")
    return h.hexdigest()[:16]
