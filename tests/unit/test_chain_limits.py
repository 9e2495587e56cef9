"""A chain file is data from a folder someone else may have written (issue 25): before a value is
read its datasets must be stored inside the file as bayesdrag stores them and be no larger than
the run's settings; after reading, the stored log posterior must be what the run's posterior
gives at the stored positions. Each refusal is one InputError line naming the file."""
import emcee
import h5py
import numpy as np
import pytest

from bayesdrag.errors import InputError
from bayesdrag.io.chain import LOG_PROB_SAMPLE, ChainFile

W, D, STEPS = 8, 3, 60
FP = "0123abcd"


def toy(X):
    """Log posterior (standard normal) and one blob (the sum) of positions (m, D)."""
    X = np.atleast_2d(X)
    return np.column_stack([-0.5 * np.sum(X ** 2, axis=1), np.sum(X, axis=1)])


@pytest.fixture
def chain(tmp_path):
    """A real chain of STEPS steps written by ChainBackend while emcee ran."""
    cf = ChainFile(tmp_path / "chain.partial.h5", flush_every=25)
    backend = cf.new_backend(W, D, fingerprint=FP)
    sampler = emcee.EnsembleSampler(W, D, toy, vectorize=True, backend=backend, blobs_dtype=float)
    sampler.run_mcmc(np.random.default_rng(1).normal(size=(W, D)), STEPS, progress=False)
    backend.flush()
    return cf


def _load(cf, **kw):
    kw = {"nwalkers": W, "ndim": D, "nblobs": 1, "fingerprint": FP, "log_prob": toy, **kw}
    return cf.load_backend(**kw)


@pytest.fixture
def reads(monkeypatch):
    """Names of the datasets whose values are read."""
    seen = []
    real = h5py.Dataset.__getitem__

    def spy(self, key):
        seen.append(self.name)
        return real(self, key)

    monkeypatch.setattr(h5py.Dataset, "__getitem__", spy)
    return seen


def _replace(cf, name, **create):
    with h5py.File(cf.path, "a") as f:
        data = f[name][()]
        del f[name]
        f.create_dataset(name, data=data, **create)


def test_a_genuine_chain_resumes_whatever_positions_are_checked(chain):
    for seed in range(5):
        b = _load(chain, max_steps=1000, rng=np.random.default_rng(seed))
        assert b.iteration == STEPS and b.chain.shape == (STEPS, W, D)


def test_external_storage_is_refused_before_its_bytes_are_read(chain, tmp_path, reads):
    secret = tmp_path / "secret.bin"
    secret.write_bytes(np.arange(STEPS * W, dtype=float).tobytes())
    with h5py.File(chain.path, "a") as f:
        del f["mcmc/log_prob"]
        f.create_dataset("mcmc/log_prob", (STEPS, W), dtype="f8", external=[(str(secret), 0, STEPS * W * 8)])
    with pytest.raises(InputError, match=r"chain\.partial\.h5: dataset 'log_prob' is stored in external files; "
                                         r"delete it to start the chain afresh"):
        _load(chain)
    assert "/mcmc/log_prob" not in reads


def test_a_virtual_dataset_is_refused_before_it_is_read(chain, tmp_path, reads):
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as g:
        g.create_dataset("x", data=np.zeros((STEPS, W)))
    layout = h5py.VirtualLayout(shape=(STEPS, W), dtype="f8")
    layout[:] = h5py.VirtualSource(str(other), "x", shape=(STEPS, W))
    with h5py.File(chain.path, "a") as f:
        del f["mcmc/log_prob"]
        f["mcmc"].create_virtual_dataset("log_prob", layout)
    with pytest.raises(InputError, match=r"dataset 'log_prob' is a virtual dataset"):
        _load(chain)
    assert "/mcmc/log_prob" not in reads


@pytest.mark.parametrize("bounded", [True, False])
def test_a_sparse_600000_row_resize_is_refused_before_it_is_read(chain, reads, bounded):
    """1.7 MB on disk took 6.7 GB: the run's --max-steps bounds the steps, and without a bound the
    unallocated rows are found in the file's layout."""
    with h5py.File(chain.path, "a") as f:
        for name in ("chain", "log_prob", "blobs"):
            f["mcmc"][name].resize(600_000, axis=0)
        f["mcmc"].attrs["iteration"] = 600_000
        f["mcmc/random_state"].attrs["step"] = 600_000
    if bounded:
        with pytest.raises(InputError, match=r"it holds 600000 steps, more than this run's --max-steps 20000"):
            _load(chain, max_steps=20000)
    else:
        with pytest.raises(InputError, match=r"dataset 'chain' is sparse: part of its first 600000 rows is not "
                                             r"stored in the file"):
            _load(chain)
    assert not reads


def test_a_compressed_dataset_is_refused(chain, reads):
    _replace(chain, "mcmc/chain", compression="gzip", chunks=(32, W, D), maxshape=(None, W, D))
    reads.clear()
    with pytest.raises(InputError, match=r"dataset 'chain' is compressed or filtered"):
        _load(chain)
    assert "/mcmc/chain" not in reads


def test_a_file_larger_than_a_chain_of_the_run_is_refused_unopened(chain):
    with h5py.File(chain.path, "a") as f:
        f.create_dataset("padding", data=np.zeros(2_000_000))
    with pytest.raises(InputError, match=r"the file is \d+ bytes, more than a chain of 8 walkers x 100 steps x 3 "
                                         r"dimensions takes"):
        _load(chain, max_steps=100)


def test_more_rows_than_max_steps_are_refused(chain):
    with pytest.raises(InputError, match=rf"it holds {STEPS} steps, more than this run's --max-steps 50 \(resume "
                                         rf"with --max-steps {STEPS} or more\)"):
        _load(chain, max_steps=50)
    assert _load(chain, max_steps=STEPS).iteration == STEPS


@pytest.mark.parametrize("forge", ["positions shifted 5 %", "last log_prob", "one earlier row", "blobs"])
def test_rows_that_do_not_match_log_prob_are_refused(chain, forge):
    with h5py.File(chain.path, "a") as f:
        g = f["mcmc"]
        if forge == "positions shifted 5 %":
            g["chain"][...] = g["chain"][()] * 1.05
        elif forge == "last log_prob":
            g["log_prob"][STEPS - 1, 3] += 0.5
        elif forge == "one earlier row":     # every earlier row: whichever are drawn, one is forged
            g["chain"][: STEPS - 1] = g["chain"][: STEPS - 1] + 0.01
        else:
            g["blobs"][...] = g["blobs"][()] + 1.0
    with pytest.raises(InputError, match=r"the stored (log posterior|blob 1) at step \d+, walker \d+ is .*, the "
                                         r"posterior of these inputs gives .* at that position: not a chain this "
                                         r"run made; delete it"):
        _load(chain)


def test_the_positions_checked_are_the_last_row_and_a_random_sample(chain):
    """Every walker's last position and LOG_PROB_SAMPLE earlier ones (all of them when the chain
    holds fewer, as this one's 59 x 8 do)."""
    calls = []

    def counting(X):
        calls.append(np.array(X))
        return toy(X)

    _load(chain, log_prob=counting, rng=np.random.default_rng(0))
    (X,) = calls
    assert X.shape == (W + min(LOG_PROB_SAMPLE, (STEPS - 1) * W), D)
    b = _load(chain, log_prob=None)
    np.testing.assert_array_equal(X[:W], b.chain[-1])


def test_a_chain_file_passes_its_max_steps_to_the_samplers_copy(tmp_path):
    outer = ChainFile(tmp_path / "c.h5", inputs="ab", max_steps=123)
    inner = ChainFile(outer, flush_every=25, inputs=outer.inputs)
    assert inner.max_steps == 123 and inner.path == outer.path
