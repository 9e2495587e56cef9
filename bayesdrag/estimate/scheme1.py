"""Scheme 1: Cd(M) over the whole flight together with the initial conditions (paper §3-4).

Choices written down:

* **Default drag model: ``spline``**, a *penalised* cubic B-spline (P-spline, Eilers & Marx
  1996): knots every :data:`PSPLINE_SPACING` Mach over the span the flight covers (from a first
  simulation with the reference drag), and a penalty on the second differences of the
  coefficients whose weight the data choose by maximising the Laplace-approximated marginal
  likelihood (the REML-type evidence of the linearised problem) over a grid of weights. Why not
  knots added one by one by BIC: BIC's ``log N`` per knot (~9 for a 1500-sample x, y, z, v
  track) refuses corrections of a few Cramér-Rao sd, so the representation error stays several
  bounds wide where Cd bends (measured: 3-7 sd near Mach 1.2-1.4 with fixed knots); the penalised
  spline follows the bend and its bounds include the smoothing. The effective number of
  parameters ``edf = tr(F_data F_total^-1)`` is reported. The bounds of a penalised fit are the
  curvature of the penalised cost, i.e. the posterior sd under the smoothness prior (Wahba 1983),
  which is what the Bayesian layer samples too. Explicit ``knots`` give a plain (unpenalised)
  spline. ``poly2`` and ``poly2-split``
  are the paper's and are kept for comparison; their misfit is reported, not hidden.
* **Initial conditions** at the first sample: from the round's launch (muzzle at the origin,
  ``velocity`` and ``elevation``) when the track starts at t = 0; otherwise from a quadratic
  Savitzky-Golay derivative of the first samples. Components the track cannot see are fixed
  (no ``y`` channel: Y0 = Uy0 = 0; no position channel: the muzzle position).
* **Earth rotation** is in the model when the round gives ``[launch] latitude`` (with
  ``azimuth``), as in ``bayesdrag simulate``.
* **Noise**: the round's ``[radar] sigma`` when given for a channel, else estimated by
  relaxation.
* **Determined Mach range**: where the Cramér-Rao sd of Cd is below 1 % of Cd, inside the Mach
  span of the data. Near the top of the span Cd correlates with the launch speed, so that end
  is often less determined than it looks.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.signal import savgol_filter

from ..drag import make_drag_model
from ..dynamics.pointmass import PointMassModel, initial_state
from ..errors import InputError
from .ml import OutputErrorProblem

#: relative CRB sd of Cd below which Cd counts as determined by the data
DETERMINED_REL_SD = 0.01
#: initial-condition parameters after the drag coefficients (X0, Y0, Z0, Ux0, Uy0, Uz0)
_N_IC = 6
#: Student-t degrees of freedom of the robust fit (4: heavy tails, finite variance)
ROBUST_NU = 4.0
#: reweighting passes of the robust fit
ROBUST_ITERATIONS = 6
#: a sample more than this many noise scales off the robust curve is listed as rejected
REJECT_K = 5.0
#: knot spacing of the penalised spline [Mach]: fine enough for the transonic rise of M101/G7-like
#: curves (rise width ~0.1 Mach), coarse enough to keep the batch small (~40 coefficients)
PSPLINE_SPACING = 0.04
#: finer knot spacing inside :data:`TRANSONIC`
PSPLINE_FINE = 0.02
#: Mach band of the drag rise where the knots are refined
TRANSONIC = (0.86, 1.20)
#: candidate sd of the coefficients' second differences (the penalty weight is 1/sd^2)
PSPLINE_SD_GRID = tuple(10.0 ** np.arange(-5.0, 0.01, 0.5))


def _initial_state(track, rnd):
    L = rnd.launch
    t0 = float(track.t[0])
    if abs(t0) < 1e-9 and L.velocity is not None and L.elevation_deg is not None:
        return initial_state(L.velocity, L.elevation_deg)
    pos = [track.channels.get(c) for c in ("x", "y", "z")]
    n = min(track.n, 21)
    if n < 7 or pos[0] is None or pos[2] is None:
        raise InputError(f"{track.source}: the track starts at t = {t0:g} s; initial conditions need "
                         f"x and z samples there (>= 7) or [launch] velocity and elevation with t = 0")
    tt = track.t[:n]
    dt = float(np.median(np.diff(tt)))
    s = np.zeros(6)
    for k, p in enumerate(pos):
        if p is None:
            continue
        s[k] = savgol_filter(p[:n], n if n % 2 else n - 1, 2, mode="interp")[0]
        s[3 + k] = savgol_filter(p[:n], n if n % 2 else n - 1, 2, deriv=1, delta=dt, mode="interp")[0]
    return s


def _coriolis(rnd):
    L = rnd.launch
    return (L.latitude_deg, L.azimuth_deg) if L.latitude_deg is not None else None


def mach_span(track, rnd, state0):
    """Mach range of the flight from a simulation with the reference (or a generic) drag."""
    from ..drag import Poly2

    ref = rnd.reference_drag
    drag = ref if ref is not None else Poly2()
    params = () if ref is not None else (0.3, 0.0, 0.0)
    model = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, drag, rnd.atmosphere,
                           coriolis=_coriolis(rnd))
    tr = model.simulate(params, state0, track.t, t_start=float(track.t[0]))
    m = tr.mach[np.isfinite(tr.mach)]
    return float(m.min()), float(m.max())


def launch_state_priors(L, P, heading=False):
    """Gaussian priors on the state at launch (t = 0) from a round's ``[launch]`` ``L``, for a
    parameter vector whose initial state starts at index ``P``: muzzle at the origin
    (``position_sd`` per axis), launch speed (``velocity_sd``), elevation (``elevation_sd``) and,
    with ``heading``, a heading along +x with the elevation's sd (the diagnosis).

    The functions take one parameter vector (n,) or many (W, n): the sampler evaluates all
    walkers at once.
    """
    from .ml import Prior

    pri = [Prior(f"{n}_muzzle", (lambda th, k=k: th[..., P + k]), 0.0, L.position_sd)
           for k, n in enumerate(("X0", "Y0", "Z0"))]
    pri.append(Prior("launch_speed", lambda th: np.sqrt(th[..., P + 3] ** 2 + th[..., P + 4] ** 2
                                                        + th[..., P + 5] ** 2), L.velocity, L.velocity_sd))
    pri.append(Prior("elevation", lambda th: np.degrees(np.arctan2(th[..., P + 5], np.hypot(th[..., P + 3],
                                                                                           th[..., P + 4]))),
                     L.elevation_deg, L.elevation_sd_deg))
    if heading:
        pri.append(Prior("heading", lambda th: np.degrees(np.arctan2(th[..., P + 4], th[..., P + 3])),
                         0.0, L.elevation_sd_deg))
    return tuple(pri)


def launch_priors(track, rnd, P):
    """The round's launch priors (:func:`launch_state_priors`) when the track starts at the
    muzzle (t = 0) and the launch is known, else none. They are weak against a full x, y, z, v
    track but keep a speed-only (Doppler) track's elevation where the gun put it."""
    L = rnd.launch
    if abs(float(track.t[0])) > 1e-9 or L.velocity is None or L.elevation_deg is None:
        return ()
    return launch_state_priors(L, P)


def fit_scheme1(track, rnd, drag="spline", channels=None, sigma=None, free_ic=True, knots=None,
                penalise=True, likelihood="gaussian", nu=ROBUST_NU):
    """Scheme 1 ML fit of one track.

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
    drag : str
        Drag model name (DESIGN.md).
    channels : sequence of str, optional
    sigma : dict, optional
        Fixed noise sd per channel (default: the round's ``[radar] sigma``).
    free_ic : bool
        Estimate the initial conditions (paper Fig. 3c) or keep them at their starting values
        (Fig. 3b).
    knots : sequence of float, optional
        Spline knots: a plain (unpenalised) spline on these knots. Default: the penalised
        spline on :func:`pspline_knots` over the Mach span.
    penalise : bool
        ``False`` with ``knots=None``: a plain spline on :func:`bayesdrag.drag.default_spline_knots`.
    likelihood : {"gaussian", "student-t"}
        ``student-t``: a robust fit for tracks with gross outliers, see :func:`robust_refit`.
    nu : float
        Degrees of freedom of the Student-t likelihood.

    Returns
    -------
    (MLResult, OutputErrorProblem)
        The problem carries ``smoothing`` (dict: chosen penalty sd and weight, effective number
        of parameters ``edf`` and ``edf_drag``, the evidence over the grid) or None.
    """
    s0 = _initial_state(track, rnd)
    lo, hi = mach_span(track, rnd, s0)
    penalised = drag == "spline" and knots is None and penalise
    if penalised:
        knots = pspline_knots(lo, hi)
        # a short track (e.g. a Doppler report every 100 yd) cannot carry ~40 coefficients: keep
        # the coefficients below a third of the data values, coarsening the knots evenly
        n_data = track.n * len(tuple(channels) if channels is not None else track.names)
        max_coef = max(4, (n_data - 6) // 3)
        if knots.size + 2 > max_coef:
            knots = pspline_knots(lo, hi, spacing=(hi - lo) / max(max_coef - 3, 1), fine=np.inf)
    try:
        dm = make_drag_model(drag, reference=rnd.reference_drag, mach_range=(lo, hi), knots=knots)
    except ValueError as exc:
        raise InputError(f"{rnd.path or 'round'}: {exc}") from None
    model = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, dm, rnd.atmosphere,
                           coriolis=_coriolis(rnd))
    theta0 = np.concatenate([dm.initial_params(rnd.reference_drag), s0])
    free = np.ones(theta0.size, bool)
    P = dm.n_params
    chans = tuple(channels) if channels is not None else track.names
    if not free_ic:
        free[P:] = False
    if "y" not in chans:
        free[P + 1] = free[P + 4] = False
    if not any(c in chans for c in ("x", "y", "z")):
        free[P:P + 3] = False
    if drag == "poly2-split":
        if hi < 1.0:
            free[3:6] = False
        if lo >= 1.0:
            free[0:3] = False
    sig = dict(rnd.radar.sigma) if sigma is None else dict(sigma)
    pri = launch_priors(track, rnd, P)
    prob = OutputErrorProblem(model, track, theta0, free=free, sigma=sig, channels=chans, priors=pri)
    if likelihood not in ("gaussian", "student-t"):
        raise InputError(f"likelihood {likelihood!r} is not allowed; use gaussian or student-t")
    if likelihood == "student-t":
        # start from a fit whose noise sd is estimated (relaxation inflates it over the
        # outliers instead of bending the curve to them), then reweight
        prob.sigma_fixed = {}
    if penalised:
        res, prob = _fit_penalised(prob, pri, P)
    else:
        prob.smoothing = None
        res = prob.fit()
    if likelihood == "student-t":
        res = robust_refit(prob, res, sigma=sig, nu=nu)
        if penalised:
            res = _drop_coefficient_correlations(res, P)
    return res, prob


def _drop_coefficient_correlations(res, P):
    """Neighbouring coefficients of a penalised spline are strongly correlated by design; only
    correlations that involve an initial condition (e.g. Cd at the top Mach vs Ux0) are news."""
    drag_names = set(res.names[:P])
    kept = tuple(w for w in res.warnings
                 if not (w.startswith("parameters ") and "strongly correlated" in w
                         and set(w.split()[1:4:2]) <= drag_names))
    return replace(res, warnings=kept)


def robust_refit(prob, res, sigma=None, nu=ROBUST_NU, iterations=ROBUST_ITERATIONS):
    """Student-t maximum likelihood by iteratively reweighted least squares.

    The t likelihood's EM weights ``w = (nu + 1) / (nu + r^2 / s^2)`` (``s`` the noise scale:
    the round's sigma when given, else a robust estimate, 1.4826 x the median absolute residual)
    are divided by their maximum ``(nu + 1) / nu`` so they lie in [0, 1] (the problem's per-sample
    weights; this rescales the noise by a constant) and the fit is repeated from the previous
    estimate with the same priors (and smoothing weight) a few times. Samples more than
    :data:`REJECT_K` scales from the curve end with a weight below 0.15: they are listed as
    rejected in ``prob.rejected`` (channel -> sample indices).

    Returns the final MLResult; ``prob.weights`` keeps the weights.
    """
    chans = prob.channels
    for _ in range(iterations):
        r = np.stack([res.residuals[c] for c in chans], axis=-1)
        scale = np.empty(len(chans))
        for j, c in enumerate(chans):
            if sigma and c in sigma:
                scale[j] = float(sigma[c])
            else:
                scale[j] = max(1.4826 * float(np.median(np.abs(r[:, j] - np.median(r[:, j])))), 1e-9)
        w = (nu + 1.0) / (nu + (r / scale) ** 2) * nu / (nu + 1.0)
        prob.weights = np.clip(w, 0.0, 1.0)
        prob.sigma_fixed = {c: float(scale[j] * np.sqrt(nu / (nu + 1.0))) for j, c in enumerate(chans)}
        prob.theta0 = res.theta.copy()
        new = prob.fit()
        if not np.all(np.isfinite(new.theta)):
            break
        step = np.abs(new.theta - res.theta)[res.free]
        res = new
        if np.all(step <= 1e-3 * np.where(res.crb[res.free] > 0, res.crb[res.free], np.inf)):
            break
    r = np.stack([res.residuals[c] for c in chans], axis=-1)
    prob.rejected = {c: [int(i) for i in np.flatnonzero(np.abs(r[:, j]) > REJECT_K * scale[j])]
                     for j, c in enumerate(chans)}
    return res


def pspline_knots(mach_min, mach_max, spacing=PSPLINE_SPACING, fine=PSPLINE_FINE, dm=0.01):
    """Knots (ends included) of the penalised spline, on multiples of ``dm`` (the kernel's grid).

    Spacing ``spacing`` [Mach], refined to ``fine`` inside :data:`TRANSONIC` where drag rises over
    ~0.1 Mach (a cubic spline on 0.04 Mach knots misses the M101 knee at Mach 0.95 by 3 %, on
    0.02 by 0.4 %; above Mach 1.2 0.04 follows it to 0.01 % rms).
    """
    lo = np.floor(mach_min / dm) * dm
    hi = np.ceil(mach_max / dm) * dm
    a, b = TRANSONIC
    pts = [lo, hi]
    pts += list(np.arange(lo, hi, spacing))
    if a < hi and b > lo and np.isfinite(fine):
        pts += list(np.arange(max(a, lo), min(b, hi), fine))
    k = np.unique(np.round(np.asarray(pts) / dm) * dm)
    # no knot closer than dm/2 to another (rounding) and at least 3 intervals
    if k.size < 4:
        k = np.round(np.linspace(lo, hi, 4) / dm) * dm
    return k


def difference_priors(P, sd, scale=None, order=2):
    """Smoothness penalty as Gaussian pseudo-priors on the B-spline coefficients.

    Each ``order``-th difference of ``c / scale`` (the first P parameters divided elementwise by
    ``scale``) has mean 0 and sd ``sd``. With ``scale`` the coefficients of the reference drag
    curve, the prior says "Cd is the reference times a smooth correction": a change of scale costs
    nothing. Without a reference ``scale`` is a generic artillery-like curve
    (:meth:`DragModel.initial_params`).

    Parameters
    ----------
    P : int
    sd : float or (P - order,) array
    scale : (P,) array, optional
    order : int

    Returns
    -------
    (priors, D, sds) : tuple of Prior, ndarray (P - order, P) acting on the coefficients
        themselves, ndarray (P - order,) of the sds.
    """
    from .ml import Prior

    scale = np.ones(P) if scale is None else np.asarray(scale, dtype=float)
    D = np.diff(np.eye(P), n=order, axis=0) / scale[None, :]
    sds = np.broadcast_to(np.asarray(sd, dtype=float), (len(D),)).copy()
    pri = tuple(Prior(f"smooth{i}", (lambda th, d=d: float(d @ th[:P])), 0.0, float(sds[i]),
                      row=np.concatenate([d, np.zeros(_N_IC)]))
                for i, d in enumerate(D))
    return pri, D, sds


def _fit_penalised(prob, base_priors, P):
    """Choose the penalty by the Laplace evidence and return the fit at the best one.

    The sd of each second difference of ``c / c_ref`` is ``sd * w_i`` with
    ``w_i = 1 + |D2 c_ref|_i / median |D2 c_ref|``: the prior allows more change where the
    reference curve itself bends (the drag rise, where shells differ from their tables most:
    the rise moves and changes height) and holds the smooth parts to a smooth correction. With a
    single weight for all, a moved rise forces a rough fit everywhere (measured: Cd errors of
    1.3 % in the supersonic part instead of 0.03 %); with two weights on a hard-edged band the
    band edge leaves a kink. ``sd`` is walked uphill in the Laplace evidence over
    :data:`PSPLINE_SD_GRID` from its middle; every fit starts from the previous one. The choice
    is recorded in ``prob.smoothing``.
    """
    c_ref = np.clip(prob.theta0[:P], 0.02, None)
    curv = np.abs(np.diff(c_ref, n=2)) / np.median(c_ref)
    med = np.median(curv[curv > 0]) if np.any(curv > 0) else 1.0
    w = 1.0 + curv / med
    grid = PSPLINE_SD_GRID
    cache = {}
    state = {"theta": prob.theta0.copy()}

    def evaluate(i):
        if i in cache:
            return cache[i][0]
        pen, D, sds = difference_priors(P, grid[i] * w, c_ref)
        prob.priors = tuple(base_priors) + pen
        prob.theta0 = state["theta"]
        res = prob.fit()
        idx = np.flatnonzero(res.free)
        ok = np.all(np.isfinite(res.theta))
        sign, logdet_cov = np.linalg.slogdet(res.cov[np.ix_(idx, idx)]) if ok else (0, 0.0)
        if sign <= 0:
            cache[i] = (-np.inf, res, prob.priors, np.nan)
            return -np.inf
        # log evidence (+ const): -1/2 chi2_penalised - 1/2 log|F| + 1/2 log|Lambda D'D|_+
        ev = -0.5 * res.cost + 0.5 * logdet_cov - float(np.sum(np.log(sds)))
        edf = float(idx.size - np.trace(res.cov[:P, :P] @ (D.T @ (D / sds[:, None] ** 2))))
        cache[i] = (float(ev), res, prob.priors, edf)
        state["theta"] = res.theta.copy()
        return float(ev)

    i = len(grid) // 2
    best = evaluate(i)
    for step in (1, -1):
        moved = False
        while 0 <= i + step < len(grid):
            ev = evaluate(i + step)
            if not ev > best:
                break
            i, best, moved = i + step, ev, True
        if moved:
            break
    ev, res, pri, edf = cache[i]
    if not np.isfinite(ev):
        from ..errors import FitError

        raise FitError("the penalised spline fit failed for every smoothing weight tried")
    prob.priors = pri
    res = _drop_coefficient_correlations(res, P)
    table = [{"sd": float(grid[k]), "log_evidence": v[0], "edf": v[3], "converged": v[1].converged}
             for k, v in sorted(cache.items())]
    n_ic = int(res.free[P:].sum())
    prob.smoothing = {"method": "P-spline: 2nd differences of c/c_reference, sd scaled by the reference's "
                                "curvature, Laplace evidence",
                      "sd": float(grid[i]), "edf": edf, "edf_drag": edf - n_ic,
                      "at_grid_end": i in (0, len(grid) - 1), "fits": len(cache), "grid": table}
    return res, prob


def cd_table(result, drag_model, mach, reference=None):
    """Cd(M) rows for result.json: ML value, CRB sd (delta method), reference."""
    P = drag_model.n_params
    B = drag_model.jacobian(mach)
    cd = drag_model.cd(result.drag_params, mach)
    var = np.einsum("ij,jk,ik->i", B, result.cov[:P, :P], B)
    varc = np.einsum("ij,jk,ik->i", B, result.cov_colored[:P, :P], B)
    rows = []
    for i, m in enumerate(mach):
        rows.append({"mach": round(float(m), 4), "ml": float(cd[i]), "crb_sd": float(np.sqrt(max(var[i], 0))),
                     "crb_sd_colored": float(np.sqrt(max(varc[i], 0))),
                     "reference": float(reference.value(m)) if reference is not None else None})
    return rows


def determined_range(rows):
    """Mach interval where the CRB relative sd of Cd is below :data:`DETERMINED_REL_SD`."""
    ok = [r["mach"] for r in rows if r["ml"] > 0 and r["crb_sd"] / r["ml"] < DETERMINED_REL_SD]
    return (min(ok), max(ok)) if ok else None
