"""A simulated campaign of 7 rounds with 1 % round-to-round Cd scatter, run as a Dask batch and
pooled; the campaign report is then redrawn with the simulation truth and checked.

    python3 examples/campaign_demo.py [-o DIR] [--rounds 7] [--scatter 0.01] [--seed 7]
                                      [--workers 2] [--mcmc] [--sequential]

Writes DIR/campaign.toml, the rounds, DIR/out/<round>/ (as ``bayesdrag fit``) and
DIR/out/campaign.json, campaign.html with the truth drawn in; prints the checks and a JSON line.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from bayesdrag.options import FitOptions

from bayesdrag.commands.batch import run_campaign
from bayesdrag.campaign.pooling import campaign_json, pool_rounds
from bayesdrag.io.campaign import read_campaign
from bayesdrag.campaign.synthetic import simulate_campaign
from bayesdrag.report.campaign import write_campaign_report


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--output", default="campaign-demo")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--scatter", type=float, default=0.01)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--mcmc", action="store_true", help="also sample each round's posterior (slow)")
    ap.add_argument("--sequential", action="store_true", help="no Dask: fit the rounds in this process")
    a = ap.parse_args(argv)
    d = Path(a.output)
    path, truth = simulate_campaign(d, n_rounds=a.rounds, scatter=a.scatter, rng=np.random.default_rng(a.seed))
    out = d / "out"
    res = run_campaign(path, out, jobs=("fit",), options=FitOptions(mcmc=a.mcmc, seed=a.seed),
                       executor="sequential" if a.sequential else "dask", workers=a.workers)
    camp = read_campaign(path)
    inputs = [json.loads((out / n / "pooling.json").read_text()) for n in camp.names
              if (out / n / "pooling.json").is_file()]
    pooled = pool_rounds(inputs, rng=np.random.default_rng(0))
    doc = campaign_json(pooled, inputs, camp.name, res["failed"])
    ref = truth["reference"]
    write_campaign_report(out, camp, inputs, pooled, doc,
                          truth={"cd": ref.value, "scatter": a.scatter, "deltas": truth["deltas"]})
    rows = doc["cd"]
    inside = [r["q05"] <= float(ref.value(r["mach"])) <= r["q95"] for r in rows]
    s = doc["scatter"]
    err = max(abs(r["mean"] / float(ref.value(r["mach"])) - 1) for r in rows)
    summary = {"rounds": len(inputs), "nodes": len(rows), "truth_inside_band": int(sum(inside)),
               "scatter_q05": s["q05"], "scatter_median": s["median"], "scatter_q95": s["q95"],
               "scatter_true": a.scatter, "sample_sd_of_true_deltas": float(np.std(truth["deltas"], ddof=1)),
               "scatter_covered": bool(s["q05"] <= a.scatter <= s["q95"]),
               "max_rel_error_of_mean": err, "mean_true_delta": float(np.mean(truth["deltas"])),
               "seconds": round(res["seconds"], 1)}
    print(f"campaign truth inside the 90 % band at {sum(inside)} of {len(rows)} nodes; scatter "
          f"{100 * s['q05']:.2f}-{100 * s['q95']:.2f} % (truth {100 * a.scatter:.2g} %); report {out / 'campaign.html'}")
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
