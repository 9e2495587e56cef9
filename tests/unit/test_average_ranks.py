"""The ranks behind R-hat and the bulk ESS (chain_diagnostics.average_ranks) are scipy's average
ranks exactly: ties (a chain's rejected moves repeat a draw), a constant column, a column with a
NaN (all NaN), one row."""
import numpy as np
import pytest
from scipy.stats import rankdata

from bayesdrag.estimate.bayes.chain_diagnostics import average_ranks


@pytest.mark.parametrize("n, K, decimals", [(1, 3, 2), (7, 1, 0), (500, 6, 1), (2000, 11, 3)])
def test_average_ranks_are_scipys(n, K, decimals):
    rng = np.random.default_rng(n + K)
    a = np.round(rng.normal(size=(n, K)), decimals)
    a[:, 0] = 0.25                                   # one value throughout: rank (n + 1) / 2
    np.testing.assert_array_equal(average_ranks(a), rankdata(a, axis=0, method="average"))


def test_a_column_with_nan_ranks_nan_and_the_others_are_untouched():
    rng = np.random.default_rng(2)
    a = np.round(rng.normal(size=(300, 4)), 1)
    a[17, 2] = np.nan
    r = average_ranks(a)
    assert np.all(np.isnan(r[:, 2]))
    keep = [0, 1, 3]
    np.testing.assert_array_equal(r[:, keep], rankdata(a[:, keep], axis=0, method="average"))
