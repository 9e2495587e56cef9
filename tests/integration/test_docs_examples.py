"""The user guide's examples run as written.

Every fenced ```bash and ```python block of the pages below is run, in the order of the page,
in one fresh folder per page (a reader following the page in one terminal), with the checkout's
package first on the path and a ``bayesdrag`` command that runs it. A block preceded by the line
``<!-- docs-test: skip -->`` is not run: installing, changing folder, resuming a killed run, Dask
clusters (tests/test_batch.py) and the command-line fits with sampling (docs/python.md samples
through the API, tests/test_readme.py and tests/test_demo.py from the command line), so that this
file stays near a minute. ``text`` blocks show output and are not run.
"""
import os
import re
import stat
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
SKIP_MARK = "<!-- docs-test: skip -->"
FENCE = re.compile(r"^(?P<skip><!-- docs-test: skip -->\n)?```(?P<lang>bash|python)\n(?P<code>.*?)^```\s*$",
                   re.S | re.M)
#: the pages whose examples are run, in the order of the user guide
PAGES = ("quickstart.md", "fitting.md", "radar.md", "diagnose.md", "python.md", "campaign.md", "planning.md")
#: seconds one page may take (the whole file runs in about a minute on 2 cores)
PAGE_TIMEOUT = 300


def code_blocks(page):
    """``[(lang, code)]`` of the runnable blocks of ``docs/page`` in document order."""
    text = (DOCS / page).read_text(encoding="utf-8")
    return [(m["lang"], m["code"]) for m in FENCE.finditer(text) if not m["skip"]]


def _environment(tmp_path):
    """PATH with ``bayesdrag`` and ``python3`` running this interpreter on the checkout."""
    bin_dir = tmp_path / "_bin"
    bin_dir.mkdir()
    for name, body in (("bayesdrag", f'exec "{sys.executable}" -m bayesdrag.cli "$@"\n'),
                       ("python3", f'exec "{sys.executable}" "$@"\n')):
        p = bin_dir / name
        p.write_text("#!/bin/sh\n" + body)
        p.chmod(p.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
    env = dict(os.environ)
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    env["MPLBACKEND"] = "Agg"
    env.pop("BAYESDRAG_DEBUG", None)
    return env


def test_every_page_has_examples_and_marks_are_attached():
    for page in PAGES:
        text = (DOCS / page).read_text(encoding="utf-8")
        assert code_blocks(page), f"{page}: no runnable example"
        # a skip mark must sit right above a fence, or it would silently skip nothing
        for m in re.finditer(re.escape(SKIP_MARK), text):
            assert text[m.end():].startswith("\n```"), f"{page}: a skip mark not followed by a code block"


@pytest.mark.parametrize("page", PAGES)
def test_page_examples_run(page, tmp_path):
    env = _environment(tmp_path)
    work = tmp_path / "work"
    work.mkdir()
    for k, (lang, code) in enumerate(code_blocks(page)):
        cmd = ["bash", "-e", "-o", "pipefail", "-c", code] if lang == "bash" else [sys.executable, "-c", code]
        p = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True, timeout=PAGE_TIMEOUT)
        assert p.returncode == 0, (f"{page}, block {k + 1} ({lang}) exited {p.returncode}:\n{code}\n"
                                   f"--- stdout ---\n{p.stdout[-2000:]}\n--- stderr ---\n{p.stderr[-3000:]}")
