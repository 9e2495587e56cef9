"""Drag-coefficient models Cd(M) behind one small interface.

Every model here is *linear in its parameters*: ``Cd(M) = B(M) @ theta`` with a basis matrix
``B`` (N, P). This is true of the paper's quadratic (Eq. 18), of its sub/supersonic split, of a
B-spline and of a scaled reference table, and it makes three things cheap and exact: evaluating
many parameter sets at once, the Jacobian dCd/dtheta used by the delta method for Cramér-Rao
bands, and the tables the fast kernel integrates with (a matrix product per parameter set).

Kernel form
-----------
The batched integrator evaluates Cd(M) from a *uniform Mach grid of cubic pieces*
(:class:`MachGrid`): on cell k, ``Cd = c0 + c1 u + c2 u^2 + c3 u^3`` with ``u = M - M_k``. The
cubic of each cell is the Hermite interpolant of the model's value and slope at both cell ends,
taken from inside the cell. This is *exact* for the polynomial models, for a PCHIP reference
table whose nodes lie on the grid, and for splines whose knots lie on the grid (the spline
model puts its knots on multiples of the grid step for this reason). A jump (``poly2-split`` at
Mach 1) is represented exactly too, because each cell uses one-sided values. Outside the grid
the end values are held constant.

Models
------
``poly2``            Cd = a0 + a1 M + a2 M^2 (paper Eq. 18)
``poly2-split``      Eq. 18 separately below and above ``mach_split`` (default 1.0)
``spline``           cubic B-spline in M with given knots; coefficients c0..c{P-1}
``reference-scale``  factor x reference table
:class:`ReferenceTable`  a fixed table (no parameters), PCHIP-interpolated
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from scipy.interpolate import BSpline, PchipInterpolator

__all__ = [
    "MachGrid", "DragModel", "Poly2", "Poly2Split", "Spline", "ReferenceTable", "ReferenceScale",
    "TableSpline",
    "make_drag_model", "default_spline_knots", "DRAG_MODEL_NAMES",
]

DRAG_MODEL_NAMES = ("poly2", "poly2-split", "spline", "reference-scale")


@dataclass(frozen=True)
class MachGrid:
    """Uniform Mach grid of cubic cells used by the fast kernel.

    Attributes
    ----------
    m0 : float
        Mach number of the first node.
    dm : float
        Cell width in Mach.
    n_cells : int
        Number of cells; the grid spans [m0, m0 + n_cells*dm].
    """

    m0: float = 0.0
    dm: float = 0.01
    n_cells: int = 500

    @classmethod
    def covering(cls, mach_min, mach_max, dm=0.01, margin=0.3):
        """Grid aligned on multiples of ``dm`` covering [mach_min - margin, mach_max + margin]."""
        lo = max(0.0, np.floor((mach_min - margin) / dm) * dm)
        hi = np.ceil((mach_max + margin) / dm) * dm
        return cls(float(lo), float(dm), int(round((hi - lo) / dm)))

    @property
    def nodes(self):
        return self.m0 + self.dm * np.arange(self.n_cells + 1)


def _hermite_cells(f_left, s_left, f_right, s_right, h):
    """Cubic coefficients (.., K, 4) of the Hermite interpolant on cells of width h."""
    d = (f_right - f_left) / h
    c0 = f_left
    c1 = s_left
    c2 = (3.0 * d - 2.0 * s_left - s_right) / h
    c3 = (s_left + s_right - 2.0 * d) / h**2
    return np.stack([c0, c1, c2, c3], axis=-1)


@lru_cache(maxsize=64)
def _cached_kernel_basis(model, grid):
    kb = model._kernel_basis_uncached(grid)
    kb.setflags(write=False)
    return kb


def _one_sided(f, slope, grid):
    """Value and slope at both ends of every cell, taken from inside the cell (a hair in from
    each node, then extrapolated back to first order): exact across value or slope jumps at
    nodes (poly2-split at Mach 1, table and spline ends)."""
    nodes = grid.nodes
    eps = 1e-9 * grid.dm
    left, right = nodes[:-1] + eps, nodes[1:] - eps
    sl, sr = slope(left), slope(right)
    return f(left) - sl * eps, sl, f(right) + sr * eps, sr


class DragModel:
    """Interface of a drag model linear in its parameters.

    Subclasses define ``name``, ``param_names``, ``basis(mach)`` -> (N, P) and
    ``basis_slope(mach)`` -> (N, P), and ``bounds``.
    """

    name: str = "abstract"
    param_names: tuple = ()

    # -- to be provided by subclasses -------------------------------------------------------
    def basis(self, mach):  # pragma: no cover - abstract
        raise NotImplementedError

    def basis_slope(self, mach):  # pragma: no cover - abstract
        raise NotImplementedError

    @property
    def bounds(self):
        """(lower, upper) arrays of shape (P,) for the parameters."""
        raise NotImplementedError  # pragma: no cover

    # -- shared machinery ------------------------------------------------------------------
    @property
    def n_params(self):
        return len(self.param_names)

    def cd(self, params, mach):
        """Evaluate Cd.

        Parameters
        ----------
        params : array_like, shape (P,) or (B, P)
        mach : array_like, shape (N,) or scalar

        Returns
        -------
        ndarray, shape (N,) or (B, N) (scalar input -> shape () or (B,))
        """
        params = np.asarray(params, dtype=float)
        m = np.asarray(mach, dtype=float)
        B = self.basis(np.atleast_1d(m).ravel())
        out = params @ B.T
        if m.ndim == 0:
            return out[..., 0]
        return out.reshape(params.shape[:-1] + m.shape)

    def curve(self, params):
        """Fast scalar callable ``f(mach) -> Cd`` for fixed parameters (used by the scipy
        reference integrator, which calls it thousands of times)."""
        params = np.asarray(params, dtype=float)
        return lambda m: float(self.cd(params, m))

    def jacobian(self, mach):
        """dCd/dtheta at ``mach`` (N,): the basis matrix, shape (N, P)."""
        return self.basis(np.atleast_1d(np.asarray(mach, dtype=float)))

    def kernel_basis(self, grid: MachGrid):
        """Per-parameter cubic cell tables, shape (K, 4, P); ``table = kernel_basis @ theta``.

        Memoised per (model, grid): the estimators call it for every batch."""
        return _cached_kernel_basis(self, grid)

    def _kernel_basis_uncached(self, grid):
        fl, sl, fr, sr = _one_sided(self.basis, self.basis_slope, grid)
        coef = _hermite_cells(fl.T, sl.T, fr.T, sr.T, grid.dm)  # (P, K, 4)
        return np.ascontiguousarray(np.transpose(coef, (1, 2, 0)))

    def kernel_table(self, params, grid: MachGrid):
        """Cubic cell coefficients for the kernel.

        Parameters
        ----------
        params : array_like, shape (P,) or (B, P)
        grid : MachGrid

        Returns
        -------
        ndarray, shape (K, 4) or (B, K, 4)
        """
        params = np.asarray(params, dtype=float)
        kb = self.kernel_basis(grid)
        K, C, P = kb.shape
        # one matrix product (BLAS) instead of einsum's loops: the sampler calls this per step
        flat = params.reshape(-1, P) @ kb.reshape(K * C, P).T
        return np.ascontiguousarray(flat.reshape(params.shape[:-1] + (K, C)))

    def params_for(self, mach, cd):
        """Parameters that follow the curve ``cd(mach)`` best in relative error (least squares),
        clipped to the bounds.

        Parameters
        ----------
        mach, cd : (K,) array_like
            Points of the target curve (Cd > 0).

        Returns
        -------
        (P,) ndarray
        """
        mach = np.asarray(mach, dtype=float)
        cd = np.asarray(cd, dtype=float)
        B = self.basis(mach) / cd[:, None]
        theta, *_ = np.linalg.lstsq(B, np.ones_like(cd), rcond=None)
        lb, ub = self.bounds
        return np.clip(theta, lb, ub)

    def initial_params(self, reference=None):
        """A reasonable starting point: least squares to ``reference`` (a DragModel with no
        free parameters, or None for a generic 155 mm-like curve) over the model's own span."""
        lo, hi = self.fit_range
        m = np.linspace(lo, hi, 200)
        target = reference.cd((), m) if reference is not None else _generic_cd(m)
        theta, *_ = np.linalg.lstsq(self.basis(m), target, rcond=None)
        lb, ub = self.bounds
        return np.clip(theta, lb, ub)

    @property
    def fit_range(self):
        return (0.5, 2.5)

    def describe(self):
        return f"{self.name} ({self.n_params} parameters: {', '.join(self.param_names)})"


def _generic_cd(m):
    """A smooth artillery-like Cd(M) used only as a starting guess without a reference."""
    m = np.asarray(m, dtype=float)
    sub = 0.15
    sup = 0.40 - 0.08 * (m - 1.1)
    rise = 1.0 / (1.0 + np.exp(-(m - 0.97) / 0.025))
    return np.where(m < 1.1, sub + (0.39 - sub) * rise, np.maximum(sup, 0.2))


@dataclass(frozen=True)
class Poly2(DragModel):
    """Paper Eq. 18: Cd = a0 + a1 M + a2 M^2 over the whole flight."""

    name: str = field(default="poly2", init=False)
    param_names: tuple = field(default=("a0", "a1", "a2"), init=False)

    def basis(self, mach):
        m = np.asarray(mach, dtype=float)
        return np.stack([np.ones_like(m), m, m * m], axis=-1)

    def basis_slope(self, mach):
        m = np.asarray(mach, dtype=float)
        return np.stack([np.zeros_like(m), np.ones_like(m), 2.0 * m], axis=-1)

    @property
    def bounds(self):
        return np.array([-10.0, -20.0, -10.0]), np.array([10.0, 20.0, 10.0])

    def curve(self, params):
        a0, a1, a2 = (float(v) for v in params)
        return lambda m: a0 + m * (a1 + m * a2)


@dataclass(frozen=True)
class Constant(DragModel):
    """A constant Cd (Scheme 2: one value per window of samples)."""

    name: str = field(default="constant", init=False)
    param_names: tuple = field(default=("cd",), init=False)

    def basis(self, mach):
        m = np.asarray(mach, dtype=float)
        return np.ones(m.shape + (1,))

    def basis_slope(self, mach):
        m = np.asarray(mach, dtype=float)
        return np.zeros(m.shape + (1,))

    @property
    def bounds(self):
        return np.array([0.0]), np.array([3.0])

    def curve(self, params):
        c = float(np.asarray(params, dtype=float).ravel()[0])
        return lambda m: c


@dataclass(frozen=True)
class Poly2Split(DragModel):
    """Eq. 18 separately below and above ``mach_split`` (the paper's practice).

    Parameters a0_sub, a1_sub, a2_sub apply for M < mach_split; a0_sup, a1_sup, a2_sup for
    M >= mach_split. Cd may jump at ``mach_split``; nothing ties the pieces together, as in the
    paper, so a flight that stays on one side leaves the other side's coefficients unidentified
    (the estimator fixes them and says so).
    """

    mach_split: float = 1.0
    name: str = field(default="poly2-split", init=False)
    param_names: tuple = field(default=("a0_sub", "a1_sub", "a2_sub", "a0_sup", "a1_sup", "a2_sup"),
                               init=False)

    def basis(self, mach):
        m = np.asarray(mach, dtype=float)
        p = np.stack([np.ones_like(m), m, m * m], axis=-1)
        sub = (m < self.mach_split)[..., None]
        return np.concatenate([p * sub, p * ~sub], axis=-1)

    def basis_slope(self, mach):
        m = np.asarray(mach, dtype=float)
        p = np.stack([np.zeros_like(m), np.ones_like(m), 2.0 * m], axis=-1)
        sub = (m < self.mach_split)[..., None]
        return np.concatenate([p * sub, p * ~sub], axis=-1)

    @property
    def bounds(self):
        lo, hi = np.array([-10.0, -20.0, -10.0]), np.array([10.0, 20.0, 10.0])
        return np.concatenate([lo, lo]), np.concatenate([hi, hi])


#: Default interior-knot candidates for :class:`Spline` (Mach). Double knots (C1 joints) sit at
#: the onset of the drag rise (~0.90), its steepest part (~0.96) and its top (~1.02): there the
#: curvature of a shell's Cd(M) jumps, which a C2 cubic cannot follow with few knots (single
#: knots at the same count follow the M101 curve 3-6 times worse: docs/measurements.md)
SPLINE_KNOT_CANDIDATES = (0.7, 0.9, 0.9, 0.93, 0.96, 0.96, 0.99, 1.02, 1.02, 1.06, 1.12, 1.22,
                          1.5, 2.0, 2.6, 3.2, 4.0)


def default_spline_knots(mach_min, mach_max, dm=0.01):
    """Knots (ends included) for :class:`Spline` over [mach_min, mach_max].

    Interior knots are the :data:`SPLINE_KNOT_CANDIDATES` inside the span (dense and doubled
    through the transonic rise, sparse elsewhere), rounded to multiples of ``dm`` so the kernel
    represents the spline exactly; candidates closer than 0.03 Mach to an end are dropped
    (they would leave an end coefficient with almost no data).
    """
    if not mach_max > mach_min:
        raise ValueError(f"spline span needs mach_max > mach_min, got [{mach_min}, {mach_max}]")
    lo = np.floor(mach_min / dm) * dm
    hi = np.ceil(mach_max / dm) * dm
    inner = [c for c in SPLINE_KNOT_CANDIDATES if lo + 0.03 < c < hi - 0.03]
    # the 0.7 knot only helps long subsonic spans
    if inner and inner[0] == 0.7 and lo > 0.55:
        inner = inner[1:]
    return np.array([lo] + inner + [hi])


@dataclass(frozen=True)
class Spline(DragModel):
    """Cubic B-spline Cd(M) with knots ``knots`` (non-decreasing; first and last are the ends,
    interior knots may repeat twice for a C1 joint).

    The parameters c0..c{P-1} are B-spline coefficients (P = len(knots) + 2); each is close to
    Cd near where its basis function peaks. Beyond the end knots the spline is held at its end
    value (zero slope), so a flight that leaves the span does not see a wild extrapolation.
    """

    knots: tuple = tuple(default_spline_knots(0.5, 2.6))
    name: str = field(default="spline", init=False)

    def __post_init__(self):
        k = np.asarray(self.knots, dtype=float)
        if k.ndim != 1 or len(k) < 2 or not np.all(np.isfinite(k)) or np.any(np.diff(k) < 0) \
                or not k[-1] > k[0]:
            raise ValueError(f"spline knots must be >= 2 finite non-decreasing Mach numbers, got {self.knots!r}")
        inner = k[1:-1]
        if np.any(inner <= k[0]) or np.any(inner >= k[-1]):
            raise ValueError("spline interior knots must lie strictly inside the end knots")
        _, counts = np.unique(inner, return_counts=True)
        if counts.size and counts.max() > 2:
            raise ValueError("spline interior knots may repeat at most twice (C1 joint)")
        object.__setattr__(self, "knots", tuple(float(v) for v in k))

    @property
    def param_names(self):
        return tuple(f"c{i}" for i in range(len(self.knots) + 2))

    @property
    def _t(self):
        k = np.asarray(self.knots)
        return np.concatenate([[k[0]] * 3, k, [k[-1]] * 3])

    def _design(self, mach, nu):
        k = np.asarray(self.knots)
        mach = np.asarray(mach, dtype=float)
        m = np.clip(mach, k[0], k[-1])
        P = len(k) + 2
        out = np.empty(m.shape + (P,))
        eye = np.eye(P)
        for j in range(P):
            out[..., j] = BSpline(self._t, eye[j], 3, extrapolate=True)(m, nu=nu)
        if nu:
            outside = (mach < k[0]) | (mach > k[-1])
            out[outside] = 0.0
        return out

    def basis(self, mach):
        return self._design(mach, 0)

    def curve(self, params):
        k = self.knots
        spl = BSpline(self._t, np.asarray(params, dtype=float), 3, extrapolate=True)
        return lambda m: float(spl(min(max(m, k[0]), k[-1])))

    def basis_slope(self, mach):
        return self._design(mach, 1)

    def basis_curvature(self, mach):
        """Second derivative of the basis d^2 B / dM^2 (..., P) (zero beyond the end knots)."""
        return self._design(mach, 2)

    @property
    def bounds(self):
        P = self.n_params
        return np.full(P, 0.0), np.full(P, 3.0)

    @property
    def fit_range(self):
        return (self.knots[0], self.knots[-1])

    def fit_curve(self, mach, cd, minimax=True):
        """Coefficients that best follow a curve ``cd(mach)`` in relative error.

        ``minimax=True`` minimises the largest relative error (a linear programme, scipy HiGHS);
        otherwise least squares in relative error. Returns (coefficients (P,), max relative
        error over the given points).
        """
        from scipy.optimize import linprog

        mach = np.asarray(mach, dtype=float)
        cd = np.asarray(cd, dtype=float)
        B = self.basis(mach) / cd[:, None]
        theta = np.linalg.lstsq(B, np.ones_like(cd), rcond=None)[0]
        if minimax:
            n, P = B.shape
            ones = np.ones((n, 1))
            res = linprog(np.r_[np.zeros(P), 1.0],
                          A_ub=np.block([[B, -ones], [-B, -ones]]),
                          b_ub=np.r_[np.ones(n), -np.ones(n)],
                          bounds=[(None, None)] * P + [(0, None)], method="highs")
            if res.success:
                theta = res.x[:P]
        return theta, float(np.max(np.abs(B @ theta - 1.0)))


@dataclass(frozen=True, eq=False)
class ReferenceTable(DragModel):
    """A fixed Cd(M) table, PCHIP-interpolated (monotone pieces: no overshoot at the transonic
    rise), held constant beyond its ends. No free parameters.

    Attributes
    ----------
    mach, cd : tuple of float
        The table (Mach increasing, Cd > 0).
    source : str
        Where the table came from (file name or citation).
    """

    mach: tuple = ()
    cd_values: tuple = ()
    source: str = ""
    name: str = field(default="reference", init=False)
    param_names: tuple = field(default=(), init=False)

    def __post_init__(self):
        m = np.asarray(self.mach, dtype=float)
        c = np.asarray(self.cd_values, dtype=float)
        src = self.source or "drag table"
        if m.ndim != 1 or m.shape != c.shape or len(m) < 2:
            raise ValueError(f"{src}: a drag table needs >= 2 rows of (mach, cd), got {len(m)}")
        if not (np.all(np.isfinite(m)) and np.all(np.isfinite(c))):
            raise ValueError(f"{src}: drag table contains non-finite values")
        if np.any(np.diff(m) <= 0):
            i = int(np.argmax(np.diff(m) <= 0)) + 1
            raise ValueError(f"{src}: mach must increase strictly; row {i + 1} has {m[i]} after {m[i - 1]}")
        if np.any(m < 0) or np.any(c <= 0) or np.any(c > 5):
            raise ValueError(f"{src}: need mach >= 0 and 0 < cd <= 5; got mach in [{m.min()}, {m.max()}],"
                             f" cd in [{c.min()}, {c.max()}]")
        object.__setattr__(self, "mach", tuple(m.tolist()))
        object.__setattr__(self, "cd_values", tuple(c.tolist()))
        object.__setattr__(self, "_pchip", PchipInterpolator(m, c, extrapolate=False))

    @property
    def mach_range(self):
        return (self.mach[0], self.mach[-1])

    def value(self, mach):
        m = np.clip(np.asarray(mach, dtype=float), self.mach[0], self.mach[-1])
        return self._pchip(m)

    def slope(self, mach):
        m = np.asarray(mach, dtype=float)
        s = self._pchip(np.clip(m, self.mach[0], self.mach[-1]), 1)
        return np.where((m < self.mach[0]) | (m > self.mach[-1]), 0.0, s)

    def basis(self, mach):
        return np.zeros(np.shape(mach) + (0,))

    def curve(self, params=()):
        lo, hi, p = self.mach[0], self.mach[-1], self._pchip
        return lambda m: float(p(min(max(m, lo), hi)))

    def basis_slope(self, mach):
        return np.zeros(np.shape(mach) + (0,))

    @property
    def bounds(self):
        return np.zeros(0), np.zeros(0)

    def cd(self, params=(), mach=None):
        if mach is None:
            raise TypeError("ReferenceTable.cd needs mach")
        params = np.asarray(params, dtype=float)
        v = self.value(mach)
        if params.ndim == 2:  # (B, 0)
            return np.broadcast_to(v, (params.shape[0],) + np.shape(v)).copy()
        return v

    def kernel_table(self, params=(), grid: MachGrid = None):
        tab = _cached_reference_cells(self, grid)
        params = np.asarray(params, dtype=float)
        if params.ndim == 2:
            return np.broadcast_to(tab, (params.shape[0],) + tab.shape).copy()
        return tab.copy()  # callers may modify; the cached cells stay read-only

    @property
    def fit_range(self):
        return self.mach_range


@dataclass(frozen=True, eq=False)
class ReferenceScale(DragModel):
    """Cd(M) = factor x reference(M): one parameter, ``factor`` (a lot-to-lot or form-factor
    difference from a firing-table curve)."""

    reference: ReferenceTable = None
    name: str = field(default="reference-scale", init=False)
    param_names: tuple = field(default=("factor",), init=False)

    def __post_init__(self):
        if not isinstance(self.reference, ReferenceTable):
            raise ValueError("reference-scale needs a reference drag table (round's projectile.reference_drag)")

    def basis(self, mach):
        return self.reference.value(mach)[..., None]

    def basis_slope(self, mach):
        return self.reference.slope(mach)[..., None]

    def _kernel_basis_uncached(self, grid):
        return np.ascontiguousarray(self.reference.kernel_table((), grid)[..., None])

    def curve(self, params):
        f, base = float(np.ravel(params)[0]), self.reference.curve()
        return lambda m: f * base(m)

    @property
    def bounds(self):
        return np.array([0.2]), np.array([5.0])

    def initial_params(self, reference=None):
        return np.array([1.0])

    @property
    def fit_range(self):
        return self.reference.mach_range


@dataclass(frozen=True, eq=False)
class TableSpline(DragModel):
    """Cd(M) = table(M) x s(M): a firing table times a smooth correction, a cubic B-spline.

    The table is evaluated exactly (its PCHIP), so a correct table costs nothing however steep
    its drag rise: the correction is then a constant. The correction's coefficients
    ``c0..c{P-1}`` are close to ``Cd / table`` near where each basis function peaks; beyond the
    end knots the correction is held at its end value while the table goes on.

    Attributes
    ----------
    reference : ReferenceTable
    knots : tuple of float
        Knots of the correction (as :class:`Spline`).
    """

    reference: ReferenceTable = None
    knots: tuple = ()
    name: str = field(default="spline", init=False)

    def __post_init__(self):
        if not isinstance(self.reference, ReferenceTable):
            raise ValueError("a table-times-correction drag model needs a reference drag table")
        spl = Spline(tuple(self.knots))  # validates the knots
        object.__setattr__(self, "knots", spl.knots)
        object.__setattr__(self, "_spline", spl)

    @property
    def param_names(self):
        return tuple(f"c{i}" for i in range(len(self.knots) + 2))

    @property
    def correction(self):
        """The correction s(M) as a :class:`Spline` (same coefficients)."""
        return self._spline

    def basis(self, mach):
        m = np.asarray(mach, dtype=float)
        return self.reference.value(m)[..., None] * self._spline.basis(m)

    def basis_slope(self, mach):
        m = np.asarray(mach, dtype=float)
        return (self.reference.slope(m)[..., None] * self._spline.basis(m)
                + self.reference.value(m)[..., None] * self._spline.basis_slope(m))

    def curve(self, params):
        s, base = self._spline.curve(params), self.reference.curve()
        return lambda m: s(m) * base(m)

    @property
    def bounds(self):
        P = self.n_params
        return np.full(P, 0.05), np.full(P, 20.0)

    def initial_params(self, reference=None):
        return self.params_for(np.linspace(*self.fit_range, 200),
                               self.reference.value(np.linspace(*self.fit_range, 200)))

    @property
    def fit_range(self):
        return (self.knots[0], self.knots[-1])


@dataclass(frozen=True, eq=False)
class ShapedTable(DragModel):
    """Cd(M) = table(M) (c_0 + sum_k c_k phi_k(M)), ``phi_k = B_k - a_k`` (k = 1..K): the drag
    curve of the ``drag_shape`` effect. ``c_0 = 1`` always (the effect's coefficients are
    ``c_1..c_K``); ``B_1..B_K`` are the cubic B-splines on ``knots`` (:class:`Spline`)
    less the first, and ``a_k`` constants: by default their Mach means over the knot span (a
    correction of zero Mach mean); the diagnosis sets them so that each shape function moves the
    track orthogonally to a constant factor (:func:`bayesdrag.effects.drag.level_free_offsets`).

    Attributes
    ----------
    reference : ReferenceTable
    knots : tuple of float
    offsets : tuple of float or None
        ``a_1..a_K`` (None: the Mach means).
    """

    reference: ReferenceTable = None
    knots: tuple = ()
    offsets: tuple | None = None
    name: str = field(default="table-shape", init=False)

    def __post_init__(self):
        if not isinstance(self.reference, ReferenceTable):
            raise ValueError("drag_shape needs a reference drag table (round's projectile.reference_drag)")
        spl = Spline(tuple(self.knots))
        if self.offsets is None:
            m = np.linspace(spl.knots[0], spl.knots[-1], 801)
            off = spl.basis(m).mean(axis=0)[1:]
        else:
            off = np.asarray(self.offsets, float)
            if off.shape != (spl.n_params - 1,) or not np.all(np.isfinite(off)):
                raise ValueError(f"drag_shape offsets must be {spl.n_params - 1} finite numbers, got {self.offsets!r}")
        object.__setattr__(self, "knots", spl.knots)
        object.__setattr__(self, "_spline", spl)
        object.__setattr__(self, "offsets", tuple(float(v) for v in off))
        object.__setattr__(self, "_means", np.concatenate([[0.0], off]))

    @property
    def n_shape(self):
        """Number of shape coefficients K (B-splines less one)."""
        return self._spline.n_params - 1

    @property
    def param_names(self):
        return ("c0",) + tuple(f"s{i + 1}" for i in range(self.n_shape))

    def shape_basis(self, mach):
        """Zero-mean shape functions (N, K) at ``mach``."""
        return self._spline.basis(np.asarray(mach, float))[..., 1:] - self._means[1:]

    def shape_slope(self, mach):
        return self._spline.basis_slope(np.asarray(mach, float))[..., 1:]

    def correction(self, coefs, mach):
        """Relative Cd change ``sum_k s_k phi_k(M)`` for coefficients (K,) at ``mach``."""
        return self.shape_basis(mach) @ np.asarray(coefs, float)

    def basis(self, mach):
        m = np.asarray(mach, dtype=float)
        t = self.reference.value(m)[..., None]
        return np.concatenate([t, t * self.shape_basis(m)], axis=-1)

    def basis_slope(self, mach):
        m = np.asarray(mach, dtype=float)
        t, dt = self.reference.value(m)[..., None], self.reference.slope(m)[..., None]
        phi = self.shape_basis(m)
        return np.concatenate([dt, dt * phi + t * self.shape_slope(m)], axis=-1)

    @property
    def bounds(self):
        P = self.n_params
        return np.full(P, -20.0), np.full(P, 20.0)

    @property
    def fit_range(self):
        return (self.knots[0], self.knots[-1])


@lru_cache(maxsize=64)
def _cached_reference_cells(table, grid):
    fl, sl, fr, sr = _one_sided(table.value, table.slope, grid)
    tab = _hermite_cells(fl, sl, fr, sr, grid.dm)
    tab.setflags(write=False)
    return tab


def make_drag_model(name, reference=None, mach_range=None, knots=None):
    """Build a drag model by its name.

    Parameters
    ----------
    name : {"poly2", "poly2-split", "spline", "reference-scale"}
    reference : ReferenceTable, optional
        Needed by ``reference-scale``.
    mach_range : (float, float), optional
        Mach span of the data; sets the spline's end knots.
    knots : sequence of float, optional
        Explicit spline knots.
    """
    if name == "poly2":
        return Poly2()
    if name == "poly2-split":
        return Poly2Split()
    if name == "spline":
        if knots is None:
            lo, hi = mach_range if mach_range is not None else (0.5, 2.6)
            knots = default_spline_knots(lo, hi)
        return Spline(tuple(knots))
    if name == "reference-scale":
        if reference is None:
            raise ValueError("drag model 'reference-scale' needs a reference drag table: set "
                             "[projectile] reference_drag in the round file")
        return ReferenceScale(reference)
    raise ValueError(f"unknown drag model {name!r}; allowed: {', '.join(DRAG_MODEL_NAMES)}")
