"""Benchmark: batched point-mass kernel vs scipy solve_ivp on the same 155 mm trajectories.

    python benchmarks/forward.py [--quick] [--batch 64] [--threads N]

The trajectory is the paper's Table 1 shell (42.6 kg, 155 mm, M101 drag) at 818 m/s and the
elevation whose flight lasts 1482 samples of 0.027 s (40 s). The batch perturbs launch speed
and elevation slightly so the trajectories differ. Both backends produce the states at the
same 1482 sample times; the error is the kernel's largest position difference from a
tight-tolerance solve_ivp (rtol 1e-11). The kernel time is the best of many repeats (the
machine is shared, so the best is the least disturbed); it is also given for the batch sizes
the ML fit (21 = 2 * 10 free parameters + 1) and emcee (64 walkers) use. Winds that change along
the flight are timed against the constant wind in the same run (``wind_profile_ratio_vs_constant_wind``:
a wind by height in layers; ``wind_downrange_ratio_vs_constant_wind``: by downrange distance).
``compile_cpu_seconds``: CPU time a fresh process with an empty ``NUMBA_CACHE_DIR`` spends
compiling the kernels a first demo needs (calm and wind-table batches of 16 and of 1 trajectory;
CPU time, so the load of a shared machine barely moves it; ``--compile-only`` prints just that).
The last line printed is one JSON object (docs/bayes.md, Speed).
"""
import argparse
import json
import os
import sys
import time

import numpy as np


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats and reference runs (< 1 min)")
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--threads", type=int, default=None, help="numba threads (default: all cores)")
    ap.add_argument("--compile-only", action="store_true", help="only the first-run compile time")
    ap.add_argument("--compile-child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.compile_child:
        return compile_child()
    compile_cpu = compile_cpu_seconds()
    if args.compile_only:
        print(json.dumps({"compile_cpu_seconds": compile_cpu}))
        return

    import numba

    from bayesdrag.io.drag_tables import load_m101
    from bayesdrag.dynamics.pointmass import PointMassModel
    from bayesdrag.dynamics.trajectory import initial_state

    if args.threads:
        numba.set_num_threads(args.threads)
    n_samples, dt = 1482, 0.027
    t = np.arange(n_samples) * dt
    model = PointMassModel(42.6, 0.155, load_m101())
    rng = np.random.default_rng(1)
    B = args.batch
    v0 = 818.0 + rng.normal(0, 2.0, B)
    el = 19.5 + rng.normal(0, 0.1, B)  # 19.5 deg: impact after ~40 s = 1482 samples
    s0 = np.stack([initial_state(v, e) for v, e in zip(v0, el)])
    P = np.zeros((B, 0))

    t0 = time.perf_counter()
    model.simulate_batch(P, s0, t)  # compile (or load the cache) + warm up
    first_call = time.perf_counter() - t0
    reps = 10 if args.quick else 40

    def best_us(n):
        times = []
        for _ in range(reps):
            t0 = time.perf_counter()
            model.simulate_batch(P[:n], s0[:n], t)
            times.append(time.perf_counter() - t0)
        return 1e6 * min(times) / n

    batch_us = best_us(B)
    by_batch = {str(n): round(best_us(n), 2) for n in (1, 21, 64) if n <= B and n != B}
    by_batch[str(B)] = round(batch_us, 2)
    batch = model.simulate_batch(P, s0, t)
    # CPU time of one thread (process_time): immune to other processes taking the cores,
    # which on a shared machine can make the wall-clock figures above a multiple of it
    n_threads = numba.get_num_threads()
    numba.set_num_threads(1)
    cpu = []
    for _ in range(reps):
        t0 = time.process_time()
        model.simulate_batch(P, s0, t)
        cpu.append(time.process_time() - t0)
    numba.set_num_threads(n_threads)
    cpu_us = 1e6 * min(cpu) / B

    # winds that change along the flight (issue 29): the same batch with a constant wind, with a
    # wind by height (6 layers of constant wind, steps spread over 100 m) and with a wind by
    # downrange distance, timed alike (one thread, CPU time, best of the repeats, interleaved
    # so that load on the shared machine hits all three)
    from bayesdrag.air.atmosphere import Atmosphere
    from bayesdrag.air.wind import WindProfile

    const = model.with_(wind=(-4.0, 3.0, 0.0))
    by_height = model.with_(atmosphere=Atmosphere(wind=WindProfile.layered(
        "altitude", (0.0, 500.0, 1000.0, 2000.0, 3000.0, 4500.0, 6000.0),
        (-2.0, -4.0, -6.0, -9.0, -12.0, -15.0), (1.0, 2.0, 3.0, 5.0, 6.0, 4.0))))
    by_range = model.with_(atmosphere=Atmosphere(wind=WindProfile.layered(
        "downrange", (0.0, 4000.0, 8000.0, 12000.0, 20000.0), (3.0, -2.0, -6.0, -9.0), (0.0, 2.0, 4.0, 6.0))))
    numba.set_num_threads(1)
    wind_cpu = {"constant": [], "altitude": [], "downrange": []}
    for m in (const, by_height, by_range):
        m.simulate_batch(P, s0, t)
    for _ in range(reps):
        for k, m in (("constant", const), ("altitude", by_height), ("downrange", by_range)):
            t0 = time.process_time()
            m.simulate_batch(P, s0, t)
            wind_cpu[k].append(time.process_time() - t0)
    numba.set_num_threads(n_threads)
    wind_us = {k: 1e6 * min(v) / B for k, v in wind_cpu.items()}
    wind_err = 0.0
    for i in range(2):
        ref_w = by_height.simulate((), s0[i], t, backend="scipy")
        k_w = by_height.simulate((), s0[i], t)
        wind_err = max(wind_err, float(np.max(np.abs(ref_w.state[:, :3] - k_w.state[:, :3]))))

    n_ref = 3 if args.quick else 8
    ref_times, err = [], 0.0
    for i in range(n_ref):
        t0 = time.perf_counter()
        ref = model.simulate((), s0[i], t, backend="scipy")
        ref_times.append(time.perf_counter() - t0)
        err = max(err, float(np.max(np.abs(ref.state[:, :3] - batch.state[i, :, :3]))))
    # a typical solve_ivp user setting (rtol 1e-6, atol 1e-6) for the speed ratio
    ivp_times = []
    for i in range(n_ref):
        t0 = time.perf_counter()
        model.simulate((), s0[i], t, backend="scipy", rtol=1e-8, atol=1e-6)
        ivp_times.append(time.perf_counter() - t0)
    ivp_us = 1e6 * float(np.median(ivp_times))
    tight_us = 1e6 * float(np.median(ref_times))
    res = {
        "batch_us_per_trajectory": round(batch_us, 2),
        "solve_ivp_us_per_trajectory": round(ivp_us, 1),
        "ratio_vs_solve_ivp": round(ivp_us / batch_us, 1),
        "max_position_error_m": float(f"{err:.3g}"),
        "solve_ivp_tight_us_per_trajectory": round(tight_us, 1),
        "batch": B, "samples": n_samples, "threads": numba.get_num_threads(),
        "us_per_trajectory_by_batch": by_batch, "cpu_us_per_trajectory_1_thread": round(cpu_us, 2), "kernel_step_s": round(model.kernel_step, 4),
        "first_call_s": round(first_call, 3), "cpu_count": os.cpu_count(),
        "wind_cpu_us_per_trajectory_1_thread": {k: round(v, 2) for k, v in wind_us.items()},
        "wind_profile_ratio_vs_constant_wind": round(wind_us["altitude"] / wind_us["constant"], 3),
        "wind_downrange_ratio_vs_constant_wind": round(wind_us["downrange"] / wind_us["constant"], 3),
        "wind_profile_max_position_error_m": float(f"{wind_err:.3g}"),
        "compile_cpu_seconds": compile_cpu,
    }
    print(f"kernel: {batch_us:.1f} us/trajectory (batch {B}, {numba.get_num_threads()} threads, "
          f"best of {reps}); solve_ivp DOP853 rtol 1e-8: {ivp_us:.0f} us; ratio {ivp_us / batch_us:.0f}x; "
          f"max position error vs rtol 1e-11 reference {err:.2e} m; us/trajectory by batch size "
          f"{by_batch}; one thread {cpu_us:.1f} us CPU/trajectory; winds (one thread, CPU): constant "
          f"{wind_us['constant']:.1f}, by height {wind_us['altitude']:.1f}, by downrange "
          f"{wind_us['downrange']:.1f} us/trajectory, wind-by-height kernel vs scipy {wind_err:.2e} m",
          file=sys.stderr)
    print(json.dumps(res))


def compile_cpu_seconds():
    """CPU seconds of :func:`compile_child` in a fresh process with an empty numba cache."""
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        done = subprocess.run([sys.executable, os.path.abspath(__file__), "--compile-child"], env=env,
                              capture_output=True, text=True, check=True)
    return json.loads(done.stdout.splitlines()[-1])["compile_cpu_seconds"]


def compile_child():
    """Compile the kernels a first demo uses (calm and with a wind table; batches of 16 and 1)
    and print the CPU seconds it took."""
    from bayesdrag.air.atmosphere import Atmosphere
    from bayesdrag.dynamics.pointmass import PointMassModel
    from bayesdrag.dynamics.trajectory import initial_state
    from bayesdrag.io.drag_tables import load_m101
    from bayesdrag.air.wind import WindProfile

    calm = PointMassModel(42.6, 0.155, load_m101())
    windy = calm.with_(atmosphere=Atmosphere(wind=WindProfile.layered("altitude", (0.0, 500.0, 1000.0),
                                                                      (-2.0, -4.0), (1.0, 2.0))))
    t = np.arange(200) * 0.027
    s0 = np.stack([initial_state(818.0 + i, 19.5) for i in range(16)])
    t0 = time.process_time()
    for model in (calm, windy):
        for B in (16, 1):
            model.simulate_batch(np.zeros((B, 0)), s0[:B], t)
    print(json.dumps({"compile_cpu_seconds": round(time.process_time() - t0, 2)}))


if __name__ == "__main__":
    main()
