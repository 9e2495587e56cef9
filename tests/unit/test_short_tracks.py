"""Short tracks (issue 26): the drag model's size follows the data, the count of what a track
can determine, the knots of a short track and the band of what its samples cannot resolve.

Tracks are simulated with bayesdrag's point-mass model from py-ballisticcalc's standard tables and
the M101 table; the independent-simulator cases are ``SHORT_CASES`` of
``tests/acceptance/pbc_suite.py``.
"""
import dataclasses

import numpy as np
import pytest
from scipy.interpolate import CubicSpline, PchipInterpolator

from bayesdrag.drag import ReferenceTable, Spline
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.errors import InputError
from bayesdrag.estimate.build.basis import coefficient_budget, sparse_knots
from bayesdrag.estimate.build.model_size import check_determinable
from bayesdrag.estimate.model.problem import OutputErrorProblem
from bayesdrag.estimate.cd.quality import BEND_CAP, bend_coefficient, unresolved_bend
from bayesdrag.estimate.scheme1.fit import fit_scheme1
from bayesdrag.estimate.build.smoothing import SMOOTHING_GRID, penalty
from bayesdrag.io.drag_tables import load_m101
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.synthetic import add_noise, simulate_round

pbc_tables = pytest.importorskip("py_ballisticcalc.drag_tables")

TABLES = ("G1", "G2", "G5", "G6", "G7", "G8", "GI", "GS", "RA4", "M101")
#: Mach spacings of the points a short track knows Cd at, for the bend bound's check
GAPS = (0.05, 0.1, 0.2, 0.3, 0.4, 0.6)
SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}


def _table(name):
    if name == "M101":
        return load_m101()
    t = getattr(pbc_tables, "Table" + name)
    return ReferenceTable(tuple(p["Mach"] for p in t), tuple(p["CD"] for p in t), source=name)


def _round(ref, mass=42.6, diameter=0.155, v0=818.0, qe=15.0):
    return Round(Projectile("test", mass, diameter, ref), Launch(elevation_deg=qe, velocity=v0),
                 radar=Radar(dict(SIGMA)))


def _short(rnd, channels, samples, dt, seed=3):
    tr = simulate_round(rnd, dt=dt)
    tr = add_noise(tr, SIGMA, np.random.default_rng(seed)).with_channels(channels)
    return tr.subset(slice(0, samples))


@pytest.mark.parametrize("name", TABLES)
def test_bend_bound_holds_on_every_standard_table(name):
    """Cd known only at points g apart (every phase) and interpolated (cubic in ln Cd) misses
    the table by no more than the bound A(M) g^2 (capped) at any Mach between the points."""
    ref = _table(name)
    m = np.asarray(ref.mach, float)
    f = PchipInterpolator(m, np.log(np.asarray(ref.cd_values, float)))
    for g in GAPS:
        for phase in np.linspace(0.0, g, 8, endpoint=False):
            nodes = np.arange(m[0] + phase, m[-1], g)
            if nodes.size < 4:
                continue
            x = np.linspace(nodes[1], nodes[-2], 1500)
            err = np.abs(CubicSpline(nodes, f(nodes), bc_type="natural")(x) - f(x))
            bound = np.minimum(bend_coefficient(x) * g * g, BEND_CAP)
            worst = int(np.argmax(err - bound))
            assert err[worst] <= bound[worst], (name, g, phase, x[worst], err[worst], bound[worst])


def test_unresolved_bend_is_wide_in_the_rise_and_narrow_where_the_drag_is_smooth():
    mach = np.linspace(0.8, 2.6, 181)
    cd = np.interp(mach, [0.8, 1.0, 1.2, 2.6], [0.15, 0.40, 0.38, 0.25])
    dense = np.linspace(0.8, 2.6, 900)
    sparse = np.linspace(0.8, 2.6, 10)                        # 0.2 Mach apart
    b_dense, b_sparse = unresolved_bend(mach, cd, dense), unresolved_bend(mach, cd, sparse)
    rise, smooth = (mach > 0.9) & (mach < 1.1), mach > 2.0
    assert b_dense.max() < 0.002                              # a dense track: nothing unresolved
    assert b_sparse[rise].min() > 0.05                        # a drag rise between samples
    assert b_sparse[smooth].max() < 0.01                      # the supersonic decline is smooth
    # a fitted curve that wiggles between the samples is not confirmed by them
    wiggly = cd * (1.0 + 0.1 * np.sin(mach / 0.05))
    assert np.all(unresolved_bend(mach, wiggly, sparse)[smooth] > 0.02)


def test_sparse_knots_keep_the_budget_and_a_sample_in_every_split():
    samples = np.array([2.4, 2.0, 1.7, 1.45, 1.25, 1.1, 1.0, 0.95, 0.9, 0.85, 0.8, 0.75])
    shape = lambda m: np.interp(m, [0.7, 0.95, 1.05, 2.5], [0.15, 0.2, 0.4, 0.28])  # noqa: E731
    budget = coefficient_budget(samples.size)
    k = sparse_knots(0.72, 2.42, [shape], budget, samples, regions=[(0.9, 1.1, 0.01)])
    assert k.size + 2 <= budget == samples.size
    assert k[0] <= 0.72 and k[-1] >= 2.42 and np.all(np.diff(k) > 0)
    # more knots where the samples and the bend are than in the smooth supersonic part
    assert np.sum((k > 0.8) & (k < 1.2)) > np.sum((k > 1.8) & (k < 2.2))


def test_penalty_rows_count_as_measurements():
    """A penalised spline with more coefficients than a short track has samples is a
    determined problem (its penalty leaves only a straight-line correction to the data); the
    same spline without the penalty is refused."""
    ref = _table("M101")
    rnd = _round(ref)
    tr = _short(rnd, ("v",), 8, 2.0)
    dm = Spline(tuple(np.linspace(0.6, 2.5, 14)))             # 16 coefficients > 8 samples
    model = PointMassModel(42.6, 0.155, dm, rnd.atmosphere)
    theta0 = np.concatenate([np.full(dm.n_params, 0.3), [0, 0, 0, 790.0, 0.0, 211.0]])
    free = np.ones(theta0.size, bool)
    free[dm.n_params:dm.n_params + 3] = free[dm.n_params + 4] = False
    with pytest.raises(InputError, match="8 samples x 1 channels are too few for 18 free parameters"):
        OutputErrorProblem(model, tr, theta0, free=free, channels=("v",))
    shape = lambda m: np.full(np.shape(m), 0.3)  # noqa: E731
    pen = penalty(dm, (None, shape))(SMOOTHING_GRID[6])[0]
    prob = OutputErrorProblem(model, tr, theta0, free=free, channels=("v",), priors=pen)
    assert prob.effective_free() == 4                         # a straight line + Ux0, Uz0


def test_too_short_for_the_smallest_model_is_refused_naming_it():
    rnd = _round(load_m101())
    two = _short(rnd, ("v",), 2, 1.0)
    with pytest.raises(InputError, match=r"2 samples x 1 channel \(v\) are too few to determine Cd: even the "
                                         r"smallest drag model, one factor on the firing table, .* at least 3 samples"):
        check_determinable(two, rnd, ("v",))
    xyz = _short(rnd, ("x", "y", "z"), 2, 1.0)
    with pytest.raises(InputError, match="7 unknowns with the 6 initial-state values"):
        check_determinable(xyz, rnd, ("x", "y", "z"))
    bare = dataclasses.replace(rnd, projectile=dataclasses.replace(rnd.projectile, reference_drag=None))
    with pytest.raises(InputError, match="straight-line correction of the drag curve read off the track"):
        check_determinable(xyz, bare, ("x", "y", "z"))
    # an explicitly chosen model too large for the track names the smallest that is not
    three = _short(rnd, ("v",), 3, 1.0)
    with pytest.raises(InputError, match=r"too few for --drag poly2 .*one factor on the firing table "
                                         r"\(--drag reference-scale\)"):
        check_determinable(three, rnd, ("v",), drag="poly2")


def test_a_track_too_short_for_the_spline_gets_the_tables_one_factor():
    """Three speeds determine one factor on the table (and the launch speed) but not the
    default spline's straight-line correction: the fit uses the factor and says so."""
    rnd = _round(load_m101())
    tr = _short(rnd, ("v",), 3, 2.0)
    assert check_determinable(tr, rnd, ("v",)) == "reference-scale"
    f1 = fit_scheme1(tr, rnd)
    assert f1.drag_model.name == "reference-scale" and f1.success
    assert "too few for the default spline" in f1.model_size["note"]


@pytest.mark.parametrize("samples", [8, 16, 24])
def test_short_track_model_size_follows_the_samples(samples):
    """A 155 mm track sampled every 2 s, speed only: no more spline coefficients than samples,
    the fit converges, and the truth is inside 3 band sd (or 2 %) over the flown span."""
    from bayesdrag.estimate.cd.quality import assess
    from bayesdrag.estimate.cd.table import cd_grid, cd_table

    ref = _table("M101")
    rnd = _round(ref, qe=30.0)
    tr = _short(rnd, ("v",), samples, 2.0, seed=samples)
    f1 = fit_scheme1(tr, rnd)
    size = f1.model_size
    assert f1.success and size["short"] and size["coefficients"] <= samples
    lo, hi = float(np.nanmin(f1.ml.mach)), float(np.nanmax(f1.ml.mach))
    grid = cd_grid(lo, hi)
    rows = cd_table(f1.ml, f1.drag_model, grid, ref)
    q = assess(f1, rows, tr, rnd.radar.sigma)
    assert any("short track" in n for n in q["notes"])
    w = 0.05 * (hi - lo)
    for r in rows:
        if lo + w <= r["mach"] <= hi - w:
            err = abs(r["ml"] - r["reference"])
            assert err <= 0.02 * r["reference"] or err <= 3.0 * r["band_sd"], r
