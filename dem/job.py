"""The DEM jobs behind ``contfab dem prepare`` and ``contfab dem run``.

``prepare_job``: a random gas of N discs compressed to P0 with μ_prep and relaxed
(:mod:`dem.prepare`), friction then switched to μ; written as one checkpoint file.

``run_job``: a loading path on a sample (prepared here, or read from a checkpoint:
a prepared sample, which may be reused for many paths, or a mid-run checkpoint, which
resumes bitwise). Writes into the output directory

    history.csv        one row per output step (:data:`dem.rve.COLUMNS`)
    history.json       settings, path, versions, timing, preparation figures
    checkpoint.npz     the latest checkpoint (every ``checkpoint_every`` rows and at the end)
    prepared.npz       the prepared sample (when prepared here)
    history.png, normals.png

For a probe family each probe runs on its own copy of the start state and writes
``history_<k>.csv``. All settings are validated before anything is written, and every
file is written atomically, so an error leaves no partial file.
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path as FsPath

import numpy as np

from dem import checkpoint
from dem.contact_law import ContactLaw
from dem.fileio import write_csv, write_json
from dem.integrator import DT_FRACTION, dynamics
from dem.servo import L_MAX_FACTOR
from dem.particles import parse_radii, sample_radii
from dem.paths import load_path
from dem.provenance import code_versions
from dem.prepare import compress_to_pressure, random_gas, switch_friction
from dem.rve import PathRunner, history_table


@dataclass(frozen=True)
class Settings:
    """Everything a DEM user sets (units: d = 1, ρ = 1, P0 = 1; κ = kn/P0)."""

    n: int = 1000
    seed: int = 0
    radii: str = "uniform:0.2"
    kappa: float = 1e4
    mu: float = 0.5
    mu_prep: float | None = None        # None: same as mu (a loose sample)
    inertial: float = 1e-3
    e: float = 0.5
    kt_ratio: float = 0.5
    mu_roll: float = 0.0
    dt_fraction: float = DT_FRACTION
    skin: float = 0.2
    prep_rate: float = 1e-2
    c_gas: float = 0.3
    checkpoint_every: int = 10

    def law(self, mu: float | None = None) -> ContactLaw:
        return ContactLaw(kn=self.kappa, kt_ratio=self.kt_ratio, e=self.e,
                          mu=self.mu if mu is None else mu, mu_roll=self.mu_roll)

    def validate(self) -> None:
        """Raise ValueError naming the first bad value and its accepted range."""
        if not (isinstance(self.n, int) and self.n >= 2):
            raise ValueError(f"number of discs n = {self.n} out of range; accepted n >= 2")
        parse_radii(self.radii)
        self.law()
        if self.mu_prep is not None:
            self.law(self.mu_prep)
        for name, v in (("prep_rate", self.prep_rate), ("inertial", self.inertial)):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} = {v} out of range; accepted (0, inf)")
        if not (0 < self.c_gas < 0.5):
            raise ValueError(f"c_gas = {self.c_gas} out of range; accepted (0, 0.5)")
        if not (isinstance(self.checkpoint_every, int) and self.checkpoint_every >= 0):
            raise ValueError(f"checkpoint_every = {self.checkpoint_every} out of range; accepted "
                             f"integers >= 0 (0: only at the end)")
        # the time step is checked against the stability limit (any mass: dt scales with it)
        dynamics(self.law(), 1.0, self.inertial, self.dt_fraction, self.skin)


def prepare_sample(settings: Settings, progress: bool = True):
    """(state, dynamics for the test, preparation info) per the module doc."""
    settings.validate()
    rng = np.random.default_rng(settings.seed)
    radius = sample_radii(parse_radii(settings.radii), settings.n, rng)
    state = random_gas(radius, settings.c_gas, rng)
    mu_prep = settings.mu if settings.mu_prep is None else settings.mu_prep
    dyn_prep = dynamics(settings.law(mu_prep), state.mass.min(), settings.prep_rate,
                        settings.dt_fraction, settings.skin, l_max=settings.prep_rate)
    bar = _bar(progress, None, "prepare (steps)")
    state, info = compress_to_pressure(state, dyn_prep, progress=_prep_progress(bar))
    if bar is not None:
        bar.close()
    dyn = replace(switch_friction(dyn_prep, settings.mu), **_rates(settings))
    return state, dyn, info


def _rates(settings: Settings) -> dict:
    """γ̇_ref = I (DEM units) and the servo's rate cap for the test."""
    return {"gdot_ref": settings.inertial, "l_max": L_MAX_FACTOR * settings.inertial}


def prepare_job(settings: Settings, out: str | FsPath, progress: bool = True) -> FsPath:
    """Prepare a sample and write it as one checkpoint file; returns its path."""
    t0 = time.perf_counter()
    state, dyn, info = prepare_sample(settings, progress)
    meta = {"job": "prepare", "settings": asdict(settings), "preparation": info.to_dict(),
            "seconds": time.perf_counter() - t0}
    out = FsPath(out)
    checkpoint.save(out, state, dyn, None, meta)
    return out


def run_job(path_name: str, settings: Settings, out_dir: str | FsPath, resume: str | None = None,
            progress: bool = True) -> dict:
    """Run ``path_name`` (see the module doc); returns {what: file written}."""
    settings.validate()
    path = load_path(path_name)
    out_dir = FsPath(out_dir)
    t0 = time.perf_counter()
    written = {}
    if resume is not None:
        state, dyn, run, meta = checkpoint.load(resume)
        prep = meta.get("preparation")
        if run is None:                      # a prepared sample: start the path on it
            dyn = replace(dyn, **_rates(settings))
    else:
        state, dyn, info = prepare_sample(settings, progress)
        prep, run = info.to_dict(), None
        written["prepared"] = checkpoint.save(out_dir / "prepared.npz", state, dyn, None,
                                              {"job": "prepare", "settings": asdict(settings),
                                               "preparation": prep})
    t_prep = time.perf_counter() - t0
    meta = {"settings": asdict(settings), "path": path.to_dict(), "preparation": prep,
            "resumed_from": resume}
    runs = path.expand()
    histories = []
    for k, sub in enumerate(runs):
        st = state.copy() if len(runs) > 1 else state
        runner = PathRunner(sub, dyn, dyn.gdot_ref)
        this_run = run if (run is not None and len(runs) == 1) else runner.start(st)
        ck = out_dir / ("checkpoint.npz" if len(runs) == 1 else f"checkpoint_{k}.npz")
        total = sum(s.length for s in sub.stages)
        bar = _bar(progress, total, f"{sub.name} (τ)")
        done = [this_run.rows[-1]["tau"] - this_run.rows[0]["tau"]]

        def on_row(r, s, bar=bar, ck=ck, done=done):
            if bar is not None:
                now = min(r.rows[-1]["tau"] - r.rows[0]["tau"], bar.total)
                bar.update(now - done[0])
                done[0] = now
            if settings.checkpoint_every and len(r.rows) % settings.checkpoint_every == 0:
                checkpoint.save(ck, s, dyn, r, meta)

        runner.run(st, this_run, on_row=on_row)
        if bar is not None:
            bar.close()
        written[ck.stem] = checkpoint.save(ck, st, dyn, this_run, meta)
        name = "history.csv" if len(runs) == 1 else f"history_{k}.csv"
        cols, table = history_table(this_run.rows)
        written[FsPath(name).stem] = write_csv(out_dir / name, cols, table)
        histories.append((sub, st, this_run))
    from dem.plots import history_plot, polar_plot
    sub, st, last = histories[0]
    history_plot(last.rows, out_dir / "history.png", sub.name)
    written["history_plot"] = out_dir / "history.png"
    polar_plot(st, out_dir / "normals.png", f"{sub.name}: contact normals at the end")
    written["normals_plot"] = out_dir / "normals.png"
    meta.update(dynamics=checkpoint.dynamics_dict(dyn), versions=code_versions(),
                timing={"prepare_s": t_prep, "total_s": time.perf_counter() - t0,
                        "steps": int(st.step)},
                files={k: str(v) for k, v in written.items()})
    written["sidecar"] = write_json(out_dir / "history.json", meta)
    return written




def _bar(enabled: bool, total, desc: str):
    if not enabled:
        return None
    from tqdm import tqdm
    return tqdm(total=total, desc=desc, unit="" if total is None else "τ", mininterval=1.0,
                bar_format=None if total is None else "{l_bar}{bar}| {n:.3g}/{total:.3g} [{elapsed}<{remaining}]")


def _prep_progress(bar):
    if bar is None:
        return None
    last = [0]

    def update(info):
        bar.update(info.steps - last[0])
        last[0] = info.steps
        bar.set_postfix(c=f"{info.c:.4f}", P=f"{info.P:.3f}", f_unb=f"{info.unbalanced:.1e}")
    return update
