"""The code stays one that can be extended in an afternoon: no function in ``src/undulate``
is longer than MAX_LINES lines (``def`` to last line, docstring included) unless a comment
containing ``long:`` says why, on the line before the ``def`` (or before its decorators) or
between the signature and the first body line included, e.g.::

    # long: one table of 90 option declarations; splitting it would hide the CLI's shape
    def options(...):
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src" / "undulate"
MAX_LINES = 80
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
