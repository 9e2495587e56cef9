"""Golden regression: what the fit computes on fixed inputs does not change by accident.

The expected ``result.json`` files were written by ``tests/golden/make_golden.py`` (its docstring
names the cases and says when to run it again). A change meant only to move or speed up code must
pass this test unchanged; a change meant to alter a result regenerates the files in a commit of its
own that says what changed and why.

Comparison (decisions):

* Numbers: within :data:`REL_TOL` relative (:data:`ABS_TOL` near zero). The fit is deterministic
  on one machine (one BLAS thread, one trajectory per kernel thread), so the files agree to
  rounding — in the environment they were written in (``expected/environment.json``: numpy,
  scipy, numba, llvmlite, processor, BLAS kernel). In another environment the last bits of every
  kernel step differ, the fit stops at its convergence test a few ulps elsewhere, and values that
  ``result.json`` rounds to 6 significant digits can flip their last digit: there the numbers are
  compared within :data:`CROSS_ENV_REL_TOL` (measured: worst 9.9e-6 relative, a 6-digit budget
  value, between the files' first environment and numpy 2.4.6, numba 0.68.1 on an AMD EPYC). A
  change of the method moves results by far more.
* Text: the words exactly, the numbers inside it as printed (half a unit in the last digit).
* Keys: every expected key must be present (new keys are allowed).
* Timing keys (``seconds``) are not compared.
* The sampled case: the posterior summaries (``cd`` rows' ``mean``, ``q05``, ``q95``; ``posterior``
  means) within :data:`MCSE_K` combined Monte-Carlo standard errors; the ML part exactly as above.
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

#: relative tolerance of a number in result.json
REL_TOL = 1e-9
#: absolute tolerance for numbers near zero (Cd, metres, seconds: all far above it where they matter)
ABS_TOL = 1e-12
#: relative tolerance when the environment differs from the one the files were written in
CROSS_ENV_REL_TOL = 3e-5
#: absolute tolerance then: initial positions near zero [m] move by the fit's convergence step
CROSS_ENV_ABS_TOL = 1e-6
#: combined Monte-Carlo standard errors a posterior summary may move
MCSE_K = 4.0
#: MCSE of a 5 % / 95 % quantile in units of sd / sqrt(ESS) (Gaussian: sqrt(p (1 - p)) / phi(z_p))
QUANTILE_MCSE_FACTOR = 2.11
#: keys whose values are wall-clock times
TIMING_KEYS = {"seconds", "timing"}
#: posterior keys compared statistically in the sampled case
POSTERIOR_ROW_KEYS = {"mean", "q05", "q25", "q50", "q75", "q95", "sd", "sd_over_crb"}
#: keys of the sampled case that depend on the chain itself (steps, acceptance, ESS): not compared
CHAIN_KEYS = {"mcmc", "posterior"}

_NUM = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def _same_environment():
    path = make_golden.EXPECTED / "environment.json"
    return path.exists() and json.loads(path.read_text()) == make_golden.environment()


if _same_environment():
    TOL = (REL_TOL, ABS_TOL)
else:
    TOL = (CROSS_ENV_REL_TOL, CROSS_ENV_ABS_TOL)


def _close(a, b):
    return math.isclose(a, b, rel_tol=TOL[0], abs_tol=TOL[1])


def _compare_text(path, got, want, errors):
    if _NUM.sub("#", got) != _NUM.sub("#", want):
        errors.append(f"{path}: text {got!r} != {want!r}")
        return
    for g, w in zip(_NUM.findall(got), _NUM.findall(want)):
        if g != w and abs(float(g) - float(w)) > _half_ulp(w) + TOL[0] * abs(float(w)) + TOL[1]:
            errors.append(f"{path}: number {g} in {got!r} != {w} in {want!r}")


def _half_ulp(token):
    """Half a unit in the last printed digit of a number in text (rounding of an equal value)."""
    mant, _, exp = token.lower().partition("e")
    decimals = len(mant.split(".")[1]) if "." in mant else 0
    return 0.5 * 10.0 ** (int(exp or 0) - decimals)


def compare(got, want, path="", errors=None, skip=frozenset()):
    """Differences between a result and its golden file (list of str; empty when equal)."""
    errors = [] if errors is None else errors
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
            compare(got[k], v, f"{path}.{k}", errors, skip)
    elif isinstance(want, list):
        if not isinstance(got, list) or len(got) != len(want):
            errors.append(f"{path}: list of {len(got) if isinstance(got, list) else '?'} != {len(want)}")
            return errors
        for i, (g, w) in enumerate(zip(got, want)):
            compare(g, w, f"{path}[{i}]", errors, skip)
    elif isinstance(want, bool) or want is None:
        if got != want:
            errors.append(f"{path}: {got!r} != {want!r}")
    elif isinstance(want, (int, float)):
        if not isinstance(got, (int, float)) or isinstance(got, bool) or not _close(float(got), float(want)):
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
    return make_golden.fit_cases_loaded(list(make_golden.FITS))


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


def test_compare_finds_a_changed_number_and_a_missing_key():
    want = {"a": 1.0, "b": {"c": [1, 2]}, "t": "Cd 0.3124 at Mach 1.20", "seconds": 3.0}
    assert compare({"a": 1.0, "b": {"c": [1, 2]}, "t": "Cd 0.3124 at Mach 1.20", "seconds": 9.0}, want) == []
    assert compare({"a": 1.0 + 1e-3, "b": {"c": [1, 2]}, "t": "Cd 0.3124 at Mach 1.20"}, want)
    assert compare({"a": 1.0, "b": {}, "t": "Cd 0.3124 at Mach 1.20"}, want) == [".b.c: missing"]
    assert compare({"a": 1.0, "b": {"c": [1, 2]}, "t": "Cd 0.3125 at Mach 1.20"}, want)
    assert compare({"a": 1.0, "b": {"c": [1, 2]}, "t": "Cd 0.3124 at Mach 1.21"}, want)
