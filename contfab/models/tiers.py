"""The one constitutive-update interface for every model tier (docs/theory.md §3).

    result = update(tier, stress_n, state_n, dstrain, dspin, params)

* ``stress_n`` (n, 3): Voigt (σxx, σyy, σxy), tension positive, in the scene's stress unit.
* ``state_n`` (n, k): the columns :data:`STATE_NAMES` [tier] (k = 1 for tier 0).
* ``dstrain`` (n, 3): Voigt increment with engineering shear (Δεxx, Δεyy, Δγxy = 2Δεxy).
* ``dspin`` (n,): spin increment Δω = (L_yx - L_xy)/2 · dt (counter-clockwise).
* ``params``: a validated :class:`contfab.params.Params`.

The result holds ``stress`` (n, 3), ``state`` (n, k), ``tangent`` (n, 3, 3) — the
algorithmic tangent ∂σ_{n+1}/∂Δε in Voigt/engineering shear, non-symmetric when ψ ≠ φ,
not including the dependence on Δω — and ``status`` (n,) int8: 0 rigid/elastic,
1 plastic (cone face), 2 apex, 3 plastic with the fabric projected onto the admissible set
(tier 2: reported, never silent), -1 failed. Failed points carry their *input* stress and
state and the elastic tangent; no NaN or inf is ever returned: the caller cuts the step.

Inputs are committed state; nothing is modified in place (trial and committed state
stay separate, as the FEM needs). Each tier's kernel is a numba function over points
``kernel(stress_n, state_n, dstrain, dspin, prm, stress, state, tangent, status)``
writing preallocated outputs; ``prm = params.array(tier)``. A new tier registers its
kernel in :data:`KERNELS`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dem.threads import numba_threads
from contfab.models import cone, fabric_cone
from contfab.params import Params, ParamError

STATE_NAMES: dict[int, tuple[str, ...]] = {
    0: ("gp",),
    1: ("gp", "c"),
    2: ("gp", "c", "A", "Bc", "Bs"),
}
"""State columns of each tier. gp: accumulated plastic shear strain Σ(Δεp1 - Δεp2)
(output only); c: the hardening packing fraction c_p (:func:`packing_fraction`); (A, Bc, Bs):
fabric state (docs/theory.md §2)."""

KERNELS = {
    0: cone.update_points_tier0,
    1: cone.update_points_tier1,
    2: fabric_cone.update_points,
}
"""The numba kernel of each available tier."""

PARALLEL_MIN_POINTS = 4096
"""Below this many points a call runs on one thread: waking the thread pool costs more
(tens of µs, up to ms on a loaded machine) than updating a few thousand points."""

STATUS_NAMES = {cone.STATUS_ELASTIC: "elastic", cone.STATUS_FACE: "plastic",
                cone.STATUS_APEX: "apex", fabric_cone.STATUS_PROJECTED: "fabric projected",
                cone.STATUS_FAILED: "failed"}


def packing_fraction(c_p, pressure, params: Params):
    r"""The packing fraction c = disc area / cell area (docs/theory.md §1: ċ/c = -tr ε̇) of a state
    whose hardening variable is c_p, at pressure P (scene units):

        c = c_p exp((P - p_ref) / K),   K = E_reg / (2(1 - ν)) (the regularization's bulk modulus).

    The hardening law (docs/theory.md §5) moves c_p with the *plastic* volume change,
    ċ_p/c_p = -tr ε̇p; the total volume change adds the elastic one of the regularization,
    tr ε̇ - tr ε̇p = -Ṗ/K exactly (the update's volumetric part: P = P_tr + K tr Δεp), so
    c/c_p = exp((P - P_s)/K) for a start at pressure P_s where both agree. Identifying c_p
    with the packing fraction at P = p_ref (where DEM starts are measured: P0 = p_ref)
    makes this a function of the state, so a continued run or an FEM point needs no
    history. c_p is the packing fraction the material would have if brought elastically to
    p_ref: the rigid-grain one, as the regularization's elastic strain plays the part of
    the DEM's contact compliance (overlaps). Why this matters (a measurement):
    in isochoric shear the DEM keeps c fixed exactly, while c_p of a dense state dilates
    plastically toward c* (0.835 -> 0.805 measured) as P rises; compared with the DEM's
    c, c_p was wrong by 0.03 and c is exact. The two differ by (P - p_ref)/K ~ 1/λ
    elsewhere (biaxial at σxx = -p_ref: < 1e-3 relative at λ = 1000).
    """
    k, _ = params.regularization.moduli()
    return c_p * np.exp((np.asarray(pressure, dtype=np.float64) - params.p_ref) / k)


@dataclass(frozen=True)
class UpdateResult:
    """Outputs of :func:`update` (arrays owned by the caller once returned)."""

    stress: np.ndarray
    state: np.ndarray
    tangent: np.ndarray
    status: np.ndarray

    @property
    def failed(self) -> np.ndarray:
        """Indices of the points whose update failed (the caller cuts the step)."""
        return np.flatnonzero(self.status == cone.STATUS_FAILED)


def _kernel(tier) -> object:
    if tier not in KERNELS:
        raise ParamError(f"tier = {tier!r} is not an available model tier "
                         f"(accepted: {', '.join(map(str, sorted(KERNELS)))})")
    return KERNELS[tier]


def allocate(tier: int, n: int) -> UpdateResult:
    """Uninitialized output arrays for ``n`` points of ``tier`` (reusable across calls)."""
    return UpdateResult(np.empty((n, 3)), np.empty((n, len(STATE_NAMES[tier]))),
                        np.empty((n, 3, 3)), np.empty(n, dtype=np.int8))


def initial_state(tier: int, params: Params, n: int) -> np.ndarray:
    """(n, k) state of ``n`` fresh points: gp = 0 and the ``[initial]`` values."""
    _kernel(tier)
    names = STATE_NAMES[tier]
    if names == ("gp",):
        return np.zeros((n, 1))
    values = params.initial.state_values()
    return np.tile(np.array([values[name] for name in names], dtype=np.float64), (n, 1))


def _as_input(name: str, a, shape: tuple[int, ...]) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=np.float64)
    if a.shape != shape:
        raise ValueError(f"{name} has shape {a.shape}, expected {shape}")
    return a


def update(tier: int, stress_n, state_n, dstrain, dspin, params: Params,
           out: UpdateResult | None = None) -> UpdateResult:
    """Constitutive update of every point (see the module doc); ``out`` reuses buffers."""
    kernel = _kernel(tier)
    stress_n = np.ascontiguousarray(stress_n, dtype=np.float64)
    if stress_n.ndim != 2 or stress_n.shape[1] != 3:
        raise ValueError(f"stress_n has shape {stress_n.shape}, expected (n, 3)")
    n = stress_n.shape[0]
    state_n = _as_input("state_n", state_n, (n, len(STATE_NAMES[tier])))
    dstrain = _as_input("dstrain", dstrain, (n, 3))
    dspin = _as_input("dspin", dspin, (n,))
    if out is None:
        out = allocate(tier, n)
    elif out.stress.shape != (n, 3) or out.state.shape != state_n.shape:
        raise ValueError(f"out is sized for {out.stress.shape[0]} points of another tier, "
                         f"expected {n} points of tier {tier}")
    args = (stress_n, state_n, dstrain, dspin, params.array(tier),
            out.stress, out.state, out.tangent, out.status)
    if n < PARALLEL_MIN_POINTS:
        with numba_threads(1):
            kernel(*args)
    else:
        kernel(*args)
    return out


def spin_derivative(stress: np.ndarray, tangent: np.ndarray, dstrain: np.ndarray) -> np.ndarray:
    """S = ∂σ_{n+1}/∂Δω = W(σ_{n+1}) - T W(Δε) of an objective update.

    Every tier rotates its inputs by the exact angle Δω and then updates objectively,
    U(Qσ, Qq, QΔεQᵀ) = Q U(σ, q, Δε) Qᵀ; differentiating that identity in the rotation angle
    gives S = W(σ_{n+1}) - T W(Δε), W(s) = d/dα (Q_α s Q_αᵀ) at α = 0, that is
    (-2 s_xy, 2 s_xy, s_xx - s_yy) for a stress and (-Δγ, Δγ, 2(Δε_xx - Δε_yy)) for Δε,
    with T the consistent tangent.

    One point ((3,), (3, 3), (3,)) or many ((n, 3), (n, 3, 3), (n, 3)) at once.
    """
    w_stress = np.stack([-2.0 * stress[..., 2], 2.0 * stress[..., 2],
                         stress[..., 0] - stress[..., 1]], axis=-1)
    w_strain = np.stack([-dstrain[..., 2], dstrain[..., 2],
                         2.0 * (dstrain[..., 0] - dstrain[..., 1])], axis=-1)
    return w_stress - np.einsum("...ij,...j->...i", tangent, w_strain)
