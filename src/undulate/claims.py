"""The claims table of a reproduction: collected from the studies' own judgements.

Each claim lives beside its study (``CLAIMS`` in ``undulate/studies/NAME.py``:
a pure function of that study's summary, judged on the 95 % intervals of its
numbers) and is judged when the study runs (``NAME.json["claims"]``).  This
module only gathers those rows for the report and for ``claims.json``.

A row: ``study``, ``claim``, ``paper`` (the paper's statement), ``measured``
(the measured value with its uncertainty, as text), ``value`` (the same as
numbers), ``verdict`` (``holds``, ``fails`` or ``no result``), ``reason``
(why there is no result), ``criterion``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ._io import atomic_write_text

__all__ = ["VERDICTS", "collect", "write_claims_json", "FIELDS"]

VERDICTS = ("holds", "fails", "no result")
FIELDS = ("study", "claim", "paper", "measured", "value", "verdict", "reason", "criterion")


def collect(out_dir: str | Path, names: list[str]) -> list[dict[str, Any]]:
    """The claim rows of studies ``names`` from ``out_dir/NAME.json`` (in that order)."""
    rows = []
    for name in names:
        p = Path(out_dir) / f"{name}.json"
        if not p.is_file():
            continue
        for r in json.loads(p.read_text()).get("claims", []):
            rows.append({k: r.get(k) for k in FIELDS})
    return rows


def write_claims_json(out_dir: str | Path, rows: list[dict[str, Any]]) -> Path:
    """Write ``out_dir/claims.json`` (atomically): ``{"claims": rows, "counts": {verdict: n}}``."""
    path = Path(out_dir) / "claims.json"
    counts = {v: sum(r["verdict"] == v for r in rows) for v in VERDICTS}
    atomic_write_text(path, json.dumps({"claims": rows, "counts": counts}, indent=2, allow_nan=False) + "\n")
    return path
