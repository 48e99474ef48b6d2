"""The numba cache directory is keyed on the kernels' sources, whatever the import order;
a callee's edit invalidates its callers, an edit outside the kernels' reach does not."""
import os
import subprocess
import sys
from pathlib import Path

from dem.numba_cache import kernel_digest, kernel_sources

ROOT = Path(__file__).resolve().parent.parent


def _cache_dir_after(imports: str) -> str:
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    code = f"{imports}; import numba; print(numba.config.CACHE_DIR)"
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, check=True,
                         capture_output=True, text=True)
    return out.stdout.strip()


def test_cache_dir_is_keyed_on_sources_when_dem_comes_first():
    assert _cache_dir_after("import dem").endswith(kernel_digest())


def test_cache_dir_is_keyed_on_sources_when_numba_comes_first():
    # numba imported before dem has already read its environment: configure() must still
    # redirect the cache, or kernels fall back to per-file keys in __pycache__ (stale).
    assert _cache_dir_after("import numba; import dem").endswith(kernel_digest())


def test_the_key_covers_the_kernels_callees_and_constants_only():
    """The tier-2 kernels, their callees in dem and the flags module are keyed; the CLI,
    the scenes and the calibration are not (a docstring edit there keeps the cache)."""
    keyed = {str(f.relative_to(ROOT)) for f in kernel_sources()}
    assert {"contfab/models/fabric_cone.py",
            "contfab/models/fabric_law.py", "contfab/models/cone.py", "contfab/jit_flags.py",
            "contfab/tensors.py", "dem/conventions.py", "dem/integrator.py"} <= keyed
    assert not keyed & {"contfab/cli.py", "contfab/scenes/case.py",
                        "contfab/calibration/calibrate.py", "contfab/material_point.py"}


def test_an_edit_of_a_callee_or_a_constant_changes_the_key(tmp_path):
    """A kernel module importing a compiled callee from one module and a constant from
    another (through a package): editing either changes the key, as editing the kernel
    does; editing a module no kernel imports does not."""
    files = {
        "dem/__init__.py": "",
        "dem/kernel.py": "from numba import njit\nfrom dem import callee\nfrom dem.consts import (\n"
                         "    SCALE,  # a global read at compile time\n)\n\n\n@njit(cache=True)\n"
                         "def run(x):\n    return callee.twice(x) * SCALE\n",
        "dem/callee.py": "import numba\n\n\n@numba.njit(cache=True)\ndef twice(x):\n    return 2 * x\n",
        "dem/consts.py": "SCALE = 3.0\n",
        "dem/driver.py": "from dem.kernel import run\n",
        "contfab/__init__.py": "",
        "contfab/cli.py": "import dem.kernel\n",
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text(text)
    assert [str(f.relative_to(tmp_path)) for f in kernel_sources(tmp_path)] == [
        "dem/__init__.py", "dem/callee.py", "dem/consts.py", "dem/kernel.py"]
    key = kernel_digest(tmp_path)
    for name, edit in (("dem/driver.py", "# a comment\n"), ("contfab/cli.py", '"""Doc."""\n'),
                       ("dem/callee.py", "# a comment\n"), ("dem/consts.py", "SCALE = 4.0\n"),
                       ("dem/kernel.py", "# a comment\n")):
        (tmp_path / name).write_text(edit + files[name])
        changed = kernel_digest(tmp_path) != key
        assert changed == (name not in ("dem/driver.py", "contfab/cli.py")), name
        (tmp_path / name).write_text(files[name])
        assert kernel_digest(tmp_path) == key


def test_is_compiled_sees_the_process_and_the_disk_cache(tmp_path):
    """A ``cache=True`` function is not compiled before its first call in a fresh cache,
    is after it, and a new process finds it on disk (the cold / warm cache of a first run)."""
    (tmp_path / "tiny_kernel.py").write_text(
        "from numba import njit\n\n\n@njit(cache=True)\ndef twice(x):\n    return 2 * x\n")
    code = ("import dem.numba_cache as c, tiny_kernel as k; a = c.is_compiled(k.twice); "
            "k.twice(1.0); print(a, c.is_compiled(k.twice))")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join((str(tmp_path), str(ROOT)))}

    def run():
        return subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, check=True,
                              capture_output=True, text=True).stdout.split()
    assert run() == ["False", "True"]          # cold: compiled by the call
    assert run() == ["True", "True"]           # warm: found in the cache directory
