"""One-sided contamination of a channel's noise: a Gaussian core plus a tail on one side only.

A chronograph radar's bad samples (a Doppler lock on the wrong echo late in the track, a fade)
read high, not high and low alike. A symmetric robust fit (Student-t) down-weights a high sample
and a low one the same, so outliers of a few sd on one side still pull the curve towards them:
measured on chronograph tracks, 10 % of the samples (from the track's second half) 2-6 sd high
moved the default fit's Cd by -0.9 band sd on average (mean z -0.39 to -1.27), and the Student-t fit did not remove it
(docs/fitting.md, "One-sided outliers"; tests/acceptance/run_chronograph_outliers.py).

The model of a channel's noise, in units of each sample's own sd (``sigma_c`` times its per-sample
scale, :func:`bayesdrag.measure.sample_noise`)::

    u ~ (1 - eps) N(0, 1) + eps EMG(lam)

``EMG(lam)``: the sample's noise plus an offset ``delta >= 0`` on the tail's side, exponential
with mean ``lam`` [core sd] (the exponentially modified Gaussian; one scale, no upper end to
choose). ``eps`` (the contamination fraction) and ``lam`` are estimated with the fit by EM: the
E-step gives each sample the probability ``p`` that it is a tail sample, the M-step refits the
trajectory by least squares with weights ``1 - p`` (and ``eps``, ``lam``, the core sd from the
weighted residuals). The tail's own pull on the curve is left out of the M-step: its expectation
over tail samples is zero for any normalised tail (``integral g'(u) du = 0``), so leaving it out
costs a little efficiency and no bias.

When it engages (:func:`one_sided_evidence`), on the white-noise fit's residuals of a channel:
they are not structured (lag-1 autocorrelation at most :data:`STRUCTURED_LAG1`: a smooth misfit
is model error, which the AR(1) noise model and the diagnosis answer), and, less their running
median (:data:`DETREND_WINDOW` samples), a mixture with a tail on each side beats a Gaussian by a
likelihood ratio above :data:`ONE_SIDED_LR` (there is a tail) and a mixture whose two tails are
alike by one above :data:`ASYMMETRY_LR` (the tail is one-sided: excess alike on both sides is a
heavy symmetric tail, the Student-t's case). Measured false-alarm rate: 0 of 600 Gaussian series
(200 and 1000 samples), 0 of the clean chronograph tracks, 0 of the robustness suite's and the
native suite's fits (docs/fitting.md, "Noise"). A refit that takes more than
:data:`MAX_WEIGHT_LOST` of a channel's weight is a misfit the mixture swallowed: not kept.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Contamination", "fit_contamination", "one_sided_evidence", "contamination_refit", "running_median",
           "TAIL_FORMS", "ONE_SIDED_LR", "ASYMMETRY_LR", "STRUCTURED_LAG1", "MAX_WEIGHT_LOST", "DETREND_WINDOW",
           "MIN_TAIL_SD", "MAX_FRACTION", "DOWN_WEIGHTED", "MIN_SAMPLES"]

#: likelihood-ratio threshold of the mixture with a tail each side against a Gaussian (its false
#: alarms, measured on Gaussian residuals and clean tracks: docs/fitting.md, "One-sided outliers")
ONE_SIDED_LR = 25.0
#: running-median window [samples] the residuals are detrended by before the test
DETREND_WINDOW = 21
#: the tail's mean offset is at least this many core sd: a tail closer in reshapes the core (a
#: scale mixture of a wider and a narrower Gaussian) instead of holding bad samples
MIN_TAIL_SD = 2.0
#: likelihood-ratio threshold of the skewed mixture against the symmetric one (unlike tails):
#: chi-square(2) at 0.95 (the test of a tail, ONE_SIDED_LR, comes first)
ASYMMETRY_LR = 5.99
#: refits of the trajectory (EM iterations) at most, and the weight change that ends them
REFIT_ITERATIONS, REFIT_WEIGHT_TOL = 12, 0.01
#: residuals whose lag-1 autocorrelation exceeds this are structured (a misfit: model error, which
#: the AR(1) noise model and the diagnosis answer), not outliers: no test (white noise: 0 +- 2/sqrt(N);
#: docs/measurements.md, "Where the constants come from")
STRUCTURED_LAG1 = 0.3
#: a refit whose weights take off more than this share of a channel's samples is no contamination
#: of a few samples but a misfit the mixture has swallowed: the Gaussian fit is kept
MAX_WEIGHT_LOST = 0.4
#: the largest contamination fraction: beyond it the "core" is no longer the majority
MAX_FRACTION = 0.5
#: a sample whose weight (probability of the core) falls below this is listed as down-weighted
DOWN_WEIGHTED = 0.5
#: fewer samples than this in a channel: no test (too few to tell a tail from the core)
MIN_SAMPLES = 40
#: EM stops when the tails hold fewer samples' worth than this: the mixture is the Gaussian (a
#: clean channel's tails shrink geometrically towards nothing; waiting for that costs time and
#: changes no likelihood ratio beyond round-off)
COLLAPSED_TAIL_SAMPLES = 0.5
#: EM iterations of the one-dimensional mixture and its relative log-likelihood tolerance
EM_ITERATIONS, EM_TOL = 200, 1e-7

_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


@dataclass(frozen=True)
class Contamination:
    """A fitted contamination mixture of one channel's residuals: a Gaussian core and a tail on
    each side (:data:`TAIL_FORMS`).

    Attributes
    ----------
    form : str
        ``"high"``, ``"low"`` (one tail), ``"skewed"`` (a tail each side, each its own fraction and
        scale) or ``"symmetric"`` (a tail each side, one fraction and one scale).
    fraction : (2,) tuple of float
        ``eps`` of the high and the low tail.
    tail_sd : (2,) tuple of float
        ``lam`` of the high and the low tail [core sd].
    sd : float
        The core sd [the residuals' unit].
    location : float
        The core's centre [the residuals' unit] (0 when held).
    loglik, loglik_gauss : float
        The mixture's log-likelihood and the Gaussian's (centre and sd fitted or held alike).
    p : (N, 2) ndarray
        Each sample's probability of the high and of the low tail.
    """

    form: str
    fraction: tuple
    tail_sd: tuple
    sd: float
    location: float
    loglik: float
    loglik_gauss: float
    p: np.ndarray

    @property
    def lr(self):
        """``2 (log L_mixture - log L_gaussian)``."""
        return max(2.0 * (self.loglik - self.loglik_gauss), 0.0)

    @property
    def weights(self):
        """Each sample's probability of the core: its weight in the least squares."""
        return np.clip(1.0 - self.p.sum(axis=1), 0.0, 1.0)


#: the mixtures :func:`fit_contamination` fits: which tails are free (high, low) and whether tied
TAIL_FORMS = {"high": (True, False, False), "low": (False, True, False), "skewed": (True, True, False),
              "symmetric": (True, True, True)}


def _log_tail(z, lam):
    """Log density of the exponentially modified Gaussian (offset ``>= 0`` of mean ``lam``, unit
    noise) at ``z`` [core sd]."""
    from scipy.special import log_ndtr

    return -math.log(lam) + 0.5 / lam**2 - z / lam + log_ndtr(z - 1.0 / lam)


def _gauss_ll(x, mu, s):
    return float(np.sum(-0.5 * ((x - mu) / s) ** 2 - _LOG_SQRT_2PI - math.log(s)))


def fit_contamination(u, form="skewed", *, sd=None, location=True):
    """Maximum likelihood (EM) of a contamination mixture on residuals ``u``.

    Parameters
    ----------
    u : (N,) array
        Residuals, each over its sample's noise scale [the channel's unit].
    form : {"high", "low", "skewed", "symmetric"}
        Which tails (:data:`TAIL_FORMS`).
    sd : float, optional
        The core sd, held (the round's sigma); default estimated.
    location : bool
        Estimate the core's centre (the residuals of a fit pulled by a tail are off-centre);
        ``False`` holds it at 0 (the refit, whose curve is the centre).

    Returns
    -------
    Contamination
    """
    if form not in TAIL_FORMS:
        raise ValueError(f"contamination form {form!r} is not known (allowed: {', '.join(TAIL_FORMS)})")
    free_hi, free_lo, tied = TAIL_FORMS[form]
    free = np.array([free_hi, free_lo])
    x = np.asarray(u, float)
    n = x.size
    mu0 = float(np.mean(x)) if location else 0.0
    s0 = float(sd) if sd else max(float(np.sqrt(np.mean((x - mu0) ** 2))), 1e-12)
    ll0 = _gauss_ll(x, mu0, s0)
    mu = float(np.median(x)) if location else 0.0
    s = float(sd) if sd else max(1.4826 * float(np.median(np.abs(x - mu))), 1e-12)
    eps = np.where(free, 0.05 / free.sum(), 0.0)
    lam = np.array([3.0, 3.0])
    ll_old, p, ll = -np.inf, np.zeros((n, 2)), ll0
    for _ in range(EM_ITERATIONS):
        z = (x - mu) / s
        logs = [math.log1p(-float(eps.sum())) - 0.5 * z**2 - _LOG_SQRT_2PI]
        for k, sign in enumerate((1.0, -1.0)):
            if free[k]:
                logs.append(math.log(eps[k]) + _log_tail(sign * z, lam[k]))
        m = np.logaddexp.reduce(np.stack(logs), axis=0)
        p = np.zeros((n, 2))
        p[:, free] = np.exp(np.stack(logs[1:], axis=1) - m[:, None])
        ll = float(np.sum(m)) - n * math.log(s)
        if abs(ll - ll_old) <= EM_TOL * max(abs(ll), 1.0) or float(eps.sum()) * n < COLLAPSED_TAIL_SAMPLES:
            break       # converged, or the tails hold less than half a sample: the Gaussian itself
        ll_old = ll
        pz = np.array([np.sum(p[:, 0] * z), -np.sum(p[:, 1] * z)])
        ps = p.sum(axis=0)
        if tied:
            eps[:] = np.clip(ps.sum() / (2 * n), 1e-6, MAX_FRACTION / 2)
            lam[:] = max(pz.sum() / max(ps.sum(), 1e-12), MIN_TAIL_SD)
        else:
            eps = np.where(free, np.clip(ps / n, 1e-6, MAX_FRACTION / free.sum()), 0.0)
            lam = np.maximum(pz / np.maximum(ps, 1e-12), MIN_TAIL_SD)
        q = 1.0 - p.sum(axis=1)
        if location:
            mu = float(np.sum(q * x) / max(np.sum(q), 1e-12))
        if not sd:
            s = max(float(np.sqrt(np.sum(q * (x - mu) ** 2) / max(np.sum(q), 1e-12))), 1e-12)
    return Contamination(form, tuple(float(e) for e in eps), tuple(float(v) for v in lam), s, mu, ll, ll0, p)


def running_median(u, window=DETREND_WINDOW):
    """Median of ``u`` over the ``window`` samples centred on each (fewer at the ends).

    Parameters
    ----------
    u : (N,) array
    window : int, odd

    Returns
    -------
    (N,) ndarray
    """
    u = np.asarray(u, float)
    h = window // 2
    pad = np.pad(u, h, constant_values=np.nan)
    return np.nanmedian(np.lib.stride_tricks.sliding_window_view(pad, window), axis=1)


#: the tail test runs only where a side holds more samples beyond this many robust sd ...
EXCESS_K = 3.0
#: ... than Gaussian noise gives at this one-sided Poisson false-alarm rate (a channel whose
#: samples all lie where Gaussian noise puts them cannot carry a tail's likelihood ratio of 25)
EXCESS_ALPHA = 1e-3


def _tail_excess(d):
    """``[high, low]`` counts of ``d`` beyond :data:`EXCESS_K` robust sd of its median, or None
    when neither exceeds the Poisson :data:`EXCESS_ALPHA` quantile of Gaussian noise's count."""
    c = float(np.median(d))
    s = 1.4826 * float(np.median(np.abs(d - c)))
    if not s > 0:
        return None
    n = [int(np.sum(d > c + EXCESS_K * s)), int(np.sum(d < c - EXCESS_K * s))]
    lam = d.size * 0.5 * math.erfc(EXCESS_K / math.sqrt(2.0))     # Gaussian count beyond, one side
    k, term, cdf = 0, math.exp(-lam), math.exp(-lam)
    while cdf < 1.0 - EXCESS_ALPHA:                               # the Poisson quantile
        k += 1
        term *= lam / k
        cdf += term
    return n if max(n) > k else None


def one_sided_evidence(u, *, threshold=ONE_SIDED_LR, asymmetry=ASYMMETRY_LR, window=DETREND_WINDOW):
    """Whether a channel's residuals show a one-sided (skewed) tail beyond what Gaussian noise,
    or a heavy tail alike on both sides, allows.

    Two likelihood ratios on the detrended residuals (less their running median): the skewed
    mixture (a tail each side, each its own fraction and scale) against a Gaussian (``lr``: is
    there a tail at all) and against the symmetric mixture (``lr_asymmetry``: are the tails
    unlike). Above ``threshold`` and ``asymmetry`` they engage the skewed model; the side whose tail holds more
    (fraction times mean offset) names it.

    Parameters
    ----------
    u : (N,) array
        A fit's residuals of one channel over their samples' noise scale, in time order.
    threshold, asymmetry : float
        :data:`ONE_SIDED_LR`, :data:`ASYMMETRY_LR`.
    window : int
        :data:`DETREND_WINDOW`.

    Returns
    -------
    dict
        ``lr``, ``lr_asymmetry``, ``lag1`` (of the residuals: above :data:`STRUCTURED_LAG1` no test
        is made, ``skipped`` says why), ``threshold``, ``asymmetry_threshold``, ``engaged`` (bool),
        ``side`` (``"high"`` or ``"low"``) and the test mixture's ``fraction`` and ``tail_sd``
        (high, low).
    """
    u = np.asarray(u, float)
    u = u[np.isfinite(u)]
    out = {"lr": 0.0, "lr_asymmetry": 0.0, "threshold": float(threshold), "asymmetry_threshold": float(asymmetry),
           "engaged": False}
    if u.size < MIN_SAMPLES:
        out["skipped"] = f"{u.size} samples, fewer than {MIN_SAMPLES}"
        return out
    e = u - np.mean(u)
    lag1 = float(e[1:] @ e[:-1] / (e @ e)) if float(e @ e) > 0 else 0.0
    out["lag1"] = round(lag1, 3)
    if lag1 > STRUCTURED_LAG1:
        out["skipped"] = f"structured residuals (lag-1 {lag1:.2f} > {STRUCTURED_LAG1}): model error, not outliers"
        return out
    d = u - running_median(u, window)
    excess = _tail_excess(d)
    out["beyond_3sd"] = excess
    if excess is None:
        out["skipped"] = "no side holds more samples beyond 3 robust sd than Gaussian noise gives"
        return out
    skew = fit_contamination(d, "skewed")
    # the symmetric mixture only matters where there is a tail to compare it with
    sym = fit_contamination(d, "symmetric") if skew.lr > threshold else skew
    asym = max(2.0 * (skew.loglik - sym.loglik), 0.0)
    mass = np.asarray(skew.fraction) * np.asarray(skew.tail_sd)
    out.update(lr=round(skew.lr, 2), lr_asymmetry=round(asym, 2),
               engaged=bool(skew.lr > threshold and asym > asymmetry),
               side="high" if mass[0] >= mass[1] else "low",
               fraction=[round(v, 4) for v in skew.fraction], tail_sd=[round(v, 3) for v in skew.tail_sd])
    return out


def contamination_refit(prob, res, *, threshold=ONE_SIDED_LR, asymmetry=ASYMMETRY_LR):
    """The one-sided contamination model fitted with the trajectory where a channel's residuals
    engage it (:func:`one_sided_evidence`: the tail on the side it names), by EM: the mixture of
    each engaged channel's residuals (core centred on the curve) gives each sample its weight
    ``1 - p`` and the core sd, the
    trajectory is refitted with them (least squares from the previous estimate, same priors), until
    no weight moves by :data:`REFIT_WEIGHT_TOL` (at most :data:`REFIT_ITERATIONS` refits).

    Parameters
    ----------
    prob : OutputErrorProblem
        The white-noise problem ``res`` was fitted on.
    res : MLResult
    threshold, asymmetry : float
        :data:`ONE_SIDED_LR`, :data:`ASYMMETRY_LR`.

    Returns
    -------
    (OutputErrorProblem, MLResult, dict)
        The reweighted problem (its ``weights`` and ``sigma_fixed``: the posterior samples it) and
        fit, unchanged when no channel engages, and the record ``ml.noise.contamination``:
        ``model``, ``engaged``, per channel the evidence and, engaged, the fitted ``fraction``
        and ``tail_sd`` (high, low), ``down_weighted`` (the samples whose weight fell below
        :data:`DOWN_WEIGHTED`) and ``weight_lost`` (samples' worth of weight taken off); ``abandoned``
        says why a refit that took more than :data:`MAX_WEIGHT_LOST` of a channel was not kept.
    """
    chans = prob.channels
    u = {c: np.asarray(res.residuals[c], float) / prob.noise_scale[:, j] for j, c in enumerate(chans)}
    ev = {c: one_sided_evidence(u[c], threshold=threshold, asymmetry=asymmetry) for c in chans}
    engaged = [c for c in chans if ev[c]["engaged"]]
    rec = {"model": "one-sided contamination: a Gaussian core and an exponentially offset tail on one side",
           "engaged": bool(engaged), "channels": ev}
    if not engaged:
        return prob, res, rec
    prob0, res0 = prob, res
    w = np.array(prob.weights, float)
    held = dict(prob.sigma_fixed)     # the round's sd (or a sigma column's): the core's sd where given
    fixed = dict(held)
    mixes = {}
    it = 0
    for it in range(1, REFIT_ITERATIONS + 1):
        old = w.copy()
        for j, c in enumerate(chans):
            if c not in engaged:
                continue
            r = np.asarray(res.residuals[c], float) / prob.noise_scale[:, j]
            r = np.where(np.isfinite(r), r, 0.0)       # a sample without a residual: no evidence either way
            mixes[c] = fit_contamination(r, ev[c]["side"], sd=held.get(c), location=False)
            w[:, j] = mixes[c].weights
            fixed[c] = float(mixes[c].sd)
        if it > 1 and float(np.max(np.abs(w - old))) < REFIT_WEIGHT_TOL:
            break
        prob = prob.replace(weights=w, theta0=res.theta, sigma_fixed=fixed)
        new = prob.fit()
        if not np.all(np.isfinite(new.theta)):
            break
        res = new
    w = np.asarray(prob.weights, float)
    lost = {c: float(np.sum(1.0 - w[:, j])) / w.shape[0] for j, c in enumerate(chans) if c in mixes}
    if any(v > MAX_WEIGHT_LOST for v in lost.values()):
        rec.update(engaged=False, abandoned=(
            f"the contamination model took {100 * max(lost.values()):.0f} % of the samples' weight (more than "
            f"{100 * MAX_WEIGHT_LOST:.0f} %): a misfit, not outliers; the Gaussian fit is kept"))
        return prob0, res0, rec
    for j, c in enumerate(chans):
        if c in mixes:
            m = mixes[c]
            ev[c].update(fraction=[round(v, 4) for v in m.fraction], tail_sd=[round(v, 3) for v in m.tail_sd],
                         core_sd=float(f"{m.sd:.6g}"),
                         down_weighted=[int(i) for i in np.flatnonzero(w[:, j] < DOWN_WEIGHTED)],
                         weight_lost=round(float(np.sum(1.0 - w[:, j])), 2))
    rec["refits"] = it
    return prob, res, rec
