"""Monte-Carlo coverage of the *total* Cd band when the air is known only roughly.

Each replicate flies a py-ballisticcalc track (an independent simulator,
``tests/support/pbc_reference.py``) in air that differs from the round's nominal ICAO air by a
density ratio drawn from N(1, DENSITY_SD) and a temperature offset drawn from
N(0, TEMPERATURE_SD) K; the round declares ``density_sd`` and ``temperature_sd`` with those
values and no firing table. A density ratio is flown as the table times the ratio (in a point
mass the drag sees only the product rho Cd; the truth Cd stays the table). The fit estimates the
two sources as nuisance parameters (``bayesdrag.estimate.build.sources``); the ML total band is
``ML +- 1.645 crb_sd`` (the joint Cramér-Rao bound, sources included) and the posterior's is
its 5-95 % interval. At ``N_MACH`` Mach values inside each track's flown span the study
records whether the bands hold the truth. The density error is common to every Mach point, so
replicates, not grid points, are the unit: coverage is reported per Mach value and pooled, with
its binomial standard error.

    python3 benchmarks/total_uncertainty.py --replicates 300 --posterior 50 [--seed 0]

Sequential (the machine is shared). The last line is JSON.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

DENSITY_SD = 0.002
TEMPERATURE_SD = 0.5
#: Mach values per track where the band is checked (quantiles of its flown span)
N_MACH = 5
#: shells: (table, mass [kg], diameter [m], v0 [m/s], QE [deg], dt [s], position noise [m])
SHELLS = (("G7", 15.0, 0.105, 700.0, 30.0, 0.05, 1.0),
          ("G1", 33.4, 0.130, 810.0, 20.0, 0.05, 1.0))


def replicate(k, rng, posterior, walkers=None):
    from acceptance.pbc_suite import table, truth_cd
    from support.pbc_reference import pbc_trajectory

    from bayesdrag.pipeline import fit
    from bayesdrag.round import Launch, Projectile, Radar, Round, Systematics
    from bayesdrag.track import RadarTrack

    name, mass, diam, v0, qe, dt, pos_sd = SHELLS[k % len(SHELLS)]
    ratio = 1.0 + DENSITY_SD * rng.standard_normal()
    dT = TEMPERATURE_SD * rng.standard_normal()
    M, C = table(name)
    o = pbc_trajectory(M, C * ratio, mass, diam, v0, qe, temperature_offset=dT,
                       exact_atmosphere=True, dense_table=False, match_density=True)
    from scipy.interpolate import CubicSpline

    spl = CubicSpline(o["t"], np.column_stack([o["x"], o["y"], o["z"], o["v"]]), axis=0)
    t = np.arange(0.0, float(o["t"][-1]) - 1e-9, dt)
    S = spl(t)
    sd = {"x": pos_sd, "y": pos_sd, "z": pos_sd, "v": 0.1 * pos_sd}
    ch = {c: S[:, j] + sd[c] * rng.standard_normal(t.size) for j, c in enumerate("xyzv")}
    track = RadarTrack(t, ch, {}, source=f"replicate {k} ({name})")
    rnd = Round(Projectile(mass=mass, diameter=diam, name=f"{name} shell"),
                Launch(velocity=v0, elevation_deg=qe), radar=Radar(sigma=sd),
                systematics=Systematics(density=DENSITY_SD, temperature=TEMPERATURE_SD))
    kw = {"walkers": walkers, "max_steps": 3000} if (posterior and walkers) else {}
    res = fit(track, rnd, mcmc=posterior, seed=int(rng.integers(2**31)), **kw)
    rows = res.record["cd"]
    mach = np.array([r["mach"] for r in rows])
    det = res.record["ml"]["mach_range_determined"] or [mach.min(), mach.max()]
    qs = np.linspace(0.1, 0.9, N_MACH)
    pick = [int(np.argmin(np.abs(mach - (det[0] + q * (det[1] - det[0]))))) for q in qs]
    out = {"shell": name, "ratio": ratio, "dT": dT, "ml": [], "post": []}
    if posterior:
        m = res.record["mcmc"]
        out["mcmc"] = {"converged": bool(m.get("converged")), "steps": m.get("steps"),
                       "seconds": m.get("seconds"), "acceptance": m.get("acceptance"),
                       "message": m.get("message")}
    for i in pick:
        r = rows[i]
        truth = float(truth_cd(name, r["mach"]))
        out["ml"].append(bool(abs(r["ml"] - truth) <= 1.645 * r["crb_sd"]))
        if posterior:
            out["post"].append(bool(r["q05"] <= truth <= r["q95"]))
    b = res.record.get("uncertainty_budget")
    if b:
        out["share_density"] = float(np.median(np.array(b["by_source"]["density"]) / np.array(b["total_sd"])))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicates", type=int, default=300, help="ML replicates (>= 300 for the acceptance)")
    ap.add_argument("--posterior", type=int, default=50, help="how many of them also sample the posterior")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--walkers", type=int, default=128,
                    help="emcee walkers of the posterior replicates (128: ~5x the ESS per trajectory of 16 on "
                         "these posteriors, see docs/bayes.md)")
    a = ap.parse_args(argv)
    rng = np.random.default_rng(a.seed)
    recs = []
    t0 = time.perf_counter()
    for k in range(a.replicates):
        recs.append(replicate(k, rng, k < a.posterior, a.walkers))
        if "mcmc" in recs[-1]:
            print(f"replicate {k}: posterior {recs[-1]['post']} {recs[-1]['mcmc']}", flush=True)
        if (k + 1) % 10 == 0:
            ml = np.mean([x for r in recs for x in r["ml"]])
            print(f"{k + 1} replicates, ML total band coverage {ml:.3f}, {time.perf_counter() - t0:.0f} s",
                  flush=True)

    def cov(key):
        X = np.array([r[key] for r in recs if r[key]], float)
        if X.size == 0:
            return None
        p = X.mean()
        n = X.shape[0]
        return {"pooled": float(p), "per_mach": [float(v) for v in X.mean(axis=0)], "replicates": int(n),
                "se": float(math.sqrt(p * (1 - p) / n))}

    conv = [r["mcmc"]["converged"] for r in recs if "mcmc" in r]
    out = {"density_sd": DENSITY_SD, "temperature_sd": TEMPERATURE_SD, "ml_total": cov("ml"),
           "posterior_converged": f"{sum(conv)}/{len(conv)}",
           "posterior_total": cov("post"), "seconds": round(time.perf_counter() - t0, 1)}
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
