"""The DEM campaign of a calibration: which runs, where their files go, running them
resumably through an executor (:mod:`contfab.executor`).

A campaign (:class:`CampaignSettings`) is a list of :class:`RunSpec` — a loading path on
a dense (μ_prep = 0) or loose (μ_prep = μ) sample at a stiffness number κ = kn/P0, with a
role: ``fit`` (the calibration fits it), ``heldout`` (validation: reported, and it chooses
the fabric law), ``reference`` (DEM curves for the tests, reported) — each run for every
seed, plus the stress-probing runs (seed 001 §3 in 2D): a loose sample loaded along the
biaxial path to ``probe_strain``, held at constant stress until its creep has stopped,
then probed by a family of load-unload stress probes with a zero-increment reference
(:class:`dem.paths.ProbeFamily`). In the rigid-grain limit the pressure enters only through
κ, so "two pressures" are two κ.

Layout under the campaign directory::

    paths/                      the campaign's own path files (preload, probes)
    dem/prepared/<density>_k<κ>_seed<s>.npz     prepared samples (one per density, κ, seed)
    dem/<path>_<density>_k<κ>/seed<s>/          one run (files of :func:`dem.job.run_job`)
    dem/.../job.json                            the job that made it

**Resume.** A job whose outputs are complete (``history.json`` written last) is reused; a
run with a ``checkpoint.npz`` continues from it (bitwise identical to an uninterrupted
run: :mod:`dem.checkpoint`); otherwise it starts from its prepared sample. An interrupted
campaign rerun therefore ends with the same files as an uninterrupted one. Each job writes
``job.json`` (its settings and path) first; a directory made by a *different* job is
refused (:class:`CampaignError`), never silently reused. A campaign directory may so be
extended (more runs, more seeds) but never mixed with runs of other settings.
``campaign.json`` records the settings of the last campaign run in it.

Phases (each a map over the executor, since a phase needs the previous one's files):
preparation, the runs (fit, held-out, probe preload), the probe families.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path as FsPath

from dem.fileio import atomic_path, write_json
from dem.job import Settings
from dem.paths import load_path

DENSITIES = ("dense", "loose")
ROLES = ("fit", "heldout", "reference")


class CampaignError(ValueError):
    """A campaign that cannot run as asked (bad settings, a directory of another campaign)."""


@dataclass(frozen=True)
class RunSpec:
    """One loading path on one kind of sample; run for every seed of the campaign."""

    path: str                 # a standard path name or a path file
    density: str              # "dense" (μ_prep = 0) or "loose" (μ_prep = μ)
    kappa: float              # stiffness number kn/P0
    role: str = "fit"         # "fit", "heldout" (validation), "reference" (curves only)

    @property
    def name(self) -> str:
        return f"{FsPath(self.path).stem}_{self.density}_k{self.kappa:g}"


def default_runs(kappas=(1e3, 1e4), kappa_heldout=3e3) -> tuple[RunSpec, ...]:
    """The default campaign (issue 4): dense and loose biaxial at every fitted κ, simple
    shear at constant normal stress with a reversal, isotropic compression (fitted); a
    biaxial at a κ not fitted, an isochoric shear and a 90° change of loading direction
    (held out), and the other standard paths (reference curves, not used to choose)."""
    k0 = kappas[0]
    runs = [RunSpec("biaxial", d, k) for k in kappas for d in DENSITIES]
    runs += [RunSpec("simple_shear_reversal", "loose", k0),
             RunSpec("isotropic_compression", "dense", k0)]
    runs += [RunSpec("biaxial", d, kappa_heldout, "heldout") for d in DENSITIES]
    runs += [RunSpec("isochoric_shear", "dense", k0, "heldout"),
             RunSpec("direction_change", "loose", k0, "heldout")]
    # the remaining standard paths, so every one has DEM reference curves
    runs += [RunSpec("proportional_strain", "loose", k0, "reference"),
             RunSpec("axes_rotation", "dense", k0, "reference"),
             RunSpec("stress_probes", "dense", k0, "reference")]
    return tuple(runs)


@dataclass(frozen=True)
class CampaignSettings:
    """Everything that defines a DEM campaign (DEM units: d = 1, ρ = 1, P0 = 1)."""

    n: int = 1000
    seeds: tuple[int, ...] = (1, 2, 3)
    runs: tuple[RunSpec, ...] = field(default_factory=default_runs)
    mu: float = 0.5
    inertial: float = 1e-3
    radii: str = "uniform:0.2"
    probe: bool = True
    probe_kappa: float = 1e3
    probe_strain: float = 0.01        # the loose sample is probed at this axial strain
    probe_hold: float = 0.02          # held at constant stress this long before probing
    probe_directions: int = 16
    probe_magnitude: float = 0.05     # |Δσ| in units of P0
    probe_length: float = 0.01        # τ of each load (and unload) ramp
    checkpoint_every: int = 10

    def validate(self) -> None:
        """Raise :class:`CampaignError` naming the first bad value and its accepted range."""
        if not self.seeds or len(set(self.seeds)) != len(self.seeds):
            raise CampaignError(f"seeds = {list(self.seeds)}: give one or more distinct seeds")
        if not self.runs:
            raise CampaignError("a campaign needs at least one run")
        for r in self.runs:
            if r.density not in DENSITIES:
                raise CampaignError(f"run {r.path}: density {r.density!r} is not one of {DENSITIES}")
            if r.role not in ROLES:
                raise CampaignError(f"run {r.path}: role {r.role!r} is not one of {ROLES}")
            if not (math.isfinite(r.kappa) and r.kappa > 0):
                raise CampaignError(f"run {r.path}: kappa = {r.kappa} out of range (0, inf)")
            load_path(r.path)                  # an unknown path is refused here
        if not any(r.role == "fit" for r in self.runs):
            raise CampaignError("a campaign needs at least one run with role 'fit'")
        for name in ("probe_strain", "probe_hold", "probe_magnitude", "probe_length",
                     "probe_kappa"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise CampaignError(f"{name} = {v} out of range; accepted (0, inf)")
        if self.probe_directions < 4:
            raise CampaignError(f"probe_directions = {self.probe_directions} out of range; "
                                f"accepted integers >= 4")
        for k in {r.kappa for r in self.runs}:
            self.dem_settings("dense", k, self.seeds[0]).validate()

    def dem_settings(self, density: str, kappa: float, seed: int) -> Settings:
        return Settings(n=self.n, seed=seed, radii=self.radii, kappa=kappa, mu=self.mu,
                        mu_prep=0.0 if density == "dense" else self.mu, inertial=self.inertial,
                        checkpoint_every=self.checkpoint_every)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["seeds"] = list(self.seeds)
        d["runs"] = [asdict(r) for r in self.runs]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "CampaignSettings":
        d = dict(d)
        d["seeds"] = tuple(d["seeds"])
        d["runs"] = tuple(RunSpec(**r) for r in d["runs"])
        return cls(**d)


# --------------------------------------------------------------------------- jobs

@dataclass(frozen=True)
class DemJob:
    """One DEM job: prepare a sample (``path`` None) or run a path from ``start``."""

    settings: Settings
    out: str                      # prepared-sample file, or run directory
    path: str | None = None
    start: str | None = None      # checkpoint to start from (a prepared sample or a run's end)

    def describe(self, base: FsPath) -> dict:
        """What the job is, with ``start`` relative to ``base`` (the folder of its record),
        so a campaign directory stays valid when it is moved or copied."""
        return {"settings": asdict(self.settings),
                "path": None if self.path is None else load_path(self.path).to_dict(),
                "start": _relative(self.start, base)}


def _relative(start: str | None, base: FsPath) -> str | None:
    if start is None:
        return None
    return os.path.relpath(os.path.abspath(start), os.path.abspath(base))


def _check_same_job(file: FsPath, job: DemJob) -> None:
    """Refuse a directory made by another job; record this job otherwise. (Records of
    before 2026-12-02 hold an absolute ``start``: compared as the file it names.)"""
    mine = json.loads(json.dumps(job.describe(file.parent)))
    if file.exists():
        theirs = json.loads(file.read_text())
        if theirs.get("start") and os.path.isabs(theirs["start"]):
            theirs["start"] = _relative(theirs["start"], file.parent)
        if theirs != mine:
            raise CampaignError(f"{file.parent} holds the results of a different job "
                                f"({file}); use a fresh campaign directory")
    else:
        write_json(file, mine)


def run_dem_job(job: DemJob) -> str:
    """Run one job resumably (module doc); returns its output (file or directory)."""
    from dem.job import prepare_job, run_job

    out = FsPath(job.out)
    if job.path is None:
        spec = out.with_suffix(".job.json")
        _check_same_job(spec, job)
        if not out.exists():
            prepare_job(job.settings, out, progress=False)
        return str(out)
    _check_same_job(out / "job.json", job)
    if (out / "history.json").exists():
        return str(out)
    ck = out / "checkpoint.npz"
    run_job(job.path, job.settings, out, resume=str(ck) if ck.exists() else job.start,
            progress=False)
    return str(out)


def warm_kernels() -> None:
    """Load (or compile) the DEM and model kernels once in this process (executor warm-up)."""
    import numpy as np

    from dem.integrator import advance, dynamics
    from dem.contact_law import ContactLaw
    from dem.measure import measure
    from dem.prepare import random_gas
    from contfab.material_point import run_path

    rng = np.random.default_rng(0)
    st = random_gas(np.full(8, 0.5), 0.3, rng)
    dyn = dynamics(ContactLaw(kn=1e3, mu=0.5), st.mass.min(), 1e-3)
    advance(st, dyn, 2)
    measure(st, dyn.law)
    for tier in (1, 2):
        run_path("biaxial", None, tier, increment=0.05)


# --------------------------------------------------------------------------- the campaign

def _write_text(file: FsPath, text: str) -> None:
    if file.exists() and file.read_text() == text:
        return
    if file.exists():
        raise CampaignError(f"{file} differs from this campaign's; use a fresh campaign directory")
    with atomic_path(file) as tmp:
        tmp.write_text(text)


@dataclass(frozen=True)
class Layout:
    """Where a campaign's files live (module doc)."""

    root: FsPath

    def prepared(self, density: str, kappa: float, seed: int) -> FsPath:
        return self.root / "dem" / "prepared" / f"{density}_k{kappa:g}_seed{seed}.npz"

    def run(self, name: str, seed: int) -> FsPath:
        return self.root / "dem" / name / f"seed{seed}"

    @property
    def preload_path(self) -> FsPath:
        return self.root / "paths" / "probe_preload.toml"

    @property
    def probes_path(self) -> FsPath:
        return self.root / "paths" / "probes.toml"

    PRELOAD = "probe_preload"
    PROBES = "probes"


def write_probe_paths(cs: CampaignSettings, layout: Layout) -> None:
    """The probe preload path (biaxial to ``probe_strain``, then held) and the probe family."""
    ramp = cs.probe_strain
    _write_text(layout.preload_path, f'''name = "probe_preload"
description = "Biaxial compression along y (sigma_xx = -P0) to eps_yy = -{ramp:g}, then the stress held for {cs.probe_hold:g} (creep stops): a state on the yield surface to probe."

[[stage]]
name = "compress"
length = {ramp!r}
output_every = {ramp / 10!r}
L = {{ yy = -1.0, xy = 0.0, yx = 0.0 }}
sigma = {{ xx = -1.0 }}
until = {{ eps_yy = -{ramp!r} }}

[[stage]]
name = "hold"
length = {cs.probe_hold!r}
output_every = {cs.probe_hold / 10!r}
L = {{ xy = 0.0 }}
sigma = {{ xx = -1.0, yy = {{ increment = 0.0 }}, yx = {{ increment = 0.0 }} }}
''')
    _write_text(layout.probes_path, f'''name = "probes"
description = "{cs.probe_directions} load-unload stress probes of {cs.probe_magnitude:g} P0 in the (sigma_xx, sigma_yy) plane and a zero-increment reference (seed 001 section 3, in 2D)."

[probes]
directions = {cs.probe_directions}
magnitude = {cs.probe_magnitude!r}
length = {cs.probe_length!r}
unload = true
hold = true
''')


def campaign_jobs(cs: CampaignSettings, root: str | FsPath) -> list[list[DemJob]]:
    """The jobs of each phase (module doc), in a fixed order."""
    layout = Layout(FsPath(root))
    kinds = {(r.density, r.kappa) for r in cs.runs}
    if cs.probe:
        kinds.add(("loose", cs.probe_kappa))
    prep, runs, probes = [], [], []
    for seed in cs.seeds:
        for density, kappa in sorted(kinds):
            prep.append(DemJob(cs.dem_settings(density, kappa, seed),
                               str(layout.prepared(density, kappa, seed))))
        for r in cs.runs:
            runs.append(DemJob(cs.dem_settings(r.density, r.kappa, seed),
                               str(layout.run(r.name, seed)), r.path,
                               str(layout.prepared(r.density, r.kappa, seed))))
        if cs.probe:
            pre = layout.run(f"{Layout.PRELOAD}_loose_k{cs.probe_kappa:g}", seed)
            s = cs.dem_settings("loose", cs.probe_kappa, seed)
            runs.append(DemJob(s, str(pre), str(layout.preload_path),
                               str(layout.prepared("loose", cs.probe_kappa, seed))))
            probes.append(DemJob(s, str(layout.run(f"{Layout.PROBES}_loose_k{cs.probe_kappa:g}",
                                                   seed)),
                                 str(layout.probes_path), str(pre / "checkpoint.npz")))
    return [prep, runs, probes]


def run_campaign(cs: CampaignSettings, root: str | FsPath, executor) -> Layout:
    """Run (or resume) every job of the campaign through ``executor``; returns the layout."""
    cs.validate()
    layout = Layout(FsPath(root))
    write_json(layout.root / "campaign.json", cs.to_dict())
    if cs.probe:
        write_probe_paths(cs, layout)
    for name, jobs in zip(("prepare", "runs", "probes"), campaign_jobs(cs, layout.root)):
        executor.map(run_dem_job, jobs, desc=f"DEM {name}")
    return layout
