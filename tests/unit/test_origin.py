"""The fit's origin check (issue 26): it says what it sees, a clock offset (along the flight
path) or a position offset (a radar frame not at the gun), and never fires on a correct origin,
even when the radar is noisier than its round says."""
import dataclasses

import numpy as np
import pytest

from bayesdrag.estimate.scheme1.fit import fit_scheme1
from bayesdrag.io.drag_tables import load_m101
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.synthetic import add_noise, simulate_round
from bayesdrag.track import RadarTrack

SIGMA = {"x": 1.0, "z": 1.0, "v": 0.3}
#: the clock estimate against the true offset [s]
CLOCK_ATOL = 0.01
#: the priors a correct origin keeps (the round's muzzle position, speed and elevation)
MUZZLE_PRIORS = ("X0_muzzle", "Y0_muzzle", "Z0_muzzle", "launch_speed", "elevation")


def _flat(qe=1.0, dt=0.05, noise=1.0, seed=1, mass=42.6, diameter=0.155):
    rnd = Round(Projectile("shell", mass, diameter, load_m101()), Launch(elevation_deg=qe, velocity=818.0),
                radar=Radar(dict(SIGMA)))
    tr = simulate_round(rnd, dt=dt, channels=("x", "z", "v"))
    sig = {c: s * noise for c, s in SIGMA.items()}
    return add_noise(tr, sig, np.random.default_rng(seed)), rnd


def _shift(track, **off):
    return RadarTrack(track.t, {c: track.channels[c] + off.get(c, 0.0) for c in track.names}, source="shifted")


def test_an_x_offset_on_a_flat_path_is_a_position_offset_by_the_speed():
    """A 40 mm shell loses 60 m/s in the 0.37 s a 300 m offset would take: its first sample at
    the launch speed says the frame, not the clock, is off."""
    tr, rnd = _flat(mass=0.89, diameter=0.04)
    f1 = fit_scheme1(_shift(tr, x=300.0), rnd)
    o = f1.launch_check["origin"]
    assert o["kind"] == "position" and "flying at the launch speed" in o["message"], o


def test_a_heavy_shell_on_a_flat_path_says_it_cannot_tell():
    """A 155 mm shell loses 13 m/s in 0.37 s, within the round's velocity sd: either offset fits,
    and the message says so instead of blaming the clock."""
    tr, rnd = _flat()
    f1 = fit_scheme1(_shift(tr, x=300.0), rnd)
    o = f1.launch_check["origin"]
    assert o["kind"] == "clock or position" and "too little speed" in o["message"], o


def test_a_late_clock_on_a_flat_path_is_a_clock_offset():
    """The 40 mm shell's first sample 0.2 s after launch flies 35 m/s slower than the launch:
    the clock is late, by the along-path distance over the speed."""
    tr, rnd = _flat(mass=0.89, diameter=0.04)
    late = tr.subset(tr.t >= 0.2 - 1e-9)
    f1 = fit_scheme1(RadarTrack(late.t - late.t[0], late.channels, source="late"), rnd)
    o = f1.launch_check["origin"]
    assert o["kind"] == "clock" and o["clock_offset"] == pytest.approx(0.2, abs=CLOCK_ATOL), o


@pytest.mark.parametrize("noise", [1.0, 10.0])
def test_a_correct_origin_never_fires(noise):
    """A radar 10x noisier than its round says: the fit's bound on the muzzle position is then
    too narrow, but the origin check measures the noise itself; and the launch priors stay (a
    check that is unsure keeps them: none is left out)."""
    for seed in range(3):
        tr, rnd = _flat(qe=15.0, noise=noise, seed=seed)
        f1 = fit_scheme1(tr, rnd)
        assert "origin" not in f1.launch_check, f1.launch_check
        assert set(MUZZLE_PRIORS) <= set(f1.launch_check["applied"]), f1.launch_check
        assert f1.launch_check["conflicts"] == [], f1.launch_check
