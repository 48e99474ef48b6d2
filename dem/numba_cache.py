"""Point numba's on-disk cache at a directory keyed on the project's source.

numba's ``cache=True`` keys a cached kernel on its *own* file only: editing a
callee in another module leaves callers' caches stale (a caller then runs the
old callee). contfab kernels call :mod:`dem.conventions`, so a per-file key is
not enough. Before numba is imported we set ``NUMBA_CACHE_DIR`` to
``~/.cache/contfab/numba/<hash of every .py file in dem/ and contfab/>``: any edit
anywhere gives a fresh cache, an unchanged tree reuses the warm one.

A user who sets ``NUMBA_CACHE_DIR`` keeps it (and owns its staleness). If numba was
imported first (a test's ``import numba`` before ``import dem``), numba has already read
its environment, so the directory is also set on ``numba.config.CACHE_DIR``, which the
cache locator reads when each ``cache=True`` kernel is decorated; otherwise those kernels
fell back to ``__pycache__`` with per-file keys — measured here: a stale tier-2 kernel
loaded from there looped forever after a callee in another module changed.
"""
from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path


def source_digest(packages: tuple[str, ...] = ("dem", "contfab")) -> str:
    """SHA-1 over the relative path and bytes of every .py file of ``packages`` (both by
    default; ``("dem",)`` keys results that depend on the DEM's code only)."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha1()
    for pkg in packages:
        for f in sorted((root / pkg).rglob("*.py")):
            h.update(str(f.relative_to(root)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()[:16]


def configure() -> None:
    """Set NUMBA_CACHE_DIR (and numba's config if numba is loaded) unless the user set it."""
    if "NUMBA_CACHE_DIR" in os.environ:
        return
    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    os.environ["NUMBA_CACHE_DIR"] = str(base / "contfab" / "numba" / source_digest())
    if "numba" in sys.modules:
        sys.modules["numba"].config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]
