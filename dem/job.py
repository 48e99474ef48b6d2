"""The DEM jobs behind ``contfab dem prepare`` and ``contfab dem run``.

``prepare_job``: a random gas of N discs compressed to P0 with μ_prep and relaxed
(:mod:`dem.prepare`), friction then switched to μ; written as one checkpoint file. The
preparation runs the default contact-law style whatever ``contact_style`` is (the style
is the loading path's), so a seed gives one sample for every style.

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

Records say what ran. A resumed run runs with the checkpoint's settings
(:func:`resumed_settings`): a setting given explicitly that differs from the checkpoint's
is refused, naming both values, except those a resumed run may change
(:data:`RESUME_FREE`); ``history.json`` records the settings that ran and where they came
from (``settings_source``). A preparation that hits its step limit unrelaxed is an error
unless ``allow_unrelaxed`` is set; then it runs with a warning, recorded in the sidecars'
``warnings``.
"""
from __future__ import annotations

import json
import math
import time
import warnings
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path as FsPath

import numpy as np

from dem import checkpoint
from dem.contact_law import STYLES, ContactLaw
from dem.fileio import write_csv, write_json
from dem.integrator import DT_FRACTION, Dynamics, dynamics, time_step
from dem.servo import L_MAX_FACTOR
from dem.particles import parse_radii, sample_radii
from dem.paths import load_path
from dem.provenance import code_versions
from dem.prepare import (CHECK_EVERY, E_SWITCH, QUENCH_EVERY, PreparationError, compress_to_pressure,
                         lower_friction, random_gas, switch_friction)
from dem.rve import PathRunner, history_table


LOOSE = {"mu_prep": 10.0, "prep_rate": 1e-3}
"""The loosest preparation measured (docs/dem_validation.md, "Packing fraction"): a slow
compression with a high friction, lowered to the test friction at P0 in a quenched collapse
(``prep_quench``, dem.prepare); c0 0.7967–0.8063 at N = 1000, κ = 1e3 (seeds 1–6), 0.0049–
0.0145 below the critical packing fraction. ``target_c0`` bounds every sample's c0."""

PACKING_MAX = math.pi / (2.0 * math.sqrt(3.0))
"""The densest packing of equal discs (hexagonal), the bound of any target c0."""


@dataclass(frozen=True)
class Settings:
    """Everything a DEM user sets (units: d = 1, ρ = 1, P0 = 1; κ = kn/P0)."""

    n: int = 1000
    seed: int = 0
    radii: str = "uniform:0.2"
    kappa: float = 1e4
    mu: float = 0.5
    mu_prep: float | None = None        # None: same as mu; the packing knob (dem.prepare)
    inertial: float = 1e-3
    e: float = 0.5
    kt_ratio: float = 0.5
    mu_roll: float = 0.0
    contact_style: str = STYLES[0]
    dt_fraction: float = DT_FRACTION
    skin: float = 0.2
    prep_rate: float = 1e-2
    prep_quench: int = QUENCH_EVERY     # velocity resets of the friction drop (dem.prepare)
    c_gas: float = 0.3
    checkpoint_every: int = 10
    prep_max_steps: int = 2_000_000
    allow_unrelaxed: bool = False
    target_c0: float | None = None      # None: the seed's first realization, whatever its c0
    target_tries: int = 8

    def law(self, mu: float | None = None) -> ContactLaw:
        return ContactLaw(kn=self.kappa, kt_ratio=self.kt_ratio, e=self.e,
                          mu=self.mu if mu is None else mu, mu_roll=self.mu_roll,
                          style=self.contact_style)

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
        if not (isinstance(self.prep_max_steps, int) and self.prep_max_steps >= CHECK_EVERY):
            raise ValueError(f"prep_max_steps = {self.prep_max_steps} out of range; accepted "
                             f"integers >= {CHECK_EVERY}")
        if not (isinstance(self.prep_quench, int) and self.prep_quench >= 0
                and (self.prep_quench == 0 or CHECK_EVERY % self.prep_quench == 0)):
            raise ValueError(f"prep_quench = {self.prep_quench} out of range; accepted 0 (the "
                             f"friction drop runs with inertia) or a divisor of {CHECK_EVERY}")
        if self.target_c0 is not None and not 0.0 < self.target_c0 < PACKING_MAX:
            raise ValueError(f"target_c0 = {self.target_c0} out of range; accepted "
                             f"(0, {PACKING_MAX:.4f}) (the hexagonal packing)")
        if not (isinstance(self.target_tries, int) and self.target_tries >= 1):
            raise ValueError(f"target_tries = {self.target_tries} out of range; accepted "
                             "integers >= 1")
        if not (isinstance(self.checkpoint_every, int) and self.checkpoint_every >= 0):
            raise ValueError(f"checkpoint_every = {self.checkpoint_every} out of range; accepted "
                             f"integers >= 0 (0: only at the end)")
        # the time step is checked against the stability limit (any mass: dt scales with it),
        # also for the damped contacts that relax a friction drop (dem.prepare.lower_friction)
        dynamics(self.law(), 1.0, self.inertial, self.dt_fraction, self.skin)
        if self.mu_prep is not None and self.mu_prep > self.mu:
            dynamics(replace(_prep_law(self), e=E_SWITCH), 1.0, self.inertial, self.dt_fraction,
                     self.skin)


def prepare_sample(settings: Settings, progress: bool = True):
    """(state, dynamics for the test, preparation info) per the module doc.

    With ``target_c0`` the seed's realizations k = 0, 1, ... (random streams
    ``default_rng(seed)`` for k = 0, ``default_rng([seed, k])`` after it) are prepared in
    turn until one ends at c0 <= target_c0 (``info.realization`` = k); none within
    ``target_tries`` is a :class:`~dem.prepare.PreparationError` naming the loosest c0
    reached. Each realization is the same protocol on another random gas, so the accepted
    sample is reproducible per seed; the target selects among the protocol's outcomes
    (their seed-to-seed scatter, docs/dem_validation.md section 9), it does not change how
    a sample is made.
    """
    settings.validate()
    loosest = math.inf
    for k in range(settings.target_tries if settings.target_c0 is not None else 1):
        rng = np.random.default_rng(settings.seed if k == 0 else [settings.seed, k])
        state, dyn, info = _prepare_realization(settings, rng, progress)
        info.realization = k
        if settings.target_c0 is None or info.c <= settings.target_c0:
            return state, dyn, info
        loosest = min(loosest, info.c)
    raise PreparationError(f"no realization of seed {settings.seed} reached c0 <= target_c0 = "
                           f"{settings.target_c0} in target_tries = {settings.target_tries} "
                           f"(loosest c0 {loosest:.4f}); accepted: a target_c0 >= {loosest:.4f}, "
                           "more target_tries, or a looser protocol (mu_prep, prep_rate, "
                           "prep_quench)")


def _prepare_realization(settings: Settings, rng: np.random.Generator, progress: bool):
    """One realization of the preparation protocol from the random stream ``rng``."""
    radius = sample_radii(parse_radii(settings.radii), settings.n, rng)
    state = random_gas(radius, settings.c_gas, rng)
    mu_prep = settings.mu if settings.mu_prep is None else settings.mu_prep
    dyn_prep = dynamics(_prep_law(settings, mu_prep), state.mass.min(), settings.prep_rate,
                        settings.dt_fraction, settings.skin, l_max=settings.prep_rate)
    bar = _bar(progress, None, "prepare (steps)")
    state, info = compress_to_pressure(state, dyn_prep, max_steps=settings.prep_max_steps,
                                       progress=_prep_progress(bar))
    if mu_prep > settings.mu and info.relaxed:
        state, info = lower_friction(state, dyn_prep, _prep_law(settings), info,
                                     max_steps=settings.prep_max_steps,
                                     progress=_prep_progress(bar),
                                     quench_every=settings.prep_quench)
    if bar is not None:
        bar.close()
    if not info.relaxed:
        what = (f"the preparation did not relax within prep_max_steps = "
                f"{settings.prep_max_steps} steps (P = {info.P:.4g}, unbalanced force ratio "
                f"{info.unbalanced:.3g}, kinetic/elastic {info.kinetic_ratio:.3g}; see "
                f"dem.prepare for the thresholds)")
        if not settings.allow_unrelaxed:
            raise PreparationError(f"{what}; accepted: a relaxed sample (raise "
                                   f"--prep-max-steps), or --allow-unrelaxed to use it anyway")
        warnings.warn(f"UNRELAXED SAMPLE used (allow_unrelaxed): {what}", UnrelaxedWarning,
                      stacklevel=2)
    dyn = loading_dynamics(switch_friction(dyn_prep, settings.mu), state,
                           settings.contact_style, settings.inertial)
    return state, dyn, info


def _prep_law(settings: Settings, mu: float | None = None) -> ContactLaw:
    """The preparation's contact law: the settings' with the default style, whatever the
    test's, so that one seed gives the same sample for every style."""
    return replace(settings.law(mu), style=STYLES[0])


def loading_dynamics(dyn: Dynamics, state, style: str, inertial: float) -> Dynamics:
    """``dyn`` with the contact-law ``style`` and the rates of inertial number ``inertial``
    for the loading path; its time step checked against the style's stability limit."""
    out = replace(dyn, law=replace(dyn.law, style=style), **_rates(inertial))
    m_min = float(state.mass.min())
    time_step(out.law, m_min, out.dt / math.sqrt(m_min / out.law.kn),
              float(state.mass.max() / state.mass.mean()))
    return out


class UnrelaxedWarning(UserWarning):
    """A sample used although its preparation hit the step limit unrelaxed."""


UNRELAXED = "UNRELAXED PREPARATION"
"""How the warning of a sample that missed the relaxation thresholds starts: only it stops
a run on the sample (unless ``allow_unrelaxed``)."""


def preparation_warnings(prep: dict | None) -> list[str]:
    """The sidecar's ``warnings`` for a preparation record (empty when it relaxed and its
    quenched collapse, if any, met its thresholds; a quench stopped at its share of the
    budget is said, but the sample relaxed under the test law and may be used)."""
    if prep is None:
        return []
    out = []
    if prep.get("quench_relaxed") is False:
        cq = prep.get("c_quenched")
        where = "it did not run" if cq is None else f"c = {cq:.4f} there"
        out.append(f"QUENCH STOPPED UNRELAXED: the quenched collapse used its share of the "
                   f"step budget without meeting its thresholds ({where}); "
                   f"the test law's relaxation then ended at c0 = {prep['c']:.4f}, which may be "
                   f"denser than the quench's")
    if not prep.get("relaxed", True):
        out.append(f"{UNRELAXED}: the sample did not meet the relaxation thresholds "
                   f"(stopped after {prep['steps']} steps at P = {prep['P']:.4g}, unbalanced "
                   f"force ratio {prep['unbalanced']:.3g}, kinetic/elastic "
                   f"{prep['kinetic_ratio']:.3g})")
    return out


def _rates(inertial: float) -> dict:
    """γ̇_ref = I (DEM units) and the servo's rate cap for the test."""
    return {"gdot_ref": inertial, "l_max": L_MAX_FACTOR * inertial}


def prepare_job(settings: Settings, out: str | FsPath, progress: bool = True) -> FsPath:
    """Prepare a sample and write it as one checkpoint file; returns its path."""
    t0 = time.perf_counter()
    state, dyn, info = prepare_sample(settings, progress)
    meta = {"job": "prepare", "settings": asdict(settings), "preparation": info.to_dict(),
            "warnings": preparation_warnings(info.to_dict()), "seconds": time.perf_counter() - t0}
    out = FsPath(out)
    checkpoint.save(out, state, dyn, None, meta)
    return out


RESUME_FREE = {"checkpoint_every": "any", "allow_unrelaxed": "any", "inertial": "prepared",
               "contact_style": "prepared"}
"""Settings a resumed run may change: on any checkpoint ("any"), or only on a prepared
sample, where the loading path has not started ("prepared")."""


def flag(name: str) -> str:
    """The command-line flag of a setting."""
    return "--" + name.replace("_", "-")


def _same(a, b) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        return a is not None and b is not None and math.isclose(a, b, rel_tol=1e-9, abs_tol=0.0)
    return a == b


def resumed_settings(file, saved: dict, state, dyn, mid_run: bool, given: dict) -> dict:
    """The settings a run resumed from checkpoint ``file`` runs with.

    They are the checkpoint's: its recorded settings (``saved``; None where it records
    none), with the contact law, n, dt, skin and rate read from the state and dynamics it
    holds. ``given``: settings set explicitly. Those in :data:`RESUME_FREE` replace the
    checkpoint's; any other that differs from the checkpoint's value (or that the
    checkpoint does not record) is refused with a ValueError naming the flag and both
    values.
    """
    law = dyn.law
    ran = {f.name: saved.get(f.name) for f in fields(Settings)}
    if "mu" in saved and ran["mu_prep"] is None:
        ran["mu_prep"] = saved["mu"]
    ran.update(n=state.n, kappa=law.kn, mu=law.mu, e=law.e, kt_ratio=law.kt_ratio,
               mu_roll=law.mu_roll, contact_style=law.style, skin=dyn.skin,
               inertial=dyn.gdot_ref)
    ran["allow_unrelaxed"] = False          # an opt-in of this run, not the checkpoint's
    if ran["dt_fraction"] is None:
        ran["dt_fraction"] = dyn.dt / math.sqrt(float(state.mass.min()) / law.kn)
    for name, value in given.items():
        if name == "mu_prep" and value is None:
            continue
        free = RESUME_FREE.get(name)
        if free == "any" or (free == "prepared" and not mid_run):
            ran[name] = value
        elif not _same(value, ran[name]):
            have = "does not record it" if ran[name] is None else f"has {name} = {ran[name]!r}"
            raise ValueError(f"--resume {file}: {flag(name)} {value!r} conflicts with the "
                             f"checkpoint, which {have}; accepted: omit {flag(name)} (a resumed "
                             f"run uses the checkpoint's settings) or give its value")
    return ran


def _given(settings: Settings) -> dict:
    """The settings that differ from the defaults (what an API caller set)."""
    return {k: v for k, v in asdict(settings).items() if not _same(v, getattr(Settings(), k))}


def run_job(path_name: str, settings: Settings, out_dir: str | FsPath, resume: str | None = None,
            progress: bool = True, given: dict | None = None) -> dict:
    """Run ``path_name`` (see the module doc); returns {what: file written}.

    ``given``: the settings set explicitly (by default those that differ from the
    defaults); on ``resume`` they are checked against the checkpoint's
    (:func:`resumed_settings`).
    """
    settings.validate()
    path = load_path(path_name)
    out_dir = FsPath(out_dir)
    t0 = time.perf_counter()
    written = {}
    if resume is not None:
        state, dyn, run, saved = checkpoint.load(resume)
        prep = saved.get("preparation")
        continues = run is not None and len(path.expand()) == 1
        if continues and saved.get("path") not in (None, json.loads(json.dumps(path.to_dict()))):
            raise ValueError(f"--resume {resume}: path {path.name!r} differs from the "
                             f"checkpoint's path {saved['path'].get('name')!r}; accepted: the "
                             f"checkpoint's path (a mid-run checkpoint continues its own path; "
                             f"a probe family starts afresh on its state)")
        ran = resumed_settings(resume, saved.get("settings", {}), state, dyn, run is not None,
                               _given(settings) if given is None else given)
        for w in preparation_warnings(prep):
            if w.startswith(UNRELAXED) and not ran["allow_unrelaxed"]:
                raise PreparationError(f"--resume {resume}: {w}; accepted: a relaxed sample, "
                                       f"or --allow-unrelaxed to use it anyway")
            warnings.warn(f"--resume {resume}: {w}", UnrelaxedWarning, stacklevel=2)
        if run is None:                      # a prepared sample: start the path on it
            dyn = loading_dynamics(dyn, state, ran["contact_style"], ran["inertial"])
        source = f"checkpoint {resume}"
    else:
        state, dyn, info = prepare_sample(settings, progress)
        prep, run, ran, source = info.to_dict(), None, asdict(settings), "given"
        written["prepared"] = checkpoint.save(out_dir / "prepared.npz", state, dyn, None,
                                              {"job": "prepare", "settings": ran,
                                               "preparation": prep,
                                               "warnings": preparation_warnings(prep)})
    t_prep = time.perf_counter() - t0
    checkpoint_every = ran["checkpoint_every"]
    meta = {"settings": ran, "settings_source": source, "path": path.to_dict(),
            "preparation": prep, "warnings": preparation_warnings(prep), "resumed_from": resume}
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
            if checkpoint_every and len(r.rows) % checkpoint_every == 0:
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
        if info.steps < last[0]:             # a new preparation stage counts from 0
            last[0] = 0
        bar.update(info.steps - last[0])
        last[0] = info.steps
        bar.set_postfix(c=f"{info.c:.4f}", P=f"{info.P:.3f}", f_unb=f"{info.unbalanced:.1e}")
    return update
