"""What the figures of an ML fit show (issue 47, item 6): the relative Cd panel exists after an ML
fit, where a 0.1 % band is visible; the budget's total is drawn above the sources it equals."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import bayesdrag

#: the band must fill at least this share of the relative panel's height where Cd is best known
VISIBLE_SHARE = 0.02


@pytest.fixture(scope="module")
def ml_fit(tmp_path_factory):
    """An ML fit of a 155 mm flight of the independent integrator (tests/fixtures/met_flight.py)."""
    from fixtures import met_flight as M

    tp, rp = M.write_icao_case(tmp_path_factory.mktemp("figures"), seed=8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return bayesdrag.fit(bayesdrag.read_track(tp), bayesdrag.read_round(rp), mcmc=False, model_check=False)


def test_the_ml_band_is_visible_relative(ml_fit):
    rel_sd = np.nanmin(ml_fit.cd.sd / ml_fit.cd.ml)
    assert rel_sd < 0.002                                       # a band invisible at full scale
    ax = ml_fit.plot_cd_relative()
    band = next(c for c in ax.collections if c.get_label() == "90% band")
    ys = band.get_paths()[0].vertices[:, 1]
    lo, hi = ax.get_ylim()
    assert 100 * 2 * 1.645 * rel_sd / (hi - lo) > VISIBLE_SHARE
    assert ys.min() >= lo and ys.max() <= hi
    assert ax.get_ylabel() == "Cd vs the table [%]"


def test_the_budget_total_is_drawn_above_the_sources(ml_fit):
    ax = ml_fit.plot_budget()
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    total = lines["total (the band the rows report)"]
    assert all(total.get_zorder() > ln.get_zorder() for k, ln in lines.items() if not k.startswith("total"))
