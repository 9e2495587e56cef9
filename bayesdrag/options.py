"""Every option of every command with its default, written once.

The command line (:mod:`bayesdrag.cli`) builds these from its flags, the Python API
(:func:`bayesdrag.fit`, ...) from keyword arguments, the batch runner from a campaign's settings;
nothing else holds a default. Construction checks each value and raises
:class:`~bayesdrag.errors.InputError` naming the option, what was given and what is allowed.
"""
from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass, fields

from .drag import DRAG_MODEL_NAMES
from .errors import InputError
from .estimate.model.likelihood import LIKELIHOODS, STUDENT_T_NU
from .round import RADAR_SITE_MAX
from .track import ALL_CHANNELS, CHANNELS

__all__ = ["FitOptions", "SimulateOptions", "DiagnoseOptions", "BatchOptions", "PlanOptions", "LIKELIHOODS", "MOVES",
           "SIMULATION_MODELS", "SIMULATION_RADARS", "JOBS"]

#: emcee move sets (auto: independence proposal from the ML fit + a local move)
MOVES = ("auto", "de", "stretch")
#: trajectory models of ``simulate``
SIMULATION_MODELS = ("pointmass", "6dof")
#: jobs a batch runs per round
JOBS = ("fit", "diagnose")
#: noise models of the channels (``auto``: per channel from the residuals)
NOISE_MODELS = ("auto", "white", "ar1")
#: the Student-t likelihood's default degrees of freedom
DEFAULT_NU = STUDENT_T_NU
#: allowed Student-t degrees of freedom: the range the posterior samples with ``--nu sample``
#: (below 1 the weights of every sample but the closest vanish: a bound of 0 and overflow)
NU_RANGE = (1.0, 100.0)
#: the smallest sampler step limit: the sampler's first convergence check comes after 100 steps,
#: and a shorter chain has no autocorrelation time, r_hat or ESS to report
MIN_MAX_STEPS = 100
#: caps checked before anything is allocated: a typing slip (``--walkers 1000000``) must not take
#: the machine's memory or hours. 1024 walkers x 10 000 samples already hold ~0.5 GB of
#: trajectories per step; a million steps is 50x the default limit
MAX_WALKERS = 1024
MAX_MAX_STEPS = 1_000_000
#: most Dask worker processes of a local cluster (each holds a Python process and the kernel)
MAX_WORKERS = 64
#: most Scheme 2 windows one fit runs (one after the other, each its own fit and chain): the
#: default window of 50 samples gives 200 on the densest track a fit uses (10 000 samples)
MAX_WINDOWS = 200
#: a Dask scheduler address: ``tcp://host:port`` (or tls, ucx, ws, wss, inproc) or ``host:port``
_SCHEDULER_RE = re.compile(r"^(?:(?:tcp|tls|ucx|ws|wss|inproc)://)?(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+)"
                           r"(?::[0-9]{1,5})?/?$")


def _bad(name, value, allowed):
    raise InputError(f"option {name} = {value!r} is not allowed; {allowed}")


def _int(name, value, minimum):
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        _bad(name, value, f"use an integer >= {minimum}")


@dataclass(frozen=True)
class FitOptions:
    """Options of a fit (``bayesdrag fit``, :func:`bayesdrag.fit`).

    Attributes
    ----------
    scheme : {1, 2}
        1: Cd(M) over the whole flight (default); 2: a constant Cd per window.
    drag : str
        Scheme 1 drag model: ``spline`` (default: the only one that follows any transonic
        rise; with a firing table it is the table times a smooth correction), ``poly2``,
        ``poly2-split``, ``reference-scale``.
    channels : tuple of str or None
        Subset of the track's x, y, z, v (default all it has).
    mcmc : bool
        Sample the posterior with emcee after the ML fit (default True).
    fix_ic : bool
        Keep the initial state at its starting values (the paper's Fig. 3b).
    likelihood : {"gaussian", "student-t"}
        Noise model; ``student-t`` is robust to gross outliers.
    nu : float or "sample"
        Student-t degrees of freedom in :data:`NU_RANGE` (default 4), or ``"sample"`` to sample
        them.
    noise_model : {"auto", "white", "ar1"}
        ``white``: independent samples (Eq. 19); ``ar1``: white noise plus an AR(1) model-error
        process per channel, so residuals that model error has made correlated widen the
        bands; ``auto`` (default): ``ar1`` for the channels whose white-noise residuals show
        such a process (:func:`bayesdrag.estimate.scheme1.fit.choose_noise_model`).
    sample_ar : bool
        Sample the AR(1) model-error coefficients (``log(1 - rho)``, ``log q`` per ``ar1``
        channel) in the posterior instead of holding them at their ML values (default False:
        where the data push rho to its bound, as on the shipped demo's v channel, the posterior
        is truncated there and the chain mixes slowly, acceptance 0.04-0.07; see docs/bayes.md).
    with_effects : "default", "none", "auto" or tuple of str
        Effects of the diagnosis library fitted with Cd as nuisance parameters (``--with``).
        ``default``: the model check's diagnosis names the material effects the round does not
        declare, and when it finds any the answer is the fit with them (nothing is added to a
        track the model fits); ``none`` (or an empty tuple): never, the check only widens the
        bands; ``auto``: the ones the diagnosis names, always; names: those effects. Effects that share a declared source's quantity
        (density, temperature, radar_time) or are confounded with Cd (density without
        ``density_sd``, drag_scale, drag_shape) are left out and the result says why.
    model_check : bool
        Unless ``with_effects`` is ``auto``, check the Cd against the misfit that remains (default True): the
        diagnosis's material effects, a robust fit for outliers, the white fit for AR(1) noise; the Cd
        shifts they imply widen the bands as model error (:mod:`bayesdrag.estimate.cd.model_error`).
        ``--no-model-check`` skips it (faster; bands then hold noise only).
    window, overlap : int
        Scheme 2: samples per window (default 50) and shared by consecutive windows (0).
    walkers : int or None
        emcee walkers (default: 16 with the ``auto`` moves, 128 when a declared ``temperature_sd``
        is sampled, else 2 x parameters + 2; :func:`bayesdrag.estimate.bayes.sampler.default_walkers`).
    max_steps : int
        Hard limit of sampler steps (the run stops earlier at convergence); at least
        :data:`MIN_MAX_STEPS`.
    moves : {"auto", "de", "stretch"}
        emcee moves.
    seed : int or None
        Seed of the sampler's random generator (reproducible chains).
    """

    scheme: int = 1
    drag: str = "spline"
    channels: tuple | None = None
    mcmc: bool = True
    fix_ic: bool = False
    likelihood: str = "gaussian"
    nu: float | str = DEFAULT_NU
    noise_model: str = "auto"
    sample_ar: bool = False
    with_effects: tuple | str = "default"
    model_check: bool = True
    window: int = 50
    overlap: int = 0
    walkers: int | None = None
    max_steps: int = 20000
    moves: str = "auto"
    seed: int | None = None

    def __post_init__(self):
        if self.scheme not in (1, 2):
            _bad("scheme", self.scheme, "use 1 (Cd over the whole flight) or 2 (a constant Cd per window)")
        if self.drag not in DRAG_MODEL_NAMES:
            _bad("drag", self.drag, f"use one of {', '.join(DRAG_MODEL_NAMES)}")
        if self.channels is not None:
            ch = tuple(self.channels) if not isinstance(self.channels, str) else tuple(
                c.strip() for c in self.channels.split(",") if c.strip())
            bad = [c for c in ch if c not in ALL_CHANNELS]
            if bad or not ch:
                _bad("channels", self.channels, f"use a non-empty subset of {', '.join(ALL_CHANNELS)}")
            twice = sorted({c for c in ch if ch.count(c) > 1})
            if twice:
                # a channel named twice would be counted twice: its noise weight doubled
                _bad("channels", ",".join(ch), f"name each channel once ({', '.join(twice)} is repeated)")
            object.__setattr__(self, "channels", ch)
        if self.likelihood not in LIKELIHOODS:
            _bad("likelihood", self.likelihood, f"use one of {', '.join(LIKELIHOODS)}")
        if (isinstance(self.with_effects, (list, tuple)) and len(self.with_effects) == 0) or \
                self.with_effects in (None, "none", ("none",)):
            object.__setattr__(self, "with_effects", ())
        elif self.with_effects not in ("auto", "default"):
            from .effects import EFFECTS

            w = self.with_effects
            names = tuple(c.strip() for c in w.split(",") if c.strip()) if isinstance(w, str) else tuple(w)
            if names in (("auto",), ("default",)):
                names = names[0]
            elif names == ("none",):
                names = ()
            else:
                bad = [n for n in names if n not in EFFECTS]
                if bad or not names:
                    _bad("with_effects", w, f"use default, none, auto or effects among {', '.join(EFFECTS)}")
            object.__setattr__(self, "with_effects", names)
        if self.with_effects and self.with_effects != "default" and self.scheme == 2:
            _bad("with_effects", self.with_effects, "--with fits effects with the Scheme 1 curve; use it without "
                 "--scheme 2 (a window's constant Cd cannot carry them)")
        if self.noise_model not in NOISE_MODELS:
            _bad("noise_model", self.noise_model, f"use one of {', '.join(NOISE_MODELS)}")
        if not isinstance(self.sample_ar, bool):
            _bad("sample_ar", self.sample_ar, "use True or False")
        if self.nu != "sample":
            try:
                nu = float(self.nu)
            except (TypeError, ValueError):
                nu = float("nan")
            lo, hi = NU_RANGE
            if not (lo <= nu <= hi):
                _bad("nu", self.nu, f"use Student-t degrees of freedom in [{lo:g}, {hi:g}] (1: Cauchy tails; "
                                    f"{hi:g}: all but Gaussian) or 'sample'")
            object.__setattr__(self, "nu", nu)
        _int("window", self.window, 1)
        _int("overlap", self.overlap, 0)
        if self.walkers is not None:
            _int("walkers", self.walkers, 1)
            if self.walkers > MAX_WALKERS:
                _bad("walkers (--walkers)", self.walkers, f"use at most {MAX_WALKERS} (16 is the default; more "
                     f"walkers do not buy effective samples per second here)")
        if isinstance(self.max_steps, bool) or not isinstance(self.max_steps, int) or self.max_steps < MIN_MAX_STEPS:
            _bad("max_steps (--max-steps)", self.max_steps,
                 f"use an integer >= {MIN_MAX_STEPS} (the sampler's first convergence check)")
        if self.max_steps > MAX_MAX_STEPS:
            _bad("max_steps (--max-steps)", self.max_steps, f"use at most {MAX_MAX_STEPS} (the run stops earlier "
                 f"at convergence; the default is 20000)")
        if self.moves not in MOVES:
            _bad("moves", self.moves, f"use one of {', '.join(MOVES)}")
        if self.seed is not None:
            _int("seed", self.seed, 0)

    def check_windows(self, n_samples):
        """Refuse (:class:`~bayesdrag.errors.InputError`) a Scheme 2 fit of a track of
        ``n_samples`` samples that would make more than :data:`MAX_WINDOWS` windows, before any
        is fitted."""
        from .estimate.scheme2 import window_slices

        n = len(window_slices(int(n_samples), self.window, self.overlap))
        if n > MAX_WINDOWS:
            _bad("window (--window)", self.window,
                 f"with overlap {self.overlap} it makes {n} Scheme 2 windows of this {n_samples}-sample track, and "
                 f"one run fits at most {MAX_WINDOWS} (one after the other): use a window of at least "
                 f"{-(-int(n_samples) // MAX_WINDOWS) + self.overlap} samples or a smaller overlap")

    @property
    def ml_nu(self):
        """Degrees of freedom of the robust ML fit (the default when the posterior samples them)."""
        return DEFAULT_NU if self.nu == "sample" else float(self.nu)

    def to_dict(self):
        """The options as a plain dict (for fingerprints and records)."""
        d = asdict(self)
        if d["channels"] is not None:
            d["channels"] = list(d["channels"])
        if not isinstance(d["with_effects"], str):
            d["with_effects"] = list(d["with_effects"])   # as JSON holds it: a fingerprint compares equal
        return d

    @classmethod
    def names(cls):
        return tuple(f.name for f in fields(cls))


#: what ``simulate --radar`` records: the gun-frame channels or the radar's own
SIMULATION_RADARS = ("gun", "native")


@dataclass(frozen=True)
class SimulateOptions:
    """Options of ``bayesdrag simulate`` / :func:`bayesdrag.simulate`.

    Attributes
    ----------
    model : {"pointmass", "6dof"}
    dt : float
        Sample interval [s] (default 0.027, the paper's radar).
    noise : bool
        Add Gaussian noise with the round's ``[radar] sigma``.
    seed : int or None
        Seed of the noise generator.
    clock_offset : float
        The radar clock is late by this much [s] (recorded time = true time - offset).
    radar : {"gun", "native"}
        ``gun`` (default) writes ``x, y, z, v`` in the gun's frame; ``native`` what a tracking
        radar at the round's ``[radar] position`` records: ``range, azimuth, elevation,
        range_rate`` (noise in those coordinates).
    """

    model: str = "pointmass"
    dt: float = 0.027
    noise: bool = False
    seed: int | None = None
    clock_offset: float = 0.0
    radar: str = "gun"

    def __post_init__(self):
        if self.model not in SIMULATION_MODELS:
            _bad("model", self.model, f"use one of {', '.join(SIMULATION_MODELS)}")
        if not (isinstance(self.dt, (int, float)) and math.isfinite(self.dt) and 1e-4 <= self.dt <= 5.0):
            _bad("dt", self.dt, "use a sample interval in [0.0001, 5] s")
        if not (isinstance(self.clock_offset, (int, float)) and math.isfinite(self.clock_offset)
                and abs(self.clock_offset) <= 1.0):
            _bad("clock_offset", self.clock_offset, "use a finite offset within +-1 s")
        if self.radar not in SIMULATION_RADARS:
            _bad("radar", self.radar, f"use one of {', '.join(SIMULATION_RADARS)}")
        if self.seed is not None:
            _int("seed", self.seed, 0)
            if not self.noise:
                raise InputError("option seed only makes sense with noise (it seeds the noise generator)")


@dataclass(frozen=True)
class DiagnoseOptions:
    """Options of ``bayesdrag diagnose`` / :func:`bayesdrag.diagnose`.

    Attributes
    ----------
    channels : tuple of str or None
        Subset of the track's channels (default all).
    material_cd_shift : float
        An effect is material when ignoring it would shift a fitted Cd by more than this
        fraction anywhere in the flown Mach range (default 0.001 = 0.1 %) ...
    material_end_sd : float
        ... or move the track by more than this many noise sd at its end (default 3).
    alpha : float
        Family-wise false-alarm rate of the verdict (default 0.05).
    """

    channels: tuple | None = None
    material_cd_shift: float = 0.001
    material_end_sd: float = 3.0
    alpha: float = 0.05

    def __post_init__(self):
        for name in ("material_cd_shift", "material_end_sd"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (v > 0 and math.isfinite(v)):
                _bad(name, v, "use a positive finite number")
        if not (isinstance(self.alpha, (int, float)) and 0 < self.alpha < 1):
            _bad("alpha", self.alpha, "use a probability in (0, 1)")
        if self.channels is not None:
            ch = tuple(self.channels)
            if not ch or any(c not in CHANNELS for c in ch):
                _bad("channels", self.channels, f"use a non-empty subset of {', '.join(CHANNELS)}")
            object.__setattr__(self, "channels", ch)


@dataclass(frozen=True)
class BatchOptions:
    """Options of ``bayesdrag batch`` and of fitting a campaign.

    Attributes
    ----------
    jobs : tuple of str
        Jobs per round: ``fit`` and/or ``diagnose``.
    fit : FitOptions
    scheduler : str or None
        Address of a Dask scheduler (default: a local cluster).
    workers : int or None
        Local cluster worker processes (default 2).
    covariance : {"colored", "crb"}
        Stage-1 covariance of each round's Cd for the pooling.
    """

    jobs: tuple = ("fit",)
    fit: FitOptions = FitOptions()
    scheduler: str | None = None
    workers: int | None = None
    covariance: str = "colored"

    def __post_init__(self):
        jobs = tuple(self.jobs)
        if not jobs or any(j not in JOBS for j in jobs):
            _bad("jobs", self.jobs, f"use a non-empty subset of {', '.join(JOBS)}")
        object.__setattr__(self, "jobs", jobs)
        if self.workers is not None:
            _int("workers", self.workers, 1)
            if self.workers > MAX_WORKERS:
                _bad("workers (--workers)", self.workers, f"use at most {MAX_WORKERS} local worker processes (the "
                     f"default is one per CPU); for more, start a Dask cluster and give --scheduler")
        if self.scheduler is not None and (not isinstance(self.scheduler, str)
                                           or not _SCHEDULER_RE.match(self.scheduler)):
            _bad("scheduler (--scheduler)", self.scheduler, "give a Dask scheduler address such as "
                 "tcp://host:8786 or host:8786")
        if self.covariance not in ("colored", "crb"):
            _bad("covariance", self.covariance, "use colored or crb")


#: a planned elevation must lie inside this open interval [deg]
PLAN_ELEVATION_RANGE = (0.0, 90.0)
#: largest planned launch velocity [m/s] (as the round's)
PLAN_VELOCITY_MAX = 3000.0
#: largest round-to-round scatter of Cd a plan accepts [-] (50 %: beyond it the shells differ)
PLAN_SCATTER_MAX = 0.5
#: most cases (elevations x velocities) one plan may hold
PLAN_MAX_CASES = 64
#: farthest candidate radar site from the gun [m]: the radar's own limit
PLAN_SITE_MAX = RADAR_SITE_MAX


def _number_list(name, values, lo, hi, unit, lo_open=True):
    """A tuple of floats in (lo, hi] (or [lo, hi] when not ``lo_open``), or None."""
    if values is None:
        return None
    vals = (values,) if isinstance(values, (int, float)) and not isinstance(values, bool) else values
    try:
        out = tuple(float(v) for v in vals if not isinstance(v, bool))
        if len(out) != len(tuple(vals)):
            raise TypeError
    except (TypeError, ValueError):
        _bad(name, values, f"use a list of numbers in {unit}")
    low_ok = (lambda v: v > lo) if lo_open else (lambda v: v >= lo)
    if not out or not all(math.isfinite(v) and low_ok(v) and v <= hi for v in out):
        _bad(name, values, f"use one or more values in {'(' if lo_open else '['}{lo:g}, {hi:g}] {unit}")
    return out


@dataclass(frozen=True)
class PlanOptions:
    """Options of ``bayesdrag plan`` / :func:`bayesdrag.plan`.

    Attributes
    ----------
    elevations : tuple of float or None, deg
        Planned quadrant elevations, each in (0, 90) (default: the round's ``[launch] elevation``).
    velocities : tuple of float or None, m/s
        Planned launch velocities (charges) (default: the round's ``[launch] velocity``). The
        cases are every elevation x velocity pair (at most 64).
    dt : float, s
        Radar sample interval (default 0.027, the paper's radar, as ``simulate``).
    rounds : int
        Rounds fired per case, pooled (default 1).
    scatter : float
        Round-to-round relative sd of Cd (0.01 = 1 %; default 0): with ``rounds`` the sd is that
        of the population mean.
    target : float or None
        Target relative sd of Cd (0.005 = 0.5 %): the plan then says which combination of the
        cases reaches it over the widest Mach interval.
    lock_on, loss : float or None, s
        The tracked part of the flight: from ``lock_on`` (default launch) to ``loss`` (default
        impact).
    seed : int
        Seed of the noisy realisation whose start curve places the fit's knots (default 0).
    radar_sites : tuple of (x, y, z) or None, m
        Candidate sites of a radar recording its own channels (``range, azimuth, elevation,
        range_rate`` in the round's ``[radar] sigma``), in the gun frame: every case is planned
        from each (cases x sites at most 64), and the plan names the best.
    """

    elevations: tuple | None = None
    velocities: tuple | None = None
    dt: float = 0.027
    rounds: int = 1
    scatter: float = 0.0
    target: float | None = None
    lock_on: float | None = None
    loss: float | None = None
    seed: int = 0
    radar_sites: tuple | None = None

    def __post_init__(self):
        lo, hi = PLAN_ELEVATION_RANGE
        if self.radar_sites is not None:
            try:
                sites = tuple(tuple(float(v) for v in p) for p in self.radar_sites)
            except (TypeError, ValueError):
                sites = None
            if not sites or any(len(p) != 3 or not all(math.isfinite(v) for v in p) or math.hypot(*p) > PLAN_SITE_MAX
                                for p in sites):
                _bad("radar_sites", self.radar_sites,
                     f"give sites as x,y,z [m] in the gun frame, each within {PLAN_SITE_MAX:g} m (e.g. -40,25,2;0,-30,1)")
            object.__setattr__(self, "radar_sites", sites)
        el = _number_list("elevations", self.elevations, lo, hi, "deg")
        if el is not None and any(v >= hi for v in el):
            _bad("elevations", self.elevations, f"use elevations in ({lo:g}, {hi:g}) deg")
        object.__setattr__(self, "elevations", el)
        object.__setattr__(self, "velocities", _number_list("velocities", self.velocities, 0.0, PLAN_VELOCITY_MAX, "m/s"))
        n_sites = len(self.radar_sites) if self.radar_sites else 1
        if el is not None and self.velocities is not None and len(el) * len(self.velocities) * n_sites > PLAN_MAX_CASES:
            _bad("elevations x velocities x radar sites", f"{len(el)} x {len(self.velocities)} x {n_sites}",
                 f"plan at most {PLAN_MAX_CASES} cases at once")
        if isinstance(self.dt, bool) or not (isinstance(self.dt, (int, float)) and math.isfinite(self.dt)
                                             and 1e-4 <= self.dt <= 5.0):
            _bad("dt", self.dt, "use a sample interval in [0.0001, 5] s")
        _int("rounds", self.rounds, 1)
        if isinstance(self.scatter, bool) or not (isinstance(self.scatter, (int, float))
                                                  and 0.0 <= self.scatter <= PLAN_SCATTER_MAX):
            _bad("scatter", self.scatter, f"use a relative sd in [0, {PLAN_SCATTER_MAX:g}] (0.01 = 1 %)")
        if self.target is not None and (isinstance(self.target, bool) or not (
                isinstance(self.target, (int, float)) and 0.0 < self.target < 1.0)):
            _bad("target", self.target, "use a relative sd of Cd in (0, 1) (0.005 = 0.5 %)")
        for name in ("lock_on", "loss"):
            v = getattr(self, name)
            if v is not None and (isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0)):
                _bad(name, v, "use a time since launch >= 0 s")
        if self.loss is not None and not self.loss > (self.lock_on or 0.0):
            _bad("loss", self.loss, f"use a time after the lock-on ({self.lock_on or 0.0:g} s)")
        _int("seed", self.seed, 0)

    def to_dict(self):
        """The options as a plain dict."""
        d = asdict(self)
        for k in ("elevations", "velocities"):
            if d[k] is not None:
                d[k] = list(d[k])
        if d["radar_sites"] is not None:
            d["radar_sites"] = [list(p) for p in d["radar_sites"]]
        return d
