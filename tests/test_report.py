"""The reproduction page in a real headless Chromium; resuming a reproduction."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from undulate.reproduce import reproduce

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
        browser = p.chromium.launch(executable_path=chromium, headless=True, args=[
            "--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
            "--disable-sync", "--no-first-run"])
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


def test_interrupted_reproduction_resumes_without_redoing_finished_studies(tmp_path):
    out = tmp_path / "r"
    cmd = [sys.executable, "-m", "undulate.cli", "reproduce", "--out", str(out), "--only", "compatibility,pairs"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    deadline = time.time() + 240
    while not (out / "compatibility.json").exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.2)
    assert (out / "compatibility.json").exists()
    time.sleep(1.0)
    os.killpg(proc.pid, signal.SIGKILL)  # interrupt mid-way through the next study
    proc.wait()
    first = (out / "compatibility.json").stat().st_mtime_ns
    state = json.loads((out / "reproduce.json").read_text())
    assert state["studies"]["compatibility"]["ok"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "compatibility: done earlier" in r.stdout
    assert (out / "compatibility.json").stat().st_mtime_ns == first  # not recomputed
    assert (out / "pairs.json").exists() and (out / "index.html").exists()
