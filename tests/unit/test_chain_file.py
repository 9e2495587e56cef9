"""The chain file (bayesdrag/io/chain.py): the random state round-trips as plain typed fields, so
a resumed run continues the exact chain; nothing read from the file is ever unpickled (a
planted pickle payload in any place the reader looks is refused with an InputError and never
runs); truncated, corrupt or mis-shaped files give one clear InputError naming the file."""
import ast
import pickle
import shutil
from pathlib import Path

import emcee
import h5py
import numpy as np
import pytest

from bayesdrag.cli import main
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.errors import InputError
from bayesdrag.estimate.bayes.posterior import LogPosterior
from bayesdrag.estimate.bayes.sampler import sample_posterior
from bayesdrag.estimate.scheme1.fit import fit_scheme1
from bayesdrag.io.chain import FORMAT, MT_KEY_SIZE, ChainFile
from bayesdrag.synthetic import add_noise
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.track import RadarTrack
from bayesdrag.io.tracks import write_track

SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
SEED = 3
STOPPED = 50          # steps in the stored chain
WALKERS = 16


class _Payload:
    """Unpickling this object creates ``marker``: proof that a file's content was unpickled."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def _payload(marker):
    return np.void(pickle.dumps(_Payload(marker)))


# ------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def short_track(m101):
    """An 8 s point-mass track (M101 truth, 1 m / 0.3 m/s noise) and its round."""
    tr = PointMassModel(42.6, 0.155, m101).simulate((), initial_state(818.0, 15.0), backend="scipy",
                                                     stop_at_impact=True, dt=0.05)
    keep = tr.t <= 8.0
    track = add_noise(RadarTrack(tr.t[keep], {c: tr.channel(c)[keep] for c in "xyzv"}, {}), SIGMA,
                      np.random.default_rng(1))
    rnd = Round(Projectile("155", 42.6, 0.155, m101, None), Launch(15.0, 818.0), radar=Radar(dict(SIGMA)),
                path="test.toml")
    return track, rnd


@pytest.fixture(scope="module")
def post(short_track):
    track, rnd = short_track
    f1 = fit_scheme1(track, rnd, drag="reference-scale")
    res, prob = f1.ml, f1.problem
    assert res.success, res.message
    return LogPosterior(prob, res)


@pytest.fixture(scope="module")
def stored(post, tmp_path_factory):
    """A valid chain file of STOPPED steps (seed SEED) and the run that wrote it."""
    path = tmp_path_factory.mktemp("chain") / "chain.partial.h5"
    run = sample_posterior(post, seed=SEED, nwalkers=WALKERS, max_steps=STOPPED, min_steps=STOPPED,
                           backend_path=path)
    return path, run


@pytest.fixture
def chain_copy(stored, tmp_path):
    path = tmp_path / "chain.partial.h5"
    shutil.copy(stored[0], path)
    return path


def _resume(post, path):
    return sample_posterior(post, seed=SEED, nwalkers=WALKERS, max_steps=2 * STOPPED, min_steps=2 * STOPPED,
                            backend_path=path, resume=True)


# ------------------------------------------------------------------ the random state
def test_file_stores_the_random_state_as_typed_fields(stored):
    """No pickle, no opaque bytes: the MT19937 key as uint32 (624,), the other fields as numbers
    and strings, and they equal the state of emcee's generator after the last stored step."""
    path, run = stored
    with h5py.File(path, "r") as f:
        g = f["mcmc"]
        assert g.attrs["format"] == FORMAT and int(g.attrs["iteration"]) == STOPPED
        assert "random_state" not in g.attrs
        rs = g["random_state"]
        assert rs["key"].dtype == np.uint32 and rs["key"].shape == (MT_KEY_SIZE,)
        assert rs.attrs["bit_generator"] == "MT19937" and int(rs.attrs["step"]) == STOPPED

        def no_opaque(name, obj):
            assert obj.dtype.kind != "V", name
            for k, v in obj.attrs.items():
                assert not isinstance(v, np.void), (name, k)

        f.visititems(lambda n, o: no_opaque(n, o) if isinstance(o, h5py.Dataset) else None)
        assert np.array_equal(run.chain, g["chain"][:])


def test_random_state_round_trip_continues_the_same_chain(tmp_path):
    """emcee with the chain backend, stopped after 30 steps: the loaded backend's random state
    is emcee's, field by field, and a sampler continued from the file draws the same 20 next
    steps as the sampler that was never stopped."""
    D, W = 3, 8
    prec = np.diag([1.0, 4.0, 0.25])

    def logp(X):
        return -0.5 * np.einsum("ij,jk,ik->i", X, prec, X)

    cf = ChainFile(tmp_path / "c.h5", flush_every=10)
    s1 = emcee.EnsembleSampler(W, D, logp, vectorize=True, backend=cf.new_backend(W, D, fingerprint="ab12"))
    p0 = np.random.default_rng(0).standard_normal((W, D))
    s1.run_mcmc(emcee.State(p0, random_state=np.random.RandomState(5).get_state()), 30)
    assert s1.iteration == 30                           # 3 full blocks flushed
    shutil.copy(cf.path, tmp_path / "copy.h5")
    back = ChainFile(tmp_path / "copy.h5").load_backend(nwalkers=W, ndim=D, nblobs=0, fingerprint="ab12")
    name, key, pos, has_gauss, cached = s1.random_state
    b_name, b_key, b_pos, b_has_gauss, b_cached = back.random_state
    assert (b_name, b_pos, b_has_gauss, b_cached) == (name, pos, has_gauss, cached)
    assert np.array_equal(b_key, key) and b_key.dtype == np.uint32
    s2 = emcee.EnsembleSampler(W, D, logp, vectorize=True, backend=back)
    s2.run_mcmc(None, 20)
    s1.run_mcmc(None, 20)
    assert np.array_equal(s1.get_chain(), s2.get_chain())


def test_resumed_run_equals_uninterrupted_run(post, stored, tmp_path):
    """sample_posterior stopped after STOPPED steps and resumed gives the chain, the retained
    draws and the noise draws of a run made in one go."""
    path, _ = stored
    copy = tmp_path / "resumed.h5"
    shutil.copy(path, copy)
    resumed = _resume(post, copy)
    whole = sample_posterior(post, seed=SEED, nwalkers=WALKERS, max_steps=2 * STOPPED, min_steps=2 * STOPPED,
                             backend_path=tmp_path / "whole.h5")
    assert resumed.resumed_from == STOPPED and resumed.steps == whole.steps == 2 * STOPPED
    assert np.array_equal(resumed.chain, whole.chain)
    assert np.array_equal(resumed.draws, whole.draws)


def test_explicit_rng_is_reproducible_and_resumable(post, tmp_path):
    """rng= (a numpy Generator) instead of seed=: the same generator state gives the same chain,
    and a chain made with it resumes exactly with a generator in the same state."""
    a = sample_posterior(post, rng=np.random.default_rng(8), max_steps=60, min_steps=60)
    b = sample_posterior(post, rng=np.random.default_rng(8), max_steps=60, min_steps=60)
    c = sample_posterior(post, rng=np.random.default_rng(9), max_steps=60, min_steps=60)
    assert np.array_equal(a.chain, b.chain) and not np.array_equal(a.chain, c.chain)
    p = tmp_path / "rng.h5"
    sample_posterior(post, rng=np.random.default_rng(8), max_steps=30, min_steps=30, backend_path=p)
    r = sample_posterior(post, rng=np.random.default_rng(8), max_steps=60, min_steps=60, backend_path=p,
                         resume=True)
    assert r.resumed_from == 30 and np.array_equal(r.chain, a.chain)
    with pytest.raises(TypeError, match="rng or seed"):
        sample_posterior(post, rng=np.random.default_rng(8), seed=8, max_steps=10)


def test_file_without_steps_starts_afresh(post, tmp_path):
    """A run killed before its first block leaves a file holding no step: resume starts over."""
    p = tmp_path / "empty.h5"
    ChainFile(p).new_backend(WALKERS, post.ndim, fingerprint="00")
    r = sample_posterior(post, seed=SEED, nwalkers=WALKERS, max_steps=30, min_steps=30, backend_path=p,
                         resume=True)
    assert r.resumed_from == 0 and r.steps == 30


# ------------------------------------------------------------------ planted pickles
ATTRS = [("mcmc", "format"), ("mcmc", "iteration"), ("mcmc", "bayesdrag_fingerprint"),
         ("mcmc/random_state", "bit_generator"), ("mcmc/random_state", "pos"),
         ("mcmc/random_state", "has_gauss"), ("mcmc/random_state", "cached_gaussian"),
         ("mcmc/random_state", "step")]
DATASETS = ["mcmc/chain", "mcmc/log_prob", "mcmc/blobs", "mcmc/accepted", "mcmc/random_state/key"]


@pytest.mark.parametrize("where,name", ATTRS, ids=[f"{g}@{a}" for g, a in ATTRS])
def test_pickle_in_an_attribute_is_never_loaded(post, chain_copy, tmp_path, where, name):
    marker = tmp_path / "PWNED"
    with h5py.File(chain_copy, "a") as f:
        f[where].attrs[name] = _payload(marker)
    with pytest.raises(InputError, match=rf"chain\.partial\.h5: .*{name}") as exc:
        _resume(post, chain_copy)
    assert not marker.exists()
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("name", DATASETS)
def test_pickle_in_a_dataset_is_never_loaded(post, chain_copy, tmp_path, name):
    marker = tmp_path / "PWNED"
    with h5py.File(chain_copy, "a") as f:
        del f[name]
        f.create_dataset(name, data=_payload(marker))
    with pytest.raises(InputError, match=rf"chain\.partial\.h5: .*'{name.removeprefix('mcmc/')}'"):
        _resume(post, chain_copy)
    assert not marker.exists()


def test_earlier_version_file_with_pickled_random_state_is_refused(post, chain_copy, tmp_path):
    """The layout of earlier versions: attribute ``random_state`` = pickled state, no format."""
    marker = tmp_path / "PWNED"
    with h5py.File(chain_copy, "a") as f:
        g = f["mcmc"]
        del g["random_state"], g.attrs["format"]
        g.attrs["random_state"] = _payload(marker)
    with pytest.raises(InputError, match=r"chain\.partial\.h5: .*earlier bayesdrag version.*pickle"):
        _resume(post, chain_copy)
    assert not marker.exists()


def test_a_pickle_as_the_whole_file_is_refused(post, tmp_path):
    marker = tmp_path / "PWNED"
    p = tmp_path / "chain.partial.h5"
    p.write_bytes(pickle.dumps(_Payload(marker)))
    with pytest.raises(InputError, match=r"chain\.partial\.h5: not a readable chain file"):
        _resume(post, p)
    assert not marker.exists()


def test_fit_resume_on_a_planted_chain_exits_2_without_running_it(short_track, tmp_path, capsys):
    """The attack itself: ``bayesdrag fit --resume`` on a DIR holding a crafted
    chain.partial.h5 (earlier layout, pickled random state) exits 2 with one line naming the
    file, and the payload never runs."""
    from importlib.resources import files

    track, _ = short_track
    write_track(tmp_path / "track.csv", track)
    m101 = Path(str(files("bayesdrag") / "data" / "cd_m101.csv")).as_posix()
    (tmp_path / "round.toml").write_text(
        f'[projectile]\nname = "155"\nmass = 42.6\ndiameter = 0.155\nreference_drag = "{m101}"\n'
        "[launch]\nelevation = 15.0\nvelocity = 818.0\n[radar]\nsigma = {x = 1.0, y = 1.0, z = 1.0, v = 0.3}\n")
    out = tmp_path / "out"
    out.mkdir()
    marker = tmp_path / "PWNED"
    with h5py.File(out / "chain.partial.h5", "w") as f:
        g = f.create_group("mcmc")
        g.attrs["iteration"] = 50
        g.attrs["bayesdrag_fingerprint"] = "0123456789abcdef"
        g.attrs["random_state"] = _payload(marker)
        g.create_dataset("chain", data=np.zeros((50, 16, 7)))
    code = main(["fit", str(tmp_path / "track.csv"), str(tmp_path / "round.toml"), "-o", str(out),
                 "--drag", "reference-scale", "--seed", "1", "--resume", "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert not marker.exists()
    assert len(err) == 1 and "chain.partial.h5" in err[0] and "pickle" in err[0], err


# ------------------------------------------------------------------ broken files
def test_truncated_file(post, chain_copy):
    data = chain_copy.read_bytes()
    chain_copy.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=r"chain\.partial\.h5: not a readable chain file"):
        _resume(post, chain_copy)


def test_not_an_hdf5_file(post, tmp_path):
    p = tmp_path / "chain.partial.h5"
    p.write_bytes(b"t,x\n0,0\n")
    with pytest.raises(InputError, match=r"chain\.partial\.h5: not a readable chain file"):
        _resume(post, p)


@pytest.mark.parametrize("name,shape,pattern", [
    ("mcmc/chain", (STOPPED, WALKERS - 2, None), r"'chain' has shape \(50, 14, \d+\), this run needs \(>=50, 16, \d+\)"),
    ("mcmc/chain", (STOPPED, WALKERS, 1), r"'chain' has shape \(50, 16, 1\)"),
    ("mcmc/log_prob", (STOPPED - 10, WALKERS), r"'log_prob' has shape \(40, 16\), this run needs \(>=50, 16\)"),
    ("mcmc/blobs", (STOPPED, WALKERS, 2), r"'blobs' has shape \(50, 16, 2\)"),
    ("mcmc/accepted", (WALKERS + 1,), r"'accepted' has shape \(17,\)"),
    ("mcmc/random_state/key", (MT_KEY_SIZE - 1,), r"'random_state/key' is <u4 \(623,\), expected uint32"),
])
def test_chain_of_the_wrong_shape(post, chain_copy, name, shape, pattern):
    with h5py.File(chain_copy, "a") as f:
        old = f[name]
        shape = tuple(post.ndim if s is None else s for s in shape)
        dtype = old.dtype
        del f[name]
        f.create_dataset(name, data=np.zeros(shape, dtype=dtype))
    with pytest.raises(InputError, match=r"chain\.partial\.h5: .*" + pattern):
        _resume(post, chain_copy)


@pytest.mark.parametrize("where,name,value,pattern", [
    ("mcmc/random_state", "pos", MT_KEY_SIZE + 1, r"'pos' must be an integer in 0\.\.624"),
    ("mcmc/random_state", "has_gauss", 2, r"'has_gauss' must be 0 or 1"),
    ("mcmc/random_state", "cached_gaussian", np.nan, r"'cached_gaussian' must be a finite number"),
    ("mcmc/random_state", "bit_generator", "PCG64", r"'bit_generator' 'PCG64', expected 'MT19937'"),
    ("mcmc/random_state", "step", STOPPED - 25, r"belongs to step 25, the chain has 50 steps"),
    ("mcmc", "iteration", -1, r"'iteration' attribute is missing or not a non-negative integer"),
    ("mcmc", "iteration", STOPPED + 1, r"'chain' has shape \(50, 16, \d+\), this run needs \(>=51"),
    ("mcmc", "format", "bayesdrag-chain/9", r"format 'bayesdrag-chain/9' is not supported"),
    ("mcmc", "bayesdrag_fingerprint", "0" * 16, r"other inputs or settings"),
])
def test_malformed_fields(post, chain_copy, where, name, value, pattern):
    with h5py.File(chain_copy, "a") as f:
        f[where].attrs[name] = value
    with pytest.raises(InputError, match=r"chain\.partial\.h5: .*" + pattern):
        _resume(post, chain_copy)


@pytest.mark.parametrize("name", ["mcmc/chain", "mcmc/log_prob", "mcmc/blobs", "mcmc/accepted"])
def test_non_finite_values(post, chain_copy, name):
    with h5py.File(chain_copy, "a") as f:
        f[name][(0,) * f[name].ndim] = np.inf if name.endswith("accepted") else np.nan
    with pytest.raises(InputError, match=rf"'{name[5:]}' holds non-finite values"):
        _resume(post, chain_copy)


@pytest.mark.parametrize("value", [-1.0, 0.5, STOPPED + 1.0])
def test_acceptance_counts_out_of_range(post, chain_copy, value):
    with h5py.File(chain_copy, "a") as f:
        f["mcmc/accepted"][0] = value
    with pytest.raises(InputError, match=r"'accepted' holds values that are not counts in 0\.\.50"):
        _resume(post, chain_copy)


def test_external_link_is_not_followed(post, chain_copy, tmp_path):
    other = tmp_path / "other.h5"
    with h5py.File(chain_copy, "r") as src, h5py.File(other, "w") as dst:
        dst.create_dataset("chain", data=src["mcmc/chain"][:])
    with h5py.File(chain_copy, "a") as f:
        del f["mcmc/chain"]
        f["mcmc/chain"] = h5py.ExternalLink(str(other), "/chain")
    with pytest.raises(InputError, match=r"dataset 'chain' is missing or not stored in this file"):
        _resume(post, chain_copy)


# ------------------------------------------------------------------ no unpickling in the package
def test_no_module_of_the_package_can_unpickle():
    """the contract (docs/formats.md): no file the program reads is unpickled or evaluated. No bayesdrag module
    imports pickle-like loaders or calls eval/exec, or np.load with allow_pickle."""
    root = Path(__file__).resolve().parents[2] / "bayesdrag"
    banned_modules = {"pickle", "cPickle", "_pickle", "marshal", "shelve", "dill", "cloudpickle", "joblib"}
    found = []
    for p in sorted(root.rglob("*.py")):
        tree = ast.parse(p.read_text(encoding="utf-8"))
        for n in ast.walk(tree):
            if isinstance(n, ast.Import):
                found += [(p.name, a.name) for a in n.names if a.name.split(".")[0] in banned_modules]
            elif isinstance(n, ast.ImportFrom) and (n.module or "").split(".")[0] in banned_modules:
                found.append((p.name, n.module))
            elif isinstance(n, ast.Call):
                fn = n.func
                name = fn.id if isinstance(fn, ast.Name) else fn.attr if isinstance(fn, ast.Attribute) else ""
                if name in ("eval", "exec", "read_pickle"):
                    found.append((p.name, name))
                if any(k.arg == "allow_pickle" for k in n.keywords):
                    found.append((p.name, "allow_pickle"))
    assert not found, found


def test_a_kill_inside_a_flush_resumes_with_the_committed_counts(post, chain_copy):
    """A kill after a flush rewrote 'accepted' and before it wrote 'iteration' leaves counts one
    flush ahead of the committed steps (the chain's rows already hold those steps): the counts
    are held to the committed steps and the chain resumes (seen as a flaky kill -9 test)."""
    with h5py.File(chain_copy, "a") as f:
        g = f["mcmc"]
        g.attrs["iteration"] = STOPPED - 1
        g["random_state"].attrs["step"] = STOPPED - 1
        g["accepted"][...] = float(STOPPED)        # every walker accepted every step, the uncommitted one too
    run = _resume(post, chain_copy)
    assert run.steps >= STOPPED and 0.0 <= run.acceptance <= 1.0


# ------------------------------------------------------------------ a kill inside a flush
BLOCK = 5             # steps a block in the kill test


def _gauss(x):
    return -0.5 * float(np.sum(x * x))


def _sample_to_file(path, steps):
    """Sample a 3-d Gaussian for ``steps`` steps, flushing a block of BLOCK steps to ``path``."""
    b = ChainFile(path, flush_every=BLOCK).new_backend(8, 3, fingerprint="ab")
    s = emcee.EnsembleSampler(8, 3, _gauss, backend=b)
    s.run_mcmc(emcee.State(np.random.default_rng(0).normal(size=(8, 3)),
                           random_state=np.random.RandomState(7).get_state()), steps)


def _killed_at_flush(path, k, steps):
    """Run :func:`_sample_to_file` in a child that SIGKILLs itself right after its k-th HDF5 flush
    (nothing closes the file: what is on disk is what a ``kill -9`` at that point leaves)."""
    import os
    import signal

    pid = os.fork()
    if pid == 0:
        try:
            calls = [0]
            plain = h5py.File.flush

            def flush(self):
                plain(self)
                calls[0] += 1
                if calls[0] == k:
                    os.kill(os.getpid(), signal.SIGKILL)

            h5py.File.flush = flush
            _sample_to_file(path, steps)
        finally:
            os._exit(3)
    _, status = os.waitpid(pid, 0)
    return os.WIFSIGNALED(status)


def _loaded(path):
    return ChainFile(path).load_backend(nwalkers=8, ndim=3, nblobs=0, fingerprint="ab")


@pytest.mark.parametrize("k", range(1, 9))
def test_a_kill_at_any_flush_of_a_block_leaves_a_chain_that_resumes_exactly(tmp_path, k):
    """Killed after each of the HDF5 flushes of the first two blocks, the file loads (no refusal)
    and holds exactly the rows, accepted counts and random state an uninterrupted run has at
    the committed step: a resume continues the same chain. Before the two-slot commit, a kill
    inside a flush left 'accepted' of unwritten bytes and a resume was refused (seen in CI)."""
    path = tmp_path / "killed.h5"
    assert _killed_at_flush(path, k, 4 * BLOCK), "the child was not killed inside a flush"
    got = _loaded(path)
    if got is None:                          # killed before the first block was committed
        assert k <= 2
        return
    n = got.iteration
    assert n in (BLOCK, 2 * BLOCK)
    ref_path = tmp_path / "ref.h5"
    _sample_to_file(ref_path, n)
    ref = _loaded(ref_path)
    assert ref.iteration == n
    np.testing.assert_array_equal(got.chain, ref.chain)
    np.testing.assert_array_equal(got.accepted, ref.accepted)
    assert got.random_state[0] == ref.random_state[0]
    np.testing.assert_array_equal(got.random_state[1], ref.random_state[1])
    assert tuple(got.random_state[2:]) == tuple(ref.random_state[2:])
