"""The standard drag functions (G1, G2, G5, G6, G7, G8, GI, GS) shipped as package data: each table
loads, is physical, spans its published Mach range, agrees with the published numbers, and only the
bare name (never a file that happens to be called G7.csv) selects one."""
import fnmatch
import sys
from importlib.resources import files
from pathlib import Path

import numpy as np
import pytest

from bayesdrag.drag import ReferenceTable
from bayesdrag.errors import InputError
from bayesdrag.io.drag_tables import (STANDARD_DRAG_FUNCTIONS, is_standard_drag, load_m101, read_drag_table,
                                      read_standard_drag, standard_drag_name)

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[2]
#: the Mach span each table is published over [-]: 0-5, except the sphere's (0-4)
PUBLISHED_SPAN = {name: (0.0, 5.0) for name in STANDARD_DRAG_FUNCTIONS} | {"GS": (0.0, 4.0)}
#: the tables print Cd to 4 decimals: agreement "to the printed digits" is half the last one [-]
PRINTED_CD_ATOL = 0.5e-4
#: Cd at Mach 2.0 as the tables print it (BRL tables, as py-ballisticcalc ships them)
CD_AT_MACH_2 = {"G1": 0.5934, "G7": 0.2980}
VALID_NAMES = "G1, G2, G5, G6, G7, G8, GI, GS"


@pytest.mark.parametrize("name", STANDARD_DRAG_FUNCTIONS)
def test_each_table_loads_positive_over_its_published_span(name):
    table = read_standard_drag(name)
    assert isinstance(table, ReferenceTable)
    assert table.source == f"{name} (standard drag function, BRL)"
    assert table.mach_range == PUBLISHED_SPAN[name]
    cd = np.asarray(table.cd_values)
    assert np.all(cd > 0) and np.all(cd < 1.5)
    assert np.all(np.diff(table.mach) > 0)
    assert len(table.mach) >= 70          # the published tables have 76-85 rows


@pytest.mark.parametrize("name", sorted(CD_AT_MACH_2))
def test_cd_at_mach_2_is_the_printed_value(name):
    assert float(read_standard_drag(name).value(2.0)) == pytest.approx(CD_AT_MACH_2[name], abs=PRINTED_CD_ATOL)


@pytest.mark.parametrize("name", STANDARD_DRAG_FUNCTIONS)
def test_rows_agree_with_py_ballisticcalc(name):
    dt = pytest.importorskip("py_ballisticcalc.drag_tables")
    theirs = getattr(dt, f"Table{name}")
    table = read_standard_drag(name)
    assert table.mach == tuple(p["Mach"] for p in theirs)
    np.testing.assert_allclose(table.cd_values, [p["CD"] for p in theirs], rtol=0, atol=PRINTED_CD_ATOL)
    if name in CD_AT_MACH_2:
        row = next(p for p in theirs if p["Mach"] == 2.0)
        assert float(table.value(2.0)) == pytest.approx(row["CD"], abs=PRINTED_CD_ATOL)


@pytest.mark.parametrize("name", STANDARD_DRAG_FUNCTIONS)
def test_each_file_names_its_source(name):
    text = (files("bayesdrag") / "data" / "drag_functions" / f"{name.lower()}.csv").read_text(encoding="utf-8")
    header = "\n".join(line for line in text.splitlines() if line.startswith("#"))
    assert f"Standard drag function {name}" in header
    assert "Ballistic Research Laboratory (BRL)" in header
    assert "py-ballisticcalc" in header and f"Table{name}" in header
    assert "mach,cd" in text.splitlines()


def test_names_are_case_insensitive():
    lower, upper = read_standard_drag("g7"), read_standard_drag("G7")
    assert lower.mach == upper.mach and lower.cd_values == upper.cd_values
    assert lower.source == "G7 (standard drag function, BRL)"
    assert read_standard_drag("gi").source.startswith("GI ")


@pytest.mark.parametrize("name, expected", [
    ("G7", True), ("g7", True), ("Gs", True), ("GI", True),
    ("G7.csv", False), ("g7.CSV", False), ("tables/G7", False), ("./G7", False), (" G7", False), ("G7 ", False),
    ("G3", False), ("RA4", False), ("", False), (7, False), (None, False),
])
def test_is_standard_drag_takes_bare_names_only(name, expected):
    assert is_standard_drag(name) is expected


@pytest.mark.parametrize("name", ["G9", "G3", "RA4", "G7.csv", "", "g 7", "GX"])
def test_unknown_names_are_refused_with_the_valid_ones(name):
    with pytest.raises(InputError, match=f"is not a standard drag function; use one of {VALID_NAMES}"):
        read_standard_drag(name)


def test_a_file_named_g7_csv_is_a_file_not_the_standard(tmp_path):
    folder = tmp_path / "tables"
    folder.mkdir()
    f = folder / "G7.csv"
    f.write_text("# my own G7-like table\nmach,cd\n0.5,0.50\n1.0,0.60\n2.0,0.70\n", encoding="utf-8")
    assert not is_standard_drag(str(f))
    assert not is_standard_drag(f.name)
    table = read_drag_table(f)
    assert table.source == str(f)
    assert table.cd_values == (0.5, 0.6, 0.7)
    assert float(table.value(2.0)) != pytest.approx(CD_AT_MACH_2["G7"], abs=PRINTED_CD_ATOL)
    assert standard_drag_name(table) is None


@pytest.mark.parametrize("name", STANDARD_DRAG_FUNCTIONS)
def test_standard_drag_name_round_trips(name):
    assert standard_drag_name(read_standard_drag(name.lower())) == name


def test_standard_drag_name_refuses_look_alikes():
    g7 = read_standard_drag("G7")
    changed = ReferenceTable(g7.mach, tuple(c * 1.01 for c in g7.cd_values), source=g7.source)
    assert standard_drag_name(changed) is None
    assert standard_drag_name(load_m101()) is None


def test_package_data_ships_the_tables():
    """pyproject's package data must take the tables into a wheel (an editable install finds them
    in the tree either way)."""
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    patterns = cfg["tool"]["setuptools"]["package-data"]["bayesdrag"]
    for name in STANDARD_DRAG_FUNCTIONS:
        rel = f"data/drag_functions/{name.lower()}.csv"
        assert (ROOT / "bayesdrag" / rel).is_file()
        assert any(_glob_matches(rel, p) for p in patterns), patterns


def _glob_matches(rel, pattern):
    """Whether a package-data glob takes ``rel``: ``*`` within one folder, ``**`` across folders."""
    if "**" in pattern:
        return fnmatch.fnmatch(rel, pattern)
    parts, pats = rel.split("/"), pattern.split("/")
    return len(parts) == len(pats) and all(fnmatch.fnmatch(a, b) for a, b in zip(parts, pats))
