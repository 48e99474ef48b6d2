"""The executor: the same jobs through serial, a spawned process pool and dask give
identical results (material-point runs and DEM sample preparations, both numba), in
order; a failing job raises; bad requests are refused with a clear message."""
import functools
import sys

import numpy as np
import pytest

from contfab import material_point as mp
from contfab.executor import ExecutorError, make_executor
from dem.job import Settings, prepare_sample


_warm = functools.partial(mp.run_path, "biaxial", None, 1, increment=0.05)
"""Load the model kernels once per worker (the executor's warm-up hook)."""


def _run_both(kind):
    point = functools.partial(mp.run_path, "isochoric_shear", None)
    prepare = functools.partial(prepare_sample, progress=False)
    dem = [Settings(n=24, seed=s, kappa=1e3, mu=0.5, mu_prep=0.0) for s in (1, 2)]
    with make_executor(kind, workers=2, warm=_warm) as ex:
        runs = ex.map(point, [0, 1, 2], desc="points", progress=False)
        states = [st for st, _, _ in ex.map(prepare, dem, desc="prepare", progress=False)]
    return runs, states


@pytest.mark.parametrize("kind", ["pool", "dask"])
def test_pool_and_dask_equal_serial_bitwise(kind):
    ser_runs, ser_states = _run_both("serial")
    par_runs, par_states = _run_both(kind)
    for a, b, tier in zip(ser_runs, par_runs, [0, 1, 2]):
        assert a.tier == tier == b.tier                             # order kept
        for col in a.columns:
            assert np.array_equal(a[col], b[col]), col
    for a, b in zip(ser_states, par_states):
        assert a.step == b.step > 0
        assert np.array_equal(a.s, b.s) and np.array_equal(a.pair_hist, b.pair_hist)
    assert not np.array_equal(ser_states[0].s, ser_states[1].s)    # two seeds, two samples


def test_a_failing_job_raises_in_map():
    with make_executor("serial") as ex:
        with pytest.raises(ValueError, match="unknown loading path"):
            ex.map(functools.partial(mp.run_path, params=None), ["biaxial", "no_such_path", "biaxial"],
                   progress=False)


def test_bad_executor_requests(monkeypatch):
    with pytest.raises(ExecutorError, match="executor 'threads' is not known; accepted: serial, pool, dask"):
        make_executor("threads")
    with pytest.raises(ExecutorError, match="workers = 0 out of range"):
        make_executor("pool", workers=0)
    with pytest.raises(ExecutorError, match="needs the dask executor"):
        make_executor("pool", scheduler="tcp://127.0.0.1:8786")
    monkeypatch.setitem(sys.modules, "dask.distributed", None)      # dask not installed
    with pytest.raises(ExecutorError, match=r"pip install 'contfab\[dist\]'"):
        make_executor("dask", workers=1)
