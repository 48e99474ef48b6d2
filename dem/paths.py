"""The loading-path description shared by the DEM cell and the material point.

A loading path (docs/theory.md §10) is a list of stages. In a stage each component of the
velocity gradient L (``xx``, ``yy``, ``xy``, ``yx``; L_xy = ∂v_x/∂y) is either

* **rate-controlled**: L_ij = rate · γ̇_ref, or
* **stress-controlled**: the matching stress component (xx -> σxx, yy -> σyy,
  xy or yx -> σxy; at most one of xy, yx) is held at a target, ramped linearly to
  it, or follows a rotation of the principal axes at fixed P and R.

Components given neither way have rate 0.

Time is measured in *reference strain* τ (dτ = γ̇_ref dt). The drivers choose
γ̇_ref: the DEM from its inertial number, γ̇_ref = I/d · sqrt(P0/ρ); the material
point from its increment size. A rate-independent model therefore sees the same
path whatever γ̇_ref is. Stresses are in units of the reference pressure P0,
tension positive (a pressure P0 is σxx = σyy = -1).

A stage runs for ``length`` in τ at most and stops earlier when any ``until``
quantity (a history column, see :mod:`dem.history`) crosses its value. Stress
ramps run over the full ``length``.

Path files are TOML (angles in degrees there, radians in code)::

    name = "biaxial"
    description = "..."
    [[stage]]
    name = "compress"
    length = 0.25                      # max τ of the stage
    output_every = 0.0025              # τ between history rows (default length/100)
    L = { yy = -1.0 }                  # rate-controlled components
    sigma = { xx = -1.0 }              # hold σxx = -P0 (or {target=.., ramp=true},
                                       #  or {increment=.., ramp=true})
    until = { eps_yy = -0.25 }         # stop when eps_yy crosses -0.25

    [[stage]]                          # principal axes rotating at fixed P and R
    rotation = { P = 1.0, R = 0.3, from_deg = 0.0, to_deg = 90.0 }
    L = { yx = 0.0 }                   # the shear component not used by σxy

A file with a ``[probes]`` table instead of stages describes a family of stress
probes (Karapiperis et al. 2020, §3, in 2D): from whatever state the driver starts in, stress
increments of size ``magnitude`` in ``directions`` equally spaced directions of the
(σxx, σyy) plane (σxy held), optionally each followed by its unloading (``unload``),
plus a zero-increment reference probe (``hold``), see :func:`Path.expand`.

Standard paths ship in ``dem/paths/*.toml``; :func:`load_path` takes either one
of their names or a file.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path as FsPath
from typing import Mapping

import numpy as np

from dem.history import HISTORY_COLUMNS

COMPONENTS = ("xx", "yy", "xy", "yx")
"""Velocity-gradient components, in the order of every (4,) array here."""

STRESS_INDEX = {"xx": 0, "yy": 1, "xy": 2, "yx": 2}
"""Stress component (index into (sxx, syy, sxy)) that each L component controls."""

STOP_QUANTITIES = tuple(c for c in HISTORY_COLUMNS if c not in ("stage", "tau"))

STANDARD_DIR = FsPath(__file__).resolve().parent / "paths"


class PathError(ValueError):
    """A loading-path description is malformed; the message names the bad entry."""


@dataclass(frozen=True)
class StressControl:
    """Target of a stress-controlled component (units of P0, tension positive).

    Exactly one of ``target`` (absolute) and ``increment`` (relative to the value
    at the stage start) is set. With ``ramp`` the target moves linearly from the
    start value over the stage length; without, it applies from the first step.
    """

    target: float | None = None
    increment: float | None = None
    ramp: bool = False

    def value(self, start: float, progress: float) -> float:
        end = self.target if self.target is not None else start + self.increment
        return start + (end - start) * progress if self.ramp else end


@dataclass(frozen=True)
class AxesRotation:
    """Principal stress axes rotating at fixed P and R (units of P0).

    σxx = -P + R cos 2α, σyy = -P - R cos 2α, σxy = R sin 2α, with α going
    linearly from ``start`` to ``end`` (radians) over the stage. α is the angle
    of the *minor* compressive (algebraically largest) principal stress from x.
    """

    pressure: float
    radius: float
    start: float
    end: float

    def stress(self, progress: float) -> np.ndarray:
        a = self.start + (self.end - self.start) * progress
        p, r = self.pressure, self.radius
        return np.array([-p + r * math.cos(2 * a), -p - r * math.cos(2 * a), r * math.sin(2 * a)])


@dataclass(frozen=True)
class StopCondition:
    """Stop when ``quantity`` crosses ``value`` (reaches it from its stage-start side)."""

    quantity: str
    value: float

    def reached(self, start: float, now: float) -> bool:
        return (start - self.value) * (now - self.value) <= 0.0


@dataclass(frozen=True)
class Stage:
    """One stage of a loading path; see the module docstring for the semantics."""

    name: str
    length: float
    rates: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    stress: Mapping[str, StressControl] = field(default_factory=dict)
    rotation: AxesRotation | None = None
    until: tuple[StopCondition, ...] = ()
    output_every: float | None = None
    rotation_shear: str = "xy"
    """In a rotation stage, the shear component of L solved for σxy."""

    @property
    def stress_controlled(self) -> np.ndarray:
        """(4,) bool: which L components are solved for a stress target."""
        if self.rotation is not None:
            return np.array([c in ("xx", "yy", self.rotation_shear) for c in COMPONENTS])
        return np.array([c in self.stress for c in COMPONENTS])

    @property
    def rate_vector(self) -> np.ndarray:
        """(4,) prescribed L / γ̇_ref, in COMPONENTS order (0 where stress-controlled)."""
        return np.where(self.stress_controlled, 0.0, np.asarray(self.rates, dtype=float))

    @property
    def output_interval(self) -> float:
        return self.output_every if self.output_every is not None else self.length / 100.0

    def stress_target(self, start: np.ndarray, progress: float) -> np.ndarray:
        """(3,) target (sxx, syy, sxy) at ``progress`` in [0, 1] of the stage.

        ``start`` is the stress at the stage start; entries of components that
        are not stress-controlled are returned unchanged from it.
        """
        if self.rotation is not None:
            return self.rotation.stress(progress)
        out = np.array(start, dtype=float, copy=True)
        for comp, ctl in self.stress.items():
            out[STRESS_INDEX[comp]] = ctl.value(float(start[STRESS_INDEX[comp]]), progress)
        return out

    def stop_reached(self, start: Mapping[str, float], now: Mapping[str, float]) -> str | None:
        """The first ``until`` quantity that has crossed its value, else None."""
        for cond in self.until:
            if cond.reached(start[cond.quantity], now[cond.quantity]):
                return cond.quantity
        return None


@dataclass(frozen=True)
class ProbeFamily:
    """Stress probes (Karapiperis et al. 2020, §3, in 2D): increments Δσ = m (cos β, sin β)
    in the (σxx, σyy) plane, β = 2πk/n, each applied from the same starting state.

    With ``unload`` each probe ramps back to its start stress in a second stage of the
    same length: the strain left after unloading is the plastic one (Bardet 1994, seed
    001 §3.3.1). With ``hold`` a last probe of zero increment runs for the same time: the
    drift of the start state itself (creep), to be subtracted from every probe."""

    directions: int
    magnitude: float
    length: float
    unload: bool = False
    hold: bool = False

    def probes(self) -> list[tuple[str, tuple[Stage, ...]]]:
        """(name, stages) of each probe, in the order of :meth:`Path.expand`."""
        out = []
        for k in range(self.directions + (1 if self.hold else 0)):
            beta = 2.0 * math.pi * k / self.directions
            m = self.magnitude if k < self.directions else 0.0
            name = f"probe_{math.degrees(beta):05.1f}deg" if k < self.directions else "probe_hold"
            dx, dy = m * math.cos(beta), m * math.sin(beta)
            stages = [self._stage(name, dx, dy)]
            if self.unload:
                stages.append(self._stage(f"{name}_unload", -dx, -dy))
            out.append((name, tuple(stages)))
        return out

    def _stage(self, name: str, dx: float, dy: float) -> Stage:
        ctl = {"xx": StressControl(increment=dx, ramp=True),
               "yy": StressControl(increment=dy, ramp=True),
               "xy": StressControl(increment=0.0)}
        return Stage(name=name, length=self.length, stress=ctl, output_every=self.length / 10.0)


@dataclass(frozen=True)
class Path:
    """A named loading path: stages, or a probe family (see :meth:`expand`)."""

    name: str
    stages: tuple[Stage, ...] = ()
    description: str = ""
    probes: ProbeFamily | None = None

    def expand(self) -> list["Path"]:
        """The single-stage-list paths to run: [self], or one path per probe."""
        if self.probes is None:
            return [self]
        return [replace(self, name=f"{self.name}/{name}", stages=stages, probes=None)
                for name, stages in self.probes.probes()]

    def to_dict(self) -> dict:
        """A JSON-able description (for the sidecar of every run)."""
        import dataclasses
        return dataclasses.asdict(self)


# --------------------------------------------------------------------------- parsing

def standard_paths() -> list[str]:
    """Names of the shipped standard paths."""
    return sorted(p.stem for p in STANDARD_DIR.glob("*.toml"))


def load_path(name_or_file: str | FsPath) -> Path:
    """A path from a TOML file, or from a standard path name (see :func:`standard_paths`)."""
    f = FsPath(name_or_file)
    if not f.is_file():
        f = STANDARD_DIR / f"{name_or_file}.toml"
        if not f.is_file():
            raise PathError(f"unknown loading path {str(name_or_file)!r}: not a file, and not one "
                            f"of the standard paths {standard_paths()}")
    try:
        data = tomllib.loads(f.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise PathError(f"{f}: not valid TOML ({exc})") from exc
    return parse_path(data, source=str(f))


def parse_path(data: Mapping, source: str = "<path>") -> Path:
    """Build and validate a :class:`Path` from its TOML table."""
    _only(data, {"name", "description", "stage", "probes"}, source)
    name = str(data.get("name", FsPath(source).stem))
    if "probes" in data:
        if "stage" in data:
            raise PathError(f"{source}: give either [probes] or [[stage]], not both")
        pr = data["probes"]
        _only(pr, {"directions", "magnitude", "length", "unload", "hold"}, f"{source} [probes]")
        for key in ("unload", "hold"):
            if not isinstance(pr.get(key, False), bool):
                raise PathError(f"{source} [probes]: {key} = {pr[key]!r} must be true or false")
        fam = ProbeFamily(directions=int(_positive(pr, "directions", f"{source} [probes]")),
                          magnitude=_positive(pr, "magnitude", f"{source} [probes]"),
                          length=_positive(pr, "length", f"{source} [probes]"),
                          unload=pr.get("unload", False), hold=pr.get("hold", False))
        return Path(name=name, description=str(data.get("description", "")), probes=fam)
    stages = data.get("stage")
    if not stages:
        raise PathError(f"{source}: a path needs at least one [[stage]] (or a [probes] table)")
    parsed = tuple(_parse_stage(s, f"{source} stage {i + 1}") for i, s in enumerate(stages))
    return Path(name=name, stages=parsed, description=str(data.get("description", "")))


def _parse_stage(t: Mapping, where: str) -> Stage:
    _only(t, {"name", "length", "output_every", "L", "sigma", "rotation", "until"}, where)
    name = str(t.get("name", where.rsplit(" ", 1)[-1]))
    where = f"{where} ({name!r})"
    length = _positive(t, "length", where)
    rates_t = t.get("L", {})
    sigma_t = t.get("sigma", {})
    _only(rates_t, set(COMPONENTS), f"{where} L", what="velocity-gradient component")
    _only(sigma_t, set(COMPONENTS), f"{where} sigma", what="stress-controlled component")
    both = set(rates_t) & set(sigma_t)
    if both:
        raise PathError(f"{where}: component(s) {sorted(both)} are given both a rate (L) and a "
                        f"stress target (sigma); choose one")
    if "xy" in sigma_t and "yx" in sigma_t:
        raise PathError(f"{where}: sigma.xy and sigma.yx both control the same stress σxy; "
                        f"stress-control at most one of them and give the other a rate")
    rates = []
    for c in COMPONENTS:
        v = rates_t.get(c, 0.0)
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            raise PathError(f"{where}: L.{c} = {v!r} must be a finite number (rate / γ̇_ref)")
        rates.append(float(v))
    stress = {c: _parse_stress(v, f"{where} sigma.{c}") for c, v in sigma_t.items()}
    rotation = None
    if "rotation" in t:
        rotation = _parse_rotation(t["rotation"], f"{where} rotation")
        given = set(rates_t)
        if {"xx", "yy"} & given or {"xy", "yx"} <= given or stress:
            raise PathError(f"{where}: a rotation stage sets σxx, σyy, σxy itself: give no sigma "
                            f"table and a rate for at most one of L.xy, L.yx (the other is solved "
                            f"for σxy); got L = {dict(rates_t)}, sigma = {dict(sigma_t)}")
    until_t = t.get("until", {})
    bad = set(until_t) - set(STOP_QUANTITIES)
    if bad:
        raise PathError(f"{where}: unknown until quantity {sorted(bad)}; accepted: "
                        f"{list(STOP_QUANTITIES)}")
    until = []
    for q, v in until_t.items():
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            raise PathError(f"{where}: until.{q} = {v!r} must be a finite number")
        until.append(StopCondition(q, float(v)))
    out_every = t.get("output_every")
    if out_every is not None:
        out_every = _positive(t, "output_every", where)
        if out_every > length:
            raise PathError(f"{where}: output_every = {out_every} exceeds the stage length "
                            f"{length}; accepted range (0, length]")
    return Stage(name=name, length=length, rates=tuple(rates), stress=stress, rotation=rotation,
                 until=tuple(until), output_every=out_every,
                 rotation_shear="yx" if "xy" in rates_t else "xy")


def _parse_stress(v, where: str) -> StressControl:
    if isinstance(v, (int, float)):
        v = {"target": v}
    if not isinstance(v, Mapping):
        raise PathError(f"{where} = {v!r}: give a number (target) or a table "
                        f"{{target=.., ramp=..}} / {{increment=.., ramp=..}}")
    _only(v, {"target", "increment", "ramp"}, where)
    if ("target" in v) == ("increment" in v):
        raise PathError(f"{where}: give exactly one of target, increment (got {dict(v)})")
    for k in ("target", "increment"):
        if k in v and (not isinstance(v[k], (int, float)) or not math.isfinite(v[k])):
            raise PathError(f"{where}: {k} = {v[k]!r} must be a finite number (units of P0)")
    if "target" in v and v["target"] > 0:
        raise PathError(f"{where}: target = {v['target']} is tensile; a cohesionless granular "
                        f"sample carries no tension (accepted range: target <= 0, units of P0, "
                        f"tension positive)")
    return StressControl(target=None if "target" not in v else float(v["target"]),
                         increment=None if "increment" not in v else float(v["increment"]),
                         ramp=bool(v.get("ramp", False)))


def _parse_rotation(v, where: str) -> AxesRotation:
    if not isinstance(v, Mapping):
        raise PathError(f"{where}: must be a table {{P=.., R=.., from_deg=.., to_deg=..}}")
    _only(v, {"P", "R", "from_deg", "to_deg"}, where)
    p = _positive(v, "P", where)
    r = float(v.get("R", math.nan))
    if not (0.0 <= r < p):
        raise PathError(f"{where}: R = {v.get('R')!r} must lie in [0, P) = [0, {p}) (R/P < 1)")
    for k in ("from_deg", "to_deg"):
        if k not in v or not math.isfinite(v[k]):
            raise PathError(f"{where}: {k} must be a finite angle in degrees")
    return AxesRotation(p, r, math.radians(v["from_deg"]), math.radians(v["to_deg"]))


def _positive(t: Mapping, key: str, where: str) -> float:
    v = t.get(key)
    if not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
        raise PathError(f"{where}: {key} = {v!r} must be a positive finite number "
                        f"(accepted range (0, inf))")
    return float(v)


def _only(t, allowed: set, where: str, what: str = "key") -> None:
    if not isinstance(t, Mapping):
        raise PathError(f"{where}: expected a table, got {t!r}")
    bad = set(t) - allowed
    if bad:
        raise PathError(f"{where}: unknown {what} {sorted(bad)}; accepted: {sorted(allowed)}")
