"""The ``contfab`` command line: parses arguments and calls the drivers, nothing more.

Each command is a pair of functions: ``_add_NAME(parser)`` declares its arguments
and ``_run_NAME(args)`` calls the driver. Register it in :data:`COMMANDS`.
Expected input errors (``ValueError`` and subclasses, missing files) end with a
one-line message and exit status 2, never a traceback.
"""
from __future__ import annotations

import argparse
import sys


# --------------------------------------------------------------------------- paths

def _add_paths(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", nargs="?", help="a standard path name or a path file; omit to list them")


def _run_paths(args) -> None:
    from dem.paths import load_path, standard_paths

    if args.name is None:
        for name in standard_paths():
            print(f"{name:24s} {load_path(name).description}")
        return
    path = load_path(args.name)
    print(f"{path.name}: {path.description}")
    for run in path.expand():
        for i, st in enumerate(run.stages):
            ctl = ", ".join(f"L.{c}={r:g}" for c, r, s in zip(("xx", "yy", "xy", "yx"),
                                                             st.rate_vector, st.stress_controlled)
                            if not s)
            sig = ", ".join(f"sigma.{c}" for c, s in zip(("xx", "yy", "xy", "yx"),
                                                        st.stress_controlled) if s)
            until = ", ".join(f"{u.quantity}->{u.value:g}" for u in st.until)
            print(f"  [{run.name}] stage {i} {st.name!r}: length {st.length:g}; {ctl}"
                  f"{'; stress-controlled ' + sig if sig else ''}{'; until ' + until if until else ''}")


# --------------------------------------------------------------------------- point

def _add_point(p: argparse.ArgumentParser) -> None:
    from contfab.material_point import DEFAULT_INCREMENT

    p.add_argument("path", help="a standard path name (see 'contfab paths') or a path file")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--params", default=None,
                   help="parameter TOML file (default: the shipped contfab/data/default_params.toml)")
    p.add_argument("--tier", type=int, default=None,
                   help="model tier (default: the 'tier' of the parameter file)")
    p.add_argument("--increment", type=float, default=DEFAULT_INCREMENT,
                   help=f"increment Δτ_max in reference strain (default {DEFAULT_INCREMENT:g}); "
                        f"halving it halves the integration error (first order)")


def _run_point(args) -> None:
    from contfab.point_job import run_job

    written = run_job(args.path, args.out, args.params, args.tier, args.increment)
    for what, f in written.items():
        print(f"{what:>14}: {f}")


# --------------------------------------------------------------------------- bench

BENCHES = {
    "model": "contfab.bench.model",
    "point": "contfab.bench.point",
}
"""Benchmark name -> module with ``run(args) -> dict`` of figures."""


def _add_bench(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", choices=sorted(BENCHES), help="which benchmark")
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    p.add_argument("--repeats", type=int, default=5, help="timed repeats per figure (median)")


def _run_bench(args) -> None:
    import importlib

    from contfab.bench import print_figures

    figures = importlib.import_module(BENCHES[args.name]).run(args)
    print_figures(f"contfab bench {args.name}", figures, args.json)


COMMANDS = {
    "paths": (_add_paths, _run_paths, "list the standard loading paths, or show one"),
    "point": (_add_point, _run_point, "drive one material point along a loading path (CSV, "
                                      "JSON, PNG)"),
    "bench": (_add_bench, _run_bench, "speed figures of a part (--json for tracking)"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="contfab", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (add, _, help_) in COMMANDS.items():
        add(sub.add_parser(name, help=help_, description=help_))
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        COMMANDS[args.command][1](args)
    except (ValueError, FileNotFoundError) as exc:
        print(f"contfab {args.command}: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
