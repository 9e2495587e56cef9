"""The diagnosis's chi2 quantile (bayesdrag.diagnosis.statistics.chi2_quantile): the numbers of
scipy.stats.chi2.ppf bit for bit, without importing scipy.stats, which every forked diagnosis
paid for (0.35-0.65 s of its time)."""
import math
import re
import statistics
import subprocess
import sys
from pathlib import Path

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


@pytest.mark.parametrize("k, want", [
    (1, statistics.NormalDist().inv_cdf(0.975) ** 2),     # chi2(1) is a squared standard normal
    (2, -2.0 * math.log(0.05)),                           # chi2(2) is exponential with mean 2
])
def test_known_quantiles_computed_without_scipy(k, want):
    assert chi2_quantile(0.95, k) == pytest.approx(want, abs=1e-12)
    assert chi2_quantile(0.95, np.int64(k)) == chi2_quantile(0.95, k)   # a numpy count, as callers pass


def test_the_diagnosis_imports_no_scipy_stats():
    """A fresh interpreter: the fit's pipeline and the whole diagnosis package load without
    scipy.stats (a forked diagnosis would import it on every fit)."""
    code = ("import sys\nimport bayesdrag.pipeline, bayesdrag.pipeline.model_check, bayesdrag.diagnosis\n"
            "print('scipy.stats' in sys.modules)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "False"


def test_no_diagnosis_source_imports_scipy_stats_anywhere():
    """An import inside a function would escape the test above and still cost every forked
    diagnosis: no line of the diagnosis package or of the check imports scipy.stats."""
    import bayesdrag

    root = Path(bayesdrag.__file__).parent
    files = sorted((root / "diagnosis").glob("*.py")) + [root / "pipeline" / "model_check.py",
                                                         root / "pipeline" / "check.py"]
    pattern = re.compile(r"^\s*(from\s+scipy\.stats\b|import\s+scipy\.stats\b|from\s+scipy\s+import\s+.*\bstats\b)",
                         re.MULTILINE)
    found = [f"{f.name}: {m.group(0).strip()}" for f in files for m in pattern.finditer(f.read_text())]
    assert len(files) > 10 and found == []
