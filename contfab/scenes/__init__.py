"""Boundary-value scenes: each a case with its geometry, loading and published reference.

:mod:`case` holds what every case shares (discovery, common options, the figure against
its reference); each other module is one case, runnable as ``contfab case NAME`` or
``python cases/NAME.py``.
"""
