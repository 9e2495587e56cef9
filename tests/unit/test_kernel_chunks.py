"""Ctrl-C inside long kernel work (issue 26): a long batch runs as several kernel calls of whole
trajectories, so the interpreter sees a Ctrl-C between two of them, and a trajectory that would
need an absurd number of steps is refused instead of running for minutes. Checked by what the
run did (the calls counted), not by a timer.
"""
import numpy as np
import pytest

import bayesdrag.dynamics.pointmass as pm
from bayesdrag.dynamics import kernel as K
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.errors import FitError
from bayesdrag.io.drag_tables import load_m101

#: chunked and single calls agree to this [m, m/s] (lane layouts differ at rounding level)
SAME_ATOL = 1e-6


def _counting(monkeypatch):
    calls = []
    real = K.integrate_batch

    def wrapped(*a):
        calls.append(a[0].shape[0])
        return real(*a)
    monkeypatch.setattr(K, "integrate_batch", wrapped)
    return calls


def test_a_long_batch_runs_as_several_calls_with_the_same_result(monkeypatch):
    model = PointMassModel(42.6, 0.155, load_m101())
    B = 40
    state0 = np.repeat(initial_state(818.0, 15.0)[None], B, axis=0)
    state0[:, 3] += np.linspace(-5.0, 5.0, B)               # 40 different trajectories
    t = np.linspace(0.0, 30.0, 301)
    one = model.simulate_batch((), state0, t)
    calls = _counting(monkeypatch)
    n_steps = pm.output_schedule(t, 0.0, model.kernel_step)[1]
    monkeypatch.setattr(pm, "CHUNK_LANE_STEPS", 8 * n_steps)  # 8 trajectories a call
    many = model.simulate_batch((), state0, t)
    assert calls == [8] * 5
    assert np.allclose(many.state, one.state, rtol=0, atol=SAME_ATOL)
    assert np.allclose(many.mach, one.mach, rtol=0, atol=1e-9)


def test_an_ordinary_batch_is_one_call(monkeypatch):
    model = PointMassModel(42.6, 0.155, load_m101())
    calls = _counting(monkeypatch)
    model.simulate_batch((), np.repeat(initial_state(818.0, 15.0)[None], 90, axis=0), np.linspace(0, 30, 1100))
    assert calls == [90]


def test_an_absurd_step_count_is_refused_before_the_kernel_runs(monkeypatch):
    model = PointMassModel(42.6, 0.155, load_m101(), max_step=1e-7)   # 3e8 steps over 30 s
    calls = _counting(monkeypatch)
    with pytest.raises(FitError, match=r"needs 300000000 RK4 steps .* check its mass and diameter"):
        model.simulate_batch((), initial_state(818.0, 15.0)[None], np.linspace(0, 30, 11))
    assert calls == []
