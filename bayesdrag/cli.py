"""Command line: ``bayesdrag simulate | fit | diagnose | batch | plan | demo``.

This module only parses arguments into the options of :mod:`bayesdrag.options`, calls
the command and maps what happened to the exit status: 0 success; 2 bad input, with
one line on stderr naming the file, row or key, what was found and what is allowed (no
traceback); 1 an internal failure, a fit that has no solution or an output folder that could not
be written to the end (a full disk; one line); 130 interrupted.
"""
from __future__ import annotations

import argparse
import contextlib
import errno
import math
import os
import sys
from pathlib import Path

from .errors import FitError, InputError, OutputError

DESCRIPTION = ("Drag coefficient Cd(Mach) of projectiles from radar tracks: maximum likelihood with "
               "Cramér-Rao bounds, emcee posterior, and the diagnosis of the gap between a simulation and "
               "the measured track.")


class _Parser(argparse.ArgumentParser):
    """argparse that reports bad options as one line and exit status 2.

    ``minus_valued`` names options whose value may start with a minus sign followed by a digit or
    a point (``--radar-sites -40,25,2;0,-30,1``): such a value is joined to its option
    (``--radar-sites=-40,...``) before parsing, since argparse would take it for an unknown option."""

    minus_valued: tuple = ()

    def error(self, message):
        raise InputError(f"command line: {message} (see `{self.prog} --help`)")

    def parse_known_args(self, args=None, namespace=None):
        if self.minus_valued and args is not None:
            args = _join_minus_values(list(args), self.minus_valued)
        return super().parse_known_args(args, namespace)


def _join_minus_values(args, options):
    """``args`` with each of ``options`` followed by a negative-number-led value joined to it by
    ``=``; everything after ``--`` left alone."""
    out, k = [], 0
    while k < len(args):
        a = args[k]
        if a == "--":
            return out + args[k:]
        nxt = args[k + 1] if k + 1 < len(args) else None
        led = isinstance(nxt, str) and len(nxt) > 1 and nxt[0] == "-" and (nxt[1].isdigit() or nxt[1] == ".")
        if a in options and led:
            out.append(f"{a}={nxt}")
            k += 2
            continue
        out.append(a)
        k += 1
    return out


def _integer(minimum, label=None):
    """An argparse type: an integer >= ``minimum``, with a message naming the option."""
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
_positive_int = _integer(1)


def _positive_float(value):
    try:
        v = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {value!r}") from None
    if not v > 0 or v != v or v == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {value!r}")
    return v


def _finite_float(value):
    try:
        v = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {value!r}") from None
    if v != v or v in (float("inf"), float("-inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {value!r}")
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
    return v


def _number_list(unit, lo, hi, hi_open=False):
    """An argparse type: comma-separated numbers in (lo, hi) or (lo, hi] (argparse names the option)."""
    allowed = f"comma-separated numbers in ({lo:g}, {hi:g}{')' if hi_open else ']'} {unit}"

    def parse(value):
        out = []
        for part in value.split(","):
            try:
                v = float(part)
            except ValueError:
                raise argparse.ArgumentTypeError(f"{value!r}: {part.strip()!r} is not a number; use {allowed}") from None
            if not (v > lo and (v < hi if hi_open else v <= hi)) or v != v:
                raise argparse.ArgumentTypeError(f"{value!r}: {part.strip()} is outside; use {allowed}")
            out.append(v)
        return tuple(out)

    return parse


#: how ``--radar-sites`` is written, for its messages: quoted (the shell ends a command at ';')
RADAR_SITES_EXAMPLE = '--radar-sites "-40,25,2;0,-30,1"'


def _radar_sites(value):
    """An argparse type: radar sites ``x,y,z;x,y,z`` [m] in the gun frame, each at most the
    radar's plausible distance from the muzzle (:data:`bayesdrag.round.RADAR_SITE_MAX`)."""
    from .round import RADAR_SITE_MAX

    sites = []
    for part in value.split(";"):
        try:
            xyz = tuple(float(v) for v in part.split(","))
        except ValueError:
            xyz = ()
        if len(xyz) != 3 or not all(v == v and abs(v) != float("inf") for v in xyz):
            raise argparse.ArgumentTypeError(f"{value!r}: {part.strip()!r} is not a site; use x,y,z [m] in the gun "
                                             f"frame, sites separated by ';', the list quoted (e.g. "
                                             f"{RADAR_SITES_EXAMPLE})")
        far = math.hypot(*xyz)      # no overflow of a square (1e200 m is refused, not a crash)
        if far > RADAR_SITE_MAX:
            raise argparse.ArgumentTypeError(f"{value!r}: the site {part.strip()} is {far:.0f} m from the muzzle, more "
                                             f"than a radar's plausible {RADAR_SITE_MAX:g} m (x, y, z in metres in "
                                             f"the gun frame)")
        sites.append(xyz)
    return tuple(sites)


def _non_negative_float(value):
    v = _finite_float(value)
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {value!r}")
    return v


def _add_plan_parser(sub):
    from .options import PLAN_ELEVATION_RANGE, PLAN_VELOCITY_MAX, PlanOptions
    from .round import RADAR_SITE_MAX

    po = PlanOptions()
    p = sub.add_parser("plan", help="predict, before firing, the Cd accuracy (sd by Mach) of planned cases "
                                    "(Cramér-Rao of the default fit on simulated tracks)")
    p.add_argument("round", help="round file (TOML): projectile, air, [radar] sigma, declared systematic sds")
    p.add_argument("-o", "--output", required=True, help="output folder (plan.json, plan.html)")
    p.add_argument("--elevations", type=_number_list("deg", *PLAN_ELEVATION_RANGE, hi_open=True),
                   default=None, help="quadrant elevations [deg], e.g. 15,30,45 (default: the round's)")
    p.add_argument("--velocities", type=_number_list("m/s", 0.0, PLAN_VELOCITY_MAX), default=None,
                   help="launch velocities (charges) [m/s], e.g. 684,818 (default: the round's); the cases are "
                        "every elevation x velocity pair")
    p.add_argument("--dt", type=_positive_float, default=po.dt, help=f"radar sample interval [s] (default {po.dt})")
    p.add_argument("--rounds", type=_integer(1, "--rounds"), default=po.rounds,
                   help="rounds fired per case, pooled (default 1); systematic sources do not shrink with them")
    p.add_argument("--scatter", type=_non_negative_float, default=po.scatter,
                   help="round-to-round relative sd of Cd, e.g. 0.01 = 1 %% (default 0)")
    p.add_argument("--target", type=_positive_float, default=None,
                   help="target relative sd of Cd, e.g. 0.005 = 0.5 %%: which cases reach it over the widest Mach range")
    p.add_argument("--lock-on", type=_non_negative_float, default=None,
                   help="radar lock-on time after launch [s] (default 0: tracked from the muzzle)")
    p.add_argument("--loss", type=_positive_float, default=None, help="radar loss time [s] (default: impact)")
    p.add_argument("--assumed-drag", default=None, metavar="CSV",
                   help="mach,cd table of the drag the shell is expected to have (default: the round's reference "
                        "drag, else a generic 155 mm curve)")
    p.add_argument("--seed", type=_seed, default=po.seed,
                   help="seed of the noisy realisation that places the fit's knots (default 0)")
    p.add_argument("--radar-sites", type=_radar_sites, default=None, metavar='"X,Y,Z;..."',
                   help=f"candidate sites [m, gun frame, each within {RADAR_SITE_MAX / 1000:g} km of the muzzle] of a "
                        f"radar recording its own channels (range, azimuth, elevation, range_rate in [radar] "
                        f"sigma): every case from each; plan.json ranks them and names best_site. Quote the list "
                        f"(the shell ends a command at ';'), e.g. {RADAR_SITES_EXAMPLE}")
    p.minus_valued = ("--radar-sites",)     # a site may start with a minus sign: -40,25,2
    _add_quiet(p)


def _add_fit_options(p, batch=False):
    """The options that change a fit's result (shared by ``fit`` and ``batch``)."""
    from .options import LIKELIHOODS, MOVES, NOISE_MODELS, FitOptions
    from .drag import DRAG_MODEL_NAMES

    d = FitOptions()
    p.add_argument("--drag", choices=DRAG_MODEL_NAMES, default=d.drag,
                   help="drag model (default spline: follows any transonic rise; with a firing table it is the "
                        "table times a smooth correction)")
    p.add_argument("--channels", default=None, help="comma-separated subset of the track's channels: x,y,z,v in the gun's frame, or the "
                                                          "radar-native range,azimuth,elevation,range_rate")
    p.add_argument("--no-mcmc", action="store_true", help="maximum likelihood only (no posterior sampling)")
    p.add_argument("--fix-ic", action="store_true", help="keep the initial conditions at their starting values")
    p.add_argument("--seed", type=_seed, default=None,
                   help="seed of the sampler (reproducible chains)" + ("; also of the pooling" if batch else ""))
    if batch:
        return
    p.add_argument("--scheme", type=int, choices=(1, 2), default=d.scheme,
                   help="1 = Cd model over the whole flight (default); 2 = a constant Cd per window")
    p.add_argument("--window", type=_positive_int, default=d.window,
                   help=f"Scheme 2: samples per window (default {d.window})")
    p.add_argument("--overlap", type=_non_negative_int, default=d.overlap,
                   help="Scheme 2: samples shared by consecutive windows (default 0)")
    p.add_argument("--walkers", type=_positive_int, default=None, help="emcee walkers (default 16)")
    p.add_argument("--max-steps", type=_positive_int, default=d.max_steps,
                   help=f"hard limit of sampler steps (default {d.max_steps}; the run stops earlier at convergence)")
    p.add_argument("--moves", choices=MOVES, default=d.moves,
                   help="emcee moves: auto (independence proposal from the ML fit + local move, default), "
                        "de (differential evolution, for posteriors far from Gaussian; needs >= 2 x parameters "
                        "walkers), stretch")
    p.add_argument("--likelihood", choices=LIKELIHOODS, default=d.likelihood,
                   help="noise model: gaussian (default) or student-t (robust to outliers)")
    p.add_argument("--noise-model", choices=NOISE_MODELS, default=d.noise_model,
                   help="auto (default: per channel from the residuals), white (independent samples) or ar1 "
                        "(white noise plus an AR(1) model-error process: correlated residuals widen the bands)")
    p.add_argument("--sample-ar", action="store_true",
                   help="sample the AR(1) model-error coefficients in the posterior (default: held at their ML "
                        "values; slow mixing where rho reaches its bound)")
    p.add_argument("--with", dest="with_effects", default="", metavar="EFFECT[,EFFECT]|auto|none",
                   help="fit these effects of the diagnosis library with Cd as nuisance parameters (auto: the ones "
                        "`bayesdrag diagnose` names; none: never). Default: when the model check finds material "
                        "effects the round does not declare, the answer is the fit with them; the report shows Cd "
                        "with and without them")
    p.add_argument("--no-model-check", dest="model_check", action="store_false",
                   help="skip the check of the Cd against the misfit that remains (the diagnosis's undeclared "
                        "effects and a robust fit, whose Cd shifts widen the bands as model error): faster, and the "
                        "bands then hold the noise only")
    p.add_argument("--nu", type=_nu, default=d.nu,
                   help=f"Student-t degrees of freedom: a number (default {d.nu:g}) or 'sample'")


def build_parser():
    from .options import SIMULATION_MODELS, SIMULATION_RADARS, SimulateOptions

    p = _Parser(prog="bayesdrag", description=DESCRIPTION)
    p.add_argument("--version", action="version", version=_version())
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    so = SimulateOptions()
    s = sub.add_parser("simulate", help="write a synthetic radar track of a round (launch to impact)")
    s.add_argument("round", help="round file (TOML)")
    s.add_argument("-o", "--output", required=True, help="track file to write (CSV)")
    s.add_argument("--model", choices=SIMULATION_MODELS, default=so.model)
    s.add_argument("--dt", type=_positive_float, default=so.dt, help=f"sample interval [s] (default {so.dt})")
    s.add_argument("--noise", action="store_true", help="add Gaussian noise with the round's [radar] sigma")
    s.add_argument("--seed", type=_seed, default=None, help="seed of the noise generator")
    s.add_argument("--clock-offset", type=_finite_float, default=so.clock_offset,
                   help="radar clock late by this many seconds (recorded = true - offset)")
    s.add_argument("--radar", choices=SIMULATION_RADARS, default=so.radar,
                   help="gun: x, y, z, v in the gun's frame (default); native: range, azimuth, elevation, "
                        "range_rate from the round's [radar] position, noise in those coordinates")
    _add_quiet(s)

    f = sub.add_parser("fit", help="estimate Cd(M) from a track (ML with Cramér-Rao bounds, then emcee posterior)")
    f.add_argument("inputs", nargs="+", metavar="TRACK [ROUND]",
                   help="a radar track (CSV) and its round (TOML); a chronograph session: a LabRadar series folder "
                        "(SR0047/) or several shot files, then the round; or a campaign file (TOML) alone")
    f.add_argument("-o", "--output", required=True, help="output folder")
    _add_fit_options(f)
    f.add_argument("--resume", action="store_true",
                   help="continue the unfinished chain in OUTPUT/chain.partial.h5 (after a kill; never in a folder "
                        "others can write)")
    f.add_argument("--allow-outside-inputs", action="store_true",
                   help="a campaign: read tracks, round files and tables outside the campaign file's folder")
    _add_columns(f)
    _add_format(f)
    _add_quiet(f)
    f.add_argument("-v", "--verbose", action="store_true",
                   help="also print the technical warnings (strong correlations, single coefficients' sds), "
                        "which otherwise only result.json holds")

    b = sub.add_parser("batch", help="run a campaign's rounds (fit and/or diagnose) as Dask tasks, then pool them")
    b.add_argument("campaign", help="campaign file (TOML)")
    b.add_argument("-o", "--output", required=True, help="output folder")
    b.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of a running Dask scheduler (default: a local cluster)")
    b.add_argument("--workers", type=_positive_int, default=None,
                   help="local cluster worker processes (default: the number of CPUs)")
    b.add_argument("--jobs", default="fit", help="comma-separated jobs per round among fit,diagnose (default fit)")
    _add_fit_options(b, batch=True)
    b.add_argument("--covariance", choices=("colored", "crb"), default="colored",
                   help="round covariance pooled: colored-residual corrected (default) or plain CRB")
    b.add_argument("--resume", action="store_true",
                   help="continue the unfinished chains of rounds killed while sampling (never in a folder others "
                        "can write); without it such a round fails")
    b.add_argument("--allow-outside-inputs", action="store_true",
                   help="read tracks, round files and tables outside the campaign file's folder")
    _add_quiet(b)

    g = sub.add_parser("diagnose", help="explain the gap between a track and the nominal simulation of its round")
    g.add_argument("track", help="radar track (CSV)")
    g.add_argument("round", help="round file (TOML)")
    g.add_argument("-o", "--output", required=True, help="output folder")
    g.add_argument("--material-cd", type=_positive_float, default=None, metavar="PERCENT",
                   help="an effect is material when ignoring it would shift a fitted Cd by more than this many "
                        "percent anywhere in the flown Mach range (default 0.1)")
    g.add_argument("--material-end-sd", type=_positive_float, default=None, metavar="N",
                   help="... or move the track's end by more than N noise sd (default 3)")
    _add_columns(g)
    _add_format(g)
    _add_quiet(g)

    _add_plan_parser(sub)

    d = sub.add_parser("demo", help="run the whole job on data shipped in the package")
    d.add_argument("-o", "--output", default="bayesdrag-demo", help="output folder (default ./bayesdrag-demo)")
    _add_quiet(d)
    return p


def _columns(value):
    """``--columns t=time,v=velocity``: ``{channel: header name}``."""
    from .track import ALL_CHANNELS as CHANNELS

    out = {}
    for part in value.split(","):
        name, sep, col = (x.strip() for x in part.partition("="))
        if not sep or not col or name not in ("t",) + CHANNELS:
            raise argparse.ArgumentTypeError(f"{value!r}: use CHANNEL=COLUMN pairs, CHANNEL one of t, "
                                             f"{', '.join(CHANNELS)} (e.g. t=time,v=velocity)")
        if name in out or col in out.values():
            raise argparse.ArgumentTypeError(f"{value!r}: {name if name in out else col} is named twice")
        out[name] = col
    return out


def _add_columns(p):
    p.add_argument("--columns", type=_columns, default=None, metavar="t=NAME,v=NAME",
                   help="which header column holds t, x, y, z or v (e.g. t=time,v=velocity); without it the "
                        "names t, x, y, z, v and the aliases of docs/formats.md are read")


def _add_format(p):
    p.add_argument("--format", default="auto", metavar="NAME",
                   help="the track file's format: auto (default: sniffed from the file), csv (bayesdrag's track "
                        "CSV) or a device's export (labradar); docs/radar.md")


def _add_quiet(p):
    """``-q`` / ``--quiet``, counted (as pip and logging levels): once, nothing on stdout and no
    notes or progress on stderr, warnings and errors still there; twice, errors only."""
    p.add_argument("-q", "--quiet", action="count", default=0,
                   help="-q: nothing on stdout, no notes or progress; warnings and errors stay on stderr. "
                        "-qq: errors only")


def _stdout(args):
    """``print`` for the command's stdout lines, or nothing with ``-q``."""
    return print if not getattr(args, "quiet", 0) else (lambda *a, **k: None)


def _batch_stdout(args, res):
    """A campaign's last line: as :func:`_stdout`, but ``-q`` still prints it when a round
    failed (the run did not succeed; ``-qq`` leaves only the failures' lines on stderr)."""
    return print if (not args.quiet or (res["failed"] and args.quiet < 2)) else (lambda *a, **k: None)


def _version():
    from . import __version__

    return f"bayesdrag {__version__}"


def _fit_options(args):
    """FitOptions from the parsed ``fit`` (or ``batch``) arguments."""
    from .options import FitOptions

    kw = {"drag": args.drag, "mcmc": not args.no_mcmc, "fix_ic": args.fix_ic, "seed": args.seed}
    if args.channels is not None:
        ch = tuple(c.strip() for c in args.channels.split(",") if c.strip())
        if not ch:
            raise InputError(f"command line: --channels {args.channels!r} names no channel; use e.g. x,z,v")
        kw["channels"] = ch
    for k in ("scheme", "window", "overlap", "walkers", "max_steps", "moves", "likelihood", "nu", "noise_model",
              "sample_ar", "model_check"):
        if hasattr(args, k):
            kw[k] = getattr(args, k)
    if getattr(args, "with_effects", ""):
        kw["with_effects"] = args.with_effects
    return FitOptions(**kw)


def cmd_simulate(args):
    from .options import SimulateOptions
    from .commands.simulate import run_simulate

    if args.seed is not None and not args.noise:
        raise InputError("command line: --seed only makes sense with --noise")
    run_simulate(args.round, args.output, SimulateOptions(model=args.model, dt=args.dt, noise=args.noise,
                                                          seed=args.seed, clock_offset=args.clock_offset,
                                                          radar=args.radar),
                 echo=_stdout(args))
    return 0


def _split_fit_inputs(args):
    """``args.track`` and ``args.round`` from ``fit``'s positional inputs: one file alone is a
    campaign file; the last of several is the round; more than one track (or a folder) is a
    chronograph session (``args.tracks``)."""
    inputs = list(args.inputs)
    args.round = inputs.pop() if len(inputs) > 1 else None
    args.tracks = inputs
    args.track = inputs[0]


def cmd_fit(args):
    _split_fit_inputs(args)
    if args.round is not None and (len(args.tracks) > 1 or Path(args.track).is_dir()):
        from .commands.session import run_session

        if args.columns:
            raise InputError("command line: --columns maps the columns of one track; a chronograph session's shot "
                             "files are read in their device's own format")
        return run_session(args.tracks, args.round, args.output, verbosity=args.quiet, echo=_stdout(args))
    if args.channels is not None and args.round is not None:
        from .io.tracks import read_track

        track = read_track(args.track, columns=args.columns, format=args.format)
        ch = [c.strip() for c in args.channels.split(",") if c.strip()]
        bad = [c for c in ch if c not in track.names]
        if bad or not ch:
            raise InputError(f"command line: --channels {args.channels!r}: {', '.join(bad) or 'empty'} not in the "
                             f"track {args.track} (it has {', '.join(track.names)})")
    opts = _fit_options(args)
    if args.round is None:  # bayesdrag fit CAMPAIGN.toml -o DIR
        from .commands.batch import run_campaign, say_done
        from .io.campaign import is_campaign_file

        if not is_campaign_file(args.track):
            raise InputError(f"command line: fit needs TRACK ROUND, or a campaign file ({args.track} is not a "
                             f"TOML file with [campaign] and [[rounds]])")
        if args.columns:
            raise InputError("command line: --columns maps the columns of one track; a campaign's tracks need "
                             "the names t, x, y, z, v or their aliases")
        res = run_campaign(args.track, args.output, jobs=("fit",), options=opts, executor="sequential",
                           quiet=args.quiet > 0, echo=_stdout(args), pool_seed=args.seed or 0, resume=args.resume,
                           allow_outside=args.allow_outside_inputs)
        return say_done(res, echo=_batch_stdout(args, res))
    from .commands.fit import run_fit

    run_fit(args.track, args.round, args.output, opts, resume=args.resume, verbosity=args.quiet,
            echo=_stdout(args), columns=args.columns, track_format=args.format, verbose=args.verbose)
    return 0


def cmd_batch(args):
    from .commands.batch import run_campaign, say_done
    from .options import BatchOptions

    jobs = tuple(j.strip() for j in args.jobs.split(",") if j.strip())
    b = BatchOptions(jobs=jobs, fit=_fit_options(args), scheduler=args.scheduler, workers=args.workers,
                     covariance=args.covariance)
    workers = b.workers or max(1, min(os.cpu_count() or 1, 64))
    res = run_campaign(args.campaign, args.output, jobs=b.jobs, options=b.fit, executor="dask",
                       scheduler=b.scheduler, workers=workers, covariance=b.covariance, quiet=args.quiet > 0,
                       echo=_stdout(args), pool_seed=args.seed or 0, resume=args.resume,
                       allow_outside=args.allow_outside_inputs)
    return say_done(res, echo=_batch_stdout(args, res))


def cmd_diagnose(args):
    from .commands.diagnose import run_diagnose

    from .options import DiagnoseOptions

    kw = {}
    if args.material_cd is not None:
        kw["material_cd_shift"] = args.material_cd / 100.0
    if args.material_end_sd is not None:
        kw["material_end_sd"] = args.material_end_sd
    run_diagnose(args.track, args.round, args.output, DiagnoseOptions(**kw), quiet=args.quiet > 0,
                 echo=_stdout(args), columns=args.columns, track_format=args.format)
    return 0


def cmd_plan(args):
    from .options import PlanOptions
    from .commands.plan import run_plan

    opts = PlanOptions(elevations=args.elevations, velocities=args.velocities, dt=args.dt, rounds=args.rounds,
                       scatter=args.scatter, target=args.target, lock_on=args.lock_on, loss=args.loss, seed=args.seed,
                       radar_sites=args.radar_sites)
    run_plan(args.round, args.output, opts, assumed_drag_path=args.assumed_drag, echo=_stdout(args))
    return 0


def cmd_demo(args):
    from .commands.demo import run_demo

    run_demo(Path(args.output), echo=_stdout(args), quiet=args.quiet > 0)
    return 0


COMMANDS = {"simulate": cmd_simulate, "fit": cmd_fit, "batch": cmd_batch, "diagnose": cmd_diagnose,
            "plan": cmd_plan, "demo": cmd_demo}


#: errors of the file system that are the user's to fix (a name, a place): one line, exit 2
_PATH_ERRNOS = {errno.ENAMETOOLONG: "the name is too long", errno.EROFS: "the file system is read-only",
                errno.ELOOP: "too many symbolic links", errno.ENOTDIR: "a part of the path is not a folder",
                errno.EACCES: "permission denied", errno.EPERM: "not permitted"}


def _check_environment(args):
    """What the command line and environment must satisfy before any work (exit 2)."""
    out = getattr(args, "output", None)
    if out is not None and not str(out).strip():
        raise InputError("command line: -o is empty; give a folder or file name (. for the current folder)")
    if os.environ.get("MPLBACKEND"):
        try:
            import matplotlib  # noqa: F401  (it checks MPLBACKEND when imported)
        except ValueError:
            raise InputError(f"environment: MPLBACKEND={os.environ['MPLBACKEND']!r} is not a matplotlib backend; "
                             f"unset it (bayesdrag draws its figures without one) or use e.g. Agg") from None


class _TolerantStdout:
    """stdout for the run's messages: text the terminal cannot encode is escaped, and a stdout
    that cannot be written (``> /dev/full``) does not turn a finished run into a failure (the
    files are written; one note on stderr says the messages were lost). A closed pipe still
    ends the run quietly (exit 141)."""

    def __init__(self, stream):
        self._stream, self.failed = stream, None

    def write(self, text):
        if self.failed is None:
            try:
                return self._stream.write(text)
            except UnicodeEncodeError:
                enc = getattr(self._stream, "encoding", None) or "ascii"
                return self.write(text.encode(enc, "backslashreplace").decode(enc))
            except BrokenPipeError:
                raise
            except OSError as exc:
                self.failed = exc
        return len(text)

    def flush(self):
        if self.failed is None:
            try:
                self._stream.flush()
            except BrokenPipeError:
                raise
            except OSError as exc:
                self.failed = exc

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _safe_stderr():
    """Escape what stderr cannot encode (an ASCII-only terminal) instead of failing."""
    with contextlib.suppress(AttributeError, ValueError, OSError):
        sys.stderr.reconfigure(errors="backslashreplace")


def main(argv=None):
    """Entry point of the ``bayesdrag`` command. Returns the exit status."""
    _safe_stderr()
    real_stdout = sys.stdout
    sys.stdout = out = _TolerantStdout(real_stdout)
    try:
        code = _main(argv)
        out.flush()
    finally:
        sys.stdout = real_stdout
    if out.failed is not None:
        with contextlib.suppress(OSError):          # nothing more for that stdout, also not at exit
            os.dup2(os.open(os.devnull, os.O_WRONLY), real_stdout.fileno())
        print(f"bayesdrag: note: the messages of this run could not be written to stdout "
              f"({out.failed.strerror or out.failed}); its files are written", file=sys.stderr)
    return code


def _main(argv):
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        _check_environment(args)
        return COMMANDS[args.command](args)
    except InputError as exc:
        print(f"bayesdrag: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except FitError as exc:
        print(f"bayesdrag: fit failed: {' '.join(str(exc).split())}", file=sys.stderr)
        return 1
    except OutputError as exc:  # a full disk: nothing of the run kept, earlier outputs intact
        print(f"bayesdrag: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("bayesdrag: interrupted", file=sys.stderr)
        return 130
    except OSError as exc:
        if isinstance(exc, BrokenPipeError) or exc.errno not in _PATH_ERRNOS:
            return _unexpected(exc)
        name = str(exc.filename if exc.filename is not None else "")
        shown = name if len(name) <= 80 else f"{name[:40]}...{name[-30:]} ({len(name)} characters)"
        print(f"bayesdrag: error: {shown}: {_PATH_ERRNOS[exc.errno]} ({exc.strerror}); choose another file or "
              f"folder", file=sys.stderr)
        return 2
    except Exception as exc:  # internal failure: exit 1, traceback only on request
        return _unexpected(exc)


def _unexpected(exc):
    if isinstance(exc, BrokenPipeError):
        # the reader of stdout went away (``bayesdrag ... | head``): the files are written; stop
        # quietly like other Unix tools, and keep Python from complaining again at exit
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    from ._runtime.signals import caused_by_interrupt

    if caused_by_interrupt(exc):  # Ctrl-C inside compiled code (numba wraps it)
        print("bayesdrag: interrupted", file=sys.stderr)
        return 130
    if os.environ.get("BAYESDRAG_DEBUG"):
        raise exc
    print(f"bayesdrag: internal error: {type(exc).__name__}: {exc} "
          f"(set BAYESDRAG_DEBUG=1 for a traceback)", file=sys.stderr)
    return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
