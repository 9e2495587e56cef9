"""``--resume`` refuses a chain with some of its stored positions forged (issue 44, item 9).

The review: the resume check recomputed the log posterior at 8 random stored positions, so a
chain with 5 % of its positions forged was accepted in 10 of 12 tries and moved the posterior
mean by 23 posterior sd. The check now recomputes :data:`LOG_PROB_SAMPLE` = 688 positions (all
of them when the chain holds fewer), the least number that catches a corruption of 1 % of the
positions with probability >= 0.999, batched through the vectorised log posterior.

The chains are written by :class:`~bayesdrag.io.chain.ChainBackend` while emcee runs: a toy
posterior for the sampling arguments (a demo-size chain, 16 walkers x 400 steps, in well under a
second), and the demo round's own posterior for the command line. The positions checked are
drawn with seeded generators, so each test is deterministic.
"""
import math
import shutil
from importlib.resources import files

import emcee
import h5py
import numpy as np
import pytest

from bayesdrag.cli import main
from bayesdrag.errors import InputError
from bayesdrag.io.chain import ChainFile

#: walkers and steps of a demo-size chain (the demo's sampler converges in ~375 steps of 16)
W, D, STEPS = 16, 3, 400
FP = "0123abcd"
#: seeds of the generators drawing the checked positions (each is one resume)
SEEDS = range(20)
#: what a forger does to a position: the review moved every forged position by 5 %
SHIFT = 1.05
#: the refusal of a forged chain
REFUSED = (r"chain\.partial\.h5: the stored (log posterior|blob \d) at step \d+, walker \d+ is .*, the posterior of "
           r"these inputs gives .* at that position: not a chain this run made; delete it to start the chain afresh")


def toy(X):
    """Log posterior (standard normal) and one blob (the sum) of positions (m, D)."""
    X = np.atleast_2d(X)
    return np.column_stack([-0.5 * np.sum(X ** 2, axis=1), np.sum(X, axis=1)])


def _chain(path, walkers=W, steps=STEPS):
    cf = ChainFile(path, flush_every=25)
    backend = cf.new_backend(walkers, D, fingerprint=FP)
    sampler = emcee.EnsembleSampler(walkers, D, toy, vectorize=True, backend=backend, blobs_dtype=float)
    sampler.run_mcmc(np.random.default_rng(1).normal(size=(walkers, D)), steps, progress=False)
    backend.flush()
    return cf


@pytest.fixture(scope="module")
def genuine(tmp_path_factory):
    """A genuine demo-size chain file (copied by each test that forges it)."""
    return _chain(tmp_path_factory.mktemp("chain") / "chain.partial.h5").path


def _load(path, seed, walkers=W, log_prob=toy):
    return ChainFile(path).load_backend(nwalkers=walkers, ndim=D, nblobs=1, fingerprint=FP, log_prob=log_prob,
                                        rng=np.random.default_rng(seed))


def _forge(path, fraction=None, count=None, rng=None):
    """Move ``fraction`` (or ``count``) of the chain's earlier positions (not its last row, which
    is always checked) by :data:`SHIFT`, their stored log posterior left as it was; returns how
    many were forged."""
    rng = np.random.default_rng(11) if rng is None else rng
    with h5py.File(path, "a") as f:
        chain = f["mcmc/chain"][()]
        S, Wn, _ = chain.shape
        earlier = (S - 1) * Wn
        k = count if count is not None else int(round(fraction * earlier))
        pick = rng.choice(earlier, size=k, replace=False)
        chain[pick // Wn, pick % Wn] *= SHIFT
        f["mcmc/chain"][...] = chain
    return k


# ------------------------------------------------------------------------------------------------
# the sample size
def test_the_sample_size_catches_one_percent_corrupted_with_probability_0999():
    """n = 688 is the least n with (1 - 0.01)^n <= 1e-3; drawn without replacement from a
    demo-size chain, the chance of missing every corrupted position is smaller still."""
    from bayesdrag.io.chain import LOG_PROB_CORRUPT_FRACTION, LOG_PROB_MISS, LOG_PROB_SAMPLE, check_sample_size

    assert (LOG_PROB_CORRUPT_FRACTION, LOG_PROB_MISS) == (0.01, 1e-3)
    n = check_sample_size()
    assert n == LOG_PROB_SAMPLE == 688
    assert (1 - 0.01) ** n <= 1e-3 < (1 - 0.01) ** (n - 1)
    assert n == math.ceil(math.log(1e-3) / math.log(1 - 0.01))
    # without replacement: P(miss) = C(N - k, n) / C(N, n), exactly, for the positions a resume draws from
    N = (STEPS - 1) * W
    k = math.ceil(0.01 * N)
    miss = math.comb(N - k, n) / math.comb(N, n)
    assert miss <= (1 - k / N) ** n <= 1e-3
    # 5 % corrupted: missed with probability ~1e-15; the old 8 positions missed it 2 times in 3
    assert (1 - 0.05) ** n < 1e-15 and (1 - 0.05) ** 8 > 0.66
    for fraction, miss in ((0.05, 1e-3), (0.01, 1e-6), (0.001, 1e-3)):
        m = check_sample_size(fraction, miss)
        assert (1 - fraction) ** m <= miss < (1 - fraction) ** (m - 1)


# ------------------------------------------------------------------------------------------------
# forged chains are refused, genuine ones resume
@pytest.mark.parametrize("fraction", [0.01, 0.05])
def test_a_chain_with_forged_positions_is_refused_on_every_resume(genuine, tmp_path, fraction):
    """1 % and 5 % of the stored positions forged (the review forged 5 %): refused whichever
    positions are drawn (20 seeded resumes), with one line naming the file."""
    path = tmp_path / "chain.partial.h5"
    shutil.copy(genuine, path)
    assert _forge(path, fraction) == round(fraction * (STEPS - 1) * W)
    for seed in SEEDS:
        with pytest.raises(InputError, match=REFUSED):
            _load(path, seed)


def test_an_unforged_chain_still_resumes_whatever_positions_are_checked(genuine):
    for seed in SEEDS:
        b = _load(genuine, seed)
        assert b.iteration == STEPS and b.chain.shape == (STEPS, W, D)


def test_every_position_is_checked_when_the_chain_holds_fewer(tmp_path):
    """8 walkers x 60 steps hold 472 earlier positions, fewer than 688: all are recomputed, so
    one forged position of 480 is always found (8 drawn of 472 found it 1 time in 59)."""
    path = _chain(tmp_path / "chain.partial.h5", walkers=8, steps=60).path
    calls = []

    def counting(X):
        calls.append(np.array(X))
        return toy(X)

    _load(path, 0, walkers=8, log_prob=counting)
    checked = np.concatenate(calls)
    with h5py.File(path, "r") as f:
        stored = f["mcmc/chain"][()].reshape(-1, D)
    assert checked.shape == stored.shape
    assert np.array_equal(np.unique(checked, axis=0), np.unique(stored, axis=0))
    _forge(path, count=1)
    for seed in SEEDS:
        with pytest.raises(InputError, match=REFUSED):
            _load(path, seed, walkers=8)


def test_the_recomputation_is_batched_through_the_vectorised_posterior(genuine, monkeypatch):
    """One call of the vectorised log posterior per LOG_PROB_BATCH positions: the last row and
    688 earlier stored positions."""
    from bayesdrag.io import chain as chain_module

    calls = []

    def counting(X):
        calls.append(np.array(X))
        return toy(X)

    _load(genuine, 3, log_prob=counting)
    assert [c.shape for c in calls] == [(W + 688, D)]
    monkeypatch.setattr(chain_module, "LOG_PROB_BATCH", 100)
    calls.clear()
    _load(genuine, 3, log_prob=counting)
    assert [len(c) for c in calls] == [100] * 7 + [4]
    X = np.concatenate(calls)
    with h5py.File(genuine, "r") as f:
        stored = f["mcmc/chain"][()]
    np.testing.assert_array_equal(X[:W], stored[-1])
    earlier = {tuple(x) for x in stored[:-1].reshape(-1, D)}
    assert all(tuple(x) in earlier for x in X[W:])      # stored positions (a rejected move repeats one)


# ------------------------------------------------------------------------------------------------
# the command line, with the demo round's posterior
RESUME = ["fit", "track.csv", "round.toml", "-o", "out", "--resume", "--max-steps", "100", "--quiet", "--drag",
          "reference-scale", "--seed", "1"]


@pytest.fixture(scope="module")
def demo_chain(tmp_path_factory):
    """The demo inputs and the chain of a finished quick sampled run of them (100 steps)."""
    d = tmp_path_factory.mktemp("demo")
    for name in ("demo_round.toml", "cd_m101.csv"):
        shutil.copy(files("bayesdrag") / "data" / name, d / name)
    (d / "round.toml").write_text((d / "demo_round.toml").read_text())
    assert main(["simulate", str(d / "round.toml"), "-o", str(d / "track.csv"), "--noise", "--seed", "1"]) == 0
    out = d / "finished"
    assert main(["fit", str(d / "track.csv"), str(d / "round.toml"), "-o", str(out), "--max-steps", "100", "--quiet",
                 "--drag", "reference-scale", "--seed", "1"]) == 0
    return d, out / "chain.h5"


@pytest.fixture
def seeded_resume(monkeypatch):
    """The positions a resume checks drawn by a seeded generator (fresh entropy otherwise)."""
    real = ChainFile.load_backend

    def load_backend(self, **kw):
        kw.setdefault("rng", np.random.default_rng(5))
        return real(self, **kw)

    monkeypatch.setattr(ChainFile, "load_backend", load_backend)


def test_fit_resume_refuses_the_demo_chain_with_one_percent_of_its_positions_forged(demo_chain, tmp_path, capsys,
                                                                                    monkeypatch, seeded_resume):
    d, chain = demo_chain
    case = tmp_path / "case"
    shutil.copytree(d, case, ignore=shutil.ignore_patterns("finished"))
    (case / "out").mkdir()
    shutil.copy(chain, case / "out" / "chain.partial.h5")
    forged = _forge(case / "out" / "chain.partial.h5", 0.01)
    assert forged >= 15
    monkeypatch.chdir(case)
    capsys.readouterr()
    code = main(RESUME)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith("bayesdrag: error: ") and "not a chain this run made" in err[0], err
    assert not (case / "out" / "result.json").exists() and not (case / "out" / "posterior.nc").exists()


def test_fit_resume_continues_the_unforged_demo_chain(demo_chain, tmp_path, capsys, monkeypatch, seeded_resume):
    d, chain = demo_chain
    case = tmp_path / "case"
    shutil.copytree(d, case, ignore=shutil.ignore_patterns("finished"))
    (case / "out").mkdir()
    shutil.copy(chain, case / "out" / "chain.partial.h5")
    monkeypatch.chdir(case)
    code = main(RESUME)
    assert code == 0, capsys.readouterr().err
    assert (case / "out" / "chain.h5").is_file() and (case / "out" / "posterior.nc").is_file()
