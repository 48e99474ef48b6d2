"""The model tiers behind the solver's material interface (the update contract, DESIGN §4).

:class:`TierMaterial` calls :func:`contfab.models.tiers.update` once over all
quadrature points and hands the solver its stress, state, tangent and status.
Per-point state arrays hold only the tier's columns (``STATE_NAMES[tier]``).

**Apex points** (status 2: σ = 0, the cohesionless material has separated) have a
zero tangent, the exact derivative. A region at the apex then has no stiffness and
the Newton matrix is singular. ``apex_stiffness`` = ε replaces their tangent *in the
Newton matrix only* by ε·C (C the regularization stiffness): the residual, hence the
converged solution, is unchanged — only the iteration path differs — so the device
needs no convergence study in ε (the case scripts still report one). ε = 0 turns it off.

**Spin tangent.** Every tier rotates its inputs by the exact spin angle and updates
objectively, so ∂σ/∂ω follows from the strain tangent without another update call
(:func:`contfab.material_point.spin_derivative`, S = W(σ) - T W(Δε)).
"""
from __future__ import annotations

import numpy as np

from contfab.material_point import spin_derivative
from contfab.models import tiers
from contfab.models.cone import STATUS_APEX
from contfab.params import ParamError, Params
from contfab.tensors import isotropic_stiffness


class TierMaterial:
    """Model tier ``tier`` with parameters ``params`` (validated); see the module doc."""

    def __init__(self, params: Params, tier: int | None = None, apex_stiffness: float = 1e-9):
        self.tier = params.tier if tier is None else tier
        self.params = params.with_tier(self.tier) if self.tier != params.tier else params
        self.state_names = tiers.STATE_NAMES[self.tier]
        if not 0.0 <= apex_stiffness < 1.0:
            raise ParamError(f"apex_stiffness = {apex_stiffness:g} is outside the accepted "
                             "range [0, 1)")
        bulk, shear = self.params.regularization.moduli()
        self._apex_tangent = apex_stiffness * isotropic_stiffness(bulk, shear)
        self.apex_stiffness = apex_stiffness

    def initial_state(self, n: int) -> np.ndarray:
        """(n, k) state of fresh points: gp = 0 and the parameter file's ``[initial]`` values."""
        return tiers.initial_state(self.tier, self.params, n)

    def update(self, stress_n, state_n, dstrain, dspin) -> tiers.UpdateResult:
        """The tier's update over all points, apex tangents regularized for the Newton matrix."""
        res = tiers.update(self.tier, stress_n, state_n, dstrain, dspin, self.params)
        if self.apex_stiffness > 0.0:
            res.tangent[res.status == STATUS_APEX] = self._apex_tangent
        return res

    def spin_tangent(self, stress_n, state_n, dstrain, dspin, res) -> np.ndarray:
        """∂σ/∂ω (npoints, 3) of the update ``res`` over (dstrain, dspin): exact, no call."""
        return spin_derivative(res.stress, res.tangent, dstrain)
