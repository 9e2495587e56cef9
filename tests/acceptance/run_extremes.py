"""Extremes suite: the undeclared effects of the honesty suite at sizes and geometries beyond its
own, judged on the rows the default fit marks determined (DESIGN "How a fit is judged", the
honesty suite's rule and judge).

    python3 tests/acceptance/run_extremes.py [--only TEXT] [--json FILE]

74 flights, each with its own seed (900, 901, ...):

* constant winds of 12-15 m/s (head, tail, cross, quartering) at QE 5, 25 and 55, flown by the
  point mass, py-ballisticcalc and the 6-DOF simulator (36);
* radar clocks late by 5 ms, 0.1 s and 0.25 s at QE 8 and 40, point mass and 6-DOF (12);
* Coriolis at latitudes 10, 65, -35 and 45 deg, azimuths 0, 90, 180 and 300 deg, QE 15 and 50 (8);
* AR(1) noise of rho 0.8 and 0.97, alone and beside a wind, at QE 6, 30 and 50 (12);
* 1 % gross outliers, alone, beside a wind, and on a 6-DOF flight, at QE 10 and 35 (6).

About 6 minutes on 2 cores. Exit status 0 when no flight claims a wrong row. A flight may claim
few rows (AR(1) noise beside a wind often leaves none determined): honest, and counted apart.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from acceptance import cases as wc, honesty_suite as hs  # noqa: E402


def flights():
    """The suite's cases (HonestyCase) in order."""
    out = []

    def add(sim, eff, params, el, **kw):
        i = len(out)
        c = wc.Case(f"x-{sim}-{eff or 'null'}-{i:03d}", sim, eff, params, el, seed=900 + i, **kw)
        out.append(hs.HonestyCase(f"w-{c.id}", "withheld", seed=c.seed, withheld=c))

    for sim in ("pm", "pbc", "6dof"):
        for wx, wy in ((-15.0, 0.0), (12.0, 0.0), (0.0, 15.0), (-6.0, -9.0)):
            for el in (5.0, 25.0, 55.0):
                add(sim, "wind", {"wx": wx, "wy": wy}, el)
    for sim in ("pm", "6dof"):
        for dt in (0.005, 0.1, 0.25):
            for el in (8.0, 40.0):
                add(sim, "radar_time", {"dt": dt}, el)
    for lat, az in ((10.0, 0.0), (65.0, 90.0), (-35.0, 180.0), (45.0, 300.0)):
        for el in (15.0, 50.0):
            add("pm", "coriolis", {}, el, latitude=lat, azimuth=az)
    for rho in (0.8, 0.97):
        for el in (6.0, 30.0, 50.0):
            add("pm", None, {}, el, rho=rho)
            add("pm", "wind", {"wx": -7.0, "wy": 3.0}, el, rho=rho)
    for el in (10.0, 35.0):
        add("pm", None, {}, el, outliers=True)
        add("pm", "wind", {"wx": 6.0, "wy": 0.0}, el, outliers=True)
        add("6dof", None, {}, el, outliers=True)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", help="the flights whose id holds this text")
    ap.add_argument("--json", help="write every flight's row here")
    a = ap.parse_args(argv)
    rows = []
    for c in flights():
        if a.only and a.only not in c.id:
            continue
        r = hs.run_case(c)
        rows.append(r)
        w = c.withheld
        print(f"{c.id:24s} {str(w.params):34s} QE {w.elevation:4.0f} rho {w.rho:4.2f} outliers {int(w.outliers)}  "
              f"determined {r['determined']:3d}/{r['rows']:3d}  wrong {r['determined_wrong']:2d}  "
              f"worst z {r['worst_z_wrong']:.1f}", flush=True)
    wrong = sum(r["determined_wrong"] for r in rows)
    few = sum(1 for r in rows if r["determined"] < 0.6 * r["rows"])
    print(f"{len(rows)} flights, {sum(r['determined'] for r in rows)} rows determined, {wrong} wrong; "
          f"{few} flights with under 60 % of their rows determined")
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))
    return 0 if wrong == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
