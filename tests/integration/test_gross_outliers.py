"""Gross outliers as the model check counts them (:func:`bayesdrag.pipeline.model_check.gross_outliers`):
a sample must stand out of the track's local scale *and* of the fit's residuals. A Doppler radar
10 m behind a mortar sees the range rate rise from ~130 to ~280 m/s in its first samples; the
track's local smoother cannot follow that bend and flagged them, which started a Student-t check
that widened every band (a 105 mm shell's Doppler track beside the gun: 2 % of the span
determined). The fit flies that geometry, so its residuals there are noise."""
import sys
from pathlib import Path

import numpy as np

from bayesdrag.estimate.model.noise import noise_and_outliers
from bayesdrag.estimate.scheme1.fit import fit_scheme1
from bayesdrag.pipeline.model_check import gross_outliers
from bayesdrag.track import RadarTrack

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "acceptance"))
import run_native as rn  # noqa: E402

#: planted spikes [noise sd]: far beyond any Gaussian sample of a track this long
SPIKE_SD = 15.0
#: samples that get one (away from the track's ends)
SPIKED = (120, 300, 610)


def test_the_radars_fast_view_near_the_gun_is_no_outlier():
    track, rnd, _ = rn.make(rn.case_by_id("dop-120-qe60-behind"))
    _, _, flags = noise_and_outliers(track, track.names, rnd.radar.sigma)
    assert flags[:10].any(), "the track's own scale flags the first samples (the case this guards)"
    f1 = fit_scheme1(track, rnd)
    assert gross_outliers(track, f1, rnd.radar.sigma) == 0


def test_planted_spikes_are_still_counted():
    track, rnd, _ = rn.make(rn.case_by_id("dop-120-qe60-behind"))
    rr = np.array(track.channels["range_rate"], float)
    rr[list(SPIKED)] += SPIKE_SD * rnd.radar.sigma["range_rate"]
    spiked = RadarTrack(track.t, {"range_rate": rr}, {}, "spiked.csv")
    f1 = fit_scheme1(spiked, rnd)
    assert gross_outliers(spiked, f1, rnd.radar.sigma) == len(SPIKED)
