"""dem: an embedded 2D disc-DEM representative volume element (periodic cell).

Does not import :mod:`contfab`; the continuum side imports the loading-path
description (:mod:`dem.paths`) and the shared conventions (:mod:`dem.conventions`)
from here.
"""
from dem.numba_cache import configure as _configure_numba_cache

_configure_numba_cache()
