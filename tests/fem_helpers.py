"""A linear isotropic elastic material behind the update contract, for solver tests only.

σ_{n+1} = σ_n + D Δe with D the 2D isotropic stiffness (contfab.tensors); the state
is carried unchanged, the status is 0 (elastic) everywhere.
"""
from types import SimpleNamespace

import numpy as np

from contfab.tensors import isotropic_stiffness


class Elastic:
    state_names = ("gp",)

    def __init__(self, bulk=2.0, shear=1.0):
        self.d = isotropic_stiffness(bulk, shear)

    def update(self, stress_n, state_n, dstrain, dspin):
        n = len(stress_n)
        return SimpleNamespace(stress=stress_n + dstrain @ self.d.T, state=state_n.copy(),
                               tangent=np.broadcast_to(self.d, (n, 3, 3)).copy(),
                               status=np.zeros(n, dtype=np.int8))


class Brittle(Elastic):
    """Elastic until |strain| exceeds ``limit`` anywhere: those points report status -1."""

    def __init__(self, limit, **kw):
        super().__init__(**kw)
        self.limit = limit

    def update(self, stress_n, state_n, dstrain, dspin):
        res = super().update(stress_n, state_n, dstrain, dspin)
        strain = np.linalg.solve(self.d, res.stress.T).T
        bad = np.abs(strain).max(axis=1) > self.limit
        res.stress[bad] = stress_n[bad]
        res.status[bad] = -1
        return res


class Rough(Elastic):
    """Elastic with a stress error of relative size ``eta`` whose sign follows the parity of
    the strain increment's 12th decimal: it flips from one Newton iterate to the next at
    random, so the relative residual stalls near ``eta`` at any step size."""

    def __init__(self, eta, **kw):
        super().__init__(**kw)
        self.eta = eta

    def update(self, stress_n, state_n, dstrain, dspin):
        res = super().update(stress_n, state_n, dstrain, dspin)
        sign = np.where(np.floor(dstrain[:, 1] * 1e12) % 2 == 0, 1.0, -1.0)
        res.stress = res.stress * (1.0 + self.eta * sign)[:, None]
        return res


class Softening(Elastic):
    """Isotropic damage with linear softening: σ = (1 - d(κ)) D ε, κ the largest |ε|
    (Euclidean norm of the Voigt strain) reached so far, with (1 - d) κ falling linearly
    from κ0 at κ0 to 0 at ``kappa_f`` (so along a proportional path the stress does).
    ``kappa0`` may differ per point (a weak zone). State: gp (unused), εxx, εyy, γxy, κ.
    Consistent tangent (loading: -D ε ⊗ d'(κ) ε/|ε| added)."""

    state_names = ("gp", "exx", "eyy", "gxy", "kappa")

    def __init__(self, kappa0, kappa_f, **kw):
        super().__init__(**kw)
        self.k0, self.kf = np.asarray(kappa0, dtype=float), float(kappa_f)

    def _intact(self, kappa):
        """1 - d(κ) and its derivative in κ."""
        k0 = np.broadcast_to(self.k0, kappa.shape)
        soft = kappa > k0
        ratio = np.where(soft, k0 * (self.kf - kappa) / (kappa * (self.kf - k0)), 1.0)
        ratio = np.clip(ratio, 0.0, 1.0)
        slope = np.where(soft & (kappa < self.kf), -k0 * self.kf / (kappa ** 2 * (self.kf - k0)), 0.0)
        return ratio, slope

    def update(self, stress_n, state_n, dstrain, dspin):
        strain = state_n[:, 1:4] + dstrain
        norm = np.linalg.norm(strain, axis=1)
        kappa = np.maximum(np.maximum(state_n[:, 4], self.k0), norm)
        loading = (norm >= kappa) & (norm > self.k0)
        intact, slope = self._intact(kappa)
        elastic = strain @ self.d.T
        n = len(stress_n)
        tangent = intact[:, None, None] * self.d
        dn = np.where(norm > 0, 1.0 / np.where(norm > 0, norm, 1.0), 0.0)
        extra = (slope * loading * dn)[:, None, None] * elastic[:, :, None] * strain[:, None, :]
        state = np.column_stack([state_n[:, 0], strain, kappa])
        return SimpleNamespace(stress=intact[:, None] * elastic, state=state, tangent=tangent + extra,
                               status=np.zeros(n, dtype=np.int8))
