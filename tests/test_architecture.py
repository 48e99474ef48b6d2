"""The layers of docs/architecture.md hold: the import-linter contracts of pyproject.toml
are kept by the code, and a forbidden import breaks them."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _lint(root: Path) -> subprocess.CompletedProcess:
    """lint-imports on the tree at ``root`` (its pyproject.toml, its packages first on the path)."""
    code = ("import sys; from importlinter.cli import lint_imports; "
            "sys.exit(lint_imports(config_filename='pyproject.toml', no_cache=True))")
    return subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True,
                          text=True, timeout=120, env={"PYTHONPATH": str(root), "PATH": ""})


def test_the_code_keeps_the_layer_contracts():
    done = _lint(ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "2 kept, 0 broken" in done.stdout


def test_a_forbidden_import_breaks_them(tmp_path):
    """The FEM importing a study and the DEM importing contfab are both caught."""
    for name in ("contfab", "dem"):
        shutil.copytree(ROOT / name, tmp_path / name,
                        ignore=shutil.ignore_patterns("__pycache__", "*.png", "*.csv"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    with open(tmp_path / "contfab" / "fem" / "mesh.py", "a") as fh:
        fh.write("\nimport contfab.tradeoff  # noqa\n")
    with open(tmp_path / "dem" / "paths.py", "a") as fh:
        fh.write("\nimport contfab.params  # noqa\n")
    done = _lint(tmp_path)
    assert done.returncode != 0
    assert "0 kept, 2 broken" in done.stdout
    assert "contfab.fem.mesh -> contfab.tradeoff" in done.stdout
    assert "dem.paths -> contfab.params" in done.stdout
