"""Fits with winds that change along the flight (issue 29 part B): does ``bayesdrag fit --with
wind_profile`` give the right Cd(M) on tracks flown in winds the round does not state?

    python tests/acceptance/wind_fit_suite.py                  # the hold-out set, --with wind_profile
    python tests/acceptance/wind_fit_suite.py --with auto      # the diagnosis chooses the effects
    python tests/acceptance/wind_fit_suite.py --diagnose       # the diagnosis: a wind named first

Acceptance (DESIGN.md "How a fit is judged", the issue's): every row marked determined is right
(Cd within 2 % of the truth anywhere within +-0.01 Mach, or within 3 of its ``band_sd``) and at
least 60 % of the flown Mach span (less 5 % of its width at each end) stays determined.

The hold-out set (:data:`HOLDOUT`) was written after the fit's wind layers were built and was not
tuned on (its last four after the diagnosis's check of a wind profile at the fit's resolution): other shells and drag tables than the 155 mm M101 flights the wind models were built
on, other zone layouts and heights, one met profile stated wrong with ``[atmosphere] wind_sd``
declared.

* ``pbc`` flights: py-ballisticcalc's own integrator and PCHIP of its standard tables, winds in
  zones by downrange distance (``Wind(until_distance=...)``), the air the round states; the truth
  is py-ballisticcalc's interpolation of the table (:func:`pbc_suite.truth_cd`).
* ``pm`` flights: bayesdrag's point mass with the scipy reference integrator (not the kernel
  the fit uses) in a wind by height (met practice), the table as bayesdrag interpolates it.

The round handed to the fit has the right table, the launch values and the radar noise; its air
is calm and standard unless the case states a met profile (``stated``), so the wind is what the
fit must find.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: a row is right within this relative error of the truth ...
REL_TOL = 0.02
#: ... or within this many of its band_sd
SD_TOL = 3.0
#: the truth is taken anywhere within this much Mach of the row (steep slopes)
MACH_SLACK = 0.01
#: at least this share of the judged span stays determined
DETERMINED_MIN = 0.6
#: the judged span is the flown one less this share of its width at each end
SPAN_TRIM = 0.05
#: sampling interval [s] of every track
DT = 0.05


@dataclass(frozen=True)
class WindCase:
    """A shell of ``mass`` [kg], ``diameter`` [m] and drag ``table`` fired at ``v0`` [m/s] and
    ``qe`` [deg] in a wind: ``zones`` [(wx, wy, until_m)] by downrange distance (py-ballisticcalc)
    or ``levels`` [m above the gun] with ``wx``, ``wy`` [m/s] by height (point mass; ``layered``:
    constant between levels). ``stated`` (a factor): the round states the true wind by height
    times it, with ``wind_sd`` [m/s] declared."""

    name: str
    sim: str
    table: str
    mass: float
    diameter: float
    v0: float
    qe: float
    pos_sd: float
    seed: int
    zones: tuple = ()
    levels: tuple = ()
    wx: tuple = ()
    wy: tuple = ()
    layered: bool = False
    stated: float | None = None
    wind_sd: float | None = None


HOLDOUT = (
    WindCase("h105-g7-zones3", "pbc", "G7", 15.0, 0.105, 600.0, 25.0, 1.0, 61,
             zones=((-3.0, 4.0, 2000.0), (5.0, -2.0, 6000.0), (9.0, 0.0, None))),
    WindCase("h130-g1-zones2", "pbc", "G1", 33.4, 0.130, 810.0, 12.0, 1.0, 62,
             zones=((6.0, 0.0, 3500.0), (-7.0, 3.0, None))),
    WindCase("h120-g2-mortar", "pbc", "G2", 13.0, 0.120, 300.0, 50.0, 1.5, 63,
             zones=((0.0, 6.0, 1500.0), (-5.0, -3.0, None))),
    WindCase("h130-gi-zones2", "pbc", "GI", 33.4, 0.130, 700.0, 30.0, 1.0, 64,
             zones=((-8.0, -2.0, 8000.0), (2.0, 5.0, None))),
    WindCase("a105-g5-height", "pm", "G5", 15.0, 0.105, 480.0, 40.0, 1.0, 65,
             levels=(0.0, 1000.0, 2500.0, 4500.0), wx=(2.0, -4.0, -9.0, -12.0), wy=(-1.0, 2.0, 5.0, 3.0)),
    WindCase("a130-g1-layers", "pm", "G1", 33.4, 0.130, 810.0, 35.0, 1.0, 66,
             levels=(0.0, 2000.0, 5000.0, 9000.0), wx=(6.0, 0.0, -10.0), wy=(3.0, -2.0, -5.0), layered=True),
    WindCase("a155-gi-stated", "pm", "GI", 45.0, 0.155, 684.0, 45.0, 1.5, 67,
             levels=(0.0, 1500.0, 4000.0, 8000.0), wx=(-3.0, -8.0, -14.0, -20.0), wy=(2.0, 4.0, 8.0, 6.0),
             stated=0.6, wind_sd=4.0),
    # written after the diagnosis's check of a wind profile at the fit's resolution (issue 29), not
    # tuned on: other shells and tables again (G8, G6, GS; an 81 mm mortar, a 175 mm gun), zone
    # steps at other distances, a layered wind by height on a flat fire
    WindCase("n076-g8-zones3", "pbc", "G8", 6.2, 0.076, 680.0, 18.0, 1.0, 68,
             zones=((4.0, -2.0, 1800.0), (-6.0, 1.0, 4500.0), (2.0, 5.0, None))),
    WindCase("n152-g6-zones2", "pbc", "G6", 43.5, 0.152, 655.0, 42.0, 1.0, 69,
             zones=((-9.0, 3.0, 5500.0), (3.0, -4.0, None))),
    WindCase("n081-gs-mortar-height", "pm", "GS", 4.1, 0.081, 250.0, 55.0, 1.0, 70,
             levels=(0.0, 600.0, 1500.0, 2500.0), wx=(3.0, -2.0, -7.0, -10.0), wy=(-4.0, -1.0, 2.0, 6.0)),
    WindCase("n175-g7-layers-flat", "pm", "G7", 66.8, 0.175, 900.0, 20.0, 1.0, 71,
             levels=(0.0, 800.0, 2000.0, 5000.0), wx=(-5.0, 4.0, 9.0), wy=(2.0, -3.0, 0.0), layered=True),
)


def _sigma(case):
    return {"x": case.pos_sd, "y": case.pos_sd, "z": case.pos_sd, "v": round(0.1 * case.pos_sd, 4)}


def _reference(case):
    from bayesdrag.drag import ReferenceTable
    from pbc_suite import table

    m, c = table(case.table)
    return ReferenceTable(tuple(m), tuple(c), source=case.table)


def _height_wind(case, factor=1.0):
    from bayesdrag.air.wind import WindProfile

    wx, wy = tuple(factor * v for v in case.wx), tuple(factor * v for v in case.wy)
    if case.layered:
        return WindProfile.layered("altitude", case.levels, wx, wy)
    return WindProfile("altitude", case.levels, wx, wy)


def truth_track(case):
    """The noise-free track of a case (launch to impact, every :data:`DT` s)."""
    from bayesdrag.air.atmosphere import Atmosphere
    from bayesdrag.dynamics.pointmass import PointMassModel
    from bayesdrag.dynamics.trajectory import initial_state
    from bayesdrag.track import RadarTrack

    if case.sim == "pbc":
        from pbc_suite import table
        from support import pbc_reference

        m, c = table(case.table)
        o = pbc_reference.pbc_trajectory(m, c, case.mass, case.diameter, case.v0, case.qe,
                                         t_out=np.arange(0.0, 400.0, DT), wind_zones=list(case.zones))
        ok = np.isfinite(o["x"]) & (o["z"] >= 0)
        return RadarTrack(o["t"][ok], {k: o[k][ok] for k in ("x", "y", "z", "v")}, {}, source="pbc")
    model = PointMassModel(case.mass, case.diameter, _reference(case), Atmosphere(wind=_height_wind(case)))
    s0 = initial_state(case.v0, case.qe)
    first = model.simulate((), s0, backend="scipy", stop_at_impact=True, dt=DT)
    st = model.simulate((), s0, np.arange(0.0, first.t_impact, DT), backend="scipy").state
    return RadarTrack(np.arange(0.0, first.t_impact, DT), {"x": st[:, 0], "y": st[:, 1], "z": st[:, 2],
                                                          "v": np.linalg.norm(st[:, 3:], axis=1)}, {}, source="pm")


def round_of(case):
    """The round the fit sees: the right table, the launch, the radar noise; calm standard air
    unless the case states a (wrong) wind by height with its ``wind_sd``."""
    from bayesdrag.air.atmosphere import Atmosphere
    from bayesdrag.round import Launch, Projectile, Radar, Round, Systematics

    atm = Atmosphere(wind=_height_wind(case, case.stated)) if case.stated is not None else Atmosphere()
    return Round(Projectile(case.name, case.mass, case.diameter, _reference(case)),
                 Launch(elevation_deg=case.qe, velocity=case.v0, azimuth_deg=90.0), atmosphere=atm,
                 radar=Radar(_sigma(case)), systematics=Systematics(wind_profile=case.wind_sd))


def truth_cd(case, mach):
    """Cd the simulator flew at ``mach``."""
    if case.sim == "pbc":
        from pbc_suite import truth_cd as pbc_truth

        return pbc_truth(case.table, mach)
    return np.asarray(_reference(case).value(np.asarray(mach, float)), float)


def judge(record, truth):
    """``(wrong determined rows, determined share of the judged span, rows judged)`` of a
    result.json record; ``truth(mach array) -> Cd``."""
    lo, hi = record["ml"]["mach_range_data"]
    w = hi - lo
    wrong, inside = [], []
    for r in record["cd"]:
        tv = np.asarray(truth(np.linspace(r["mach"] - MACH_SLACK, r["mach"] + MACH_SLACK, 21)), float)
        err = float(np.min(np.abs(r["ml"] - tv)))
        sd = r.get("band_sd") or r["crb_sd"]
        right = err <= REL_TOL * float(np.max(tv)) or err <= SD_TOL * sd
        if r["determined"] and not right:
            wrong.append({"mach": r["mach"], "ml": r["ml"], "truth": float(np.mean(tv)), "band_sd": sd})
        if lo + SPAN_TRIM * w <= r["mach"] <= hi - SPAN_TRIM * w:
            inside.append(r["determined"])
    return wrong, (sum(inside) / len(inside) if inside else 0.0), len(inside)


def run_case(case, with_effects=("wind_profile",)):
    """Fit one case (ML, no sampling) and judge it; returns a JSON-able record."""
    import bayesdrag
    from bayesdrag.synthetic import add_noise

    track = add_noise(truth_track(case), _sigma(case), np.random.default_rng(2900 + case.seed))
    t0 = time.perf_counter()
    res = bayesdrag.fit(track, round_of(case), mcmc=False, with_effects=with_effects)
    rec = res.to_dict()
    wrong, share, n = judge(rec, lambda m: truth_cd(case, m))
    we = rec["ml"].get("with_effects") or {}
    lay = we.get("wind_layers") or {}
    return {"name": case.name, "with": with_effects if isinstance(with_effects, str) else list(with_effects), "fitted": we.get("fitted"), "axis": lay.get("axis"),
            "determined_wrong": len(wrong), "determined_share": round(share, 3), "rows_judged": n,
            "ok": not wrong and share >= DETERMINED_MIN,
            "chi2": {c: round(v["chi2_per_sample"], 2) for c, v in rec["ml"]["quality"]["channels"].items()},
            "budget_wind_profile": "wind_profile" in rec["uncertainty_budget"]["by_source"],
            "layers": [[round(v["wx"], 2), round(v["wy"], 2)] for v in lay.get("layers", [])],
            "wrong": wrong[:3], "seconds": round(time.perf_counter() - t0, 1)}


def diagnose_case(case):
    """Diagnose one case (the round's air as the fit sees it): is a wind named first, and how
    much of the gap does it remove (the issue's >= 0.9)?"""
    import bayesdrag
    from bayesdrag.synthetic import add_noise

    track = add_noise(truth_track(case), _sigma(case), np.random.default_rng(2900 + case.seed))
    t0 = time.perf_counter()
    s = bayesdrag.diagnose(track, round_of(case)).to_dict()
    rows = {r["name"]: r for r in s["effects"]}
    first = s["verdict"][0] if s["verdict"] else None
    shrink = rows[first]["shrink"] if first in rows else None
    return {"name": case.name, "verdict": s["verdict"], "wind_first": first in ("wind", "wind_profile"),
            "wind_shrink": shrink, "ok": first in ("wind", "wind_profile") and (shrink or 0.0) >= 0.9,
            "axis": (rows.get("wind_profile", {}).get("layers") or {}).get("axis"),
            "seconds": round(time.perf_counter() - t0, 1)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=None, help="comma-separated case names")
    ap.add_argument("--with", dest="with_", default="wind_profile", help="the fit's --with (default wind_profile)")
    ap.add_argument("--out", default=None, help="write the records to this JSON file")
    ap.add_argument("--diagnose", action="store_true", help="diagnose the flights instead of fitting them")
    a = ap.parse_args(argv)
    cases = [c for c in HOLDOUT if a.only is None or c.name in a.only.split(",")]
    if a.diagnose:
        out = [diagnose_case(c) for c in cases]
        for r in out:
            print(json.dumps(r), flush=True)
        print(json.dumps({"n": len(out), "ok": sum(r["ok"] for r in out)}))
        return 0 if all(r["ok"] for r in out) else 1
    w = a.with_ if a.with_ in ("auto", "none") else tuple(a.with_.split(","))
    w = () if w == "none" else w
    out = []
    for c in cases:
        r = run_case(c, w)
        out.append(r)
        print(json.dumps(r), flush=True)
    summary = {"n": len(out), "ok": sum(r["ok"] for r in out),
               "determined_wrong": sum(r["determined_wrong"] for r in out),
               "min_determined_share": min((r["determined_share"] for r in out), default=None)}
    if a.out:
        Path(a.out).write_text(json.dumps({"cases": out, "summary": summary}, indent=1))
    print(json.dumps(summary))
    return 0 if summary["ok"] == summary["n"] else 1


if __name__ == "__main__":
    sys.exit(main())
