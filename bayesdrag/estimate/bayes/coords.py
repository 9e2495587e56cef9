"""Sampling coordinates in which the air and shell sources decouple from a spline Cd(M).

A radar track determines the drag *force*, i.e. the product ``rho * Kref * Cd(v / a)`` along the
flight, far better than it determines each factor. When the round declares the air density, the
temperature, the mass or the diameter as uncertain (``bayesdrag.estimate.build.sources``) the
posterior of the spline coefficients ``c`` and those sources is a thin curved ridge: a density
ratio ``r`` is only known through ``r * c`` (a bilinear coupling) and a temperature offset
``dT`` moves every data point along the Mach axis (``M = M0 * sqrt(T / (T + dT))``), so the
coefficients that fit the track change with ``dT`` through the slope of Cd(M), which itself
depends on the coefficients. A Gaussian (Laplace) proposal then misses the ridge, although
every single direction of it is close to the true curvature (docs/measurements.md, "Sampling
coordinates").

:class:`DriftCoordinates` samples instead the coefficients ``c~`` of the *identified* curve: with
``psi(M, dT) = rho(z, 0) / rho(z, dT)`` and ``k(M, dT) = a(z, dT) / a(z, 0)`` the density and
sound-speed changes of a temperature offset at the height ``z(M)`` where the flight passes Mach
``M`` (from the fit's trajectory and the round's atmosphere, so a track whose transonic part
flies high gets that height's temperature),

    Cd(M) = psi(M, dT) / f * g(k(M, dT) M),   f = r (d / d0)^2 (m0 / m),   g(M) = sum c~_j B_j(M)

expanded to second order in ``dT``: ``c = (I + dT A1 + dT^2 / 2 A2) c~ / f`` with ``A1``, ``A2``
the least-squares projections onto the spline basis ``B`` of the Taylor terms of
``psi B(k M)`` (``B'``, ``B''`` the basis derivatives). The map is a smooth bijection for any
offset a round can declare; the posterior density in the new coordinates carries the log
Jacobian ``log|det(I + dT A1 + dT^2 / 2 A2)| - P log f``, so the target is exactly the same
posterior whatever the quality of the approximation; only the sampler's efficiency depends on
it. Reported draws are mapped back to ``c`` (:meth:`DriftCoordinates.to_theta`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

#: parameter names of the sources the map uses (``bayesdrag.estimate.build.sources.SOURCE_PARAMS``)
DENSITY, TEMPERATURE, MASS, DIAMETER = "density.ratio", "temperature.dT", "mass", "diameter"
#: Mach points per knot interval of the projection grid
GRID_PER_INTERVAL = 12
#: smallest singular value the temperature matrix may reach inside its ``dT_range`` (the Taylor
#: terms grow with dT until the map from c~ back to c is no longer invertible)
MIN_SINGULAR = 0.5
#: offsets scanned per side of 0 for that range, up to RANGE_MAX_K [K]
RANGE_STEPS = 40
RANGE_MAX_K = 10.0


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
        First- [1/K] and second-order [1/K^2] temperature matrices.
    m0, d0 : float
        Nominal mass [kg] and diameter [m].
    dT_range : (float, float)
        Offsets [K] between which the temperature term follows dT; beyond, it is held at the
        nearer end (:data:`MIN_SINGULAR` keeps the matrix well conditioned there, so the map
        stays a bijection over the whole support: for each dT, ``c~ -> c`` is invertible and
        the Jacobian is block triangular).
    """

    drag: np.ndarray
    pos: dict
    A1: np.ndarray
    A2: np.ndarray
    m0: float
    d0: float
    dT_range: tuple = (0.0, 0.0)

    # ------------------------------------------------------------------------------------
    def _factors(self, T):
        """``(f, dT)`` (each (W,)) of free-parameter vectors ``T`` (W, n)."""
        W = T.shape[0]
        f = np.ones(W)
        dT = np.zeros(W)
        p = self.pos
        if DENSITY in p:
            f = f * T[:, p[DENSITY]]
        if TEMPERATURE in p:
            dT = np.clip(T[:, p[TEMPERATURE]], *self.dT_range)
        if DIAMETER in p:
            f = f * (T[:, p[DIAMETER]] / self.d0) ** 2
        if MASS in p:
            f = f * self.m0 / T[:, p[MASS]]
        return f, dT

    def _matrix(self, delta):
        """(W, P, P) ``I + dT A1 + dT^2 / 2 A2`` of offsets ``delta`` (W,) [K]."""
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


def drift_coordinates(problem, idx, theta, *, mass=None, diameter=None):
    """The :class:`DriftCoordinates` of a posterior, or ``None`` where they do not apply.

    They apply when the drag model is linear in its coefficients with a spline basis (it has
    ``basis``, ``basis_slope`` and ``knots``; a table scaled by one factor has no shape to
    stretch), all its coefficients are free, and at least one of the density, temperature, mass
    or diameter sources is a free parameter.

    Parameters
    ----------
    problem : OutputErrorProblem
        Its ``names``, ``P``, ``model`` (``drag``, ``atmosphere``), ``channels`` and ``predict``.
    idx : (n,) ndarray of int
        Indices of the free parameters in the problem's full vector.
    theta : (n_full,) ndarray
        The full parameter vector whose trajectory gives the height at each Mach number.
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
    if not set(range(P)) <= set(np.asarray(idx).tolist()):
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
    pinv = np.linalg.pinv(B)
    A1 = A2 = np.zeros((P, P))
    try:
        air = air_derivatives(problem.model.atmosphere, height_at_mach(problem, theta, grid))
    except (AttributeError, TypeError, ValueError):   # no atmosphere model to differentiate
        air = None
    if TEMPERATURE in pos and air is not None:
        psi1, psi2, k1, k2 = air
        B1 = grid[:, None] * drag.basis_slope(grid)
        B2 = (grid ** 2)[:, None] * (drag.basis_curvature(grid) if hasattr(drag, "basis_curvature")
                                     else np.zeros_like(B))
        A1 = pinv @ (psi1[:, None] * B + k1[:, None] * B1)
        A2 = pinv @ (psi2[:, None] * B + k2[:, None] * B1 + (k1 ** 2)[:, None] * B2
                     + (2 * psi1 * k1)[:, None] * B1)
    dT_range = (0.0, 0.0)
    if TEMPERATURE in pos:
        j = int(np.asarray(idx)[pos[TEMPERATURE]])
        dT_range = (_conditioned_end(A1, A2, float(problem.lower[j])),
                    _conditioned_end(A1, A2, float(problem.upper[j])))
    drag_pos = np.array([free_names.index(problem.names[j]) for j in range(P)])
    return DriftCoordinates(drag_pos, pos, A1, A2, float(mass or 1.0), float(diameter or 1.0), dT_range)


def _conditioned_end(A1, A2, bound):
    """The offset [K] towards ``bound`` up to which ``I + dT A1 + dT^2 / 2 A2`` keeps its
    singular values >= :data:`MIN_SINGULAR` (0 if none)."""
    if not np.isfinite(bound) or bound == 0.0:
        return 0.0
    end = 0.0
    eye = np.eye(A1.shape[0])
    for d in np.linspace(0.0, float(np.clip(bound, -RANGE_MAX_K, RANGE_MAX_K)), RANGE_STEPS + 1)[1:]:
        if np.linalg.svd(eye + d * A1 + 0.5 * d * d * A2, compute_uv=False).min() < MIN_SINGULAR:
            break
        end = float(d)
    return end


def height_at_mach(problem, theta, mach):
    """Height above the gun [m] (M,) where the trajectory of ``theta`` flies Mach ``mach`` (M,).

    Interpolated in the samples sorted by Mach (a flight that passes a Mach number twice gets
    one of the heights; outside its span the nearest end's). 0 when the problem has no ``z``.
    """
    y, m = problem.predict(np.asarray(theta, float)[None])
    m = np.asarray(m[0], float)
    if "z" not in problem.channels:
        return np.zeros_like(np.asarray(mach, float))
    z = np.asarray(y[0, :, problem.channels.index("z")], float)
    ok = np.isfinite(m) & np.isfinite(z)
    if not ok.any():
        return np.zeros_like(np.asarray(mach, float))
    order = np.argsort(m[ok])
    return np.interp(mach, m[ok][order], z[ok][order])


#: temperature step [K] of the air derivatives
AIR_STEP_K = 1.0


def air_derivatives(atm, z):
    """First and second derivatives in a temperature offset [1/K, 1/K^2] of the density factor
    ``psi = rho(z, 0) / rho(z, dT)`` and the sound-speed ratio ``k = a(z, dT) / a(z, 0)``.

    Parameters
    ----------
    atm : Atmosphere or MetProfile
        Anything with ``temperature_offset`` (a dataclass field) and ``at_height``.
    z : (M,) ndarray
        Heights above the gun [m].

    Returns
    -------
    psi1, psi2, k1, k2 : (M,) ndarray
    """
    h = AIR_STEP_K
    s = [atm.at_height(z) if d == 0 else replace(atm, temperature_offset=atm.temperature_offset + d).at_height(z)
         for d in (-h, 0.0, h)]
    rho = [np.asarray(a.density, float) for a in s]
    snd = [np.asarray(a.speed_of_sound, float) for a in s]
    psi = [rho[1] / r for r in rho]
    k = [a / snd[1] for a in snd]
    return ((psi[2] - psi[0]) / (2 * h), (psi[2] - 2 * psi[1] + psi[0]) / h ** 2,
            (k[2] - k[0]) / (2 * h), (k[2] - 2 * k[1] + k[0]) / h ** 2)
