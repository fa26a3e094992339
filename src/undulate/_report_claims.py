"""The claims part of the report page: a table to scan, and one section per claim with the rest.

The table holds one short line per claim: study, claim, the measured value with its 95 %
interval, the verdict as a badge and the cause in one sentence (the first sentence of the
claim's own explanation, cut at ``CAUSE_WORDS`` words) with a link to the claim's section.
The section below the table (id :func:`claim_anchor`) carries everything else: the paper's
statement, the full measured text, the criterion, the whole explanation with its evidence, and
the evidence figure.  Nothing here changes the claim rows (``claims.json`` is written from the
same rows by :mod:`undulate.claims`).
"""

from __future__ import annotations

import hashlib
import html
import re
from pathlib import Path
from typing import Any

from .claims import VERDICTS

#: The longest cause sentence the table shows, and the longest measured text, in words.
CAUSE_WORDS = 25
MEASURED_WORDS = 40

#: A verdict's badge class.
BADGE = {"holds": "ok", "explained": "ex", "fails": "no", "no result": "na", "failed": "no"}

_SENTENCE_END = re.compile(r"(?<=[.!?])\s+(?=[A-Z])")


def esc(x: Any) -> str:
    return html.escape(str(x), quote=True)


def badge(verdict: Any) -> str:
    return f"<span class='badge {BADGE.get(verdict, 'na')}'>{esc(verdict)}</span>"


def clip(text: Any, max_words: int) -> str:
    """``text`` with its whitespace collapsed, cut after ``max_words`` words with an ellipsis."""
    words = str(text or "").split()
    if len(words) <= max_words:
        return " ".join(words)
    return " ".join(words[:max_words]).rstrip(",;:") + " …"


def _n_words(tokens: list[str]) -> int:
    """Words among whitespace-separated tokens: those with a letter or digit (not ``=``, ``/``, ``-``)."""
    return sum(1 for t in tokens if any(ch.isalnum() for ch in t))


def first_sentence(text: Any, max_words: int = CAUSE_WORDS) -> str:
    """The first sentence of ``text``; one longer than ``max_words`` words is cut with an
    ellipsis, at its last ``:`` or ``;`` within them when that keeps at least a third."""
    s = _SENTENCE_END.split(" ".join(str(text or "").split()), maxsplit=1)[0]
    tokens = s.split()
    if _n_words(tokens) <= max_words:
        return s
    head = tokens
    while _n_words(head) > max_words:
        head = head[:-1]
    for i in range(len(head) - 1, len(head) // 3, -1):
        if head[i].endswith((":", ";")):
            head = head[:i + 1]
            break
    return " ".join(head).rstrip(",;:") + " …"


def claim_anchor(study: str, claim: str) -> str:
    """The id of a claim's section: readable, stable and unique per (study, claim)."""
    slug = re.sub(r"[^a-z0-9]+", "-", str(claim).lower()).strip("-")[:40].strip("-")
    digest = hashlib.sha1(f"{study}\0{claim}".encode()).hexdigest()[:6]
    return f"claim-{re.sub(r'[^a-z0-9]+', '-', str(study).lower()).strip('-')}-{slug}-{digest}"


def anchors(rows: list[dict[str, Any]]) -> list[str]:
    """:func:`claim_anchor` of every row, made unique where two rows name the same claim."""
    seen: dict[str, int] = {}
    out = []
    for r in rows:
        a = claim_anchor(r["study"], r["claim"])
        seen[a] = seen.get(a, 0) + 1
        out.append(a if seen[a] == 1 else f"{a}-{seen[a]}")
    return out


def _cause_text(c: dict[str, Any]) -> tuple[str, str]:
    """(label, long text) of a row's cause: its shown explanation, the explanations its runs
    did not show, or why there is no result; ("", "") when there is none."""
    if c.get("explanation"):
        return "", c["explanation"].get("cause") or ""
    if c.get("explanations_not_shown"):
        return "tested, not shown: ", c["explanations_not_shown"][0].get("cause") or ""
    if c.get("verdict") == "no result" and c.get("reason"):
        return "", c["reason"]
    return "", ""


def _cause_cell(c: dict[str, Any], anchor: str, previous: tuple[str, str] | None) -> str:
    label, text = _cause_text(c)
    link = f"<a class='more' href='#{esc(anchor)}'>details</a>"
    if previous is not None and text and (label, text) == previous:
        return f"<span class='na'>same cause as the row above</span> · {link}"
    if text:
        return f"{esc(label)}{esc(first_sentence(text))} · {link}"
    if c.get("verdict") == "fails":
        return f"<span class='na'>no cause shown</span> · {link}"
    return link


def claims_table(rows: list[dict[str, Any]], ids: list[str], statuses: list[dict[str, Any]]) -> list[str]:
    """The claims table, in the studies' order; a failed study is one row."""
    out = [("<table class='claims'><thead><tr><th>study</th><th>claim</th><th>measured (95 % interval)</th>"
           "<th>verdict</th><th>cause</th></tr></thead><tbody>")]
    by_study: dict[str, list[tuple[dict, str]]] = {}
    for r, a in zip(rows, ids):
        by_study.setdefault(r["study"], []).append((r, a))
    for st in statuses:
        name = st["name"]
        if not st.get("ok"):
            out.append(f"<tr><td><a href='#{esc(name)}'>{esc(name)}</a></td><td colspan='2'>study failed</td>"
                       f"<td>{badge('failed')}</td><td>{esc(first_sentence(st.get('error')))}"
                       f" · <a class='more' href='#{esc(name)}'>details</a></td></tr>")
            continue
        previous = None
        for c, a in by_study.get(name, []):
            out.append(f"<tr><td>{esc(name)}</td><td>{esc(c.get('claim', ''))}</td>"
                       f"<td>{esc(clip(c.get('measured', ''), MEASURED_WORDS))}</td><td>{badge(c.get('verdict'))}</td>"
                       f"<td>{_cause_cell(c, a, previous)}</td></tr>")
            previous = _cause_text(c)
    out.append("</tbody></table>")
    return out


def _figures(c: dict[str, Any]) -> list[tuple[str, str]]:
    """(file, the study it is from) of a claim's evidence: the shown explanation's figure, or the
    claim's own study's figure and those of the explanations its runs did not show."""
    ex = c.get("explanation")
    if ex and ex.get("evidence_figure"):
        return [(ex["evidence_figure"], ex.get("evidence_study") or "")]
    figs = [(f"{c['study']}.png", c["study"])]
    for e in c.get("explanations_not_shown") or []:
        if e.get("evidence_figure") and e["evidence_figure"] not in [f for f, _ in figs]:
            figs.append((e["evidence_figure"], e.get("evidence_study") or ""))
    return figs


def _evidence(e: dict[str, Any], title: str) -> list[str]:
    ev, fig = e.get("evidence_study") or "", e.get("evidence_figure") or ""
    where = [f"<a href='#{esc(ev)}'>{esc(ev)}</a> study"] if ev else []
    where += [f"<a href='{esc(fig)}'>figure</a>"] if fig else []
    return [f"<dt>{esc(title)}</dt><dd>{esc(e.get('cause'))}</dd>",
            f"<dt>evidence</dt><dd>{esc(e.get('measured'))}" + (f" ({', '.join(where)})" if where else "") + "</dd>"]


def claim_section(c: dict[str, Any], anchor: str, out_dir: Path) -> list[str]:
    """One claim's section: every number and word the table leaves out, and its evidence figure."""
    verdict = c.get("verdict")
    out = [(f"<section class='claim' id='{esc(anchor)}'><h3>{esc(c['study'])}: {esc(c.get('claim', ''))} "
           f"{badge(verdict)}</h3><div class='claim-body'><dl>"),
           f"<dt>paper</dt><dd>{esc(c.get('paper', ''))}</dd>",
           f"<dt>measured</dt><dd>{esc(c.get('measured', ''))}</dd>",
           f"<dt>criterion</dt><dd>{esc(c.get('criterion', ''))}</dd>"]
    if c.get("reason") and c.get("reason") not in str(c.get("measured", "")):
        out.append(f"<dt>no result because</dt><dd>{esc(c['reason'])}</dd>")
    if c.get("explanation"):
        out += _evidence(c["explanation"], "cause (shown by the runs)")
    for e in c.get("explanations_not_shown") or []:
        out += _evidence(e, "cause tested, not shown by the runs")
    out.append("</dl>")
    figs = [(f, s) for f, s in _figures(c) if (out_dir / f).is_file()] if verdict != "holds" else []
    if figs:
        out.append("<div class='figs'>")
        for fig, study in figs:
            cap = f"the <a href='#{esc(study)}'>{esc(study)}</a> study's figure" if study else esc(fig)
            out.append(f"<figure><a href='{esc(fig)}'><img class='fig' src='{esc(fig)}' "
                       f"alt='{esc(fig)}'></a><figcaption>Evidence: {cap}</figcaption></figure>")
        out.append("</div>")
    out.append("</div><p class='back'><a href='#claims'>back to the claims table</a></p></section>")
    return out


def claims_part(rows: list[dict[str, Any]], statuses: list[dict[str, Any]], out_dir: Path) -> list[str]:
    """The claims heading, the table, and every claim's section below it."""
    ids = anchors(rows)
    counts = {v: sum(r["verdict"] == v for r in rows) for v in VERDICTS}
    out = ["<h2 id='claims'>The paper's claims</h2>",
           "<p>One line per claim; measured values carry 95 % intervals in brackets and every criterion "
           f"is stated on them. {badge('explained')}: the claim fails under the default model and a study's "
           "own runs show the cause; a failing claim without a demonstrated cause stays "
           f"{badge('fails')}. Each claim's section below the table has the paper's statement, the "
           "criterion, the whole explanation with its numbers, and the evidence figure. Counts: "
           + ", ".join(f"{badge(k)} {n}" for k, n in counts.items())
           + ". Also in <a href='claims.json'>claims.json</a>.</p>"]
    out += claims_table(rows, ids, statuses)
    out.append("<h2 id='claim-details'>The claims one by one</h2>")
    for c, a in zip(rows, ids):
        out += claim_section(c, a, out_dir)
    return out
