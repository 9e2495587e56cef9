"""The noise model's own uncertainty in the bands (bayesdrag.estimate.model.noise_spread): the
whitening's transpose and the correlation's product against dense matrices, the averaged
sandwich against its dense form, and the restricted likelihood's spread of the correlation
against the spread of its estimates over many noise draws."""
import math

import numpy as np
import pytest

from bayesdrag.estimate.model import colored, noise_spread, restricted

#: agreement of the O(N) recursions with dense linear algebra [relative]
DENSE_RTOL = 1e-10


def _irregular(rng, n):
    return rng.uniform(0.5, 2.0, n - 1)


def _dense(rho, q, dtr):
    t = np.concatenate([[0.0], np.cumsum(dtr)])
    R = rho ** np.abs(t[:, None] - t[None, :])
    return R, np.eye(t.size) + q * R


def test_adjoint_standardize_is_the_transpose_of_the_whitening():
    rng = np.random.default_rng(3)
    n = 80
    dtr = _irregular(rng, n)
    rho, q = 0.93, 4.0
    _, corr = _dense(rho, q, dtr)
    Linv, _ = colored.standardize(np.eye(n), rho, q, dtr)
    y = rng.normal(size=(n, 3))
    np.testing.assert_allclose(colored.adjoint_standardize(y, rho, q, dtr), Linv.T @ y, rtol=DENSE_RTOL, atol=1e-12)
    a = rng.normal(size=n)
    u, _ = colored.standardize(a, rho, q, dtr)
    np.testing.assert_allclose(colored.adjoint_standardize(u, rho, q, dtr), np.linalg.solve(corr, a),
                               rtol=DENSE_RTOL, atol=1e-12)


def test_correlation_apply_matches_the_dense_correlation():
    rng = np.random.default_rng(4)
    n = 70
    dtr = _irregular(rng, n)
    R, _ = _dense(0.8, 1.0, dtr)
    z = rng.normal(size=(n, 4))
    np.testing.assert_allclose(colored.correlation_apply(z, 0.8, dtr), R @ z, rtol=DENSE_RTOL, atol=1e-12)


def test_channel_change_is_the_averaged_sandwich():
    rng = np.random.default_rng(5)
    n, k = 60, 3
    dtr = _irregular(rng, n)
    J = rng.normal(size=(n, k))
    rho0, q0, s20 = 0.9, 3.0, 0.7
    points = ((0.85, 2.0, 0.8), (0.95, 5.0, 0.6))
    S0 = s20 * _dense(rho0, q0, dtr)[1]
    Z = np.linalg.solve(S0, J)
    want = sum(Z.T @ (s2 * _dense(r, q, dtr)[1]) @ Z for r, q, s2 in points) / 2 - Z.T @ S0 @ Z
    got = noise_spread.channel_change(J, rho0, q0, s20, points, dtr)
    np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-10 * np.abs(want).max())


def test_channel_change_vanishes_at_the_estimate():
    rng = np.random.default_rng(6)
    n = 50
    dtr = np.ones(n - 1)
    J = rng.normal(size=(n, 2))
    got = noise_spread.channel_change(J, 0.9, 3.0, 0.5, ((0.9, 3.0, 0.5),) * 2, dtr)
    assert np.abs(got).max() == 0.0


def _ar1_noise(rng, n, rho, q, sigma):
    d = np.empty(n)
    d[0] = rng.normal(0.0, math.sqrt(q))
    for i in range(1, n):
        d[i] = rho * d[i - 1] + rng.normal(0.0, math.sqrt(q * (1 - rho * rho)))
    return sigma * (rng.normal(size=n) + d)


#: noise draws of the Monte-Carlo check, and how far the spread's median sd may sit from the
#: estimates' own sd in log(1 - rho) (a factor: 60 draws give the sd to about 10 %; seeds 7, 11
#: and 12 give ratios 1.23, 1.12 and 1.35, the spread a little wide: the search's bound at the
#: plain estimate cuts the short side of the estimates' scatter)
MC_DRAWS, MC_FACTOR = 60, 1.45


def test_restricted_spread_matches_the_spread_of_the_estimates():
    """rho 0.9 with a white part, a quadratic trend fitted: the restricted likelihood's sd of
    log(1 - rho) is the scatter of its estimates over noise draws."""
    rng = np.random.default_rng(7)
    n, rho, q = 400, 0.9, 4.0
    dtr = np.ones(n - 1)
    t = np.linspace(-1.0, 1.0, n)
    J = np.column_stack([np.ones(n), t, t * t])
    A, g = np.zeros((3, 3)), np.zeros(3)
    est, sds = [], []
    for _ in range(MC_DRAWS):
        e = _ar1_noise(rng, n, rho, q, 1.0)
        _, r0, q0, _ = colored.fit_noise(e, dtr)
        _, r1, q1 = restricted.fit_noise_restricted(e, dtr, (r0, q0), J, A, g)
        sd, points = restricted.restricted_spread(e, dtr, J, A, g, r1, q1)
        est.append(math.log(1.0 - r1))
        sds.append(sd)
        assert len(points) == 2 and points[0][0] > r1 > points[1][0]
    spread = float(np.median(sds))
    scatter = float(np.std(est, ddof=1))
    assert scatter / MC_FACTOR < spread < scatter * MC_FACTOR, (spread, scatter)


def test_no_spread_for_a_correlation_beyond_the_track():
    rng = np.random.default_rng(8)
    n = 200
    e = rng.normal(size=n)
    J = np.ones((n, 1))
    sd, points = restricted.restricted_spread(e, np.ones(n - 1), J, np.zeros((1, 1)), np.zeros(1),
                                              1.0 - 0.5 / n, 10.0)
    assert sd == 0.0 and points == ()
