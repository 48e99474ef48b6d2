"""Numerical stability at the extremes: a declarative matrix per component.

:mod:`.core` judges one point (PASS / ACCURACY_LOST / CLEAR_ERROR / FAIL);
:mod:`.dem_matrix`, :mod:`.point_matrix`, :mod:`.fem_matrix` declare the points of the
DEM, the material point and the FEM; :mod:`.report` runs a matrix and writes
``stability.csv`` and ``stability.png``.
"""
