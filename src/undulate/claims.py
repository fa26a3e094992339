"""The claims table of a reproduction: collected from the studies' own judgements.

Each claim lives beside its study (``CLAIMS`` in ``undulate/studies/NAME.py``:
a pure function of that study's summary, judged on the intervals of its
numbers) and is judged when the study runs (``NAME.json["claims"]``).  This
module gathers those rows for the report and for ``claims.json``.  How a
verdict is decided (intervals, several criteria, staged runs, the look
correction) is told in the documentation's *Verdicts* page.

Verdicts (:data:`VERDICTS`): ``holds``, ``fails``, ``undecided`` (an interval
straddles its criterion's boundary: the row's ``reason`` names the boundary
and ``runs_needed`` estimates the runs that would decide it), ``no result``
(from the claim's own study) and ``explained``: the claim fails under the
default model **and** a study's :class:`~undulate.studies.Explanation` of it
was shown by that study's own runs (``NAME.json["explanations"]``, ``shown``
true: e.g. the claim's criterion holds with only the named factor changed).
Nothing else turns a failing claim into ``explained``: an explanation that
its runs did not show (``shown`` false) or left undecided (``shown`` null) is
listed with the row (``explanations_not_shown``) and the claim stays
``fails``.  A *finding* (an explanation that needs several changes together:
:class:`~undulate.studies._explanations.CaseFinding`) never changes a verdict: it is written beside the
claim (``findings``), shown or not.  Every study's summary and claim values must stay inside their
quantities' physical domains (:func:`undulate.stats.domain_violations`), or :func:`collect` refuses it.

A row: ``study``, ``claim``, ``paper`` (the paper's statement), ``measured``
(the measured value with its uncertainty, as text), ``value`` (the same as
numbers), ``verdict``, ``reason`` (why there is no result, or the boundary an
undecided claim straddles), ``criterion``, ``reference`` (whose claim it is:
``"paper"``, the reproduced paper, or ``"prx2021"``, beyond the paper:
synchronization through contact, Zhou, Hao & Gravish, Phys. Rev. X 11, 031051
(2021); a row from a study file written before the field existed counts as
``"paper"``), ``runs_needed`` (for ``undecided``: about how many runs would
decide it, or null), ``decided_at`` (for a claim that holds or fails: the
look of its study's staged plan that decided it, ``stage``, ``of``,
``confidence_level``; the look whose numbers the row shows,
``measured_at_stage``, the last that decided it the same way; and the
verdicts the study's later looks, run for other claims, gave it on their
own, ``later_verdicts``; null otherwise, and for a study file written before
the field existed), ``explanation`` (for
``explained``: ``cause``, ``measured`` evidence numbers, ``value``,
``evidence_study``, ``evidence_figure``, ``shown``, ``decided_at``; else
null) and, when some explanation of the
claim was tested but not shown, ``explanations_not_shown`` (the same fields,
``shown`` false or null).

``quote`` (the paper's own sentence the claim tests, verbatim from ``paper.tex``; for a PRX 2021 claim
the statement as SPEC.md §6 gives it), ``where`` (the paper's section and figure), ``superseded`` (the
criteria the claim was judged by before, each judged again on the same summary: ``criterion``, ``why``,
``verdict``, ``measured``, ``reason``; empty when the criterion never changed; a study file written
before these fields existed gives ``""``, ``""`` and ``[]``).

``claims.json``: ``{"claims": rows, "counts": {verdict: n},
"counts_by_reference": {"paper": {verdict: n}, "prx2021": {verdict: n}}}``;
``counts`` counts every row (as before), ``counts_by_reference`` each
reference's rows apart; both list every verdict of :data:`VERDICTS`.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from ._io import atomic_write_text

__all__ = ["VERDICTS", "REFERENCES", "collect", "apply_explanations", "counts", "counts_by_reference",
           "reference_of", "write_claims_json", "FIELDS", "quote_text", "claims_table_markdown"]

VERDICTS = ("holds", "explained", "undecided", "fails", "no result")
REFERENCES = ("paper", "prx2021")
"""Whose claims a row judges: the reproduced paper, or beyond it the PRX 2021 synchronization paper
(:attr:`undulate.studies.Study.reference`)."""
FIELDS = ("study", "claim", "paper", "quote", "where", "measured", "value", "verdict", "reason", "criterion",
          "reference", "runs_needed", "decided_at", "superseded")
_EXPLANATION_FIELDS = ("cause", "measured", "value", "evidence_study", "evidence_figure", "shown", "decided_at")


def reference_of(row: dict[str, Any]) -> str:
    """A row's reference; a row without one (a study file older than the field) is the paper's."""
    return row.get("reference") or "paper"


def apply_explanations(rows: list[dict[str, Any]], explanations: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Rows with ``explanation`` set and ``fails`` -> ``explained`` where a shown explanation
    names that (study, claim); explanations not shown (false or undecided) go to
    ``explanations_not_shown``.  A finding (an explanation row with ``finding`` true: several changes
    together, :class:`~undulate.studies._explanations.CaseFinding`) never changes the verdict: shown or
    not, it goes to ``findings``, written beside the claim."""
    out = []
    for r in rows:
        r = {**r, "explanation": None}
        about = [e for e in explanations if e.get("study") == r["study"] and e.get("claim") == r["claim"]]
        findings = [{k: e.get(k) for k in _EXPLANATION_FIELDS} for e in about if e.get("finding")]
        if findings:
            r["findings"] = findings
        mine = [e for e in about if not e.get("finding")]
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
    explanations of every study among ``names`` applied (:func:`apply_explanations`).  A row
    without ``reference`` (an older study file) gets ``"paper"``.  A study whose summary or claim
    values report a number or interval outside its quantity's physical domain is refused
    (:func:`undulate.stats.check_domains`: :class:`~undulate.errors.UndulateError`)."""
    rows, explanations = [], []
    for name in names:
        p = Path(out_dir) / f"{name}.json"
        if not p.is_file():
            continue
        doc = json.loads(p.read_text())
        for r in doc.get("claims", []):
            row = {k: r.get(k) for k in FIELDS}
            row["reference"] = reference_of(row)
            row["quote"], row["where"] = row["quote"] or "", row["where"] or ""
            row["superseded"] = row["superseded"] or []
            rows.append(row)
        explanations += doc.get("explanations", [])
        from . import stats

        stats.check_domains({"summary": doc.get("summary"), "claims": [r.get("value") for r in doc.get("claims", [])]},
                            f"study {name!r} ({p})")
    return apply_explanations(rows, explanations)


def counts(rows: list[dict[str, Any]]) -> dict[str, int]:
    """``{verdict: n}`` over ``rows``, every verdict of :data:`VERDICTS` (in that order)."""
    return {v: sum(r.get("verdict") == v for r in rows) for v in VERDICTS}


def counts_by_reference(rows: list[dict[str, Any]]) -> dict[str, dict[str, int]]:
    """:func:`counts` of each reference's rows: every one of :data:`REFERENCES` (zero counts when it
    has no rows), then any other reference met, in the order met."""
    refs = list(REFERENCES) + [x for x in dict.fromkeys(reference_of(r) for r in rows) if x not in REFERENCES]
    return {ref: counts([r for r in rows if reference_of(r) == ref]) for ref in refs}


def write_claims_json(out_dir: str | Path, rows: list[dict[str, Any]]) -> Path:
    """Write ``out_dir/claims.json`` (atomically): ``{"claims": rows, "counts": {verdict: n},
    "counts_by_reference": {reference: {verdict: n}}}``."""
    path = Path(out_dir) / "claims.json"
    doc = {"claims": rows, "counts": counts(rows), "counts_by_reference": counts_by_reference(rows)}
    atomic_write_text(path, json.dumps(doc, indent=2, allow_nan=False) + "\n")
    return path


# ------------------------------------------------------------------- the paper's sentences
_CITE = re.compile(r"\s*~?\\cite[tp]?\{[^}]*\}")
_REF_PAREN = re.compile(r"\s*\((?:Figs?\.|Figure|Eqns?\.|Equations?|Sections?)[^()]*?\\ref\{[^}]*\}[^()]*\)")
_FIGURES = {"fig:fig1": "1", "fig:methods": "2", "fig:two_robot_experiment": "3", "fig:compatibility": "4",
            "fig:more_links": "5", "fig:robotgroups": "6", "fig:spatial_packing": "7", "fig:basins": "8",
            "fig:spacing_basins": "9", "fig:potential": "10"}
"""The paper's figure labels and their numbers (the order of its figures in ``paper.tex``)."""
_REF = re.compile(r"\\ref\{([^}]*)\}")


def quote_text(text: str) -> str:
    """A sentence of ``paper.tex`` as a claim quotes it and the page shows it: citations
    (``\\cite{...}``) and parenthesised references to figures, equations or sections
    (``(Fig.~\\ref{fig:potential}d)``: the claim's ``where`` says it) taken out, a figure's other
    ``\\ref`` replaced by its number, ``~`` by a space, whitespace collapsed; math is kept as written.
    The same on both sides decides whether a quote is verbatim (``tests/test_paper_claims.py``)."""
    t = _REF_PAREN.sub("", _CITE.sub("", str(text or "")))
    t = _REF.sub(lambda m: _FIGURES.get(m.group(1), m.group(0)), t)
    return " ".join(t.replace("~", " ").split())


def _cell(text: Any) -> str:
    return " ".join(str(text or "").split()).replace("|", "\\|")


def claims_table_markdown(claims: str | Path | dict[str, Any]) -> str:
    """The claims table of a ``claims.json`` (its path, or the document) as Markdown: the counts of
    each reference apart (the paper's first), then one row per claim: study, claim, verdict, the
    measured value, and the paper's sentence it tests with where the paper states it.  What
    ``docs/full_reproduction.md`` opens with (``undulate claims-table CLAIMS_JSON``)."""
    doc = claims if isinstance(claims, dict) else json.loads(Path(claims).read_text())
    rows = doc.get("claims", [])
    by = doc.get("counts_by_reference") or counts_by_reference(rows)
    names = {"paper": "The paper's claims", "prx2021": "Beyond the paper (PRX 2021, against our controllers)"}
    out = ["| claims | " + " | ".join(VERDICTS) + " | all |", "|---|" + "---:|" * (len(VERDICTS) + 1)]
    for ref, k in by.items():
        out.append(f"| {names.get(ref, ref)} | " + " | ".join(str(k.get(v, 0)) for v in VERDICTS)
                   + f" | {sum(k.get(v, 0) for v in VERDICTS)} |")
    for ref in by:
        mine = [r for r in rows if reference_of(r) == ref]
        if not mine:
            continue
        out += ["", f"**{names.get(ref, ref)}**", "",
                "| study | claim | verdict | measured | the sentence it tests (where) |", "|---|---|---|---|---|"]
        for r in mine:
            quote = quote_text(r.get("quote") or "") or f"(paraphrase) {r.get('paper') or ''}"
            where = f"({r['where']})" if r.get("where") else ""
            old = "; ".join(f"before: {o.get('criterion')} -> {o.get('verdict')}" for o in r.get("superseded") or [])
            verdict = r.get("verdict", "") + (f" ({old})" if old else "")
            out.append(f"| {_cell(r.get('study'))} | {_cell(r.get('claim'))} | {_cell(verdict)} | "
                       f"{_cell(r.get('measured'))} | \u201c{_cell(quote)}\u201d {_cell(where)} |")
    return "\n".join(out) + "\n"
