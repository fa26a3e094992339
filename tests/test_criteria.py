"""The claims' criteria are stated once (``undulate.studies._criteria``) and judged by that one value."""

from __future__ import annotations

import ast
from pathlib import Path

import undulate.studies as studies
from undulate.studies import _criteria as criteria

STUDIES_DIR = Path(studies.__file__).parent


def _modules():
    return [p for p in sorted(STUDIES_DIR.glob("*.py")) if p.name != "_criteria.py"]


def _assigned_names(tree: ast.Module) -> set[str]:
    out = set()
    for node in tree.body:
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else []
        for t in targets:
            out |= {n.id for n in ast.walk(t) if isinstance(n, ast.Name)}
    return out


def test_no_study_module_redeclares_a_criterion():
    names = set(criteria.__all__)
    for path in _modules():
        clash = _assigned_names(ast.parse(path.read_text())) & names
        assert not clash, f"{path.name} redeclares {sorted(clash)}: import them from undulate.studies._criteria"


def test_the_pair_channel_is_written_once():
    """No study module spells the pair channel's 0.13 m as a number (docstrings and messages aside)."""
    for path in _modules():
        tree = ast.parse(path.read_text())
        doc_nodes = {id(n.value) for n in ast.walk(tree) if isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)}
        literals = [n.lineno for n in ast.walk(tree)
                    if isinstance(n, ast.Constant) and n.value == criteria.PAIR_CHANNEL_M and id(n) not in doc_nodes]
        assert not literals, f"{path.name} lines {literals}: use criteria.PAIR_CHANNEL_M"


def test_studies_judge_with_the_shared_values():
    """The studies' criterion texts quote the shared numbers (the text a report shows is the rule applied)."""
    from undulate.studies import describe

    text = " ".join(c.criterion for c in describe("pairs").claims)
    assert f"1 +- {criteria.LINE_SLOPE_TOL}" in text and f"below {criteria.LINE_RMS_TOL} lambda" in text
    groups = " ".join(c.criterion for c in describe("groups").claims)
    assert f"1 +- {criteria.GROUP_SLOPE_TOL}" in groups and f"d = {criteria.PAIR_CHANNEL_M} m" in groups
    assert f">= {criteria.R2_MIN}" in " ".join(c.criterion for c in describe("potential").claims)
