"""Fitting what users bring: the data-driven start, the knots, the table-times-correction model,
the physics unit check, the launch-prior check and the quality gate.

Tracks are simulated with bayesdrag's point-mass model from py-ballisticcalc's standard tables
(G1, G7, ...) and the M101 table; the independent-simulator suite is
``tests/acceptance/test_robustness_suite.py``.
"""
import dataclasses

import numpy as np
import pytest

from bayesdrag.drag import ReferenceTable, Spline, TableSpline
from bayesdrag.io.drag_tables import load_m101
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.errors import InputError
from bayesdrag.estimate.build.basis import adaptive_knots, rise_regions
from bayesdrag.estimate.cd.quality import CHI2_LIMIT
from bayesdrag.estimate.cd.table import cd_grid, cd_table
from bayesdrag.estimate.scheme1.fit import fit_scheme1
from bayesdrag.estimate.build.start import check_gravity_units, data_start, smooth_kinematics
from bayesdrag.synthetic import add_noise, simulate_round
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.track import RadarTrack

pbc_tables = pytest.importorskip("py_ballisticcalc.drag_tables")

SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
#: the start curve away from steep slopes (|d ln Cd/dM| < 1) [relative] (measured 0.8-2.0 %)
START_FLAT_RTOL = 0.03
#: ... and in a steep drag rise, where the smoothing window smears it (measured up to 5 %)
START_STEEP_RTOL = 0.08
#: Mach span read off the track against the simulated one
SPAN_ATOL = 0.01
#: a cubic spline on the adaptive knots follows a table to this (issue: a G7 or G1 rise to 0.3 %)
KNOT_FOLLOW_RTOL = 0.003
#: fitted Cd against the truth over the flown span less 5 % at each end [relative]
CD_RTOL = 0.005
#: ... or within this many band sd
CD_Z = 3.0
#: ... or, on a steep slope, within CD_STEEP_RTOL of the truth somewhere within this Mach
MACH_SLACK = 0.01
CD_STEEP_RTOL = 0.02


def _table(name):
    if name == "M101":
        return load_m101()
    t = getattr(pbc_tables, "Table" + name)
    return ReferenceTable(tuple(p["Mach"] for p in t), tuple(p["CD"] for p in t), source=name)


def _round(ref, mass, diameter, v0, qe, sigma=SIGMA):
    return Round(Projectile("test", mass, diameter, ref), Launch(elevation_deg=qe, velocity=v0),
                 radar=Radar(dict(sigma)))


def _track(ref, mass, diameter, v0, qe, dt=0.05, seed=1, sigma=SIGMA, wind=(0.0, 0.0, 0.0)):
    rnd = _round(ref, mass, diameter, v0, qe, sigma)
    tr = simulate_round(rnd, dt=dt, wind=wind)
    return add_noise(tr, sigma, np.random.default_rng(seed)), rnd


def _without_table(rnd, **launch):
    p = dataclasses.replace(rnd.projectile, reference_drag=None, reference_drag_path=None)
    return dataclasses.replace(rnd, projectile=p, launch=dataclasses.replace(rnd.launch, **launch))


CASES = [("G1", 33.4, 0.13, 810.0, 8.0), ("G7", 15.0, 0.105, 700.0, 20.0),
         ("M101", 42.6, 0.155, 818.0, 15.0), ("G6", 0.39, 0.03, 1000.0, 5.0)]


@pytest.mark.parametrize("name, mass, diameter, v0, qe", CASES)
def test_start_curve_reads_cd_and_span_off_the_track(name, mass, diameter, v0, qe):
    ref = _table(name)
    track, rnd = _track(ref, mass, diameter, v0, qe, dt=0.02 if mass < 1 else 0.05)
    ds = data_start(track, _without_table(rnd))
    tru = PointMassModel(mass, diameter, ref).mach_of(
        np.column_stack([track.x, track.y, track.z, *_velocity(track, ref, mass, diameter, v0, qe)]))
    assert ds.mach_span[0] == pytest.approx(tru.min(), abs=SPAN_ATOL)
    assert ds.mach_span[1] == pytest.approx(tru.max(), abs=SPAN_ATOL)
    lo, hi = ds.mach_span
    m = ds.mach[(ds.mach > lo + 0.05 * (hi - lo)) & (ds.mach < hi - 0.05 * (hi - lo))]
    err = np.abs(ds.curve(m) / ref.value(m) - 1.0)
    steep = np.abs(np.gradient(np.log(ref.value(m)), m)) >= 1.0
    assert np.max(err[~steep]) < START_FLAT_RTOL
    if steep.any():
        assert np.max(err[steep]) < START_STEEP_RTOL
    assert np.linalg.norm(ds.state0[3:]) == pytest.approx(v0, rel=0.01)


def _velocity(track, ref, mass, diameter, v0, qe):
    """Noise-free velocity components at the track's times (for the true Mach)."""
    tr = PointMassModel(mass, diameter, ref).simulate((), initial_state(v0, qe), track.t, backend="scipy")
    return tr.state[:, 3], tr.state[:, 4], tr.state[:, 5]


@pytest.mark.parametrize("name", ["G1", "G2", "G5", "G6", "G7", "G8", "GI", "GS", "RA4", "M101"])
def test_adaptive_knots_follow_every_standard_table(name):
    ref = _table(name)
    knots = adaptive_knots(0.5, 2.5, [ref.value], regions=[(a, b, 0.01) for a, b in rise_regions(0.5, 2.5, ref.value)])
    m = np.linspace(0.5, 2.5, 2001)
    _, err = Spline(tuple(knots)).fit_curve(m, ref.value(m), minimax=False)
    assert err < KNOT_FOLLOW_RTOL
    assert np.all(np.diff(knots) >= 0.01 - 1e-9)
    assert len(knots) < 0.5 * (2.5 - 0.5) / 0.01  # fine only where the table bends: < half of 0.01 everywhere


def test_table_spline_with_unit_correction_is_the_table(m101):
    knots = adaptive_knots(0.8, 2.5, [lambda m: np.ones_like(m)])
    dm = TableSpline(m101, tuple(knots))
    c = np.ones(dm.n_params)
    m = np.linspace(0.8, 2.5, 500)
    assert np.max(np.abs(dm.cd(c, m) / m101.value(m) - 1)) < 1e-12
    # and through the kernel: the same trajectory as the table itself
    t = np.arange(0.0, 30.0, 0.05)
    a = PointMassModel(42.6, 0.155, m101).simulate((), initial_state(818.0, 15.0), t)
    b = PointMassModel(42.6, 0.155, dm).simulate(c, initial_state(818.0, 15.0), t)
    assert np.max(np.abs(a.state[:, :3] - b.state[:, :3])) < 1e-3  # m over 30 s


def test_track_in_feet_is_refused_by_the_physics(m101):
    track, rnd = _track(m101, 42.6, 0.155, 818.0, 15.0)
    feet = RadarTrack(track.t, {c: v / 0.3048 for c, v in track.channels.items()})
    kin = smooth_kinematics(feet)
    with pytest.raises(InputError, match=r"gravity were 32\.\d.*look like feet and ft/s"):
        check_gravity_units(kin, "feet.csv")
    check_gravity_units(smooth_kinematics(track))  # metres: silent


@pytest.mark.parametrize("name, mass, diameter, v0, qe", CASES[:2])
def test_no_table_fit_recovers_cd(name, mass, diameter, v0, qe):
    ref = _table(name)
    track, rnd = _track(ref, mass, diameter, v0, qe)
    f1 = fit_scheme1(track, _without_table(rnd))
    res, prob = f1.ml, f1.problem
    assert res.converged, res.message
    _assert_recovers(f1, ref, track, rnd)


def _assert_recovers(f1, ref, track, rnd):
    from bayesdrag.estimate.cd.quality import assess

    res, prob = f1.ml, f1.problem
    lo, hi = float(res.mach.min()), float(res.mach.max())
    rows = cd_table(res, prob.model.drag, cd_grid(lo, hi))
    assess(f1, rows, track, rnd.radar.sigma)
    w = hi - lo
    for r in rows:
        if lo + 0.05 * w <= r["mach"] <= hi - 0.05 * w:
            tru = float(ref.value(r["mach"]))
            err = abs(r["ml"] - tru)
            near = ref.value(np.linspace(r["mach"] - MACH_SLACK, r["mach"] + MACH_SLACK, 21))
            steep_ok = np.any(np.abs(r["ml"] / near - 1.0) < CD_STEEP_RTOL)
            assert err < CD_RTOL * tru or err < CD_Z * r["band_sd"] or steep_ok, (r["mach"], r["ml"], tru, r["band_sd"])


@pytest.mark.parametrize("velocity", [700.0, 795.0])
def test_a_wrong_launch_velocity_is_reported_not_obeyed(m101, velocity):
    track, rnd = _track(m101, 42.6, 0.155, 818.0, 15.0)
    wrong = dataclasses.replace(rnd, launch=dataclasses.replace(rnd.launch, velocity=velocity))
    f1 = fit_scheme1(track, wrong)
    res, prob = f1.ml, f1.problem
    assert res.converged, res.message
    conflicts = {c["prior"]: c for c in f1.launch_check["conflicts"]}
    assert "launch_speed" in conflicts
    assert conflicts["launch_speed"]["track"] == pytest.approx(818.0, abs=1.0)
    assert "launch_speed" not in f1.launch_check["applied"]
    _assert_recovers(f1, m101, track, rnd)


def test_an_ordinary_lot_difference_is_a_prior(m101):
    track, rnd = _track(m101, 42.6, 0.155, 818.0, 15.0)
    near = dataclasses.replace(rnd, launch=dataclasses.replace(rnd.launch, velocity=810.0))
    f1 = fit_scheme1(track, near)
    res, prob = f1.ml, f1.problem
    assert res.converged
    assert f1.launch_check["conflicts"] == []
    assert "launch_speed" in f1.launch_check["applied"]


def test_time_origin_at_the_first_radar_sample_is_reported(m101):
    track, rnd = _track(m101, 42.6, 0.155, 818.0, 15.0)
    late = track.subset(track.t >= 0.5)
    shifted = RadarTrack(late.t - late.t[0], late.channels)
    f1 = fit_scheme1(shifted, rnd)
    res, prob = f1.ml, f1.problem
    assert res.converged
    first = f1.launch_check["conflicts"][0]
    assert "clock looks" in first["message"] and "a clock offset, not a position offset" in first["message"]
    assert f1.launch_check["origin"]["kind"] == "clock"
    assert f1.launch_check["time_origin_offset"] == pytest.approx(0.5, abs=0.05)
    assert f1.launch_check["applied"] == []


def test_quality_gate_flags_a_withheld_cross_wind(m101):
    from bayesdrag.estimate.cd.quality import assess

    track, rnd = _track(m101, 42.6, 0.155, 818.0, 15.0, wind=(0.0, 6.0, 0.0))
    f1 = fit_scheme1(track, rnd)
    res, prob = f1.ml, f1.problem
    rows = cd_table(res, prob.model.drag, cd_grid(float(res.mach.min()), float(res.mach.max())))
    q = assess(f1, rows, track, rnd.radar.sigma)
    assert not q["ok"]
    assert q["channels"]["y"]["chi2_per_sample"] > CHI2_LIMIT
    assert any(p.kind == "misfit" and str(p).startswith("channel y") for p in q["problems"])
    assert q["band"] == "colored"
    assert all(r["band_sd"] >= r["crb_sd"] for r in rows)


def test_white_noise_fit_is_clean_and_keeps_the_cramer_rao_band(m101):
    from bayesdrag.estimate.cd.quality import assess

    track, rnd = _track(m101, 42.6, 0.155, 818.0, 15.0)
    f1 = fit_scheme1(track, rnd)
    res, prob = f1.ml, f1.problem
    rows = cd_table(res, prob.model.drag, cd_grid(float(res.mach.min()), float(res.mach.max())))
    q = assess(f1, rows, track, rnd.radar.sigma)
    assert q["ok"], q["problems"]
    assert q["band"] == "cramer-rao"
    assert all(r["band_sd"] == r["crb_sd"] for r in rows)
    assert sum(r["determined"] for r in rows) > 0.9 * len(rows)


def test_rigid_model_is_checked_against_the_flexible_fit(tmp_path):
    """poly2-split cannot follow a G7 rise; its band does not know that: the result says so."""
    import json

    from bayesdrag.cli import main
    from bayesdrag.io.rounds import write_round
    from bayesdrag.io.tracks import write_track

    ref = _table("G7")
    track, rnd = _track(ref, 15.0, 0.105, 700.0, 20.0)
    (tmp_path / "g7.csv").write_text("mach,cd\n" + "".join(f"{a},{b}\n" for a, b in zip(ref.mach, ref.cd_values)))
    write_track(tmp_path / "t.csv", track)
    write_round(tmp_path / "r.toml", _without_table(rnd))
    assert main(["fit", str(tmp_path / "t.csv"), str(tmp_path / "r.toml"), "-o", str(tmp_path / "o"),
                 "--no-mcmc", "--drag", "poly2-split", "--quiet"]) == 0
    q = json.loads((tmp_path / "o" / "result.json").read_text())["ml"]["quality"]
    assert q["rigid_check"]["misses"]
    assert any("misses the flexible fit" in p for p in q["problems"])
    assert not q["ok"]


def test_scheme2_windows_carry_quality(m101):
    from bayesdrag.estimate.scheme2 import fit_scheme2, windows_table

    track, rnd = _track(m101, 42.6, 0.155, 818.0, 15.0)
    rows = windows_table(fit_scheme2(track, rnd))
    for w in rows:
        assert {"band_sd", "determined", "quality"} <= set(w)
        assert set(w["quality"]["channels"]) == set(track.names)
    assert sum(w["determined"] for w in rows) >= len(rows) // 2
