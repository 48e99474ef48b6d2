"""Meshes: generators, gmsh files with named boundaries, and clear errors on bad input."""
import meshio
import numpy as np
import pytest

from contfab.fem import mesh as M


def _square_cells():
    points = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]])
    cells = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    return points, cells


def test_tensor_mesh_area_and_named_sides():
    for kind in ("tri", "quad"):
        m = M.tensor(M.graded(0.0, 3.0, 6, 0.2), np.linspace(0.0, 2.0, 5), kind=kind)
        areas = np.abs(M.signed_corner_areas(m.p.T, m.t.T))
        if kind == "tri":       # twice the area at each corner of a triangle
            assert areas[:, 0].sum() / 2 == pytest.approx(6.0, rel=1e-12)
        for side, (axis, value) in {"left": (0, 0.0), "right": (0, 3.0),
                                    "bottom": (1, 0.0), "top": (1, 2.0)}.items():
            x = m.p[:, m.facets[:, M.boundary(m, side)]]
            assert np.allclose(x[axis], value)


def test_graded_spacing_ratio():
    x = M.graded(0.0, 1.0, 10, ratio=0.1)
    w = np.diff(x)
    assert x[0] == 0.0 and x[-1] == pytest.approx(1.0)
    assert w[-1] / w[0] == pytest.approx(0.1, rel=1e-12)


def test_gmsh_file_brings_physical_lines_as_boundaries(tmp_path):
    points, cells = _square_cells()
    m = meshio.Mesh(np.column_stack((points, np.zeros(5))),
                    [("line", np.array([[0, 1]])), ("triangle", cells)],
                    cell_data={"gmsh:physical": [np.array([7]), np.ones(4, int)],
                               "gmsh:geometrical": [np.array([1]), np.ones(4, int)]},
                    field_data={"base": np.array([7, 1]), "soil": np.array([1, 2])})
    path = tmp_path / "square.msh"
    meshio.write(path, m, file_format="gmsh22", binary=False)
    mesh = M.load(path)
    base = mesh.facets[:, M.boundary(mesh, "base")]
    assert sorted(base.ravel().tolist()) == [0, 1]
    with pytest.raises(M.MeshError, match=r"unknown boundary 'top'.*\['base'\]"):
        M.boundary(mesh, "top")


def test_unreadable_mesh_file_is_a_clear_error(tmp_path):
    bad = tmp_path / "bad.msh"
    bad.write_text("$MeshFormat\nthis is not gmsh\n")
    with pytest.raises(M.MeshError, match="cannot read mesh"):
        M.load(bad)
    with pytest.raises(M.MeshError, match="does not exist"):
        M.load(tmp_path / "missing.msh")


def test_inverted_element_is_reported_with_its_coordinates():
    points, cells = _square_cells()
    cells[2] = cells[2][::-1]
    with pytest.raises(M.MeshError, match=r"1 inverted element\(s\).*#2 at"):
        M.from_arrays(points, cells)


def test_folded_quad_is_inverted():
    points = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [2.0, 0.0], [2.0, 1.0]])
    good = np.array([[0, 1, 3, 2], [1, 4, 5, 3]])
    M.from_arrays(points, good)
    bowtie = np.array([[0, 1, 2, 3], [1, 4, 5, 3]])
    with pytest.raises(M.MeshError, match="inverted"):
        M.from_arrays(points, bowtie)


def test_degenerate_element_is_reported():
    points, cells = _square_cells()
    points[4] = [0.5, 0.0]           # the centre on the bottom edge: cell 0 has zero area
    with pytest.raises(M.MeshError, match=r"degenerate element\(s\).*#0 at"):
        M.from_arrays(points, cells)


def test_boundary_predicate_selecting_nothing_is_an_error():
    m = M.tensor(np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    with pytest.raises(M.MeshError, match="'footing' selects no boundary facet"):
        M.name_boundaries(m, {"footing": lambda x: x[1] > 5.0})
