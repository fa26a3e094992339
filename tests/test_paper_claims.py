"""Every claim of the paper's studies quotes the sentence it tests and has its row in docs/paper_claims.md.

The chain: a claim's ``quote`` must be one of the sentences ``docs/paper_claims.md`` quotes (in the repository,
so this holds on a fresh clone), each of those must be verbatim in ``paper.tex`` (where it is at hand:
``$UNDULATE_PAPER_TEX`` or ``/work/shared/paper.tex``), and every claim must be named there, so a new claim
without its row fails.  Both sides go through the same normalisation, :func:`undulate.claims.quote_text`.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

from undulate.claims import claims_table_markdown, quote_text
from undulate.studies import describe, names

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "paper_claims.md"
PAPER = Path(os.environ.get("UNDULATE_PAPER_TEX", "/work/shared/paper.tex"))


def _claims(reference: str):
    return [(n, c) for n in names() if describe(n).reference == reference for c in describe(n).claims]


def _doc_quotes() -> list[str]:
    return [quote_text(line[2:]) for line in DOC.read_text().splitlines() if line.startswith("> ")]


def test_every_paper_claim_quotes_a_sentence_of_the_paper_and_says_where():
    claims = _claims("paper")
    assert len(claims) >= 17
    quotes = _doc_quotes()
    for study, c in claims:
        q = quote_text(c.quote)
        assert q and c.where, f"{study}: {c.claim!r} has no quote or no where"
        assert re.search(r"Sec\.|Fig\.", c.where), c.where
        assert any(q in d for d in quotes) or any(d in q for d in quotes if len(d) > 40), \
            f"{study}: {c.claim!r} quotes a sentence docs/paper_claims.md does not list: {q[:80]!r}"


def test_the_prx_claims_say_whose_statement_they_quote():
    claims = _claims("prx2021")
    assert claims
    for study, c in claims:
        assert c.quote.strip() and ("PRX 2021" in c.where or "SPEC.md" in c.where), (study, c.claim, c.where)


def test_docs_paper_claims_names_every_paper_claim():
    """A claim of the paper's studies without its row in docs/paper_claims.md fails here."""
    text = DOC.read_text().replace("\\|", "|")
    missing = [f"{s}: {c.claim}" for s, c in _claims("paper") if f"**{s}**: {c.claim}" not in text]
    assert missing == [], f"add a row to docs/paper_claims.md for: {missing}"
    names_in_doc = set(re.findall(r"\*\*([a-z-]+)\*\*: ", text))
    assert names_in_doc <= set(names()), names_in_doc - set(names())


@pytest.mark.skipif(not PAPER.is_file(), reason="paper.tex is not at hand (UNDULATE_PAPER_TEX)")
def test_every_sentence_the_docs_and_claims_quote_is_verbatim_in_the_paper():
    paper = quote_text(PAPER.read_text())
    bad = [q for q in _doc_quotes() if q not in paper]
    bad += [quote_text(c.quote) for _, c in _claims("paper") if quote_text(c.quote) not in paper]
    assert bad == []


def test_quote_text_removes_citations_and_parenthesised_references_and_keeps_math():
    s = r"We found that k decreases (Fig.~\ref{fig:potential}d) as in \cite{Yuan2014-xs} with $\Delta x$~= 0."
    assert quote_text(s) == r"We found that k decreases as in with $\Delta x$ = 0."
    assert quote_text(r"see Figure~\ref{fig:spatial_packing}b and Eqn.~\ref{eqn:sep}") == \
        r"see Figure 7b and Eqn. \ref{eqn:sep}"
    assert quote_text("a  b\n c") == "a b c"


def test_the_claims_table_renders_every_claim_with_its_sentence_and_the_paper_counts_apart():
    rows = [{"study": "pairs", "claim": "xi = 1: follows | the line", "verdict": "holds", "measured": "slope 1.0",
             "quote": r"Similarly in simulation (Fig.~\ref{fig:two_robot_experiment}c) we agree.", "where": "Sec. III.B",
             "reference": "paper", "superseded": [{"criterion": "old", "verdict": "fails"}]},
            {"study": "sync", "claim": "relay: locks", "verdict": "fails", "measured": "2/9", "quote": "locks",
             "where": "PRX 2021", "reference": "prx2021"}]
    md = claims_table_markdown({"claims": rows})
    lines = md.splitlines()
    assert lines[2].startswith("| The paper's claims | 1 | 0 | 0 | 0 | 0 | 1 |")
    assert lines[3].startswith("| Beyond the paper") and lines[3].endswith("| 0 | 0 | 0 | 1 | 0 | 1 |")
    (row,) = [x for x in lines if x.startswith("| pairs |")]
    assert "follows \\| the line" in row and "Similarly in simulation we agree." in row and "(Sec. III.B)" in row
    assert "holds (before: old -> fails)" in row
    assert md.index("The paper's claims**") < md.index("Beyond the paper (PRX 2021, against our controllers)**")


def test_the_claims_table_command_prints_a_claims_json_and_refuses_anything_else(tmp_path, capfd):
    from undulate.claims import write_claims_json
    from undulate.cli import main

    rows = [{"study": "pairs", "claim": "xi = 1: follows the line", "verdict": "fails", "measured": "slope 0.5",
             "quote": "We agree.", "where": "Sec. III.B", "reference": "paper"}]
    path = write_claims_json(tmp_path, rows)
    assert main(["claims-table", str(path)]) in (0, None)
    out = capfd.readouterr().out
    assert out == claims_table_markdown(path) and "| pairs | xi = 1: follows the line | fails |" in out
    for bad in (tmp_path / "missing.json", tmp_path):
        assert main(["claims-table", str(bad)]) == 2
        err = capfd.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "CLAIMS_JSON" in err[0]
    (tmp_path / "list.json").write_text("[1, 2]")
    assert main(["claims-table", str(tmp_path / "list.json")]) == 2


def test_claims_json_rows_carry_the_quote_where_and_superseded_verdicts(tmp_path):
    """``collect`` keeps each row's quote, where and superseded criteria (judged rows from
    :func:`undulate.studies.judge`); a study file older than the fields gives "", "" and []."""
    import json

    from undulate.claims import collect
    from undulate.studies import Claim, SupersededCriterion, Verdict
    from undulate.studies._protocol import judge

    claim = Claim("k falls", "k decreases", "rho < 0", lambda s: Verdict.judged(s["rho"] < 0, f"rho {s['rho']}"),
                  quote="We found that k decreases.", where="Sec. III.G, Fig. 10d",
                  superseded=(SupersededCriterion("no step rises", lambda s: Verdict.judged(False, "a step rose"),
                                                  "one noisy step decided it"),))
    rows = judge("potential", (claim,), {"rho": -0.5})
    (tmp_path / "potential.json").write_text(json.dumps({"claims": rows}))
    old = {k: v for k, v in rows[0].items() if k not in ("quote", "where", "superseded")}
    (tmp_path / "old.json").write_text(json.dumps({"claims": [{**old, "study": "old"}]}))
    new, older = collect(tmp_path, ["potential", "old"])
    assert (new["quote"], new["where"], new["verdict"]) == ("We found that k decreases.", "Sec. III.G, Fig. 10d", "holds")
    assert new["superseded"] == [{"criterion": "no step rises", "why": "one noisy step decided it", "verdict": "fails",
                                  "measured": "a step rose", "reason": ""}]
    assert (older["quote"], older["where"], older["superseded"]) == ("", "", [])
