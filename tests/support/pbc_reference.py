"""Independent trajectory reference computed with py-ballisticcalc 3.x (``py_ballisticcalc``).

This module is a *test oracle*, not part of ``bayesdrag``.  It exposes

``pbc_trajectory(mach, cd, mass, diameter, velocity, elevation_deg, wind=(0, 0), t_out=None,
max_range=None, altitude=0.0, temperature_offset=0.0) -> dict``
    trajectory of a point mass with drag table ``cd(mach)`` computed by py-ballisticcalc, returned
    as numpy arrays ``{"t", "x", "y", "z", "v"}`` in SI units and in **bayesdrag's frame**
    (x downrange horizontal, y cross-range positive to the right looking downrange, z up, origin at
    the muzzle, t = 0 at launch; ``v`` is the ground speed |dr/dt|).

``scipy_reference(...)`` (same signature and outputs)
    a small, self-contained ``scipy.integrate.solve_ivp`` implementation of bayesdrag's point-mass
    model, used by the ``__main__`` self-check at the bottom.

Both run until the projectile comes back down to z = 0 (the muzzle height) or reaches
``max_range`` [m] downrange, whichever is first.  With ``t_out=None`` the samples are every
``SAMPLE_DT`` s plus the exact end point (impact); otherwise they are taken at ``t_out`` and
samples later than the end of the flight are NaN.

Model being reproduced (bayesdrag)
----------------------------------
    d^2 r/dt^2 = -(rho(z) pi d^2 / (8 m)) Cd(M) |v - w| (v - w) + (0, 0, -9.80665),
    M = |v - w| / a(z),  w = (wx, wy, 0) constant,
Cd = PCHIP of the table (scipy ``PchipInterpolator``), held constant beyond the table ends.
ICAO atmosphere, T = 288.15 - 0.0065 H (+ temperature_offset), p from hydrostatic balance with the
pressure at the gun kept standard, rho = p / (287.05287 T), a = sqrt(1.4 * 287.05287 T);
isothermal above 11 km.  bayesdrag uses *geopotential* altitude H = r0 h / (r0 + h),
r0 = 6 356 766 m (``scipy_reference(geopotential=True)``, the default).

What py-ballisticcalc 3.1.1 does, and how it is configured here
----------------------------------------------------------------
(all read from the installed sources: ``drag_model.py``, ``shot.py``, ``conditions.py``,
``constants.py``, ``engines/base_engine.py``, ``engines/rk4.py``, ``engines/scipy_engine.py``,
``interpolation.py``, ``trajectory_data.py``, ``unit.py``.)

Internal units and frame.
    Engines work in feet, fps, seconds, with state (x downrange, y UP, z cross-range, positive to
    the shooter's RIGHT).  Public objects carry units (``Distance``, ``Velocity``, ``Weight``,
    ``Angular``, ``Pressure``, ``Temperature``; ``Unit.Meter(1)`` etc.) and are converted with
    ``>>`` (e.g. ``row.distance >> Distance.Meter``).  Note ``Velocity`` converts m/s -> fps with
    3.2808399 (vs 1/0.3048 = 3.280839895..., 1.5e-9 relative) - negligible.
    Mapping to our frame: x = distance, y = windage, z = height (``TrajectoryData.distance``,
    ``.windage``, ``.height``); ``.velocity`` is the ground speed.  ``.mach`` in the rows is
    *ground* speed / local speed of sound, not the air-relative Mach used for the drag.

Custom drag table and BC.
    ``DragModel(bc, drag_table, weight, diameter)`` with ``drag_table`` a list of
    ``DragDataPoint(Mach, CD)`` (or dicts ``{"Mach":..., "CD":...}``), the same form as the
    built-in ``TableG1`` etc.  Weight/diameter are only used for sectional density / form
    factor / spin drift; the drag itself uses only ``bc`` and the table.
    ``ShotProps.drag_by_mach``: drag "SDF" = Cd(M) * 2.08551e-04 / bc, and the engines use
    acceleration [ft/s^2] = -density_ratio * SDF * |v_rel|_fps * v_rel_fps, where
    2.08551e-04 = rho0_imp * pi / (4 * 2 * 144), rho0_imp = 0.076474 lb/ft^3 (= 1.2249960 kg/m^3),
    bc in lb/in^2 (sectional density m/d^2 [lb/in^2] divided by a form factor).
    Equating with our SI drag gives the exact BC for "Cd is the projectile's own Cd":
        bc = 8 m K / (0.3048 pi d^2 rho_ref),  K = 2.08551e-4,
    where rho_ref is the density py-ballisticcalc's density_ratio = 1 stands for (1.225 kg/m^3
    divided by a real-gas correction, see below).  For an ideal 1.225 this is
    bc = 0.99999919 * SD(lb/in^2) (form factor 1 up to the rounding of K and of 0.076474);
    for the 155 mm M101 (42.6 kg): SD = 2.522016 lb/in^2, bc = 2.522014 lb/in^2.
    Verified numerically in ``_check_drag_constant()`` (drag acceleration reconstructed from
    ``ShotProps`` vs our formula: 1.3e-6 relative, from the resampled table and the stock
    speed-of-sound constant; the drag constant itself matches to rounding).
Drag-table interpolation.
    ``ShotProps._precalc_drag_curve`` -> ``interpolation.pchip_prepare``: monotone PCHIP with
    Fritsch-Butland interior slopes (same as scipy) but a slightly different end-slope limiter,
    and ``pchip_eval`` *extrapolates* the end cubic beyond the table (bayesdrag clamps).
    To reproduce our Cd exactly we hand py-ballisticcalc a dense resampling (dM = 0.0005) of
    scipy's PCHIP of the table, plus flat extensions (Mach 0 ... first row, last row ... Mach 10)
    so that its PCHIP is constant outside the table.  Relative Cd error of the resampled curve
    < 1e-6 (``_dense_table``).
Atmosphere (``conditions.Atmo``).
    ``Atmo.icao(altitude)``: ICAO/ISA troposphere with T0 = 15 C, lapse -0.0019812 K/ft
    (= -0.0065 K/m), p0 = 1013.25 hPa, pressure exponent 5.255876 (ours 5.25588), humidity 0 %
    by default (``cStandardHumidity = 0``).  Density: CIPM-2007 real-gas formula
    (``calculate_air_density``, with compressibility factor Z and M_a = 28.96546 g/mol), which
    gives 1.2255214 kg/m^3 at sea level, i.e. ``density_ratio = 1.000426`` relative to
    1.225 - this is the biggest atmosphere difference (0.043 % density, ~ 3 m at 15 km range) and
    is compensated by scaling bc by ``density_ratio0 / (rho_ours(gun) / 1.225)``, which is exact
    because py-ballisticcalc scales density_ratio(h) = density_ratio0 * (p/p0)(T0/T).
    Altitude dependence: T = T0 + lapse * (h - h0) and p = p0 (1 + lapse (h - h0)/T0)^5.255876
    with *geometric* height h (no geopotential correction), troposphere only (above 36089 ft it
    only warns and keeps the lapse rate, no isothermal layer), and for |h - h0| < 30 ft it uses
    the gun-level density and speed of sound unchanged (a "fast path", a step discontinuity
    of ~0.09 % in density at +-9.1 m).  Speed of sound: a = 20.0467 sqrt(T) m/s
    (ours sqrt(1.4 * 287.05287) = 20.046796; 5e-6 relative), at the gun via 49.0223 sqrt(degR).
    By default (``exact_atmosphere=True``) we pass a small ``Atmo`` subclass that overrides
    ``get_density_and_mach_for_altitude`` with bayesdrag's atmosphere (geopotential, isothermal
    above 11 km, no 30-ft fast path); with ``exact_atmosphere=False`` the stock py-ballisticcalc
    atmosphere is used (with the gun conditions and density normalisation still matched).
    ``temperature_offset`` has the same meaning in both: the whole profile shifted by dT at the
    standard pressure at the gun (py-ballisticcalc: ``Atmo(altitude, pressure=p_std,
    temperature=T_std + dT)`` - its pressure lapse is hydrostatic with the shifted T0).
Gravity.
    ``cGravityConstant = -32.17405`` ft/s^2 (= 9.8066504 m/s^2); set here to exactly
    -9.80665 / 0.3048 through the engine config.  Flat Earth, constant g.
Coriolis, spin drift, powder temperature.
    Coriolis only if ``Shot(latitude=...)`` is given (default None -> off).  Spin drift
    (Litz) only if the weapon twist and the bullet length/diameter are non-zero: we use
    ``Weapon(twist=0)`` and no length -> off.  ``Ammo(use_powder_sensitivity=False)`` (default).
Sight height / look angle / zero.
    ``Weapon(sight_height=0)`` (the launch point is then the origin), ``look_angle=0`` and no
    zeroing: ``Shot(relative_angle=elevation)`` with ``weapon.zero_elevation = 0``, so
    ``Shot.barrel_elevation = look_angle + cos(cant) (zero_elevation + relative_angle)`` =
    our elevation exactly.  No cant.
Wind (``Wind(velocity, direction_from, until_distance)``).
    ``direction_from`` 0 = from behind the shooter (tailwind), 90 deg = from the shooter's left,
    blowing to the right; vector = speed (cos(dir), 0, sin(dir)) in (downrange, up, right).
    So our (wx, wy) -> speed hypot(wx, wy), direction_from = atan2(wy, wx)  (headwind wx = -10:
    180 deg; wy = +10: 90 deg).  ``until_distance`` defaults to 1e8 ft (constant wind).
Integration engine.
    Engines: ``python+rk4`` (default, fixed step 0.0025 s * cStepMultiplier; NOTE it freezes
    density, Mach and Cd at the start of each step, so it is only first-order in the drag
    variation), ``python+euler``, ``python+verlet``, and ``scipy+<method>``
    (``SciPyIntegrationEngine``: ``solve_ivp`` with adaptive step, full RHS at every stage,
    dense output, terminal events; config ``integration_method``, ``relative_tolerance``,
    ``absolute_tolerance``, ``max_time`` (default 90 s - too short for a 45 deg 155 mm shot,
    raised here to 400 s)).  No compiled (``py_ballisticcalc.exts``, ``cython+rk4``) engine is
    installed.  We use ``scipy+DOP853`` with rtol 1e-11, atol 1e-9 (ft), ``cMinimumVelocity = 0``,
    ``cMaximumDrop`` / ``cMinimumAltitude`` far away, and call ``engine.integrate(shot, max_range,
    dist_step=max_range, time_step=dt, stop_at_zero=True)`` - ``stop_at_zero`` (a SciPy-engine
    keyword) adds a terminal event on the downward crossing of the sight line (= z = 0 with
    look angle 0), and the final row is the exact crossing state.  Rows requested via
    ``time_step`` are evaluated from the solver's dense output at multiples of dt; arbitrary
    ``t_out`` are obtained by a cubic spline through these rows (dt = SAMPLE_DT = 0.02 s;
    interpolation error << 1 mm).
    Range limit: ``max_range`` -> ``range_limit`` (terminal event at x = limit + 1 ft; the row at
    exactly x = limit is found by root finding).  Default here 1000 km, i.e. no limit.

Ranges / limits for a 155 mm shell.
    M101 table, 42.6 kg, 818 m/s, sea level: QE 15 deg lands at 14.04 km after 32.5 s (apex
    1.36 km); QE 45 deg at 21.66 km after 76.5 s (apex 7.45 km, still below 11 km).  The stock
    SciPy-engine ``max_time = 90 s`` would cut high-angle fire, and ``cMaximumDrop = -10000 ft``
    / ``cMinimumAltitude = -1500 ft`` / ``cMinimumVelocity = 50 fps`` are harmless here but are
    disabled anyway; ``max_time = 400 s``; range limit 1000 km unless ``max_range`` is given.

Measured agreement (``python tests/pbc_reference.py``, Python 3.11, py-ballisticcalc 3.1.1)
    M101, 42.6 kg, 0.155 m, 818 m/s, sea level, max position difference over the whole flight
    between ``pbc_trajectory`` (defaults) and ``scipy_reference``:
        QE 15 no wind 1.3e-5 m, crosswind wy=+10 1.7e-5 m (drift +147.04 m), headwind
        wx=-10 1.5e-5 m; QE 45 3e-5 m (5e-5 m with wind) - all < 0.1 mm, also at 1500 m
        altitude with dT = +10 / -15 K and an oblique wind.  Runtime 0.2-0.6 s per trajectory
        (reference 0.2-0.4 s).
    What each convention is worth (QE 15): bc = plain sectional density (no real-gas
    correction) 2.2 m; stock py-ballisticcalc atmosphere 0.057 m (0.010 m against a reference
    using geometric altitude; ~1.8 m for QE 30 from a 1500 m gun, growing with apex height);
    default g 0.2 mm; raw (not resampled) M101 table < 0.1 mm (its 0.01-Mach rows leave only the
    end-slope / extrapolation differences, outside the flight's Mach 0.9-2.4); scipy RK45 at
    the engine's default rtol 1e-8 3 mm; ``python+rk4`` default 0.0025 s step 0.08 m (1.3 s),
    0.00025 s step 8 mm (13 s).
"""
from __future__ import annotations

import math
import time
import warnings

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline, PchipInterpolator

# --------------------------------------------------------------------------------------------
# constants of OUR model (bayesdrag)
# --------------------------------------------------------------------------------------------
G0 = 9.80665
R_AIR = 287.05287
GAMMA = 1.4
T0_STD = 288.15
P0_STD = 101325.0
LAPSE = -0.0065
H_TROPO = 11000.0
R_EARTH = 6356766.0
RHO_STD = 1.225  # py-ballisticcalc's cStandardDensityMetric (density_ratio = 1)

FT = 0.3048
PBC_K = 2.08551e-04  # py-ballisticcalc ShotProps.drag_by_mach constant
SAMPLE_DT = 0.02  # s, spacing of the py-ballisticcalc rows used for interpolation
DENSE_DM = 0.0005  # Mach spacing of the resampled drag table handed to py-ballisticcalc


# --------------------------------------------------------------------------------------------
# our atmosphere (inline, ICAO troposphere + isothermal layer)
# --------------------------------------------------------------------------------------------
def _geopot(h, geopotential=True):
    h = np.asarray(h, dtype=float)
    return R_EARTH * h / (R_EARTH + h) if geopotential else h


def _icao(h, temperature_offset=0.0, gun_altitude=0.0, geopotential=True):
    """Our atmosphere at geometric altitude h [m] (above sea level).

    T = 288.15 - 0.0065 H + dT (H < 11 km), isothermal above; the pressure at the gun is the
    standard one and elsewhere follows hydrostatic balance with the shifted temperatures.
    Returns (rho [kg/m^3], a [m/s], T [K], p [Pa]).
    """
    dT = temperature_offset
    H = _geopot(h, geopotential)
    Hg = _geopot(gun_altitude, geopotential)
    expo = -G0 / (R_AIR * LAPSE)  # 5.25588

    def std_p(Hx, shift):
        # pressure with the profile shifted by `shift`, starting from the STANDARD p0 at H = 0
        T11 = T0_STD + LAPSE * H_TROPO + shift
        p11 = P0_STD * (T11 / (T0_STD + shift)) ** expo
        Ht = np.minimum(Hx, H_TROPO)
        p = P0_STD * ((T0_STD + shift + LAPSE * Ht) / (T0_STD + shift)) ** expo
        return np.where(Hx <= H_TROPO, p, p11 * np.exp(-G0 * (Hx - H_TROPO) / (R_AIR * T11)))

    T = T0_STD + LAPSE * np.minimum(H, H_TROPO) + dT
    # standard pressure at the gun, then hydrostatic with the shifted profile
    p = std_p(Hg, 0.0) * std_p(H, dT) / std_p(Hg, dT)
    rho = p / (R_AIR * T)
    a = np.sqrt(GAMMA * R_AIR * T)
    return rho, a, T, p


def _read_table(path):
    """Read a ``mach,cd`` CSV ('#' comment lines, one header line)."""
    rows = []
    with open(path) as fh:
        for line in fh:
            line = line.split("#", 1)[0].strip()
            if not line or line.lower().startswith("mach"):
                continue
            a, b = line.split(",")[:2]
            rows.append((float(a), float(b)))
    arr = np.array(rows)
    return arr[:, 0], arr[:, 1]


def _cd_function(mach, cd):
    mach = np.asarray(mach, float)
    cd = np.asarray(cd, float)
    pchip = PchipInterpolator(mach, cd, extrapolate=False)
    lo, hi = float(mach[0]), float(mach[-1])

    def f(m):
        return float(pchip(min(max(m, lo), hi)))

    return f, pchip


# --------------------------------------------------------------------------------------------
# scipy reference of OUR model
# --------------------------------------------------------------------------------------------
def _finish(t_all, sol, t_end, t_out):
    if t_out is None:
        t = np.append(np.arange(0.0, t_end, SAMPLE_DT), t_end)
        if len(t) > 1 and t[-1] - t[-2] < 1e-9:
            t = np.delete(t, -2)
    else:
        t = np.asarray(t_out, dtype=float)
    ok = (t >= 0.0) & (t <= t_end + 1e-12)
    out = {k: np.full(t.shape, np.nan) for k in ("x", "y", "z", "v")}
    if np.any(ok):
        s = sol(np.clip(t[ok], 0.0, t_end))
        out["x"][ok], out["y"][ok], out["z"][ok] = s[0], s[1], s[2]
        out["v"][ok] = np.sqrt(s[3] ** 2 + s[4] ** 2 + s[5] ** 2)
    out["t"] = t
    return out


def scipy_reference(mach, cd, mass, diameter, velocity, elevation_deg, wind=(0.0, 0.0), t_out=None,
                    max_range=None, altitude=0.0, temperature_offset=0.0, geopotential=True,
                    rtol=1e-12, atol=1e-10):
    """Our point-mass model integrated with solve_ivp (DOP853). Same outputs as pbc_trajectory."""
    cdf, _ = _cd_function(mach, cd)
    kref = math.pi * diameter ** 2 / (8.0 * mass)
    wx, wy = float(wind[0]), float(wind[1])
    el = math.radians(elevation_deg)
    s0 = [0.0, 0.0, 0.0, velocity * math.cos(el), 0.0, velocity * math.sin(el)]

    def rhs(t, s):
        rho, a, _, _ = _icao(altitude + s[2], temperature_offset, altitude, geopotential)
        ux, uy, uz = s[3] - wx, s[4] - wy, s[5]
        u = math.sqrt(ux * ux + uy * uy + uz * uz)
        k = float(rho) * kref * cdf(u / float(a)) * u
        return [s[3], s[4], s[5], -k * ux, -k * uy, -k * uz - G0]

    def ground(t, s):
        return s[2] if t > 0 else 1.0

    ground.terminal, ground.direction = True, -1
    events = [ground]
    if max_range is not None:
        def downrange(t, s):
            return s[0] - max_range
        downrange.terminal, downrange.direction = True, 1
        events.append(downrange)
    sol = solve_ivp(rhs, (0.0, 1000.0), s0, method="DOP853", rtol=rtol, atol=atol,
                    dense_output=True, events=events)
    if sol.status != 1:
        raise RuntimeError(f"reference integration did not reach the ground: {sol.message}")
    return _finish(sol.t, sol.sol, float(sol.t[-1]), t_out)


# --------------------------------------------------------------------------------------------
# py-ballisticcalc
# --------------------------------------------------------------------------------------------
def _dense_table(mach, cd, dm=DENSE_DM):
    """Resample scipy's PCHIP of (mach, cd) densely, with flat extensions, for py-ballisticcalc."""
    _, pchip = _cd_function(mach, cd)
    lo, hi = float(mach[0]), float(mach[-1])
    n = max(int(math.ceil((hi - lo) / dm)), 1)
    m = np.linspace(lo, hi, n + 1)
    c = pchip(m)
    ext_lo = [x for x in (0.0, lo / 2) if x < lo - 1e-9]
    ext_hi = [x for x in (hi + (10.0 - hi) / 2, 10.0) if x > hi + 1e-9]
    m_all = np.concatenate([ext_lo, m, ext_hi])
    c_all = np.concatenate([[c[0]] * len(ext_lo), c, [c[-1]] * len(ext_hi)])
    return m_all, c_all


def _make_exact_atmo_class():
    from py_ballisticcalc import Atmo

    class BayesdragAtmo(Atmo):
        """py-ballisticcalc Atmo whose altitude dependence is bayesdrag's ICAO model."""

        def configure(self, gun_altitude, temperature_offset):
            self._bd_gun = float(gun_altitude)
            self._bd_dT = float(temperature_offset)
            rho_g, _, _, _ = _icao(self._bd_gun, self._bd_dT, self._bd_gun)
            self._bd_rho_g = float(rho_g)
            return self

        def get_density_and_mach_for_altitude(self, altitude):  # altitude in feet ASL
            rho, a, _, _ = _icao(altitude * FT, self._bd_dT, self._bd_gun)
            # density ratio is relative to the stock gun-level value (bc is scaled for that)
            return self._density_ratio * float(rho) / self._bd_rho_g, float(a) / FT

    return BayesdragAtmo


_ATMO_CLASS = None


def pbc_trajectory(mach, cd, mass, diameter, velocity, elevation_deg, wind=(0.0, 0.0), t_out=None,
                   max_range=None, altitude=0.0, temperature_offset=0.0, *,
                   exact_atmosphere=True, dense_table=True, match_density=True,
                   exact_gravity=True, engine="scipy", method="DOP853", rtol=1e-11, atol=1e-9,
                   step_multiplier=1.0, sample_dt=SAMPLE_DT, wind_zones=None):
    """Trajectory from py-ballisticcalc for a custom Cd(M) table, in SI and bayesdrag's frame.

    Parameters
    ----------
    mach, cd : array_like
        Drag table (Cd referred to pi d^2/4), interpolated like bayesdrag (PCHIP, clamped).
    mass, diameter : float
        kg, m.
    velocity, elevation_deg : float
        Muzzle velocity [m/s] and barrel elevation (quadrant elevation) [deg].
    wind : (wx, wy)
        Constant wind [m/s]; wx > 0 tailwind, wy > 0 blowing towards +y (right).
    wind_zones : sequence of (wx, wy, until_m), optional
        Winds that change with DOWNRANGE DISTANCE, as py-ballisticcalc models them (its
        ``Wind(until_distance=...)``): each zone's wind [m/s] blows until ``until_m`` [m]
        downrange (None or inf: to the end). Replaces ``wind``.
    t_out : array_like or None
        Output times [s]; None -> every ``sample_dt`` plus the end point.
    max_range : float or None
        Stop at this downrange distance [m] if the shell has not landed before.
    altitude, temperature_offset : float
        Gun altitude above sea level [m] and temperature offset of the ICAO profile [K].
    exact_atmosphere : bool
        True (default): use bayesdrag's atmosphere through an ``Atmo`` subclass.  False: stock
        py-ballisticcalc atmosphere (geometric altitude, troposphere only, 30-ft fast path) with
        the gun-level density normalised to ours.
    dense_table : bool
        True (default): hand py-ballisticcalc a dense resampling of scipy's PCHIP (exactly our
        Cd); False: the raw table (its own PCHIP variant, extrapolated beyond the ends).
    match_density, exact_gravity : bool
        (for diagnostics) False: plain bc = sectional density [lb/in^2] (no correction for
        py-ballisticcalc's real-gas density_ratio0 = 1.000426) / its default g = 32.17405 ft/s^2.
    engine : "scipy" (default, ``SciPyIntegrationEngine`` with ``method``/``rtol``/``atol``) or
        "rk4" (``RK4IntegrationEngine``, fixed step 0.0025 s * ``step_multiplier``).

    Returns
    -------
    dict of numpy arrays "t" [s], "x", "y", "z" [m], "v" [m/s] (ground speed).
    """
    global _ATMO_CLASS
    from py_ballisticcalc import Ammo, Atmo, DragDataPoint, DragModel, Shot, Weapon, Wind
    from py_ballisticcalc import TrajFlag
    from py_ballisticcalc.engines import RK4IntegrationEngine, SciPyIntegrationEngine
    from py_ballisticcalc.unit import Angular, Distance, Pressure, Temperature, Velocity, Weight

    mach = np.asarray(mach, float)
    cd = np.asarray(cd, float)
    m_tab, c_tab = _dense_table(mach, cd) if dense_table else (mach, cd)
    table = [DragDataPoint(float(a), float(b)) for a, b in zip(m_tab, c_tab)]

    # --- atmosphere at the gun: our T and p, then py-ballisticcalc's density_ratio there
    rho_g, _, T_g, p_g = _icao(altitude, temperature_offset, altitude)
    atmo_kwargs = dict(altitude=Distance.Meter(altitude), pressure=Pressure.hPa(float(p_g) / 100.0),
                       temperature=Temperature.Kelvin(float(T_g)), humidity=0.0)
    if exact_atmosphere:
        if _ATMO_CLASS is None:
            _ATMO_CLASS = _make_exact_atmo_class()
        atmo = _ATMO_CLASS(**atmo_kwargs).configure(altitude, temperature_offset)
    else:
        atmo = Atmo(**atmo_kwargs)
    # density py-ballisticcalc uses at the gun = density_ratio0 * rho_ref_K, want rho_g:
    # bc = 8 m K / (0.3048 pi d^2 rho_g / density_ratio0)
    bc = 8.0 * mass * PBC_K * atmo.density_ratio / (FT * math.pi * diameter ** 2 * float(rho_g))
    if not match_density:
        bc = (mass / 0.45359237) / (diameter / 0.0254) ** 2  # sectional density, lb/in^2

    dm = DragModel(bc, table, weight=Weight.Kilogram(mass), diameter=Distance.Meter(diameter))
    ammo = Ammo(dm, mv=Velocity.MPS(velocity), use_powder_sensitivity=False)
    weapon = Weapon(sight_height=Distance.Meter(0.0), twist=Distance.Inch(0.0))
    if wind_zones is not None:
        winds = []
        for wx, wy, until in wind_zones:
            far = until is None or not math.isfinite(until)
            winds.append(Wind(Velocity.MPS(math.hypot(wx, wy)), Angular.Radian(math.atan2(wy, wx)),
                              until_distance=Distance.Meter(1.0e7 if far else float(until))))
    else:
        wx, wy = float(wind[0]), float(wind[1])
        speed = math.hypot(wx, wy)
        winds = [Wind(Velocity.MPS(speed), Angular.Radian(math.atan2(wy, wx)))] if speed > 0 else None
    shot = Shot(ammo=ammo, atmo=atmo, weapon=weapon, winds=winds, look_angle=Angular.Degree(0.0),
                relative_angle=Angular.Degree(elevation_deg), cant_angle=Angular.Degree(0.0))

    common = dict(cMinimumVelocity=0.0, cMinimumAltitude=-1e7)
    if exact_gravity:
        common["cGravityConstant"] = -G0 / FT
    limit = Distance.Meter(1.0e6 if max_range is None else float(max_range))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        if engine == "scipy":
            eng = SciPyIntegrationEngine(dict(
                common, integration_method=method, relative_tolerance=rtol,
                absolute_tolerance=atol, max_time=400.0, cMaximumDrop=-1e7))
            hit = eng.integrate(shot, limit, limit, time_step=sample_dt, stop_at_zero=True)
            rows = list(hit.records)
        elif engine == "rk4":
            # the fixed-step engines have no stop-at-zero: stop on the first step below z = 0
            # (cMaximumDrop = 0 while descending) and cut at the interpolated ZERO_DOWN row
            eng = RK4IntegrationEngine(dict(common, cMaximumDrop=0.0,
                                            cStepMultiplier=step_multiplier))
            hit = eng.integrate(shot, limit, limit, time_step=sample_dt,
                                filter_flags=TrajFlag.ZERO_DOWN)
            rows = list(hit.records)
            iz = [k for k, r in enumerate(rows) if r.flag & TrajFlag.ZERO_DOWN]
            if iz:
                rows = rows[:iz[0] + 1]
        else:
            raise ValueError(f"unknown engine {engine!r}")

    rows.sort(key=lambda r: r.time)
    t = np.array([r.time for r in rows])
    P = np.array([[r.distance >> Distance.Meter, r.windage >> Distance.Meter,
                   r.height >> Distance.Meter, r.velocity >> Velocity.MPS] for r in rows])
    keep = np.concatenate([[True], np.diff(t) > 1e-9])
    t, P = t[keep], P[keep]
    t_end = float(t[-1])
    if t_out is None:
        return {"t": t, "x": P[:, 0], "y": P[:, 1], "z": P[:, 2], "v": P[:, 3]}
    tq = np.asarray(t_out, dtype=float)
    ok = (tq >= 0.0) & (tq <= t_end + 1e-12)
    out = {"t": tq}
    spl = CubicSpline(t, P, axis=0)
    vals = spl(np.clip(tq, 0.0, t_end))
    for i, k in enumerate(("x", "y", "z", "v")):
        col = np.full(tq.shape, np.nan)
        col[ok] = vals[ok, i]
        out[k] = col
    return out


# --------------------------------------------------------------------------------------------
# checks
# --------------------------------------------------------------------------------------------
def _check_drag_constant(mach, cd, mass, diameter):
    """Reconstruct py-ballisticcalc's drag deceleration from ShotProps and compare with ours."""
    from py_ballisticcalc import Ammo, Atmo, DragDataPoint, DragModel, Shot
    from py_ballisticcalc.shot import ShotProps
    from py_ballisticcalc.unit import Distance, Velocity, Weight

    m_tab, c_tab = _dense_table(mach, cd)
    atmo = Atmo.icao()
    rho_g = float(_icao(0.0)[0])
    bc = 8.0 * mass * PBC_K * atmo.density_ratio / (FT * math.pi * diameter ** 2 * rho_g)
    dm = DragModel(bc, [DragDataPoint(a, b) for a, b in zip(m_tab, c_tab)],
                   weight=Weight.Kilogram(mass), diameter=Distance.Meter(diameter))
    props = ShotProps.from_shot(Shot(ammo=Ammo(dm, Velocity.MPS(500.0)), atmo=atmo))
    cdf, _ = _cd_function(mach, cd)
    worst = 0.0
    for v in (150.0, 300.0, 340.0, 400.0, 600.0, 818.0):
        dr, mach_fps = props.get_density_and_mach_for_altitude(0.0)
        v_fps = v / FT
        a_pbc = dr * props.drag_by_mach(v_fps / mach_fps) * v_fps ** 2 * FT  # m/s^2
        rho, a, _, _ = _icao(0.0)
        a_ours = float(rho) * math.pi * diameter ** 2 / (8 * mass) * cdf(v / float(a)) * v ** 2
        worst = max(worst, abs(a_pbc / a_ours - 1.0))
    sd = (mass / 0.45359237) / (diameter / 0.0254) ** 2
    return bc, sd, atmo.density_ratio, worst


def _max_diff(a, b):
    n = min(len(a["t"]), len(b["t"]))
    d = np.sqrt((a["x"][:n] - b["x"][:n]) ** 2 + (a["y"][:n] - b["y"][:n]) ** 2
                + (a["z"][:n] - b["z"][:n]) ** 2)
    return float(np.nanmax(d))


if __name__ == "__main__":
    import os

    path = os.path.join(os.path.dirname(__file__), "..", "..", "bayesdrag", "data", "cd_m101.csv")
    M, CD = _read_table(path)
    mass, diam, v0 = 42.6, 0.155, 818.0

    bc, sd, dr0, worst = _check_drag_constant(M, CD, mass, diam)
    print(f"M101: SD = {sd:.6f} lb/in^2, bc used = {bc:.6f} lb/in^2 (bc/SD = {bc / sd:.6f}, "
          f"py-ballisticcalc density_ratio at sea level = {dr0:.7f}); "
          f"drag-acceleration mismatch {worst:.2e} (relative)")

    cases = [("no wind", 15.0, (0.0, 0.0)), ("crosswind wy=+10", 15.0, (0.0, 10.0)),
             ("headwind wx=-10", 15.0, (-10.0, 0.0)), ("no wind QE45", 45.0, (0.0, 0.0))]
    for name, qe, w in cases:
        t0 = time.perf_counter()
        p = pbc_trajectory(M, CD, mass, diam, v0, qe, wind=w)
        t_pbc = time.perf_counter() - t0
        t0 = time.perf_counter()
        r = scipy_reference(M, CD, mass, diam, v0, qe, wind=w, t_out=p["t"])
        t_ref = time.perf_counter() - t0
        r_end = scipy_reference(M, CD, mass, diam, v0, qe, wind=w)
        print(f"QE {qe:4.1f} {name:18s}: impact pbc t={p['t'][-1]:.4f} s x={p['x'][-1]:.3f} "
              f"y={p['y'][-1]:+.3f} | ref t={r_end['t'][-1]:.4f} s x={r_end['x'][-1]:.3f} "
              f"y={r_end['y'][-1]:+.3f} | max |dr| over flight = {_max_diff(p, r):.1e} m "
              f"| runtime pbc {t_pbc:.2f} s, ref {t_ref:.2f} s")
    # what each matched convention is worth (QE 15, no wind and 10 m/s crosswind)
    print("effect of each convention / setting: max |dr| over the flight vs the reference [m]")
    for label, kw, rkw in [
        ("all matched (default)", {}, {}),
        ("bc = SD (no real-gas density_ratio0 fix)", dict(match_density=False), {}),
        ("py-ballisticcalc default g = 32.17405 ft/s^2", dict(exact_gravity=False), {}),
        ("stock Atmo (geometric h, 30-ft fast path)", dict(exact_atmosphere=False), {}),
        ("  same, vs reference with geometric h", dict(exact_atmosphere=False),
         dict(geopotential=False)),
        ("raw table (pbc PCHIP variant, extrapolating)", dict(dense_table=False), {}),
        ("scipy RK45 at the engine default tolerances", dict(method="RK45", rtol=1e-8, atol=1e-6),
         {}),
        ("python+rk4, default step 0.0025 s", dict(engine="rk4"), {}),
        ("python+rk4, step 0.00025 s", dict(engine="rk4", step_multiplier=0.1), {}),
    ]:
        for name, w in (("no wind", (0.0, 0.0)), ("wy=+10", (0.0, 10.0))):
            t0 = time.perf_counter()
            q = pbc_trajectory(M, CD, mass, diam, v0, 15.0, wind=w, **kw)
            dt = time.perf_counter() - t0
            r = scipy_reference(M, CD, mass, diam, v0, 15.0, wind=w, t_out=q["t"], **rkw)
            print(f"  {label:46s} {name:8s}: {_max_diff(q, r):8.1e} m  ({dt:.2f} s)")
