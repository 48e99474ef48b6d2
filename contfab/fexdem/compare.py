"""``contfab fexdem CASE``: one scene with DEM cells and with model tiers 1 and 2.

The scene (:mod:`contfab.fexdem.scenes`) runs three times from the same initial stress
(the prepared cell's, times p0) and state (its c and fabric): FE×DEM (a DEM cell per
quadrature point, :mod:`contfab.fexdem.material`), then tiers 1 and 2
(:class:`contfab.fem.material.TierMaterial`, the given parameter file with p_ref = p0).
Written into ``--out`` (atomically):

    <run>_curve.csv, <run>.pvd + vtu, <run>_curve.png ...   per run (contfab.fem.analysis)
    cells/             the cells' and the FE field's checkpoints of the last converged step
                       (FexdemSolver.resume); the FE×DEM curve CSV is rewritten every step
    overlay.png        the load-displacement curves of the three runs
    <case>_dem_band.png  the FE×DEM shear strain γ at the end (contfab.fexdem.band; every
                       run's localization measures are in the report, "band")
    report.json        settings, N per cell, cells, wall times, Newton figures, errors, costs,
                       "profile": where the FE×DEM time went and the cost model's T(W)
    profile.npz        the per-call, per-cell timings behind it (contfab.fexdem.profile.load)

With ``adaptive`` = a tolerance (``--adaptive TOL``) the scene runs a fourth time as
adaptive FE×DEM (:mod:`contfab.fexdem.adaptive`: the cheapest model whose measured R/P
error bound meets TOL, a DEM cell where none does), written as ``<case>_adaptive*``; the
report's ``adaptive`` holds the choice, the switched points (the model's and the cell's
state at each switch) and the CPU of the model updates, the cells and the switches, and
``cost_ratio_cpu_adaptive_over_dem`` that CPU over the FE×DEM cells' CPU.

Errors of a tier (or of the adaptive run) against FE×DEM: the curve error max|y_tier - y_dem| / max|y_dem| with
the tier's curve interpolated at the FE×DEM abscissae, and at the end of the stage the
relative L2 field errors (quadrature-weighted) of the stress, of R/P and of c. The
cost ratio is the FE×DEM wall time over the tier's (each tier's kernels are loaded or
compiled by one untimed update first).

``reference`` = the directory of a finished FE×DEM run of the same scene and sample
(``--reference DIR``) takes that run's curve, last field and report as the FE×DEM run
instead of running it again (the tiers and the adaptive run are compared with it).

``viscosity`` = η > 0 (``--viscosity ETA``) puts a linear dashpot in parallel with every
cell (:mod:`contfab.fem.dashpot`: σ = σ_cell + η Δε/Δt, Δt the step of the stage's loading
parameter t ∈ [0, 1], η in p0 units times t); the FE×DEM curve carries its overstress
(``overstress_max``, ``overstress_mean``: the largest and the mean |σ_v| of the step, units
of p0, 0 without a dashpot) and the report its ``dashpot`` figures. The dashpot has no
state: a resumed run may continue with another η (the report's ``newton.viscosity`` is the
resumed part's). The adaptive run has the same dashpot at every point, cell or model, so
that it and FE×DEM solve the same regularized problem; a ``reference`` run of another η is
refused.

``resume=True`` (``contfab fexdem ... --resume``) continues an interrupted or killed
FE×DEM run in ``--out`` from ``cells/`` (same scene and settings): the field and the
cells restart from the field's last checkpointed step (the cells keep two generations
of checkpoints, so a kill between the cells' and the field's checkpoint of a step
resumes from the step before), the curve keeps the rows recorded before it, and the
stage ends with the numbers of an uninterrupted run (tests/test_fexdem.py). The report's FE×DEM
wall time and cost ratios then count the resumed part only (``resumed_from_t``).
"""
from __future__ import annotations

import csv
import json
import time
from dataclasses import replace
from types import SimpleNamespace
from pathlib import Path

import numpy as np

from contfab.executor import WORKER_ENV
from contfab.fem import analysis, dashpot
from contfab.fem.material import TierMaterial
from contfab.fem.solver import NewtonOptions, Solver
from contfab.fexdem.adaptive import AdaptiveMaterial, AdaptiveSolver, model_choice
from contfab.fexdem.band import band_figure, localization
from contfab.fexdem.backends import DaskCells, ProcessCells, SerialCells
from contfab.fexdem.cell import CellOptions
from contfab.fexdem.material import (FE_CHECKPOINT, STATE_NAMES, DemMaterial, FexdemSolver,
                                     checkpointed_step, elastic_modulus, initial_fields)
from contfab.fexdem.profile import costs
from contfab.fexdem.scenes import build
from contfab.models import tiers
from contfab.params import Params
from dem.fileio import atomic_path, write_json

DEM_NEWTON = NewtonOptions(tol=1e-3, tol_stall=5e-3, max_iter=12, line_search=0, spin_step=0,
                           extrapolate=False)   # each trial is a DEM run: the measured path
"""FE×DEM Newton with the cells' own tangent (``DemMaterial(tangent="dem")``). Measured
(docs/fexdem.md): the cells' stress noise is ~1e-5 P0 (the same increment ±2 % gives
stresses within 1e-5 of a line; a repeated run is bitwise equal), i.e. a relative
residual floor of ~1e-5; with the cells' tangent the residual falls ~10x per iteration
to 1e-5 before the peak, and near the peak points switching between loading and
unloading keep it at 1e-4..1e-3. tol = 1e-3 is 100x above the noise floor; 5e-3 is
accepted once the iteration stalls. (The former elastic tangent contracted only by
0.6-0.8 per iteration: 18 iterations for 1e-3 at 0.2 % axial strain, none near the peak.)"""

TANGENT = "dem"

CELL_OPTIONS = CellOptions(force_tol=float("inf"), kinetic_tol=float("inf"))
"""The cells follow the increments at the campaign's inertial number I = 1e-3 without a
hold: the tiers were calibrated on continuous I = 1e-3 DEM paths (default_params.toml
[provenance.campaign]), and a cell run so is bitwise such a path (:mod:`contfab.fexdem.cell`). A hold
until equilibrium (force_tol finite) relaxes the stress by a number of steps that
jumps in multiples of ``check_every`` with the increment: measured, near the peak the
Newton residual then cycled at 1e-3..1e-1 and the step could not be completed."""

CASES = {
    "biaxial": dict(nx=2, ny=2, width=1.0, height=1.5, rough=True, strain=0.01, steps=20,
                    curve=("strain", "sigma_yy")),
    "shear": dict(nx=3, ny=1, width=3.0, height=1.0, strain=0.03, steps=20,
                  curve=("gamma", "tau")),
}


def make_cells(backend: str, prepared: str, n: int, options: CellOptions, workers: int,
               address: str | None, ckdir: Path, progress: bool, resume: int = 0,
               blocks: int | None = None, layout: str = "interleaved"):
    """The cell backend by name: serial, process (``workers``), dask (``address`` or local;
    ``blocks`` actors, default one per worker); ``resume`` = k > 0: the cells restart
    from their checkpoints of step k in ``ckdir``."""
    if backend == "serial":
        return SerialCells(prepared, n, options, ckdir, resume, progress=progress)
    if backend == "process":
        return ProcessCells(prepared, n, options, workers, ckdir, resume, progress=progress,
                            layout=layout)
    if backend == "dask":
        from distributed import Client, LocalCluster
        cluster = None if address else LocalCluster(n_workers=workers, threads_per_worker=1,
                                                   dashboard_address=None, env=dict(WORKER_ENV))
        client = Client(address or cluster)
        cells = DaskCells(prepared, n, options, client, blocks, ckdir=ckdir, resume=resume,
                          progress=progress, layout=layout)
        cells.owned = (client, cluster)
        return cells
    raise ValueError(f"backend {backend!r} unknown; accepted serial, process, dask")


def _rows_before(curve: Path, solver: FexdemSolver, measure) -> list[list]:
    """The curve of an interrupted run up to its restored step: the CSV's rows before the
    restored t, then the restored state's own row (the kill may have come between the
    step's checkpoint and its CSV row)."""
    t = solver.committed.t
    rows = []
    if curve.exists():
        with curve.open(newline="") as f:
            for r in list(csv.reader(f))[1:]:           # stage, t, iterations, cuts, measures
                if float(r[1]) < t - 1e-12:
                    rows.append([r[0], float(r[1]), int(r[2]), int(r[3]), *map(float, r[4:])])
    last = solver.records[-1]
    now = measure(solver)
    # rows of a run written before the curve carried the dashpot's columns: no dashpot, 0
    pad = [0.0] * max(0, len(now) - max((len(r) - 4 for r in rows), default=len(now)))
    return [r + pad for r in rows] + [[last.stage, t, last.iterations, last.cuts, *now.values()]]


def band_of_run(case: str, out: str | Path, nx: int | None = None, ny: int | None = None,
                since: str | Path | None = None) -> dict:
    """Localization (:mod:`contfab.fexdem.band`) of the FE×DEM field checkpointed in
    ``out``/cells (a finished or interrupted run of ``case`` on ``nx`` × ``ny`` elements):
    its total strain since the start, or with ``since`` (a copy of an earlier field
    checkpoint of the same run) the strain increment since that checkpoint; written to
    ``out``/band.json and ``out``/<case>_dem_band.png (``band_since.json`` and
    ``<case>_dem_band_since.png`` with ``since``)."""
    if case not in CASES:
        raise ValueError(f"case {case!r} unknown; accepted {sorted(CASES)}")
    cfg = {k: v for k, v in CASES[case].items() if k in ("nx", "ny", "width", "height")}
    cfg.update({k: v for k, v in (("nx", nx), ("ny", ny)) if v is not None})
    out = Path(out)
    ck = out / "cells" / FE_CHECKPOINT
    if not ck.exists():
        raise FileNotFoundError(f"no FE×DEM field checkpoint {ck}")
    disc = build(case, **cfg).disc
    with np.load(ck) as z:
        u, t, step = z["u"], float(z["t"]), int(z["fe_step"])
    if len(u) != disc.ndofs:
        raise ValueError(f"{ck} has {len(u)} DOFs, the {cfg['nx']} x {cfg['ny']} mesh of {case} "
                         f"{disc.ndofs} (give the run's --nx and --ny)")
    title, tag, extra = f"{case}: FE×DEM shear strain at t = {t:.3g}", "", {}
    if since is not None:
        with np.load(since) as z:
            u0, t0 = z["u"], float(z["t"])
        if len(u0) != len(u) or not t0 < t:
            raise ValueError(f"since = {since}: a field of {len(u0)} DOFs at t = {t0}; accepted "
                             f"an earlier checkpoint (t < {t}) of this run ({len(u)} DOFs)")
        u = u - u0
        title, tag, extra = (f"{case}: FE×DEM shear strain increment, t = {t0:.3g} to {t:.3g}",
                             "_since", {"since": str(since), "t_since": t0})
    strain = disc.strain(u)[0]
    res = {"case": case, "t": t, "step": step, **extra, **cfg, **localization(disc, strain)}
    res["figure"] = str(band_figure(out / f"{case}_dem_band{tag}.png", disc, strain, title))
    res["json"] = str(write_json(out / f"band{tag}.json", res))
    return res


def dem_measure(scene, p0: float):
    """The scene's curve quantities of an FE×DEM run and its step's dashpot overstress
    (largest and weighted mean |σ_v| over the points, units of p0; 0 without a dashpot)."""
    def measure(solver) -> dict:
        rec = solver.records[-1] if solver.records else None
        return {**scene.measure(solver),
                "overstress_max": 0.0 if rec is None else rec.overstress / p0,
                "overstress_mean": 0.0 if rec is None else rec.overstress_mean / p0}
    return measure


def _fexdem(report, curves, finals, *, case, scene, prepared, out, params, p0, backend, workers,
            address, options, progress, resume, blocks, layout, modulus, xcol, ycol,
            viscosity) -> None:
    """The FE×DEM run of ``run`` into ``report``, ``curves`` and ``finals``."""
    disc = scene.disc
    newton = replace(DEM_NEWTON, viscosity=viscosity)
    measure = dem_measure(scene, p0)
    t0 = time.perf_counter()
    cells = make_cells(backend, prepared, disc.npoints, options, workers, address, out / "cells",
                       progress, checkpointed_step(out / "cells") if resume else 0, blocks, layout)
    try:
        mat = DemMaterial(cells, disc, params, p_unit=p0, tangent=TANGENT, modulus=modulus,
                          tangent_tier=params.tier if params.tier in (1, 2) else 2)
        outputs = analysis.Outputs(out, f"{case}_dem", curve_axes=(xcol, ycol),
                                   curve_each_step=True)
        if resume:
            solver, start = FexdemSolver.resume(disc, mat, newton, out / "cells", scene.stage)
            report["resumed_from_t"] = start[0]
            again = analysis.Resume(start, _rows_before(out / f"{outputs.name}_curve.csv", solver,
                                                        measure))
        else:
            solver, again = FexdemSolver(disc, mat, newton, ckdir=out / "cells"), None
        startup = time.perf_counter() - t0
        res = analysis.run(solver, [scene.stage], measure, outputs, progress, resume=again)
        from dem.checkpoint import load
        st, dyn, _, _ = load(prepared)
        report["discs_per_cell"] = st.n
        report["cell_dem"] = {"kappa": dyn.law.kn, "mu": dyn.law.mu, "inertial": dyn.gdot_ref,
                              "c0": st.packing_fraction}
        report["newton"] = {"tol": newton.tol, "tol_stall": newton.tol_stall,
                            "max_iter": newton.max_iter, "tangent": TANGENT,
                            "probe": mat.probe, "viscosity": newton.viscosity}
        report["dashpot"] = {
            "viscosity_p0_time": viscosity,
            "overstress_max_p0": max((r.overstress / p0 for r in solver.records), default=0.0),
            "overstress_mean_max_p0": max((r.overstress_mean / p0 for r in solver.records),
                                          default=0.0)}
        report["cell_options"] = {k: (v if np.isfinite(v) else "inf") for k, v in (
            (k, getattr(options, k)) for k in ("force_tol", "kinetic_tol", "relax_budget",
                                               "check_every", "max_increment"))}
        report["cell_modulus_P0"] = mat.modulus
        report["dem_steps_per_cell"] = {"strain": int(mat.cell_steps[0]), "relax": int(mat.cell_steps[1])}
        report["recoveries"] = cells.recoveries
        report["profile"] = costs(cells, out / "profile.npz")
    finally:
        cells.close()
        for owned in getattr(cells, "owned", ()):
            if owned is not None:
                owned.close()
    report["runs"]["dem"] = _summary(res, solver, time.perf_counter() - t0)
    report["runs"]["dem"]["band"] = localization(disc, disc.strain(solver.committed.u)[0])
    report["band_figure"] = band_figure(out / f"{case}_dem_band.png", disc,
                                        disc.strain(solver.committed.u)[0],
                                        f"{case}: FE×DEM shear strain at the end").name
    report["profile"]["startup_s"] = startup    # cells made, kernels loaded (or compiled)
    report["profile"]["outputs_and_close_s"] = (report["runs"]["dem"]["wall_s"] - startup
                                                - report["profile"]["stage_s"])
    curves["dem"], finals["dem"] = res, solver.committed


def _reference(report, curves, finals, *, case, scene, cfg, prepared, ref: Path,
               viscosity: float) -> None:
    """A finished FE×DEM run of the same scene, sample and dashpot ``viscosity`` in ``ref``
    as the reference of ``run`` (its report, curve and last field checkpoint) into
    ``report``, ``curves`` and ``finals``."""
    path = ref / "report.json"
    if not path.exists():
        raise FileNotFoundError(f"no finished FE×DEM run in {ref} (its report.json is missing)")
    old = json.loads(path.read_text())
    same = {k: (old.get(k), v) for k, v in (("case", case), ("scene", cfg), ("p0", scene.p0))}
    bad = {k: v for k, v in same.items() if v[0] != v[1]}
    if bad:
        raise ValueError(f"reference {ref} is another scene: " + ", ".join(
            f"{k} {v[0]!r} there, {v[1]!r} here" for k, v in bad.items()))
    if old["newton"].get("viscosity", 0.0) != viscosity:
        raise ValueError(f"reference {ref} ran with the dashpot viscosity "
                         f"{old['newton'].get('viscosity', 0.0)!r}, this run with {viscosity!r}: "
                         f"give the same --viscosity (the adaptive run uses it at every point)")
    if old["cell_dem"]["c0"] != initial_fields(prepared, 1, 1.0)[1][0, STATE_NAMES.index("c")]:
        raise ValueError(f"reference {ref} ran cells of another sample (c0 = "
                         f"{old['cell_dem']['c0']}) than {prepared}")
    with np.load(ref / "cells" / FE_CHECKPOINT) as z:
        if abs(float(z["t"]) - 1.0) > 1e-9:
            raise ValueError(f"reference {ref}: its field checkpoint is at t = {float(z['t'])}, "
                             f"not at the end of the stage")
        finals["dem"] = SimpleNamespace(**{k: z[k] for k in ("u", "stress", "state")})
    with open(ref / f"{case}_dem_curve.csv", newline="") as f:
        rows = list(csv.reader(f))
    curves["dem"] = analysis.RunResult(rows[0], [[r[0], *map(float, r[1:])] for r in rows[1:]])
    for key in ("discs_per_cell", "cell_dem", "newton", "cell_options", "cell_modulus_P0",
                "profile", "dashpot"):
        if key in old:
            report[key] = old[key]
    report["runs"]["dem"] = old["runs"]["dem"]
    report["reference"] = str(ref)


def _rel_l2(w: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """sqrt(Σ w |a - b|² / Σ w |b|²) over the quadrature points (weights ``w``)."""
    a, b = a.reshape(len(w), -1), b.reshape(len(w), -1)
    return float(np.sqrt(np.sum(w[:, None] * (a - b) ** 2) / np.sum(w[:, None] * b ** 2)))


def _mobilized(s: np.ndarray) -> np.ndarray:
    """R/P per point (docs/theory.md §1)."""
    return np.hypot(0.5 * (s[:, 0] - s[:, 1]), s[:, 2]) / (-0.5 * (s[:, 0] + s[:, 1]))


def field_errors(disc, ref_stress, ref_c, stress, c) -> dict:
    """Relative L2 errors of stress, R/P and c against the reference (FE×DEM) fields."""
    w = disc.weights.reshape(-1)
    return {"stress": _rel_l2(w, stress, ref_stress),
            "R_over_P": _rel_l2(w, _mobilized(stress), _mobilized(ref_stress)),
            "c": _rel_l2(w, c, ref_c)}


def run(case: str, prepared: str, out: str | Path, params: Params, p0: float = 1.0,
        backend: str = "serial", workers: int = 2, address: str | None = None,
        options: CellOptions = CELL_OPTIONS, progress: bool = True, resume: bool = False,
        blocks: int | None = None, layout: str = "interleaved", adaptive: float | None = None,
        reference: str | Path | None = None, shadows: int = 0, viscosity: float = 0.0,
        **overrides) -> dict:
    """Run ``case`` three ways (four with ``adaptive``, the tolerance of adaptive FE×DEM;
    ``shadows``: its shadow cells; ``reference``: a finished FE×DEM run's directory instead
    of running it) and write the report (see the module doc); returns it."""
    if case not in CASES:
        raise ValueError(f"case {case!r} unknown; accepted {sorted(CASES)}")
    viscosity = dashpot.check_viscosity(viscosity)
    if adaptive is not None:
        model_choice(adaptive)               # a bad tolerance fails before the runs
    if not (isinstance(shadows, int) and shadows >= 0) or (shadows and adaptive is None):
        raise ValueError(f"shadows = {shadows!r} out of range; accepted integers >= 0, "
                         f"> 0 only with adaptive")
    cfg = dict(CASES[case], **overrides)
    xcol, ycol = cfg.pop("curve")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    scene = build(case, p0=p0, **cfg)
    disc = scene.disc
    report = {"case": case, "scene": cfg, "p0": p0, "prepared": str(prepared), "elements": disc.ne,
              "element": disc.element, "cells": disc.npoints, "backend": backend, "runs": {}}
    curves, finals = {}, {}
    modulus = elastic_modulus(prepared)   # first: a cold kernel cache is filled once, here
    stress0, state0 = initial_fields(prepared, disc.npoints, p0)
    if reference is None:
        _fexdem(report, curves, finals, case=case, scene=scene, prepared=prepared, out=out,
                params=params, p0=p0, backend=backend, workers=workers, address=address,
                options=options, progress=progress, resume=resume, blocks=blocks,
                layout=layout, modulus=modulus, xcol=xcol, ycol=ycol, viscosity=viscosity)
    else:
        _reference(report, curves, finals, case=case, scene=scene, cfg=cfg, prepared=prepared,
                   ref=Path(reference), viscosity=viscosity)
    for tier in (1, 2):
        tmat = TierMaterial(params.replace("regularization", p_ref=p0), tier)
        cols = [STATE_NAMES.index(n) for n in tiers.STATE_NAMES[tier]]
        tmat.update(stress0[:1], state0[:1, cols], np.zeros((1, 3)), np.zeros(1))  # JIT, untimed
        t0 = time.perf_counter()
        tsolver = Solver(disc, tmat, stress0, state0[:, cols])
        tres = analysis.run(tsolver, [scene.stage], scene.measure,
                            analysis.Outputs(out, f"{case}_tier{tier}", curve_axes=(xcol, ycol)),
                            progress)
        _compare(report, f"tier{tier}", tres, tsolver, time.perf_counter() - t0, curves, finals,
                 disc, xcol, ycol)
    if adaptive is not None:
        amat = AdaptiveMaterial(prepared, disc, params, adaptive, options, p_unit=p0,
                                modulus=modulus, shadows=shadows)
        amat.update(stress0, state0, np.zeros((disc.npoints, 3)),
                    np.zeros(disc.npoints))                          # JIT, untimed
        t0 = time.perf_counter()
        asolver = AdaptiveSolver(disc, amat, replace(DEM_NEWTON, viscosity=viscosity))
        ares = analysis.run(asolver, [scene.stage], scene.measure,
                            analysis.Outputs(out, f"{case}_adaptive", curve_axes=(xcol, ycol),
                                             curve_each_step=True), progress)
        _compare(report, "adaptive", ares, asolver, time.perf_counter() - t0, curves, finals,
                 disc, xcol, ycol)
        report["adaptive"] = amat.report() | {"viscosity": viscosity}
        dem_cpu = report["profile"]["trials"]["cell_cpu_s"]
        report["adaptive"]["cost_ratio_cpu_adaptive_over_dem"] = (
            sum(amat.cpu.values()) / dem_cpu if dem_cpu > 0 else None)
    report["overlay"] = _overlay(out / "overlay.png", curves, xcol, ycol, case).name
    report["report"] = str(write_json(out / "report.json", report))
    return report


def _compare(report: dict, name: str, res, solver, wall: float, curves: dict, finals: dict,
             disc, xcol: str, ycol: str) -> None:
    """Run ``name``'s summary and its errors and cost ratio against FE×DEM into ``report``."""
    report["runs"][name] = _summary(res, solver, wall)
    report["runs"][name]["band"] = localization(disc, disc.strain(solver.committed.u)[0])
    curves[name], finals[name] = res, solver.committed
    x, y = curves["dem"].column(xcol), curves["dem"].column(ycol)
    yt = np.interp(x, res.column(xcol), res.column(ycol))
    ref, fin = finals["dem"], solver.committed
    names = solver.material.state_names
    report["runs"][name]["errors"] = {
        "curve": float(np.max(np.abs(yt - y)) / np.max(np.abs(y))),
        "fields": field_errors(disc, ref.stress, ref.state[:, STATE_NAMES.index("c")],
                               fin.stress, fin.state[:, names.index("c")]),
        "cost_ratio_dem_over_tier": report["runs"]["dem"]["wall_s"] / wall}


def _summary(res, solver, wall: float) -> dict:
    its = [r.iterations for r in solver.records]
    return {"wall_s": wall, "steps": len(solver.records), "newton_iterations": int(sum(its)),
            "max_iterations": int(max(its)) if its else 0,
            "stalled_steps": int(sum(r.stalled for r in solver.records)),
            "final_residual_max": float(max((r.residuals[-1] for r in solver.records), default=0.0)),
            "residuals": [{"t": r.t, "cuts": r.cuts, "residuals": [float(x) for x in r.residuals]}
                          for r in solver.records],
            "curve_end": {k: float(res.column(k)[-1]) for k in res.columns[4:]} if res.rows else {}}


def _overlay(path: Path, curves: dict, xcol: str, ycol: str, case: str) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    for name, res in curves.items():
        ax.plot(res.column(xcol), res.column(ycol), "o-" if name == "dem" else "-", ms=3,
                label={"dem": "FE×DEM", "adaptive": "adaptive FE×DEM"}.get(
                    name, name.replace("tier", "tier ")))
    ax.set_xlabel(xcol)
    ax.set_ylabel(f"{ycol} (stress unit p0)")
    ax.set_title(f"{case}: FE×DEM and the model tiers")
    ax.legend()
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120)
    plt.close(fig)
    return path
