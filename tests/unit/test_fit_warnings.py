"""A fit's warnings are typed records (kind, params, message) that code tests by kind; the Python
API emits them through ``warnings`` as :class:`bayesdrag.BayesdragWarning`; ``result.json`` holds
their sentences unchanged."""
from __future__ import annotations

import ast
import dataclasses
import json
import warnings
from pathlib import Path

import pytest

import bayesdrag
from bayesdrag._runtime.beside import plain_json
from bayesdrag.errors import QUIET_KINDS, WARNING_KINDS, BayesdragWarning, FitWarning, as_warning
from bayesdrag.results.document import jsonable

PKG = Path(bayesdrag.__file__).resolve().parent
#: the iterables whose items are warnings, by the name the package gives them
WARNING_LISTS = {"warnings", "problems", "warns"}


def test_record_is_its_sentence_and_frozen():
    w = FitWarning("at_bound", "parameter c3 = 20 is at its bound [-20, 20]", ["c3"])
    assert str(w) == w.message and f"{w}" == w.message
    assert w.params == ("c3",)
    with pytest.raises(dataclasses.FrozenInstanceError):
        w.kind = "correlated"   # type: ignore[misc]


def test_unknown_kind_is_refused():
    with pytest.raises(ValueError, match="warning kind 'typo' is not one of"):
        FitWarning("typo", "anything")


def test_json_holds_the_sentence():
    w = FitWarning("correlated", "parameters a0 and a1 are strongly correlated (rho = -0.993)", ("a0", "a1"))
    doc = {"ml": {"warnings": [w], "quality": {"problems": [w.within("window 2: ")]}}}
    assert json.loads(json.dumps(jsonable(doc))) == {
        "ml": {"warnings": [w.message], "quality": {"problems": ["window 2: " + w.message]}}}
    assert json.loads(json.dumps([w], default=plain_json)) == [w.message]   # the forked helper's answer


def test_read_back_sentences_are_recorded_kind():
    w = as_warning("a sentence from result.json")
    assert (w.kind, w.message) == ("recorded", "a sentence from result.json")
    assert "recorded" in WARNING_KINDS


def _iter_name(src):
    """The name a comprehension iterates over (``res.warnings`` -> ``warnings``), or None."""
    return (src.attr if isinstance(src, ast.Attribute) else
            src.slice.value if isinstance(src, ast.Subscript) and isinstance(src.slice, ast.Constant) else
            src.id if isinstance(src, ast.Name) else None)


def _warning_lists(tree):
    """:data:`WARNING_LISTS` and the names assigned a comprehension over one of them (a filtered
    list of warnings is still warnings: ``ic_bound = [w for w in res.warnings if ...]``)."""
    names = set(WARNING_LISTS)
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and isinstance(node.value, (ast.ListComp, ast.GeneratorExp)) \
                and any(_iter_name(g.iter) in names for g in node.value.generators):
            names.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return names


def _substring_tests(tree):
    """Comprehensions over a warning list whose condition compares the item with ``in``/``not in``
    or calls a string method on it: a warning found by its words."""
    lists = _warning_lists(tree)
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, (ast.ListComp, ast.GeneratorExp, ast.SetComp)):
            continue
        for gen in node.generators:
            if _iter_name(gen.iter) not in lists or not isinstance(gen.target, ast.Name):
                continue
            item = gen.target.id
            for cond in [n for c in gen.ifs for n in ast.walk(c)] + [n for n in ast.walk(node.elt)]:
                if isinstance(cond, ast.Compare) and any(isinstance(op, (ast.In, ast.NotIn)) for op in cond.ops) \
                        and any(isinstance(c, ast.Name) and c.id == item for c in cond.comparators):
                    found.append(node.lineno)
                if isinstance(cond, ast.Call) and isinstance(cond.func, ast.Attribute) \
                        and isinstance(cond.func.value, ast.Name) and cond.func.value.id == item \
                        and cond.func.attr in {"startswith", "endswith", "find", "split", "lower"}:
                    found.append(node.lineno)
    return found


def test_no_warning_is_found_by_its_words():
    hits = {}
    for f in sorted(PKG.rglob("*.py")):
        lines = _substring_tests(ast.parse(f.read_text(encoding="utf-8")))
        if lines:
            hits[str(f.relative_to(PKG))] = lines
    assert hits == {}, f"warnings tested by substring (test their kind instead): {hits}"


def test_the_scan_sees_a_substring_test():
    # the scan above is no test if it cannot find what it looks for
    tree = ast.parse('kept = [w for w in res.warnings if "is at its bound" not in w]\n'
                     'x = any(p.startswith("channel") for p in quality["problems"])\n'
                     'names = [w.split()[1] for w in kept]\n')
    assert sorted(_substring_tests(tree)) == [1, 2, 3]


def test_fit_emits_its_warnings(demo_track_and_round):
    track, rnd = demo_track_and_round
    # a quadratic Cd over the whole flight: it misses the track, and its coefficients correlate
    with pytest.warns(BayesdragWarning) as got:
        res = bayesdrag.fit(track, rnd, mcmc=False, drag="poly2", model_check=False)
    assert res.warnings, "this fit should warn"
    emitted = [str(w.message) for w in got if issubclass(w.category, BayesdragWarning)]
    kinds = {w.kind for w in res.warnings}
    assert {"correlated", "misfit"} <= kinds
    # the ones worth reading are emitted; the technical ones (correlations) stay in res.warnings
    assert emitted == [w.message for w in res.warnings if w.shown]
    assert not any(w.kind in QUIET_KINDS for w in res.warnings if w.message in emitted)
    assert all(set(w.params) <= set(res.scheme1.ml.names) for w in res.warnings if w.kind == "correlated")
    # result.json holds the sentences, as it did when warnings were strings
    assert res.to_dict()["ml"]["warnings"] == [w.message for w in res.scheme1.ml.warnings]


def test_a_user_can_silence_them(demo_track_and_round):
    track, rnd = demo_track_and_round
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", category=BayesdragWarning)
        res = bayesdrag.fit(track, rnd, mcmc=False, drag="poly2", model_check=False)
    assert res.warnings      # silenced, not lost


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    """A 155 mm flight of the independent integrator (tests/fixtures/met_flight.py), calm ICAO
    air, the M101 table: (track path, round path)."""
    from fixtures import met_flight as M

    return M.write_icao_case(tmp_path_factory.mktemp("flight"), seed=4)


@pytest.fixture(scope="module")
def demo_track_and_round(flight):
    return bayesdrag.read_track(flight[0]), bayesdrag.read_round(flight[1])


def test_the_console_prints_what_matters_and_counts_the_rest(flight, tmp_path, capsys):
    """``bayesdrag fit``: the misfit is printed, the strong correlations are counted in one note
    (result.json keeps them); ``--verbose`` prints them; the report lists them apart."""
    from bayesdrag.cli import main

    args = [str(flight[0]), str(flight[1]), "--no-mcmc", "--drag", "poly2", "--no-model-check"]
    assert main(["fit", *args, "-o", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "bayesdrag: warning: channel" in err and "strongly correlated" not in err
    assert "technical warnings (correlated: nothing to act on) in result.json; --verbose prints them" in err
    doc = json.loads((tmp_path / "a" / "result.json").read_text())
    assert any("strongly correlated" in w for w in doc["ml"]["warnings"])
    html = (tmp_path / "a" / "report.html").read_text()
    assert "technical notes (strong correlations" in html and "strongly correlated" in html
    assert main(["fit", *args, "-o", str(tmp_path / "b"), "--verbose"]) == 0
    assert "bayesdrag: warning: parameters a0 and a1 are strongly correlated" in capsys.readouterr().err


def test_angles_in_warnings_are_in_degrees():
    """A fitted angle (a radar's azimuth bias, a launch yaw) is said in degrees, as the round gives
    angles; other parameters as fitted (issue 47, item 3)."""
    from bayesdrag.effects import param_unit
    from bayesdrag.estimate.model.ml import _angle_scale

    assert param_unit("azimuth_bias.bias") == "rad" and param_unit("range_bias.bias") == "m"
    assert param_unit("c3") == "" and param_unit("Ux0") == ""
    k, unit = _angle_scale("elevation_bias.bias")
    assert unit == " deg" and abs(k * 0.001 - 0.0572958) < 1e-6          # 1 mrad = 0.0573 deg
    assert _angle_scale("lift.factor") == (1.0, "")
