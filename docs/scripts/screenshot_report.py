"""Screenshot a report.html with headless Chromium (what a reader sees first).

    python docs/scripts/screenshot_report.py OUT_DIR/report.html -o report.png [--width 1200 --height 1600]

Needs a Chromium on PATH (``chromium``, ``chromium-browser`` or ``google-chrome``; on Debian/Ubuntu
``apt-get install -y chromium``). The page is self-contained (figures embedded), so no server is
needed. Prints the PNG's path. Used to check that the page opens with the headline (Cd at a few
Mach numbers with its total band, the determined range, whether the answer is clean) above the
first figure.
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_browser():
    """The first headless-capable Chromium on PATH, or None."""
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    return None


def screenshot(html, png, width=1200, height=1600, browser=None, timeout=120):
    """Render ``html`` (a file) to ``png`` with headless Chromium; returns the PNG's path."""
    browser = browser or find_browser()
    if browser is None:
        raise SystemExit("no Chromium found on PATH (tried " + ", ".join(BROWSERS) + "): install one, e.g. "
                         "apt-get install -y chromium")
    html, png = Path(html).resolve(), Path(png).resolve()
    if not html.is_file():
        raise SystemExit(f"{html}: no such file")
    with tempfile.TemporaryDirectory() as profile:   # a throwaway profile: no user state read or left
        cmd = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
               f"--user-data-dir={profile}", f"--window-size={width},{height}", f"--screenshot={png}",
               html.as_uri()]
        subprocess.run(cmd, check=True, timeout=timeout, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    if not png.is_file():
        raise SystemExit(f"{browser} wrote no screenshot")
    return png


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("html")
    ap.add_argument("-o", "--output", default="report.png")
    ap.add_argument("--width", type=int, default=1200)
    ap.add_argument("--height", type=int, default=1600)
    a = ap.parse_args(argv)
    print(screenshot(a.html, a.output, a.width, a.height))


if __name__ == "__main__":
    sys.exit(main())
