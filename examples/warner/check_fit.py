"""Fit the converted Warner Doppler tracks and compare with the published Cd.

Steps, for each bullet (files from ``convert.py``):

1. ``reference-scale`` fit in the round's standard atmosphere: the fitted factor f multiplies
   the published Cd. Drag depends on rho * Cd only, so f < 1 says the air was thinner than
   ICAO sea level by that ratio (or the published Cd is f too high: the two are confounded;
   ``bayesdrag diagnose`` weighs density against temperature and drag_scale).
2. With ``[atmosphere] density_ratio = f`` (written as ``round_density.toml``): flexible fits
   (``poly2`` and a 3-knot spline) on x and v, and on v alone, and their error against the
   published Cd at every published Mach inside the Mach range of the data.
3. A figure ``docs/figures/warner_cd.png`` (fitted vs published Cd).

Run: ``python examples/warner/check_fit.py`` (a few seconds). Prints one JSON line last.
"""
from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from bayesdrag.estimate.cd.table import cd_table
from bayesdrag.estimate.scheme1.fit import fit_scheme1
from bayesdrag.io.rounds import read_round, write_round
from bayesdrag.io.tracks import read_track

HERE = Path(__file__).resolve().parent
BULLETS = ("338_flatline", "65_flatline")
#: spline knots for a 16-sample Doppler track (the default knot set has too many coefficients
#: for 16 samples); 3 knots spanning the data's Mach range
SPLINE_KNOTS = (1.3, 2.0, 2.9)
FITS = (("poly2", None), ("spline", SPLINE_KNOTS))
CHANNELS = (("x", "v"), ("v",))


def _errors(res, prob, ref):
    lo, hi = float(res.mach.min()), float(res.mach.max())
    mach = np.array([m for m in ref.mach if lo <= m <= hi])
    rows = cd_table(res, prob.model.drag, mach, ref)
    return lo, hi, rows


def check(bullet, write=True):
    d = HERE / bullet
    track, rnd = read_track(d / "track.csv"), read_round(d / "round.toml")
    ref = rnd.reference_drag
    f1 = fit_scheme1(track, rnd, drag="reference-scale")
    res = f1.ml
    factor = float(res.params["factor"])
    thin = dataclasses.replace(rnd, atmosphere=dataclasses.replace(rnd.atmosphere, density_ratio=factor))
    if write:
        write_round(d / "round_density.toml", thin,
                    comment=f"{rnd.projectile.name}: round.toml with density_ratio = {factor:.4f}, the factor of a\n"
                            f"reference-scale fit in ICAO air (examples/warner/check_fit.py); not a measured density")
    out = {"bullet": bullet, "reference_scale_factor": round(factor, 4),
           "reference_scale_crb": round(float(res.crb[list(res.names).index("factor")]), 5), "fits": []}
    curves = []
    for drag, knots in FITS:
        for ch in CHANNELS:
            f1 = fit_scheme1(track, thin, drag=drag, channels=ch, knots=knots)
            r, prob = f1.ml, f1.problem
            lo, hi, rows = _errors(r, prob, ref)
            err = [100 * (row["ml"] / row["reference"] - 1) for row in rows]
            out["fits"].append({"drag": drag, "channels": ",".join(ch), "converged": bool(r.converged),
                                "mach_range": [round(lo, 3), round(hi, 3)],
                                "published_mach": [row["mach"] for row in rows],
                                "error_percent": [round(e, 2) for e in err],
                                "max_abs_error_percent": round(max(abs(e) for e in err), 2)})
            if ch == ("x", "v"):
                grid = np.linspace(lo, hi, 60)
                curves.append((f"{drag}, x+v", grid, np.array([row["ml"] for row in cd_table(r, prob.model.drag, grid)])))
    return out, curves, ref, factor


def figure(results, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(results), figsize=(10, 4), constrained_layout=True)
    for ax, (out, curves, ref, factor) in zip(np.atleast_1d(axes), results):
        ax.plot(ref.mach, ref.cd_values, "ko", label="published (Warner)")
        for label, m, cd in curves:
            ax.plot(m, cd, label=f"fit, density x {factor:.3f} ({label})")
        lo, hi = curves[0][1][[0, -1]]
        m = np.linspace(lo, hi, 60)
        ax.plot(m, factor * ref.value(m), "k:", label=f"reference-scale fit in ICAO air (published x {factor:.3f})")
        ax.set(xlabel="Mach", ylabel="Cd", title=out["bullet"].replace("_", " "))
        ax.legend(fontsize=7)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    results = [check(b) for b in BULLETS]
    for out, *_ in results:
        print(f"{out['bullet']}: reference-scale factor {out['reference_scale_factor']} "
              f"(CRB sd {out['reference_scale_crb']})")
        for f in out["fits"]:
            print(f"  {f['drag']:7s} {f['channels']:4s} Mach {f['mach_range'][0]:.2f}-{f['mach_range'][1]:.2f}: "
                  f"error % at published Mach {f['published_mach']}: {f['error_percent']}")
    fig_dir = HERE.parents[1] / "docs" / "figures"
    if fig_dir.is_dir():
        figure(results, fig_dir / "warner_cd.png")
    print(json.dumps([r[0] for r in results]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
