"""What the default fit's model check costs beside its ML fit (issue 45), on the demo and on the
tracks a range meets: a 155 mm shell seen by a tracking radar (x, y, z every 0.05 s at 1 m,
v at 0.3 m/s, ~1 200 samples), flown by the independent integrator of
tests/fixtures/met_flight.py.

Cases:

* ``demo``: the shipped demo track and round;
* ``demo-g1``: the demo track with the G1 function as the round's reference drag;
* ``calm-other-table``: calm ICAO air, flown on a similar shell's drag (M101 with its transonic
  rise 0.03 Mach later and 4 % more drag), the round giving the M101 table;
* ``calm-no-table``: the same flight, the round giving no table;
* ``wind-undeclared``: a head wind growing with height (2 to 12 m/s over 3 km), the round calm;
* ``wind-metcm``: the same wind given as a METCM message;
* ``wind-metcm-sd``: the METCM with ``wind_sd = 2`` m/s.

Each case is fitted twice with ``bayesdrag.fit(..., mcmc=False)`` (the second, warm, counts). From
its ``result.json`` ``timing``: ``ml`` (the first ML fit) and ``total``; the check's cost is
``(total - ml) / ml`` (issue 45: at most 0.5 when the check refits nothing material, at most 1
when it refits a material effect), with the effects the fit added. The machine's load is printed:
on a shared 2-core machine every time scales with it.

    python3 benchmarks/check_cost.py [--only NAME ...] [--json FILE] [--own]

``--own`` times the check's own work instead (:func:`own_work`: ``model_error`` given the
diagnosis, and the added effects' sizes), which the fork decisions of a busy machine do not move.

The last line is one JSON object ``{case: {...}}``.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

#: the flights' quadrant elevation [deg] and sample interval [s] (~1 200 samples)
QE, DT = 30.0, 0.05
#: the similar shell: M101 with its Mach axis shifted by this and its Cd scaled by that
SHIFT, SCALE = 0.03, 1.04
#: the stated wind sd of the last case [m/s]
WIND_SD = 2.0


def growing(alt):
    """A head wind growing smoothly from 2 m/s at the gun to 12 m/s at 3 km (then steady)."""
    from fixtures import met_flight as M

    h = min(max(alt - M.GUN_ALTITUDE, 0.0), 3000.0)
    return (-2.0 - 10.0 * (1.0 - math.cos(math.pi * h / 3000.0)) / 2.0, 1.0)


def calm(alt):
    return (0.0, 0.0)


def _round_text(ref, profile, extra=""):
    from fixtures import met_flight as M

    head = f'reference_drag = "{ref}"\n' if ref else ""
    air = f'profile = "{profile}"\n' if profile else 'model = "icao"\n'
    return (f"[projectile]\nmass = 42.6\ndiameter = 0.155\n{head}[launch]\nelevation = {QE}\nvelocity = 818.0\n"
            f"azimuth = 90.0\naltitude = {M.GUN_ALTITUDE}\n[atmosphere]\n{air}{extra}[radar]\n"
            "sigma = {x = 1.0, y = 1.0, z = 1.0, v = 0.3}\n")


def case_inputs(name, folder):
    """(track, round) of case ``name``, its files written in ``folder``."""
    import bayesdrag
    from fixtures import met_flight as M

    folder = Path(folder)
    if name.startswith("demo"):
        from bayesdrag.commands.demo import demo_inputs

        tp, rp = demo_inputs()
        text = Path(rp).read_text()
        if name == "demo-g1":
            text = text.replace('reference_drag = "cd_m101.csv"', 'reference_drag = "G1"')
        else:
            text = text.replace('"cd_m101.csv"', f'"{Path(rp).parent / "cd_m101.csv"}"')
        (folder / "round.toml").write_text(text)
        return bayesdrag.read_track(tp), bayesdrag.read_round(folder / "round.toml")
    wind = growing if name.startswith("wind") else calm
    drag = None
    if name.startswith("calm"):
        m, cd = M.m101()
        drag = (m + SHIFT, SCALE * cd)
    t, pos, v, _, _ = M.fly(wind, 0.0, qe=QE, dt=DT, drag=drag)
    M.write_track(folder, t, pos, v, np.random.default_rng(45))
    ref = "" if name == "calm-no-table" else str(M.REF)
    profile = M.write_metcm(folder, wind, 0.0) if "metcm" in name else None
    extra = f"wind_sd = {WIND_SD}\n" if name.endswith("-sd") else ""
    (folder / "round.toml").write_text(_round_text(ref, profile, extra))
    return bayesdrag.read_track(folder / "track.csv"), bayesdrag.read_round(folder / "round.toml")


CASES = ("demo", "demo-g1", "calm-other-table", "calm-no-table", "wind-undeclared", "wind-metcm", "wind-metcm-sd")


def measure(name):
    """The warm default ``fit --no-mcmc`` of one case: its timing and what the check did."""
    import warnings

    import bayesdrag

    with tempfile.TemporaryDirectory() as tmp:
        track, rnd = case_inputs(name, tmp)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for _ in range(2):
                res = bayesdrag.fit(track, rnd, mcmc=False)
    d = res.to_dict()
    timing = d["timing"]
    ml = d["ml"]
    added = (ml.get("with_effects") or {}).get("effects", [])
    cost = (timing["total"] - timing["ml"]) / timing["ml"]
    return {"samples": track.n, "timing": timing, "check_ratio": round(cost, 3), "effects_added": added,
            "determined": int(sum(r["determined"] for r in d["cd"])), "rows": len(d["cd"]),
            "verdict": ((ml.get("quality") or {}).get("model_error") or {}).get("verdict")}


def own_work(name):
    """The check's own work on case ``name`` with the diagnosis already made, so a shared machine's
    fork decisions do not enter: the plain fit (timed: ``ml``), ``model_error`` given the
    diagnosis (best of two: ``check_own``) and the added effects' sizes (``sizes``), in seconds,
    all in this process with one BLAS thread."""
    import time
    import warnings

    from bayesdrag._runtime.threads import single_blas
    from bayesdrag.estimate.scheme1.effect_sizes import effect_sizes
    from bayesdrag.estimate.scheme1.fit import fit_scheme1
    from bayesdrag.options import FitOptions
    from bayesdrag.pipeline.ml import answer_of
    from bayesdrag.pipeline.model_check import diagnosis_record, model_error

    with tempfile.TemporaryDirectory() as tmp, single_blas(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        track, rnd = case_inputs(name, tmp)
        opts = FitOptions(mcmc=False)
        t0 = time.perf_counter()
        f1 = fit_scheme1(track, rnd, noise_model=opts.noise_model)
        ml = time.perf_counter() - t0
        diagnosis = diagnosis_record(track, rnd, track.names)
        own, fit = [], None
        for _ in range(2):
            ans = answer_of(f1, rnd, None)
            t0 = time.perf_counter()
            _, fit = model_error(track, rnd, opts, track.names, f1, ans.grid, ans.rows, diagnosis=diagnosis)
            own.append(time.perf_counter() - t0)
        sizes = None
        if fit is not None and fit.effects:
            t0 = time.perf_counter()
            effect_sizes(fit)
            sizes = time.perf_counter() - t0
    return {"ml": round(ml, 3), "check_own": round(min(own), 3), "sizes": None if sizes is None else round(sizes, 3),
            "effects": list(fit.effects) if fit is not None else []}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--json", default=None)
    ap.add_argument("--own", action="store_true",
                    help="the check's own work with the diagnosis made (own_work), not the fit's timing")
    args = ap.parse_args(argv)
    out = {}
    print(f"load {os.getloadavg()[0]:.2f}")
    if args.own:
        for name in args.only or CASES:
            out[name] = r = own_work(name)
            print(f"{name:18s} ml {r['ml']:6.2f} s  check's own {r['check_own']:6.2f} s  sizes "
                  f"{'-' if r['sizes'] is None else format(r['sizes'], '.2f')} s  added {','.join(r['effects']) or '-'}",
                  flush=True)
        print(json.dumps(out))
        return
    for name in args.only or CASES:
        out[name] = r = measure(name)
        t = r["timing"]
        print(f"{name:18s} n={r['samples']:5d} ml {t['ml']:6.2f} s  total {t['total']:6.2f} s  check/ml "
              f"{r['check_ratio']:5.2f}  added {','.join(r['effects_added']) or '-':22s} verdict "
              f"{','.join(r['verdict'] or []) or '-'}  {t}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
