"""The FE×DEM scenes: a biaxial specimen and a simple-shear layer, for any material.

Both start from an isotropic stress -p0 I (p0 = the confining pressure, the scene's
stress unit; a DEM cell prepared at P0 carries p0 per P0) and are driven by
displacement over one stage:

* ``biaxial``: W × H, left side ux = 0, bottom uy = 0, top uy = -ε H, right side under
  the dead pressure p0. ``rough`` platens also fix ux on the top and bottom (the
  specimen then deforms non-uniformly); with smooth platens the strain is uniform.
  Measured: axial strain ε = -uy_top/H, axial stress σyy = (top reaction)/W (tension
  positive), lateral strain ux_right/W (means over the side's DOFs).
* ``shear``: W × H layer, bottom fixed, top ux = γ H and uy free under the dead
  pressure p0, both sides ux = γ y (rigid side walls, the simple-shear box), uy free.
  Measured: γ, shear stress τ = (top x reaction)/W, dilation uy_top/H.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from contfab.fem import loads
from contfab.fem import mesh as meshes
from contfab.fem.assembly import Discretization
from contfab.fem.solver import Stage

SCENES = ("biaxial", "shear")


@dataclass(frozen=True)
class Scene:
    """A meshed scene: discretization, its stage, and what to measure after each step."""

    name: str
    disc: Discretization
    stage: Stage
    p0: float
    width: float
    height: float
    measured: dict           # name -> ("u" mean or "reaction" sum, dofs, factor)

    def measure(self, solver) -> dict:
        """The scene's curve quantities at the committed state (see the module doc)."""
        c = solver.committed
        out = {}
        for name, (kind, dofs, factor) in self.measured.items():
            v = np.sum(c.residual[dofs]) if kind == "reaction" else np.mean(c.u[dofs])
            out[name] = float(factor * v)
        return out


def _dofs(disc, name, comp):
    return loads.boundary_dofs(disc, name, comp)


def build(name: str, p0: float = 1.0, strain: float = 0.01, nx: int = 1, ny: int = 1,
          width: float = 1.0, height: float = 1.0, element: str = "Q8R", rough: bool = True,
          steps: int = 10) -> Scene:
    """Scene ``name`` (one of :data:`SCENES`) with ``nx`` × ``ny`` elements (see module doc)."""
    if name not in SCENES:
        raise ValueError(f"scene {name!r} unknown; accepted {SCENES}")
    for what, v in (("p0", p0), ("strain", strain), ("width", width), ("height", height)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{what} = {v} out of range; accepted (0, inf)")
    if not (isinstance(steps, int) and steps >= 1):
        raise ValueError(f"steps = {steps} out of range; accepted integers >= 1")
    kind = "quad" if element.startswith("Q") else "tri"
    mesh = meshes.tensor(np.linspace(0, width, nx + 1), np.linspace(0, height, ny + 1), kind)
    disc = Discretization(mesh, element)
    x, y = disc.basis.doflocs
    dt = 1.0 / steps
    if name == "biaxial":
        fixed = [_dofs(disc, "left", "x"), _dofs(disc, "bottom", "y"), _dofs(disc, "top", "y")]
        if rough:
            fixed += [_dofs(disc, "bottom", "x"), _dofs(disc, "top", "x")]
        fixed = np.unique(np.concatenate(fixed))
        top_y = _dofs(disc, "top", "y")
        inc = np.where(np.isin(fixed, top_y), -strain * height, 0.0)
        inc[np.isin(fixed, _dofs(disc, "left", "x"))] = 0.0
        f_dead = loads.surface_load(disc, "right", pressure=p0)
        measured = {"strain": ("u", top_y, -1.0 / height),
                    "sigma_yy": ("reaction", top_y, 1.0 / width),
                    "lateral_strain": ("u", _dofs(disc, "right", "x"), 1.0 / width)}
    else:
        sides = np.concatenate([_dofs(disc, s, "x") for s in ("left", "right", "top", "bottom")])
        fixed = np.unique(np.concatenate([sides, _dofs(disc, "bottom", "y")]))
        inc = np.where(np.isin(fixed, sides), strain * y[fixed], 0.0)
        f_dead = loads.surface_load(disc, "top", pressure=p0)
        top_x = _dofs(disc, "top", "x")
        measured = {"gamma": ("u", top_x, 1.0 / height), "tau": ("reaction", top_x, 1.0 / width),
                    "dilation": ("u", _dofs(disc, "top", "y"), 1.0 / height)}
    stage = Stage(name, fixed.astype(np.int64), inc, f_dead, dt0=dt, dt_min=dt / 64, dt_max=dt)
    return Scene(name, disc, stage, p0, width, height, measured)
