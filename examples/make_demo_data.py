"""Regenerate the demo track shipped in the package (bayesdrag/data/demo_track.csv).

The paper's Table 1 shell fired at 818 m/s, QE 15 deg, flown by the 6-DOF model
(bayesdrag.dynamics.sixdof: M101 zero-yaw drag, M107-like aerodynamics, 1/20 twist, standard
atmosphere, no wind), sampled every 0.027 s to impact, with Gaussian radar noise of the
round's [radar] sigma (1 m in x, y, z; 0.3 m/s in v), seed 101.

    python examples/make_demo_data.py
"""
from importlib.resources import files

import numpy as np

from bayesdrag.synthetic import add_noise, simulate_round
from bayesdrag.io.rounds import read_round
from bayesdrag.io.tracks import write_track


def main():
    data = files("bayesdrag") / "data"
    rnd = read_round(data / "demo_round.toml")
    clean = simulate_round(rnd, model="6dof", dt=0.027)
    noisy = add_noise(clean, rnd.radar.sigma, np.random.default_rng(101))
    write_track(data / "demo_track.csv", noisy,
                comment="bayesdrag demo track: 6-DOF, paper Table 1 shell, M101 drag, 818 m/s, "
                        "QE 15 deg, dt 0.027 s, noise sigma x,y,z 1 m, v 0.3 m/s, seed 101 "
                        "(examples/make_demo_data.py)")
    print(f"wrote {data / 'demo_track.csv'}: {noisy.n} samples")


if __name__ == "__main__":
    main()
