"""Files of a study: the table (CSV), error against CPU time (PNG), a Markdown summary.

``DIR/NAME.csv``: one row per table row of the study: knobs, wall and CPU time (s), cost, every
error, the combined error (the largest), ``pareto`` (1 on the front) and ``default``.
``DIR/NAME.png``: combined error against CPU time, log-log, every row as a dot, the
Pareto front as a line, the default setting as a star.
``DIR/NAME.md``: what the study measures, its table, where the default setting sits
(on the front, beaten by which settings, or not run) and its notes.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from contfab.tradeoff.study import Study, combined_error, is_default, pareto_front
from dem.fileio import atomic_path, write_csv


def table(study: Study, rows: list[dict]) -> tuple[tuple[str, ...], list[list]]:
    """(columns, rows) of the CSV table (module doc)."""
    front = pareto_front(rows)
    cols = (*study.knobs, "wall_s", "cpu_s", "cost", *(f"error_{q}" for q in study.quantities),
            "error", "pareto", "default")
    out = []
    for r, f in zip(rows, front):
        out.append([r["knobs"][k] for k in study.knobs] + [r["wall_s"], r["cpu_s"], r["cost"]]
                   + [r["errors"].get(q, math.nan) for q in study.quantities]
                   + [combined_error(r), int(f), int(is_default(study, r))])
    return cols, out


def plot(study: Study, rows: list[dict], path: Path) -> Path:
    """Combined error against CPU time, log-log, front and default marked."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    front = pareto_front(rows)
    t = [r["cpu_s"] for r in rows]
    e = [combined_error(r) for r in rows]
    fig, ax = plt.subplots(figsize=(6, 4.2))
    ax.loglog(t, e, "o", color="0.6", label="settings")
    for r, ti, ei in zip(rows, t, e):
        ax.annotate(_label(study, r), (ti, ei), fontsize=6, xytext=(3, 3),
                    textcoords="offset points")
    fr = sorted((ti, ei) for ti, ei, f in zip(t, e, front) if f)
    if fr:
        ax.loglog(*zip(*fr), "-", color="C0", label="Pareto front")
    d = [(ti, ei) for r, ti, ei in zip(rows, t, e) if is_default(study, r)]
    if d:
        ax.loglog(*zip(*d), "*", color="C3", markersize=14, label="default")
    ax.set_xlabel("CPU time per point (s, one thread)")
    ax.set_ylabel(f"error ({study.error_meaning})")
    ax.set_title(f"{study.name}: {study.description}", fontsize=8)
    ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return path


def _label(study: Study, row: dict) -> str:
    return ",".join(f"{v:g}" if isinstance(v, (int, float)) else str(v)
                    for v in (row["knobs"][k] for k in study.knobs))


def markdown(study: Study, rows: list[dict], notes: dict, png_name: str | None = None) -> str:
    """The study's section of the summary (module doc)."""
    cols, data = table(study, rows)
    lines = [f"## {study.name}", "", study.description, "",
             f"Error: {study.error_meaning}. Cost: {study.cost_unit}. "
             f"Front: not beaten in both CPU time and error; ★ the default setting.", ""]
    head = [*study.knobs, "wall s", "CPU s", "cost", *study.quantities, "error", "front"]
    lines.append("| " + " | ".join(head) + " |")
    lines.append("|" + "---|" * len(head))
    for row in data:
        knob_vals = [_fmt(v) for v in row[:len(study.knobs)]]
        nums = [_fmt(v) for v in row[len(study.knobs):-2]]
        mark = ("✓" if row[-2] else "") + (" ★" if row[-1] else "")
        lines.append("| " + " | ".join(knob_vals + nums + [mark.strip()]) + " |")
    lines += ["", f"- default setting {json.dumps(study.default)}: {default_verdict(study, rows)}"]
    for k, v in notes.items():
        lines.append(f"- {k}: {_fmt(v) if not isinstance(v, (dict, list)) else json.dumps(v)}")
    if png_name:
        lines += ["", f"![{study.name}]({png_name})"]
    return "\n".join(lines) + "\n"


def default_verdict(study: Study, rows: list[dict]) -> str:
    """Where the default setting sits: on the front, beaten (by which rows), or not run."""
    front = pareto_front(rows)
    mine = [i for i, r in enumerate(rows) if is_default(study, r)]
    if not mine:
        return "not among these settings"
    i = mine[0]
    if front[i]:
        return "on the Pareto front"
    t, e = rows[i]["cpu_s"], combined_error(rows[i])
    better = [_label(study, r) for j, r in enumerate(rows) if j != i
              and r["cpu_s"] <= t and combined_error(r) <= e]
    return f"off the front, beaten by {', '.join(better)} (cheaper and at least as accurate)"


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.3g}"
    return str(v)


def write(study: Study, rows: list[dict], notes: dict, out: str | Path) -> dict[str, Path]:
    """Write the CSV, the PNG and the Markdown section into ``out``; returns the paths."""
    out = Path(out)
    csv = write_csv(out / f"{study.name}.csv", *table(study, rows))
    png = plot(study, rows, out / f"{study.name}.png")
    md = out / f"{study.name}.md"
    with atomic_path(md) as tmp:
        Path(tmp).write_text(markdown(study, rows, notes, png.name))
    return {"table": csv, "plot": png, "summary": md}
