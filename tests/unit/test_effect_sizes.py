"""The split-consistency part of an added effect's sd (bayesdrag.estimate.scheme1.effect_sizes)."""
import math

import pytest

from bayesdrag.estimate.scheme1.effect_sizes import split_excess


def test_a_part_that_differs_by_its_own_noise_adds_nothing():
    # whole 2.0 +- 1.0; a part 2.0 +- sqrt(5) away by exactly its extra noise sd 2: no excess
    assert split_excess(2.0, 1.0, [(4.0, math.sqrt(5.0))]) == pytest.approx(0.0, abs=1e-12)


def test_a_part_beyond_its_noise_gives_the_excess_variance_averaged_over_parts():
    # part 1: difference 3 with no extra noise -> 9; part 2: difference 1, extra variance 3 -> 0
    assert split_excess(0.0, 1.0, [(3.0, 1.0), (1.0, 2.0)]) == pytest.approx(4.5, rel=1e-12)
    # a part with a smaller sd than the whole (a chance of the fit) is taken as adding no noise
    assert split_excess(0.0, 1.0, [(2.0, 0.5)]) == pytest.approx(4.0, rel=1e-12)


def test_no_parts_no_excess():
    assert split_excess(1.0, 1.0, []) is None
    assert split_excess(1.0, 1.0, [(float("nan"), 1.0)]) is None
