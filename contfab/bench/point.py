"""``contfab bench point``: the cost of a material-point step, and what the increment buys.

Cost: microseconds per accepted increment of the driver (:mod:`contfab.material_point`)
for every registered tier, on the standard biaxial path (mixed control: one Newton solve
per increment, dense start c0 = 0.83) and on the isochoric shear (strain control: one
update per increment), with the update evaluations per increment. Single thread, CPU
time of the process (a per-core figure), median of ``--repeats``.

Trade: the biaxial path at tier 1 (dense) with the increment knob 2.5e-3 ... 3.1e-4 in
reference strain: the maximum error over all output rows of R/P and of c against a run
at 1/64 of the coarsest increment, with the run's CPU time. Backward Euler is first order,
so each halving should halve the error and double the time.
"""
from __future__ import annotations

import time

import numpy as np

from contfab import material_point as mp
from contfab.bench import median_seconds
from contfab.models import tiers
from contfab.params import default_params

DENSE = {"c": 0.83}
TRADE_INCREMENTS = (2.5e-3, 1.25e-3, 6.25e-4, 3.125e-4)
REFERENCE_FRACTION = 1.0 / 64.0


def _state0(tier):
    return DENSE if "c" in tiers.STATE_NAMES[tier] else None


def run(args) -> dict:
    repeats = getattr(args, "repeats", 5)
    params = default_params()
    figures: dict[str, float] = {}
    for tier in sorted(tiers.KERNELS):
        for name in ("biaxial", "isochoric_shear"):
            kw = dict(increment=mp.DEFAULT_INCREMENT, state0=_state0(tier))
            res = mp.run_path(name, params, tier, **kw)
            seconds = median_seconds(lambda: mp.run_path(name, params, tier, **kw),
                                     repeats=repeats, clock=time.process_time)
            n = res.stats["increments"]
            figures[f"tier{tier}_{name}_us_per_increment"] = 1e6 * seconds / n
            figures[f"tier{tier}_{name}_updates_per_increment"] = res.stats["evaluations"] / n
    ref = mp.run_path("biaxial", params, 1, increment=TRADE_INCREMENTS[0] * REFERENCE_FRACTION,
                      state0=DENSE)
    for h in TRADE_INCREMENTS:
        res = mp.run_path("biaxial", params, 1, increment=h, state0=DENSE)
        seconds = median_seconds(lambda: mp.run_path("biaxial", params, 1, increment=h,
                                                     state0=DENSE),
                                 repeats=repeats, clock=time.process_time)
        key = f"tier1_biaxial_h{h:.4g}"
        figures[f"{key}_error_RP"] = float(np.max(np.abs(res["RP"] - ref["RP"])))
        figures[f"{key}_error_c"] = float(np.max(np.abs(res["c"] - ref["c"])))
        figures[f"{key}_ms"] = 1e3 * seconds
    return figures
