"""The live view and the config editor in a real browser: Debian's chromium driven by Playwright
(nothing downloaded: ``executable_path`` is the system's chromium).

A tiny UMa run started with ``--live``: the page's progress and decision timeline advance
between two reads while the run goes, the map has drawn pixels and the timeline five rows.
The editor rejects an out-of-range field with the package's own line and starts a run from a
valid config, whose live view then follows it. The pages work under their Content Security
Policy (no violation reported), carry the session token of the printed URL, show "no access"
without it, and cannot be framed by another page.
"""

from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from veriloc_rt.detectors.outcomes import DETECTORS
from veriloc_rt.live.editor import check_config, editor_config, set_field

CHROMIUM = Path("/usr/bin/chromium")
pytestmark = pytest.mark.skipif(not CHROMIUM.exists(), reason="needs Debian's chromium at "
                                "/usr/bin/chromium (.ci/run installs it: apt-get install chromium)")

#: the installed console script (what a user runs)
ENTRY = Path(sys.executable).with_name("veriloc-rt")
#: chromium without anything that reaches the network or the user's profile
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage"]   # containers often have a tiny /dev/shm
#: a tiny UMa run that lasts some seconds: 30 points of 'none' (chains of 'fbs' computed with
#: them), no encrypted-PRS pass, DigSig from the HMAC chain's tag checks
LIVE_RUN = {"propagation": {"model": "uma"},
            "trajectory": {"num_points": 30, "adversary_lag_points": 2},
            "run": {"scenarios": ["none", "fbs"], "evaluate_encrypted": False, "digsig": "shared"}}
#: longest wait for anything the page shows, ms (the whole test takes well under a minute)
WAIT_MS = 45_000
#: the map's background colour (#fbfbfc in live.css) and how far a drawn pixel is from it
BACKGROUND_RGB = np.array([0xFB, 0xFB, 0xFC])
DRAWN_MIN_DIFF = 24
#: the canyon's blocks alone cover a large part of the map: at least this share is drawn
MIN_DRAWN_SHARE = 0.05
#: BS markers (#c62828) and the true trajectory (#2a62c9): pixels within this of the colour
COLOUR_TOL = 30


def _start(args: list[str], cwd: Path) -> tuple[subprocess.Popen, str]:
    """``veriloc-rt ARGS`` in its own process group; its URL (the last word of its first
    output line, with the session token)."""
    proc = subprocess.Popen([str(ENTRY), *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL, text=True,
                            start_new_session=True)
    line: list[str] = []
    t = threading.Thread(target=lambda: line.append(proc.stdout.readline()), daemon=True)
    t.start()
    t.join(WAIT_MS / 1000)
    if not line or not line[0].split() or "?token=" not in line[0]:
        _stop(proc)
        pytest.fail(f"{args[0]} printed no URL with a token: {line!r}")
    return proc, line[0].split()[-1]


def _watch(page) -> list[str]:
    """The page's script errors and console errors (a CSP violation is one)."""
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    return errors


def _stop(proc: subprocess.Popen) -> None:
    """Ctrl-C to the process group (the view, a run it started), as a terminal would."""
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    proc.stdout.close()


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    from playwright.sync_api import sync_playwright

    profile = tmp_path_factory.mktemp("chromium-profile")
    with sync_playwright() as p:
        ctx = p.chromium.launch_persistent_context(
            str(profile), executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_ARGS,
            viewport={"width": 1280, "height": 900})
        try:
            yield ctx
        finally:
            ctx.close()


def _pixels(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)


def _near(img: np.ndarray, hex_rgb: str) -> int:
    rgb = np.array([int(hex_rgb[i:i + 2], 16) for i in (1, 3, 5)])
    return int((np.abs(img - rgb).max(axis=-1) <= COLOUR_TOL).sum())


def test_live_run_progress_timeline_and_map(tmp_path, browser):
    cfg = tmp_path / "live.json"
    cfg.write_text(json.dumps(LIVE_RUN))
    proc, url = _start(["run", str(cfg), "--out", "r", "--live", "--port", "0", "--no-browser",
                        "--workers", "1"], tmp_path)
    try:
        page = browser.new_page()
        errors = _watch(page)
        page.goto(url)
        # first read: the run is going and 'none' has some of its points, not all
        n = LIVE_RUN["trajectory"]["num_points"]
        page.wait_for_function(
            "() => document.getElementById('status').textContent === 'running'"
            " && +document.getElementById('progress-none')?.dataset.done >= 1"
            f" && +document.getElementById('progress-none').dataset.done < {n}"
            " && +document.getElementById('decisions').dataset.points >= 1",
            timeout=WAIT_MS)
        done1 = int(page.get_attribute("#progress-none", "data-done"))
        shown1 = int(page.get_attribute("#decisions", "data-points"))
        assert 1 <= shown1 <= done1 < n
        # second read: both advanced
        page.wait_for_function(
            f"() => +document.getElementById('progress-none').dataset.done > {done1}"
            f" && +document.getElementById('decisions').dataset.points > {shown1}",
            timeout=WAIT_MS)
        rows = page.eval_on_selector_all(".decision-row", "rs => rs.map(r => r.dataset.detector)")
        assert rows == list(DETECTORS)
        page.wait_for_function("() => +document.getElementById('map').dataset.drawn >= 1",
                               timeout=WAIT_MS)
        img = _pixels(page.locator("#map").screenshot())
        drawn = np.abs(img - BACKGROUND_RGB).max(axis=-1) > DRAWN_MIN_DIFF
        assert drawn.mean() > MIN_DRAWN_SHARE
        assert _near(img, "#c62828") > 20 and _near(img, "#2a62c9") > 20   # BSs, trajectory
        shot = tmp_path / "live.png"
        page.screenshot(path=str(shot), full_page=True)
        assert shot.stat().st_size > 10_000
        assert errors == []
        page.close()
    finally:
        _stop(proc)


def test_editor_rejects_out_of_range_then_starts_a_run(tmp_path, browser):
    cfg = tmp_path / "edit.json"
    cfg.write_text(json.dumps(LIVE_RUN))
    proc, url = _start(["edit", str(cfg), "--out", str(tmp_path / "run"), "--port", "0",
                        "--no-browser"], tmp_path)
    try:
        page = browser.new_page()
        errors = _watch(page)
        page.goto(url)
        page.wait_for_selector("body[data-ready='1']", timeout=WAIT_MS)
        # the file and the folder the editor was started on, shown and not editable
        assert page.input_value("#save-path") == str(cfg)
        assert page.input_value("#out-dir") == str(tmp_path / "run")
        assert page.get_attribute("#save-path", "readonly") is not None
        field = "#f-trajectory-num_points"
        assert page.input_value(field) == "30"
        page.fill(field, "1")
        page.click("#validate")
        page.wait_for_selector("#message.error", timeout=WAIT_MS)
        expected = check_config(set_field(editor_config(cfg), "trajectory.num_points", 1))
        assert page.text_content("#message") == f"error: {expected}"
        assert page.get_attribute(".field.bad", "data-path") == "trajectory.num_points"
        page.fill(field, "12")
        page.click("#run")
        base, token = url.split("/edit?token=")
        page.wait_for_url(f"{base}/?token={token}", timeout=WAIT_MS)   # the token kept
        page.wait_for_function("() => +document.getElementById('progress-none')?.dataset.done >= 1",
                               timeout=WAIT_MS)
        assert json.loads(cfg.read_text())["trajectory"]["num_points"] == 12
        assert (tmp_path / "run" / "run.json").exists()
        # the live view's link back to the editor keeps the token too
        assert page.get_attribute("a[data-page='/edit']", "href") == f"/edit?token={token}"
        assert errors == []
        page.close()
        # without the token the page loads but reads nothing
        page = browser.new_page()
        page.goto(base + "/")
        page.wait_for_function("() => document.getElementById('status').textContent"
                               ".startsWith('no access')", timeout=WAIT_MS)
        page.close()
        # another page cannot frame the editor (frame-ancestors 'none', X-Frame-Options)
        page = browser.new_page()
        page.set_content(f'<iframe id="f" src="{url}" width="800" height="600"></iframe>')
        page.wait_for_timeout(2000)
        framed = [f for f in page.frames if f != page.main_frame]
        assert framed and all(f.query_selector("#run") is None for f in framed)
        page.close()
    finally:
        _stop(proc)


#: the editor's pages without a run: the form and the map's "no run" note come at once, ms
NO_RUN_WAIT_MS = 10_000


def test_editor_without_a_run_shows_the_form_and_says_the_map_has_no_run(tmp_path, browser):
    proc, url = _start(["edit", "--out", str(tmp_path / "run"), "--port", "0", "--no-browser"],
                       tmp_path)
    try:
        page = browser.new_page()
        errors = _watch(page)
        page.goto(url)
        page.wait_for_selector("body[data-ready='1']", timeout=NO_RUN_WAIT_MS)
        assert page.input_value("#f-trajectory-num_points") != ""
        base, token = url.split("/edit?token=")
        page.goto(f"{base}/?token={token}")
        page.wait_for_function("() => document.getElementById('map').dataset.state === 'no-run'",
                               timeout=NO_RUN_WAIT_MS)
        assert page.text_content("#status") == "waiting"
        assert page.get_attribute("#map", "data-drawn") == "0"
        # the note is drawn: some pixels differ from the background
        img = _pixels(page.locator("#map").screenshot())
        assert (np.abs(img - BACKGROUND_RGB).max(axis=-1) > DRAWN_MIN_DIFF).any()
        assert not (tmp_path / "run").exists()
        assert errors == []
        page.close()
    finally:
        _stop(proc)
