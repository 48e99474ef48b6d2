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


# --------------------------------------------------------------------------- case

def _add_case(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", nargs="?", help="a case of cases/ (omit to list them)")
    p.add_argument("args", nargs=argparse.REMAINDER,
                   help="the case's own options (--fast, --json, --out DIR, ...; see --help)")


def _run_case(args) -> int:
    from contfab import cases

    if args.name is None:
        for name in cases.case_names():
            print(f"{name:24s} {cases.load_case(name).DESCRIPTION.splitlines()[0]}")
        return 0
    return cases.main(cases.load_case(args.name), args.args, prog=f"contfab case {args.name}")


# --------------------------------------------------------------------------- bench

BENCHES = {
    "fem": "contfab.bench.fem",
}


def _add_bench(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", choices=sorted(BENCHES), help="which benchmark")
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    p.add_argument("--repeats", type=int, default=3, help="timing repeats (median)")


def _run_bench(args) -> None:
    import importlib

    from contfab.bench import print_figures

    figures = importlib.import_module(BENCHES[args.name]).run(args)
    print_figures(f"contfab bench {args.name}", figures, args.json)


COMMANDS = {
    "paths": (_add_paths, _run_paths, "list the standard loading paths, or show one"),
    "case": (_add_case, _run_case, "run a boundary-value case of cases/ (or list them)"),
    "bench": (_add_bench, _run_bench, "run a benchmark and print its figures"),
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
        status = COMMANDS[args.command][1](args)
    except (ValueError, FileNotFoundError) as exc:
        print(f"contfab {args.command}: error: {exc}", file=sys.stderr)
        return 2
    return status or 0


if __name__ == "__main__":
    sys.exit(main())
