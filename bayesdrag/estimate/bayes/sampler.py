"""Sampling a :class:`~bayesdrag.estimate.bayes.posterior.LogPosterior` with emcee until converged.

Run (choices measured, see ``docs/bayes.md`` and ``benchmarks/fit.py --moves``)
    * ``emcee.EnsembleSampler(vectorize=True)``: one kernel call per half-ensemble move, with
      the moves of :mod:`bayesdrag.estimate.bayes.moves`.
    * Walkers start as draws from the Gaussian (Laplace) approximation of the posterior
      (:meth:`~bayesdrag.estimate.bayes.posterior.LogPosterior.initial_walkers`), so the burn-in is
      short.
    * Run length: every ``check_every`` steps the integrated autocorrelation time tau is
      estimated (emcee's walker-averaged estimator, :func:`integrated_time`); the run stops when
      the chain is longer than ``TAU_FACTOR`` (50) x max tau, tau changed by < ``TAU_RTOL``
      (5 %) since the last check, and, on the burnt-in and thinned draws, the rank-normalised
      split ``r_hat < 1.01`` and bulk and tail ESS >= 400 for every parameter; or at
      ``max_steps`` (then ``converged=False`` with a message). Burn-in = ceil(3 max tau),
      thinning = max(1, floor(min tau / 2)).
    * Diagnostics (:func:`split_rank_rhat`, :func:`ess`, :func:`convergence_table`, in
      :mod:`bayesdrag.estimate.bayes.chain_diagnostics`) are numpy versions of ArviZ's ``rhat``,
      ``ess`` and ``mcse`` (Vehtari et al. 2021): the same numbers, without ArviZ.
    * Progress: the bar's total (and the status lines) are the steps convergence needs by the
      chain's current tau (:func:`steps_to_converge`), re-estimated at every check.
    * The chain is written as it runs to an HDF5 file (:class:`bayesdrag.io.chain.ChainFile`,
      flushed every ``check_every`` steps); a run restarted on the same file (``resume=True``)
      continues it from its last flushed step with the stored random state, so the continued
      chain is the one an uninterrupted run would have produced.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import math
import time
from dataclasses import dataclass, field

import emcee
import numpy as np

from ..._runtime.renamed import renamed_getattr, warn_renamed
from ..._runtime.threads import single_blas
from ..._runtime.signals import deferred_interrupt
from ...errors import FitWarning, InputError
from ...io.chain import ChainFile
from .chain_diagnostics import ess, integrated_time, split_rank_rhat, convergence_table
from .coords import TEMPERATURE
from .moves import describe_moves, make_moves

#: run until the chain is this many autocorrelation times long
TAU_FACTOR = 50.0
#: relative change of tau between checks below which it counts as stable
TAU_RTOL = 0.05
#: convergence thresholds (rank-normalised split R-hat, bulk and tail ESS)
RHAT_MAX = 1.01
ESS_MIN = 400
#: default number of walkers
DEFAULT_WALKERS = 16
#: default walkers when a declared temperature offset is sampled (drift coordinates with a
#: temperature): a few walkers mix that posterior eight times slower (docs/bayes.md, Known limits)
SOURCE_WALKERS = 128
#: default steps between convergence checks (and chain-file flushes)
CHECK_EVERY = 25


@dataclass(frozen=True, eq=False)
class BayesResult:
    """Outcome of :func:`sample_posterior`.

    Attributes
    ----------
    names : tuple of str
        Sampled parameter names plus ``log_sigma_<c>`` (and ``log_nu``) in the draws.
    draws : (chains, draws, K) ndarray
        Burnt-in, thinned draws; walkers are the chains. The last columns are the noise
        ``log_sigma_<c>`` (Gaussian: exact conditional draws) [log m or log m/s].
    lp : (chains, draws) ndarray
        Log posterior of each draw (sampled coordinates).
    thetas : (chains, draws, n) ndarray
        Full parameter vectors (fixed parameters included), for predictions.
    tau : (D,) ndarray
        Integrated autocorrelation time per sampled coordinate [steps].
    steps, burn, thin, nwalkers : int
        Chain length, burn-in and thinning [steps]; walkers.
    acceptance : float
        Mean acceptance fraction.
    converged : bool
    message : str
    convergence : pandas.DataFrame
        Per name of ``names``: mean, sd, q05, q50, q95, mcse_mean, ess_bulk, ess_tail, r_hat
        (:func:`convergence_table`; ArviZ's definitions).
    elapsed : float
        Wall-clock seconds of sampling (this call).
    moves : str
        The move mix, described.
    likelihood : str
    warnings : tuple of str
    resumed_from : int
        Steps already in the chain file when this call started (0: a fresh chain).
    tau_history : tuple of (steps, max tau)
    chain : (steps, walkers, D) ndarray
        The whole chain of the sampled coordinates, burn-in included (for trace plots).
    """

    names: tuple
    draws: np.ndarray
    lp: np.ndarray
    thetas: np.ndarray
    tau: np.ndarray
    steps: int
    burn: int
    thin: int
    nwalkers: int
    acceptance: float
    converged: bool
    message: str
    convergence: object
    elapsed: float
    moves: str
    likelihood: str
    warnings: tuple = ()
    resumed_from: int = 0
    tau_history: tuple = field(default_factory=tuple)
    chain: np.ndarray = None

    @property
    def summary(self):
        """Deprecated name of :attr:`convergence` (removed in release 0.3): "summary" is a
        result's printable table."""
        warn_renamed("BayesResult.summary", "BayesResult.convergence")
        return self.convergence

    @property
    def r_hat(self):
        """dict name -> rank-normalised split R-hat."""
        return dict(zip(self.convergence.index, self.convergence["r_hat"].astype(float)))

    @property
    def ess_bulk(self):
        """dict name -> bulk effective sample size [draws]."""
        return dict(zip(self.convergence.index, self.convergence["ess_bulk"].astype(float)))

    @property
    def ess_tail(self):
        """dict name -> tail effective sample size [draws]."""
        return dict(zip(self.convergence.index, self.convergence["ess_tail"].astype(float)))


# --------------------------------------------------------------------------- diagnostics
@dataclass(frozen=True)
class _Streams:
    """The random streams of one run: walkers' start, noise draws, emcee's generator."""

    start: np.random.Generator
    noise: np.random.Generator
    emcee_state: tuple
    label: object          # identifies the streams in the chain file's fingerprint


def _streams(rng, seed):
    """Derive a run's three random streams (walker start, noise draws, emcee's generator) from
    ``rng``, or from ``seed`` by a fixed rule (so a given seed always gives the same chain)."""
    if rng is not None and seed is not None:
        raise TypeError("sample_posterior: give rng or seed, not both")
    if rng is None:
        seed = None if seed is None else int(seed)
        rs = np.random.RandomState(None if seed is None else np.random.SeedSequence(seed).generate_state(1)[0])
        return _Streams(np.random.default_rng(seed), np.random.default_rng(None if seed is None else seed + 1),
                        rs.get_state(), seed)
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"sample_posterior: rng must be a numpy.random.Generator, got {type(rng).__name__}")
    state = json.dumps(rng.bit_generator.state, sort_keys=True, default=lambda a: np.asarray(a).tolist())
    label = "rng:" + hashlib.sha256(state.encode()).hexdigest()[:16]
    start, noise, mt = np.random.SeedSequence(rng.integers(0, 2**63, size=4)).spawn(3)
    return _Streams(np.random.default_rng(start), np.random.default_rng(noise),
                    np.random.RandomState(np.random.MT19937(mt)).get_state(), label)


def _fingerprint(post, nwalkers, moves, label):
    """Hash of everything that defines a chain, stored in the chain file to refuse resuming a
    different problem."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(post.problem.z).tobytes())
    h.update(np.ascontiguousarray(post.problem.track.t).tobytes())
    h.update(np.round(post.laplace_mean, 9).tobytes())
    h.update(json.dumps([list(post.names), post.likelihood, str(post.nu), nwalkers, moves, label]).encode())
    return h.hexdigest()[:16]


def sample_posterior(post, *, nwalkers=None, max_steps=20000, min_steps=100, check_every=None, rng=None,
                     seed=None, moves="auto", move_options=None, backend_path=None, resume=False,
                     progress=False, log=None):
    """Sample ``post`` with emcee until converged (module docstring) or ``max_steps``.

    Parameters
    ----------
    post : LogPosterior
    nwalkers : int, optional
        Default :data:`DEFAULT_WALKERS` (16; rounded up to even). The stopping rule counts steps
        (50 tau, and r_hat < 1.01 needs some 100 effective draws per walker), so the cost grows
        with the walkers; the independence move needs no minimum number, and 16 walkers give a
        total ESS well above 400 at the stop.
    max_steps : int
        Hard limit of ensemble steps (the chain's total length, resumed part included).
    min_steps : int
        Never stop before this many steps.
    check_every : int, optional
        Steps between convergence checks and chain-file flushes (default 25 x walkers // 16, at
        least 25: a check costs in proportion to the walkers).
    rng : numpy.random.Generator, optional
        Consumed once to derive the walkers' start, the noise draws and emcee's generator.
    seed : int, optional
        Alternative to ``rng`` (give one of them): derives the streams by a fixed rule, so a
        given seed always gives the same chain. Neither: fresh entropy.
    moves : {"auto", "de", "stretch"}
        Move mix (:func:`~bayesdrag.estimate.bayes.moves.make_moves`).
    move_options : dict, optional
        Keyword options of :func:`~bayesdrag.estimate.bayes.moves.make_moves` (weight, scale, dof).
    backend_path : path, optional
        HDF5 file the chain is written to as it runs (:class:`~bayesdrag.io.chain.ChainFile`;
        ``None``: memory only).
    resume : bool
        Continue the chain in ``backend_path`` (checked: same problem and settings, consistent
        and finite values); a file holding no step is started afresh.
    progress : bool
        Show a tqdm progress bar.
    log : callable, optional
        Called with one-line status messages at each convergence check.

    Returns
    -------
    BayesResult

    Raises
    ------
    InputError
        Bad walkers or moves, or a chain file that cannot be resumed (one line naming it).
    """
    with single_blas():   # the kernel's threads use the cores, not BLAS's
        D = post.ndim
        nwalkers = int(DEFAULT_WALKERS if nwalkers is None else nwalkers)
        nwalkers += nwalkers % 2
        if nwalkers < 2 * D and moves != "auto":
            raise InputError(f"--walkers {nwalkers}: ensemble moves need at least 2 x {D} walkers")
        if nwalkers < 8:
            raise InputError(f"--walkers {nwalkers}: at least 8 walkers are needed")
        # a check reads the whole chain (autocorrelation FFT, split R-hat): its cost grows with the
        # walkers, so larger ensembles check less often
        check_every = int(check_every or CHECK_EVERY * max(1, nwalkers // DEFAULT_WALKERS))
        streams = _streams(rng, seed)
        move_list = make_moves(moves, post, nwalkers=nwalkers, **(move_options or {}))
        backend, resumed = _open_backend(backend_path, resume, post, nwalkers, check_every,
                                         _fingerprint(post, nwalkers, moves, streams.label))
        sampler = emcee.EnsembleSampler(nwalkers, D, post, moves=move_list, vectorize=True, backend=backend,
                                        blobs_dtype=float)
        state = None
        if not resumed:
            state = emcee.State(post.initial_walkers(nwalkers, rng=streams.start), random_state=streams.emcee_state)
        t0 = time.perf_counter()
        converged, message, tau, tau_hist = _run(sampler, state, post, backend, resumed, max_steps, min_steps,
                                                 check_every, progress, log)
        elapsed = time.perf_counter() - t0
        return _collect(post, sampler, tau, converged, message, elapsed, moves, streams.noise, resumed, tau_hist)


def _open_backend(path, resume, post, nwalkers, check_every, fingerprint):
    """(backend, steps already stored): the resumed chain file, a fresh one, or (None, 0)."""
    if path is None:
        return None, 0
    # a ChainFile given by the command carries the digest of the input files' bytes
    cf = ChainFile(path, flush_every=check_every, inputs=getattr(path, "inputs", None))
    backend = None
    if resume and cf.exists():
        backend = cf.load_backend(nwalkers=nwalkers, ndim=post.ndim, nblobs=post.C, fingerprint=fingerprint,
                                  log_prob=post)   # stored values recomputed before the chain is continued
    if backend is None:
        return cf.new_backend(nwalkers, post.ndim, fingerprint=fingerprint), 0
    return backend, backend.iteration


def _run(sampler, state, post, backend, done, max_steps, min_steps, check_every, progress, log):
    """The sampling loop with its convergence checks; returns (converged, message, tau,
    tau history)."""
    bar = None
    target = min(max_steps, max(min_steps, done + check_every))
    if progress:
        from tqdm.auto import tqdm

        # the bar's total is the steps convergence needs as the chain shows them (re-estimated at
        # every check), not --max-steps: a run converging at 925 steps ends at 100 %
        bar = tqdm(total=target, initial=done, desc="mcmc (to convergence)", unit="step", leave=False)
    old_tau = None
    tau = np.full(post.ndim, np.nan)
    tau_hist = []
    stop = contextlib.ExitStack()
    interrupted = stop.enter_context(deferred_interrupt())   # Ctrl-C between blocks, not inside numba/emcee
    try:
        while done < max_steps:
            n = min(check_every, max_steps - done) if done >= min_steps else max(min_steps - done, 1)
            n = min(n, max_steps - done)
            sampler.run_mcmc(state, n, progress=False, skip_initial_state_check=True)
            state = None
            done = sampler.iteration
            if backend is not None:
                backend.flush()
            interrupted()
            if bar is not None:
                bar.update(n)
            if done < min_steps:
                continue
            tau = integrated_time(sampler.get_chain())
            tmax = float(np.max(tau))
            tau_hist.append((done, tmax))
            stable = old_tau is not None and np.all(np.abs(tau - old_tau) < TAU_RTOL * old_tau)
            old_tau = tau
            target = steps_to_converge(done, tmax, sampler.nwalkers, check_every, max_steps)
            if bar is not None:
                bar.total = target
                bar.set_description("mcmc (to convergence)" if stable else "mcmc (to convergence, at least)")
            # a short chain's tau is a lower bound until two checks agree: so is the target then
            msg = (f"mcmc: {done} of {'~' if stable else 'at least ~'}{target} steps (the convergence target: "
                   f"{TAU_FACTOR:g} tau and ESS "
                   f">= {ESS_MIN:g}), tau max {tmax:.1f}, acceptance {np.mean(sampler.acceptance_fraction):.2f}")
            if done >= TAU_FACTOR * tmax and stable and np.isfinite(tmax):
                draws, burn, _ = _retained(sampler, tau)
                fast_r = float(np.max(split_rank_rhat(draws)))
                ess_est = sampler.nwalkers * (done - burn) / tmax
                msg += f", r_hat max {fast_r:.4f}, ESS ~{ess_est:.0f}"
                if fast_r < RHAT_MAX and ess_est >= ESS_MIN:
                    # the reported diagnostics (bulk and tail ESS too) must confirm before stopping;
                    # the reported r_hat is split_rank_rhat of these draws, i.e. fast_r
                    worst_r = fast_r
                    min_ess = _min_finite(np.concatenate([ess(draws, method="bulk"), ess(draws, method="tail")]))
                    if worst_r < RHAT_MAX and min_ess >= ESS_MIN:
                        if bar is not None:
                            bar.total = done
                            bar.refresh()
                        if log:
                            log(msg)
                        return (True, f"converged: {done} steps >= {TAU_FACTOR:g} tau (max {tmax:.1f}), "
                                      f"r_hat max {worst_r:.4f}, ESS min {min_ess:.0f}", tau, tuple(tau_hist))
            if log:
                log(msg)
    finally:
        if bar is not None:
            bar.close()
        stop.close()
    if not np.isfinite(tau).any():       # a resumed chain already at max_steps: no block was run
        tau = integrated_time(sampler.get_chain())
    tau_txt = f"{np.max(tau):.1f}" if np.isfinite(tau).any() else "unknown"
    message = (f"not converged after {done} steps (max_steps): tau max {tau_txt} "
               f"needs {TAU_FACTOR:g} tau; the draws are reported but check the diagnostics")
    return False, message, tau, tuple(tau_hist)


def steps_to_converge(done, tau_max, nwalkers, check_every, max_steps):
    """The chain length [steps] convergence needs by the chain's current autocorrelation time:
    :data:`TAU_FACTOR` tau, and an ESS of :data:`ESS_MIN` after the burn-in of 3 tau; at least
    one more block than is done, at most ``max_steps``. The progress bar's total."""
    if not np.isfinite(tau_max) or tau_max <= 0:
        return int(min(max_steps, done + check_every))
    need = max(TAU_FACTOR * tau_max, 3.0 * tau_max + ESS_MIN * tau_max / max(nwalkers, 1))
    return int(min(max_steps, max(math.ceil(need), done + check_every)))


def _min_finite(x):
    """Smallest non-NaN value of ``x`` (NaN when there is none), as ``convergence_table``'s columns'
    ``min()`` gives it."""
    x = np.asarray(x, float)
    x = x[~np.isnan(x)]
    return float(x.min()) if x.size else float("nan")


def _retained(sampler, tau):
    """Burnt-in, thinned draws (walkers, draws, D), burn-in and thinning [steps]."""
    tmax = float(np.max(tau))
    burn = int(math.ceil(3 * tmax))
    thin = max(1, int(np.min(tau) // 2))
    draws = np.swapaxes(sampler.get_chain(discard=burn, thin=thin), 0, 1)
    return draws, burn, thin


def _collect(post, sampler, tau, converged, message, elapsed, moves, noise_rng, resumed, tau_hist):
    """The :class:`BayesResult` of a finished run (noise draws from ``noise_rng``)."""
    if not np.all(np.isfinite(tau)):
        tau = integrated_time(sampler.get_chain())
    draws, burn, thin = _retained(sampler, tau)
    if draws.shape[1] < 4:  # very short (max_steps tiny): keep the second half
        burn = sampler.iteration // 2
        thin = 1
        draws = np.swapaxes(sampler.get_chain(discard=burn), 0, 1)
    lp = np.swapaxes(sampler.get_log_prob(discard=burn, thin=thin), 0, 1)
    blobs = np.swapaxes(sampler.get_blobs(discard=burn, thin=thin), 0, 1)  # (W, S, C)
    W, S, D = draws.shape
    flat = draws.reshape(-1, D)
    sig = post.sigma_draws(flat, blobs.reshape(-1, post.C), rng=noise_rng)
    draws = post.reported(flat).reshape(W, S, D)      # sampled coordinates -> parameters' units
    if post.likelihood == "gaussian":
        full = np.concatenate([draws, np.log(sig).reshape(W, S, post.C)], axis=-1)
        names = post.names + tuple(f"log_sigma_{c}" for c in post.channels)
    else:
        full = draws
        names = post.names
    thetas = post.full_theta(flat).reshape(W, S, -1)
    convergence = convergence_table(full, names)
    warns = [] if converged else [FitWarning("sampler", message)]
    bad_r = [n for n, r in zip(convergence.index, convergence["r_hat"]) if not r < RHAT_MAX]
    if bad_r:
        warns.append(FitWarning("sampler", f"r_hat >= {RHAT_MAX} for {', '.join(bad_r[:6])}", tuple(bad_r[:6])))
    acc = float(np.mean(sampler.acceptance_fraction))
    if acc < 0.1:
        warns.append(FitWarning("sampler", f"mean acceptance {acc:.3f} is very low: the chain barely moves"
                                + (" (the posterior is far from its Gaussian approximation, e.g. a poorly "
                                   "identified drag model; try --moves de)" if moves == "auto" else "")))
    return BayesResult(names, full, lp, thetas, np.asarray(tau), int(sampler.iteration), burn, thin, W,
                       acc, converged, message, convergence, elapsed, describe_moves(moves), post.likelihood,
                       tuple(warns), resumed, tau_hist, sampler.get_chain())


def default_walkers(post, moves="auto"):
    """Walkers of a run whose ``nwalkers`` was not given.

    Parameters
    ----------
    post : LogPosterior
        Its ``ndim`` and ``coords`` (:mod:`bayesdrag.estimate.bayes.coords`).
    moves : str
        The move mix's name.

    Returns
    -------
    int
        ``2 ndim + 2`` for the ensemble moves (``de``, ``stretch``); :data:`SOURCE_WALKERS` for
        the ``auto`` mix when a temperature offset is sampled; else :data:`DEFAULT_WALKERS`.
    """
    if moves != "auto":
        return 2 * post.ndim + 2
    coords = getattr(post, "coords", None)
    if coords is not None and TEMPERATURE in coords.pos:
        return SOURCE_WALKERS
    return DEFAULT_WALKERS

#: old names, kept with a warning until release 0.3
__getattr__ = renamed_getattr(__name__, {"summarize": "convergence_table"}, globals())
