"""posterior.nc is written from the fit's arrays without ArviZ (bayesdrag.io.netcdf), and reads
back with ``arviz.from_netcdf`` as the InferenceData the result gives: every group, variable,
coordinate, value and attribute (but the time stamp) the same as when ArviZ writes it."""
import arviz as az
import numpy as np
import pytest

import bayesdrag
from bayesdrag.estimate.bayes.posterior_groups import fit_groups
from bayesdrag.io.netcdf import write_groups
from bayesdrag.options import FitOptions

#: a short chain: the file is compared with itself, not with a converged posterior
STEPS = 300


@pytest.fixture(scope="module")
def fitted():
    from bayesdrag.commands.demo import demo_inputs
    from bayesdrag.io.rounds import read_round
    from bayesdrag.io.tracks import read_track

    track_path, round_path = demo_inputs()
    return bayesdrag.fit(read_track(track_path), read_round(round_path),
                         FitOptions(seed=2, with_effects="none", max_steps=STEPS))


def _attrs(ds):
    return {k: np.asarray(v).tolist() for k, v in ds.attrs.items() if k != "created_at"}


def test_the_file_reads_back_as_the_inference_data(fitted, tmp_path):
    ours, theirs = tmp_path / "ours.nc", tmp_path / "arviz.nc"
    write_groups(ours, *fit_groups(fitted._posterior_arrays()))
    fitted.to_inference_data().to_netcdf(str(theirs))
    a, b = az.from_netcdf(str(ours)), az.from_netcdf(str(theirs))
    assert sorted(a.groups()) == sorted(b.groups()) == sorted(
        ["posterior", "posterior_predictive", "sample_stats", "observed_data", "constant_data", "log_likelihood"])
    for g in b.groups():
        assert a[g].drop_attrs().identical(b[g].drop_attrs()), g     # values, dims, coords, dtypes
        assert _attrs(a[g]) == _attrs(b[g]), g
    assert list(a.log_likelihood.coords) == ["chain", "draw", "observation", "obs_channel", "obs_time"]
    loo = az.loo(a, reff=1.0)                      # what the log_likelihood group is for
    assert np.isfinite(loo.elpd_loo)


def test_the_written_folder_holds_that_file(fitted, tmp_path):
    fitted.write(tmp_path / "out")
    back = bayesdrag.load_result(tmp_path / "out")
    idata = fitted.to_inference_data()
    assert np.array_equal(back.to_inference_data().posterior["cd"].values, idata.posterior["cd"].values)
    assert np.array_equal(back.cd_draws(), fitted.cd_draws())


def test_groups_whose_dimensions_disagree_are_refused(tmp_path):
    from bayesdrag.estimate.bayes.posterior_groups import Group

    bad = {"posterior": Group({"a": (("chain", "draw"), np.zeros((2, 3))), "b": (("chain",), np.zeros(4))}, {})}
    with pytest.raises(ValueError, match="dimension chain has lengths 2 and 4"):
        write_groups(tmp_path / "bad.nc", bad)
