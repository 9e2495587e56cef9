"""Export of a fitted Cd(M) as a py-ballisticcalc custom drag table: py-ballisticcalc flying the
exported table reproduces the radar track within its noise.

py-ballisticcalc is driven as in ``tests/support/pbc_reference.py`` (SciPy DOP853 engine, exact g, no
spin drift, bayesdrag's atmosphere through its ``Atmo`` subclass), but with *our exported*
``bc`` and table loaded from the file, so the test checks the export, not the oracle.
"""
import json
import math

import numpy as np
import pytest

pbc = pytest.importorskip("py_ballisticcalc")

from bayesdrag.estimate.scheme1.fit import fit_scheme1  # noqa: E402
from bayesdrag.io.export import PBC_STANDARD_DENSITY, density_match, drag_table, export_fit, export_result, load_pbc_drag_model, pbc_ballistic_coefficient
from bayesdrag.synthetic import add_noise, simulate_round  # noqa: E402
from bayesdrag.round import Launch, Projectile, Radar, Round  # noqa: E402

#: noise of the synthetic radar [m], [m/s]
SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
#: residual rms of py-ballisticcalc against the track, in units of the noise sd (1 = pure noise)
RMS_OVER_SIGMA_MAX = 1.3
#: a table of the *reference* Cd off by 1 % must be visibly worse (the test can fail)
WRONG_SCALE = 1.01
#: PCHIP through result.json's <= 0.01-Mach rows vs the exact spline (worst at the drag-rise knee)
ROW_INTERP_REL_TOL = 0.006


def _pbc_track(doc_path, v0, el_deg, t_out, rnd):
    from support.pbc_reference import FT, G0, _make_exact_atmo_class
    from py_ballisticcalc import Ammo, Shot, Weapon
    from py_ballisticcalc.engines import SciPyIntegrationEngine
    from py_ballisticcalc.unit import Angular, Distance, Pressure, Temperature, Velocity

    rho, a = rnd.atmosphere.density_and_sound_speed(0.0)
    T = float(a) ** 2 / (1.4 * 287.05287)
    p = float(rho) * 287.05287 * T
    atmo = _make_exact_atmo_class()(altitude=Distance.Meter(0.0), pressure=Pressure.hPa(p / 100),
                                    temperature=Temperature.Kelvin(T), humidity=0.0).configure(0.0, 0.0)
    dm = load_pbc_drag_model(doc_path)
    dm.BC *= density_match(atmo, rnd.atmosphere)  # same air density at the gun in both codes
    shot = Shot(ammo=Ammo(dm, mv=Velocity.MPS(v0), use_powder_sensitivity=False), atmo=atmo,
                weapon=Weapon(sight_height=Distance.Meter(0.0), twist=Distance.Inch(0.0)),
                look_angle=Angular.Degree(0.0), relative_angle=Angular.Degree(el_deg), cant_angle=Angular.Degree(0.0))
    eng = SciPyIntegrationEngine(dict(cMinimumVelocity=0.0, cMinimumAltitude=-1e7, cGravityConstant=-G0 / FT,
                                      integration_method="DOP853", relative_tolerance=1e-10,
                                      absolute_tolerance=1e-8, max_time=400.0, cMaximumDrop=-1e7))
    limit = Distance.Meter(1e6)
    hit = eng.integrate(shot, limit, limit, time_step=0.02, stop_at_zero=True)
    rows = sorted(hit.records, key=lambda r: r.time)
    t = np.array([r.time for r in rows])
    P = np.array([[r.distance >> Distance.Meter, r.windage >> Distance.Meter, r.height >> Distance.Meter,
                   r.velocity >> Velocity.MPS] for r in rows])
    keep = np.concatenate([[True], np.diff(t) > 1e-9])
    from scipy.interpolate import CubicSpline

    out = CubicSpline(t[keep], P[keep], axis=0)(np.clip(t_out, 0, t[keep][-1]))
    return dict(zip("xyzv", out.T))


@pytest.fixture(scope="module")
def fitted(m101, tmp_path_factory):
    d = tmp_path_factory.mktemp("export")
    launch = Launch(elevation_deg=15.0, velocity=818.0)
    truth = Round(Projectile("155", 42.6, 0.155, reference_drag=m101), launch, radar=Radar(SIGMA))
    track = add_noise(simulate_round(truth, dt=0.1), SIGMA, np.random.default_rng(2))
    f1 = fit_scheme1(track, truth)
    res, prob = f1.ml, f1.problem
    return d, track, truth, res, prob


def test_bc_is_the_sectional_density_for_form_factor_one():
    sd = (42.6 / 0.45359237) / (0.155 / 0.0254) ** 2  # lb/in^2
    assert pbc_ballistic_coefficient(42.6, 0.155) == pytest.approx(sd, rel=2e-6)
    with pytest.raises(ValueError, match="mass and diameter must be positive"):
        pbc_ballistic_coefficient(0.0, 0.155)


def test_table_is_dense_and_flat_outside_the_fitted_range(m101):
    m, c = drag_table(m101.value, (0.9, 2.4))
    assert m[0] == 0.0 and m[-1] == 10.0 and np.all(np.diff(m) > 0)
    inside = (m >= 0.9) & (m <= 2.4)
    assert np.max(np.diff(m[inside])) <= 0.005 + 1e-12
    assert np.all(c[m < 0.9] == c[inside][0]) and np.all(c[m > 2.4] == c[inside][-1])
    with pytest.raises(ValueError, match="mach_range"):
        drag_table(m101.value, (2.4, 0.9))


def test_pbc_with_the_exported_table_reproduces_the_track_within_noise(fitted):
    d, track, rnd, res, prob = fitted
    path = d / "cd_pbc.json"
    lo, hi = float(np.min(res.mach)), float(np.max(res.mach))
    doc = export_fit(path, prob.model.drag, res.drag_params, (lo, hi), 42.6, 0.155)
    assert doc["bc"] == pytest.approx(pbc_ballistic_coefficient(42.6, 0.155))
    s0 = res.state0
    v0 = float(np.linalg.norm(s0[3:]))
    el = math.degrees(math.atan2(s0[5], math.hypot(s0[3], s0[4])))
    y = _pbc_track(path, v0, el, track.t, rnd)
    ratios = {c: float(np.sqrt(np.mean((track.channels[c] - (y[c] + (s0[i] if i < 3 else 0.0))) ** 2)) / SIGMA[c])
              for i, c in enumerate("xyzv") if c != "y"}
    assert max(ratios.values()) < RMS_OVER_SIGMA_MAX, ratios
    # the same check can fail: a table 1 % off misses the track by many sd in x
    wrong = json.loads(path.read_text())
    for row in wrong["drag_table"]:
        row["CD"] *= WRONG_SCALE
    (d / "wrong.json").write_text(json.dumps(wrong))
    yw = _pbc_track(d / "wrong.json", v0, el, track.t, rnd)
    assert float(np.sqrt(np.mean((track.channels["x"] - yw["x"] - s0[0]) ** 2))) > 5 * SIGMA["x"]


def test_export_from_a_result_folder_and_csv(fitted, tmp_path):
    d, track, rnd, res, prob = fitted
    from bayesdrag.estimate.cd.table import cd_grid, cd_table, determined_range

    grid = cd_grid(np.min(res.mach), np.max(res.mach))  # the grid result.json carries
    rows = cd_table(res, prob.model.drag, grid, rnd.reference_drag)
    (tmp_path / "result.json").write_text(json.dumps({"drag_model": "spline", "cd": rows,
                                                       "ml": {"mach_range_determined": list(determined_range(rows))}}))
    doc = export_result(tmp_path / "t.json", tmp_path, 42.6, 0.155)
    m = np.array([r["Mach"] for r in doc["drag_table"]])
    c = np.array([r["CD"] for r in doc["drag_table"]])
    lo, hi = doc["mach_fitted"]
    sel = (m >= lo) & (m <= hi)
    exact = prob.model.drag.cd(res.drag_params, m[sel])
    assert np.max(np.abs(c[sel] / exact - 1)) < ROW_INTERP_REL_TOL
    export_result(tmp_path / "t.csv", tmp_path, 42.6, 0.155)
    text = (tmp_path / "t.csv").read_text()
    assert "Mach,CD" in text and f"bc = {doc['bc']:.8g}" in text
    with pytest.raises(Exception, match="no result.json or campaign.json"):
        export_result(tmp_path / "x.json", tmp_path / "nothing", 42.6, 0.155)
    assert PBC_STANDARD_DENSITY == pytest.approx(0.076474 * 16.0185, rel=1e-5)
