"""Calibration from the DEM: run the campaign, reduce the curves, fit, report.

Data flow: a loading path (:mod:`dem.paths`) runs in the DEM (:mod:`campaign`: the
campaign's runs, resumable, through an executor) and on the material point
(:mod:`point_job` writes one point run); :mod:`curves` reads both histories into the
same quantities; :mod:`fitting` fits tier 1 and tier 2 by least squares on them;
:mod:`calibrate` runs the whole pipeline (``contfab calibrate``) and :mod:`report` writes
overlays and error tables; :mod:`probing` maps the incremental response (stress probes);
:mod:`compare` puts the DEM and the model side by side on one path (``contfab compare``).
"""
