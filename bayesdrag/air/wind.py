"""Winds that change along the flight: :class:`WindProfile`, horizontal wind by height above sea
level (met practice: a met file's levels, a METCM message's zones) or by downrange distance from
the gun (how small-arms tools and py-ballisticcalc give winds by zone). Linear between its levels,
a step where a level repeats (spread over :data:`WIND_STEP_WIDTH`), constant beyond its ends.
The atmospheres carry one (:attr:`bayesdrag.air.atmosphere.Atmosphere.wind`); the point-mass kernel,
its scipy reference and the 6-DOF fly it.
"""
from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np

from ..validate import float_tuple as _float_tuple

__all__ = ["WindProfile", "WIND_AXES", "WIND_STEP_WIDTH", "PROFILE_WIND_MAX"]

#: largest plausible wind component [m/s] (jet-stream cores reach ~100 m/s)
PROFILE_WIND_MAX = 150.0

#: the coordinates a wind profile can change along: geometric height above mean sea level [m]
#: (met practice) or downrange distance x from the gun along the firing azimuth [m]
WIND_AXES = ("altitude", "downrange")
#: width [m] over which a step of a wind profile turns from the lower wind to the upper (a cubic
#: smoothstep centred on the level, at most half of either neighbouring layer): winds do not
#: jump, and a jump is what a fixed-step integrator cannot cross accurately (an exact step put
#: the RK4 kernel 5-27 cm off the scipy reference on a 155 mm flight, depending on where its
#: steps fell; 100 m: 1 mm, docs/real_data.md)
WIND_STEP_WIDTH = 100.0


@dataclass(frozen=True)
class WindProfile:
    """Horizontal wind that changes along one coordinate of the flight.

    The wind is linear in the coordinate between consecutive levels and constant beyond the
    first and the last. A level may appear twice in a row: the wind steps there (the first of
    the two rows holds below the level, the second above it), which is how layers of constant
    wind (a METCM message's zones, the ``wind_profile`` effect's layers) are written. A step is
    spread over :data:`WIND_STEP_WIDTH` centred on its level (a cubic smoothstep between the two
    sides' linear pieces, at most half of either neighbouring layer wide), for the kernel and
    the scipy reference alike.

    Attributes
    ----------
    axis : {"altitude", "downrange"}
        ``altitude``: geometric height above mean sea level [m], like a met profile's levels;
        ``downrange``: distance x [m] from the gun along the firing azimuth (track frame).
    levels : tuple of float, m
        Non-decreasing; a value repeats at most once and not at either end.
    wind_x, wind_y : tuple of float, m/s
        Wind at each level in the track frame (x downrange, y right): ``wind_x`` > 0 a
        tailwind, ``wind_y`` > 0 blowing toward +y. At most :data:`PROFILE_WIND_MAX` in size.

    Raises
    ------
    ValueError
        Unknown axis, lengths that differ, levels out of order, a level repeated more than once or
        at an end, a non-finite or implausible wind.

    Examples
    --------
    >>> w = WindProfile.layered("altitude", (0.0, 1000.0, 3000.0), (2.0, -4.0), (0.0, 1.0))
    >>> w.at([500.0, 1000.0, 2000.0]).tolist()
    [[2.0, 0.0], [-1.0, 0.5], [-4.0, 1.0]]
    """

    axis: str
    levels: tuple
    wind_x: tuple
    wind_y: tuple

    def __post_init__(self):
        if self.axis not in WIND_AXES:
            raise ValueError(f"wind profile axis {self.axis!r} is not allowed; use one of {', '.join(WIND_AXES)}")
        lv, wx, wy = _checked_values(self.levels, self.wind_x, self.wind_y)
        if not (len(lv) == len(wx) == len(wy)) or not lv:
            raise ValueError(f"a wind profile needs one wind_x and wind_y per level; got {len(lv)} levels, "
                             f"{len(wx)} wind_x, {len(wy)} wind_y")
        L = np.array(lv)
        d = np.diff(L)
        if (d < 0).any():
            i = int(np.argmax(d < 0)) + 1
            raise ValueError(f"wind level {lv[i]:g} m is below the previous level {lv[i - 1]:g} m; levels must "
                             f"be sorted by increasing {self.axis}")
        rep = np.flatnonzero(d == 0)
        if rep.size and (rep[0] == 0 or rep[-1] == len(lv) - 2 or (np.diff(rep) == 1).any()):
            i = int(rep[0])
            raise ValueError(f"wind level {lv[i]:g} m repeats more than once or at an end; a level may repeat "
                             f"once inside the profile (a step in the wind)")
        w = np.column_stack([wx, wy])
        if (np.abs(w) > PROFILE_WIND_MAX).any():
            for j, (name, comp) in enumerate((("wind_x", wx), ("wind_y", wy))):
                wa = np.abs(w[:, j])
                if (wa > PROFILE_WIND_MAX).any():
                    i = int(np.argmax(wa > PROFILE_WIND_MAX))
                    raise ValueError(f"{name} = {comp[i]:g} m/s at {self.axis} {lv[i]:g} m exceeds the plausible "
                                     f"{PROFILE_WIND_MAX:g} m/s (knots or km/h? the unit is m/s)")
        object.__setattr__(self, "levels", lv)
        object.__setattr__(self, "wind_x", wx)
        object.__setattr__(self, "wind_y", wy)
        # each step: (level, half width, left value, left slope, right value, right slope) per
        # component, all steps at once (a fit builds a profile per perturbed trajectory)
        steps, rows = (), (np.zeros((0, 2)),) * 4
        if rep.size:
            v = L[rep]
            hw = np.minimum(np.minimum(0.5 * WIND_STEP_WIDTH, 0.5 * (v - L[rep - 1])), 0.5 * (L[rep + 2] - v))
            left = (w[rep] - w[rep - 1]) / (v - L[rep - 1])[:, None]
            right = (w[rep + 2] - w[rep + 1]) / (L[rep + 2] - v)[:, None]
            rows = (w[rep], left, w[rep + 1], right)
            steps = tuple(zip(v.tolist(), hw.tolist(), *rows))
        object.__setattr__(self, "_steps", steps)
        object.__setattr__(self, "_step_rows", rows)      # the same as (S, 2) arrays

    @classmethod
    def layered(cls, axis, edges, wind_x, wind_y):
        """Layers of constant wind: layer k spans ``[edges[k], edges[k + 1])`` with
        ``(wind_x[k], wind_y[k])``; below the first edge the first layer's wind holds, above the
        last the last layer's.

        Parameters
        ----------
        axis : {"altitude", "downrange"}
        edges : (K + 1,) strictly increasing, m
        wind_x, wind_y : (K,) m/s
        """
        e = np.asarray(edges, float)
        wx, wy = np.asarray(wind_x, float).reshape(-1), np.asarray(wind_y, float).reshape(-1)
        K = e.size - 1
        if K < 1 or wx.size != K or wy.size != K or np.any(np.diff(e) <= 0):
            raise ValueError(f"layers need K + 1 strictly increasing edges and K winds; got {e.size} edges, "
                             f"{wx.size} wind_x, {wy.size} wind_y")
        lv = np.repeat(e, 2)[1:-1]               # e0, e1, e1, e2, e2, ..., eK
        w = np.column_stack([wx, wy])            # (K, 2): each layer's wind
        if (axis not in WIND_AXES or not np.isfinite(e).all() or not np.isfinite(w).all()
                or np.abs(w).max() > PROFILE_WIND_MAX):
            return cls(axis, tuple(lv), tuple(np.repeat(wx, 2)), tuple(np.repeat(wy, 2)))  # names what is wrong
        # valid by construction: the checks of __post_init__ are skipped and what depends on the
        # edges alone is memoised (a fit builds a profile per trajectory). Its step rows are those
        # __post_init__ computes: inside a layer the wind is constant, so both slopes are 0.0
        levels, v, hw, zero = _layer_steps(e.tobytes())
        prof = object.__new__(cls)
        for name, value in (("axis", axis), ("levels", levels), ("wind_x", tuple(np.repeat(wx, 2).tolist())),
                            ("wind_y", tuple(np.repeat(wy, 2).tolist()))):
            object.__setattr__(prof, name, value)
        rows = (w[:-1], zero, w[1:], zero)
        object.__setattr__(prof, "_steps", tuple(zip(v, hw, *rows)))
        object.__setattr__(prof, "_step_rows", rows)
        return prof

    @classmethod
    def layered_many(cls, axis, edges, wind_x, wind_y):
        """``[layered(axis, edges, wind_x[p], wind_y[p]) for p in range(P)]``, the same profiles
        made at once (a fit's perturbed trajectories each fly their own).

        Parameters
        ----------
        axis : {"altitude", "downrange"}
        edges : (K + 1,) strictly increasing, m
        wind_x, wind_y : (P, K) m/s
        """
        e = np.asarray(edges, float)
        wx, wy = np.asarray(wind_x, float), np.asarray(wind_y, float)
        K = e.size - 1
        w = np.stack([wx, wy], axis=-1) if wx.ndim == 2 and wx.shape == wy.shape else None
        if (w is None or w.shape[1] != K or K < 1 or axis not in WIND_AXES or np.any(np.diff(e) <= 0)
                or not np.isfinite(e).all() or not np.isfinite(w).all()
                or np.abs(w).max(initial=0.0) > PROFILE_WIND_MAX):
            return [cls.layered(axis, e, a, b) for a, b in zip(wx, wy)]   # names what is wrong
        levels, v, hw, zero = _layer_steps(e.tobytes())
        rx, ry = np.repeat(wx, 2, axis=1).tolist(), np.repeat(wy, 2, axis=1).tolist()
        out = []
        for p in range(w.shape[0]):
            prof = object.__new__(cls)
            for name, value in (("axis", axis), ("levels", levels), ("wind_x", tuple(rx[p])),
                                ("wind_y", tuple(ry[p]))):
                object.__setattr__(prof, name, value)
            wp = w[p]
            object.__setattr__(prof, "_step_places", (v, hw))      # _steps made when first read
            object.__setattr__(prof, "_step_rows", (wp[:-1], zero, wp[1:], zero))
            out.append(prof)
        return out

    @cached_property
    def _steps(self):
        """Each step's ``(level, half width, left value, left slope, right value, right slope)``
        (set by ``__post_init__`` and :meth:`layered`; made here for :meth:`layered_many`'s
        profiles, which the kernel tabulates without reading them)."""
        return tuple(zip(*self._step_places, *self._step_rows))

    @property
    def n_layers(self):
        """Number of steps plus one when the profile is layered (every other level repeats)."""
        return int(np.count_nonzero(np.diff(self.levels) == 0)) + 1

    def at(self, s):
        """Wind (wx, wy) [m/s] at coordinates ``s`` [m] (height above sea level or downrange
        distance, by :attr:`axis`), shape ``s.shape + (2,)``."""
        s = np.asarray(s, dtype=float)
        w = np.column_stack([self.wind_x, self.wind_y])
        if len(self.levels) == 1:
            return np.broadcast_to(w[0], s.shape + (2,)).copy()
        k, k1, f, near, joint = _placement(self.levels, tuple(st[:2] for st in self._steps), s.shape, s.tobytes())
        wk = w.take(k, axis=0)
        out = wk + f[..., None] * (w.take(k1, axis=0) - wk)
        if joint is not None:           # every step's coordinates at once, each with its step's row
            at, which, d, g = joint
            if which.size:
                wl, sl, wr, sr = (a.take(which, axis=0) for a in self._step_rows)
                lo, hi = wl + d[:, None] * sl, wr + d[:, None] * sr
                out[at] = lo + g * (hi - lo)
            return out
        for (v, hw, wl, sl, wr, sr), (at, d, g) in zip(self._steps, near):
            if at is not None:
                lo, hi = wl + d[:, None] * sl, wr + d[:, None] * sr
                out[at] = lo + g * (hi - lo)
        return out

    def at_scalar(self, s):
        """:meth:`at` for one coordinate [m], as two floats (the scipy reference's fast path)."""
        lv = self.levels
        n = len(lv)
        if n == 1 or s <= lv[0]:
            return self.wind_x[0], self.wind_y[0]
        if s >= lv[-1]:
            return self.wind_x[-1], self.wind_y[-1]
        for v, hw, wl, sl, wr, sr in self._steps:
            d = s - v
            if -hw < d < hw:
                u = (d + hw) / (2.0 * hw)
                g = u * u * (3.0 - 2.0 * u)
                lo0, lo1 = wl[0] + d * sl[0], wl[1] + d * sl[1]
                return lo0 + g * (wr[0] + d * sr[0] - lo0), lo1 + g * (wr[1] + d * sr[1] - lo1)
        k = min(bisect_right(lv, s) - 1, n - 2)
        f = (s - lv[k]) / (lv[k + 1] - lv[k])
        return (self.wind_x[k] + f * (self.wind_x[k + 1] - self.wind_x[k]),
                self.wind_y[k] + f * (self.wind_y[k + 1] - self.wind_y[k]))

    def at_level(self, s):
        """The wind at ``s`` [m] from the levels alone (linear between them, a step exactly at a
        repeated level, the upper side there), without the smoothing of steps: the value a file
        row at ``s`` must hold for the file to define this profile."""
        lv = self.levels
        if len(lv) == 1 or s <= lv[0]:
            return self.wind_x[0], self.wind_y[0]
        if s >= lv[-1]:
            return self.wind_x[-1], self.wind_y[-1]
        k = min(bisect_right(lv, s) - 1, len(lv) - 2)
        f = (s - lv[k]) / (lv[k + 1] - lv[k]) if lv[k + 1] > lv[k] else 0.0
        return (self.wind_x[k] + f * (self.wind_x[k + 1] - self.wind_x[k]),
                self.wind_y[k] + f * (self.wind_y[k + 1] - self.wind_y[k]))

    def plus(self, other):
        """The sum of two profiles along the same axis (levels merged; a step of either is a
        step of the sum)."""
        if other.axis != self.axis:
            raise ValueError(f"cannot add a wind by {other.axis} to a wind by {self.axis}")
        return _sum_profiles(self, other)


def tables_at(profiles, s):
    """``np.stack([p.at(s) for p in profiles])`` for profiles that share their axis, levels and
    steps (:func:`same_shape`), computed at once by the same operations: (P, n, 2) [m/s].

    Parameters
    ----------
    profiles : sequence of WindProfile, length P >= 1
    s : (n,) ndarray
        Coordinates [m] (1-D).
    """
    p0 = profiles[0]
    s = np.asarray(s, dtype=float)
    w = np.stack([np.array([p.wind_x for p in profiles]), np.array([p.wind_y for p in profiles])], axis=-1)
    if len(p0.levels) == 1:
        return np.broadcast_to(w[:, :1], (w.shape[0],) + s.shape + (2,)).copy()
    k, k1, f, near, joint = _placement(p0.levels, _places(p0), s.shape, s.tobytes())
    wk = w.take(k, axis=1)
    out = wk + f[..., None] * (w.take(k1, axis=1) - wk)
    at, which, d, g = joint
    if which.size:
        wl, sl, wr, sr = (np.stack([p._step_rows[j] for p in profiles]).take(which, axis=1) for j in range(4))
        lo, hi = wl + d[:, None] * sl, wr + d[:, None] * sr
        out[(slice(None),) + at] = lo + g * (hi - lo)
    return out


def same_shape(a, b):
    """Do profiles ``a`` and ``b`` share their axis and levels, and so their steps (where and
    how wide: the levels alone set them), so that :func:`tables_at` can tabulate them together?"""
    return a.axis == b.axis and a.levels == b.levels


def _places(p):
    """Each step's ``(level, half width)`` of profile ``p``, as :meth:`WindProfile.at` keys
    :func:`_placement` by them."""
    vh = p.__dict__.get("_step_places")
    return tuple(zip(*vh)) if vh is not None else tuple(st[:2] for st in p._steps)


def _checked_values(levels, wind_x, wind_y):
    """The three sequences as tuples of finite floats; a non-finite or non-numeric one raises
    the ValueError of :func:`bayesdrag.validate.float_tuple` naming it."""
    try:
        out = tuple(tuple(np.asarray(v, dtype=float).reshape(-1).tolist()) for v in (levels, wind_x, wind_y))
    except (TypeError, ValueError):
        out = None
    if out is None or not all(map(math.isfinite, out[0] + out[1] + out[2])):
        out = (_float_tuple("wind levels", levels), _float_tuple("wind_x", wind_x), _float_tuple("wind_y", wind_y))
    return out


@lru_cache(maxsize=16)
def _placement(levels, steps, shape, data):
    """Where coordinates ``data`` (the bytes of a float array of ``shape``) fall among
    ``levels``: the level below each and the one above, the fraction between them, and per
    step ``(v, hw)`` the indices of the coordinates it smooths with their offset ``d`` and
    smoothstep weight ``g`` (Nones when none), and (for an array of coordinates) the same of
    all steps joined, with each coordinate's step.
    It depends on the levels alone, not on the winds: the profiles of one fit share it
    (memoised; every array read-only)."""
    s = np.frombuffer(data, dtype=float).reshape(shape)
    lv = np.asarray(levels)
    sc = np.clip(s, lv[0], lv[-1])
    k = np.clip(np.searchsorted(lv, sc, side="right") - 1, 0, lv.size - 2)
    span = lv[k + 1] - lv[k]
    f = np.where(span > 0, (sc - lv[k]) / np.where(span > 0, span, 1.0), 0.0)
    near = []
    for v, hw in steps:
        mask = np.abs(sc - v) < hw
        if not np.any(mask):
            near.append((None, None, None))
            continue
        d = sc[mask] - v
        u = (d + hw) / (2.0 * hw)
        g = (u * u * (3.0 - 2.0 * u))[:, None]
        at = np.nonzero(mask) if mask.ndim else mask       # a 0-d coordinate keeps its mask
        for a in (at if mask.ndim else (at,)) + (d, g):
            a.setflags(write=False)
        near.append((at, d, g))
    joint = None
    if s.ndim:          # the steps' coordinates joined (no coordinate is near two steps: hw <= half a layer)
        hit = [(i, n) for i, n in enumerate(near) if n[0] is not None]
        at = tuple(np.concatenate([n[0][j] for _, n in hit]) if hit else np.zeros(0, np.intp) for j in range(s.ndim))
        which = np.concatenate([np.full(n[1].size, i) for i, n in hit]) if hit else np.zeros(0, np.intp)
        d = np.concatenate([n[1] for _, n in hit]) if hit else np.zeros(0)
        g = np.concatenate([n[2] for _, n in hit]) if hit else np.zeros((0, 1))
        for a in at + (which, d, g):
            a.setflags(write=False)
        joint = (at, which, d, g)
    k1 = k + 1
    for a in (k, k1, f):
        a.setflags(write=False)
    return k, k1, f, tuple(near), joint


@lru_cache(maxsize=64)
def _layer_steps(edges):
    """What the steps of layers with ``edges`` (the bytes of a float array) depend on: the
    levels (a tuple), each step's level and half width (lists of floats, computed as
    :meth:`WindProfile.__post_init__` computes them) and a (K - 1, 2) array of zeros (the slopes
    inside the layers). Memoised; the array is read-only."""
    L = np.repeat(np.frombuffer(edges, dtype=float), 2)[1:-1]
    rep = np.flatnonzero(np.diff(L) == 0)
    v = L[rep]
    hw = np.minimum(np.minimum(0.5 * WIND_STEP_WIDTH, 0.5 * (v - L[rep - 1])), 0.5 * (L[rep + 2] - v))
    zero = np.zeros((rep.size, 2))
    zero.setflags(write=False)
    return tuple(L.tolist()), v.tolist(), hw.tolist(), zero


def _side_value(p, v, upper):
    """Wind of profile ``p`` at level ``v`` from below (``upper`` False) or above (True)."""
    lv = p.levels
    for i in range(len(lv) - 1):
        if lv[i] == lv[i + 1] == v:
            j = i + 1 if upper else i
            return p.wind_x[j], p.wind_y[j]
    return p.at_scalar(v)


def _sum_profiles(a, b):
    lv, wx, wy = [], [], []
    for v in sorted(set(a.levels) | set(b.levels)):
        lo = [_side_value(p, v, False) for p in (a, b)]
        hi = [_side_value(p, v, True) for p in (a, b)]
        for side in ((lo, hi) if lo != hi else (lo,)):
            lv.append(v)
            wx.append(side[0][0] + side[1][0])
            wy.append(side[0][1] + side[1][1])
    return WindProfile(a.axis, tuple(lv), tuple(wx), tuple(wy))
