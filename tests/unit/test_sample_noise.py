"""Per-sample noise (issue 28, docs/radar.md): a ``sigma_<channel>`` or ``snr`` column gives each
sample its own noise sd; the fit weights each sample by it, its residuals standardised by it are
white with one sd per channel, and the bound is the one of the samples' own noise."""
import math

import numpy as np
import pytest

from bayesdrag.errors import InputError
from bayesdrag.estimate.model.problem import OutputErrorProblem
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.drag import ReferenceScale
from bayesdrag.io.tracks import read_track, write_track
from bayesdrag.measure import sample_noise
from bayesdrag.measure.sample_noise import SCALE_MAX, SCALE_MIN
from bayesdrag.track import RadarTrack

#: relative agreement of computed and exact scales
EXACT = 1e-12
#: the standardised residuals' sd in each half of the track, against 1 (N ~ 150 per half: 3 se)
SD_TOL = 0.2
#: bound ratio against the information of the samples' own noise (linearisation at the fit)
CRB_REL = 0.02


def test_snr_gives_sd_proportional_to_one_over_root_snr():
    t = np.arange(5.0)
    snr = np.array([30.0, 24.0, 30.0, 36.0, 30.0])
    tr = RadarTrack(t, {"range_rate": np.linspace(800, 700, 5)}, {"snr": snr})
    scale, level = sample_noise(tr, ("range_rate",))
    # 6 dB less power is twice the sd: sd ~ 1 / sqrt(SNR linear)
    assert scale[:, 0] == pytest.approx([1.0, 10 ** (6 / 20), 1.0, 10 ** (-6 / 20), 1.0], rel=EXACT)
    assert level == {}
    assert sample_noise(RadarTrack(t, {"v": np.linspace(800, 700, 5)}), ("v",)) == (None, {})


def test_sigma_column_gives_shape_and_level_and_wins_over_snr():
    t = np.arange(4.0)
    sd = np.array([0.1, 0.2, 0.1, 1e3])
    tr = RadarTrack(t, {"range_rate": np.linspace(800, 700, 4), "range": np.linspace(100, 400, 4)},
                    {"sigma_range_rate": sd, "snr": np.array([10.0, 10.0, 10.0, 40.0])})
    scale, level = sample_noise(tr, ("range", "range_rate"))
    assert level == {"range_rate": pytest.approx(0.15)}
    assert scale[:, 1] == pytest.approx(sd / 0.15, rel=EXACT)                  # as given, never clipped
    assert scale[:, 0] == pytest.approx([1.0, 1.0, 1.0, SCALE_MIN])   # 30 dB above the median: clipped


def test_csv_round_trip_and_bad_values(tmp_path):
    t = np.linspace(0.0, 1.0, 5)
    tr = RadarTrack(t, {"range": np.linspace(100, 900, 5), "elevation": np.radians(np.linspace(10, 20, 5))},
                    {"sigma_elevation": np.radians(np.full(5, 0.03)), "snr": np.full(5, 20.0)})
    write_track(tmp_path / "a.csv", tr)
    back = read_track(tmp_path / "a.csv")
    assert back.extra["sigma_elevation"] == pytest.approx(np.radians(0.03))   # degrees in the file
    assert any("give each sample's noise" in n for n in back.notes)
    text = (tmp_path / "a.csv").read_text().splitlines()
    head = text[0].split(",")
    j = head.index("sigma_elevation")
    row = text[3].split(",")
    row[j] = "-0.03"
    text[3] = ",".join(row)
    (tmp_path / "b.csv").write_text("\n".join(text) + "\n")
    with pytest.raises(InputError, match=r"b\.csv: line 4: sigma_elevation = -0\.03 deg"):
        read_track(tmp_path / "b.csv")


def test_a_fit_weights_each_sample_by_its_own_noise(m101):
    """A speed track whose second half is 10x noisier than its first: with the ``sigma_v``
    column the standardised residuals at the truth are white with sd 1 in both halves, and the
    bound of the scale of Cd is the weighted one (smaller than the bound of the same track fitted
    with one sd, which the noisy half sets)."""
    model = PointMassModel(42.6, 0.155, ReferenceScale(m101))
    s0 = initial_state(818.0, 15.0)
    t = np.arange(0.05, 20.0, 0.05)
    truth = model.simulate_batch(np.array([[1.0]]), s0[None], t, t_start=0.0).state[0]
    v = np.linalg.norm(truth[:, 3:], axis=1)
    sd = np.where(t < 10.0, 0.1, 1.0)
    rng = np.random.default_rng(28)
    z = v + sd * rng.standard_normal(t.size)
    weighted = RadarTrack(t, {"v": z}, {"sigma_v": sd})
    plain = RadarTrack(t, {"v": z})
    theta = np.concatenate([[1.0], s0])
    free = np.array([True] + [False] * 6)
    pw = OutputErrorProblem(model, weighted, theta, free=free, t_ic=0.0)
    assert pw.sigma_fixed == {"v": pytest.approx(float(np.median(sd)))}
    y, _ = pw.predict(theta[None])
    e = pw.weighted(pw.z - y[0], pw.sigma_fixed)[:, 0]
    for half in (t < 10.0, t >= 10.0):
        assert abs(float(np.std(e[half])) - 1.0) < SD_TOL
    rw = pw.fit()
    rp = OutputErrorProblem(model, plain, theta, free=free, t_ic=0.0).fit()
    assert abs(rw.theta[0] - 1.0) < 3 * rw.crb[0]
    # information sum S_i^2 / sd_i^2 of the samples' own noise, against sum S_i^2 / s^2 of one
    # sd s (the plain fit's residual rms)
    S = pw.sensitivities(theta)[2][:, 0, 0]
    ratio_info = float(np.sum(S ** 2 / sd ** 2) / np.sum(S ** 2 / rp.sigma["v"] ** 2))
    assert rp.crb[0] / rw.crb[0] == pytest.approx(math.sqrt(ratio_info), rel=CRB_REL)
    assert rw.crb[0] < 0.5 * rp.crb[0]
