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
from pathlib import Path

from .errors import FitError, InputError
from .io.outputs import atomic_write as _atomic_write


class _Parser(argparse.ArgumentParser):
    """argparse that reports bad options as one line and exit status 2."""

    def error(self, message):
        raise InputError(f"command line: {message} (see `{self.prog} --help`)")


def _integer(minimum, label=None):
    """An argparse type: an integer >= ``minimum`` (0 or 1), with a message naming the option."""
    kind = "non-negative" if minimum == 0 else "positive"
    head = f"{label} must be" if label else "expected"

    def parse(value):
        try:
            v = int(value)
        except ValueError:
            v = None
        if v is None or v < minimum:
            raise argparse.ArgumentTypeError(f"{head} a {kind} integer, got {value!r}")
        return v

    return parse


_seed = _integer(0, "--seed")
_non_negative_int = _integer(0)
_walkers = _integer(1)


def _positive_float(value):
    try:
        v = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {value!r}") from None
    if not v > 0 or v != v or v == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {value!r}")
    return v


def _nu(value):
    if value == "sample":
        return value
    try:
        v = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--nu must be a positive number or 'sample', got {value!r}") from None
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"--nu must be a positive number or 'sample', got {value!r}")
    return value


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

    f = sub.add_parser("fit", help="estimate Cd(M) from a track (ML with Cramér-Rao bounds, then emcee posterior)")
    f.add_argument("track", help="radar track (CSV), or a campaign file (TOML) without ROUND")
    f.add_argument("round", nargs="?", default=None, help="round file (TOML); omitted for a campaign")
    f.add_argument("-o", "--output", required=True, help="output folder")
    f.add_argument("--scheme", type=int, choices=(1, 2), default=1,
                   help="1 = Cd model over the whole flight (default); 2 = a constant Cd per window")
    f.add_argument("--window", type=_walkers, default=50, help="Scheme 2: samples per window (default 50)")
    f.add_argument("--overlap", type=_non_negative_int, default=0,
                   help="Scheme 2: samples shared by consecutive windows (default 0)")
    f.add_argument("--drag", choices=("poly2", "poly2-split", "spline", "reference-scale"), default="spline",
                   help="drag model (default spline: the only one that follows a transonic rise)")
    f.add_argument("--channels", default=None, help="comma-separated subset of the track's x,y,z,v")
    f.add_argument("--no-mcmc", action="store_true", help="maximum likelihood only (no posterior sampling)")
    f.add_argument("--fix-ic", action="store_true", help="keep the initial conditions at the launch values")
    f.add_argument("--seed", type=_seed, default=None, help="seed of the sampler (reproducible chains)")
    f.add_argument("--resume", action="store_true",
                   help="continue the unfinished chain in OUTPUT/chain.partial.h5 (after a kill)")
    f.add_argument("--quiet", action="store_true", help="no progress bar or status lines")
    f.add_argument("--walkers", type=_walkers, default=None, help="emcee walkers (default 16)")
    f.add_argument("--max-steps", type=_walkers, default=20000,
                   help="hard limit of sampler steps (default 20000; the run stops earlier at convergence)")
    f.add_argument("--moves", choices=("auto", "de", "stretch"), default="auto",
                   help="emcee moves: auto (independence proposal from the ML fit + local move, default), "
                        "de (differential evolution, for posteriors far from Gaussian; needs >= 2 x parameters "
                        "walkers), stretch")
    f.add_argument("--likelihood", choices=("gaussian", "student-t"), default="gaussian",
                   help="noise model: gaussian (default) or student-t (robust to outliers)")
    f.add_argument("--nu", type=_nu, default="4",
                   help="Student-t degrees of freedom: a number (default 4) or 'sample'")

    from .batch import add_batch_parser  # campaigns on Dask (issue 8)

    add_batch_parser(sub, {"seed": _seed, "walkers": _walkers, "nu": _nu})

    g = sub.add_parser("diagnose", help="explain the gap between a track and the nominal simulation of its round")
    g.add_argument("track", help="radar track (CSV)")
    g.add_argument("round", help="round file (TOML)")
    g.add_argument("-o", "--output", required=True, help="output folder")

    d = sub.add_parser("demo", help="run the whole job on data shipped in the package")
    d.add_argument("-o", "--output", default="bayesdrag-demo", help="output folder (default ./bayesdrag-demo)")
    return p


def _version():
    from . import __version__

    return f"bayesdrag {__version__}"


def cmd_simulate(args):
    import numpy as np

    from .simulate import add_noise, simulate_round
    from .io.rounds import read_round
    from .io.tracks import write_track

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


def cmd_diagnose(args):
    from .diagnose_report import run_diagnose

    return run_diagnose(args)


def cmd_fit(args):
    from .fitting import run_fit

    if args.round is None:  # bayesdrag fit CAMPAIGN.toml -o DIR
        from .batch import run_campaign_fit
        from .io.campaign import is_campaign_file

        if not is_campaign_file(args.track):
            raise InputError(f"command line: fit needs TRACK ROUND, or a campaign file ({args.track} is not a "
                             f"TOML file with [campaign] and [[rounds]])")
        return run_campaign_fit(args)
    return run_fit(args)


def cmd_batch(args):
    from .batch import cmd_batch as run

    return run(args)


COMMANDS = {"simulate": cmd_simulate, "fit": cmd_fit, "demo": cmd_demo, "diagnose": cmd_diagnose}
COMMANDS["batch"] = cmd_batch


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
