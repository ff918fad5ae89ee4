"""An editable install after a non-editable one works (issue 38: after ``pip install .`` and then
``pip install -e '.[casadi]'``, ``import exo_bench`` failed with "cannot import name 'prepare'").

The cause: pip removes only the files it installed. numba's cache files, written at run time into
``site-packages/exo_bench/**/__pycache__``, stayed after the uninstall that ``pip install -e .`` does
first; the ``exo_bench`` folder they kept (no ``__init__.py`` any more) is a namespace package to
Python's path finder, which runs before the editable install's finder, and it shadowed the checkout.
Now an installed copy's compiled kernels go beside the package, in ``exo_bench.numba-cache``
(models/machine/numba_cache.py ``InstalledCacheLocator``), which no import can mistake for the package.

The two installs are simulated (a real pair of pip installs takes minutes): the files pip leaves
behind are laid out in a site folder, and the editable install is a finder appended to
``sys.meta_path``, as setuptools' editable finder is.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from exo_bench.models.machine import numba_cache

#: A process (no site-packages of its own: -S) whose path has ``site`` (what pip left behind) and whose editable finder serves the
#: package ``exo_bench`` from ``src`` (its ``__init__.py`` defines ``prepare``).
IMPORT = """
import importlib.abc, importlib.util, sys
site, src = sys.argv[1], sys.argv[2]
sys.path.insert(0, site)

class EditableFinder(importlib.abc.MetaPathFinder):  # as setuptools' __editable___*_finder
    def find_spec(self, name, path=None, target=None):
        if name == "exo_bench":
            return importlib.util.spec_from_file_location(name, src + "/exo_bench/__init__.py")
        return None

sys.meta_path.append(EditableFinder())
from exo_bench import prepare
print("imported", prepare)
"""


def _import_with_leftovers(tmp_path: Path, leftovers: list[Path]) -> subprocess.CompletedProcess:
    site, src = tmp_path / "site-packages", tmp_path / "checkout"
    (src / "exo_bench").mkdir(parents=True)
    (src / "exo_bench" / "__init__.py").write_text("prepare = 'the checkout'\n")
    site.mkdir(exist_ok=True)
    for f in leftovers:
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_bytes(b"numba machine code")
    return subprocess.run(
        [sys.executable, "-I", "-S", "-c", IMPORT, str(site), str(src)], capture_output=True, text=True, timeout=60
    )


def _cache_file(package: Path, module: str) -> Path:
    """Where a kernel of ``package/<module>`` writes its cache index in an installed copy."""
    folder = numba_cache.installed_cache_folder(package / module, package)
    assert folder is not None
    return folder / (Path(module).stem + ".k-1.py311.nbi")


def test_the_leftovers_of_the_old_layout_shadow_the_editable_install(tmp_path):
    """The failure as reported: cache files inside site-packages/exo_bench/**/__pycache__."""
    site = tmp_path / "site-packages"
    r = _import_with_leftovers(tmp_path, [site / "exo_bench" / "models" / "__pycache__" / "lean.k-1.py311.nbi"])
    assert r.returncode != 0 and "cannot import name 'prepare'" in r.stderr, r.stderr


def test_an_installed_copys_cache_leaves_nothing_that_shadows_the_editable_install(tmp_path):
    site = tmp_path / "site-packages"
    package = site / "exo_bench"
    leftovers = [
        _cache_file(package, "models/newton_euler/compiled.py"),
        _cache_file(package, "models/machine/fast_trig.py"),
    ]
    for f in leftovers:
        assert not f.is_relative_to(package), f  # never inside the package folder
        assert f.is_relative_to(site / "exo_bench.numba-cache"), f
    r = _import_with_leftovers(tmp_path, leftovers)
    assert r.returncode == 0 and "imported the checkout" in r.stdout, r.stderr


def test_the_installed_cache_folder_keeps_the_package_layout_and_only_for_its_files(tmp_path):
    package = tmp_path / "site-packages" / "exo_bench"
    got = numba_cache.installed_cache_folder(package / "matrix_method" / "numba_kernels" / "k.py", package)
    assert got == tmp_path / "site-packages" / "exo_bench.numba-cache" / "matrix_method" / "numba_kernels"
    assert numba_cache.installed_cache_folder(tmp_path / "elsewhere" / "k.py", package) is None


def test_numbas_locators_put_the_installed_copys_first_and_a_checkout_keeps_numbas_own():
    """After the runtime's set-up the installed copy's locator comes before numba's in-tree one (the
    kernels' locator, first, wraps whichever applies); in this checkout (editable) it applies to nothing."""
    pytest.importorskip("numba")
    from numba.core import caching

    from exo_bench.models.machine import numba_runtime

    numba_runtime.ensure()
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
    order = list(impl._locator_classes)
    assert order.index(numba_cache.InstalledCacheLocator) < order.index(numba_cache._InTreeLocator)
    assert order[0] is numba_cache.KernelSourceLocator
    if numba_cache.installed_package() is None:  # a checkout: the cache stays in its __pycache__ folders
        assert numba_cache.InstalledCacheLocator.from_function(lambda: None, numba_cache.__file__) is None


def test_an_installed_copy_follows_numba_cache_dir_when_the_user_sets_it(tmp_path, monkeypatch):
    """``NUMBA_CACHE_DIR`` is the user's choice: numba's own locator serves it, installed copy or not."""
    from numba.core import config

    package = tmp_path / "site-packages" / "exo_bench"
    (package / "models").mkdir(parents=True)
    (package / "models" / "k.py").write_text("")
    monkeypatch.setattr(numba_cache, "installed_package", lambda: package)
    monkeypatch.setattr(config, "CACHE_DIR", "", raising=False)
    loc = numba_cache.InstalledCacheLocator.from_function(lambda: None, str(package / "models" / "k.py"))
    assert (
        loc is not None
        and Path(loc.get_cache_path()) == tmp_path / "site-packages" / "exo_bench.numba-cache" / "models"
    )
    monkeypatch.setattr(config, "CACHE_DIR", str(tmp_path / "mine"), raising=False)
    assert numba_cache.InstalledCacheLocator.from_function(lambda: None, str(package / "models" / "k.py")) is None
