"""The numba cache directory is keyed on the project's sources, whatever the import order."""
import os
import subprocess
import sys
from pathlib import Path

from dem.numba_cache import source_digest

ROOT = Path(__file__).resolve().parent.parent


def _cache_dir_after(imports: str) -> str:
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    code = f"{imports}; import numba; print(numba.config.CACHE_DIR)"
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, check=True,
                         capture_output=True, text=True)
    return out.stdout.strip()


def test_cache_dir_is_keyed_on_sources_when_dem_comes_first():
    assert _cache_dir_after("import dem").endswith(source_digest())


def test_cache_dir_is_keyed_on_sources_when_numba_comes_first():
    # numba imported before dem has already read its environment: configure() must still
    # redirect the cache, or kernels fall back to per-file keys in __pycache__ (stale).
    assert _cache_dir_after("import numba; import dem").endswith(source_digest())
