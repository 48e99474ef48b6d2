"""Model parameters: a TOML file of sections, validated on load.

A parameter file holds the selected ``tier`` and one table per section::

    tier = 1
    [regularization]   lambda, p_ref, nu          (all tiers)
    [tier0]            phi_deg, psi_deg            (tier 0)
    [tier1]            phi_star_deg, dphi_dc_deg, dpsi_dc_deg, c_star, phi_min_deg, phi_max_deg
    [tier2]            fabric_weight, dilatancy_fabric, fabric_law, kappa_a, k_c, k_o,
                       z_crit, b_ratio_crit, relax_rate (tier 2, with [tier1])
    [initial]          c0, A0, B0, theta_p0_deg    (initial state of tiers >= 1)
    [provenance]       free-form (how the file was made, e.g. by ``contfab calibrate``);
                       not validated, not part of the parameter set

Each section is a small frozen dataclass (a :class:`Section`) whose fields declare
their unit, accepted range and meaning; loading checks every value against its
range, then the section's cross-field rules, then rules that involve two sections
(:meth:`Section.check_with`). Every failure raises :class:`ParamError` (a
``ValueError``) whose message names the value and the accepted range.

Adding a section is local: write its dataclass, add it to :data:`SECTIONS`, and
list which sections a tier's kernel reads in :data:`TIER_SECTIONS`.
:meth:`Params.array` places their :meth:`Section.array` parts into the flat
float64 array the kernel reads, each value at its named offset (the module constants
``BULK`` ... ``RELAX_RATE`` below); the kernels read ``prm[NAME]`` by the same names.

Units: angles in degrees here (user-facing), radians in the arrays; stresses in
the scene's stress unit (``p_ref`` is the scene's stress scale, e.g. P0 = 1 in DEM
units, or kPa); c and the fabric are dimensionless (A = z/π per radian).
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import MISSING, dataclass, field, fields, replace
from pathlib import Path
from typing import ClassVar, Mapping

import numpy as np

from dem.conventions import admissibility_margin


class ParamError(ValueError):
    """A parameter is missing, unknown, or outside its accepted range."""


# --------------------------------------------------------------------------- field specs

@dataclass(frozen=True)
class Range:
    """An interval of accepted values; ``closed`` says which ends belong to it."""

    lo: float
    hi: float
    lo_closed: bool = False
    hi_closed: bool = False

    def __contains__(self, x: float) -> bool:
        above = x >= self.lo if self.lo_closed else x > self.lo
        below = x <= self.hi if self.hi_closed else x < self.hi
        return above and below

    def __str__(self) -> str:
        return (f"{'[' if self.lo_closed else '('}{self.lo:g}, "
                f"{self.hi:g}{']' if self.hi_closed else ')'}")


def param(unit: str, accepted: Range, doc: str, *, key: str | None = None,
          default: float = MISSING):
    """A section field: its unit, accepted range, meaning, and TOML key (default: its name)."""
    return field(default=default,
                 metadata={"unit": unit, "range": accepted, "doc": doc, "key": key})


def _key(f) -> str:
    return f.metadata["key"] or f.name


class Section:
    """Base of a parameter section (subclasses are frozen dataclasses of :func:`param` fields)."""

    NAME: ClassVar[str] = ""

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            where = f"[{self.NAME}] {_key(f)}"
            accepted = f"{f.metadata['range']}{' ' + f.metadata['unit'] if f.metadata['unit'] else ''}"
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ParamError(f"{where} = {value!r} is not a number (accepted range {accepted})")
            value = float(value)
            if math.isnan(value) or value not in f.metadata["range"]:
                raise ParamError(f"{where} = {value:g} is outside the accepted range {accepted} "
                                 f"({f.metadata['doc']})")
            object.__setattr__(self, f.name, value)
        self.check()

    def check(self) -> None:
        """Cross-field rules of this section (raise :class:`ParamError`)."""

    def check_with(self, sections: Mapping[str, "Section"]) -> None:
        """Rules that involve other sections of the same file (raise :class:`ParamError`)."""

    def array(self) -> dict[int, float]:
        """This section's part of a kernel's parameter array: {offset: value} (offsets: the
        module constants)."""
        return {}

    def to_dict(self) -> dict[str, float]:
        """The section as its TOML table (the inverse of :meth:`from_dict`)."""
        return {_key(f): getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, table: Mapping) -> "Section":
        if not isinstance(table, Mapping):
            raise ParamError(f"[{cls.NAME}] must be a table, got {table!r}")
        by_key = {_key(f): f for f in fields(cls)}
        unknown = sorted(set(table) - set(by_key))
        if unknown:
            raise ParamError(f"[{cls.NAME}] has unknown key(s) {', '.join(unknown)}; "
                             f"known: {', '.join(by_key)}")
        missing = [k for k, f in by_key.items() if f.default is MISSING and k not in table]
        if missing:
            raise ParamError(f"[{cls.NAME}] is missing {', '.join(missing)}")
        return cls(**{by_key[k].name: v for k, v in table.items()})


POSITIVE = Range(0.0, math.inf)
UNIT_OPEN = Range(0.0, 1.0)


# --------------------------------------------------------------------------- kernel arrays
# Offset of each value in the flat array of Params.array(tier): the sections' array()
# write by these names and the kernels read prm[NAME], so the two cannot disagree on the
# order. numba freezes them at compile time (its cache is keyed on every source file, so
# an edit here recompiles the kernels: dem.numba_cache).
# All tiers: the regularization's moduli.
BULK = 0            # K
SHEAR = 1           # G
# Tier 0.
SIN_PHI = 2         # sin phi
SIN_PSI = 3         # sin psi
# Tiers 1 and 2 (angles in radians).
PHI_STAR = 2        # phi*
DPHI_DC = 3         # phi' = dphi/dc
DPSI_DC = 4         # psi' = dpsi/dc
C_STAR = 5          # c*
PHI_MIN = 6         # clamps of phi(c)
PHI_MAX = 7
# Tier 2.
FABRIC_WEIGHT = 8     # w: the cone's axis alpha = w (Bc, Bs)/A
DILATANCY_FABRIC = 9  # k_d: D = sin psi(c) + k_d (alignment - w b_c)
FABRIC_LAW = 10       # Tier2.LAWS code: 0 balance, 1 relaxation
KAPPA_A = 11          # balance law: kappa_a, kc, ko
K_C = 12
K_O = 13
A_CRIT = 14           # relaxation law: A_c = z_c/pi, b_c = B_c/A_c, rate k per unit plastic shear
B_RATIO_CRIT = 15
RELAX_RATE = 16
FABRIC_SPEED = 17     # relaxation law: largest speed v of the anisotropy (inf: exponential)
FABRIC_DILATION = 18  # relaxation law: acceleration beta of the rate by dilation


# --------------------------------------------------------------------------- sections

@dataclass(frozen=True)
class Regularization(Section):
    """The elastic regularization of the rigid-plastic model (docs/theory.md §3).

    Isotropic 2D elasticity with Young-like modulus E_reg = λ·p_ref and Poisson-like
    ratio ν: bulk K = E_reg / (2(1 - ν)) (mean stress = K tr ε), shear G = E_reg / (2(1 + ν))
    (deviator = 2G dev ε). Rigid-plastic is λ → ∞; the elastic strain at a stress of order
    p_ref is of order 1/λ.
    """

    NAME: ClassVar[str] = "regularization"
    lam: float = param("", POSITIVE, "stiffness ratio E_reg / p_ref; rigid-plastic as lambda -> inf",
                       key="lambda")
    p_ref: float = param("stress", POSITIVE, "the scene's stress scale (e.g. P0)")
    nu: float = param("", Range(-1.0, 1.0), "Poisson-like ratio of the regularization", default=0.0)

    def moduli(self) -> tuple[float, float]:
        """(K, G) of the regularization, in the scene's stress unit."""
        e = self.lam * self.p_ref
        return e / (2.0 * (1.0 - self.nu)), e / (2.0 * (1.0 + self.nu))

    def array(self) -> dict[int, float]:
        bulk, shear = self.moduli()
        return {BULK: bulk, SHEAR: shear}

    def check_return(self, min_sin_product: float, what: str) -> None:
        """The cone return divides by G + K sin φ sin ψ: it must stay positive.

        ``min_sin_product`` is the smallest sin φ · sin ψ the tier can reach (negative
        only for contractant flow, ψ < 0).
        """
        k, g = self.moduli()
        if g + k * min_sin_product <= 0.0:
            raise ParamError(
                f"[regularization] nu = {self.nu:g} makes the cone return ill-posed with {what}: "
                f"need (1 + nu)/(1 - nu) * sin(phi) * (-sin(psi)) < 1, got "
                f"{k / g * -min_sin_product:.4g}; lower nu (accepted range here: "
                f"nu < {(1 + min_sin_product) / (1 - min_sin_product):.4g})")


@dataclass(frozen=True)
class Tier0(Section):
    """Tier 0: constant friction angle φ and dilatancy angle ψ (Roux & Radjaï 2001, §3)."""

    NAME: ClassVar[str] = "tier0"
    phi_deg: float = param("deg", Range(0.0, 90.0), "friction angle phi")
    psi_deg: float = param("deg", Range(-90.0, 90.0), "dilatancy angle psi, |psi| <= phi",
                           default=0.0)

    def check(self) -> None:
        if abs(self.psi_deg) > self.phi_deg:
            raise ParamError(f"[tier0] psi_deg = {self.psi_deg:g} is outside the accepted range "
                             f"[-phi, phi] = [{-self.phi_deg:g}, {self.phi_deg:g}] deg")

    def check_with(self, sections) -> None:
        sections["regularization"].check_return(
            math.sin(math.radians(self.phi_deg)) * math.sin(math.radians(self.psi_deg)),
            f"[tier0] phi_deg = {self.phi_deg:g}, psi_deg = {self.psi_deg:g}")

    def array(self) -> dict[int, float]:
        return {SIN_PHI: math.sin(math.radians(self.phi_deg)),
                SIN_PSI: math.sin(math.radians(self.psi_deg))}


@dataclass(frozen=True)
class Tier1(Section):
    """Tier 1: φ(c), ψ(c) linear around the critical state c* (docs/theory.md §5).

    φ(c) = φ* + φ'(c - c*) clamped to [phi_min, phi_max]; ψ(c) = ψ'(c - c*) clamped to
    [-φ(c), φ(c)] (so |ψ| <= φ at every c and ψ(c*) = 0). The clamps only act at c far
    from c*, where the linear (Taylor) law has left its range of validity anyway; both
    stay continuous in c. φ' >= 0 and ψ' >= 0: denser is stronger and more dilatant,
    which makes the implicit c update well-posed (see :mod:`contfab.models.cone`).
    """

    NAME: ClassVar[str] = "tier1"
    phi_star_deg: float = param("deg", Range(0.0, 90.0), "critical-state friction angle phi*")
    dphi_dc_deg: float = param("deg per unit c", Range(0.0, math.inf, lo_closed=True),
                               "phi' = dphi/dc at c*")
    dpsi_dc_deg: float = param("deg per unit c", Range(0.0, math.inf, lo_closed=True),
                               "psi' = dpsi/dc at c*")
    c_star: float = param("", UNIT_OPEN, "critical packing fraction c*")
    phi_min_deg: float = param("deg", Range(0.0, 90.0), "lower clamp of phi(c)", default=1.0)
    phi_max_deg: float = param("deg", Range(0.0, 90.0), "upper clamp of phi(c)", default=60.0)

    def check(self) -> None:
        if not self.phi_min_deg <= self.phi_star_deg <= self.phi_max_deg:
            raise ParamError(
                f"[tier1] phi_star_deg = {self.phi_star_deg:g} is outside the accepted range "
                f"[phi_min_deg, phi_max_deg] = [{self.phi_min_deg:g}, {self.phi_max_deg:g}] deg")

    def check_with(self, sections) -> None:
        # For c < c* (the only place ψ < 0) φ(c) <= φ*, and |ψ| <= φ: sin φ sin ψ >= -sin²φ*.
        s = math.sin(math.radians(self.phi_star_deg))
        sections["regularization"].check_return(
            -s * s if self.dpsi_dc_deg > 0 else 0.0,
            f"[tier1] phi_star_deg = {self.phi_star_deg:g} (worst case psi = -phi*)")

    def array(self) -> dict[int, float]:
        r = math.radians
        return {PHI_STAR: r(self.phi_star_deg), DPHI_DC: r(self.dphi_dc_deg),
                DPSI_DC: r(self.dpsi_dc_deg), C_STAR: self.c_star,
                PHI_MIN: r(self.phi_min_deg), PHI_MAX: r(self.phi_max_deg)}


@dataclass(frozen=True)
class Tier2(Section):
    """Tier 2: the cone whose axis follows the fabric, fabric hardening (docs/theory.md §6–§7).

    Yield |s + P α| <= m(c) P with the axis α = w (Bc, Bs)/A and the radius
    m(c) = sin φ(c) - w b_c (φ(c) and ψ(c) are tier 1's, read from ``[tier1]``: where the
    fabric is the critical one aligned with the loading, the strength is tier 1's); flow
    along u = s + P α with dilatancy D = sin ψ(c) + k_d (ā - w b_c), ā the axis' alignment
    with the flow's compression axis (:mod:`contfab.models.fabric_cone`). ``fabric_law``:
    "relaxation" (toward the critical fabric z_crit, b_ratio_crit at rate relax_rate per
    unit plastic shear strain) or "balance" (the projected balance law, κa, kc, ko)
    (:mod:`contfab.models.fabric_law`).
    """

    NAME: ClassVar[str] = "tier2"
    LAWS: ClassVar[dict[str, int]] = {"balance": 0, "relaxation": 1}
    fabric_weight: float = param("-", Range(0.0, 1.0, lo_closed=True),
                                 "w: the contact part of the stress ratio per unit B/A "
                                 "(1/2 in the stress-force-fabric relation)", default=0.5)
    dilatancy_fabric: float = param("-", Range(0.0, 10.0, True, True),
                                    "k_d: dilatancy per unit misalignment of the fabric "
                                    "(Rowe-Taylor slope)", default=0.9)
    fabric_law: float = param("balance | relaxation", Range(0.0, 1.0, True, True),
                              "fabric hardening law", default=1.0)
    kappa_a: float = param("-", Range(0.0, math.inf, lo_closed=True),
                           "balance law: advection coefficient kappa_a", default=3.94)
    k_c: float = param("-", Range(0.0, math.inf, lo_closed=True),
                       "balance law: creation coefficient kc", default=17.76)
    k_o: float = param("-", Range(0.0, math.inf, lo_closed=True),
                       "balance law: opening coefficient ko", default=10.0)
    z_crit: float = param("-", Range(0.0, 6.0), "critical coordination z_c (relaxation law)",
                          default=3.0)
    b_ratio_crit: float = param("-", Range(0.0, 1.0, lo_closed=True),
                                "critical anisotropy b_c = B/A", default=0.25)
    relax_rate: float = param("per unit plastic shear strain", Range(0.0, math.inf, lo_closed=True),
                              "relaxation law: rate k", default=13.0)
    fabric_speed: float = param("per unit plastic shear strain",
                                Range(0.0, math.inf, hi_closed=True),
                                "relaxation law: largest speed v of B/A_c toward its target "
                                "(inf: exponential relaxation at rate k)", default=math.inf)
    fabric_dilation: float = param("-", Range(0.0, math.inf, lo_closed=True),
                                   "relaxation law: the rate times 1 + beta tr(dep)/dgamma_s "
                                   "while dilating", default=0.0)

    def to_dict(self) -> dict:
        """As :meth:`Section.to_dict`, with ``fabric_law`` by name."""
        names = {code: name for name, code in self.LAWS.items()}
        return {**super().to_dict(), "fabric_law": names[int(self.fabric_law)]}

    @classmethod
    def from_dict(cls, table: Mapping) -> "Tier2":
        """As :meth:`Section.from_dict`, with ``fabric_law`` given by name."""
        if isinstance(table, Mapping) and isinstance(table.get("fabric_law"), str):
            law = table["fabric_law"]
            if law not in cls.LAWS:
                raise ParamError(f"[tier2] fabric_law = {law!r} is not a known law "
                                 f"(accepted: {', '.join(cls.LAWS)})")
            table = {**table, "fabric_law": cls.LAWS[law]}
        return super().from_dict(table)

    def check(self) -> None:
        if self.fabric_law != int(self.fabric_law):
            raise ParamError(f"[tier2] fabric_law = {self.fabric_law:g} is not a known law "
                             f"(accepted: {', '.join(self.LAWS)})")
        a_c = self.z_crit / math.pi
        steric = 1.0 - math.pi / 6.0 * a_c - math.sqrt(3.0) / 4.0 * self.b_ratio_crit * a_c
        if not steric > 0.0:
            raise ParamError(
                f"[tier2] z_crit = {self.z_crit:g}, b_ratio_crit = {self.b_ratio_crit:g} is not "
                f"an admissible critical fabric: need B/A < 1 and z_c/6 + (sqrt(3)/4) "
                f"b z_c/pi < 1 (Roux & Radjai 2001, eqs 1.14-1.15), got "
                f"{self.z_crit / 6 + math.sqrt(3) / 4 * self.b_ratio_crit * a_c:.4g}")

    def check_with(self, sections) -> None:
        """The cone's radius m(c) = sin φ(c) - w b_c must stay positive for every c: its
        smallest value is at tier 1's lower clamp φ_min."""
        tier1 = sections.get("tier1")
        if tier1 is None:
            return
        shift = self.fabric_weight * self.b_ratio_crit
        if not math.sin(math.radians(tier1.phi_min_deg)) > shift:
            raise ParamError(
                f"[tier1] phi_min_deg = {tier1.phi_min_deg:g} leaves tier 2's cone empty: its "
                f"radius sin(phi) - w b_c must be positive, i.e. phi_min_deg > "
                f"{math.degrees(math.asin(min(shift, 1.0))):.4g} for w = {self.fabric_weight:g}, "
                f"b_ratio_crit = {self.b_ratio_crit:g}")

    def array(self) -> dict[int, float]:
        return {FABRIC_WEIGHT: self.fabric_weight, DILATANCY_FABRIC: self.dilatancy_fabric,
                FABRIC_LAW: self.fabric_law,
                KAPPA_A: self.kappa_a, K_C: self.k_c, K_O: self.k_o,
                A_CRIT: self.z_crit / math.pi, B_RATIO_CRIT: self.b_ratio_crit,
                RELAX_RATE: self.relax_rate, FABRIC_SPEED: self.fabric_speed,
                FABRIC_DILATION: self.fabric_dilation}


@dataclass(frozen=True)
class Initial(Section):
    """The initial state: packing fraction and fabric (A, B, θp), p(θ) = A + B cos 2(θ - θp)."""

    NAME: ClassVar[str] = "initial"
    c0: float = param("", UNIT_OPEN, "initial packing fraction")
    A0: float = param("1/rad", Range(0.0, 6.0 / math.pi, lo_closed=True, hi_closed=True),
                      "initial A = z/pi (z: coordination number)", default=3.0 / math.pi)
    B0: float = param("1/rad", Range(0.0, 6.0 / math.pi, lo_closed=True, hi_closed=True),
                      "initial fabric anisotropy B, 0 <= B <= A", default=0.0)
    theta_p0_deg: float = param("deg", Range(-90.0, 90.0, hi_closed=True),
                                "initial fabric direction theta_p", default=0.0)

    def check(self) -> None:
        margin = float(admissibility_margin(self.A0, self.B0))
        if margin < 0.0:
            raise ParamError(
                f"[initial] A0 = {self.A0:g}, B0 = {self.B0:g} is not an admissible fabric: "
                f"need 0 <= B0 <= A0 and (pi/6) A0 + (sqrt(3)/4) B0 <= 1 (Roux & Radjai 2001, eqs 1.14-1.15), "
                f"got B0 - A0 = {self.B0 - self.A0:.4g}, "
                f"(pi/6) A0 + (sqrt(3)/4) B0 = {math.pi / 6 * self.A0 + math.sqrt(3) / 4 * self.B0:.4g}")

    def state_values(self) -> dict[str, float]:
        """Initial value of every state variable name of :data:`contfab.models.tiers.STATE_NAMES`."""
        two = 2.0 * math.radians(self.theta_p0_deg)
        return {"gp": 0.0, "c": self.c0, "A": self.A0,
                "Bc": self.B0 * math.cos(two), "Bs": self.B0 * math.sin(two)}


SECTIONS: dict[str, type[Section]] = {
    "regularization": Regularization,
    "tier0": Tier0,
    "tier1": Tier1,
    "tier2": Tier2,
    "initial": Initial,
}
"""Every known section, by its TOML table name."""

TIER_SECTIONS: dict[int, tuple[str, ...]] = {
    0: ("regularization", "tier0"),
    1: ("regularization", "tier1"),
    2: ("regularization", "tier1", "tier2"),     # tier 2 reads tier 1's c-terms and clamps
}
"""Sections whose :meth:`Section.array` parts, together, form a tier's kernel array."""

def _check_tier(tier) -> int:
    if isinstance(tier, bool) or not isinstance(tier, (int, np.integer)) or int(tier) not in TIER_SECTIONS:
        raise ParamError(f"tier = {tier!r} is not a known model tier "
                         f"(accepted: {', '.join(map(str, sorted(TIER_SECTIONS)))})")
    return int(tier)


# --------------------------------------------------------------------------- the parameter set

@dataclass(frozen=True)
class Params:
    """A validated parameter set: the selected tier and its sections.

    Sections are reachable as attributes (``params.tier1.c_star``).
    """

    tier: int
    sections: Mapping[str, Section]
    source: str = "<dict>"
    _arrays: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "tier", _check_tier(self.tier))
        for name in self.required_sections(self.tier):
            if name not in self.sections:
                raise ParamError(f"tier {self.tier} needs a [{name}] section, absent from {self.source}")
        for section in self.sections.values():
            section.check_with(self.sections)

    def __getattr__(self, name: str) -> Section:
        sections = object.__getattribute__(self, "sections")
        if name in sections:
            return sections[name]
        raise AttributeError(f"no section or attribute {name!r} in these parameters")

    @staticmethod
    def required_sections(tier: int) -> tuple[str, ...]:
        """Sections a tier needs: its kernel's, plus ``[initial]`` for tiers with a state beyond gp."""
        return TIER_SECTIONS[tier] + (("initial",) if tier >= 1 else ())

    @property
    def p_ref(self) -> float:
        """The scene's stress scale."""
        return self.sections["regularization"].p_ref

    def array(self, tier: int | None = None) -> np.ndarray:
        """The flat float64 parameter array of ``tier``'s kernel (default: the selected tier)."""
        tier = self.tier if tier is None else _check_tier(tier)
        if tier not in self._arrays:     # sections are frozen: build each array once
            missing = [s for s in TIER_SECTIONS[tier] if s not in self.sections]
            if missing:
                raise ParamError(f"tier {tier} needs section(s) {', '.join(missing)}, "
                                 f"absent from {self.source}")
            at = {}
            for s in TIER_SECTIONS[tier]:
                at.update(self.sections[s].array())
            self._arrays[tier] = np.array([at[k] for k in range(len(at))], dtype=np.float64)
        return self._arrays[tier].copy()

    def replace(self, section: str, **changes) -> "Params":
        """A new validated parameter set with some fields of one section changed."""
        if section not in self.sections:
            raise ParamError(f"no [{section}] section in {self.source}")
        new = dict(self.sections)
        try:
            new[section] = replace(self.sections[section], **changes)
        except TypeError as exc:   # an unknown field name
            raise ParamError(f"[{section}]: {exc}") from None
        return Params(self.tier, new, self.source)

    def with_tier(self, tier: int) -> "Params":
        """The same sections with another tier selected (validated)."""
        return Params(tier, self.sections, self.source)

    def to_dict(self) -> dict:
        """The parameter set as a TOML/JSON document (the inverse of :meth:`from_dict`)."""
        return {"tier": self.tier, **{name: s.to_dict() for name, s in self.sections.items()}}

    @classmethod
    def from_dict(cls, data: Mapping, source: str = "<dict>") -> "Params":
        """Validate a parsed TOML document (``tier`` plus one table per section)."""
        data = dict(data)
        data.pop("provenance", None)      # free-form record of how the file was made
        if "tier" not in data:
            raise ParamError(f"{source}: missing the top-level 'tier' "
                             f"(accepted: {', '.join(map(str, sorted(TIER_SECTIONS)))})")
        tier = data.pop("tier")
        unknown = sorted(set(data) - set(SECTIONS))
        if unknown:
            raise ParamError(f"{source}: unknown section(s) {', '.join(unknown)}; "
                             f"known: {', '.join(SECTIONS)}")
        sections = {name: SECTIONS[name].from_dict(table) for name, table in data.items()}
        return cls(tier, sections, source)


def load_params(path: str | Path) -> Params:
    """Read and validate a parameter TOML file."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ParamError(f"{path}: not valid TOML: {exc}") from None
    return Params.from_dict(data, source=str(path))


def default_params_path() -> Path:
    """The shipped default parameter file (``contfab calibrate`` at its defaults)."""
    return Path(__file__).resolve().parent / "data" / "default_params.toml"


def default_params() -> Params:
    """The shipped default parameters, validated."""
    return load_params(default_params_path())


def default_params_digest() -> str:
    """A short content hash of the shipped parameter file: results computed with the
    defaults carry it, so a recalibration is not mistaken for the same material."""
    import hashlib

    return hashlib.sha1(default_params_path().read_bytes()).hexdigest()[:12]
