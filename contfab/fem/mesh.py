"""Meshes for the boundary-value solver: generators, gmsh files, named boundaries.

A mesh is a scikit-fem ``MeshTri`` or ``MeshQuad`` (linear geometry; the element
order is chosen separately, see :mod:`contfab.fem.elements`) whose
``mesh.boundaries`` maps a name to facet indices. Every mesh that enters the solver
went through :func:`check_cells`: no inverted (folded) and no degenerate (zero-area)
element. scikit-fem sorts triangle connectivity and so forgets orientation, which
is why the check runs on the raw cells, before the mesh is built.

Generators name the four sides of a rectangle ``left``, ``right``, ``bottom``, ``top``;
gmsh files bring their physical line groups as names. Any other name comes from
:func:`name_boundaries` (a predicate on facet midpoints) and must select facets.
"""
from __future__ import annotations

import os
from typing import Callable, Mapping

import numpy as np
import skfem

DEGENERATE_RTOL = 1e-10
"""An element whose area is below this fraction of the median element area is degenerate."""


class MeshError(ValueError):
    """A mesh that cannot be read, has inverted or degenerate elements, or lacks a boundary."""


def signed_corner_areas(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Twice the signed area of the corner triangles of each cell, shape (ncells, ncorners).

    Corner k of cell e spans (x[k+1] - x[k]) × (x[k-1] - x[k]) (counter-clockwise
    positive). A triangle has three equal values; a convex quadrilateral four of one
    sign; a folded (self-intersecting) or re-entrant quadrilateral mixes signs.
    """
    x = points[cells]                                   # (ne, nc, 2)
    nxt = np.roll(x, -1, axis=1) - x
    prv = np.roll(x, 1, axis=1) - x
    return nxt[..., 0] * prv[..., 1] - nxt[..., 1] * prv[..., 0]


def check_cells(points: np.ndarray, cells: np.ndarray) -> None:
    """Raise :class:`MeshError` on inverted or degenerate cells (triangles or quads).

    Orientation must be uniform: the cells whose corners turn against the majority
    (or mix turning directions, for quads) are inverted. A cell with a corner area
    below ``DEGENERATE_RTOL`` times the median is degenerate. The message names the
    first offending cells and their vertex coordinates.
    """
    points = np.asarray(points, dtype=float)
    cells = np.asarray(cells, dtype=np.int64)
    if points.ndim != 2 or points.shape[1] != 2 or not np.all(np.isfinite(points)):
        raise MeshError(f"points must be a finite (n, 2) array, got shape {points.shape}")
    if cells.ndim != 2 or cells.shape[1] not in (3, 4) or len(cells) == 0:
        raise MeshError(f"cells must be a non-empty (ne, 3) or (ne, 4) array, got shape {cells.shape}")
    if cells.min() < 0 or cells.max() >= len(points):
        raise MeshError(f"cell vertex indices must lie in [0, {len(points) - 1}], "
                        f"got [{cells.min()}, {cells.max()}]")
    areas = signed_corner_areas(points, cells)
    scale = np.median(np.abs(areas))
    degenerate = np.nonzero(np.min(np.abs(areas), axis=1) <= DEGENERATE_RTOL * scale)[0]
    if degenerate.size:
        raise MeshError(f"{degenerate.size} degenerate element(s) (area below "
                        f"{DEGENERATE_RTOL:g} x median), first: {_describe(points, cells, degenerate)}")
    orientation = 1.0 if np.sum(areas > 0) >= np.sum(areas < 0) else -1.0
    inverted = np.nonzero(np.any(areas * orientation < 0, axis=1))[0]
    if inverted.size:
        raise MeshError(f"{inverted.size} inverted element(s) (orientation against the rest "
                        f"of the mesh, or a folded quadrilateral), first: "
                        f"{_describe(points, cells, inverted)}")


def _describe(points, cells, bad, k=3) -> str:
    return "; ".join(f"#{e} at {np.round(points[cells[e]], 6).tolist()}" for e in bad[:k])


def from_arrays(points: np.ndarray, cells: np.ndarray):
    """A checked mesh from vertex coordinates (n, 2) and cells (ne, 3) or (ne, 4), no names yet."""
    points = np.asarray(points, dtype=float)
    cells = np.asarray(cells, dtype=np.int64)
    check_cells(points, cells)
    cls = skfem.MeshTri if cells.shape[1] == 3 else skfem.MeshQuad
    return cls(np.ascontiguousarray(points.T, dtype=float), np.ascontiguousarray(cells.T))


def graded(start: float, stop: float, n: int, ratio: float = 1.0) -> np.ndarray:
    """``n + 1`` coordinates from ``start`` to ``stop``; the last interval is ``ratio`` x the first.

    A geometric progression (uniform for ratio 1): ratio < 1 refines toward ``stop``.
    """
    if n < 1:
        raise MeshError(f"number of intervals n = {n} must be >= 1")
    if not ratio > 0:
        raise MeshError(f"grading ratio = {ratio} must be > 0")
    if n == 1 or ratio == 1.0:
        return np.linspace(start, stop, n + 1)
    q = ratio ** (1.0 / (n - 1))
    widths = q ** np.arange(n)
    return start + (stop - start) * np.concatenate(([0.0], np.cumsum(widths) / widths.sum()))


def tensor(xs, ys, kind: str = "tri"):
    """Structured mesh on the grid ``xs`` × ``ys``, sides named left/right/bottom/top.

    ``kind`` = ``"tri"`` splits each cell into four triangles about its centre
    (the "union-jack" crossed pattern: no preferred diagonal, which matters for
    collapse loads), ``"quad"`` keeps quadrilaterals.
    """
    xs = np.asarray(xs, dtype=float)
    ys = np.asarray(ys, dtype=float)
    for name, v in (("xs", xs), ("ys", ys)):
        if v.ndim != 1 or len(v) < 2 or np.any(np.diff(v) <= 0):
            raise MeshError(f"{name} must be a strictly increasing sequence of >= 2 coordinates")
    nx, ny = len(xs), len(ys)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    points = np.column_stack((X.ravel(), Y.ravel()))
    idx = np.arange(nx * ny).reshape(nx, ny)
    c00, c10 = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c11, c01 = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    if kind == "quad":
        cells = np.column_stack((c00, c10, c11, c01))
    elif kind == "tri":
        centres = 0.25 * (points[c00] + points[c10] + points[c11] + points[c01])
        cc = nx * ny + np.arange(len(c00))
        points = np.vstack((points, centres))
        cells = np.vstack([np.column_stack((a, b, cc)) for a, b in
                           ((c00, c10), (c10, c11), (c11, c01), (c01, c00))])
    else:
        raise MeshError(f"kind = {kind!r}: expected 'tri' or 'quad'")
    mesh = from_arrays(points, cells)
    x0, x1, y0, y1 = xs[0], xs[-1], ys[0], ys[-1]
    tol = 1e-9 * max(x1 - x0, y1 - y0)
    return name_boundaries(mesh, {
        "left": lambda x: np.abs(x[0] - x0) < tol,
        "right": lambda x: np.abs(x[0] - x1) < tol,
        "bottom": lambda x: np.abs(x[1] - y0) < tol,
        "top": lambda x: np.abs(x[1] - y1) < tol,
    })


def delaunay_rectangle(width: float, height: float, h: float, seed: int = 0, jitter: float = 0.3):
    """Unstructured triangles on [0, width] × [0, height], element size about ``h``.

    The Delaunay triangulation of a jittered grid of interior points (each moved by up
    to ``jitter``·h, kept 0.3h from the sides) plus evenly spaced side points: no
    preferred direction, unlike a structured mesh whose diagonals attract shear bands.
    Sides named left/right/bottom/top.
    """
    from scipy.spatial import Delaunay

    if not (h > 0 and width > 2 * h and height > 2 * h):
        raise MeshError(f"element size h = {h:g} must be > 0 and below half the smaller side "
                        f"of the {width:g} x {height:g} rectangle")
    if not 0 <= jitter < 0.5:
        raise MeshError(f"jitter = {jitter:g} is outside the accepted range [0, 0.5)")
    nx, ny = int(round(width / h)), int(round(height / h))
    xs, ys = np.linspace(0, width, nx + 1), np.linspace(0, height, ny + 1)
    sides = np.vstack([np.column_stack((xs, np.zeros_like(xs))),
                       np.column_stack((xs, np.full_like(xs, height))),
                       np.column_stack((np.zeros(ny - 1), ys[1:-1])),
                       np.column_stack((np.full(ny - 1, width), ys[1:-1]))])
    gx, gy = np.meshgrid(xs[1:-1], ys[1:-1], indexing="ij")
    rng = np.random.default_rng(seed)
    inner = np.column_stack((gx.ravel(), gy.ravel()))
    inner += rng.uniform(-jitter, jitter, inner.shape) * np.array([width / nx, height / ny])
    inner[:, 0] = np.clip(inner[:, 0], 0.3 * h, width - 0.3 * h)
    inner[:, 1] = np.clip(inner[:, 1], 0.3 * h, height - 0.3 * h)
    points = np.vstack((sides, inner))
    cells = Delaunay(points).simplices
    a = signed_corner_areas(points, cells)[:, 0]
    cells[a < 0] = cells[a < 0][:, ::-1]
    mesh = from_arrays(points, cells)
    tol = 1e-9 * max(width, height)
    return name_boundaries(mesh, {
        "left": lambda x: np.abs(x[0]) < tol,
        "right": lambda x: np.abs(x[0] - width) < tol,
        "bottom": lambda x: np.abs(x[1]) < tol,
        "top": lambda x: np.abs(x[1] - height) < tol,
    })


def name_boundaries(mesh, predicates: Mapping[str, Callable[[np.ndarray], np.ndarray]]):
    """Add named boundaries: boundary facets whose midpoint ``x`` (shape (2, nf)) passes.

    Each predicate must select at least one facet, else :class:`MeshError`.
    """
    boundary = mesh.boundary_facets()
    mid = mesh.p[:, mesh.facets[:, boundary]].mean(axis=1)
    named = dict(mesh.boundaries or {})
    for name, pred in predicates.items():
        sel = boundary[np.asarray(pred(mid), dtype=bool)]
        if sel.size == 0:
            raise MeshError(f"boundary {name!r} selects no boundary facet")
        named[name] = sel.astype(np.int32)
    return mesh.with_boundaries(named)


def boundary(mesh, name: str) -> np.ndarray:
    """Facet indices of the named boundary; :class:`MeshError` listing the names if unknown."""
    named = mesh.boundaries or {}
    if name not in named:
        raise MeshError(f"unknown boundary {name!r}; this mesh has {sorted(named) or 'none'}")
    return np.asarray(named[name])


def load(path: str | os.PathLike):
    """Read a gmsh (or any meshio-readable) 2D mesh of triangles or quads.

    Physical line groups become named boundaries. Unreadable files, 3D or mixed
    meshes, and inverted or degenerate elements raise :class:`MeshError`.
    """
    import meshio

    path = os.fspath(path)
    if not os.path.isfile(path):
        raise MeshError(f"mesh file {path!r} does not exist")
    try:
        m = meshio.read(path)
    except SystemExit:  # meshio exits when no reader for the extension accepts the file
        raise MeshError(f"cannot read mesh {path!r}: not a gmsh (or other meshio-readable) "
                        "mesh file") from None
    except Exception as exc:  # meshio raises many types (ReadError, KeyError, ValueError...)
        raise MeshError(f"cannot read mesh {path!r}: {type(exc).__name__}: {exc}") from None
    kinds = [k for k in ("triangle", "quad") if k in m.cells_dict]
    if len(kinds) != 1:
        raise MeshError(f"mesh {path!r} must hold linear triangles or quads (one kind), "
                        f"found cell types {sorted(m.cells_dict)}")
    points = np.asarray(m.points, dtype=float)
    if points.shape[1] == 3:
        if np.any(np.abs(points[:, 2]) > 0):
            raise MeshError(f"mesh {path!r} is not planar (z != 0)")
        points = points[:, :2]
    cells = m.cells_dict[kinds[0]]
    mesh = from_arrays(points, cells)
    named = _physical_lines(m, mesh)
    return mesh.with_boundaries(named) if named else mesh


def _physical_lines(m, mesh) -> dict[str, np.ndarray]:
    """Named facet sets from gmsh physical groups of line cells (names from field_data)."""
    if "line" not in m.cells_dict or "gmsh:physical" not in m.cell_data_dict:
        return {}
    tags = m.cell_data_dict["gmsh:physical"].get("line")
    if tags is None:
        return {}
    names = {int(v[0]): k for k, v in m.field_data.items() if len(v) > 1 and int(v[1]) == 1}
    lines = np.sort(m.cells_dict["line"], axis=1)
    facets = np.sort(mesh.facets.T, axis=1)
    key = {(int(a), int(b)): i for i, (a, b) in enumerate(facets)}
    named: dict[str, list[int]] = {}
    for (a, b), tag in zip(lines, tags):
        f = key.get((int(a), int(b)))
        if f is None:
            raise MeshError(f"boundary line ({a}, {b}) of group {names.get(int(tag), tag)!r} "
                            "is not an element edge")
        named.setdefault(names.get(int(tag), str(tag)), []).append(f)
    return {k: np.array(v, dtype=np.int32) for k, v in named.items()}
