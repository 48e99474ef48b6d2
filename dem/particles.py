"""Disc sizes, masses and moments of inertia.

Units: the mean diameter is d = 1 and the 2D mass density (mass per area) is ρ, so a
disc of radius r has mass m = ρ π r² and moment of inertia I = m r² / 2.

Radii distributions (all normalized to a mean diameter of exactly 1 in expectation):

* ``uniform:W``       diameters uniform in [1 - W, 1 + W], 0 <= W < 1 (the w0 of Madadi
                      et al. 2004 is the same relative half-width on radii: radii in
                      [(1-w0)ā, (1+w0)ā]).
                      Stratified sampling: one radius per 1/N quantile slice, shuffled,
                      so the sample's moments are those of the law to O(1/N²).
* ``bidisperse:Q:F``  two radii in ratio Q = r_large/r_small >= 1, a number fraction F of
                      small discs (0 < F < 1); exactly round(F N) small ones.
* explicit radii      an array given by the caller (``RadiiSpec.explicit``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


class ParticleError(ValueError):
    """Bad particle sizes or configuration; the message names the value and accepted range."""


@dataclass(frozen=True)
class RadiiSpec:
    """A radii distribution; see the module docstring for the kinds."""

    kind: str
    width: float = 0.0
    ratio: float = 1.0
    fraction: float = 0.5
    values: tuple[float, ...] = ()

    @classmethod
    def explicit(cls, radii) -> "RadiiSpec":
        r = np.asarray(radii, dtype=float).ravel()
        bad = ~np.isfinite(r) | (r <= 0)
        if r.size == 0 or bad.any():
            first = r[bad][0] if bad.any() else None
            raise ParticleError(f"explicit radius {first!r} is not allowed: every radius must be a "
                                f"positive finite number (accepted range (0, inf))"
                                if bad.any() else "explicit radii: need at least one radius")
        return cls("explicit", values=tuple(float(x) for x in r))

    def describe(self) -> str:
        if self.kind == "uniform":
            return f"uniform:{self.width:g}"
        if self.kind == "bidisperse":
            return f"bidisperse:{self.ratio:g}:{self.fraction:g}"
        return f"explicit({len(self.values)} radii)"


def parse_radii(text: str) -> RadiiSpec:
    """A :class:`RadiiSpec` from ``uniform:W`` or ``bidisperse:Q:F`` (see the module doc)."""
    parts = str(text).split(":")
    try:
        nums = [float(x) for x in parts[1:]]
    except ValueError:
        raise ParticleError(f"radii spec {text!r}: numbers expected after the kind, e.g. "
                            f"'uniform:0.2' or 'bidisperse:3:0.5'") from None
    if parts[0] == "uniform" and len(nums) == 1:
        w = nums[0]
        if not (0.0 <= w < 1.0):
            raise ParticleError(f"radii spec {text!r}: width W = {w} out of range; accepted "
                                f"0 <= W < 1 (diameters in [1-W, 1+W] must stay positive)")
        return RadiiSpec("uniform", width=w)
    if parts[0] == "bidisperse" and len(nums) == 2:
        q, f = nums
        if not (q >= 1.0 and np.isfinite(q)):
            raise ParticleError(f"radii spec {text!r}: ratio Q = {q} out of range; accepted "
                                f"1 <= Q < inf (r_large / r_small)")
        if not (0.0 < f < 1.0):
            raise ParticleError(f"radii spec {text!r}: small-disc number fraction F = {f} out of "
                                f"range; accepted 0 < F < 1")
        return RadiiSpec("bidisperse", ratio=q, fraction=f)
    raise ParticleError(f"radii spec {text!r} not understood; accepted 'uniform:W' "
                        f"(0 <= W < 1) or 'bidisperse:Q:F' (Q >= 1, 0 < F < 1)")


def sample_radii(spec: RadiiSpec, n: int, rng: np.random.Generator) -> np.ndarray:
    """(n,) radii drawn from ``spec`` (mean diameter 1 in expectation)."""
    if n < 1:
        raise ParticleError(f"number of discs n = {n} out of range; accepted n >= 1")
    if spec.kind == "uniform":
        u = (np.arange(n) + rng.random(n)) / n
        r = 0.5 * (1.0 - spec.width + 2.0 * spec.width * u)
        return rng.permutation(r)
    if spec.kind == "bidisperse":
        small = 0.5 / (spec.fraction + (1.0 - spec.fraction) * spec.ratio)
        ns = int(round(spec.fraction * n))
        r = np.full(n, small * spec.ratio)
        r[:ns] = small
        return rng.permutation(r)
    if spec.kind == "explicit":
        if len(spec.values) != n:
            raise ParticleError(f"explicit radii: {len(spec.values)} given for n = {n} discs")
        return np.array(spec.values, dtype=float)
    raise ParticleError(f"unknown radii kind {spec.kind!r}; accepted uniform, bidisperse, explicit")


def masses(radius: np.ndarray, rho: float = 1.0) -> np.ndarray:
    """m = ρ π r² (2D density ρ: mass per unit area)."""
    if not (np.isfinite(rho) and rho > 0):
        raise ParticleError(f"density rho = {rho} out of range; accepted (0, inf)")
    return rho * np.pi * np.asarray(radius, dtype=float) ** 2


def inertia(mass: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Moment of inertia of a uniform disc, I = m r² / 2."""
    return 0.5 * mass * radius**2
