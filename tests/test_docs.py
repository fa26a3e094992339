"""The documentation site: it builds with warnings as errors, its internal links resolve, its API pages import.

The site is built once per session (``mkdocs build --strict`` into a temporary folder, a few seconds);
the link check then walks every generated HTML file.
"""

from __future__ import annotations

import importlib
import os
import re
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urljoin, urlsplit

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
_EXTERNAL = ("http:", "https:", "mailto:", "data:", "javascript:", "tel:")
_API_DIRECTIVE = re.compile(r"^:::\s+([\w.]+)", re.MULTILINE)


class _Page(HTMLParser):
    """The ids (anchors) of one HTML page and every ``href``/``src`` it links to."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.links: list[str] = []

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if value is None:
                continue
            if name == "id" or (tag == "a" and name == "name"):
                self.ids.add(value)
            elif name in ("href", "src"):
                self.links.append(value)

    handle_startendtag = handle_starttag


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def build_site(site_dir: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site_dir)],
                          cwd=ROOT, capture_output=True, text=True, timeout=600,
                          env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})


def broken_links(site_dir: Path) -> list[str]:
    """Every internal ``href``/``src`` in the built site whose file, or ``#anchor`` on its page, is missing."""
    pages: dict[Path, _Page] = {}

    def page(path: Path) -> _Page:
        if path not in pages:
            pages[path] = _parse(path)
        return pages[path]

    broken = []
    for html in sorted(site_dir.rglob("*.html")):
        rel = html.relative_to(site_dir).as_posix()
        for link in page(html).links:
            if link.startswith(_EXTERNAL) or link.startswith("//") or link in ("", "#"):
                continue
            url = urlsplit(urljoin("/" + rel, link))
            target = site_dir / unquote(url.path).lstrip("/")
            if url.path.endswith("/") or target.is_dir():
                target = target / "index.html"
            if not target.is_file():
                broken.append(f"{rel}: {link} (no file {target.relative_to(site_dir)})")
            elif url.fragment and target.suffix == ".html" and unquote(url.fragment) not in page(target).ids:
                broken.append(f"{rel}: {link} (no id {url.fragment!r} in {target.relative_to(site_dir)})")
    return broken


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    site_dir = tmp_path_factory.mktemp("site")
    proc = build_site(site_dir)
    assert proc.returncode == 0, f"mkdocs build --strict failed:\n{proc.stdout}\n{proc.stderr}"
    return site_dir


def test_site_builds_strict(site):
    assert (site / "index.html").is_file()
    for page in ("getting_started", "guide/simulation", "contact", "api/params", "api/undulate"):
        assert (site / page / "index.html").is_file(), page
    # mkdocstrings rendered the docstrings (not an empty page)
    assert 'id="undulate.params.Scene"' in (site / "api/params/index.html").read_text(encoding="utf-8")


def test_every_internal_link_resolves(site):
    n_links = sum(len(_parse(p).links) for p in site.rglob("*.html"))
    assert n_links > 1000  # the walk saw the site
    broken = broken_links(site)
    assert not broken, "broken links:\n" + "\n".join(broken[:50])


def test_link_checker_catches_a_broken_link(site, tmp_path):
    """The check above is not vacuous: a missing page and a missing anchor are both reported."""
    bad = tmp_path / "site"
    bad.mkdir()
    (bad / "index.html").write_text('<a href="gone/">x</a> <a href="api/#nowhere">y</a> <a id="here" href="#here">z</a>'
                                    '<a href="#missing">w</a>', encoding="utf-8")
    (bad / "api").mkdir()
    (bad / "api/index.html").write_text('<h1 id="somewhere">API</h1>', encoding="utf-8")
    found = broken_links(bad)
    assert len(found) == 3, found
    assert any("gone/" in b for b in found) and any("nowhere" in b for b in found) and any("missing" in b for b in found)


def api_modules() -> list[str]:
    mods = []
    for md in sorted((DOCS / "api").glob("*.md")):
        mods += _API_DIRECTIVE.findall(md.read_text(encoding="utf-8"))
    return mods


def test_api_pages_list_the_main_modules():
    mods = set(api_modules())
    for m in ("undulate", "undulate.params", "undulate.simulation", "undulate.scene", "undulate.observables",
              "undulate.theory", "undulate.stats", "undulate.control", "undulate.schema", "undulate.stopping",
              "undulate.sweep", "undulate.studies", "undulate.claims", "undulate.report", "undulate.reproduce",
              "undulate.robot", "undulate.track", "undulate.compare", "undulate.animation"):
        assert m in mods, m


@pytest.mark.parametrize("module", api_modules())
def test_api_module_imports(module):
    importlib.import_module(module)


def test_getting_started_has_the_readme_commands():
    """The install / reproduce and test commands are copied from the README exactly."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    block = readme.split("```bash", 1)[1].split("```", 1)[0]
    commands = [line for line in block.splitlines() if line.startswith("python3 -m venv")]
    assert len(commands) == 2
    guide = (DOCS / "getting_started.md").read_text(encoding="utf-8")
    for command in commands:
        assert command in guide, command


# ------------------------------------------------------------------ docs state what is, not when
SRC = ROOT / "src" / "undulate"
_DATE = re.compile(r"\b(?:19|20)\d\d-[01]\d-[0-3]\d\b")
# a commit-hash-looking token: 7-40 hex digits with at least one digit and one letter a-f
_HASH = r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b"
_HASH_IN_PARENS = re.compile(r"\([^)]*" + _HASH + r"[^)]*\)")
_COMMIT_HASH = re.compile(r"\bcommits?\s+" + _HASH)
_HEADING = re.compile(r"^#{1,6}\s")


def dated_headings(text: str) -> list[str]:
    """The section headings of a markdown text (outside fenced code) that carry a date (YYYY-MM-DD), a
    commit-hash-looking token in parentheses, or "commit <hash>": a lab notebook's sections, which
    belong in CHANGELOG.md and benchmarks/, not in a page that says what is."""
    found, fenced = [], False
    for line in text.splitlines():
        if line.lstrip().startswith(("```", "~~~")):
            fenced = not fenced
            continue
        if not fenced and _HEADING.match(line) and (
                _DATE.search(line) or _HASH_IN_PARENS.search(line) or _COMMIT_HASH.search(line)):
            found.append(line)
    return found


def dated_lines(text: str) -> list[str]:
    """The lines of a text that contain a calendar date, YYYY-MM-DD."""
    return [line for line in text.splitlines() if _DATE.search(line)]


def test_the_dated_checks_catch_what_they_are_for():
    """The two checks below are not vacuous: the headings the docs used to have are caught, plain ones are not."""
    notebook = ("# The GPU backend\n\n## The H200 check, second lease (2026-11-27 evening, e9b2b39)\n"
                "### Before that: commit 3516c02\n## Full mode (3e5da81)\n"
                "```bash\n# 2026-11-27 a shell comment in a code block\n```\n")
    assert len(dated_headings(notebook)) == 3
    current = ("# Performance\n\n## Current figures\n### `undulate robot run`\n## Agreement (measured)\n"
               "## Kernels (sm_90, sm_75)\n## How to measure (decade, facade)\n")
    assert dated_headings(current) == []
    assert dated_lines('x = 1\n"""Sized on 2026-11-29 by the runs."""\nfmt = "%Y-%m-%d"\n') == [
        '"""Sized on 2026-11-29 by the runs."""']


def test_no_page_has_a_dated_section():
    """Every page under docs/ states current facts: its history lives in CHANGELOG.md and benchmarks/."""
    pages = sorted(DOCS.rglob("*.md"))
    assert len(pages) > 20  # the walk saw the docs
    bad = [f"{p.relative_to(ROOT)}: {h}" for p in pages for h in dated_headings(p.read_text(encoding="utf-8"))]
    assert not bad, "dated section headings:\n" + "\n".join(bad)


def test_no_source_line_has_a_date():
    """A constant's docstring says why its value is what it is, not when: no YYYY-MM-DD in src/undulate."""
    files = sorted(SRC.rglob("*.py"))
    assert len(files) > 50
    bad = [f"{f.relative_to(ROOT)}: {line.strip()}" for f in files for line in dated_lines(f.read_text(encoding="utf-8"))]
    assert not bad, "dated lines in src/:\n" + "\n".join(bad)


def test_the_history_has_one_home():
    """The measurement history is CHANGELOG.md at the root, newest first, linking to the benchmark files it moved to."""
    changelog = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    for moved in ("benchmarks/gpu_leases.md", "benchmarks/performance_history.md", "benchmarks/readme_history.md"):
        assert (ROOT / moved).is_file(), moved
        assert moved in changelog, moved
    assert not (DOCS / "history.md").exists()
    # one page each for the robots and the tracking (the guide's twins were merged into them)
    assert not (DOCS / "guide" / "robots.md").exists() and not (DOCS / "guide" / "tracking.md").exists()
