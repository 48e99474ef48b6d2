"""``contfab bench fem``: where a Newton iteration of the footing spends its time.

The strip footing (:mod:`contfab.scenes.strip_footing`, N_q, φ = 30°, associated flow) on its
mesh level 3 with P2 elements (~47k DOFs), pushed to collapse. Every call of the
constitutive update (``TierMaterial.update`` and ``spin_tangent``: the update itself,
line-search trials and the exact spin tangent), of the assembly (strain, internal force,
tangent) and of the linear solve (SuperLU factorization and back-solve) is timed;
the figures are the totals per Newton iteration and their ratios to the solve.
Goals: update + assembly <= 0.5x the solve, and <= 6 Newton iterations per step on
median. The cost per step of the non-associated strategy (:data:`NONASSOCIATED`) is
measured against the associated footing on the same mesh. The calls are timed in CPU
seconds of this process (``time.process_time``; every timed part runs on one thread), so a
shared, loaded
machine does not inflate them; the run is repeated ``--repeats`` times (each run
takes minutes: ``contfab bench fem --repeats 3`` is the tracked setting) and every
figure is the median over the runs. ``wall_s`` is the wall time of one run (median).
"""
from __future__ import annotations

import contextlib
import statistics
import time

from contfab.scenes.case import load_case
from contfab.fem import assembly, material, solver
from contfab.params import default_params

ELEMENT, LEVEL, PHI = "P2", 3, 30.0
NONASSOCIATED = {"element": "P2", "level": 1, "settlement": 0.3, "relaxation_time": 1e-4,
                 "explicit": 100_000}
"""The non-associated cost figures: N_γ at φ = 30° to 0.3 B on the coarse footing mesh,
ψ = 0 with the Duvaut–Lions material and by explicit dynamic relaxation in 1e5 cycles
(docs/fem_validation.md §7) against ψ = φ rate-independent (Newton)."""


@contextlib.contextmanager
def _timing(totals: dict, counts: dict, targets):
    """Wrap (class, method, bucket) triples so each call adds its wall time to ``totals``."""
    saved = []
    for cls, name, bucket in targets:
        original = getattr(cls, name)
        saved.append((cls, name, original))

        def wrapper(*a, _f=original, _b=bucket, **k):
            t0 = time.process_time()
            try:
                return _f(*a, **k)
            finally:
                totals[_b] = totals.get(_b, 0.0) + time.process_time() - t0
                counts[_b] = counts.get(_b, 0) + 1
        setattr(cls, name, wrapper)
    try:
        yield
    finally:
        for cls, name, original in saved:
            setattr(cls, name, original)


def run(args) -> dict:
    """The median of each figure over ``args.repeats`` footing runs (3 without the CLI)."""
    repeats = getattr(args, "repeats", None) or 3
    if repeats < 1:
        raise ValueError(f"repeats = {repeats} must be >= 1")
    progress = not getattr(args, "json", False)
    runs = [_one_run(progress) | _nonassociated_cost(progress) for _ in range(repeats)]
    return {k: (statistics.median(r[k] for r in runs) if isinstance(runs[0][k], float)
                else runs[0][k]) for k in runs[0]} | {"repeats": repeats}


def _one_run(progress: bool) -> dict:
    footing = load_case("strip_footing")
    totals: dict = {}
    counts: dict = {}
    targets = [(material.TierMaterial, "update", "update"),
               (material.TierMaterial, "spin_tangent", "update"),
               (assembly.Discretization, "strain", "assembly"),
               (assembly.Discretization, "internal_force", "assembly"),
               (assembly.Discretization, "tangent", "assembly"),
               (solver.ConstrainedSystem, "solve", "solve")]
    t0, c0 = time.perf_counter(), time.process_time()
    with _timing(totals, counts, targets):
        r = footing.solve(PHI, PHI, "Nq", ELEMENT, LEVEL, default_params(), None,
                          progress=progress)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    iterations = counts["solve"]
    per = {k: totals[k] / iterations for k in ("update", "assembly", "solve")}
    return {
        "dofs": r["dofs"],
        "element": ELEMENT,
        "steps": r["steps"],
        "newton_iterations": iterations,
        "median_newton_per_step": float(r["median_newton"]),
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
        "cpu_s": cpu,
        "other_s_per_iteration": (cpu - sum(totals.values())) / iterations,
    }


def _nonassociated_cost(progress: bool) -> dict:
    """CPU seconds of the non-associated N_γ footing (ψ = 0) to 0.3 B: per Newton step with
    the Duvaut–Lions material, and in all by explicit dynamic relaxation; against the
    associated one (rate-independent Newton)."""
    footing = load_case("strip_footing")
    out = {}
    for key, psi, tau, cycles in (("associated", PHI, None, None),
                                  ("nonassociated", 0.0, NONASSOCIATED["relaxation_time"], None),
                                  ("explicit", 0.0, None, NONASSOCIATED["explicit"])):
        c0 = time.process_time()
        r = footing.solve(PHI, psi, "Ngamma", NONASSOCIATED["element"], NONASSOCIATED["level"],
                          default_params(), None, progress=progress,
                          settlement=NONASSOCIATED["settlement"], relaxation_time=tau,
                          explicit=cycles)
        cpu = time.process_time() - c0
        out |= {f"{key}_N_gamma": float(r["computed"]), f"{key}_cpu_s": cpu}
        if cycles is None:
            out |= {f"{key}_steps": r["steps"],
                    f"{key}_median_newton_per_step": float(r["median_newton"]),
                    f"{key}_cpu_s_per_step": cpu / r["steps"]}
        else:
            out |= {f"{key}_cycles": cycles, f"{key}_cpu_s_per_cycle": cpu / cycles}
    out["nonassociated_over_associated_cpu_per_step"] = \
        out["nonassociated_cpu_s_per_step"] / out["associated_cpu_s_per_step"]
    out["explicit_over_associated_cpu"] = out["explicit_cpu_s"] / out["associated_cpu_s"]
    return out
