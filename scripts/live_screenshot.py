"""Screenshot of the live view on a run folder (docs/img/live-view.png), with Debian's chromium.

Serves the folder with the live view's own server, opens it in headless chromium through
Playwright (``executable_path=/usr/bin/chromium``; nothing downloaded), selects a scenario tab
and writes a PNG reduced to a 128-colour palette (the page is flat colours: a few tens of kB).

Usage (from the repository root)::

    .venv/bin/python scripts/live_screenshot.py RUN_DIR docs/img/live-view.png [--scenario fbs]
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from veriloc_rt.live.server import LiveServer  # noqa: E402

ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run_dir")
    p.add_argument("png")
    p.add_argument("--scenario", default="fbs", help="the tab shown (default: fbs)")
    p.add_argument("--width", type=int, default=1280)
    p.add_argument("--height", type=int, default=900)
    a = p.parse_args(argv)
    from PIL import Image
    from playwright.sync_api import sync_playwright

    server = LiveServer(a.run_dir, port=0).start()
    try:
        server.view.scene()          # starts building the map's layer
        server.view.wait_scene(120)
        with sync_playwright() as pw, tempfile.TemporaryDirectory() as profile:
            ctx = pw.chromium.launch_persistent_context(
                profile, executable_path="/usr/bin/chromium", headless=True, args=ARGS,
                viewport={"width": a.width, "height": a.height})
            page = ctx.new_page()
            page.goto(server.url)
            # predicates as functions: a plain expression is eval'd, which the page's CSP forbids
            page.wait_for_function("() => +document.getElementById('map').dataset.drawn >= 1")
            page.click(f"#tabs button:text-is('{a.scenario}')")
            page.wait_for_function(
                f"() => document.getElementById('decisions-scenario').textContent.includes('{a.scenario}')"
                " && +document.getElementById('map').dataset.drawn >= 1")
            png = page.screenshot(full_page=True)
            ctx.close()
    finally:
        server.shutdown()
    img = Image.open(io.BytesIO(png)).convert("RGB").quantize(colors=128, method=Image.Quantize.FASTOCTREE)
    Path(a.png).parent.mkdir(parents=True, exist_ok=True)
    img.save(a.png, optimize=True)
    print(f"wrote {a.png} ({Path(a.png).stat().st_size / 1024:.0f} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
