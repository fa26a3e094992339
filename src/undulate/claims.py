"""The claims table of a reproduction: collected from the studies' own judgements.

Each claim lives beside its study (``CLAIMS`` in ``undulate/studies/NAME.py``:
a pure function of that study's summary, judged on the 95 % intervals of its
numbers) and is judged when the study runs (``NAME.json["claims"]``).  This
module gathers those rows for the report and for ``claims.json``.

Verdicts: ``holds``, ``fails``, ``no result`` (from the claim's own study)
and ``explained``: the claim fails under the default model **and** a study's
:class:`~undulate.studies.Explanation` of it was shown by that study's own
runs (``NAME.json["explanations"]``, ``shown`` true: e.g. the claim's
criterion holds with only the named factor changed).  Nothing else turns a
failing claim into ``explained``: an explanation that its runs did not show
is listed with the row (``explanations_not_shown``) and the claim stays
``fails``.

A row: ``study``, ``claim``, ``paper`` (the paper's statement), ``measured``
(the measured value with its uncertainty, as text), ``value`` (the same as
numbers), ``verdict``, ``reason`` (why there is no result), ``criterion``,
``explanation`` (for ``explained``: ``cause``, ``measured`` evidence numbers,
``evidence_study``, ``evidence_figure``; else None).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ._io import atomic_write_text

__all__ = ["VERDICTS", "collect", "apply_explanations", "write_claims_json", "FIELDS"]

VERDICTS = ("holds", "explained", "fails", "no result")
FIELDS = ("study", "claim", "paper", "measured", "value", "verdict", "reason", "criterion")
_EXPLANATION_FIELDS = ("cause", "measured", "value", "evidence_study", "evidence_figure")


def apply_explanations(rows: list[dict[str, Any]], explanations: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Rows with ``explanation`` set and ``fails`` -> ``explained`` where a shown explanation
    names that (study, claim); explanations not shown go to ``explanations_not_shown``."""
    out = []
    for r in rows:
        r = {**r, "explanation": None}
        mine = [e for e in explanations if e.get("study") == r["study"] and e.get("claim") == r["claim"]]
        shown = [e for e in mine if e.get("shown") is True]
        if r["verdict"] == "fails" and shown:
            r["verdict"] = "explained"
            r["explanation"] = {k: shown[0].get(k) for k in _EXPLANATION_FIELDS}
        not_shown = [{k: e.get(k) for k in _EXPLANATION_FIELDS} for e in mine if e.get("shown") is not True]
        if not_shown:
            r["explanations_not_shown"] = not_shown
        out.append(r)
    return out


def collect(out_dir: str | Path, names: list[str]) -> list[dict[str, Any]]:
    """The claim rows of studies ``names`` from ``out_dir/NAME.json`` (in that order), with the
    explanations of every study among ``names`` applied (:func:`apply_explanations`)."""
    rows, explanations = [], []
    for name in names:
        p = Path(out_dir) / f"{name}.json"
        if not p.is_file():
            continue
        doc = json.loads(p.read_text())
        for r in doc.get("claims", []):
            rows.append({k: r.get(k) for k in FIELDS})
        explanations += doc.get("explanations", [])
    return apply_explanations(rows, explanations)


def write_claims_json(out_dir: str | Path, rows: list[dict[str, Any]]) -> Path:
    """Write ``out_dir/claims.json`` (atomically): ``{"claims": rows, "counts": {verdict: n}}``."""
    path = Path(out_dir) / "claims.json"
    counts = {v: sum(r["verdict"] == v for r in rows) for v in VERDICTS}
    atomic_write_text(path, json.dumps({"claims": rows, "counts": counts}, indent=2, allow_nan=False) + "\n")
    return path
