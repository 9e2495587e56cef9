"""Warm timings of the fits on one round (issues 4 and 5).

* one Scheme 1 ML fit (``poly2-split``: 6 drag coefficients + 6 initial conditions) of a
  ~1500-sample point-mass track (M101 truth, 1 m / 0.3 m/s noise): time and iterations;
* a full Scheme 1 Bayesian fit (ML + emcee to convergence, default settings) of the same track
  with ``reference-scale`` (7 parameters) and with the default ``spline`` (P-spline, ~54):
  time, tau, steps (``--quick``: reference-scale only);
* with ``--moves``: the autocorrelation time of the move mixes on the poly2-split posterior
  after a fixed number of steps. That posterior is far from Gaussian (the subsonic quadratic is
  barely identified by a track that ends at Mach 0.92): the default independence mix gets an
  acceptance of ~0.02 there, which is why ``fit --moves de`` exists.

Every timing is the second of two runs (numba's compiled kernel and caches warm). The machine's
load average is printed with the results: on a shared 2-core machine the kernel time scales
with it. The last line is one JSON object.

    python3 benchmarks/fit.py [--moves] [--quick]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}


def round_and_track(dt=0.0217):
    from bayesdrag.io.drag_tables import load_m101
    from bayesdrag.dynamics.pointmass import PointMassModel
    from bayesdrag.dynamics.trajectory import initial_state
    from bayesdrag.synthetic import add_noise
    from bayesdrag.round import Launch, Projectile, Radar, Round
    from bayesdrag.track import RadarTrack

    m101 = load_m101()
    tr = PointMassModel(42.6, 0.155, m101).simulate((), initial_state(818.0, 15.0), backend="scipy",
                                                     stop_at_impact=True, dt=dt)
    track = add_noise(RadarTrack(tr.t, {c: tr.channel(c) for c in "xyzv"}, {}), SIGMA, np.random.default_rng(3))
    rnd = Round(Projectile("155", 42.6, 0.155, m101, None), Launch(15.0, 818.0), radar=Radar(dict(SIGMA)),
                path="bench.toml")
    return track, rnd


def time_ml(track, rnd, drag):
    from bayesdrag.estimate.scheme1 import fit_scheme1

    fit_scheme1(track, rnd, drag=drag)
    t = time.perf_counter()
    f1 = fit_scheme1(track, rnd, drag=drag)
    res, prob = f1.ml, f1.problem
    return time.perf_counter() - t, res, prob


def time_bayes(track, rnd, drag, seed=1):
    """ML + LogPosterior + sampling to convergence; returns (seconds, BayesResult, n params)."""
    from bayesdrag.estimate.posterior import LogPosterior
    from bayesdrag.estimate.sampler import sample_posterior
    from bayesdrag.estimate.scheme1 import fit_scheme1

    def once():
        t = time.perf_counter()
        f1 = fit_scheme1(track, rnd, drag=drag)
        res, prob = f1.ml, f1.problem
        post = LogPosterior(prob, res)
        b = sample_posterior(post, seed=seed)
        return time.perf_counter() - t, b, post.ndim

    once()
    return once()


def compare_moves(track, rnd, steps):
    from bayesdrag.estimate.posterior import LogPosterior
    from bayesdrag.estimate.sampler import sample_posterior
    from bayesdrag.estimate.scheme1 import fit_scheme1

    f1 = fit_scheme1(track, rnd, drag="poly2-split")
    res, prob = f1.ml, f1.problem
    post = LogPosterior(prob, res)
    out = {}
    D = post.ndim
    for kind, W in (("auto", 16), ("de", 2 * D + 2), ("stretch", 2 * D + 2)):
        t = time.perf_counter()
        b = sample_posterior(post, seed=2, moves=kind, nwalkers=W, max_steps=steps, min_steps=steps)
        out[kind] = {"walkers": W, "steps": steps, "tau_max": float(np.max(b.tau)),
                     "simulations_per_tau": float(W * np.max(b.tau)), "acceptance": b.acceptance,
                     "seconds": round(time.perf_counter() - t, 2)}
        print(f"moves {kind:8s}: {W} walkers, tau max {np.max(b.tau):7.1f} steps, "
              f"{W * np.max(b.tau):8.0f} simulations per tau, acceptance {b.acceptance:.2f}", flush=True)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--moves", action="store_true", help="also compare the move mixes")
    ap.add_argument("--quick", action="store_true", help="skip the spline Bayesian fit")
    a = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    track, rnd = round_and_track()
    load = os.getloadavg()[0]
    out = {"samples": track.n, "load_average_1min": load, "cpus": os.cpu_count()}
    t_ml, res, prob = time_ml(track, rnd, "poly2-split")
    print(f"ML, poly2-split ({int(res.free.sum())} free parameters, {track.n} samples): {t_ml:.3f} s warm, "
          f"{res.iterations} iterations ({res.message})", flush=True)
    out["ml_seconds"] = round(t_ml, 4)
    out["ml_iterations"] = res.iterations
    out["ml_parameters"] = int(res.free.sum())
    for drag in ("reference-scale",) + (() if a.quick else ("spline",)):
        t_b, b, D = time_bayes(track, rnd, drag)
        print(f"Bayes, {drag} ({D} sampled parameters): {t_b:.2f} s warm (ML + sampling), "
              f"tau max {np.max(b.tau):.1f} steps, {b.steps} steps x {b.nwalkers} walkers, {b.message}", flush=True)
        out[f"bayes_{drag}"] = {"seconds": round(t_b, 3), "tau_max": float(np.max(b.tau)), "steps": b.steps,
                                "walkers": b.nwalkers, "parameters": D, "converged": b.converged,
                                "r_hat_max": float(b.summary["r_hat"].max()),
                                "ess_bulk_min": float(b.summary["ess_bulk"].min())}
    if a.moves:
        out["moves"] = compare_moves(track, rnd, steps=400)
    out["load_average_1min_end"] = os.getloadavg()[0]
    print(f"load average (1 min) {load:.1f} at the start, {out['load_average_1min_end']:.1f} at the end, "
          f"on {os.cpu_count()} CPUs")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
