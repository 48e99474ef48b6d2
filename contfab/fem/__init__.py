"""The scikit-fem boundary-value solver (docs/theory.md §13).

Modules, bottom to top: :mod:`mesh` (meshes, named boundaries, validation),
:mod:`elements` (element families and quadrature), :mod:`assembly` (strain,
internal force Bᵀσ and tangent BᵀDB from per-point arrays), :mod:`loads`
(body force, boundary tractions, prescribed displacements), :mod:`material`
(the model tiers behind one update call), :mod:`nonlocal_density` (an internal length:
the packing fraction averaged over a neighbourhood), :mod:`solver` (Newton with step
control), :mod:`output` (VTU series, curve CSV, plots), :mod:`analysis` (runs
stages with a progress bar and writes the outputs).
"""
