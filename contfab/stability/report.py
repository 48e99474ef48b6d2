"""Run the stability matrix and write ``stability.csv`` and ``stability.png``.

Each component's points run serially in one child process (``spawn``: a process forked after
numba's threading layer has started can hang) that reports every outcome as it finishes. The
parent waits at most a point's time budget (plus :data:`STARTUP_S` for the child's import
and kernel loading) for each; a point that exceeds it is a hang: the child is killed, the
point recorded as FAIL, and a new child resumes at the next point. So a hang never stops
the matrix, and every outcome is measured, not assumed.
"""
from __future__ import annotations

import multiprocessing as mp
import queue
from pathlib import Path

from contfab.stability.core import (ACCURACY_LOST, CLEAR_ERROR, COMPONENTS, FAIL, OUTCOMES, PASS,
                                    Outcome, Point, evaluate)

STARTUP_S = 120.0
"""Allowance for a fresh child: interpreter, imports, numba kernels from the cache."""


def matrix(component: str) -> list[Point]:
    """Every point of ``component`` (full matrix; filter on ``full_only`` for the reduced one)."""
    if component == "dem":
        from contfab.stability import dem_matrix as m
    elif component == "point":
        from contfab.stability import point_matrix as m
    elif component == "fem":
        from contfab.stability import fem_matrix as m
    else:
        raise ValueError(f"component {component!r} is not one of {', '.join(COMPONENTS)}")
    return m.points()


def selected(component: str, full: bool) -> list[Point]:
    return [p for p in matrix(component) if full or not p.full_only]


def _child(component: str, full: bool, start: int, out: mp.Queue) -> None:
    import numba
    numba.set_num_threads(1)
    pts = selected(component, full)
    for k in range(start, len(pts)):
        out.put(("start", k, None))
        out.put(("done", k, evaluate(pts[k])))
    out.put(("end", len(pts), None))


def run_component(component: str, full: bool, on_outcome=None) -> list[Outcome]:
    """All outcomes of one component, each point supervised as the module doc says."""
    pts = selected(component, full)
    ctx = mp.get_context("spawn")
    outcomes: list[Outcome] = []
    k = 0
    while k < len(pts):
        q = ctx.Queue()
        proc = ctx.Process(target=_child, args=(component, full, k, q), daemon=True)
        proc.start()
        wait = STARTUP_S + pts[k].budget_s
        while k < len(pts):
            try:
                kind, idx, result = q.get(timeout=wait)
            except queue.Empty:
                proc.kill()
                proc.join()
                p = pts[k]
                o = Outcome(p.component, p.axis, p.value, FAIL, seconds=wait,
                            message=f"hang: no result within {wait:g} s (budget {p.budget_s:g} s "
                                    f"+ start-up allowance); the run was killed")
                outcomes.append(o)
                if on_outcome:
                    on_outcome(o)
                k += 1
                break
            if kind == "start":
                wait = pts[idx].budget_s + (STARTUP_S if idx == k and not outcomes else 30.0)
            elif kind == "done":
                outcomes.append(result)
                if on_outcome:
                    on_outcome(result)
                k = idx + 1
            else:
                k = len(pts)
        proc.join(timeout=10)
        if proc.is_alive():
            proc.kill()
    return outcomes


def run(out_dir: str | Path, full: bool = False, only: str | None = None,
        progress: bool = True) -> dict:
    """Run the matrix (all components, or ``only`` one), write the CSV and the map."""
    from tqdm import tqdm

    from dem.fileio import write_csv
    comps = COMPONENTS if only is None else (only,)
    for c in comps:
        if c not in COMPONENTS:
            raise ValueError(f"--only {c!r} is not one of {', '.join(COMPONENTS)}")
    total = sum(len(selected(c, full)) for c in comps)
    bar = tqdm(total=total, desc="stability points", disable=not progress)
    outcomes = []
    for c in comps:
        def tick(o, bar=bar):
            bar.update(1)
            bar.set_postfix_str(f"{o.component}:{o.axis}={o.value} {o.outcome}"[:60])
        outcomes += run_component(c, full, tick)
    bar.close()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv = write_csv(out_dir / "stability.csv", Outcome.COLUMNS, [o.as_row() for o in outcomes])
    png = plot_map(outcomes, out_dir / "stability.png")
    return {"csv": csv, "png": png, "counts": counts(outcomes), "outcomes": outcomes}


def counts(outcomes: list[Outcome]) -> dict:
    return {k: sum(o.outcome == k for o in outcomes) for k in OUTCOMES}


COLOURS = {PASS: "#2ca02c", ACCURACY_LOST: "#ffbf00", CLEAR_ERROR: "#1f77b4", FAIL: "#d62728"}


def plot_map(outcomes: list[Outcome], path: Path) -> Path:
    """One row per (component, axis), one coloured cell per value (module doc of core)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    from dem.fileio import atomic_path
    rows: dict[str, list[Outcome]] = {}
    for o in outcomes:
        rows.setdefault(f"{o.component}: {o.axis}", []).append(o)
    width = max(len(v) for v in rows.values())
    fig, ax = plt.subplots(figsize=(2.0 + 1.3 * width, 0.9 + 0.32 * len(rows)))
    for y, (label, items) in enumerate(rows.items()):
        for x, o in enumerate(items):
            ax.add_patch(plt.Rectangle((x, y), 0.95, 0.85, color=COLOURS[o.outcome]))
            ax.text(x + 0.47, y + 0.42, o.value[:14], ha="center", va="center", fontsize=6)
    ax.set_xlim(0, width)
    ax.set_ylim(len(rows), 0)
    ax.set_yticks([i + 0.42 for i in range(len(rows))], list(rows), fontsize=7)
    ax.set_xticks([])
    ax.set_title("contfab stability matrix (cell text: the value on the axis)", fontsize=9)
    ax.legend(handles=[Patch(color=COLOURS[k], label=k.lower().replace("_", " ")) for k in OUTCOMES],
              loc="upper center", bbox_to_anchor=(0.5, -0.01), ncol=4, fontsize=7, frameon=False)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=130, format="png")
    plt.close(fig)
    return path
