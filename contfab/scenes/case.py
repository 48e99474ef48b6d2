"""The boundary-value cases: discovery, common options and the error report.

A case is a module ``contfab.scenes.NAME`` (listed in :data:`SCENES`) exposing
``DESCRIPTION``, ``add_arguments(parser)`` and ``run(args) -> CaseResult``. It runs as
``contfab case NAME``, and as ``python cases/NAME.py`` (a thin script calling
:func:`main` on the module, to read and copy). Common options:
``--fast`` (the test-suite preset), ``--json`` (print one JSON object: the headline
figure's reference, computed value and relative error, and every figure), ``--out``
(output directory), ``--quiet`` (no progress bars).
"""
from __future__ import annotations

import argparse
import importlib
import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

SCENES = ("biaxial_shear_band", "retaining_wall", "simple_shear_reversal", "strip_footing")
"""The case modules of this package, by name."""


@dataclass
class Figure:
    """A computed number against its reference: relative error = computed/reference - 1."""

    name: str
    computed: float
    reference: float
    source: str

    @property
    def relative_error(self) -> float:
        return self.computed / self.reference - 1.0

    def as_dict(self) -> dict:
        return {"name": self.name, "reference": self.reference, "computed": self.computed,
                "relative_error": self.relative_error, "source": self.source}


@dataclass
class CaseResult:
    """What a case reports: figures (the first is the headline), notes, written files."""

    figures: list[Figure]
    notes: dict = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)

    def as_dict(self) -> dict:
        head = self.figures[0]
        return {"reference": head.reference, "computed": head.computed,
                "relative_error": head.relative_error, "figure": head.name,
                "figures": [f.as_dict() for f in self.figures], **self.notes,
                "files": [str(f) for f in self.files]}


def failure_note(exc, *columns: str) -> dict:
    """The notes entry of a study sub-run that ended in a ConvergenceError ``exc``.

    Records the error message, where the last converged step was (stage, t), the last
    converged values of the case's measured ``columns`` and the largest value of the
    first one so far (None where no step of the recorded stages converged). A study
    continues with its other sub-runs; only the run behind the headline figure re-raises.
    """
    curve = getattr(exc, "curve", None)
    have = curve is not None and bool(curve.rows)
    last = {c: float(curve.column(c)[-1]) if have and c in curve.columns else None
            for c in columns}
    top = columns[0] if columns else None
    peak = float(curve.column(top).max()) if have and top in curve.columns else None
    return {"failed": True, "message": str(exc), "last_converged_stage": exc.last.stage,
            "last_converged_t": float(exc.last.t), "last_converged": last,
            f"max_{top}_so_far": peak}


def case_names() -> list[str]:
    """Names of the cases (:data:`SCENES`)."""
    return list(SCENES)


def load_case(name: str):
    """The module ``contfab.scenes.NAME`` (a ValueError listing the cases if unknown)."""
    if name not in SCENES:
        raise ValueError(f"unknown case {name!r}; available: {', '.join(SCENES)}")
    return importlib.import_module(f"contfab.scenes.{name}")


def build_parser(module, prog: str) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=prog, description=module.DESCRIPTION)
    parser.add_argument("--fast", action="store_true", help="the quick preset used by the test suite")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON object {reference, computed, relative_error, ...}")
    parser.add_argument("--out", default=None,
                        help="output directory (default runs/NAME; 'none' writes nothing)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    module.add_arguments(parser)
    return parser


def run_case(name: str, argv: list[str] | None = None) -> CaseResult:
    """Parse ``argv`` for case ``name`` and run it (what the tests call)."""
    module = load_case(name)
    args = build_parser(module, f"contfab case {name}").parse_args(argv or [])
    _resolve_out(args, name)
    return module.run(args)


def _resolve_out(args, name: str) -> None:
    if args.out is None:
        args.out = Path("runs") / name
    elif str(args.out).lower() == "none":
        args.out = None
    else:
        args.out = Path(args.out)


def print_result(result: CaseResult, as_json: bool) -> None:
    """One JSON object, or a line per figure with its reference, its source and its error."""
    if as_json:
        print(json.dumps(_finite(result.as_dict()), default=_plain, allow_nan=False))
        return
    for f in result.figures:
        if not math.isfinite(f.reference):
            print(f"{f.name}: computed {f.computed:.4g}; {f.source}")
            continue
        print(f"{f.name}: computed {f.computed:.4g}, reference {f.reference:.4g} ({f.source}), "
              f"error {100 * f.relative_error:+.2f}%")
    for k, v in result.notes.items():
        print(f"  {k}: {_fmt(v)}")
    if result.files:
        print(f"wrote {len(result.files)} files to {Path(result.files[0]).parent}: "
              + ", ".join(sorted({Path(f).name for f in result.files if not str(f).endswith('.vtu')})))


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def _finite(obj):
    """NaN and inf become null (strict JSON), recursively; numpy scalars become floats."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if hasattr(obj, "item") and getattr(obj, "ndim", 1) == 0:
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _plain(obj):
    if hasattr(obj, "tolist"):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serializable: {type(obj).__name__}")


def main(module, argv: list[str] | None = None, prog: str | None = None) -> int:
    """Run a case module from the command line: parse, run, print; exit 2 on a clear input error."""
    name = module.__name__.rsplit(".", 1)[-1]
    args = build_parser(module, prog or f"python cases/{name}.py").parse_args(argv)
    _resolve_out(args, name)
    try:
        result = module.run(args)
    except (ValueError, FileNotFoundError) as exc:
        print(f"{name}: error: {exc}", file=sys.stderr)
        return 2
    print_result(result, args.json)
    return 0
