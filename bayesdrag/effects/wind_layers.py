"""The ``wind_profile`` effect's layers (:class:`WindLayers`: horizontal wind constant in each of a
few layers by height or by downrange distance, added to the round's own wind) and the model that
flies them per trajectory (:class:`WindProfileModel`, read from the kernel inputs as
:class:`bayesdrag.effects.drag.DragShapeModel` reads its coefficients)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..air.wind import WindProfile

__all__ = ["WindLayers", "WindProfileModel", "wind_profile_free", "path_layers", "equal_edges", "WIND_LAYERS_MAX",
           "WIND_STEP_SD",
           "WIND_LEVEL_SD", "WIND_PROFILE_KEY", "PROFILE_LAYERS", "EDGE_ROUND"]

#: most layers a wind_profile has (the fit lays this many, the diagnosis PROFILE_LAYERS; unused
#: ones are held at 0 and cost nothing)
WIND_LAYERS_MAX = 10
#: prior sd [m/s] of the change of wind between neighbouring layers (the random walk that ties
#: them): wind shear rarely exceeds a few m/s per km, and a layer spans a few km of height or
#: range; the zone winds small-arms tools take change by up to ~15 m/s at one distance, which
#: this prior costs (15 / 5)^2 = 9 in chi2 -- nothing against a gap of thousands
WIND_STEP_SD = 5.0
#: prior sd [m/s] of a wind's mean level when the round declares no [atmosphere] wind_sd (the
#: evidence that chooses between no wind, a constant wind and a profile needs a proper prior)
WIND_LEVEL_SD = 10.0
#: override key of wind_profile's layer winds (not a kernel column: read by WindProfileModel)
WIND_PROFILE_KEY = "wind_profile"
#: layers laid over a flight on each axis: enough to follow a wind that turns or strengthens once
#: along the flight, few enough that each layer holds a quarter of the track
PROFILE_LAYERS = 4
#: the edges of a layer grid are rounded to this [m]
EDGE_ROUND = 10.0

@dataclass(frozen=True)
class WindLayers:
    """The layers of ``wind_profile``: the coordinate and the layer edges, and the round's own
    wind the layers add to.

    Attributes
    ----------
    axis : {"altitude", "downrange"}
        ``altitude``: height above sea level [m] (the layers of a met message); ``downrange``:
        distance x from the gun [m].
    edges : tuple of float, m
        K + 1 strictly increasing edges (K <= :data:`WIND_LAYERS_MAX`); below the first and
        above the last the nearest layer's wind holds.
    base : WindProfile or None
        The round's wind on the same axis (the layers are what it did not state); None: calm.
    constant_cross : bool
        The cross wind is one value for all layers (``wy_1``; ``wy_2..`` are not used): beside the
        ``lift`` effect a cross wind that changes along the flight cannot be told from the spin
        drift's shape (the effect's Mach shape and spin decay are generic), so only the
        along-range wind may change.
    """

    axis: str
    edges: tuple
    base: WindProfile | None = None
    constant_cross: bool = False

    def __post_init__(self):
        e = tuple(float(v) for v in self.edges)
        if not 2 <= len(e) <= WIND_LAYERS_MAX + 1 or any(b <= a for a, b in zip(e, e[1:])):
            raise ValueError(f"wind layers need 2 to {WIND_LAYERS_MAX + 1} strictly increasing edges, got {e}")
        if self.base is not None and self.base.axis != self.axis:
            raise ValueError(f"the base wind is by {self.base.axis}, the layers by {self.axis}")
        object.__setattr__(self, "edges", e)

    @property
    def n(self):
        """Number of layers K."""
        return len(self.edges) - 1

    def profile(self, values):
        """The wind of layer values ``(wx_1, wy_1, wx_2, wy_2, ...)`` (the effect's parameter
        order; entries beyond ``2 K`` ignored) plus the base wind."""
        v = np.asarray(values, float)
        wy = np.full(self.n, v[1]) if self.constant_cross else v[1:2 * self.n:2]
        w = WindProfile.layered(self.axis, self.edges, v[0:2 * self.n:2], wy)
        return w if self.base is None else w.plus(self.base)

    def profiles(self, values):
        """``[self.profile(v) for v in values]`` for rows ``values`` (P, >= 2 K), made at once."""
        v = np.asarray(values, float)
        if self.base is not None or v.shape[0] < 2:
            return [self.profile(r) for r in v]
        wy = np.repeat(v[:, 1:2], self.n, axis=1) if self.constant_cross else v[:, 1:2 * self.n:2]
        return WindProfile.layered_many(self.axis, self.edges, v[:, 0:2 * self.n:2], wy)


class WindProfileModel:
    """A point-mass model flying ``layers`` (:class:`WindLayers`) with the layer winds read per
    trajectory from the kernel inputs' ``(WIND_PROFILE_KEY, i)`` entries (the ``wind_profile``
    effect; missing ones are 0). Everything else is the wrapped model's (it may itself be a
    :class:`DragShapeModel`).

    Parameters
    ----------
    model : PointMassModel or DragShapeModel
    layers : WindLayers
    """

    def __init__(self, model, layers):
        self.model = model
        self.layers = layers

    def __getattr__(self, name):
        return getattr(self.model, name)

    def with_(self, **changes):
        """Copy with some attributes of the wrapped model changed (the layers kept)."""
        return WindProfileModel(self.model.with_(**changes), self.layers)

    def simulate_batch(self, drag_params, state0, t_out, *, overrides=None, **kw):
        """As :meth:`PointMassModel.simulate_batch`; ``overrides`` may hold the layer winds under
        ``(WIND_PROFILE_KEY, i)``."""
        ov = dict(overrides or {})
        keys = [k for k in ov if isinstance(k, tuple) and k[0] == WIND_PROFILE_KEY]
        B = max(np.atleast_2d(np.asarray(state0, float)).shape[0], np.atleast_2d(drag_params).shape[0])
        vals = np.zeros((B, 2 * WIND_LAYERS_MAX))
        for k in keys:
            vals[:, k[1]] = ov.pop(k)          # one value per trajectory, or one for all
        # one profile per distinct row (bytewise: a dictionary, where np.unique's sort of rows
        # cost as much as building the profiles)
        first = {}
        for b, r in enumerate(vals):
            first.setdefault(r.tobytes(), b)
        made = dict(zip(first, self.layers.profiles(vals[list(first.values())])))
        winds = [made[r.tobytes()] for r in vals]
        return self.model.simulate_batch(drag_params, state0, t_out, overrides=ov or None, winds=winds, **kw)


def wind_profile_free(ctx, name):
    """Is ``wind_profile``'s parameter ``name`` (``wx_3``) used on this track? (The layers set
    how many there are, and whether the cross wind is one value; the rest are held at 0.)"""
    lay = ctx.wind_layers
    if lay is None:
        return False
    k = int(name.rsplit("_", 1)[1])
    return k <= lay.n and not (lay.constant_cross and k > 1 and name.split(".")[-1].startswith("wy"))


def path_layers(axis, x, z, gun_altitude, base_wind=None, n=PROFILE_LAYERS, edges=None):
    """The ``wind_profile`` layers laid over a flight's path: ``n`` equal layers over the flown
    range of the coordinate (height from the gun to the apex, or downrange distance from the gun
    to the last point), the round's own wind carried onto that axis as their base.

    Parameters
    ----------
    axis : {"altitude", "downrange"}
    x, z : (N,) arrays or None, m
        Downrange distance and height above the gun along the path (None: not known).
    gun_altitude : float, m
        Height of the gun above sea level (altitude layers are above sea level).
    base_wind : WindProfile or None
        The round's wind (on either axis); None: calm.
    n : int
        Number of layers (without ``edges``).
    edges : sequence of float, optional
        Layer edges already chosen (the diagnosis's): used as given.

    Returns
    -------
    WindLayers or None when the coordinate has no span (no path along it).
    """
    h_gun = float(gun_altitude)
    if edges is None:
        if axis == "altitude":
            lo, hi = h_gun, h_gun + float(np.nanmax(z)) if z is not None else None
        else:
            lo, hi = 0.0, float(np.nanmax(x)) if x is not None else None
        if hi is None or not hi > lo + n * EDGE_ROUND:
            return None
        edges = equal_edges(lo, hi, n)
        if edges is None:
            return None
    base = None
    if base_wind is not None:
        base = base_wind if base_wind.axis == axis else _mapped(base_wind, axis, x, z, h_gun)
    return WindLayers(axis, tuple(float(v) for v in edges), base)


def equal_edges(lo, hi, n):
    """``n + 1`` edges [m] of ``n`` equal layers from ``lo`` to ``hi``, the inner ones rounded to
    :data:`EDGE_ROUND`; None when rounding leaves two edges equal."""
    e = np.round(np.linspace(lo, hi, n + 1) / EDGE_ROUND) * EDGE_ROUND
    e[0], e[-1] = lo, hi
    if np.any(np.diff(e) <= 0):
        return None
    return tuple(float(v) for v in e)


def _mapped(wind, axis, x, z, h_gun):
    """The round's wind by one coordinate carried onto the other along a path (downrange x is
    single-valued along a flight; height is not, so a wind by downrange distance becomes one by
    height on the ascent)."""
    if x is None or z is None:
        return None
    x, z = np.asarray(x, float), np.asarray(z, float)
    if axis == "downrange":
        order = np.argsort(x)
        s = np.linspace(0.0, float(np.max(x)), 200)
        w = wind.at(np.interp(s, x[order], z[order]) + h_gun)
    else:
        top = int(np.argmax(z))
        s = np.linspace(h_gun, h_gun + float(z[top]), 200)
        w = wind.at(np.interp(s - h_gun, z[:top + 1], x[:top + 1]))
    return WindProfile(axis, tuple(s), tuple(w[:, 0]), tuple(w[:, 1]))
