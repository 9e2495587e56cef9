"""Planning a drag firing: the Cd accuracy a planned test will reach, before it is fired.

The Fisher information of a simulated track is the accuracy any unbiased fit of that track can
reach (Cramér-Rao). :func:`plan_case` turns one planned case (an elevation and a launch
velocity of the round, the radar's noise and sample interval, the tracked part of the flight)
into the sd of Cd by Mach that the default fit (``bayesdrag fit``, Scheme 1, penalised spline)
will report, and splits it into the statistical part and the share of each declared systematic
source. :func:`plan` runs every elevation x velocity case and
:mod:`bayesdrag.planning.plan` answers "which cases reach the target".

How one case is predicted, and why (decisions):

* **The nominal track** is the round flown by the point mass (scipy reference integrator, as
  ``bayesdrag simulate``) with the *assumed drag*: the round's reference drag, or the drag the
  caller assumes (``assumed_drag``: what the shell is expected to have), or, without either, the
  generic curve :func:`generic_drag` (the shipped 155 mm M101 table; the result says so). The
  samples are every ``dt`` from ``lock_on`` (default launch) to ``loss`` (default impact), in
  the channels the round's ``[radar] sigma`` gives, with its atmosphere and Coriolis geometry.
  More samples than a fit uses (:data:`~bayesdrag.track.MAX_FIT_SAMPLES`) are thinned to every
  k-th as the fit thins such a track: the plan predicts what that fit reports, and a tiny ``dt``
  costs no more than a dense track (:func:`nominal_flight`).
* **The fit's own machinery, not a look-alike.** The drag model is the one the default fit
  builds for such a track (:func:`bayesdrag.estimate.scheme1.fit.build_drag_model`: the table times
  a smooth correction with a table, a spline in Cd without, knots placed from the data's start
  curve): its knots depend on the noise (the start's noise sets how finely the knots may follow
  the shape), so they are placed from *one seeded noisy realisation* of the nominal track
  (:data:`PLAN_SEED`), read by :func:`bayesdrag.estimate.build.start.data_start` exactly as the fit
  reads a track. The launch priors are the fit's (:func:`launch_state_priors`, applied when the
  track starts at launch), the smoothness penalty the fit's (:func:`smoothing.penalty`).
* **The smoothing weight as the fit would choose it on the planned noise.** The fit walks its
  Laplace evidence uphill over :data:`SMOOTHING_GRID` from the middle. Here the same walk runs on
  the *expected* evidence of the linearised problem at the truth (:func:`expected_log_evidence`):
  for whitened Jacobian ``G`` (data, launch priors, penalty), information ``F = G'G`` and the
  penalty's residual ``p`` at the truth, ``E[chi2_min] = const - tr(F^-1 F_meas) + p'p -
  g'F^-1 g`` with ``g = R'p``. Expected rather than one realisation's: one realisation's walk
  stops a grid step early or late at random, the expectation gives the typical choice and needs
  no fit (a fit per case would cost ~1 s; the plan of four cases runs in seconds).
* **Systematic sources** (the round's declared ``_sd`` keys, docs/formats.md). Density, mass and
  diameter (:data:`LEVEL_SOURCES`) are exactly confounded with the level of Cd: the track sees
  only ``rho Cd d^2 / m``, so an error of one is an error of Cd by the same relative amount at
  every Mach, and the data spend no information on it. Their shares are therefore analytic
  (``-cd * density_sd``, ``cd * mass_sd / mass``, ``-2 cd * diameter_sd / diameter``), not
  extra parameters: as parameters, a spline-in-Cd penalty (on the curvature of Cd itself, which
  a scale factor changes) would seem to inform them and put the sd up to 5 % below the
  density's share at some Mach (measured on a 105 mm track without a table), which no fit can
  achieve. The others are extra parameters with Gaussian priors of precision ``1 / sd^2``;
  their track sensitivities are central differences of the nominal track with the round
  perturbed (temperature as the atmosphere's offset, the radar clock as a time shift: the
  recorded time is the true time - dt), and analytic for the linear radar scale factors (``x,
  y, z`` times ``1 + e``, ``v`` times ``1 + e``). They are marginalised in the augmented
  information matrix.
* **The budget** (``by_source``): the information is a sum of independent sources (data noise,
  launch priors, smoothness prior, each systematic prior), so the covariance is exactly
  ``sum_s F^-1 G_s' G_s F^-1`` and the variance of Cd at a Mach splits into non-negative shares
  that add up to the total without a cross term. ``statistical`` is the share of the data, the
  launch priors and the smoothness prior; each systematic source has its own share. The level
  sources add their analytic shares independently (they are confounded with Cd, not with the
  data), so the total never falls below any of them: with ``density_sd`` declared, never below
  ``cd * density_sd`` (Cd ∝ 1/rho), whatever the rounds.
* **Several rounds** (``rounds = N``): each round is fitted and the rounds are pooled, so the
  statistical part falls as ``1 / sqrt(N)``; the round-to-round scatter of Cd (``scatter``,
  relative) enters as the uncertainty of a population mean, ``scatter * cd / sqrt(N)``; the
  systematic sources are shared by the rounds (one air-density measurement method, one radar
  calibration) and do not shrink: ``sd^2 = (stat^2 + (scatter cd)^2) / N + sum_k share_k^2``.
  For a source the data partly identify (temperature, the radar clock) this is slightly
  conservative: pooled data would constrain it a little better.

What the prediction assumes: the point-mass model is right (no unmodelled effect: wind, lift,
yaw drag; see ``bayesdrag diagnose``), the noise is white Gaussian with the stated sd, the
assumed drag is near the shell's (the Fisher information depends on the drag curve through the
trajectory), and the fit converges (it does on such tracks). A penalised fit's reported sd is
its posterior sd under the smoothness prior, which exceeds the spread of its estimates over
noise realisations where the penalty carries information (up to 1.6x on a 105 mm G2 track
without a table, ``tests/acceptance/test_plan_mc.py``); the plan predicts the reported sd.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .._runtime.threads import single_blas
from ..drag import ReferenceTable
from ..dynamics.pointmass import PointMassModel
from ..dynamics.trajectory import initial_state
from ..effects.inputs import ExtraParam
from ..effects import EffectContext, sources_fn
from ..errors import InputError
from ..io.drag_tables import load_m101
from ..measure import angle_blind_samples, channel_values, site_of
from ..measure.geometry import MIN_ANGLE_RANGE, VERTICAL_LINE_OF_SIGHT
from ..round import SYSTEMATIC_SOURCES
from ..synthetic import add_noise
from ..track import ALL_CHANNELS, ANGLE_CHANNELS, MAX_FIT_SAMPLES, NATIVE_CHANNELS, RadarTrack
from ..estimate.build.launch import launch_state_priors
from ..estimate.cd.budget import LEVEL_SOURCES
from ..estimate.model.layout import ParameterLayout
from ..estimate.model.problem import OutputErrorProblem
from ..estimate.scheme1.fit import build_drag_model, coriolis_of
from ..estimate.build.smoothing import SMOOTHING_GRID, penalty, walk_evidence
from ..estimate.build.native_start import start_view
from ..estimate.build.sources import RADAR_SOURCES, radar_extras
from ..estimate.build.start import data_start
from ..effects import TEMPERATURE

__all__ = ["CasePlan", "plan_case", "ASSUMPTIONS", "generic_drag", "drag_assumption", "expected_log_evidence",
           "walk_evidence", "case_mach_grid", "systematic_parameters", "level_shares", "LEVEL_SOURCES", "DEFAULT_DT", "PLAN_SEED",
           "PLAN_MACH_STEP", "MIN_TRACKED_SAMPLES", "declared_sources", "PLAN_SOURCES"]

#: default radar sample interval [s] (the paper's radar, as ``bayesdrag simulate``)
DEFAULT_DT = 0.027
#: seed of the one noisy realisation of the nominal track whose start curve places the knots
PLAN_SEED = 0
#: Mach step of the predicted rows (the fit's Cd grid step)
PLAN_MACH_STEP = 0.01
#: fewest tracked samples a case needs (a fit of ~40 coefficients needs many more samples)
MIN_TRACKED_SAMPLES = 30
#: longest flight simulated [s]
MAX_FLIGHT_TIME = 600.0
#: most samples the nominal flight is evaluated at in one go (checked from ``dt`` before
#: simulating: 600 s at dt >= 6 ms); a finer ``dt`` finds the impact on :data:`COARSE_DT` first
MAX_DIRECT_SAMPLES = 100_000
COARSE_DT = 0.05
#: tolerances of the nominal flight's integration (relative; absolute [m, m/s]): millimetres over
#: a flight, far below any radar's noise (the simulator's tighter 1e-11 is for reference tracks;
#: here the nominal track only sets where the sensitivities are taken)
NOMINAL_RTOL = 1e-8
NOMINAL_ATOL = 1e-6
#: finite-difference steps of the temperature offset [K] and the clock offset [s]
TEMPERATURE_STEP = 0.05
TIME_STEP = 1e-4
#: what every plan assumes (written in plan.json and plan.html)
ASSUMPTIONS = (
    "the point-mass model is the shell's physics (no wind, lift, yaw drag or other unmodelled effect)",
    "white Gaussian radar noise with the round's [radar] sigma in every channel it gives",
    "the assumed drag curve is near the shell's (the information depends on the drag through the trajectory)",
    "the fit is the default one (Scheme 1, penalised spline, launch priors when tracked from launch) and "
    "converges; its smoothing weight is the one the evidence would choose on the planned noise",
    "systematic sources (declared _sd keys) are shared by the rounds; undeclared ones are held at their "
    "nominal values and the Cd is conditional on them",
)


def generic_drag():
    """The generic drag curve of a plan without a reference drag: the 155 mm M101 zero-yaw
    drag shipped with bayesdrag (BRL MR-1167, Mach 0.5-2.6), a typical spin-stabilised HE shell.

    Why a real shell's table and not a smooth made-up curve: the Fisher information depends on
    the drag through the trajectory (how fast the shell slows, where it crosses Mach 1), and a
    measured curve has a realistic transonic rise; beyond Mach 2.6 it is held constant.
    """
    m = load_m101()
    return ReferenceTable(m.mach, m.cd_values, source="generic curve: the 155 mm M101 table shipped with bayesdrag")


def drag_assumption(rnd, assumed_drag=None):
    """The drag the nominal track is flown with.

    Returns
    -------
    (ReferenceTable, str, bool)
        The table, where it comes from (for the report) and whether it is the generic curve.
    """
    if assumed_drag is not None:
        if not isinstance(assumed_drag, ReferenceTable):
            raise InputError(f"assumed_drag must be a ReferenceTable (a mach,cd table), got "
                             f"{type(assumed_drag).__name__}")
        return assumed_drag, f"the table given as the assumed drag ({assumed_drag.source or 'a mach,cd table'})", False
    if rnd.reference_drag is not None:
        ref = rnd.reference_drag
        return ref, f"the round's reference drag ({rnd.projectile.reference_drag_path or ref.source})", False
    g = generic_drag()
    return g, g.source, True


def radar_channels(rnd):
    """The channels the radar gives (those with a ``[radar] sigma``: the gun frame's ``x, y, z,
    v`` or the radar's own ``range, azimuth, elevation, range_rate``, seen from its site) and
    their sd."""
    sig = dict(rnd.radar.sigma)
    chans = tuple(c for c in ALL_CHANNELS if c in sig)
    if not chans:
        raise InputError(f"{rnd.path or 'round'}: plan needs the radar's noise: [radar] sigma = "
                         f"{{x = 1.0, y = 1.0, z = 1.0, v = 0.3}} (the channels it tracks and their sd)")
    return chans, {c: float(sig[c]) for c in chans}


def case_round(rnd, elevation_deg, velocity):
    """The round with its launch at the planned elevation [deg] and velocity [m/s]."""
    try:
        launch = replace(rnd.launch, elevation_deg=float(elevation_deg), velocity=float(velocity))
    except ValueError as exc:
        raise InputError(f"planned case: {exc}") from None
    if not launch.elevation_deg > 0.0:
        raise InputError(f"planned elevation {launch.elevation_deg:g} deg is not allowed; a planned "
                         f"firing needs an elevation in (0, 90) deg")
    return replace(rnd, launch=launch)


def nominal_flight(rnd_case, truth, dt, lock_on=None, loss=None):
    """The nominal trajectory of one case, sampled like the radar, at most as densely as a fit
    uses a track.

    The radar's samples are every ``dt`` from launch, impact included, in the tracked part;
    more than :data:`~bayesdrag.track.MAX_FIT_SAMPLES` of them are thinned to every k-th
    (first and last kept) exactly as :func:`~bayesdrag.track.thin_for_fit` thins the track the
    fit gets, so the plan predicts what that fit reports and its work is bounded. The bound is
    checked before simulating: a flight of up to :data:`MAX_FLIGHT_TIME` at ``dt`` gives at most
    :data:`MAX_DIRECT_SAMPLES` samples, else the impact is found on a coarser grid first and only
    the kept samples are evaluated (``plan --dt 0.0001`` asked for 400 000 samples per case and
    15 GB).

    Returns
    -------
    (t, state, mach, t_impact)
        Tracked sample times [s] (N,), states (N, 6), air-relative Mach (N,) and impact time.
    """
    L = rnd_case.launch
    model = PointMassModel(rnd_case.projectile.mass, rnd_case.projectile.diameter, truth, rnd_case.atmosphere,
                           coriolis=coriolis_of(rnd_case))
    s0 = initial_state(L.velocity, L.elevation_deg)
    direct = math.ceil(MAX_FLIGHT_TIME / dt) <= MAX_DIRECT_SAMPLES
    tr = model.simulate((), s0, backend="scipy", stop_at_impact=True, dt=dt if direct else COARSE_DT,
                        max_time=MAX_FLIGHT_TIME, rtol=NOMINAL_RTOL, atol=NOMINAL_ATOL)
    if not tr.success or tr.t_impact is None:
        raise InputError(f"the planned case QE {L.elevation_deg:g} deg, {L.velocity:g} m/s does not land within "
                         f"{MAX_FLIGHT_TIME:.0f} s ({tr.message})")
    t_imp = float(tr.t_impact)
    t0 = 0.0 if lock_on is None else float(lock_on)
    t1 = t_imp if loss is None else min(float(loss), t_imp)
    if t0 >= t_imp:
        raise InputError(f"option lock_on = {lock_on:g} s is not allowed for QE {L.elevation_deg:g} deg, "
                         f"{L.velocity:g} m/s: the shell lands at {t_imp:.1f} s; use a lock-on before impact")
    t_all = tr.t if direct else _radar_times(t_imp, dt)
    keep = np.flatnonzero((t_all >= t0 - 1e-9) & (t_all <= t1 + 1e-9))
    if keep.size < MIN_TRACKED_SAMPLES:
        raise InputError(f"the tracked part {t0:g}-{t1:.2f} s of QE {L.elevation_deg:g} deg, {L.velocity:g} m/s "
                         f"has {keep.size} samples at dt = {dt:g} s; a fit needs at least "
                         f"{MIN_TRACKED_SAMPLES}: track longer (lock_on, loss) or sample faster (dt)")
    k = -(-keep.size // MAX_FIT_SAMPLES)
    idx = np.arange(0, keep.size, k)
    if idx[-1] != keep.size - 1:
        idx = np.append(idx, keep.size - 1)
    sel = keep[idx]
    if direct:
        return tr.t[sel], tr.state[sel], tr.mach[sel], t_imp
    tr = model.simulate((), s0, t_all[sel], backend="scipy", rtol=NOMINAL_RTOL, atol=NOMINAL_ATOL)
    if not tr.success or tr.t.size != sel.size:
        raise InputError(f"the planned case QE {L.elevation_deg:g} deg, {L.velocity:g} m/s could not be sampled "
                         f"at dt = {dt:g} s ({tr.message})")
    return tr.t, tr.state, tr.mach, t_imp


def _radar_times(t_imp, dt):
    """The radar's sample times of a flight landing at ``t_imp``: every ``dt`` from launch, and
    the impact (as :meth:`PointMassModel.simulate` gives them with ``dt``)."""
    t = np.arange(0.0, t_imp, dt)
    return np.append(t, t_imp) if t_imp - t[-1] > 1e-9 else t


def _check_line_of_sight(rc, chans, site, t, state, elevation_deg, velocity):
    """Refuse angle channels from a site whose line of sight to the shell is undefined at a
    planned sample (:func:`~bayesdrag.measure.geometry.angle_blind_samples`: a site at the muzzle,
    or on the vertical of the line of fire): there the angles' sensitivities divide by zero,
    which no planned case can hold.

    Raises
    ------
    InputError
        Naming the site, the case, the time and the geometry, and what to change.
    """
    angles = [c for c in chans if c in ANGLE_CHANNELS]
    blind = angle_blind_samples(state, site) if angles else ()
    if len(blind) == 0:
        return
    i = int(blind[0])
    pos = [float(v) for v in rc.radar.position]
    launch = " (the muzzle at launch)" if i == 0 else ""
    R = float(np.linalg.norm(state[i, :3] - np.asarray(pos)))
    if R < MIN_ANGLE_RANGE:
        how = (f"is {R:.2g} m from it at t = {t[i]:.3g} s{launch}, nearer than {MIN_ANGLE_RANGE:g} m, where a "
               f"radar has no angles" + (" (the site is the muzzle, the default when the round gives no [radar] "
                                         "position)" if not any(pos) else ""))
        fix = "give the radar's own site ([radar] position or --radar-sites)"
    else:
        where = "below" if state[i, 2] < pos[2] else "above"
        how = (f"passes straight {where} it at t = {t[i]:.3g} s{launch}, its line of sight within "
               f"{math.degrees(VERTICAL_LINE_OF_SIGHT):g} deg of the vertical, where the azimuth is undefined")
        fix = "move the site off the vertical of the line of fire (a few metres aside)"
    raise InputError(f"radar site {pos} m: QE {elevation_deg:g} deg, {velocity:g} m/s {how}: {' and '.join(angles)} "
                     f"cannot be planned from there; {fix}, or plan range and range_rate only")


def _outputs(state, chans, site):
    """The channels (dict of (N,) arrays) a radar at ``site`` records of the states (N, 6)."""
    y = channel_values(state, chans, site)
    return {c: y[:, j] for j, c in enumerate(chans)}


def site_round(rnd, position):
    """The round with its radar at ``position`` [m] in the gun frame (a candidate site)."""
    try:
        radar = replace(rnd.radar, position=tuple(float(v) for v in position))
    except (TypeError, ValueError) as exc:
        raise InputError(f"radar site {position!r}: {exc}") from None
    return replace(rnd, radar=radar)


#: every systematic source a plan carries, in the order of its budget: the round's declared
#: ``_sd`` keys, then the radar's biases and site (those its planned channels depend on)
PLAN_SOURCES = tuple(SYSTEMATIC_SOURCES) + tuple(RADAR_SOURCES)


def declared_sources(rnd, chans=()):
    """The declared systematic sources a plan of channels ``chans`` carries (dict stem -> sd):
    the round's ``_sd`` keys, and the radar's biases and site where the channels depend on them
    (a range bias needs a range channel; the site, any radar-native channel)."""
    radar = {stem: sd for stem, _, _, sd in radar_extras(rnd, chans)}
    return {**rnd.systematics.declared(), **radar}


def systematic_parameters(rnd, chans=()):
    """The declared systematic sources as extra parameters of the output-error problem.

    Returns
    -------
    (list of (stem, ExtraParam, prior sd), list of (stem, prior sd))
        Sources entering the simulation (temperature, time_offset, and for the channels
        ``chans`` the radar's biases and site: finite differences by the problem; the site is
        three parameters of one stem) and the radar scale factors (position_scale,
        velocity_scale: analytic sensitivities). The level sources (:data:`LEVEL_SOURCES`) are
        not parameters: their shares are :func:`level_shares`.
    """
    declared = rnd.systematics.declared()
    steps = {TEMPERATURE.source: (0.0, TEMPERATURE_STEP), "time_offset": (0.0, TIME_STEP)}
    sim, scale = [], []
    for stem, sd in declared.items():
        if stem in LEVEL_SOURCES:
            continue
        if stem in steps:
            start, h = steps[stem]
            sim.append((stem, ExtraParam(f"systematic.{stem}", start, -np.inf, np.inf, h), float(sd)))
        else:
            scale.append((stem, float(sd)))
    sim += [(stem, p, float(sd)) for stem, p, _, sd in radar_extras(rnd, chans)]
    return sim, scale


def level_shares(rnd, cd):
    """Signed Cd shares {stem: (K,)} of the declared level sources (mass, diameter, density) at
    the assumed Cd ``cd`` (K,): exact, since the track cannot tell them from the level of Cd."""
    m0, d0 = rnd.projectile.mass, rnd.projectile.diameter
    return {stem: cd * LEVEL_SOURCES[stem](float(sd), m0, d0)
            for stem, sd in rnd.systematics.declared().items() if stem in LEVEL_SOURCES}


def systematic_effect_fn(rnd, sim):
    """``effect_fn`` of the simulated systematic sources (B, E) -> SimInputs: each through the
    mapping the fit's declared sources use (:func:`bayesdrag.effects.sources_fn`), the temperature
    as one atmosphere per trajectory."""
    return sources_fn([s for s, _, _ in sim], EffectContext(atmosphere=rnd.atmosphere))


@dataclass(frozen=True, eq=False)
class CaseInformation:
    """The whitened Jacobians of one case at the truth.

    Attributes
    ----------
    A : (N C, n) ndarray
        Data rows (sensitivities over the noise sd) for the free parameters: drag coefficients
        (P), the free initial state, then the systematic parameters.
    L : (k, n) ndarray
        Launch-prior rows (whitened by their sd).
    P : int
        Drag coefficients (the first P columns).
    n_stat : int
        Columns of the drag and the state (the systematic ones follow).
    systematics : tuple of (stem, sd)
        The systematic columns in order, with their prior sd (in the column's unit).
    """

    A: np.ndarray
    L: np.ndarray
    P: int
    n_stat: int
    systematics: tuple


def case_information(rnd_case, dm, track, state0, theta_drag, sigma, chans):
    """Data and launch-prior information of one case (:class:`CaseInformation`).

    The drag and state sensitivities and those of the simulated systematic sources come from one
    batch of central differences of :class:`OutputErrorProblem` (the fit's own sensitivities);
    the radar scale factors are analytic.
    """
    P = dm.n_params
    sim, scale = systematic_parameters(rnd_case, chans)
    model = PointMassModel(rnd_case.projectile.mass, rnd_case.projectile.diameter, dm, rnd_case.atmosphere,
                           coriolis=coriolis_of(rnd_case))
    extras = tuple(p for _, p, _ in sim)
    theta = np.concatenate([theta_drag, state0, [p.start for p in extras]])
    free = np.ones(theta.size, bool)
    lay = ParameterLayout(P, len(extras))
    if "y" not in chans:
        free[lay.index("y")] = free[lay.index("vy")] = False
    if not any(c in chans for c in ("x", "y", "z")):
        free[lay.position] = False
    native = any(c in NATIVE_CHANNELS for c in chans)
    if native:
        free[lay.state] = True        # a radar's range and angles see every coordinate ...
        if "azimuth" not in chans and abs(float(rnd_case.radar.position[1])) < 1e-6:
            free[lay.index("y")] = free[lay.index("vy")] = False   # ... nor across a plane of fire holding its site
    prob = OutputErrorProblem(model, track, theta, free=free, sigma=sigma, channels=chans, extras=extras,
                              effect_fn=systematic_effect_fn(rnd_case, sim) if extras else None,
                              site=site_of(rnd_case, chans) if native else None)
    y, _, S = prob.sensitivities(theta)
    if not np.all(np.isfinite(S)):
        raise InputError("the planned track's sensitivities are not finite (the flight leaves the drag "
                         "model's range?)")
    cols = [S]
    for stem, _ in scale:
        g = np.zeros_like(y)
        for j, c in enumerate(chans):
            if (stem == "position_scale" and c in "xyz") or (stem == "velocity_scale" and c == "v"):
                g[:, j] = y[:, j]
        cols.append(g[:, :, None])
    S = np.concatenate(cols, axis=-1)
    w = 1.0 / np.array([sigma[c] for c in chans])
    A = (S * w[None, :, None]).reshape(-1, S.shape[-1])
    n_stat = int(free[:lay.state.stop].sum())
    L = np.zeros((0, A.shape[1]))
    if abs(float(track.t[0])) < 1e-9:
        _, J = prob.replace(priors=launch_state_priors(rnd_case.launch, P)).prior_terms(theta)
        L = np.concatenate([J, np.zeros((J.shape[0], len(scale)))], axis=1)
    systematics = tuple((s, sd) for s, _, sd in sim) + tuple(scale)
    return CaseInformation(A, L, P, n_stat, systematics)


def _penalty_rows(pen, sd, n, P, theta_drag):
    """Whitened penalty rows (K, n) at penalty sd ``sd`` and the penalty residuals at the truth."""
    _, D, sds = pen(sd)
    R = np.zeros((D.shape[0], n))
    R[:, :P] = D / sds[:, None]
    p = -(D @ theta_drag) / sds
    return R, p, sds


def expected_log_evidence(F_meas, R, p, sds, prior_diag):
    """Expected Laplace log evidence (up to a constant) of the linearised penalised problem at
    the truth, and its effective number of parameters.

    Parameters
    ----------
    F_meas : (n, n) ndarray
        Information of the measurements and the launch priors (``A'A + L'L``).
    R : (K, n) ndarray
        Whitened penalty rows; ``p`` (K,) the penalty residuals at the truth; ``sds`` (K,)
        their sd.
    prior_diag : (n,) ndarray
        Prior precision of the systematic parameters (0 elsewhere).

    Returns
    -------
    (float, float, ndarray)
        Expected log evidence, edf of the fit (``n - tr(F^-1 R'R)``) and ``F^-1``.

    The fit's evidence (:func:`bayesdrag.estimate.build.smoothing.fit_penalised`) is
    ``-chi2_min / 2 + log|F^-1| / 2 - sum log sds``; for ``y = J theta* + e`` the minimum of the
    penalised chi2 has expectation ``const - tr(F^-1 F_meas) + p'p - g'F^-1 g``, ``g = R'p``.
    """
    F = F_meas + R.T @ R + np.diag(prior_diag)
    Finv = np.linalg.inv(F)
    sign, logdet = np.linalg.slogdet(F)
    if sign <= 0:
        return -np.inf, float("nan"), Finv
    g = R.T @ p
    chi2 = -np.trace(Finv @ F_meas) + p @ p - g @ Finv @ g
    ev = -0.5 * chi2 - 0.5 * logdet - float(np.sum(np.log(sds)))
    edf = float(F.shape[0] - np.trace(Finv @ (R.T @ R)) - np.count_nonzero(prior_diag))
    return float(ev), edf, Finv


def case_mach_grid(lo, hi, step=PLAN_MACH_STEP):
    """Rows of a case: multiples of ``step`` inside [lo, hi] (at least the two ends)."""
    a, b = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)
    if b < a:
        return np.array([round(0.5 * (lo + hi), 4)])
    return np.round(np.arange(a, b + 1) * step, 4)


@dataclass(frozen=True, eq=False)
class CasePlan:
    """The predicted Cd accuracy of one planned case.

    Attributes
    ----------
    elevation_deg : float, deg
    velocity : float, m/s
    rounds : int
        Rounds fired in this case (pooled).
    scatter : float
        Round-to-round relative sd of Cd stated by the user [-].
    dt : float, s
    t_tracked : (float, float), s
        First and last tracked sample.
    t_impact : float, s
    samples : int
    mach_range : (float, float)
        Mach span the tracked flight covers.
    mach : (K,) ndarray
    cd : (K,) ndarray
        The assumed drag at ``mach``.
    statistical : (K,) ndarray
        Statistical share of the Cd sd of one round (data noise, launch priors, smoothness prior).
    by_source : dict stem -> (K,) ndarray
        Signed share of each declared systematic source (the Cd error per 1 sd of the source).
    smoothing : dict
        The penalty sd the evidence would choose, its edf, ``at_grid_end`` and the grid.
    drag_model : str
        The fit's drag model for this track (name and number of coefficients).
    notes : tuple of str
    radar : dict or None
        A radar's own channels: its site ``position`` [m] in the gun frame and the ``channels``.
    model : DragModel
        That drag model itself, with ``base`` (the table and shape its penalty is relative to,
        :func:`build_drag_model`) and ``truth_params`` (its coefficients of the assumed drag):
        enough to rebuild the fit's problem for this case.
    """

    elevation_deg: float
    velocity: float
    rounds: int
    scatter: float
    dt: float
    t_tracked: tuple
    t_impact: float
    samples: int
    mach_range: tuple
    mach: np.ndarray
    cd: np.ndarray
    statistical: np.ndarray
    by_source: dict
    smoothing: dict
    drag_model: str
    notes: tuple = field(default=())
    model: object = field(default=None, repr=False)
    base: tuple | None = field(default=None, repr=False)
    truth_params: np.ndarray = field(default=None, repr=False)
    radar: dict | None = None

    @property
    def systematic(self):
        """Combined systematic share (K,): the root sum of squares of ``by_source``."""
        if not self.by_source:
            return np.zeros_like(self.mach)
        return np.sqrt(np.sum([v ** 2 for v in self.by_source.values()], axis=0))

    @property
    def sd_one_round(self):
        """The Cd sd one fit of one round will report (K,)."""
        return np.sqrt(self.statistical ** 2 + self.systematic ** 2)

    def sd_for(self, rounds):
        """Predicted sd (K,) of the pooled Cd of ``rounds`` rounds of this case: statistical part
        and round-to-round scatter over sqrt(rounds), systematic part shared."""
        var = (self.statistical ** 2 + (self.scatter * self.cd) ** 2) / rounds + self.systematic ** 2
        return np.sqrt(var)

    @property
    def sd(self):
        """Predicted sd (K,) with this case's ``rounds``."""
        return self.sd_for(self.rounds)

    @property
    def relative_sd(self):
        return self.sd / self.cd


def plan_case(rnd, elevation_deg, velocity, *, dt=DEFAULT_DT, rounds=1, scatter=0.0, lock_on=None, loss=None,
              assumed_drag=None, seed=PLAN_SEED):
    """Predict the Cd sd by Mach of one planned case (module docstring: how and why).

    Parameters
    ----------
    rnd : Round
        Its projectile, atmosphere, ``[radar] sigma`` (required) and declared systematic sds.
    elevation_deg : float, deg
        Quadrant elevation, in (0, 90).
    velocity : float, m/s
        Launch velocity.
    dt : float, s
        Radar sample interval.
    rounds : int
        Rounds fired in this case.
    scatter : float
        Round-to-round relative sd of Cd [-] (0.01 = 1 %).
    lock_on, loss : float or None, s
        Tracked part of the flight (default: launch to impact).
    assumed_drag : ReferenceTable, optional
        The drag the shell is expected to have (default: the round's reference, else
        :func:`generic_drag`).
    seed : int
        Seed of the noisy realisation that places the knots.

    Returns
    -------
    CasePlan
    """
    with single_blas():   # the kernel's threads use the cores, not BLAS's
        truth, _, _ = drag_assumption(rnd, assumed_drag)
        chans, sigma = radar_channels(rnd)
        rc = case_round(rnd, elevation_deg, velocity)
        t, state, mach, t_imp = nominal_flight(rc, truth, dt, lock_on, loss)
        thinned = int(round((t[1] - t[0]) / dt))          # k > 1: every k-th radar sample (nominal_flight)
        site = site_of(rc, chans)
        _check_line_of_sight(rc, chans, site, t, state, elevation_deg, velocity)
        out = _outputs(state, chans, site)
        flat = [c for c in chans if c in NATIVE_CHANNELS
                and np.ptp(out[c]) <= 1e-12 * max(1.0, float(np.max(np.abs(out[c]))))]
        if len(flat) == len(chans):
            flat = []                     # nothing left to plan with: the track's own check says why
        if flat:
            # a radar on the line of fire sees a constant azimuth: no information, and no track has it
            chans = tuple(c for c in chans if c not in flat)
            sigma = {c: sigma[c] for c in chans}
            out = {c: out[c] for c in chans}
        track = RadarTrack(t, out, {}, source=f"planned QE {elevation_deg:g} deg, {velocity:g} m/s")
        noisy = add_noise(track, sigma, np.random.default_rng(seed))
        start = data_start(start_view(noisy, rc, site_of(rc, chans)), rc)   # as the fit reads its start
        lo, hi = float(mach.min()), float(mach.max())
        span = (min(start.mach_span[0], lo), max(start.mach_span[1], hi))
        dm, base = build_drag_model("spline", rnd.reference_drag, start, span=span)
        m = np.linspace(*dm.fit_range, 400)
        theta_drag = dm.params_for(m, truth.value(m))
        info = case_information(rc, dm, track, state[0], theta_drag, sigma, chans)
        smoothing, Finv = _choose_smoothing(info, penalty(dm, base), theta_drag)
        grid = case_mach_grid(lo, hi)
        cd = truth.value(grid)
        stat, shares = _budget(info, Finv, dm.jacobian(grid), smoothing["R"], level_shares(rc, cd))
        smoothing.pop("R")
        notes = []
        if flat:
            notes.append(f"QE {elevation_deg:g}° at {velocity:g} m/s: the radar at {list(rc.radar.position)} m sees a "
                         f"constant {', '.join(flat)} (on the line of fire): planned without it")
        if thinned > 1:
            notes.append(f"QE {elevation_deg:g}° at {velocity:g} m/s: samples every {dt:g} s are more than a fit uses "
                         f"({MAX_FIT_SAMPLES}): planned with one sample in {thinned} ({t.size} samples), as the fit "
                         f"thins such a track")
        if loss is not None and loss > t_imp:
            notes.append(f"QE {elevation_deg:g}° at {velocity:g} m/s lands at {t_imp:.1f} s, before the loss at "
                         f"{loss:g} s: tracked to impact")
        hi_table = truth.mach_range[1]
        if hi > hi_table + 0.05:
            notes.append(f"the flight reaches Mach {hi:.2f}, beyond the assumed drag table's last row "
                         f"(Mach {hi_table:.2f}): Cd is held at its end value above it")
        kind = "the table times a spline correction" if base is not None and base[0] is not None else "spline in Cd"
        radar = None
        if any(c in NATIVE_CHANNELS for c in chans):
            radar = {"position": [float(v) for v in rc.radar.position], "channels": list(chans)}
        return CasePlan(float(elevation_deg), float(velocity), int(rounds), float(scatter), float(dt),
                        (float(t[0]), float(t[-1])), t_imp, int(t.size), (lo, hi), grid, cd,
                        stat, shares, smoothing, f"{kind}, {dm.n_params} coefficients", tuple(notes),
                        dm, base, theta_drag, radar)


def _choose_smoothing(info, pen, theta_drag):
    """The fit's evidence walk on the expected evidence; returns the record and ``F^-1``."""
    n = info.A.shape[1]
    F_meas = info.A.T @ info.A + info.L.T @ info.L
    prior = np.zeros(n)
    for j, (_, sd) in enumerate(info.systematics):
        prior[info.n_stat + j] = 1.0 / sd ** 2
    cache = {}

    def evaluate(i):
        if i not in cache:
            R, p, sds = _penalty_rows(pen, SMOOTHING_GRID[i], n, info.P, theta_drag)
            ev, edf, Finv = expected_log_evidence(F_meas, R, p, sds, prior)
            cache[i] = (ev, edf, Finv, R)
        return cache[i][0]

    i = walk_evidence(evaluate, len(SMOOTHING_GRID))
    ev, edf, Finv, R = cache[i]
    end = "stiff" if i == 0 else ("flexible" if i == len(SMOOTHING_GRID) - 1 else None)
    record = {"sd": float(SMOOTHING_GRID[i]), "edf": edf, "at_grid_end": end, "R": R,
              "grid": [{"sd": float(SMOOTHING_GRID[k]), "expected_log_evidence": v[0]} for k, v in sorted(cache.items())]}
    return record, Finv


def _budget(info, Finv, B, R, level):
    """Statistical share (K,) and signed systematic shares {stem: (K,)} of the Cd sd at the rows
    of ``B`` (K, P), with the analytic shares ``level`` of the level sources (module docstring:
    the shares add up in squares to the total)."""
    n = Finv.shape[0]
    Bemb = np.zeros((B.shape[0], n))
    Bemb[:, :info.P] = B
    X = Finv @ Bemb.T                                           # (n, K)
    stat_var = np.sum((info.A @ X) ** 2, axis=0) + np.sum((R @ X) ** 2, axis=0)
    if info.L.size:
        stat_var += np.sum((info.L @ X) ** 2, axis=0)
    shares = {}
    for j, (stem, sd) in enumerate(info.systematics):
        x = X[info.n_stat + j] / sd
        # one stem of several parameters (the radar's site x, y, z): their shares add in squares
        shares[stem] = np.sqrt(shares[stem] ** 2 + x ** 2) if stem in shares else x
    shares.update(level)
    order = [s for s in PLAN_SOURCES if s in shares]
    return np.sqrt(stat_var), {s: shares[s] for s in order}
