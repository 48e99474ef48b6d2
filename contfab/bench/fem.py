"""``contfab bench fem``: where a Newton iteration of the footing spends its time.

The strip footing (``cases/strip_footing.py``, N_q, φ = 30°, associated flow) on its
mesh level 3 with P2 elements (~47k DOFs), pushed to collapse. Every call of the
constitutive update (``TierMaterial.update``: the update itself, the spin-tangent
difference and line-search trials), of the assembly (strain, internal force,
tangent) and of the linear solve (SuperLU factorization and back-solve) is timed;
the figures are the totals per Newton iteration and their ratios to the solve.
Goals (issue 5): update + assembly <= 0.5x the solve, and < 8 Newton iterations per
step on median. One run (several minutes): the per-iteration figures are already
means over hundreds of iterations; ``--repeats`` is not used. Wall-clock times, so a
loaded machine inflates them all alike (the ratios stay meaningful).
"""
from __future__ import annotations

import contextlib
import math
import time


from contfab.cases import load_case
from contfab.fem import assembly, material, solver
from contfab.params import default_params

ELEMENT, LEVEL, PHI = "P2", 3, 30.0


@contextlib.contextmanager
def _timing(totals: dict, counts: dict, targets):
    """Wrap (class, method, bucket) triples so each call adds its wall time to ``totals``."""
    saved = []
    for cls, name, bucket in targets:
        original = getattr(cls, name)
        saved.append((cls, name, original))

        def wrapper(*a, _f=original, _b=bucket, **k):
            t0 = time.perf_counter()
            try:
                return _f(*a, **k)
            finally:
                totals[_b] = totals.get(_b, 0.0) + time.perf_counter() - t0
                counts[_b] = counts.get(_b, 0) + 1
        setattr(cls, name, wrapper)
    try:
        yield
    finally:
        for cls, name, original in saved:
            setattr(cls, name, original)


def run(args) -> dict:
    footing = load_case("strip_footing")
    totals: dict = {}
    counts: dict = {}
    targets = [(material.TierMaterial, "update", "update"),
               (assembly.Discretization, "strain", "assembly"),
               (assembly.Discretization, "internal_force", "assembly"),
               (assembly.Discretization, "tangent", "assembly"),
               (solver.ConstrainedSystem, "solve", "solve")]
    t0 = time.perf_counter()
    with _timing(totals, counts, targets):
        r = footing.solve(PHI, PHI, "Nq", ELEMENT, LEVEL, default_params(), None,
                          progress=not getattr(args, "json", False))
    wall = time.perf_counter() - t0
    iterations = counts["solve"]
    per = {k: totals[k] / iterations for k in ("update", "assembly", "solve")}
    return {
        "dofs": r["dofs"],
        "element": ELEMENT,
        "steps": r["steps"],
        "newton_iterations": iterations,
        "median_newton_per_step": r["median_newton"],
        "update_calls_per_iteration": counts["update"] / iterations,
        "update_s_per_iteration": per["update"],
        "assembly_s_per_iteration": per["assembly"],
        "solve_s_per_iteration": per["solve"],
        "update_over_solve": per["update"] / per["solve"],
        "assembly_over_solve": per["assembly"] / per["solve"],
        "update_plus_assembly_over_solve": (per["update"] + per["assembly"]) / per["solve"],
        "N_q": float(r["computed"]),
        "N_q_error": float(r["computed"] / r["reference"] - 1.0),
        "wall_s": wall,
        "other_s_per_iteration": (wall - sum(totals.values())) / iterations
        if math.isfinite(wall) else float("nan"),
    }
