"""Golden regression: what the fit computes on fixed inputs does not change by accident.

The expected ``result.json`` files were written by ``tests/golden/make_golden.py`` (its docstring
names the cases and says when to run it again). A change meant only to move or speed up code must
pass this test unchanged; a change meant to alter a result regenerates the files in a commit of its
own that says what changed and why.

Comparison (decisions): every number is compared by **its own uncertainty**, so that the test passes
on any processor and numerical library and fails for a change of the method.

* Why not bit for bit: the last bits of every compiled kernel step depend on the instruction set
  numba compiles for and on the BLAS kernel chosen for the processor, and the fit stops at its
  convergence test (parameter steps under 1e-3 Cramér-Rao sd) a few ulps elsewhere. Measured on
  the files' own cases, against the files written on an AMD EPYC (AVX2): an Intel Xeon with
  AVX-512 moved the demo's ``Y0`` by 8e-5 relative (4e-6 of its Cramér-Rao sd), the x channel's
  AR(1) ``q`` by 1.7e-4 relative and a row's model-error term by 3e-4 relative (1e-3 of the
  row's band); the same Xeon under ``NUMBA_CPU_NAME=generic`` (no AVX) moved those terms by as
  much again and nothing else by more than 6e-7 relative (docs/testing.md has the table and the
  commands). A bit-for-bit check is still what a refactor wants, on one machine, between two
  commits: ``tests/golden/identical.py`` does that.
* A number with an uncertainty in ``result.json`` is compared within :data:`K_SD` of it: a fit
  parameter by its Cramér-Rao sd (``ml.crb``), a Cd row's estimate and every term of its band
  (``crb_sd``, ``model_error_sd``, ...) by the row's ``band_sd``, a budget entry by the row's
  ``total_sd`` (``cross``, a variance, by twice ``K_SD`` times ``total_sd`` squared), a model-error
  part by its row's band, an AR(1) correlation by its restricted-likelihood sd
  (``(1 - rho) * sd_log_1m_rho``), an effect's fitted size by its Cramér-Rao sd.
  :data:`K_SD` = 1e-2: ten times the convergence test's step (an extra iteration on another
  processor moves a parameter by at most 1e-3 sd), a hundred times under what a change of the
  method moves (a 0.1 % change of the drag model's coefficients moves the demo's Cd rows by 0.5 to
  several band sd; ``test_golden_catches_*`` below show it).
* A number without one (a chi-square, a noise sd, the AR(1) variance ratio ``q``, a Mach grid point)
  is compared within :data:`REL_TOL` relative: 5e-3, thirty times the largest difference two
  instruction sets produced on such a number (``q``: 1.7e-4, a noise split the track leaves
  open), and below the 1 % that a changed noise model moves them (the test below).
* Integers that count a search's steps (``iterations``) may differ by one across environments
  (the convergence test above); every other integer, boolean and word exactly; the numbers inside
  text as printed (half a unit in the last digit, or :data:`REL_TOL`).
* Keys: every expected key must be present (new keys are allowed). Timing keys are not compared.
* The sampled case: the posterior summaries (``cd`` rows' ``mean``, ``q05``, ``q95``; ``posterior``
  means) within :data:`MCSE_K` combined Monte-Carlo standard errors; the ML part as above.
"""
from __future__ import annotations

import json
import math
import re
import sys
from pathlib import Path

import pytest

GOLDEN = Path(__file__).resolve().parents[1] / "golden"
sys.path.insert(0, str(GOLDEN))
import make_golden  # noqa: E402

#: fraction of a number's own sd that a difference between environments may reach [-]
K_SD = 1e-2
#: relative tolerance of a number that result.json gives no uncertainty for [-]
REL_TOL = 5e-3
#: absolute floor for such numbers near zero (correlations, shares: all of order 0.01-1 where they matter)
ABS_TOL = 1e-9
#: keys counting a search's steps: one more or fewer across environments
STEP_COUNT_KEYS = {"iterations"}
#: combined Monte-Carlo standard errors a posterior summary may move
MCSE_K = 4.0
#: MCSE of a 5 % / 95 % quantile in units of sd / sqrt(ESS) (Gaussian: sqrt(p (1 - p)) / phi(z_p))
QUANTILE_MCSE_FACTOR = 2.11
#: keys whose values are wall-clock times
TIMING_KEYS = {"seconds", "timing"}
#: posterior keys of a cd row compared statistically in the sampled case
POSTERIOR_ROW_KEYS = {"mean", "q05", "q25", "q50", "q75", "q95", "sd", "sd_over_crb", "total_sd_over_crb",
                      "model_error_widening", "sampled_q05", "sampled_q50", "sampled_q95", "sampled_sd"}
#: keys of the sampled case that depend on the chain itself (steps, acceptance, ESS): not compared
CHAIN_KEYS = {"mcmc", "posterior"}
#: per-row lists whose entries are compared by the row's band (their index is the cd row's)
ROW_PARTS = ("uncertainty_budget", "model_error")

_NUM = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def _get(doc, *keys):
    """``doc[k0][k1]...`` as a positive float, or None where any key is absent or not a number."""
    for k in keys:
        try:
            doc = doc[k]
        except (KeyError, IndexError, TypeError):
            return None
    return float(doc) if isinstance(doc, (int, float)) and not isinstance(doc, bool) and doc > 0 else None


def _row_band(doc, i):
    """The band sd of cd row ``i`` (its Cramér-Rao sd where the row has no band)."""
    return _get(doc, "cd", i, "band_sd") or _get(doc, "cd", i, "crb_sd")


def own_sd(path, doc):
    """The uncertainty ``result.json`` gives the number at ``path`` (a tuple of keys and
    indices into ``doc``, the expected document), or None where it gives none."""
    if len(path) == 3 and path[0] == "cd" and path[2] != "mach":
        return _row_band(doc, path[1])
    if len(path) == 4 and path[:2] == ("headline", "cd") and path[3] != "mach":
        return _get(doc, *path[:3], "band_sd")
    if len(path) == 3 and path[0] == "windows" and path[2] not in ("mach", "t_start", "t_end"):
        return _get(doc, "windows", path[1], "crb_sd")
    if path[0] == "uncertainty_budget" and isinstance(path[-1], int) and path[-2] != "mach":
        total = _get(doc, "uncertainty_budget", "total_sd", path[-1])
        if total is not None and path[-2] == "cross":
            return 2.0 * total * total      # a variance: d(total^2) = 2 total d(total)
        return total
    if path[:4] == ("ml", "quality", "model_error", "parts") and isinstance(path[-1], int):
        return _row_band(doc, path[-1])
    if len(path) == 3 and path[:2] == ("ml", "params"):
        return _get(doc, "ml", "crb", path[2])
    if len(path) == 5 and path[:3] == ("ml", "with_effects", "sizes") and path[4] == "value":
        return _get(doc, *path[:4], "crb_sd")
    if len(path) == 5 and path[:3] == ("ml", "noise", "ar") and path[4] == "rho":
        spread = _get(doc, *path[:4], "sd_log_1m_rho")
        rho = doc["ml"]["noise"]["ar"][path[3]]["rho"]
        return None if spread is None else (1.0 - rho) * spread
    return None


def _close(a, b, sd):
    if sd is not None:
        return abs(a - b) <= K_SD * sd
    return math.isclose(a, b, rel_tol=REL_TOL, abs_tol=ABS_TOL)


def _compare_text(path, got, want, errors):
    if _NUM.sub("#", got) != _NUM.sub("#", want):
        errors.append(f"{path}: text {got!r} != {want!r}")
        return
    for g, w in zip(_NUM.findall(got), _NUM.findall(want)):
        if g != w and abs(float(g) - float(w)) > 2.0 * _half_ulp(w) + REL_TOL * abs(float(w)) + ABS_TOL:
            errors.append(f"{path}: number {g} in {got!r} != {w} in {want!r}")


def _half_ulp(token):
    """Half a unit in the last printed digit of a number in text (rounding of an equal value)."""
    mant, _, exp = token.lower().partition("e")
    decimals = len(mant.split(".")[1]) if "." in mant else 0
    return 0.5 * 10.0 ** (int(exp or 0) - decimals)


def _dotted(keys):
    return "".join(f"[{k}]" if isinstance(k, int) else f".{k}" for k in keys)


def compare(got, want, skip=frozenset(), *, doc=None, keys=(), errors=None):
    """Differences between a result and its golden file (list of str; empty when equal), each
    number within its own uncertainty (:func:`own_sd`) or :data:`REL_TOL`."""
    errors = [] if errors is None else errors
    doc = want if doc is None else doc
    path = _dotted(keys)
    if isinstance(want, dict):
        if not isinstance(got, dict):
            errors.append(f"{path}: {type(got).__name__} instead of an object")
            return errors
        for k, v in want.items():
            if k in TIMING_KEYS or k in skip:
                continue
            if k not in got:
                errors.append(f"{path}.{k}: missing")
                continue
            compare(got[k], v, skip, doc=doc, keys=keys + (k,), errors=errors)
    elif isinstance(want, list):
        if not isinstance(got, list) or len(got) != len(want):
            errors.append(f"{path}: list of {len(got) if isinstance(got, list) else '?'} != {len(want)}")
            return errors
        for i, (g, w) in enumerate(zip(got, want)):
            compare(g, w, skip, doc=doc, keys=keys + (i,), errors=errors)
    elif isinstance(want, bool) or want is None:
        if got != want:
            errors.append(f"{path}: {got!r} != {want!r}")
    elif isinstance(want, int) and keys and keys[-1] in STEP_COUNT_KEYS:
        if not isinstance(got, int) or abs(got - want) > 1:
            errors.append(f"{path}: {got!r} != {want!r} (a search's steps: one more or fewer allowed)")
    elif isinstance(want, int):
        if got != want or isinstance(got, bool):
            errors.append(f"{path}: {got!r} != {want!r}")
    elif isinstance(want, float):
        if (not isinstance(got, (int, float)) or isinstance(got, bool)
                or not _close(float(got), want, own_sd(keys, doc))):
            errors.append(f"{path}: {got!r} != {want!r}")
    elif isinstance(want, str):
        if not isinstance(got, str):
            errors.append(f"{path}: {got!r} != {want!r}")
        else:
            _compare_text(path, got, want, errors)
    return errors


@pytest.fixture(scope="module")
def computed():
    """Every case's ``result.json`` from one fresh process running cache-loaded compiled code
    (:func:`make_golden.fit_cases_loaded`: code compiled inside a process differs from it in the
    last bits)."""
    return make_golden.fit_cases_loaded(list(make_golden.FITS) + list(make_golden.PROBES))


def _expected(name):
    return json.loads((make_golden.EXPECTED / f"{name}.json").read_text())


@pytest.mark.parametrize("name", [n for n, o in make_golden.FITS.items() if not o.get("mcmc")])
def test_ml_fit_matches_golden(name, computed):
    errors = compare(computed[name], _expected(name))
    assert not errors, f"{len(errors)} differences, first: " + "; ".join(errors[:8])


def _mcse(sd, ess, factor=1.0):
    return factor * sd / math.sqrt(ess)


def test_sampled_fit_matches_golden_within_mcse(computed):
    name = "demo-bayes"
    got, want = computed[name], _expected(name)
    errors = compare(got, want, skip=POSTERIOR_ROW_KEYS | CHAIN_KEYS)
    assert not errors, f"{len(errors)} differences, first: " + "; ".join(errors[:8])
    ess_want = min(v for k, v in want["posterior"]["ess_bulk"].items() if k.startswith("c"))
    ess_got = min(v for k, v in got["posterior"]["ess_bulk"].items() if k.startswith("c"))
    worst = 0.0
    for g, w in zip(got["cd"], want["cd"]):
        for key, factor in (("mean", 1.0), ("q05", QUANTILE_MCSE_FACTOR), ("q95", QUANTILE_MCSE_FACTOR)):
            se = math.hypot(_mcse(w["sd"], ess_want, factor), _mcse(g["sd"], ess_got, factor))
            z = abs(g[key] - w[key]) / se
            worst = max(worst, z)
            assert z <= MCSE_K, f"Mach {w['mach']}: {key} {g[key]:.6g} vs golden {w[key]:.6g} ({z:.1f} MCSE)"
    for p, m in want["posterior"]["mean"].items():
        sd = want["posterior"]["sd"][p]
        se = math.hypot(_mcse(sd, want["posterior"]["ess_bulk"][p]),
                        _mcse(got["posterior"]["sd"][p], got["posterior"]["ess_bulk"][p]))
        assert abs(got["posterior"]["mean"][p] - m) <= MCSE_K * se, f"posterior mean of {p}"


def test_golden_catches_a_changed_noise_model(computed):
    """The demo fitted with white noise on every channel (the golden file: AR(1) on all four) is
    a change of the method: the comparison reports it, Cd rows among the differences."""
    errors = compare(computed["demo-ml-white"], _expected("demo-ml"))
    assert any(e.startswith(".ml.noise.model") for e in errors), errors[:8]
    moved_rows = [e for e in errors if re.match(r"\.cd\[\d+\]\.(ml|crb_sd|band_sd):", e)]
    assert len(moved_rows) > 100, f"only {len(moved_rows)} Cd row values moved: {moved_rows[:4]}"


#: relative change of the drag model's coefficients the comparison must catch [-]
DRAG_CHANGE = 1e-3


def test_golden_catches_a_0p1_percent_change_of_the_drag_coefficients(computed):
    """Every drag coefficient of the demo's fit times 1.001: the drag model is the table times a
    spline correction linear in its coefficients, so each Cd row and the headline move by the
    same 0.1 %. The comparison must report every row (each moves by 0.5 to 20 of its band sd,
    50 to 2 000 times :data:`K_SD`) and every coefficient."""
    got = computed["demo-ml"]
    assert got["drag_model"] == "spline" and got["ml"]["smoothing"]["base"] == "table"
    changed = json.loads(json.dumps(got))
    coeffs = [k for k in changed["ml"]["params"] if re.fullmatch(r"c\d+", k)]
    for k in coeffs:
        changed["ml"]["params"][k] *= 1.0 + DRAG_CHANGE
    for row in changed["cd"]:
        row["ml"] *= 1.0 + DRAG_CHANGE
    for row in changed["headline"]["cd"]:
        row["cd"] *= 1.0 + DRAG_CHANGE
    errors = set(compare(changed, got))
    missed = [k for k in coeffs if not any(e.startswith(f".ml.params.{k}:") for e in errors)]
    assert not missed, f"a 0.1 % change of {missed} passed"
    missed = [i for i in range(len(got["cd"])) if not any(e.startswith(f".cd[{i}].ml:") for e in errors)]
    assert not missed, f"a 0.1 % change of Cd passed on rows {missed}"
    assert compare(got, got) == []


def test_own_sd_scales():
    """Each number with an uncertainty is compared by the right one."""
    doc = {"cd": [{"mach": 1.0, "ml": 0.3, "crb_sd": 0.001, "band_sd": 0.002}],
           "headline": {"cd": [{"mach": 1.0, "cd": 0.3, "band_sd": 0.004}]},
           "ml": {"params": {"X0": 1.0}, "crb": {"X0": 0.5},
                  "noise": {"ar": {"x": {"rho": 0.9, "q": 2.0, "sd_log_1m_rho": 0.3}}},
                  "quality": {"model_error": {"parts": {"noise": [1e-5]}}},
                  "with_effects": {"sizes": {"lift.factor": {"value": 1.0, "crb_sd": 0.01}}}},
           "uncertainty_budget": {"mach": [1.0], "total_sd": [0.003], "by_source": {"cross": [1e-7]}}}
    assert own_sd(("cd", 0, "ml"), doc) == 0.002
    assert own_sd(("cd", 0, "crb_sd"), doc) == 0.002
    assert own_sd(("cd", 0, "mach"), doc) is None
    assert own_sd(("headline", "cd", 0, "cd"), doc) == 0.004
    assert own_sd(("ml", "params", "X0"), doc) == 0.5
    assert own_sd(("ml", "noise", "ar", "x", "rho"), doc) == pytest.approx(0.1 * 0.3)
    assert own_sd(("ml", "noise", "ar", "x", "q"), doc) is None
    assert own_sd(("ml", "quality", "model_error", "parts", "noise", 0), doc) == 0.002
    assert own_sd(("ml", "with_effects", "sizes", "lift.factor", "value"), doc) == 0.01
    assert own_sd(("uncertainty_budget", "total_sd", 0), doc) == 0.003
    assert own_sd(("uncertainty_budget", "by_source", "cross", 0), doc) == pytest.approx(2 * 0.003 ** 2)
    assert own_sd(("uncertainty_budget", "mach", 0), doc) is None
    # within K_SD of its sd passes, beyond fails; a number without one by REL_TOL
    assert compare({**doc, "ml": {**doc["ml"], "params": {"X0": 1.0 + 0.9 * K_SD * 0.5}}}, doc) == []
    assert compare({**doc, "ml": {**doc["ml"], "params": {"X0": 1.0 + 1.1 * K_SD * 0.5}}}, doc)
    assert compare({**doc, "uncertainty_budget": {**doc["uncertainty_budget"], "mach": [1.0 + 2 * REL_TOL]}}, doc)
    assert compare({"iterations": 8}, {"iterations": 7}) == []
    assert compare({"iterations": 9}, {"iterations": 7})
    assert compare({"fits": 8}, {"fits": 7})


def test_compare_finds_a_changed_number_and_a_missing_key():
    want = {"a": 1.0, "b": {"c": [1, 2]}, "t": "Cd 0.3124 at Mach 1.20", "seconds": 3.0}
    assert compare({"a": 1.0, "b": {"c": [1, 2]}, "t": "Cd 0.3124 at Mach 1.20", "seconds": 9.0}, want) == []
    assert compare({"a": 1.0 + 2 * REL_TOL, "b": {"c": [1, 2]}, "t": "Cd 0.3124 at Mach 1.20"}, want)
    assert compare({"a": 1.0, "b": {}, "t": "Cd 0.3124 at Mach 1.20"}, want) == [".b.c: missing"]
    assert compare({"a": 1.0, "b": {"c": [1, 2]}, "t": "Cd 0.3125 at Mach 1.20"}, want) == []   # a flip
    assert compare({"a": 1.0, "b": {"c": [1, 2]}, "t": "Cd 0.3164 at Mach 1.20"}, want)
    assert compare({"a": 1.0, "b": {"c": [1, 2]}, "t": "Cd 0.3124 at Mach 1.23"}, want)
    assert compare({"a": 1.0, "b": {"c": [1, 2]}, "t": "Cd 0.3124 at Mach 1.20 or 3"}, want)


def test_identical_lists_every_difference_and_ignores_timing():
    import identical

    a = {"cd": [{"ml": 0.3}], "timing": {"ml": 1.0}, "x": 1}
    assert identical.differences(a, {"cd": [{"ml": 0.3}], "timing": {"ml": 2.0}, "x": 1}) == []
    assert identical.differences(a, {"cd": [{"ml": 0.1 + 0.2}], "x": 1}) == \
        [".cd[0].ml: 0.3 (this tree) != 0.30000000000000004"]
    assert identical.differences(a, {"cd": [{"ml": 0.3}], "x": 1.0}) == [".x: 1 (this tree) != 1.0"]
    assert identical.differences(a, {"cd": [{"ml": 0.3}]}) == [".x: only in this tree"]
