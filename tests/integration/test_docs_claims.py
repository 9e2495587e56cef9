"""Statements of the user documentation checked against the program (issue 26: formats.md said
the systematic `_sd` keys were refused, diagnose.md said "No options." and listed two, the
README's demo time was far from a fresh machine's and it never named `bayesdrag plan`)."""
import argparse
import re
from pathlib import Path

import pytest

from bayesdrag.cli import build_parser
from bayesdrag.io.rounds import read_round
from bayesdrag.round import SYSTEMATIC_SOURCES

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"


def _options(command):
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {s for a in sub.choices[command]._actions for s in a.option_strings if s.startswith("--")} - {"--help"}


def test_formats_states_the_systematic_sd_keys_the_round_accepts(tmp_path):
    text = (DOCS / "formats.md").read_text()
    assert "are **not accepted**" not in text
    table = text[text.index("| key | section | unit | largest accepted |"):]
    rows = re.findall(r"^\| `(\w+)_sd` \| `\[(\w+)\]` \|", table, flags=re.M)
    assert {k: sec for k, sec in rows} == {k: v[0] for k, v in SYSTEMATIC_SOURCES.items()}
    example = re.search(r"```toml\n(\[projectile\]\nmass = 42.6\nmass_sd.*?)```", text, flags=re.S).group(1)
    (tmp_path / "r.toml").write_text(example)
    rnd = read_round(tmp_path / "r.toml")
    assert rnd.systematics.declared() == {"mass": 0.05, "density": 0.01}


def test_diagnose_page_names_every_option_of_the_command():
    text = (DOCS / "diagnose.md").read_text()
    assert "No options" not in text
    for opt in _options("diagnose") - {"--output", "--quiet"}:
        assert f"`{opt}" in text, opt
    assert "`-q`" in text


@pytest.mark.parametrize("command", ["plan", "simulate", "fit", "diagnose", "batch", "demo"])
def test_readme_names_every_command(command):
    assert f"bayesdrag {command}" in (ROOT / "README.md").read_text()


def test_python_docs_name_only_existing_api():
    import bayesdrag

    text = (DOCS / "python.md").read_text()
    table = text[:text.index("\n## ")]
    for name in re.findall(r"`([A-Z][A-Za-z]+)`", table):
        assert hasattr(bayesdrag, name), name
    assert not re.search(r"`Diagnosis`", text + (DOCS / "api.md").read_text())
