"""The compiled functions' cache is named by the module's place in the package and its source
hash, not by the folder the package is installed in (a new installation of the same source
reuses the compiled kernel); other files are left to numba's own locators."""
import os
import shutil

import pytest

numba = pytest.importorskip("numba")

from bayesdrag._runtime import numba_cache as _numba_cache  # noqa: E402
from bayesdrag.dynamics import kernel  # noqa: E402


def test_bayesdrag_registers_its_locator_first():
    assert os.environ["NUMBA_CACHE_LOCATOR_CLASSES"].split(",")[0] == "bayesdrag._runtime.numba_cache.PackageCacheLocator"


def test_cache_folder_does_not_depend_on_the_install_folder(tmp_path, monkeypatch):
    monkeypatch.setattr(numba.core.config, "CACHE_DIR", str(tmp_path / "cache"))
    fn = kernel.integrate_blocks.py_func
    here = _numba_cache.PackageCacheLocator.from_function(fn, kernel.__file__)
    # the same source in another installation: the same folder
    other = tmp_path / "site" / "bayesdrag" / "dynamics"
    other.mkdir(parents=True)
    shutil.copy(kernel.__file__, other / "kernel.py")
    monkeypatch.setattr(_numba_cache, "_ROOT", str(tmp_path / "site"))
    monkeypatch.setattr(_numba_cache, "_PKG", str(tmp_path / "site" / "bayesdrag"))
    there = _numba_cache.PackageCacheLocator.from_function(fn, str(other / "kernel.py"))
    assert here.get_cache_path() == there.get_cache_path()
    assert os.path.basename(here.get_cache_path()).startswith("bayesdrag_dynamics_kernel_")
    # edited source: another folder (and numba's index checks the content hash too)
    (other / "kernel.py").write_text((other / "kernel.py").read_text() + "\n# edited\n")
    edited = _numba_cache.PackageCacheLocator.from_function(fn, str(other / "kernel.py"))
    assert edited.get_cache_path() != here.get_cache_path()


def test_files_outside_the_package_are_left_to_numba(tmp_path, monkeypatch):
    monkeypatch.setattr(numba.core.config, "CACHE_DIR", str(tmp_path / "cache"))
    f = tmp_path / "user_code.py"
    f.write_text("def g(x):\n    return x\n")
    ns = {}
    exec(compile(f.read_text(), str(f), "exec"), ns)
    assert _numba_cache.PackageCacheLocator.from_function(ns["g"], str(f)) is None


def test_compile_summary_names_the_package_functions_it_compiled_or_loaded():
    """What the demo reports: compiled (with numba's compiler time) or loaded from the cache."""
    import numpy as np

    from bayesdrag.estimate.model import colored

    colored.whitened_ss(np.zeros((2, 5)), 0.5, 1.0, np.ones(4))
    s = _numba_cache.compile_record()
    assert set(s) == {"compiled", "compile_seconds", "loaded", "cache_dir"}
    assert s["loaded"] + len(s["compiled"]) >= 1
    assert all(n.split(".")[0] in ("dynamics", "estimate") for n in s["compiled"])
    assert s["compile_seconds"] >= 0.0
