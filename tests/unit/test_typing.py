"""The public API is typed (like py-ballisticcalc's): every exported function and every method,
property and field of the result values carries annotations; ``mypy --disallow-untyped-defs``
passes on the public surface (``bayesdrag/__init__.py`` and ``bayesdrag/results/``, the modules
behind them followed for their types); the package ships ``py.typed``; type checkers see the same
names as ``bayesdrag.__all__``."""
import ast
import dataclasses
import importlib.util
import inspect
import re
import subprocess
import sys
from pathlib import Path

import pytest

import bayesdrag
from bayesdrag import results

ROOT = Path(__file__).resolve().parents[2]
#: the result values whose every public method, property and field is annotated
RESULT_CLASSES = (results.FitResult, results.CdTable, results.Summary, results.DiagnosisResult, results.PlanResult)
#: the files mypy checks with --disallow-untyped-defs (the public surface)
PUBLIC_SURFACE = ("bayesdrag/__init__.py", "bayesdrag/results")
#: mypy's seconds on the public surface are a few; a hang is a failure
MYPY_TIMEOUT = 600


def _unannotated(fn, owner):
    """Parameters (and ``return``) of ``fn`` without annotations."""
    sig = inspect.signature(fn)
    missing = [p.name for p in sig.parameters.values()
               if p.name not in ("self", "cls") and p.annotation is inspect.Parameter.empty]
    if sig.return_annotation is inspect.Signature.empty and fn.__name__ != "__init__":
        missing.append("return")
    return [f"{owner}{fn.__name__}: {m}" for m in missing]


def test_exported_functions_are_annotated():
    bad = []
    for name in bayesdrag.__all__:
        obj = getattr(bayesdrag, name)
        if inspect.isfunction(obj):
            bad += _unannotated(obj, "bayesdrag.")
    assert not bad, bad


@pytest.mark.parametrize("cls", RESULT_CLASSES, ids=lambda c: c.__name__)
def test_result_values_are_annotated(cls):
    bad = []
    for name, member in vars(cls).items():
        generated = dataclasses.is_dataclass(cls) and name.startswith("__")     # dataclass's own dunders
        if (name.startswith("_") and name != "__init__") or generated:
            continue
        if isinstance(member, property):
            bad += _unannotated(member.fget, f"{cls.__name__}.")
        elif isinstance(member, (classmethod, staticmethod)):
            bad += _unannotated(member.__func__, f"{cls.__name__}.")
        elif inspect.isfunction(member):
            bad += _unannotated(member, f"{cls.__name__}.")
    fields = dataclasses.fields(cls) if dataclasses.is_dataclass(cls) else ()
    declared = inspect.get_annotations(cls)
    bad += [f"{cls.__name__}.{f.name}: field" for f in fields if f.name not in declared]
    assert not bad, bad


def test_result_fields_are_declared():
    """Every attribute a result sets in its constructor is declared with its type."""
    res = results.FitResult({"scheme": 1, "drag_model": "spline", "ml": {}, "cd": [
        {"mach": 1.0, "ml": 0.3, "band_sd": 1e-3, "crb_sd": 1e-3, "determined": True, "reference": None}]})
    declared = inspect.get_annotations(results.FitResult)
    assert set(vars(res)) <= set(declared), set(vars(res)) - set(declared)


def test_type_checkers_see_the_public_names():
    """The ``if TYPE_CHECKING:`` imports of ``bayesdrag/__init__.py`` name exactly the public API,
    each from the module ``_API`` loads it from."""
    tree = ast.parse((ROOT / "bayesdrag" / "__init__.py").read_text(encoding="utf-8"))
    seen = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and getattr(node.test, "id", None) == "TYPE_CHECKING":
            for imp in node.body:
                assert isinstance(imp, ast.ImportFrom), ast.dump(imp)
                mod = "bayesdrag" + ("." + imp.module if imp.module else "")
                seen.update({a.name: mod for a in imp.names})
    assert seen == bayesdrag._API


def test_the_package_ships_py_typed():
    assert (ROOT / "bayesdrag" / "py.typed").is_file()
    assert '"py.typed"' in (ROOT / "pyproject.toml").read_text(encoding="utf-8")


def _private_untyped(line, path):
    """An untyped-def error on a private helper (``_name``, not a dunder): not the public surface
    (the import-time set-up of ``bayesdrag/__init__.py``)."""
    src = (ROOT / path).read_text(encoding="utf-8")
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.lineno == line:
            return node.name.startswith("_") and not node.name.endswith("__")
    return False


#: a user's script: every line type-checks except the marked one, which mypy must catch (the
#: types flow from ``bayesdrag.fit`` through the result to its arrays)
USER_SCRIPT = """
import numpy as np
import bayesdrag

def widest(track: bayesdrag.RadarTrack, rnd: bayesdrag.Round) -> float:
    res = bayesdrag.fit(track, rnd, mcmc=False)
    lo, hi = res.band(0.9)
    table: bayesdrag.CdTable = res.cd
    text: str = str(res.summary())
    back: bayesdrag.FitResult = bayesdrag.load_result("fit")
    return float(np.max(hi - lo)) + len(text) + len(table) + back.scheme

def wrong(track: bayesdrag.RadarTrack, rnd: bayesdrag.Round) -> None:
    bayesdrag.fit(track, rnd).cd.mean_value  # MUST-FAIL
"""


@pytest.mark.skipif(importlib.util.find_spec("mypy") is None, reason="mypy not installed (pip install '.[test]')")
def test_mypy_passes_on_the_public_surface(tmp_path):
    script = tmp_path / "user_script.py"
    script.write_text(USER_SCRIPT, encoding="utf-8")
    must_fail = USER_SCRIPT.splitlines().index("    bayesdrag.fit(track, rnd).cd.mean_value  # MUST-FAIL") + 1
    r = subprocess.run([sys.executable, "-m", "mypy", "--disallow-untyped-defs", "--cache-dir", str(tmp_path / "cache"),
                        "--no-error-summary", *PUBLIC_SURFACE, str(script)], cwd=ROOT, capture_output=True, text=True,
                       timeout=MYPY_TIMEOUT)
    errors, caught = [], False
    for line in r.stdout.splitlines():
        m = re.match(r"(?P<path>[^:]+):(?P<line>\d+): error: .*\[(?P<code>[a-z-]+)\]$", line)
        if m is None:
            continue
        if m["path"] == str(script) and int(m["line"]) == must_fail and m["code"] == "attr-defined":
            caught = True
            continue
        if m["code"] == "no-untyped-def" and _private_untyped(int(m["line"]), m["path"]):
            continue
        errors.append(line)
    assert r.returncode in (0, 1) and not r.stderr.strip(), r.stderr[-2000:]
    assert not errors, "\n".join(errors)
    assert caught, "mypy did not see the result's types through bayesdrag.fit:\n" + r.stdout[-2000:]
