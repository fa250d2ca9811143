"""railtwin's physics: vibro-impact rolling contact of a wheel on a rail (MODEL.md).

Pure functions and plain arrays: no I/O, no Zenoh, MCAP or Rerun here.

One piece of process setup lives here because it must come before numba is imported: the
compiled physics is cached in ``<venv>/numba-cache``, where ``make venv``/``railtwin warm``
put it (the Makefile exports ``NUMBA_CACHE_DIR``). A process started outside make, such
as ``.venv/bin/railtwin diagnose`` from a shell, gets the same directory when it runs in a
virtual environment and ``NUMBA_CACHE_DIR`` is not set; else numba's default applies
(``__pycache__`` beside the sources), whose first use compiles everything again (74 s for
``railtwin diagnose`` on a fresh clone, measured).
"""

import os as _os
import sys as _sys


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


_default_numba_cache()
