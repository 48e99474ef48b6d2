"""Checkpoints: restart is bitwise identical (acceptance 6); clones are independent."""
import numpy as np
import pytest

from conftest import make_dynamics
from dem import checkpoint
from dem.paths import parse_path
from dem.rve import PathRunner

PATH = parse_path({"name": "short_biaxial", "stage": [
    {"name": "compress", "length": 0.01, "output_every": 0.001, "L": {"yy": -1.0},
     "sigma": {"xx": -1.0}},
    {"name": "shear", "length": 0.01, "output_every": 0.001, "L": {"xy": 1.0},
     "sigma": {"yy": -1.0}}]})


def test_restart_from_a_mid_run_checkpoint_is_bitwise_identical(packing_frictional, tmp_path):
    st = packing_frictional.copy()
    dyn = make_dynamics(st, gdot=1e-2)
    runner = PathRunner(PATH, dyn, 1e-2)
    run = runner.start(st)
    runner.run(st, run, max_rows=13)          # into the second stage
    assert run.stage == 1 and not run.finished
    f = checkpoint.save(tmp_path / "mid.npz", st, dyn, run, {"note": "test"})
    runner.run(st, run)                       # the uninterrupted run goes on
    st2, dyn2, run2, settings = checkpoint.load(f)
    assert dyn2 == dyn and settings == {"note": "test"}
    PathRunner(PATH, dyn2, 1e-2).run(st2, run2)
    assert run2.rows == run.rows and len(run.rows) == 23  # 1 + 2 x (10 rows + stage end)
    for name, arr in st.arrays().items():
        assert np.array_equal(arr, st2.arrays()[name]), name
    assert (st2.step, st2.n_pairs, st2.rebuilds) == (st.step, st.n_pairs, st.rebuilds)


def test_clones_of_one_checkpoint_are_independent(packing_frictional, tmp_path):
    st = packing_frictional.copy()
    dyn = make_dynamics(st, gdot=1e-2)
    f = checkpoint.save(tmp_path / "c.npz", st, dyn)
    a, _, run, _ = checkpoint.load(f)
    b, _, _, _ = checkpoint.load(f)
    assert run is None
    a.v += 1.0
    assert not np.array_equal(a.v, b.v) and np.array_equal(b.v, st.v)


def test_garbage_is_not_a_checkpoint(tmp_path):
    bad = tmp_path / "x.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(checkpoint.CheckpointError, match="cannot read"):
        checkpoint.load(bad)
