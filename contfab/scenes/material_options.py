"""The model options every boundary-value case shares: tier, parameter file, initial density.

    --tier 0|1|2|auto   the model tier (auto: the cheapest model per quadrature point whose
                        measured bound meets --tolerance, :mod:`contfab.fem.auto`)
    --params FILE       the parameter file (default: the shipped, DEM-calibrated one)
    --c0 C|dense|loose  the initial packing fraction of tiers >= 1: a number, ``dense`` (the
                        parameter file's ``[initial] c0``, the default) or ``loose``
                        (:data:`LOOSE_C0`)

Tiers >= 1 take their friction and dilatancy angles from the model at the state: at the
start φ0 = φ(c0), ψ0 = ψ(c0) (:func:`initial_angles`; tier 1's linear laws about c*,
docs/theory.md §5). A dense start (c0 > c*) dilates, softens from φ0 toward the critical
φ* and its ψ falls to 0; a loose one (c0 < c*) contracts and hardens toward φ*.
"""
from __future__ import annotations

import math

import numpy as np

from contfab.models.cone import tier1_angles
from contfab.params import ParamError, Params, default_params, load_params

TIERS = ("0", "1", "2", "auto")
LOOSE_C0 = 0.805
"""The loosest packing fraction the DEM's preparation reaches at P0 (0.8050, seeds 1–2 of
the μ_prep = 10, rate 1e-3 preparation, docs/dem_validation.md §9): c* - 0.007 with the
shipped calibration."""


def add_arguments(p, default_tier: str = "1", tiers=TIERS, default_help: str | None = None
                  ) -> None:
    """Add ``--tier``, ``--params``, ``--c0`` and ``--tolerance`` to a case's parser
    (``default_help`` describes a default the case resolves itself; ``default_tier`` None)."""
    p.add_argument("--tier", choices=tiers, default=default_tier,
                   help=f"model tier (default {default_help or default_tier}); auto: the "
                        "cheapest model per point whose measured bound meets --tolerance "
                        "(contfab.fem.auto)")
    p.add_argument("--params", default=None, help="parameter file (default: the shipped one)")
    p.add_argument("--c0", default=None,
                   help="initial packing fraction of tiers >= 1: a number, 'dense' (the "
                        "parameter file's [initial] c0, the default) or 'loose' "
                        f"({LOOSE_C0}, the DEM's loosest preparation)")
    p.add_argument("--tolerance", type=float, default=0.09,
                   help="auto: tolerated RMS error of R/P against the DEM (default 0.09)")


def load(args) -> Params:
    """The case's parameters: ``--params`` (or the shipped file) with ``--c0`` applied."""
    params = default_params() if args.params is None else load_params(args.params)
    return with_c0(params, args.c0)


def with_c0(params: Params, c0) -> Params:
    """``params`` with ``[initial] c0`` set from a number, 'dense' or 'loose' (None: kept)."""
    if c0 is None or c0 == "dense":
        return params
    if c0 == "loose":
        value = LOOSE_C0
    else:
        try:
            value = float(c0)
        except ValueError:
            raise ParamError(f"c0 = {c0!r} is not a packing fraction; accepted: a number in "
                             "(0, 1), 'dense' or 'loose'") from None
    if not (math.isfinite(value) and 0.0 < value < 1.0):
        raise ParamError(f"c0 = {value:g} is outside the accepted range (0, 1)")
    return params.replace("initial", c0=value)


def initial_angles(params: Params) -> tuple[float, float]:
    """(φ0, ψ0) in degrees of tier 1 at the parameter set's ``[initial] c0``."""
    return angles_at(params, params.initial.c0)


def angles_at(params: Params, c: float) -> tuple[float, float]:
    """(φ(c), ψ(c)) in degrees of tier 1's laws (also tier 2's) at the packing fraction ``c``."""
    phi, psi, _, _ = tier1_angles(float(c), params.array(1))
    return math.degrees(phi), math.degrees(psi)


def tier_arg(tier: str):
    """The ``--tier`` string as an int, or "auto"."""
    return tier if tier == "auto" else int(tier)


def point_updates(material) -> dict[int, int]:
    """{tier: point updates} of a :class:`contfab.fem.material.TierMaterial` (plain ints)."""
    return {int(k): int(v) for k, v in material.point_updates.items()}


def max_tier(tier) -> int:
    """The highest tier of an int or of a per-point array of tiers."""
    return int(np.max(tier))
