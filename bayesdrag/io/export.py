"""Export a fitted Cd(M) as a custom drag table for py-ballisticcalc 3.x.

py-ballisticcalc takes a drag model as ``DragModel(bc, drag_table)`` with ``drag_table`` a list
of ``{"Mach": M, "CD": Cd}`` points (or ``DragDataPoint``) and a ballistic coefficient ``bc`` in
lb/in². Its drag deceleration is ``density_ratio * Cd(M) * K / bc * v^2`` [ft/s²] with
``K = 2.08551e-4`` and ``density_ratio`` relative to 1.2250 kg/m³ (see ``tests/support/pbc_reference.py``
for the whole derivation, read from its sources). Equating with bayesdrag's
``rho * pi d^2 / (8 m) * Cd * v^2`` gives the **bc that makes the table the projectile's own
Cd** (form factor 1)::

    bc = 8 m K / (0.3048 pi d^2 * 1.2250 kg/m^3)   [lb/in^2]  (= sectional density to 1e-6)

Choices written down:

* **Dense table**: the fitted curve is sampled every :data:`TABLE_DM` Mach over the Mach range
  the data determine (py-ballisticcalc interpolates the table with its own monotone PCHIP; at
  0.005 Mach its curve equals ours to ~1e-5 relative even through the drag rise).
* **Outside the fitted range Cd is held at the end values**, as bayesdrag does, by flat
  extension rows down to Mach 0 and up to Mach 10 (py-ballisticcalc would otherwise *extrapolate*
  the end cubic). The exported file says which range the data determined (``mach_fitted``):
  beyond it the table is not a measurement.
* **Atmosphere**: py-ballisticcalc's density is CIPM-2007 real gas (0.043 % above the ICAO ideal
  gas bayesdrag uses at sea level). ``density_match`` (a factor; :func:`density_match` computes
  it for a py-ballisticcalc ``Atmo`` and a bayesdrag atmosphere) scales ``bc`` so both codes use
  the same air density at the gun; default 1 (the physical bc, the atmosphere models differ by
  that 0.04 %).

File format (``.json``)::

    {"format": "py-ballisticcalc custom drag table", "bc": 2.522, "bc_units": "lb/in^2",
     "mass_kg": 42.6, "diameter_m": 0.155, "mach_fitted": [0.93, 2.40],
     "drag_table": [{"Mach": 0.0, "CD": 0.14}, ...], "source": "...", "notes": [...]}

and use it as ``DragModel(doc["bc"], doc["drag_table"], weight=Weight.Kilogram(mass), ...)``
(:func:`load_pbc_drag_model` does this). ``.csv`` writes the ``Mach,CD`` table alone with the bc
in a comment line.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..errors import InputError

#: py-ballisticcalc's drag constant: rho0 pi / (4 * 2 * 144) with rho0 = 0.076474 lb/ft^3
PBC_DRAG_CONSTANT = 2.08551e-04
#: density py-ballisticcalc's density_ratio = 1 stands for [kg/m^3]
PBC_STANDARD_DENSITY = 1.2250
FT = 0.3048
#: Mach step of the exported table
TABLE_DM = 0.005
#: Mach up to which the last value is held by the flat extension rows
MACH_MAX = 10.0


def pbc_ballistic_coefficient(mass, diameter, density_match=1.0):
    """py-ballisticcalc ``bc`` [lb/in²] for which its drag with a table of *our* Cd equals
    bayesdrag's drag of a projectile of ``mass`` [kg] and ``diameter`` [m].

    ``density_match`` multiplies the result: pass :func:`density_match` to make
    py-ballisticcalc's air density at the gun equal to bayesdrag's.
    """
    if not (mass > 0 and diameter > 0):
        raise ValueError(f"mass and diameter must be positive, got {mass!r} kg, {diameter!r} m")
    return 8.0 * mass * PBC_DRAG_CONSTANT / (FT * math.pi * diameter ** 2 * PBC_STANDARD_DENSITY) * density_match


def density_match(pbc_atmo, atmosphere):
    """Factor on ``bc`` that makes py-ballisticcalc's density at the gun equal bayesdrag's.

    Parameters
    ----------
    pbc_atmo : py_ballisticcalc.Atmo
        The atmosphere the py-ballisticcalc shot will use (its ``density_ratio`` at the gun).
    atmosphere : bayesdrag.air.atmosphere.Atmosphere or MetProfile
        bayesdrag's atmosphere of the round (heights relative to the gun).

    Returns
    -------
    float
        ``density_ratio_pbc / (rho_bayesdrag(gun) / 1.2250)``; 1.000426 for ICAO sea level.
    """
    rho, _ = atmosphere.density_and_sound_speed(0.0)
    return float(pbc_atmo.density_ratio) / (float(rho) / PBC_STANDARD_DENSITY)


def drag_table(cd_fn, mach_range, dm=TABLE_DM, reference=None):
    """Dense ``[(Mach, Cd)]`` of ``cd_fn`` over ``mach_range`` with extensions to 0 and
    :data:`MACH_MAX`: flat, or, with a ``reference``, the reference's shape scaled to meet the
    fitted curve at each end (a solver flies the whole table; a rifle bullet's Cd held flat from
    Mach 2 down to 0 is 2-3 times too high at subsonic speed).

    Parameters
    ----------
    cd_fn : callable (n,) Mach -> (n,) Cd
    mach_range : (lo, hi)
    dm : float
        Step [Mach].
    reference : object with ``value(mach)``, optional
        The reference drag (a table or a standard function) whose shape continues the curve.

    Returns
    -------
    (mach, cd) : ndarrays
    """
    if reference is not None:
        return _joined_table(cd_fn, mach_range, dm, reference)
    lo, hi, m, c = _fitted_part(cd_fn, mach_range, dm)
    ext_lo = [x for x in (0.0, lo / 2) if x < lo - 1e-9]
    ext_hi = [x for x in ((hi + MACH_MAX) / 2, MACH_MAX) if x > hi + 1e-9]
    return (np.concatenate([ext_lo, m, ext_hi]),
            np.concatenate([[c[0]] * len(ext_lo), c, [c[-1]] * len(ext_hi)]))


def _fitted_part(cd_fn, mach_range, dm):
    """(lo, hi, Mach grid, Cd) of the fitted curve over ``mach_range`` every ``dm``, checked."""
    lo, hi = float(mach_range[0]), float(mach_range[1])
    if not (0 <= lo < hi <= MACH_MAX):
        raise ValueError(f"mach_range must satisfy 0 <= lo < hi <= {MACH_MAX}, got {mach_range}")
    n = max(int(math.ceil((hi - lo) / dm)), 1)
    m = np.linspace(lo, hi, n + 1)
    c = np.asarray(cd_fn(m), float)
    if not np.all(np.isfinite(c)) or np.any(c <= 0):
        raise ValueError("the Cd curve must be positive and finite over the exported range")
    return lo, hi, m, c


#: Mach step of the reference-shaped extensions beyond the fitted span
EXTENSION_DM = 0.025


def _joined_table(cd_fn, mach_range, dm, reference):
    """:func:`drag_table` with the reference's shape beyond the fitted span, scaled at each end."""
    lo, hi, m, c = _fitted_part(cd_fn, mach_range, dm)
    below = np.arange(0.0, lo - 1e-9, EXTENSION_DM)
    above = np.arange(hi + EXTENSION_DM, MACH_MAX + 1e-9, EXTENSION_DM)
    r_lo, r_hi = float(reference.value(lo)), float(reference.value(hi))
    c_below = np.asarray(reference.value(below), float) * (c[0] / r_lo) if below.size else np.zeros(0)
    c_above = np.asarray(reference.value(above), float) * (c[-1] / r_hi) if above.size else np.zeros(0)
    return np.concatenate([below, m, above]), np.concatenate([c_below, c, c_above])


def export_curve(path, cd_fn, mach_range, mass, diameter, source, reference=None, density_factor=1.0,
                 dm=TABLE_DM):
    """Write a fitted curve ``cd_fn`` over ``mach_range`` as a py-ballisticcalc table (``.json`` or
    ``.csv`` by the suffix), continued beyond the span by the ``reference``'s shape when given.
    Returns the document."""
    m, c = drag_table(cd_fn, mach_range, dm, reference=reference)
    beyond = (f"the reference's shape ({getattr(reference, 'source', '') or 'reference'}) scaled to meet the fitted "
              f"curve" if reference is not None else None)
    return _write(path, m, c, mass, diameter, mach_range, source, density_factor, beyond)


def export_fit(path, drag_model, params, mach_range, mass, diameter, source="", density_factor=1.0,
               dm=TABLE_DM):
    """Write the fitted curve ``drag_model.cd(params, M)`` over ``mach_range`` as a
    py-ballisticcalc table (``.json`` or ``.csv`` by the suffix). Returns the document."""
    m, c = drag_table(lambda x: drag_model.cd(np.asarray(params, float), x), mach_range, dm)
    return _write(path, m, c, mass, diameter, mach_range, source or f"bayesdrag fit ({drag_model.name})",
                  density_factor)


def export_result(path, result_dir, mass, diameter, which="ml", density_factor=1.0, dm=TABLE_DM):
    """Export the Cd of a ``bayesdrag fit`` output folder (``result.json``; ``which`` = "ml" or
    "mean" for the posterior mean) or of a campaign folder (``campaign.json``: the pooled mean).

    The rows of those files are on a grid of ~0.02 Mach (fit) or on the campaign nodes; they are
    interpolated by PCHIP (monotone: no overshoot at the drag rise) onto the dense table, which
    costs up to ~0.5 % at the sharpest bend of the rise (measured 0.46 % on the M101 knee; < 1e-4 elsewhere). Use :func:`export_fit` with the fitted
    drag model for the exact curve. The range written as fitted is the one the data determine
    (``ml.mach_range_determined``) when known, else the rows' span.
    """
    from scipy.interpolate import PchipInterpolator

    d = Path(result_dir)
    determined = None
    if (d / "campaign.json").is_file():
        doc = json.loads((d / "campaign.json").read_text(encoding="utf-8"))
        rows, key, src = doc["cd"], "mean", f"bayesdrag campaign {doc.get('name', '')} ({d})"
    elif (d / "result.json").is_file():
        doc = json.loads((d / "result.json").read_text(encoding="utf-8"))
        rows, key, src = doc["cd"], which, f"bayesdrag fit {d} ({doc.get('drag_model')}, {which})"
        determined = doc.get("ml", {}).get("mach_range_determined")
    else:
        raise InputError(f"{d}: no result.json or campaign.json to export")
    if not rows or rows[0].get(key) is None:
        raise InputError(f"{d}: the Cd rows have no {key!r} values (posterior means need a fit with sampling)")
    m = np.array([r["mach"] for r in rows], float)
    c = np.array([r[key] for r in rows], float)
    f = PchipInterpolator(m, c)
    lo, hi = determined if determined else (m[0], m[-1])
    mm, cc = drag_table(f, (lo, hi), dm)
    return _write(path, mm, cc, mass, diameter, (lo, hi), src, density_factor)


def _write(path, m, c, mass, diameter, fitted, source, density_factor, beyond=None):
    path = Path(path)
    bc = pbc_ballistic_coefficient(mass, diameter, density_factor)
    beyond = beyond or "Cd held at its end values"
    notes = [f"{beyond} outside Mach {fitted[0]:.3f}-{fitted[1]:.3f} (not measured there)",
             "bc makes the table the projectile's own Cd in py-ballisticcalc (form factor 1)"]
    doc = {"format": "py-ballisticcalc custom drag table", "bc": bc, "bc_units": "lb/in^2",
           "mass_kg": float(mass), "diameter_m": float(diameter), "mach_fitted": [float(fitted[0]), float(fitted[1])],
           "density_factor": float(density_factor), "source": source, "notes": notes,
           "drag_table": [{"Mach": round(float(a), 6), "CD": float(b)} for a, b in zip(m, c)]}
    from .outputs import atomic_write

    if path.suffix.lower() == ".csv":
        body = (f"# py-ballisticcalc custom drag table from {source}\n# bc = {bc:.8g} lb/in^2 "
                f"(mass {mass} kg, diameter {diameter} m); " + "; ".join(notes) + "\nMach,CD\n"
                + "".join(f"{a:.6g},{b:.8g}\n" for a, b in zip(m, c)))
        atomic_write(path, lambda tmp: Path(tmp).write_text(body, encoding="utf-8"))
    else:
        atomic_write(path, lambda tmp: Path(tmp).write_text(json.dumps(doc, indent=1), encoding="utf-8"))
    return doc


def load_pbc_drag_model(path):
    """A ``py_ballisticcalc.DragModel`` from a ``.json`` file written here."""
    from py_ballisticcalc import DragModel
    from py_ballisticcalc.unit import Distance, Weight

    doc = json.loads(Path(path).read_text(encoding="utf-8"))
    return DragModel(doc["bc"], doc["drag_table"], weight=Weight.Kilogram(doc["mass_kg"]),
                     diameter=Distance.Meter(doc["diameter_m"]))
