"""The Levenberg-Marquardt step with parameters on their bounds (``estimate.model.ml.bounded_step``):
a parameter on a bound that the descent direction, or the others' step, pushes out is held, and
the others take the step of the reduced system; with none pushed out the step is the plain one,
bit for bit (a fit that never touches a bound is unchanged)."""
import numpy as np
import pytest

from bayesdrag.estimate.model.ml import bounded_step

#: agreement of two solves of the same small system [-]
SOLVE_RTOL = 1e-12


def _system(rng, n=5):
    J = rng.normal(size=(40, n))
    return J.T @ J + 0.1 * np.eye(n), rng.normal(size=n)


def test_no_bound_touched_gives_the_plain_step_bit_for_bit():
    A, g = _system(np.random.default_rng(1))
    none = np.zeros(g.size, bool)
    assert np.array_equal(bounded_step(A, g, none, none), np.linalg.solve(A, g))


def test_a_bound_the_descent_points_out_of_is_held_and_the_rest_solve_without_it():
    A, g = _system(np.random.default_rng(2))
    g[0] = -abs(g[0]) - 1.0            # descent pushes parameter 0 below its lower bound
    at_lo = np.zeros(g.size, bool)
    at_lo[0] = True
    step = bounded_step(A, g, at_lo, np.zeros(g.size, bool))
    assert step[0] == 0.0
    np.testing.assert_allclose(step[1:], np.linalg.solve(A[1:, 1:], g[1:]), rtol=SOLVE_RTOL)


def test_a_bound_the_descent_points_away_from_is_left_free():
    A = np.eye(3)
    g = np.array([1.0, -2.0, 0.5])     # parameter 0 sits on its lower bound and is pushed up
    at_lo = np.array([True, False, False])
    step = bounded_step(A, g, at_lo, np.zeros(3, bool))
    np.testing.assert_allclose(step, g, rtol=SOLVE_RTOL)


def test_a_bound_the_others_step_pushes_out_is_held_too():
    # parameter 1 on its upper bound: its own descent component is 0 (not pushed out), but the
    # coupled step would raise it; it is held and parameter 0 solves alone
    A = np.array([[1.0, -0.9], [-0.9, 1.0]])
    g = np.array([1.0, 0.0])
    at_hi = np.array([False, True])
    assert np.linalg.solve(A, g)[1] > 0
    step = bounded_step(A, g, np.zeros(2, bool), at_hi)
    assert step[1] == 0.0
    assert step[0] == pytest.approx(g[0] / A[0, 0], rel=SOLVE_RTOL)


def test_every_parameter_held_gives_no_step():
    A, g = _system(np.random.default_rng(3), n=2)
    g = -np.abs(g) - 0.1
    step = bounded_step(A, g, np.ones(2, bool), np.zeros(2, bool))
    assert np.array_equal(step, np.zeros(2))


def test_a_bound_touched_but_not_pushed_out_gives_the_plain_step_bit_for_bit():
    A, g = _system(np.random.default_rng(4))
    plain = np.linalg.solve(A, g)
    at_lo = plain > 0                  # on the lower bound where the step moves up: free
    at_hi = plain < 0                  # on the upper bound where it moves down: free
    at_lo &= g > 0
    at_hi &= g < 0
    assert at_lo.any() or at_hi.any()
    assert np.array_equal(bounded_step(A, g, at_lo, at_hi), plain)


def test_a_parameter_pinned_by_equal_bounds_never_moves():
    A, g = _system(np.random.default_rng(5), n=3)
    pinned = np.array([False, True, False])      # lower == upper: on both bounds at once
    step = bounded_step(A, g, pinned, pinned)
    assert step[1] == 0.0
    np.testing.assert_allclose(step[[0, 2]], np.linalg.solve(A[np.ix_([0, 2], [0, 2])], g[[0, 2]]),
                               rtol=SOLVE_RTOL)
