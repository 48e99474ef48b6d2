"""A wheel install runs the cases: the scenes and their data are packaged, and nothing in
the library reaches for files of the checkout."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _run(cmd: list[str], cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, f"{' '.join(cmd)}\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}"
    return done


def test_a_wheel_install_runs_a_case_outside_the_checkout(tmp_path):
    from contfab.scenes.case import SCENES

    # built from a copy of what the wheel is made of, so the build leaves nothing here
    source = tmp_path / "source"
    for name in ("contfab", "dem"):
        shutil.copytree(ROOT / name, source / name, ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, source / name)
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q",
          "-w", str(tmp_path / "dist"), str(source)], cwd=tmp_path)
    wheel = next((tmp_path / "dist").glob("contfab-*.whl"))
    names = set(zipfile.ZipFile(wheel).namelist())
    for scene in SCENES:
        assert f"contfab/scenes/{scene}.py" in names
    for data in ("contfab/scenes/data/simple_shear_reversal_dem.csv",
                 "contfab/selection/data/tier_errors.csv", "contfab/data/default_params.toml",
                 "dem/paths/biaxial.toml"):
        assert data in names

    # a venv that sees this interpreter's dependencies, with the wheel installed in it: its
    # own site-packages comes first, so `contfab` is the wheel's, not the checkout's
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], cwd=tmp_path)
    py = venv / ("Scripts" if os.name == "nt" else "bin") / "python"
    _run([str(py), "-m", "pip", "install", "-q", "--no-deps", "--no-index", str(wheel)],
         cwd=tmp_path)
    where = _run([str(py), "-c", "import contfab; print(contfab.__file__)"], cwd=tmp_path)
    assert Path(where.stdout.strip()).is_relative_to(venv)

    out = tmp_path / "out"
    # the footing at constant angles (the main job's tier-0 check; the calibrated run is
    # tests/test_fem_cases.py's): its scene, mesh and references come from the wheel
    done = _run([str(py), "-m", "contfab.cli", "case", "strip_footing", "--tier", "0", "--fast",
                 "--json", "--quiet", "--out", str(out)], cwd=tmp_path)
    result = json.loads(done.stdout)
    assert abs(result["relative_error"]) < 0.05  # N_q against Prandtl–Reissner, coarse preset
    assert any(out.glob("*.pvd"))
