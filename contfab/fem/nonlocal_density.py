"""Nonlocal packing fraction: an internal length for the softening of tiers >= 1.

Tiers 1 and 2 soften through the packing fraction c (state column ``c``): a dense point
dilates, c falls toward c*, and φ(c), ψ(c) fall with it (docs/theory.md §5). Without a
length in the model a band of softening points is as thin as the elements. Here the
strength and dilatancy of a point follow an effective packing fraction that mixes its own
c with a weighted average over a neighbourhood of size ℓ (docs/theory.md §13):

    c_eff,p = c_p + δ_e(p),      δ_e = m (c̄_e − c_e)
    c_e     = Σ_{q in e} w_q c_q / Σ_{q in e} w_q                (element mean, w_q the
                                                                   quadrature weights)
    c̄_e     = Σ_f a_f g(r_ef) c_f / Σ_f a_f g(r_ef),   g(r) = exp(−(r/ℓ)²)

with r_ef the distance between the centroids of elements e and f, a_f the area of f, and
the sum over the elements within ``cutoff``·ℓ (default 3ℓ: g(3ℓ) = 1.2e-4). m = 1 is the
plain nonlocal model (c_eff = c̄ up to the point's deviation from its element mean);
m > 1 is the over-nonlocal variant of Vermeer & Brinkgreve (1994), whose local part
c (1 − m) is negative: it keeps the softening from concentrating into a band thinner than
ℓ, which the plain average allows (Brinkgreve 1994; Jirásek & Rolshoven 2003).

Convention. ℓ is in the mesh's length unit; g is the Gaussian of the nonlocal
literature written with ℓ (not ℓ/√2 or ℓ/2): its second moment in 2D is ℓ²/2 per
direction. The average is evaluated on element means (an element-by-element operator,
ne × ne, small even where a point-by-point one would hold 10⁷ entries); within an element
each point keeps its own deviation from the mean. Properties: the rows of the operator sum
to 1, so a constant field has δ = 0 exactly; on a regular lattice of centroids a linear
field is reproduced in the interior (more than ``cutoff``·ℓ from a side) to the Gaussian's
truncation, so δ = 0 there too; near a side the operator averages over the part of the
neighbourhood inside the body (normalized by the weights present). As ℓ → 0 every
element sees only itself and δ = 0 exactly: the local model.

Time integration (implicit in the point's own contribution, explicit in its neighbours').
A step starts from δ⁰ = δ of the committed state (the state the solver passes to every update
of a step). Inside the step each point's own change of c counts with the weight the model
gives an element's own change, ∂c_eff,e/∂c_e = 1 + m (A_ee − 1), A_ee the operator's
diagonal; the neighbours' change enters at the next step's δ⁰ (a lag of one step):

    c_eff,p = c_eff,p⁰ + ω_e (c_p − c_p⁰),   ω_e = 1 − κ_e,   κ_e = m (1 − A_ee),

c_eff,p⁰ = c_p⁰ + δ⁰_e. Over-nonlocal weights make ω < 0 where the elements are small
against ℓ (m = 1.25, ℓ = 0.1 in the biaxial case: median ω 0.09, −0.17, −0.21 at
h = 0.125, 0.0625, 0.0417): a point's own dilation then raises its c_eff and hardens it within
the step, as it does in the converged model, instead of softening it at the local rate. With
δ held fixed over the whole step (the purely staggered scheme, ω = 1), where the plastic zone
is ℓ wide its points flip between elastic unloading and plastic loading from one Newton
iteration to the next, and the steps must be small.

The relation is written per point, not for the element mean (δ_e = δ_e⁰ + m (A_ee − 1)
(c_e − c_e⁰)): the mean couples the points of an element, whose tangent would then not be one
3×3 matrix per point (the solver's assembly takes one per point). The two differ by
κ_e (Δc_e − Δc_p), the spread of a step's increment within an element, which the next step's
δ⁰ (computed exactly from the committed state) takes back like the neighbours' lag: both are
errors of first order in the step size, and as ℓ → 0 (κ = 0) the update is the local one.

Implementation (no kernel change): the wrapped update runs at c_n + δ⁰ + s, s a per-point
shift, and returns its own change Δc(s) = c_out − (c_n + δ⁰ + s); its end state then carries
c_eff⁰ + ω Δc exactly when

    s = −κ_e Δc(s),

a scalar equation per point, solved by Newton (∂Δc/∂s by a forward difference of the
vectorized update, safeguarded by bisection on the bracket of sign changes) to
|s + κ Δc| <= ``OWN_TOL``; elastic points have Δc = 0 and s = 0. The state keeps
c = c_n + Δc. Tangent, by the chain rule through s(Δε):

    D = ∂σ/∂Δε|_s + ∂σ/∂s ⊗ ds/dΔε,   ds/dΔε = −κ ∂Δc/∂Δε / (1 + κ ∂Δc/∂s),

∂σ/∂Δε|_s the wrapped material's consistent tangent, ∂σ/∂s, ∂Δc/∂s and ∂Δc/∂Δε forward
differences of the update (``OWN_STEP_C``, ``OWN_STEP_STRAIN``): two update calls per Newton
iteration on s and three more for the tangent (the cost: docs/fem_validation.md §3). The
spin tangent follows from D as for the wrapped material: s depends on the rotation-invariant
Δc only, so the update stays objective.

References: Pijaudier-Cabot & Bažant (1987) J. Eng. Mech. 113(10), 1512–1533 (nonlocal
damage); Vermeer & Brinkgreve (1994) "A new effective non-local strain measure for
softening plasticity", in Localisation and Bifurcation Theory for Soils and Rocks,
Balkema, 89–100; Brinkgreve (1994) Geomaterial models and numerical analysis of softening,
PhD thesis, TU Delft; Jirásek & Rolshoven (2003) Int. J. Eng. Sci. 41, 1553–1602.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from contfab.models.cone import STATUS_FAILED
from contfab.params import ParamError

OWN_MAXIT = 30
"""Newton iterations on a step's own shift s = −κ Δc(s) (module doc) before the points still
off the tolerance are reported failed (status −1: the solver cuts the step)."""
OWN_TOL = 1e-12
"""|s + κ Δc(s)| accepted as the root, in units of c."""
OWN_STEP_C = 1e-8
"""Forward-difference step in c for ∂σ/∂s and ∂Δc/∂s (≈ √ε_machine, c ~ 1)."""
OWN_STEP_STRAIN = 1e-9
"""Forward-difference step in each strain component for ∂Δc/∂Δε: far below the elastic
strains, p/(λ p_ref) ~ 1e-3 with the shipped λ = 1000, so a step rarely crosses a point's
elastic/plastic boundary."""


def averaging_matrix(centroids: np.ndarray, areas: np.ndarray, length: float,
                     cutoff: float = 3.0) -> sp.csr_matrix:
    """The (ne, ne) operator c̄ = A c of the module doc: A_ef ∝ a_f exp(−(r_ef/ℓ)²) for
    r_ef <= cutoff·ℓ, rows normalized to 1."""
    if not (np.isfinite(length) and length > 0.0):
        raise ParamError(f"internal length = {length!r} is outside the accepted range (0, inf)")
    if not (np.isfinite(cutoff) and cutoff >= 1.0):
        raise ParamError(f"cutoff = {cutoff!r} is outside the accepted range [1, inf) "
                         "(in internal lengths)")
    tree = cKDTree(centroids)
    pairs = tree.sparse_distance_matrix(tree, cutoff * length, output_type="ndarray")
    i, j, r = pairs["i"], pairs["j"], pairs["v"]
    diag = np.arange(len(centroids))             # a zero distance may be left out: add self
    i, j, r = np.concatenate([i[i != j], diag]), np.concatenate([j[i != j], diag]), \
        np.concatenate([r[i != j], np.zeros(len(diag))])
    w = areas[j] * np.exp(-(r / length) ** 2)
    a = sp.csr_matrix((w, (i, j)), shape=(len(centroids),) * 2)
    a.data /= np.repeat(np.asarray(a.sum(axis=1)).ravel(), np.diff(a.indptr))
    return a


class NonlocalMaterial:
    """``material`` (any tier with a ``c`` state column) with the nonlocal packing fraction
    of the module doc, over the quadrature points of ``disc``: internal length ``length``
    (mesh units, > 0), weight ``m`` (>= 1; 1 plain, > 1 over-nonlocal). ``matrix`` is the
    operator A, ``kappa`` (npoints,) the κ = m (1 − A_ee) of each point's element."""

    def __init__(self, material, disc, length: float, m: float = 1.0, cutoff: float = 3.0):
        if "c" not in material.state_names:
            raise ParamError(f"a nonlocal packing fraction needs a state column 'c'; the "
                             f"material carries {material.state_names} (tier 0 has none: "
                             "use tier 1 or 2)")
        if not (np.isfinite(m) and m >= 1.0):
            raise ParamError(f"nonlocal weight m = {m!r} is outside the accepted range [1, inf)")
        self.material = material
        self.state_names = material.state_names
        self.length, self.m = float(length), float(m)
        self._col = material.state_names.index("c")
        self._disc = disc
        centroids = disc.mesh.p[:, disc.mesh.t].mean(axis=1).T
        self.matrix = averaging_matrix(centroids, disc.weights.sum(axis=1), length, cutoff)
        self.kappa = np.repeat(self.m * (1.0 - self.matrix.diagonal()), disc.nq)

    @property
    def params(self):
        return self.material.params

    @property
    def point_updates(self) -> dict:
        return self.material.point_updates

    def initial_state(self, n: int) -> np.ndarray:
        return self.material.initial_state(n)

    def offset(self, state: np.ndarray) -> np.ndarray:
        """δ per point (npoints,) of the state ``state``: m (c̄_e − c_e) of its element."""
        c_e = self._disc.element_mean(np.asarray(state)[:, self._col])
        return np.repeat(self.m * (self.matrix @ c_e - c_e), self._disc.nq)

    def update(self, stress_n, state_n, dstrain, dspin):
        """The update of the module doc: the wrapped update at c_n + δ⁰ + s (δ⁰ of
        ``state_n``, the step's start), s solving s = −κ Δc(s) point by point, the tangent
        by the chain rule through s, the shift taken back. Points where s does not converge
        in ``OWN_MAXIT`` iterations fail (status −1, input stress and state)."""
        col, kappa = self._col, self.kappa
        stress_n = np.asarray(stress_n, dtype=np.float64)
        state_n = np.asarray(state_n, dtype=np.float64)
        delta = self.offset(state_n)

        def run(s, de=dstrain):
            """The wrapped update started from c_n + δ⁰ + s, and its own change of c."""
            shifted = state_n.copy()
            shifted[:, col] += delta + s
            res = self.material.update(stress_n, shifted, de, dspin)
            return res, res.state[:, col] - shifted[:, col]

        s = np.zeros(len(state_n))
        lo, hi = np.full(len(s), -np.inf), np.full(len(s), np.inf)
        for it in range(OWN_MAXIT):
            res, dc = run(s)
            res_h, dc_h = run(s + OWN_STEP_C)
            g = s + kappa * dc
            done = (np.abs(g) <= OWN_TOL) | (res.status < 0)
            if done.all():
                break
            if it == OWN_MAXIT - 1:
                res.status[~done] = STATUS_FAILED
                break
            slope = 1.0 + kappa * (dc_h - dc) / OWN_STEP_C
            hi = np.where(g > 0.0, np.minimum(hi, s), hi)
            lo = np.where(g < 0.0, np.maximum(lo, s), lo)
            trial = s - g / np.where(slope > 0.0, slope, 1.0)
            bisect = np.flatnonzero(np.isfinite(lo) & np.isfinite(hi)
                                    & ~((trial > lo) & (trial < hi)))
            trial[bisect] = 0.5 * (lo[bisect] + hi[bisect])
            s = np.where(done, s, trial)
        coupled = (kappa > 0.0) & (res.status >= 0) & ((dc != 0.0) | (dc_h != 0.0))
        if coupled.any():
            # ds/dε = −κ ∂Δc/∂ε / (1 + κ ∂Δc/∂s), D = ∂σ/∂ε + ∂σ/∂s ⊗ ds/dε
            dsig_ds = (res_h.stress - res.stress) / OWN_STEP_C
            slope = 1.0 + kappa * (dc_h - dc) / OWN_STEP_C
            ddc_de = np.empty((len(s), 3))
            for j in range(3):
                de = np.array(dstrain, dtype=np.float64)
                de[:, j] += OWN_STEP_STRAIN
                ddc_de[:, j] = (run(s, de)[1] - dc) / OWN_STEP_STRAIN
            ds_de = -kappa[:, None] * ddc_de / slope[:, None]
            k = np.flatnonzero(coupled & (slope > 0.0))
            res.tangent[k] += dsig_ds[k, :, None] * ds_de[k, None, :]
        res.state[:, col] -= delta + s
        failed = res.status < 0
        res.stress[failed], res.state[failed] = stress_n[failed], state_n[failed]
        return res

    def spin_tangent(self, stress_n, state_n, dstrain, dspin, res) -> np.ndarray:
        return self.material.spin_tangent(stress_n, state_n, dstrain, dspin, res)
