"""Warm timings of the fits on one round (issues 4, 5 and 17).

* ``bayes_spline``: a full Bayesian fit (``bayesdrag.fit`` with the default options:
  ML + sampling to convergence) of the default spline on the shipped demo track, warm, with the
  trajectories it simulated, the batched kernel's limit for them (trajectories x the kernel's
  microseconds per trajectory on large batches of the same track, measured in the same run),
  their ratio, and the ESS per second (the smallest bulk ESS of the sampled coordinates over the
  fit's seconds), and under ``no_check`` the same fit without the model check
  (``model_check=False``: the ML fit and the sampling alone), its own trajectories at the same
  kernel rate (timed last). With ``--reference FILE`` the posterior (Cd at five Mach numbers: mean, 5 % and
  95 % quantiles with their Monte-Carlo standard errors) is compared with the run stored there
  (``benchmarks/reference_posterior_demo.json``, taken before issue 17's changes);
  ``--save-reference FILE`` stores this run's.

``--check`` runs only :mod:`check_cost` (``benchmarks/check_cost.py``): the default fit's
``(total - ml) / ml`` from ``result.json`` ``timing`` on the demo and six tracks of a tracking
radar (another shell's table, no table, an undeclared wind growing with height, the same wind as a
METCM with and without ``wind_sd``), the ratios issue 45 asks for.

The older synthetic-track timings (keys ``ml_*``, ``bayes_reference-scale`` and, without
``--quick``, ``synthetic_bayes_spline``):

* one Scheme 1 ML fit (``poly2-split``: 6 drag coefficients + 6 initial conditions) of a
  ~1500-sample point-mass track (M101 truth, 1 m / 0.3 m/s noise): time and iterations;
* a full Scheme 1 Bayesian fit (ML + emcee to convergence, default settings) of the same track
  with ``reference-scale`` (7 parameters) and with the default ``spline`` (P-spline, ~54):
  time, tau, steps (``--quick``: reference-scale only);
* with ``--moves``: the autocorrelation time of the move mixes on the poly2-split posterior
  after a fixed number of steps. That posterior is far from Gaussian (the subsonic quadratic is
  barely identified by a track that ends at Mach 0.92): the default independence mix gets an
  acceptance of ~0.02 there, which is why ``fit --moves de`` exists.

The user's loop around that fit (issue 31), measured in the same run (``--no-outputs`` skips it):

* ``write_seconds``: ``res.write(DIR)`` of the timed fit's result (warm: the warm-up fit's
  result was written first), with ``write_ratio`` = write / fit;
* ``demo_seconds``: wall time of ``python -m bayesdrag demo`` in a fresh process (numba's
  cache warm: the second of two demos), with ``demo_ratio`` to the fit above and
  ``demo_fit_seconds`` (the demo's own fit, as its report states it) and ``demo_ratio_own_fit``;
* ``no_mcmc_seconds``: wall time of ``python -m bayesdrag fit TRACK ROUND -o DIR --no-mcmc`` on
  the demo track, with ``no_mcmc_fit_seconds`` (its report's fit time) and their ratio;
* ``first_run_compile_seconds``: the numba compile time of a demo on a fresh install
  (``NUMBA_CACHE_DIR`` an empty temporary folder; from its ``summary.json``), with the functions
  compiled and the demo's wall time.

When a core is free the fit's model check diagnosis runs in a forked process beside the ML fit
and the sampling (``timing.beside``, reported with the key): the trajectories it simulates are
then not in ``trajectories_simulated`` (counted in this process).

The fit is pinned to no added effects: ``with_effects="none"`` where the option takes that
value, else the default (which adds none); ``effects_option`` says which.

Every timing is the second of two runs (numba's compiled kernel and caches warm). The machine's
load average is printed with the results: on a shared 2-core machine the kernel time scales
with it. The last line is one JSON object.

    python3 benchmarks/fit.py [--moves] [--quick] [--no-outputs] [--reference FILE] [--save-reference FILE]
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


#: Mach numbers at which the demo posterior is compared with the reference run
REFERENCE_MACH = (0.95, 1.1, 1.5, 2.0, 2.35)
#: a statistic agrees with the reference within this many combined Monte-Carlo standard errors
#: (3 sqrt(2) MCSE when both runs have the same MCSE)
REFERENCE_Z = 3.0
#: trajectories per batch for the kernel's limit (the best of these sizes counts)
LIMIT_BATCHES = (64, 128, 256)
DEMO_SEED = 1


def demo_round_and_track():
    """The shipped demo track (as ``bayesdrag demo`` reads it) and its round."""
    from bayesdrag.commands.demo import demo_inputs
    from bayesdrag.io.rounds import read_round
    from bayesdrag.io.tracks import read_track
    from bayesdrag.track import thin_for_fit

    track_path, round_path = demo_inputs()
    return thin_for_fit(read_track(track_path)), read_round(round_path)


class KernelCount:
    """Counts the trajectories (and the seconds) of every batched-kernel call while active: the
    kernel module's two entry points are wrapped for the duration (benchmark instrumentation)."""

    def __init__(self):
        self.trajectories = 0
        self.calls = 0
        self.seconds = 0.0

    def __enter__(self):
        from bayesdrag.dynamics import kernel as K

        self._orig = fn = K.integrate_batch

        def run(y0, *args, **kw):
            t = time.perf_counter()
            out = fn(y0, *args, **kw)
            self.seconds += time.perf_counter() - t
            self.trajectories += y0.shape[0]
            self.calls += 1
            return out

        K.integrate_batch = run
        return self

    def __exit__(self, *exc):
        from bayesdrag.dynamics import kernel as K

        K.integrate_batch = self._orig


def kernel_us_per_trajectory(problem, theta, cov, *, batches=LIMIT_BATCHES, repeats=5, seed=0):
    """Batched kernel's best microseconds per trajectory over batches of ``batches`` parameter
    sets of ``problem`` drawn around ``theta`` (free coordinates ~ N(theta, cov)): kernel time
    only, the best of ``repeats`` calls per size."""
    return min(_kernel_us(problem, theta, cov, b, repeats, seed) for b in batches)


def _kernel_us(problem, theta, cov, batch, repeats, seed):
    rng = np.random.default_rng(seed)
    idx = np.flatnonzero(problem.free)
    th = np.repeat(np.asarray(theta, float)[None], batch, axis=0)
    L = np.linalg.cholesky(cov)
    th[:, idx] += rng.standard_normal((batch, idx.size)) @ L.T
    th[:, idx] = np.clip(th[:, idx], problem.lower[idx], problem.upper[idx])
    best = np.inf
    for _ in range(repeats):
        with KernelCount() as kc:
            problem.predict(th)
        best = min(best, kc.seconds / kc.trajectories)
    return 1e6 * best


def demo_posterior(result):
    """Cd at :data:`REFERENCE_MACH` from a fit's posterior: mean, q05, q95 and their MCSE
    (ArviZ's mean and quantile MCSE on the walkers as chains), plus r_hat."""
    import arviz as az

    from bayesdrag.estimate.bayes.draws import cd_draws
    from bayesdrag.estimate.bayes.sampler import split_rank_rhat

    f1 = result.scheme1
    cd = cd_draws(result.posterior, f1.drag_model, np.array(REFERENCE_MACH), f1.problem.P)   # (W, S, M)
    rhat = split_rank_rhat(cd)
    out = {}
    for j, m in enumerate(REFERENCE_MACH):
        flat = cd[..., j].reshape(-1)
        x = az.convert_to_dataset({"cd": cd[..., j]})
        row = {"mean": float(flat.mean()), "mcse_mean": float(az.mcse(x, method="mean")["cd"]),
               "r_hat": float(rhat[j]), "ess_bulk": float(az.ess(x, method="bulk")["cd"])}
        for p, k in ((0.05, "q05"), (0.95, "q95")):
            row[k] = float(np.quantile(flat, p))
            row[f"mcse_{k}"] = float(az.mcse(x, method="quantile", prob=p)["cd"])
        out[f"{m:g}"] = row
    return out


def compare_posterior(new, ref):
    """Each statistic's difference from the reference in combined MCSE units; ok when all are
    within :data:`REFERENCE_Z` and every r_hat < 1.01."""
    worst, rows = 0.0, {}
    for m, r in ref.items():
        n = new[m]
        z = {}
        for k in ("mean", "q05", "q95"):
            se = np.hypot(r[f"mcse_{k}"], n[f"mcse_{k}"])
            z[k] = round(float((n[k] - r[k]) / se), 2)
            worst = max(worst, abs(z[k]))
        rows[m] = z
    rhat = max(n["r_hat"] for n in new.values())
    return {"z": rows, "max_abs_z": round(worst, 2), "r_hat_max": rhat,
            "ok": bool(worst <= REFERENCE_Z and rhat < 1.01)}


def pinned_options(seed):
    """The benchmark's fit options: no added effects (``with_effects="none"`` where the option
    takes it, else the default, which adds none). Returns ``(FitOptions, which)``."""
    from bayesdrag.errors import InputError
    from bayesdrag.options import FitOptions

    try:
        return FitOptions(seed=seed, with_effects="none"), 'with_effects="none"'
    except (InputError, ValueError):
        return FitOptions(seed=seed), "default (no added effects)"


def time_default_fit(none_seconds, seed=DEMO_SEED):
    """The demo's fit with the default options as a user runs it (the model check's search for
    the cause and the refit with the effects it names included), the second of two runs, against
    the ``with_effects="none"`` fit of the same run (``none_seconds``)."""
    from bayesdrag.options import FitOptions
    from bayesdrag.pipeline import fit

    track, rnd = demo_round_and_track()
    fit(track, rnd, FitOptions(seed=seed))
    t = time.perf_counter()
    res = fit(track, rnd, FitOptions(seed=seed))
    seconds = time.perf_counter() - t
    d = res.to_dict()
    return {"seconds": round(seconds, 3), "ratio_to_none": round(seconds / none_seconds, 2),
            "effects_added": (d["ml"].get("with_effects") or {}).get("effects", []), "timing": d.get("timing")}


def time_demo_bayes(seed=DEMO_SEED, outputs=True):
    """The ``bayes_spline`` benchmark: ``bayesdrag.fit`` of the shipped demo track
    with the default options (spline, ML + sampling to convergence), the second of two runs;
    with ``outputs`` also ``res.write`` of that result (the first run's result written first,
    to warm the figure code)."""
    import tempfile

    from bayesdrag.pipeline import fit

    track, rnd = demo_round_and_track()
    opts, which = pinned_options(seed)
    first = fit(track, rnd, opts)
    with tempfile.TemporaryDirectory() as tmp:
        if outputs:
            first.write(Path(tmp) / "warm")
        with KernelCount() as kc:
            t = time.perf_counter()
            res = fit(track, rnd, opts)
            seconds = time.perf_counter() - t
        write_seconds = None
        if outputs:
            t = time.perf_counter()
            res.write(Path(tmp) / "timed")
            write_seconds = time.perf_counter() - t
    b = res.posterior
    post = res.log_posterior
    us = kernel_us_per_trajectory(res.scheme1.problem, post.mode, post.laplace_cov[:post.n_theta, :post.n_theta])
    sampled = list(post.names)
    ess_bulk = float(b.convergence.loc[sampled, "ess_bulk"].min())
    ess_tail = float(b.convergence.loc[sampled, "ess_tail"].min())
    limit = kc.trajectories * us * 1e-6
    out = {"seconds": round(seconds, 3), "trajectories_simulated": kc.trajectories, "kernel_calls": kc.calls,
           "kernel_seconds": round(kc.seconds, 3), "kernel_us_per_trajectory_large_batch": round(us, 2),
           "kernel_limit_seconds": round(limit, 3), "ratio_to_limit": round(seconds / limit, 2),
           "sampling_seconds": round(b.elapsed, 3), "ess_bulk_min": ess_bulk, "ess_tail_min": ess_tail,
           "ess_per_second": round(ess_bulk / seconds, 1),
           "ess_per_sampling_second": round(ess_bulk / b.elapsed, 1),
           "parameters": post.ndim, "steps": b.steps, "walkers": b.nwalkers, "tau_max": float(np.max(b.tau)),
           "acceptance": round(b.acceptance, 3), "converged": b.converged,
           "r_hat_max": float(b.convergence["r_hat"].max()), "samples": track.n, "seed": seed,
           "effects_option": which, "timing": res.to_dict().get("timing")}
    if write_seconds is not None:
        out["write_seconds"] = round(write_seconds, 3)
        out["write_ratio"] = round(write_seconds / seconds, 2)
    return out, demo_posterior(res)


def time_without_check(us, seed=DEMO_SEED):
    """The ``bayes_spline`` fit with ``model_check=False`` (no diagnosis, no noise check), warm,
    its own trajectories counted at the kernel's microseconds per trajectory ``us`` measured for
    ``bayes_spline`` (the same rate, this fit's own limit): what the ML fit and the sampling cost
    without the check (issue 45), a reference in the same run for ``ratio_to_limit``. Run after
    the other timings, whose fork decisions its load would move."""
    from dataclasses import replace

    from bayesdrag.pipeline import fit

    track, rnd = demo_round_and_track()
    opts, _ = pinned_options(seed)
    plain = replace(opts, model_check=False)
    fit(track, rnd, plain)
    with KernelCount() as kc:
        t = time.perf_counter()
        res = fit(track, rnd, plain)
        seconds = time.perf_counter() - t
    limit = kc.trajectories * us * 1e-6
    return {"seconds": round(seconds, 3), "trajectories_simulated": kc.trajectories,
            "kernel_limit_seconds": round(limit, 3), "ratio_to_limit": round(seconds / limit, 2),
            "timing": res.to_dict().get("timing")}


def _command(args, env=None):
    """Wall time [s] of ``python -m bayesdrag ARGS`` in a fresh process (this checkout's
    package); raises when it fails."""
    import subprocess

    root = str(Path(__file__).resolve().parents[1])
    full = dict(os.environ, **(env or {}))
    full["PYTHONPATH"] = root + os.pathsep + full.get("PYTHONPATH", "")
    t = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "bayesdrag", *args], env=full, capture_output=True, text=True)
    seconds = time.perf_counter() - t
    if done.returncode != 0:
        raise RuntimeError(f"bayesdrag {' '.join(args)} failed ({done.returncode}): {done.stderr[-2000:]}")
    return seconds


def _report_fit_seconds(folder):
    """The fit's wall-clock time a report states (``report.html``, one decimal) [s]."""
    import re

    m = re.search(r"wall-clock time</th><td[^>]*>([0-9.]+) s", (Path(folder) / "report.html").read_text())
    return float(m.group(1)) if m else None


def time_user_loop(fit_seconds):
    """``demo`` warm, ``fit --no-mcmc`` and a first demo's compile time, each in a fresh
    process (module docstring)."""
    import tempfile

    from bayesdrag.commands.demo import demo_inputs

    track_path, round_path = demo_inputs()
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        _command(["demo", "-o", str(tmp / "demo0")])           # numba's cache and the .pyc files warm
        out["demo_seconds"] = round(_command(["demo", "-o", str(tmp / "demo1")]), 2)
        out["demo_ratio"] = round(out["demo_seconds"] / fit_seconds, 2)
        own = _report_fit_seconds(tmp / "demo1")
        out["demo_fit_seconds"] = own
        out["demo_ratio_own_fit"] = round(out["demo_seconds"] / own, 2) if own else None
        out["no_mcmc_seconds"] = round(_command(["fit", str(track_path), str(round_path), "-o", str(tmp / "nomcmc"),
                                                 "--no-mcmc", "-q"]), 2)
        own = _report_fit_seconds(tmp / "nomcmc")
        out["no_mcmc_fit_seconds"] = own
        out["no_mcmc_ratio"] = round(out["no_mcmc_seconds"] / own, 2) if own else None
        cache = tmp / "numba-cache"
        cache.mkdir()
        wall = _command(["demo", "-o", str(tmp / "cold")], env={"NUMBA_CACHE_DIR": str(cache)})
        compiled = json.loads((tmp / "cold" / "summary.json").read_text())["compiled_code"]
        out["first_run_compile_seconds"] = compiled["compile_seconds"]
        out["first_run_compiled"] = compiled["compiled"]
        out["first_run_demo_seconds"] = round(wall, 2)
    return out


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
    from bayesdrag.estimate.scheme1.fit import fit_scheme1

    fit_scheme1(track, rnd, drag=drag)
    t = time.perf_counter()
    f1 = fit_scheme1(track, rnd, drag=drag)
    res, prob = f1.ml, f1.problem
    return time.perf_counter() - t, res, prob


def time_bayes(track, rnd, drag, seed=1):
    """ML + LogPosterior + sampling to convergence; returns (seconds, BayesResult, n params)."""
    from bayesdrag.estimate.bayes.posterior import LogPosterior
    from bayesdrag.estimate.bayes.sampler import sample_posterior
    from bayesdrag.estimate.scheme1.fit import fit_scheme1

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
    from bayesdrag.estimate.bayes.posterior import LogPosterior
    from bayesdrag.estimate.bayes.sampler import sample_posterior
    from bayesdrag.estimate.scheme1.fit import fit_scheme1

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
    ap.add_argument("--quick", action="store_true", help="skip the synthetic spline Bayesian fit")
    ap.add_argument("--demo-only", action="store_true", help="only the bayes_spline benchmark on the demo track")
    ap.add_argument("--no-outputs", action="store_true",
                    help="skip the user's loop (write, demo, fit --no-mcmc, first-run compile)")
    ap.add_argument("--reference", type=Path, default=None,
                    help="compare the demo posterior with this stored run (reference_posterior_demo.json)")
    ap.add_argument("--save-reference", type=Path, default=None, help="store the demo posterior here")
    ap.add_argument("--check", action="store_true",
                    help="only the model check's cost beside the ML fit on the demo and six tracks "
                         "(benchmarks/check_cost.py; issue 45's ratios)")
    a = ap.parse_args(argv)
    if a.check:
        import check_cost

        return check_cost.main([])
    warnings.simplefilter("ignore")
    load = os.getloadavg()[0]
    out = {"load_average_1min": load, "cpus": os.cpu_count()}
    spline, cd = time_demo_bayes(outputs=not a.no_outputs)
    if not a.no_outputs:
        spline.update(time_user_loop(spline["seconds"]))
    out["bayes_spline"] = spline
    out["default"] = time_default_fit(spline["seconds"])
    spline["no_check"] = time_without_check(spline["kernel_us_per_trajectory_large_batch"])
    print(f"default fit (effect search included): {out['default']['seconds']:.2f} s = "
          f"{out['default']['ratio_to_none']:.2f} x the with_effects=none fit; added "
          f"{out['default']['effects_added'] or 'nothing'}", flush=True)
    print(f"Bayes, default spline on the demo track ({spline['parameters']} sampled parameters, "
          f"{spline['samples']} samples): {spline['seconds']:.2f} s warm (fit), sampling {spline['sampling_seconds']:.2f} s, "
          f"{spline['steps']} steps x {spline['walkers']} walkers, tau max {spline['tau_max']:.1f}; "
          f"{spline['trajectories_simulated']} trajectories, kernel {spline['kernel_us_per_trajectory_large_batch']:.1f} "
          f"us/trajectory on large batches -> limit {spline['kernel_limit_seconds']:.2f} s, ratio "
          f"{spline['ratio_to_limit']:.1f}; ESS (bulk, min) {spline['ess_bulk_min']:.0f} -> "
          f"{spline['ess_per_second']:.0f} per second; without the model check {spline['no_check']['seconds']:.2f} s, "
          f"ratio {spline['no_check']['ratio_to_limit']:.1f} (ML {spline['no_check']['timing']['ml']:.2f} s, "
          f"sampling {spline['no_check']['timing']['sampling']:.2f} s)", flush=True)
    if not a.no_outputs:
        print(f"user's loop ({spline['effects_option']}): res.write {spline['write_seconds']:.2f} s = "
              f"{spline['write_ratio']:.2f} x the fit; bayesdrag demo warm {spline['demo_seconds']:.2f} s = "
              f"{spline['demo_ratio']:.2f} x the fit ({spline['demo_ratio_own_fit']} x its own fit of "
              f"{spline['demo_fit_seconds']} s); fit --no-mcmc {spline['no_mcmc_seconds']:.2f} s wall = "
              f"{spline['no_mcmc_ratio']} x its fit ({spline['no_mcmc_fit_seconds']} s); first demo on a fresh "
              f"install: {spline['first_run_compile_seconds']:.1f} s compiling {len(spline['first_run_compiled'])} "
              f"functions, {spline['first_run_demo_seconds']:.1f} s wall", flush=True)
    if a.save_reference is not None:
        a.save_reference.write_text(json.dumps({"what": "Cd posterior of bayesdrag.fit on the shipped demo track, "
                                                        "default options, seed %d" % DEMO_SEED,
                                                "load_average_1min": load, "bayes_spline": spline,
                                                "cd": cd}, indent=1) + "\n")
        print(f"reference posterior written to {a.save_reference}")
    if a.reference is not None:
        ref = json.loads(a.reference.read_text())
        cmp = compare_posterior(cd, ref["cd"])
        ref_ess = ref["bayes_spline"]["ess_per_second"]
        cmp["ess_per_second_reference"] = ref_ess
        cmp["ess_per_second_gain"] = round(spline["ess_per_second"] / ref_ess, 2)
        out["posterior_vs_reference"] = cmp
        print(f"posterior vs {a.reference.name}: max |difference| {cmp['max_abs_z']:.2f} combined MCSE "
              f"(allowed {REFERENCE_Z:g}), r_hat max {cmp['r_hat_max']:.4f}: {'OK' if cmp['ok'] else 'DIFFERENT'}; "
              f"ESS/s x{cmp['ess_per_second_gain']:.1f} the reference run's (load then "
              f"{ref['load_average_1min']:.1f})", flush=True)
    if not a.demo_only:
        track, rnd = round_and_track()
        out["samples"] = track.n
        t_ml, res, prob = time_ml(track, rnd, "poly2-split")
        print(f"ML, poly2-split ({int(res.free.sum())} free parameters, {track.n} samples): {t_ml:.3f} s warm, "
              f"{res.iterations} iterations ({res.message})", flush=True)
        out["ml_seconds"] = round(t_ml, 4)
        out["ml_iterations"] = res.iterations
        out["ml_parameters"] = int(res.free.sum())
        for drag in ("reference-scale",) + (() if a.quick else ("spline",)):
            t_b, b, D = time_bayes(track, rnd, drag)
            print(f"Bayes, {drag}, synthetic track ({D} sampled parameters): {t_b:.2f} s warm (ML + sampling), "
                  f"tau max {np.max(b.tau):.1f} steps, {b.steps} steps x {b.nwalkers} walkers, {b.message}",
                  flush=True)
            key = "bayes_reference-scale" if drag == "reference-scale" else "synthetic_bayes_spline"
            out[key] = {"seconds": round(t_b, 3), "tau_max": float(np.max(b.tau)), "steps": b.steps,
                        "walkers": b.nwalkers, "parameters": D, "converged": b.converged,
                        "r_hat_max": float(b.convergence["r_hat"].max()),
                        "ess_bulk_min": float(b.convergence["ess_bulk"].min())}
        if a.moves:
            out["moves"] = compare_moves(track, rnd, steps=400)
    out["load_average_1min_end"] = os.getloadavg()[0]
    print(f"load average (1 min) {load:.1f} at the start, {out['load_average_1min_end']:.1f} at the end, "
          f"on {os.cpu_count()} CPUs")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
