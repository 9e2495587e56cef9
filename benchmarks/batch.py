"""Benchmark: a campaign of many rounds (ML fit + gap diagnosis per round) as Dask tasks on a
LocalCluster with 1 and with 2 workers; rounds per minute and the speed-up.

    python benchmarks/batch.py [--rounds 50] [--workers 1,2] [--dt 0.2] [--quick]

The rounds are short, cheap point-mass tracks of the 155 mm M101 shell (QE 12-20 deg, 790-840
m/s, 1 % round-to-round Cd scatter) sampled every ``--dt`` s (0.2 s: ~160 samples of x, y, z,
v; the default penalised-spline fit and the full diagnosis run on each). Each configuration
writes into a fresh folder (nothing skipped); the numba kernel is compiled and cached on disk
before timing so each worker only loads it. Reported per configuration: wall-clock seconds
from the first submitted task to the last result (cluster start-up apart), rounds per minute,
and the mean task wall and CPU time inside the workers (their ratio is the CPU share a worker
got: below 1 when other processes compete for the cores); the speed-up is the 1-worker wall time over the
2-worker one. Other processes sharing the CPUs slow the 2-worker run most, so the load average
is printed too. The last line printed is one JSON object.
"""
import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=50)
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--dt", type=float, default=0.2)
    ap.add_argument("--quick", action="store_true", help="10 rounds")
    ap.add_argument("--keep", default=None, help="keep the outputs in this folder")
    a = ap.parse_args(argv)
    n = 10 if a.quick else a.rounds
    workers = [int(w) for w in a.workers.split(",")]

    from bayesdrag.options import FitOptions

    from bayesdrag.commands.batch import _Dask, round_task
    from bayesdrag.io.campaign import read_campaign
    from bayesdrag.campaign.synthetic import simulate_campaign

    root = Path(a.keep or tempfile.mkdtemp(prefix="bayesdrag-batch-bench-"))
    path, _ = simulate_campaign(root / "campaign", n_rounds=n, scatter=0.01, rng=np.random.default_rng(1), dt=a.dt)
    camp = read_campaign(path)
    # warm the on-disk numba cache (compile once, here)
    r0 = camp.rounds[0]
    round_task(r0.name, str(r0.track), str(r0.round), str(root / "warm" / r0.name), jobs=("fit", "diagnose"),
               options=FitOptions(mcmc=False))
    out = {"rounds": n, "dt": a.dt, "jobs": "fit,diagnose", "cpus": os.cpu_count(), "configs": {}}
    for w in workers:
        dest = root / f"out_w{w}"
        shutil.rmtree(dest, ignore_errors=True)
        calls = [dict(name=r.name, track=str(r.track), round_path=str(r.round), outdir=str(dest / r.name),
                      jobs=("fit", "diagnose"), options=FitOptions(mcmc=False)) for r in camp.rounds]
        load0 = os.getloadavg()[0]
        ex = _Dask(None, w)
        t_start = time.perf_counter()
        first = None
        reports = []
        for rep in ex.run(calls, None):
            if first is None:
                first = time.perf_counter()
            reports.append(rep)
        t_end = time.perf_counter()
        failed = [r["name"] for r in reports if any(v["status"] != "done" for v in r["jobs"].values())]
        task = [sum(v["seconds"] for v in r["jobs"].values()) for r in reports]
        cpu = [sum(v.get("cpu_seconds", 0.0) for v in r["jobs"].values()) for r in reports]
        # the cluster start-up is inside ex.run before the first submit; estimate it as the time
        # to the first result minus one mean task time
        startup = max(0.0, (first - t_start) - float(np.mean(task)))
        wall = t_end - t_start - startup
        out["configs"][str(w)] = {"workers": w, "wall_s": round(wall, 2), "startup_s": round(startup, 2),
                                  "rounds_per_minute": round(60.0 * n / wall, 2),
                                  "mean_task_s": round(float(np.mean(task)), 3),
                                  "mean_task_cpu_s": round(float(np.mean(cpu)), 3),
                                  "cpu_share_per_worker": round(float(np.sum(cpu) / np.sum(task)), 3), "failed": failed,
                                  "loadavg_before": round(load0, 2), "loadavg_after": round(os.getloadavg()[0], 2)}
        print(f"{w} worker(s): {n} rounds in {wall:.1f} s ({60 * n / wall:.1f} rounds/min; start-up "
              f"{startup:.1f} s apart; mean task {np.mean(task):.2f} s wall, {np.mean(cpu):.2f} s CPU; load {load0:.1f}); "
              f"failed: {failed or 'none'}",
              file=sys.stderr, flush=True)
    if "1" in out["configs"] and "2" in out["configs"]:
        out["speedup_2_vs_1"] = round(out["configs"]["1"]["wall_s"] / out["configs"]["2"]["wall_s"], 3)
        print(f"speed-up 2 workers vs 1: {out['speedup_2_vs_1']:.2f}x", file=sys.stderr)
    if not a.keep:
        shutil.rmtree(root, ignore_errors=True)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
