"""A start from the data: Mach span, Cd(M) and the initial state read off the track itself.

The maximum-likelihood fit is a local method: it needs a start from which Gauss-Newton walks
downhill to the right answer, and a drag model whose Mach span and knots match the flight. None
of this may come from the round's nominal launch values or a generic curve: a round file can be
wrong by a lot (a nominal muzzle velocity 15 % off, a time origin at the first radar sample), and
a generic 155 mm curve is a factor two off a bullet's. This module reads them from the track:

1. **Smoothed kinematics** (:func:`smooth_kinematics`). Each channel is smoothed by a cubic
   smoothing spline whose weight generalised cross-validation chooses (scipy's
   ``make_smoothing_spline``, or :func:`~.gcv_spline.gcv_smoothing_spline`, the same spline
   found faster; it handles gaps and uneven sampling). Speed ``V`` comes from the
   ``v`` channel when there is one, else from the derivative of the positions; the path angle
   ``gamma`` from the positions (``atan2(dz/dt, horizontal speed)``), or, without ``z``, from
   ``cos gamma = (dx/dt) / V`` or, for a speed-only (Doppler) track, by integrating the gravity
   turn ``d gamma/dt = -g cos gamma / V`` from the round's elevation. Height ``z`` from its
   channel or by integrating ``V sin gamma``.
2. **Cd per sample** (:func:`drag_samples`): the drag deceleration along the path is
   ``D = -dV/dt - g sin gamma`` (point mass, no wind), and ``Cd = D / (k rho(z) V^2)`` with
   ``k = pi d^2 / (8 m)``, at ``M = V / a(z)`` in the round's atmosphere.
3. **Start curve** (:func:`start_curve`): the per-sample values averaged in 0.01 Mach bins and
   smoothed across Mach (again a GCV smoothing spline, weighted by the bin counts), so that an
   ascent and a descent through the same Mach agree on one curve. It is within a few percent
   of the truth wherever the track flies (measured in ``tests/unit/test_start.py``); in a steep
   drag rise it is smeared over the Mach the smoothing window spans, which the fit then sharpens.
4. **Initial state** at the first sample from the smoothed positions and velocity.

The same kinematics give a check of the units from the physics (:func:`check_gravity_units`): a
point-mass path bends under gravity alone, ``d gamma / dt = -g cos gamma / V``, so the gravity a
track implies, in its own length unit, is ~9.81 in metres and ~32.2 in feet whatever the round
says.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...air.atmosphere import G0
from ...errors import InputError
from ..model.noise import hf_noise_sd
from .gcv_spline import gcv_smoothing_spline

#: Mach bin width of the start curve
START_BIN = 0.01
#: lower and upper clip of the start curve's Cd (a start, not an answer: keeps a noisy end sane)
START_CD_CLIP = (0.02, 3.0)
#: Mach scale over which :attr:`DataStart.shape` is smoothed (a steep rise is ~0.1 Mach wide)
SHAPE_SCALE = 0.04
#: a window of the model-based start spans at most this relative change of speed, and this many
#: samples (7 parameters need a few dozen values; too long a window averages Cd over much Mach)
WINDOW_DV = 0.08
WINDOW_MIN, WINDOW_MAX = 12, 60
#: fewest samples the smoothing spline accepts (scipy needs 5)
MIN_SMOOTH_SAMPLES = 5
#: gravity check: a track's implied gravity off from g by more than this factor is a unit error
GRAVITY_RATIO_LIMIT = 1.25
#: ... and by more than this many of its own standard errors
GRAVITY_SIGNIFICANCE = 5.0
#: (gravity ratio, what it means) for the unit check from the physics
_GRAVITY_UNITS = (
    (1.0 / 0.3048, "x, y, z and v look like feet and ft/s (expected m and m/s)"),
    (1.0 / 0.9144, "x, y, z and v look like yards and yd/s (expected m and m/s)"),
    (1e-3, "x, y, z and v look like km and km/s (expected m and m/s)"),
    (1e3, "x, y, z and v look like mm and mm/s (expected m and m/s), or t like milliseconds"),
)


@dataclass(frozen=True, eq=False)
class Kinematics:
    """Smoothed flight state along a track.

    Attributes
    ----------
    t : (N,) ndarray [s]
        Sample times.
    speed : (N,) ndarray [m/s]
        Ground speed V.
    dspeed : (N,) ndarray [m/s^2]
        dV/dt.
    gamma : (N,) ndarray [rad]
        Path angle above the horizontal.
    heading : (N,) ndarray [rad]
        Direction of the horizontal velocity, from +x towards +y.
    z : (N,) ndarray [m]
        Height above the muzzle.
    position : (N, 3) ndarray [m]
        Smoothed x, y, z (missing channels: reconstructed or 0).
    gamma_measured : bool
        True when gamma comes from the positions (x or y, and z); False when reconstructed by
        the gravity turn (then it cannot check the units).
    notes : tuple of str
        What was assumed where a channel was missing.
    """

    t: np.ndarray
    speed: np.ndarray
    dspeed: np.ndarray
    gamma: np.ndarray
    heading: np.ndarray
    z: np.ndarray
    position: np.ndarray
    gamma_measured: bool
    notes: tuple = ()


@dataclass(frozen=True, eq=False)
class DataStart:
    """What the track says before any fit.

    Attributes
    ----------
    mach_span : (float, float)
        Mach range the track flies (from the smoothed speed and height).
    mach : (K,) ndarray
        Mach grid of the start curve (step :data:`START_BIN`, covering ``mach_span``).
    cd : (K,) ndarray
        Start Cd on that grid.
    shape : (K,) ndarray
        The same, smoothed over :data:`SHAPE_SCALE` Mach: where the drag bends, without the
        percent-level wiggles the noise leaves in ``cd`` (knots and penalty weights use it).
    shape_noise : float
        Robust relative scatter of ``cd`` about ``shape`` (1.4826 x median absolute relative
        difference): how much of the start's fine structure is noise.
    state0 : (6,) ndarray
        Position [m] and velocity [m/s] at the first sample.
    samples_mach, samples_cd : (N,) ndarray
        The per-sample values behind the curve.
    kinematics : Kinematics
    notes : tuple of str
    track_mach : (N,) ndarray or None
        Mach at each sample, in time order, from the smoothed speed (where the track's samples
        lie in Mach: how finely it can resolve Cd(M); :mod:`bayesdrag.estimate.build.basis`).
    """

    mach_span: tuple
    mach: np.ndarray
    cd: np.ndarray
    shape: np.ndarray
    shape_noise: float
    state0: np.ndarray
    samples_mach: np.ndarray
    samples_cd: np.ndarray
    kinematics: Kinematics
    notes: tuple = field(default=())
    track_mach: np.ndarray | None = None

    @property
    def mach_step(self):
        """Median |Delta M| between consecutive samples (0 without :attr:`track_mach`)."""
        if self.track_mach is None or self.track_mach.size < 2:
            return 0.0
        steps = np.abs(np.diff(self.track_mach))
        steps = steps[np.isfinite(steps)]
        return float(np.median(steps)) if steps.size else 0.0

    def curve(self, mach):
        """Start Cd at ``mach`` (held constant beyond the grid)."""
        return np.interp(np.asarray(mach, float), self.mach, self.cd)

    def shape_curve(self, mach):
        """The smoothed shape at ``mach`` (held constant beyond the grid)."""
        return np.interp(np.asarray(mach, float), self.mach, self.shape)


def divided_difference_matrix(t, order):
    """Sparse (N - order, N) matrix of divided differences of ``order`` on the abscissae ``t``
    (uneven spacing allowed): ``D @ y`` approximates the order-th derivative / order!."""
    from scipy.sparse import diags, identity

    D = identity(t.size, format="csr")
    for k in range(1, order + 1):
        n = t.size - k
        step = t[k:] - t[:-k]
        Dk = diags([-1.0 / step, 1.0 / step], [0, 1], shape=(n, n + 1), format="csr")
        D = Dk @ D
    return D


def penalized_smooth(t, y, order, sigma):
    """A penalized least-squares smoother whose weight matches the noise: minimise
    ``sum (y - f)^2 + lam |D_order f|^2`` (``D`` the divided differences on ``t``), with ``lam``
    chosen so that the residual rms equals ``sigma`` (the discrepancy principle: the smoother
    takes out what the noise could have put in and no more).

    The penalty's null space is the polynomials of degree < ``order``: with order 3 on
    positions, a constant acceleration costs nothing, so a shell decelerating at 200 m/s^2 at
    its first sample is followed there (a cubic smoothing spline, which penalises acceleration,
    starts it tens of m/s slow).

    Parameters
    ----------
    t, y : (N,) ndarray
        Times [s] (increasing) and values.
    order : int
        Derivative penalised (3 for positions, 2 for a speed).
    sigma : float
        Noise sd of ``y`` (same unit).

    Returns
    -------
    f, df : (N,) ndarray
        The smoothed values and their time derivative at ``t``.
    """
    from scipy.linalg import solveh_banded

    n = t.size
    if n < order + 3 or not sigma > 0:
        p = np.polyfit(t, y, min(order - 1, max(n - 1, 0))) if n >= 2 else np.array([float(y[0])])
        return np.polyval(p, t), np.polyval(np.polyder(p), t) if p.size > 1 else np.zeros(n)
    ts = float(t[-1] - t[0])
    u = (t - t[0]) / ts
    D = divided_difference_matrix(u, order)
    P = (D.T @ D).tocsr()
    band = np.zeros((order + 1, n))
    for k in range(order + 1):
        dk = P.diagonal(k)
        band[order - k, k:] = dk
    band /= max(float(np.max(band[order])), 1e-300)  # lam = 1: the penalty as strong as the data

    def solve(lam):
        ab = band * lam
        ab[order] += 1.0
        return solveh_banded(ab, y, lower=False, check_finite=False)

    target = sigma * sigma
    lo, hi = -6.0, 11.0           # log10 lam (penalty normalised to the identity's scale)
    f_lo, f_hi = solve(10.0**lo), solve(10.0**hi)
    if np.mean((y - f_hi) ** 2) <= target:
        f = f_hi
    elif np.mean((y - f_lo) ** 2) >= target:
        f = f_lo
    else:
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            f = solve(10.0**mid)
            if np.mean((y - f) ** 2) > target:
                hi = mid
            else:
                lo = mid
            if hi - lo < 0.02:
                break
        f = solve(10.0 ** (0.5 * (lo + hi)))
    return f, np.gradient(f, t, edge_order=2)


def _integrate(t, f, y0):
    """Cumulative trapezoid of f(t) from y0 at t[0]."""
    out = np.empty_like(t)
    out[0] = y0
    out[1:] = y0 + np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(t))
    return out


def smooth_kinematics(track, elevation_deg=None, g=G0, sigma=None):
    """Smoothed speed, its rate, path angle, heading and height along a track.

    Parameters
    ----------
    track : RadarTrack
        Any subset of x, y, z [m] and v [m/s].
    elevation_deg : float, optional
        Launch elevation [deg]: the path angle at the first sample of a track without ``z`` that
        starts at the launch (t = 0), or of one with neither ``z`` nor ``x`` (a Doppler speed
        record; without it such a track is taken as flat fire). ``cos gamma = (dx/dt) / V``
        cannot tell a flat path's few tenths of a degree from noise.
    g : float
        Gravity [m/s^2].
    sigma : dict, optional
        Noise sd per channel (the round's ``[radar] sigma``); channels without one get the sd
        their own high-frequency content shows.

    Returns
    -------
    Kinematics
    """
    t = np.asarray(track.t, float)
    ch = track.channels
    notes = []
    # the round's sd where given, but never below what the track's own high-frequency content
    # shows: a stated sd smaller than the noise makes the smoother follow the noise (and a track
    # in feet has 3.3 times the noise the round states in metres)
    sig = {c: max(float((sigma or {}).get(c, 0.0)), hf_noise_sd(t, ch[c])) for c in ch}
    pos, vel = {}, {}
    for c in ("x", "y", "z"):
        if c in ch:
            pos[c], vel[c] = penalized_smooth(t, ch[c], 3, sig[c])
    if "v" in ch:
        speed, dspeed = penalized_smooth(t, ch["v"], 2, sig["v"])
    elif vel:
        sp = np.sqrt(sum(v**2 for v in vel.values()))
        speed, dspeed = penalized_smooth(t, sp, 2, hf_noise_sd(t, sp))
        if "z" not in vel or not ({"x", "y"} & set(vel)):
            notes.append("speed from the positions without all of x and z: it misses the path's "
                         "other components")
    else:  # pragma: no cover - a track has at least one channel
        raise InputError(f"{track.source}: the track has no channel to read the speed from")
    speed = np.maximum(speed, 1e-3)
    horiz = np.hypot(vel.get("x", 0.0 * t), vel.get("y", 0.0 * t))
    measured = "z" in vel and ("x" in vel or "y" in vel)
    if measured:
        gamma = np.arctan2(vel["z"], horiz)
    elif "z" in vel:
        gamma = np.arcsin(np.clip(vel["z"] / speed, -1.0, 1.0))
    elif "x" in vel and (elevation_deg is None or abs(float(t[0])) > 1e-9):
        # cos gamma = dx/dt / V; the sign flips at the summit (where dx/dt / V peaks)
        cg = np.clip(vel["x"] / speed, -1.0, 1.0)
        mag = np.arccos(cg)
        apex = int(np.argmax(cg))
        gamma = np.where(np.arange(t.size) <= apex, mag, -mag)
        notes.append("path angle from dx/dt and v (no z channel)")
    else:
        g0 = math.radians(elevation_deg) if elevation_deg is not None else 0.0
        if elevation_deg is None:
            notes.append("speed-only track without a launch elevation: taken as flat fire")
        gamma = np.empty_like(t)
        gamma[0] = g0
        for i in range(1, t.size):  # gravity turn, explicit midpoint
            h = t[i] - t[i - 1]
            gm = gamma[i - 1] - 0.5 * h * g * math.cos(gamma[i - 1]) / speed[i - 1]
            gamma[i] = gamma[i - 1] - h * g * math.cos(gm) / (0.5 * (speed[i] + speed[i - 1]))
        notes.append("path angle by the gravity turn from the launch elevation (speed-only track)")
    heading = np.arctan2(vel["y"], vel["x"]) if ("x" in vel and "y" in vel) else np.zeros_like(t)
    z = pos["z"] if "z" in pos else _integrate(t, speed * np.sin(gamma), 0.0)
    if "z" not in pos:
        notes.append("height by integrating V sin(gamma) from 0 at the first sample")
    cols = []
    for k, c in enumerate(("x", "y", "z")):
        if c in pos:
            cols.append(pos[c])
        elif c == "z":
            cols.append(z)
        elif c == "x":
            cols.append(_integrate(t, speed * np.cos(gamma) * np.cos(heading), 0.0))
        else:
            cols.append(np.zeros_like(t))
    return Kinematics(t, speed, dspeed, gamma, heading, z, np.column_stack(cols), bool(measured),
                      tuple(notes))


def drag_samples(kin, mass, diameter, atmosphere, g=G0):
    """Mach and Cd at every sample from the deceleration along the path.

    ``D = -dV/dt - g sin(gamma)`` [m/s^2] and ``Cd = D / (k rho V^2)``, ``k = pi d^2 / (8 m)``;
    no wind (the air speed is the ground speed).

    Parameters
    ----------
    kin : Kinematics
    mass : float [kg]
    diameter : float [m]
    atmosphere : Atmosphere or MetProfile
    g : float [m/s^2]

    Returns
    -------
    mach, cd : (N,) ndarray
    """
    k = math.pi * diameter**2 / (8.0 * mass)
    z = np.clip(kin.z, -400.0, 20000.0)
    air = atmosphere.at_height(z)
    D = -kin.dspeed - g * np.sin(kin.gamma)
    return kin.speed / air.speed_of_sound, D / (k * air.density * kin.speed**2)


def start_curve(mach, cd, dm=START_BIN):
    """A smooth Cd(M) through per-sample values: bin means, then a GCV smoothing spline in Mach.

    Parameters
    ----------
    mach, cd : (N,) ndarray
    dm : float
        Bin width [Mach].

    Returns
    -------
    grid, curve : (K,) ndarray
        Bin centres covering the samples' Mach range and the smoothed Cd there, clipped to
        :data:`START_CD_CLIP`.
    """
    ok = np.isfinite(mach) & np.isfinite(cd)
    mach, cd = mach[ok], cd[ok]
    if mach.size == 0:
        raise InputError("no finite speed along the track: cannot read a Mach number off it")
    lo = math.floor(mach.min() / dm) * dm
    hi = math.ceil(mach.max() / dm) * dm
    edges = np.arange(lo, hi + 0.5 * dm, dm)
    if edges.size < 3:
        # a track that flies within one bin (a short piece of a slow flight): two bins, so the
        # curve is a table of at least two rows
        edges = np.array([lo, lo + dm, lo + 2 * dm])
    idx = np.clip(np.digitize(mach, edges) - 1, 0, edges.size - 2)
    cnt = np.bincount(idx, minlength=edges.size - 1)
    tot = np.bincount(idx, weights=cd, minlength=edges.size - 1)
    have = cnt > 0
    centres = 0.5 * (edges[:-1] + edges[1:])
    xm, ym, wm = centres[have], tot[have] / cnt[have], cnt[have].astype(float)
    if xm.size >= MIN_SMOOTH_SAMPLES:
        try:
            spl = gcv_smoothing_spline(xm, ym, wm / wm.mean())
            curve = spl(centres)
        except (ValueError, np.linalg.LinAlgError):
            curve = np.interp(centres, xm, ym)
    elif xm.size >= 2:
        curve = np.polyval(np.polyfit(xm, ym, 1, w=np.sqrt(wm)), centres)
    else:
        curve = np.full(centres.size, float(np.average(ym, weights=wm)))
    return centres, np.clip(curve, *START_CD_CLIP)


def whittaker(y, w, scale_bins):
    """Whittaker smoother: minimise ``sum w (y - f)^2 + lam sum (second differences of f)^2``
    with ``lam = scale_bins^4`` (the equivalent kernel is ~``scale_bins`` points wide).

    Parameters
    ----------
    y, w : (K,) ndarray
        Values and weights (0 = no data there).
    scale_bins : float

    Returns
    -------
    (K,) ndarray
    """
    from scipy.sparse import diags
    from scipy.sparse.linalg import spsolve

    K = y.size
    if K < 3:
        return y.copy()
    D = diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(K - 2, K))
    A = diags(w) + float(scale_bins) ** 4 * (D.T @ D)
    return np.asarray(spsolve(A.tocsc(), w * y), float)


def _window_bounds(speed, n_min, n_max, dv):
    """Sample ranges [i0, i1) of consecutive windows, each spanning at most a relative change
    ``dv`` of ``speed`` (and ``n_min``..``n_max`` samples); a short remainder joins the last."""
    n = speed.size
    out, i0 = [], 0
    while n - i0 >= n_min:
        ref = speed[i0]
        j = i0 + n_min
        while j < min(n, i0 + n_max) and abs(speed[j] / ref - 1.0) <= dv:
            j += 1
        out.append([i0, j])
        i0 = j
    if out and i0 < n:
        out[-1][1] = n
    return [tuple(w) for w in out]


def window_fits(track, rnd, kin, cd0, sigma=None, ends_only=False):
    """Constant-Cd maximum-likelihood fits over short windows of a track with positions.

    The point-mass model integrates the flight exactly within each window, so a shell that
    loses a third of its speed in half a second (a sphere at Mach 1.6) is read as well as a
    slow one, where derivatives of smoothed positions are biased at the track's ends. Each
    window spans at most :data:`WINDOW_DV` relative change of speed (and :data:`WINDOW_MIN` to
    :data:`WINDOW_MAX` samples); its start is the smoothed state and ``cd0`` at its Mach.

    Parameters
    ----------
    track : RadarTrack
        Needs ``x`` and ``z``.
    rnd : Round
    kin : Kinematics
        The smoothed kinematics (window starts).
    cd0 : callable
        ``cd0(mach)``: starting Cd.
    sigma : dict, optional
        Noise sd per channel (default the round's; missing channels are estimated).
    ends_only : bool
        Only the first and the last window (where smoothed derivatives are least certain).

    Returns
    -------
    list of dict with ``i0``, ``i1``, ``mach`` (mean, min, max), ``cd``, ``state0`` (6,) at the
    window's first sample; only windows whose fit converged.
    """
    from ...drag import Constant
    from ...dynamics.pointmass import PointMassModel
    from ...errors import FitError
    from ..model.problem import OutputErrorProblem

    if "x" not in track.channels or "z" not in track.channels:
        return []
    model = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, Constant(), rnd.atmosphere)
    sig = dict(rnd.radar.sigma if sigma is None else sigma)
    chans = track.names
    out = []
    bounds = _window_bounds(kin.speed, WINDOW_MIN, WINDOW_MAX, WINDOW_DV)
    if ends_only and len(bounds) > 2:
        bounds = [bounds[0], bounds[-1]]
    for i0, i1 in bounds:
        g, h, V = kin.gamma[i0], kin.heading[i0], kin.speed[i0]
        s0 = np.concatenate([kin.position[i0], V * np.array([math.cos(g) * math.cos(h),
                                                             math.cos(g) * math.sin(h), math.sin(g)])])
        a = model.atmosphere.at_height(np.array([kin.z[i0]])).speed_of_sound[0]
        theta0 = np.concatenate([[float(np.clip(cd0(V / a), 0.02, 2.9))], s0])
        free = np.ones(7, bool)
        if "y" not in chans:
            free[[2, 5]] = False
        try:
            prob = OutputErrorProblem(model, track.subset(slice(i0, i1)), theta0, free=free, sigma=sig,
                                      channels=chans)
            res = prob.fit(max_iter=30)
        except (FitError, InputError, ValueError, np.linalg.LinAlgError):
            continue
        m = res.mach[np.isfinite(res.mach)] if res.mach is not None else np.zeros(0)
        if not (res.converged and m.size and 0.0 < res.theta[0] < 2.99):
            continue
        out.append({"i0": int(i0), "i1": int(i1), "mach": float(m.mean()), "mach_min": float(m.min()),
                    "mach_max": float(m.max()), "cd": float(res.theta[0]), "state0": res.theta[1:].copy()})
    return out


def data_start(track, rnd):
    """Mach span, start Cd(M) and the state at the first sample, read off the track.

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
        Its projectile (mass, diameter) and atmosphere; the launch elevation only for a
        speed-only track.

    Returns
    -------
    DataStart
    """
    kin = smooth_kinematics(track, elevation_deg=rnd.launch.elevation_deg, sigma=rnd.radar.sigma)
    mach, cd = drag_samples(kin, rnd.projectile.mass, rnd.projectile.diameter, rnd.atmosphere)
    track_mach = mach.copy()
    grid, curve = start_curve(mach, cd)
    # the track's ends, where a smoothed derivative is least certain and a fast-decelerating
    # shell's speed is biased most, are read by the model itself (a constant-Cd window fit):
    # its samples take the window's Cd over the window's fitted Mach range, and the first
    # window gives the state at the first sample
    wins = window_fits(track, rnd, kin, lambda m: np.interp(m, grid, curve), ends_only=True)
    state_w = None
    if wins:
        keep = np.ones(mach.size, bool)
        for w in wins:
            keep[w["i0"]:w["i1"]] = False
        mach = np.concatenate([mach[keep]] + [np.linspace(w["mach_min"], w["mach_max"], w["i1"] - w["i0"])
                                              for w in wins])
        cd = np.concatenate([cd[keep]] + [np.full(w["i1"] - w["i0"], w["cd"]) for w in wins])
        grid, curve = start_curve(mach, cd)
        if wins[0]["i0"] == 0:
            state_w = wins[0]["state0"]
    # the shape: the start curve smoothed over SHAPE_SCALE, weighted by where samples are
    fin = np.isfinite(mach) & np.isfinite(cd)
    cnt = np.bincount(np.clip(np.rint((mach[fin] - grid[0]) / START_BIN).astype(int), 0, grid.size - 1),
                      minlength=grid.size).astype(float)
    wts = np.clip(cnt / max(cnt.mean(), 1e-9), 0.05, None)
    shape = np.clip(whittaker(curve, wts, SHAPE_SCALE / START_BIN), *START_CD_CLIP)
    have = cnt > 0
    noise = float(1.4826 * np.median(np.abs(curve[have] / shape[have] - 1.0))) if have.any() else 0.0
    state0 = np.concatenate([kin.position[0],
                             kin.speed[0] * np.array([math.cos(kin.gamma[0]) * math.cos(kin.heading[0]),
                                                      math.cos(kin.gamma[0]) * math.sin(kin.heading[0]),
                                                      math.sin(kin.gamma[0])])])
    if state_w is not None:
        state0 = state_w
    fin = np.isfinite(mach)
    span = (float(mach[fin].min()), float(mach[fin].max()))
    return DataStart(span, grid, curve, shape, noise, state0, mach, cd, kin, kin.notes, track_mach=track_mach)


def gravity_ratio(kin, g=G0, pieces=6):
    """The gravity a track implies in its own units, over g: ~1 for metres.

    A point mass turns under gravity alone: ``d gamma/dt = -g cos(gamma) / V``. Over each of
    ``pieces`` consecutive parts of the track (inner 90 %) the turn ``-delta gamma`` is divided
    by ``integral cos(gamma) / V dt``; the median of the parts over ``g`` is the ratio and their
    spread its standard error.

    Returns
    -------
    (ratio, standard_error) or (None, None) when the path angle was not measured or the track
    turns too little to tell.
    """
    if not kin.gamma_measured or kin.t.size < 4 * pieces:
        return None, None
    n = kin.t.size
    a, b = int(0.05 * n), int(0.95 * n) - 1
    cuts = np.linspace(a, b, pieces + 1).astype(int)
    f = np.cos(kin.gamma) / kin.speed
    vals = []
    for i, j in zip(cuts[:-1], cuts[1:]):
        if j - i < 2:
            continue
        integ = float(np.sum(0.5 * (f[i + 1:j + 1] + f[i:j]) * np.diff(kin.t[i:j + 1])))
        if integ > 0:
            vals.append(-(kin.gamma[j] - kin.gamma[i]) / integ / g)
    if len(vals) < 3:
        return None, None
    vals = np.asarray(vals)
    med = float(np.median(vals))
    se = float(1.2533 * 1.4826 * np.median(np.abs(vals - med)) / math.sqrt(len(vals)))
    return med, se


def check_heights(track, rnd):
    """Raise :class:`InputError` when the track's heights leave the round's atmosphere model
    (the standard atmosphere covers -5 km to 32.2 km above sea level; a met profile its own
    span): a flight there would be fitted in air held at the model's edge. Checked before any
    fitting work; heights are ``z`` above the gun plus the gun's altitude."""
    z = track.channels.get("z")
    if z is None or not np.size(z):
        return
    atm = rnd.atmosphere
    lo, hi = float(np.min(z)), float(np.max(z))
    try:
        atm.at_height(np.array([lo, hi]))
    except ValueError as exc:
        g = float(getattr(atm, "gun_altitude", 0.0))
        raise InputError(f"{track.source or 'track'}: z spans {lo:.0f} to {hi:.0f} m above the gun "
                         f"({(lo + g) / 1000:.1f} to {(hi + g) / 1000:.1f} km above sea level), outside the round's "
                         f"atmosphere ({exc}); fit the part of the flight inside it, or check that z is in metres "
                         f"above the gun") from None


def check_gravity_units(kin, source="track", g=G0, channels=("x", "y", "z", "v")):
    """Raise :class:`InputError` when the track's path bends as if gravity were far from g in
    metres: the whole track is in another length unit (feet, yards, km, mm).

    A mix of units between the positions and the speed is caught when the track is read
    (:func:`bayesdrag.io.tracks.read_track`); a track entirely in feet is self-consistent there and
    only the physics tells. The message names the track's own length channels (``channels``: a
    radar-native track's ``range`` and ``range_rate``, not x, y, z and v).
    """
    r, se = gravity_ratio(kin, g)
    if r is None or not r > 0:
        return
    off = max(r, 1.0 / r)
    if off < GRAVITY_RATIO_LIMIT or abs(r - 1.0) < GRAVITY_SIGNIFICANCE * se:
        return
    guess = min(_GRAVITY_UNITS, key=lambda u: abs(math.log(r / u[0])))
    lengths = [c for c in channels if c not in ("azimuth", "elevation")]
    why = _named(guess[1], lengths) if abs(math.log(r / guess[0])) < math.log(1.1) else \
        f"check the units of {', '.join(lengths)} (m, m/s) and t (s)"
    raise InputError(f"{source}: units look wrong: the path bends as if gravity were {r * g:.3g} "
                     f"length units/s^2 (9.81 m/s^2 expected); {why}")


def _named(words, channels):
    """A unit guess of :data:`_GRAVITY_UNITS` with the track's own channels in place of x, y, z, v."""
    if set(channels) <= {"x", "y", "z", "v"}:
        return words
    return words.replace("x, y, z and v", " and ".join([", ".join(channels[:-1]), channels[-1]]) if len(channels) > 1
                         else channels[0])


#: a track's first speed and the round's launch velocity in m/s differ by a unit when their ratio
#: is within this factor of a unit's (a first sample 0.1 s after the muzzle has lost ~1 % of it)
LAUNCH_SPEED_MATCH = 1.08
#: ... and the ratio is beyond what a gun-launched projectile can show: above this (a tail wind or
#: a nominal velocity a few % off give a few %) or, for a track that starts within
#: :data:`LAUNCH_SPEED_EARLY` of the launch, below its inverse
LAUNCH_SPEED_LIMIT = 1.4
LAUNCH_SPEED_EARLY = 0.5
#: (ratio of the track's speed to the round's, what it means) for :func:`check_launch_speed`
_SPEED_UNITS = (
    (1.0 / 0.3048, "the track's speed looks like ft/s (expected m/s)"),
    (3.6, "the track's speed looks like km/h (expected m/s)"),
    (1.0 / 0.44704, "the track's speed looks like mph (expected m/s)"),
    (0.3048, "the round's [launch] velocity looks like ft/s (in m/s: {v:.4g})"),
    (1.0 / 3.6, "the round's [launch] velocity looks like km/h (in m/s: {v:.4g})"),
)


def check_launch_speed(track, rnd, channels):
    """Raise :class:`InputError` when the track's first speed and the round's launch velocity
    differ by a unit: a LabRadar's ``Vel`` in ft/s under an ``m/s`` header, a round's velocity
    typed in ft/s. Only the clear cases (the ratio within :data:`LAUNCH_SPEED_MATCH` of a unit's
    and beyond :data:`LAUNCH_SPEED_LIMIT`); a velocity a few % off is the launch check's to say.

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
    channels : sequence of str
        The fitted channels: the speed is ``v``, else ``range_rate`` (a chronograph's, seen from
        near the muzzle, where it is the speed).
    """
    v0 = rnd.launch.velocity
    chan = "v" if "v" in channels else "range_rate" if "range_rate" in channels else None
    if v0 is None or chan is None or not v0 > 0:
        return
    t = np.asarray(track.t, float)
    first = np.flatnonzero(t <= t[0] + 1.0)[:5]
    speed = float(np.median(np.abs(np.asarray(track.channels[chan], float)[first])))
    r = speed / float(v0)
    early = t[0] <= LAUNCH_SPEED_EARLY
    if not (r > LAUNCH_SPEED_LIMIT or (early and r < 1.0 / LAUNCH_SPEED_LIMIT)):
        return
    factor, words = min(_SPEED_UNITS, key=lambda u: abs(math.log(r / u[0])))
    if abs(math.log(r / factor)) >= math.log(LAUNCH_SPEED_MATCH):
        return
    raise InputError(f"{track.source or 'track'}: units look wrong: the track's first speed ({chan}) is {speed:.4g} "
                     f"m/s, {r:.3g} times the round's launch velocity {v0:g} m/s; "
                     + words.format(v=float(v0) * factor))
