"""Declared systematic sources as nuisance parameters, and the uncertainty budget of Cd.

A round may declare how well it knows the quantities the fit otherwise holds at their nominal
values (:class:`bayesdrag.round.Systematics`, the ``_sd`` keys of the round file). Each declared
quantity becomes one extra parameter after the initial state, with a Gaussian prior (mean the
nominal value, sd as declared), estimated with Cd by the ML fit and sampled by emcee:

===============  =====================  =====================================================
source           parameter [unit]       what it does to the simulation
===============  =====================  =====================================================
mass             ``mass`` [kg]          drag constant ``k = pi d^2 / (8 m)`` (with diameter)
diameter         ``diameter`` [m]       the same constant
density          ``density.ratio`` [-]  air density multiplier (the ``density`` effect)
temperature      ``temperature.dT`` [K] the whole temperature profile offset (the
                                        ``temperature`` effect): density and speed of sound
position_scale   ``position_scale`` [-] the radar reports ``(1 + s)`` times x, y, z
velocity_scale   ``velocity_scale`` [-] the radar reports ``(1 + s)`` times v
time_offset      ``radar_time.dt`` [s]  the radar clock is late by dt (the ``radar_time``
                                        effect, same sign)
range_bias       ``range_bias`` [m]     added to the radar's measured range
azimuth_bias     ``azimuth_bias`` [rad] added to its measured azimuth
elevation_bias   ``elevation_bias``     added to its measured elevation
                 [rad]
radar_position   ``radar_position.x``,  the radar stands this far [m] from its declared site
                 ``.y``, ``.z`` [m]     (one budget key for the three)
===============  =====================  =====================================================

The radar's sources (``[radar] range_bias_sd``, ``azimuth_bias_sd``, ``elevation_bias_sd``,
``position_sd``) act on its own channels only: each is fitted when the fit's channels depend on
it (a range bias on ``range``, an angle bias on its angle, the site on every native channel) and
otherwise stated as declared but not fitted (:func:`radar_unused`); an undeclared one the
channels depend on is named in the budget's ``conditional_on`` (:func:`radar_conditional`).

One quantity is one parameter: the names of the density, temperature and clock sources are the
parameters of the diagnosis effects of the same quantity, so a ``--with`` of such an effect adds
nothing new (:func:`merge_with_effects`).

Temperature enters through the atmosphere's tables: building an atmosphere per walker would cost
more than the trajectory, so the tables at ``dT = -h, 0, +h`` (``h`` = :data:`T_NODE_SDS` sd,
at least :data:`T_NODE_MIN` K) are interpolated quadratically in dT (the density and 1/a are
smooth in dT: the interpolation error is below 1e-7 relative within the nodes).

The budget (:func:`uncertainty_budget`) is the GUM's linearised split of the joint covariance:
with ``Sigma`` the covariance of (drag coefficients d, sources s) at the ML estimate,

    Sigma_dd = Sigma_d|s + A Sigma_ss A^T,   A = Sigma_ds Sigma_ss^-1,

``statistical`` is the Cd sd from ``Sigma_d|s`` (what the track alone leaves, sources held),
a source's share is ``|g^T A_i| sqrt(Sigma_ss,ii)`` (``g`` the Cd row of the drag basis) and
``cross`` is what the sources' correlations add (signed, in variance units), so that
``statistical^2 + sum share^2 + cross = total^2``.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ...errors import FitWarning
from ...effects.inputs import ExtraParam
from ...effects import LAUNCH_YAW_DECAY, T_NODE_MIN, T_NODE_SDS, confounded_with_cd, effect_sources, \
    partly_trading_with_cd, sources_context, sources_fn  # noqa: F401  (T_NODE_*: re-exported, their old home)
from ...round import SYSTEMATIC_SOURCES
from ...track import NATIVE_CHANNELS
from ..model.problem import Prior
from ..model.layout import ParameterLayout
from ...effects import AZIMUTH_BIAS, CORIOLIS, DENSITY, DRAG_SHAPE, ELEVATION_BIAS, LIFT, RADAR_POSITION, RANGE_BIAS, \
    TEMPERATURE, WIND_PROFILE, YAW_DRAG

__all__ = ["SOURCE_PARAMS", "RADAR_SOURCES", "source_extras", "assumed_extras", "assumed_record", "source_priors", "source_fn", "radar_conditional",
           "radar_unused"]

#: parameter name of each source (the diagnosis effect's name where one exists)
SOURCE_PARAMS = {"mass": "mass", "diameter": "diameter", DENSITY.source: "density.ratio",
                 TEMPERATURE.source: "temperature.dT", "position_scale": "position_scale",
                 "velocity_scale": "velocity_scale", "time_offset": "radar_time.dt"}
#: the radar's systematic sources: budget key -> (``Radar`` attribute of its sd, the native
#: channels it moves; None: every native channel)
RADAR_SOURCES = {RANGE_BIAS.source: ("range_bias_sd", ("range",)),
                 AZIMUTH_BIAS.source: ("azimuth_bias_sd", ("azimuth",)),
                 ELEVATION_BIAS.source: ("elevation_bias_sd", ("elevation",)),
                 RADAR_POSITION.source: ("position_sd", None)}
#: (a declared temperature's interpolation nodes: at +-T_NODE_SDS declared sd, at least T_NODE_MIN
#: K: :data:`bayesdrag.effects.T_NODE_SDS`, imported above)
#: finite-difference step of a source's sensitivities, in declared sd (a 0.05 K temperature step
#: for a 0.5 K sd: well above the integrator's error, well inside the linear range)
FD_STEP_SDS = 0.1
#: how far (in declared sd) a source's bounds lie from its nominal value
BOUND_SDS = 20.0
#: sd of the launch yaw [deg] assumed for a spinning shell whose lift the track shows: a stable
#: shell leaves the muzzle with a first maximum yaw of one to a few degrees. Its decaying induced
#: drag ``Cd k delta^2`` is a change of the Cd curve over the Mach numbers flown first, which the
#: track cannot tell from Cd: held at zero, rows are claimed with the yaw's drag in them
#: (docs/fitting.md, "Launch yaw")
LAUNCH_YAW_SD_DEG = 3.0
#: decay rate [1/s] of the assumed launch yaw's amplitude (its drag decays at twice this): the
#: slow mode of the 6-DOF shells damps with an amplitude e-folding time of 1.7-2 s
#: (:data:`bayesdrag.effects.LAUNCH_YAW_DECAY`, imported above)


def _depends(stem, channels):
    """Whether channels depend on the radar source ``stem`` (bool)."""
    moved = RADAR_SOURCES[stem][1]
    return any(c in (NATIVE_CHANNELS if moved is None else moved) for c in channels)


def radar_conditional(channels, fitted):
    """The radar sources the channels depend on that are not fitted (list of budget keys): the
    Cd is conditional on them (held at their nominal values: no bias, the declared site).

    Parameters
    ----------
    channels : sequence of str
        The fit's channels.
    fitted : collection of str
        The stems of the sources fitted.
    """
    return [k for k in RADAR_SOURCES if k not in fitted and _depends(k, channels)]


def radar_unused(rnd, channels):
    """The declared radar sources the channels do not depend on, with why (dict stem -> str)."""
    out = {}
    for stem, (attr, moved) in RADAR_SOURCES.items():
        if getattr(rnd.radar, attr) is not None and not _depends(stem, channels):
            what = "no radar-native channel" if moved is None else f"no {moved[0]} channel"
            out[stem] = f"[radar] {attr} is declared but the fit has {what}: not fitted (nothing depends on it)"
    return out


def radar_extras(rnd, channels):
    """Extra parameters of the declared radar sources the channels depend on.

    Parameters
    ----------
    rnd : Round
    channels : sequence of str

    Returns
    -------
    tuple of (stem, ExtraParam, nominal, sd)
        ``radar_position`` gives three (``radar_position.x``, ``.y``, ``.z``), one stem.
    """
    out = []
    for stem, (attr, _) in RADAR_SOURCES.items():
        sd = getattr(rnd.radar, attr)
        if sd is None or not _depends(stem, channels):
            continue
        names = (stem,) if stem != RADAR_POSITION.source else tuple(f"{stem}.{a}" for a in "xyz")
        for n in names:
            out.append((stem, ExtraParam(n, 0.0, -BOUND_SDS * sd, BOUND_SDS * sd, sd * FD_STEP_SDS), 0.0, sd))
    return tuple(out)


def source_extras(rnd, channels=()):
    """Extra parameters of the round's declared sources (in :data:`SOURCE_PARAMS` order, then
    the radar's the channels depend on, :func:`radar_extras`).

    Parameters
    ----------
    rnd : Round
    channels : sequence of str
        The fit's channels (the radar's sources act on its native channels only).

    Returns
    -------
    tuple of (stem, ExtraParam, nominal, sd)
    """
    out = []
    m, d = rnd.projectile.mass, rnd.projectile.diameter
    nominal = {"mass": m, "diameter": d, DENSITY.source: 1.0, TEMPERATURE.source: 0.0, "position_scale": 0.0,
               "velocity_scale": 0.0, "time_offset": 0.0}
    for stem, sd in rnd.systematics.declared().items():
        nom = nominal[stem]
        lo, hi = nom - BOUND_SDS * sd, nom + BOUND_SDS * sd
        if stem in ("mass", "diameter", DENSITY.source):
            lo = max(lo, 0.2 * nom)
        out.append((stem, ExtraParam(SOURCE_PARAMS[stem], nom, lo, hi, max(sd * FD_STEP_SDS, 1e-9)), nom, sd))
    return tuple(out) + radar_extras(rnd, channels)


def assumed_extras(effects):
    """The sources the fit assumes beside the declared ones: a launch yaw of sd
    :data:`LAUNCH_YAW_SD_DEG` when ``lift`` is fitted (the track shows a spinning shell's yaw)
    and ``yaw_drag`` is not (one quantity, one parameter).

    Its parameter is the ``yaw_drag`` amplitude ``a = k delta0^2`` (:mod:`bayesdrag.effects`)
    with a Gaussian prior of mean 0 and sd ``k sd^2``, the decay held at
    :data:`LAUNCH_YAW_DECAY`: a launch yaw of one sd adds ``k sd^2`` (2.7 %) to the drag at the
    muzzle. Where the track cannot tell it from the Cd curve, the budget's ``launch_yaw`` share
    is that prior carried into Cd over the first seconds; where it can, the data size it.

    Returns
    -------
    tuple of (stem, ExtraParam, nominal, sd)
    """
    from ...effects import K_YAW, YAW_AMP_MAX

    if LIFT.name not in effects or YAW_DRAG.name in effects:
        return ()
    sd = K_YAW * math.radians(LAUNCH_YAW_SD_DEG) ** 2
    return (("launch_yaw", ExtraParam("launch_yaw.yaw_amp", 0.0, -0.5, YAW_AMP_MAX, sd * FD_STEP_SDS), 0.0, sd),)


def assumed_record(stems):
    """``uncertainty_budget.assumed`` of a fit whose sources are ``stems``: what it assumed and
    why (empty when it assumed nothing)."""
    if "launch_yaw" not in stems:
        return {}
    return {"launch_yaw": {"sd_deg": LAUNCH_YAW_SD_DEG, "decay_per_s": LAUNCH_YAW_DECAY,
                           "why": "the track shows a spinning shell's lift: its launch yaw, which no round states, "
                                  "adds a decaying drag the track cannot tell from the Cd of the first seconds"}}


def source_priors(extras, offset):
    """Gaussian priors of the sources whose parameters start at index ``offset`` of theta."""
    pri = []
    for k, (stem, ep, nom, sd) in enumerate(extras):
        j = offset + k
        row = np.zeros(j + 1)
        row[j] = 1.0
        name = f"{stem}_sd" + (ep.name[len(stem):] if ep.name.startswith(stem + ".") else "")
        pri.append(Prior(name, (lambda th, j=j: th[..., j]), float(nom), float(sd), row=row))
    return tuple(pri)


def source_fn(extras, rnd, model, inner=None, n_inner=0):
    """``effect_fn`` of the sources (and of effects ``inner`` fitted before them).

    Each source enters the simulation through the mapping of the effect of the same quantity
    (:attr:`bayesdrag.effects.Effect.to_inputs`) or its own (:data:`bayesdrag.effects.OWN_SOURCE_INPUTS`),
    added to the inner effects' inputs by field (:func:`bayesdrag.effects.sources_fn`); a declared
    temperature enters as atmosphere tables interpolated quadratically between nodes at
    +-:data:`T_NODE_SDS` sd (at least :data:`T_NODE_MIN` K).

    Parameters
    ----------
    extras : tuple from :func:`source_extras`
    rnd : Round
    model : PointMassModel
        The fit's model (its atmosphere is the nominal one; needed only with a declared
        temperature).
    inner : callable, optional
        ``effect_fn`` of the first ``n_inner`` extra parameters (``--with`` effects).
    n_inner : int

    Returns
    -------
    callable ``E (B, n_inner + len(extras)) -> SimInputs``
    """
    ctx = sources_context({e[0]: e[3] for e in extras}, rnd.projectile.mass, rnd.projectile.diameter,
                          lambda: model.atmosphere)
    stems = [e[0] for e in extras]
    return sources_fn(stems, ctx, inner=inner, n_inner=n_inner)


#: effects that carry a source's quantity (one quantity is one parameter)
EFFECT_SOURCE = effect_sources(SYSTEMATIC_SOURCES)
#: effects fitted beside Cd that trade with it (a temperature's density part is the Cd level, a
#: decaying yaw's drag a change of its shape): with one of them the edges are not placed, since a
#: search over edges then trades the layers with Cd as well
TRADES_WITH_CD = partly_trading_with_cd()
#: effects that cannot be fitted with Cd without a declared sd: a constant factor on the drag
#: (``density``, ``drag_scale``) or its shape (``drag_shape``) is Cd itself
CONFOUNDED_EFFECTS = confounded_with_cd()


def plan_effects(names, rnd):
    """Which requested ``--with`` effects are fitted, and why the others are not.

    Returns
    -------
    (tuple of str, dict name -> reason)
    """
    declared = rnd.systematics.declared()
    keep, skipped = [], {}
    for n in names:
        if n in EFFECT_SOURCE and EFFECT_SOURCE[n] in declared:
            skipped[n] = f"its quantity is the declared {EFFECT_SOURCE[n]}_sd (one quantity, one parameter)"
        elif n in RADAR_SOURCES and getattr(rnd.radar, RADAR_SOURCES[n][0]) is not None:
            skipped[n] = f"its quantity is the declared [radar] {RADAR_SOURCES[n][0]} (one quantity, one parameter)"
        elif n in CONFOUNDED_EFFECTS:
            skipped[n] = ("confounded with the Cd level the fit estimates" if n != DRAG_SHAPE.name else
                          "confounded with the Cd curve the fit estimates") + \
                         (": declare density_sd in the round to include the air density" if n == DENSITY.name else "")
        elif n == CORIOLIS.name and rnd.launch.latitude_deg is None:
            skipped[n] = "needs [launch] latitude"
        elif n not in keep:
            keep.append(n)
    return tuple(keep), skipped


def fit_with_sources(prob, res, rnd, effects=(), wind_layers=None):
    """Stage C of Scheme 1: the fit again with the declared sources and the ``--with`` effects
    as nuisance parameters.

    The drag model, the chosen smoothing, the launch priors, the sample weights and the noise
    model stay as ``prob`` has them; the sources start at their nominal values with their
    priors, the effects at "no effect" (no prior: bounded only; ``wind_profile``'s layers tied
    by their random walk, and held near the round's winds by a declared ``[atmosphere] wind_sd``,
    which also adds the effect when it is not asked for: :mod:`.winds`).

    Parameters
    ----------
    prob : OutputErrorProblem
        The Scheme 1 problem as finally defined.
    res : MLResult
        Its fit.
    rnd : Round
    effects : sequence of str
        Effects of :mod:`bayesdrag.effects` to fit (already checked by :func:`plan_effects`).
    wind_layers : WindLayers or str, optional
        The layers of ``wind_profile``, or the axis to lay them on (the diagnosis's); default:
        laid over the fitted flight by height and by downrange distance, the better fit kept.

    Returns
    -------
    (OutputErrorProblem, MLResult, tuple, tuple, placements)
        The problem with the nuisance parameters, its fit, the sources (:func:`source_extras`)
        and the effects fitted; the inputs and empty tuples when there is nothing to add or the
        fit fails. A declared radar source nothing in the fit depends on is said so in the
        fit's warnings. ``placements``: the wind layers' equivalent placements
        (:func:`.winds.equivalent_placements`), None without placed layers.
    """
    unused = tuple(FitWarning("radar_unused", why, (stem,)) for stem, why in radar_unused(rnd, prob.channels).items())
    out = _fit_sources_effects(prob, res, rnd, effects, wind_layers)
    out = tuple(out) + (None,) * (5 - len(out))
    if not unused:
        return out
    return (out[0], replace(out[1], warnings=tuple(out[1].warnings) + unused)) + tuple(out[2:])


def _fit_sources_effects(prob, res, rnd, effects, wind_layers):
    """:func:`fit_with_sources` but for the note on declared radar sources nothing depends on."""
    from ...effects import EffectContext
    from .winds import PLACED_AXES, WIND_AXES, deviance, edge_penalty, equivalent_placements, fit_layers, placed_layers

    effects = tuple(effects)
    if rnd.systematics.wind_profile is not None and WIND_PROFILE.name not in effects:
        effects = effects + ("wind_profile",)
    L = rnd.launch
    ctx = EffectContext(atmosphere=rnd.atmosphere, latitude_deg=L.latitude_deg, azimuth_deg=L.azimuth_deg,
                        v0=L.velocity)
    if WIND_PROFILE.name not in effects:
        return _fit_with(prob, res, rnd, effects, ctx)
    if wind_layers is None or isinstance(wind_layers, str):
        axes = WIND_AXES if wind_layers is None else (wind_layers,)
        layers = [fit_layers(prob, res, rnd, ax) for ax in axes]
    else:
        layers = [wind_layers]
    layers = [lay for lay in layers if lay is not None]
    if not layers:   # no span to lay layers over (no path): the wind stays the round's
        return _fit_with(prob, res, rnd, tuple(e for e in effects if e != WIND_PROFILE.name), ctx)
    best = None
    for lay in layers:   # the axes compared at their equal grids: one fit each
        out = _fit_with(prob, res, rnd, effects, replace(ctx, wind_layers=lay))
        if out[3] and (best is None or out[1].cost < best[0][1].cost):
            best = (out, lay)
    if best is None:
        return prob, res, (), ()
    if not isinstance(wind_layers, (type(None), str)) or best[1].axis not in PLACED_AXES \
            or any(e in TRADES_WITH_CD for e in effects):
        return best[0]

    def score(lay, start):
        th = None if start is None else start[1].theta
        out = _fit_with(prob, res, rnd, effects, replace(ctx, wind_layers=lay), start=th)
        return (deviance(out[0], out[1]) if out[3] else np.inf), out

    tried = []
    kept = placed_layers(best[1], best[0], deviance(best[0][0], best[0][1]), score,
                         lambda k: edge_penalty(prob, k), tried)[1]
    return kept + (equivalent_placements(tried, kept),)


def _fit_with(prob, res, rnd, effects, ctx, start=None):
    """:func:`fit_with_sources` with the effects' context (and wind layers) settled; ``start``:
    the estimate of a fit with the same parameters (other wind layers) to start from."""
    from ...effects import effect_fn, extra_params, get_effect, static_model
    from ...measure import gun_equivalent
    from ..model.problem import OutputErrorProblem
    from .winds import layer_free, wind_layer_priors

    extras = source_extras(rnd, prob.channels) + assumed_extras(effects)
    effs = tuple(get_effect(n) for n in effects)
    if not extras and not effs:
        return prob, res, (), ()
    model = static_model(prob.model, [e for e in effs if e.k == 0 or e.name == WIND_PROFILE.name], ctx)
    with_par = [e for e in effs if e.k > 0]
    eff_extras = extra_params(with_par)
    if prob.E:
        raise ValueError("fit_with_sources extends a Scheme 1 problem, which has no extra parameters yet")
    lay = ParameterLayout(prob.P)
    n0 = lay.size
    inner_fn = effect_fn(with_par, ctx, res.theta[lay.state]) if with_par else None
    n_inner = len(eff_extras)
    theta0 = np.concatenate([res.theta, [e.start for e in eff_extras], [e[2] for e in extras]])
    if start is not None and len(start) == len(theta0):
        theta0 = np.asarray(start, float).copy()
    seen = gun_equivalent(prob.channels)   # a radar's range, angles, range rate observe x, y, z, v
    # no cross-range view (a range rate alone, a speed): the cross wind is held, as the diagnosis holds it
    eff_free = [layer_free(ctx.wind_layers, e.name, seen) if e.name.startswith("wind_profile.")
                else not (e.name == "wind.wy" and "y" not in seen) for e in eff_extras]
    free = np.concatenate([res.free, eff_free, np.ones(len(extras), bool)])
    names = [""] * n0 + [e.name for e in eff_extras] + [e[1].name for e in extras]
    walk = wind_layer_priors(names, free, rnd.systematics.wind_profile) if ctx.wind_layers is not None else ()
    fn = source_fn(extras, rnd, model, inner=inner_fn, n_inner=n_inner)

    def build(free):
        return OutputErrorProblem(model, prob.track, theta0, free=free, sigma=prob.sigma_fixed,
                                  priors=tuple(prob.priors) + source_priors(extras, n0 + len(eff_extras)) + walk,
                                  channels=prob.channels,
                                  extras=tuple(eff_extras) + tuple(e[1] for e in extras),
                                  effect_fn=fn, t_ic=prob.t_ic, weights=prob.weights, noise_model=prob.noise_model,
                                  site=prob.site, noise_scale=prob.noise_scale)
    p2 = build(free)
    if any(n.startswith("radar_position.") for n in names[n0:n0 + n_inner]):
        p2 = build(_hold_unseen_site(p2, res, free, names, n0 + n_inner))
    res2 = p2.fit(fallback=True)
    if not res2.success:
        return prob, res, (), ()
    return p2, res2, extras, tuple(e.name for e in effs)


def _hold_unseen_site(p2, res, free, names, stop):
    """Free flags with the ``radar_position`` effect's coordinates (before index ``stop``) that the
    channels see no more of than a shift of the flight held at 0 (a range rate from a site on
    the line of fire has no first-order view of a sideways shift: the fit would be singular)."""
    from ...effects import SITE_SEEN_FRACTION, unabsorbed_fraction

    _, _, S = p2.sensitivities(p2.theta0)
    A = p2.weighted(S, res.sigma).reshape(-1, S.shape[-1])
    _, pJ = p2.prior_terms(p2.theta0)
    A = np.vstack([A, pJ]) if pJ.shape[0] else A
    fidx = np.flatnonzero(free)
    site = [k for k, j in enumerate(fidx) if j < stop and names[j].startswith("radar_position.")]
    out = np.array(free, bool, copy=True)
    out[fidx[site]] = unabsorbed_fraction(np.delete(A, site, axis=1), A[:, site]) >= SITE_SEEN_FRACTION
    return out
