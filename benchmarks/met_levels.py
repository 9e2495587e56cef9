"""What a dense sounding costs: reading a met CSV of N levels and the ML fit of a 155 mm track
through it (no model check), against the six-level file of the same air, in the same run
(issue 44, item 10).

    python3 benchmarks/met_levels.py [--quick]

A met CSV is thinned on reading to at most ``bayesdrag.io.met.MAX_MET_LEVELS`` levels, so the
cost of a file of 200 000 levels (11 MB) is its reading, not the fit's. Before the thinning, a
20 000-level file took 88 s and 805 MB through a fit and 200 000 levels gave no result in 500 s.
The last line is a JSON object: per N, ``read_seconds``, ``fit_seconds``, ``levels_flown`` and
``ratio_to_6`` (read plus fit, over the six-level file's).
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROUND = """[projectile]
mass = 42.6
diameter = 0.155
reference_drag = "G1"
[launch]
elevation = 40.0
velocity = 818.0
azimuth = 90.0
altitude = 150.0
[atmosphere]
profile = "met.csv"
"""


def write_met(folder, n):
    """A met CSV of ``n`` levels from the gun (150 m) to 8 km: ICAO + 8 K, a wind growing with height."""
    from bayesdrag.air.atmosphere import standard_atmosphere

    z = np.linspace(150.0, 8000.0, n)
    s = standard_atmosphere(z, temperature_offset=8.0, gun_altitude=150.0)
    wx = -2.0 - 10.0 * (z - 150.0) / 7850.0
    body = "".join(f"{a:.2f},{b:.2f},{c:.1f},{d:.2f},1.0\n" for a, b, c, d in zip(z, s.temperature, s.pressure, wx))
    (Path(folder) / "met.csv").write_text("altitude,temperature,pressure,wind_x,wind_y\n" + body)
    (Path(folder) / "r.toml").write_text(ROUND)
    return Path(folder) / "r.toml"


def measure(n, track):
    import bayesdrag
    from bayesdrag.io.rounds import read_round

    with tempfile.TemporaryDirectory() as tmp:
        path = write_met(tmp, n)
        t0 = time.perf_counter()
        rnd = read_round(path)
        t1 = time.perf_counter()
        bayesdrag.fit(track, rnd, mcmc=False, model_check=False, with_effects="none")
        t2 = time.perf_counter()
    return {"read_seconds": round(t1 - t0, 3), "fit_seconds": round(t2 - t1, 3),
            "levels_flown": len(rnd.atmosphere.altitude)}


def track_of_six_levels():
    """The shell's track through the six-level file, with radar noise (seed 0), 0.1 s apart."""
    from bayesdrag.io.rounds import read_round
    from bayesdrag.synthetic import add_noise, simulate_round

    with tempfile.TemporaryDirectory() as tmp:
        rnd = read_round(write_met(tmp, 6))
        tr = simulate_round(rnd, dt=0.1)
    return add_noise(tr, {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}, np.random.default_rng(0))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="up to 20 000 levels")
    args = ap.parse_args(argv)
    sizes = (6, 2000, 20_000) if args.quick else (6, 2000, 20_000, 200_000)
    track = track_of_six_levels()
    measure(6, track)                            # compile and warm
    out = {}
    for n in sizes:
        out[n] = measure(n, track)
        print(f"{n:7d} levels: read {out[n]['read_seconds']:.3f} s, fit {out[n]['fit_seconds']:.3f} s, "
              f"{out[n]['levels_flown']} levels flown", file=sys.stderr)
    base = out[6]["read_seconds"] + out[6]["fit_seconds"]
    for n in sizes:
        out[n]["ratio_to_6"] = round((out[n]["read_seconds"] + out[n]["fit_seconds"]) / base, 2)
    print(json.dumps({str(k): v for k, v in out.items()}))


if __name__ == "__main__":
    main()
