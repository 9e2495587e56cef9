"""Reproduce the paper's simulated-data study (its Section 4.1 and 4.3) with bayesdrag.

The paper's Table 1 shell (42.6 kg, 155 mm; here with the M101 zero-yaw drag as the "true" Cd)
is flown by the 6-DOF model at 818 m/s and 360 m/s, QE 7 deg, sampled every 0.027 s to impact.
Then, as in the paper:

* **Table 2 analogue**: Scheme 1 with the quadratic Cd = a0 + a1 M + a2 M^2 (Eq. 18), fitted
  over the supersonic flight (818 m/s) and the subsonic flight (360 m/s), coefficients with
  their Cramér-Rao sd, beside the paper's values.
* **Fig. 3 analogue** (818 m/s): (a) noise 0 %, (b) noise 5 % without initial-condition
  estimation (initial conditions from the first noisy samples, as the paper did), (c) noise 5 %
  with initial-condition estimation. "5 %" is the paper's: 5 % of a 20 m maximum error,
  i.e. sigma = 1 m in x, y, z (we add 0.3 m/s in v).
* **Fig. 5 analogue** (Scheme 2, windows of 50 samples = 1.35 s): (a) noise 0 %, (b) noise 5 %
  with initial conditions from raw differences, (c) noise 5 % with 5th-order polynomial
  (Savitzky-Golay) smoothing, initial conditions frozen (paper), (d) the same with initial
  conditions refined in each window (bayesdrag's default).

Writes figures to ``docs/figures/paper_*.png`` and the numbers to
``docs/paper_reproduction.json``; prints a Markdown table. Takes about a minute.

    python examples/paper_reproduction.py [--out docs]
"""
from __future__ import annotations

import argparse
import json
from dataclasses import replace
from importlib.resources import files
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.estimate.model.problem import OutputErrorProblem
from bayesdrag.estimate.cd.table import cd_table
from bayesdrag.estimate.scheme1.fit import fit_scheme1
from bayesdrag.estimate.scheme2 import fit_scheme2
from bayesdrag.synthetic import add_noise, simulate_round
from bayesdrag.io.rounds import read_round

PAPER_TABLE2 = {818: {"a0": (-0.549, 0.0028), "a1": (-0.2137, 0.0026), "a2": (0.0346, 0.0007)},
                360: {"a0": (-5.449, 0.6611), "a1": (9.737, 1.3507), "a2": (-3.983, 0.6887)}}
NOISE_5PCT = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
QE = 7.0


def rounds():
    base = read_round(files("bayesdrag") / "data" / "demo_round.toml")
    return {v: replace(base, launch=replace(base.launch, velocity=float(v), elevation_deg=QE)) for v in (818, 360)}


def naive_initial_state(track):
    """The paper's first attempt: position from the first (noisy) sample, velocity from the
    difference of the first two."""
    s = np.zeros(6)
    for k, c in enumerate("xyz"):
        p = track.channels[c]
        s[k] = p[0]
        s[3 + k] = (p[1] - p[0]) / (track.t[1] - track.t[0])
    return s


def table2(tracks, rnds, ref):
    out = {}
    for v, tr in tracks.items():
        f1 = fit_scheme1(tr, rnds[v], drag="poly2", sigma=NOISE_5PCT)
        res, prob = f1.ml, f1.problem
        m = np.linspace(res.mach.min(), res.mach.max(), 60)
        err = prob.model.drag.cd(res.drag_params, m) / ref.value(m) - 1
        out[v] = {"params": {n: float(res.theta[i]) for i, n in enumerate(("a0", "a1", "a2"))},
                  "crb": {n: float(res.crb[i]) for i, n in enumerate(("a0", "a1", "a2"))},
                  "mach_range": [float(res.mach.min()), float(res.mach.max())],
                  "max_abs_rel_error_vs_truth": float(np.max(np.abs(err))), "converged": res.converged}
    return out


def fig3(clean, rnd, ref, rng, out):
    noisy = add_noise(clean, NOISE_5PCT, rng)
    cases = {}
    f1_a = fit_scheme1(clean, rnd, drag="poly2", sigma=NOISE_5PCT)
    res_a, prob_a = f1_a.ml, f1_a.problem
    cases["(a) noise 0 %"] = (res_a, prob_a)
    # (b): ICs frozen at the naive values from the noisy data
    model = prob_a.model
    th0 = np.concatenate([prob_a.theta0[:3], naive_initial_state(noisy)])
    free = np.r_[np.ones(3, bool), np.zeros(6, bool)]
    prob_b = OutputErrorProblem(model, noisy, th0, free=free, sigma=NOISE_5PCT)
    cases["(b) noise 5 %, ICs from the first samples"] = (prob_b.fit(), prob_b)
    f1 = fit_scheme1(noisy, rnd, drag="poly2", sigma=NOISE_5PCT)
    cases["(c) noise 5 %, ICs estimated"] = (f1.ml, f1.problem)
    f1 = fit_scheme1(noisy, rnd, sigma=NOISE_5PCT)
    cases["bayesdrag default: P-spline, noise 5 %"] = (f1.ml, f1.problem)
    fig, axes = plt.subplots(1, 4, figsize=(16, 4), sharey=True)
    summary = {}
    for ax, (name, (res, prob)) in zip(axes, cases.items()):
        m = np.linspace(res.mach.min(), res.mach.max(), 80)
        rows = cd_table(res, prob.model.drag, m, ref)
        cd = np.array([r["ml"] for r in rows])
        sd = np.array([r["crb_sd"] for r in rows])
        ax.plot(m, ref.value(m), "k-", lw=1, label="true Cd (M101)")
        ax.plot(m, cd, "C0-", label="estimate")
        ax.fill_between(m, cd - 2 * sd, cd + 2 * sd, color="C0", alpha=0.3, label="±2 CRB sd")
        ax.set_title(name, fontsize="small")
        ax.set_xlabel("Mach")
        err = cd / ref.value(m) - 1
        summary[name] = {"max_abs_rel_error": float(np.max(np.abs(err))), "converged": bool(res.converged),
                         "max_abs_z": float(np.max(np.abs((cd - ref.value(m)) / np.where(sd > 0, sd, np.nan))))}
    axes[0].set_ylabel("Cd")
    axes[0].legend(fontsize="small")
    fig.suptitle("Paper Fig. 3 analogue: Scheme 1, 6-DOF Table 1 shell, 818 m/s, QE 7°")
    fig.tight_layout()
    fig.savefig(out / "figures" / "paper_fig3_scheme1.png", dpi=110)
    plt.close(fig)
    return summary, noisy


def fig5(clean, noisy, rnd, ref, out):
    cases = {
        "(a) noise 0 %": dict(track=clean, free_ic=False),
        "(b) noise 5 %, raw differences, ICs frozen": dict(track=noisy, free_ic=False, smooth=3, polyorder=1),
        "(c) noise 5 %, 5th-order smoothing, ICs frozen": dict(track=noisy, free_ic=False),
        "(d) noise 5 %, smoothing, ICs refined (default)": dict(track=noisy, free_ic=True),
    }
    fig, axes = plt.subplots(1, 4, figsize=(16, 4), sharey=True)
    summary = {}
    for ax, (name, kw) in zip(axes, cases.items()):
        tr = kw.pop("track")
        r = fit_scheme2(tr, rnd, window=50, sigma=NOISE_5PCT, **kw)
        m = np.array([w["mach"] for w in r.windows])
        cd = np.array([w["ml"] for w in r.windows])
        sd = np.array([w["crb_sd"] for w in r.windows])
        mm = np.linspace(m.min(), m.max(), 200)
        ax.plot(mm, ref.value(mm), "k-", lw=1, label="true Cd (M101)")
        ax.errorbar(m, cd, yerr=2 * sd, fmt="o", ms=3, color="C1", label="window Cd ± 2 CRB sd")
        ax.set_title(name, fontsize="small")
        ax.set_xlabel("Mach")
        z = (cd - ref.value(m)) / sd
        summary[name] = {"windows": len(cd), "max_abs_rel_error": float(np.max(np.abs(cd / ref.value(m) - 1))),
                         "median_abs_rel_error": float(np.median(np.abs(cd / ref.value(m) - 1))),
                         "max_abs_z": float(np.max(np.abs(z))), "share_within_3sd": float(np.mean(np.abs(z) < 3))}
    axes[0].set_ylabel("Cd")
    axes[0].set_ylim(0.2, 0.45)
    axes[0].legend(fontsize="small")
    fig.suptitle("Paper Fig. 5 analogue: Scheme 2 (50-sample windows), 818 m/s, QE 7°")
    fig.tight_layout()
    fig.savefig(out / "figures" / "paper_fig5_scheme2.png", dpi=110)
    plt.close(fig)
    return summary


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="docs", help="folder for paper_reproduction.json and figures/")
    ap.add_argument("--seed", type=int, default=5)
    args = ap.parse_args(argv)
    out = Path(args.out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    rnds = rounds()
    ref = rnds[818].reference_drag
    clean = {v: simulate_round(r, model="6dof", dt=0.027) for v, r in rnds.items()}
    t2 = table2(clean, rnds, ref)
    f3, noisy = fig3(clean[818], rnds[818], ref, np.random.default_rng(args.seed), out)
    f5 = fig5(clean[818], noisy, rnds[818], ref, out)
    results = {"table2": t2, "paper_table2": PAPER_TABLE2, "fig3": f3, "fig5": f5,
               "setup": {"shell": "paper Table 1 (42.6 kg, 155 mm), M101 drag, 6-DOF", "qe_deg": QE, "dt": 0.027,
                         "noise_5pct": NOISE_5PCT, "seed": args.seed,
                         "samples": {str(v): int(c.n) for v, c in clean.items()},
                         "initial_state_818": initial_state(818.0, QE).tolist()}}
    (out / "paper_reproduction.json").write_text(json.dumps(results, indent=2))
    print("| V0 | coefficient | bayesdrag (CRB sd) | paper (CRB sd) |")
    print("|---|---|---|---|")
    for v in (818, 360):
        for n in ("a0", "a1", "a2"):
            p, s = PAPER_TABLE2[v][n]
            print(f"| {v} m/s | {n} | {t2[v]['params'][n]:.4f} ({t2[v]['crb'][n]:.4f}) | {p} ({s}) |")
    for v in (818, 360):
        print(f"{v} m/s: Mach {t2[v]['mach_range'][0]:.2f}-{t2[v]['mach_range'][1]:.2f}, quadratic within "
              f"{100 * t2[v]['max_abs_rel_error_vs_truth']:.1f} % of the truth")
    for name, s in f3.items():
        print(f"Fig. 3 {name}: max |error| {100 * s['max_abs_rel_error']:.2f} %, max |z| {s['max_abs_z']:.1f}")
    for name, s in f5.items():
        print(f"Fig. 5 {name}: {s['windows']} windows, median |error| {100 * s['median_abs_rel_error']:.2f} %, "
              f"max {100 * s['max_abs_rel_error']:.1f} %, within 3 CRB sd {100 * s['share_within_3sd']:.0f} %")
    print(f"wrote {out / 'paper_reproduction.json'} and {out / 'figures'}/paper_fig3_scheme1.png, paper_fig5_scheme2.png")


if __name__ == "__main__":
    main()
