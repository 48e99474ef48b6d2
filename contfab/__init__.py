"""contfab: a micro-informed rigid-plastic fabric model for granular materials.

Model tiers, return mapping kernels, the material-point driver, calibration from the
embedded DEM (:mod:`dem`), and a scikit-fem boundary-value solver.
"""
import dem as _dem  # noqa: F401  (configures the numba cache before any kernel loads)

__version__ = "0.1.0"
