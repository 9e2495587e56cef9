"""The planner's predicted Cd sd against fits of simulated firings (issue 18).

For each case, ``bayesdrag.plan`` predicts the sd of Cd by Mach; then the nominal track is
re-noised ``N`` times (seeded), each replicate is fitted with the default fit (Scheme 1,
penalised spline, ML: ``fit_scheme1``), and at every checked Mach the prediction is compared

* with the sd the fits report (their Cramér-Rao sd, averaged over the replicates): the ratio
  within :data:`REPORTED_BAND` = 0.8-1.25;
* with the Monte-Carlo spread of their estimates: within :data:`SPREAD_BAND` = 0.6-1.8 (a
  penalised fit's reported sd is its posterior sd under the smoothness prior and may exceed the
  spread of its estimates: measured 1.4-1.7x on a 105 mm G2 track).

Cases (two shells, two elevations each), radar sigma 1 m / 0.3 m/s every 0.027 s, launch to
impact, tracks from bayesdrag's point-mass reference integrator (as ``bayesdrag simulate``):

* 155 mm, 42.6 kg, 818 m/s, M101 drag, the round's reference drag = the truth (the fit's model is
  the table times a smooth correction);
* 105 mm, 15 kg, 600 m/s, py-ballisticcalc's G2 table as the truth and *no* table in the round
  (the fit's model is a spline in Cd; the plan is told the assumed drag).

Checked Mach: every 0.1 Mach inside the flown range less 5 % of its width at each end (the
robustness suite's trim: a fit's ends are its least determined part).

Measured (40 replicates, seed 100; ``pytest -m slow -s``): predicted / reported 0.90-1.02, predicted /
Monte Carlo 0.69-1.63 over the four cases (docs/planning.md has the table per case).

The quick test runs one case with :data:`QUICK_REPLICATES` replicates, the spread band widened
by the 99.9 % chi-square interval of an sd from that many samples, and checks that the
marginalised systematic sources match the fit's own Cramér-Rao sd with each source as a nuisance
parameter (:data:`NUISANCE_RTOL`).
"""
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import chi2

import bayesdrag
from bayesdrag.drag import ReferenceTable
from bayesdrag.effects import EFFECTS, EffectContext, effect_fn, extra_params
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.estimate.build.launch import launch_state_priors
from bayesdrag.planning.case import case_round, nominal_flight
from bayesdrag.estimate.model.problem import OutputErrorProblem, Prior
from bayesdrag.estimate.cd.table import cd_table
from bayesdrag.estimate.scheme1.fit import fit_scheme1
from bayesdrag.estimate.build.smoothing import smoothness_priors
from bayesdrag.round import Launch, Projectile, Radar, Round, Systematics
from bayesdrag.synthetic import add_noise, simulate_round
from bayesdrag.track import RadarTrack

SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
DT = 0.027
#: predicted sd / the sd the fits report (issue 18 acceptance)
REPORTED_BAND = (0.8, 1.25)
#: predicted sd / Monte-Carlo sd of the estimates (issue 18 acceptance)
SPREAD_BAND = (0.6, 1.8)
#: replicates of the slow test (the acceptance asks >= 30) and of the quick one
REPLICATES = 40
QUICK_REPLICATES = 8
#: the evaluation span is the flown Mach span less this fraction of its width at each end
SPAN_TRIM = 0.05
#: checked Mach step
CHECK_STEP = 0.1
#: marginal sd of Cd with one systematic source: plan vs the fit's CRB with the source as a
#: nuisance parameter (same linearisation, different code: effects' finite differences, the
#: fit's prior terms; measured 1e-6 to 4e-6, docs/planning.md says 1e-4) [-]
NUISANCE_RTOL = 1e-4
SEED = 100


def _g2():
    from acceptance.pbc_suite import table

    m, c = table("G2")
    return ReferenceTable(tuple(m), tuple(c), source="py-ballisticcalc G2")


def shell(name, elevation):
    """(round the fit sees, round that flies the truth, assumed drag for the plan)."""
    if name == "155":
        from bayesdrag.io.drag_tables import load_m101

        m101 = load_m101()
        rnd = Round(Projectile("155 mm M101", 42.6, 0.155, m101), Launch(elevation, 818.0), radar=Radar(dict(SIGMA)))
        return rnd, rnd, None
    g2 = _g2()
    fit_rnd = Round(Projectile("105 mm, no table", 15.0, 0.105), Launch(elevation, 600.0), radar=Radar(dict(SIGMA)))
    truth = replace(fit_rnd, projectile=Projectile("105 mm G2", 15.0, 0.105, g2))
    return fit_rnd, truth, g2


def checked_mach(lo, hi):
    trim = SPAN_TRIM * (hi - lo)
    a, b = np.ceil((lo + trim) / CHECK_STEP), np.floor((hi - trim) / CHECK_STEP)
    return np.round(np.arange(a, b + 1) * CHECK_STEP, 4)


def replicate_fits(name, elevation, n, seed=SEED):
    """Predicted sd, mean reported sd and MC sd of the estimates at the checked Mach."""
    fit_rnd, truth_rnd, assumed = shell(name, elevation)
    case = bayesdrag.plan(fit_rnd, dt=DT, assumed_drag=assumed).cases[0]
    mach = checked_mach(*case.mach_range)
    clean = simulate_round(truth_rnd, dt=DT)
    rng = np.random.default_rng(seed)
    est, rep = [], []
    for _ in range(n):
        f = fit_scheme1(add_noise(clean, SIGMA, rng), fit_rnd)
        assert f.ml.converged, f.ml.message
        rows = cd_table(f.ml, f.drag_model, mach)
        est.append([r["ml"] for r in rows])
        rep.append([r["crb_sd"] for r in rows])
    pred = np.interp(mach, case.mach, case.sd)
    return mach, pred, np.mean(rep, axis=0), np.std(est, axis=0, ddof=1)


def _check(name, elevation, n, spread_band):
    mach, pred, rep, mc = replicate_fits(name, elevation, n)
    r_rep, r_mc = pred / rep, pred / mc
    print(f"{name} mm QE {elevation:g}: {mach.size} Mach {mach[0]:.1f}-{mach[-1]:.1f}; predicted/reported "
          f"{r_rep.min():.3f}-{r_rep.max():.3f}; predicted/MC {r_mc.min():.3f}-{r_mc.max():.3f}")
    assert mach.size >= 5
    assert np.all((r_rep >= REPORTED_BAND[0]) & (r_rep <= REPORTED_BAND[1])), dict(zip(mach, np.round(r_rep, 3)))
    assert np.all((r_mc >= spread_band[0]) & (r_mc <= spread_band[1])), dict(zip(mach, np.round(r_mc, 3)))


def _widened(n):
    """SPREAD_BAND times the 99.9 % interval of sd_true / sd_sample for n samples."""
    lo = np.sqrt((n - 1) / chi2.ppf(0.9995, n - 1))
    hi = np.sqrt((n - 1) / chi2.ppf(0.0005, n - 1))
    return SPREAD_BAND[0] * lo, SPREAD_BAND[1] * hi


def test_prediction_matches_fits_quick():
    _check("155", 15.0, QUICK_REPLICATES, _widened(QUICK_REPLICATES))


@pytest.mark.slow
@pytest.mark.parametrize("name, elevation", [("155", 15.0), ("155", 45.0), ("105", 15.0), ("105", 45.0)])
def test_prediction_matches_fits(name, elevation):
    _check(name, elevation, REPLICATES, SPREAD_BAND)


@pytest.mark.parametrize("effect, stem, sd, null", [("temperature", "temperature", 1.0, 0.0),
                                                     ("density", "density", 0.003, 1.0),
                                                     ("radar_time", "time_offset", 0.002, 0.0)])
def test_marginalised_source_matches_the_fits_nuisance_crb(effect, stem, sd, null):
    """The plan's total sd with one declared source equals the CRB of the fit's own problem with
    that source as an effect parameter (bayesdrag.effects) under a Gaussian prior of that sd, at
    the plan's drag model and smoothing, on the nominal track."""
    base, _, _ = shell("155", 15.0)
    rnd = replace(base, systematics=Systematics(**{stem: sd}))
    case = bayesdrag.plan(rnd, dt=DT).cases[0]
    rc = case_round(rnd, 15.0, 818.0)
    t, state, _, _ = nominal_flight(rc, rnd.reference_drag, DT)
    track = RadarTrack(t, {"x": state[:, 0], "y": state[:, 1], "z": state[:, 2],
                           "v": np.linalg.norm(state[:, 3:], axis=1)})
    dm, P = case.model, case.model.n_params
    eff = [EFFECTS[effect]]
    smooth = tuple(Prior(p.name, p.fn, p.mean, p.sd, row=np.append(p.row, 0.0))
                   for p in smoothness_priors(dm, case.base, case.smoothing["sd"]))
    priors = launch_state_priors(rc.launch, P) + smooth + (Prior(stem, lambda th: th[..., P + 6], null, sd),)
    prob = OutputErrorProblem(PointMassModel(rc.projectile.mass, rc.projectile.diameter, dm, rc.atmosphere), track,
                              np.concatenate([case.truth_params, state[0], [null]]), sigma=SIGMA, priors=priors,
                              extras=extra_params(eff), effect_fn=effect_fn(eff, EffectContext(atmosphere=rc.atmosphere)))
    res = prob.fit()
    assert res.converged, res.message
    B = dm.jacobian(case.mach)
    sd_fit = np.sqrt(np.einsum("ij,jk,ik->i", B, res.cov[:P, :P], B))
    np.testing.assert_allclose(case.sd_one_round, sd_fit, rtol=NUISANCE_RTOL)
