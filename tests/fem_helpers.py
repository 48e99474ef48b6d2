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
