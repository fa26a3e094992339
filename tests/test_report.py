"""The reproduction page in a real headless Chromium (the claims table fits the screen and links
every claim's section); the report leaves ``claims.json`` alone; an animation is drawn again only when
what made it changed.  An interrupted reproduction resuming: tests/test_side_by_side.py."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess

import numpy as np
import pytest

from undulate._report_claim_sections import claim_anchor, first_sentence
from undulate.claims import collect, write_claims_json
from undulate.report import write_report
from undulate.reproduce import reproduce

VIEWPORT = {"width": 1366, "height": 768}
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--no-first-run"]


def ensure_chromium() -> str:
    """Debian's headless Chromium, installed by this test setup when missing (root + apt only)."""
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found:
        return found
    if os.geteuid() == 0 and shutil.which("apt-get"):
        env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
        subprocess.run(["apt-get", "update", "-qq"], check=True, env=env, capture_output=True)
        subprocess.run(["apt-get", "install", "-y", "-qq", "chromium"], check=True, env=env, capture_output=True)
        found = shutil.which("chromium")
    if not found:
        pytest.fail("headless Chromium is needed for the report test: install Debian's `chromium` package")
    return found


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("repro")
    path, statuses = reproduce(out, quick=True, studies=["compatibility"], log=lambda m: None, animation_s=2.0)
    assert all(s["ok"] for s in statuses)
    return out


def test_page_is_self_contained_with_relative_links(report_dir):
    page = (report_dir / "index.html").read_text()
    refs = re.findall(r"(?:src|href)='([^']+)'", page)
    assert refs, "the page links nothing"
    ids = set(re.findall(r"id='([^']+)'", page))
    assert [r for r in refs if r.startswith("#") and r[1:] not in ids] == []  # in-page links land somewhere
    refs = [r for r in refs if not r.startswith("#")]
    for ref in refs:
        assert not re.match(r"^[a-z]+://", ref) and not ref.startswith("/"), ref
        assert (report_dir / ref).is_file(), ref
    assert "compatibility.nc" in refs and "compatibility.png" in refs
    assert len({r for r in refs if r.endswith(".gif")}) == 3  # the three animations


def test_page_loads_every_image_in_headless_chromium(report_dir, tmp_path):
    chromium = ensure_chromium()
    from playwright.sync_api import sync_playwright

    failed, shot = [], tmp_path / "shot.png"
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, headless=True, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1200, "height": 1600})
        page.on("requestfailed", lambda r: failed.append(r.url))
        page.on("response", lambda r: failed.append(r.url) if r.status >= 400 else None)
        page.goto((report_dir / "index.html").as_uri(), wait_until="load")
        broken = page.evaluate(
            "Array.from(document.images).filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.src)")
        n_images = page.evaluate("document.images.length")
        page.screenshot(path=str(shot), full_page=False)
        browser.close()
    assert failed == [] and broken == []
    assert n_images >= 4  # one figure + three animations
    from PIL import Image

    px = np.asarray(Image.open(shot).convert("L"), dtype=float)
    assert px.std() > 10, "the screenshot is blank"


# A long, multi-sentence explanation (about 200 words), shown by its runs for two claims at once.
LONG_CAUSE = (
    "the compatibility model assumes each body is a travelling sinusoid in the lab frame. "
    + "Free bodies are not, in two ways that do not shrink with the number of links: "
    + " ".join([("on isotropic drag a free body turns back and forth as it bends, which adds a standing wave "
                "to its shape, and its wavelength along the channel is shorter than its length.")] * 4)
    + " Shown only if, with the amplitude held and the recoil removed by a heading guide, the error falls "
    + "with N by the claim's own criterion, while the runs with only one of the two changes do not. "
    + "The other candidate causes were each tested and did not show it.")
LONG_EVIDENCE = "; ".join(f"case {i}: RMS / lambda 0.0{i}46 [0.0{i}30, 0.0{i}41] at N = 3, 5, 7, 9" for i in range(1, 7))
TESTED_CAUSE = ("in the groups' channels neighbour centre lines settle farther apart than the pairs'; at that "
                "spacing the contact-free band is wider. Shown only if the narrower channel meets the criterion.")


SLOPE = {"value": 1.01, "stderr": 0.03, "ci95": [0.95, 1.07], "n": 9, "method": "t", "level": 0.95}


def _claim(study, claim, verdict, measured="slope 1.01 [0.95, 1.07]", reason=""):
    return {"study": study, "claim": claim, "paper": f"the paper says: {claim}", "measured": measured,
            "value": {"slope": SLOPE, "d_over_2A": [0.6, 0.9, 1.2], "width": [0.0, 0.01, 0.2], "n_runs": 9},
            "verdict": verdict, "reason": reason, "criterion": "the 95 % interval lies within 1 +- 0.2",
            "quote": f"We observed that {claim} (Fig.~\\ref{{fig:potential}}c).", "where": "Sec. III.G, Fig. 10c"}


def _explanation(study, claim, cause, shown):
    return {"study": study, "claim": claim, "cause": cause, "shown": shown, "measured": LONG_EVIDENCE,
            "value": None, "evidence_study": "beta", "evidence_figure": "beta.png"}


@pytest.fixture(scope="module")
def claims_report(tmp_path_factory):
    """A report from hand-written study files: every verdict, a long explanation shown for two claims,
    a failing claim with no cause, one whose tested cause was not shown, and a failed study."""
    from PIL import Image

    out = tmp_path_factory.mktemp("claims_report")
    a = ["xi = 1: pairs follow dx < lambda & \"the line\"", "links A: error falls with N",
         "links B: error falls with N", "xi = 3/4: pairs follow the line", "free pairs lock where H predicts"]
    alpha = [_claim("alpha", a[0], "holds"), _claim("alpha", a[1], "fails"), _claim("alpha", a[2], "fails"),
             _claim("alpha", a[3], "fails"),
             _claim("alpha", a[4], "no result", "no result: H is zero", "H is zero within its interval at every dphi")]
    beta = [{**_claim("beta", "groups follow the line with more scatter", "fails"),
             "superseded": [{"criterion": "no step rises beyond its interval", "why": "one noisy step decided it",
                             "verdict": "holds", "measured": "steps 0.1, 0.2", "reason": ""}]}]
    expl = [_explanation("alpha", a[1], LONG_CAUSE, True), _explanation("alpha", a[2], LONG_CAUSE, True),
            _explanation("beta", beta[0]["claim"], TESTED_CAUSE, False)]
    (out / "alpha.json").write_text(json.dumps({"claims": alpha, "files": ["alpha.png"]}))
    (out / "beta.json").write_text(json.dumps({"claims": beta, "explanations": expl, "files": ["beta.png"]}))
    for i, name in enumerate(("alpha", "beta")):
        Image.new("RGB", (400, 240), (60 + 90 * i, 120, 200)).save(out / f"{name}.png")
    statuses = [{"name": "alpha", "ok": True, "wall_s": 1.0}, {"name": "beta", "ok": True, "wall_s": 2.0},
                {"name": "gamma", "ok": False, "wall_s": 0.5, "error": "RuntimeError: " + "boom " * 80}]
    write_report(out, statuses, mode="quick")
    return out, collect(out, ["alpha", "beta"])


_MEASURE_CLAIMS = """() => {
  const table = document.querySelector('h2#claims ~ table');
  const cells = Array.from(table.querySelectorAll('td, th'), c => ({
      h: c.getBoundingClientRect().height, words: c.innerText.split(/\\s+/).filter(Boolean).length}));
  const links = Array.from(table.querySelectorAll('a[href^="#"]'), a => a.getAttribute('href').slice(1));
  const rows = Array.from(table.querySelectorAll('tr'), tr => ({
      text: tr.innerText, links: Array.from(tr.querySelectorAll('a[href^="#"]'), a => a.getAttribute('href').slice(1))}));
  const targets = {};
  for (const id of links) {
    const el = document.getElementById(id);
    targets[id] = el && {inTable: table.contains(el), text: el.innerText,
                         images: Array.from(el.querySelectorAll('img'), i => i.complete && i.naturalWidth > 0)};
  }
  return {cells, rows, targets, tableText: table.innerText};
}"""


def _measure(out, script: str):
    """``script``'s result on ``out/index.html`` in headless Chromium at :data:`VIEWPORT`."""
    chromium = ensure_chromium()
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, headless=True, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport=VIEWPORT)
        page.goto((out / "index.html").as_uri(), wait_until="load")
        m = page.evaluate(script)
        browser.close()
    return m


def test_claims_table_fits_the_screen_and_links_each_claims_own_section(claims_report):
    """At 1366 x 768 no cell of the claims table is taller than the screen (nor than a quarter of it:
    a screen shows at least four rows) or holds long text; every
    in-page link of the table lands on an element; every explained or failing claim has its own section
    (outside the table) with its whole explanation and a loaded evidence figure, linked from its row."""
    out, rows = claims_report
    m = _measure(out, _MEASURE_CLAIMS)
    tallest = max(c["h"] for c in m["cells"])
    assert tallest <= VIEWPORT["height"], f"a claims-table cell is {tallest:.0f} px tall"
    assert tallest <= VIEWPORT["height"] / 4, f"a {tallest:.0f} px cell: fewer than four rows fit the screen"
    assert max(c["words"] for c in m["cells"]) <= 60, "long text in the claims table"
    assert [i for i, t in m["targets"].items() if t is None] == [], "table links to missing ids"
    assert LONG_CAUSE[:200] not in m["tableText"] and LONG_EVIDENCE not in m["tableText"]
    assert m["tableText"].count(first_sentence(LONG_CAUSE)) <= 1  # a shared cause is not repeated
    assert "boom boom" in m["tableText"] and ("boom " * 40) not in m["tableText"]  # the failed study: clipped
    judged = [r for r in rows if r["verdict"] in ("explained", "fails")]
    assert len(judged) == 4
    for r in judged:
        (row,) = [x for x in m["rows"] if r["claim"] in x["text"]]
        own = [m["targets"][i] for i in row["links"] if not m["targets"][i]["inTable"]
               and r["claim"] in m["targets"][i]["text"]]
        assert own, f"no section of its own for {r['claim']!r}"
        section = own[0]
        assert r["measured"] in section["text"] and r["criterion"] in section["text"]
        for e in [r.get("explanation")] + r.get("explanations_not_shown", []):
            if e:
                assert e["cause"] in section["text"] and e["measured"] in section["text"]
        assert section["images"] and all(section["images"]), f"no evidence figure for {r['claim']!r}"


def test_claim_sections_have_stable_ids_and_the_cause_is_a_first_sentence():
    assert claim_anchor("pairs", "xi = 1: contact drives pairs to a steady dx that follows the compatibility line") \
        == "claim-pairs-xi-1-contact-drives-pairs-to-a-steady-dx-505964"
    assert claim_anchor("links", "a") != claim_anchor("links", "b") != claim_anchor("groups", "b")
    assert first_sentence("One short sentence. Another one.") == "One short sentence."
    assert first_sentence("e.g. not a sentence end. Next.") == "e.g. not a sentence end."
    long = "word " * 40 + "end."
    assert first_sentence(long) == " ".join(["word"] * 25) + " …"
    clause = "with N = 3 links and " + "more words " * 8 + "in antiphase (a test): a standing wave " + "x " * 20
    assert first_sentence(clause).endswith("in antiphase (a test) …")
    assert first_sentence(LONG_CAUSE) == "the compatibility model assumes each body is a travelling sinusoid in the lab frame."
    assert first_sentence("") == ""


def test_the_report_writer_leaves_the_claims_data_unchanged(claims_report):
    """``claims.json`` is written from the same rows before the page; writing the page changes neither."""
    out, _ = claims_report
    names = ["alpha", "beta"]
    path = write_claims_json(out, collect(out, names))
    before = path.read_bytes()
    rows = collect(out, names)
    statuses = [{"name": n, "ok": True, "wall_s": 1.0} for n in names]
    write_report(out, statuses, mode="quick")
    assert path.read_bytes() == before
    assert collect(out, names) == rows
    assert write_claims_json(out, collect(out, names)).read_bytes() == before
    doc = json.loads(before)
    assert doc["counts"] == {"holds": 1, "explained": 2, "undecided": 0, "fails": 2, "no result": 1}
    # the hand-written rows carry no `reference` (study files older than the field): the paper's
    assert doc["counts_by_reference"]["paper"] == doc["counts"]
    assert set(doc["counts_by_reference"]["prx2021"].values()) == {0}
    assert {r["reference"] for r in doc["claims"]} == {"paper"}


# Beyond the paper: PRX 2021 claims, judged per controller (the claim text opens with its name).
PRX_UNDECIDED_REASON = "median last/first force ratio 0.48 [0.31, 0.62] straddles 0.5 (region < 0.5)"


@pytest.fixture(scope="module")
def tables_report(tmp_path_factory):
    """A report with the paper's claims (one study file without `reference`, as written before the
    field, one with it and an undecided claim) and a PRX 2021 study whose claims name their controller,
    one undecided with the runs it would need; the PRX study ran 2 of 3 stages."""
    from PIL import Image

    out = tmp_path_factory.mktemp("tables_report")
    old = [_claim("alpha", "xi = 1: pairs follow the line", "holds"),
           _claim("alpha", "links A: error falls with N", "fails")]
    new = [{**_claim("beta", "groups follow the line", "holds"), "reference": "paper", "runs_needed": None},
           {**_claim("beta", "the central state broadens", "undecided",
                     reason="slope 0.9 [0.7, 1.1] straddles 0.8 (region > 0.8) (about 37 runs would decide it)"),
            "reference": "paper", "runs_needed": 37}]
    prx = [{**_claim("sync", f"{c}: synchronization sharply reduces the interaction force", v,
                     reason=PRX_UNDECIDED_REASON if v == "undecided" else ""),
            "reference": "prx2021", "runs_needed": 52 if v == "undecided" else None}
           for c, v in (("self-oscillating", "holds"), ("phase-oscillator", "fails"), ("relay", "undecided"))]
    relay = prx[2]["claim"]
    stages = [{"stage": k, "of": 3, "confidence_level": lvl, "n_runs": n, "n_computed": n - m,
               "verdicts": {}, "undecided": u, "futile": f}
              for k, lvl, n, m, u, f in ((1, 0.995, 12, 0, ["x"], []), (2, 0.985, 24, 12, [], [relay]))]
    (out / "alpha.json").write_text(json.dumps({"claims": old, "files": []}))
    (out / "beta.json").write_text(json.dumps({"claims": new, "files": []}))
    (out / "sync.json").write_text(json.dumps({"claims": prx, "files": [], "stages": stages}))
    for i, name in enumerate(("alpha", "beta", "sync")):
        Image.new("RGB", (400, 240), (60 + 60 * i, 120, 200)).save(out / f"{name}.png")
    names = ["alpha", "beta", "sync"]
    statuses = [{"name": n, "ok": True, "wall_s": 1.0} for n in names]
    rows = collect(out, names)
    write_claims_json(out, rows)
    write_report(out, statuses, mode="quick")
    return out, rows


_MEASURE_TABLES = """() => {
  const table = h => { let el = document.getElementById(h).nextElementSibling;
                       while (el && el.tagName !== 'TABLE') el = el.nextElementSibling; return el; };
  const intro = h => document.getElementById(h).nextElementSibling.innerText;
  const rows = t => Array.from(t.querySelectorAll('tbody tr'), tr => Array.from(tr.cells, c => c.innerText));
  const un = Array.from(document.querySelectorAll('.badge.un'), b => getComputedStyle(b).backgroundColor);
  const ok = getComputedStyle(document.querySelector('.badge.ok')).backgroundColor;
  const sec = Array.from(document.querySelectorAll('section.claim'))
                   .filter(s => s.querySelector('.badge.un')).map(s => s.innerText);
  const studies = document.getElementById('studies').parentElement.innerText;
  return {paper: rows(table('claims')), prx: rows(table('claims-prx2021')),
          paperIntro: intro('claims'), prxIntro: intro('claims-prx2021'),
          prxHead: Array.from(table('claims-prx2021').querySelectorAll('th'), th => th.innerText),
          un, ok, sec, studies};
}"""


def test_the_paper_and_prx_claims_are_two_tables_with_their_own_counts(tables_report):
    out, rows = tables_report
    doc = json.loads((out / "claims.json").read_text())
    by = doc["counts_by_reference"]
    assert by["paper"] == {"holds": 2, "explained": 0, "undecided": 1, "fails": 1, "no result": 0}
    assert by["prx2021"] == {"holds": 1, "explained": 0, "undecided": 1, "fails": 1, "no result": 0}
    assert doc["counts"] == {v: by["paper"][v] + by["prx2021"][v] for v in doc["counts"]}
    assert [r["reference"] for r in doc["claims"]] == ["paper"] * 4 + ["prx2021"] * 3  # old rows: the paper's
    assert [r["runs_needed"] for r in doc["claims"] if r["verdict"] == "undecided"] == [37, 52]

    m = _measure(out, _MEASURE_TABLES)
    assert [r[0] for r in m["paper"]] == ["alpha", "alpha", "beta", "beta"]  # no PRX row in the paper's table
    assert [r[0] for r in m["prx"]] == ["sync"] * 3
    assert m["paperIntro"].startswith("2 of the paper's 4 claims hold, 1 is undecided (beta)")
    assert m["paperIntro"].rstrip().endswith("and 1 fails.")
    assert m["prxIntro"].startswith("1 of the 3 PRX 2021 claims judged against our controllers holds")
    assert "controller" in m["prxHead"]
    # each row names its controller
    assert [r[1] for r in m["prx"]] == ["self-oscillating", "phase-oscillator", "relay"]
    (relay,) = [r for r in m["prx"] if r[1] == "relay"]
    assert "undecided" in relay and "straddles 0.5" in relay[-1] and "about 52 runs would decide it" in relay[-1]
    (central,) = [r for r in m["paper"] if "central state" in r[1]]
    assert "straddles 0.8" in central[-1] and "about 37 runs would decide it" in central[-1]
    assert len(m["un"]) >= 2 and len(set(m["un"])) == 1 and m["un"][0] != m["ok"]  # its own badge style
    assert any(PRX_UNDECIDED_REASON in s and "about 52" in s for s in m["sec"])  # the section: boundary and runs
    assert ("Stages: 2 of 3 ran (stopped early: the rest futile (the cap could not decide them): relay: "
            "synchronization sharply reduces the interaction force)") in m["studies"]
    assert "24 runs (12 computed) at 98.5 % intervals" in m["studies"]


def test_an_animation_is_kept_only_while_its_code_and_parameters_are_those_it_was_made_from(tmp_path):
    """A reproduction rerun into the same folder keeps an animation whose stamp (code hash, scene,
    duration, caption, drawing) is the current one, and draws it again when any of them changed, or
    when its GIF is gone."""
    import xarray as xr

    from undulate import reproduce as rep
    from undulate._io import write_netcdf

    stem, caption, kw, _ = rep.ANIMATIONS[0]
    gif, nc = tmp_path / "animations" / f"{stem}.gif", tmp_path / "animations" / f"{stem}.nc"

    def make(duration_s=0.3, caption=caption):
        rep._make_animation(tmp_path, stem, caption, kw, duration_s)
        with xr.open_dataset(nc) as ds:
            return gif.stat().st_mtime_ns, json.loads(ds.attrs["animation_stamp"]), float(ds["time"].values[-1])

    first, stamp, t_end = make()
    assert stamp["duration_s"] == 0.3 and stamp["scene"] == json.loads(json.dumps(kw)) and len(stamp["code"]) == 16
    assert t_end == pytest.approx(0.3, abs=0.11)  # recorded at 10 Hz
    assert make()[0] == first  # the same stamp: kept
    longer, stamp, t_end = make(0.5)  # another duration: drawn again
    assert longer != first and stamp["duration_s"] == 0.5 and t_end == pytest.approx(0.5, abs=0.11)
    assert make(0.5, caption + ".")[0] != longer  # another caption: drawn again
    ds = xr.load_dataset(nc)
    ds.attrs["animation_stamp"] = json.dumps({**json.loads(ds.attrs["animation_stamp"]), "code": "0" * 16})
    write_netcdf(ds, nc)  # as if made by other code
    redrawn = make(0.5, caption + ".")[0]
    assert make(0.5, caption + ".")[0] == redrawn  # its stamp is current again
    gif.unlink()
    assert make(0.5, caption + ".")[0] != redrawn and gif.is_file()


def test_current_animations_are_kept_without_a_worker_and_only_the_stale_one_is_drawn(tmp_path, monkeypatch):
    """The reproduction checks its animations' stamps itself: a rerun with every animation current starts
    no worker process, and one whose GIF is gone is the only one drawn again."""
    from undulate import reproduce as rep
    from undulate.sweep import _executors

    anims = rep._animations(tmp_path, 0.3, log=pytest.fail, workers=1)
    assert [a["file"] for a in anims] == [f"animations/{stem}.gif" for stem, *_ in rep.ANIMATIONS]
    gifs = [tmp_path / a["file"] for a in anims]
    made = [g.stat().st_mtime_ns for g in gifs]

    def no_pool(n):
        raise AssertionError(f"a pool of {n} was started for animations that are current")

    monkeypatch.setattr(_executors, "local_pool", no_pool)
    assert rep._animations(tmp_path, 0.3, log=pytest.fail, workers=2) == anims
    assert [g.stat().st_mtime_ns for g in gifs] == made
    gifs[1].unlink()
    assert rep._animations(tmp_path, 0.3, log=pytest.fail, workers=2) == anims  # one to draw: drawn here
    assert [g.stat().st_mtime_ns for g in gifs[::2]] == made[::2] and gifs[1].stat().st_mtime_ns != made[1]


def test_animation_duration_is_validated(tmp_path, capfd):
    """``--animation-s`` (and ``reproduce(animation_s=...)``): seconds, at least two frames; anything else
    is one line naming it, exit code 2, nothing written."""
    from undulate.cli import main
    from undulate.errors import ParameterError
    from undulate.reproduce import MAX_ANIMATION_S, MIN_ANIMATION_S, reproduce

    out = tmp_path / "r"
    for bad in ("0", "-1", "nan", "inf", "0.1", "abc", "601", "1e300"):
        assert main(["reproduce", "--out", str(out), "--animation-s", bad]) == 2, bad
        err = capfd.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error:") and "--animation-s" in err[0], (bad, err)
    for bad in (0.1, float("nan"), "2", True):
        with pytest.raises(ParameterError, match="animation_s"):
            reproduce(out, studies=["compatibility"], animation_s=bad, log=pytest.fail)
    assert not out.exists() and MIN_ANIMATION_S == pytest.approx(0.2) and MAX_ANIMATION_S == 600


def test_animation_option_help_states_the_codes_limits():
    """The ``--animation-s`` help names the least and the longest durations and the animations' own; the
    CLI does not import :mod:`undulate.reproduce` to build its help (start-up time), so the numbers are
    written there and checked here against the code."""
    from typer.main import get_command

    from undulate.cli import app
    from undulate.reproduce import ANIMATIONS, MAX_ANIMATION_S, MIN_ANIMATION_S

    (opt,) = [p for p in get_command(app).commands["reproduce"].params if p.name == "animation_s"]
    own = [a[-1] for a in ANIMATIONS]
    assert f"{MIN_ANIMATION_S:g} to {MAX_ANIMATION_S:g}" in opt.help, opt.help
    assert f"{min(own):g}-{max(own):g} s" in opt.help, opt.help


@pytest.mark.parametrize("last, why", [
    ({"stage": 1, "of": 2, "undecided": [], "futile": []}, "stopped early: nothing left undecided"),
    ({"stage": 1, "of": 2, "undecided": [], "futile": ["a", "b"]},
     "stopped early: the rest futile (the cap could not decide them): a; b"),
    ({"stage": 2, "of": 2, "undecided": ["k falls"], "futile": ["a"]},
     "still undecided after the last: k falls; futile (the cap could not decide them; their runs stopped "
     "growing): a"),
    ({"stage": 2, "of": 2, "undecided": [], "futile": []}, "all ran"),
    ({"stage": 2, "of": 2, "undecided": ["k falls"]}, "still undecided after the last: k falls"),  # before futility
])
def test_the_stages_line_says_why_a_study_stopped(last, why):
    """A study's stages line names the claims still open after its last look and, apart from them, those
    left futile (the quick cap could not decide them); a study that stopped early stopped because nothing
    was left undecided, or because what was left was futile."""
    from undulate.report import _stages

    looks = [{"stage": 1, "of": 2, "n_runs": 6, "n_computed": 6, "undecided": ["k falls"], "futile": []}]
    (line,) = _stages({"stages": (looks + [last]) if last["stage"] == 2 else [last]})
    k = last["stage"]
    assert f"Stages: {k} of 2 ran ({why}); stage 1: " in line


_MEASURE_SECTIONS = """() => Array.from(document.querySelectorAll('section.claim'), s => ({
  id: s.id, text: s.innerText,
  quotes: Array.from(s.querySelectorAll('blockquote.quote'), q => q.innerText),
  figs: Array.from(s.querySelectorAll('img.evidence'), i => ({src: i.getAttribute('src'), ok: i.complete && i.naturalWidth > 0,
                                                             w: i.getBoundingClientRect().width, natural: i.naturalWidth}))}))"""


def test_each_claim_section_has_its_own_evidence_figure_and_quotes_the_paper(claims_report):
    """Every claim's section (held ones too) shows one figure of its own, loaded, no other section's, drawn
    no wider than it is (readable at 1366 px: its labels at their drawn size); it quotes the paper's sentence
    without its LaTeX reference, says where, and shows a replaced criterion's verdict beside the current one."""
    out, rows = claims_report
    secs = _measure(out, _MEASURE_SECTIONS)
    assert len(secs) == len(rows) == 6
    srcs = [f["src"] for s in secs for f in s["figs"]]
    assert all(len(s["figs"]) == 1 for s in secs), [len(s["figs"]) for s in secs]
    assert len(set(srcs)) == len(secs) and all(src.startswith("evidence/") for src in srcs)
    for s in secs:
        (f,) = s["figs"]
        assert f["ok"], f"evidence figure not loaded in {s['id']}"
        assert f["w"] >= 0.95 * min(f["natural"], 560) and f["w"] <= f["natural"] + 3, f  # its own size (+ border)
        (q,) = s["quotes"]
        assert q.startswith("We observed that ") and "\\ref" not in q and "~" not in q and q.endswith(".")
        assert "Sec. III.G, Fig. 10c" in s["text"]
    (beta,) = [s for s in secs if "groups follow the line" in s["text"]]
    assert "criterion before" in beta["text"] and "no step rises beyond its interval" in beta["text"]
    assert "one noisy step decided it" in beta["text"]
    table = _measure(out, "() => document.querySelector('h2#claims ~ table').innerText")
    assert "before: holds" in table  # the replaced criterion's verdict beside the current one in the table too
    from PIL import Image

    for src in srcs:
        with Image.open(out / src) as im:
            assert im.size[0] <= 600 and im.size[1] <= 900, im.size  # few elements, small


def test_the_generic_evidence_figure_draws_each_estimate_group_its_region_and_the_explaining_runs(tmp_path):
    """One panel per kind of number (a key and its "pairs_" twin share one, compared), the criterion's region
    shaded where it is known, a curve from equal-length lists, the explaining runs beside an explained claim's
    numbers; a figure is drawn again only when what it shows changed."""
    from undulate._evidence import evidence_figure, write_evidence

    e = lambda v, lo, hi: {"value": v, "stderr": 0.1, "ci95": [lo, hi], "n": 9, "method": "t", "level": 0.95}  # noqa: E731
    row = {"study": "groups", "claim": "c", "paper": "p", "verdict": "fails",
           "value": {"slope": e(0.6, 0.5, 0.7), "rms": e(0.3, 0.2, 0.4), "pairs_rms": e(0.05, 0.0, 0.1),
                     "d_over_2A": [0.6, 0.9, 1.2], "width": [0.0, 0.1, 0.2], "n_runs": 9}}
    fig = evidence_figure(row, {"slope": (0.8, 1.2), "rms": (None, 0.2)})
    axes = [a for a in fig.axes if a.get_visible()]
    assert [a.get_title() for a in axes] == ["slope", "rms", "width"]
    slope, rms, width = axes
    assert [t.get_text() for t in rms.get_xticklabels()] == ["measured", "pairs"]
    lines = {round(y, 6) for a in (slope,) for ln in a.get_lines() if len(set(ln.get_ydata())) == 1
             for y in ln.get_ydata()[:1]}
    assert {0.8, 1.2} <= lines and slope.patches  # the region's edges and its shading
    assert not width.patches and width.get_xlabel() == "d_over_2A"
    explained = {**row, "verdict": "explained",
                 "explanation": {"cause": "x", "shown": True, "value": {"default": False, "changed": True}}}
    ax = [a for a in evidence_figure(explained, {}).axes if a.get_visible()][-1]
    assert "explaining runs" in ax.get_title() and [t.get_text() for t in ax.texts] == ["default: fails", "changed: holds"]
    finding = {**row, "findings": [{"cause": "y", "shown": True, "value": {"guide+wavelength": True}}]}
    ax = [a for a in evidence_figure(finding, {}).axes if a.get_visible()][-1]
    assert "finding" in ax.get_title() and [t.get_text() for t in ax.texts] == ["guide+wavelength: holds"]
    assert evidence_figure(row, {}, evidence=lambda r: ("own", r["claim"])) == ("own", "c")  # a claim's own hook
    counts = [a for a in evidence_figure({"paper": "p", "value": {"both": 3, "n_runs": 9}}).axes if a.get_visible()]
    assert [a.get_title() for a in counts] == ["counts"] and [b.get_width() for b in counts[0].patches] == [3, 9]
    first = write_evidence(row, tmp_path, "claim-a")
    made = (tmp_path / first).stat().st_mtime_ns
    assert write_evidence(row, tmp_path, "claim-a") == first and (tmp_path / first).stat().st_mtime_ns == made
    assert write_evidence({**row, "value": {"slope": e(0.9, 0.85, 0.95)}}, tmp_path, "claim-a") != first


def test_a_claims_own_evidence_figure_is_drawn_again_when_its_hooks_module_changes(tmp_path, monkeypatch):
    """The figure's key covers the source of the module that defines the claim's evidence hook, not only
    undulate._evidence: a changed hook never leaves an old picture on the page."""
    import sys
    import textwrap

    from undulate._evidence import write_evidence

    def hook_module(body: str):
        path = tmp_path / "hookmod.py"
        path.write_text(textwrap.dedent(f"""
            def own(row):
                from matplotlib.figure import Figure
                fig = Figure(figsize=(2, 1))
                fig.text(0.1, 0.5, {body!r})
                return fig
            """))
        monkeypatch.syspath_prepend(str(tmp_path))
        sys.modules.pop("hookmod", None)
        import hookmod

        return hookmod.own

    row = {"study": "s", "claim": "c", "paper": "p", "verdict": "holds", "value": {"n_runs": 3}}
    out = tmp_path / "out"
    first = write_evidence(row, out, "c", evidence=hook_module("one"))
    assert write_evidence(row, out, "c", evidence=hook_module("one")) == first
    assert write_evidence(row, out, "c", evidence=hook_module("two")) != first


def test_quotes_show_their_math_as_text_on_the_page():
    from undulate._report_claim_sections import readable_math

    assert readable_math(r"when $\frac{d}{2A} > 1$ swimmers") == "when d/2A > 1 swimmers"
    assert readable_math(r"$\Delta x_{i,i+1}$ versus $\Delta \phi_{i,i+1}$") == "Δx_(i,i+1) versus Δφ_(i,i+1)"
    assert readable_math(r"$\frac{d}{2A} \in [0.6, 1.2]$ and $\delta x_0$, $\rho = \frac{1}{w}$") == \
        "d/2A ∈ [0.6, 1.2] and δx0, ρ = 1/w"
    assert readable_math("no math here") == "no math here"


def test_a_claim_whose_evidence_cannot_be_drawn_says_so_and_the_page_is_still_written(tmp_path, monkeypatch):
    from undulate import _evidence

    def broken(*a, **k):
        raise ValueError("a value of a new shape")

    monkeypatch.setattr(_evidence, "evidence_figure", broken)
    (tmp_path / "alpha.json").write_text(json.dumps({"claims": [_claim("alpha", "k falls", "holds")]}))
    write_report(tmp_path, [{"name": "alpha", "ok": True, "wall_s": 1.0}], mode="quick")
    page = (tmp_path / "index.html").read_text()
    assert "No evidence figure: drawing it failed (ValueError: a value of a new shape)" in page
    assert "img class='fig evidence'" not in page
