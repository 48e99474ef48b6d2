"""The job behind ``contfab point``: a loading path on a material point, written to files.

Writes into the output directory (names as the DEM's ``contfab dem run``, so a DEM run and
a model run of the same path sit side by side)

    history.csv     one row per output step: :data:`dem.history.HISTORY_COLUMNS` (fabric
                    columns empty for tiers without a fabric), then
                    :data:`contfab.material_point.EXTRA_COLUMNS`
    history.json    sidecar: parameters, tier, path, increments, timing, code version, files
    history.png     R/P, ε_v, c (and A, B, θp) against τ

For a probe family each probe writes ``history_<k>.csv`` (k in the order of
``Path.expand()``) and ``response.png`` shows the response envelope. The path and the
parameters are validated and every run finishes before anything is written; every file is
written atomically, so an error leaves no partial file. The first tier-2 run after an
install or an edit of the kernels' sources says on stderr, once, that it is compiling
(:data:`COMPILE_TIME`).
"""
from __future__ import annotations

import time
from pathlib import Path as FsPath


from contfab import material_point as mp
from contfab.models import tiers
from contfab.params import default_params, default_params_path, load_params
from dem.fileio import write_csv, write_json
from dem.numba_cache import announce_compiling
from dem.provenance import code_versions
from dem.paths import load_path

COMPILE_TIME = {2: "25 s"}
"""Cold compile time of the tiers whose kernels take long to compile (measured, one core)."""


def run_job(path_name: str, out_dir: str | FsPath, params_file: str | None = None,
            tier: int | None = None, increment: float = mp.DEFAULT_INCREMENT,
            progress: bool = True) -> dict[str, FsPath]:
    """Run ``path_name`` (a standard path name or a path file) and write the files of the
    module doc into ``out_dir``; returns {what: file written}."""
    path = load_path(path_name)
    params = default_params() if params_file is None else load_params(params_file)
    if tier is not None:
        params = params.with_tier(tier)          # validates the tier and its sections
    if params.tier in COMPILE_TIME:
        announce_compiling(tiers.KERNELS[params.tier], f"the tier-{params.tier} model kernels",
                           COMPILE_TIME[params.tier])
    t0 = time.perf_counter()
    results = mp.run_family(path, params, increment=increment, progress=progress)
    seconds = time.perf_counter() - t0
    out_dir = FsPath(out_dir)
    written: dict[str, FsPath] = {}
    for k, res in enumerate(results):
        name = "history.csv" if len(results) == 1 else f"history_{k}.csv"
        written[FsPath(name).stem] = write_csv(out_dir / name, *res.rows())
    from contfab.plots import history_plot, response_plot
    tier = params.tier
    title = f"{path.name}: tier {tier}"
    history_plot(results, out_dir / "history.png", title)
    written["history_plot"] = out_dir / "history.png"
    if path.probes is not None:
        response_plot(results, out_dir / "response.png", title)
        written["response_plot"] = out_dir / "response.png"
    stats = [dict(res.stats) for res in results]
    increments = sum(s["increments"] for s in stats)
    sidecar = {
        "job": "material point",
        "path": path.to_dict(),
        "tier": tier,
        "params": params.to_dict(),
        "params_file": str(params_file or default_params_path()),
        "start": {"stress_P0": [-1.0, -1.0, 0.0], "state": dict(zip(
            tiers.STATE_NAMES[tier], mp.start_state(tier, params).tolist()))},
        "increments": {"increment": increment, "min_increment": stats[0]["min_increment"],
                       "taken": increments, "cuts": sum(s["cuts"] for s in stats),
                       "update_evaluations": sum(s["evaluations"] for s in stats),
                       "newton_iterations": sum(s["newton_iterations"] for s in stats),
                       "stops": [s["stops"] for s in stats]},
        "timing": {"total_s": seconds, "us_per_increment": 1e6 * seconds / max(increments, 1)},
        "versions": code_versions(),
        "files": {k: str(v) for k, v in written.items()},
    }
    written["sidecar"] = write_json(out_dir / "history.json", sidecar)
    return written


