"""Convert the Warner Tool Company Doppler-radar reports (CSV files ``<stem>_doppler.csv``, ``<stem>_cd.csv``) into bayesdrag
files in SI units.

Source: Warner Tool Company Doppler-radar reports, 2019-01-03: .338 Flatline (285 gr, 0.338 in)
and 6.5 mm Flatline (123 gr, 0.264 in) bullets; velocity and time of flight every 100 yd, and
the published drag coefficient by Mach number. The site atmosphere is not stated.

For each bullet this writes ``examples/warner/<bullet>/``:

``track.csv``
    columns ``t`` [s], ``x`` [m] (downrange distance), ``v`` [m/s] (flat fire: no y, z).
    Note the roles: the report tabulates time and velocity at fixed distances; bayesdrag's track
    treats ``t`` as exact and ``x``, ``v`` as measured. Time is given to 1 ms, so ``x`` carries
    the time rounding (uniform +-0.5 ms x ~900 m/s: sd ~0.26 m).
``cd_published.csv``
    ``mach,cd`` as published, used as the round's reference drag.
``round.toml``
    mass, diameter, reference drag; launch velocity = the 0 yd velocity; elevation = the angle
    that brings a vacuum trajectory back to muzzle height at the last distance (flat fire: the
    speed is insensitive to it, g sin(0.6 deg) ~ 0.1 m/s^2 against ~200 m/s^2 of drag
    deceleration); ICAO standard atmosphere at sea level (nothing else is stated);
    ``reference_extrapolate = true`` because the published Cd stops at Mach 2.5 while the
    muzzle Mach is ~2.75 (Cd held at its Mach 2.5 value there); radar sigma from the rounding
    of the published numbers (x 0.3 m from 1 ms in t, v 0.05 m/s from 0.1 ft/s plus margin).

Run: ``python examples/warner/convert.py [DATA_DIR]`` (the folder holding the report CSVs; default ``../shared/data/warner``,
where this repository's developers keep them).
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

FT = 0.3048            # m per foot (exact)
YD = 0.9144            # m per yard (exact)
INCH = 0.0254          # m per inch (exact)
GRAIN = 64.79891e-6    # kg per grain (exact)
G0 = 9.80665

BULLETS = {
    # folder: (source stem, name, mass [gr], diameter [in])
    "338_flatline": ("338_flatline", ".338 Flatline 285 gr", 285.0, 0.338),
    "65_flatline": ("65_flatline", "6.5 mm Flatline 123 gr", 123.0, 0.264),
}
SIGMA = {"x": 0.3, "v": 0.05}
SOURCE = ("Warner Tool Company Doppler-radar report, published 2019-01-03 "
          "({stem}_{kind}.csv)")


def read_rows(path):
    """Numeric rows and header of a ``#``-commented CSV."""
    lines = [ln for ln in Path(path).read_text().splitlines() if ln.strip() and not ln.startswith("#")]
    header = [h.strip() for h in lines[0].split(",")]
    data = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
    return header, data


def convert(data_dir, out_dir):
    data_dir, out_dir = Path(data_dir), Path(out_dir)
    for folder, (stem, name, mass_gr, diam_in) in BULLETS.items():
        d = out_dir / folder
        d.mkdir(parents=True, exist_ok=True)
        header, dop = read_rows(data_dir / f"{stem}_doppler.csv")
        assert header == ["distance_yd", "velocity_fps", "time_s"], header
        x, v, t = dop[:, 0] * YD, dop[:, 1] * FT, dop[:, 2]
        src = SOURCE.format(stem=stem, kind="doppler")
        body = "".join(f"{ti:.3f},{xi:.4f},{vi:.4f}\n" for ti, xi, vi in zip(t, x, v))
        (d / "track.csv").write_text(
            f"# {name}: Doppler radar, flat fire, converted to SI by examples/warner/convert.py\n"
            f"# source: {src}\n"
            f"# x = distance [m] (100 yd steps), v = velocity [m/s], t = time of flight [s] (given to 1 ms)\n"
            f"t,x,v\n{body}")
        header, cd = read_rows(data_dir / f"{stem}_cd.csv")
        assert header == ["mach", "cd"], header
        (d / "cd_published.csv").write_text(
            f"# {name}: published drag coefficient by Mach number\n"
            f"# source: {SOURCE.format(stem=stem, kind='cd')}\nmach,cd\n"
            + "".join(f"{m:g},{c:g}\n" for m, c in cd))
        # vacuum: z(t_end) = x tan(el) - g t_end^2 / 2 = 0  ->  tan(el) = g t_end^2 / (2 x_end)
        elevation = math.degrees(math.atan(G0 * t[-1] ** 2 / (2 * x[-1])))
        (d / "round.toml").write_text(f'''# {name}, converted by examples/warner/convert.py
# source: {src}
# units: kg, m, deg, m/s
[projectile]
name = "{name}"
mass = {mass_gr * GRAIN:.6g}          # {mass_gr:g} gr
diameter = {diam_in * INCH:.6g}      # {diam_in:g} in
reference_drag = "cd_published.csv"
# the published Cd stops at Mach {cd[-1, 0]:g}; the muzzle Mach is ~{v[0] / 340.294:.2f} in ICAO air
reference_extrapolate = true

[launch]
velocity = {v[0]:.4f}      # m/s, the 0 yd velocity ({dop[0, 1]:g} ft/s)
elevation = {elevation:.4f}    # deg: back to muzzle height at {dop[-1, 0]:g} yd (flat fire; not stated)
velocity_sd = 1.0        # m/s: the 0 yd Doppler velocity is measured, not nominal

[atmosphere]
model = "icao"           # site atmosphere not stated in the report: standard sea-level day

[radar]
sigma = {{x = {SIGMA['x']}, v = {SIGMA['v']}}}   # from the rounding of the published numbers
''')
        print(f"wrote {d}: {len(t)} samples, t = 0 .. {t[-1]:.3f} s, v = {v[0]:.1f} .. {v[-1]:.1f} m/s")


if __name__ == "__main__":
    here = Path(__file__).resolve().parent
    default = here.parents[2] / "shared" / "data" / "warner"
    convert(sys.argv[1] if len(sys.argv) > 1 else default, here)
