"""The GCV smoothing spline of the start curve, its smoothing found ten times faster.

:func:`gcv_smoothing_spline` is ``scipy.interpolate.make_smoothing_spline(x, y, w)`` (the cubic
smoothing spline whose regularisation ``lam`` minimises the generalised cross-validation
criterion) to the last bit: the same banded matrices, the same criterion evaluated by the same
floating-point operations in the same order, the same bounded minimiser, and scipy's own solve
for the spline once ``lam`` is known. What differs is how the criterion's sequential loops run:
scipy's reach into numpy arrays element by element (~1.7 ms per evaluation for the ~150 bins of
a start curve, 36 evaluations per spline, two splines per fit: 0.12 s of a 0.35 s ML fit of the
demo track); here they run over Python floats, and the trace's backward recursion compiled
(docs/measurements.md, "The start curve's smoothing"). ``tests/unit/test_gcv_spline.py`` compares the two bit for bit.

The design matrix, penalty and criterion follow scipy 1.17's ``_bsplines.py`` (BSD-3-Clause,
Copyright (c) 2001-2002 Enthought, Inc. 2003, SciPy Developers), after Woltring's algorithm and
Hutchinson & de Hoog (1985) for the trace.
"""
from __future__ import annotations

import numpy as np
from numba import njit
from scipy.interpolate import BSpline, make_smoothing_spline
from scipy.linalg import cholesky_banded, solve_banded
from scipy.optimize import minimize_scalar

__all__ = ["gcv_smoothing_spline", "gcv_lambda"]


def gcv_smoothing_spline(x, y, w):
    """The cubic smoothing spline of ``(x, y)`` with weights ``w`` whose smoothing minimises
    the GCV criterion: ``make_smoothing_spline(x, y, w)``, bit for bit.

    Parameters
    ----------
    x : (n,) ndarray
        Strictly increasing abscissas, n >= 5.
    y : (n,) ndarray
        Ordinates.
    w : (n,) ndarray
        Positive weights (not squared in the residual sum).

    Returns
    -------
    scipy.interpolate.BSpline

    Raises
    ------
    ValueError
        Abscissas not increasing, weights not positive, fewer than 5 points, an ill-posed
        problem or a failed search (as scipy's).
    """
    x = np.ascontiguousarray(x, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    w = np.ascontiguousarray(w, dtype=float)
    if x.ndim != 1 or y.shape != x.shape or w.shape != x.shape or x.size <= 4:
        raise ValueError(f"x, y and w must be 1-D of one length >= 5; got {x.shape}, {y.shape}, {w.shape}")
    if np.any(x[1:] - x[:-1] <= 0):
        raise ValueError("``x`` should be an ascending array")
    if np.any(w <= 0):
        raise ValueError("Invalid vector of weights")
    return make_smoothing_spline(x, y, w=w, lam=gcv_lambda(x, y, w))


def gcv_lambda(x, y, w):
    """The regularisation ``lam`` minimising the GCV criterion over ``[0, n]`` (scipy's
    ``_compute_optimal_gcv_parameter``; inputs as :func:`gcv_smoothing_spline`, checked)."""
    X, wE = _natural_design(x, w)
    n = x.size
    XtWX = _banded_xtwy(X, w, X)
    XtE = _banded_xtwy(X, w, wE)
    est = minimize_scalar(_gcv, bounds=(0, n), method="Bounded", args=(X, XtWX, wE, XtE, y))
    if not est.success:
        raise ValueError(f"Unable to find minimum of the GCV function: {est.message}")
    return est.x


def _natural_design(x, w):
    """The design matrix ``X`` of the natural cubic spline basis and the penalty ``W^-1 E``,
    both (5, n) in LAPACK banded storage (as scipy's ``make_smoothing_spline`` builds them)."""
    t = np.r_[[x[0]] * 3, x, [x[-1]] * 3]
    n = x.shape[0]
    X_bspl = BSpline.design_matrix(x, t, 3)
    X = np.zeros((5, n))
    for i in range(1, 4):
        X[i, 2: -2] = X_bspl[i: i - 4, 3: -3][np.diag_indices(n - 4)]
    X[1, 1] = X_bspl[0, 0]
    X[2, :2] = ((x[2] + x[1] - 2 * x[0]) * X_bspl[0, 0], X_bspl[1, 1] + X_bspl[1, 2])
    X[3, :2] = ((x[2] - x[0]) * X_bspl[1, 1], X_bspl[2, 2])
    X[1, -2:] = (X_bspl[-3, -3], (x[-1] - x[-3]) * X_bspl[-2, -2])
    X[2, -2:] = (X_bspl[-2, -3] + X_bspl[-2, -2], (2 * x[-1] - x[-2] - x[-3]) * X_bspl[-1, -1])
    X[3, -2] = X_bspl[-1, -1]
    wE = np.zeros((5, n))
    wE[2:, 0] = _divided_diff(x[:3]) / w[:3]
    wE[1:, 1] = _divided_diff(x[:4]) / w[:4]
    for j in range(2, n - 2):
        wE[:, j] = (x[j + 2] - x[j - 2]) * _divided_diff(x[j - 2:j + 3]) / w[j - 2: j + 3]
    wE[:-1, -2] = -_divided_diff(x[-4:]) / w[-4:]
    wE[:-2, -1] = _divided_diff(x[-3:]) / w[-3:]
    wE *= 6
    return X, wE


def _divided_diff(x):
    """Coefficients of the divided difference over the points ``x``."""
    n = x.shape[0]
    res = np.zeros(n)
    for i in range(n):
        pp = 1.
        for k in range(n):
            if k != i:
                pp *= (x[i] - x[k])
        res[i] = 1. / pp
    return res


def _banded_xtwy(X, w, Y):
    """The 4 unique bands of the symmetric 7-banded ``X^T W Y`` (X, Y 5-banded), (4, n)."""
    W_Y = np.copy(Y)
    W_Y[2] *= w
    for i in range(2):
        W_Y[i, 2 - i:] *= w[:-2 + i]
        W_Y[3 + i, :-1 - i] *= w[1 + i:]
    n = X.shape[1]
    res = np.zeros((4, n))
    for i in range(n):
        for j in range(min(n - i, 4)):
            res[-j - 1, i + j] = sum(X[j:, i] * W_Y[:5 - j, i + j])
    return res


def _b_inv(A):
    """The 3 central bands of ``A^-1`` for the symmetric positive definite banded ``A``
    ((4, n) upper LAPACK storage), as (4, n) with a zero first row (Hutchinson & de Hoog)."""
    U = cholesky_banded(A)
    for i in range(2, 5):
        U[-i, i - 1:] /= U[-1, :-i + 1]
    D = 1. / (U[-1]) ** 2
    U[-1] /= U[-1]
    B = _b_inv_bands(U, D)
    B[0] = 0.
    return B


@njit(cache=True)
def _b_inv_bands(U, D):
    """Hutchinson & de Hoog's backward recursion of :func:`_b_inv` over the scaled Cholesky
    bands ``U`` (4, n) and ``D`` (n,): scipy's loop, compiled, with the same operations in the
    same order."""
    n = U.shape[1]
    b = np.zeros((4, n))
    for i in range(n - 1, -1, -1):
        rng = min(3, n - i - 1)
        for j in range(rng, -1, -1):
            s = 0.
            if j == 0:
                for k in range(1, rng + 1):
                    s -= U[3 - k, i + k] * b[3 - k, i + k]
                s += D[i]
                b[3, i] = s
            else:
                for k in range(1, rng + 1):
                    diag = abs(k - j)
                    s -= U[3 - k, i + k] * b[3 - diag, i + min(k, j) + diag]
                b[3 - j, i + j] = s
    return b


def _gcv(lam, X, XtWX, wE, XtE, y):
    """The GCV criterion at ``lam`` (Wahba 1990, (1.3.2))."""
    n = X.shape[1]
    c = solve_banded((2, 2), X + lam * wE, y)
    tmp = (wE * c).tolist()
    res = np.array([_band_sum(tmp, i, n) for i in range(n)])
    numer = np.linalg.norm(lam * res) ** 2 / n
    lhs = XtWX + lam * XtE
    try:
        tr = _b_inv(lhs) * XtWX
        tr[:-1] *= 2
        denom = (1 - sum(sum(tr)) / n) ** 2
    except np.linalg.LinAlgError:
        raise ValueError("Seems like the problem is ill-posed") from None
    return numer / denom


def _band_sum(tmp, i, n):
    """``(W^-1 E c)[i]`` from the banded products ``tmp`` (added from 0.0 in scipy's order)."""
    s = 0.
    for j in range(max(0, i - n + 3), min(5, i + 3)):
        s += tmp[j][i + 2 - j]
    return s
