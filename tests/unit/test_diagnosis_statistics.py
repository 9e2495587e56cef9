"""The diagnosis's chi2 quantile (bayesdrag.diagnosis.statistics.chi2_quantile): the numbers of
scipy.stats.chi2.ppf bit for bit, without importing scipy.stats, which every forked diagnosis
paid for (0.35-0.65 s of its time)."""
import subprocess
import sys

import numpy as np
import pytest
from scipy.stats import chi2

from bayesdrag.diagnosis.statistics import chi2_quantile


def test_the_quantiles_the_diagnosis_uses_are_scipy_s_bit_for_bit():
    # the levels the tests take: 0.95, Bonferroni 1 - alpha / K over up to ~20 candidates and the
    # yaw decay's multiplicity, for 1 to 40 parameters (a drag shape, wind layers)
    levels = [0.95] + [1 - a / K for a in (0.05, 0.05 / 5) for K in range(1, 25)]
    for q in levels:
        for k in range(1, 41):
            assert chi2_quantile(q, k) == chi2.ppf(q, k), (q, k)


def test_random_levels_and_degrees_of_freedom_agree_bit_for_bit():
    rng = np.random.default_rng(11)
    q = 1.0 - 10.0 ** rng.uniform(-10, -0.01, 2000)
    k = rng.integers(1, 80, 2000)
    np.testing.assert_array_equal(chi2_quantile(q, k), chi2.ppf(q, k))
    assert chi2_quantile(1.0, 3) == np.inf and chi2_quantile(0.0, 3) == 0.0


@pytest.mark.parametrize("k", [1, 7])
def test_a_known_quantile(k):
    # chi2 with 1 dof at 0.95: 1.96^2; with 7 dof: 14.067 (tables), within 1e-3 absolute
    want = {1: 1.959963984540054 ** 2, 7: 14.067140449340169}[k]
    assert chi2_quantile(0.95, k) == pytest.approx(want, abs=1e-9)


def test_the_diagnosis_imports_no_scipy_stats():
    """A fresh interpreter: the fit's pipeline and the whole diagnosis package load without
    scipy.stats (a forked diagnosis would import it on every fit)."""
    code = ("import sys\nimport bayesdrag.pipeline, bayesdrag.pipeline.model_check, bayesdrag.diagnosis\n"
            "print('scipy.stats' in sys.modules)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "False"
