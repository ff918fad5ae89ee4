"""numba's on-disk cache keyed on the source of every function a kernel inlines.

numba keys a cached kernel on its own file only (the source stamp of its cache index): an edit to
an element function that a kernel inlines from another file (``register_jitable``), or an upgrade
that changes only that file, would leave the old machine code serving wrong forces, silently.
:class:`KernelSourceLocator` wraps numba's own locator for the kernels of the kernel folders of
:data:`KERNEL_SOURCES` (same cache folder, same file names) and adds to the source stamp a hash of
every module of the kernel's folder and of the files its kernels inline (:func:`inlined_sources`):
any edit there makes the index's stamp differ, so numba recompiles and overwrites the entry instead
of loading it. tests/test_compiled.py and tests/test_kernel_cache.py edit an element function in a
copy of the package and see the new forces from the compiled kernels.

This module only defines the keys; importing it changes nothing in numba. Installing them (the
locator first in numba's list, :func:`index_key_by_code` as numba's index key) is
:func:`exo_bench.models.machine.numba_runtime.ensure`'s, before any kernel is defined.

numba's documentation says a cached function is invalidated "when the corresponding source file is
modified" and that changes to functions it calls in other files are not detected; this closes that
gap for our kernels (numba/core/caching.py: ``_CacheLocator.get_source_stamp``, ``CacheImpl._locator_classes``).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import inspect
import os
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

from numba.core import caching
from numba.extending import register_jitable

_CacheLocator = caching._CacheLocator
#: numba's cache implementation, whose ``_locator_classes`` lists the locators tried in order
#: (``CacheImpl`` in numba 0.68; ``_CacheImpl`` before).
_CacheImpl: Any = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl")  # noqa: B009

_HERE = Path(__file__).resolve().parent  # models/machine/ (exo_bench/models/machine in an installed package)
_MODELS = _HERE.parent  # models/
_MATRIX = _MODELS.parent / "matrix_method"

#: The kernel folders (a kernel defined in a file of one uses :class:`KernelSourceLocator`), each with
#: the files beyond its own modules whose functions its kernels inline (:func:`inline` refuses a
#: function from any other file, so that no inlined source is left out of the key).
KERNEL_SOURCES: Mapping[Path, tuple[Path, ...]] = MappingProxyType(
    {
        # cholesky_forward.py calls the compiled checks of forward_check.py
        _MATRIX / "numba_kernels": (
            *(_MATRIX / "closed_forms" / f for f in ("planar.py", "transitions.py", "factored.py")),
            _MODELS / "runtime" / "forward_check.py",
        ),
        # its kernels inline the rod elements (rod_elements.py, below every method: external_forces.py
        # projects with them too); forward_fused.py and the derivatives' one-sample entry (derivatives_simd.py)
        # call the compiled checks of forward_check.py (and the states' pass: a shared source)
        _MODELS / "newton_euler": (_MODELS / "mechanism" / "rod_elements.py", _MODELS / "runtime" / "forward_check.py"),
        # one kernel file of its own (a key may be a file: its kernels are keyed on it and these, not on
        # the rest of models/): f_ext's pass projects with the rod elements
        _MODELS / "runtime" / "external_forces_kernel.py": (_MODELS / "mechanism" / "rod_elements.py",),
    }
)


def inline(functions: Iterable[Callable[..., Any]], kernel_dir: str | Path, always: bool = False) -> None:
    """Register ``functions`` with numba (``register_jitable``: callable from a kernel, and still plain
    Python for numpy and sympy) for the kernels of ``kernel_dir``, whose cache is keyed on their source
    files; ``always``: inline them in numba's IR (generated call lists, which must compile as if
    written out). A ValueError if a function's file is neither in that folder, nor listed for it in
    :data:`KERNEL_SOURCES`, nor one of :data:`SHARED_SOURCES`. Every kernel file declares here what it
    inlines (its key is checked at each call), and each function is registered once however many kernel
    files inline it (the rod elements: the per-sample and SIMD Newton-Euler kernels and the f_ext kernel):
    numba keeps every registration as one more overload template of the function."""
    folder = Path(kernel_dir).resolve()
    for f in functions:
        file = Path(inspect.getfile(f)).resolve()
        if file.parent != folder and file not in (*KERNEL_SOURCES.get(folder, ()), *SHARED_SOURCES):
            raise ValueError(
                f"numba cache: {f.__qualname__} of {file} is inlined by the kernels of {folder}: expected its "
                "file listed for that folder in models/machine/numba_cache.py KERNEL_SOURCES (else an edit to it "
                "would leave stale machine code)"
            )
        _register(f, always)


@functools.cache  # once per function: a second registration would add a second overload template
def _register(f: Callable[..., Any], always: bool) -> None:
    if always:
        register_jitable(inline="always")(f)
    else:
        register_jitable(f)


#: The modules of this layer that the kernels of every family compile in: the branch-free sin/cos, the
#: SIMD modules (``simd_*.py``: the blocks of samples, their transposes and the 8 x 8 tiles those move,
#: the angles), the jit options and these keys. Keyed for every kernel folder (a folder that does not
#: use one recompiles for nothing after an edit to it; one that does never serves stale code): their
#: functions are imported by name into the kernel files, not registered through :func:`inline`, and an
#: edit to ``sincos_reduced`` once left the cached SIMD kernels of both families on the old sin/cos.
SHARED_SOURCES = tuple(
    sorted(
        {
            *_HERE.glob("simd_*.py"),
            *(_HERE / f for f in ("fast_trig.py", "numba_runtime.py", "numba_cache.py")),
            _MODELS / "states" / "validation_pass.py",
        }
    )
)


def inlined_sources(kernel_dir: str | Path) -> list[Path]:
    """The source files the kernels of ``kernel_dir`` depend on: every module of that folder, the
    modules of the element functions registered for it, and :data:`SHARED_SOURCES`."""
    folder = Path(kernel_dir).resolve()
    own = [folder] if folder.suffix == ".py" else sorted(p.resolve() for p in folder.glob("*.py"))
    extra = list(KERNEL_SOURCES.get(folder, ())) + list(SHARED_SOURCES)
    return own + list(dict.fromkeys(p for p in extra if p not in own))


@functools.cache  # the sources as this process first read them (the locator asks at each load and save)
def inlined_sources_hash(kernel_dir: Path) -> str:
    h = hashlib.sha256()
    for p in inlined_sources(kernel_dir):
        h.update(str(p.name).encode())
        h.update(p.read_bytes())
    return h.hexdigest()


class KernelSourceLocator(_CacheLocator):
    """numba's own locator for a kernel file of a registered folder, with a source stamp that also
    covers :func:`inlined_sources`."""

    def __init__(self, inner: _CacheLocator, kernel_dir: Path) -> None:
        self._inner = inner
        self._kernel_dir = kernel_dir

    def ensure_cache_path(self) -> None:
        self._inner.ensure_cache_path()

    def get_cache_path(self) -> str:
        return self._inner.get_cache_path()

    def get_disambiguator(self) -> str:
        return self._inner.get_disambiguator()

    def get_source_stamp(self) -> Any:
        return (self._inner.get_source_stamp(), inlined_sources_hash(self._kernel_dir))

    @classmethod
    def from_function(cls, py_func: Callable[..., Any], py_file: str) -> KernelSourceLocator | None:
        try:
            file = Path(py_file).resolve()
        except OSError:
            return None
        folder = file if file in KERNEL_SOURCES else file.parent  # a kernel file of its own, else its folder
        if folder not in KERNEL_SOURCES:
            return None
        for base in _CacheImpl._locator_classes:
            if base is cls:
                continue
            inner = base.from_function(py_func, py_file)
            if inner is not None:
                return cls(inner, folder)
        return None


# --------------------------------------------------------------------------- an installed copy's cache
#: numba's in-tree locator (``InTreeCacheLocator`` in numba 0.68; ``_InTreeCacheLocator`` before).
_InTreeLocator: Any = getattr(caching, "InTreeCacheLocator", None) or getattr(caching, "_InTreeCacheLocator")  # noqa: B009
#: The folder beside an installed package (``<package><suffix>``) that holds its compiled kernels.
INSTALLED_CACHE_SUFFIX = ".numba-cache"


def installed_cache_folder(py_file: str | Path, package: str | Path) -> Path | None:
    """Where numba's cache of ``py_file`` goes when ``package`` is an installed copy of exo_bench:
    ``<package>.numba-cache/<the file's folder relative to the package>``, beside the package, never
    inside it. None for a file outside ``package``."""
    package = Path(package)
    try:
        rel = Path(py_file).resolve().parent.relative_to(package.resolve())
    except (OSError, ValueError):
        return None
    return package.parent / f"{package.name}{INSTALLED_CACHE_SUFFIX}" / rel


def installed_package() -> Path | None:
    """The ``exo_bench`` folder when this is an installed copy (``pip install .``: the modules inside
    the package folder), None in a checkout (the editable install: the modules at the top level)."""
    root = _MODELS.parent
    return root if root.name == "exo_bench" and (root / "__init__.py").is_file() else None


class InstalledCacheLocator(_InTreeLocator):
    """numba's in-tree locator, with the cache folder of an installed copy beside the package instead
    of in its ``__pycache__`` folders (:func:`installed_cache_folder`).

    Why: pip removes only the files it installed. The machine code numba wrote into
    ``site-packages/exo_bench/**/__pycache__`` stayed after ``pip uninstall`` (and after the uninstall
    that ``pip install -e .`` does first), and the ``exo_bench`` folder it kept is a namespace
    package to Python's path finder, which runs before the editable install's finder:
    ``from exo_bench import prepare`` failed with "cannot import name 'prepare'" (issue 38).
    ``exo_bench.numba-cache`` is no package name: left behind, it shadows nothing."""

    def __init__(self, py_func: Callable[..., Any], py_file: str, folder: Path) -> None:
        super().__init__(py_func, py_file)
        self._cache_path = str(folder)

    @classmethod
    def from_function(cls, py_func: Callable[..., Any], py_file: str) -> InstalledCacheLocator | None:
        from numba.core import config

        if getattr(config, "CACHE_DIR", ""):  # NUMBA_CACHE_DIR: the user's choice, numba's own locator
            return None
        package = installed_package()
        folder = installed_cache_folder(py_file, package) if package is not None else None
        return None if folder is None else cls(py_func, py_file, folder)


# --------------------------------------------------------------------------- closures' index keys
def _describe(value: Any, depth: int = 0) -> Any:
    """A description of a closure cell's value that is the same in every process: a compiled or
    plain function by its module, qualified name, bytecode, constants and (recursively) its own cells;
    numbers, strings and tuples by value. ``None`` where there is none (then numba's key is kept)."""
    fn = getattr(value, "py_func", value)
    if inspect.isfunction(fn):
        if depth > 8:
            return None
        cells = tuple(_describe(c.cell_contents, depth + 1) for c in fn.__closure__ or ())
        if any(c is None for c in cells):
            return None
        return ("function", fn.__module__, fn.__qualname__, _code(fn.__code__), cells)
    if isinstance(value, (bool, int, float, str, bytes, type(None))):
        return (type(value).__name__, repr(value))
    if isinstance(value, tuple):
        items = tuple(_describe(v, depth + 1) for v in value)
        return None if any(i is None for i in items) else ("tuple", items)
    return None


def _code(code: Any) -> tuple:
    """A code object by its bytecode and constants (nested code objects alike: their repr holds an address)."""
    consts = tuple(_code(c) if inspect.iscode(c) else repr(c) for c in code.co_consts)
    return (code.co_code, consts)


def index_key_by_code(numba_index_key: Callable[..., Any]) -> Callable[..., Any]:
    """``FunctionCache._index_key`` (numba's, given) except for the closures of a kernel folder: numba
    hashes a closure's cells by pickling them, and a cell holding another kernel (a dispatcher)
    pickles with a random per-process id, so such a kernel (newton-euler's SIMD kernels, closures of
    ``build(lanes)`` that call each other) never hit the cache: each process recompiled it (2-3 s) and
    added a new machine-code file to the cache folder. Here those cells are hashed by
    :func:`_describe`: the same in every process, and different for different block sizes or bytecode."""

    def _index_key(self, sig, codegen):
        key = numba_index_key(self, sig, codegen)
        fn = self._py_func
        if fn.__closure__ is None:
            return key
        try:
            folder = Path(inspect.getfile(fn)).resolve().parent
        except (OSError, TypeError):
            return key
        if folder not in KERNEL_SOURCES:
            return key
        cells = _describe(fn)
        if cells is None:
            return key
        return (key[0], key[1], (key[2][0], hashlib.sha256(repr(cells).encode()).hexdigest()))

    _index_key.keyed_by_code = True  # type: ignore[attr-defined]  # numba_runtime.ensure installs it once
    return _index_key


# --------------------------------------------------------------------------- one writer at a time
@contextlib.contextmanager
def index_lock(index_path: str, shared: bool) -> Iterator[None]:
    """Hold ``<index_path>.lock`` (an ``flock``: shared to read, exclusive to write) while numba reads
    or rewrites a function's cache index. Not held where no lock can be taken (no ``fcntl``, or a
    read-only cache folder without the lock file: no process writes there)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: numba's own unlocked index
        yield
        return
    path = f"{index_path}.lock"
    flags = getattr(os, "O_NOFOLLOW", 0)  # never a link planted in the cache folder
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | flags, 0o666)
    except OSError:
        try:
            fd = os.open(path, os.O_RDONLY | flags)
        except OSError:
            yield
            return
    try:
        fcntl.flock(fd, fcntl.LOCK_SH if shared else fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def index_locked(method: Callable[..., Any], shared: bool) -> Callable[..., Any]:
    """numba's ``IndexDataCacheFile.save`` (``shared=False``) or ``.load`` (``shared=True``), holding
    :func:`index_lock` on the function's index. numba's save reads the index, takes the first free data
    file, rewrites the index and then writes the data, without a lock: two processes saving two
    signatures of one function at once (two commands or Dask workers in one checkout, the test suite's
    two workers on one ``NUMBA_CACHE_DIR``) both took data file 1, and the index left named one
    signature, possibly beside the other's machine code (numba issues 4807, 10128). Saves now take
    turns, and a load never sees an index entry before its data file is written."""

    @functools.wraps(method)
    def locked(self: Any, *args: Any) -> Any:
        with index_lock(self._index_path, shared):
            return method(self, *args)

    locked.index_locked = True  # type: ignore[attr-defined]  # numba_runtime.ensure installs it once
    return locked
