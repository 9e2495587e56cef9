"""Command line: ``bayesdrag simulate | fit | demo`` (``fit`` is maximum likelihood, Scheme 1,
for now; the Bayesian layer, Scheme 2 and ``diagnose`` arrive with their issues).

Exit status (DESIGN.md): 0 success; 2 bad input, with one line on stderr naming the file, row
or key, what was found and what is allowed (no traceback); 1 internal failure. Outputs are
written to a temporary name and renamed into place only when complete, so a failed run never
deletes or overwrites a file it did not finish.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

from .errors import FitError, InputError


class _Parser(argparse.ArgumentParser):
    """argparse that reports bad options as one line and exit status 2."""

    def error(self, message):
        raise InputError(f"command line: {message} (see `{self.prog} --help`)")


def _atomic_write(path, write_fn):
    """Call ``write_fn(tmp_path)`` then rename the finished file to ``path``."""
    path = Path(path)
    if path.exists() and path.is_dir():
        raise InputError(f"{path}: output path is a directory; give a file name such as {path / 'track.csv'}")
    if not path.parent.exists():
        raise InputError(f"{path}: output folder {path.parent} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    os.close(fd)
    try:
        write_fn(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _seed(value):
    try:
        s = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--seed must be a non-negative integer, got {value!r}") from None
    if s < 0:
        raise argparse.ArgumentTypeError(f"--seed must be a non-negative integer, got {value!r}")
    return s


def _positive_float(value):
    try:
        v = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {value!r}") from None
    if not v > 0 or v != v or v == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {value!r}")
    return v


def build_parser():
    p = _Parser(prog="bayesdrag", description=__doc__.split("\n\n")[0])
    p.add_argument("--version", action="version", version=_version())
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    s = sub.add_parser("simulate", help="write a synthetic radar track of a round (launch to impact)")
    s.add_argument("round", help="round file (TOML)")
    s.add_argument("-o", "--output", required=True, help="track file to write (CSV)")
    s.add_argument("--model", choices=("pointmass", "6dof"), default="pointmass")
    s.add_argument("--dt", type=_positive_float, default=0.027, help="sample interval [s] (default 0.027)")
    s.add_argument("--noise", action="store_true", help="add Gaussian noise with the round's [radar] sigma")
    s.add_argument("--seed", type=_seed, default=None, help="seed of the noise generator")
    s.add_argument("--clock-offset", type=float, default=0.0,
                   help="radar clock late by this many seconds (recorded = true - offset)")

    f = sub.add_parser("fit", help="estimate Cd(M) from a track (maximum likelihood, Scheme 1)")
    f.add_argument("track", help="radar track (CSV)")
    f.add_argument("round", help="round file (TOML)")
    f.add_argument("-o", "--output", required=True, help="output folder")
    f.add_argument("--scheme", type=int, choices=(1,), default=1,
                   help="1 = Cd model over the whole flight (Scheme 2 is being built)")
    f.add_argument("--drag", choices=("poly2", "poly2-split", "spline", "reference-scale"), default="spline",
                   help="drag model (default spline: the only one that follows a transonic rise)")
    f.add_argument("--channels", default=None, help="comma-separated subset of the track's x,y,z,v")
    f.add_argument("--no-mcmc", action="store_true", help="maximum likelihood only (the Bayesian layer is being built)")
    f.add_argument("--fix-ic", action="store_true", help="keep the initial conditions at the launch values")

    d = sub.add_parser("demo", help="run the whole job on data shipped in the package")
    d.add_argument("-o", "--output", default="bayesdrag-demo", help="output folder (default ./bayesdrag-demo)")
    return p


def _version():
    from . import __version__

    return f"bayesdrag {__version__}"


def cmd_simulate(args):
    import numpy as np

    from .simulate import add_noise, simulate_round
    from .track import read_round, write_track

    rnd = read_round(args.round)
    if args.seed is not None and not args.noise:
        raise InputError("command line: --seed only makes sense with --noise")
    track = simulate_round(rnd, model=args.model, dt=args.dt, clock_offset=args.clock_offset)
    comment = f"synthetic track: {args.model}, dt = {args.dt} s, from {args.round}"
    if args.noise:
        if not rnd.radar.sigma:
            raise InputError(f"{args.round}: --noise needs [radar] sigma = {{x = ..., z = ..., v = ...}}")
        track = add_noise(track, rnd.radar.sigma, np.random.default_rng(args.seed))
        comment += f"; Gaussian noise {rnd.radar.sigma}, seed {args.seed}"
    _atomic_write(args.output, lambda tmp: write_track(tmp, track, comment=comment))
    print(f"wrote {args.output}: {track.n} samples, t = 0 .. {track.t[-1]:.2f} s, "
          f"range {track.x[-1]:.0f} m" if track.x is not None else f"wrote {args.output}")
    return 0


def cmd_demo(args):
    from .demo import run_demo

    run_demo(Path(args.output))
    return 0


def _write_json(path, obj):
    import json

    _atomic_write(path, lambda tmp: Path(tmp).write_text(json.dumps(obj, indent=2, allow_nan=False)))


def cmd_fit(args):
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


COMMANDS = {"simulate": cmd_simulate, "fit": cmd_fit, "demo": cmd_demo}


def main(argv=None):
    """Entry point of the ``bayesdrag`` command. Returns the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        return COMMANDS[args.command](args)
    except InputError as exc:
        print(f"bayesdrag: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except FitError as exc:
        print(f"bayesdrag: fit failed: {' '.join(str(exc).split())}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("bayesdrag: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # internal failure: exit 1, traceback only on request
        if os.environ.get("BAYESDRAG_DEBUG"):
            raise
        print(f"bayesdrag: internal error: {type(exc).__name__}: {exc} "
              f"(set BAYESDRAG_DEBUG=1 for a traceback)", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
