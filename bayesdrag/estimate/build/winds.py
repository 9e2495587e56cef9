"""The ``wind_profile`` effect in a Scheme 1 fit: the layers laid over the fitted flight and the
priors that tie them (``fit --with wind_profile``, or a declared ``[atmosphere] wind_sd``).

* **Layers.** :data:`FIT_LAYERS` equal layers over the flight's span of the coordinate, read off
  the fit before the effect (:func:`fit_layers`): by height (met practice, the axis of the round's
  met profile) or by downrange distance (how small-arms tools zone winds). With ``--with auto``
  the diagnosis's axis is used; otherwise both axes are fitted and the one with the smaller cost
  is kept (the two have the same number of parameters and the same priors, so the cost is their
  evidence up to the determinants). More layers than the diagnosis lays (which only has to name
  the wind); the random walk keeps the extra layers from wandering. The axes are compared at
  their equal grids only (one fit each: the same effort, so the cost comparison is fair).
* **Edges.** A wind that steps inside a layer leaves a misfit the Cd spline bends to follow. On
  the chosen axis, when it is one of :data:`PLACED_AXES`, the edges are then placed by the fit's
  deviance (:func:`placed_layers`): the equal grid shifted by fractions of a layer, then the
  edges the wind steps across moved by halving steps, each try started from the best fit so
  far. A placement is kept only when its deviance drop beats the BIC price of the edge
  parameters it chose (:func:`edge_penalty`: ``ln N`` per parameter); else the equal grid stays.
* **Placement as model error.** Each placement tried gives its own Cd (the spline bends where
  a wind step is put), and the track supports each by its likelihood. The edges are nuisance
  parameters: their Cd spread about the kept fit's, weighted by the likelihood ratios
  (:func:`equivalent_placements`), is added to each row's model error (:func:`placement_sd`).
* **A layer's size.** A layer's constant is the track's sensitivity-weighted mean of a wind that
  may change inside it; the Cramér-Rao sd holds the noise only. The wind read through the layer
  middles (:func:`within_layer_sd`) says how much it changes inside each layer, and that change,
  spread uniformly, is the layer's representation sd, added to its bound in squares.
* **Priors.** Neighbouring layers differ with sd :data:`bayesdrag.effects.wind_layers.WIND_STEP_SD` per
  component (the random walk of the diagnosis); with ``[atmosphere] wind_sd`` declared, each
  layer's wind is also ``N(0, wind_sd^2)`` around the round's own wind (the layers are what the
  met profile did not state). Without it the layers are bounded only, and what the track tells
  of the wind is all the fit knows.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...effects.wind_layers import EDGE_ROUND, WIND_LAYERS_MAX, WIND_STEP_SD, equal_edges, path_layers, wind_profile_free
from ..model.problem import Prior

__all__ = ["wind_layer_priors", "fit_layers", "placed_layers", "equivalent_placements", "placement_sd",
           "edge_penalty", "deviance", "within_layer_sd", "layer_sizes", "layers_over", "at_fit_resolution", "layer_free", "WIND_AXES",
           "PLACED_AXES", "FIT_LAYERS"]

#: layers of a fitted wind profile (the diagnosis lays fewer: it only has to name the wind)
FIT_LAYERS = WIND_LAYERS_MAX
#: the axes a wind profile may be laid on, met practice first
WIND_AXES = ("altitude", "downrange")
#: the axes whose edges are placed: zones by downrange distance end at one place; a height is
#: crossed twice (up and down), where a placed edge traded against transonic Cd
PLACED_AXES = ("downrange",)
#: the equal grid is also tried shifted by these fractions of a layer
GRID_SHIFTS = (0.25, 0.5, 0.75)
#: an edge the fitted wind changes across by more than this [m/s] (the random walk's sd per
#: layer: a zone boundary, not a gradient) is moved
EDGE_PLACE_STEP = WIND_STEP_SD
#: at most this many edges are moved, largest change first
EDGE_PLACE_MAX = 2
#: halving steps of an edge's move, from a quarter layer
EDGE_PLACE_ROUNDS = 3


def _layer_index(names, effect="wind_profile"):
    """{(component, layer): index} of an effect's layer parameters among ``names``."""
    out = {}
    for j, n in enumerate(names):
        if n.startswith(effect + "."):
            c, k = n.split(".", 1)[1].rsplit("_", 1)
            out[(c, int(k))] = j
    return out


def wind_layer_priors(names_all, free, level_sd=None):
    """Priors of ``wind_profile``'s used layers (linear rows of the full parameter vector).

    Parameters
    ----------
    names_all : sequence of str
        The problem's parameter names (``wind_profile.wx_1``, ...; others are ignored).
    free : (n,) bool
        Which parameters are estimated (a held layer gets no prior).
    level_sd : float or None, m/s
        The declared ``[atmosphere] wind_sd``: each free layer component ``N(0, level_sd^2)``
        around the round's own wind. None: only the random walk.

    Returns
    -------
    tuple of Prior
        The random-walk differences first (each neighbouring pair per component,
        ``N(0, WIND_STEP_SD^2)``), then the levels.
    """
    idx = _layer_index(names_all)
    n = len(names_all)
    out = []
    for c in ("wx", "wy"):
        ks = sorted(k for (cc, k) in idx if cc == c and free[idx[(c, k)]])
        for k0, k1 in zip(ks, ks[1:]):
            i0, i1 = idx[(c, k0)], idx[(c, k1)]
            row = np.zeros(n)
            row[i1], row[i0] = 1.0, -1.0
            out.append(Prior(f"wind_profile.{c}_{k1}-{c}_{k0}", (lambda th, a=i1, b=i0: th[..., a] - th[..., b]),
                             0.0, WIND_STEP_SD, row=row))
    if level_sd is not None:
        for (c, k), j in sorted(idx.items(), key=lambda kv: kv[1]):
            if free[j]:
                row = np.zeros(n)
                row[j] = 1.0
                out.append(Prior(f"wind_sd.{c}_{k}", (lambda th, j=j: th[..., j]), 0.0, float(level_sd), row=row))
    return tuple(out)


def fit_layers(prob, res, rnd, axis):
    """The ``wind_profile`` layers on ``axis`` over the flight a fit describes.

    Parameters
    ----------
    prob : OutputErrorProblem
        The fit's problem (its model flies the path).
    res : MLResult
        The fit before the wind layers.
    rnd : Round
        Its atmosphere's wind is the layers' base; its gun altitude the height datum.
    axis : {"altitude", "downrange"}

    Returns
    -------
    WindLayers or None when the flight has no span on that axis.
    """
    t = np.asarray(prob.track.t, float)
    tr = prob.model.simulate_batch(res.drag_params[None], res.state0[None], t, t_start=prob.t_ic)
    st = tr.state[0]
    ok = np.all(np.isfinite(st[:, :3]), axis=1)
    if not ok.any():
        return None
    return layers_over(axis, st[ok, 0], st[ok, 2], rnd.atmosphere, FIT_LAYERS)


def deviance(prob, res):
    """-2 log-likelihood of a fit up to a constant shared by fits of the same track and noise
    model: its cost (chi2 with the priors) plus ``sum_c n_c ln sigma_c^2`` for the noise sd the fit
    estimated (constant when the sd is held), ``n_c`` the channel's weighted sample count."""
    w = np.asarray(prob.weights, float)
    return float(res.cost) + sum(float(np.sum(w[:, j])) * 2.0 * np.log(res.sigma[c])
                                 for j, c in enumerate(prob.channels) if c not in prob.sigma_fixed)


def edge_penalty(prob, k):
    """BIC price [deviance] of ``k`` edge parameters a placement chose (a shift of the grid, each
    edge moved): ``k ln N``, ``N`` the weighted residual count."""
    return k * float(np.log(max(float(np.sum(prob.weights)), 2.0)))


def _shifted(layers, frac):
    """``layers`` with every inner edge moved up by ``frac`` of a layer's width."""
    e = np.asarray(layers.edges, float)
    w = (e[-1] - e[0]) / layers.n
    inner = np.round((e[1:-1] + frac * w) / EDGE_ROUND) * EDGE_ROUND
    out = np.concatenate([[e[0]], inner, [e[-1]]])
    return replace(layers, edges=tuple(float(v) for v in out)) if np.all(np.diff(out) > 0) else None


def _moved(layers, i, pos):
    """``layers`` with inner edge ``i`` (1..n-1) at ``pos`` [m]; None when it would pass a
    neighbour."""
    e = list(layers.edges)
    pos = float(np.round(pos / EDGE_ROUND) * EDGE_ROUND)
    if not e[i - 1] < pos < e[i + 1] or pos == e[i]:
        return None
    e[i] = pos
    return replace(layers, edges=tuple(e))


def _jumps(layers, res):
    """{inner edge index: size [m/s] of the fitted wind's change across it}."""
    vals = dict(zip(res.names, res.theta))
    w = np.array([[vals.get(f"wind_profile.{c}_{k}", 0.0) for c in ("wx", "wy")] for k in range(1, layers.n + 1)])
    return {i: float(np.hypot(*(w[i] - w[i - 1]))) for i in range(1, layers.n)}


def placed_layers(layers, fit, d0, score, penalty, tried=None):
    """The layers' edges placed where the track puts the wind's steps, or ``layers`` unchanged.

    Tries the grid shifted by :data:`GRID_SHIFTS` of a layer, then in the best grid each edge the
    fitted wind changes across by more than :data:`EDGE_PLACE_STEP` (largest first, at most
    :data:`EDGE_PLACE_MAX`) moved by halving steps (:data:`EDGE_PLACE_ROUNDS`), each try started
    from the best fit so far. The best try is kept only when ``d0 - score > penalty(k)``, ``k``
    the edge parameters it chose (1 for a shift, 1 per edge moved), and when the kept grid fitted
    from the plain start reaches the same optimum (deviance within ``penalty(1)``): separate
    optima mean the wind and Cd trade and the band of one optimum is not Cd's uncertainty.

    Parameters
    ----------
    layers : WindLayers
        The equal layers.
    fit : tuple
        Their fit ``(problem, MLResult, ...)`` (as :func:`~.systematics.fit_with_sources` returns).
    d0 : float
        Its deviance.
    score : callable ``score(WindLayers, fit or None) -> (float, fit)``
        The fit with those layers started from ``fit``'s estimate (None: from the fit before the
        wind), and its deviance (inf when it fails).
    penalty : callable ``penalty(k) -> float``
    tried : list, optional
        Each placement's ``(deviance, fit)`` is appended to it, the equal layers' first
        (:func:`equivalent_placements` reads it).

    Returns
    -------
    (WindLayers, fit)
        The layers kept and their fit (``fit`` itself when the equal layers stay).
    """
    if tried is not None:
        tried.append((d0, fit))
        inner = score

        def score(lay, start):
            d, out = inner(lay, start)
            tried.append((d, out))
            return d, out
    best = (d0, fit, layers, 0)
    for f in GRID_SHIFTS:
        lay = _shifted(layers, f)
        if lay is not None:
            d, out = score(lay, best[1])
            if d < best[0]:
                best = (d, out, lay, 1)
    w = (layers.edges[-1] - layers.edges[0]) / layers.n
    jumps = sorted(((j, i) for i, j in _jumps(best[2], best[1][1]).items() if j > EDGE_PLACE_STEP), reverse=True)
    for _, i in jumps[:EDGE_PLACE_MAX]:
        step, moved = w / 4.0, False
        for _ in range(EDGE_PLACE_ROUNDS):
            centre = best[2].edges[i]
            for pos in (centre - step, centre + step):
                lay = _moved(best[2], i, pos)
                if lay is not None:
                    d, out = score(lay, best[1])
                    if d < best[0]:
                        best = (d, out, lay, best[3] + (not moved))
                        moved = True
            step /= 2.0
    if not best[3] or d0 - best[0] <= penalty(best[3]):
        return layers, fit
    # each try started from the last: the kept grid fitted again from the plain start must reach
    # the same optimum, else the likelihood has separate optima and the band of one is not Cd's
    d_cold, _ = score(best[2], None)
    return (best[2], best[1]) if d_cold - best[0] <= penalty(1) else (layers, fit)


def equivalent_placements(tried, kept):
    """The placements tried, weighted by how well the track supports each.

    The edges' positions are nuisance parameters the fit chose among a few tries; each try's
    weight is its likelihood relative to the best, ``exp(-(d - d_min) / 2)`` (``d`` the deviance,
    -2 log likelihood up to a constant), i.e. the edges marginalised with a flat prior over the
    positions tried.

    Parameters
    ----------
    tried : list of (float, fit)
        Deviance and fit of every placement :func:`placed_layers` tried.
    kept : fit
        The fit it kept.

    Returns
    -------
    (ndarray, tuple of ndarray, ndarray) or None
        The kept fit's drag coefficients, every converged try's (the kept one among them) and
        their weights (summing to 1); None when no other placement converged.
    """
    ok = [(d, f) for d, f in tried if f is not None and np.isfinite(d) and f[3]]
    if not any(f[1] is kept[1] for _, f in ok) or len(ok) < 2:
        return None
    d = np.array([d for d, _ in ok], float)
    w = np.exp(-0.5 * (d - d.min()))
    return (np.array(kept[1].drag_params, float), tuple(np.array(f[1].drag_params, float) for _, f in ok),
            w / w.sum())


def placement_sd(drag_model, placements, mach):
    """Cd's sd [Cd] from where the layers' edges are put: the weighted RMS, over the placements
    tried (:func:`equivalent_placements`), of their Cd less the kept placement's (its spread and
    the kept placement's distance from their weighted mean, together).

    Parameters
    ----------
    drag_model : DragModel
    placements : (ndarray, tuple of ndarray, ndarray) or None
    mach : (M,) array

    Returns
    -------
    (M,) ndarray
        Zeros without placements.
    """
    mach = np.asarray(mach, float)
    if not placements:
        return np.zeros(mach.size)
    kept, tries, w = placements
    base = drag_model.cd(kept, mach)
    diff = np.array([drag_model.cd(a, mach) - base for a in tries])
    return np.sqrt(np.asarray(w, float) @ diff**2)


def layers_over(axis, x, z, atmosphere, n=FIT_LAYERS):
    """``n`` equal ``wind_profile`` layers on ``axis`` over a path (the one construction the fit
    and the diagnosis share): height from the gun to the apex or downrange distance from the gun
    to the last point, the atmosphere's own wind as their base.

    Parameters
    ----------
    axis : {"altitude", "downrange"}
    x, z : (N,) arrays or None, m
        Downrange distance and height above the gun along the path (None: not known).
    atmosphere : Atmosphere
        Its gun altitude is the height datum; its wind (if any) the layers' base.
    n : int

    Returns
    -------
    WindLayers or None when the path has no span on that axis.
    """
    return path_layers(axis, x, z, atmosphere.gun_altitude, getattr(atmosphere, "wind", None), n)


def at_fit_resolution(layers, n=FIT_LAYERS):
    """The same layers (span, axis, base, cross-wind rule) cut into the fit's ``n`` equal layers;
    None when ``layers`` is None or already has that many."""
    if layers is None or layers.n >= n:
        return None
    e = equal_edges(layers.edges[0], layers.edges[-1], n)
    return None if e is None else replace(layers, edges=e)


def layer_free(layers, name, channels):
    """Is the fit's parameter ``name`` (``wind_profile.wy_2``) estimated? The layers set how many
    there are; without a ``y`` channel the cross wind has no lateral signature and is held at 0."""
    from ...effects import EffectContext

    if not wind_profile_free(EffectContext(wind_layers=layers), name):
        return False
    return not (".wy_" in name and "y" not in channels)


def within_layer_sd(lower, upper, values):
    """What a layer's constant cannot say [m/s]: the sd of the wind inside each layer about any
    weighted mean of it.

    The track sees each layer only through a weighted mean of the wind flown inside it (the
    weights are the track's sensitivities, not the samples' count); a wind that changes inside
    the layer makes every weighting give another mean. The simplest wind the layers describe runs
    linearly through their middles (extrapolated over the outer half-layers); over layer ``k`` it
    spans a range ``R_k`` (its values at the two edges and at the middle), and a mean with weights
    the track cannot state lies anywhere in that range: uniformly, sd ``R_k / sqrt(12)``.

    Parameters
    ----------
    lower, upper : (K,) arrays, m
        Each layer's edges on its axis (height or downrange distance), the layers in order.
    values : (K,) array, m/s
        Each layer's fitted wind (one component).

    Returns
    -------
    (K,) ndarray, m/s
        Zeros for a single layer or a constant profile.
    """
    a, b = np.asarray(lower, float), np.asarray(upper, float)
    v = np.asarray(values, float)
    if v.size < 2:
        return np.zeros(v.size)
    mid = 0.5 * (a + b)

    def at(p):      # the line through the middles, extended over the outer half-layers
        k = np.clip(np.searchsorted(mid, p) - 1, 0, v.size - 2)
        return v[k] + (v[k + 1] - v[k]) * (p - mid[k]) / (mid[k + 1] - mid[k])
    lo, hi = at(a), at(b)
    span = np.max([lo, v, hi], axis=0) - np.min([lo, v, hi], axis=0)
    return span / np.sqrt(12.0)


def layer_sizes(layers, names, theta, free, crb, crb_colored):
    """Each layer's fitted wind and its sd [m/s] as ``ml.with_effects.wind_layers.layers`` reports
    them: ``wx``, ``wy`` (0 for a held component), ``wx_sd`` = the larger of the Cramér-Rao sd
    and its colored form (correlated residuals) with :func:`within_layer_sd` added in squares,
    ``wx_crb_sd`` the plain Cramér-Rao sd and ``wx_within_sd`` the representation part (None for
    a held component).

    Parameters
    ----------
    layers : WindLayers
    names : sequence of str
        The fit's parameter names (``wind_profile.wx_1``, ...).
    theta, free, crb, crb_colored : (n,) arrays
        The fit's estimate, which parameters are free, and their sd.

    Returns
    -------
    list of dict
        One per layer: ``layer``, ``from``, ``to`` and the keys above.
    """
    names = list(names)
    rows = [{"layer": k, "from": layers.edges[k - 1], "to": layers.edges[k]} for k in range(1, layers.n + 1)]
    for c in ("wx", "wy"):
        js = [names.index(f"wind_profile.{c}_{k if not (c == 'wy' and layers.constant_cross) else 1}")
              for k in range(1, layers.n + 1)]
        held = [not free[j] for j in js]
        vals = np.array([0.0 if h else float(theta[j]) for j, h in zip(js, held)])
        within = np.zeros(layers.n)
        fk = np.flatnonzero(~np.array(held))
        if len(set(js)) > 1 and fk.size > 1:      # over the free layers only (a held one is no wind)
            e = np.asarray(layers.edges, float)
            within[fk] = within_layer_sd(e[fk], e[fk + 1], vals[fk])
        for row, j, h, w in zip(rows, js, held, within):
            row[c] = float(vals[row["layer"] - 1])
            sds = [float(v) for v in (crb[j], crb_colored[j]) if np.isfinite(v)]
            base = max(sds) if sds else float("nan")
            row[f"{c}_sd"] = None if h else float(np.hypot(base, w))
            row[f"{c}_crb_sd"] = None if h else float(crb[j])
            row[f"{c}_within_sd"] = None if h else float(w)
    return rows
