"""Messy tracks with known truth (issue 7): dropouts and gaps, irregular sampling, a radar that
locks on late, a track that ends before impact. Each is a noisy point-mass track of the 155 mm
M101 shell (42.6 kg, 818 m/s, QE 15 deg; truth = the M101 table, BRL MR-1167) fitted by the
Scheme 1 spline (:func:`bayesdrag.estimate.scheme1.fit.fit_scheme1`), and Cd must come back over the
Mach range the remaining data cover.

Measured (seed 5/11, radar sigma 1 m / 0.3 m/s, 0.1 s nominal sampling): largest |Cd error|
0.74 % (dropouts), 0.48 % (irregular), 0.47 % (late lock), 0.57 % (ends early); largest
error / CRB sd 2.0.
"""
import numpy as np
import pytest

from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.estimate.cd.table import cd_table, determined_range
from bayesdrag.estimate.scheme1.fit import fit_scheme1
from bayesdrag.synthetic import add_noise, drop_samples
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.track import RadarTrack

#: Cd recovery over the Mach range the data cover (issue 4's 1 % for the spline)
CD_RTOL = 0.01
#: error over its own Cramér-Rao sd: "of order one"
Z_MAX = 3.0
#: late lock: the fitted state at the first sample against the truth there [m], [m/s]
IC_POS_TOL, IC_VEL_TOL = 1.5, 0.5
SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
V0, QE = 818.0, 15.0


@pytest.fixture(scope="module")
def truth(m101):
    return PointMassModel(42.6, 0.155, m101)


@pytest.fixture(scope="module")
def round_(m101):
    return Round(Projectile("155 mm", 42.6, 0.155, m101, None), Launch(QE, V0), radar=Radar(dict(SIGMA)),
                 path="messy.toml")


def _track(truth, t):
    tr = truth.simulate((), initial_state(V0, QE), t, backend="scipy", stop_at_impact=True)
    return RadarTrack(tr.t, {c: tr.channel(c) for c in "xyzv"}, {}, source="synthetic")


@pytest.fixture(scope="module")
def full(truth):
    return _track(truth, np.arange(0.0, 60.0, 0.1))


def _cases(full, truth):
    rng = np.random.default_rng(5)
    ti = np.concatenate([[0.0], np.cumsum(rng.uniform(0.02, 0.2, 800))])
    return {
        # 30 % random dropouts plus two 3 s gaps (one supersonic, one near the transonic dip)
        "dropouts": drop_samples(full, 0.3, gaps=[(5.0, 8.0), (20.0, 23.0)], rng=rng),
        # sample intervals uniform in 20-200 ms
        "irregular": _track(truth, ti[ti < 60.0]),
        # radar locks on 2 s after launch: ICs belong to the first sample (t = 2 s)
        "late_lock": full.subset(full.t >= 2.0),
        # track lost at 25 s, before impact (32.4 s)
        "ends_early": full.subset(full.t <= 25.0),
    }


@pytest.fixture(scope="module")
def fits(full, truth, round_):
    out = {}
    for name, tr in _cases(full, truth).items():
        noisy = add_noise(tr, SIGMA, np.random.default_rng(11))
        f1 = fit_scheme1(noisy, round_, drag="spline")
        out[name] = (noisy, f1.ml, f1.problem)
    return out


@pytest.mark.parametrize("case", ["dropouts", "irregular", "late_lock", "ends_early"])
def test_messy_track_recovers_cd(case, fits, m101):
    track, res, prob = fits[case]
    assert res.success and res.converged, res.message
    lo, hi = float(res.mach.min()), float(res.mach.max())
    mach = np.linspace(lo, hi, 41)
    rows = cd_table(res, prob.model.drag, mach, m101)
    err = np.array([r["ml"] / r["reference"] - 1 for r in rows])
    z = np.array([(r["ml"] - r["reference"]) / r["crb_sd"] for r in rows])
    assert np.max(np.abs(err)) < CD_RTOL, f"{case}: max |Cd error| {np.max(np.abs(err)):.4f} over Mach {lo:.2f}-{hi:.2f}"
    assert np.max(np.abs(z)) < Z_MAX, f"{case}: error/CRB {np.round(z, 2)}"
    # Cd is determined (CRB < 1 %) over the whole span the data cover
    det = determined_range(rows)
    assert det is not None and det[0] <= lo + 0.05 and det[1] >= hi - 0.05


def test_case_data_are_messy(fits, full):
    """The cases really are what they claim (guards against a fixture that silently fits the
    full track)."""
    tr = fits["dropouts"][0]
    assert tr.n < 0.72 * full.n and not np.any((tr.t > 5.05) & (tr.t < 7.95))
    dt = np.diff(fits["irregular"][0].t)
    assert dt.min() < 0.03 and dt.max() > 0.15
    assert fits["late_lock"][0].t[0] == pytest.approx(2.0)
    assert fits["ends_early"][0].t[-1] <= 25.0 < full.t[-1] - 4.0
    assert fits["ends_early"][0].z[-1] > 500.0  # lost ~900 m up, well before impact


def test_late_lock_initial_state_is_at_first_sample(fits, truth):
    track, res, _ = fits["late_lock"]
    ref = truth.simulate((), initial_state(V0, QE), np.array([0.0, track.t[0]]), backend="scipy").state[-1]
    ic = np.array([res.params[k] for k in ("X0", "Y0", "Z0", "Ux0", "Uy0", "Uz0")])
    assert np.abs(ic[:3] - ref[:3]).max() < IC_POS_TOL
    assert np.abs(ic[3:] - ref[3:]).max() < IC_VEL_TOL
