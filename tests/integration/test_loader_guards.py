"""The loaders refuse what a hostile folder holds (issue 44, items 4 and 5), each case as the review
found it: ``posterior.nc`` a symbolic link, stored in another file (external storage, an external
link, a virtual dataset), a gzip variable declaring far more than the file, a chunk inflating far
beyond itself, huge declared dimensions, a non-HDF5 file; ``result.json``, ``diagnosis.json`` and
``plan.json`` with keys of the wrong type and numbers that are not finite. Every refusal is an
:class:`InputError` naming the file and the key or dataset. A genuine written fit (Scheme 1 and
Scheme 2) still loads equal to the fit that wrote it."""
import json
import math
import os
import shutil
import zlib

import arviz as az
import h5py
import numpy as np
import pytest

import bayesdrag
from bayesdrag.commands.demo import demo_inputs
from bayesdrag.errors import InputError

#: a short synthetic track: sample spacing [s] (about 130 samples) and the sampler's step limit
TRACK_DT = 0.25
STEPS = 100
#: samples per Scheme 2 window (three windows on the short track)
SCHEME2_WINDOW = 50
#: what a compression bomb chunk inflates to [bytes]: far beyond its chunk of 16 float64
BOMB_BYTES = 64 << 20
#: the huge dimensions a 16 MB file declared in the review (4 x 1e6 x 1000 float64: 29.8 GiB)
HUGE_SHAPE = (4, 1_000_000, 1000)
#: the chain dimension of the fixture's posterior (16 walkers)
WALKERS = 16


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    rnd = bayesdrag.read_round(demo_inputs()[1])
    track = bayesdrag.simulate(rnd, noise=True, seed=3, dt=TRACK_DT)
    res = bayesdrag.fit(track, rnd, mcmc=True, seed=1, with_effects="none", max_steps=STEPS)
    out = tmp_path_factory.mktemp("fit")
    res.write(out)
    return res, out


@pytest.fixture()
def folder(fitted, tmp_path):
    """A copy of the written fit's result.json and posterior.nc."""
    d = tmp_path / "fit"
    d.mkdir()
    for name in ("result.json", "posterior.nc"):
        shutil.copyfile(fitted[1] / name, d / name)
    return d


def _use(res):
    """What a reader does with a loaded result: every method that reads the document."""
    repr(res)
    str(res.summary())
    res.to_dict()
    if hasattr(res, "to_dataframe"):
        res.to_dataframe()
    if hasattr(res, "band"):
        res.band(0.9)


def _load_fit(d):
    _use(bayesdrag.load_result(d))


# ------------------------------------------------------------------------------ the genuine folder
def test_a_genuine_written_fit_loads_equal(fitted):
    res, out = fitted
    back = bayesdrag.load_result(out)
    assert back == res and back.cd == res.cd
    idata = back.to_inference_data()
    with az.rc_context({"data.load": "eager"}):
        theirs = az.from_netcdf(str(out / "posterior.nc"))
    assert sorted(idata.groups()) == sorted(theirs.groups())
    for g in theirs.groups():
        assert idata[g].identical(theirs[g]), g
    assert np.array_equal(back.cd_draws(), res.cd_draws())
    _use(back)


def test_a_genuine_scheme2_fit_loads_equal(tmp_path):
    # Scheme 2's posterior.nc is written through ArviZ, and bounded by its windows
    rnd = bayesdrag.read_round(demo_inputs()[1])
    track = bayesdrag.simulate(rnd, noise=True, seed=3, dt=TRACK_DT)
    res = bayesdrag.fit(track, rnd, mcmc=True, scheme=2, window=SCHEME2_WINDOW, max_steps=STEPS, seed=1)
    res.write(tmp_path)
    back = bayesdrag.load_result(tmp_path)
    assert back == res
    assert np.array_equal(back.band(0.9, kind="posterior"), res.band(0.9, kind="posterior"))


# ------------------------------------------------------------------------------ posterior.nc
def test_a_symlinked_posterior_is_refused(folder, fitted, tmp_path):
    elsewhere = tmp_path / "elsewhere.nc"
    shutil.copyfile(fitted[1] / "posterior.nc", elsewhere)
    (folder / "posterior.nc").unlink()
    (folder / "posterior.nc").symlink_to(elsewhere)
    with pytest.raises(InputError, match=r"posterior\.nc: the posterior file is a symbolic link"):
        bayesdrag.load_result(folder)


def test_a_dangling_symlinked_posterior_is_refused(folder, tmp_path):
    (folder / "posterior.nc").unlink()
    (folder / "posterior.nc").symlink_to(tmp_path / "missing.nc")
    with pytest.raises(InputError, match=r"posterior\.nc: the posterior file is a symbolic link"):
        bayesdrag.load_result(folder)


def test_external_storage_is_refused(folder, tmp_path):
    secret = tmp_path / "secret.bin"
    with h5py.File(folder / "posterior.nc", "a") as f:
        g = f["posterior"]
        shape, dtype = g["cd"].shape, g["cd"].dtype
        nbytes = math.prod(shape) * dtype.itemsize
        secret.write_bytes(np.arange(math.prod(shape), dtype=dtype).tobytes())
        del g["cd"]
        ds = g.create_dataset("cd", shape, dtype, external=[(str(secret), 0, nbytes)])
        for i, dim in enumerate(("chain", "draw", "mach")):
            ds.dims[i].attach_scale(g[dim])
    with pytest.raises(InputError, match=r"posterior\.nc: dataset 'posterior/cd' is stored in external files "
                                         r"\(.*secret\.bin\)"):
        bayesdrag.load_result(folder)


def test_an_external_link_is_refused(folder, tmp_path):
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["data"] = np.arange(WALKERS, dtype=float)
    with h5py.File(folder / "posterior.nc", "a") as f:
        f["posterior"]["stolen"] = h5py.ExternalLink(str(other), "/data")
    with pytest.raises(InputError, match=r"posterior\.nc: 'posterior/stolen' is an external link"):
        bayesdrag.load_result(folder)


def test_a_virtual_dataset_is_refused(folder, tmp_path):
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["data"] = np.arange(WALKERS, dtype=float)
    layout = h5py.VirtualLayout(shape=(WALKERS,), dtype=float)
    layout[:] = h5py.VirtualSource(str(other), "data", shape=(WALKERS,))
    with h5py.File(folder / "posterior.nc", "a") as f:
        ds = f["posterior"].create_virtual_dataset("stolen", layout)
        ds.dims[0].attach_scale(f["posterior"]["chain"])
    with pytest.raises(InputError, match=r"posterior\.nc: dataset 'posterior/stolen' is a virtual dataset"):
        bayesdrag.load_result(folder)


def _largest_dimension(path):
    with h5py.File(path, "r") as f:
        sizes = []
        f.visititems(lambda _, o: sizes.extend(o.shape) if isinstance(o, h5py.Dataset) else None)
    return max(sizes)


def test_a_gzip_variable_declaring_far_more_than_the_fit_made_is_refused(folder):
    # every dimension as long as the genuine file's longest: only the product is too large
    n = _largest_dimension(folder / "posterior.nc")
    before = os.path.getsize(folder / "posterior.nc")
    shape, chunk = (n, n, n), (1, n, n)
    zeros = zlib.compress(bytes(8 * n * n), 9)
    with h5py.File(folder / "posterior.nc", "a") as f:
        ds = f["posterior"].create_dataset("bomb", shape, "f8", chunks=chunk, compression="gzip")
        for i in range(shape[0]):
            ds.id.write_direct_chunk((i, 0, 0), zeros)
    assert os.path.getsize(folder / "posterior.nc") - before < 8 * math.prod(shape) / 100   # a small bomb
    with pytest.raises(InputError, match=r"posterior\.nc: dataset 'posterior/bomb' declares \d+x\d+x\d+ values "
                                         r"\(\d+ bytes\), more than the \d+ that result\.json's sampler allows"):
        bayesdrag.load_result(folder)


def test_a_chunk_inflating_beyond_its_size_is_refused(folder):
    with h5py.File(folder / "posterior.nc", "a") as f:
        g = f["posterior"]
        ds = g.create_dataset("bomb", (WALKERS,), "f8", chunks=(WALKERS,), compression="gzip")
        ds.id.write_direct_chunk((0,), zlib.compress(bytes(BOMB_BYTES), 9))
        ds.dims[0].attach_scale(g["chain"])
    with pytest.raises(InputError, match=r"posterior\.nc: a chunk of dataset 'posterior/bomb' \(\d+ bytes stored\) "
                                         r"inflates to more than the 128 bytes of a chunk \(a compression bomb\)"):
        bayesdrag.load_result(folder)


def test_huge_declared_dimensions_in_a_small_file_are_refused(folder):
    with h5py.File(folder / "posterior.nc", "a") as f:
        f["posterior"].create_dataset("huge", HUGE_SHAPE, "f8", chunks=(1, 1000, 1000))
    with pytest.raises(InputError, match=r"posterior\.nc: dimension 1 of dataset 'posterior/huge' has length 1000000, "
                                         r"more than the \d+ that result\.json's sampler allows"):
        bayesdrag.load_result(folder)


def test_values_never_written_are_refused(folder):
    with h5py.File(folder / "posterior.nc", "a") as f:
        g = f["posterior"]
        ds = g.create_dataset("unwritten", (WALKERS,), "f8", chunks=(4,), fillvalue=np.nan)
        ds[:4] = 1.0
        ds.dims[0].attach_scale(g["chain"])
    with pytest.raises(InputError, match=r"posterior\.nc: dataset 'posterior/unwritten' is sparse: 3 of its 4 chunks"):
        bayesdrag.load_result(folder)


def test_a_file_larger_than_the_fit_made_is_refused(folder):
    with open(folder / "posterior.nc", "r+b") as f:
        f.truncate(1 << 30)                 # a sparse file: no disk space taken
    with pytest.raises(InputError, match=r"posterior\.nc: the posterior file is 1073741824 bytes, more than the \d+ "
                                         r"that result\.json's sampler allows"):
        bayesdrag.load_result(folder)


@pytest.mark.parametrize("content", [b"not a NetCDF file\n", b"", b"\x89HDF\r\n\x1a\n" + bytes(100)])
def test_a_file_that_is_not_hdf5_is_refused(folder, content):
    (folder / "posterior.nc").write_bytes(content)
    with pytest.raises(InputError, match=r"posterior\.nc: not an HDF5 \(NetCDF-4\) posterior file"):
        bayesdrag.load_result(folder)


def test_a_folder_named_posterior_is_refused(folder):
    (folder / "posterior.nc").unlink()
    (folder / "posterior.nc").mkdir()
    with pytest.raises(InputError, match=r"posterior\.nc: the posterior file is not a regular file"):
        bayesdrag.load_result(folder)


def test_a_posterior_beside_a_fit_that_did_not_sample_is_refused(folder):
    doc = json.loads((folder / "result.json").read_text())
    del doc["mcmc"]
    (folder / "result.json").write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"posterior\.nc: result\.json records no sampling"):
        bayesdrag.load_result(folder)


# ------------------------------------------------------------------------------ result.json
def _set(doc, path, value):
    """``doc`` with the key at ``path`` (a tuple of keys and indices) set to ``value``."""
    d = doc
    for k in path[:-1]:
        d = d[k]
    d[path[-1]] = value


#: a value JSON cannot hold, written as its raw token
RAW = {"NaN": "NaN", "Infinity": "Infinity", "-Infinity": "-Infinity", "1e999": "1e999"}


def _write(path, doc, raw=None):
    text = json.dumps(doc)
    if raw is not None:
        text = text.replace('"@raw@"', RAW[raw])
    path.write_text(text)


@pytest.mark.parametrize("path, value, match", [
    (("cd",), "x", r"cd is the string 'x', expected a list"),
    (("cd", 3, "mach"), "x", r"cd\[3\]\.mach is the string 'x', expected a number"),
    (("cd", 3), "x", r"cd\[3\] is the string 'x', expected an object"),
    (("cd", 2, "ml"), [1], r"cd\[2\]\.ml is a list of 1 item, expected a number"),
    (("cd", 4, "determined"), "yes", r"cd\[4\]\.determined is the string 'yes', expected true or false"),
    (("cd", 5, "mach"), 0.1, r"cd\[5\]\.mach is 0\.1, below cd\[4\]\.mach .*: the rows must be in increasing mach"),
    (("cd",), [], r"cd is a list of 0 items, expected a list of at least 1 item"),
    (("ml",), [1, 2, 3], r"ml is a list of 3 items, expected an object"),
    (("ml", "quality"), "x", r"ml\.quality is the string 'x', expected an object"),
    (("ml", "quality", "problems"), "x", r"ml\.quality\.problems is the string 'x', expected a list"),
    (("ml", "quality", "channels", "x", "chi2_per_sample"), "x",
     r"ml\.quality\.channels\.x\.chi2_per_sample is the string 'x', expected a number"),
    (("ml", "mach_range_data"), [1.0], r"ml\.mach_range_data is a list of 1 item, expected a list of two items"),
    (("mcmc",), "x", r"mcmc is the string 'x', expected an object"),
    (("mcmc", "tau_max"), "x", r"mcmc\.tau_max is the string 'x', expected a number"),
    (("mcmc", "walkers"), 0, r"mcmc\.walkers is the number 0, expected an integer >= 1"),
    (("scheme",), "x", r"scheme is the string 'x', expected an integer in 1\.\.2"),
    (("scheme",), True, r"scheme is true, expected an integer in 1\.\.2"),
    (("drag_model",), 3, r"drag_model is the number 3, expected a string"),
    (("windows",), "x", r"windows is the string 'x', expected a list"),
    (("uncertainty_budget", "by_source"), [],
     r"uncertainty_budget\.by_source is a list of 0 items, expected an object"),
])
def test_a_malformed_result_json_names_the_key(folder, path, value, match):
    (folder / "posterior.nc").unlink()
    doc = json.loads((folder / "result.json").read_text())
    _set(doc, path, value)
    _write(folder / "result.json", doc)
    with pytest.raises(InputError, match=r"result\.json: " + match + r"; the file is not as bayesdrag writes it"):
        _load_fit(folder)


@pytest.mark.parametrize("raw, what", [("NaN", "NaN"), ("Infinity", "infinite"), ("-Infinity", "-infinite"),
                                       ("1e999", "infinite")])
@pytest.mark.parametrize("path, where", [(("cd", 2, "ml"), r"cd\[2\]\.ml"), (("cd", 0, "mach"), r"cd\[0\]\.mach"),
                                         (("timing", "total"), r"timing\.total")])
def test_numbers_that_are_not_finite_are_refused(folder, raw, what, path, where):
    (folder / "posterior.nc").unlink()
    doc = json.loads((folder / "result.json").read_text())
    doc.setdefault("timing", {})
    _set(doc, path, "@raw@")
    _write(folder / "result.json", doc, raw)
    with pytest.raises(InputError, match=rf"result\.json: {where} is {what}: JSON numbers must be finite"):
        _load_fit(folder)


def test_an_integer_beyond_the_float_range_is_refused(folder):
    (folder / "posterior.nc").unlink()
    doc = json.loads((folder / "result.json").read_text())
    _set(doc, ("cd", 1, "mach"), 10 ** 400)
    _write(folder / "result.json", doc)
    with pytest.raises(InputError, match=r"result\.json: cd\[1\]\.mach is an integer of 401 digits, beyond the float"):
        _load_fit(folder)


def test_a_symlinked_result_json_is_refused(folder, tmp_path):
    elsewhere = tmp_path / "elsewhere.json"
    shutil.move(folder / "result.json", elsewhere)
    (folder / "result.json").symlink_to(elsewhere)
    with pytest.raises(InputError, match=r"result\.json: the result\.json is a symbolic link"):
        bayesdrag.load_result(folder)


# ------------------------------------------------------------------------------ diagnosis.json, plan.json
def _diagnosis():
    """A diagnosis.json as ``bayesdrag diagnose`` writes it, cut to the keys its result reads."""
    effect = {"name": "wind", "significant": True, "material": True, "shrink": 0.8, "delta_loglik": 12.5,
              "delta_bic": -20.0, "test_statistic": 25.0, "threshold": 7.7, "cd_shift_max": 0.002,
              "end_shift_sd": 4.0, "confounded_with": [], "params": {"wx": 1.5}, "sd": {"wx": 0.1},
              "units": {"wx": "m/s"}}
    return {"baseline": {"chi2_per_sample": 1.8, "gap": 240.0}, "effects": [effect], "verdict": ["wind"],
            "immaterial": [], "summary": "Found: wind.", "reference_drag": True, "tests": {"candidates": 1}}


def _plan():
    """A plan.json as ``bayesdrag plan`` writes it, cut to the keys its result reads."""
    case = {"elevation": 45.0, "velocity": 818.0, "rounds": 1, "mach_range": [0.86, 2.4], "best_relative_sd": 1e-4,
            "drag_model": "spline", "target_mach_range": [0.9, 2.4],
            "tracked": {"samples": 766, "t_start": 0.0, "t_end": 76.5}}
    return {"cases": [case], "summary": "One case.", "rounds": 1,
            "target": {"paragraph": "Target reached.", "relative_sd": 0.002},
            "radar": {"sigma": {"x": 1.0, "v": 0.3}}, "round": {"name": "155 mm"}, "assumed_drag": {"source": "ref"}}


def test_well_formed_diagnosis_and_plan_documents_load(tmp_path):
    _write(tmp_path / "diagnosis.json", _diagnosis())
    _write(tmp_path / "plan.json", _plan())
    d, p = bayesdrag.load_diagnosis(tmp_path), bayesdrag.load_plan(tmp_path)
    _use(d)
    _use(p)
    assert d.verdict == ["wind"] and p.to_dict() == _plan()


@pytest.mark.parametrize("path, value, raw, match", [
    (("effects",), "x", None, r"effects is the string 'x', expected a list"),
    (("effects", 0, "shrink"), "x", None, r"effects\[0\]\.shrink is the string 'x', expected a number"),
    (("effects", 0, "params", "wx"), "x", None, r"effects\[0\]\.params\.wx is the string 'x', expected a number"),
    (("effects", 0), {"shrink": 0.1, "significant": False}, None, r"effects\[0\] has no key 'name'"),
    (("verdict",), "wind", None, r"verdict is the string 'wind', expected a list"),
    (("baseline",), [1, 2], None, r"baseline is a list of 2 items, expected an object"),
    (("tests",), "x", None, r"tests is the string 'x', expected an object"),
    (("baseline", "gap"), "@raw@", "NaN", r"baseline\.gap is NaN: JSON numbers must be finite"),
    (("effects", 0, "params", "wx"), "@raw@", "1e999", r"effects\[0\]\.params\.wx is infinite"),
])
def test_a_malformed_diagnosis_json_names_the_key(tmp_path, path, value, raw, match):
    doc = _diagnosis()
    _set(doc, path, value)
    _write(tmp_path / "diagnosis.json", doc, raw)
    with pytest.raises(InputError, match=r"diagnosis\.json: " + match):
        _use(bayesdrag.load_diagnosis(tmp_path))


@pytest.mark.parametrize("path, value, raw, match", [
    (("cases",), {"a": 1}, None, r"cases is an object, expected a list"),
    (("cases", 0, "mach_range"), [1, 2, 3], None, r"cases\[0\]\.mach_range is a list of 3 items, expected a list of "
                                                  r"two items"),
    (("cases", 0, "elevation"), "x", None, r"cases\[0\]\.elevation is the string 'x', expected a number"),
    (("cases", 0), "x", None, r"cases\[0\] is the string 'x', expected an object"),
    (("target",), "x", None, r"target is the string 'x', expected an object"),
    (("radar", "sigma", "x"), "1", None, r"radar\.sigma\.x is the string '1', expected a number"),
    (("round",), "x", None, r"round is the string 'x', expected an object"),
    (("cases", 0, "best_relative_sd"), "@raw@", "Infinity", r"cases\[0\]\.best_relative_sd is infinite"),
    (("target", "relative_sd"), "@raw@", "NaN", r"target\.relative_sd is NaN"),
])
def test_a_malformed_plan_json_names_the_key(tmp_path, path, value, raw, match):
    doc = _plan()
    _set(doc, path, value)
    _write(tmp_path / "plan.json", doc, raw)
    with pytest.raises(InputError, match=r"plan\.json: " + match):
        _use(bayesdrag.load_plan(tmp_path))
