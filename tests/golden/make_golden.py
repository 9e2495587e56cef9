"""Write the golden regression files: what ``bayesdrag fit`` computes today on fixed inputs.

``tests/integration/test_golden.py`` compares every later version of the package with these
files, so that a change meant to move code (a reorganisation, a faster figure) is shown to change
nothing the fit computes. Run it only when a change is *meant* to change a result, in a commit of
its own that says what changed and why:

    python tests/golden/make_golden.py            # all cases
    python tests/golden/make_golden.py demo-ml    # one case

Cases (inputs kept under ``tests/golden/cases/<name>/`` so that the golden files do not depend on
another simulator's version):

* ``demo-ml`` - the shipped demo track and round (6-DOF truth, M101 table), ``mcmc=False``:
  the default Scheme 1 fit with AR(1) model-error noise chosen per channel and its floor.
* ``p40-g8-pos``, ``b42-g8-xv``, ``s130-g1-part`` - three robustness-suite tracks flown by
  py-ballisticcalc (``tests/acceptance/pbc_suite.py``): positions only without a table (a spline
  in Cd itself), a Doppler-like ``x, v`` bullet with its table, a partial 130 mm track (late
  lock-on, early loss) with its table. ``mcmc=False``.
* ``demo-bayes`` - the demo with sampling, ``seed=0``: compared within the Monte-Carlo standard
  error of the posterior (a move that changes the order of random draws may change the chain,
  not the posterior).
"""
from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
CASES = HERE / "cases"
EXPECTED = HERE / "expected"
#: robustness-suite cases copied into ``cases/`` (their generator needs py-ballisticcalc)
SUITE_CASES = ("p40-g8-pos", "b42-g8-xv", "s130-g1-part")
#: every golden case and the options of its fit
FITS = {
    "demo-ml": dict(mcmc=False),
    "p40-g8-pos": dict(mcmc=False),
    "b42-g8-xv": dict(mcmc=False),
    "s130-g1-part": dict(mcmc=False),
    "demo-bayes": dict(mcmc=True, seed=0),
}
#: fits that are not golden files: a deliberate change of the method, for the test to show it fails
PROBES = {
    "demo-ml-white": dict(mcmc=False, noise_model="white"),
}


def case_inputs(name):
    """(track path, round path) of a golden case."""
    folder = "demo" if name.startswith("demo") else name
    return CASES / folder / "track.csv", CASES / folder / "round.toml"


def copy_inputs():
    """Copy the demo's and the suite cases' inputs into ``cases/`` (once: they are fixed)."""
    from bayesdrag.commands.demo import demo_inputs

    demo = CASES / "demo"
    if not demo.exists():
        demo.mkdir(parents=True)
        track, rnd = demo_inputs()
        shutil.copy(track, demo / "track.csv")
        shutil.copy(rnd, demo / "round.toml")
        shutil.copy(Path(rnd).parent / "cd_m101.csv", demo / "cd_m101.csv")
    sys.path.insert(0, str(HERE.parent))
    from acceptance import pbc_suite

    for name in SUITE_CASES:
        dest = CASES / name
        if dest.exists():
            continue
        tmp = HERE / ".tmp"
        pbc_suite.generate(pbc_suite.case_by_name(name), tmp)
        dest.mkdir(parents=True)
        for f in ("track.csv", "round.toml", "ref.csv"):
            if (tmp / name / f).exists():
                shutil.copy(tmp / name / f, dest / f)
        shutil.rmtree(tmp)


def fit_case(name):
    """``result.json`` of a golden case as the current package computes it."""
    import bayesdrag

    track, rnd = case_inputs(name)
    res = bayesdrag.fit(bayesdrag.read_track(track), bayesdrag.read_round(rnd), **{**FITS, **PROBES}[name])
    return res.to_dict()


def fit_cases_loaded(names, root=None):
    """``result.json`` of the golden cases computed in a fresh process whose compiled code was
    loaded from numba's cache, as ``{name: dict}``.

    Why a fresh process: the kernel machine code numba compiles inside a process and the code it
    writes to (and later loads from) its cache differ in their last bits (fastmath contractions),
    enough to move the demo's ML fit by one iteration (8 vs 9, Cd ~1e-8 relative). Code loaded
    from the cache is the same whichever process compiled it, so the golden files are written,
    and compared, with loaded code: a process that had to compile anything is run once more.

    ``root``: the folder holding the ``bayesdrag`` package to run (default: the one imported
    here); ``tests/golden/identical.py`` runs another commit's.
    """
    import os
    import subprocess

    if root is None:
        import bayesdrag

        root = Path(bayesdrag.__file__).resolve().parents[1]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(root)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    for _ in range(2):   # without a kept cache (an unsafe cache folder) the second run compiles too
        out = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--print", *names], env=env,
                             capture_output=True, text=True, check=True)
        got = json.loads(out.stdout.splitlines()[-1])
        if not got.pop("_compiled"):
            break
    return got


def _print(names):
    try:
        from bayesdrag._runtime.numba_cache import compile_record
    except ImportError:   # a tree before the rename, fitted for tests/golden/identical.py
        from bayesdrag._runtime.numba_cache import compile_summary as compile_record

    out = {name: fit_case(name) for name in names}
    out["_compiled"] = compile_record()["compiled"]
    print(json.dumps(out))


def environment():
    """What the last bits of a fit depend on besides the package: the numerical libraries, the
    processor and the BLAS kernel chosen for it. The golden files hold the one they were
    written in (``expected/environment.json``)."""
    import os
    import platform

    import llvmlite
    import numba
    import numpy
    import scipy

    cpu = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        cpu = platform.processor()
    return {"python": platform.python_version(), "numpy": numpy.__version__, "scipy": scipy.__version__,
            "numba": numba.__version__, "llvmlite": llvmlite.__version__, "machine": platform.machine(),
            "cpu": cpu, "openblas_coretype": os.environ.get("OPENBLAS_CORETYPE", "")}


def main(names):
    copy_inputs()
    EXPECTED.mkdir(exist_ok=True)
    (EXPECTED / "environment.json").write_text(json.dumps(environment(), indent=1, sort_keys=True) + "\n")
    got = fit_cases_loaded(list(names or FITS))
    for name, d in got.items():
        (EXPECTED / f"{name}.json").write_text(json.dumps(d, indent=1, sort_keys=True) + "\n")
        print(f"wrote {EXPECTED / (name + '.json')}")


if __name__ == "__main__":
    if sys.argv[1:2] == ["--print"]:
        _print(sys.argv[2:])
    else:
        main(sys.argv[1:])
