"""``contfab bench model``: constitutive updates per second per core, at a yielding state.

Each case updates the same kind of points: stresses on its yield surface (P in [0.5, 2]
p_ref, random principal directions) loaded further along their deviator by a strain
increment of 1e-4 with a small random spin, so every point takes the plastic branch
(the benchmark reports the plastic fraction). All cases use the shipped (calibrated)
parameters. Tier 2 is measured twice: from the ``[initial]`` isotropic fabric, and as
``tier2_aniso`` from an anisotropic one (B/A = :data:`B_RATIO` along the compression axis of
each point's random shear direction), where the cone's axis is off the origin and the fabric
coupling does its full work. The kernel runs on one thread with preallocated outputs; the
reference is a plain numpy elastic update σ + C Δε of the same points in the same run, and
each case's rate is also given as a ratio to it. Timings are medians of ``--repeats`` runs of
the process's CPU time (both sides are single-threaded, so this is the per-core figure even
when other jobs share the cores; ``*_wall`` figures give the wall-clock rate too).

Measured (updates/s per core, ``python -m contfab.cli bench model --json --repeats 3``, three
runs on the shared 2-core machine at load 10-11; medians in brackets): tier0 2.25e7, 2.25e7,
2.35e7 (2.25e7); tier1 7.57e6, 7.70e6, 7.72e6 (7.70e6); tier2 5.38e5, 5.33e5, 5.50e5
(5.38e5); tier2_aniso 5.10e5, 5.15e5, 5.21e5 (5.15e5).

The targets (5e6 for tiers 0/1, 5e5 for tier 2 per core) are met. A load on the other core
lowers the per-core rate (by ~15 % between load 0.5 and load 10 on earlier tier-2 code), so a
single figure taken under load can fall below.

What a tier-2 update does (:mod:`contfab.models.fabric_cone`): the trial and its elastic
check; on the plastic branch the frozen-state return (one scalar equation in Δγ, a few
Newton steps), then Newton on the 8 unknowns (s, P, Δγ, c, A, Bc, Bs), each iteration one
residual and analytic Jacobian with a fabric-law step and an 8x8 LU, and the tangent's three
columns from the converged LU.
"""
from __future__ import annotations

import time

import numpy as np

from dem.threads import numba_threads
from contfab.bench import median_seconds
from contfab.models import tiers
from contfab.params import BULK, SHEAR, default_params
from contfab.tensors import isotropic_stiffness

BENCH_CASES = {"tier0": (0, False), "tier1": (1, False), "tier2": (2, False),
               "tier2_aniso": (2, True)}
"""Case name -> (tier, anisotropic). A new tier: add it here once registered in tiers.KERNELS."""
POINTS = 200_000
STRAIN = 1e-4
B_RATIO = 0.25
"""B/A of the anisotropic case's start fabric (the DEM's steady biaxial anisotropy)."""


def yielding_points(params, tier: int, n: int, seed: int = 0, anisotropic: bool = False):
    """(stress_n, state_n, dstrain, dspin): points on the yield surface, loaded further.

    Tier-agnostic: isotropic stresses (P in [0.5, 2] p_ref, the ``[initial]`` state with c
    spread over c0 ± 0.01; with ``anisotropic`` the fabric has B = B_RATIO·A with θp along
    the compression axis of the point's shear, the DEM's steady biaxial fabric) are first
    sheared far past yield by one update, which returns them onto the yield surface; the
    benchmark increment continues that shear by STRAIN.
    """
    rng = np.random.default_rng(seed)
    p = params.p_ref * rng.uniform(0.5, 2.0, n)
    stress = np.stack([-p, -p, np.zeros(n)], axis=1)
    two = 2.0 * rng.uniform(0.0, np.pi, n)
    direction = np.stack([np.cos(two), -np.cos(two), 2.0 * np.sin(two)], axis=1)
    names = tiers.STATE_NAMES[tier]
    state = tiers.initial_state(tier, params, n)
    if "c" in names:      # dense and loose: the local solve has work to do
        state[:, names.index("c")] += rng.uniform(-0.01, 0.01, n)
    if anisotropic:
        b = B_RATIO * state[:, names.index("A")]
        two_theta_p = two + np.pi      # the shear extends along two/2: compression at +90°
        state[:, names.index("Bc")] = b * np.cos(two_theta_p)
        state[:, names.index("Bs")] = b * np.sin(two_theta_p)
    shear = params.array(tier)[SHEAR]
    onto = tiers.update(tier, stress, state, 2.0 * params.p_ref / shear * direction,
                        np.zeros(n), params)
    dspin = 1e-4 * rng.standard_normal(n)
    return onto.stress, onto.state, STRAIN * direction, dspin


def run(args) -> dict:
    repeats = getattr(args, "repeats", 5)
    n = getattr(args, "points", POINTS)
    figures = {"points": n}
    with numba_threads(1):
        for name, (tier, anisotropic) in BENCH_CASES.items():
            params = default_params()
            stress, state, dstrain, dspin = yielding_points(params, tier, n,
                                                            anisotropic=anisotropic)
            out = tiers.allocate(tier, n)
            prm = params.array(tier)
            kernel = tiers.KERNELS[tier]

            def model():
                kernel(stress, state, dstrain, dspin, prm, out.stress, out.state, out.tangent,
                       out.status)

            c = isotropic_stiffness(prm[BULK], prm[SHEAR])

            def elastic():
                return stress + np.einsum("ij,nj->ni", c, dstrain)

            t_model = median_seconds(model, repeats=repeats, clock=time.process_time)
            t_elastic = median_seconds(elastic, repeats=repeats, clock=time.process_time)
            figures[f"{name}_updates_per_s_per_core"] = n / t_model
            figures[f"{name}_vs_numpy_elastic"] = t_elastic / t_model
            figures[f"{name}_plastic_fraction"] = float(np.mean(out.status == 1))
            figures[f"{name}_updates_per_s_wall"] = n / median_seconds(model, repeats=repeats)
        figures["numpy_elastic_updates_per_s_per_core"] = n / t_elastic
    return figures
