"""dem: an embedded 2D disc-DEM representative volume element (periodic cell).

Does not import :mod:`contfab`; the continuum side imports the loading-path
description (:mod:`dem.paths`) and the shared conventions (:mod:`dem.conventions`)
from here.
"""
import os as _os

from dem.numba_cache import configure as _configure_numba_cache

_configure_numba_cache()
# Waiting OpenMP threads sleep instead of spinning: a spinning barrier with a descheduled
# thread stalls each join (measured on 2 shared cores: 2 threads 0.8e6 particle-steps/s
# spinning vs 4.4e6 passive). The DEM itself runs on one thread unless asked (dem.threads).
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
