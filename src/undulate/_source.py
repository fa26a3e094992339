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

The hash must name the code the process *runs*, not the files as they are
when the hash is taken: :func:`snapshot` records every package file when
``undulate`` is imported, and a hash taken after one of them changed on
disk raises :class:`SourceChangedError` (so does :func:`check_unchanged`,
which a sweep calls before it writes its merged result).
"""

from __future__ import annotations

import ast
import functools
import hashlib
import sys
from collections.abc import Callable, Iterable
from pathlib import Path

from .errors import UndulateError
from .execution import Execution, current

__all__ = ["PACKAGE", "module_files", "import_graph", "find_cycle", "closure", "code_hash", "function_modules",
           "snapshot", "check_unchanged", "SourceChangedError"]

PACKAGE = "undulate"
_ROOT = Path(__file__).resolve().parent
BACKEND_MODULES = {"warp": tuple(f"undulate.simulation._warp{part}" for part in (
    "", "_device", "_group", "_kernels", "_private", "_servo", "_timeline", "_worlds"))}
"""The modules of each optional stepping backend.  :func:`code_hash` counts those of the session's
backend only (:attr:`undulate.execution.Execution.backend`): an edit to the Warp
backend does not invalidate results of the MuJoCo one, and a Warp result names its backend's code."""


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


_SEEN: dict[str, tuple[int, int]] = {}
"""``{file: (mtime_ns, size)}`` of the package's files as this process first saw them (at ``import
undulate``: :func:`snapshot`), i.e. the code this process runs."""


def _stat(path: Path) -> tuple[int, int]:
    st = path.stat()
    return st.st_mtime_ns, st.st_size


def snapshot(root: Path = _ROOT) -> None:
    """Record the package's files as they are now (called once, when ``undulate`` is imported)."""
    for p in module_files(root).values():
        _SEEN.setdefault(str(p), _stat(p))


class SourceChangedError(UndulateError, RuntimeError):
    """A package file changed on disk after this process loaded the package: a result computed now
    could not be attributed to one version of the code."""


def _digest(path: Path) -> str:
    now = _stat(path)
    first = _SEEN.get(str(path), now)  # files outside the package (a user's module) are hashed as they are
    if now != first:
        raise SourceChangedError(
            f"{path} changed after this process started: a result computed now would be labelled with code "
            "it did not run; start the command again (finished runs are kept, and recomputed only where "
            "their code changed)")
    return _file_digest(str(path), *now)


def check_unchanged(fn: Callable) -> None:
    """Raise :class:`SourceChangedError` if a file behind ``fn`` (see :func:`code_hash`) changed since
    this process loaded the package (the sweep engine calls it before it writes a merged result)."""
    code_hash(fn)


def code_hash(fn: Callable, execution: Execution | None = None) -> str:
    """SHA-256 (hex, 16 characters) of the source behind ``fn``.

    The files of the modules :func:`function_modules` names and, for
    ``undulate`` modules, of every ``undulate`` module they reach
    (:func:`closure`), of the stepping backend ``execution`` names only (None: the settings in effect,
    :func:`undulate.execution.current`).  A module outside the package (a test's or a user's
    sweep function) contributes its own file.
    """
    files = module_files()
    mods = function_modules(fn)
    own = closure([m for m in mods if m in files])
    optional = {m for ms in BACKEND_MODULES.values() for m in ms}
    if own & optional:  # the code reaches the backends: count the session's own only
        selected = set(BACKEND_MODULES.get((execution or current()).backend, ()))
        own = (own - optional) | (selected & set(files))
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
