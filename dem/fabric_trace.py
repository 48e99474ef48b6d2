"""The trace of the volume-weighted fabric of frictionless packings against Madadi et al. (2004).

Madadi et al. (2004, eq. 11) predict tr<F>_V = C̄ ν g2 with g2 of eq. (12) (exact) computed
from the size distribution (:func:`dem.measure.g2_exact`, applied to the sample's own
radii, as the paper does with its local g2). This module prepares a frictionless packing
at a target packing fraction ν (:func:`dem.prepare.compress_to_fraction`) and reports

    ratio = tr<F>_V / (C̄ ν g2)      (C̄ = mean contacts per disc, rattlers included,
                                      as in the paper's evaluation)
    ratio_no_rattlers               (the same with rattlers and their contacts removed
                                      from tr<F>_V, C̄, ν and g2)
    z_no_rattlers                   (C̄ with rattlers excluded; >= 4 for a jammed
                                      frictionless packing, isostaticity)

and the nominal g2 of the distribution (1.223 for bidisperse 1:3 50/50 and 1.085 for
uniform w0 = 0.5 in the paper).
"""
from __future__ import annotations

import numpy as np

from dem.contact_law import ContactLaw
from dem.integrator import Dynamics, time_step
from dem.measure import Contacts, g2_exact, measure, rattler_mask
from dem.particles import parse_radii, sample_radii
from dem.prepare import compress_to_fraction, random_gas
from dem.servo import time_constant


def fabric_trace(radii: str, n: int, c: float, seed: int = 0, kn: float = 1e3, e: float = 0.3,
                 rate: float = 1e-2, max_steps: int = 3_000_000, progress=None) -> dict:
    """Prepare a frictionless packing of ``n`` discs at packing fraction ``c``; figures above."""
    rng = np.random.default_rng(seed)
    radius = sample_radii(parse_radii(radii), n, rng)
    st = random_gas(radius, 0.3, rng)
    law = ContactLaw(kn=kn, e=e, mu=0.0)
    dyn = Dynamics(law, time_step(law, st.mass.min()), 0.2 * float(2 * radius.mean()), rate,
                   time_constant(kn), rate)
    st, info = compress_to_fraction(st, dyn, c, rate, max_steps=max_steps, progress=progress)
    m = measure(st, law)
    cts = Contacts(st)
    ratt = rattler_mask(st.n, cts.i, cts.j, 3)
    keep = ~ratt
    trf = m["trF_V"]
    z = m["z"]
    g2 = g2_exact(st.radius)
    ratio = trf / (z * m["c"] * g2)
    # without rattlers: contacts between non-rattlers only, normalized by non-rattlers
    live = keep[cts.i] & keep[cts.j]
    counts = np.bincount(cts.i[live], minlength=st.n) + np.bincount(cts.j[live], minlength=st.n)
    area_live = np.pi * st.radius[keep] ** 2
    trf_nr = float(np.sum(area_live * counts[keep]) / st.volume)
    c_nr = float(area_live.sum() / st.volume)
    z_nr = float(counts[keep].mean()) if keep.any() else 0.0
    g2_nr = g2_exact(st.radius[keep]) if keep.any() else float("nan")
    return {"radii": radii, "n": n, "seed": seed, "c_target": c, "c": m["c"], "P": m["P"],
            "kn": kn, "relaxed": info.relaxed, "steps": info.steps,
            "unbalanced": info.unbalanced, "kinetic_ratio": info.kinetic_ratio,
            "trF_V": trf, "z": z, "g2_sample": g2, "ratio": ratio,
            "z_no_rattlers": z_nr, "rattler_fraction": float(ratt.mean()),
            "ratio_no_rattlers": trf_nr / (z_nr * c_nr * g2_nr) if z_nr > 0 else float("nan"),
            "mean_overlap_over_d": float(cts.delta.mean() / (2 * st.radius.mean())) if cts.count else 0.0}


def g2_nominal(radii: str, samples: int = 200_001) -> float:
    """g2 of eq. (12) for the *law* of a radii spec (a fine deterministic quantile sample)."""
    spec = parse_radii(radii)
    if spec.kind == "bidisperse":
        small = 0.5 / (spec.fraction + (1 - spec.fraction) * spec.ratio)
        ns = int(round(spec.fraction * samples))
        r = np.r_[np.full(ns, small), np.full(samples - ns, small * spec.ratio)]
    else:
        u = (np.arange(samples) + 0.5) / samples
        r = 0.5 * (1.0 - spec.width + 2.0 * spec.width * u)
    return g2_exact(r)
