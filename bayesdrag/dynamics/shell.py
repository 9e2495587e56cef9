"""A spin-stabilised shell for the 6-DOF model: its mass properties (:class:`Shell`), its
aerodynamic coefficients by Mach (:class:`ShellAero`, representative M107 values in
:func:`m107_aero`), the paper's Table 1 shell, and linear theory (gyroscopic stability, yaw of
repose) to check the 6-DOF integration against. See :mod:`bayesdrag.dynamics.sixdof` for what
the coefficients mean and where they come from."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..drag import ReferenceTable
from ..io.drag_tables import load_m101

__all__ = ["ShellAero", "Shell", "m107_aero", "table1_shell", "default_spin_rate", "gyroscopic_stability",
           "LinearTheory", "linear_theory", "MAX_VALID_YAW"]

#: largest total yaw [rad] for which the linear aerodynamic model is trusted (20 deg); a run
#: exceeding it is reported with ``success=False``
MAX_VALID_YAW = math.radians(20.0)


# ---------------------------------------------------------------------------------------------
# aerodynamic data
# ---------------------------------------------------------------------------------------------
def _as_table(values, name, n):
    a = np.asarray(values, dtype=float)
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise ValueError(f"ShellAero.{name} must be {n} finite numbers (one per Mach node), "
                         f"got shape {a.shape}")
    return tuple(a.tolist())


@dataclass(frozen=True)
class ShellAero:
    """Aerodynamic coefficients of a spin-stabilised shell as tables over Mach number.

    All coefficients use the reference area ``S = pi d^2 / 4`` and length ``d``, moments about
    the centre of mass, angles in radians; signs as in McCoy (1999) ch. 9 (see module
    docstring). Values are interpolated linearly between nodes and held constant outside.

    Attributes
    ----------
    mach : tuple of float
        Mach nodes, strictly increasing.
    cd_delta2 : tuple of float
        Yaw-drag coefficient ``C_D_delta2``: ``C_D = C_D0 + C_D_delta2 sin^2(delta)``.
    cl_alpha : tuple of float
        Lift-force coefficient slope ``C_L_alpha`` [1/rad].
    cm_alpha : tuple of float
        Overturning-moment coefficient slope ``C_M_alpha`` [1/rad] (> 0 for a shell).
    cmq_cmad : tuple of float
        Pitch-damping moment coefficient sum ``C_M_q + C_M_alpha_dot`` (< 0 damps).
    cnpa_force : tuple of float
        Magnus-force coefficient ``C_N_p_alpha``.
    cnpa_moment : tuple of float
        Magnus-moment coefficient ``C_n_p_alpha``.
    clp : tuple of float
        Spin-damping moment coefficient ``C_l_p`` (< 0).
    source : str
        Citation.
    """

    mach: tuple
    cd_delta2: tuple
    cl_alpha: tuple
    cm_alpha: tuple
    cmq_cmad: tuple
    cnpa_force: tuple
    cnpa_moment: tuple
    clp: tuple
    source: str = ""

    _FIELDS = ("cd_delta2", "cl_alpha", "cm_alpha", "cmq_cmad", "cnpa_force", "cnpa_moment", "clp")

    def __post_init__(self):
        m = np.asarray(self.mach, dtype=float)
        if m.ndim != 1 or len(m) < 2 or np.any(np.diff(m) <= 0) or not np.all(np.isfinite(m)):
            raise ValueError(f"ShellAero.mach must be >= 2 finite, strictly increasing Mach numbers,"
                             f" got {self.mach!r}")
        object.__setattr__(self, "mach", tuple(m.tolist()))
        for name in self._FIELDS:
            object.__setattr__(self, name, _as_table(getattr(self, name), name, len(m)))

    def at(self, mach):
        """All coefficients at ``mach`` (scalar or array): dict name -> value(s)."""
        m = np.asarray(mach, dtype=float)
        return {name: np.interp(m, self.mach, getattr(self, name)) for name in self._FIELDS}

    def table(self):
        """(K, 8) array: columns mach, then the coefficients in ``_FIELDS`` order (kernel form)."""
        cols = [self.mach] + [getattr(self, n) for n in self._FIELDS]
        return np.ascontiguousarray(np.column_stack(cols), dtype=float)

    def scaled(self, **factors):
        """A copy with coefficients multiplied by factors, e.g. ``scaled(cl_alpha=0.0)``."""
        kw = {n: tuple(np.asarray(getattr(self, n)) * factors.pop(n, 1.0)) for n in self._FIELDS}
        if factors:
            raise ValueError(f"unknown coefficient(s) {sorted(factors)}; allowed: {self._FIELDS}")
        return ShellAero(self.mach, source=self.source + " (scaled)", **kw)


def m107_aero():
    """Representative 155 mm M107 aerodynamic coefficients versus Mach number.

    Source: rounded, smoothed values after the 155 mm HE M107 data in R. L. McCoy, *Modern
    Exterior Ballistics* (Schiffer, 1999), chs. 2 and 10 (BRL spark-range and wind-tunnel
    measurements), entered without the book at hand: *representative* values of a 155 mm
    shell, not a transcription (see the module docstring; verify against the book before
    quoting individual numbers). With the paper's Table 1 shell and a 1-in-20-calibre twist they give
    gyroscopic stability Sg ~ 2-3 at the muzzle and both epicyclic modes damped over
    Mach 0.5-2.5 (see :func:`linear_theory`). The zero-yaw drag is *not* in this table: it comes
    from the M101 curve (BRL MR-1167), see :func:`table1_shell`.
    """
    mach = (0.40, 0.60, 0.80, 0.90, 0.95, 1.00, 1.05, 1.10, 1.20, 1.50, 2.00, 2.50, 3.00)
    return ShellAero(
        mach=mach,
        cd_delta2=(2.9, 2.9, 3.0, 3.3, 3.6, 3.9, 4.0, 3.9, 3.8, 3.5, 3.2, 3.0, 2.9),
        cl_alpha=(1.55, 1.60, 1.70, 1.80, 1.85, 1.90, 2.05, 2.20, 2.40, 2.60, 2.80, 2.90, 3.00),
        cm_alpha=(3.70, 3.80, 4.00, 4.20, 4.35, 4.40, 4.30, 4.20, 4.00, 3.60, 3.20, 2.95, 2.80),
        cmq_cmad=(-8.0, -8.0, -8.5, -9.0, -9.5, -10.0, -11.0, -11.5, -11.5, -11.0, -10.0, -9.5,
                  -9.0),
        cnpa_force=(-0.30, -0.30, -0.30, -0.28, -0.26, -0.24, -0.22, -0.20, -0.20, -0.18, -0.15,
                   -0.12, -0.10),
        cnpa_moment=(0.30, 0.30, 0.28, 0.26, 0.25, 0.24, 0.22, 0.20, 0.18, 0.15, 0.12, 0.10, 0.08),
        clp=(-0.016, -0.016, -0.015, -0.015, -0.014, -0.014, -0.013, -0.013, -0.013, -0.012,
             -0.011, -0.010, -0.010),
        source="155 mm HE M107, representative values after McCoy, Modern Exterior Ballistics "
               "(1999), chs. 2 and 10 (not a transcription)",
    )


@dataclass(frozen=True, eq=False)
class Shell:
    """Mass properties, geometry and aerodynamics of a symmetric spin-stabilised shell.

    Attributes
    ----------
    mass : float, kg
    diameter : float, m
        Reference diameter d (reference area pi d^2 / 4).
    Ix : float, kg m^2
        Axial (roll) moment of inertia.
    Iy : float, kg m^2
        Transverse (pitch = yaw) moment of inertia about the centre of mass.
    aero : ShellAero
        Yaw-dependent coefficients.
    cd0 : ReferenceTable
        Zero-yaw drag coefficient C_D0(M).
    name : str
    """

    mass: float
    diameter: float
    Ix: float
    Iy: float
    aero: ShellAero
    cd0: ReferenceTable
    name: str = "shell"

    def __post_init__(self):
        for n in ("mass", "diameter", "Ix", "Iy"):
            v = getattr(self, n)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"Shell.{n} must be a finite positive number, got {v!r}")
        if not isinstance(self.aero, ShellAero):
            raise ValueError(f"Shell.aero must be a ShellAero, got {type(self.aero).__name__}")
        if not isinstance(self.cd0, ReferenceTable):
            raise ValueError(f"Shell.cd0 must be a bayesdrag.drag.ReferenceTable, got "
                             f"{type(self.cd0).__name__}")

    @property
    def area(self):
        """Reference area pi d^2 / 4 [m^2]."""
        return math.pi * self.diameter ** 2 / 4.0


def table1_shell():
    """The paper's Table 1 example shell with M101 zero-yaw drag and M107 aerodynamics.

    42.6 kg, d = 0.155 m, Ix = 0.146 kg m^2, Iy = 1.709 kg m^2 (paper Table 1); ``cd0`` from
    :func:`bayesdrag.io.drag_tables.load_m101` (BRL MR-1167); other coefficients :func:`m107_aero`.
    """
    return Shell(mass=42.6, diameter=0.155, Ix=0.146, Iy=1.709, aero=m107_aero(),
                 cd0=load_m101(), name="paper Table 1 shell (M101 drag, M107 aerodynamics)")


def default_spin_rate(velocity, diameter, twist_calibres=20.0):
    """Muzzle spin [rad/s] for a rifling twist of one turn in ``twist_calibres`` calibres:
    ``2 pi V / (twist d)``. 818 m/s, 0.155 m, 1/20 -> 1658 rad/s (paper Table 1: 1657)."""
    return 2.0 * math.pi * velocity / (twist_calibres * diameter)


# ---------------------------------------------------------------------------------------------
# stability
# ---------------------------------------------------------------------------------------------
def gyroscopic_stability(shell, velocity, spin_rate, density, mach):
    """Gyroscopic stability factor Sg (McCoy 1999, ch. 10).

    ``Sg = Ix^2 p^2 / (2 rho S d Iy V^2 C_M_alpha(M))`` = P^2 / (4 M) of linear theory. A shell
    is gyroscopically stable when Sg > 1 (in practice Sg >= 1.3 is asked for at the muzzle).

    Parameters
    ----------
    shell : Shell
    velocity : float or ndarray, m/s
        Air-relative speed V.
    spin_rate : float or ndarray, rad/s
        Axial spin p.
    density : float or ndarray, kg/m^3
    mach : float or ndarray
        Mach number (selects C_M_alpha).

    Returns
    -------
    float or ndarray
    """
    cma = np.interp(np.asarray(mach, dtype=float), shell.aero.mach, shell.aero.cm_alpha)
    sg = (shell.Ix ** 2 * np.asarray(spin_rate, float) ** 2
          / (2.0 * np.asarray(density, float) * shell.area * shell.diameter * shell.Iy
             * np.asarray(velocity, float) ** 2 * cma))
    return float(sg) if np.ndim(sg) == 0 else sg


@dataclass(frozen=True)
class LinearTheory:
    """Linear-theory stability of the epicyclic yaw motion at one flight condition.

    Attributes
    ----------
    sg : float
        Gyroscopic stability factor.
    sd : float
        Dynamic stability factor 2T/H.
    fast_damping, slow_damping : float, 1/s
        Exponential rates lambda_F, lambda_S of the fast (nutation) and slow (precession) yaw
        arms in time (< 0: the arm decays).
    fast_frequency, slow_frequency : float, rad/s
        Turning rates of the two arms.
    """

    sg: float
    sd: float
    fast_damping: float
    slow_damping: float
    fast_frequency: float
    slow_frequency: float

    @property
    def stable(self):
        return self.sg > 1.0 and self.fast_damping < 0.0 and self.slow_damping < 0.0


def linear_theory(shell, velocity, spin_rate, density, mach, cd=None):
    """McCoy's (1999, ch. 10) linear-theory stability factors and damping rates.

    Uses ``P = Ix p d / (Iy V)``, ``M = rho S d/(2m) k_t^-2 C_M_alpha``,
    ``H = rho S d/(2m) [C_L_alpha - C_D - k_t^-2 (C_M_q + C_M_alpha_dot)]``,
    ``T = rho S d/(2m) [C_L_alpha + k_a^-2 C_n_p_alpha]`` (per calibre of travel) and
    ``lambda_F,S = -(H -+ P (2T - H) / sqrt(P^2 - 4M)) / 2``, converted to time by V/d.

    Parameters
    ----------
    shell : Shell
    velocity : float, m/s (air-relative)
    spin_rate : float, rad/s
    density : float, kg/m^3
    mach : float
    cd : float, optional
        Drag coefficient; default ``shell.cd0.value(mach)``.

    Returns
    -------
    LinearTheory
    """
    c = {k: float(v) for k, v in shell.aero.at(mach).items()}
    if cd is None:
        cd = float(shell.cd0.value(mach))
    m, d = shell.mass, shell.diameter
    k = density * shell.area * d / (2.0 * m)
    kt2 = m * d * d / shell.Iy   # k_t^-2
    ka2 = m * d * d / shell.Ix   # k_a^-2
    P = shell.Ix * spin_rate * d / (shell.Iy * velocity)
    M = k * kt2 * c["cm_alpha"]
    H = k * (c["cl_alpha"] - cd - kt2 * c["cmq_cmad"])
    T = k * (c["cl_alpha"] + ka2 * c["cnpa_moment"])
    disc = P * P - 4.0 * M
    sg = P * P / (4.0 * M) if M > 0 else math.inf
    sd = 2.0 * T / H
    scale = velocity / d  # per calibre -> per second
    if disc <= 0.0:
        return LinearTheory(sg, sd, math.nan, math.nan, math.nan, math.nan)
    root = math.sqrt(disc)
    lam_f = -0.5 * (H - P * (2.0 * T - H) / root)
    lam_s = -0.5 * (H + P * (2.0 * T - H) / root)
    return LinearTheory(sg, sd, lam_f * scale, lam_s * scale, 0.5 * (P + root) * scale,
                        0.5 * (P - root) * scale)
