"""Sampling coordinates in which the air and shell sources decouple from a spline Cd(M).

A radar track determines the drag *force*, i.e. the product ``rho * Kref * Cd(v / a)`` along the
flight, far better than it determines each factor. When the round declares the air density, the
temperature, the mass or the diameter as uncertain (``bayesdrag.estimate.systematics``) the
posterior of the spline coefficients ``c`` and those sources is a thin curved ridge: a density
ratio ``r`` is only known through ``r * c`` (a bilinear coupling) and a temperature offset
``dT`` moves every data point along the Mach axis (``M = M0 * sqrt(T / (T + dT))``), so the
coefficients that fit the track change with ``dT`` through the slope of Cd(M), which itself
depends on the coefficients. A Gaussian (Laplace) proposal then misses the ridge: measured on a
py-ballisticcalc track with ``density_sd = 0.002`` and ``temperature_sd = 0.5``, the log
importance weights of the independence proposal had a standard deviation of 83 (an effective
sample fraction of 4 %, acceptance ~0.1), although every single direction of the Laplace
approximation was within 30 % of the true curvature.

:class:`DriftCoordinates` samples instead the coefficients of the *identified* curve

    g(M0) = f * Cd(M0 * k),   f = r * T / (T + dT) * (d / d0)^2 * (m0 / m),   k = sqrt((T + dT) / T)

on the nominal Mach axis ``M0`` (``T`` the air temperature at the track's mean height): ``c~``
with ``c = (I + delta A1 + delta^2 / 2 A2) c~ / f``, ``delta = k - 1``, where ``A1`` and ``A2``
are the least-squares projections of ``M B'(M)`` and ``M^2 B''(M)`` onto the spline basis
``B`` (the first terms of the Taylor series of ``B(k M)`` in ``k``). The map is a smooth
bijection for any ``|delta| << 1``; the posterior density in the new coordinates carries the log
Jacobian ``log|det(I + delta A1 + delta^2 / 2 A2)| - P log f``, so the target is exactly the
same posterior whatever the quality of the approximation; only the sampler's efficiency depends
on it. Reported draws are mapped back to ``c`` (:meth:`DriftCoordinates.to_theta`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: parameter names of the sources the map uses (``bayesdrag.estimate.systematics.SOURCE_PARAMS``)
DENSITY, TEMPERATURE, MASS, DIAMETER = "density.ratio", "temperature.dT", "mass", "diameter"
#: Mach points per knot interval of the projection grid
GRID_PER_INTERVAL = 12


@dataclass(frozen=True, eq=False)
class DriftCoordinates:
    """The coordinate map of the module docstring on the free-parameter block of a posterior.

    Attributes
    ----------
    drag : (P,) ndarray of int
        Positions of the spline coefficients in the free-parameter vector.
    pos : dict name -> int
        Positions of the sources present (density ratio, temperature offset [K], mass [kg],
        diameter [m]) in the free-parameter vector.
    A1, A2 : (P, P) ndarray
        First- and second-order stretch matrices.
    T_ref : float
        Air temperature [K] at the track's mean height.
    m0, d0 : float
        Nominal mass [kg] and diameter [m].
    """

    drag: np.ndarray
    pos: dict
    A1: np.ndarray
    A2: np.ndarray
    T_ref: float
    m0: float
    d0: float

    # ------------------------------------------------------------------------------------
    def _factors(self, T):
        """``(f, delta)`` (each (W,)) of free-parameter vectors ``T`` (W, n)."""
        W = T.shape[0]
        f = np.ones(W)
        delta = np.zeros(W)
        p = self.pos
        if DENSITY in p:
            f = f * T[:, p[DENSITY]]
        if TEMPERATURE in p:
            dT = T[:, p[TEMPERATURE]]
            ratio = (self.T_ref + dT) / self.T_ref
            f = f / ratio
            delta = np.sqrt(np.maximum(ratio, 1e-6)) - 1.0
        if DIAMETER in p:
            f = f * (T[:, p[DIAMETER]] / self.d0) ** 2
        if MASS in p:
            f = f * self.m0 / T[:, p[MASS]]
        return f, delta

    def _matrix(self, delta):
        """(W, P, P) ``I + delta A1 + delta^2 / 2 A2``."""
        P = self.A1.shape[0]
        d = delta[:, None, None]
        return np.eye(P)[None] + d * self.A1[None] + 0.5 * d * d * self.A2[None]

    def to_theta(self, X):
        """Free-parameter vectors (W, n) of sampled coordinates ``X`` (W, n)."""
        X = np.atleast_2d(np.asarray(X, float))
        T = X.copy()
        f, delta = self._factors(X)
        ct = X[:, self.drag]
        c = ct + delta[:, None] * (ct @ self.A1.T) + 0.5 * (delta ** 2)[:, None] * (ct @ self.A2.T)
        T[:, self.drag] = c / f[:, None]
        return T

    def from_theta(self, T):
        """Sampled coordinates (W, n) of free-parameter vectors ``T`` (W, n) (inverse map)."""
        T = np.atleast_2d(np.asarray(T, float))
        X = T.copy()
        f, delta = self._factors(T)
        rhs = (T[:, self.drag] * f[:, None])[..., None]
        X[:, self.drag] = np.linalg.solve(self._matrix(delta), rhs)[..., 0]
        return X

    def log_jacobian(self, X):
        """``log |d theta / d X|`` (W,) of sampled coordinates ``X`` (W, n)."""
        X = np.atleast_2d(np.asarray(X, float))
        f, delta = self._factors(X)
        P = self.drag.size
        _, logdet = np.linalg.slogdet(self._matrix(delta))
        with np.errstate(divide="ignore", invalid="ignore"):
            return logdet - P * np.log(np.abs(f))

    def jacobian(self, X, step=1e-7):
        """``d theta / d X`` (n, n) at one point ``X`` (n,) (central differences)."""
        X = np.asarray(X, float)
        n = X.size
        J = np.empty((n, n))
        for j in range(n):
            h = step * max(1.0, abs(X[j]))
            e = np.zeros(n)
            e[j] = h
            J[:, j] = (self.to_theta(X + e)[0] - self.to_theta(X - e)[0]) / (2 * h)
        return J


def drift_coordinates(problem, idx, *, mass=None, diameter=None):
    """The :class:`DriftCoordinates` of a posterior, or ``None`` where they do not apply.

    They apply when the drag model is linear in its coefficients with a spline basis (it has
    ``basis`` and ``basis_slope``; a table scaled by one factor has no shape to stretch), all its
    coefficients are free, and at least one of the density, temperature, mass or diameter
    sources is a free parameter.

    Parameters
    ----------
    problem : OutputErrorProblem
        Its ``names``, ``P``, ``model`` (``drag``, ``atmosphere``) and ``track``.
    idx : (n,) ndarray of int
        Indices of the free parameters in the problem's full vector.
    mass, diameter : float, keyword-only
        Nominal mass [kg] and diameter [m] (needed only when those sources are free).

    Returns
    -------
    DriftCoordinates or None
    """
    drag = problem.model.drag
    if not (hasattr(drag, "basis") and hasattr(drag, "basis_slope") and hasattr(drag, "knots")):
        return None
    free_names = [problem.names[j] for j in idx]
    P = problem.P
    if not all(j in set(idx.tolist()) for j in range(P)):
        return None
    pos = {n: free_names.index(n) for n in (DENSITY, TEMPERATURE, MASS, DIAMETER) if n in free_names}
    if not mass:
        pos.pop(MASS, None)
    if not diameter:
        pos.pop(DIAMETER, None)
    if not pos:
        return None
    knots = np.unique(np.asarray(drag.knots, float))
    grid = np.concatenate([np.linspace(a, b, GRID_PER_INTERVAL, endpoint=False)
                           for a, b in zip(knots[:-1], knots[1:])] + [knots[-1:]])
    B = drag.basis(grid)
    B1 = drag.basis_slope(grid)
    B2 = drag.basis_curvature(grid) if hasattr(drag, "basis_curvature") else np.zeros_like(B)
    pinv = np.linalg.pinv(B)
    A1 = pinv @ (grid[:, None] * B1)
    A2 = pinv @ ((grid ** 2)[:, None] * B2)
    T_ref = 288.15
    try:
        z = problem.track.channels.get("z")
        zbar = float(np.nanmean(z)) if z is not None else 0.0
        T_ref = float(problem.model.atmosphere.at_height(zbar).temperature)
    except Exception:  # noqa: BLE001 - any atmosphere without at_height: sea-level ICAO
        pass
    drag_pos = np.array([free_names.index(problem.names[j]) for j in range(P)])
    return DriftCoordinates(drag_pos, pos, A1, A2, T_ref, float(mass or 1.0), float(diameter or 1.0))
