"""Run a boundary-value problem's stages with a progress bar and write its outputs.

Outputs in ``outdir`` (each written atomically, :mod:`contfab.fem.output`):
``NAME.pvd`` + ``NAME_####.vtu`` (the field series), ``NAME_curve.csv`` (one row
per converged step: stage, t, Newton iterations, step cuts, and the case's measured
quantities), ``NAME_curve.png`` and ``NAME_plastic_zone.png`` (the increment of
plastic shear strain over the last steps: the active mechanism). When Newton
fails below the minimum step, the last converged state is written as a frame, the
curve so far is saved, ``NAME_failure.json`` holds the report, and the
:class:`~contfab.fem.solver.ConvergenceError` is re-raised with the paths added and
the curve so far as its ``curve`` (also without an output directory). With
``Outputs.curve_each_step`` the curve CSV is rewritten after every recorded step, so a
killed run leaves its curve so far (the input of a resumed run, ``resume``).

Each committed step also feeds the loading indicators of every quadrature point
(:class:`contfab.selection.indicators.Tracker`: axes rotation, reversal, distance from c*), the
run-time input of ``tier = "auto"`` (:mod:`contfab.fem.auto`); ``RunResult.indicators``.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
from tqdm import tqdm

from contfab.fem.output import VtuSeries, plot_curve, plot_field
from contfab.fem.solver import ConvergenceError, Solver, Stage
from contfab.selection.indicators import Tracker
from dem.fileio import write_csv, write_json


@dataclass
class Outputs:
    """Where and what to write: ``frames`` every k-th step (0: first/last only), plots."""

    outdir: str | os.PathLike | None
    name: str
    frame_every: int = 0
    curve_axes: tuple[str, str] | None = None       # (x column, y column) for the PNG
    reference: float | None = None                    # horizontal line on the curve plot
    reference_label: str = "reference"
    window: tuple[float, float, float, float] | None = None  # plastic-zone plot extent
    curve_each_step: bool = False                     # rewrite NAME_curve.csv every step


@dataclass
class Resume:
    """Where a resumed run starts: ``start`` of :meth:`Solver.run_stage` in the first
    stage, and the curve rows recorded before it (the restored state's row included)."""

    start: tuple
    rows: list[list]


@dataclass
class RunResult:
    """The curve rows, the written files and the Newton records of a run."""

    columns: list[str]
    rows: list[list]
    files: list[Path] = field(default_factory=list)
    iterations: list[int] = field(default_factory=list)
    indicators: Tracker | None = None

    def column(self, name: str) -> np.ndarray:
        j = self.columns.index(name)
        return np.array([row[j] for row in self.rows], dtype=float)


def run(solver: Solver, stages: Sequence[Stage], measure: Callable[[Solver], dict],
        outputs: Outputs, progress: bool = True, record_stages: Sequence[str] | None = None,
        resume: Resume | None = None) -> RunResult:
    """Run ``stages`` in order; after each step record ``measure(solver)`` (a dict of floats).

    Only steps of ``record_stages`` (default: all) enter the curve. Frames are
    written every ``outputs.frame_every`` recorded steps and at the end. ``resume``: the
    solver holds a restored mid-stage state of ``stages[0]``; the curve continues
    ``resume.rows`` (the indicators and frames cover the resumed part only).
    """
    record_stages = [s.name for s in stages] if record_stages is None else list(record_stages)
    first = measure(solver)
    result = RunResult(["stage", "t", "iterations", "cuts", *first],
                       [] if resume is None else [list(r) for r in resume.rows])
    names = solver.material.state_names
    c_col = names.index("c") if "c" in names else None
    params = getattr(solver.material, "params", None)
    c_star = params.tier1.c_star if c_col is not None and params is not None else float("nan")
    result.indicators = tracker = Tracker(solver.committed.stress, c_star)
    series = None
    if outputs.outdir is not None:
        series = VtuSeries(outputs.outdir, outputs.name, solver.disc, solver.material.state_names)
    gp_col = solver.material.state_names.index("gp")
    gp_last = solver.committed.state[:, gp_col]
    gp_before = gp_last
    try:
        for k, stage in enumerate(stages):
            bar = tqdm(total=1.0, desc=f"{outputs.name}: {stage.name}", disable=not progress,
                       bar_format="{desc} {percentage:3.0f}%|{bar}| {elapsed}<{remaining}{postfix}",
                       leave=False)
            start = resume.start if resume is not None and k == 0 else None
            with bar:
                if start is not None:
                    bar.update(start[0])
                stress_before = solver.committed.stress
                for rec in solver.run_stage(stage, start):
                    c = solver.committed
                    gp_before, gp_last = gp_last, c.state[:, gp_col]
                    tracker.update(stress_before, c.stress, c.dstrain, c.status >= 1,
                                   None if c_col is None else c.state[:, c_col])
                    stress_before = c.stress
                    bar.update(rec.dt)
                    bar.set_postfix_str(f"t={rec.t:.3f} newton={rec.iterations} cuts={rec.cuts}")
                    if stage.name not in record_stages:
                        continue
                    result.rows.append([stage.name, rec.t, rec.iterations, rec.cuts,
                                        *measure(solver).values()])
                    result.iterations.append(rec.iterations)
                    step = len(result.rows)
                    if outputs.curve_each_step and outputs.outdir is not None:
                        write_csv(Path(outputs.outdir) / f"{outputs.name}_curve.csv",
                                  result.columns, result.rows)
                    if series is not None and outputs.frame_every and step % outputs.frame_every == 0:
                        series.write(solver.committed, step)
    except ConvergenceError as exc:
        exc.curve = result
        if outputs.outdir is not None:
            result.files += _write(solver, series, result, outputs, gp_before)
            report = Path(outputs.outdir) / f"{outputs.name}_failure.json"
            write_json(report, {"message": str(exc), "last_converged_t": exc.last.t,
                                "last_converged_stage": exc.last.stage, "attempts": exc.attempts})
            result.files.append(report)
            raise ConvergenceError(f"{exc}\nlast converged state and curve written to "
                                   f"{outputs.outdir} (report {report.name})",
                                   exc.last, exc.attempts, result) from None
        raise
    if outputs.outdir is not None:
        result.files += _write(solver, series, result, outputs, gp_before)
    return result


def _write(solver: Solver, series, result: RunResult, outputs: Outputs, gp_before) -> list[Path]:
    """The final frame, the curve CSV and the two PNGs."""
    out = Path(outputs.outdir)
    files = [series.write(solver.committed, len(result.rows)), series.pvd]
    files.append(write_csv(out / f"{outputs.name}_curve.csv", result.columns, result.rows))
    if outputs.curve_axes is not None and result.rows:
        x, y = outputs.curve_axes
        files.append(plot_curve(out / f"{outputs.name}_curve.png", result.column(x),
                                result.column(y), x, y, outputs.name, outputs.reference,
                                outputs.reference_label))
    disc = solver.disc
    gp = solver.committed.state[:, solver.material.state_names.index("gp")]
    files.append(plot_field(out / f"{outputs.name}_plastic_zone.png", disc,
                            disc.element_mean(gp - gp_before),
                            "plastic shear strain increment",
                            f"{outputs.name}: plastic zone (last steps)", outputs.window))
    return files
