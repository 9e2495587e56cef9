"""Screenshots of bayesdrag's HTML reports in headless Chromium, with a check that every image
loads and the page logs no console error.

Used to check that a change to how figures are laid out or rendered leaves the reports showing
the same figures and tables (issue 31): run it before and after, look at the screenshots.

    python3 docs/scripts/screenshot_reports.py OUT_DIR REPORT.html [REPORT.html ...]

For each report it writes ``OUT_DIR/<folder>_<name>.png`` (the whole page, 1280 px wide) and
``OUT_DIR/<folder>_<name>_partK.png`` (the same cut into pieces at most 2000 px tall, for
viewers that shrink tall images), and prints one line per report: the images found, how many
loaded (``complete`` with a non-zero natural width) and the console errors. Exit status 1 when an
image did not load or the console logged an error, 2 when Chromium is missing
(``apt-get install -y chromium``).

How: the report is copied to a temporary folder with two small scripts added: the first records
``console.error`` calls, uncaught exceptions and resources that fail to load; the last, once the
page has loaded, writes the image counts and those errors into an element.
``chromium --headless --dump-dom`` prints the DOM after load; ``--screenshot`` shoots the page.
"""
from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

#: page width of the screenshots [px] and the tallest piece a screenshot is cut into
WIDTH, PIECE = 1280, 2000
#: the page is shot this tall first [px]; the shot is then cropped to the content's height
TALL = 16000
#: first in the page: records console.error calls, uncaught exceptions and failed resource loads
_EARLY = """<script>window.__shotErrors = [];
(function () { var e = console.error; console.error = function () {
  window.__shotErrors.push(Array.from(arguments).join(" ")); e.apply(console, arguments); }; })();
window.addEventListener("error", function (ev) {
  window.__shotErrors.push(ev.message || ("failed to load " + (ev.target && (ev.target.src || ev.target.href)))); }, true);
</script>"""
#: last in the page: once loaded, writes the image counts and the errors into an element
_PROBE = """<script>window.addEventListener("load", function () {
  var imgs = Array.from(document.images), ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; });
  var d = document.createElement("div"); d.id = "shot-probe";
  d.textContent = "images=" + imgs.length + " loaded=" + ok.length + " height=" + document.documentElement.scrollHeight
    + " errors=" + JSON.stringify(window.__shotErrors);
  document.body.appendChild(d);
});</script>"""


def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def _run(browser, *args):
    cmd = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
           "--virtual-time-budget=5000", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


def _instrument(html):
    """The report with :data:`_EARLY` first and :data:`_PROBE` last."""
    head = re.search(r"<head[^>]*>", html, flags=re.I)
    html = html[:head.end()] + _EARLY + html[head.end():] if head else _EARLY + html
    return html.replace("</body>", _PROBE + "</body>") if "</body>" in html else html + _PROBE


def check_report(browser, report, out_dir):
    """Screenshot ``report`` and check its images; returns ``(ok, line)``."""
    import numpy as np
    from PIL import Image

    report = Path(report).resolve()
    stem = f"{report.parent.name}_{report.stem}"
    with tempfile.TemporaryDirectory() as tmp:
        probe = Path(tmp) / report.name
        html = report.read_text(encoding="utf-8")
        probe.write_text(_instrument(html), encoding="utf-8")
        dom = _run(browser, "--dump-dom", probe.as_uri())
        m = re.search(r'id="shot-probe">images=(\d+) loaded=(\d+) height=(\d+) errors=(.*?)</div>', dom.stdout)
        shot = Path(out_dir) / f"{stem}.png"
        _run(browser, f"--screenshot={shot}", f"--window-size={WIDTH},{TALL}", report.as_uri())
    if m is None:
        return False, f"{report}: the page did not finish loading ({dom.returncode})"
    import html as htmllib
    import json

    n, loaded, height = map(int, m.groups()[:3])
    errors = json.loads(htmllib.unescape(m.group(4)))
    img = Image.open(shot)
    img = img.crop((0, 0, img.width, min(img.height, max(height, 1))))
    img.save(shot)
    for k, top in enumerate(range(0, img.height, PIECE)):
        img.crop((0, top, img.width, min(img.height, top + PIECE))).save(shot.with_name(f"{stem}_part{k}.png"))
    blank = float(np.asarray(img.convert("L")).std()) < 1.0
    ok = loaded == n and not errors and not blank
    line = (f"{report}: {n} images, {loaded} loaded, {len(errors)} console errors, page {height} px"
            f"{', BLANK screenshot' if blank else ''} -> {shot}")
    return ok, line + "".join(f"\n  {e}" for e in errors)


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) < 2:
        print(__doc__.strip().split("\n\n")[2], file=sys.stderr)
        return 2
    browser = _chromium()
    if browser is None:
        print("screenshot_reports: no chromium found (apt-get install -y chromium)", file=sys.stderr)
        return 2
    out = Path(argv[0])
    out.mkdir(parents=True, exist_ok=True)
    good = True
    for report in argv[1:]:
        ok, line = check_report(browser, report, out)
        good &= ok
        print(("OK   " if ok else "FAIL ") + line, flush=True)
    return 0 if good else 1


if __name__ == "__main__":
    sys.exit(main())
