"""The parameter vector's layout (drag coefficients, initial state, effects) has one home."""
import numpy as np
import pytest

from bayesdrag.estimate.model.layout import N_STATE, STATE, ParameterLayout


def test_blocks_tile_the_vector_in_order():
    lay = ParameterLayout(n_drag=5, n_effects=3)
    theta = np.arange(lay.size)
    assert lay.size == 5 + N_STATE + 3
    assert list(theta[lay.drag]) + list(theta[lay.state]) + list(theta[lay.effects]) == list(theta)
    assert list(theta[lay.position]) + list(theta[lay.velocity]) == list(theta[lay.state])
    assert [lay.index(c) for c in STATE] == list(range(5, 5 + N_STATE))


def test_an_unknown_state_component_is_refused():
    with pytest.raises(ValueError, match="not in tuple"):
        ParameterLayout(3).index("w")


def test_the_problem_and_its_result_use_the_layout(round_, clean_track):
    import bayesdrag

    res = bayesdrag.fit(clean_track, round_, mcmc=False, with_effects="none", model_check=False)
    prob, ml = res.scheme1.problem, res.scheme1.ml
    lay = prob.layout
    assert lay == ParameterLayout(prob.P, prob.E)
    np.testing.assert_array_equal(ml.state0, ml.theta[lay.state])
    assert len(ml.theta) == lay.size
