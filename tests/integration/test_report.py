"""`bayesdrag fit` with sampling: result.json with the posterior part, posterior.nc readable by
ArviZ, a self-contained report.html (every figure embedded), and kill + --resume."""
import base64
import json
import os
import signal
import subprocess
import sys
from html.parser import HTMLParser

import numpy as np
import pytest

from bayesdrag.cli import main
from fixtures.shell155 import write_shell155_inputs

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def inputs(tmp_path_factory, m101):
    """A 12 s point-mass track (M101 truth, noise) and its round file."""
    return write_shell155_inputs(tmp_path_factory.mktemp("inputs"), m101, elevation=15.0, seconds=12.0, seed=1)


@pytest.fixture(scope="module")
def fitted(inputs, tmp_path_factory):
    track, rnd = inputs
    out = tmp_path_factory.mktemp("fit") / "out"
    code = main(["fit", str(track), str(rnd), "-o", str(out), "--drag", "reference-scale", "--seed", "4",
                 "--quiet"])
    assert code == 0
    return out


class _Images(HTMLParser):
    def __init__(self):
        super().__init__()
        self.imgs, self.links = [], []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.imgs.append(a.get("src", ""))
        for k in ("href", "src"):
            if k in a and tag != "img":
                self.links.append(a[k])


def test_result_json_has_posterior_part(fitted):
    r = json.loads((fitted / "result.json").read_text())
    for k in ("mean", "sd", "r_hat", "ess_bulk"):
        assert set(r["posterior"][k]) >= {"factor", "Ux0", "log_sigma_v"}
    assert r["mcmc"]["converged"] and max(r["posterior"]["r_hat"].values()) < 1.01
    for row in r["cd"]:
        assert row["q05"] <= row["mean"] <= row["q95"]
        assert row["sd_over_crb"] > 0
    # the factor times M101 is the truth: factor's 90 % interval holds 1
    assert r["posterior"]["q05"]["factor"] <= 1.0 <= r["posterior"]["q95"]["factor"]


def test_posterior_nc_opens_with_arviz(fitted):
    import arviz as az

    idata = az.from_netcdf(str(fitted / "posterior.nc"))
    s = az.summary(idata, round_to="none")
    assert "drag_coefficients[factor]" in s.index and s["r_hat"].max() < 1.01
    # the Cd curve over a mach dim, the coefficients as one vector (the file format)
    assert idata.posterior["cd"].dims == ("chain", "draw", "mach")
    assert idata.posterior["drag_coefficients"].dims == ("chain", "draw", "coefficient")
    assert {"posterior", "sample_stats", "observed_data", "constant_data",
            "posterior_predictive"} <= set(idata.groups())


def test_report_is_self_contained_with_every_figure(fitted):
    html = (fitted / "report.html").read_text()
    p = _Images()
    p.feed(html)
    pngs = sorted(f.name for f in fitted.glob("*.png"))
    assert len(p.imgs) == len(pngs) >= 5
    for src in p.imgs:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == PNG_MAGIC
    assert not [u for u in p.links if u.startswith(("http", "//", "file:"))]   # opens offline
    for needle in ("Convergence", "Cramér-Rao", "Posterior summary (ArviZ)", "Versions", "emcee"):
        assert needle in html


def test_fresh_run_refuses_to_overwrite_an_unfinished_chain(inputs, tmp_path, capsys):
    track, rnd = inputs
    out = tmp_path / "o"
    out.mkdir()
    (out / "chain.partial.h5").write_bytes(b"x")
    code = main(["fit", str(track), str(rnd), "-o", str(out), "--drag", "reference-scale", "--quiet"])
    assert code == 2
    assert "--resume" in capsys.readouterr().err
    assert (out / "chain.partial.h5").read_bytes() == b"x"


def test_kill_and_resume_gives_the_full_chain(inputs, tmp_path):
    """SIGKILL a fit mid-way (after its first chain checkpoint), rerun with --resume: it
    continues from the checkpoint and the final chain equals an uninterrupted run's."""
    import h5py

    track, rnd = inputs
    args = ["fit", str(track), str(rnd), "--drag", "reference-scale", "--seed", "9", "--walkers", "16"]
    cmd = [sys.executable, "-m", "bayesdrag.cli"]
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    killed = tmp_path / "killed"
    p = subprocess.Popen(cmd + args + ["-o", str(killed)], stderr=subprocess.PIPE, stdout=subprocess.DEVNULL,
                         text=True, env=env)
    try:
        for line in p.stderr:
            if line.startswith("mcmc:"):       # a checkpoint has been written
                p.send_signal(signal.SIGKILL)
                break
    finally:
        p.wait(timeout=300)
    assert p.returncode == -signal.SIGKILL
    partial = killed / "chain.partial.h5"
    with h5py.File(partial, "r") as f:
        n_killed = int(f["mcmc"].attrs["iteration"])
    assert n_killed > 0 and not (killed / "chain.h5").exists()
    r = subprocess.run(cmd + args + ["-o", str(killed), "--resume", "--quiet"], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    whole = tmp_path / "whole"
    r2 = subprocess.run(cmd + args + ["-o", str(whole), "--quiet"], capture_output=True, text=True, timeout=600)
    assert r2.returncode == 0, r2.stderr
    res_k = json.loads((killed / "result.json").read_text())["mcmc"]
    res_w = json.loads((whole / "result.json").read_text())["mcmc"]
    assert res_k["resumed_from"] == n_killed and res_w["resumed_from"] == 0
    assert res_k["steps"] == res_w["steps"] > n_killed
    with h5py.File(killed / "chain.h5", "r") as a, h5py.File(whole / "chain.h5", "r") as b:
        assert np.array_equal(a["mcmc/chain"][:], b["mcmc/chain"][:])


def test_scheme2_samples_every_window(inputs, tmp_path):
    """--scheme 2: every window gets a posterior (Cd, initial state, noise); result.json
    'windows' rows carry mean/q05/q95 next to ML and CRB; the report embeds the windows figure."""
    import arviz as az

    track, rnd = inputs
    out = tmp_path / "s2"
    assert main(["fit", str(track), str(rnd), "-o", str(out), "--scheme", "2", "--seed", "1", "--quiet"]) == 0
    r = json.loads((out / "result.json").read_text())
    assert r["scheme"] == 2 and len(r["windows"]) >= 3
    for w in r["windows"]:
        assert w["q05"] <= w["mean"] <= w["q95"] and w["mcmc_converged"] and w["r_hat_max"] < 1.01
        # white noise, constant Cd per window: posterior width near the bound
        assert 0.6 < w["sd_over_crb"] < 1.6
    p = _Images()
    p.feed((out / "report.html").read_text())
    assert len(p.imgs) == 1 and p.imgs[0].startswith("data:image/png;base64,")
    idata = az.from_netcdf(str(out / "posterior.nc"))
    assert idata.posterior["cd"].sizes["window"] == len(r["windows"])


def test_moves_de_option(inputs, tmp_path):
    """--moves de (for posteriors far from Gaussian) samples with emcee's DE mix and 2 D + 2
    walkers and converges on the same problem."""
    track, rnd = inputs
    out = tmp_path / "de"
    assert main(["fit", str(track), str(rnd), "-o", str(out), "--drag", "reference-scale", "--moves", "de",
                 "--seed", "3", "--quiet"]) == 0
    m = json.loads((out / "result.json").read_text())["mcmc"]
    assert m["converged"] and "DEMove" in m["moves"] and m["walkers"] == 2 * 7 + 2
