"""A planned case never builds more samples than a fit uses (issue 25: ``plan --dt 0.0001`` took
15 GB for one case and 64 cases gave nothing in 280 s): the bound is checked from ``dt`` before
simulating, the radar samples are thinned to every k-th as the fit thins a dense track, and the
prediction is the one for the samples the fit would keep."""
from importlib.resources import files

import numpy as np
import pytest

from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.planning import case as plan_module
from bayesdrag.planning.case import MAX_DIRECT_SAMPLES, MAX_FLIGHT_TIME, case_round, nominal_flight, plan_case
from bayesdrag.io.rounds import read_round
from bayesdrag.track import MAX_FIT_SAMPLES

#: relative agreement of two plans of the same samples: their times differ in the last bit (k x
#: 0.1 ms against multiples of k x 0.1 ms), which moves the kernel's sub-steps (measured 2e-5)
TOL_SD_REL = 1e-4


@pytest.fixture(scope="module")
def rnd():
    return read_round(files("bayesdrag") / "data" / "demo_round.toml")


@pytest.fixture
def requests(monkeypatch):
    """The samples each simulation of the nominal flight was asked for (its dt grid or times)."""
    seen = []
    real = PointMassModel.simulate

    def recording(self, drag_params, state0, t_out=None, **kw):
        if t_out is not None:
            seen.append(len(t_out))
        else:
            seen.append(int(np.ceil(kw.get("max_time", 600.0) / kw["dt"])))
        return real(self, drag_params, state0, t_out, **kw)

    monkeypatch.setattr(PointMassModel, "simulate", recording)
    return seen


@pytest.mark.parametrize("elevation, velocity", [(e, v) for e in np.linspace(10, 45, 8)
                                                 for v in np.linspace(650, 830, 8)])
def test_every_one_of_64_cases_at_dt_1e_4_is_bounded_before_simulating(rnd, requests, elevation, velocity):
    rc = case_round(rnd, elevation, velocity)
    t, state, mach, t_imp = nominal_flight(rc, rnd.reference_drag, 1e-4)
    assert max(requests) <= MAX_DIRECT_SAMPLES, requests       # no simulation evaluated more
    assert requests[0] == int(np.ceil(MAX_FLIGHT_TIME / plan_module.COARSE_DT))
    assert t.size <= MAX_FIT_SAMPLES + 1 and state.shape == (t.size, 6)
    n_radar = int(np.ceil(t_imp / 1e-4)) + 1          # every 0.1 ms from launch, and the impact
    k = int(round((t[1] - t[0]) / 1e-4))
    assert k == -(-n_radar // MAX_FIT_SAMPLES)             # thinned as thin_for_fit thins the track
    np.testing.assert_allclose(np.diff(t[:-1]), k * 1e-4, rtol=1e-6)
    assert t[-1] == pytest.approx(t_imp, abs=1e-12)


def test_a_dense_plan_predicts_what_the_fit_of_the_thinned_track_reports(rnd):
    """dt = 0.1 ms thinned to one sample in k is the plan of the samples every k x 0.1 ms, and
    says so."""
    dense = plan_case(rnd, 15.0, 818.0, dt=1e-4)
    k = int(round((dense.t_tracked[1] - dense.t_tracked[0]) / (dense.samples - 1) / 1e-4))
    assert dense.samples <= MAX_FIT_SAMPLES + 1
    assert any(f"one sample in {k} ({dense.samples} samples)" in n for n in dense.notes), dense.notes
    coarse = plan_case(rnd, 15.0, 818.0, dt=k * 1e-4)
    assert coarse.samples == dense.samples and not coarse.notes
    np.testing.assert_allclose(dense.sd, coarse.sd, rtol=TOL_SD_REL)


def test_the_default_dt_is_planned_on_every_sample(rnd, requests):
    c = plan_case(rnd, 15.0, 818.0)
    assert not c.notes and requests[0] == int(np.ceil(MAX_FLIGHT_TIME / c.dt))
    assert c.samples == int(np.floor((c.t_tracked[1] - c.t_tracked[0]) / c.dt + 1e-9)) + 1 + 1   # + impact
