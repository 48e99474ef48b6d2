r"""Duvaut–Lions viscoplastic regularization of a rate-independent material.

The rate-independent update of a model (the update contract: stress, state, tangent,
status over the increments Δε, Δω) gives the inviscid state σ̄_{n+1}, q̄_{n+1}, the return
of the elastic trial σ_tr = Q σ_n Qᵀ + C Δε (Q the rotation by Δω, C the regularization's
isotropic stiffness). The Duvaut–Lions model lets the stress relax towards it with a
relaxation time τ,

    ε̇_vp = C⁻¹ (σ - σ̄) / τ,        q̇ = -(q - q̄) / τ,

and its backward-Euler step over a time step Δt, with k = Δt/τ, is the blend (Simo &
Hughes 1998, *Computational Inelasticity*, §2.7)

    σ_{n+1} = (σ_tr + k σ̄_{n+1}) / (1 + k),     q_{n+1} = (q_n + k q̄_{n+1}) / (1 + k),
    ∂σ_{n+1}/∂Δε = (C + k D̄) / (1 + k),

D̄ the inviscid algorithmic tangent. k → ∞ (τ → 0) is the rate-independent model, k → 0
the elastic one. The blend is objective (both σ_tr and σ̄ are), so the spin tangent keeps
the form S = W(σ) - T W(Δε) of the inviscid update. The state blend is exact for scalar
state (γp, c); a tensorial state (tier 2's fabric) is blended in the frame of the step's
end, an O(Δω) difference.

**Why it helps a boundary-value problem.** With non-associated flow the inviscid
incremental problem at collapse has points at neutral loading flipping between elastic
and plastic from one Newton iterate to the next and no reachable solution nearby
(docs/fem_validation.md §5). The viscous step's tangent jumps by only k/(1 + k) of the
inviscid jump across the yield switch, and as the step is cut (Δt → 0) the step becomes
elastic and linear: cutting always ends in convergence. The solution tends to the
rate-independent one as τ → 0, but the overstress τ C ε̇_vp acts as a rate-dependent
cohesion, to which collapse loads are sensitive: on the N_γ footing the excess fell only
as τ^0.47 (docs/fem_validation.md §7), so a run at an affordable τ gives the viscous
material's collapse load, not the rate-independent one.

Time is the stage parameter t times :attr:`contfab.fem.solver.Stage.duration`; the solver
applies :func:`blend` with k = Δt/τ (``NewtonOptions.relaxation_time``).
"""
from __future__ import annotations

import numpy as np

from contfab.models.cone import STATUS_FAILED
from contfab.tensors import isotropic_stiffness


def elastic_stiffness(material) -> np.ndarray:
    """C (3, 3) of a tier material's regularization (``material.params.regularization``)."""
    return isotropic_stiffness(*material.params.regularization.moduli())


def blend(res, stress_n, state_n, dstrain, dspin, elastic: np.ndarray, k: float):
    """Turn the inviscid update ``res`` in place into the Duvaut–Lions step with ratio k = Δt/τ.

    σ = (σ_tr + k σ̄)/(1 + k), q = (q_n + k q̄)/(1 + k), T = (C + k T̄)/(1 + k) at every point
    whose update did not fail (failed points keep status -1 and their inputs). Returns ``res``.
    """
    if not k > 0.0:
        raise ValueError(f"Duvaut-Lions ratio k = dt/tau = {k!r} must be > 0")
    w = k / (1.0 + k)
    ok = res.status != STATUS_FAILED
    trial = rotated(stress_n, dspin) + dstrain @ elastic.T
    res.stress[ok] = (1.0 - w) * trial[ok] + w * res.stress[ok]
    res.state[ok] = (1.0 - w) * np.asarray(state_n)[ok] + w * res.state[ok]
    res.tangent[ok] = (1.0 - w) * elastic + w * res.tangent[ok]
    return res


def rotated(stress: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Q σ Qᵀ per point (Voigt rows), Q the counter-clockwise rotation by ``angle``."""
    mean = 0.5 * (stress[:, 0] + stress[:, 1])
    d = 0.5 * (stress[:, 0] - stress[:, 1])
    c2, s2 = np.cos(2.0 * angle), np.sin(2.0 * angle)
    dn = c2 * d - s2 * stress[:, 2]
    return np.stack([mean + dn, mean - dn, s2 * d + c2 * stress[:, 2]], axis=1)
