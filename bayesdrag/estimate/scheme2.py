"""Scheme 2: a constant Cd per window of samples (paper §4, second scheme).

The track is cut into windows of ``window`` samples (default 50; the paper uses 50-100), with an
optional ``overlap``. In each window Cd is a constant; the state at the window's first sample
comes from differentiating the data smoothed by 5th-order local polynomials (Savitzky-Golay).
Each window gives Cd with its Cramér-Rao sd at the window's mean Mach number, and the windows
together give a stitched Cd(M) curve that assumes no functional form at all.

Choices written down:

* **Smoothing**: a Savitzky-Golay block of ``smooth`` samples (default: the window length
  rounded up to odd, at least ``4 * polyorder + 1``) centred on the window's first sample where
  the track allows, clipped at the track's ends. With uniform sampling the coefficients come from
  :func:`scipy.signal.savgol_coeffs` (``pos`` = the sample's place in the block); with irregular
  sampling (dropouts) the same local polynomial is fitted by least squares on the actual times.
* **Initial conditions are refined, not frozen** (default ``free_ic=True``): the smoothed state
  is the starting value of an ML fit of [Cd, X0, Y0, Z0, Ux0, Uy0, Uz0] to the window's own data.
  Freezing it (the paper's practice, ``free_ic=False``) ignores the error of the smoothed
  velocity, which then leaks into Cd while the Cramér-Rao bound does not know it: a bound that
  is too small. Refined ICs cost a larger, honest bound. Using the smoothed state as a prior
  would count the same samples twice, so it is only the start.
* **Channels**: the window's state needs position channels (``x`` and ``z``; ``y`` when
  present, else the cross-range state is zero): a speed-only (Doppler) track cannot start a window
  and gives a clear error — use Scheme 1 there.
* **The last, short window**: a remainder shorter than half a window is merged into the last
  full window; a longer one becomes a window of its own.
* **Noise**: the round's ``[radar] sigma`` per channel when given, else relaxation in each window.
* **Mach of a window**: the mean Mach number of the fitted trajectory over the window's samples.
  For a Cd varying linearly with Mach the constant fit estimates Cd there; curvature of Cd(M)
  within a window (the transonic rise) biases it, which the stitched curve shows honestly.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._runtime.threads import single_blas
from ..drag import Constant
from ..dynamics.pointmass import PointMassModel
from ..errors import InputError
from ..measure import gun_equivalent, gun_frame_track, site_of
from .model.problem import OutputErrorProblem
from .model.filters import savgol_coeffs
from .model.noise import noise_and_outliers
from .cd.claims import DataBand, claim
from .cd.quality import assess_window, intervals
from .scheme1.fit import coriolis_of
from .build.start import data_start

#: fewest samples a window may have (7 free parameters, >= 4 samples per parameter per channel)
MIN_WINDOW = 15
#: polynomial order of the Savitzky-Golay smoother (paper: 5th-order polynomials)
POLYORDER = 5


@dataclass(frozen=True)
class Scheme2Result:
    """Scheme 2 fit of one track.

    Attributes
    ----------
    windows : list of dict
        Per window (Mach-sorted as flown): ``t_start``, ``t_end`` [s], ``i_start``, ``i_end``
        (sample indices, end exclusive), ``n``, ``mach`` (mean Mach), ``mach_min``,
        ``mach_max``, ``ml`` (Cd), ``crb_sd``, ``crb_sd_colored``, ``reference`` (Cd of the
        reference table at ``mach`` or None), ``converged``, ``message``, ``warnings``.
    results : tuple of MLResult
    problems : tuple of OutputErrorProblem
        One per window; theta = [Cd, X0, Y0, Z0, Ux0, Uy0, Uz0] at the window's first sample.
    smoothed : ndarray, shape (W, 6)
        The smoothed (Savitzky-Golay) state at each window's first sample.
    window, overlap : int
    """

    windows: list
    results: tuple
    problems: tuple
    smoothed: np.ndarray
    window: int
    overlap: int
    free_ic: bool = True
    notes: tuple = field(default=())

    @property
    def success(self):
        return all(r.success for r in self.results)

    def stitched(self, mach):
        """Stitched Cd(M): linear interpolation through the windows' (mach, Cd), held at the ends.

        Parameters
        ----------
        mach : array_like, shape (N,)

        Returns
        -------
        (cd, sd) : ndarrays, shape (N,) — Cd and its CRB sd interpolated the same way.
        """
        m = np.array([w["mach"] for w in self.windows])
        order = np.argsort(m)
        cd = np.array([w["ml"] for w in self.windows])[order]
        sd = np.array([w["crb_sd"] for w in self.windows])[order]
        return np.interp(mach, m[order], cd), np.interp(mach, m[order], sd)


def window_slices(n, window=50, overlap=0):
    """Sample ranges of the windows.

    Parameters
    ----------
    n : int
        Number of samples in the track.
    window : int
        Samples per window.
    overlap : int
        Samples shared by consecutive windows (0 <= overlap < window).

    Returns
    -------
    list of (start, stop) index pairs (stop exclusive).
    """
    if not isinstance(window, (int, np.integer)) or window < MIN_WINDOW:
        raise InputError(f"Scheme 2: window = {window!r} samples; allowed: an integer >= {MIN_WINDOW} "
                         f"(the paper uses 50-100)")
    if not isinstance(overlap, (int, np.integer)) or not 0 <= overlap < window:
        raise InputError(f"Scheme 2: overlap = {overlap!r} samples; allowed: 0 <= overlap < window ({window})")
    if window > n:
        raise InputError(f"Scheme 2: window of {window} samples is longer than the track ({n} samples); "
                         f"use a shorter --window or Scheme 1")
    stride = window - overlap
    out = []
    start = 0
    while start + window <= n:
        out.append([start, start + window])
        start += stride
    rest = n - out[-1][1]
    if rest > 0:
        if rest + overlap >= max(window // 2, MIN_WINDOW):
            out.append([out[-1][1] - overlap, n])
        else:
            out[-1][1] = n
    return [tuple(s) for s in out]


def smoothed_state(t, positions, i, smooth, polyorder=POLYORDER):
    """Position and velocity at sample ``i`` from local polynomial (Savitzky-Golay) smoothing.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times [s].
    positions : sequence of 3 arrays (N,) or None
        x, y, z [m]; None for a missing channel (its position and velocity are returned as 0).
    i : int
        Sample at which to evaluate.
    smooth : int
        Samples in the smoothing block (odd, > polyorder).
    polyorder : int

    Returns
    -------
    state : ndarray, shape (6,)
        [x, y, z, vx, vy, vz] at ``t[i]`` (m, m/s).
    gain : ndarray, shape (2,)
        Noise gains: sd of the smoothed position and of the velocity per 1 m of white position
        noise (multiply by the channel's sigma).
    """
    n = t.size
    L = min(smooth, n if n % 2 else n - 1)
    b0 = int(np.clip(i - L // 2, 0, n - L))
    tt = t[b0:b0 + L]
    pos = i - b0
    dts = np.diff(tt)
    dt = float(np.mean(dts))
    state = np.zeros(6)
    if np.ptp(dts) <= 1e-6 * dt:  # uniform block: scipy's Savitzky-Golay coefficients
        c0 = savgol_coeffs(L, polyorder, deriv=0, pos=pos, use="dot")
        c1 = savgol_coeffs(L, polyorder, deriv=1, delta=dt, pos=pos, use="dot")
    else:  # irregular sampling: the same local polynomial by least squares on the real times
        V = np.vander((tt - t[i]) / dt, polyorder + 1, increasing=True)
        pinv = np.linalg.pinv(V)
        c0, c1 = pinv[0], pinv[1] / dt
    for k, p in enumerate(positions):
        if p is None:
            continue
        blk = np.asarray(p[b0:b0 + L], dtype=float)
        state[k] = c0 @ blk
        state[3 + k] = c1 @ blk
    return state, np.array([np.linalg.norm(c0), np.linalg.norm(c1)])


def fit_scheme2(track, rnd, window=50, overlap=0, channels=None, sigma=None, free_ic=True,
                smooth=None, polyorder=POLYORDER, progress=None):
    """Scheme 2 ML fit: a constant Cd in each window of samples.

    Parameters
    ----------
    track : RadarTrack
        Needs ``x`` and ``z`` (window initial states); ``y`` and ``v`` are used when present.
    rnd : Round
    window : int
        Samples per window (default 50).
    overlap : int
        Samples shared by consecutive windows.
    channels : sequence of str, optional
        Channels fitted (default all the track has).
    sigma : dict, optional
        Fixed noise sd per channel (default: the round's ``[radar] sigma``).
    free_ic : bool
        Refine each window's initial state with Cd (default) or keep the smoothed one (paper).
    smooth : int, optional
        Samples of the Savitzky-Golay block (odd); default ``max(window | 1, 4 polyorder + 1)``.
    polyorder : int
        Order of the smoothing polynomials (default 5, as in the paper).
    progress : callable, optional
        Called as ``progress(k, n_windows)`` after each window.

    Returns
    -------
    Scheme2Result
    """
    with single_blas():   # the kernel's threads use the cores, not BLAS's
        chans = tuple(channels) if channels is not None else track.names
        site = site_of(rnd, chans)
        seen = track.with_channels(chans) if set(chans) != set(track.names) else track
        # window starts from positions: the gun-frame ones, or a radar's range and angles turned into them
        view = gun_frame_track(seen, site) if ("x" not in chans or "z" not in chans) else seen
        if view is None or "x" not in view.channels or "z" not in view.channels:
            raise InputError(f"{track.source}: Scheme 2 needs x and z (or the radar's range, azimuth and elevation) in "
                             f"the track to start each window (it has {', '.join(track.names)}); fit a speed-only "
                             f"track with Scheme 1")
        slices = window_slices(track.n, window, overlap)
        if smooth is None:
            smooth = max(window | 1, 4 * polyorder + 1)
        if smooth <= polyorder + 1:
            raise InputError(f"Scheme 2: smoothing block of {smooth} samples is too short for order {polyorder}")
        model = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, Constant(), rnd.atmosphere,
                               coriolis=coriolis_of(rnd))
        ref = rnd.reference_drag
        sig = dict(rnd.radar.sigma) if sigma is None else dict(sigma)
        positions = [view.channels.get(c) for c in ("x", "y", "z")]
        t = track.t
        windows, results, problems, smoothed = [], [], [], []
        # the track's own noise, for each window's goodness of fit; the start curve for each
        # window's starting Cd (the round's table may be another shell's, or absent)
        sig_data, source, _ = noise_and_outliers(track, chans, sig)
        try:
            start = data_start(view, rnd)
        except InputError:
            start = None
        for k, (i0, i1) in enumerate(slices):
            s0, _ = smoothed_state(t, positions, i0, smooth, polyorder)
            sub = track.subset(np.arange(i0, i1))
            cd0 = _start_cd(model, s0, ref, start)
            theta0 = np.concatenate([[cd0], s0])
            free = np.ones(7, bool)
            if not free_ic:
                free[1:] = False
            if "y" not in gun_equivalent(chans):
                free[[2, 5]] = False
            prob = OutputErrorProblem(model, sub, theta0, free=free, sigma=sig, channels=chans, site=site)
            res = prob.fit(fallback=True)
            mach = res.mach[np.isfinite(res.mach)] if res.mach is not None else np.array([np.nan])
            mmean = float(np.mean(mach))
            windows.append({
                "t_start": float(t[i0]), "t_end": float(t[i1 - 1]), "i_start": int(i0), "i_end": int(i1),
                "n": int(i1 - i0), "mach": mmean, "mach_min": float(np.min(mach)), "mach_max": float(np.max(mach)),
                "ml": float(res.theta[0]), "crb_sd": float(res.crb[0]), "crb_sd_colored": float(res.crb_colored[0]),
                "reference": float(ref.value(mmean)) if ref is not None else None,
                "converged": bool(res.converged), "message": res.message, "warnings": list(res.warnings),
                **assess_window(res, chans, (sig_data, source)),
            })
            results.append(res)
            problems.append(prob)
            smoothed.append(s0)
            if progress is not None:
                progress(k + 1, len(slices))
        return Scheme2Result(windows, tuple(results), tuple(problems), np.array(smoothed), int(window),
                             int(overlap), bool(free_ic))


def _start_cd(model, s0, reference, start=None):
    """Starting Cd of a window at its starting Mach: the track's own start curve
    (:mod:`bayesdrag.estimate.build.start`), else the reference, else 0.3."""
    _, a = model.atmosphere.density_and_sound_speed(float(s0[2]))
    m = float(np.linalg.norm(s0[3:])) / a
    if start is not None:
        return float(start.curve(m))
    if reference is None:
        return 0.3
    return float(reference.value(m))


def windows_table(result):
    """The ``windows`` part of result.json: one dict per window."""
    keys = ("t_start", "t_end", "mach", "ml", "crb_sd", "crb_sd_colored", "band_sd", "determined", "reference",
            "n", "mach_min", "mach_max", "converged", "quality")
    return [{k: w[k] for k in keys} for w in result.windows]


def window_budget(rows, ok, draws, rnd, seed):
    """Scheme 2's budget: the declared level sources (density, mass, diameter: one factor on
    every window's Cd) added to each window's bound and, by Monte Carlo (an independent factor
    per draw), to its posterior draws; the windows stay conditional on the other sources.
    Window rows gain ``crb_sd_statistical``; ``crb_sd`` becomes the total."""
    from .cd.budget import level_shares

    rel, cond = level_shares(rnd)
    s_rel = float(np.sqrt(sum(v * v for v in rel.values())))
    by = {"statistical": [], **{k: [] for k in rel}, "cross": []}
    total = []
    rng = np.random.default_rng(None if seed is None else seed + 10_000)
    for k, r in enumerate(rows):
        stat = float(r["crb_sd"]) if r.get("crb_sd") is not None else float("nan")
        cd = float(r["ml"]) if r.get("ml") is not None else float("nan")
        r["crb_sd_statistical"] = stat
        tot = float(np.sqrt(stat ** 2 + (s_rel * cd) ** 2))
        r["crb_sd"] = tot
        by["statistical"].append(stat)
        for n, v in rel.items():
            by[n].append(abs(cd) * v)
        by["cross"].append(0.0)
        total.append(tot)
        if k in draws and s_rel > 0:
            d = draws[k]
            d = d * (1.0 + s_rel * rng.standard_normal(d.shape))
            draws[k] = d
            flat = d.reshape(-1)
            q = np.quantile(flat, [0.05, 0.5, 0.95])
            r.update(mean=float(flat.mean()), sd=float(flat.std(ddof=1)), q05=float(q[0]), q50=float(q[1]),
                     q95=float(q[2]), sd_over_crb=float(flat.std(ddof=1) / tot) if tot else None)
    r6 = lambda a: [float(f"{v:.6g}") for v in a]  # noqa: E731
    return {"mach": [round(float(r["mach"]), 4) for r in rows], "total_sd": r6(total),
            "by_source": {k: r6(v) for k, v in by.items()}, "conditional_on": cond,
            "note": "windows: the level sources (density, mass, diameter) are included; conditional on "
                    + (", ".join(cond) if cond else "nothing")}


def stitched_rows(rows, ok, mach, grid, rnd, sampled):
    """Scheme 2's ``cd`` rows on a Mach grid through the windows, and its ``ml.quality``: a grid
    point is determined when the windows on both sides of it are."""
    order = np.argsort(mach[ok])
    mk = mach[ok][order]

    def interp(key):
        v = np.array([rows[k][key] for k in ok], float)[order]
        return np.interp(grid, mk, v)

    cols = {key: interp(key) for key in ("ml", "crb_sd", "band_sd") + (("mean", "q05", "q95") if sampled else ())}
    det_w = np.array([rows[k]["determined"] for k in ok], bool)[order]
    j_hi = np.clip(np.searchsorted(mk, grid), 0, len(mk) - 1)
    j_lo = np.clip(j_hi - 1, 0, len(mk) - 1)
    inside = (grid >= mk[0]) & (grid <= mk[-1])
    cd_rows = []
    for i, m in enumerate(grid):
        r = {key: float(v[i]) for key, v in cols.items() if key != "band_sd"}
        r["mach"] = float(m)
        r["reference"] = float(rnd.reference_drag.value(m)) if rnd.reference_drag is not None else None
        cd_rows.append(r)
    # a grid point is claimed where the windows on both sides of it are
    claim(cd_rows, DataBand.plain(cols["band_sd"], usable=inside & det_w[j_lo] & det_w[j_hi]))
    problems = [p.within(f"window {k} (Mach {rows[k]['mach']:.2f}): ") for k in ok for p in rows[k]["quality"]["problems"]]
    quality = {"ok": not problems and len(ok) == len(rows),
               "undetermined": intervals(grid, ~np.array([r["determined"] for r in cd_rows])),
               "windows_determined": int(det_w.sum()), "problems": problems}
    return cd_rows, quality

