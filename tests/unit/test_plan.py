"""The firing planner (``bayesdrag.planning.case``, ``bayesdrag.planning.plan``, ``bayesdrag.plan``): the
plan.json contract, the budget's arithmetic (density floor, rounds scaling, scatter), the
expected evidence against a Monte Carlo of a linear problem, the combination rule and the error
paths. The check of the prediction against fits of simulated firings is
``tests/acceptance/test_plan_mc.py``."""
from dataclasses import replace

import numpy as np
import pytest

import bayesdrag
from bayesdrag.errors import InputError
from bayesdrag.planning.case import CasePlan, expected_log_evidence, walk_evidence
from bayesdrag.planning.plan import best_combination, combine
from bayesdrag.round import Launch, Projectile, Radar, Round, Systematics

SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
#: declared systematic sds of the budget tests (the contract (docs/formats.md) units)
SYSTEMATICS = dict(mass=0.05, diameter=0.0002, density=0.003, temperature=1.0, position_scale=1e-4,
                   velocity_scale=1e-4, time_offset=0.002)
#: relative tolerance of quantities that are equal by algebra but computed by finite
#: differences and matrix inverses [-]
ALGEBRA_RTOL = 1e-3


@pytest.fixture(scope="module")
def rnd(m101):
    return Round(Projectile("155 mm", 42.6, 0.155, m101), Launch(15.0, 818.0), radar=Radar(dict(SIGMA)),
                 path="plan_test.toml")


@pytest.fixture(scope="module")
def with_sys(rnd):
    return replace(rnd, systematics=Systematics(**SYSTEMATICS))


@pytest.fixture(scope="module")
def plan_sys(with_sys):
    return bayesdrag.plan(with_sys, elevations=(15.0, 45.0), velocities=(818.0,), rounds=4, scatter=0.01)


@pytest.fixture(scope="module")
def plan_one(rnd):
    return bayesdrag.plan(rnd)


def test_plan_json_has_the_design_contract(plan_sys):
    d = plan_sys.to_dict()
    assert [(c["elevation"], c["velocity"], c["rounds"]) for c in d["cases"]] == [(15.0, 818.0, 4), (45.0, 818.0, 4)]
    for c in d["cases"]:
        lo, hi = c["mach_range"]
        assert 0.5 < lo < hi < 2.6
        assert c["cd"] and all(set(r) >= {"mach", "sd"} for r in c["cd"])
        m = np.array([r["mach"] for r in c["cd"]])
        assert np.all(np.diff(m) > 0) and lo - 1e-9 <= m[0] and m[-1] <= hi + 1e-9
        assert all(r["sd"] > 0 and np.isfinite(r["sd"]) for r in c["cd"])
        assert set(c["cd"][0]["by_source"]) == set(SYSTEMATICS)
    assert d["systematics"]["declared"] == SYSTEMATICS and d["systematics"]["undeclared"] == []
    assert d["assumed_drag"]["generic"] is False
    assert d["target"] is None and d["summary"]


def test_defaults_are_the_rounds_launch_and_one_round(plan_one):
    (c,) = plan_one.to_dict()["cases"]
    assert (c["elevation"], c["velocity"], c["rounds"], c["dt"]) == (15.0, 818.0, 1, 0.027)
    assert c["tracked"]["t_start"] == 0.0 and c["tracked"]["t_end"] == pytest.approx(c["tracked"]["t_impact"])


def test_density_floor_and_level_sources(plan_sys):
    """Cd is proportional to m / (rho d^2): density, mass and diameter shares are the level's, and the
    predicted sd never falls below the density's share, however many rounds."""
    for c in plan_sys.cases:
        assert np.all(c.sd >= c.cd * SYSTEMATICS["density"])
        assert np.all(c.sd_for(10 ** 6) >= c.cd * SYSTEMATICS["density"])
        np.testing.assert_allclose(np.abs(c.by_source["density"]), c.cd * SYSTEMATICS["density"], rtol=ALGEBRA_RTOL)
        np.testing.assert_allclose(np.abs(c.by_source["mass"]), c.cd * SYSTEMATICS["mass"] / 42.6, rtol=ALGEBRA_RTOL)
        np.testing.assert_allclose(np.abs(c.by_source["diameter"]), 2 * c.cd * SYSTEMATICS["diameter"] / 0.155,
                                   rtol=ALGEBRA_RTOL)


def test_density_floor_holds_for_a_spline_in_cd(rnd):
    """Without a table the fit's model is a spline in Cd whose penalty (on Cd's own curvature)
    changes with Cd's level; the density share must still be the whole cd * density_sd, at
    every Mach and for any number of rounds (the track cannot tell density from Cd)."""
    bare = replace(rnd, projectile=Projectile("105 mm", 15.0, 0.105), systematics=Systematics(density=0.003))
    for c in bayesdrag.plan(bare, elevations=(10.0, 45.0), velocities=(600.0,)).cases:
        assert "spline in Cd" in c.drag_model
        np.testing.assert_allclose(np.abs(c.by_source["density"]), c.cd * 0.003, rtol=1e-12)
        for n in (1, 10 ** 9):
            assert np.all(c.sd_for(n) >= c.cd * 0.003)


def test_rounds_shrink_the_statistical_part_not_the_systematic(plan_sys):
    for row in plan_sys.to_dict()["cases"][0]["cd"]:
        sys2 = sum(v ** 2 for v in row["by_source"].values())
        stat2 = row["statistical"] ** 2 + (0.01 * row["reference"]) ** 2
        assert row["sd"] == pytest.approx(np.sqrt(stat2 / 4 + sys2), rel=1e-5)
        assert row["sd_one_round"] == pytest.approx(np.sqrt(row["statistical"] ** 2 + sys2), rel=1e-5)
    c = plan_sys.cases[0]
    assert np.all(c.sd_for(100) < c.sd_for(4)) and np.all(c.sd_for(100) > c.systematic)


def test_marginalising_sources_widens_the_band(plan_one, rnd, with_sys):
    """The same case with the sources declared is never narrower. Sources exactly confounded with
    the level of Cd (mass, diameter, density) leave the data's share as it was (the data cannot
    tell them from Cd, so they spend no information on them); a source the data partly identify
    (temperature, through where the drag rises) takes some of the data's information and so raises
    the statistical share (by up to 2x at the lowest Mach of this track)."""
    base = plan_one.cases[0]
    c = bayesdrag.plan(with_sys).cases[0]
    np.testing.assert_array_equal(c.mach, base.mach)
    assert np.all(c.sd_one_round >= base.sd_one_round * (1 - ALGEBRA_RTOL))
    level = replace(rnd, systematics=Systematics(mass=0.05, diameter=0.0002, density=0.003))
    c = bayesdrag.plan(level).cases[0]
    np.testing.assert_allclose(c.statistical, base.statistical, rtol=ALGEBRA_RTOL)
    level_rel = np.hypot(np.hypot(0.05 / 42.6, 2 * 0.0002 / 0.155), 0.003)
    np.testing.assert_allclose(c.sd_one_round, np.hypot(base.statistical, level_rel * c.cd), rtol=ALGEBRA_RTOL)


def test_generic_drag_without_a_reference(rnd):
    bare = replace(rnd, projectile=Projectile("105 mm", 15.0, 0.105))
    d = bayesdrag.plan(bare, velocities=(600.0,)).to_dict()
    assert d["assumed_drag"]["generic"] is True and "M101" in d["assumed_drag"]["source"]
    assert "generic" in d["summary"]
    assert "spline in Cd" in d["cases"][0]["drag_model"]


def test_lock_on_and_loss_trim_the_track(rnd, plan_one):
    c = bayesdrag.plan(rnd, lock_on=2.0, loss=20.0).to_dict()["cases"][0]
    full = plan_one.to_dict()["cases"][0]
    assert c["tracked"]["t_start"] >= 2.0 and c["tracked"]["t_end"] <= 20.0
    assert c["mach_range"][0] > full["mach_range"][0] and c["mach_range"][1] < full["mach_range"][1]
    assert c["tracked"]["samples"] < full["tracked"]["samples"]


def test_expected_evidence_matches_monte_carlo_of_a_linear_problem():
    """E[-chi2_min / 2] of a penalised linear least-squares problem, by the formula and by 4000
    noise draws, for two penalty weights (the difference is what the evidence walk compares)."""
    rng = np.random.default_rng(5)
    M, n = 60, 6
    A = rng.standard_normal((M, n))
    theta = rng.standard_normal(n)
    D = np.diff(np.eye(n), 2, axis=0)
    out = []
    for sd in (0.3, 3.0):
        R = D / sd
        p = -(R @ theta)
        ev, _, _ = expected_log_evidence(A.T @ A, R, p, np.full(D.shape[0], sd), np.zeros(n))
        G = np.vstack([A, R])
        H = G @ np.linalg.solve(G.T @ G, G.T)
        e = rng.standard_normal((4000, M))
        r = np.hstack([e, np.tile(p, (4000, 1))])
        chi2 = np.einsum("ki,ij,kj->k", r, np.eye(M + D.shape[0]) - H, r)
        _, logdet = np.linalg.slogdet(G.T @ G)
        mc = -0.5 * (chi2.mean() - M) - 0.5 * logdet - D.shape[0] * np.log(sd)
        out.append((ev, mc, chi2.std() / np.sqrt(4000)))
    # 4 standard errors of the Monte-Carlo mean
    assert abs((out[0][0] - out[1][0]) - (out[0][1] - out[1][1])) < 4 * 0.5 * np.hypot(out[0][2], out[1][2])


def test_walk_evidence_is_the_fits_walk():
    # from the middle (index 2 of 5) uphill towards flexible; else towards stiff
    assert walk_evidence(lambda i: [0, 1, 2, 3, 4][i], 5) == 4
    assert walk_evidence(lambda i: [4, 3, 2, 1, 0][i], 5) == 0
    assert walk_evidence(lambda i: [0, 5, 2, 1, 0][i], 5) == 1
    assert walk_evidence(lambda i: [9, 0, 2, 3, 1][i], 5) == 3  # stops at the first maximum uphill


def _case(lo, hi, rel_stat, share=0.0, rounds=1):
    m = np.round(np.arange(round(lo / 0.01), round(hi / 0.01) + 1) * 0.01, 4)
    cd = np.full(m.size, 0.3)
    by = {"density": np.full(m.size, -share * 0.3)} if share else {}
    return CasePlan(15.0, 800.0, rounds, 0.0, 0.027, (0.0, 10.0), 10.0, 400, (lo, hi), m, cd,
                    np.full(m.size, rel_stat * 0.3), by, {"sd": 1.0, "edf": 3.0, "at_grid_end": None}, "spline")


def test_combination_prefers_the_widest_range_then_fewer_cases():
    a, b, c = _case(0.9, 1.5, 0.004), _case(1.4, 2.2, 0.004), _case(1.0, 1.3, 0.004)
    best = best_combination((a, b, c), 0.005)
    assert best["cases"] == [0, 1] and best["mach_range"] == [0.9, 2.2]
    # one case enough: it alone, not every case
    assert best_combination((a, _case(0.9, 1.5, 0.004)), 0.005)["cases"] == [0]


def test_pooling_divides_the_statistical_part_but_not_a_shared_source():
    a = _case(1.0, 2.0, 0.006, share=0.003)
    grid, cd, sd, sys = combine((a, a))
    np.testing.assert_allclose(sys / cd, 0.003)
    np.testing.assert_allclose(sd / cd, np.sqrt(0.006 ** 2 / 2 + 0.003 ** 2))
    # one case gives 0.67 %, both 0.52 %
    best = best_combination((a, a), 0.0055)
    assert best["mach_range"] == [1.0, 2.0] and best["cases"] == [0, 1]
    # a target below the shared floor: nothing reaches it and more rounds cannot help
    none = best_combination((a, a), 0.002)
    assert none["mach_range"] is None and none["rounds_needed"] is None
    assert none["floor"]["largest_source"] == "density"


def test_rounds_needed_when_the_statistical_part_is_too_large():
    a = _case(1.0, 2.0, 0.01)
    best = best_combination((a,), 0.005)
    assert best["mach_range"] is None and best["rounds_needed"]["per_case"] == 4


def test_recommendation_paragraph(plan_sys):
    p = bayesdrag.plan(plan_sys.round, elevations=(15.0, 45.0), target=0.005)
    d = p.to_dict()
    assert d["target"]["relative_sd"] == 0.005 and d["target"]["paragraph"] == p.paragraph
    assert p.paragraph.startswith("Target 0.5 %") and "density" in p.paragraph


@pytest.mark.parametrize("kwargs, match", [
    (dict(elevations=(95.0,)), "elevations"),
    (dict(elevations=(0.0,)), "elevations"),
    (dict(elevations=("x",)), "elevations"),
    (dict(velocities=(-5.0,)), "velocities"),
    (dict(dt=0.0), "dt"),
    (dict(rounds=0), "rounds"),
    (dict(scatter=-0.1), "scatter"),
    (dict(target=1.5), "target"),
    (dict(lock_on=5.0, loss=2.0), "loss"),
    (dict(lock_on=500.0), "lock_on .*lands"),
    (dict(dt=2.0, loss=10.0), "samples"),
    (dict(elevations=tuple(range(1, 10)), velocities=tuple(range(100, 900, 100))), "at most 64"),
])
def test_bad_options_name_what_is_wrong(rnd, kwargs, match):
    with pytest.raises(InputError, match=match):
        bayesdrag.plan(rnd, **kwargs)


def test_a_round_without_radar_sigma_or_launch_is_refused(rnd):
    with pytest.raises(InputError, match=r"\[radar\] sigma"):
        bayesdrag.plan(replace(rnd, radar=Radar()))
    with pytest.raises(InputError, match="elevations"):
        bayesdrag.plan(replace(rnd, launch=Launch(velocity=800.0)))
    with pytest.raises(InputError, match="velocities"):
        bayesdrag.plan(replace(rnd, launch=Launch(elevation_deg=20.0)))
