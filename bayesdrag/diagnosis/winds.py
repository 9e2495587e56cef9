"""Which wind: none, a constant wind, or a wind that changes along the flight by height or by
downrange distance, chosen by evidence (part of steps 4 and 6 of :mod:`bayesdrag.diagnosis`).

The ``wind_profile`` effect (:class:`bayesdrag.effects.wind_layers.WindLayers`) needs its layers: here
they are :data:`PROFILE_LAYERS` equal layers over the flown range of the coordinate, by height
from the gun to the apex (met practice) or by downrange distance from the gun to the last sample
(how small-arms tools zone winds). Both are fitted; the wind models are then compared by their
Laplace evidence with proper priors (:func:`log_evidence`), a constant wind being the one-layer
profile: the layer winds' mean has sd :data:`WIND_LEVEL_SD` (or the round's ``[atmosphere]
wind_sd``), neighbouring layers differ with sd :data:`WIND_STEP_SD` (the random walk the fit
carries as a prior), and the data's information is counted in colored units (divided by the
colored inflation of the fitted change, as every test of the diagnosis is). The chi2 drop pays
for the extra layers through the Occam factor ``det(prior precision) / det(posterior precision)``
-- a BIC whose penalty per parameter is what the prior says a layer may do, not ln n.

The model the evidence prefers stands for the wind in the selection; the others are kept out of it
(``superseded_by``). When other effects enter the verdict beside a wind, the wind model is chosen
again in their company (:func:`rechoose_wind`): an along-range wind and a warm day, or a wind that
changes and a table's shape, trade against each other, and what a wind explains alone is not what
it explains beside them.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..effects import EFFECTS, LIFT, WIND, WIND_PROFILE, drag_along_the_flight, drag_level_effects, wind_effects
from ..errors import FitError
from ..estimate.build.winds import at_fit_resolution, layers_over, wind_layer_priors
from ..effects.wind_layers import PROFILE_LAYERS, WIND_LAYERS_MAX, WIND_LEVEL_SD, WIND_STEP_SD
from ..estimate.model.layout import ParameterLayout

__all__ = ["PROFILE_LAYERS", "WIND_FAMILY", "layers_for", "rw_priors", "rw_information", "log_evidence",
           "wind_prior_precision", "occam", "data_cost", "fit_wind_profile", "rechoose_wind", "cannot_separate", "separable",
           "SEPARATE_SD", "TRADE_PARTNERS", "SHAPE_RIVAL_SHARE", "shape_rival_share", "finer_layers",
           "refined_start"]

#: the wind models, simplest first: the evidence chooses one of them to stand for the wind
WIND_FAMILY = wind_effects()
#: effects whose signature trades against a wind that changes along the flight (an along-range
#: wind changes the drag along the flight as warmer or thinner air does)
TRADE_PARTNERS = drag_along_the_flight()
#: two effects fitted together are separated when each one's size alone is at least this many of
#: its sd in their joint fit (the joint fit can tell "all of the signature is this effect" from
#: "none of it is"); otherwise the verdict reports the pair as one the data cannot separate
SEPARATE_SD = 3.0
#: the table's shape in place of a wind profile: when it removes at least this share of what the
#: profile removes (beside the other verdict members), the data cannot separate a wind that
#: changes along the flight from a drag that changes with Mach, and the profile is not named. A
#: 6-DOF shell's drag from its yaw of repose near the apex, which the point mass lacks: 0.84; the
#: winds that change along the flight of the suite's tuning cases: 0-0.55
SHAPE_RIVAL_SHARE = 0.75


def layers_for(setup, y_base, axis, n=PROFILE_LAYERS):
    """The wind_profile layers of this track: ``n`` equal layers over the flown range of the
    coordinate (height from the gun to the apex, or downrange distance from the gun to the last
    sample), read off the baseline's fitted outputs, with the round's own wind as the base
    (:func:`bayesdrag.estimate.build.winds.layers_over`, the fit's construction).

    Parameters
    ----------
    setup : Setup
    y_base : (N, C) array
        The baseline's fitted outputs.
    axis : {"altitude", "downrange"}
    n : int

    Returns
    -------
    WindLayers or None when the coordinate has no span (no x or z channel and no model path).
    """
    x, z = _path(setup, y_base)
    return layers_over(axis, x, z, setup.rnd.atmosphere, n)


def finer_layers(layers):
    """The layers of a wind profile at the fit's resolution (``fit --with wind_profile``:
    :func:`bayesdrag.estimate.build.winds.at_fit_resolution`); None when ``layers`` is None or
    already that fine."""
    return at_fit_resolution(layers)


def refined_start(setup, names, res, coarse, fine):
    """Starting parameters of effects ``names`` with ``wind_profile`` on ``fine`` layers, from a
    fit ``res`` with it on ``coarse`` ones: each fine layer starts at the wind of the coarse layer
    holding its middle, every other parameter at its value in ``res``."""
    vals = dict(zip(res.names, res.theta))
    mid = 0.5 * (np.asarray(fine.edges[:-1]) + np.asarray(fine.edges[1:]))
    home = np.clip(np.searchsorted(np.asarray(coarse.edges), mid, side="right"), 1, coarse.n)
    out = [res.theta[:ParameterLayout(setup.P).size]]
    for n in names:
        e = EFFECTS[n]
        row = []
        for p in e.params:
            key = f"{n}.{p.name}"
            if n == WIND_PROFILE.name:
                c, k = p.name.rsplit("_", 1)
                k = int(k)
                key = f"{n}.{c}_{int(home[k - 1])}" if k <= fine.n else None
            row.append(vals.get(key, p.start) if key is not None else p.start)
        out.append(np.asarray(row, float))
    return np.concatenate(out)


def _path(setup, y_base):
    """Downrange x and height z [m] of the baseline's fitted path at the track's samples (None
    for a channel the track does not have)."""
    ch = setup.channels
    x = y_base[:, ch.index("x")] if "x" in ch else None
    z = y_base[:, ch.index("z")] if "z" in ch else None
    if setup.path is not None:   # a radar's own channels: the baseline's path in the gun's frame
        x = setup.path[:, 0] if x is None else x
        z = setup.path[:, 2] if z is None else z
    return x, z


def rw_priors(names_all, free):
    """The random-walk priors of ``wind_profile``'s used layers: each neighbouring pair's
    difference ~ N(0, WIND_STEP_SD^2), per component (linear rows of the full parameter vector;
    the fit's :func:`bayesdrag.estimate.build.winds.wind_layer_priors` without a level).

    Parameters
    ----------
    names_all : sequence of str
        The problem's parameter names (drag, state, extras: ``wind_profile.wx_1``, ...).
    free : (n,) bool
        Which parameters are estimated (a held layer gets no prior).

    Returns
    -------
    tuple of Prior
    """
    return wind_layer_priors(names_all, free)


def rw_information(names, free):
    """Information (n, n) of the random-walk priors over a fit's parameters (zeros elsewhere):
    what the effective number of parameters (:func:`bayesdrag.diagnosis.setup.edf`) discounts."""
    names = list(names)
    Lam = np.zeros((len(names), len(names)))
    for p in rw_priors(names, free):
        r = np.asarray(p.row, float) / p.sd
        Lam += np.outer(r, r)
    return Lam


def wind_prior_precision(k, level_sd):
    """Prior precision (2k, 2k) of a wind of ``k`` layers in parameter order (wx_1, wy_1, wx_2,
    ...): the layers' mean has sd ``level_sd`` per component and neighbours differ with sd
    :data:`WIND_STEP_SD`. A constant wind is k = 1."""
    P1 = np.outer(np.ones(k), np.ones(k)) / (k * k * level_sd ** 2)
    if k > 1:
        D = np.diff(np.eye(k), axis=0)
        P1 = P1 + D.T @ D / WIND_STEP_SD ** 2
    out = np.zeros((2 * k, 2 * k))
    out[0::2, 0::2] = P1
    out[1::2, 1::2] = P1
    return out


def _wind_block(setup, name, res):
    """(indices, values, prior precision) of a wind model's free parameters in a fit."""
    names = list(res.names)
    if name == WIND.name:
        keys = [f"wind.{c}" for c in ("wx", "wy")]
        k = 1
    else:
        n = setup.ctx.wind_layers.n if setup.ctx.wind_layers is not None else WIND_LAYERS_MAX
        keys = [f"wind_profile.{c}_{j}" for j in range(1, n + 1) for c in ("wx", "wy")]
        k = n
    level_sd = setup.rnd.systematics.wind_profile or WIND_LEVEL_SD
    Lam = wind_prior_precision(k, level_sd)
    lay = setup.ctx.wind_layers
    if name == WIND_PROFILE.name and lay is not None and lay.constant_cross:
        # one cross wind for all layers: its prior is a constant wind's (wy_2.. are no parameters)
        Lam[1::2, 1::2] = 0.0
        Lam[1, 1] = 1.0 / level_sd ** 2
    idx = [names.index(n) for n in keys]
    free = [i for i, j in enumerate(idx) if res.free[j]]
    idx = [idx[i] for i in free]
    return np.array(idx), res.theta[idx], Lam[np.ix_(free, free)]


def occam(setup, name, res, infl):
    """The Occam factor of a wind model's fit, in log: ``- p' L p / 2 + ln det L / 2 -
    ln det(I / g + L) / 2`` with ``p`` the wind's parameters, ``L`` their prior precision
    (:func:`wind_prior_precision`), ``I`` the data's information on them with the nuisance
    parameters marginalised (the inverse of their block of the fit's covariance, less the
    random-walk prior's share) and ``g`` the colored inflation of the wind's signature (the
    information in colored units). ``-inf`` when it cannot be formed."""
    idx, p, L = _wind_block(setup, name, res)
    if idx.size == 0:
        return 0.0
    rw = rw_information(res.names, res.free)[np.ix_(idx, idx)]
    g = max(float(infl), 1e-9)
    cov = res.cov[np.ix_(idx, idx)]
    with np.errstate(all="ignore"):
        try:
            info = np.linalg.inv(cov) - rw
        except np.linalg.LinAlgError:
            return -math.inf
    if not np.all(np.isfinite(info)):
        return -math.inf
    w, V = np.linalg.eigh(0.5 * (info + info.T))
    info = (V * np.clip(w, 0.0, None)) @ V.T
    sign_l, logdet_l = np.linalg.slogdet(L)
    sign_p, logdet_p = np.linalg.slogdet(info / g + L)
    if sign_l <= 0 or sign_p <= 0:
        return -math.inf
    return -0.5 * float(p @ L @ p) + 0.5 * logdet_l - 0.5 * logdet_p


def data_cost(res):
    """A fit's cost less the random-walk prior's terms (those belong to the Occam factor)."""
    return float(res.cost) - _rw_cost(res)


def log_evidence(setup, name, res, ref_res, infl_pair, infl_info, ref_log_z=0.0, ref_occam=0.0):
    """Log evidence of a wind model (Laplace, colored units), chained from a reference fit.

    ``ln Z = ln Z_ref + (c_ref - c) / (2 g) + occam - occam_ref`` with ``c`` the data's chi2 (the
    fit's cost less its random-walk terms), ``g`` the colored inflation of the output change
    *between the two fits*: the wind models are compared with each other through their
    difference (chained through the constant wind), never each through its whole drop from the
    baseline, where a 3 % difference of two inflations outweighed a chi2 difference of 8.

    Parameters
    ----------
    setup : Setup
    name : {"wind", "wind_profile"}
    res : MLResult
        The fit with the wind model.
    ref_res : MLResult
        The reference fit (the baseline, or the constant wind's fit).
    infl_pair : float
        Colored inflation of the output change from ``ref_res`` to ``res``.
    infl_info : float
        Colored inflation of the wind's signature (from the fit without any wind), for the
        Occam factor (:func:`occam`).
    ref_log_z, ref_occam : float
        The reference's log evidence and Occam factor (0 for the baseline).

    Returns
    -------
    float
    """
    d = data_cost(ref_res) - data_cost(res)
    o = occam(setup, name, res, infl_info)
    if not np.isfinite(d) or not np.isfinite(o):
        return -math.inf
    return ref_log_z + 0.5 * d / max(float(infl_pair), 1e-9) + o - ref_occam


def _rw_cost(res):
    """The random-walk prior's share of a fit's cost."""
    th = res.theta
    total = 0.0
    for p in rw_priors(list(res.names), res.free):
        total += float((p.fn(th) / p.sd) ** 2)
    return total


def fit_wind_profile(setup, y_base, base_theta, fit):
    """Fit ``wind_profile`` with the layers by height and by downrange distance; return the
    variants ``[(layers, (res, prob, y)), ...]`` whose fit succeeded (``fit(setup)`` fits it)."""
    out = []
    for axis in ("altitude", "downrange"):
        lay = layers_for(setup, y_base, axis)
        if lay is None:
            continue
        saved = setup.ctx
        setup.ctx = replace(saved, wind_layers=lay)
        try:
            f = fit(setup)
        except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
            f = None
        finally:
            setup.ctx = saved
        if f is not None and np.all(np.isfinite(f[2])):
            out.append((lay, f))
    return out


def _size_over_sd(res_joint, res_alone, effect):
    """How many of its joint-fit sd an effect's size is: ``sqrt(p' S^-1 p)`` with ``p`` its free
    parameters (less their no-effect values) fitted in ``res_alone`` (its size alone; pass the
    joint fit for its size there) and ``S`` their block of the joint fit's colored covariance."""
    names = list(res_joint.names)
    e = EFFECTS[effect]
    idx, p = [], []
    alone = dict(zip(res_alone.names, res_alone.theta))
    for q in e.params:
        key = f"{effect}.{q.name}"
        if key in names and res_joint.free[names.index(key)] and key in alone:
            idx.append(names.index(key))
            p.append(alone[key] - q.start)
    if not idx:
        return math.inf
    cov = res_joint.cov_colored if np.all(np.isfinite(res_joint.cov_colored)) else res_joint.cov
    S = cov[np.ix_(idx, idx)]
    p = np.array(p)
    try:
        return float(np.sqrt(max(p @ np.linalg.solve(S, p), 0.0)))
    except np.linalg.LinAlgError:
        return 0.0


def separable(res_joint, fits, a, b):
    """Do the data separate effects ``a`` and ``b`` in their joint fit? Not when one of them can be
    neither confirmed nor excluded there: its size in the joint fit is below :data:`SEPARATE_SD`
    of its sd (not confirmed) while the size it took alone, where it stood in for the whole
    signature, is below that too (not excluded) -- the joint fit cannot tell "this effect" from
    "the other" (:func:`_size_over_sd`)."""
    for n in (a, b):
        if (_size_over_sd(res_joint, res_joint, n) < SEPARATE_SD
                and _size_over_sd(res_joint, fits[n][0], n) < SEPARATE_SD):
            return False
    return True


def cannot_separate(setup, verdict, fit, fits, rows, fit_fn):
    """The pairs the data cannot separate: two verdict members in the verdict's joint fit, and a
    wind of the verdict against each significant trade partner outside it (:data:`TRADE_PARTNERS`,
    one of the twins density/drag_scale), fitted together for the purpose.

    Parameters
    ----------
    setup : Setup
    verdict : list of str
    fit : (res, prob, y) or None
        The verdict's joint fit (None for a single effect: its own fit).
    fits : dict name -> fit alone
    rows : dict name -> candidate row
    fit_fn : callable ``fit_fn(names, start_fit) -> (res, prob, y)``

    Returns
    -------
    list of dict ``{"effects": [a, b], "size_over_sd": {a: float, b: float}, "fitted_together": bool}``
    """
    out = []
    if not verdict:
        return out
    fit = fit if fit is not None else fits.get(verdict[0])
    if fit is None:
        return out
    for i, a in enumerate(verdict):
        for b in verdict[i + 1:]:
            if a in fits and b in fits and not separable(fit[0], fits, a, b):
                out.append(_pair(fit[0], fits, a, b, True))
    winds = [n for n in verdict if n in WIND_FAMILY and n in fits]
    partners = [n for n in TRADE_PARTNERS if n in fits and n not in verdict and rows.get(n, {}).get("significant")]
    twins = drag_level_effects()
    if all(n in partners for n in twins):
        partners = [n for n in partners if n not in twins[1:]]         # twins: one stands for both
    for w in winds:
        for q in partners:
            try:
                jf = fit_fn(list(verdict) + [q], fit)
            except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
                continue
            if np.all(np.isfinite(jf[2])) and not separable(jf[0], fits, w, q):
                out.append(_pair(jf[0], fits, w, q, False))
    return out


def _pair(res, fits, a, b, together):
    return {"effects": [a, b],
            "size_over_sd": {n: round(_size_over_sd(res, res, n), 3) for n in (a, b)},
            "size_alone_over_sd": {n: round(_size_over_sd(res, fits[n][0], n), 3) for n in (a, b)},
            "in_verdict": together}


def rechoose_wind(setup, verdict, fit, alternatives, fit_fn, infl_fn, admit_fn=None):
    """The wind model of a verdict chosen again beside its other members, by evidence chained
    through the constant wind fitted with them (:func:`log_evidence`).

    Parameters
    ----------
    setup : Setup
    verdict : list of str
        The selected effects, one wind model among them.
    fit : (res, prob, y)
        Their joint fit.
    alternatives : list of (str, WindLayers or None)
        The wind models to try (name, and the layers for ``wind_profile``).
    fit_fn : callable ``fit_fn(names, start_fit) -> (res, prob, y)``
        Fits the baseline plus effects ``names`` (with ``setup.ctx`` as set).
    infl_fn : callable ``infl_fn(fit_a, fit_b) -> float``
        Colored inflation of the output change from ``fit_a`` to ``fit_b``.
    admit_fn : callable ``admit_fn(name, fit_without, fit_with) -> bool``, optional
        The selection's admission test (:func:`bayesdrag.diagnosis.selection.admits`): whether a
        wind is there at all is the selection's question (the evidence is more liberal with
        model error than its colored test and practical-size rules); the evidence chooses only
        among the wind models it admits.

    Returns
    -------
    (list of str, fit, WindLayers or None, list of dict)
        The verdict with the best wind model (without a wind when none has a positive log
        evidence beside the others: the wind then stood in for what they explain), its joint
        fit, the layers it uses and the evidence of each model tried (``[{"model", "axis",
        "log_evidence"}]``, relative to the other members without a wind; model None: no wind).
    """
    wind = next(n for n in verdict if n in WIND_FAMILY)
    others = [n for n in verdict if n != wind]
    if LIFT.name in others:  # beside the spin drift only the along-range wind may change
        alternatives = [(n, lay if lay is None else replace(lay, constant_cross=True)) for n, lay in alternatives]
    saved = setup.ctx
    current = (wind, saved.wind_layers if wind == WIND_PROFILE.name else None)
    fitted = {}
    try:
        ref = fit_fn(others, fit)
        for name, lay in [("wind", None)] + list(alternatives):
            key = (name, lay)
            if key in fitted:
                continue
            if name == current[0] and (name == WIND.name or lay == current[1]):
                fitted[key] = fit
                continue
            setup.ctx = replace(saved, wind_layers=lay if lay is not None else saved.wind_layers)
            try:
                f = fit_fn(others + [name], ref)
                if np.all(np.isfinite(f[2])):
                    fitted[key] = f
            except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
                pass
            finally:
                setup.ctx = saved
    except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
        setup.ctx = saved
        return verdict, fit, saved.wind_layers, []
    chain = fitted.get(("wind", None))
    # no wind at all: the others alone (the reference of every evidence here, ln Z = 0)
    tried, best = [{"model": None, "axis": None, "log_evidence": 0.0, "admitted": True}], (0.0, None, ref, None)
    for (name, lay), f in fitted.items():
        setup.ctx = replace(saved, wind_layers=lay if lay is not None else saved.wind_layers)
        g_info = infl_fn(ref, f)
        if chain is None or name == WIND.name:
            ev = log_evidence(setup, name, f[0], ref[0], g_info, g_info)
        else:
            g_w = infl_fn(ref, chain)
            z_w = log_evidence(setup, "wind", chain[0], ref[0], g_w, g_w)
            ev = log_evidence(setup, name, f[0], chain[0], infl_fn(chain, f), g_info, z_w,
                              occam(setup, "wind", chain[0], g_w))
        setup.ctx = saved
        setup.ctx = replace(saved, wind_layers=lay if lay is not None else saved.wind_layers)
        admitted = admit_fn is None or admit_fn(name, ref, f)
        setup.ctx = saved
        tried.append({"model": name, "axis": _axis(name, lay), "log_evidence": ev, "admitted": bool(admitted)})
        if admitted and ev > best[0]:
            best = (ev, name, f, lay if lay is not None else saved.wind_layers)
    _, name, f, lay = best
    if name is None:
        return others, f, saved.wind_layers, tried
    order = [name if n == wind else n for n in verdict]
    return order, f, lay, tried


def _axis(name, layers):
    return None if name == WIND.name or layers is None else layers.axis



def shape_rival_share(c_ref, c_profile, c_rival):
    """The share of what a wind profile removes (data cost from ``c_ref`` down to ``c_profile``)
    that a rival in its place removes (down to ``c_rival``); 0 when the profile removes nothing."""
    gain = c_ref - c_profile
    return float(np.clip((c_ref - c_rival) / gain, 0.0, np.inf)) if gain > 0 else 0.0
