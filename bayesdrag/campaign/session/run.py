"""A chronograph session from its shots and one round to the record ``campaign.json`` holds:
the session model built from the round, the fit, the claims (docs/radar.md, "Chronograph
sessions"; the schema is DESIGN's "Campaigns" section, extended)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...errors import FitError, InputError
from ...air.station import is_station_air
from ...io.drag_tables import read_standard_drag
from . import claims
from .fit import fit_session
from .model import MACH_TABLE_STEP, SessionModel, Shot

__all__ = ["SessionOutcome", "fit_chronograph_session", "session_model", "STANDARDS", "DEFAULT_REFERENCE"]

#: the standard drag functions every session reports its form factor and ballistic coefficient against
STANDARDS = ("G1", "G7")
#: the reference shape when the round names none: G7, the standard of modern long boat-tailed
#: bullets; the correction polynomial takes up the shape's differences the data determine
DEFAULT_REFERENCE = "G7"
#: the reference is tabulated over the flown span widened by this [Mach] (fits move the speeds)
_TABLE_MARGIN = 0.3


@dataclass(frozen=True)
class SessionOutcome:
    """A session's fit and its record (``campaign.json``)."""

    fit: object = field(repr=False)
    record: dict = field(repr=False)
    shots: tuple = field(repr=False)
    reference: object = field(default=None, repr=False)


def _air(rnd):
    """(density [kg/m^3], speed of sound [m/s]) at the gun."""
    st = rnd.atmosphere.at_height(np.array([0.0]))
    return float(np.ravel(st.density)[0]), float(np.ravel(st.speed_of_sound)[0])


def session_model(rnd, shots):
    """The :class:`SessionModel` of a round for these shots (reference tabulated over their speeds)."""
    p = rnd.projectile
    ref = p.reference_drag if p.reference_drag is not None else read_standard_drag(DEFAULT_REFERENCE)
    rho, c = _air(rnd)
    v_lo = min(float(np.min(s.v)) for s in shots)
    v_hi = max(float(np.max(s.v)) for s in shots)
    m_lo, m_hi = max(v_lo / c - _TABLE_MARGIN, 0.05), v_hi / c + _TABLE_MARGIN
    mach = np.arange(m_lo, m_hi + MACH_TABLE_STEP, MACH_TABLE_STEP)
    k_air = rho * math.pi * p.diameter ** 2 / 4.0 / (2.0 * p.mass)
    el = math.radians(rnd.launch.elevation_deg or 0.0)
    ra = rnd.radar
    d_typed = ra.device_offset or 0.0
    q_fixed = ra.position[1] ** 2 - d_typed ** 2
    return SessionModel(mach, ref.value(mach), k_air=k_air, sound_speed=c, mach_center=float(np.mean(mach)),
                        mach_half=0.1, elevation=el, site_x=float(ra.position[0]), site_z=float(ra.position[2]),
                        q_fixed=float(q_fixed)), ref


def _q_mode(rnd):
    """(fit q?, its prior (mean, sd) or None): known when the round types an offset and gives no
    sd for it; a prior from ``device_offset_sd`` (or ``position_sd``); free without an offset."""
    ra = rnd.radar
    sd = ra.device_offset_sd if ra.device_offset_sd is not None else ra.position_sd
    if ra.device_offset is not None and sd is None:
        return False, None
    if ra.device_offset is None and sd is None:
        return True, None
    y = ra.position[1]
    q0 = y * y - (ra.device_offset or 0.0) ** 2
    return True, (q0, math.sqrt(4 * y * y * sd * sd + 2 * sd ** 4))


def _declared_rel_sd(rnd):
    """Relative Cd sd of the round's declared mass, diameter and density tolerances (Cd scales as
    m / (rho d^2)), which a session cannot tell from its Cd, keyed by the round's key."""
    sy, p = rnd.systematics, rnd.projectile
    parts = {}
    if sy.mass:
        parts["mass_sd"] = sy.mass / p.mass
    if sy.diameter:
        parts["diameter_sd"] = 2 * sy.diameter / p.diameter
    if sy.density:
        parts["density_sd"] = sy.density
    return parts


def fit_chronograph_session(files, rnd, *, log=None):
    """Fit a chronograph session (:class:`bayesdrag.io.sessions.SessionFiles`) with one round.

    Returns
    -------
    SessionOutcome

    Raises
    ------
    FitError
        Fewer than two shots could be read, or the fit failed.
    InputError
        The round lacks the projectile's mass or diameter.
    """
    p = rnd.projectile
    if p.mass is None or p.diameter is None:
        raise InputError(f"{rnd.path or 'round'}: a chronograph session needs [projectile] mass and diameter")
    usable = [s for s in files.shots if s.track is not None]
    if len(usable) < 2:
        raise FitError(f"{files.name}: {len(usable)} readable shot(s); a session needs at least 2 "
                       + "; ".join(f"{s.name}: {s.skipped}" for s in files.shots if s.skipped)[:400])
    shots = [Shot(s.name, s.track.t, s.track.channels["range_rate"],
                  s.track.extra.get("snr"), s.path) for s in usable]
    model, ref = session_model(rnd, shots)
    fit_q, q_prior = _q_mode(rnd)
    fit = fit_session(shots, model, fit_q=fit_q, q_prior=q_prior, log=log)
    record = session_record(fit, files, rnd, ref)
    return SessionOutcome(fit, record, tuple(shots), ref)


def session_record(fit, files, rnd, ref):
    """The ``campaign.json`` record of a session fit."""
    declared = _declared_rel_sd(rnd)
    wind = claims.wind_rel_sd(fit, rnd.systematics.wind_profile)
    if wind:
        declared["wind_sd"] = wind
    extra = math.sqrt(sum(v * v for v in declared.values()))
    all_rows = claims.rows(fit, extra)
    # a curve that goes through zero is no drag coefficient there: those rows are not written
    rows = [r for r in all_rows if r["physical"]]
    unphysical = [r["mach"] for r in all_rows if not r["physical"]]
    central = claims.central_row(fit, extra)
    determined = [r for r in rows if r["determined"]]
    chosen = determined or [central]
    ff, bc = {}, {}
    for name in STANDARDS:
        if central["mean"] <= 0:
            ff[name] = {"value": None, "sd": None, "rows": 0, "from": "no physical Cd"}
            bc[name] = {"value": None, "sd": None, "unit": "lb/in^2", "value_kg_m2": None, "sd_kg_m2": None}
            continue
        ff[name] = claims.form_factor(fit, read_standard_drag(name), chosen, extra)
        ff[name]["from"] = "the determined rows" if determined else "the central row (no row determined)"
        bc[name] = claims.ballistic_coefficient(ff[name], rnd.projectile.mass, rnd.projectile.diameter)
    L, sd = fit.layout, fit.sd()
    by_name = {s.name: i for i, s in enumerate(fit.shots)}
    shots = []
    for s in files.shots:
        i = by_name.get(s.name)
        if i is None:
            shots.append({"name": s.name, "v0": None, "v0_sd": None, "samples": 0, "outliers": 0,
                          "skipped": s.skipped, "source": s.path})
            continue
        k = fit.keep[i]
        shots.append({"name": s.name, "v0": float(L.v0(fit.theta)[i]), "v0_sd": float(sd[L.block("v0")][i]),
                      "t0": float(L.t0(fit.theta)[i]), "t0_sd": float(sd[L.block("t0")][i]),
                      "drag_level": float(fit.levels[i]), "drag_level_sd": float(fit.level_sd[i]),
                      "samples": int(k.sum()), "outliers": int((~k).sum()), "noise_sd": float(fit.sigma[i]),
                      "rho": float(fit.rho[i]), "skipped": None, "source": s.path,
                      "mach_mean": float(np.mean(fit.mach[i][k])),
                      "v0_reported": (s.report or {}).get("v0_reported")})
    n_det = len(determined)
    warnings = []
    if not n_det:
        warnings.append(f"no Cd row is determined to {100 * claims.DETERMINED_REL_SD:g} % (the central row at Mach "
                        f"{central['mach']:.3f}: {100 * central['rel_sd']:.2g} %)")
    if central["claimed"] and not central["determined"]:
        warnings.append(f"the central row's band is {100 * central['rel_sd']:.2g} %: claimed (at most "
                        f"{100 * claims.CLAIM_REL_SD:g} %) but not determined (at most "
                        f"{100 * claims.DETERMINED_REL_SD:g} %)")
    if unphysical or central["mean"] <= 0:
        warnings.insert(0, f"the fitted curve is not a drag coefficient (Cd <= 0 at Mach {min(unphysical or [central['mach']]):.3f}"
                           f"{'-' + format(max(unphysical), '.3f') if len(unphysical) > 1 else ''}): the shots do not "
                           f"determine their deceleration there; no row is written there")
    skipped = [s for s in shots if s["skipped"]]
    air = rnd.atmosphere
    return {
        "kind": "chronograph_session",
        "name": files.name,
        "rounds": [s.name for s in fit.shots],
        "cd": rows,
        "central": central,
        "scatter": claims.scatter(fit),
        "shots": shots,
        "muzzle_velocity": claims.muzzle_velocity(fit),
        "form_factor": ff,
        "bc": bc,
        "reference": getattr(ref, "source", "") or DEFAULT_REFERENCE,
        "model": {"order": L.K, "bic": {str(k): v for k, v in fit.bic.items()}, "mach_center": fit.model.mach_center,
                  "mach_half": fit.model.mach_half, "coefficients": [float(c) for c in L.curve(fit.theta)],
                  "coefficients_sd": [float(x) for x in sd[: L.K]], "dof": fit.dof},
        "fit": {"chi2": fit.chi2, "samples": fit.n_data, "parameters": L.size, "shots": len(fit.shots),
                "skipped": len(skipped), "noise_sd_median": float(np.median(fit.sigma)),
                "rho_median": float(np.median(fit.rho))},
        "site": claims.site(fit, rnd.radar.device_offset),
        "uncertainty": {"declared": declared, "band": "Student t with the shots' degrees of freedom"},
        "conditional_on": ([] if hasattr(air, "stated_error") or is_station_air(air) else
                           ["the stated air (density and speed of sound at the gun): a session cannot tell the air's "
                            "density from the Cd level"])
        + ["the device's setup: its position along the line of fire and its own speed processing are not "
           "determined by a range rate; one bullet measured in two setups differed by 25 % in level with bands "
           "of 1 % (docs/real_data.md)"],
        "air": dict(zip(("rho", "sound_speed"), _air(rnd))),
        "determined": {"rows": n_det, "of": len(rows)},
        "warnings": warnings,
        "notes": list(files.notes),
    }
