"""Convergence diagnostics of an MCMC chain, in numpy (the ranks' tie pass compiled): the integrated autocorrelation time
(:func:`integrated_time`, emcee's walker-averaged estimator), the rank-normalised split R-hat
(:func:`split_rank_rhat`), the bulk and tail effective sample size (:func:`ess`) and the
per-parameter convergence table (:func:`convergence_table`). They are ArviZ's ``rhat``, ``ess`` and ``mcse``
(Vehtari et al. 2021): the same numbers (tests compare them with ArviZ), without ArviZ, which
only :mod:`bayesdrag.estimate.bayes.inference` imports. :mod:`bayesdrag.estimate.bayes.sampler` stops its
chains by them.
"""
from __future__ import annotations


import numpy as np
from numba import njit
from scipy.fft import next_fast_len
from scipy.special import ndtri

from ..._runtime.renamed import renamed_getattr

__all__ = ["integrated_time", "average_ranks", "split_rank_rhat", "ess", "convergence_table"]


def integrated_time(chain, *, c=5):
    """Walker-averaged integrated autocorrelation time per coordinate: emcee's estimator
    (``emcee.autocorr.integrated_time(chain, c=5, tol=0)``: FFT autocorrelation per walker,
    averaged over walkers, Sokal's automatic window), computed for all walkers and coordinates in
    one FFT instead of one call per walker and coordinate (the sampler checks it every 25 steps).

    Parameters
    ----------
    chain : (n_steps, n_walkers, n_dim) array
    c : float, keyword-only
        Sokal's window factor.

    Returns
    -------
    (n_dim,) ndarray
        tau [steps].
    """
    x = np.asarray(chain, dtype=float)
    n = x.shape[0]
    n2 = 1 << int(np.ceil(np.log2(max(n, 1))))
    f = np.fft.rfft(x - x.mean(axis=0), n=2 * n2, axis=0)
    acf = np.fft.irfft(f * np.conjugate(f), n=2 * n2, axis=0)[:n]
    with np.errstate(invalid="ignore", divide="ignore"):
        acf = acf / acf[0]
    acf = np.nan_to_num(acf).mean(axis=1)                       # (n, n_dim)
    taus = 2.0 * np.cumsum(acf, axis=0) - 1.0
    m = np.arange(n)[:, None] < c * taus
    window = np.where(m.all(axis=0), n - 1, np.argmin(m, axis=0))
    return taus[window, np.arange(taus.shape[1])]


def _split(draws):
    """(chains, S, K) -> (2 chains, S // 2, K): first and last halves as separate chains."""
    h = draws.shape[1] // 2
    return np.concatenate([draws[:, :h], draws[:, draws.shape[1] - h:]], axis=0)


def average_ranks(a):
    """Ranks 1..n of each column of ``a`` (n, K), ties given their average rank: the numbers of
    ``scipy.stats.rankdata(a, axis=0, method="average")`` (a column holding NaN: all NaN).

    One sort of the transposed, contiguous columns (a sort down a strided axis cost 5x more;
    the draws of a chain hold many exact ties, one per rejected move), then one compiled pass
    over each sorted column (:func:`_tie_ranks`; six numpy passes over the (K, n) array cost
    three times the sort)."""
    a = np.asarray(a, float)
    rows = np.ascontiguousarray(a.T)                          # (K, n)
    ranks = _tie_ranks(rows, np.argsort(rows, axis=1))
    ranks[np.isnan(rows).any(axis=1)] = np.nan
    return ranks.T


@njit(cache=True)
def _tie_ranks(rows, order):
    """Ranks of each row of ``rows`` (K, n) from its ascending ``order``: a run of equal values
    at sorted positions ``i..j`` gets ``(i + j) / 2 + 1``."""
    K, n = rows.shape
    out = np.empty((K, n))
    for k in range(K):
        i = 0
        while i < n:
            v = rows[k, order[k, i]]
            j = i
            while j + 1 < n and rows[k, order[k, j + 1]] == v:
                j += 1
            r = 0.5 * (i + j) + 1.0
            for m in range(i, j + 1):
                out[k, order[k, m]] = r
            i = j + 1
    return out


def _z_scale(x):
    """Rank-normalised values (Blom's offset 3/8) per parameter of x (chains, draws, K)."""
    n = x.shape[0] * x.shape[1]
    r = average_ranks(x.reshape(n, -1)).reshape(x.shape)
    return ndtri((r - 0.375) / (n + 0.25))


def split_rank_rhat(draws):
    """Rank-normalised split R-hat (Vehtari et al. 2021), max of bulk and folded, per parameter.

    The same numbers as ``arviz.rhat`` (tests check the two agree), fast enough for the in-run
    convergence checks.

    Parameters
    ----------
    draws : (chains, draws, K) ndarray

    Returns
    -------
    (K,) ndarray
    """
    x = _split(np.asarray(draws, float))
    h = x.shape[1]

    def rhat(y):
        z = _z_scale(y)
        B = h * z.mean(axis=1).var(axis=0, ddof=1)
        Wv = z.var(axis=1, ddof=1).mean(axis=0)
        return np.sqrt(((h - 1) / h * Wv + B / h) / Wv)

    folded = np.abs(x - np.median(x.reshape(-1, x.shape[-1]), axis=0))
    return np.maximum(rhat(x), rhat(folded))


def _ess_chains(x):
    """ESS of each parameter of x (chains, draws, K), chains as given: ArviZ's ``_ess``
    (Geyer's initial positive then initial monotone sequence on the multi-chain
    autocorrelation)."""
    m, n, K = x.shape
    xc = x - x.mean(axis=1, keepdims=True)
    nfft = next_fast_len(2 * n, real=True)
    f = np.fft.rfft(xc, n=nfft, axis=1)
    acov = np.fft.irfft(f * np.conjugate(f), n=nfft, axis=1)[:, :n] / n    # (m, n, K)
    mean_var = acov[:, 0].mean(axis=0) * n / (n - 1.0)
    var_plus = mean_var * (n - 1.0) / n
    if m > 1:
        var_plus = var_plus + x.mean(axis=1).var(axis=0, ddof=1)
    out = np.empty(K)
    for k in range(K):
        if np.ptp(x[..., k]) < np.finfo(float).resolution:
            out[k] = m * n
            continue
        with np.errstate(invalid="ignore", divide="ignore"):
            rho = 1.0 - (mean_var[k] - acov[..., k].mean(axis=0)) / var_plus[k]
        out[k] = _geyer_ess(rho, m * n)
    return out


def _geyer_ess(rho, size):
    """ESS from the autocorrelations ``rho`` (n,) of ``size`` draws (ArviZ's ``_ess``)."""
    n = rho.size
    rt = np.zeros(n)
    rt[0] = even = 1.0
    rt[1] = odd = rho[1]
    t = 1
    while t < n - 3 and even + odd > 0.0:                      # initial positive sequence
        even, odd = rho[t + 1], rho[t + 2]
        if even + odd >= 0:
            rt[t + 1], rt[t + 2] = even, odd
        t += 2
    max_t = t - 2
    if even > 0:
        rt[max_t + 1] = even
    t = 1
    while t <= max_t - 2:                                      # initial monotone sequence
        if rt[t + 1] + rt[t + 2] > rt[t - 1] + rt[t]:
            rt[t + 1] = rt[t + 2] = (rt[t - 1] + rt[t]) / 2.0
        t += 2
    tau = -1.0 + 2.0 * np.sum(rt[:max_t + 1]) + np.sum(rt[max_t + 1:max_t + 2])
    tau = max(tau, 1 / np.log10(size))
    return np.nan if np.isnan(rt).any() else size / tau


def ess(draws, *, method="bulk"):
    """Effective sample size per parameter, as ``arviz.ess(..., method=method)``.

    Parameters
    ----------
    draws : (chains, draws, K) ndarray
    method : {"bulk", "tail", "mean"}, keyword-only
        ``bulk``: of the rank-normalised split chains; ``tail``: the smaller of the ESS of the
        indicators of the 5 % and 95 % quantiles; ``mean``: of the split chains as they are.

    Returns
    -------
    (K,) ndarray
        ESS [draws]; NaN for parameters with non-finite draws or fewer than 4 draws per chain.
    """
    x = np.asarray(draws, float)
    K = x.shape[-1]
    if x.shape[1] < 4:
        return np.full(K, np.nan)
    if method == "bulk":
        out = _ess_chains(_z_scale(_split(x)))
    elif method == "mean":
        out = _ess_chains(_split(x))
    elif method == "tail":
        q = np.quantile(x.reshape(-1, K), [0.05, 0.95], axis=0)
        out = np.minimum(_ess_chains(_split((x <= q[0]).astype(float))),
                         _ess_chains(_split((x <= q[1]).astype(float))))
    else:
        raise ValueError(f"method {method!r} not known (allowed: bulk, tail, mean)")
    out[~np.all(np.isfinite(x), axis=(0, 1))] = np.nan
    return out


def convergence_table(draws, names):
    """Convergence summary of draws: the columns of ``arviz.summary`` that bayesdrag reports.

    Parameters
    ----------
    draws : (chains, draws, K) ndarray
    names : sequence of str
        K parameter names (the index).

    Returns
    -------
    pandas.DataFrame
        Columns mean, sd, q05, q50, q95, mcse_mean (sd / sqrt(ESS of the mean)), ess_bulk,
        ess_tail, r_hat (rank-normalised split R-hat).
    """
    import pandas as pd

    x = np.asarray(draws, float)
    flat = x.reshape(-1, x.shape[-1])
    q = np.quantile(flat, [0.05, 0.5, 0.95], axis=0)
    sd = flat.std(0, ddof=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mcse = sd / np.sqrt(ess(x, method="mean"))
        rhat = split_rank_rhat(x) if x.shape[1] >= 4 else np.full(x.shape[-1], np.nan)
    return pd.DataFrame({"mean": flat.mean(0), "sd": sd, "q05": q[0], "q50": q[1], "q95": q[2],
                         "mcse_mean": mcse, "ess_bulk": ess(x, method="bulk"), "ess_tail": ess(x, method="tail"),
                         "r_hat": rhat}, index=list(names))


# --------------------------------------------------------------------------- the run

#: old names, kept with a warning until release 0.3
__getattr__ = renamed_getattr(__name__, {"summarize": "convergence_table"}, globals())
