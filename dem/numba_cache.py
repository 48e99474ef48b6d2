"""Point numba's on-disk cache at a directory keyed on the project's source.

numba's ``cache=True`` keys a cached kernel on its *own* file only: editing a
callee in another module leaves callers' caches stale (ENGINEERING.md, seen on this
machine class). contfab kernels call :mod:`dem.conventions`, so a per-file key is
not enough. Before numba is imported we set ``NUMBA_CACHE_DIR`` to
``~/.cache/contfab/numba/<hash of every .py file in dem/ and contfab/>``: any edit
anywhere gives a fresh cache, an unchanged tree reuses the warm one.

A user who sets ``NUMBA_CACHE_DIR`` keeps it (and owns its staleness).
"""
from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path


def source_digest() -> str:
    """SHA-1 over the relative path and bytes of every .py file of both packages."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha1()
    for pkg in ("dem", "contfab"):
        for f in sorted((root / pkg).rglob("*.py")):
            h.update(str(f.relative_to(root)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()[:16]


def configure() -> None:
    """Set NUMBA_CACHE_DIR unless the user did, or numba is already imported."""
    if "NUMBA_CACHE_DIR" in os.environ or "numba" in sys.modules:
        return
    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    os.environ["NUMBA_CACHE_DIR"] = str(base / "contfab" / "numba" / source_digest())
