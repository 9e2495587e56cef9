"""Where a diagnosis spends its fits (issue 45): every Levenberg-Marquardt fit of the model
check's diagnosis of a :mod:`check_cost` case, and each candidate's score drop beside its fitted
drop.

    python3 benchmarks/diagnosis_fits.py [--only NAME ...] [--json FILE]

For each case (``benchmarks/check_cost.py``'s ``CASES``), the diagnosis the check makes
(:func:`bayesdrag.pipeline.model_check.diagnosis_record`, warm: the second of two, in this
process) is run with :func:`bayesdrag.diagnosis.setup.fit_effects` wrapped, and prints:

* every fit: its effects, iterations, whether it converged, seconds, and the parameters that end
  at a bound (a fit whose optimum lies on a bound is where the clipped Levenberg-Marquardt steps
  crept for their whole budget);
* per candidate fitted alone from the baseline: the fitted chi2 drop, the *score* drop (the
  baseline's whitened residuals projected on the candidate's signature with the nuisance
  parameters projected out, :func:`bayesdrag.diagnosis.signatures.nuisance_basis`: a one-step
  Gauss-Newton prediction that costs no fit, since the signatures are made anyway), the test
  statistic and its threshold. Where the two drops agree, a screen on the score could dismiss the
  candidate without its fit; where the score falls far short (a table's shape beside a table of
  another shell) it could not.

The last line is one JSON object ``{case: {"fits": [...], "candidates": [...], "seconds": ...,
"fit_share": ..., "stuck_share": ...}}``: ``fit_share`` is the share of the diagnosis's time spent
in its fits, ``stuck_share`` the share of that fitting time in fits that stopped unconverged
(ratios within one run; the seconds are those of a shared 2-core machine).
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))


def _at_bounds(res, prob):
    """Names of the free parameters of a fit that end on one of their bounds."""
    th, lo, hi = np.asarray(res.theta, float), np.asarray(prob.lower, float), np.asarray(prob.upper, float)
    at = (th <= lo) | (th >= hi)
    return [n for n, a, f in zip(res.names, at, prob.free) if a and f]


def _score_drop(setup, base, Q):
    """The baseline's whitened residuals (launch priors appended) projected on the orthonormal
    signature basis ``Q`` [chi2]: the one-step drop of adding that effect."""
    from bayesdrag.diagnosis.signatures import nuisance_basis

    sw, _, _, n_pr = nuisance_basis(setup, base.theta)
    r = (np.stack([base.residuals[c] for c in setup.channels], -1) * sw).reshape(-1)
    pr = np.array([(p.mean - p.fn(base.theta)) / p.sd for p in setup.priors])[:n_pr]
    r = np.concatenate([r, np.pad(pr, (0, n_pr - pr.size))])
    return float(np.sum((Q.T @ r) ** 2)) if Q is not None and Q.shape[0] == r.size else None


def profile_case(name):
    """The fits and the candidates' drops of the check's diagnosis of case ``name``."""
    import check_cost as C
    import bayesdrag.diagnosis.candidates as CA
    import bayesdrag.diagnosis.core as CO
    import bayesdrag.diagnosis.setup as SU
    from bayesdrag.pipeline.model_check import diagnosis_record

    fits, calls = [], []
    orig_fit, orig_cand, orig_screen = SU.fit_effects, CO.fit_candidates, CO.screen_candidates

    def fit_effects(setup, effs, start, *a, **k):
        t0 = time.perf_counter()
        out = orig_fit(setup, effs, start, *a, **k)
        res, prob, _ = out
        fits.append({"effects": [e.name for e in effs], "iterations": int(res.iterations),
                     "converged": bool(res.converged), "seconds": round(time.perf_counter() - t0, 3),
                     "at_bounds": _at_bounds(res, prob)})
        return out

    def screen_candidates(setup, *a, **k):
        effs, sigs, skipped = orig_screen(setup, *a, **k)
        calls.append({"sigs": dict(sigs)})
        return effs, sigs, skipped

    def fit_candidates(setup, effs, base_fit, *a, **k):
        rows, got = orig_cand(setup, effs, base_fit, *a, **k)
        calls[-1].update(setup=setup, base=base_fit[0], rows=rows)
        return rows, got

    patched = [m for m in list(sys.modules.values())
               if getattr(m, "__name__", "").startswith("bayesdrag.diagnosis") and hasattr(m, "fit_effects")]
    try:
        for m in patched:
            m.fit_effects = fit_effects
        CO.fit_candidates, CO.screen_candidates = fit_candidates, screen_candidates
        with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            track, rnd = C.case_inputs(name, tmp)
            diagnosis_record(track, rnd, None)
            fits.clear()
            calls.clear()
            t0 = time.perf_counter()
            d = diagnosis_record(track, rnd, None)
            seconds = time.perf_counter() - t0
    finally:
        for m in patched:
            m.fit_effects = orig_fit
        CO.fit_candidates, CO.screen_candidates = orig_cand, orig_screen
    cands = []
    for k, c in enumerate(calls):
        for row in c.get("rows", []):
            q = c["sigs"].get(row["name"], (None, 0.0))[0]
            cands.append({"diagnosis": k, "name": row["name"], "fitted_drop": float(row["delta_chi2"]),
                          "score_drop": _score_drop(c["setup"], c["base"], q),
                          "statistic": float(row["test_statistic"]), "threshold": float(row["threshold"]),
                          "significant": bool(row["significant"])})
    total = sum(f["seconds"] for f in fits)
    stuck = sum(f["seconds"] for f in fits if not f["converged"])
    return {"fits": fits, "candidates": cands, "seconds": round(seconds, 3),
            "fit_share": round(total / seconds, 3) if seconds > 0 else None,
            "stuck_share": round(stuck / total, 3) if total > 0 else None,
            "verdict": d.get("record", {}).get("verdict")}


def main(argv=None):
    import check_cost as C

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", nargs="+", choices=C.CASES, help="these cases only")
    ap.add_argument("--json", type=Path, help="also write the JSON object here")
    a = ap.parse_args(argv)
    out = {}
    for name in a.only or C.CASES:
        r = out[name] = profile_case(name)
        fits = r["fits"]
        stuck = [f for f in fits if not f["converged"]]
        print(f"{name}: diagnosis {r['seconds']:.2f} s, verdict {r['verdict']}, {len(fits)} fits "
              f"({sum(f['seconds'] for f in fits):.2f} s), {len(stuck)} not converged "
              f"({sum(f['seconds'] for f in stuck):.2f} s), {sum(bool(f['at_bounds']) for f in fits)} ending at a bound")
        for f in fits:
            print(f"   {'+'.join(f['effects']) or '(baseline)':42s} {f['iterations']:3d} it "
                  f"{'   ' if f['converged'] else 'NC '} {f['seconds']:6.3f} s  {', '.join(f['at_bounds'])}")
        for c in r["candidates"]:
            sd = "-" if c["score_drop"] is None else f"{c['score_drop']:.4g}"
            print(f"   [{c['diagnosis']}] {c['name']:14s} fitted drop {c['fitted_drop']:11.4g}  score drop {sd:>11s}  "
                  f"statistic {c['statistic']:9.3g} / {c['threshold']:5.2f} {'significant' if c['significant'] else ''}")
    line = json.dumps(out)
    if a.json:
        a.json.write_text(line)
    print(line)


if __name__ == "__main__":
    main()
