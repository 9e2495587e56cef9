"""The session model: every shot of a chronograph session flown with one Cd(M), what the device
reports of each, and where each parameter sits in the parameter vector.

Cd of shot ``i`` at Mach ``M`` is ``(1 + delta_i) * Cd_ref(M) * P(M)``, with the reference's shape
``Cd_ref`` (the round's table or a standard drag function) and a correction polynomial
``P(M) = c_0 + c_1 u + ... + c_{K-1} u^{K-1}``, ``u = (M - M_c) / H`` about the session's
information-weighted Mach ``M_c`` (so ``c_0`` is the form factor there). ``delta_i`` is the shot's
drag scatter (lot, yaw), a random effect of sd ``tau`` across shots. Each shot has its own muzzle
speed ``v0_i`` and time origin ``t0_i``; the session shares the air, the curve and ``q`` (the
device's site as a range rate sees it, :mod:`bayesdrag.measure.chronograph`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...dynamics.flat_fire import fly
from ...measure.chronograph import reported_speed

__all__ = ["Shot", "SessionModel", "Layout", "MACH_TABLE_STEP"]

#: step of the tabulated reference [Mach]: linear interpolation of a smooth table between such
#: points is within 1e-5 relative of the table's own interpolant, far inside any band
MACH_TABLE_STEP = 5e-4


@dataclass(frozen=True)
class Shot:
    """One shot's track as the device wrote it.

    Attributes
    ----------
    name : str
        The shot's name (``Shot0001``).
    t : ndarray, shape (N,), s
        Sample times on the device's clock (from its trigger).
    v : ndarray, shape (N,), m/s
        The reported speed.
    snr : ndarray or None, shape (N,), dB
    source : str
        The file it was read from.
    """

    name: str
    t: np.ndarray
    v: np.ndarray
    snr: np.ndarray | None = None
    source: str = ""

    def __post_init__(self):
        t, v = np.asarray(self.t, float), np.asarray(self.v, float)
        if t.shape != v.shape or t.ndim != 1:
            raise ValueError(f"shot {self.name}: t and v must be 1-D arrays of one length")
        for a in (t, v):
            a.setflags(write=False)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "v", v)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.size)


@dataclass(frozen=True)
class Layout:
    """Where the parameters sit: ``K`` curve coefficients, ``q`` when fitted, then per shot
    ``v0``, ``t0``, ``delta`` (each a block of ``S``)."""

    K: int
    S: int
    fit_q: bool

    @property
    def n_shared(self) -> int:
        return self.K + int(self.fit_q)

    @property
    def size(self) -> int:
        return self.n_shared + 3 * self.S

    def curve(self, theta):
        return np.asarray(theta[: self.K])

    def q(self, theta, q_fixed):
        return float(theta[self.K]) if self.fit_q else q_fixed

    def v0(self, theta):
        return np.asarray(theta[self.n_shared: self.n_shared + self.S])

    def t0(self, theta):
        return np.asarray(theta[self.n_shared + self.S: self.n_shared + 2 * self.S])

    def delta(self, theta):
        return np.asarray(theta[self.n_shared + 2 * self.S:])

    def block(self, which):
        """Slice of a per-shot block: ``"v0"``, ``"t0"`` or ``"delta"``."""
        k = {"v0": 0, "t0": 1, "delta": 2}[which]
        start = self.n_shared + k * self.S
        return slice(start, start + self.S)


@dataclass(frozen=True)
class SessionModel:
    """The physics shared by the shots of a session.

    Attributes
    ----------
    reference_mach, reference_cd : ndarray
        The reference Cd(M) tabulated on a uniform grid every :data:`MACH_TABLE_STEP` over the
        session's span.
    k_air : float, 1/m
        ``rho * A / (2 m)``.
    sound_speed : float, m/s
    mach_center, mach_half : float
        ``M_c`` and ``H`` of the correction polynomial.
    elevation : float, rad
    site_x, site_z : float, m
        The device's position along the line of fire and up.
    q_fixed : float, m^2
        ``q`` when it is not fitted.
    head_wind : float, m/s
    """

    reference_mach: np.ndarray = field(repr=False)
    reference_cd: np.ndarray = field(repr=False)
    k_air: float
    sound_speed: float
    mach_center: float
    mach_half: float
    elevation: float = 0.0
    site_x: float = 0.0
    site_z: float = 0.0
    q_fixed: float = 0.0
    head_wind: float = 0.0

    def reference(self, mach):
        """The reference Cd at ``mach`` (linear between the tabulated points)."""
        return np.interp(mach, self.reference_mach, self.reference_cd)

    def correction(self, coefs, mach):
        """``P(M)`` for curve coefficients ``coefs``."""
        u = (np.asarray(mach, float) - self.mach_center) / self.mach_half
        return np.polyval(np.asarray(coefs, float)[::-1], u)

    def cd(self, coefs, mach):
        """The session's Cd(M)."""
        return self.reference(mach) * self.correction(coefs, mach)

    def correction_basis(self, mach, K):
        """``dP/dc_k`` at ``mach``, shape (len(mach), K)."""
        u = (np.asarray(mach, float) - self.mach_center) / self.mach_half
        return u[:, None] ** np.arange(K)[None, :]

    def predict(self, theta, layout, shots):
        """The reported speed of every shot [m/s] and the Mach of each sample, for ``theta``.

        Returns
        -------
        (list of ndarray, list of ndarray)
            Predicted reported speed and flight Mach, shot by shot.
        """
        coefs = layout.curve(theta)
        drag = (float(self.reference_mach[0]), float(self.reference_mach[1] - self.reference_mach[0]),
                self.reference_cd * self.correction(coefs, self.reference_mach))
        states = fly(layout.v0(theta), layout.t0(theta), 1.0 + layout.delta(theta),
                     drag, [s.t for s in shots], k_air=self.k_air,
                     sound_speed=self.sound_speed, elevation=self.elevation, head_wind=self.head_wind)
        q = layout.q(theta, self.q_fixed)
        pred, mach = [], []
        for x, z, vx, vz in states:
            pred.append(reported_speed(x, z, vx, vz, q, self.site_x, self.site_z))
            mach.append(np.hypot(vx + self.head_wind, vz) / self.sound_speed)
        return pred, mach
