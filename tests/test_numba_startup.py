"""Numba's start-up (``sim_core/__init__.py``): without scipy.linalg
(``_preload_cython_blas``), and cache loads that leave numba's lowering registries alone
(``_lean_cache_loads``).

The preload must change only when scipy.linalg is imported, never what anything computes:
numba's BLAS calls still reach the same Cython module, and a later ``import scipy.linalg``
finds and uses it. The lean cache loads must change only what is imported: a diagnosis
gives the same numbers to the last bit as with numba's full refresh, and a function the
cache lacks is still compiled. Run in fresh interpreters, as both act on a process's first
cache load or compile.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

_SCRIPT = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    import sim_core  # noqa: F401  (the preload)
    import numba

    @numba.njit
    def matmul(a, b):
        return np.dot(a, b)

    a = np.array([[1.0, 2.0], [3.0, 4.0]])
    product = matmul(a, a).tolist()  # numba's first compile, then BLAS dgemm
    before = "scipy.linalg" in sys.modules
    blas = sys.modules.get("scipy.linalg.cython_blas")
    import importlib
    import scipy.linalg
    solved = scipy.linalg.solve(a, np.array([5.0, 6.0])).tolist()
    print(json.dumps({
        "product": product,
        "scipy_linalg_before": before,
        "preloaded": blas is not None,
        "same_module": blas is importlib.import_module("scipy.linalg.cython_blas"),
        "solved": solved,
    }))
    """
)


def _run() -> dict[str, object]:
    done = subprocess.run(
        [sys.executable, "-c", _SCRIPT], capture_output=True, text=True, timeout=300, check=True
    )
    result: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def test_numbas_first_compile_does_not_import_scipy_linalg_and_blas_still_works() -> None:
    out = _run()
    assert out["scipy_linalg_before"] is False
    assert out["preloaded"] is True
    assert out["product"] == [[7.0, 10.0], [15.0, 22.0]]
    # scipy.linalg imported afterwards uses the very module numba's BLAS calls go through
    assert out["same_module"] is True
    solved = out["solved"]
    assert isinstance(solved, list)
    assert abs(solved[0] - (-4.0)) < 1e-12 and abs(solved[1] - 4.5) < 1e-12


_DIAGNOSE = textwrap.dedent(
    """
    import io, json, sys
    from contextlib import redirect_stdout
    from service.cli.main import main
    wide, passage = sys.argv[1], sys.argv[2]
    out = io.StringIO()
    with redirect_stdout(out):
        code = main(["diagnose", "--site", f"{wide}/W01.site.toml", "--passage", passage,
                     "--measured", f"{wide}/W01.csv", "--format", "json"])
    diagnosis = json.loads(out.getvalue())
    diagnosis.pop("wall_time")
    import numba
    import numpy as np
    from sim_core.contact_laws import contact_force

    @numba.njit(cache=False)
    def fresh(x):  # not in any cache: compiled here, calling cached code
        return np.sum(np.sqrt(x)) + contact_force(1e-4, 0, 1e8, 0.0, 0.0, 0.0)

    lowered_before = "numba.np.npyimpl" in sys.modules
    compiled = fresh(np.array([4.0, 9.0]))
    print(json.dumps({"code": code, "diagnosis": diagnosis, "lowered": lowered_before,
                      "compiled": compiled}))
    """
)


def _diagnose_w01(tmp_path: Path, full_refresh: bool) -> dict[str, object]:
    from validation.wide_set import WIDE_DIR, load_case

    passage = tmp_path / "W01.passage.json"
    passage.write_text(load_case("W01").passage.model_dump_json(), encoding="utf-8")
    env = dict(os.environ)
    env.pop("RAILTWIN_NUMBA_FULL_REFRESH", None)
    if full_refresh:
        env["RAILTWIN_NUMBA_FULL_REFRESH"] = "1"
    done = subprocess.run(
        [sys.executable, "-c", _DIAGNOSE, str(WIDE_DIR), str(passage)],
        capture_output=True,
        text=True,
        timeout=600,
        check=True,
        env=env,
    )
    result: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def test_lean_cache_loads_change_what_is_imported_not_what_is_computed(tmp_path: Path) -> None:
    _diagnose_w01(tmp_path, full_refresh=False)  # fills the cache, should anything lack
    lean = _diagnose_w01(tmp_path, full_refresh=False)
    full = _diagnose_w01(tmp_path, full_refresh=True)
    assert lean["code"] == full["code"] == 0
    assert lean["diagnosis"] == full["diagnosis"]  # every number, to the last bit
    # the lowering registries were not imported to load the cached physics...
    assert lean["lowered"] is False and full["lowered"] is True
    # ...and a function no cache holds is still compiled (numba's own path)
    assert lean["compiled"] == full["compiled"] == pytest.approx(5.0 + 1e8 * 1e-6)


def test_a_cache_index_naming_a_type_the_code_no_longer_has_reads_as_stale(
    tmp_path: Path,
) -> None:
    """An index pickled by older code whose signatures name a class that is gone (the stepper's
    ``State`` once): numba would raise ``AttributeError`` on the first call; the function must
    compile instead, and its save must replace the stale index."""
    src = tmp_path / "cached_mod.py"
    src.write_text(
        textwrap.dedent(
            """
            import numba

            @numba.njit(cache=True)
            def twice(x):
                return 2.0 * x
            """
        )
    )
    probe = textwrap.dedent(
        """
        import pickle, sys
        from pathlib import Path
        import sim_core  # noqa: F401  (the tolerant index)
        import numba
        sys.path.insert(0, sys.argv[1])
        import cached_mod
        assert cached_mod.twice(2.0) == 4.0  # compiled, index written
        index = next(Path(sys.argv[2]).rglob("*.nbi"))
        # rewrite the index as older code would have left it: its pickle names a class of a
        # module that no longer defines it
        with open(index, "rb") as f:
            version = pickle.load(f)
            stamp, overloads = pickle.loads(f.read())
        class Gone:  # a type the next process will not find
            pass
        Gone.__module__ = "cached_mod"
        Gone.__qualname__ = "GoneState"
        cached_mod.GoneState = Gone
        with open(index, "wb") as f:
            pickle.dump(version, f, protocol=-1)
            f.write(pickle.dumps((stamp, {**overloads, ("sig", Gone): "x.nbc"}), protocol=-1))
        print(index)
        """
    )
    cache = tmp_path / "cache"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    out = subprocess.run(
        [sys.executable, "-c", probe, str(tmp_path), str(cache)],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    index = Path(out.stdout.strip().splitlines()[-1])
    second = textwrap.dedent(
        """
        import sys
        import sim_core  # noqa: F401
        sys.path.insert(0, sys.argv[1])
        import cached_mod
        print(cached_mod.twice(3.0))
        """
    )
    run = subprocess.run(
        [sys.executable, "-c", second, str(tmp_path)],
        env=env,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "6.0"
    # the stale index was replaced: a process without the tolerance reads it too
    plain = textwrap.dedent(
        """
        import pickle, sys
        with open(sys.argv[1], "rb") as f:
            pickle.load(f)
            pickle.loads(f.read())
        print("ok")
        """
    )
    check = subprocess.run(
        [sys.executable, "-c", plain, str(index)], capture_output=True, text=True
    )
    assert check.stdout.strip() == "ok", check.stderr


_FEATURES_PROBE = textwrap.dedent(
    """
    import json
    import llvmlite.binding as ll
    import sim_core  # noqa: F401  (the vector width)
    import numba
    from numba.core import config
    from numba.core.registry import cpu_target
    print(json.dumps({
        "wide": bool(ll.get_host_cpu_features().get("avx512f"))
        and ll.get_host_cpu_name() in sim_core.WIDE_VECTOR_CPUS,
        "config": config.CPU_FEATURES,
        "target": cpu_target.target_context.codegen()._tm_features,
    }))
    """
)


def _features(env: dict[str, str]) -> dict[str, object]:
    base = {
        k: v for k, v in os.environ.items() if k not in ("NUMBA_CPU_FEATURES", "RAILTWIN_NUMBA_256")
    }
    out = subprocess.run(
        [sys.executable, "-c", _FEATURES_PROBE],
        env={**base, **env},
        capture_output=True,
        text=True,
        check=True,
    )
    result: dict[str, object] = json.loads(out.stdout.strip().splitlines()[-1])
    return result


def test_wide_vectors_only_on_the_listed_cpus() -> None:
    """numba's target lifts LLVM's 256-bit preference on the CPUs of ``WIDE_VECTOR_CPUS``,
    before it is built; elsewhere, and when asked not to, numba's default stands; a user's own
    ``NUMBA_CPU_FEATURES`` wins, and so does ``NUMBA_ENABLE_AVX=0``."""
    got = _features({})
    if got["wide"]:
        assert isinstance(got["config"], str) and got["config"].endswith(",-prefer-256-bit")
        assert "-prefer-256-bit" in str(got["target"])
    else:
        assert got["config"] is None
        assert "prefer-256-bit" not in str(got["target"])
    assert _features({"RAILTWIN_NUMBA_256": "1"})["config"] is None
    assert _features({"NUMBA_ENABLE_AVX": "0"})["config"] is None
    assert _features({"RAILTWIN_NUMBA_256": "0"})["config"] == got["config"]
    own = _features({"NUMBA_CPU_FEATURES": "+sse2"})
    assert own["config"] == "+sse2"
