"""What ignoring an effect would do, and whether that matters (steps 8 and 9 of
:mod:`bayesdrag.diagnosis`).

:func:`effect_change` is the output change an effect causes in a fit; :func:`end_shift` how far
it moves the track's end in noise sd; :func:`cd_shift` the Cd change a Scheme 1 fit that ignored
it would absorb (linearised). An effect is material (:func:`materiality`) when
ignoring it would shift a fitted Cd by more than ``MATERIAL_CD_SHIFT`` (0.1 %) anywhere in the
flown Mach range or move the track's last sample by more than ``MATERIAL_END_SD`` (3) noise sd.
:func:`judge_impacts` fills both figures and the judgement into the candidate rows.
"""
from __future__ import annotations

import math

import numpy as np

from ..effects import EFFECTS
from ..errors import FitError
from ..estimate.model.problem import OutputErrorProblem
from ..estimate.model.layout import ParameterLayout
from .setup import effect_problem, launch_priors

__all__ = ["effect_change", "end_shift", "cd_shift", "materiality", "judge_impacts",
           "MATERIAL_CD_SHIFT", "MATERIAL_END_SD"]

#: the Cd shift is computed for the verdict and this many best-ranked candidates
CD_SHIFT_TOP = 2
#: materiality: an effect is material when ignoring it would shift a fitted Cd by
#: more than this (relative, 0.001 = 0.1 %) anywhere in the flown Mach range ...
MATERIAL_CD_SHIFT = 0.001
#: ... or move the track at its last sample by more than this many noise sd (any channel)
MATERIAL_END_SD = 3.0


def effect_change(setup, fit, name):
    """The output change effect ``name`` causes in a fit: the fit's outputs minus those of the
    same model and parameters with that effect switched off (the others kept).

    Parameters
    ----------
    setup : Setup
    fit : (MLResult, OutputErrorProblem, (N, C) outputs)
        A fit with ``name`` among its effects (a single-effect fit or a verdict's joint fit).
    name : str

    Returns
    -------
    dy : (N, C) array, model units
    mach : (N,) Mach along the trajectory without the effect
    """
    res, prob, y = fit
    effs = [EFFECTS[n] for n in prob.effect_names]
    k0 = ParameterLayout(setup.P).size
    keep, j = [res.theta[:k0]], k0
    for e in effs:
        if e.k and e.name != name:
            keep.append(res.theta[j:j + e.k])
        j += e.k
    th = np.concatenate(keep)
    others = [e for e in effs if e.name != name]
    y_o, mach_o = effect_problem(setup, others, th).predict(th[None])
    return y - y_o[0], mach_o[0]


def end_shift(setup, dy):
    """How far an output change moves the track at its end, in noise sd.

    Parameters
    ----------
    setup : Setup
    dy : (N, C) array
        Output change (model units) from :func:`effect_change`.

    Returns
    -------
    dict with ``per_channel`` (channel -> |dy| / sigma at the channel's last weighted sample) and
    ``max_sd``: the length of that end displacement in noise units, ``sqrt(sum_c (dy_c /
    sigma_c)^2)`` (with x, y, z at 1 m noise: how many metres the end point moves). A clock 10 ms
    late moves a 15-deg shell's end 2.7 m along x and 1.5 m in z: 3.1 sd.
    """
    out = {}
    for j, c in enumerate(setup.channels):
        w = np.flatnonzero(setup.weights[:, j] > 0)
        if w.size:
            out[c] = float(dy[w[-1], j] / setup.sigma[c])
    norm = math.sqrt(sum(v * v for v in out.values()))
    return {"per_channel": {c: abs(v) for c, v in out.items()}, "max_sd": norm}


def cd_shift(setup, theta_eff, dy, mach, n_mach=9):
    """Cd change a Scheme 1 fit would absorb had an effect been ignored (linearised).

    The output change the effect causes, ``dy`` (:func:`effect_change`), is least-squares fitted
    (noise-weighted, zero-weight samples out) by Cd and initial-state sensitivities at the fitted
    state, with the launch priors as pseudo-measurements (the effect cannot hide in the initial
    state); ``dCd(M) = B(M) d beta``. The Cd model is the Scheme 1 one: with a reference table the
    table times a cubic-spline correction on :func:`bayesdrag.drag.default_spline_knots` (a
    constant or smooth change of the table costs nothing, and relative shifts read straight off
    the correction); without one the diagnosis' nuisance spline at its fitted coefficients with
    its smoothness penalty (the penalised refit is what the Scheme 1 fit would do).

    Parameters
    ----------
    setup : Setup
    theta_eff : (P + 6 + ...) array
        The fit's parameters (drag coefficients and the initial state are used).
    dy : (N, C) array
    mach : (N,) Mach along the trajectory (its finite range is the flown range)

    Returns
    -------
    dict with ``mach`` (list), ``cd_relative`` (list, dCd / Cd), ``max_abs_relative``.
    """
    from ..drag import TableSpline, default_spline_knots

    P = setup.P
    s0 = theta_eff[ParameterLayout(P).state]
    m = np.asarray(mach, float)
    m = m[np.isfinite(m)]
    lo, hi = float(m.min()), float(m.max())
    if hi - lo < 0.02:  # a (nearly) constant-Mach flight: a 0.02 span around it
        lo, hi = lo - 0.01, hi + 0.01
    ref = setup.rnd.reference_drag
    if ref is not None:
        dm = TableSpline(ref, tuple(default_spline_knots(lo, hi)))
        beta = dm.initial_params()
        model = setup.model.with_(drag=dm)
        pri = launch_priors(setup.rnd.launch, dm.n_params) if setup.launch_known else ()
    else:
        dm, beta, model = setup.model.drag, theta_eff[:P], setup.model
        pri = setup.priors + setup.smooth
    Pn = dm.n_params
    th = np.concatenate([beta, s0])
    free = np.concatenate([np.ones(Pn, bool), setup.free[ParameterLayout(P).state]])
    prob = OutputErrorProblem(model, setup.track, th, free=free, sigma=setup.sigma, priors=pri,
                              channels=setup.channels, t_ic=setup.t_ic, weights=setup.weights, site=setup.site)
    _, _, S = prob.sensitivities(th)
    sw = np.sqrt(setup.weights) / np.array([setup.sigma[c] for c in setup.channels])[None, :]
    A = (S * sw[:, :, None]).reshape(-1, S.shape[-1])
    b = (dy * sw).reshape(-1)
    # the Scheme 1 fit keeps its launch priors (and, without a table, its smoothness penalty):
    # linearised about the fit, they enter as pseudo-measurements of a zero change
    _, pJ = prob.prior_terms(th)
    if pJ.shape[0]:
        A = np.vstack([A, pJ])
        b = np.concatenate([b, np.zeros(pJ.shape[0])])
    d, *_ = np.linalg.lstsq(A, b, rcond=None)
    grid = np.linspace(lo, hi, n_mach)
    cd0 = dm.cd(beta, grid)
    rel = (dm.jacobian(grid) @ d[:Pn]) / cd0
    return {"mach": [round(float(v), 3) for v in grid], "cd_relative": [float(v) for v in rel],
            "max_abs_relative": float(np.max(np.abs(rel)))}


def materiality(cd_shift_max, end_shift_sd, cd_tol=MATERIAL_CD_SHIFT, end_tol=MATERIAL_END_SD):
    """Is an effect material? Ignoring it would shift a fitted Cd by more than
    ``cd_tol`` (relative) anywhere in the flown range, or move the track's end by more than
    ``end_tol`` noise sd.

    Parameters
    ----------
    cd_shift_max : float or None
        Largest |dCd / Cd| (:func:`cd_shift`); None when not computed: an unknown Cd shift
        counts as material (a detected effect is never called immaterial on half the evidence).
    end_shift_sd : float
        :func:`end_shift` ``max_sd``.
    cd_tol, end_tol : float

    Returns
    -------
    (bool, str) : material, and the reason in words.
    """
    cd_txt = ("Cd shift not computed" if cd_shift_max is None else
              f"Cd shift {100 * cd_shift_max:.3g} % ({'>' if cd_shift_max > cd_tol else '<='} {100 * cd_tol:g} %)")
    end_txt = f"end of track moved {end_shift_sd:.3g} noise sd ({'>' if end_shift_sd > end_tol else '<='} {end_tol:g})"
    material = cd_shift_max is None or cd_shift_max > cd_tol or end_shift_sd > end_tol
    return bool(material), f"{'material' if material else 'immaterial'}: {cd_txt}, {end_txt}"


def judge_impacts(setup, rows, found, joint_fit, fits, *, cd_shifts=True, material_cd_shift=MATERIAL_CD_SHIFT,
                  material_end_sd=MATERIAL_END_SD):
    """Fill each candidate row with what ignoring its effect would do and whether that matters.

    A detected effect is judged in the detected effects' joint fit when there are several,
    every other candidate in its own fit. Each row gets ``impact_from``, ``end_shift``,
    ``end_shift_sd`` [noise sd], ``cd_shift_max`` (relative, or None), ``cd_shift`` (for the
    detected, significant and ``CD_SHIFT_TOP`` best-ranked candidates), ``material`` and
    ``materiality``.

    Parameters
    ----------
    setup : Setup
    rows : list of dict
        Candidate rows, best first; changed in place.
    found : list of str
        The detected effects.
    joint_fit : (MLResult, OutputErrorProblem, (N, C) outputs) or None
        Their joint fit (used when ``len(found) > 1``).
    fits : dict name -> fit
        Every candidate's single fit.
    cd_shifts : bool
        Compute the Cd shifts (one sensitivity batch each); without them a detected effect counts
        as material.
    material_cd_shift : float
        Relative Cd shift above which an effect is material.
    material_end_sd : float
        End-of-track shift [noise sd] above which an effect is material.
    """
    for i, r in enumerate(rows):
        n = r["name"]
        fit = joint_fit if (n in found and len(found) > 1) else fits[n]
        r["impact_from"] = "joint fit" if (n in found and len(found) > 1) else "fitted alone"
        try:
            dy, mach_o = effect_change(setup, fit, n)
            es = end_shift(setup, dy)
        except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError) as exc:
            dy, es = None, None
            r["end_shift"] = {"error": f"{type(exc).__name__}: {exc}"}
        if es is not None:
            r["end_shift"] = es
        r["end_shift_sd"] = None if es is None else es["max_sd"]
        r["cd_shift_max"] = None
        if cd_shifts and dy is not None and (n in found or r["significant"] or i < CD_SHIFT_TOP):
            try:
                r["cd_shift"] = cd_shift(setup, fit[0].theta, dy, mach_o)
                r["cd_shift_max"] = r["cd_shift"]["max_abs_relative"]
            except Exception as exc:  # noqa: BLE001 - a report item, never the verdict
                r["cd_shift"] = {"error": f"{type(exc).__name__}: {exc}"}
        if (r["significant"] or n in found) and r["end_shift_sd"] is not None:
            r["material"], r["materiality"] = materiality(r["cd_shift_max"], r["end_shift_sd"],
                                                          material_cd_shift, material_end_sd)
        else:
            r["material"] = False
            r["materiality"] = ("not detected: its test statistic is below the threshold" if not r["significant"]
                                else "impact not computed: " + r["end_shift"].get("error", ""))
