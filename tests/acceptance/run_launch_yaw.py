"""Launch-yaw suite: flights launched yawing with no other effect, judged on the rows the
default fit marks determined (DESIGN "How a fit is judged", the honesty suite's rule).

    python3 tests/acceptance/run_launch_yaw.py [--only 6dof|pm] [--json FILE]

* ``6dof``, 32 flights: the 105 and 155 mm shells of the diagnosis suite flown by the 6-DOF
  simulator, launch yaw 0, 1.5, 3 and 5 deg, QE 12, 25, 35 and 45 (seeds 500, 501, ...).
* ``pm``, 36 flights: the point mass with the ``yaw_drag`` effect (``Cd (1 + 10 delta^2)``, the
  yaw decaying at ``decay``), delta0 0.05, 0.09, 0.12 and 0.16 rad, decay 0.3, 0.8 and 2 /s,
  QE 10, 30 and 45 (seeds 700, 701, ...).

White radar noise, each flight its own seed. About 5 minutes on 2 cores. Exit status 0 when no
flight claims a wrong row. Why: docs/fitting.md, "Launch yaw".
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from acceptance import cases as wc, honesty_suite as hs  # noqa: E402

SHELLS = ("105", "155")
YAWS_DEG = (0.0, 1.5, 3.0, 5.0)
QES_DEG = (12.0, 25.0, 35.0, 45.0)


PM_DELTA0 = (0.05, 0.09, 0.12, 0.16)
PM_DECAY = (0.3, 0.8, 2.0)
PM_QES_DEG = (10.0, 30.0, 45.0)


def flights(only=None):
    """The suite's cases (HonestyCase) in grid order."""
    out = []
    if only in (None, "6dof"):
        grid = [(s, y, q) for s in SHELLS for y in YAWS_DEG for q in QES_DEG]
        for i, (shell, yaw, qe) in enumerate(grid):
            c = wc.Case(f"yaw-{shell}-{yaw:g}-{qe:g}", "6dof", None, {}, qe, seed=500 + i, shell=shell,
                        initial_yaw_deg=yaw, expect="lift")
            out.append(hs.HonestyCase(f"w-{c.id}", "withheld", seed=c.seed, withheld=c))
    if only in (None, "pm"):
        grid = [(d, k, q) for d in PM_DELTA0 for k in PM_DECAY for q in PM_QES_DEG]
        for i, (d0, decay, qe) in enumerate(grid):
            c = wc.Case(f"pmyaw-{d0}-{decay}-{qe:g}", "pm", "yaw_drag", {"delta0": d0, "decay": decay}, qe,
                        seed=700 + i)
            out.append(hs.HonestyCase(f"w-{c.id}", "withheld", seed=c.seed, withheld=c))
    return out


def run(case):
    import bayesdrag

    track, rnd, truth = hs.make(case)
    d = bayesdrag.fit(track, rnd, mcmc=False).to_dict()
    j = hs.judge(d, truth)
    z = [abs(r["ml"] - float(truth["cd"](np.array([r["mach"]]))[0])) / r["band_sd"]
         for r in d["cd"] if r.get("determined")]
    return {"id": case.id, **{k: j[k] for k in ("rows", "determined", "determined_wrong", "worst_z_wrong")},
            "largest_z": max(z) if z else None,
            "fitted": (d["ml"].get("with_effects") or {}).get("fitted")}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=("6dof", "pm"), help="one of the two sets")
    ap.add_argument("--json", help="write every flight's row here")
    a = ap.parse_args(argv)
    rows = []
    for c in flights(a.only):
        r = run(c)
        rows.append(r)
        print(f"{r['id']:22s} determined {r['determined']:3d}/{r['rows']:3d}  wrong {r['determined_wrong']:2d}  "
              f"largest |z| {r['largest_z'] if r['largest_z'] is None else round(r['largest_z'], 2)}  "
              f"fitted {r['fitted']}", flush=True)
    wrong = sum(r["determined_wrong"] for r in rows)
    print(f"{len(rows)} flights, {sum(r['determined'] for r in rows)} rows determined, {wrong} wrong")
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))
    return 0 if wrong == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
