"""The claims value (issue 46): each band term named with the budget key it is reported under,
``band_sd`` and ``determined`` made by one function, and no other code writing them."""
import ast
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from bayesdrag.estimate.cd.claims import (BUDGET_KEYS, DATA_TERMS, DETERMINED_REL_SD, BandTerm, DataBand,
                                          add_model_error, claim, claimed, set_model_error)

PKG = Path(__file__).resolve().parents[2] / "bayesdrag"
GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "expected"
#: relative agreement of numbers result.json rounds to 4 significant digits
ROUNDED_RTOL = 1e-3
#: the row fields only bayesdrag.estimate.cd.claims writes
CLAIM_FIELDS = {"band_sd", "determined", "model_error_sd", "model_error_floor"}


def declared_terms():
    """``{name: (reported_under, module)}`` of every ``BandTerm(...)`` the package declares (an
    AST scan: a term is declared where it is sized, in its stage's module)."""
    out = {}
    for f in PKG.rglob("*.py"):
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "BandTerm" and node.args:
                if not isinstance(node.args[0], ast.Constant):
                    continue      # the class's own code
                args = [a.value for a in node.args if isinstance(a, ast.Constant)]
                kw = {k.arg: k.value.value for k in node.keywords if isinstance(k.value, ast.Constant)}
                under = args[1] if len(args) > 1 else kw.get("reported_under", "model_error")
                name = args[0]
                assert name not in out, f"band term {name!r} declared twice: {out[name][1]} and {f.name}"
                out[name] = (under, str(f.relative_to(PKG)))
    return out


def test_every_band_term_is_reported_under_a_budget_key():
    terms = declared_terms()
    assert {t.name for t in DATA_TERMS} <= set(terms)
    assert {"effects", "noise", "alternative", "effect_residual", "placement"} <= set(terms), sorted(terms)
    bad = {n: u for n, (u, _) in terms.items() if u not in BUDGET_KEYS}
    assert not bad, bad
    with pytest.raises(ValueError, match="not one of"):
        BandTerm("a_term", "nowhere")


def test_every_term_the_package_adds_is_declared():
    """Each term a stage adds goes in as a declared BandTerm (``add_model_error(rows, NAME_TERM,
    ...)``), and each part the model check records is one of its declared terms: a new term
    without its declaration fails here."""
    from bayesdrag.pipeline.model_check import CHECK_TERMS

    added = set()
    for f in PKG.rglob("*.py"):
        added |= set(re.findall(r'add_model_error\(\s*[\w.]+\s*,\s*([^,\s]+)\s*,', f.read_text(encoding="utf-8")))
    added.discard("term")        # the docstring's and the definition's own
    assert added, "the scan found no term: the pattern no longer matches the code"
    assert all(a.endswith("_TERM") for a in added), added
    text = (PKG / "pipeline" / "model_check.py").read_text(encoding="utf-8")
    parts = set(re.findall(r'parts\["(\w+)"\]\s*=', text))
    assert parts and parts <= {t.name for t in CHECK_TERMS}, parts
    with pytest.raises(TypeError, match="BandTerm"):
        add_model_error([{"ml": 0.3}], "an_undeclared_term", [0.001])
    with pytest.raises(ValueError, match="none of the declared terms"):
        set_model_error([{"ml": 0.3}], {"an_undeclared_term": [0.001]}, CHECK_TERMS)


def _claim_writes(path):
    """(line, field) of every assignment to ``something["<claim field>"]`` in a module."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] \
            if isinstance(node, (ast.AugAssign, ast.AnnAssign)) else []
        for t in targets:
            if isinstance(t, ast.Subscript) and isinstance(t.slice, ast.Constant) and t.slice.value in CLAIM_FIELDS:
                if isinstance(t.value, ast.Name) and t.value.id == "budget":
                    continue    # uncertainty_budget's list of the rows' values, not a row
                out.append((node.lineno, t.slice.value))
    return out


def test_no_code_outside_the_claims_writes_a_rows_band_or_claim():
    writes = {str(f.relative_to(PKG)): w for f in PKG.rglob("*.py") if f.name != "claims.py" or "cd" not in f.parts
              for w in [_claim_writes(f)] if w}
    assert not writes, writes
    # the scan sees such a write where there is one
    assert _claim_writes(PKG / "estimate" / "cd" / "claims.py")


def test_claimed_is_the_rule():
    ml = np.array([0.3, 0.3, 0.3, 0.3, 0.3, -0.1])
    sd = np.array([0.001, 0.004, 0.0, 0.001, np.inf, 0.001])
    data = DataBand(sd, np.zeros(6), np.array([True, True, True, False, True, True]))
    band, det = claimed(ml, data)
    np.testing.assert_array_equal(band, sd)
    # 0.33 % claimed, 1.3 % not, a zero band is no bound, unusable, infinite, a negative Cd
    assert det.tolist() == [True, False, False, False, False, False]
    me = np.full(6, 0.004)
    band, det = claimed(ml, data, me)
    assert band[0] == pytest.approx(math.hypot(0.001, 0.004), rel=1e-15) and not det[0]
    _, det = claimed(ml, data, withdrawn=True)
    assert not det.any()


def test_a_declared_source_widens_the_band_but_is_not_the_datas_failure():
    """The declared sources' share counts in the band and not in the judgement."""
    ml = np.array([0.3])
    band, det = claimed(ml, DataBand(np.array([0.004]), np.array([0.004**2 - 0.001**2]), np.array([True])))
    assert band[0] == pytest.approx(0.004) and det[0]
    assert 0.004 / 0.3 > DETERMINED_REL_SD


def test_claim_reads_the_rows_model_error_and_a_second_claim_withdraws():
    from bayesdrag.pipeline.claim import PLACEMENT_TERM
    from bayesdrag.pipeline.model_check import CHECK_TERMS

    rows = [{"ml": 0.3}, {"ml": 0.3}]
    set_model_error(rows, {"effects": np.array([0.0, 0.003]), "noise": np.array([0.0, 0.002])}, CHECK_TERMS)
    add_model_error(rows, PLACEMENT_TERM, [0.0, 0.0])
    assert rows[1]["model_error_sd"] == pytest.approx(math.hypot(0.003, 0.002))
    data = DataBand.plain([0.0005, 0.0005])
    claim(rows, data)
    assert [r["determined"] for r in rows] == [True, False]
    assert rows[1]["band_sd"] == pytest.approx(math.sqrt(0.0005**2 + 0.003**2 + 0.002**2))
    claim(rows, data, withdrawn=np.array([True, False]))
    assert [r["determined"] for r in rows] == [False, False]


@pytest.mark.parametrize("name", sorted(p.stem for p in GOLDEN.glob("*.json") if p.stem != "environment"))
def test_the_budget_reports_each_rows_terms(name):
    """On each golden result.json: every model-error part is a named term, the budget's
    ``model_error`` is the rows' ``model_error_sd`` (which holds at least the parts), and the
    squares of the budget's sources and ``cross`` add up to each row's band."""
    d = json.loads((GOLDEN / f"{name}.json").read_text())
    rows, by = d["cd"], d["uncertainty_budget"]["by_source"]
    parts = ((d["ml"].get("quality") or {}).get("model_error") or {}).get("parts") or {}
    assert set(parts) <= {n for n, (u, _) in declared_terms().items() if u == "model_error"}
    me = np.array([r.get("model_error_sd", 0.0) for r in rows])
    if parts:
        np.testing.assert_allclose(by["model_error"], me, rtol=ROUNDED_RTOL)
        in_parts = np.sqrt(sum(np.square(np.asarray(p, float)) for p in parts.values()))
        assert np.all(in_parts <= me * (1 + ROUNDED_RTOL) + 1e-12)
    total = sum(np.square(np.asarray(v, float)) for k, v in by.items() if k != "cross") + np.asarray(by["cross"], float)
    np.testing.assert_allclose(np.sqrt(total), [r["band_sd"] for r in rows], rtol=ROUNDED_RTOL)
