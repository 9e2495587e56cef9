"""The ``wind_profile`` effect in a Scheme 1 fit: the layers laid over the fitted flight and the
priors that tie them (``fit --with wind_profile``, or a declared ``[atmosphere] wind_sd``).

* **Layers.** :data:`FIT_LAYERS` equal layers over the flight's span of the coordinate, read off
  the fit before the effect (:func:`fit_layers`): by height (met practice, the axis of the round's
  met profile) or by downrange distance (how small-arms tools zone winds). With ``--with auto``
  the diagnosis's axis is used; otherwise both axes are fitted and the one with the smaller cost
  is kept (the two have the same number of parameters and the same priors, so the cost is their
  evidence up to the determinants). More layers than the diagnosis lays (which only has to name
  the wind); the random walk keeps the extra layers from wandering.
* **Priors.** Neighbouring layers differ with sd :data:`bayesdrag.wind_layers.WIND_STEP_SD` per
  component (the random walk of the diagnosis); with ``[atmosphere] wind_sd`` declared, each
  layer's wind is also ``N(0, wind_sd^2)`` around the round's own wind (the layers are what the
  met profile did not state). Without it the layers are bounded only, and what the track tells
  of the wind is all the fit knows.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...wind_layers import WIND_LAYERS_MAX, WIND_STEP_SD, equal_edges, path_layers, wind_profile_free
from ..model.problem import Prior

__all__ = ["wind_layer_priors", "fit_layers", "layers_over", "at_fit_resolution", "layer_free", "WIND_AXES",
           "FIT_LAYERS"]

#: layers of a fitted wind profile (the diagnosis lays fewer: it only has to name the wind)
FIT_LAYERS = WIND_LAYERS_MAX
#: the axes a wind profile may be laid on, met practice first
WIND_AXES = ("altitude", "downrange")


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
