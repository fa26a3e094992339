"""The code stays one that can be extended in an afternoon: no function in ``src/undulate``
is longer than MAX_LINES lines (``def`` to last line, docstring included) unless a comment
containing ``long:`` says why, on the line before the ``def`` (or before its decorators) or
between the signature and the first body line included, e.g.::

    # long: one table of 90 option declarations; splitting it would hide the CLI's shape
    def options(...):

and no module is longer than MAX_MODULE_LINES lines unless it is one cohesive thing that the first
line of its docstring names, listed in LONG_MODULES with the reason it stays whole.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src" / "undulate"
MAX_LINES = 80
MAX_MODULE_LINES = 600
LONG_MODULES = {
    "params.py": "the frozen, validated parameter types: one dataclass per concept, each validated where it is defined",
    "scene.py": "one builder: the MjSpec of swimmers in a channel and its name -> address index",
    "execution.py": "the execution seam: one settings object and the policy of where runs go, kept in one module",
    "robot/runner.py": "one run of the real robots: the servo loop, its controllers' commands and its log",
    "studies/packing.py": "one study (paper Fig. 7): its plan, bisection runs, summary, claims and figure",
    "studies/potential.py": "one study (paper Fig. 10): its plan, impulse, force and release runs, claims and figure",
    "studies/_analysis.py": "the one analysis of pair runs every pair study shares: neighbours, steady state, fits",
    "sweep/_store.py": "one on-disk store of a sweep: its manifest, one file per run, the merge",
}
"""Modules over :data:`MAX_MODULE_LINES` lines that stay whole, each with the reason (path under
``src/undulate``)."""
_REASON = re.compile(r"#.*\blong:")

def _has_reason(lines: list[str], node: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
    candidates = [first - 1, *range(node.lineno, node.body[0].lineno + 1)]  # 1-based line numbers
    return any(1 <= i <= len(lines) and _REASON.search(lines[i - 1]) for i in candidates)


def long_functions(root: Path = SRC) -> list[str]:
    """``path:line name (n lines)`` of every function over MAX_LINES lines without a ``long:`` reason."""
    out = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        text = path.read_text()
        lines = text.splitlines()
        for node in ast.walk(ast.parse(text)):
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            n = node.end_lineno - node.lineno + 1
            if n > MAX_LINES and not _has_reason(lines, node):
                out.append(f"{rel}:{node.lineno} {node.name} ({n} lines)")
    return out


def test_no_function_is_longer_than_80_lines_without_a_reason():
    found = long_functions()
    assert not found, (f"functions over {MAX_LINES} lines: split them into named steps, or put a "
                       f"'# long: <why>' comment on the line before the def:\n  " + "\n  ".join(found))


def test_the_rule_sees_long_functions_and_reasons(tmp_path):
    body = "".join(f"    x{i} = {i}\n" for i in range(MAX_LINES))
    (tmp_path / "a.py").write_text(f"def too_long():\n{body}\n\ndef short():\n    pass\n")
    (tmp_path / "b.py").write_text(f"# long: a table\n@staticmethod\ndef explained():\n{body}")
    deeper = body.replace("    ", "        ")
    (tmp_path / "c.py").write_text(f"class K:\n    def method(self):\n        # long: generated\n{deeper}")
    (tmp_path / "d.py").write_text(f"def inner_only():\n    def nested():\n{deeper}")
    assert long_functions(tmp_path) == [f"a.py:1 too_long ({MAX_LINES + 1} lines)",
                                        f"d.py:1 inner_only ({MAX_LINES + 2} lines)",
                                        f"d.py:2 nested ({MAX_LINES + 1} lines)"]


def long_modules(root: Path = SRC) -> dict[str, int]:
    """``path -> lines`` of every module over MAX_MODULE_LINES lines."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        n = len(path.read_text().splitlines())
        if n > MAX_MODULE_LINES:
            out[path.relative_to(root).as_posix()] = n
    return out


def test_no_module_is_longer_than_600_lines_unless_listed_with_its_reason():
    found = long_modules()
    unlisted = {p: n for p, n in found.items() if p not in LONG_MODULES}
    assert not unlisted, (f"modules over {MAX_MODULE_LINES} lines: split them along their seams, or add them to "
                          f"LONG_MODULES with why they are one thing: {unlisted}")
    stale = sorted(set(LONG_MODULES) - set(found))
    assert not stale, f"LONG_MODULES lists modules that are no longer long (remove them): {stale}"
    for path in LONG_MODULES:  # one thing, named by the first line of its docstring
        import ast as _ast

        doc = _ast.get_docstring(_ast.parse((SRC / path).read_text())) or ""
        assert doc.strip() and LONG_MODULES[path].strip(), path


def test_the_module_rule_sees_long_modules(tmp_path):
    (tmp_path / "a.py").write_text("x = 1\n" * (MAX_MODULE_LINES + 1))
    (tmp_path / "b.py").write_text("x = 1\n" * MAX_MODULE_LINES)
    assert long_modules(tmp_path) == {"a.py": MAX_MODULE_LINES + 1}
