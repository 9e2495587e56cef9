"""Effects on the drag law itself: a constant factor on the firing table (``drag_scale``) and a
change of its shape in Mach (``drag_shape``: the table times a smooth correction without a
level, :class:`ShapedTable`, flown by :class:`DragShapeModel`)."""
from __future__ import annotations

import math

import numpy as np

from ..drag import ReferenceTable, ShapedTable
from ..dynamics import kernel as K
from .base import Effect
from .inputs import ExtraParam

__all__ = ["DRAG_SCALE", "DRAG_SHAPE", "ShapedTable", "DragShapeModel", "drag_shape_knots", "drag_shape_model",
           "level_free_offsets", "drag_shape_free", "DRAG_SHAPE_MAX", "DRAG_SHAPE_STEP", "DRAG_SHAPE_RISE_WEIGHT",
           "DRAG_SHAPE_BOUND", "DRAG_SHAPE_KEY"]

#: largest number of drag_shape coefficients (the cubic B-splines on at most DRAG_SHAPE_MAX - 2
#: knot intervals, less the first, whose place the level -- drag_scale -- takes): enough to follow another shell's
#: drag rise relative to the table, few enough that a fit stays cheap (2 (6 + K) trajectories
#: per sensitivity batch)
DRAG_SHAPE_MAX = 8

#: one knot interval per this much "weighted Mach length" (Mach width plus the table's total
#: log-variation over the span, so a steep rise counts as wide as its change in ln Cd)
DRAG_SHAPE_STEP = 0.4

#: the knots are equidistributed in Mach + ln Cd(table): a rise's change in ln Cd counts this
#: many times its Mach width
DRAG_SHAPE_RISE_WEIGHT = 1.0

#: bound on each drag_shape coefficient (a relative Cd change): the standard tables and M101
#: differ in shape, their best common factor taken out, by at most 0.44 (G7 against the sphere
#: GS over Mach 0.5-2.5; median pair 0.27), and a B-spline coefficient at a sharp rise exceeds
#: the curve it makes (0.74 for an M101 shell against a G1 table); a wider bound lets a
#: correction alternating in sign stand in for a density change (docs/measurements.md, "Where the constants come from")
DRAG_SHAPE_BOUND = 1.0

#: override key of drag_shape's coefficients (not a kernel column: read by DragShapeModel)
DRAG_SHAPE_KEY = "drag_shape"


def _drag_scale_inputs(values, ctx, state0):
    return {"overrides": {K.P_CD_SCALE: values[:, 0]}}


def _drag_shape_inputs(values, ctx, state0):
    return {"overrides": {(DRAG_SHAPE_KEY, i): values[:, i] for i in range(values.shape[1])}}


def _drag_shape_model(model, ctx):
    if ctx.drag_shape is None:
        raise ValueError("the drag_shape effect needs a reference drag table and the flown Mach span "
                         "(EffectContext.drag_shape from drag_shape_model)")
    if model.drag.n_params != 0:
        raise ValueError(f"the drag_shape effect multiplies a fixed reference table; the model's drag "
                         f"{model.drag.name!r} has {model.drag.n_params} free coefficients (no table)")
    return DragShapeModel(model, ctx.drag_shape)


# ----------------------------------------------------------------------------------------------
# drag_shape: the table times a zero-mean smooth correction


def drag_shape_knots(reference, mach_min, mach_max, max_params=DRAG_SHAPE_MAX, step=DRAG_SHAPE_STEP,
                     rise_weight=DRAG_SHAPE_RISE_WEIGHT):
    """Knots of the ``drag_shape`` correction over the flown Mach span.

    The knots equidistribute ``1 + rise_weight |d ln Cd_table / dM|`` over [mach_min, mach_max]:
    where the table rises or falls steeply (the transonic rise, where shells differ most: a boat
    tail rises later and sharper than a flat base, a sphere earlier) they are closer. Their
    number is one interval per ``step`` of that weighted length, between 1 and
    ``max_params - 2`` (``n`` intervals give ``n + 3`` B-splines, ``n + 2`` zero-mean shape
    functions).

    Parameters
    ----------
    reference : ReferenceTable
    mach_min, mach_max : float
        Flown Mach span.
    max_params, step, rise_weight : see :data:`DRAG_SHAPE_MAX`, :data:`DRAG_SHAPE_STEP`,
        :data:`DRAG_SHAPE_RISE_WEIGHT`.

    Returns
    -------
    (n + 1,) ndarray of Mach numbers, ends included, rounded to 0.01.
    """
    lo, hi = float(mach_min), float(mach_max)
    if not hi > lo:
        raise ValueError(f"drag_shape needs a Mach span with mach_max > mach_min, got [{lo}, {hi}]")
    m = np.linspace(lo, hi, 401)
    f = np.clip(np.asarray(reference.value(m), float), 1e-4, None)
    dens = 1.0 + rise_weight * np.abs(np.gradient(np.log(f), m))
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(m))])
    n = int(np.clip(math.ceil(cum[-1] / step - 1e-9), 1, max(max_params - 2, 1)))
    inner = np.interp(np.linspace(0.0, cum[-1], n + 1)[1:-1], cum, m)
    knots = np.unique(np.round(np.concatenate([[lo], inner, [hi]]), 2))
    knots[0], knots[-1] = min(knots[0], lo), max(knots[-1], hi)
    return knots


def drag_shape_model(reference, mach_span, offsets=None):
    """The :class:`ShapedTable` of ``drag_shape`` for a table and a flown Mach span (lo, hi)."""
    return ShapedTable(reference, tuple(drag_shape_knots(reference, *mach_span)), offsets)


def level_free_offsets(shape, S, A_nuisance=None):
    """Offsets ``a_k`` that make each shape function of ``shape`` move the track orthogonally to
    a constant drag factor, so that ``drag_shape`` cannot mimic ``drag_scale`` (or ``density``)
    to first order: a zero *Mach* mean does not stop a coefficient at a sparsely flown end of the
    span from carrying a level change for the rest of the flight.

    Parameters
    ----------
    shape : ShapedTable
        With its current offsets.
    S : (n, K + 1) array
        Noise-weighted output sensitivities (stacked samples x channels) to ``c_0..c_K`` at the
        baseline: column 0 is the constant factor.
    A_nuisance : (n, q) array, optional
        Sensitivities of the nuisance parameters (the initial state, with the launch priors as
        extra rows in all arrays) projected out first: the level direction is what is left of
        a constant factor once the initial state has taken what it can.

    Returns
    -------
    (K,) ndarray: the new offsets (``shape.offsets`` plus the projections).
    """
    S = np.asarray(S, float)
    if A_nuisance is not None and A_nuisance.size:
        Q, _ = np.linalg.qr(A_nuisance)
        S = S - Q @ (Q.T @ S)
    lev = S[:, 0]
    nn = float(lev @ lev)
    b = (S[:, 1:].T @ lev) / nn if nn > 0 else np.zeros(S.shape[1] - 1)
    return np.asarray(shape.offsets, float) + b


def drag_shape_free(ctx, index):
    """Is drag_shape's coefficient ``index`` (0-based) used on this track? (The span sets how
    many there are; the rest are held at 0.)"""
    return ctx.drag_shape is not None and index < ctx.drag_shape.n_shape


class DragShapeModel:
    """A point-mass model whose drag is ``shape`` (:class:`ShapedTable`) with the coefficients
    ``(1, s_1..s_K)`` read per trajectory from the kernel inputs' ``(DRAG_SHAPE_KEY, k)``
    entries (the ``drag_shape`` effect). Everything else is the wrapped model's; its own drag
    (the fixed table) is what :attr:`drag` reports, so the fit's parameter layout is unchanged.

    Parameters
    ----------
    model : PointMassModel
        With a parameter-free drag (the reference table).
    shape : ShapedTable
    """

    def __init__(self, model, shape):
        self.model = model
        self.shape = shape
        self._shaped = model.with_(drag=shape)

    def __getattr__(self, name):
        return getattr(self.model, name)

    def with_(self, **changes):
        """Copy with some attributes of the wrapped model changed (the shape kept)."""
        return DragShapeModel(self.model.with_(**changes), self.shape)

    def simulate_batch(self, drag_params, state0, t_out, *, overrides=None, **kw):
        """As :meth:`PointMassModel.simulate_batch`; ``overrides`` may hold the shape
        coefficients under ``(DRAG_SHAPE_KEY, k)`` (missing ones are 0)."""
        ov = dict(overrides or {})
        keys = sorted((k for k in ov if isinstance(k, tuple) and k[0] == DRAG_SHAPE_KEY), key=lambda k: k[1])
        B = max(np.atleast_2d(np.asarray(state0, float)).shape[0], np.atleast_2d(drag_params).shape[0])
        coef = np.zeros((B, self.shape.n_params))
        coef[:, 0] = 1.0
        for k in keys:
            v = ov.pop(k)
            if k[1] < self.shape.n_shape:
                coef[:, 1 + k[1]] = np.broadcast_to(np.asarray(v, float), (B,))
        return self._shaped.simulate_batch(coef, state0, t_out, overrides=ov or None, **kw)


DRAG_SCALE = Effect("drag_scale", (ExtraParam("factor", 1.0, 0.2, 5.0, 1e-4),), ("-",),
                    "This shell's drag is a constant factor times the firing table (lot, fuze, driving "
                    "band or form differences); identical in its signature to a density ratio.",
                    acts_on="drag", drag_change="level", to_inputs=_drag_scale_inputs,
                    label="a drag level off the table's")


DRAG_SHAPE = Effect("drag_shape", tuple(ExtraParam(f"s{i + 1}", 0.0, -DRAG_SHAPE_BOUND, DRAG_SHAPE_BOUND, 1e-4)
                                        for i in range(DRAG_SHAPE_MAX)),
                    ("-",) * DRAG_SHAPE_MAX,
                    "The firing table has the wrong shape for this shell (a table of another shell: its "
                    "drag rise earlier, later, higher or lower): the table times a smooth correction in "
                    "Mach that carries no overall level (the level is drag_scale).",
                    acts_on="drag", drag_change="shape", needs=("reference",),
                    to_inputs=_drag_shape_inputs, wrap_model=_drag_shape_model,
                    label="a drag curve of another shape than the table's")
