"""``contfab compare``: the DEM and the material point on one loading path, side by side.

The DEM prepares a sample (dense: μ_prep = 0, or loose: μ_prep = μ) and runs the path
(resumable, as a campaign job: :func:`contfab.calibration.campaign.run_dem_job`); the material point
runs the same path from the DEM sample's initial state (c0, and the fabric for tier 2)
with the given parameters. Both are sampled at the same strains (:mod:`contfab.calibration.curves`).
Writes into the output directory

    dem/                    the DEM run (history.csv, history.json, checkpoints, plots)
    model_<name>.csv        the material point's history (one per probe of a family)
    compare_<name>.png      the overlay (R/P, ε_v, c, A, B, θp)
    errors.csv, errors.json the error metrics per quantity (:func:`contfab.calibration.curves.errors`)
"""
from __future__ import annotations

from pathlib import Path as FsPath

from contfab.calibration.campaign import DemJob, run_dem_job
from contfab.calibration.curves import dem_curve, errors, read_history
from contfab.calibration.fitting import Target, run_model
from contfab.params import default_params, default_params_path, load_params
from contfab.calibration.report import error_rows, overlay_plot, write_tables
from dem.fileio import write_csv, write_json
from dem.job import Settings
from dem.paths import load_path
from dem.provenance import code_versions


def compare(path_name: str, out: str | FsPath, params_file: str | None = None,
            tier: int | None = None, n: int = 1000, seed: int = 1, kappa: float = 1e3,
            density: str = "dense", mu: float = 0.5, inertial: float = 1e-3) -> dict[str, FsPath]:
    """Run the DEM and the model on ``path_name`` and write the files of the module doc."""
    path = load_path(path_name)
    if density not in ("dense", "loose"):
        raise ValueError(f"density {density!r} is not known; accepted: dense, loose")
    params = default_params() if params_file is None else load_params(params_file)
    tier = params.tier if tier is None else tier
    params = params.with_tier(tier)
    settings = Settings(n=n, seed=seed, kappa=kappa, mu=mu,
                        mu_prep=0.0 if density == "dense" else mu, inertial=inertial)
    settings.validate()
    out = FsPath(out)
    prepared = out / "dem" / "prepared_sample.npz"
    run_dem_job(DemJob(settings, str(prepared)))
    run_dir = run_dem_job(DemJob(settings, str(out / "dem" / "run"), path_name, str(prepared)))
    written: dict[str, FsPath] = {}
    rows, metrics = [], {}
    subs = path.expand()
    for k, sub in enumerate(subs):
        name = path.name if len(subs) == 1 else sub.name.rsplit("/", 1)[-1]
        hist = read_history(FsPath(run_dir) / ("history.csv" if len(subs) == 1 else f"history_{k}.csv"))
        target = Target(name, sub, dem_curve(sub, [hist]))
        sample, result = run_model(params, tier, target)
        errs = errors(target.curve, sample)
        metrics[name] = errs
        rows += error_rows("compare", name, f"tier {tier}", errs)
        if result is not None:
            written[f"model_{name}"] = write_csv(out / f"model_{name}.csv", *result.rows())
        written[f"plot_{name}"] = overlay_plot(
            target.curve, {f"tier {tier}": sample}, out / f"compare_{name}.png",
            f"{name}: DEM (N = {n}, seed {seed}, κ = {kappa:g}, {density}) vs tier {tier}")
    written["errors_csv"], written["errors_md"] = write_tables(rows, out / "errors")
    written["errors_json"] = write_json(out / "errors.json", {
        "path": path.to_dict(), "tier": tier, "params_file": str(params_file or default_params_path()),
        "dem": {"settings": settings.__dict__, "run": str(run_dir)}, "errors": metrics,
        "versions": code_versions()})
    return written
