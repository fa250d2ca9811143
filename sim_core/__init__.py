"""railtwin's physics: vibro-impact rolling contact of a wheel on a rail (MODEL.md).

Pure functions and plain arrays: no I/O, no Zenoh, MCAP or Rerun here.

One piece of process setup lives here because it must come before numba is imported: the
compiled physics is cached in ``<venv>/numba-cache``, where ``make venv``/``railtwin warm``
put it (the Makefile exports ``NUMBA_CACHE_DIR``). A process started outside make, such
as ``.venv/bin/railtwin diagnose`` from a shell, gets the same directory when it runs in a
virtual environment and ``NUMBA_CACHE_DIR`` is not set; else numba's default applies
(``__pycache__`` beside the sources), whose first use compiles everything again (74 s for
``railtwin diagnose`` on a fresh clone, measured).

A second, for start-up time: numba initialises its CPU target on a process's first compile
or cache load, and one of the modules it then imports (``numba.np.arraymath``) probes for
BLAS with ``import scipy.linalg.cython_blas``. That statement runs all of
``scipy/linalg/__init__.py`` (every decomposition and scipy's array-API layer, which touches
``numpy.f2py`` and ``numpy.testing``): 0.1 s of the 0.2 s numba's first call costs on the
project's machine, for code that calls no BLAS. The probe only needs the extension module,
so ``_preload_cython_blas`` loads that one file (the same file scipy would load, under the
same name) before numba looks; ``scipy.linalg`` is then imported only by code that uses it,
and finds its submodule in ``sys.modules`` (reached by import, as numba reaches it, not as
an attribute of ``scipy.linalg``). Anything unexpected leaves numba's own path.
``tests/test_numba_startup.py`` checks that numba's BLAS and scipy.linalg still work.

A third, also for start-up time: numba 0.68's ``Cache.load_overload`` refreshes the whole
target context before it loads a cached function, which imports and installs every
lowering registry numba has (``numba.cpython.*``, ``numba.np.*``, typed containers,
jitclass, ...), for code that is loaded as machine code and lowered by nothing. Loading
needs only numba's runtime (NRT), which that refresh also initialised (numba issue 2198),
and the LLVM symbols that modules register when imported: numba's C helpers and math
functions are registered when its CPU context is made, and of the registry modules only
``numba.cpython.hashing`` registers any (the hash secret, for cached code that hashes;
``numba.np.ufunc.parallel`` registers its own on first parallel use, and nothing here is
parallel). ``_lean_cache_loads`` replaces the method, for the pinned numba only, with one
that imports ``numba.cpython.hashing``, initialises the runtime and loads; a function that
is not in the cache is compiled by numba's own path, which refreshes the context itself.
A numba pull request proposed the same (numba PR 9806, refresh on a cache hit only where
object mode needs it; closed unmerged); nothing in a railtwin process uses object mode.
Importing ``sim_core`` therefore imports numba (every part of sim_core that computes uses it
anyway). Measured on W01: the first simulation 0.18 -> 0.08 s, ``railtwin diagnose`` 0.70
-> 0.56 s. ``tests/test_numba_startup.py`` checks that a fresh process gives the same
numbers either way, and compiles what the cache lacks, calling cached code.

A fourth, for upgrades: numba's cache index is a pickle of each function's compiled
signatures, and a signature names its argument types. When a new version of the code drops
or renames such a type (a ``NamedTuple`` the stepper once took), unpickling the old index
raises ``AttributeError`` before numba compares its source stamp, and the first call fails
instead of compiling (numba issue 6522; seen here when the stepper's ``State`` became
``Slots``). ``_tolerate_stale_cache_index`` gives the pinned numba an index reader that is
its own but for that one unpickling, where such an error means a stale index: read as empty,
the function compiles, and saving it writes a fresh index over the stale one.

A fifth, for speed: LLVM targets Intel's server CPUs with a preference for 256-bit vectors,
which numba inherits. The track stepper's loops over the modes are bound by their arithmetic
on cache-line-aligned rows (``sim_core.track.lanes``), and with 512-bit vectors they run ~40 %
faster on this project's Emerald Rapids (0.35 -> 0.20 µs a step's pass over 416 modes; the
site case's first wheel 5-6 % faster, docs/benchmarks.md, "sixth round"). ``_wide_vectors``
lifts the preference (numba's ``CPU_FEATURES``: the host's own features plus
``-prefer-256-bit``) on the CPUs of ``WIDE_VECTOR_CPUS``, before numba builds its target;
other CPUs are left as they are. ``NUMBA_CPU_FEATURES`` set by the user wins, so does
``NUMBA_ENABLE_AVX=0``, and ``RAILTWIN_NUMBA_256=1`` keeps LLVM's default (for comparison).
numba's cache keys its entries on the features, so the two builds never mix; a process that
compiles numba code before it imports ``sim_core`` gets LLVM's default (and compiles its own
cache entries). Sums over the modes then reduce in 16 lanes, not 8: results differ from a
256-bit build by float32 rounding (~2e-6 of P), as they may between any two CPUs.
"""

import os as _os
import sys as _sys
from typing import Any


def _default_numba_cache() -> None:
    if "NUMBA_CACHE_DIR" in _os.environ or _sys.prefix == _sys.base_prefix:
        return
    if "numba" in _sys.modules:  # too late: numba read its configuration already
        return
    path = _os.path.join(_sys.prefix, "numba-cache")
    try:
        _os.makedirs(path, exist_ok=True)
    except OSError:
        return
    if _os.access(path, _os.W_OK):
        _os.environ["NUMBA_CACHE_DIR"] = path


def _preload_cython_blas() -> None:
    name = "scipy.linalg.cython_blas"
    if name in _sys.modules or "scipy.linalg" in _sys.modules:
        return
    if "numba.np.arraymath" in _sys.modules:  # too late: the probe has run
        return
    import importlib.machinery as _machinery
    import importlib.util as _util

    try:
        scipy_spec = _util.find_spec("scipy")
    except (ImportError, ValueError):
        return
    if scipy_spec is None or not scipy_spec.submodule_search_locations:
        return
    for root in scipy_spec.submodule_search_locations:
        for suffix in _machinery.EXTENSION_SUFFIXES:
            path = _os.path.join(root, "linalg", "cython_blas" + suffix)
            if not _os.path.isfile(path):
                continue
            loader = _machinery.ExtensionFileLoader(name, path)
            spec = _util.spec_from_file_location(name, path, loader=loader)
            if spec is None:
                return
            module = _util.module_from_spec(spec)
            _sys.modules[name] = module
            try:
                loader.exec_module(module)
            except Exception:  # any failure: numba's own import path
                del _sys.modules[name]
            return


_default_numba_cache()
_preload_cython_blas()


WIDE_VECTOR_CPUS = frozenset({"sapphirerapids", "emeraldrapids", "graniterapids"})
"""LLVM's names of the CPUs whose 512-bit vectors ``_wide_vectors`` lets numba use: Intel's
server cores since Sapphire Rapids, which run them without the deep clock drop of
Skylake-SP and Cascade Lake (measured here on Emerald Rapids). Elsewhere LLVM's own choice
stands."""


def _wide_vectors() -> None:
    if "NUMBA_CPU_FEATURES" in _os.environ or _os.environ.get("RAILTWIN_NUMBA_256", "0") != "0":
        return
    try:
        import llvmlite.binding as ll
        from numba.core import config
    except ImportError:
        return
    if getattr(config, "CPU_FEATURES", None) is not None or not getattr(config, "ENABLE_AVX", True):
        return
    try:
        name = ll.get_host_cpu_name()
        features = ll.get_host_cpu_features()
    except RuntimeError:  # llvmlite cannot read this host's features: leave numba's default
        return
    if name in WIDE_VECTOR_CPUS and features.get("avx512f"):
        setattr(config, "CPU_FEATURES", features.flatten() + ",-prefer-256-bit")  # noqa: B010


_LEAN_NUMBA = "0.68.1"
"""The numba whose ``Cache.load_overload`` ``_lean_cache_loads`` knows (pyproject pins it)."""


def _lean_cache_loads() -> None:
    if _os.environ.get("RAILTWIN_NUMBA_FULL_REFRESH"):  # numba's own path, for comparison
        return
    try:
        import numba
        import numba.cpython.hashing  # registers the hash secret's LLVM symbols
        from numba.core import caching
        from numba.core.runtime import rtsys
    except ImportError:
        return
    if numba.__version__ != _LEAN_NUMBA or getattr(caching.Cache, "_railtwin_lean", False):
        return

    def load_overload(self: caching.Cache, sig: object, target_context: object) -> object:
        rtsys.initialize(target_context)  # what loading machine code needs of the refresh
        with self._guard_against_spurious_io_errors():
            return self._load_overload(sig, target_context)

    caching.Cache.load_overload = load_overload  # type: ignore[method-assign]
    caching.Cache._railtwin_lean = True  # type: ignore[attr-defined]


_wide_vectors()
_lean_cache_loads()


def _tolerate_stale_cache_index() -> None:
    try:
        import pickle

        import numba
        from numba.core import caching
    except ImportError:
        return
    index = getattr(caching, "IndexDataCacheFile", None)
    if (
        numba.__version__ != _LEAN_NUMBA
        or index is None
        or getattr(index, "_railtwin_tolerant", False)
    ):
        return

    def _load_index(self: Any) -> dict[Any, Any]:
        # numba 0.68.1's own, but for the one unpickling of the signatures
        try:
            with open(self._index_path, "rb") as f:
                version = pickle.load(f)
                data = f.read()
        except FileNotFoundError:
            return {}
        if version != self._version:
            return {}
        try:
            stamp, overloads = pickle.loads(data)
        except (AttributeError, ImportError, pickle.UnpicklingError, EOFError):
            return {}  # written by code that named a type this code no longer has: stale
        if stamp != self._source_stamp:
            return {}
        result: dict[Any, Any] = overloads
        return result

    index._load_index = _load_index
    index._railtwin_tolerant = True


_tolerate_stale_cache_index()
