"""Run the honesty suite (:mod:`acceptance.honesty_suite`) and print its table.

    python tests/acceptance/run_honesty.py [--small] [--case ID ...] [--json OUT] [--with-none] [--reseed K]

Columns: rows in the judged span, right (accuracy), determined, determined but wrong (the defect),
worst |z| of a wrong determined row, determined fraction of the span, quality gate, seconds, the
effects the fit added, and their size against the truth: the largest |z| (fitted - true, in the
parameter's sd) and whether every judged parameter lies within 3 sd ("-": none to judge;
"unsized": an sd over ten times the true size, which fails).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from acceptance import honesty_suite as hs  # noqa: E402


def _size(r):
    """The added effects' size column: worst |z| against the truth and within 3 sd or not."""
    if r.get("effect_size_ok") is None:
        return "  -" if r.get("effects_added") else ""
    worst = max(abs(q["z"]) for q in r["effect_size"])
    return f"  {worst:.1f} {'y' if r['effect_size_ok'] else 'n'}" + (" unsized" if r.get("effect_unsized") else "")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--small", action="store_true")
    ap.add_argument("--case", nargs="*")
    ap.add_argument("--json")
    ap.add_argument("--with-none", action="store_true", help="fit with with_effects='none' (no added effects)")
    ap.add_argument("--reseed", type=int, default=0, metavar="K",
                    help="judge the cases made anew (draw K >= 1: new seeds, elevations, effect sizes)")
    a = ap.parse_args(argv)
    cases = [hs.case_by_id(c) for c in a.case] if a.case else hs.all_cases(small=a.small)
    if a.reseed:
        cases = hs.reseeded(cases, a.reseed)
    opts = {"with_effects": "none"} if a.with_none else {}
    out = []
    print(f"{'case':28s} {'effect':12s} {'rows':>4s} {'right':>5s} {'det':>4s} {'WRONG':>5s} {'worst z':>7s} "
          f"{'det %':>6s} {'ok':>3s}  s   added  size (max |z|)")
    t_all = time.perf_counter()
    for c in cases:
        t0 = time.perf_counter()
        r = hs.run_case(c, **opts)
        r["seconds"] = round(time.perf_counter() - t0, 1)
        out.append(r)
        if "error" in r:
            print(f"{c.id:28s} {r['effect']:12s} ERROR {r['error'][:80]}")
            continue
        print(f"{c.id:28s} {r['effect']:12s} {r['rows']:4d} {r['right']:5d} {r['determined']:4d} "
              f"{r['determined_wrong']:5d} {r['worst_z_wrong']:7.1f} {100 * r['determined_fraction']:6.1f} "
              f"{'y' if r['quality_ok'] else 'n':>3s} {r['seconds']:5.1f} {','.join(r.get('effects_added') or [])}"
              f"{_size(r)}", flush=True)
    sized = [r for r in out if r.get("effect_size_ok") is not None]
    if sized:
        off = [r for r in sized if not r["effect_size_ok"]]
        print(f"added effects' size within {hs.EFFECT_TOL_SD:g} sd of the truth: {len(sized) - len(off)}/{len(sized)} "
              f"cases" + (" (not: " + ", ".join(
                  f"{r['id']} {q['name']} {q['value']:.4g} +- {q['sd']:.2g} for {q['truth']:.4g}"
                  for r in off for q in r["effect_size"]
                  if abs(q["z"]) > hs.EFFECT_TOL_SD or q["name"] in r.get("effect_unsized", ())) + ")" if off else ""))
    cond = [r for r in out if r.get("conditional") and "error" not in r]
    if cond:
        print(f"conditional on the stated air (left out of the totals): "
              + ", ".join(f"{r['id']} {r['determined_wrong']}/{r['determined']}" for r in cond))
    ok = [r for r in out if "error" not in r and not r.get("conditional")]
    bad = [r for r in ok if r["determined_wrong"]]
    print(f"\n{len(out)} cases, {sum('error' in r for r in out)} errors; cases with a wrong determined row: {len(bad)} "
          f"({', '.join(r['id'] for r in bad)}); determined rows wrong: "
          f"{sum(r['determined_wrong'] for r in ok)}/{sum(r['determined'] for r in ok)}; "
          f"rows right (accuracy): {sum(r['right'] for r in ok)}/{sum(r['rows'] for r in ok)}; "
          f"mean determined fraction {sum(r['determined_fraction'] for r in ok) / max(len(ok), 1):.2f}; "
          f"{time.perf_counter() - t_all:.0f} s")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
