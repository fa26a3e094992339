"""The claims part of the report page: tables to scan, and one section per claim with the rest.

Two tables, each under its own heading with its own counts and a sentence saying what held: the
reproduced paper's claims, and beyond the paper the PRX 2021 synchronization claims (rows whose
``reference`` is ``"prx2021"``), each row of which names the controller it was judged against.
A table holds one short line per claim: study, claim, the measured value with its 95 %
interval, the verdict as a badge and the cause in one sentence (the first sentence of the
claim's own explanation, cut at ``CAUSE_WORDS`` words; for an undecided claim the boundary its
interval straddles and the runs that would decide it) with a link to the claim's section.
The section below the tables (id :func:`claim_anchor`) carries everything else: the paper's own
sentence the claim tests (quoted, with where the paper states it) and its paraphrase, the full
measured text, the criterion, the verdicts of the criteria it was judged by before, the whole
explanation with its evidence, and the claim's own evidence figure (:mod:`undulate._evidence`:
the numbers that decide it with the criterion's region; for an explained claim the explaining
runs beside them), written to ``evidence/`` in the report's folder.  Nothing here changes the claim rows (``claims.json`` is written from the
same rows by :mod:`undulate.claims`).
"""

from __future__ import annotations

import hashlib
import html
import re
from pathlib import Path
from typing import Any

from .claims import REFERENCES, counts, quote_text, reference_of

#: The longest cause sentence the table shows, and the longest measured text, in words.
CAUSE_WORDS = 25
MEASURED_WORDS = 40

#: A verdict's badge class.
BADGE = {"holds": "ok", "explained": "ex", "undecided": "un", "fails": "no", "no result": "na", "failed": "no"}

#: Each reference's table: (heading id, heading, the claims' owner in the summary sentence).
TABLES = {
    "paper": ("claims", "The paper's claims", "the paper's {n} claims"),
    "prx2021": ("claims-prx2021", "Beyond the paper: synchronization through contact (PRX 2021)",
                "the {n} PRX 2021 claims judged against our controllers"),
}
_RUNS_SUFFIX = re.compile(r"\s*\(about \d+ runs would decide it\)\s*$")

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
    if c.get("verdict") == "undecided":
        return "undecided: ", _RUNS_SUFFIX.sub("", str(c.get("reason") or "")) or "no boundary named"
    if c.get("explanations_not_shown"):
        e = c["explanations_not_shown"][0]
        return ("tested, undecided: " if e.get("shown") is None and "shown" in e else "tested, not shown: "), \
            e.get("cause") or ""
    if c.get("verdict") == "no result" and c.get("reason"):
        return "", c["reason"]
    if c.get("findings"):
        return "finding: ", c["findings"][0].get("cause") or ""
    return "", ""


def decided_text(c: dict[str, Any]) -> str:
    """For a claim decided at a look its study went on past, where some later look on its own did not
    decide it the same way (``decided_at``): "at stage 1 of 4 (99.5 % intervals), …"; else ""."""
    at = c.get("decided_at") or {}
    later = at.get("later_verdicts") or []
    verdict = "fails" if c.get("verdict") == "explained" else c.get("verdict")
    if all(v == verdict for v in later):
        return ""
    lvl = at.get("confidence_level")
    level = f" ({100 * lvl:.4g} % intervals)" if isinstance(lvl, (int, float)) else ""
    return (f"{verdict} at stage {at.get('stage')} of {at.get('of')}{level}, measured as of stage "
            f"{at.get('measured_at_stage', at.get('stage'))}, and kept: a decided claim is not reopened; the "
            f"later looks, run for other claims, gave on their own: {', '.join(map(str, later))}")


def runs_needed_text(c: dict[str, Any]) -> str:
    """"about N runs would decide it" for an undecided row whose ``runs_needed`` is known, else ""."""
    n = c.get("runs_needed")
    return f"about {n} runs would decide it" if c.get("verdict") == "undecided" and n is not None else ""


def _cause_cell(c: dict[str, Any], anchor: str, previous: tuple[str, str] | None) -> str:
    label, text = _cause_text(c)
    link = f"<a class='more' href='#{esc(anchor)}'>details</a>"
    runs = runs_needed_text(c)
    if runs:
        link = f"{esc(runs)} · {link}"
    if previous is not None and text and (label, text) == previous:
        return f"<span class='na'>same cause as the row above</span> · {link}"
    if text:
        return f"{esc(label)}{esc(first_sentence(text))} · {link}"
    if c.get("verdict") == "fails":
        return f"<span class='na'>no cause shown</span> · {link}"
    return link


def controller_of(claim: Any) -> tuple[str, str]:
    """(controller, the rest of the claim) of a claim text that opens with its controller's name
    (``"relay: groups synchronize ..."``, as the PRX 2021 studies write them); ("", text) when it
    opens with none (a name of one word before the first ``": "``)."""
    text = str(claim or "")
    head, sep, rest = text.partition(": ")
    if sep and head and " " not in head.strip() and rest:
        return head.strip(), rest
    return "", text


def claims_table(rows: list[dict[str, Any]], ids: list[str], statuses: list[dict[str, Any]], *,
                 controller: bool = False) -> list[str]:
    """A claims table, in the studies' order; a failed study is one row.  ``controller``: a column
    naming the controller each claim was judged against (taken from the claim's text)."""
    ctl_head = "<th>controller</th>" if controller else ""
    out = [(f"<table class='claims'><thead><tr><th>study</th>{ctl_head}<th>claim</th>"
            "<th>measured (interval; 95 % over the looks)</th><th>verdict</th><th>cause</th></tr></thead><tbody>")]
    by_study: dict[str, list[tuple[dict, str]]] = {}
    for r, a in zip(rows, ids):
        by_study.setdefault(r["study"], []).append((r, a))
    for st in statuses:
        name = st["name"]
        if not st.get("ok"):
            out.append(f"<tr><td><a href='#{esc(name)}'>{esc(name)}</a></td>"
                       f"<td colspan='{3 if controller else 2}'>study failed</td>"
                       f"<td>{badge('failed')}</td><td>{esc(first_sentence(st.get('error')))}"
                       f" · <a class='more' href='#{esc(name)}'>details</a></td></tr>")
            continue
        previous = None
        for c, a in by_study.get(name, []):
            claim = esc(c.get("claim", ""))
            if controller:
                ctl, rest = controller_of(c.get("claim"))
                ctl_cell = esc(ctl) if ctl else "<span class='na'>not named</span>"
                claim = f"<td>{ctl_cell}</td><td>{esc(rest)}</td>"
            else:
                claim = f"<td>{claim}</td>"
            before = "".join(f"<br><span class='na before'>before: {esc(o.get('verdict'))}</span>"
                             for o in c.get("superseded") or [])
            out.append(f"<tr class='verdict-{BADGE.get(c.get('verdict'), 'na')}'><td>{esc(name)}</td>{claim}"
                       f"<td>{esc(clip(c.get('measured', ''), MEASURED_WORDS))}</td><td>{badge(c.get('verdict'))}"
                       f"{before}</td>"
                       f"<td>{_cause_cell(c, a, previous)}</td></tr>")
            previous = _cause_text(c)
    out.append("</tbody></table>")
    return out


def _figures(c: dict[str, Any]) -> list[tuple[str, str]]:
    """(file, the study it is from) of the whole figures behind a claim's evidence (linked under its own
    figure): its own study's, and that of its shown explanation, its findings and the explanations its runs
    did not show."""
    figs = [(f"{c['study']}.png", c["study"])]
    for e in [c.get("explanation") or {}] + (c.get("findings") or []) + (c.get("explanations_not_shown") or []):
        if e.get("evidence_figure") and e["evidence_figure"] not in [f for f, _ in figs]:
            figs.append((e["evidence_figure"], e.get("evidence_study") or ""))
    return figs


def _evidence(e: dict[str, Any], title: str) -> list[str]:
    ev, fig = e.get("evidence_study") or "", e.get("evidence_figure") or ""
    where = [f"<a href='#{esc(ev)}'>{esc(ev)}</a> study"] if ev else []
    where += [f"<a href='{esc(fig)}'>figure</a>"] if fig else []
    return [f"<dt>{esc(title)}</dt><dd>{esc(e.get('cause'))}</dd>",
            f"<dt>evidence</dt><dd>{esc(e.get('measured'))}" + (f" ({', '.join(where)})" if where else "") + "</dd>"]


_GREEK = {"Delta": "\u0394", "delta": "\u03b4", "phi": "\u03c6", "lambda": "\u03bb", "pi": "\u03c0",
          "rho": "\u03c1", "xi": "\u03be", "omega": "\u03c9", "beta": "\u03b2", "alpha": "\u03b1",
          "in": "\u2208", "leq": "\u2264", "geq": "\u2265", "neq": "\u2260", "cdot": "\u00b7", "tilde": ""}


_OPERATORS = ("in", "leq", "geq", "neq", "cdot")


def readable_math(text: str) -> str:
    """A quote's LaTeX math as plain text for the page (``$\\frac{\\Delta y}{2A} > 1$`` -> ``Δy/2A > 1``);
    the quote itself, in ``claims.json``, stays as the paper writes it."""
    def one(m: re.Match) -> str:
        s = m.group(1)
        for _ in range(3):
            s = re.sub(r"\\frac\{([^{}]*)\}\{([^{}]*)\}", r"\1/\2", s)
        s = re.sub(r"\\(?:text|mathrm)\{([^{}]*)\}", r"\1", s)
        s = re.sub(r"\\([A-Za-z]+)(?: (?=[A-Za-z\\]))?",  # "\\Delta x" -> "Δx"; "\\in [" keeps its space
                   lambda g: _GREEK.get(g.group(1), g.group(1)) + (" " if g.group(1) in _OPERATORS else ""), s)
        s = re.sub(r"_\{([^{}]*)\}", lambda g: g.group(1) if len(g.group(1)) == 1 else f"_({g.group(1)})", s)
        s = re.sub(r"_(\w)", r"\1", s)
        s = re.sub(r"\^\{([^{}]*)\}", r"^\1", s)
        return " ".join(s.replace("{", "").replace("}", "").split())
    return re.sub(r"\$([^$]*)\$", one, str(text or ""))


def _claim_hooks(study: str, claim: str) -> tuple[dict[str, Any], Any]:
    """(bands, evidence hook) of a registered claim (:class:`~undulate.studies.Claim`); ({}, None) for a
    claim the registry does not know (a study file from other code)."""
    from .errors import ParameterError
    from .studies import describe

    try:
        mine = [c for c in describe(study).claims if c.claim == claim]
    except ParameterError:
        return {}, None
    return (dict(mine[0].bands), mine[0].evidence) if mine else ({}, None)


def evidence_file(c: dict[str, Any], anchor: str, out_dir: Path) -> str:
    """The claim's own evidence figure, written under ``out_dir/evidence/`` (kept while what it is drawn
    from is unchanged); its path relative to ``out_dir``."""
    from ._evidence import write_evidence

    bands, hook = _claim_hooks(str(c.get("study")), str(c.get("claim")))
    return write_evidence(c, out_dir, anchor, bands, hook)


def _superseded(c: dict[str, Any]) -> list[str]:
    """The criteria the claim was judged by before, each with the verdict it gives on the same numbers."""
    out = []
    for o in c.get("superseded") or []:
        why = f" (replaced: {esc(o.get('why'))})" if o.get("why") else ""
        out.append(f"<dt>criterion before</dt><dd>{esc(o.get('criterion'))}{why}<br>verdict: "
                   f"{badge(o.get('verdict'))} {esc(o.get('measured') or '')}"
                   + (f" ({esc(o.get('reason'))})" if o.get("reason") else "") + "</dd>")
    return out


def claim_section(c: dict[str, Any], anchor: str, out_dir: Path, back: str = "claims") -> list[str]:
    """One claim's section: every number and word the table leaves out, and its own evidence figure;
    ``back``: the id of the table it comes from."""
    verdict = c.get("verdict")
    prx = reference_of(c) == "prx2021"
    quote = quote_text(c.get("quote") or "")
    where = f" <span class='where'>({esc(c['where'])})</span>" if c.get("where") else ""
    out = [(f"<section class='claim' id='{esc(anchor)}'><h3>{esc(c['study'])}: {esc(c.get('claim', ''))} "
           f"{badge(verdict)}</h3><div class='claim-body'><dl>")]
    if quote:
        out.append(f"<dt>{'the statement (PRX 2021)' if prx else 'the paper says'}</dt>"
                   f"<dd><blockquote class='quote'>{esc(readable_math(quote))}</blockquote>{where}</dd>")
    out += [f"<dt>{'PRX 2021' if prx else 'paper'}{' (paraphrase)' if quote else ''}</dt>"
            f"<dd>{esc(c.get('paper', ''))}</dd>",
            f"<dt>measured</dt><dd>{esc(c.get('measured', ''))}</dd>",
            f"<dt>criterion</dt><dd>{esc(c.get('criterion', ''))}</dd>"]
    if c.get("superseded"):
        out.append(f"<dt>verdict now</dt><dd>{badge(verdict)} by the criterion above</dd>")
        out += _superseded(c)
    if verdict == "undecided":
        out.append(f"<dt>undecided: the interval straddles</dt><dd>{esc(c.get('reason') or 'no boundary named')}</dd>")
        n = c.get("runs_needed")
        out.append("<dt>runs that would decide it</dt><dd>"
                   + (f"about {esc(n)} (if the interval shrinks as 1/&radic;n)" if n is not None else "not known")
                   + "</dd>")
    elif c.get("reason") and c.get("reason") not in str(c.get("measured", "")):
        out.append(f"<dt>no result because</dt><dd>{esc(c['reason'])}</dd>")
    decided = decided_text(c)
    if decided:
        out.append(f"<dt>decided</dt><dd>{esc(decided)}</dd>")
    if c.get("explanation"):
        out += _evidence(c["explanation"], "cause (shown by the runs)")
    for e in c.get("explanations_not_shown") or []:
        out += _evidence(e, "cause tested, undecided by the runs" if e.get("shown") is None and "shown" in e
                         else "cause tested, not shown by the runs")
    for e in c.get("findings") or []:  # several changes together: written beside the verdict, never explaining it
        out += _evidence(e, "finding (not an explanation: the verdict stands)")
    out.append("</dl>")
    whole = [f"<a href='{esc(f)}'>{esc(s or f)}</a>" for f, s in _figures(c) if (out_dir / f).is_file()]
    cap = ("The numbers that decide it, with the criterion's accepted region shaded"
           + ("; beside them, the explaining runs" if c.get("explanation") else "") + "."
           + (f" Whole figures: {', '.join(whole)}." if whole else ""))
    try:
        own = evidence_file(c, anchor, out_dir)
    except (OSError, MemoryError):  # the disk or the machine, not the claim: the reproduction stops here
        raise
    except Exception as e:  # a value the drawing does not know: said on the page, which the rest still gets
        out.append(f"<div class='figs failed'>No evidence figure: drawing it failed ({esc(type(e).__name__)}: "
                   f"{esc(e)}). {cap}</div>")
    else:
        out.append(f"<div class='figs'><figure class='evidence'><a href='{esc(own)}'><img class='fig evidence' "
                   f"src='{esc(own)}' alt='evidence for {esc(c.get('claim', ''))}'></a>"
                   f"<figcaption>{cap}</figcaption></figure></div>")
    out.append(f"</div><p class='back'><a href='#{esc(back)}'>back to the claims table</a></p></section>")
    return out


def _n(k: int, one: str, many: str) -> str:
    return f"{k} {one if k == 1 else many}"


def summary_sentence(rows: list[dict[str, Any]], owner: str) -> str:
    """One sentence saying what held among ``rows`` (``owner``: e.g. "the paper's {n} claims"),
    naming the studies of the undecided claims, e.g. "12 of the paper's 17 claims hold, 3 are explained
    by a demonstrated cause, 2 are undecided (pairs, groups)." (rows below name the boundaries)."""
    k = counts(rows)
    n = len(rows)
    if n == 0:
        return "No claim was judged."
    whose = owner.format(n=n)
    if n == 1:
        whose = whose.replace("claims", "claim")
    parts = [f"{k['holds']} of {whose} {'holds' if n == 1 or k['holds'] == 1 else 'hold'}"]
    if k["explained"]:
        parts.append(f"{k['explained']} {'is' if k['explained'] == 1 else 'are'} explained by a demonstrated cause")
    if k["undecided"]:
        per_study: dict[str, int] = {}
        for r in rows:
            if r.get("verdict") == "undecided":
                per_study[str(r["study"])] = per_study.get(str(r["study"]), 0) + 1
        names = ", ".join(st if m == 1 else f"{m} of {st}" for st, m in per_study.items())
        parts.append(f"{k['undecided']} {'is' if k['undecided'] == 1 else 'are'} undecided ({names})")
    if k["fails"]:
        parts.append(_n(k["fails"], "fails", "fail"))
    if k["no result"]:
        parts.append(_n(k["no result"], "has no result", "have no result"))
    text = parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1]
    return text + "."


def _intro(ref: str, rows: list[dict[str, Any]], failed: list[str]) -> str:
    """The paragraph that opens a table: what held, how to read it, its counts."""
    head = summary_sentence(rows, TABLES.get(ref, (None, None, f"the {{n}} {ref} claims"))[2])
    if failed:
        head += f" {_n(len(failed), 'study', 'studies')} failed ({', '.join(failed)}): its claims are not counted."
    if ref == "prx2021":
        how = ("Beyond the reproduced paper: the claims of <i>synchronization through contact</i> (Zhou, Hao &amp; "
               "Gravish, Phys. Rev. X 11, 031051 (2021)), each judged against one of our candidate controllers "
               "(named in its row); a claim that fails says that controller does not show it.")
    else:
        how = ("One line per claim; measured values carry 95 % intervals in brackets and every criterion "
               f"is stated on them. {badge('explained')}: the claim fails under the default model and a study's "
               "own runs show the cause; a failing claim without a demonstrated cause stays "
               f"{badge('fails')}. {badge('undecided')}: an interval straddles its criterion's boundary "
               "(the row names it, and about how many runs would decide it). Each claim's section below the "
               "tables quotes the paper's sentence it tests and has the criterion, the whole explanation with its "
               "numbers, and its own evidence figure: the numbers that decide it with the criterion's region.")
    k = counts(rows)
    return (f"<p class='verdicts'><b>{esc(head)}</b></p><p>{how} Counts: "
            + ", ".join(f"{badge(v)} {n}" for v, n in k.items())
            + ". Also in <a href='claims.json'>claims.json</a>.</p>")


def _study_reference(name: str, rows: list[dict[str, Any]], st: dict[str, Any]) -> str:
    mine = [reference_of(r) for r in rows if r["study"] == name]
    return mine[0] if mine else (st.get("reference") or "paper")


def claims_part(rows: list[dict[str, Any]], statuses: list[dict[str, Any]], out_dir: Path) -> list[str]:
    """The paper's claims table, the PRX 2021 table (when it has rows or a failed study), each
    under its heading with its counts, and every claim's section below them.  A status's optional
    ``reference`` places a failed study (one with no rows) in its table."""
    ids = anchors(rows)
    refs = list(REFERENCES) + [x for x in dict.fromkeys(reference_of(r) for r in rows) if x not in REFERENCES]
    back: dict[str, str] = {}
    out: list[str] = []
    for ref in refs:
        mine = [(r, a) for r, a in zip(rows, ids) if reference_of(r) == ref]
        sts = [st for st in statuses if _study_reference(st["name"], rows, st) == ref]
        if ref != "paper" and not mine and not any(not st.get("ok") for st in sts):
            continue
        hid, title, _ = TABLES.get(ref, (f"claims-{ref}", f"Claims of {ref}", ""))
        failed = [st["name"] for st in sts if not st.get("ok")]
        out.append(f"<h2 id='{esc(hid)}'>{esc(title)}</h2>")
        out.append(_intro(ref, [r for r, _ in mine], failed))
        out += claims_table([r for r, _ in mine], [a for _, a in mine], sts, controller=(ref == "prx2021"))
        back.update({a: hid for _, a in mine})
    out.append("<h2 id='claim-details'>The claims one by one</h2>")
    for c, a in zip(rows, ids):
        out += claim_section(c, a, out_dir, back.get(a, "claims"))
    return out
