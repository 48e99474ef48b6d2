"""``contfab bench model``: constitutive updates per second per core, at a yielding state.

Each tier updates the same points: stresses on its yield surface (P in [0.5, 2] p_ref,
random principal directions) loaded further along their deviator by a strain
increment of 1e-4 with a small random spin, so every point takes the plastic branch
(the benchmark reports the plastic fraction). The kernel runs on one
thread with preallocated outputs; the reference is a plain numpy elastic update σ + C Δε
of the same points in the same run, and each tier's rate is also given as a ratio to it.
Timings are medians of ``--repeats`` runs of the process's CPU time (both sides are
single-threaded, so this is the per-core figure even when other jobs share the cores;
``*_wall`` figures give the wall-clock rate too).
"""
from __future__ import annotations

import time

import numba
import numpy as np

from contfab.bench import median_seconds
from contfab.models import tiers
from contfab.params import default_params
from contfab.tensors import isotropic_stiffness

BENCH_TIERS = (0, 1, 2)
"""Tiers measured (a new tier: add it here once registered in tiers.KERNELS)."""
POINTS = 200_000
STRAIN = 1e-4


def yielding_points(params, tier: int, n: int, seed: int = 0):
    """(stress_n, state_n, dstrain, dspin): points on the yield surface, loaded further.

    Tier-agnostic: isotropic states (P in [0.5, 2] p_ref, the ``[initial]`` state with c
    spread over c0 ± 0.01) are first sheared far past yield by one update, which returns
    them onto the yield surface; the benchmark increment continues that shear by STRAIN.
    """
    rng = np.random.default_rng(seed)
    p = params.p_ref * rng.uniform(0.5, 2.0, n)
    stress = np.stack([-p, -p, np.zeros(n)], axis=1)
    two = 2.0 * rng.uniform(0.0, np.pi, n)
    direction = np.stack([np.cos(two), -np.cos(two), 2.0 * np.sin(two)], axis=1)
    state = tiers.initial_state(tier, params, n)
    if "c" in tiers.STATE_NAMES[tier]:      # dense and loose: the local solve has work to do
        column = tiers.STATE_NAMES[tier].index("c")
        state[:, column] += rng.uniform(-0.01, 0.01, n)
    shear = params.array(tier)[1]
    onto = tiers.update(tier, stress, state, 2.0 * params.p_ref / shear * direction,
                        np.zeros(n), params)
    dspin = 1e-4 * rng.standard_normal(n)
    return onto.stress, onto.state, STRAIN * direction, dspin


def run(args) -> dict:
    repeats = getattr(args, "repeats", 5)
    n = getattr(args, "points", POINTS)
    params = default_params()
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    figures = {"points": n}
    try:
        for tier in BENCH_TIERS:
            stress, state, dstrain, dspin = yielding_points(params, tier, n)
            out = tiers.allocate(tier, n)
            prm = params.array(tier)
            kernel = tiers.KERNELS[tier]

            def model():
                kernel(stress, state, dstrain, dspin, prm, out.stress, out.state, out.tangent,
                       out.status)

            c = isotropic_stiffness(*params.array(tier)[:2])

            def elastic():
                return stress + np.einsum("ij,nj->ni", c, dstrain)

            t_model = median_seconds(model, repeats=repeats, clock=time.process_time)
            t_elastic = median_seconds(elastic, repeats=repeats, clock=time.process_time)
            figures[f"tier{tier}_updates_per_s_per_core"] = n / t_model
            figures[f"tier{tier}_vs_numpy_elastic"] = t_elastic / t_model
            figures[f"tier{tier}_plastic_fraction"] = float(np.mean(out.status == 1))
            figures[f"tier{tier}_updates_per_s_wall"] = n / median_seconds(model, repeats=repeats)
        figures["numpy_elastic_updates_per_s_per_core"] = n / t_elastic
    finally:
        numba.set_num_threads(threads)
    return figures
