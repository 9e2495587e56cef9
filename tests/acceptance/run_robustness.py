"""Run the robustness validation suite (py-ballisticcalc tracks of many shells) and print a table of
converged / max error / max |err|/sd / coverage / time per track, then the pooled coverage and the
counts; optionally the issue's own failure list. Cases and rules: ``pbc_suite.py``.

    python tests/acceptance/run_robustness.py                     # 29 tracks + 3 withheld winds, with diagnose
    python tests/acceptance/run_robustness.py --skip-diagnose     # fits only
    python tests/acceptance/run_robustness.py --only b26-g7-flat,s155-m101 --poly2-split
    python tests/acceptance/run_robustness.py --issue-cases       # also the issue's failure list
    python tests/acceptance/run_robustness.py --fast              # the default-test subset
    python tests/acceptance/run_robustness.py --random-short 40   # random short tracks (8-24 samples)

Exit status 0 when the acceptance holds, 1 otherwise. ``--json FILE`` writes every row.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import pbc_suite as S  # noqa: E402

_FOLDER = None


def _init(folder):
    global _FOLDER
    _FOLDER = folder
    S.warm_up(folder)


def _job(spec):
    kind, name, drag, diagnose, subproc = spec
    c = S.case_by_name(name)
    if kind == "issue":
        row = S.run_issue_case(c, _FOLDER, subprocess_mode=subproc)
        if diagnose:
            row.update(S.run_diagnose_case(c, S.generate(c, _FOLDER), Path(_FOLDER) / c.name / "diag", subproc))
            row["pass"] = row["pass"] and row["diag_pass"]
        return row
    return S.run_case(c, _FOLDER, drag=drag, diagnose=diagnose, subprocess_mode=subproc)


def _run(specs, folder, jobs):
    if jobs <= 1:
        _init(folder)
        out = []
        for sp in specs:
            r = _job(sp)
            print(f"  {r['case']:<20} {r.get('drag', ''):<12} exit {r['exit']} {r['time_s']:5.1f} s "
                  f"{'PASS' if r.get('pass') else 'FAIL'}", file=sys.stderr, flush=True)
            out.append(r)
        return out
    with ProcessPoolExecutor(jobs, mp_context=get_context("spawn"), initializer=_init,
                             initargs=(folder,)) as ex:
        return list(ex.map(_job, specs))


def _issue_table(rows):
    head = (f"{'issue case':<20} {'expect':<16} {'exit':>4} {'conv':>4} {'maxerr%':>8} {'max|e|/sd':>9} "
            f"{'cover%':>6} {'time s':>6} {'result':<6} note / stderr")
    lines = ["issue failure list", head, "-" * len(head)]
    for r in rows:
        conv = {True: "yes", False: "no", None: "-"}[r.get("converged")]
        tail = r["stderr_tail"] if r["exit"] != 0 else ""
        extra = ""
        if r.get("diag_exit") is not None:
            extra = f" | diagnose verdict {r.get('diag_verdict')} ({'ok' if r.get('diag_pass') else 'BAD'})"
        if r.get("time_conflict_reported") is not None:
            extra += f" | time-origin conflict reported: {r['time_conflict_reported']}"
        lines.append(f"{r['case']:<20} {r['expect']:<16} {r['exit']:>4} {conv:>4} "
                     f"{S._f(r.get('max_err_pct'), '.2f', 8)} {S._f(r.get('max_z'), '.1f', 9)} "
                     f"{S._f(None if r.get('coverage') is None else 100 * r['coverage'], '.0f', 6)} "
                     f"{r['time_s']:>6.1f} {'PASS' if r['pass'] else 'FAIL':<6} {r['note']}"
                     f"{' | ' + tail[:150] if tail else ''}{extra}")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", default=None, help="comma-separated case names")
    ap.add_argument("--fast", action="store_true", help="only the default-test subset")
    ap.add_argument("--skip-diagnose", action="store_true")
    ap.add_argument("--poly2-split", action="store_true", help="also fit every case with --drag poly2-split")
    ap.add_argument("--issue-cases", action="store_true", help="also run the issue's own failure list")
    ap.add_argument("--random", type=int, default=0, metavar="N",
                    help="run N random cases (pbc_suite.random_cases) instead of the fixed suite")
    ap.add_argument("--random-short", type=int, default=0, metavar="N",
                    help="run N random short tracks of 8-24 samples (pbc_suite.random_short_cases)")
    ap.add_argument("--random-seed", type=int, default=0, help="seed of the random cases (default 0)")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    ap.add_argument("--out", default=None, help="folder for the generated tracks and fit outputs "
                                                "(default: <tmp>/bayesdrag-robustness)")
    ap.add_argument("--json", default=None, help="write all rows to this JSON file")
    ap.add_argument("--subprocess", action="store_true", help="run the real command line (cold) per case")
    ap.add_argument("--stock-air", action="store_true",
                    help="fly the tracks in py-ballisticcalc's stock air (real-gas sea-level density +0.043 %%, "
                         "30-ft gun-level fast path) instead of the round's ICAO air (see pbc_suite.py)")
    a = ap.parse_args(argv)
    if a.stock_air:  # read by pbc_suite at import, also in spawned workers
        os.environ["BAYESDRAG_SUITE_STOCK_AIR"] = "1"
        S.PBC_OPTIONS.update(exact_atmosphere=False, match_density=False)
    folder = Path(a.out or Path(tempfile.gettempdir()) / "bayesdrag-robustness")
    folder.mkdir(parents=True, exist_ok=True)
    cases = (S.random_cases(a.random, a.random_seed) if a.random else
             S.random_short_cases(a.random_short, a.random_seed) if a.random_short else S.ALL_CASES)
    issue = list(S.ISSUE_CASES) if a.issue_cases else []
    if a.fast:
        cases = [c for c in cases if c.name in S.FAST]
    if a.only:
        names = [n.strip() for n in a.only.split(",") if n.strip()]
        for n in names:
            S.case_by_name(n)  # unknown names fail loudly
        cases = [c for c in S.ALL_CASES if c.name in names]
        issue = [c for c in S.ISSUE_CASES if c.name in names]

    t0 = time.perf_counter()
    for c in cases + issue:
        S.generate(c, folder)
    t_gen = time.perf_counter() - t0
    print(f"generated {len(cases) + len(issue)} tracks in {t_gen:.1f} s under {folder}", file=sys.stderr)

    specs = [("suite", c.name, None, not a.skip_diagnose, a.subprocess) for c in cases]
    if a.poly2_split:
        specs += [("suite", c.name, "poly2-split", False, a.subprocess) for c in cases if not c.withheld]
    specs += [("issue", c.name, None, (not a.skip_diagnose) and c.name == S.ISSUE_DIAGNOSE, a.subprocess)
              for c in issue]
    t1 = time.perf_counter()
    rows = _run(specs, str(folder), a.jobs)
    t_run = time.perf_counter() - t1
    suite = [r for sp, r in zip(specs, rows) if sp[0] == "suite" and sp[2] is None]
    poly2 = [r for sp, r in zip(specs, rows) if sp[0] == "suite" and sp[2] == "poly2-split"]
    issue_rows = [r for sp, r in zip(specs, rows) if sp[0] == "issue"]

    if suite:
        print(S.format_table(suite, "robustness suite: bayesdrag fit --no-mcmc (default drag)"))
        notes = S.failure_notes(suite)
        if notes:
            print("failures:")
            print("\n".join(notes))
    if poly2:
        print()
        print(S.format_table(poly2, "robustness suite: bayesdrag fit --no-mcmc --drag poly2-split "
                                    "(followable: judged like the spline; else on reporting its misfit)"))
        for r in poly2:
            if not r.get("poly2_followable"):
                r.setdefault("reports_misfit", None)
        print("poly2-split followable cases: " + (", ".join(r["case"] for r in poly2 if r["poly2_followable"])
                                                  or "none"))
        notes = S.failure_notes(poly2)
        if notes:
            print("failures:")
            print("\n".join(notes))
    if issue_rows:
        print()
        print(_issue_table(issue_rows))
    s = S.summarise(suite, poly2, issue_rows)
    s.update(generation_s=round(t_gen, 1), suite_s=round(t_run, 1))
    print()
    if suite:
        cov = s["pooled_coverage"]
        print(f"cases {s['n_cases']} (+{s['n_withheld']} withheld wind): fit PASS {s['fit_pass']}/{s['n_cases']}, "
              f"converged {s['converged']}/{s['n_cases']}, within {S.TIME_LIMIT_S:g} s "
              f"{s['within_time']}/{s['n_cases']}; pooled 90 % band coverage "
              f"{'-' if cov is None else f'{100 * cov:.1f} %'} ({s['covered_points']}/{s['grid_points']} grid "
              f"points, need >= {100 * S.COVERAGE_MIN:.0f} %); diagnose {s['diag_pass']}/{s['diag_run']} ok; "
              f"tables missing: {s['missing_tables'] or 'none'}")
    if poly2:
        pc = s["poly2_pooled_coverage_followable"]
        print(f"poly2-split: PASS {s['poly2_pass']}/{s['poly2_cases']} ({s['poly2_followable']} followable; "
              f"their pooled coverage {'-' if pc is None else f'{100 * pc:.1f} %'})")
    if issue_rows:
        print(f"issue failure list: PASS {s['issue_pass']}/{s['issue_cases']}")
    print(f"generation {t_gen:.1f} s, suite {t_run:.1f} s; acceptance {'MET' if s['accepted'] else 'NOT met'}")
    if a.json:
        Path(a.json).write_text(json.dumps({"summary": s, "suite": suite, "poly2_split": poly2,
                                            "issue": issue_rows}, indent=1, default=str))
    print(json.dumps(s, default=str))
    return 0 if s["accepted"] else 1


if __name__ == "__main__":
    sys.exit(main())
