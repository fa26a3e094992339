"""One self-contained HTML page for a reproduction run (``DIR/index.html``).

The page uses relative links only, so the folder can be moved, zipped or
opened offline.  It shows every study's figure, the table of the paper's
claims (the claim, the paper's statement, the measured number and whether it holds: see
:mod:`undulate.claims`), provenance,
wall times, animations and links to every data file.  A failed study is
shown as failed, with its error.
"""

from __future__ import annotations

import html
import json
import platform
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from ._io import atomic_output
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
body{font-family:system-ui,-apple-system,Segoe UI,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.6em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}td,th{border:1px solid #ddd;padding:.3em .6em;text-align:left;vertical-align:top}
th{background:#f4f4f4}.ok{color:#176b2c;font-weight:600}.ex{color:#8a5a00;font-weight:600}.why{font-weight:400;color:#444;font-size:.9em}.no{color:#b3141f;font-weight:600}.na{color:#777}
img.fig{max-width:100%;border:1px solid #eee}.anims{display:flex;flex-wrap:wrap;gap:1em}.anims figure{margin:0;max-width:520px}
.anims img{max-width:100%;border:1px solid #eee}.failed{background:#fde8ea;border:1px solid #f3b5bc;padding:.6em}
code{background:#f6f6f6;padding:0 .2em}
"""


def write_report(out_dir: str | Path, statuses: list[dict[str, Any]], *, mode: str,
                 animations: list[dict[str, str]] | None = None, total_wall_s: float | None = None) -> Path:
    """Write ``out_dir/index.html`` from the studies' JSON summaries.

    ``statuses``: one dict per study, in order, with ``name``, ``ok``,
    ``wall_s`` and ``error``; ``animations``: dicts with ``file`` (relative
    to ``out_dir``) and ``caption``.
    """
    out = Path(out_dir)
    prov = provenance()
    docs: dict[str, dict] = {}
    for st in statuses:
        p = out / f"{st['name']}.json"
        if st.get("ok") and p.is_file():
            docs[st["name"]] = json.loads(p.read_text())

    parts: list[str] = []
    add = parts.append
    add("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>")
    add("<meta name='viewport' content='width=device-width, initial-scale=1'>")
    add(f"<title>undulate reproduction ({_esc(mode)})</title><style>{_CSS}</style></head><body>")
    add("<h1>Lateral contact yields longitudinal cohesion in active undulatory systems — reproduction</h1>")
    n_ok = sum(1 for s in statuses if s.get("ok"))
    failed = [s["name"] for s in statuses if not s.get("ok")]
    add(f"<p>Mode: <b>{_esc(mode)}</b>. Studies: {n_ok} of {len(statuses)} completed"
        + (f"; <span class='no'>failed: {_esc(', '.join(failed))}</span>" if failed else "")
        + (f". Total wall time {total_wall_s:.0f} s." if total_wall_s is not None else ".") + "</p>")

    # claims (rows with the studies' demonstrated explanations applied: undulate.claims)
    from .claims import collect

    rows = collect(out, [st["name"] for st in statuses if st.get("ok")])
    counts = {v: sum(r["verdict"] == v for r in rows) for v in ("holds", "explained", "fails", "no result")}
    add("<h2 id='claims'>The paper's claims</h2>")
    add("<p>Measured values carry 95 % intervals in brackets; every criterion is stated on them. "
        "<b>explained</b>: the claim fails under the default model and a study's own runs show the cause "
        "(the evidence and its figure are linked); a failing claim without a demonstrated cause stays "
        "<b>fails</b>. Counts: " + ", ".join(f"{_esc(k)} {n}" for k, n in counts.items())
        + ". Also in <a href='claims.json'>claims.json</a>.</p>")
    add("<table><tr><th>study</th><th>claim</th><th>paper</th><th>measured</th><th>criterion</th>"
        "<th>verdict</th></tr>")
    by_study: dict[str, list[dict]] = {}
    for r in rows:
        by_study.setdefault(r["study"], []).append(r)
    for st in statuses:
        name = st["name"]
        if not st.get("ok"):
            add(f"<tr><td>{_esc(name)}</td><td colspan='4' class='no'>study failed: {_esc(st.get('error'))}</td>"
                "<td class='no'>—</td></tr>")
            continue
        for c in by_study.get(name, []):
            verdict = c.get("verdict")
            cls = {"holds": "ok", "fails": "no", "explained": "ex"}.get(verdict, "na")
            reason = f" ({c['reason']})" if c.get("reason") else ""
            why = ""
            ex = c.get("explanation")
            if ex:
                ev = ex.get("evidence_study", "")
                why = (f"<br><span class='why'>cause: {_esc(ex.get('cause'))} Evidence: {_esc(ex.get('measured'))} "
                       f"(<a href='#{_esc(ev)}'>{_esc(ev)}</a>, <a href='{_esc(ex.get('evidence_figure'))}'>"
                       "figure</a>)</span>")
            elif c.get("explanations_not_shown"):
                why = "".join(f"<br><span class='why'>cause tested, not shown by the runs: {_esc(e.get('cause'))} "
                              f"({_esc(e.get('measured'))})</span>" for e in c["explanations_not_shown"])
            add(f"<tr><td>{_esc(name)}</td><td>{_esc(c.get('claim', ''))}</td><td>{_esc(c.get('paper', ''))}</td>"
                f"<td>{_esc(c.get('measured', ''))}</td><td>{_esc(c.get('criterion', ''))}</td>"
                f"<td class='{cls}'>{_esc(verdict)}{_esc(reason)}{why}</td></tr>")
    add("</table>")

    # animations
    if animations:
        add("<h2 id='animations'>Animations</h2><div class='anims'>")
        for a in animations:
            if (out / a["file"]).is_file():
                add(f"<figure><img src='{_esc(a['file'])}' alt='{_esc(a['caption'])}'>"
                    f"<figcaption>{_esc(a['caption'])} (<a href='{_esc(a['file'])}'>file</a>"
                    + (f", <a href='{_esc(a['data'])}'>data</a>" if a.get("data") else "") + ")</figcaption></figure>")
        add("</div>")

    # studies
    add("<h2 id='studies'>Studies</h2>")
    for st in statuses:
        name = st["name"]
        wall = st.get("wall_s")
        add(f"<h3 id='{_esc(name)}'>{_esc(name)}</h3>")
        if not st.get("ok"):
            add(f"<div class='failed'>This study <b>failed</b>: <code>{_esc(st.get('error'))}</code></div>")
            continue
        doc = docs.get(name, {})
        add(f"<img class='fig' src='{_esc(name)}.png' alt='{_esc(name)} figure'>")
        links = [f"<a href='{_esc(f)}'>{_esc(f)}</a>" for f in doc.get("files", []) + [f"{name}.json"]]
        add("<p>Files: " + " · ".join(links) + (f" — wall time {wall:.1f} s" if wall is not None else "") + "</p>")
        add("<details><summary>provenance of this study's files</summary><table>")
        for k, v in {**doc.get("provenance", {}), **{f"identity.{k}": v for k, v in doc.get("identity", {}).items()}}.items():
            add(f"<tr><th>{_esc(k)}</th><td>{_esc(v)}</td></tr>")
        for sw in doc.get("sweeps", []):
            add(f"<tr><th>sweep {_esc(sw.get('part'))}</th><td><code>{_esc(sw.get('function'))}</code> code "
                f"{_esc(sw.get('code'))}, undulate {_esc(sw.get('undulate_version'))}: {_esc(sw.get('n_runs'))} runs "
                f"({_esc(sw.get('n_computed'))} computed, {_esc(sw.get('n_reused'))} reused, "
                f"{_esc(sw.get('n_failed'))} failed)</td></tr>")
        add("</table></details>")
        if doc.get("failures"):
            add("<div class='failed'>Failed runs:<br>" + "<br>".join(_esc(f) for f in doc["failures"][:20]) + "</div>")
        table = doc.get("summary", {}).get("table")
        if isinstance(table, list) and table and all(isinstance(t, dict) for t in table):
            cols = list(table[0])
            add("<table><tr>" + "".join(f"<th>{_esc(k)}</th>" for k in cols) + "</tr>")
            for t in table:
                add("<tr>" + "".join(f"<td>{_esc(_fmt(t.get(k, '')))}</td>" for k in cols) + "</tr>")
            add("</table>")
        rows = _summary_rows({k: v for k, v in doc.get("summary", {}).items() if k != "table"})
        if rows:
            add("<details><summary>summary numbers</summary><table>")
            for k, v in rows:
                add(f"<tr><td>{_esc(k)}</td><td>{_esc(v)}</td></tr>")
            add("</table></details>")

    # provenance
    add("<h2 id='provenance'>Provenance</h2><p>Of this page (each study's own, recorded when its files "
        "were written, is under the study).</p><table>")
    info = {**prov, "report_written_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "machine": f"{platform.machine()} {platform.system()} {platform.release()}", "mode": mode}
    for k, v in info.items():
        add(f"<tr><th>{_esc(k)}</th><td>{_esc(v)}</td></tr>")
    add("</table><table><tr><th>study</th><th>status</th><th>wall time (s)</th></tr>")
    for st in statuses:
        w = st.get("wall_s")
        add(f"<tr><td>{_esc(st['name'])}</td><td class='{'ok' if st.get('ok') else 'no'}'>"
            f"{'ok' if st.get('ok') else 'failed'}</td><td>{'' if w is None else f'{w:.1f}'}</td></tr>")
    add("</table></body></html>")

    path = out / "index.html"
    with atomic_output(path) as tmp:
        tmp.write_text("\n".join(parts), encoding="utf-8")
    return path
