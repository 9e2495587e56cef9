"""``bayesdrag batch``: rounds as Dask tasks on a LocalCluster, failing rounds reported, finished
rounds skipped, a killed batch resumed with identical results."""
import dataclasses
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from bayesdrag.options import FitOptions

from bayesdrag.commands.batch import WORKER_ENV, fingerprint, job_done, marker_path, round_task, run_campaign
from bayesdrag.campaign.synthetic import simulate_campaign
from bayesdrag.io.campaign import write_campaign
from bayesdrag.cli import main

#: how long the kill test waits for the first finished round before giving up [s]
FIRST_ROUND_TIMEOUT_S = 240


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    d = tmp_path_factory.mktemp("batch")
    path, truth = simulate_campaign(d, n_rounds=2, scatter=0.01, rng=np.random.default_rng(4), dt=0.2)
    # a third round whose track is broken: it must fail alone
    (d / "bad.csv").write_text("t,x,z\n0,0,0\n0.1,nan,1\n")
    write_campaign(d / "with_bad.toml", "two good rounds and a bad one",
                   [("r1", d / "r1.csv", d / "r1.toml"), ("bad", d / "bad.csv", d / "r2.toml"),
                    ("r2", d / "r2.csv", d / "r2.toml")])
    return d, path


@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster reached by its address: the ``--scheduler ADDRESS`` code path."""
    import logging

    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None, env=dict(WORKER_ENV),
                      silence_logs=logging.CRITICAL) as c:
        yield c


def test_batch_reports_the_failing_round_and_pools_the_others(campaign, cluster, capsys):
    d, _ = campaign
    out = d / "out"
    code = main(["batch", str(d / "with_bad.toml"), "-o", str(out), "--scheduler", cluster.scheduler_address,
                 "--no-mcmc", "--drag", "reference-scale", "--quiet"])
    cap = capsys.readouterr()
    assert code == 1
    assert "round bad (fit) failed" in cap.err and "bad.csv" in cap.err
    assert "2 jobs run, 0 skipped" in cap.out and "1 failed" in cap.out
    doc = json.loads((out / "campaign.json").read_text())
    assert doc["rounds"] == ["r1", "r2"]
    assert doc["failed"][0]["name"] == "bad"
    for n in ("r1", "r2"):
        res = json.loads((out / n / "result.json").read_text())
        assert res["drag_model"] == "reference-scale" and res["ml"]["converged"]
        assert marker_path(out / n, "fit").is_file()
    assert not marker_path(out / "bad", "fit").exists()


def test_worker_processes_run_one_numba_thread(cluster):
    from distributed import Client

    def probe():
        import numba

        import bayesdrag.dynamics.pointmass  # noqa: F401  (imports numba's kernel module)

        return os.getpid(), os.environ.get("NUMBA_NUM_THREADS"), numba.get_num_threads()

    with Client(cluster.scheduler_address) as client:
        pid, env, threads = client.submit(probe, pure=False).result()
    assert pid != os.getpid() and env == "1" and threads == 1


def test_changed_inputs_or_options_are_redone_not_skipped(campaign, tmp_path):
    d, _ = campaign
    out = tmp_path / "r1"
    opts = FitOptions(mcmc=False, drag="reference-scale")
    rep = round_task("r1", str(d / "r1.csv"), str(d / "r1.toml"), str(out), options=opts)
    assert rep["jobs"]["fit"]["status"] == "done"
    assert round_task("r1", str(d / "r1.csv"), str(d / "r1.toml"), str(out), options=opts)["jobs"]["fit"]["status"] \
        == "skipped"
    fp = fingerprint(str(d / "r1.csv"), str(d / "r1.toml"), "fit", opts)
    assert job_done(out, "fit", fp)
    assert not job_done(out, "fit", fingerprint(str(d / "r1.csv"), str(d / "r1.toml"), "fit", dataclasses.replace(opts, drag="spline")))
    # the same track with one sample changed is another input
    track2 = tmp_path / "r1_changed.csv"
    lines = (d / "r1.csv").read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if ln and ln[0].isdigit()) + 5
    parts = lines[i].split(",")
    parts[1] = f"{float(parts[1]) + 0.5:.3f}"
    lines[i] = ",".join(parts)
    track2.write_text("\n".join(lines) + "\n")
    assert not job_done(out, "fit", fingerprint(str(track2), str(d / "r1.toml"), "fit", opts))
    rep = round_task("r1", str(track2), str(d / "r1.toml"), str(out), options=opts)
    assert rep["jobs"]["fit"]["status"] == "done"


def test_unknown_job_is_exit_2(campaign, capsys):
    d, path = campaign
    assert main(["batch", str(path), "-o", str(d / "x"), "--jobs", "fit,plot"]) == 2
    assert "use a non-empty subset of fit, diagnose" in capsys.readouterr().err


def test_killed_batch_resumes_without_redoing_finished_rounds(tmp_path):
    """Kill a batch (process group: the CLI and its Dask workers) after its first round is
    done; rerun: finished rounds are skipped (files untouched) and the campaign equals an
    uninterrupted run's."""
    path, _ = simulate_campaign(tmp_path / "c", n_rounds=3, scatter=0.01, rng=np.random.default_rng(9), dt=0.2)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "bayesdrag.cli", "batch", str(path), "-o", str(out), "--workers", "1",
           "--no-mcmc", "--drag", "reference-scale", "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
    t0 = time.monotonic()
    markers = [marker_path(out / f"r{i}", "fit") for i in (1, 2, 3)]
    try:
        while not any(m.exists() for m in markers):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() - t0 < FIRST_ROUND_TIMEOUT_S, "no round finished in time"
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
    done_at_kill = [m.parent.name for m in markers if m.exists()]
    assert 1 <= len(done_at_kill) < 3, f"the kill was not mid-way: {done_at_kill}"
    assert not (out / "campaign.json").exists()
    stamp = {n: {f.name: f.stat().st_mtime_ns for f in (out / n).iterdir()} for n in done_at_kill}
    saved = {n: (out / n / "result.json").read_text() for n in done_at_kill}

    # without --quiet: its summary line on stdout (-q prints nothing there on success)
    res = subprocess.run([c for c in cmd if c != "--quiet"], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert f"{3 - len(done_at_kill)} jobs run, {len(done_at_kill)} skipped" in res.stdout
    for n in done_at_kill:  # not redone: same files, same modification times
        assert {f.name: f.stat().st_mtime_ns for f in (out / n).iterdir()} == stamp[n]
        assert (out / n / "result.json").read_text() == saved[n]
    # identical to an uninterrupted run of the same campaign (in this process, no Dask)
    ref = run_campaign(path, tmp_path / "ref", jobs=("fit",), options=FitOptions(mcmc=False, drag="reference-scale"),
                       executor="sequential",
                       quiet=True, echo=lambda *a: None)
    a = json.loads((out / "campaign.json").read_text())
    b = ref["campaign"]
    assert a["rounds"] == b["rounds"]
    np.testing.assert_allclose([r["mean"] for r in a["cd"]], [r["mean"] for r in b["cd"]], rtol=1e-9)
    np.testing.assert_allclose([a["scatter"][k] for k in ("q05", "q95")], [b["scatter"][k] for k in ("q05", "q95")],
                               rtol=1e-9)
    for n in ("r1", "r2", "r3"):
        ra = json.loads((out / n / "result.json").read_text())["ml"]["params"]
        rb = json.loads((tmp_path / "ref" / n / "result.json").read_text())["ml"]["params"]
        np.testing.assert_allclose(list(ra.values()), list(rb.values()), rtol=1e-9)
