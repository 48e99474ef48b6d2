"""Provenance recorded in every result sidecar: code version and library versions."""
from __future__ import annotations

import platform
import subprocess
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path


def code_versions() -> dict:
    """Package version, git commit of the checkout (and whether it is dirty), libraries."""
    import numba
    import numpy
    import scipy

    try:
        own = version("contfab")
    except PackageNotFoundError:
        own = None
    here = Path(__file__).parent
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True,
                                text=True, timeout=5).stdout.strip() or None
        dirty = bool(subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                                    cwd=here, capture_output=True, text=True,
                                    timeout=5).stdout.strip()) if commit else None
    except (OSError, subprocess.SubprocessError):
        commit, dirty = None, None
    return {"contfab": own, "git_commit": commit, "git_dirty": dirty,
            "python": platform.python_version(), "numpy": numpy.__version__,
            "numba": numba.__version__, "scipy": scipy.__version__}
