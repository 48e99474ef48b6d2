r"""Stress probing (seed 001 §3, in 2D): the plastic strain direction and the yield-surface
normal at a state on the yield surface, and the non-associativity angle between them.

A probe family with unloading and a hold reference (:class:`dem.paths.ProbeFamily`,
``unload = true, hold = true``) is run from one state, by the DEM or by the material point.
Each probe k ramps the stress by Δσ_k = m (cos β_k, sin β_k) in the (σxx, σyy) plane
(σxy held) and back. Following Bardet (1994) as seed 001 §3.3.1 does, the strain left
after unloading is the plastic strain, and the elastic strain is the rest:

    Δε_k  = ε(end of loading) - ε(start) - [same for the hold probe]
    Δεp_k = ε(end of unloading) - ε(start) - [same for the hold probe]

(the hold probe removes the drift of the start state itself, e.g. the DEM's creep).

For an elastic-plastic material with yield normal n and flow direction m (both unit
vectors in the (xx, yy) plane; stress and strain spaces paired by σxx εxx + σyy εyy),
Δεp = m (n·Δσ)₊ / H: the plastic strains share one direction (seed 001: an approximately
unique plastic strain direction), and their size along it, p_k = Δεp_k · m, follows
a (n·Δσ_k/|Δσ_k|)₊. So

* flow direction m: the direction of Σ_k Δεp_k over the probes whose plastic strain is at
  least ``LOADING_FRACTION`` of the largest;
* yield normal n = (cos β_n, sin β_n): the least-squares fit of p_k ≈ a max(0, cos(β_k - β_n))
  over every probe (a >= 0 in closed form for each β_n, β_n by a grid then a bounded
  scalar minimization): "the locus of stress states of the same plastic strain norm"
  (seed 001 §3.3.1) in incremental form;
* non-associativity angle δ = β_n - angle(m), wrapped to (-180°, 180°]; δ = 0 for an
  associated flow rule.

For the isotropic cone (tiers 0/1) at a biaxial state σxy = 0, σyy < σxx:
n ∝ (1 + sin φ, -1 + sin φ) and m ∝ (1 + sin ψ, -1 + sin ψ) (DESIGN §4), so δ follows in
closed form (:func:`cone_angles`); the tests check the probe analysis against it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

LOADING_FRACTION = 0.25
PLASTIC_FLOOR = 1e-6
"""Plastic strains below this fraction of the total response are round-off: no plasticity."""


@dataclass(frozen=True)
class ProbeResponse:
    """Per probe: stress increment at the end of loading, total and plastic strain (xx, yy)."""

    dsig: np.ndarray       # (n, 2)
    total: np.ndarray      # (n, 2)
    plastic: np.ndarray    # (n, 2)
    start_stress: np.ndarray   # (3,) (sxx, syy, sxy) of the start state, units of P0


def probe_response(histories: Sequence[Mapping[str, np.ndarray]]) -> ProbeResponse:
    """The response of a load-unload family whose last history is the hold probe."""
    if len(histories) < 5:
        raise ValueError(f"a probe family needs >= 4 probes and the hold reference, got "
                         f"{len(histories)} histories")

    def parts(h):
        stage = np.asarray(h["stage"]).astype(int)
        if stage.max() != 1:
            raise ValueError("probe histories must have a loading and an unloading stage "
                             "(ProbeFamily with unload = true)")
        i = np.flatnonzero(stage == 0)[-1]
        strain = np.stack([np.asarray(h["eps_xx"]), np.asarray(h["eps_yy"])], 1)
        stress = np.stack([np.asarray(h["sxx"]), np.asarray(h["syy"])], 1)
        return stress[i] - stress[0], strain[i] - strain[0], strain[-1] - strain[0]

    *probes, hold = histories
    _, hold_total, hold_resid = parts(hold)
    dsig, total, plastic = [], [], []
    for h in probes:
        ds, tot, res = parts(h)
        dsig.append(ds)
        total.append(tot - hold_total)
        plastic.append(res - hold_resid)
    h0 = histories[0]
    start = np.array([h0["sxx"][0], h0["syy"][0], h0["sxy"][0]], dtype=float)
    return ProbeResponse(np.array(dsig), np.array(total), np.array(plastic), start)


@dataclass(frozen=True)
class FlowAnalysis:
    """Directions (degrees, in the (xx, yy) plane) of the yield normal and the plastic flow,
    their difference δ (the non-associativity angle), and the fit's quality."""

    normal_deg: float
    flow_deg: float
    nonassociativity_deg: float
    sin_psi: float             # tr Δεp / |Δεp_xx - Δεp_yy| of the flow direction
    fit_r2: float              # of p_k ≈ a max(0, cos(β_k - β_n))
    plastic_max: float         # largest |Δεp_k|

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def _wrap_deg(a: float) -> float:
    return -((-a + 180.0) % 360.0 - 180.0)


def analyse(resp: ProbeResponse) -> FlowAnalysis:
    """Flow direction, yield normal and non-associativity angle (module doc)."""
    from scipy.optimize import minimize_scalar

    size = np.hypot(resp.plastic[:, 0], resp.plastic[:, 1])
    total = np.hypot(resp.total[:, 0], resp.total[:, 1]).max()
    if not np.all(np.isfinite(size)) or size.max() <= PLASTIC_FLOOR * total:
        raise ValueError("no plastic strain in any probe: the start state is not on the "
                         "yield surface (or the probes are too small)")
    loading = size >= LOADING_FRACTION * size.max()
    m = resp.plastic[loading].sum(axis=0)
    m = m / np.hypot(*m)
    p = resp.plastic @ m
    beta = np.arctan2(resp.dsig[:, 1], resp.dsig[:, 0])

    def sse(bn):
        g = np.maximum(0.0, np.cos(beta - bn))
        a = max(0.0, float(g @ p) / float(g @ g)) if g @ g > 0 else 0.0
        r = p - a * g
        return float(r @ r)

    grid = np.radians(np.arange(0.0, 360.0, 0.5))
    b0 = grid[np.argmin([sse(b) for b in grid])]
    bn = minimize_scalar(sse, bounds=(b0 - math.radians(1), b0 + math.radians(1)),
                         method="bounded", options={"xatol": 1e-10}).x
    r2 = 1.0 - sse(bn) / float(((p - p.mean()) ** 2).sum())
    normal = math.degrees(bn)
    flow = math.degrees(math.atan2(m[1], m[0]))
    return FlowAnalysis(_wrap_deg(normal), flow, _wrap_deg(normal - flow),
                        float((m[0] + m[1]) / abs(m[0] - m[1])), float(r2), float(size.max()))


def cone_angles(sin_phi: float, sin_psi: float) -> tuple[float, float, float]:
    """(normal, flow, δ) in degrees of the isotropic cone at a biaxial state with σyy < σxx
    (module doc)."""
    normal = math.degrees(math.atan2(-1.0 + sin_phi, 1.0 + sin_phi))
    flow = math.degrees(math.atan2(-1.0 + sin_psi, 1.0 + sin_psi))
    return normal, flow, _wrap_deg(normal - flow)
