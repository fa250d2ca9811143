"""Numba's start-up without scipy.linalg (``sim_core/__init__.py``'s ``_preload_cython_blas``).

The preload must change only when scipy.linalg is imported, never what anything computes:
numba's BLAS calls still reach the same Cython module, and a later ``import scipy.linalg``
finds and uses it. Run in a fresh interpreter, as the preload only acts before numba's
first compile.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

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
