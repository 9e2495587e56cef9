"""The output-error problem: one track, one point-mass model, the parameters and their priors
(paper Eq. 19). :mod:`bayesdrag.estimate.model.ml` fits it.

* parameters ``theta`` = drag-model coefficients + initial state ``X0, Y0, Z0, Ux0, Uy0, Uz0``
  at ``t_ic`` (by default the first sample time), each free or fixed, then optional extra
  (effect) parameters;
* outputs = the channels the track has (any subset of x, y, z, v and of the radar-native range,
  azimuth, elevation, range_rate, computed by :mod:`bayesdrag.measure` from the state and the
  radar's site: residuals in the radar's own units, azimuth residuals wrapped);
* cost (Eq. 19) ``J = sum_i (z_i - y_i(theta))^T R^-1 (z_i - y_i(theta))`` with ``R`` diagonal
  (one noise variance per channel: the round's ``[radar] sigma`` where given, else estimated by
  relaxation), plus Gaussian priors as pseudo-measurements (extra weighted residuals).

Extra parameters (the diagnosis' unmodelled effects, :mod:`bayesdrag.effects`) are appended
after the initial state: ``theta = [drag (P), state (6), extras (E)]``. Each :class:`ExtraParam`
has a name, start value, bounds and finite-difference step; an ``effect_fn`` maps the extra
values of a batch (B, E) to :class:`SimInputs` (kernel override columns, per-trajectory
atmospheres, a radar clock offset ``dt``: the model is evaluated at ``t + dt``).

Optional per-sample weights (N, C) in [0, 1] multiply ``R^-1`` sample by sample: 0 removes a
sample (a flagged gross outlier) from the cost, the sensitivities, the bounds and the residual
autocorrelation.

Noise model per channel (``noise_model``): ``white`` (independent samples, Eq. 19 as written) or
``ar1``: white noise of sd ``sigma_c`` plus a first-order autoregressive model-error process
(coefficient ``rho_c`` per median sample interval, variance ``q_c sigma_c^2``); residuals and
sensitivities are whitened by its Kalman filter (:mod:`bayesdrag.estimate.model.colored`, which says
why a pure AR(1) of the whole residual is not enough), so the least squares is the generalised one
and its information matrix gives the colored bound. The AR parameters of a channel are estimated
from its residuals like the noise sd (relaxation); the radar's sigma, when given, is not used for
an ``ar1`` channel.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from ...effects.inputs import ExtraParam, SimInputs  # noqa: F401  (the extras this problem fits)
from ...errors import InputError
from ...measure import RadarSite, channel_jacobian, channel_values, near_branch, sample_noise
from ...track import ALL_CHANNELS, NATIVE_CHANNELS
from . import colored, restricted
from .layout import ParameterLayout

IC_NAMES = ("X0", "Y0", "Z0", "Ux0", "Uy0", "Uz0")
_CH_INDEX = {"x": 0, "y": 1, "z": 2}

#: finite-difference steps for the initial state (m, m/s): small against radar noise, large
#: against the kernel's rounding
IC_STEPS = (0.01, 0.01, 0.01, 0.001, 0.001, 0.001)

#: longest backward extrapolation from the initial state for a shifted radar clock [s]
MAX_BACKWARD = 0.25
#: noise models of a channel
NOISE_MODELS = ("white", "ar1")
#: passes over the ``ar1`` channels of the restricted noise search (each channel's depends on the
#: others' through their information), and the change of log(1 - rho) below which it stops [-]
RESTRICTED_PASSES, RESTRICTED_PASS_TOL = 2, 0.01


@dataclass(frozen=True)
class Prior:
    """Gaussian prior on a function of the parameters, ``f(theta) ~ N(mean, sd^2)``.

    ``fn`` maps the full parameter vector (P + 6,) to a float; ``name`` labels it. ``row``, when
    given, says the prior is linear: ``fn(theta) = row @ theta`` with ``row`` of the full
    parameter length, so its Jacobian needs no finite differences (the spline smoothness penalty
    has ~45 such priors). ``depends``, when given, names the indices of theta that ``fn`` reads:
    the finite-difference Jacobian of a nonlinear prior then perturbs those alone (the others'
    columns are exactly zero).
    """

    name: str
    fn: object
    mean: float
    sd: float
    row: object = None
    depends: tuple = None


def outputs(traj_state, channels, site=None, measured=None, offset=None, site_shift=None):
    """Model outputs (B, N, C) for channels from states (B, N, 6).

    Parameters
    ----------
    traj_state : (B, N, 6) array
    channels : sequence of str
    site : RadarSite, optional
        The radar's site (native channels); default the muzzle, azimuth 0.
    measured : (N, C) array, optional
        The measurements: a predicted azimuth is put on the branch (whole turns) nearest its
        measurement, so that measurement minus prediction is the wrapped difference.
    offset : dict channel -> (B,) array, optional
        Constants added per trajectory (a radar's range [m] and angle [rad] biases).
    site_shift : (B, 3) array, optional, m
        The radar's site moved per trajectory: its native channels are seen from there.
    """
    site = RadarSite() if site is None else site
    # a trial step that made a trajectory diverge gives inf or nan outputs, which the fit rejects:
    # numpy's overflow warnings would only alarm the user (a real rifle shot printed several)
    with np.errstate(over="ignore", invalid="ignore"):
        return _outputs(traj_state, channels, site, measured, offset, site_shift)


def _outputs(traj_state, channels, site, measured, offset, site_shift):
    """:func:`outputs` with the site settled."""
    out = channel_values(traj_state, channels, site)
    native = [j for j, c in enumerate(channels) if c in NATIVE_CHANNELS]
    if site_shift is not None and native:
        # the line of sight depends on the shell's position less the site's: shift the shell
        moved = np.array(traj_state, float, copy=True)
        moved[..., :3] -= np.asarray(site_shift, float)[:, None, :]
        out[..., native] = channel_values(moved, [channels[j] for j in native], site)
    for j, c in enumerate(channels):
        if offset and c in offset:
            out[..., j] += np.asarray(offset[c], float)[:, None]
    if measured is not None and "azimuth" in channels:
        j = list(channels).index("azimuth")
        out[..., j] = near_branch(out[..., j], measured[:, j])
    return out


class OutputErrorProblem:
    """An output-error fit of one track with one point-mass model.

    Parameters
    ----------
    model : PointMassModel
        Its ``drag`` is the model whose coefficients are estimated.
    track : RadarTrack
    theta0 : (P + 6,) array
        Starting values: drag coefficients, then the state at ``track.t[0]``.
    free : (P + 6,) bool array, optional
        Which parameters are estimated (default all).
    sigma : dict channel -> sd, optional
        Fixed noise sd; channels missing here have their sd estimated by relaxation.
    priors : sequence of Prior, optional
    channels : sequence of str, optional
        Channels to fit (default: all the track has).
    extras : sequence of ExtraParam, optional
        Effect parameters appended after the initial state (``theta0`` then has P + 6 + E
        entries; their start values are taken from ``theta0``).
    effect_fn : callable, optional
        ``effect_fn(E)`` with ``E`` (B, n_extras) returns :class:`SimInputs`; required with extras.
    t_ic : float, optional, s
        Time of the initial state (default ``track.t[0]``; the diagnosis uses 0 = launch).
    weights : (N, C) array, optional
        Per-sample weights in [0, 1] on ``R^-1`` (0 drops a sample).
    noise_model : dict channel -> {"white", "ar1"}, optional
        Default white for every channel. ``ar1`` channels need unit weights.
    site : RadarSite, optional
        Where the radar stands (its native channels are seen from there); default the muzzle
        with azimuth 0, which only gun-frame channels may rely on.
    noise_scale : (N, C) array, optional
        Each sample's noise sd over its channel's sd (``sigma_c``); default read off the
        track's ``sigma_<channel>`` and ``snr`` columns (:func:`bayesdrag.measure.sample_noise`),
        else 1. A ``sigma_<channel>`` column's median also fixes the channel's sd unless
        ``sigma`` gives it.
    effect_names : sequence of str, optional
        The effects the extras belong to, in the order of the parameters (the diagnosis's
        reports read them).

    Notes
    -----
    A problem is a value: set once here and frozen. A fit that continues from another start,
    with other priors, weights, noise sd or noise models works on :meth:`replace`'s copy, so a
    problem handed to a function is never changed behind its caller's back. The finite-difference
    steps stay those of the first start (a continued fit differentiates as the first one did).
    """

    #: what :meth:`replace` may change; everything else follows from the model and the track
    REPLACEABLE = ("theta0", "priors", "sigma_fixed", "weights", "noise_model")

    def __init__(self, model, track, theta0, free=None, sigma=None, priors=(), channels=None,
                 extras=(), effect_fn=None, t_ic=None, weights=None, noise_model=None, site=None,
                 noise_scale=None, effect_names=()):
        self.model = model
        self.track = track
        self.site = RadarSite() if site is None else site
        self.channels = tuple(channels) if channels is not None else track.names
        for c in self.channels:
            if c not in ALL_CHANNELS or track.channels.get(c) is None:
                raise InputError(f"{track.source}: channel {c!r} is not in the track (has {', '.join(track.names)})")
        self.P = model.drag.n_params
        self.extras = tuple(extras)
        self.E = len(self.extras)
        if self.E and effect_fn is None:
            raise ValueError("extra parameters need an effect_fn mapping them to the simulation")
        self.effect_fn = effect_fn
        self.t_ic = float(track.t[0]) if t_ic is None else float(t_ic)
        self.names = tuple(model.drag.param_names) + IC_NAMES + tuple(e.name for e in self.extras)
        n = self.layout.size
        self.theta0 = np.asarray(theta0, dtype=float).copy()
        if self.theta0.shape != (n,):
            raise ValueError(f"theta0 must have {n} entries, got {self.theta0.shape}")
        self.free = np.ones(n, bool) if free is None else np.asarray(free, bool).copy()
        self.sigma_fixed = {c: float(s) for c, s in (sigma or {}).items() if c in self.channels}
        self.priors = tuple(priors)
        self.z = np.stack([track.channels[c] for c in self.channels], axis=-1)  # (N, C)
        if noise_scale is None:
            noise_scale, level = sample_noise(track, self.channels)
            for c, s in level.items():
                self.sigma_fixed.setdefault(c, s)
        #: each sample's noise sd over its channel's (N, C); ones when every sample is alike
        self.noise_scale = np.ones_like(self.z) if noise_scale is None else np.array(noise_scale, float)
        if self.noise_scale.shape != self.z.shape or not np.all(self.noise_scale > 0):
            raise ValueError(f"noise_scale must be (N, C) = {self.z.shape} and positive")
        if weights is None:
            self.weights = np.ones_like(self.z)
        else:
            self.weights = np.array(weights, dtype=float)
            if self.weights.shape != self.z.shape or np.any(self.weights < 0) or np.any(self.weights > 1):
                raise ValueError(f"weights must be (N, C) = {self.z.shape} in [0, 1]")
        for j, c in enumerate(self.channels):
            if np.ptp(self.z[:, j]) == 0.0 and c != "y":
                raise InputError(f"{track.source}: channel {c} is constant ({self.z[0, j]}); "
                                 f"it carries no information — drop the column or fix the track")
        self.noise_model = MappingProxyType({c: "white" for c in self.channels})
        self._set_noise_model(noise_model or {})
        dt = np.diff(np.asarray(track.t, float))
        ratio = dt / float(np.median(dt)) if dt.size else dt
        #: sample intervals over their median (exactly 1.0 on a regular grid)
        self.dt_ratio = np.where(np.abs(ratio - 1.0) < 1e-6, 1.0, ratio)
        lb, ub = model.drag.bounds
        big = np.full(6, np.inf)
        self.lower = np.concatenate([lb, -big, [e.lower for e in self.extras]])
        self.upper = np.concatenate([ub, big, [e.upper for e in self.extras]])
        self.steps = np.concatenate([np.maximum(1e-6, 1e-5 * np.abs(self.theta0[:self.P]) + 1e-7),
                                     IC_STEPS, [e.step for e in self.extras]])
        self.effect_names = tuple(effect_names)
        n_free = self.effective_free()
        if self.z.shape[0] * len(self.channels) <= n_free:
            raise InputError(f"{track.source}: {self.z.shape[0]} samples x {len(self.channels)} channels "
                             f"are too few for {n_free} free parameters")
        for a in (self.theta0, self.free, self.z, self.noise_scale, self.weights, self.lower, self.upper,
                  self.steps, self.dt_ratio):
            a.flags.writeable = False
        self._frozen = True

    def __setattr__(self, name, value):
        if getattr(self, "_frozen", False):
            raise AttributeError(f"an OutputErrorProblem is frozen: use problem.replace({name}=...) "
                                 f"for a copy with another {name}")
        object.__setattr__(self, name, value)

    def part(self, index, theta0=None):
        """The same problem over the samples ``index`` of its track: its model, parameters, priors,
        effects, noise models, per-sample arrays and finite-difference steps, started at
        ``theta0`` (default its own start). A fit of it is the nested-data fit :mod:`~bayesdrag.estimate.scheme1.effect_sizes`
        compares with the whole's.

        Parameters
        ----------
        index : (n,) int array
            Sample indices, increasing.
        theta0 : (P + 6 + E,) array, optional

        Returns
        -------
        OutputErrorProblem
        """
        idx = np.asarray(index)
        new = OutputErrorProblem(self.model, self.track.subset(idx), self.theta0 if theta0 is None else theta0,
                                 free=self.free, sigma=self.sigma_fixed, priors=self.priors, channels=self.channels,
                                 extras=self.extras, effect_fn=self.effect_fn, t_ic=self.t_ic,
                                 weights=self.weights[idx], noise_model=dict(self.noise_model), site=self.site,
                                 noise_scale=self.noise_scale[idx], effect_names=self.effect_names)
        object.__setattr__(new, "steps", self.steps)    # it differentiates as this problem does
        return new

    def replace(self, **changes):
        """A copy of this problem with some of :attr:`REPLACEABLE` changed.

        Parameters
        ----------
        theta0 : (P + 6 + E,) array, optional
            Another start.
        priors : sequence of Prior, optional
        sigma_fixed : dict channel -> sd, optional
            The noise sd held fixed ({} estimates every channel's).
        weights : (N, C) array in [0, 1], optional
        noise_model : dict channel -> {"white", "ar1"}, optional
            Channels' noise models; channels not named keep theirs.

        Returns
        -------
        OutputErrorProblem
            Sharing the track, model and every array not changed with this one.
        """
        unknown = set(changes) - set(self.REPLACEABLE)
        if unknown:
            raise TypeError(f"replace() cannot change {', '.join(sorted(unknown))}; "
                            f"it changes {', '.join(self.REPLACEABLE)}")
        new = copy.copy(self)
        object.__setattr__(new, "_frozen", False)
        if "theta0" in changes:
            th = np.array(changes["theta0"], dtype=float)
            if th.shape != self.theta0.shape:
                raise ValueError(f"theta0 must have {self.theta0.size} entries, got {th.shape}")
            th.flags.writeable = False
            new.theta0 = th
        if "priors" in changes:
            new.priors = tuple(changes["priors"])
        if "sigma_fixed" in changes:
            new.sigma_fixed = {c: float(s) for c, s in changes["sigma_fixed"].items() if c in self.channels}
        if "weights" in changes:
            w = np.array(changes["weights"], dtype=float)
            if w.shape != self.z.shape or np.any(w < 0) or np.any(w > 1):
                raise ValueError(f"weights must be (N, C) = {self.z.shape} in [0, 1]")
            w.flags.writeable = False
            new.weights = w
        if "noise_model" in changes:
            new._set_noise_model(changes["noise_model"])
        new._frozen = True
        return new

    # ----------------------------------------------------------------------------------------
    def effective_free(self):
        """Free parameters the data must determine: the free count less the independent
        constraints the priors put on them (a prior is a pseudo-measurement: a penalised
        spline's smoothness rows leave only the penalty's null space, a straight-line
        correction, to the data however many coefficients it has)."""
        n_free = int(self.free.sum())
        if not self.priors or self.z.shape[0] * len(self.channels) > n_free:
            return n_free        # enough samples either way: the rank is not needed
        J = self.prior_terms(self.theta0)[1]
        J = J[:, np.all(np.isfinite(J), axis=0)] if J.size else J
        return n_free - (int(np.linalg.matrix_rank(J)) if J.size else 0)

    def _set_noise_model(self, model):
        """Set channels' noise models (dict channel -> ``white`` or ``ar1``); others unchanged
        (while the problem is built: :meth:`replace` afterwards)."""
        new = dict(self.noise_model)
        for c, m in model.items():
            if c not in self.channels:
                continue
            if m not in NOISE_MODELS:
                raise ValueError(f"noise model {m!r} of channel {c} is not known; allowed: {', '.join(NOISE_MODELS)}")
            if m == "ar1" and np.any(self.weights[:, self.channels.index(c)] != 1.0):
                raise ValueError(f"channel {c}: AR(1) noise needs unit sample weights (not a Student-t fit)")
            new[c] = m
        object.__setattr__(self, "noise_model", MappingProxyType(new))

    @property
    def ar_channels(self):
        """Channels with ``ar1`` noise."""
        return tuple(c for c in self.channels if self.noise_model[c] == "ar1")

    def whiten(self, a, ar):
        """Whiten residual-like arrays along samples (the Kalman filter of the ``ar1`` channels).

        Parameters
        ----------
        a : (N, C, ...) array
            Residuals (N, C) [m or m/s] or sensitivities (N, C, k).
        ar : dict channel -> (rho, q) or None
            Model-error parameters of the ``ar1`` channels; white channels pass unchanged.

        Returns
        -------
        Array of ``a``'s shape: standardised innovations, independent with the white noise
        variance under the noise model.
        """
        if not ar or not any(ar.get(c, (0.0, 0.0))[1] > 0.0 for c in self.ar_channels):
            return a
        out = np.array(a, float, copy=True)
        for j, c in enumerate(self.channels):
            if self.noise_model[c] == "ar1" and c in ar and ar[c][1] > 0.0:
                out[:, j], _ = colored.standardize(a[:, j], ar[c][0], ar[c][1], self.dt_ratio)
        return out

    def weighted(self, a, sigma, ar=None):
        """Whitened, noise-normalised residuals (N, C) or sensitivities (N, C, k): the rows of
        the least-squares problem at white noise sd ``sigma`` (dict) and ``ar`` (dict)."""
        sw = np.sqrt(self.weights) / np.array([sigma[c] for c in self.channels])[None, :]
        if a.ndim == 3:
            sw = sw[:, :, None]
        return self.whiten(self.standardized(a), ar) * sw

    def standardized(self, a):
        """Residual-like arrays (N, C) or (N, C, k) over each sample's noise scale: samples of
        one channel then share its sd (``a`` itself when every sample is alike)."""
        if np.all(self.noise_scale == 1.0):
            return a
        return a / (self.noise_scale if a.ndim == 2 else self.noise_scale[:, :, None])

    def update_noise(self, resid, sigma, ar):
        """Noise relaxation: new ``(sigma, ar)`` at fixed parameters.

        White channels: the round's sigma where fixed, else the weighted residual rms. ``ar1``
        channels: sigma, rho and q of maximum likelihood (:func:`colored.fit_noise`, warm
        started at the previous ``ar``).
        """
        sig = self.update_sigma(resid, sigma)
        new = {}
        for j, c in enumerate(self.channels):
            if self.noise_model[c] != "ar1":
                continue
            start = (ar or {}).get(c)
            s, rho, q, _ = colored.fit_noise(resid[:, j] / self.noise_scale[:, j], self.dt_ratio, start=start)
            new[c] = (rho, q)
            sig[c] = s
        return sig, new

    def update_noise_restricted(self, resid, sigma, ar, S, priors=None):
        """:meth:`update_noise` with the ``ar1`` channels' noise of restricted likelihood
        (:func:`restricted.fit_noise_restricted`), started and bounded at the plain estimate.

        The channels are searched in turn, each with the others' information and gradient at
        their latest noise, for :data:`RESTRICTED_PASSES` passes at most (fewer once no channel's
        correlation moves by more than :data:`RESTRICTED_PASS_TOL` in ``log(1 - rho)``).

        Parameters
        ----------
        resid : (N, C) ndarray
        sigma, ar : dict
            The current noise.
        S : (N, C, K) ndarray
            Sensitivities of the free parameters.
        priors : (pr, pJ), optional
            The priors' residuals (M,) and Jacobian (M, K) at the parameters.

        Returns
        -------
        sigma, ar : dict
        """
        sig, new = self.update_noise(resid, sigma, ar)
        plain = dict(new)
        if priors is not None and priors[0].size:
            A_p, g_p = priors[1].T @ priors[1], priors[1].T @ priors[0]
        else:
            A_p = g_p = 0.0
        Sn = self.standardized(S)
        rn = self.standardized(resid)

        def info(j, c):
            # channel j's information and gradient at its current noise (a channel's rows whiten alone)
            sw = np.sqrt(self.weights[:, j]) / sig[c]
            if self.noise_model[c] == "ar1" and new.get(c, (0.0, 0.0))[1] > 0.0:
                u, _ = colored.standardize(np.column_stack([rn[:, j], Sn[:, j, :]]), new[c][0], new[c][1],
                                           self.dt_ratio)
            else:
                u = np.column_stack([rn[:, j], Sn[:, j, :]])
            u = u * sw[:, None]
            return u[:, 1:].T @ u[:, 1:], u[:, 1:].T @ u[:, 0]

        parts = [info(j, c) for j, c in enumerate(self.channels)]
        for _ in range(RESTRICTED_PASSES):
            moved = 0.0
            for j, c in enumerate(self.channels):
                if c not in new:
                    continue
                A_o = sum(p[0] for k, p in enumerate(parts) if k != j) + A_p
                g_o = sum(p[1] for k, p in enumerate(parts) if k != j) + g_p
                s, rho, q = restricted.fit_noise_restricted(rn[:, j], self.dt_ratio, plain[c], Sn[:, j, :], A_o, g_o)
                moved = max(moved, abs(math.log((1.0 - rho) / (1.0 - new[c][0]))))
                new[c] = (rho, q)
                sig[c] = s
                parts[j] = info(j, c)
            if moved < RESTRICTED_PASS_TOL:
                break
        return sig, new

    @property
    def layout(self):
        """Where the drag coefficients, the initial state and the effects sit in theta
        (:class:`~bayesdrag.estimate.model.layout.ParameterLayout`)."""
        return ParameterLayout(self.P, self.E)

    def predict(self, thetas):
        """Model outputs (B, N, C) and Mach (B, N) for parameter sets (B, P + 6)."""
        thetas = np.atleast_2d(thetas)
        if not self.E:
            lay = self.layout
            tr = self.model.simulate_batch(thetas[:, lay.drag], thetas[:, lay.state], self.track.t,
                                           t_start=self.t_ic)
            return self.outputs(tr.state), tr.mach
        inp = self.effect_fn(thetas[:, self.layout.effects])
        y, mach = self._predict_effects(thetas, inp)
        if inp.output_scale:
            for j, c in enumerate(self.channels):
                if c in inp.output_scale:
                    y[:, :, j] *= np.asarray(inp.output_scale[c], float)[:, None]
        return y, mach

    def outputs(self, state, inp=None, g=None):
        """The problem's channels (B, N, C) from states (B, N, 6), seen from its radar site
        (moved and biased per trajectory by :class:`SimInputs` ``inp``, rows ``g`` of its batch)."""
        if inp is None or (not inp.output_offset and inp.site_shift is None):
            return outputs(state, self.channels, self.site, self.z)
        off = {c: np.asarray(v, float)[g] for c, v in inp.output_offset.items()}
        shift = None if inp.site_shift is None else np.asarray(inp.site_shift, float)[g]
        return outputs(state, self.channels, self.site, self.z, off, shift)

    def _predict_effects(self, thetas, inp):
        """Outputs and Mach of a batch whose extras give ``inp`` (:class:`SimInputs`)."""
        B = thetas.shape[0]
        shift = np.zeros(B) if inp.time_shift is None else np.asarray(inp.time_shift, float)
        y = np.full((B, self.track.n, len(self.channels)), np.nan)
        mach = np.full((B, self.track.n), np.nan)
        # one kernel call per distinct clock offset (a finite-difference batch has at most 3)
        for s in np.unique(shift):
            g = np.flatnonzero(shift == s)
            t_out = self.track.t + s
            if t_out[0] < self.t_ic - MAX_BACKWARD:
                continue  # too far before the initial state: left NaN, the fit rejects the step
            ov = {k: np.asarray(v, float)[g] for k, v in inp.overrides.items()}
            atm = None if inp.atmospheres is None else [inp.atmospheres[i] for i in g]
            if inp.atmosphere_tables is not None:
                atm = np.asarray(inp.atmosphere_tables)[g]
            state, m = self._simulate_shifted(thetas[g], t_out, ov, atm)
            y[g] = self.outputs(state, inp, g)
            mach[g] = m
        return y, mach

    def _simulate_shifted(self, th, t_out, ov, atm):
        """States (G, N, 6) and Mach (G, N) at ``t_out``; samples before the initial state (an
        early radar clock) are extrapolated backwards to second order from it."""
        pre = t_out < self.t_ic - 1e-12
        if not pre.any():
            tr = self.model.simulate_batch(th[:, self.layout.drag], th[:, self.layout.state], t_out, t_start=self.t_ic,
                                           overrides=ov, atmospheres=atm)
            return tr.state, tr.mach
        hh = 1e-3
        t_post = t_out[~pre]
        extra = [t for t in (self.t_ic, self.t_ic + hh) if not np.any(np.abs(t_post - t) < 1e-9)]
        t_req = np.sort(np.concatenate([extra, t_post]))
        tr = self.model.simulate_batch(th[:, self.layout.drag], th[:, self.layout.state], t_req, t_start=self.t_ic,
                                       overrides=ov, atmospheres=atm)
        st = tr.state
        i1 = int(np.argmin(np.abs(t_req - (self.t_ic + hh))))
        a0 = (st[:, i1, 3:] - st[:, 0, 3:]) / (t_req[i1] - t_req[0])
        tau = (t_out[pre] - self.t_ic)[None, :, None]
        pos = st[:, :1, :3] + st[:, :1, 3:] * tau + 0.5 * a0[:, None, :] * tau**2
        vel = st[:, :1, 3:] + a0[:, None, :] * tau
        post = np.searchsorted(t_req, t_post - 1e-9)
        state = np.concatenate([np.concatenate([pos, vel], axis=-1), st[:, post]], axis=1)
        mach = np.concatenate([np.repeat(tr.mach[:, :1], int(pre.sum()), axis=1), tr.mach[:, post]], axis=1)
        return state, mach

    def sensitivities(self, theta):
        """Outputs at theta (N, C) and d outputs / d theta_free (N, C, n_free) by central
        differences, all trajectories in one batch."""
        idx = np.flatnonzero(self.free)
        h = self.steps[idx]
        batch = np.repeat(theta[None], 1 + 2 * idx.size, axis=0)
        for k, j in enumerate(idx):
            batch[1 + 2 * k, j] += h[k]
            batch[2 + 2 * k, j] -= h[k]
        if idx.size and not self.E and any(c in NATIVE_CHANNELS for c in self.channels):
            return self._native_sensitivities(theta, batch[1:], h)
        if idx.size:
            y, _ = self.predict(batch[1:])
            S = (y[0::2] - y[1::2]) / (2 * h[:, None, None])  # (n_free, N, C)
        else:
            S = np.zeros((0, self.z.shape[0], self.z.shape[1]))
        # the outputs at theta itself come from a one-trajectory call, the same code path as the
        # trial steps of the fit (a batch runs the SIMD lanes, a single trajectory the scalar
        # code; they agree to ~1e-9 m, but at the optimum that is the whole cost change and a
        # mixed comparison would make every step look uphill)
        y0, mach0 = self.predict(theta[None])
        return y0[0], mach0[0], np.moveaxis(S, 0, -1)

    def _native_sensitivities(self, theta, batch, h):
        """:meth:`sensitivities` of a problem without effects that measures a radar's own
        channels: central differences of the states, mapped to the channels by their analytic
        Jacobian at theta (:func:`bayesdrag.measure.channel_jacobian`). The chain rule agrees
        with differences of the channels to the differences' own truncation error, and skips the
        line-of-sight geometry (arctangents, square roots) on every trial trajectory, which cost
        as much as integrating them."""
        lay = self.layout
        tr = self.model.simulate_batch(batch[:, lay.drag], batch[:, lay.state], self.track.t, t_start=self.t_ic)
        dstate = tr.state[0::2] - tr.state[1::2]                                # (n_free, N, 6)
        dstate /= (2 * h)[:, None, None]         # in place: a second temporary of this size took half the time
        one = self.model.simulate_batch(theta[None, lay.drag], theta[None, lay.state], self.track.t,
                                        t_start=self.t_ic)
        J = channel_jacobian(one.state[0], self.channels, self.site)             # (N, C, 6)
        S = J @ dstate.transpose(1, 2, 0)                                       # (N, C, n_free)
        return self.outputs(one.state)[0], one.mach[0], S

    def prior_terms(self, theta):
        """Weighted prior residuals (K,) and their Jacobian (K, n_free)."""
        if not self.priors:
            return np.zeros(0), np.zeros((0, int(self.free.sum())))
        idx = np.flatnonzero(self.free)
        r = np.array([(p.mean - p.fn(theta)) / p.sd for p in self.priors])
        J, other = self._linear_prior_jacobian(theta.size)
        if other:
            J = J.copy()
            tp, tm = theta.copy(), theta.copy()
            for k, j in enumerate(idx):
                rows = [i for i in other if self.priors[i].depends is None or j in self.priors[i].depends]
                if not rows:
                    continue
                tp[j] += self.steps[j]
                tm[j] -= self.steps[j]
                J[rows, k] = [(self.priors[i].fn(tp) - self.priors[i].fn(tm)) / (2 * self.steps[j] * self.priors[i].sd)
                              for i in rows]
                tp[j] = tm[j] = theta[j]
        return r, J

    def _linear_prior_jacobian(self, n):
        """The Jacobian (K, n_free) of the priors with the rows of the linear ones filled (the
        others zero) and the indices of the others: made once per set of priors (a fit asks on
        every step; the problem's priors and free parameters never change)."""
        memo = self.__dict__.get("_prior_jacobian_memo")
        if memo is not None and memo[0] is self.priors and memo[1] == n:
            return memo[2], memo[3]
        idx = np.flatnonzero(self.free)
        J = np.zeros((len(self.priors), idx.size))
        lin = np.array([p.row is not None for p in self.priors])
        if lin.any():
            rows = np.array([np.pad(np.asarray(p.row, float), (0, n - len(p.row))) for p in self.priors
                             if p.row is not None])
            sds = np.array([p.sd for p in self.priors if p.row is not None])
            J[lin] = rows[:, idx] / sds[:, None]
        J.flags.writeable = False
        other = [k for k, p in enumerate(self.priors) if p.row is None]
        object.__setattr__(self, "_prior_jacobian_memo", (self.priors, n, J, other))
        return J, other

    # ----------------------------------------------------------------------------------------

    def fit(self, max_iter=50, tol_cost=1e-8, tol_step=1e-3, tol_sigma=1e-3, fallback=False, restricted=True):
        """Fit by Levenberg-Marquardt with noise relaxation (:func:`bayesdrag.estimate.model.ml.fit`).

        Parameters
        ----------
        max_iter : int
        tol_cost, tol_step, tol_sigma : float
            Convergence rules (:mod:`bayesdrag.estimate.model.ml`).
        fallback : bool
            Continue an unconverged fit with scipy's trust-region reflective least squares.
        restricted : bool
            ``ar1`` noise of restricted likelihood once converged (:func:`~bayesdrag.estimate.model.ml.fit`).

        Returns
        -------
        MLResult
        """
        from . import ml

        return ml.fit(self, max_iter=max_iter, tol_cost=tol_cost, tol_step=tol_step, tol_sigma=tol_sigma,
                      fallback=fallback, restricted=restricted)

    def fit_trust_region(self, theta, sigma, max_nfev=200):
        """Minimise the cost at fixed noise sd with scipy's trust-region reflective least
        squares from ``theta`` (:func:`bayesdrag.estimate.model.ml.fit_trust_region`)."""
        from . import ml

        return ml.fit_trust_region(self, theta, sigma, max_nfev=max_nfev)

    def update_sigma(self, resid, old):
        sig = {}
        for j, c in enumerate(self.channels):
            if c in self.sigma_fixed:
                sig[c] = self.sigma_fixed[c]
            else:
                w = self.weights[:, j]
                e = resid[:, j] / self.noise_scale[:, j]
                sig[c] = max(float(np.sqrt(np.sum(w * e ** 2) / max(np.sum(w), 1.0))), 1e-9)
        return sig

    def cost(self, resid, sigma, theta, ar=None):
        """Eq. 19 at noise ``sigma`` (and model-error parameters ``ar``), plus the prior terms."""
        J = float(np.sum(self.weighted(resid, sigma, ar) ** 2))
        if self.priors:
            J += float(sum(((p.mean - p.fn(theta)) / p.sd) ** 2 for p in self.priors))
        return J
