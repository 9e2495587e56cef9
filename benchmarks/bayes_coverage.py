"""Coverage study of the Bayesian layer (issue 5): do the 90 % intervals hold the truth 90 % of
the time?

Each replicate simulates a point-mass track of the 155 mm shell (818 m/s, QE 15 deg, first
``--duration`` s, Mach 2.4 -> ~1.6 by default) whose true drag is a cubic spline that *is* in
the fitted model (the spline on the same knots fitted to M101: no representation error, so the
study measures the inference, not the model), adds white noise (1 m, 0.3 m/s), fits it by ML
(explicit knots, unpenalised) and samples the posterior (default settings). For Cd at three
Mach numbers it records whether the posterior 5-95 % interval and the Gaussian CRB interval
``ML +- 1.645 CRB sd`` hold the true Cd. Coverage ``p`` is reported with its binomial standard
error ``sqrt(p (1 - p) / n)``.

    python3 benchmarks/bayes_coverage.py --replicates 200 [--write-docs]

Sequential on purpose (the machine is shared); ~3-6 s per replicate. The last line is JSON.
``--write-docs`` replaces the table between the coverage markers in docs/bayes.md.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

MACH = (1.8, 2.0, 2.2)
SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
KNOTS = (1.5, 1.7, 1.9, 2.1, 2.3, 2.45)


def truth_model():
    from bayesdrag.io.drag_tables import load_m101
    from bayesdrag.drag import make_drag_model

    m101 = load_m101()
    dm = make_drag_model("spline", knots=KNOTS, mach_range=(KNOTS[0], KNOTS[-1]))
    m = np.linspace(KNOTS[0], KNOTS[-1], 400)
    c, *_ = np.linalg.lstsq(dm.jacobian(m), m101.value(m), rcond=None)
    return dm, c, m101


def replicate(i, dm, c_true, m101, duration, seed0=1000):
    from bayesdrag.dynamics.pointmass import PointMassModel
    from bayesdrag.dynamics.trajectory import initial_state
    from bayesdrag.estimate.bayes.posterior import LogPosterior
    from bayesdrag.estimate.bayes.draws import cd_draws
    from bayesdrag.estimate.bayes.sampler import sample_posterior
    from bayesdrag.estimate.cd.table import cd_table
    from bayesdrag.estimate.scheme1.fit import fit_scheme1
    from bayesdrag.synthetic import add_noise
    from bayesdrag.round import Launch, Projectile, Radar, Round
    from bayesdrag.track import RadarTrack

    rng = np.random.default_rng(seed0 + i)
    t = np.arange(0.0, duration + 1e-9, 0.027)
    tr = PointMassModel(42.6, 0.155, dm).simulate(c_true, initial_state(818.0, 15.0), t)
    track = add_noise(RadarTrack(t, {ch: tr.channel(ch) for ch in "xyzv"}, {}), SIGMA, rng)
    rnd = Round(Projectile("155", 42.6, 0.155, m101, None), Launch(15.0, 818.0), radar=Radar(dict(SIGMA)),
                path="coverage.toml")
    f1 = fit_scheme1(track, rnd, drag="spline", knots=KNOTS)
    res, prob = f1.ml, f1.problem
    if not res.success:
        return None
    post = LogPosterior(prob, res)
    b = sample_posterior(post, seed=seed0 + i, max_steps=5000)
    m = np.array(MACH)
    cd = cd_draws(b, prob.model.drag, m, prob.P).reshape(-1, m.size)
    q05, q95 = np.quantile(cd, [0.05, 0.95], axis=0)
    rows = cd_table(res, prob.model.drag, m)
    ml = np.array([r["ml"] for r in rows])
    sd = np.array([r["crb_sd"] for r in rows])
    true = dm.jacobian(m) @ c_true
    return {"bayes": ((q05 <= true) & (true <= q95)).tolist(),
            "crb": (np.abs(ml - true) <= 1.645 * sd).tolist(),
            "width_ratio": ((q95 - q05) / (2 * 1.645 * sd)).tolist(),
            "converged": b.converged, "steps": b.steps, "rhat_max": float(b.convergence["r_hat"].max())}


def table(stats, n):
    lines = ["| Mach | posterior 90 % interval | CRB-Gaussian 90 % interval | width posterior / CRB |",
             "|---|---|---|---|"]
    for k, m in enumerate(MACH):
        pb, pc = stats["bayes"][k], stats["crb"][k]
        eb, ec = math.sqrt(pb * (1 - pb) / n), math.sqrt(pc * (1 - pc) / n)
        lines.append(f"| {m:.1f} | {100 * pb:.1f} % ± {100 * eb:.1f} | {100 * pc:.1f} % ± {100 * ec:.1f} | "
                     f"{stats['width_ratio'][k]:.3f} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--replicates", type=int, default=200)
    ap.add_argument("--duration", type=float, default=8.0, help="track length [s] (default 8)")
    ap.add_argument("--write-docs", action="store_true", help="put the table into docs/bayes.md")
    a = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    dm, c_true, m101 = truth_model()
    out = []
    t0 = time.perf_counter()
    for i in range(a.replicates):
        r = replicate(i, dm, c_true, m101, a.duration)
        if r is not None:
            out.append(r)
        if (i + 1) % 10 == 0:
            print(f"{i + 1} replicates, {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    n = len(out)
    stats = {k: np.mean([r[k] for r in out], axis=0).tolist() for k in ("bayes", "crb", "width_ratio")}
    tab = table(stats, n)
    print(tab)
    summary = {"replicates": n, "failed_fits": a.replicates - n, "mach": list(MACH),
               "coverage_posterior_90": stats["bayes"], "coverage_crb_90": stats["crb"],
               "binomial_se": [math.sqrt(p * (1 - p) / n) for p in stats["bayes"]],
               "width_ratio_posterior_over_crb": stats["width_ratio"],
               "converged_share": float(np.mean([r["converged"] for r in out])),
               "median_steps": float(np.median([r["steps"] for r in out])),
               "seconds": round(time.perf_counter() - t0, 1)}
    if a.write_docs:
        doc = ROOT / "docs" / "bayes.md"
        text = doc.read_text()
        a0, a1 = "<!-- coverage-table -->", "<!-- /coverage-table -->"
        if a0 in text and a1 in text:
            head, rest = text.split(a0, 1)
            _, tail = rest.split(a1, 1)
            body = (f"\n{n} replicates (`python3 benchmarks/bayes_coverage.py --replicates {a.replicates} "
                    f"--write-docs`, {summary['seconds']:.0f} s; converged {100 * summary['converged_share']:.0f} %, "
                    f"median {summary['median_steps']:.0f} steps):\n\n{tab}\n")
            doc.write_text(head + a0 + body + a1 + tail)
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
