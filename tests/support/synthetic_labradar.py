"""Synthetic LabRadar series with a known truth, flown by an integrator independent of bayesdrag's.

Each series is a folder ``SR####/`` with ``TRK/Shot#### Track.csv`` written as the device writes
them (:func:`bayesdrag.io.formats.labradar.write_labradar`: fps, the extrapolated first row) and a
round file. The flight is scipy's ``solve_ivp`` (DOP853, rtol 1e-10) of a 3-D point mass with the
truth's Cd taken from py-ballisticcalc's drag tables (an independent copy of the standard
functions) times a form factor and a slope; the round names another standard function as its
reference, so the session must find the shape's difference.

What varies (seeded): bullet (mass, diameter, speed), truth shape and round reference, shots
(8-15), charge ladders, shot-to-shot drag scatter 0-3 %, a decaying initial yaw in some series,
the device's true distance from the line of fire off the typed offset by up to 0.3 m (the typed
offset unknown in some), its position along the line of fire, lock-on at 5-8 m, reach 60-150 m,
dropouts, noise as the real tracks show it (0.1-0.2 m/s near the muzzle growing with the echo's
weakening, about 10 ** (-0.7 dSNR / 20), the echo 38 dB at 5 m and 26 dB weaker per decade of
range, lost below 3 dB; sample-to-sample correlation 0-0.6; one-sided high outliers near the end
of the track).
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
from py_ballisticcalc import drag_tables
from scipy.integrate import solve_ivp

from bayesdrag.io.formats.labradar import write_labradar

#: the echo weakens by this much per decade of range [dB] (the real tracks: 38 dB at 5 m, 7-15 dB at 60 m)
SNR_DB_PER_DECADE = 26.0
#: below this SNR the device loses the track [dB] (the real tracks' weakest samples: 7 dB)
SNR_LOCK_DB = 3.0
GRAIN = 6.479891e-5
INCH = 0.0254
RHO, C_SOUND = 1.225, 340.294     # ICAO at sea level
G = 9.80665

#: (name, mass [gr], diameter [in], muzzle speed [m/s], truth shape, round reference)
BULLETS = [("6.5 mm 140 gr", 140, 0.264, 820, "G7", "G7"), ("6.5 mm 142 gr", 142, 0.264, 760, "G8", "G7"),
           (".308 175 gr", 175, 0.308, 790, "G7", "G1"), (".308 150 gr flat base", 150, 0.308, 850, "G1", "G1"),
           (".223 55 gr", 55, 0.224, 960, "G2", "G1"), (".223 77 gr", 77, 0.224, 830, "G7", "G7"),
           ("8 mm 180 gr", 180, 0.323, 740, "G5", "G7"), (".338 250 gr", 250, 0.338, 880, "G6", "G7")]


def _table(name):
    tab = getattr(drag_tables, f"Table{name}")
    return np.array([r["Mach"] for r in tab]), np.array([r["CD"] for r in tab])


def truth_cd(shape, ff, slope, m_ref):
    """The truth Cd(M): form factor x the shape x (1 + slope (M - m_ref))."""
    m, cd = _table(shape)
    return lambda mach: ff * np.interp(mach, m, cd) * (1.0 + slope * (np.asarray(mach) - m_ref))


def _fly(v0, cd_fn, k_air, scale, yaw0, yaw_decay, t_end):
    """solve_ivp of the 3-D point mass (x downrange, y right, z up), a Cd multiplier for a decaying yaw."""
    def rhs(t, s):
        vx, vy, vz = s[3:]
        u = math.sqrt(vx * vx + vy * vy + vz * vz)
        yaw = yaw0 * math.exp(-yaw_decay * t)
        k = k_air * scale * float(cd_fn(u / C_SOUND)) * (1.0 + 15.0 * yaw * yaw) * u
        return [vx, vy, vz, -k * vx, -k * vy, -k * vz - G]

    sol = solve_ivp(rhs, (0.0, t_end), [0, 0, 0, v0, 0, 0], method="DOP853", rtol=1e-10, atol=1e-9,
                    dense_output=True)
    return sol.sol


def make_series(folder, rng, index, noise_scale=1.0, outliers=True, ar=True, noise_rng=None):
    """Write one synthetic series into ``folder``; return its truth record."""
    name, gr, d_in, v_nom, shape, ref = BULLETS[index % len(BULLETS)]
    mass, diam = gr * GRAIN, d_in * INCH
    k_air = RHO * math.pi * diam ** 2 / 4 / (2 * mass)
    n_shots = int(rng.integers(8, 16))
    ladder = rng.random() < 0.3
    v0s = (v_nom + np.linspace(-30, 30, n_shots) + rng.normal(0, 3, n_shots) if ladder
           else v_nom + rng.normal(0, rng.uniform(3, 10), n_shots))
    tau = float(rng.choice([0.0, 0.005, 0.01, 0.02, 0.03]))
    deltas = rng.normal(0, tau, n_shots) if tau else np.zeros(n_shots)
    ff = float(rng.uniform(0.85, 1.15))
    slope = float(rng.uniform(-0.1, 0.1))
    m_ref = v_nom / C_SOUND
    cd = truth_cd(shape, ff, slope, m_ref)
    yaw = rng.random() < 0.15
    typed = float(rng.uniform(0.3, 1.0))
    y_true = max(0.05, typed + rng.uniform(-0.3, 0.3))
    x_dev = 0.0
    z_dev = float(rng.uniform(-0.1, 0.05))
    offset_known = rng.random() < 0.7
    reach = float(rng.uniform(60, 150))
    rho_ar = float(rng.uniform(0.0, 0.6))
    beta, sd_near = float(os.environ.get("SYN_BETA", 0.7)), float(rng.uniform(0.08, 0.2))
    trk = Path(folder) / "TRK"
    trk.mkdir(parents=True, exist_ok=True)
    for i in range(n_shots):
        v0 = float(v0s[i])
        t_end = reach / v0 * 1.6 + 0.02
        sol = _fly(v0, cd, k_air, 1.0 + deltas[i], math.radians(rng.uniform(2, 4)) if yaw else 0.0,
                   rng.uniform(20, 60), t_end)
        t0_trig = float(rng.normal(0, 3e-4))        # the trigger a little off the muzzle exit
        lock = rng.uniform(5, 8)
        t = np.arange(0.0, t_end, 1e-3)
        s = sol(np.clip(t - t0_trig, 0, None))
        x, y, z, vx, vy, vz = s
        dx, dy, dz = x - x_dev, y - y_true, z - z_dev
        R = np.sqrt(dx * dx + dy * dy + dz * dz)
        rr = (dx * vx + dy * vy + dz * vz) / R
        rep = rr * R / np.sqrt(np.maximum(R * R - typed * typed, 1e-6))
        use = (x >= lock) & (x <= reach) & (t - t0_trig > 0)
        keep = use & (rng.random(t.size) > 0.03)            # dropouts
        t, R, rep = t[keep], R[keep], rep[keep]
        nr = noise_rng if noise_rng is not None else rng
        snr = 38.0 - SNR_DB_PER_DECADE * np.log10(R / 5.0) + nr.normal(0, 1.0, R.size)
        lock = snr >= SNR_LOCK_DB                          # the device loses a weak echo
        t, R, rep, snr = t[lock], R[lock], rep[lock], snr[lock]
        sd = sd_near * 10.0 ** (-beta * (snr - 38.0) / 20.0)
        e = np.empty(t.size)
        e[0] = nr.normal()
        for j in range(1, t.size):
            e[j] = (rho_ar * e[j - 1] + math.sqrt(1 - rho_ar ** 2) * nr.normal()) if ar else nr.normal()
        noise = sd * e
        late = np.flatnonzero(R > 0.6 * reach)
        if late.size:
            hit = late[nr.random(late.size) < 0.05]
            noise[hit] += np.abs(nr.normal(6, 2, hit.size)) * sd[hit] * outliers
        v = rep + noise_scale * noise
        dist = np.cumsum(np.r_[t[0], np.diff(t)] * v)
        write_labradar(trk / f"Shot{i + 1:04d} Track.csv", t, v, dist, snr, v0_extrapolated=v[0] + 2.0,
                       series=index + 1, shot=i + 1)
    device = ("" if not offset_known else f"device_offset = {typed:.4f}\ndevice_offset_sd = 0.3\n")
    (Path(folder) / "round.toml").write_text(
        f'[projectile]\nname = "{name}"\nmass = {mass:.8g}\ndiameter = {diam:.6g}\nreference_drag = "{ref}"\n'
        f'[launch]\nelevation = 0.0\n[atmosphere]\nmodel = "icao"\n[radar]\n{device}')
    return {"series": index, "bullet": name, "shots": n_shots, "tau": tau, "ladder": bool(ladder), "yaw": bool(yaw),
            "shape": shape, "reference": ref, "ff": ff, "slope": slope, "m_ref": m_ref, "typed": typed,
            "y_true": y_true, "z_dev": z_dev, "offset_known": bool(offset_known), "reach": reach,
            "truth": cd, "deltas": deltas.tolist()}
