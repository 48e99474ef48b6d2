r"""A linear dashpot in parallel with the material at every quadrature point.

The stress that enters equilibrium is the material's plus a viscous stress proportional
to the strain rate over the step in pseudo-time,

    σ = σ_mat(Δε) + σ_v,        σ_v = η Δε / Δt,

η the viscosity (stress × time, the time unit of :attr:`contfab.fem.solver.Stage.duration`:
the stage's loading parameter t when the duration is 1), Δε the tensorial strain
increment of the step (Voigt rows Δεxx, Δεyy, Δγxy with Δγxy = 2 Δεxy, so σ_v,xy =
η Δγxy / (2 Δt)). Its tangent is

    ∂σ_v/∂Δe = (η/Δt) diag(1, 1, 1/2)        (Voigt, engineering shear),

positive definite. The dashpot carries no stress from one step to the next (at the step's
start Δε = 0, so σ_v = 0): it has no state. The material's stress and
state are not touched: the committed stress the next step starts from is the material's;
only the residual (hence the reactions) and the Newton matrix see σ_v.

**Why it helps a softening, localizing boundary-value problem.** Where a material point
softens, the step's incremental problem can lose uniqueness (a band may take the strain
while its surroundings unload) and with a non-smooth, incrementally non-linear material
(loading and unloading stiffnesses differ) a Newton iteration can cycle between
loading/unloading point sets. The dashpot adds η/Δt to every point's stiffness: as the
step is cut, η/Δt grows, the step's tangent becomes positive definite and the strain
increment of the step becomes unique. η → 0 is the rate-independent problem; the
price is the overstress η ε̇ (``overstress``), a rate effect of the regularization, not
of the material: it is largest where the strain rate concentrates, in the band.
"""
from __future__ import annotations

import math

import numpy as np

_SHAPE = np.diag([1.0, 1.0, 0.5])
"""∂(Voigt σ)/∂(Voigt Δe) of σ = Δε per unit η/Δt (engineering shear strain)."""


def check_viscosity(eta: float) -> float:
    """``eta`` as a float if it lies in [0, inf), else ValueError naming the accepted range."""
    if not (isinstance(eta, (int, float, np.floating)) and math.isfinite(eta) and eta >= 0):
        raise ValueError(f"viscosity = {eta!r} is outside the accepted range [0, inf) "
                         "(stress × stage time; 0: no dashpot)")
    return float(eta)


def stiffness(eta: float, dt: float) -> np.ndarray:
    """(3, 3) Voigt tangent (η/Δt) diag(1, 1, 1/2) of the dashpot over a step of time ``dt``."""
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dashpot time step dt = {dt!r} is outside the accepted range (0, inf)")
    return (check_viscosity(eta) / dt) * _SHAPE


def stress(dstrain: np.ndarray, stiff: np.ndarray) -> np.ndarray:
    """σ_v (n, 3) = stiffness · Δe per point for Voigt strain increments ``dstrain`` (n, 3)."""
    return np.asarray(dstrain) @ stiff.T


def magnitude(sv: np.ndarray) -> np.ndarray:
    """|σ_v| per point: the tensor norm sqrt(σxx² + σyy² + 2σxy²) of Voigt rows."""
    return np.sqrt(sv[:, 0] ** 2 + sv[:, 1] ** 2 + 2.0 * sv[:, 2] ** 2)
