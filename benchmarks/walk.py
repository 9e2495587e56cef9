"""The walk of one track: how many folder boundaries the default fit crosses, and how often it
climbs back up a layer (issues 46 and 50 measure the house by it).

    python3 benchmarks/walk.py [--json FILE]

A trace of ``bayesdrag.fit`` on the shipped demo track and round with ``mcmc=False`` (the model
check included, run in this process), recorded with :func:`sys.setprofile`: every call from one
bayesdrag function to another. Counted over the *distinct* caller -> callee folder pairs (a
folder is a module's package: ``bayesdrag/estimate/scheme1`` for
``bayesdrag.estimate.scheme1.fit``; the top-level modules share ``bayesdrag``):

* **crossings**: pairs whose two folders differ;
* **climbs**: crossings into a folder of a *higher* layer than the caller's (the layers of
  ``tests/unit/test_architecture.py``, lowest first): a call that goes back up, through a
  callback or a function handed down, where the import graph only goes down.

Counting distinct pairs, not calls, makes the number a property of the code's shape, not of how
many iterations the fit took. The last line is a JSON object ``{"crossings": ..., "climbs": ...,
"pairs": [...]}``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "unit"))


def layers():
    """The architecture test's layers, lowest first (module-name prefixes)."""
    import test_architecture

    return test_architecture.LAYERS


def layer_of(module, table):
    """Index of the layer holding ``module`` (the longest matching prefix), or None."""
    best, depth = None, -1
    for i, names in enumerate(table):
        for n in names:
            if (module == n or module.startswith(n + ".")) and len(n) > depth:
                best, depth = i, len(n)
    return best


def folder_of(module, is_package):
    """The package a module lives in (a package's ``__init__`` lives in the package itself)."""
    return module if is_package else module.rpartition(".")[0]


def trace_fit():
    """Distinct (caller module, callee module) pairs of bayesdrag functions in one demo fit."""
    import bayesdrag
    from bayesdrag.commands.demo import demo_inputs

    track_path, round_path = demo_inputs()
    track, rnd = bayesdrag.read_track(track_path), bayesdrag.read_round(round_path)
    pairs = set()

    def profile(frame, event, arg):
        if event != "call":
            return
        callee = frame.f_globals.get("__name__", "")
        caller_frame = frame.f_back
        if caller_frame is None or not callee.startswith("bayesdrag"):
            return
        caller = caller_frame.f_globals.get("__name__", "")
        if caller.startswith("bayesdrag") and caller != callee:
            pairs.add((caller, callee))

    import threading

    # a second live thread keeps the model check's diagnosis in this process (bayesdrag forks a
    # helper only when its thread is the process's only one), where the profile sees it
    stop = threading.Event()
    idle = threading.Thread(target=stop.wait, daemon=True)
    idle.start()
    sys.setprofile(profile)
    try:
        bayesdrag.fit(track, rnd, mcmc=False)
    finally:
        sys.setprofile(None)
        stop.set()
    return pairs


def count(pairs):
    """(crossings, climbs, folder pairs) of the traced module pairs."""
    table = layers()
    packages = {name for name, mod in sys.modules.items()
                if name.startswith("bayesdrag") and hasattr(mod, "__path__")}
    folder_pairs, climbs = set(), set()
    for a, b in pairs:
        fa, fb = folder_of(a, a in packages), folder_of(b, b in packages)
        if fa == fb:
            continue
        folder_pairs.add((fa, fb))
        la, lb = layer_of(a, table), layer_of(b, table)
        if la is not None and lb is not None and lb > la:
            climbs.add((fa, fb))
    return len(folder_pairs), len(climbs), sorted(folder_pairs), sorted(climbs)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    n_cross, n_climb, folder_pairs, climbs = count(trace_fit())
    for a, b in folder_pairs:
        print(f"{'climb ' if (a, b) in climbs else '      '}{a} -> {b}")
    out = {"crossings": n_cross, "climbs": n_climb, "pairs": [list(p) for p in folder_pairs],
           "climb_pairs": [list(p) for p in climbs]}
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    print(json.dumps({"crossings": n_cross, "climbs": n_climb}))


if __name__ == "__main__":
    main()
