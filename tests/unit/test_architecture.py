"""The package's shape, checked: layers, no import cycles, no reaching into private names, modules
and functions of a readable size (docs/architecture.md). Imports inside functions count."""
import ast
from collections import defaultdict
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[2] / "bayesdrag"
#: module size [lines] above which the architecture test reports a module (a report: concepts decide
#: boundaries), and the longest function [lines] a newcomer should have to read at once
MAX_MODULE_LINES = 700
MAX_FUNCTION_LINES = 150

#: the layers, lowest first: a module may import only from its own layer or lower ones
LAYERS = [
    ["bayesdrag.errors", "bayesdrag.constants", "bayesdrag.validate", "bayesdrag._runtime"],
    # (bayesdrag.atmosphere, .wind, .station_air: deprecated re-exports of air/ until release 0.3)
    ["bayesdrag.air", "bayesdrag.atmosphere", "bayesdrag.wind", "bayesdrag.station_air", "bayesdrag.drag"],
    ["bayesdrag.track", "bayesdrag.round"],
    ["bayesdrag.io"],
    ["bayesdrag.dynamics"],
    ["bayesdrag.measure"],
    # (bayesdrag.effect_inputs, .wind_layers: deprecated re-exports of effects/ until release 0.3)
    ["bayesdrag.effects", "bayesdrag.effect_inputs", "bayesdrag.wind_layers"],
    ["bayesdrag.synthetic"],
    ["bayesdrag.estimate"],
    ["bayesdrag.planning"],
    ["bayesdrag.results"],
    ["bayesdrag.diagnosis"],
    # (bayesdrag.model_check, .sampling: deprecated re-exports of pipeline/ until release 0.3)
    ["bayesdrag.options", "bayesdrag.model_check", "bayesdrag.sampling", "bayesdrag.pipeline"],
    ["bayesdrag.campaign"],
    ["bayesdrag.plots"],
    ["bayesdrag.report"],
    ["bayesdrag.commands"],
    ["bayesdrag.cli", "bayesdrag"],
]
#: the upward imports allowed, each only inside a function (a method's body): the results'
#: presentation methods (figures, writing the folder) draw and write through plots/ and report/
UPWARD_INSIDE_FUNCTIONS = {("bayesdrag.results", "bayesdrag.plots"), ("bayesdrag.results", "bayesdrag.report")}


def _modules():
    out = {}
    for f in sorted(PKG.rglob("*.py")):
        parts = f.relative_to(PKG.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = f
    return out


def _function_imports(tree):
    """The import nodes inside a function's body (any depth)."""
    inside = set()
    for fn in ast.walk(tree):
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            inside.update(id(n) for n in ast.walk(fn) if isinstance(n, (ast.Import, ast.ImportFrom)))
    return inside


def _imports(name, path, *, in_function=False):
    """(module imported, names imported, line) of every import in a module, functions included
    (``in_function=True``: each with a fourth item, whether it sits inside a function)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    is_pkg = path.name == "__init__.py"
    base = name.split(".") if is_pkg else name.split(".")[:-1]
    local = _function_imports(tree)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                b = base[:len(base) - node.level + 1]
                mod = ".".join(b + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.startswith("bayesdrag"):
                out.append((mod, [a.name for a in node.names], node.lineno, id(node) in local))
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("bayesdrag"):
                    out.append((a.name, [], node.lineno, id(node) in local))
    return out if in_function else [t[:3] for t in out]


def _layer(mod):
    best = None
    for i, layer in enumerate(LAYERS):
        for prefix in layer:
            if mod == prefix or mod.startswith(prefix + "."):
                if best is None or len(prefix) > best[1]:
                    best = (i, len(prefix))
    return None if best is None else best[0]


MODULES = _modules()


def _resolve(mod, names):
    """Modules an import statement depends on: ``from pkg import sub`` depends on ``pkg.sub``."""
    out = []
    for n in names or [None]:
        if n is not None and f"{mod}.{n}" in MODULES:
            out.append(f"{mod}.{n}")
        elif mod in MODULES:
            out.append(mod)
    return out


def test_modules_and_functions_are_readable_sizes():
    """Functions stay under :data:`MAX_FUNCTION_LINES`. A module's size is reported, not refused:
    a boundary follows a concept, never a line count (the modules over :data:`MAX_MODULE_LINES`
    are printed with ``pytest -s``, for a maintainer to ask whether they hold two concepts)."""
    too_long, long_funcs = [], []
    for name, f in MODULES.items():
        n = len(f.read_text(encoding="utf-8").splitlines())
        if n > MAX_MODULE_LINES:
            too_long.append(f"{name}: {n} lines")
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    long_funcs.append(f"{name}.{node.name}: {length} lines")
    if too_long:
        print(f"modules over {MAX_MODULE_LINES} lines (a report, not a failure): " + "; ".join(sorted(too_long)))
    assert not long_funcs, long_funcs


def test_no_module_imports_another_modules_private_names():
    bad = []
    for name, f in MODULES.items():
        for mod, names, line in _imports(name, f):
            for n in names:
                if n.startswith("_") and not n.startswith("__") and mod != name:
                    bad.append(f"{name}:{line} imports {mod}.{n}")
    assert not bad, bad


def _allowed_upward(name, dep, in_function):
    """An upward import of :data:`UPWARD_INSIDE_FUNCTIONS`, inside a function."""
    layer_of = {i: p for i, layer in enumerate(LAYERS) for p in layer}
    pair = (layer_of.get(_layer(name)), layer_of.get(_layer(dep)))
    return in_function and pair in UPWARD_INSIDE_FUNCTIONS


def test_layers_import_only_downwards():
    bad = []
    for name, f in MODULES.items():
        lay = _layer(name)
        assert lay is not None, f"{name} is in no layer of tests/test_architecture.py (add it to LAYERS)"
        for mod, names, line, in_function in _imports(name, f, in_function=True):
            for dep in _resolve(mod, names):
                dl = _layer(dep)
                if dl is not None and dl > lay and not _allowed_upward(name, dep, in_function):
                    bad.append(f"{name}:{line} (layer {lay}) imports {dep} (layer {dl})")
    assert not bad, bad


def test_no_import_cycles():
    graph = defaultdict(set)
    for name, f in MODULES.items():
        for mod, names, _ in _imports(name, f):
            for dep in _resolve(mod, names):
                if dep != name and not name.startswith(dep + ".") and dep != "bayesdrag":
                    graph[name].add(dep)
    seen, cycles = set(), []

    def visit(n, path):
        if n in path:
            cycles.append(path[path.index(n):] + [n])
            return
        if n in seen:
            return
        seen.add(n)
        for m in sorted(graph[n]):
            visit(m, path + [n])

    for n in sorted(MODULES):
        visit(n, [])
    assert not cycles, [" -> ".join(c) for c in cycles[:5]]


@pytest.mark.parametrize("name", ["read_track", "read_round", "fit", "simulate", "FitResult", "diagnose",
                                  "DiagnosisResult", "plan", "PlanResult", "PlanOptions"])
def test_public_api_names(name):
    import bayesdrag

    assert name in bayesdrag.__all__
    assert getattr(bayesdrag, name) is not None


#: estimate/'s sub-layers, lowest first: the output-error model; what every problem is built from
#: (``build/``: start, launch priors, smoothing, basis, model size, wind layers, declared sources);
#: the three concepts built on them (the Scheme 1 recipe, what is claimed about Cd, Bayesian
#: sampling), which do not import each other; Scheme 2, which borrows the Scheme 1 start and the
#: quality gate
ESTIMATE_LAYERS = [["model"], ["build"], ["scheme1", "cd", "bayes"], ["scheme2"]]


def _estimate_part(mod):
    parts = mod.split(".")
    return parts[2] if len(parts) > 2 and parts[:2] == ["bayesdrag", "estimate"] else None


def test_estimate_sub_layers_import_only_downwards_and_siblings_stay_apart():
    level = {p: i for i, layer in enumerate(ESTIMATE_LAYERS) for p in layer}
    bad = []
    for name, f in MODULES.items():
        part = _estimate_part(name)
        if part is None:
            continue
        assert part in level, f"{name}: estimate/{part} is in no sub-layer of ESTIMATE_LAYERS"
        for mod, names, line in _imports(name, f):
            for dep in _resolve(mod, names):
                dp = _estimate_part(dep)
                if dp is None or dp == part:
                    continue
                if level[dp] >= level[part]:
                    bad.append(f"{name}:{line} (estimate/{part}) imports {dep} (estimate/{dp})")
    assert not bad, bad


def test_commands_call_the_pipeline_not_the_estimators():
    bad = [f"{name}:{line} imports {mod}" for name, f in MODULES.items() if name.startswith("bayesdrag.commands")
           for mod, _, line in _imports(name, f) if mod.startswith("bayesdrag.estimate")]
    assert not bad, bad


#: the effect library's names (bayesdrag.effects.EFFECTS), as literals
def _effect_names():
    from bayesdrag.effects import EFFECTS

    return set(EFFECTS)


#: modules that hold the effect concept (their literals of effect names are its own)
EFFECT_MODULES = ("bayesdrag.effects", "bayesdrag.effect_inputs", "bayesdrag.wind_layers")
#: literals of effect names compared or used as keys outside the effect concept
#: (:func:`effect_name_literals`): 175 at 697b642, 181 with the met file's stated error (its sds
#: filled by source stem) and the missing radar site's check (issue 44; two of them a met CSV's
#: column name ``temperature``), 155 with the nine effect-name tuples derived from the effects'
#: traits, 8 with the effects' one mapping, the radar effects' channels in effects/ and the rest
#: asked of effects/ (trait queries, or the effect's ``.name`` / ``.source``) (issue 50). The 8
#: left are homonyms in files another change owns: the round file's source stems
#: (``round.SYSTEMATIC_SOURCES``, the met file's stated sds, ``io.rounds``) and a met CSV's
#: column ``temperature`` (``io.met``). A ratchet: it may only fall.
EFFECT_NAME_LITERALS_MAX = 8


def effect_name_literals():
    """``[(module, line, name)]``: string literals equal to an effect's name that package code
    outside :data:`EFFECT_MODULES` *compares or uses as a key*: an operand of a comparison or a
    membership test (or an element of the tuple tested), a subscript's key, a dict literal's key,
    or an element of a tuple, list or set of two or more effect names (the effect-name tuples).
    Each one is code that tests an effect by its name instead of asking the effect. Run
    ``python3 -c "import test_architecture as t; print(len(t.effect_name_literals()))"`` from
    tests/unit for the count."""
    names = _effect_names()
    out = []
    for name, f in MODULES.items():
        if name.startswith(EFFECT_MODULES):
            continue
        tree = ast.parse(f.read_text(encoding="utf-8"))
        parent = {id(c): n for n in ast.walk(tree) for c in ast.iter_child_nodes(n)}

        def used_as_name(node):
            up = parent.get(id(node))
            if isinstance(up, ast.Compare):
                return True
            if isinstance(up, ast.Subscript) and up.slice is node:
                return True
            if isinstance(up, ast.Dict) and any(k is node for k in up.keys):
                return True
            if isinstance(up, (ast.Tuple, ast.List, ast.Set)):
                if isinstance(parent.get(id(up)), ast.Compare):
                    return True
                peers = [e for e in up.elts if isinstance(e, ast.Constant) and e.value in names]
                return len(peers) >= 2
            return False

        for n in ast.walk(tree):
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and n.value in names and used_as_name(n):
                out.append((name, n.lineno, n.value))
    return out


def test_effect_names_are_not_spread_as_literals():
    found = effect_name_literals()
    print(f"string literals of effect names outside the effect modules: {len(found)}")
    assert len(found) <= EFFECT_NAME_LITERALS_MAX, (
        f"{len(found)} literals of effect names outside {EFFECT_MODULES} (at most {EFFECT_NAME_LITERALS_MAX}): "
        f"ask the Effect for its traits instead of testing its name; new ones: {found[-5:]}")


def effect_name_collections():
    """``[(module, line)]``: tuples, lists and sets of two or more effect names written as
    literals in package code outside :data:`EFFECT_MODULES` (a set of effects is a query on their
    traits, :func:`bayesdrag.effects.effects_where`)."""
    names = _effect_names()
    out = []
    for name, f in MODULES.items():
        if name.startswith(EFFECT_MODULES):
            continue
        for n in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(n, (ast.Tuple, ast.List, ast.Set)):
                if sum(isinstance(e, ast.Constant) and e.value in names for e in n.elts) >= 2:
                    out.append((name, n.lineno))
    return out


def test_no_effect_name_tuple_outside_the_effects():
    found = effect_name_collections()
    assert not found, f"tuples of effect names outside {EFFECT_MODULES} (ask effects/ with a query instead): {found}"


#: the most modules the top level of bayesdrag/ holds, each a noun a user meets (docs/architecture.md);
#: the deprecated re-exports are not counted (their docstring starts "Deprecated", and each is
#: listed in docs/architecture.md with the release that removes it)
MAX_TOP_LEVEL_MODULES = 12


def _is_shim(path):
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    return doc.startswith("Deprecated")


def test_the_top_level_holds_few_modules():
    top = sorted(f.stem for f in PKG.glob("*.py") if not _is_shim(f))
    print(f"top-level modules ({len(top)}): {', '.join(top)}")
    assert len(top) <= MAX_TOP_LEVEL_MODULES, f"{len(top)} top-level modules (at most {MAX_TOP_LEVEL_MODULES}): {top}"


def test_every_shim_is_listed_as_deprecated_in_the_architecture_notes():
    notes = (PKG.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    shims = [f for f in PKG.rglob("*.py") if _is_shim(f)]
    missing = [str(f.relative_to(PKG.parent)) for f in shims
               if "`" + ".".join(f.relative_to(PKG.parent).with_suffix("").parts) + "`" not in notes]
    assert not missing, f"deprecated re-exports not listed in docs/architecture.md: {missing}"
