"""The top of a reproduction's report page as a screenshot (``docs/gallery/report_top.png``).

Rewrites ``DIR/index.html`` from the files a reproduction left in ``DIR`` (the studies'
JSON, ``reproduce.json`` for their statuses and wall times, the animations that exist;
nothing is simulated and ``claims.json`` is not touched), opens it in Debian's headless
Chromium through Playwright at 1366 x 768 and saves the first screen as a PNG (about 170 kB).
It prints the tallest cell of the claims table, in pixels, against the viewport's height.

    python explorations/report_screenshot.py /tmp/rep_report_work
    python explorations/report_screenshot.py reproduction --png /tmp/top.png --no-rewrite
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from undulate.report import write_report
from undulate.reproduce import ANIMATIONS

ROOT = Path(__file__).resolve().parents[1]
VIEWPORT = {"width": 1366, "height": 768}
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]


def rewrite(out: Path) -> Path:
    """``out/index.html`` again from ``out``'s files (statuses from ``reproduce.json``)."""
    state = json.loads((out / "reproduce.json").read_text())
    statuses = [{"name": n, "ok": s.get("ok"), "wall_s": s.get("wall_s"), "error": s.get("error")}
                for n, s in state["studies"].items()]
    anims = [{"file": f"animations/{stem}.gif", "data": f"animations/{stem}.nc", "caption": caption}
             for stem, caption, _, _ in ANIMATIONS if (out / "animations" / f"{stem}.gif").is_file()]
    return write_report(out, statuses, mode=state.get("mode", "quick"), animations=anims,
                        total_wall_s=sum(s["wall_s"] or 0 for s in statuses))


def screenshot(page_path: Path, png: Path) -> float:
    """Save the first screen of ``page_path`` to ``png``; the tallest claims-table cell (px)."""
    from playwright.sync_api import sync_playwright

    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, headless=True, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport=VIEWPORT)
        page.goto(page_path.resolve().as_uri(), wait_until="load")
        tallest = page.evaluate("""() => {
            const t = document.querySelector('h2#claims ~ table');
            return t ? Math.max(...Array.from(t.querySelectorAll('td,th'),
                                            c => c.getBoundingClientRect().height)) : 0; }""")
        png.parent.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(png), full_page=False)
        browser.close()
    return tallest


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", type=Path, help="a reproduction's output folder")
    ap.add_argument("--png", type=Path, default=ROOT / "docs" / "gallery" / "report_top.png")
    ap.add_argument("--no-rewrite", action="store_true", help="keep the folder's index.html as it is")
    a = ap.parse_args()
    page = a.out / "index.html" if a.no_rewrite else rewrite(a.out)
    tallest = screenshot(page, a.png)
    print(f"{page}: tallest claims-table cell {tallest:.0f} px (viewport {VIEWPORT['height']} px); "
          f"{a.png} {a.png.stat().st_size / 1e3:.0f} kB")


if __name__ == "__main__":
    main()
