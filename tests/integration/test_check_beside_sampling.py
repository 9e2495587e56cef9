"""What a fit computes that does not change what it runs beside goes to a forked process: the
model check's diagnosis beside the ML fit (and beside the sampling when the check cannot change
what is sampled: ``with_effects="none"`` or named effects), the added effects' sizes beside the
sampling. The result is the same as when all runs here, to the last bit, and ``timing.beside``
says what ran in a forked process."""
import json
import os
import sys

import pytest

import bayesdrag
from bayesdrag._runtime import beside as _beside
from bayesdrag.options import FitOptions

#: a forked process can run the check on this platform
FORKS = hasattr(os, "fork") and sys.platform.startswith("linux")
#: a short chain: the comparison is of two runs of one seed, not of a converged posterior
STEPS = 300


@pytest.fixture(scope="module")
def demo():
    from bayesdrag.commands.demo import demo_inputs
    from bayesdrag.io.rounds import read_round
    from bayesdrag.io.tracks import read_track

    track_path, round_path = demo_inputs()
    return read_track(track_path), read_round(round_path)


def _without_clock(d):
    d = dict(d)
    timing = d.pop("timing")
    d["mcmc"] = {k: v for k, v in d["mcmc"].items() if k != "seconds"}
    return json.dumps(d, sort_keys=True, default=str), timing


def test_the_diagnosis_beside_the_fit_gives_the_same_result(demo, monkeypatch):
    track, rnd = demo
    opts = FitOptions(seed=3, with_effects="none", max_steps=STEPS)
    monkeypatch.setattr(_beside, "free_core", lambda: True)
    beside, t_beside = _without_clock(bayesdrag.fit(track, rnd, opts).to_dict())
    monkeypatch.setattr(_beside, "free_core", lambda: False)
    after, t_after = _without_clock(bayesdrag.fit(track, rnd, opts).to_dict())
    assert beside == after
    assert t_after["beside"] == []
    assert t_beside["beside"] == (["diagnosis"] if FORKS else [])
    assert json.loads(beside)["ml"]["quality"]["model_error"]["verdict"] == ["lift"]   # the check did run


def test_the_default_check_decides_what_is_sampled_and_the_sizes_go_beside(demo, monkeypatch):
    track, rnd = demo
    opts = FitOptions(seed=3, max_steps=STEPS)
    monkeypatch.setattr(_beside, "free_core", lambda: True)
    beside, t_beside = _without_clock(bayesdrag.fit(track, rnd, opts).to_dict())
    monkeypatch.setattr(_beside, "free_core", lambda: False)
    after, t_after = _without_clock(bayesdrag.fit(track, rnd, opts).to_dict())
    assert beside == after
    assert json.loads(beside)["ml"]["with_effects"]["added_by"] == "default"   # the check ran first
    assert t_beside["beside"] == (["diagnosis", "effect_sizes"] if FORKS else []) and t_after["beside"] == []
