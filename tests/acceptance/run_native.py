"""Run the native acceptance suite: radar-native tracks fitted with the default options, judged.

    python tests/acceptance/run_native.py [--small | --holdout] [--case ID ...] [--json OUT]

Each case is one flight (shell, launch, the radar's site and channels, noise, and an undeclared
effect or none) simulated by the point mass and recorded in the radar's own coordinates
(``range, azimuth, elevation, range_rate`` seen from its site, noise in those coordinates), then
fitted by :func:`bayesdrag.fit` (default options, no posterior) and judged by the project's rule:
a Cd row is right within 2 % of the truth (taken anywhere within +-0.01 Mach) or within 3 of its
band sd; every row inside the flown Mach span (5 % margin at each end) is judged, and a row
marked determined that is wrong is the defect counted. The effects the default fit added are
sized against the truth (|z| in the fit's sd; within 3 sd or not).

Columns: rows judged, right, determined, determined but wrong, determined share, quality gate,
seconds, the diagnosis's verdict (the model check's), the effects the fit added and their size.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from acceptance import honesty_suite as hs  # noqa: E402

#: a tracking radar's noise: 2 m in range, 0.03 deg in each angle, 0.1 m/s in range rate
TRACKING = {"range": 2.0, "azimuth": math.radians(0.03), "elevation": math.radians(0.03), "range_rate": 0.1}
#: a Doppler radar's range rate noise [m/s]
DOPPLER = {"range_rate": 0.1}
#: sample interval [s] of the suite's tracks (longer than a radar's 27 ms: the suite's cost)
DT = 0.05


@dataclass(frozen=True)
class NativeCase:
    """One flight: ``shell`` of :data:`acceptance.honesty_suite.SHELLS`, muzzle speed [m/s] and QE
    [deg], the radar's ``site`` [m, gun frame] and ``sigma`` (its channels), a ``noise`` factor
    on that sigma, and the undeclared ``wind`` (wx, wy) [m/s] and radar ``clock`` offset [s]."""

    id: str
    shell: str
    v0: float
    qe: float
    site: tuple
    sigma: dict = field(default_factory=lambda: dict(TRACKING))
    noise: float = 1.0
    wind: tuple = (0.0, 0.0)
    clock: float = 0.0
    seed: int = 0

    @property
    def effect(self):
        names = (["wind"] if any(self.wind) else []) + (["radar_time"] if self.clock else [])
        return "+".join(names) or "none"


def _rr():
    return dict(DOPPLER)


def _angles():
    return {c: TRACKING[c] for c in ("range", "azimuth", "elevation")}


CASES = [
    NativeCase("trk-155-qe45-behind", "155", 818.0, 45.0, (-40.0, 25.0, 2.0), seed=2801),
    NativeCase("trk-155-qe45-beside-wind", "155", 818.0, 45.0, (-5.0, 30.0, 1.0), _angles(), wind=(-6.0, 0.0),
               seed=2802),
    NativeCase("trk-155-qe45-beside-clock", "155", 818.0, 45.0, (-5.0, 30.0, 1.0), _angles(), clock=0.04, seed=2803),
    NativeCase("trk-155-qe30-far-side", "155", 818.0, 30.0, (2000.0, -3000.0, 10.0), noise=2.0, seed=2804),
    NativeCase("trk-s105-qe25-behind-xwind", "s105", 600.0, 25.0, (-30.0, -10.0, 1.0), wind=(4.0, -6.0), seed=2805),
    NativeCase("trk-s105-qe40-beside-noisy", "s105", 600.0, 40.0, (0.0, 50.0, 3.0), noise=3.0, seed=2806),
    NativeCase("trk-m81-qe50-behind-clock", "m81", 300.0, 50.0, (-15.0, 5.0, 1.0), clock=0.03, seed=2807),
    NativeCase("dop-120-qe60-behind", "m120", 310.0, 60.0, (-10.0, 0.0, 1.0), _rr(), seed=2808),
    NativeCase("dop-120-qe60-behind-wind", "m120", 310.0, 60.0, (-10.0, 0.0, 1.0), _rr(), wind=(-6.0, 0.0),
               seed=2809),
    NativeCase("dop-120-qe60-behind-clock", "m120", 310.0, 60.0, (-10.0, 0.0, 1.0), _rr(), clock=0.04, seed=2810),
    NativeCase("dop-155-qe15-behind-xwind", "155", 818.0, 15.0, (-20.0, 0.0, 1.5), _rr(), wind=(0.0, 5.0),
               seed=2811),
    NativeCase("dop-m81-qe45-behind-noisy", "m81", 300.0, 45.0, (-8.0, 1.0, 0.5), _rr(), noise=3.0, seed=2812),
]
#: cases written after the suite's figures were settled, never tuned on (``--holdout``): a radar
#: near the impact looking back, one on a hill to the side, Doppler radars beside and behind in
#: high-angle fire, angles alone from 4 km to the side (it found the start curve read off such
#: positions trading against the initial position: fixed by holding it, issue 28), a noisy
#: mortar, a rifle bullet in flat fire, and a clock offset beside a wind
HOLDOUT = [
    NativeCase("ho-155-qe30-downrange-lookback", "155", 818.0, 30.0, (16000.0, 300.0, 20.0), seed=7001),
    NativeCase("ho-155-qe55-hill-side", "155", 818.0, 55.0, (500.0, -1500.0, 150.0), wind=(3.0, -4.0), seed=7002),
    NativeCase("ho-s105-qe20-dop-beside-clock", "s105", 600.0, 20.0, (0.0, 15.0, 1.0), _rr(), clock=0.03,
               seed=7003),
    NativeCase("ho-m81-qe65-dop-behind-wind", "m81", 300.0, 65.0, (-6.0, 2.0, 0.5), _rr(), wind=(5.0, 0.0),
               seed=7004),
    NativeCase("ho-155-qe40-ang-far-xwind", "155", 818.0, 40.0, (1000.0, 4000.0, 30.0), _angles(),
               wind=(0.0, 7.0), seed=7005),
    NativeCase("ho-m120-qe45-trk-behind-noisy-wind", "m120", 310.0, 45.0, (-20.0, -10.0, 1.0), noise=2.5,
               wind=(-4.0, 3.0), seed=7006),
    NativeCase("ho-b308-qe2-dop-behind", "b308", 850.0, 2.0, (-2.0, 0.5, 0.2), _rr(), seed=7007),
    NativeCase("ho-s105-qe35-trk-beside-clock-wind", "s105", 600.0, 35.0, (0.0, 40.0, 2.0), clock=0.02,
               wind=(-5.0, 2.0), seed=7008),
]
#: the quick subset (--small): one tracking radar and one Doppler radar with an effect, two clean
SMALL = ("trk-155-qe45-behind", "trk-155-qe45-beside-clock", "dop-120-qe60-behind", "dop-120-qe60-behind-wind")
#: the suite's shells beside the honesty suite's: a 120 mm mortar bomb on the M101 curve
SHELLS = {**hs.SHELLS, "m120": dict(mass=13.2, diameter=0.12, table="M101")}


def case_by_id(cid):
    for c in CASES + HOLDOUT:
        if c.id == cid:
            return c
    raise KeyError(f"no native case {cid!r}; cases: {', '.join(c.id for c in CASES + HOLDOUT)}")


def make(case):
    """(track, round, truth) of a case: the track in the radar's own channels with noise in its
    coordinates; truth ``{"cd": Cd(M), "mach_span": (lo, hi)}`` of the flight as flown."""
    from bayesdrag.drag import ReferenceTable
    from bayesdrag.round import Launch, Projectile, Radar, Round
    from bayesdrag.synthetic import add_noise, simulate_round

    sh = SHELLS[case.shell]
    M, C = hs._table(sh["table"])
    ref = ReferenceTable(tuple(M), tuple(C), source=sh["table"])
    sigma = {c: s * case.noise for c, s in case.sigma.items()}
    rnd = Round(Projectile(case.shell, sh["mass"], sh["diameter"], ref, None),
                Launch(case.qe, case.v0, azimuth_deg=90.0), radar=Radar(dict(sigma), position=case.site),
                path=f"{case.id}.toml")
    kw = dict(dt=DT, clock_offset=case.clock, wind=(case.wind[0], case.wind[1], 0.0))
    clean = simulate_round(rnd, channels=tuple(sigma), **kw)
    track = add_noise(clean, sigma, np.random.default_rng(case.seed))
    mach = _flown_mach(rnd, case, np.asarray(clean.t, float) + case.clock)
    truth = {"cd": lambda m: np.asarray(ref.cd((), np.asarray(m, float)), float),
             "mach_span": (float(np.min(mach)), float(np.max(mach)))}
    return track, rnd, truth


def _flown_mach(rnd, case, t_true):
    """Mach of the flight (its airspeed in the wind) at the samples' true times."""
    from bayesdrag.dynamics.pointmass import PointMassModel
    from bayesdrag.dynamics.trajectory import initial_state

    model = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, rnd.reference_drag, rnd.atmosphere,
                           wind=(case.wind[0], case.wind[1], 0.0))
    return np.asarray(model.simulate((), initial_state(case.v0, case.qe), t_true, backend="scipy").mach, float)


def _effect_sizes(d, case):
    """The added effects' parameters with a truth: value, sd, truth, z."""
    ml = d["ml"]
    truth = {}
    if any(case.wind):
        truth["wind.wx"] = case.wind[0]
        truth["wind.wy"] = case.wind[1]
    if case.clock:
        truth["radar_time.dt"] = case.clock
    out = []
    for name, t in truth.items():
        v, sd = ml.get("params", {}).get(name), (ml.get("crb") or {}).get(name)
        if v is None or not sd:
            continue
        out.append({"name": name, "value": float(v), "sd": float(sd), "truth": float(t), "z": float((v - t) / sd)})
    return out


def run_case(case):
    """Fit one case with the default options (no posterior) and judge it."""
    import bayesdrag

    track, rnd, truth = make(case)
    try:
        res = bayesdrag.fit(track, rnd, mcmc=False)
    except (bayesdrag.InputError, bayesdrag.FitError) as exc:
        return {"id": case.id, "effect": case.effect, "error": str(exc)}
    d = res.to_dict()
    q = d["ml"]["quality"]
    out = {"id": case.id, "effect": case.effect, **hs.judge(d, truth), "quality_ok": bool(q["ok"]),
           "verdict": list((q.get("model_error") or {}).get("verdict") or []),
           "diagnosis_failed": (q.get("model_error") or {}).get("diagnosis_failed")}
    we = d["ml"].get("with_effects") or {}
    out["effects_added"] = list(we.get("fitted") or [])
    out["effect_size"] = _effect_sizes(d, case) if out["effects_added"] else []
    out["effect_size_ok"] = (all(abs(p["z"]) <= hs.EFFECT_TOL_SD for p in out["effect_size"])
                             if out["effect_size"] else None)
    return out


def _size(r):
    if r.get("effect_size_ok") is None:
        return ""
    worst = max(abs(p["z"]) for p in r["effect_size"])
    return f" {worst:.1f} {'y' if r['effect_size_ok'] else 'n'}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--small", action="store_true", help="the quick subset: " + ", ".join(SMALL))
    ap.add_argument("--case", nargs="*")
    ap.add_argument("--holdout", action="store_true", help="the hold-out cases (HOLDOUT) instead of the suite's")
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    cases = ([case_by_id(c) for c in a.case] if a.case else list(HOLDOUT) if a.holdout
             else [c for c in CASES if not a.small or c.id in SMALL])
    print(f"{'case':30s} {'effect':16s} {'rows':>4s} {'right':>5s} {'det':>4s} {'WRONG':>5s} {'det %':>6s} "
          f"{'ok':>3s} {'s':>6s}  verdict / added  size (max |z|)")
    out = []
    t_all = time.perf_counter()
    for c in cases:
        t0 = time.perf_counter()
        r = run_case(c)
        r["seconds"] = round(time.perf_counter() - t0, 1)
        out.append(r)
        if "error" in r:
            print(f"{c.id:30s} {r['effect']:16s} ERROR {r['error'][:80]}", flush=True)
            continue
        print(f"{c.id:30s} {r['effect']:16s} {r['rows']:4d} {r['right']:5d} {r['determined']:4d} "
              f"{r['determined_wrong']:5d} {100 * r['determined_fraction']:6.1f} {'y' if r['quality_ok'] else 'n':>3s} "
              f"{r['seconds']:6.1f}  {','.join(r['verdict']) or '-'} / {','.join(r['effects_added']) or '-'}"
              f"{_size(r)}" + (f"  (diagnosis failed: {r['diagnosis_failed'][:60]})" if r["diagnosis_failed"] else ""),
              flush=True)
    ok = [r for r in out if "error" not in r]
    bad = [r for r in ok if r["determined_wrong"]]
    sized = [r for r in ok if r.get("effect_size_ok") is not None]
    print(f"\n{len(out)} cases, {len(out) - len(ok)} errors; cases with a wrong determined row: {len(bad)} "
          f"({', '.join(r['id'] for r in bad)}); determined rows wrong: "
          f"{sum(r['determined_wrong'] for r in ok)}/{sum(r['determined'] for r in ok)}; rows right (accuracy): "
          f"{sum(r['right'] for r in ok)}/{sum(r['rows'] for r in ok)}; mean determined share "
          f"{sum(r['determined_fraction'] for r in ok) / max(len(ok), 1):.2f}; added effects sized within "
          f"{hs.EFFECT_TOL_SD:g} sd: {sum(bool(r['effect_size_ok']) for r in sized)}/{len(sized)}; "
          f"{time.perf_counter() - t_all:.0f} s")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))
    return 1 if bad or len(ok) < len(out) else 0


if __name__ == "__main__":
    sys.exit(main())
