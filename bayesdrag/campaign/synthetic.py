"""Simulated campaigns (tests, benchmark, tutorial): rounds of a shell whose Cd scatters from round
to round, written as campaign, round and track files."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..drag import ReferenceTable
from ..io.campaign import write_campaign
from ..io.drag_tables import load_m101
from ..io.rounds import write_round
from ..io.tracks import write_track
from ..round import Launch, Projectile, Radar, Round
from ..synthetic import add_noise, simulate_round

__all__ = ["simulate_campaign"]


def simulate_campaign(directory, n_rounds=7, scatter=0.01, rng=None, velocities=(790.0, 840.0),
                      elevations=(12.0, 20.0), dt=0.054, sigma=None, reference=None, mass=42.6,
                      diameter=0.155, name="simulated campaign"):
    """Write a simulated campaign: rounds whose Cd is ``reference * (1 + delta_r)`` with
    ``delta_r ~ N(0, scatter^2)``, launch speed and elevation spread over the given ranges
    (so the rounds cover different Mach spans), point-mass tracks with Gaussian noise.

    Parameters
    ----------
    directory : path
        Created if needed; receives ``campaign.toml``, ``reference.csv`` and per round
        ``<name>.toml``, ``<name>.csv``.
    n_rounds : int
    scatter : float
        Round-to-round relative sd of Cd.
    rng : numpy.random.Generator
    velocities, elevations : (lo, hi)
        Launch speed [m/s] and quadrant elevation [deg] ranges (evenly spread, shuffled).
    dt : float, s
        Radar sample interval.
    sigma : dict, optional
        Noise sd per channel (default x, y, z 1 m, v 0.3 m/s).
    reference : ReferenceTable, optional
        Campaign truth (default the 155 mm M101 table shipped in the package).

    Returns
    -------
    (Path, dict)
        The campaign file and the truth: ``deltas`` (list), ``scatter``, ``reference``.
    """
    rng = np.random.default_rng() if rng is None else rng
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    ref = load_m101() if reference is None else reference
    sigma = dict(sigma or {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3})
    ref_path = d / "reference.csv"
    ref_path.write_text("# campaign truth: population Cd(M)\nmach,cd\n"
                        + "".join(f"{m:.6g},{c:.8g}\n" for m, c in zip(ref.mach, ref.cd_values)), encoding="utf-8")
    deltas = scatter * rng.standard_normal(n_rounds)
    vel = np.linspace(*velocities, n_rounds)[rng.permutation(n_rounds)]
    el = np.linspace(*elevations, n_rounds)[rng.permutation(n_rounds)]
    rows = []
    for i in range(n_rounds):
        nm = f"r{i + 1}"
        table = ReferenceTable(ref.mach, tuple(np.asarray(ref.cd_values) * (1.0 + deltas[i])), source=f"{nm} truth")
        launch = Launch(elevation_deg=float(round(el[i], 3)), velocity=float(round(vel[i], 2)), azimuth_deg=90.0)
        proj = Projectile("simulated shell", mass, diameter, reference_drag=table)
        truth_round = Round(proj, launch, radar=Radar(sigma))
        track = add_noise(simulate_round(truth_round, dt=dt), sigma, rng)
        file_round = Round(Projectile("simulated shell", mass, diameter, reference_drag=ref,
                                      reference_drag_path=str(ref_path)), launch, radar=Radar(sigma))
        write_round(d / f"{nm}.toml", file_round, comment=f"{name}: round {nm} (truth delta = {deltas[i]:+.5f})")
        write_track(d / f"{nm}.csv", track, comment=f"{name}: round {nm}, simulated point mass, noise {sigma}")
        rows.append((nm, d / f"{nm}.csv", d / f"{nm}.toml"))
    path = write_campaign(d / "campaign.toml", name, rows)
    return path, {"deltas": deltas.tolist(), "scatter": scatter, "reference": ref}
