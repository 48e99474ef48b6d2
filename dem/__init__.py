"""dem: an embedded 2D disc-DEM representative volume element (periodic cell).

Does not import :mod:`contfab`; the continuum side imports the loading-path
description (:mod:`dem.paths`) and the shared conventions (:mod:`dem.conventions`)
from here.
"""
import os as _os

from dem.numba_cache import configure as _configure_numba_cache

_configure_numba_cache()
# Parallel kernels synchronize several times per DEM step. With GNU OpenMP's default
# spinning barrier, a thread descheduled on a busy machine stalls every step (measured on
# 2 shared cores: 2 threads 0.8e6 particle-steps/s spinning vs 4.4e6 passive, 1 thread 8.4e6).
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
