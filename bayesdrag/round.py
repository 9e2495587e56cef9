"""Everything known about one firing besides the track: the projectile, the launch, the air and
the radar (``Projectile``, ``Launch``, ``Radar``, ``Round``). Values only; the round file (TOML)
is read and written by :mod:`bayesdrag.io.rounds`.

Construction checks every value and raises ``ValueError`` naming the key, what was found and
what is allowed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .air.atmosphere import Atmosphere
from .drag import ReferenceTable
from .track import ALL_CHANNELS, SAMPLE_SIGMA_FLOOR, UNITS
from .validate import number, positive, type_name

__all__ = ["Projectile", "Launch", "Radar", "Systematics", "Round", "DEFAULT_VELOCITY_SD",
           "DEFAULT_ELEVATION_SD_DEG", "DEFAULT_POSITION_SD", "SYSTEMATIC_SOURCES", "SIGMA_BOUNDS", "sigma_bounds",
           "RADAR_SITE_MAX"]

#: default a-priori sd of the launch velocity [m/s]: round-to-round muzzle-velocity dispersion of
#: a lot is ~0.3-0.5 % (2.5-4 m/s at 800 m/s); 5 m/s also absorbs a nominal value taken from the
#: firing table rather than measured, while staying far looser than what a track determines.
DEFAULT_VELOCITY_SD = 5.0
#: default a-priori sd of the launch elevation [deg]: laying error (~1 mil = 0.056 deg) plus
#: vertical jump (typically 0.5-2 mil) gives ~0.1 deg; 0.2 deg (3.5 mil) is deliberately loose.
DEFAULT_ELEVATION_SD_DEG = 0.2
#: default a-priori sd of the muzzle position at t = 0 per axis [m]: survey of radar vs muzzle and
#: the offset of the muzzle from the trunnion are decimetres; 1 m is loose.
DEFAULT_POSITION_SD = 1.0

#: plausible ranges checked when a round is built (SI / degrees as noted)
MASS_MAX = 10000.0              # kg
DIAMETER_RANGE = (0.004, 1.0)   # m
#: plausible mass per cubic calibre m / d^3 [kg/m^3]: a hollow ping-pong ball has ~40, a solid
#: steel sphere 4100, a bullet or a shell 10 000-15 000, a tungsten long rod of 50 calibres
#: ~760 000; beyond these a mass is in another unit (tonnes, grams) or a typing mistake
MASS_PER_CALIBRE3 = (20.0, 1.0e6)
ELEVATION_RANGE_DEG = (-10.0, 90.0)  # open interval
VELOCITY_MAX = 3000.0           # m/s
ALTITUDE_RANGE = (-1000.0, 10000.0)  # m above sea level of the gun


#: mass per cubic calibre [kg/m^3] of the projectiles a range fires: a .177 pellet ~5 800, a shotgun
#: slug ~4 400, a 155 mm shell ~11 400, a 5.56 mm bullet ~19 000, a .308 bullet ~24 000. A unit
#: mistake is named only when its correction lands in this band (a long rod, ~200 000, is allowed
#: but no correction is ever guessed to reach it)
TYPICAL_MASS_PER_CALIBRE3 = (3000.0, 60000.0)
#: the units a mass or a diameter may have been typed in, factor to SI
MASS_UNITS = {"kg": 1.0, "tonnes": 1e3, "grams": 1e-3, "grains": 6.479891e-5, "pounds": 0.45359237,
              "ounces": 0.028349523125}
DIAMETER_UNITS = {"metres": 1.0, "millimetres": 1e-3, "centimetres": 1e-2, "inches": 0.0254}


def unit_guesses(mass, d):
    """The unit mistakes that make ``mass`` [kg] and ``d`` [m] a typical projectile
    (:data:`TYPICAL_MASS_PER_CALIBRE3`, diameter within :data:`DIAMETER_RANGE`): a list of
    ``(mass unit, diameter unit, mass in kg, diameter in m)``, fewest changed units first, then the
    closest to a shell's 12 000 kg/m^3; empty when none does or nothing needs changing."""
    lo, hi = TYPICAL_MASS_PER_CALIBRE3
    out = []
    for mu, fm in MASS_UNITS.items():
        for du, fd in DIAMETER_UNITS.items():
            m, dd = mass * fm, d * fd
            if (fm, fd) == (1.0, 1.0) or not DIAMETER_RANGE[0] <= dd <= DIAMETER_RANGE[1] or not 0 < m <= MASS_MAX:
                continue
            k = m / dd**3
            if lo <= k <= hi:
                out.append(((fm != 1.0) + (fd != 1.0), abs(math.log(k / 12000.0)), mu, du, m, dd))
    return [(mu, du, m, dd) for _, _, mu, du, m, dd in sorted(out)]


def _guess_words(guess):
    """A unit guess of :func:`unit_guesses` in words: what looks like what, and the SI values."""
    mu, du, m, dd = guess
    parts = ([f"the mass looks like {mu} (in kg: {m:g})"] if mu != "kg" else []) + (
        [f"the diameter looks like {du} (in m: {dd:g})"] if du != "metres" else [])
    return " and ".join(parts)


def _check_sectional_density(mass, d):
    """Refuse a mass implausible for its diameter (:data:`MASS_PER_CALIBRE3`), with the likely
    unit: a 42.6 kg shell typed as 0.0426 (tonnes) would fly like a feather and its fit would
    run for minutes before saying nothing useful; a .308 bullet's diameter typed in inches is the
    diameter's mistake, not the mass's."""
    lo, hi = MASS_PER_CALIBRE3
    k = mass / d**3
    if lo <= k <= hi:
        return
    sd = mass / d**2
    guesses = unit_guesses(mass, d)
    best = guesses[0] if guesses else None
    hint = ("; it looks like tonnes (in kg: {:g})".format(mass * 1e3) if best and best[:2] == ("tonnes", "metres")
            else "; it looks like grams (in kg: {:g})".format(mass * 1e-3) if best and best[:2] == ("grams", "metres")
            else f"; {_guess_words(best)}" if best else "")
    what = "lighter than a hollow ball" if k < lo else "heavier than a solid tungsten rod"
    raise ValueError(f"mass = {mass:g} kg is implausible for diameter {d:g} m (sectional density {sd:.3g} kg/m^2, "
                     f"{what}; allowed {lo * d**3:.3g}-{hi * d**3:.3g} kg for this diameter){hint}")


@dataclass(frozen=True, eq=False)
class Projectile:
    """The shell.

    Attributes
    ----------
    name : str
    mass : float, kg
        In (0, 10000].
    diameter : float, m
        Reference diameter (area pi d^2/4), in [0.004, 1.0].
    reference_drag : ReferenceTable or None
        Firing-table Cd(M), if known.
    reference_drag_path : str or None
        Where ``reference_drag`` was read from (as resolved from the round file).
    reference_extrapolate : bool
        The round allows the flight to go beyond the table's Mach range (Cd held at the end
        values); see :func:`read_round`.
    """

    name: str = ""
    mass: float = None
    diameter: float = None
    reference_drag: "ReferenceTable | None" = field(default=None, repr=False)
    reference_drag_path: str | None = None
    reference_extrapolate: bool = False

    def __post_init__(self):
        if not isinstance(self.name, str):
            raise ValueError(f"name must be a string, got {type_name(self.name)}")
        mass = number("mass", self.mass, "kg")
        if not 0.0 < mass <= MASS_MAX:
            raise ValueError(f"mass = {mass:g} kg is outside (0, {MASS_MAX:g}] kg")
        d = number("diameter", self.diameter, "m")
        lo, hi = DIAMETER_RANGE
        if not lo <= d <= hi:
            # the unit that makes this a typical projectile with its mass (155 -> mm, 6.1 -> inches)
            seen = [g for g in unit_guesses(mass, d) if g[0] == "kg"]
            if seen:
                raise ValueError(f"diameter = {d:g} looks like {seen[0][1]}; diameter is in metres "
                                 f"({seen[0][3]:g}); allowed [{lo:g}, {hi:g}] m")
            raise ValueError(f"diameter = {d:g} m is outside the plausible range [{lo:g}, {hi:g}] m")
        _check_sectional_density(mass, d)
        object.__setattr__(self, "mass", mass)
        object.__setattr__(self, "diameter", d)
        if self.reference_drag_path is not None:
            object.__setattr__(self, "reference_drag_path", str(self.reference_drag_path))

    @property
    def area(self):
        """Reference area pi d^2 / 4 [m^2]."""
        return math.pi * self.diameter ** 2 / 4.0


@dataclass(frozen=True, eq=False)
class Launch:
    """Launch conditions: initial guesses, priors, simulator input, Coriolis geometry.

    Messages name the TOML keys (``elevation`` for ``elevation_deg`` etc.).

    Attributes
    ----------
    elevation_deg : float or None, deg
        Quadrant elevation, in (-10, 90). None: unknown (estimated from the track).
    velocity : float or None, m/s
        Launch (muzzle) velocity, in (0, 3000]. None: unknown.
    azimuth_deg : float or None, deg
        Firing azimuth clockwise from true north, normalised to [0, 360). None (the default):
        not given, held at 0 (north) and :attr:`azimuth_given` False; it matters for Coriolis
        (with ``latitude_deg``), a METCM message's winds and a radar's azimuth channel, which
        refuse a round without it.
    latitude_deg : float or None, deg
        Latitude of the gun, north positive, in [-90, 90]. None: unknown (no Coriolis geometry).
    altitude : float, m
        Gun altitude above mean sea level, in [-1000, 10000]; default 0.
    velocity_sd : float, m/s
        A-priori sd of ``velocity``; default :data:`DEFAULT_VELOCITY_SD` = 5 m/s (lot dispersion
        0.3-0.5 % plus a firing-table nominal value).
    elevation_sd_deg : float, deg
        A-priori sd of ``elevation_deg``; default :data:`DEFAULT_ELEVATION_SD_DEG` = 0.2 deg
        (laying error plus jump).
    position_sd : float, m
        A-priori sd of the muzzle position at t = 0, per axis; default
        :data:`DEFAULT_POSITION_SD` = 1 m (radar/muzzle survey).
    """

    elevation_deg: float | None = None
    velocity: float | None = None
    azimuth_deg: float | None = None
    latitude_deg: float | None = None
    altitude: float = 0.0
    velocity_sd: float = DEFAULT_VELOCITY_SD
    elevation_sd_deg: float = DEFAULT_ELEVATION_SD_DEG
    position_sd: float = DEFAULT_POSITION_SD

    def __post_init__(self):
        el = number("elevation", self.elevation_deg, "deg", optional=True)
        lo, hi = ELEVATION_RANGE_DEG
        if el is not None and not lo < el < hi:
            raise ValueError(f"elevation = {el:g} deg is outside ({lo:g}, {hi:g}) deg")
        vel = number("velocity", self.velocity, "m/s", optional=True)
        if vel is not None and not 0.0 < vel <= VELOCITY_MAX:
            raise ValueError(f"velocity = {vel:g} m/s is outside (0, {VELOCITY_MAX:g}] m/s")
        given = self.azimuth_deg is not None
        az = number("azimuth", self.azimuth_deg, "deg", optional=True)
        az = 0.0 if az is None else az % 360.0
        lat = number("latitude", self.latitude_deg, "deg", optional=True)
        if lat is not None and not -90.0 <= lat <= 90.0:
            raise ValueError(f"latitude = {lat:g} deg is outside [-90, 90] deg")
        alt = number("altitude", self.altitude, "m")
        if not ALTITUDE_RANGE[0] <= alt <= ALTITUDE_RANGE[1]:
            raise ValueError(f"altitude = {alt:g} m is outside [{ALTITUDE_RANGE[0]:g}, "
                             f"{ALTITUDE_RANGE[1]:g}] m above sea level")
        values = dict(elevation_deg=el, velocity=vel, azimuth_deg=az, latitude_deg=lat, altitude=alt,
                      velocity_sd=positive("velocity_sd", self.velocity_sd, "m/s"),
                      elevation_sd_deg=positive("elevation_sd", self.elevation_sd_deg, "deg"),
                      position_sd=positive("position_sd", self.position_sd, "m"))
        for k, v in values.items():
            object.__setattr__(self, k, v)
        object.__setattr__(self, "_azimuth_given", given)

    @property
    def azimuth_given(self):
        """Whether the firing azimuth was given (else it is held at 0, north)."""
        return self._azimuth_given

    @property
    def elevation(self):
        """Elevation [rad], or None."""
        return None if self.elevation_deg is None else math.radians(self.elevation_deg)

    @property
    def elevation_sd(self):
        """Elevation sd [rad]."""
        return math.radians(self.elevation_sd_deg)

    @property
    def azimuth(self):
        """Azimuth [rad] clockwise from true north."""
        return math.radians(self.azimuth_deg)

    @property
    def latitude(self):
        """Latitude [rad], or None."""
        return None if self.latitude_deg is None else math.radians(self.latitude_deg)


#: largest plausible distance of the radar's site from the muzzle [m]: a tracking radar stands
#: beside or behind the gun, at most a few km away; beyond this a position is in another unit
RADAR_SITE_MAX = 20_000.0
#: largest plausible a-priori sd of a radar bias: range [m], angles [rad] (1 deg: an encoder
#: off by more is a setup mistake, not an uncertainty)
RANGE_BIAS_SD_MAX = 100.0
#: largest plausible offset typed into a chronograph radar [m]: it stands beside the muzzle
DEVICE_OFFSET_MAX = 10.0
ANGLE_BIAS_SD_MAX = math.radians(1.0)
#: plausible noise sd of one radar sample, by the channel's unit inside the code: (floor, ceiling).
#: Below the floor no radar measures (0.1 mm, 0.1 mm/s, 0.2 arc seconds: a unit mistake); above the
#: ceiling (1 km, 100 m/s, 10 deg) a radar tracks nothing, and 1 / sd^2 of the likelihood would
#: overflow (1e308 m ended a fit in an OverflowError)
SIGMA_BOUNDS = {"m": (SAMPLE_SIGMA_FLOOR["m"], 1e3), "m/s": (SAMPLE_SIGMA_FLOOR["m/s"], 1e2),
                "rad": (SAMPLE_SIGMA_FLOOR["rad"], math.radians(10.0))}


def sigma_bounds(channel):
    """The plausible (floor, ceiling) of a channel's noise sd in its unit inside the code
    (:data:`SIGMA_BOUNDS`: m, m/s, rad)."""
    return SIGMA_BOUNDS[UNITS[channel]]


def _check_sigma_bounds(sig):
    """Refuse a noise sd outside :data:`SIGMA_BOUNDS`, naming the channel (angles also in deg)."""
    for c, v in sig.items():
        lo, hi = sigma_bounds(c)
        if lo <= v <= hi:
            continue
        unit = UNITS[c]
        shown = (lambda a: f"{a:g} rad ({math.degrees(a):g} deg)") if unit == "rad" else (lambda a: f"{a:g} {unit}")
        why = ("no radar measures that precisely (a unit mistake?)" if v < lo else
               "a radar that noisy tracks nothing (a unit mistake?)")
        raise ValueError(f"sigma.{c} = {shown(v)} is outside the plausible {shown(lo)} .. {shown(hi)}: {why}; "
                         f"give the noise sd of one sample")


@dataclass(frozen=True, eq=False)
class Radar:
    """The radar: its a-priori noise, its site and its systematic errors.

    Attributes
    ----------
    sigma : dict of str -> float
        Noise sd per channel in the channel's unit inside the code (``x, y, z, range`` [m],
        ``v, range_rate`` [m/s], ``azimuth, elevation`` [rad]; the round file gives the angles
        in degrees), each within :data:`SIGMA_BOUNDS` (0.1 mm .. 1 km, 0.1 mm/s .. 100 m/s,
        5e-5 .. 10 deg); may be empty (then the fit estimates the noise).
    position : tuple of 3 floats, m
        The radar's site in the gun's frame at launch (x downrange, y right, z up); default the
        muzzle (0, 0, 0). Used only by radar-native channels.
    range_bias_sd : float or None, m
        A-priori sd of a constant range offset.
    azimuth_bias_sd, elevation_bias_sd : float or None, rad
        A-priori sd of a constant encoder / boresight offset of each angle.
    position_sd : float or None, m
        How well the site is known, per axis.
    device_offset : float or None, m
        A chronograph radar's offset from the line of fire as typed into the device: its own
        correction of the radial speed, which the measurement equations model
        (:class:`bayesdrag.measure.RadarSite`). The round file's ``position`` defaults to
        ``{y = device_offset}`` when it gives this.
    device_offset_sd : float or None, m
        How well the device's true distance from the line of fire is known, when it may differ
        from the typed ``device_offset``: a chronograph session then fits what a range rate sees
        of it (docs/radar.md, "Chronograph sessions"). A session without ``device_offset`` fits it
        with no prior. Also the ``position_sd`` when the round gives none: one shot fitted as a
        round then carries the site as its declared ``radar_position``.
    """

    sigma: dict = field(default_factory=dict)
    position: tuple = (0.0, 0.0, 0.0)
    range_bias_sd: float | None = None
    azimuth_bias_sd: float | None = None
    elevation_bias_sd: float | None = None
    position_sd: float | None = None
    device_offset: float | None = None
    device_offset_sd: float | None = None

    def __post_init__(self):
        if not isinstance(self.sigma, dict):
            raise ValueError(f"sigma must be a table like {{x = 1.0, v = 0.3}}, got {type_name(self.sigma)}")
        bad = [k for k in self.sigma if k not in ALL_CHANNELS]
        if bad:
            raise ValueError(f"sigma has unknown channel(s) {', '.join(map(str, bad))}; "
                             f"allowed: {', '.join(ALL_CHANNELS)}")
        sig = {k: positive(f"sigma.{k}", self.sigma[k], UNITS[k]) for k in ALL_CHANNELS if k in self.sigma}
        _check_sigma_bounds(sig)
        object.__setattr__(self, "sigma", sig)
        pos = self.position
        if isinstance(pos, dict):
            unknown = [k for k in pos if k not in ("x", "y", "z")]
            if unknown:
                raise ValueError(f"position has unknown key(s) {', '.join(map(str, unknown))}; allowed: x, y, z")
            pos = tuple(pos.get(k, 0.0) for k in ("x", "y", "z"))
        if isinstance(pos, (str, bytes)) or not hasattr(pos, "__len__") or len(pos) != 3:
            raise ValueError(f"position must be a table {{x = ..., y = ..., z = ...}} in m, got {type_name(pos)}")
        pos = tuple(number(f"position.{k}", v, "m") for k, v in zip("xyz", pos))
        if math.hypot(*pos) > RADAR_SITE_MAX:
            raise ValueError(f"position = {pos} is {math.hypot(*pos):.0f} m from the muzzle, more than the plausible "
                             f"{RADAR_SITE_MAX:g} m (metres, in the gun's frame: x downrange, y right, z up)")
        object.__setattr__(self, "position", pos)
        for key, unit, hi in (("range_bias_sd", "m", RANGE_BIAS_SD_MAX), ("azimuth_bias_sd", "rad", ANGLE_BIAS_SD_MAX),
                              ("elevation_bias_sd", "rad", ANGLE_BIAS_SD_MAX), ("position_sd", "m", RADAR_SITE_MAX),
                              ("device_offset_sd", "m", DEVICE_OFFSET_MAX), ("device_offset", "m", None)):
            val = number(key, getattr(self, key), unit, optional=True)
            if val is not None and key != "device_offset":
                val = positive(key, val, unit)
                if val > hi:
                    raise ValueError(f"{key} = {val:g} {unit} is larger than the plausible {hi:g} {unit}")
            elif val is not None and not 0.0 <= val <= DEVICE_OFFSET_MAX:
                raise ValueError(f"{key} = {val:g} m is not a chronograph radar's offset from the line of fire "
                                 f"(allowed 0 .. {DEVICE_OFFSET_MAX:g} m)")
            object.__setattr__(self, key, val)
        if self.device_offset_sd is not None and self.position_sd is None:
            # one shot fitted as a round carries the device's site as the declared radar_position
            object.__setattr__(self, "position_sd", self.device_offset_sd)


#: the systematic sources a round may declare: key stem -> (round-file section, unit, largest
#: plausible sd). The bounds refuse values that cannot be meant (a 50 % density uncertainty is a
#: wrong unit, not a measurement) while leaving every real tolerance far inside them.
SYSTEMATIC_SOURCES = {
    "mass": ("projectile", "kg", None),            # bound: a fraction of the mass, checked in Round
    "diameter": ("projectile", "m", None),         # bound: a fraction of the diameter, checked in Round
    "density": ("atmosphere", "relative", 0.2),
    "temperature": ("atmosphere", "K", 30.0),
    "position_scale": ("radar", "relative", 0.05),
    "velocity_scale": ("radar", "relative", 0.05),
    "time_offset": ("radar", "s", 1.0),
}
#: largest mass_sd / mass and diameter_sd / diameter accepted
SYSTEMATIC_RELATIVE_MAX = 0.2
#: largest plausible ``[atmosphere] wind_sd`` [m/s]: a met message's winds are known to a few m/s;
#: beyond this the profile says nothing and the wind is better left to the data
WIND_SD_MAX = 30.0


@dataclass(frozen=True, eq=False)
class Systematics:
    """Declared a-priori sds of quantities the fit otherwise holds at their nominal values.

    Each declared sd makes its quantity a nuisance parameter with a Gaussian prior (mean: the
    nominal value, sd as given) that the fit estimates with Cd and whose share of the Cd
    uncertainty is reported; None (the default) holds the quantity at its nominal value and the
    result says the Cd is conditional on it.

    Attributes
    ----------
    mass : float or None, kg
        sd of the projectile mass (``[projectile] mass_sd``).
    diameter : float or None, m
        sd of the reference diameter (``[projectile] diameter_sd``).
    density : float or None, relative
        sd of the air density ratio at unchanged temperature (``[atmosphere] density_sd``;
        0.003 = 0.3 %).
    temperature : float or None, K
        sd of an offset of the whole temperature profile (``[atmosphere] temperature_sd``).
    position_scale : float or None, relative
        sd of a common scale error of x, y, z (``[radar] position_scale_sd``).
    velocity_scale : float or None, relative
        sd of a scale error of v (``[radar] velocity_scale_sd``).
    time_offset : float or None, s
        sd of the radar clock against the launch (``[radar] time_offset_sd``).
    wind_profile : float or None, m/s
        How well the round's winds (its met profile's, or none: calm) are known, per layer
        (``[atmosphere] wind_sd``): the prior sd of the ``wind_profile`` effect's layers, with
        budget key ``wind_profile``. Stored on the round; the diagnosis takes it as the prior of
        a wind's level. (Not yet a source of :data:`SYSTEMATIC_SOURCES`: the fit adds it with
        ``--with wind_profile``.)
    from_met_file : tuple of str
        The stems whose sd is the round's met file's own error (its resolution, the default wind
        sd: :meth:`with_met_error`), not a declaration of the round file.
    """

    mass: float | None = None
    diameter: float | None = None
    density: float | None = None
    temperature: float | None = None
    position_scale: float | None = None
    velocity_scale: float | None = None
    time_offset: float | None = None
    wind_profile: float | None = None
    from_met_file: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "from_met_file", tuple(self.from_met_file))
        wsd = number("wind_sd", self.wind_profile, "m/s", optional=True)
        if wsd is not None:
            wsd = positive("wind_sd", wsd, "m/s")
            if wsd > WIND_SD_MAX:
                raise ValueError(f"wind_sd = {wsd:g} m/s is larger than the plausible {WIND_SD_MAX:g} m/s "
                                 f"(the sd of each layer's wind, in m/s: knots or km/h?)")
        object.__setattr__(self, "wind_profile", wsd)
        for stem, (_, unit, hi) in SYSTEMATIC_SOURCES.items():
            val = number(f"{stem}_sd", getattr(self, stem), unit, optional=True)
            if val is not None:
                val = positive(f"{stem}_sd", val, unit)
                if hi is not None and val > hi:
                    raise ValueError(f"{stem}_sd = {val:g} {unit} is larger than the plausible {hi:g} {unit}"
                                     + (" (it is a fraction: 0.003 means 0.3 %)" if unit == "relative" else ""))
            object.__setattr__(self, stem, val)

    def with_met_error(self, stated):
        """These sds with the met file's own error (:class:`bayesdrag.air.atmosphere.MetError`, or
        None) in the places the round left open: ``density``, ``temperature`` and
        ``wind_profile`` (where the file has winds). The round's own declarations stand."""
        if stated is None:
            return self
        fill = {"density": stated.density_sd, "temperature": stated.temperature_sd, "wind_profile": stated.wind_sd}
        fill = {k: v for k, v in fill.items() if v is not None and v > 0 and getattr(self, k) is None}
        if not fill:
            return self
        values = {k: getattr(self, k) for k in (*SYSTEMATIC_SOURCES, "wind_profile")}
        return Systematics(**{**values, **fill}, from_met_file=tuple(self.from_met_file) + tuple(fill))

    def declared(self):
        """The declared sources as ``{stem: sd}``, in :data:`SYSTEMATIC_SOURCES` order (the met
        file's stated error among them, :attr:`from_met_file`)."""
        return {k: getattr(self, k) for k in SYSTEMATIC_SOURCES if getattr(self, k) is not None}

    def undeclared(self):
        """The stems of the sources held at their nominal values."""
        return [k for k in SYSTEMATIC_SOURCES if getattr(self, k) is None]


@dataclass(frozen=True, eq=False)
class Round:
    """Everything known about one firing besides the track.

    Attributes
    ----------
    projectile : Projectile
    launch : Launch
    atmosphere : Atmosphere or MetProfile
        ``gun_altitude`` equals ``launch.altitude`` (built so by :func:`read_round`, and by
        default when None is passed).
    radar : Radar
    path : str
        The round file, or "".
    systematics : Systematics
        Declared sds of mass, diameter, air and radar calibration (none by default).
    """

    projectile: Projectile
    launch: Launch = field(default_factory=Launch)
    atmosphere: Atmosphere = None
    radar: Radar = field(default_factory=Radar)
    path: str = ""
    systematics: Systematics = field(default_factory=Systematics)

    def __post_init__(self):
        if self.atmosphere is None:
            object.__setattr__(self, "atmosphere", Atmosphere(gun_altitude=self.launch.altitude))
        object.__setattr__(self, "path", str(self.path))
        if not isinstance(self.systematics, Systematics):
            raise ValueError(f"systematics must be a Systematics, got {type_name(self.systematics)}")
        sy = self.systematics
        for stem, nominal in (("mass", self.projectile.mass), ("diameter", self.projectile.diameter)):
            sd = getattr(sy, stem)
            if sd is not None and sd > SYSTEMATIC_RELATIVE_MAX * nominal:
                raise ValueError(f"{stem}_sd = {sd:g} is more than {SYSTEMATIC_RELATIVE_MAX:.0%} of the "
                                 f"{stem} ({nominal:g}); is it in the wrong unit?")

    @property
    def reference_drag(self):
        """The projectile's firing-table drag (``ReferenceTable``) or None."""
        return self.projectile.reference_drag
