"""Write the example LabRadar track export ``Shot0001 Track.csv`` (a simulated 6.5 mm bullet).

The bullet and its drag are the Warner 6.5 mm Flatline round (``examples/warner/65_flatline``);
the point-mass track is sampled every ~2.5 ms with jitter for 0.35 s (~300 m, where a LabRadar
typically loses a rifle bullet), velocity noise 0.15 m/s at the median SNR (sd ~ 1/sqrt(SNR)), written in LabRadar's layout and units
(fps, yd). Run from anywhere: ``python3 examples/radar_export/make_example.py``.
"""
from pathlib import Path

import numpy as np

from bayesdrag.synthetic import simulate_round
from bayesdrag.io.rounds import read_round
from bayesdrag.measure.sample_noise import SCALE_MAX, SCALE_MIN

HERE = Path(__file__).resolve().parent


def main(seed=1):
    rng = np.random.default_rng(seed)
    rnd = read_round(HERE / "round.toml")
    tr = simulate_round(rnd, dt=0.0005)
    keep = tr.t <= 0.35
    t_all, v_all = tr.t[keep], tr.v[keep]
    r_all = np.hypot(tr.x[keep], tr.z[keep])
    t_s = np.cumsum(0.0025 * (0.8 + 0.4 * rng.random(200))) + 0.0045
    t_s = t_s[t_s <= 0.35]
    e = rng.standard_normal(t_s.size)
    r = np.interp(t_s, t_all, r_all)
    snr = 48.0 - 20 * np.log10(np.maximum(r, 5.0) / 5.0) + rng.normal(0, 1.0, t_s.size)
    # the noise follows the echo: sd ~ 1/sqrt(SNR), 0.15 m/s at the median SNR (docs/radar.md)
    scale = np.clip(10 ** ((np.median(snr) - snr) / 20), SCALE_MIN, SCALE_MAX)
    v = np.interp(t_s, t_all, v_all) + 0.15 * scale * e
    lines = ["sep=;", "Device ID;LBR-0000042;;", "", "Series No;0001;;", "Shot No;0001;;", "",
             "Units velocity;fps;;", "Units distances;yd;;", "", "Time (s);Vel (fps);Dist (yd);SNR",
             f"0.000000;{tr.v[0] / 0.3048:.2f};0.00;-"]
    lines += [f"{a:.6f};{b / 0.3048:.2f};{c / 0.9144:.2f};{d:.2f}" for a, b, c, d in zip(t_s, v, r, snr)]
    (HERE / "Shot0001 Track.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
