"""Effect signatures and confounding (step 5 of :mod:`bayesdrag.diagnosis`).

An effect's signature is its output sensitivity at the baseline with the nuisance parameters
(initial state with its launch priors, and without a reference drag the fitted Cd) projected out
(:func:`signatures`). An effect whose signature is (almost) wholly absorbed is not identifiable.
Two effects are ``confounded_with`` each other when their signatures span nearly the same
direction (canonical correlation >= ``CONFOUND_CORR``: density vs drag_scale is exactly 1) and
the part they do not share is too small to detect, or when both are significant and the data
prefer one over the other by less than the 95 % point of chi2(1) in colored units
(:func:`mark_confounded`).
"""
from __future__ import annotations

import numpy as np

from .setup import effect_problem, k_free
from .statistics import chi2_quantile
from ..effects import LIFT, RADAR_POSITION, WIND_PROFILE, YAW_DRAG

__all__ = ["signatures", "nuisance_basis", "canonical_corr", "mark_confounded", "seen_axes"]

#: canonical correlation of two effects' signatures above which the data cannot separate them
CONFOUND_CORR = 0.995
#: projected-signature norm fraction below which an effect is unidentifiable (absorbed by the
#: initial state and, without reference drag, the fitted Cd)
IDENTIFIABLE_FRACTION = 0.02


def nuisance_basis(setup, base_theta):
    """The noise weights, the baseline's outputs and an orthonormal basis of what the nuisance
    parameters (the initial state with its launch priors and, without a reference drag, the
    fitted Cd) can do at ``base_theta``: ``(sw (N, C), y0 (N, C), Qn, n_pr)``, ``n_pr`` the
    prior rows appended. Made once per baseline and kept on the setup (``setup.basis``): the
    signature of the wind profile is asked again once the evidence has chosen its layers."""
    key = np.asarray(base_theta, float).tobytes()
    if setup.basis is not None and setup.basis[0] == key:
        return setup.basis[1]
    sw = np.sqrt(setup.weights / np.array([setup.sigma[c] for c in setup.channels])[None, :] ** 2)
    prob0 = effect_problem(setup, [], base_theta)
    y0, _, S0 = prob0.sensitivities(base_theta)
    A = (S0 * sw[:, :, None]).reshape(-1, S0.shape[-1])
    # the launch priors are pseudo-measurements: appending their Jacobian makes the projection
    # below the Schur complement (information left for the effect after the nuisance)
    _, pJ = prob0.prior_terms(base_theta)
    n_pr = pJ.shape[0]
    A = np.vstack([A, pJ]) if n_pr else A
    Qn, _ = np.linalg.qr(A)
    setup.basis = (key, (sw, y0, Qn, n_pr))
    return setup.basis[1]


def signatures(setup, base_theta, effects):
    """Effect signatures at the baseline with the nuisance parameters projected out
    (:func:`nuisance_basis`).

    Returns
    -------
    dict name -> (Q (n, r) orthonormal basis of the projected signature or None, fraction of the
    signature norm left after projection)
    """
    sw, y0, Qn, n_pr = nuisance_basis(setup, base_theta)
    out = {}
    for e in effects:
        if e.k == 0:
            prob = effect_problem(setup, [e], base_theta)
            y1, _ = prob.predict(base_theta[None])
            cols = ((y1[0] - y0) * sw).reshape(-1, 1)
        else:
            prob = effect_problem(setup, [e], base_theta)
            th = prob.theta0.copy()
            if e.name == YAW_DRAG.name:
                th[-2] = 0.05  # the decay column is flat at zero amplitude: evaluate at a small one
            if e.name == LIFT.name:
                # the vertical part of the lift is even in the factor (flat at 0): the signature
                # of a typical right-hand-spin shell's lift, at factor 1
                th[-1] = 1.0
            _, _, S = prob.sensitivities(th)
            kf = k_free(setup, e)
            cols = (S[:, :, -kf:] * sw[:, :, None]).reshape(-1, kf)
        cols = np.vstack([cols, np.zeros((n_pr, cols.shape[1]))]) if n_pr else cols
        norms = np.linalg.norm(cols, axis=0)
        keep = norms > 0
        if not keep.any():
            out[e.name] = (None, 0.0)
            continue
        cols = cols[:, keep] / norms[keep]
        proj = cols - Qn @ (Qn.T @ cols)
        frac = float(np.max(np.linalg.norm(proj, axis=0)))
        pn = np.linalg.norm(proj, axis=0)
        if frac < 1e-12:
            out[e.name] = (None, frac)
            continue
        Q, _ = np.linalg.qr(proj[:, pn > 1e-12 * pn.max()])
        out[e.name] = (Q, frac)
    return out


def seen_axes(setup, base_theta):
    """The coordinates of ``radar_position`` (``x``, ``y``, ``z``) whose signature the nuisance
    parameters leave at least :data:`IDENTIFIABLE_FRACTION` of, each alone: a shift of the site
    along them is more than a shift of the flight (its start against the launch priors, the
    lines of sight as the flight goes on). A range rate from a site on the line of fire, for
    one, has no first-order view of a sideways shift."""
    from dataclasses import replace

    from ..effects import EFFECTS, unabsorbed_fraction

    full = replace(setup, ctx=replace(setup.ctx, radar_axes=("x", "y", "z")))
    sw = np.sqrt(setup.weights / np.array([setup.sigma[c] for c in setup.channels])[None, :] ** 2)
    prob = effect_problem(full, [EFFECTS[RADAR_POSITION.name]], base_theta)
    _, _, S = prob.sensitivities(prob.theta0)
    A = (S * sw[:, :, None]).reshape(-1, S.shape[-1])
    _, pJ = prob.prior_terms(prob.theta0)
    if pJ.shape[0]:    # the launch priors as pseudo-measurements (as in signatures)
        A = np.vstack([A, pJ])
    frac = unabsorbed_fraction(A[:, :-3], A[:, -3:])
    return tuple(a for a, f in zip("xyz", frac) if f >= IDENTIFIABLE_FRACTION)


def canonical_corr(Qa, Qb):
    """Largest canonical correlation between two orthonormal bases (1 = same direction)."""
    if Qa is None or Qb is None:
        return 0.0
    return float(np.linalg.svd(Qa.T @ Qb, compute_uv=False).max())


def mark_confounded(rows, sigs, alpha, K):
    """Fill in each candidate row's ``confounded_with`` and ``signature_corr``.

    Parameters
    ----------
    rows : list of dict
        Candidate rows (:func:`bayesdrag.diagnosis.candidates.candidate_row`), best first; changed
        in place.
    sigs : dict
        :func:`signatures` of the candidates.
    alpha : float
        Family-wise false-alarm rate.
    K : int
        Number of candidates tested (Bonferroni).
    """
    for a in rows:
        a["confounded_with"] = []
    for i, a in enumerate(rows):
        for b in rows[i + 1:]:
            cc = canonical_corr(sigs[a["name"]][0], sigs[b["name"]][0])
            a.setdefault("_corr", {})[b["name"]] = cc
            if WIND_PROFILE.name in (a["name"], b["name"]):
                # nested wind models: the evidence chooses between them; against the others, the
                # profile's layers span much of any drag-like signature alone, so whether the data
                # separate them is asked of their joint fit (diagnosis.winds.cannot_separate)
                continue
            close = (a["significant"] and b["significant"]
                     and abs(a["delta_chi2"] - b["delta_chi2"]) / max(a["inflation"], b["inflation"])
                     < chi2_quantile(0.95, 1))
            # near-collinear signatures confound two effects only if the part one does not share
            # with the other is too small to detect at the size the data give it: (1 - cc^2) of
            # the smaller chi2 drop, in colored units (a wind and Coriolis share 99.7 % of their
            # signature, yet with a large gap the rest is plain; density/drag_scale share all)
            unshared = (1.0 - cc * cc) * max(min(a["delta_chi2"], b["delta_chi2"]), 0.0) / max(
                a["inflation"], b["inflation"])
            if (cc >= CONFOUND_CORR and unshared < chi2_quantile(1 - alpha / K, 1)) or close:
                a["confounded_with"].append(b["name"])
                b["confounded_with"].append(a["name"])
    for r in rows:
        corr = r.pop("_corr", {})
        r["signature_corr"] = {k: round(v, 4) for k, v in corr.items()}
