"""The one-sided contamination model's test and mixture on plain residual series
(bayesdrag.estimate.model.contamination): Gaussian noise does not engage it, a one-sided tail of a
few sd does, a symmetric one (gross outliers of both signs) or a smooth misfit does not, and the
mixture finds the share and side of the tail it was given."""
import numpy as np
import pytest

from bayesdrag.estimate.model.contamination import (ASYMMETRY_LR, ONE_SIDED_LR, fit_contamination,
                                                    one_sided_evidence)

#: Gaussian series tried, and how many of them may engage the model (measured: 0 of 600)
GAUSS_SERIES, GAUSS_ENGAGED_MAX = 60, 0
#: samples per series
N = 200


def _one_sided(rng, share=0.10, lo=2.0, hi=6.0, n=N):
    u = rng.standard_normal(n)
    idx = rng.choice(np.arange(n // 2, n), int(share * n), replace=False)
    u[idx] += rng.uniform(lo, hi, idx.size)
    return u, idx


def test_gaussian_noise_does_not_engage_it():
    rng = np.random.default_rng(28)
    engaged = sum(one_sided_evidence(rng.standard_normal(N))["engaged"] for _ in range(GAUSS_SERIES))
    assert engaged <= GAUSS_ENGAGED_MAX


@pytest.mark.parametrize("share,lo,hi", [(0.10, 2.0, 6.0), (0.05, 3.0, 8.0), (0.15, 2.0, 12.0)])
def test_late_high_outliers_engage_it_on_the_high_side(share, lo, hi):
    rng = np.random.default_rng(2801)
    u, _ = _one_sided(rng, share, lo, hi)
    ev = one_sided_evidence(u)
    assert ev["engaged"], ev
    assert ev["side"] == "high"
    assert ev["lr"] > ONE_SIDED_LR and ev["lr_asymmetry"] > ASYMMETRY_LR


def test_low_outliers_engage_it_on_the_low_side():
    u, _ = _one_sided(np.random.default_rng(2802), 0.10, 3.0, 8.0)
    ev = one_sided_evidence(-u)
    assert ev["engaged"] and ev["side"] == "low"


def test_gross_outliers_of_both_signs_do_not_engage_it():
    rng = np.random.default_rng(2803)
    u = rng.standard_normal(N)
    idx = rng.choice(N, 10, replace=False)
    u[idx] += 15.0 * np.tile([1.0, -1.0], 5)
    ev = one_sided_evidence(u)
    assert ev["lr"] > ONE_SIDED_LR          # a tail there is ...
    assert not ev["engaged"], ev            # ... but not a one-sided one


def test_a_smooth_misfit_is_not_taken_for_outliers():
    rng = np.random.default_rng(2804)
    t = np.linspace(0.0, 1.0, N)
    u = rng.standard_normal(N) + 8.0 * np.exp(-((t - 0.3) / 0.08) ** 2)   # a residual bump: model error
    ev = one_sided_evidence(u)
    assert not ev["engaged"]
    assert "structured" in ev.get("skipped", "")


#: the tail's mean offset in the mixture's own-form test [sd]
TAIL_MEAN = 5.0


def test_the_mixture_finds_the_share_of_a_tail_of_its_own_form():
    """Offsets exponential of mean TAIL_MEAN sd: the fitted fraction is the tail's share within a
    few binomial sd, its mean offset within 25 %, and the samples the mixture gives most of their
    weight away are mostly moved ones."""
    rng = np.random.default_rng(2805)
    share, n = 0.10, 1000
    u = rng.standard_normal(n)
    idx = rng.choice(n, int(share * n), replace=False)
    u[idx] += rng.exponential(TAIL_MEAN, idx.size)
    mix = fit_contamination(u, "high", location=True)
    assert abs(mix.tail_sd[0] / TAIL_MEAN - 1.0) < 0.25
    assert mix.fraction[1] == 0.0
    assert abs(mix.fraction[0] - share) < 3.0 * np.sqrt(share * (1 - share) / u.size) + 0.01
    down = np.flatnonzero(mix.weights < 0.5)
    assert np.isin(down, idx).mean() > 0.9


def test_an_unknown_form_is_refused():
    with pytest.raises(ValueError, match="contamination form 'both' is not known"):
        fit_contamination(np.zeros(50), "both")
