"""Model selection: which tier a point needs.

:mod:`indicators` measures the loading a point sees (rotation of the principal stress
axes, reversal, distance from the critical state); :mod:`auto_tier` holds the measured
error bound of each model per loading class and chooses the cheapest model that meets a
tolerance (``tier = "auto"``).
"""
