"""The model tiers behind the solver's material interface (the update contract, DESIGN §4).

:class:`TierMaterial` calls :func:`contfab.models.tiers.update` over the quadrature points
and hands the solver their stress, state, tangent and status. One tier everywhere, or
**mixed tiers** (``point_tiers``: a tier per point): the state arrays then hold the columns
of the highest tier present (``STATE_NAMES[max]``); every lower tier's columns are a prefix
of them (gp; gp, c; gp, c, A, Bc, Bs), so a point of a lower tier updates its own prefix
and carries the rest unchanged (a tier-1 point keeps its initial fabric, which it does not
use). Each tier's points go through :func:`~contfab.models.tiers.update` once per call, the
one update of that tier: no copy of the loop per mix. ``point_updates`` counts the point
updates per tier (the cost measure of a mixed run).

**Apex points** (status 2: σ = 0, the cohesionless material has separated) have a
zero tangent, the exact derivative. A region at the apex then has no stiffness and
the Newton matrix is singular. ``apex_stiffness`` = ε replaces their tangent *in the
Newton matrix only* by ε·C (C the regularization stiffness): the residual, hence the
converged solution, is unchanged — only the iteration path differs — so the device
needs no convergence study in ε (the case scripts still report one). ε = 0 turns it off.

**Spin tangent.** Every tier rotates its inputs by the exact spin angle and updates
objectively, so ∂σ/∂ω follows from the strain tangent without another update call
(:func:`contfab.models.tiers.spin_derivative`, S = W(σ) - T W(Δε)).
"""
from __future__ import annotations

import numpy as np

from contfab.models import tiers
from contfab.models.tiers import spin_derivative
from contfab.models.cone import STATUS_APEX
from contfab.params import ParamError, Params
from contfab.tensors import isotropic_stiffness


class TierMaterial:
    """Model tier ``tier`` (or a tier per point, ``point_tiers``) with parameters ``params``
    (validated); see the module doc."""

    def __init__(self, params: Params, tier: int | None = None, apex_stiffness: float = 1e-9,
                 point_tiers=None):
        if point_tiers is not None:
            point_tiers = np.asarray(point_tiers)
            if point_tiers.ndim != 1 or not np.isin(point_tiers, list(tiers.KERNELS)).all():
                raise ParamError(f"point_tiers must be a 1-d array of available tiers "
                                 f"({', '.join(map(str, sorted(tiers.KERNELS)))}), got "
                                 f"values {np.unique(point_tiers).tolist()}")
            tier = int(point_tiers.max())
            top = tiers.STATE_NAMES[tier]
            if any(top[:len(tiers.STATE_NAMES[t])] != tiers.STATE_NAMES[t] for t in point_tiers):
                raise ParamError("mixed tiers need each tier's state columns to be a prefix of "
                                 f"the highest tier's {top}")
            self.groups = {int(t): np.flatnonzero(point_tiers == t) for t in np.unique(point_tiers)}
        else:
            self.groups = None
        self.tier = params.tier if tier is None else tier
        self.params = params.with_tier(self.tier) if self.tier != params.tier else params
        self.state_names = tiers.STATE_NAMES[self.tier]
        self.point_tiers = point_tiers
        self.point_updates = {t: 0 for t in (self.groups or {self.tier: None})}
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
        if self.groups is None:
            res = tiers.update(self.tier, stress_n, state_n, dstrain, dspin, self.params)
            self.point_updates[self.tier] += len(res.status)
        else:
            res = self._mixed_update(stress_n, state_n, dstrain, dspin)
        if self.apex_stiffness > 0.0:
            res.tangent[res.status == STATUS_APEX] = self._apex_tangent
        return res

    def _mixed_update(self, stress_n, state_n, dstrain, dspin) -> tiers.UpdateResult:
        n = len(self.point_tiers)
        if np.shape(stress_n) != (n, 3):
            raise ValueError(f"stress_n has shape {np.shape(stress_n)}, expected {(n, 3)} "
                             f"(one row per point of point_tiers)")
        state_n = np.asarray(state_n, dtype=np.float64)
        out = tiers.allocate(self.tier, n)
        out.state[:] = state_n                     # the columns a lower tier does not carry
        for tier, idx in self.groups.items():
            k = len(tiers.STATE_NAMES[tier])
            r = tiers.update(tier, stress_n[idx], state_n[idx, :k], dstrain[idx], dspin[idx],
                             self.params)
            out.stress[idx], out.state[idx, :k] = r.stress, r.state
            out.tangent[idx], out.status[idx] = r.tangent, r.status
            self.point_updates[tier] += len(idx)
        return out

    def spin_tangent(self, stress_n, state_n, dstrain, dspin, res) -> np.ndarray:
        """∂σ/∂ω (npoints, 3) of the update ``res`` over (dstrain, dspin): exact, no call."""
        return spin_derivative(res.stress, res.tangent, dstrain)
