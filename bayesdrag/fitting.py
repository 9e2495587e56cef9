"""``bayesdrag fit``: read a track and a round, fit, write result.json and figures.

Kept apart from :mod:`bayesdrag.cli` (argument parsing, exit codes) and from the estimators
(:mod:`bayesdrag.estimate`), which stay free of I/O.
"""
from __future__ import annotations

import sys
from pathlib import Path

from .errors import FitError, InputError
from .outputs import atomic_write as _atomic_write
from .outputs import write_json as _write_json


def run_fit(args):
    import numpy as np

    from .estimate.scheme1 import cd_table, determined_range, fit_scheme1
    from .track import read_round, read_track

    track = read_track(args.track)
    rnd = read_round(args.round)
    for note in getattr(track, "notes", ()):
        print(f"bayesdrag: note: {note}", file=sys.stderr)
    chans = None
    if args.channels:
        chans = tuple(c.strip() for c in args.channels.split(",") if c.strip())
        bad = [c for c in chans if c not in track.names]
        if bad or not chans:
            raise InputError(f"command line: --channels {args.channels!r}: {', '.join(bad) or 'empty'} not in "
                             f"the track {args.track} (it has {', '.join(track.names)})")
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: output path exists and is not a folder")
    res, prob = fit_scheme1(track, rnd, drag=args.drag, channels=chans, free_ic=not args.fix_ic)
    if not res.success:
        from .errors import FitError

        raise FitError(f"{args.track}: {res.message}")
    out.mkdir(parents=True, exist_ok=True)
    dm = prob.model.drag
    lo, hi = float(np.min(res.mach)), float(np.max(res.mach))
    grid = np.round(np.linspace(lo, hi, 81), 4)
    rows = cd_table(res, dm, grid, rnd.reference_drag)
    det = determined_range(rows)
    free = [n for n, f in zip(res.names, res.free) if f]
    result = {
        "scheme": 1, "drag_model": dm.name,
        "ml": {"params": res.params, "crb": {n: float(s) for n, s, f in zip(res.names, res.crb, res.free) if f},
               "crb_colored": {n: float(s) for n, s, f in zip(res.names, res.crb_colored, res.free) if f},
               "fixed": [n for n in res.names if n not in free],
               "converged": res.converged, "iterations": res.iterations, "cost": res.cost,
               "message": res.message, "sigma": res.sigma,
               "rms": {c: float(np.sqrt(np.mean(r**2))) for c, r in res.residuals.items()},
               "warnings": list(res.warnings),
               "mach_range_data": [lo, hi], "mach_range_determined": list(det) if det else None},
        "cd": rows,
    }
    if not args.no_mcmc:
        print("bayesdrag: note: the Bayesian layer is not built yet; writing the ML result only "
              "(use --no-mcmc to silence this)", file=sys.stderr)
    _write_json(out / "result.json", result)
    _fit_figures(out, res, dm, rows, rnd, track)
    for w in res.warnings:
        print(f"bayesdrag: warning: {w}", file=sys.stderr)
    print(f"fit: {res.message} in {res.iterations} iterations; Cd determined over Mach "
          f"{det[0]:.2f}-{det[1]:.2f}" if det else f"fit: {res.message}; Cd nowhere determined to 1 %")
    print(f"  wrote {out / 'result.json'}, cd.png, residuals.png")
    return 0


def _fit_figures(out, res, dm, rows, rnd, track):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plots import plot_cd_ml, plot_residuals

    ax = plot_cd_ml(rows, label=f"ML ({dm.name})")
    _atomic_write(out / "cd.png", lambda tmp: ax.figure.savefig(tmp, dpi=110, format="png"))
    plt.close(ax.figure)
    fig = plot_residuals(track.t, res.residuals, res.sigma)
    _atomic_write(out / "residuals.png", lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
    plt.close(fig)


