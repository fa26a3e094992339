"""One self-contained HTML page for a reproduction run (``DIR/index.html``).

The page uses relative links only, so the folder can be moved, zipped or
opened offline.  It shows the table of the paper's claims and, beyond the
paper, the table of the PRX 2021 synchronization claims (each judged against
a named controller), each with its own counts and one sentence saying what
held; one short line per claim (study, claim, measured value with its 95 %
interval, verdict, the cause in one sentence, or for an undecided claim the
boundary its interval straddles: see :mod:`undulate.claims`) with every
claim's own section below them (the paper's own sentence quoted with where it
stands, the criterion and the verdicts of the criteria it replaced, the whole
explanation, and the claim's own evidence figure, ``evidence/*.png``:
:mod:`undulate._report_claim_sections`, :mod:`undulate._evidence`), every
study's figure, the stages it ran, provenance, wall times, animations and
links to every data file.  A failed study is shown as failed, with its error.
"""

from __future__ import annotations

import html
import json
import platform
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from ._io import atomic_output
from ._report_claim_sections import claims_part
from .provenance import provenance
from .stats import Estimate

__all__ = ["write_report"]


def _esc(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, list) and len(v) <= 12 and all(isinstance(u, (int, float)) for u in v):
        return "[" + ", ".join(_fmt(u) for u in v) + "]"
    if isinstance(v, (dict, list)):
        s = json.dumps(v)
        return s if len(s) < 160 else s[:157] + "..."
    return str(v)


def _summary_rows(summary: dict[str, Any], prefix: str = "") -> list[tuple[str, str]]:
    rows = []
    for k, v in summary.items():
        if k == "claims":
            continue
        if isinstance(v, dict) and "value" in v and "ci95" in v:  # an undulate.stats.Estimate
            rows.append((f"{prefix}{k}", format(Estimate.from_dict(v), ".4g")))
        elif isinstance(v, dict) and len(v) <= 12:
            rows.extend(_summary_rows(v, f"{prefix}{k}."))
        else:
            rows.append((f"{prefix}{k}", _fmt(v)))
    return rows


_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,sans-serif;max-width:1200px;margin:1.5em auto;padding:0 1em;color:#222;line-height:1.4}
h1{font-size:1.5em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}td,th{border:1px solid #ddd;padding:.3em .6em;text-align:left;vertical-align:top}
th{background:#f4f4f4}.ok{color:#176b2c;font-weight:600}.no{color:#b3141f;font-weight:600}.na{color:#666}
table.claims{width:100%;font-size:.88em}table.claims td,table.claims th{padding:.25em .5em}
table.claims th{position:sticky;top:0}table.claims tbody tr:nth-child(even){background:#fafafa}
.badge{display:inline-block;padding:0 .55em;border-radius:.8em;font-size:.9em;font-weight:600;white-space:nowrap}
.badge.ok{background:#dcf2e1;color:#125523}.badge.ex{background:#fdf0d0;color:#7a4d00}
.badge.no{background:#fadadd;color:#9b111b}.badge.na{background:#ececec;color:#555}
.badge.un{background:#fff1c2;color:#8a5a00;border:1px dashed #d99a00}p.verdicts{margin-bottom:.2em}
a.more{white-space:nowrap}
section.claim{border-top:1px solid #eee;padding-top:.2em}section.claim h3{font-size:1.05em}
.claim-body{display:flex;flex-wrap:wrap;gap:1em;align-items:flex-start}.claim-body dl{flex:1 1 420px;margin:0}
.claim-body dt{font-weight:600;margin-top:.3em}.claim-body dd{margin:0 0 0 1em}
.claim-body .figs{flex:1 1 420px;max-width:560px}.claim-body figure{margin:0 0 .8em}p.back{font-size:.85em;margin:.3em 0 1em}
img.fig{max-width:100%;border:1px solid #eee}.anims{display:flex;flex-wrap:wrap;gap:1em}.anims figure{margin:0;max-width:520px}
.anims img{max-width:100%;border:1px solid #eee}.failed{background:#fde8ea;border:1px solid #f3b5bc;padding:.6em}
code{background:#f6f6f6;padding:0 .2em}
blockquote.quote{margin:.1em 0;padding:.1em .6em;border-left:3px solid #9bb7d4;font-style:italic}
.where{color:#555;font-size:.9em}
"""


def _load_docs(out: Path, statuses: list[dict[str, Any]]) -> dict[str, dict]:
    """The JSON of every study that completed, by name."""
    docs: dict[str, dict] = {}
    for st in statuses:
        p = out / f"{st['name']}.json"
        if st.get("ok") and p.is_file():
            docs[st["name"]] = json.loads(p.read_text())
    return docs


def _head(mode: str, statuses: list[dict[str, Any]], total_wall_s: float | None, beyond: bool = False,
          not_run: list[str] | None = None) -> list[str]:
    """The document head, the title and the one-line status of the run (``beyond``: the page has
    the table of claims beyond the paper; ``not_run``: registered studies beyond the paper that this
    reproduction did not run)."""
    n_ok = sum(1 for s in statuses if s.get("ok"))
    failed = [s["name"] for s in statuses if not s.get("ok")]
    left_out = ([f"<p>Not run here, beyond the paper: {_esc(', '.join(not_run))} (the PRX 2021 comparisons; "
                 "<code>--beyond-paper</code> runs them, in either mode).</p>"] if not_run else [])
    return ["<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
            "<meta name='viewport' content='width=device-width, initial-scale=1'>",
            f"<title>undulate reproduction ({_esc(mode)})</title><style>{_CSS}</style></head><body>",
            "<h1>Lateral contact yields longitudinal cohesion in active undulatory systems — reproduction</h1>",
            f"<p>Mode: <b>{_esc(mode)}</b>. Studies: {n_ok} of {len(statuses)} completed"
            + (f"; <span class='no'>failed: {_esc(', '.join(failed))}</span>" if failed else "")
            + (f". Total wall time {total_wall_s:.0f} s." if total_wall_s is not None else ".")
            + " Contents: <a href='#claims'>the paper's claims</a>"
            + (" · <a href='#claims-prx2021'>beyond the paper (PRX 2021)</a>" if beyond else "")
            + " · <a href='#claim-details'>the claims one by one</a>"
            + " · <a href='#studies'>studies</a> · <a href='#provenance'>provenance</a>.</p>"] + left_out


def _animations(out: Path, animations: list[dict[str, str]] | None) -> list[str]:
    """The animations that exist, side by side, each with its file and data."""
    if not animations:
        return []
    parts = ["<h2 id='animations'>Animations</h2><div class='anims'>"]
    for a in animations:
        if (out / a["file"]).is_file():
            parts.append(f"<figure><img src='{_esc(a['file'])}' alt='{_esc(a['caption'])}'>"
                         f"<figcaption>{_esc(a['caption'])} (<a href='{_esc(a['file'])}'>file</a>"
                         + (f", <a href='{_esc(a['data'])}'>data</a>" if a.get("data") else "")
                         + ")</figcaption></figure>")
    parts.append("</div>")
    return parts


def _study_provenance(doc: dict[str, Any]) -> list[str]:
    """A study's own provenance, identity and sweeps, folded."""
    parts = ["<details><summary>provenance of this study's files</summary><table>"]
    for k, v in {**doc.get("provenance", {}), **{f"identity.{k}": v for k, v in doc.get("identity", {}).items()}}.items():
        parts.append(f"<tr><th>{_esc(k)}</th><td>{_esc(v)}</td></tr>")
    for sw in doc.get("sweeps", []):
        parts.append(f"<tr><th>sweep {_esc(sw.get('part'))}</th><td><code>{_esc(sw.get('function'))}</code> code "
                     f"{_esc(sw.get('code'))}, undulate {_esc(sw.get('undulate_version'))}: {_esc(sw.get('n_runs'))} "
                     f"runs ({_esc(sw.get('n_computed'))} computed, {_esc(sw.get('n_reused'))} reused, "
                     f"{_esc(sw.get('n_failed'))} failed)</td></tr>")
    parts.append("</table></details>")
    return parts


def _study_numbers(doc: dict[str, Any]) -> list[str]:
    """A study's failed runs, its summary table and its other summary numbers (folded)."""
    parts = []
    if doc.get("failures"):
        parts.append("<div class='failed'>Failed runs:<br>" + "<br>".join(_esc(f) for f in doc["failures"][:20])
                     + "</div>")
    table = doc.get("summary", {}).get("table")
    if isinstance(table, list) and table and all(isinstance(t, dict) for t in table):
        cols = list(table[0])
        parts.append("<table><tr>" + "".join(f"<th>{_esc(k)}</th>" for k in cols) + "</tr>")
        for t in table:
            parts.append("<tr>" + "".join(f"<td>{_esc(_fmt(t.get(k, '')))}</td>" for k in cols) + "</tr>")
        parts.append("</table>")
    rows = _summary_rows({k: v for k, v in doc.get("summary", {}).items() if k != "table"})
    if rows:
        parts.append("<details><summary>summary numbers</summary><table>")
        parts += [f"<tr><td>{_esc(k)}</td><td>{_esc(v)}</td></tr>" for k, v in rows]
        parts.append("</table></details>")
    return parts


def _stages(doc: dict[str, Any]) -> list[str]:
    """One line on the stages a study ran (``NAME.json["stages"]``): how many of how many, the runs
    and the confidence level of each look, and why it stopped (the claims still open, and those left
    futile: more runs within the cap would not decide them, so their runs stopped growing); nothing for
    a study file without them."""
    looks = [s for s in doc.get("stages") or [] if isinstance(s, dict)]
    if not looks:
        return []
    last = looks[-1]
    k, of = len(looks), last.get("of", len(looks))

    def look(s: dict[str, Any]) -> str:
        lvl = s.get("confidence_level")
        at = f" at {100 * lvl:.4g} % intervals" if isinstance(lvl, (int, float)) else ""
        return f"{s.get('n_runs', '?')} runs ({s.get('n_computed', '?')} computed){at}"

    if of == 1:
        return [f"<p class='stages'>One stage: {_esc(look(last))}.</p>"]
    still, futile = ("; ".join(map(str, last.get(key) or [])) for key in ("undecided", "futile"))
    if k < of:
        why = f"stopped early: the rest futile (the cap could not decide them): {futile}" if futile else \
            "stopped early: nothing left undecided"
    else:
        why = "; ".join(([f"still undecided after the last: {still}"] if still else [])
                        + ([f"futile (the cap could not decide them; their runs stopped growing): {futile}"]
                           if futile else [])) or "all ran"
    return [f"<p class='stages'>Stages: {k} of {of} ran ({_esc(why)}); "
            + "; ".join(f"stage {_esc(s.get('stage', i + 1))}: {_esc(look(s))}" for i, s in enumerate(looks))
            + ".</p>"]


def _study(st: dict[str, Any], doc: dict[str, Any]) -> list[str]:
    """One study: its figure, files, wall time, provenance and numbers, or its error."""
    name, wall = st["name"], st.get("wall_s")
    parts = [f"<h3 id='{_esc(name)}'>{_esc(name)}</h3>"]
    if not st.get("ok"):
        return parts + [f"<div class='failed'>This study <b>failed</b>: <code>{_esc(st.get('error'))}</code></div>"]
    parts.append(f"<img class='fig' src='{_esc(name)}.png' alt='{_esc(name)} figure'>")
    links = [f"<a href='{_esc(f)}'>{_esc(f)}</a>" for f in doc.get("files", []) + [f"{name}.json"]]
    parts.append("<p>Files: " + " · ".join(links) + (f" — wall time {wall:.1f} s" if wall is not None else "") + "</p>")
    return parts + _stages(doc) + _study_provenance(doc) + _study_numbers(doc)


def _provenance(mode: str, statuses: list[dict[str, Any]]) -> list[str]:
    """The page's own provenance and every study's status and wall time."""
    parts = [("<h2 id='provenance'>Provenance</h2><p>Of this page (each study's own, recorded when its files "
             "were written, is under the study).</p><table>")]
    info = {**provenance(), "report_written_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "machine": f"{platform.machine()} {platform.system()} {platform.release()}", "mode": mode}
    parts += [f"<tr><th>{_esc(k)}</th><td>{_esc(v)}</td></tr>" for k, v in info.items()]
    parts.append("</table><table><tr><th>study</th><th>status</th><th>wall time (s)</th></tr>")
    for st in statuses:
        w = st.get("wall_s")
        parts.append(f"<tr><td>{_esc(st['name'])}</td><td class='{'ok' if st.get('ok') else 'no'}'>"
                     f"{'ok' if st.get('ok') else 'failed'}</td><td>{'' if w is None else f'{w:.1f}'}</td></tr>")
    parts.append("</table>")
    return parts


def _reference(name: str) -> str:
    """A registered study's :attr:`~undulate.studies.Study.reference` ("paper" for a name the registry
    does not know): places a failed study, which has no claim rows, in its claims table."""
    from .errors import ParameterError
    from .studies import describe

    try:
        return describe(name).reference
    except ParameterError:  # not a registered study
        return "paper"


def write_report(out_dir: str | Path, statuses: list[dict[str, Any]], *, mode: str,
                 animations: list[dict[str, str]] | None = None, total_wall_s: float | None = None) -> Path:
    """Write ``out_dir/index.html`` from the studies' JSON summaries.

    ``statuses``: one dict per study, in order, with ``name``, ``ok``,
    ``wall_s``, ``error`` and optionally ``reference`` (else the registered
    study's); ``animations``: dicts with ``file`` (relative
    to ``out_dir``) and ``caption``.  Reads the claim rows as
    :func:`undulate.claims.collect` gives them and writes nothing but the page.
    """
    from .claims import collect, reference_of

    out = Path(out_dir)
    docs = _load_docs(out, statuses)
    rows = collect(out, [st["name"] for st in statuses if st.get("ok")])
    statuses = [{**st, "reference": st.get("reference") or _reference(st["name"])} for st in statuses]
    beyond = any(reference_of(r) != "paper" for r in rows) or any(
        not st.get("ok") and st["reference"] != "paper" for st in statuses)
    from .studies import describe, names

    ran = {st["name"] for st in statuses}
    not_run = [n for n in names() if n not in ran and describe(n).reference != "paper"]
    parts = _head(mode, statuses, total_wall_s, beyond, not_run)
    parts += claims_part(rows, statuses, out)
    parts += _animations(out, animations)
    parts.append("<h2 id='studies'>Studies</h2>")
    for st in statuses:
        parts += _study(st, docs.get(st["name"], {}))
    parts += _provenance(mode, statuses)
    parts.append("</body></html>")
    path = out / "index.html"
    with atomic_output(path) as tmp:
        tmp.write_text("\n".join(parts), encoding="utf-8")
    return path
