"""Robustness validation suite: does ``bayesdrag fit`` recover the right Cd(M) on tracks of many
shells, made by an independent simulator (py-ballisticcalc)?

The acceptance of the robustness issue, verbatim where it sets numbers: at least 24 tracks covering
every standard table py-ballisticcalc ships (G1, G2, G5, G6, G7, G8, GI, GS, RA4) and the M101
table; 2.6 g bullets to 45 kg shells and a mortar bomb; QE 1-60 deg, 300-1000 m/s; with no table,
the right table, a table of another shell, a table 10 % off; partial tracks (late lock-on, early
loss); sampling 0.01-1 s; noise 0.1-3 m; the round's launch velocity off by +-3 % and by 15 %.
Every track converges; over the Mach span each track flies less 5 % of its width at each end
(whatever the fit reports as determined) Cd is within 2 % of the truth (or within 2 % of the truth
anywhere within +-0.01 Mach, for steep slopes) or |err| <= 3 sd; there the ML 90 % band holds the
truth, to within 0.1 % of Cd, at >= 85 % of all grid points pooled; every case answers (or exits
2 with one clear line) in under 10 s. ``diagnose`` names nothing material when the table is right
or absent, blames the drag (not the weather) when the table is wrong, and finds a withheld wind.

Run: ``python tests/acceptance/run_robustness.py`` (table), ``pytest tests/acceptance/
test_robustness_suite.py`` (fast subset), ``-m slow`` (everything).

Simulator (why it is independent)
---------------------------------
``tests/support/pbc_reference.pbc_trajectory`` with ``exact_atmosphere=True, dense_table=False,
match_density=True``: py-ballisticcalc 3.1.1's own SciPy DOP853 engine and its own PCHIP of the
raw table (a different end-slope limiter, extrapolating beyond the table), flown in the air the
round states. Flat Earth, no Coriolis, no spin drift (bayesdrag's fit has no Coriolis either
when the round gives no latitude: none is written).

Why the air is the round's (decision): a track flown in other air than the round states carries
a withheld density effect, which the diagnosis is right to find. py-ballisticcalc's stock air
differs from ICAO in two ways that are modelling conventions, not shells: its sea-level density
is the CIPM-2007 real-gas 1.22552 kg/m^3 (0.043 % above ICAO's 1.225: on the long precise
tracks the track's end moves by more than 3 noise sd, which the contract (docs/formats.md) calls material, and
``diagnose`` named ``density`` 1.0004-1.0008 on 9 of 20 right/absent-table tracks), and a 30-ft
"fast path" holds the gun-level air within +-9.1 m (a 0.09 % step; flat-fire bullets fly their
whole path in it and ``diagnose`` named ``density``/``yaw_drag`` there). Both are checked where
they belong, in ``tests/test_pointmass.py``'s comparison with py-ballisticcalc. ``--stock-air``
(environment ``BAYESDRAG_SUITE_STOCK_AIR=1``) flies the tracks in py-ballisticcalc's stock air to
show these effects; the fit criteria (0.1 % of Cd tolerance) hold there too.

The truth
---------
``truth_cd(table, M)`` is py-ballisticcalc's own interpolation of the table
(``interpolation.pchip_prepare/pchip_eval``, exactly what drove the track), not bayesdrag's PCHIP
of it. The truth is always the unscaled table: "a table 10 % off" is the *round's* reference
(``scaled:1.10`` = the truth table times 1.10) while the track is flown with the truth.

The Mach span of a case is the air-relative speed of the truth trajectory at the *tracked* samples
(after lock-on, before loss) over the ICAO speed of sound (``bayesdrag.air.atmosphere``) at the
sample's height, min to max; the air speed is the ground speed when there is no wind and |dr/dt -
w| otherwise (dr/dt from a cubic spline of the simulator's 0.02 s rows). The evaluation span is
that span less ``SPAN_TRIM`` = 5 % of its width at each end.

Cases (decisions and reasons)
-----------------------------
* Projectiles: a 2.6 g, 5.7 mm bullet (a .22 LR-sized bullet: subsonic with RA4 at 330-380 m/s; a
  light varmint bullet at 900-950 m/s with G1/G7: a 1-3 s flat flight through the whole transonic
  region), 7.62 mm 9.5 g and 12.7 mm 42 g bullets, a 30 mm 0.39 kg projectile at 1000 m/s (G6), a
  40 mm 0.89 kg (G8), a 25 mm steel ball (64 g) and a 50 mm one (0.51 kg) for the sphere table GS,
  81 mm 4.2 kg mortar bombs at 250 and 320 m/s (QE 45 and 60), a 120 mm 13 kg mortar bomb at 300
  m/s (QE 50), 105 mm 15 kg shells (G7, G5), 130 mm 33.4 kg shells (G1, GI), 155 mm 42.6 kg M101
  shells and a 45 kg 155 mm shell (M101 and GI) up to QE 60.
* Every table is the truth of >= 2 cases; M101 of 7. M101 is used only where the flight stays in
  its Mach 0.5-2.6 rows (py-ballisticcalc would extrapolate its end cubic), and as another
  shell's table only where the launch Mach is within the table (bayesdrag refuses a reference
  that stops short of the launch Mach: that is a round error, not this suite's subject).
* Reference: ``none`` (the default spline from a generic start), ``right``, ``other:<table>``
  (another shell's table: a G7 boat-tail for a G1 flat base, G1 for M101, ...), ``scaled:1.10``.
* Launch velocity in the round: exact, x0.97, x1.03, x0.85 and x1.15 (the velocity_sd prior is
  left at bayesdrag's default, as a user would).
* Sampling 0.01-1 s, position noise sd 0.1-3 m, speed noise sd 0.1 of it in m/s (typical of a
  Doppler radar); the round's ``[radar] sigma`` is the true noise. At most ~2500 samples a track.
* Partial tracks: lock-on 0.5-2 s after launch, loss before impact; t stays launch-relative
  (the contract (docs/formats.md): t = 0 at launch).
* Channels: x,y,z,v (y is pure noise about 0 without wind, as a radar would give it), two
  positions-only tracks (x,y,z) and two Doppler-like x,v tracks.
* Withheld wind: three extra cases (``withheld`` set) flown in a constant wind the round does not
  state. They are for ``diagnose`` (which must name ``wind``); their fit, which is told nothing of
  the wind, is reported but is not part of the fit acceptance or the pooled coverage.
* Seeds: one ``np.random.default_rng(seed)`` per case.

Evaluation (one function for the runner and the tests)
------------------------------------------------------
``evaluate_fit``: exit code, wall time, ``ml.converged``; over the result's ``cd`` rows inside the
evaluation span: max |ml/truth - 1|, max |err|/sd, a row passes if |err| <= 2 % of truth, or
|err| <= 3 sd, or some truth value within +-0.01 Mach of the row is within 2 % of ml; coverage
|ml - truth| <= 1.645 sd + 0.001 truth. sd is ``band_sd`` when a row has it, else
``crb_sd_colored`` when the fit warns of autocorrelated residuals, else ``crb_sd``. A case passes
when it exits 0, converges, answers within ``TIME_LIMIT_S``, its Cd grid reaches over the whole
evaluation span (a fit that reports Cd over less than the flown span has not answered there) and
every row there passes. Exit 2 is a FAIL in the suite (every suite track is answerable); it is an
accepted outcome only in the issue's own failure list (``ISSUE_CASES``).

``--drag poly2-split`` (paper Eq. 18 below and above Mach 1) is judged like the spline where it can
follow the curve: where the least-squares poly2-split approximation of the truth over the
evaluation span stays within ``POLY2_FOLLOW_TOL`` = 1 % (half the accuracy tolerance). Elsewhere it
is judged on reporting its misfit: a warning about correlated residuals / model error / misfit, a
``quality`` that is not clean, or the failing rows marked ``determined: false``.

Timing: the fit is called in process (``bayesdrag.cli.main``) after one warm-up fit (numba's
compiled kernel loaded once, as a long-running service would have it); ``--subprocess`` in the
runner times the real command line instead.
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import os
import shutil
import subprocess
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

# ------------------------------------------------------------------------------------------
# named tolerances (the acceptance's numbers)
# ------------------------------------------------------------------------------------------
#: relative Cd error a grid point may have [-]
REL_TOL = 0.02
#: ... or this many sd
SD_TOL = 3.0
#: steep slopes: within REL_TOL of the truth anywhere within +-this many Mach
MACH_SLACK = 0.01
#: 90 % two-sided band: ml +- 1.645 sd
BAND_Z = 1.645
#: the two simulators' air and table interpolation differ by about 0.1 % of Cd
BAND_FLOOR = 0.001
#: pooled share of grid points whose band holds the truth
COVERAGE_MIN = 0.85
#: evaluation span = flown Mach span less this fraction of its width at each end
SPAN_TRIM = 0.05
#: every case answers (or exits 2) within this wall time [s]
TIME_LIMIT_S = 10.0
#: poly2-split "can follow the curve" when its best least-squares fit to the truth over the
#: evaluation span is within this relative error everywhere
POLY2_FOLLOW_TOL = 0.01
#: generator version: cached cases made by an older generator are remade
GENERATOR_VERSION = 3
#: how py-ballisticcalc is driven (see "Simulator" above): the round's air, py-ballisticcalc's
#: integrator and table interpolation; ``BAYESDRAG_SUITE_STOCK_AIR=1`` (runner ``--stock-air``)
#: flies py-ballisticcalc's stock air instead.
_STOCK_AIR = os.environ.get("BAYESDRAG_SUITE_STOCK_AIR", "") not in ("", "0")
PBC_OPTIONS = dict(exact_atmosphere=not _STOCK_AIR, dense_table=False, match_density=not _STOCK_AIR)

TABLES = ("G1", "G2", "G5", "G6", "G7", "G8", "GI", "GS", "RA4", "M101")
WEATHER = ("wind", "temperature")
CHANNELS = ("x", "y", "z", "v")
#: words in a fit warning that say its residuals show model error (misfit)
MISFIT_WORDS = ("autocorrelat", "misfit", "model error", "cannot follow", "does not follow", "chi2",
                "far above the noise", "lack of fit")
#: the words of the fit's origin check (a first sample away from the muzzle at t = 0)
ORIGIN_WORDS = "from the muzzle at t = 0"
#: words that say a fit noticed the time origin is not the launch
TIME_WORDS = ("time origin", "t = 0", "t=0", "clock", "time offset", "launch time", "first sample",
              "time zero")


# ------------------------------------------------------------------------------------------
# tables and the truth
# ------------------------------------------------------------------------------------------
_TABLE_CACHE = {}


def table(name):
    """(mach, cd) arrays of a py-ballisticcalc standard table or the M101 table."""
    if name not in _TABLE_CACHE:
        if name == "M101":
            from bayesdrag.io.drag_tables import load_m101

            m = load_m101()
            _TABLE_CACHE[name] = (np.asarray(m.mach, float), np.asarray(m.cd_values, float))
        else:
            import py_ballisticcalc.drag_tables as dt

            rows = getattr(dt, f"Table{name}")
            _TABLE_CACHE[name] = (np.array([float(r["Mach"]) for r in rows]),
                                  np.array([float(r["CD"]) for r in rows]))
    return _TABLE_CACHE[name]


_PCHIP_CACHE = {}


def truth_cd(name, mach):
    """Cd the simulator used at Mach ``mach``: py-ballisticcalc's PCHIP of the raw table."""
    from py_ballisticcalc.interpolation import pchip_eval, pchip_prepare

    if name not in _PCHIP_CACHE:
        m, c = table(name)
        _PCHIP_CACHE[name] = pchip_prepare([float(v) for v in m], [float(v) for v in c])
    prep = _PCHIP_CACHE[name]
    mach = np.asarray(mach, float)
    return np.vectorize(lambda v: float(pchip_eval(prep, float(v))))(mach) if mach.ndim else \
        float(pchip_eval(prep, float(mach)))


# ------------------------------------------------------------------------------------------
# cases
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Case:
    """One track: a shell of ``mass`` [kg] and ``diameter`` [m] with drag ``table`` fired at ``v0``
    [m/s] and ``qe`` [deg], sampled every ``dt`` [s] from ``lock_on`` to ``loss`` [s after launch]
    with Gaussian noise ``pos_sd`` [m] on x, y, z and ``v_sd`` [m/s] on v, handed to bayesdrag with
    the round's reference ``ref`` ("none" | "right" | "other:<table>" | "scaled:<factor>") and
    launch velocity ``v0 * vel_factor``."""

    name: str
    table: str
    mass: float
    diameter: float
    v0: float
    qe: float
    dt: float
    pos_sd: float
    v_sd: float
    lock_on: float | None = None
    loss: float | None = None
    channels: tuple = CHANNELS
    ref: str = "right"
    vel_factor: float = 1.0
    seed: int = 0
    wind: tuple | None = None           # withheld constant wind (wx, wy) [m/s]
    transform: str | None = None        # issue cases: "yards", "feet", "t0_first_sample"
    expect: str = "answer"              # "answer" | "answer_or_exit2" | "exit2_units" | "time_conflict"
    drag: str | None = None             # None = fit's default; "poly2-split"
    note: str = ""
    samples: int | None = None          # short tracks: keep only the first this many samples
    range_step: float | None = None     # ... taken every this many m downrange (a Doppler report)

    @property
    def withheld(self):
        return self.wind is not None

    @property
    def ref_label(self):
        return self.ref if self.ref in ("none", "right") else self.ref.replace("other:", "oth:").replace(
            "scaled:", "x")


def _c(name, table_, mass, diam, v0, qe, dt, pos_sd, seed, **kw):
    kw.setdefault("v_sd", round(0.1 * pos_sd, 4))
    return Case(name, table_, mass, diam, v0, qe, dt, pos_sd, seed=seed, **kw)


XZ = ("x", "y", "z")   # positions only
XV = ("x", "v")        # Doppler-like: range and speed

CASES = [
    # 2.6 g, 5.7 mm bullets: 1-3 s flat flights (RA4: .22 LR-like, subsonic)
    _c("b26-g7-flat", "G7", 0.0026, 0.0057, 950.0, 1.0, 0.01, 0.1, 1),
    _c("b26-ra4-none", "RA4", 0.0026, 0.0057, 330.0, 1.0, 0.01, 0.1, 2, ref="none"),
    _c("b26-ra4-x110", "RA4", 0.0026, 0.0057, 380.0, 8.0, 0.02, 0.2, 3, ref="scaled:1.10"),
    _c("b26-g1-other", "G1", 0.0026, 0.0057, 900.0, 2.0, 0.02, 0.2, 4, ref="other:G7"),
    # rifle and machine-gun bullets
    _c("b95-g7-x110", "G7", 0.0095, 0.00782, 830.0, 3.0, 0.02, 0.3, 5, ref="scaled:1.10"),
    _c("b42-g2-v103", "G2", 0.042, 0.0127, 880.0, 5.0, 0.05, 0.5, 6, vel_factor=1.03),
    _c("b42-g8-xv", "G8", 0.042, 0.0127, 880.0, 4.0, 0.02, 0.3, 7, channels=XV),
    # steel spheres (GS)
    _c("s25-gs-loss", "GS", 0.064, 0.025, 500.0, 3.0, 0.02, 0.2, 8, loss=2.0),
    _c("s50-gs-other", "GS", 0.51, 0.050, 600.0, 20.0, 0.05, 0.5, 9, ref="other:G1"),
    # 30 mm and 40 mm
    _c("p30-g6-none", "G6", 0.39, 0.030, 1000.0, 5.0, 0.02, 0.5, 10, ref="none"),
    _c("p30-g6-late", "G6", 0.39, 0.030, 1000.0, 2.0, 0.05, 1.0, 11, lock_on=0.5, loss=6.0, vel_factor=0.97),
    _c("p40-g8-right", "G8", 0.89, 0.040, 880.0, 10.0, 0.05, 1.0, 12),
    _c("p40-g8-pos", "G8", 0.89, 0.040, 880.0, 15.0, 0.1, 2.0, 13, channels=XZ, ref="none"),
    # mortar bombs
    _c("m81-g5-x110", "G5", 4.2, 0.081, 250.0, 45.0, 0.1, 2.0, 14, ref="scaled:1.10"),
    _c("m81-g2-pos60", "G2", 4.2, 0.081, 320.0, 60.0, 0.2, 3.0, 15, channels=XZ),
    _c("m120-g1-late", "G1", 13.0, 0.120, 300.0, 50.0, 0.1, 1.5, 16, ref="none", lock_on=2.0),
    # 105 mm
    _c("s105-g7-right", "G7", 15.0, 0.105, 600.0, 20.0, 0.05, 1.0, 17),
    _c("s105-g7-v115", "G7", 15.0, 0.105, 600.0, 20.0, 0.1, 1.0, 18, ref="none", vel_factor=1.15),
    _c("s105-g5-other", "G5", 15.0, 0.105, 480.0, 35.0, 0.1, 1.5, 19, ref="other:G7"),
    # 130 mm
    _c("s130-g1-none", "G1", 33.4, 0.130, 810.0, 8.0, 0.05, 1.0, 20, ref="none"),
    _c("s130-g1-part", "G1", 33.4, 0.130, 810.0, 8.0, 0.05, 1.0, 21, lock_on=1.0, loss=12.0),
    _c("s130-gi-x110", "GI", 33.4, 0.130, 700.0, 25.0, 0.1, 2.0, 22, ref="scaled:1.10"),
    # 155 mm (M101 42.6 kg; a 45 kg shell)
    _c("s155-m101", "M101", 42.6, 0.155, 818.0, 15.0, 0.05, 1.0, 23),
    _c("s155-m101-v85", "M101", 42.6, 0.155, 818.0, 15.0, 0.05, 1.0, 24, vel_factor=0.85),
    _c("s155-m101-v97", "M101", 42.6, 0.155, 818.0, 30.0, 0.1, 2.0, 25, ref="none", vel_factor=0.97),
    _c("s155-m101-dt1", "M101", 45.0, 0.155, 818.0, 45.0, 1.0, 3.0, 26, vel_factor=1.03),
    _c("s155-m101-xv", "M101", 42.6, 0.155, 818.0, 10.0, 0.02, 0.5, 27, channels=XV),
    _c("s155-m101-oth", "M101", 42.6, 0.155, 818.0, 20.0, 0.05, 1.0, 28, ref="other:G1", lock_on=1.5),
    _c("s155-gi-qe60", "GI", 45.0, 0.155, 684.0, 60.0, 0.5, 3.0, 29, ref="other:M101"),
]

#: withheld constant wind (for diagnose: it must find ``wind``)
WIND_CASES = [
    _c("w130-g1-wind", "G1", 33.4, 0.130, 810.0, 8.0, 0.05, 1.0, 41, wind=(-6.0, 4.0)),
    _c("w155-m101-wind", "M101", 42.6, 0.155, 818.0, 15.0, 0.05, 1.0, 42, wind=(0.0, 8.0)),
    _c("w105-g7-wind", "G7", 15.0, 0.105, 600.0, 20.0, 0.05, 1.0, 43, ref="none", wind=(5.0, -5.0)),
]

#: short tracks (8-24 samples): a Doppler report every 100 yd, a chronograph radar's handful of
#: points, a sparse tracking radar sampling a shell every 1-2 s; speed only (``t, v``) and
#: ``x, z, v``. Judged like the rest of the suite.
VO = ("v",)             # Doppler speed only
XZV = ("x", "z", "v")
YD100 = 91.44           # 100 yd [m]
SHORT_CASES = [
    _c("sb65-g7-16xv", "G7", 0.00797, 0.0067, 950.0, 1.2, 0.01, 0.3, 201, v_sd=0.05, channels=XV,
       range_step=YD100, samples=16, note="a 6.5 mm bullet's Doppler report every 100 yd (Warner-like)"),
    _c("sb65-g7-8v", "G7", 0.00797, 0.0067, 950.0, 1.2, 0.01, 0.3, 202, v_sd=0.05, channels=VO, ref="none",
       range_step=2 * YD100, samples=8, note="speed every 200 yd, no table"),
    _c("sb95-g1-12v", "G1", 0.0095, 0.00782, 830.0, 2.0, 0.1, 0.3, 203, v_sd=0.1, channels=VO, samples=12,
       note="a chronograph radar: 12 speeds 0.1 s apart"),
    _c("sb42-g7-24xzv", "G7", 0.042, 0.0127, 880.0, 3.0, 0.1, 0.3, 204, channels=XZV, ref="scaled:1.10",
       samples=24),
    _c("sm81-g2-12xzv", "G2", 4.2, 0.081, 250.0, 45.0, 1.0, 2.0, 205, channels=XZV, ref="none", samples=12),
    _c("sm120-g1-8v", "G1", 13.0, 0.120, 300.0, 50.0, 2.0, 2.0, 206, channels=VO, samples=8),
    _c("ss155-m101-24xzv", "M101", 42.6, 0.155, 818.0, 30.0, 2.0, 2.0, 207, channels=XZV, samples=24),
    _c("ss105-g7-16v", "G7", 15.0, 0.105, 600.0, 20.0, 1.0, 1.0, 208, channels=VO, ref="none", samples=16),
    _c("ss130-g1-12xzv", "G1", 33.4, 0.130, 810.0, 8.0, 1.5, 1.0, 209, channels=XZV, ref="other:G7",
       samples=12),
]

ALL_CASES = CASES + WIND_CASES + SHORT_CASES

#: projectile classes for random cases: (label, mass [kg], diameter [m], v0 range [m/s], QE range
#: [deg], tables that suit the shape, dt choices [s], noise choices [m])
_CLASSES = (
    ("bullet", (0.0026, 0.012), (0.0057, 0.0085), (700.0, 1000.0), (0.5, 5.0), ("G1", "G7", "G2", "G5"),
     (0.005, 0.01, 0.02), (0.05, 0.1, 0.2)),
    ("subsonic", (0.0026, 0.02), (0.0057, 0.0115), (280.0, 330.0), (1.0, 10.0), ("RA4", "G1"),
     (0.01, 0.02), (0.05, 0.1)),
    ("sphere", (0.06, 0.6), (0.025, 0.05), (400.0, 650.0), (2.0, 25.0), ("GS",), (0.02, 0.05), (0.2, 0.5)),
    ("cannon", (0.3, 1.0), (0.025, 0.040), (800.0, 1050.0), (2.0, 15.0), ("G6", "G8", "G1"),
     (0.02, 0.05, 0.1), (0.5, 1.0, 2.0)),
    ("mortar", (3.0, 14.0), (0.060, 0.120), (200.0, 330.0), (40.0, 65.0), ("G2", "G5", "G1"),
     (0.1, 0.2, 0.5), (1.0, 2.0, 3.0)),
    ("shell", (12.0, 46.0), (0.100, 0.155), (450.0, 900.0), (5.0, 50.0), ("M101", "G7", "G1", "GI", "G5"),
     (0.05, 0.1, 0.5, 1.0), (0.5, 1.0, 2.0, 3.0)),
)


def random_cases(n, seed=0):
    """``n`` random cases (a check on shells, tables and conditions nobody chose), reproducible
    from ``seed``: a projectile class, its mass, diameter, speed and elevation drawn uniformly in
    the class's range, a table that suits its shape, the sampling and noise, the channels
    (mostly x, y, z, v; sometimes positions only or x and v), the round's reference (none, right,
    another shell's, 10 % off) and launch velocity (right, +-3 %, -15 %), sometimes a late lock-on
    or an early loss. M101 is drawn only where the launch Mach stays inside its table."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        label, (m0, m1), (d0, d1), (v0a, v0b), (q0, q1), tabs, dts, noises = _CLASSES[rng.integers(len(_CLASSES))]
        u = rng.uniform()
        mass, diam = m0 + u * (m1 - m0), d0 + u * (d1 - d0)  # heavier with larger calibre
        v0 = float(rng.uniform(v0a, v0b))
        qe = float(rng.uniform(q0, q1))
        tab = str(rng.choice(tabs))
        if tab == "M101" and not (340.0 * 0.6 < v0 < 340.0 * 2.5):
            tab = "G7"
        pos = float(rng.choice(noises))
        dt = float(rng.choice(dts))
        ch_draw = rng.uniform()
        channels = CHANNELS if ch_draw < 0.8 else (XZ if ch_draw < 0.9 else XV)
        ref_draw = rng.uniform()
        if ref_draw < 0.35:
            ref = "none"
        elif ref_draw < 0.7:
            ref = "right"
        elif ref_draw < 0.85:
            other = [t for t in ("G1", "G7", "G2", "G5", "G6", "G8") if t != tab]
            ref = "other:" + str(rng.choice(other))
        else:
            ref = "scaled:1.10"
        vel_factor = float(rng.choice([1.0, 1.0, 1.0, 0.97, 1.03, 0.85]))
        part = rng.uniform()
        lock = float(rng.uniform(0.3, 1.5)) if part < 0.15 and label not in ("bullet", "subsonic") else None
        out.append(_c(f"r{seed}-{i:02d}-{label}-{tab.lower()}", tab, round(mass, 5), round(diam, 5), round(v0, 1),
                      round(qe, 2), dt, pos, 1000 * seed + i, channels=channels, ref=ref,
                      vel_factor=vel_factor, lock_on=lock,
                      note=f"random case {i} of seed {seed} ({label})"))
    return out

def random_short_cases(n, seed=0):
    """``n`` random short tracks (8, 12, 16 or 24 samples), reproducible from ``seed``: the
    classes of :func:`random_cases`; speed only (``t, v``) or ``x, z, v``; bullets reported every
    50-200 m downrange or every 0.05-0.2 s, the others sampled every 0.5-2 s; the reference and
    the launch velocity drawn as there."""
    rng = np.random.default_rng(10_000 + seed)
    out = []
    for i in range(n):
        label, (m0, m1), (d0, d1), (v0a, v0b), (q0, q1), tabs, dts, noises = _CLASSES[rng.integers(len(_CLASSES))]
        u = rng.uniform()
        mass, diam = m0 + u * (m1 - m0), d0 + u * (d1 - d0)
        v0 = float(rng.uniform(v0a, v0b))
        qe = float(rng.uniform(q0, q1))
        tab = str(rng.choice(tabs))
        if tab == "M101" and not (340.0 * 0.6 < v0 < 340.0 * 2.5):
            tab = "G7"
        pos = float(rng.choice(noises))
        n_s = int(rng.choice([8, 12, 16, 24]))
        channels = VO if rng.uniform() < 0.5 else XZV
        small = label in ("bullet", "subsonic")
        step = float(rng.choice([50.0, 100.0, 200.0])) if small and rng.uniform() < 0.5 else None
        dt = float(rng.choice([0.05, 0.1, 0.2])) if small else float(rng.choice([0.5, 1.0, 1.5, 2.0]))
        ref_draw = rng.uniform()
        ref = ("none" if ref_draw < 0.35 else "right" if ref_draw < 0.7 else
               "other:" + str(rng.choice([t for t in ("G1", "G7", "G2", "G5", "G6", "G8") if t != tab]))
               if ref_draw < 0.85 else "scaled:1.10")
        vel_factor = float(rng.choice([1.0, 1.0, 1.0, 0.97, 1.03]))
        out.append(_c(f"q{seed}-{i:02d}-{label}-{tab.lower()}-{n_s}{''.join(channels)}", tab, round(mass, 5),
                      round(diam, 5), round(v0, 1), round(qe, 2), dt, pos, 2000 * seed + 500 + i,
                      channels=channels, ref=ref, vel_factor=vel_factor, samples=n_s, range_step=step,
                      note=f"random short case {i} of seed {seed} ({label})"))
    return out


#: fast subset for the default test run: a flat bullet, a positions-only mortar at QE 60, a
#: partial 130 mm track, the 155 mm shell with the round's velocity 15 % low, a 30 mm late lock-on
FAST = ("b26-g7-flat", "m81-g2-pos60", "s130-g1-part", "s155-m101-v85", "p30-g6-late")

#: the issue's own failure list (each: a right answer or exit 2 with one stderr line, < 10 s)
ISSUE_CASES = [
    _c("i1-130-g1-none", "G1", 33.4, 0.130, 810.0, 8.0, 0.05, 1.0, 101, ref="none", expect="answer_or_exit2",
       note="130 mm G1-like, 810 m/s, QE 8, no firing table"),
    _c("i1-130-g1-none-p2s", "G1", 33.4, 0.130, 810.0, 8.0, 0.05, 1.0, 101, ref="none",
       expect="answer_or_exit2", drag="poly2-split", note="case 1 with --drag poly2-split"),
    _c("i2-130-g1-part", "G1", 33.4, 0.130, 810.0, 8.0, 0.05, 1.0, 102, ref="none", lock_on=1.0, loss=12.0,
       expect="answer_or_exit2", note="case 1, lock-on 1 s, loss 12 s"),
    _c("i2-130-g1-part-p2s", "G1", 33.4, 0.130, 810.0, 8.0, 0.05, 1.0, 102, ref="none", lock_on=1.0,
       loss=12.0, expect="answer_or_exit2", drag="poly2-split", note="case 2 with --drag poly2-split"),
    _c("i3-30-g6", "G6", 0.39, 0.030, 1000.0, 5.0, 0.02, 0.5, 103, ref="none", expect="answer_or_exit2",
       note="30 mm 0.39 kg, G6, 1000 m/s"),
    _c("i4-105-g7-right", "G7", 15.0, 0.105, 600.0, 20.0, 0.05, 1.0, 104, expect="answer_or_exit2",
       note="105 mm with the correct G7 table"),
    _c("i5-155-v700", "M101", 42.6, 0.155, 818.0, 15.0, 0.05, 1.0, 105, vel_factor=700.0 / 818.0,
       expect="answer_or_exit2", note="M101 818 m/s, round says 700 m/s"),
    _c("i5-155-v795", "M101", 42.6, 0.155, 818.0, 15.0, 0.05, 1.0, 105, vel_factor=795.0 / 818.0,
       expect="answer_or_exit2", note="round says 795 m/s"),
    _c("i5-155-v805", "M101", 42.6, 0.155, 818.0, 15.0, 0.05, 1.0, 105, vel_factor=805.0 / 818.0,
       expect="answer_or_exit2", note="round says 805 m/s"),
    _c("i6-yards", "M101", 42.6, 0.155, 818.0, 15.0, 0.05, 1.0, 106, transform="yards", expect="exit2_units",
       note="positions in yards, speed in m/s"),
    _c("i7-dt1", "M101", 42.6, 0.155, 818.0, 15.0, 1.0, 1.0, 107, expect="answer_or_exit2",
       note="sampled every 1 s"),
    _c("i8-t0-first", "M101", 42.6, 0.155, 818.0, 15.0, 0.05, 1.0, 108, lock_on=0.5,
       transform="t0_first_sample", expect="time_conflict",
       note="t = 0 at the first radar sample (0.5 s after launch)"),
    _c("i9-feet", "M101", 42.6, 0.155, 818.0, 15.0, 0.05, 1.0, 109, transform="feet", expect="exit2_units",
       note="whole track in feet (positions and speed)"),
]
#: issue case 10: diagnose on case 1 must name nothing material
ISSUE_DIAGNOSE = "i1-130-g1-none"


def case_by_name(name):
    for c in ALL_CASES + ISSUE_CASES:
        if c.name == name:
            return c
    if name[:1] in ("r", "q") and name.count("-") >= 2:  # a random case: r<seed>-<i>-... (q: short)
        try:
            seed, i = int(name[1:].split("-")[0]), int(name.split("-")[1])
            c = (random_cases if name[0] == "r" else random_short_cases)(i + 1, seed)[i]
            if c.name == name:
                return c
        except (ValueError, IndexError):
            pass
    raise KeyError(f"no case {name!r}")


# ------------------------------------------------------------------------------------------
# generation
# ------------------------------------------------------------------------------------------
def _pbc():
    here = str(Path(__file__).resolve().parents[1])
    if here not in sys.path:
        sys.path.insert(0, here)
    from support import pbc_reference

    return pbc_reference


def _case_key(case):
    d = asdict(case)
    d["generator"] = GENERATOR_VERSION
    d["pbc_options"] = dict(PBC_OPTIONS)
    return json.loads(json.dumps(d))


def _fit_quadratics(m, c, split=1.0):
    """Max relative error of the least-squares poly2-split approximation of c(m)."""
    worst = 0.0
    for sel in (m < split, m >= split):
        if sel.sum() == 0:
            continue
        mm, cc = m[sel], c[sel]
        A = np.stack([np.ones_like(mm), mm, mm * mm], axis=1)
        coef, *_ = np.linalg.lstsq(A / cc[:, None], np.ones_like(cc), rcond=None)  # relative LSQ
        worst = max(worst, float(np.max(np.abs(A @ coef / cc - 1.0))))
    return worst


def generate(case, folder):
    """Make (or reuse) the case's track CSV, round TOML, reference CSV and truth JSON under
    ``folder/<name>/``. Returns the truth dict (with the file paths)."""
    import tomli_w
    from scipy.interpolate import CubicSpline

    from bayesdrag.air.atmosphere import standard_atmosphere

    d = Path(folder) / case.name
    tj = d / "truth.json"
    key = _case_key(case)
    if tj.exists():
        try:
            old = json.loads(tj.read_text())
            if old.get("case") == key and (d / "track.csv").exists():
                return old
        except (ValueError, OSError):
            pass
    if d.exists():
        shutil.rmtree(d)
    d.mkdir(parents=True)
    pbc = _pbc()
    M, C = table(case.table)
    wind = case.wind or (0.0, 0.0)
    o = pbc.pbc_trajectory(M, C, case.mass, case.diameter, case.v0, case.qe, wind=wind, t_out=None,
                           **PBC_OPTIONS)
    t_end = float(o["t"][-1])
    P = np.column_stack([o["x"], o["y"], o["z"], o["v"]])
    spl = CubicSpline(o["t"], P, axis=0)
    t = np.arange(0.0, t_end, case.dt)
    t = t[t <= t_end - 1e-9]
    if case.lock_on is not None:
        t = t[t >= case.lock_on - 1e-9]
    if case.loss is not None:
        t = t[t <= case.loss + 1e-9]
    if case.range_step is not None:  # a Doppler report: the times at which x passes each step
        marks = np.arange(0.0, float(o["x"][-1]), case.range_step)
        t = np.interp(marks, o["x"], o["t"])
    if case.samples is not None:
        t = t[:case.samples]
    S = spl(t)
    if case.wind is None:
        air = S[:, 3]
    else:
        vel = spl(t, 1)[:, :3]
        air = np.linalg.norm(vel - np.array([wind[0], wind[1], 0.0]), axis=1)
    a = standard_atmosphere(np.maximum(S[:, 2], 0.0)).speed_of_sound
    mach = air / a
    lo, hi = float(mach.min()), float(mach.max())
    w = hi - lo
    ev = (lo + SPAN_TRIM * w, hi - SPAN_TRIM * w)
    # noise
    rng = np.random.default_rng(case.seed)
    clean = {"x": S[:, 0], "y": S[:, 1], "z": S[:, 2], "v": S[:, 3]}
    noisy = {}
    for ch in CHANNELS:  # draw for all four so a channel subset does not change the others' noise
        sd = case.v_sd if ch == "v" else case.pos_sd
        noisy[ch] = clean[ch] + rng.normal(0.0, sd, size=t.size)
    tt = t.copy()
    cols = {c: noisy[c] for c in case.channels}
    if case.transform == "yards":
        cols = {c: (v / 0.9144 if c != "v" else v) for c, v in cols.items()}
    elif case.transform == "feet":
        cols = {c: v / 0.3048 for c, v in cols.items()}
    elif case.transform == "t0_first_sample":
        tt = tt - tt[0]
    names = ["t", *case.channels]
    lines = ["# robustness suite (tests/acceptance/pbc_suite.py): py-ballisticcalc 3.x truth",
             f"# case {case.name}: table {case.table}, {case.mass} kg, {case.diameter} m, {case.v0} m/s, "
             f"QE {case.qe} deg, dt {case.dt} s, noise {case.pos_sd} m / {case.v_sd} m/s, seed {case.seed}",
             ",".join(names)]
    arr = np.column_stack([tt] + [cols[c] for c in case.channels])
    for row in arr:
        lines.append(",".join([f"{row[0]:.6f}"] + [f"{v:.4f}" for v in row[1:]]))
    (d / "track.csv").write_text("\n".join(lines) + "\n")
    # round
    proj = {"name": f"{case.name} ({case.diameter * 1000:g} mm, {case.table} drag)", "mass": case.mass,
            "diameter": case.diameter}
    if case.ref != "none":
        if case.ref == "right":
            rm, rc = table(case.table)
        elif case.ref.startswith("other:"):
            rm, rc = table(case.ref.split(":", 1)[1])
        elif case.ref.startswith("scaled:"):
            rm, rc = table(case.table)
            rc = rc * float(case.ref.split(":", 1)[1])
        else:
            raise ValueError(f"case {case.name}: bad ref {case.ref!r}")
        (d / "ref.csv").write_text("mach,cd\n" + "\n".join(f"{a:.4f},{b:.6f}" for a, b in zip(rm, rc)) + "\n")
        proj["reference_drag"] = "ref.csv"
    sig = {c: (case.v_sd if c == "v" else case.pos_sd) for c in case.channels}
    if case.transform == "feet":
        sig = {c: s / 0.3048 for c, s in sig.items()}
    elif case.transform == "yards":
        sig = {c: (s / 0.9144 if c != "v" else s) for c, s in sig.items()}
    doc = {"projectile": proj,
           "launch": {"elevation": float(case.qe), "velocity": round(case.v0 * case.vel_factor, 4)},
           "atmosphere": {"model": "icao"},
           "radar": {"sigma": sig}}
    (d / "round.toml").write_text(f"# robustness case {case.name}\n" + tomli_w.dumps(doc))
    # truth: the curve on a fine grid, poly2-split followability, the interpolation difference
    mg = np.linspace(ev[0], ev[1], 401)
    cg = truth_cd(case.table, mg)
    from scipy.interpolate import PchipInterpolator

    bd = PchipInterpolator(M, C, extrapolate=False)(np.clip(mg, M[0], M[-1]))
    truth = {"case": key, "table": case.table, "n_samples": int(t.size),
             "t_range": [float(t[0]), float(t[-1])], "t_impact": t_end,
             "mach_span": [lo, hi], "eval_span": [float(ev[0]), float(ev[1])],
             "cd_truth_range": [float(cg.min()), float(cg.max())],
             "poly2_split_error": _fit_quadratics(mg, cg),
             "interp_diff_max": float(np.max(np.abs(bd / cg - 1.0))),
             "track": str(d / "track.csv"), "round": str(d / "round.toml")}
    truth["poly2_followable"] = truth["poly2_split_error"] <= POLY2_FOLLOW_TOL
    tj.write_text(json.dumps(truth, indent=1))
    return truth


# ------------------------------------------------------------------------------------------
# running the command line
# ------------------------------------------------------------------------------------------
def run_cli(argv, subprocess_mode=False):
    """Run ``bayesdrag ARGV``; returns (exit code, stdout, stderr, wall seconds)."""
    t0 = time.perf_counter()
    if subprocess_mode:
        p = subprocess.run([sys.executable, "-m", "bayesdrag.cli", *argv], capture_output=True, text=True)
        return p.returncode, p.stdout, p.stderr, time.perf_counter() - t0
    from bayesdrag.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(list(argv))
        except SystemExit as exc:  # --help/--version style exits
            rc = exc.code if isinstance(exc.code, int) else 1
    return rc, out.getvalue(), err.getvalue(), time.perf_counter() - t0


def _fresh(path):
    p = Path(path)
    if p.exists():
        shutil.rmtree(p)
    return p


def error_lines(stderr):
    """The command's error lines (``bayesdrag: error: ...``)."""
    return [ln for ln in stderr.splitlines() if ln.startswith("bayesdrag: error")]


def clear_exit2(rc, stderr):
    """Exit 2 with one clear line on stderr (the contract (docs/formats.md)): exactly one error line, no traceback."""
    return rc == 2 and len(error_lines(stderr)) == 1 and "Traceback" not in stderr


def fit_warnings(result, stderr):
    w = []
    if result:
        w += list((result.get("ml") or {}).get("warnings") or [])
        w += list(result.get("warnings") or [])
    for ln in stderr.splitlines():
        if "warning:" in ln:
            w.append(ln.split("warning:", 1)[1].strip())
    seen, out = set(), []
    for x in w:
        if x not in seen:
            seen.add(x)
            out.append(x)
    return out


def row_sd(row, autocorrelated):
    if row.get("band_sd") is not None:
        return float(row["band_sd"])
    if autocorrelated and row.get("crb_sd_colored") is not None:
        return float(row["crb_sd_colored"])
    return float(row["crb_sd"])


def _quality_flags_misfit(q):
    """Does ``ml.quality`` say the fit is not a clean answer? (tolerant of its final layout:
    ``ok: false``, listed ``problems``, or a channel's chi2 per sample above 2)"""
    if not isinstance(q, dict):
        return False
    if q.get("ok") is False or q.get("clean") is False:
        return True
    if q.get("problems"):
        return True
    chans = q.get("channels")
    vals = []
    if isinstance(chans, dict):
        vals = [c.get("chi2_per_sample") for c in chans.values() if isinstance(c, dict)]
    elif isinstance(q.get("chi2_per_sample"), dict):
        vals = list(q["chi2_per_sample"].values())
    vals = [v for v in vals if isinstance(v, (int, float))]
    return bool(vals) and max(vals) > 2.0


def quality_notes(q):
    """Text of what ``ml.quality`` lists as problems and launch conflicts (searched like warnings)."""
    if not isinstance(q, dict):
        return []
    out = [json.dumps(p) if not isinstance(p, str) else p for p in q.get("problems") or []]
    launch = q.get("launch") if isinstance(q.get("launch"), dict) else {}
    out += [json.dumps(p) if not isinstance(p, str) else p for p in launch.get("conflicts") or []]
    return out


def evaluate_rows(truth, result, warnings):
    """Per-row accuracy and coverage over the evaluation span. Returns a dict."""
    tab = truth["table"]
    lo, hi = truth["eval_span"]
    rows = [r for r in (result.get("cd") or []) if lo <= r["mach"] <= hi]
    autoc = any("autocorrelat" in w.lower() for w in warnings)
    grid = [r["mach"] for r in (result.get("cd") or [])]
    step = (max(grid) - min(grid)) / max(len(grid) - 1, 1) if grid else 0.0
    covers = bool(grid) and min(grid) <= lo + step and max(grid) >= hi - step
    out = {"n_rows": len(rows), "covers_span": covers,
           "grid_span": [min(grid), max(grid)] if grid else None, "autocorrelated": autoc}
    if not rows:
        out.update(max_err_pct=None, max_z=None, covered=0, coverage=None, rows_ok=False, bad_rows=[])
        return out
    errs, zs, cov, bad = [], [], 0, []
    for r in rows:
        m, ml = float(r["mach"]), float(r["ml"])
        tr = float(truth_cd(tab, m))
        sd = row_sd(r, autoc)
        err = ml - tr
        rel = abs(err) / tr
        z = abs(err) / sd if sd > 0 else math.inf
        near = truth_cd(tab, np.linspace(m - MACH_SLACK, m + MACH_SLACK, 21))
        slope_ok = bool(np.any(np.abs(ml / near - 1.0) <= REL_TOL))
        ok = rel <= REL_TOL or z <= SD_TOL or slope_ok
        inband = abs(err) <= BAND_Z * sd + BAND_FLOOR * tr
        cov += inband
        errs.append(rel)
        zs.append(z)
        if not ok:
            bad.append({"mach": m, "ml": ml, "truth": tr, "sd": sd, "determined": r.get("determined")})
    out.update(max_err_pct=100.0 * max(errs), max_z=max(zs), covered=cov, coverage=cov / len(rows),
               rows_ok=not bad, bad_rows=bad)
    return out


def run_fit_case(case, truth, outdir, drag=None, subprocess_mode=False):
    """Fit one generated case with ``bayesdrag fit --no-mcmc`` and evaluate it. Returns a row dict."""
    drag = drag or case.drag
    out = _fresh(outdir)
    argv = ["fit", truth["track"], truth["round"], "-o", str(out), "--no-mcmc"]
    if drag:
        argv += ["--drag", drag]
    rc, so, se, secs = run_cli(argv, subprocess_mode)
    result = None
    if rc == 0 and (out / "result.json").exists():
        result = json.loads((out / "result.json").read_text())
    ml = (result or {}).get("ml") or {}
    warns = fit_warnings(result, se) + quality_notes(ml.get("quality"))
    errs = error_lines(se)
    row = {"case": case.name, "drag": drag or "default", "exit": rc, "time_s": round(secs, 2),
           "stderr_tail": errs[-1] if errs else (se.strip().splitlines()[-1] if se.strip() else ""),
           "clear_exit2": clear_exit2(rc, se),
           "converged": ml.get("converged"), "det_range": ml.get("mach_range_determined"),
           "quality": ml.get("quality"), "n_warnings": len(warns), "warnings": warns,
           "eval_span": truth["eval_span"], "mach_span": truth["mach_span"], "n_samples": truth["n_samples"]}
    if result is not None:
        row.update(evaluate_rows(truth, result, warns))
    else:
        row.update(n_rows=0, covers_span=False, max_err_pct=None, max_z=None, covered=0, coverage=None,
                   rows_ok=False, bad_rows=[])
    # judgement
    reasons = []
    if rc != 0:
        reasons.append(f"exit {rc}")
    else:
        if not row["converged"]:
            reasons.append("not converged")
        if not row["covers_span"]:
            reasons.append(f"Cd grid {row.get('grid_span')} misses the span")
        if not row["rows_ok"]:
            reasons.append(f"{len(row['bad_rows'])} rows off")
    if secs > TIME_LIMIT_S:
        reasons.append(f"{secs:.1f} s > {TIME_LIMIT_S:g} s")
    # issue 26: the origin check never fires on a track whose t = 0 is the launch at the muzzle
    row["origin_alarm"] = any(ORIGIN_WORDS in w for w in warns)
    if row["origin_alarm"] and case.transform != "t0_first_sample":
        reasons.append("false origin alarm")
    followable = truth["poly2_followable"]
    row["poly2_followable"] = followable if drag == "poly2-split" else None
    row["poly2_split_error"] = truth["poly2_split_error"]
    if drag == "poly2-split" and not followable and rc == 0:
        misfit = (any(any(k in w.lower() for k in MISFIT_WORDS) for w in warns)
                  or _quality_flags_misfit(row["quality"])
                  or (row["bad_rows"] and all(b.get("determined") is False for b in row["bad_rows"])))
        row["reports_misfit"] = bool(misfit)
        # judged on reporting its misfit, not on following a curve it cannot
        reasons = [r for r in reasons if not r.endswith("rows off") and "misses the span" not in r]
        if not misfit and not row["rows_ok"]:
            reasons.append("misfit not reported")
    row["fit_pass"] = not reasons
    row["fit_reasons"] = reasons
    return row


def diagnose_expectation(case):
    if case.wind is not None:
        return "wind"
    if case.ref in ("none", "right"):
        return "nothing"
    return "drag"


def judge_verdict(expect, diag):
    """Does the diagnosis verdict satisfy the acceptance rule? (see module docstring)"""
    verdict = list(diag.get("verdict") or [])
    if expect == "wind":
        return "wind" in verdict
    if expect == "nothing":
        return verdict == []
    effects = {e.get("name"): e for e in diag.get("effects") or []}

    def is_drag(n):
        if n == "drag_scale" or n.startswith("drag"):
            return True
        return n == "density" and "drag_scale" in (effects.get(n, {}).get("confounded_with") or [])

    return any(is_drag(n) for n in verdict) and not any(n in WEATHER for n in verdict)


def run_diagnose_case(case, truth, outdir, subprocess_mode=False):
    out = _fresh(outdir)
    rc, so, se, secs = run_cli(["diagnose", truth["track"], truth["round"], "-o", str(out)], subprocess_mode)
    diag = None
    if rc == 0 and (out / "diagnosis.json").exists():
        diag = json.loads((out / "diagnosis.json").read_text())
    expect = diagnose_expectation(case)
    ok = diag is not None and judge_verdict(expect, diag)
    if case.samples is not None and diag is None:
        # a short track below the diagnosis' minimum: one clear line naming it is the answer
        ok = clear_exit2(rc, se) and "too few for a diagnosis" in se
    return {"diag_exit": rc, "diag_time_s": round(secs, 2), "diag_expect": expect,
            "diag_verdict": None if diag is None else diag.get("verdict"), "diag_pass": ok,
            "diag_stderr_tail": se.strip().splitlines()[-1] if (rc != 0 and se.strip()) else ""}


def run_case(case, folder, drag=None, diagnose=True, subprocess_mode=False):
    """Generate, fit (and diagnose) one case; returns its row."""
    t0 = time.perf_counter()
    truth = generate(case, folder)
    gen = time.perf_counter() - t0
    d = Path(folder) / case.name
    tag = "fit" if not (drag or case.drag) else f"fit-{drag or case.drag}"
    row = run_fit_case(case, truth, d / tag, drag=drag, subprocess_mode=subprocess_mode)
    row.update(table=case.table, ref=case.ref, ref_label=case.ref_label, mass=case.mass, v0=case.v0,
               qe=case.qe, dt=case.dt, pos_sd=case.pos_sd, channels="".join(case.channels),
               vel_factor=case.vel_factor, withheld=case.withheld, gen_s=round(gen, 2))
    if diagnose:
        row.update(run_diagnose_case(case, truth, d / "diag", subprocess_mode))
    else:
        row.update(diag_exit=None, diag_verdict=None, diag_pass=None)
    # a withheld-wind case is judged on its diagnosis only
    if case.withheld:
        row["pass"] = bool(row["diag_pass"]) if diagnose else None
    else:
        row["pass"] = row["fit_pass"] and (row["diag_pass"] is not False)
    return row


def run_issue_case(case, folder, subprocess_mode=False):
    """One case of the issue's failure list, judged by its ``expect``."""
    truth = generate(case, folder)
    d = Path(folder) / case.name
    row = run_fit_case(case, truth, d / "fit", subprocess_mode=subprocess_mode)
    row.update(table=case.table, ref=case.ref, ref_label=case.ref_label, mass=case.mass, v0=case.v0,
               qe=case.qe, dt=case.dt, pos_sd=case.pos_sd, channels="".join(case.channels),
               vel_factor=case.vel_factor, withheld=False, note=case.note, expect=case.expect)
    exit2 = row["clear_exit2"] and row["time_s"] <= TIME_LIMIT_S
    if case.expect == "exit2_units":
        tail = row["stderr_tail"].lower()
        ok = exit2 and ("unit" in tail or "feet" in tail or " ft" in tail or "yard" in tail)
    elif case.expect == "time_conflict":
        conflict = any(any(k in w.lower() for k in TIME_WORDS) for w in row["warnings"])
        row["time_conflict_reported"] = conflict
        ok = exit2 or (row["fit_pass"] and conflict)
    else:  # answer_or_exit2
        ok = exit2 or row["fit_pass"]
    row["pass"] = bool(ok)
    return row


# ------------------------------------------------------------------------------------------
# summaries and printing
# ------------------------------------------------------------------------------------------
def pooled_coverage(rows):
    """Pooled band coverage over the fit-acceptance rows (withheld-effect cases excluded)."""
    n = sum(r.get("n_rows") or 0 for r in rows if not r.get("withheld") and r.get("coverage") is not None)
    k = sum(r.get("covered") or 0 for r in rows if not r.get("withheld") and r.get("coverage") is not None)
    return (k / n if n else None), k, n


def _f(v, fmt, width):
    if v is None:
        return "-".rjust(width)
    return format(v, fmt).rjust(width)


def format_table(rows, title="robustness suite"):
    head = (f"{'case':<17} {'table/ref':<13} {'m kg':>7} {'v0':>5} {'QE':>4} {'dt':>5} {'noise':>5} "
            f"{'ch':<4} {'exit':>4} {'conv':>4} {'maxerr%':>8} {'max|e|/sd':>9} {'cover%':>6} "
            f"{'det. range':<11} {'time s':>6} {'diag verdict':<22} result")
    lines = [title, head, "-" * len(head)]
    for r in rows:
        det = r.get("det_range")
        det_s = f"{det[0]:.2f}-{det[1]:.2f}" if det else "-"
        verdict = r.get("diag_verdict")
        vs = "-" if r.get("diag_exit") is None else (
            f"exit {r['diag_exit']}" if r.get("diag_exit") != 0 else ("[]" if not verdict else ",".join(verdict)))
        if r.get("diag_pass") is not None:
            vs += " ok" if r["diag_pass"] else " BAD"
        res = "PASS" if r.get("pass") else ("FAIL" if r.get("pass") is not None else "-")
        if r.get("withheld"):
            res += " (wind)"
        conv = {True: "yes", False: "no", None: "-"}[r.get("converged")]
        lines.append(
            f"{r['case']:<17} {r['table'] + '/' + r.get('ref_label', r.get('ref', '')):<13} "
            f"{r['mass']:>7.4g} {r['v0']:>5.0f} {r['qe']:>4.0f} {r['dt']:>5.2g} {r['pos_sd']:>5.2g} "
            f"{r.get('channels', ''):<4} {r['exit']:>4} {conv:>4} {_f(r.get('max_err_pct'), '.2f', 8)} "
            f"{_f(r.get('max_z'), '.1f', 9)} "
            f"{_f(None if r.get('coverage') is None else 100 * r['coverage'], '.0f', 6)} {det_s:<11} "
            f"{r['time_s']:>6.1f} {vs[:22]:<22} {res}")
    return "\n".join(lines)


def failure_notes(rows):
    out = []
    for r in rows:
        why = list(r.get("fit_reasons") or [])
        if r.get("diag_pass") is False:
            why.append(f"diagnose expected {r.get('diag_expect')}, got {r.get('diag_verdict')}"
                       + (f" (exit {r['diag_exit']}: {r.get('diag_stderr_tail', '')})" if r.get("diag_exit") else ""))
        if r.get("exit") not in (0, None) and r.get("stderr_tail"):
            why.append(f"stderr: {r['stderr_tail'][:160]}")
        if not r.get("pass") and why:
            out.append(f"  {r['case']}: " + "; ".join(why))
    return out


def warm_up(folder):
    """One untimed fit so that the timed ones do not pay the imports and numba's cache load."""
    c = case_by_name("b26-ra4-none")
    truth = generate(c, folder)
    out = _fresh(Path(folder) / f"_warmup-{os.getpid()}")  # one per worker process
    run_cli(["fit", truth["track"], truth["round"], "-o", str(out), "--no-mcmc"])
    shutil.rmtree(out, ignore_errors=True)


def summarise(rows, poly2_rows=(), issue_rows=()):
    """The acceptance in numbers (shared by the runner and the slow tests)."""
    fit_rows = [r for r in rows if not r.get("withheld")]
    cov, k, n = pooled_coverage(fit_rows)
    diag = [r for r in rows if r.get("diag_pass") is not None]
    s = {"n_cases": len(fit_rows), "n_withheld": len(rows) - len(fit_rows),
         "tables": sorted({r["table"] for r in fit_rows}),
         "missing_tables": sorted(set(TABLES) - {r["table"] for r in fit_rows}),
         "fit_pass": sum(bool(r.get("fit_pass")) for r in fit_rows),
         "converged": sum(bool(r.get("converged")) for r in fit_rows),
         "within_time": sum((r.get("time_s") or 0) <= TIME_LIMIT_S for r in fit_rows),
         "pooled_coverage": cov, "covered_points": k, "grid_points": n,
         "diag_run": len(diag), "diag_pass": sum(bool(r["diag_pass"]) for r in diag),
         "pass": sum(bool(r.get("pass")) for r in rows)}
    if poly2_rows:
        fol = [r for r in poly2_rows if r.get("poly2_followable")]
        pc, pk, pn = pooled_coverage(fol)
        s.update(poly2_cases=len(poly2_rows), poly2_followable=len(fol),
                 poly2_pass=sum(bool(r.get("fit_pass")) for r in poly2_rows),
                 poly2_pooled_coverage_followable=pc, poly2_covered_points=pk, poly2_grid_points=pn)
    if issue_rows:
        s.update(issue_cases=len(issue_rows), issue_pass=sum(bool(r.get("pass")) for r in issue_rows))
    s["accepted"] = (s["n_cases"] >= 24 and not s["missing_tables"] and s["fit_pass"] == s["n_cases"]
                     and cov is not None and cov >= COVERAGE_MIN and s["diag_pass"] == s["diag_run"]
                     and (not poly2_rows or s["poly2_pass"] == s["poly2_cases"])
                     and (not issue_rows or s["issue_pass"] == s["issue_cases"]))
    return s
