"""The effect concept: the :class:`Effect` value (its traits and the one mapping of its
parameters to the simulation's inputs), what it needs to know about the round
(:class:`EffectContext`), and how effects compose into an ``effect_fn`` and into the model
(:func:`add_inputs`, :func:`effect_fn`, :func:`static_model`). No effect is named here: each
lives in its concept's module (:mod:`.air`, :mod:`.drag`, :mod:`.flight`, :mod:`.radar`) and
the library (:mod:`.library`) lists them.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..air.atmosphere import Atmosphere
from .inputs import ExtraParam, SimInputs

__all__ = ["Effect", "EffectContext", "add_inputs", "effect_fn", "static_model", "extra_params",
           "unabsorbed_fraction"]


@dataclass(frozen=True)


class EffectContext:
    """What an effect needs to know about the round besides its parameters.

    Attributes
    ----------
    atmosphere : Atmosphere
        The round's (nominal) atmosphere.
    wind_layers : WindLayers or None
        The layers of ``wind_profile`` (axis, edges); None: the effect cannot be formed.
    latitude_deg, azimuth_deg : float or None
        Coriolis geometry (None: unknown latitude).
    v0 : float or None, m/s
        Launch velocity (spin-setting speed for ``lift``).
    drag_shape : ShapedTable or None
        The table-times-correction drag of ``drag_shape`` over the flown Mach span
        (:func:`drag_shape_model`); None: the effect cannot be formed (no reference table).
    """

    atmosphere: Atmosphere = field(default_factory=Atmosphere)
    latitude_deg: float | None = None
    azimuth_deg: float = 0.0
    v0: float | None = None
    drag_shape: object = None
    wind_layers: object = None
    #: the coordinates of ``radar_position`` the track's channels see (the others held at 0)
    radar_axes: tuple = ("x", "y", "z")
    #: ``(h, tables)``: a temperature offset enters as the kernel's atmosphere tables
    #: interpolated between ``tables`` (3, n, 2) at -h, 0, +h K (:func:`temperature_nodes`: the
    #: fit's declared temperature, one table set for every walker) instead of one atmosphere per
    #: trajectory; None: atmospheres
    temperature_nodes: tuple | None = None
    #: the projectile's nominal mass [kg] and diameter [m] (the declared mass and diameter
    #: sources vary them)
    mass: float | None = None
    diameter: float | None = None


@dataclass(frozen=True)


class Effect:
    """One unmodelled effect.

    Attributes
    ----------
    name : str
    params : tuple of ExtraParam
        Fitted parameters (their ``start`` is the "no effect" value).
    units : tuple of str
    explanation : str
        One or two sentences of physics for the report.
    acts_on : {"air", "drag", "flight", "measurement"}
        What it changes: the air the shell flies through, its drag, its flight otherwise (forces
        other than drag, Earth rotation), or only what the radar records.
    drag_change : {None, "level", "shape", "partly"}
        How it trades with the Cd a fit estimates: a constant factor on the drag (``"level"``: the
        Cd level itself), a change of the drag's shape in Mach (``"shape"``), a part of it that
        does (``"partly"``: a temperature's density part, a decaying yaw's early drag), or none.
    source : str or None
        The declared systematic source (round key stem ``<source>_sd``) that is the same quantity.
    needs : tuple of str
        What the round or the fit must give for the effect to be formed (``"latitude"``,
        ``"reference"``: a firing table, ``"wind_layers"``, ``"radar_channels"``).
    seen_by : {"all", "cross_range"}
        The channels that see it (``"cross_range"``: only a drift across the line of fire).
    to_inputs : callable or None
        How a batch of its parameter values enters the simulation: ``to_inputs(values (B, k),
        ctx, state0) -> dict`` (the keys :meth:`apply` lists), a pure function. The fit's
        ``--with``, the diagnosis, the declared source of the same quantity and the planner all
        call it (:func:`effect_fn`, :func:`bayesdrag.effects.sources.sources_fn`).
    wrap_model : callable or None
        For an effect that changes the model itself: ``wrap_model(model, ctx) -> model`` (the
        Coriolis matrix, a drag or wind wrapper that reads the kernel inputs), folded in by
        :func:`static_model`.
    to_report, to_report_sd : callable or None
        ``to_report(values) -> dict`` and ``to_report_sd(values, sd) -> dict``: the reported
        parameters and their sds where they are not the fitted ones (``yaw_drag`` fits an
        amplitude and reports the launch yaw); None: the fitted ones.
    label : str
        What it is in a few words, for the lines that tell a user the fit found and fitted it
        ("a wind changing along the flight"); empty: the explanation's first clause.
    """

    name: str
    params: tuple
    units: tuple
    explanation: str
    acts_on: str = "flight"
    drag_change: str | None = None
    source: str | None = None
    needs: tuple = ()
    seen_by: str = "all"
    to_inputs: object = field(default=None, repr=False, compare=False)
    wrap_model: object = field(default=None, repr=False, compare=False)
    to_report: object = field(default=None, repr=False, compare=False)
    to_report_sd: object = field(default=None, repr=False, compare=False)
    label: str = field(default="", compare=False)

    @property
    def headline(self):
        """What it is in a few words: :attr:`label`, else the explanation up to its first colon."""
        return self.label or self.explanation.split(":")[0].split(";")[0].strip()

    @property
    def k(self):
        """Number of parameters."""
        return len(self.params)

    @property
    def null(self):
        """Parameter values meaning "no effect", shape (k,)."""
        return np.array([p.start for p in self.params])

    def apply(self, values, ctx, state0=None):
        """Kernel inputs for a batch of parameter values: :attr:`to_inputs`, the one mapping the
        fit, the diagnosis, the declared sources and the planner all use.

        Parameters
        ----------
        values : (B, k) array
        ctx : EffectContext
        state0 : (B, 6) array, optional
            Initial states (``lift`` without a launch velocity).

        Returns
        -------
        dict with optional keys ``overrides`` (column -> (B,)), ``atmospheres`` (list of B
        Atmosphere), ``atmosphere_tables`` ((B, n, 2)), ``time_shift`` ((B,) s),
        ``output_offset`` (channel -> (B,): a radar's bias), ``output_scale`` (channel -> (B,)),
        ``site_shift`` ((B, 3) m: where the radar stands against its stated site); how they
        compose: :func:`add_inputs`.
        """
        if self.to_inputs is None:
            raise ValueError(f"effect {self.name!r} has no mapping to the simulation's inputs (to_inputs)")
        return self.to_inputs(np.atleast_2d(values), ctx, state0)

    def report_params(self, values):
        """Parameters as reported in diagnosis.json (names and units of the file format;
        :attr:`to_report` where the fitted parameters are not the reported ones)."""
        values = np.asarray(values, dtype=float)
        if self.to_report is not None:
            return self.to_report(values)
        return {p.name: float(v) for p, v in zip(self.params, values)}

    def report_sd(self, values, cov):
        """Standard deviations of the reported parameters (:attr:`to_report_sd`: the delta method
        where the reported parameters are functions of the fitted ones)."""
        sd = np.sqrt(np.clip(np.diag(np.atleast_2d(cov)), 0, None)) if self.k else np.zeros(0)
        if self.to_report_sd is not None:
            return self.to_report_sd(values, sd)
        return {p.name: float(s) for p, s in zip(self.params, sd)}


def unabsorbed_fraction(nuisance, cols):
    """Share of each column's norm (k,) that the span of ``nuisance`` (n, q) leaves: how much of an
    effect parameter's signature (weighted output sensitivities, prior rows appended) is more than
    the nuisance parameters can make (:data:`bayesdrag.effects.radar.SITE_SEEN_FRACTION`)."""
    Q, _ = np.linalg.qr(nuisance)
    norms = np.linalg.norm(cols, axis=0)
    left = np.linalg.norm(cols - Q @ (Q.T @ cols), axis=0)
    return np.where(norms > 0, left / np.where(norms > 0, norms, 1.0), 0.0)


def extra_params(effects):
    """ExtraParam list for a sequence of effects; parameter names are prefixed with the effect
    name (``wind.wx``) so that several effects can be fitted together."""
    return tuple(ExtraParam(f"{e.name}.{p.name}", p.start, p.lower, p.upper, p.step)
                 for e in effects for p in e.params)


def add_inputs(base, out, what="effects"):
    """``base`` (:class:`SimInputs`) with one effect's or source's inputs ``out`` (a dict as
    :meth:`Effect.apply` returns) added, by field: kernel columns side by side (one set twice is
    refused: they would overwrite each other), atmospheres or atmosphere tables taken, a clock
    shift, a bias and a site shift added to what is there, an output scale multiplied."""
    ov = dict(base.overrides)
    for col, v in out.get("overrides", {}).items():
        if col in ov:
            raise ValueError(f"{what} set the same kernel column")
        ov[col] = np.asarray(v, float)
    shift = base.time_shift
    if "time_shift" in out:
        v = out["time_shift"]
        shift = v if shift is None else np.asarray(shift, float) + v
    offset = dict(base.output_offset)
    for c, v in out.get("output_offset", {}).items():
        offset[c] = np.asarray(v, float) + offset.get(c, 0.0)
    scale = dict(base.output_scale)
    for c, v in out.get("output_scale", {}).items():
        scale[c] = np.asarray(v, float) * scale.get(c, 1.0)
    site = base.site_shift
    if "site_shift" in out:
        site = out["site_shift"] if site is None else site + out["site_shift"]
    return replace(base, overrides=ov, atmospheres=out.get("atmospheres", base.atmospheres), time_shift=shift,
                   output_scale=scale, atmosphere_tables=out.get("atmosphere_tables", base.atmosphere_tables),
                   output_offset=offset, site_shift=site)


def effect_fn(effects, ctx, base_state0=None):
    """``effect_fn`` for :class:`OutputErrorProblem` combining ``effects``.

    Parameters
    ----------
    effects : sequence of Effect
    ctx : EffectContext
    base_state0 : (6,) array, optional
        Initial state used for ``lift`` when ``ctx.v0`` is None.

    Returns
    -------
    callable ``E (B, sum k) -> SimInputs``: each effect's :attr:`Effect.to_inputs` added
    (:func:`add_inputs`). Two effects setting the same kernel column are rejected (they would
    overwrite each other).
    """
    effects = tuple(effects)
    what = "effects " + ", ".join(x.name for x in effects)

    def fn(E):
        E = np.atleast_2d(E)
        B = E.shape[0]
        inp = SimInputs()
        j = 0
        for e in effects:
            s0 = None if base_state0 is None else np.tile(base_state0, (B, 1))
            inp = add_inputs(inp, e.apply(E[:, j:j + e.k] if e.k else np.zeros((B, 0)), ctx, s0), what)
            j += e.k
        return inp

    return fn


def static_model(model, effects, ctx):
    """Effects that change the model itself (:attr:`Effect.wrap_model`) folded into it: ``coriolis``
    (its Coriolis matrix), ``drag_shape`` (a :class:`DragShapeModel` around it, whose drag takes
    the effect's coefficients from the kernel inputs) and ``wind_profile`` (a
    :class:`WindProfileModel`, whose winds take the layers' values from the kernel inputs)."""
    for e in effects:
        if e.wrap_model is not None:
            model = e.wrap_model(model, ctx)
    return model
