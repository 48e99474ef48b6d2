"""Stability matrix of the DEM RVE (:mod:`dem`).

Validity range (declared where it is checked: :class:`dem.contact_law.ContactLaw`,
:func:`dem.integrator.time_step`, :func:`dem.particles.parse_radii`,
:func:`dem.neighbours` for the cell width): κ = kn/P0 > 0, μ in [0, inf], e in (0, 1],
diameters uniform in [1 - W, 1 + W] with 0 <= W < 1, I > 0, and a periodic cell at least
two neighbour cut-offs wide.

Each point prepares a small sample (:func:`dem.job.prepare_sample`) and runs a path on
it. Its accuracy is the energy balance error |W_ext - (E_el + E_kin + D)| / W_ext, the
conservation law the integrator's books close on; a run also checks that no disc is lost
(every position finite, count unchanged), the cell is not collapsed (both widths above
two cut-offs) and the fabric stays admissible, else its accuracy is NaN. The
preparation points measure instead the relaxed pressure against its target P0 = 1.
Every sample is checked for crystallization (monodisperse discs order) with the
bond-orientational order ψ6 = |mean over contacts of exp(6iθ)| (1 for a single triangular
crystal, ~1/sqrt(Nc) for a random network); ψ6 > CRYSTAL_PSI6 is reported as
CRYSTALLIZED in the note, not judged.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from contfab.stability.core import Measured, Point
from dem.job import Settings, prepare_sample
from dem.measure import Contacts
from dem.paths import parse_path
from dem.periodic_cell import widths
from dem.rve import PathRunner

ENERGY_TOL = 1e-2
"""Energy balance error, relative to the external work (measured: 1e-4–3e-3 at N ~ 100)."""
CRYSTAL_PSI6 = 0.5
"""ψ6 above this: the sample has crystallized (reported in the note)."""
N_SMALL = 64


def hexatic_order(state) -> float:
    """ψ6 = |(1/Nc) Σ_contacts exp(6iθ_c)|, the bond-orientational order of the contact
    network (module doc); θ_c is the contact normal's angle (θ and θ + π give the same)."""
    c = Contacts(state)
    if c.count == 0:
        return 0.0
    return float(abs(np.mean(np.exp(6j * np.arctan2(c.n[:, 1], c.n[:, 0])))))


def shear_path(gamma: float, output: float):
    return parse_path({"name": "stability_shear", "stage": [{
        "length": gamma, "output_every": output, "L": {"xx": 0.0, "xy": 1.0, "yx": 0.0},
        "sigma": {"yy": -1.0}}]})


def stretch_path(strain: float, output: float):
    """Pure shear: x stretched at unit rate, σyy = -P0: the cell's aspect ratio ~ exp(2ε)."""
    return parse_path({"name": "stability_stretch", "stage": [{
        "length": strain, "output_every": output, "L": {"xx": 1.0, "xy": 0.0, "yx": 0.0},
        "sigma": {"yy": -1.0}}]})


def run_shear(settings: Settings, path, progress=None) -> tuple[Measured, dict]:
    """Prepare, run ``path``, check the invariants of the module doc."""
    state, dyn, info = prepare_sample(settings, progress=False)
    n0 = state.n
    runner = PathRunner(path, dyn, dyn.gdot_ref)
    run = runner.run(state, runner.start(state), on_row=progress)
    rows = run.rows
    last = rows[-1]
    cut = 2.0 * (2.0 * float(state.radius.max()) + dyn.skin)
    w = min(widths(state.h))
    margin = min(r["admissibility"] for r in rows)
    err = abs(last["energy_error"]) / max(abs(last["W_external"]), 1e-300)
    lost = state.n != n0 or not np.all(np.isfinite(state.s))
    psi6 = hexatic_order(state)
    h = state.h
    aspect = max(np.hypot(*h[:, 0]), np.hypot(*h[:, 1])) / w
    facts = dict(energy_error=err, admissibility=margin, width=w, aspect=aspect, psi6=psi6,
                 gamma=last["gamma"], c=last["c"], z=last["z"], RP=last["RP"], prep_steps=info.steps,
                 steps=int(state.step))
    note = (f"energy error {err:.2g} of W_ext; min fabric margin {margin:.3g}; cell width "
            f"{w:.3g} (cut-off x2 {cut:.3g}), aspect {aspect:.3g}; gamma {last['gamma']:.3g}, "
            f"c {last['c']:.4f}, z {last['z']:.3g}, R/P {last['RP']:.3g}; psi6 {psi6:.2f}"
            + (" CRYSTALLIZED" if psi6 > CRYSTAL_PSI6 else ""))
    bad = lost or margin < 0 or w < cut or not all(
        math.isfinite(r[k]) for r in rows for k in ("sxx", "syy", "sxy", "energy_error"))
    if bad:
        return Measured(math.nan, ENERGY_TOL, "energy balance", "invariant broken: " + note), facts
    return Measured(err, ENERGY_TOL, "energy balance W_ext = E_el + E_kin + D", note), facts


def run_prepare(settings: Settings) -> Measured:
    """The relaxed preparation: |P - P0| against the servo target, c reported."""
    state, dyn, info = prepare_sample(settings, progress=False)
    psi6 = hexatic_order(state)
    note = (f"c = {info.c:.4f}, relaxed {info.relaxed}, unbalanced {info.unbalanced:.2g}, "
            f"{info.steps} steps; psi6 {psi6:.2f}")
    if not (info.relaxed and math.isfinite(info.P)):
        return Measured(math.nan, 1e-3, "relaxation", "not relaxed: " + note)
    return Measured(abs(info.P - 1.0), 1e-3, "servo target P0 = 1 (relaxed)", note)


def points() -> list[Point]:
    base = Settings(n=N_SMALL, seed=3, kappa=1e3, mu=0.5, inertial=1e-2, checkpoint_every=0)
    short = shear_path(0.2, 0.05)
    pts: list[Point] = []

    def add(axis, value, settings=None, path=short, budget=240.0, full=False, fn=None):
        s = base if settings is None else settings
        run = fn if fn is not None else (lambda s=s, path=path: run_shear(s, path)[0])
        pts.append(Point("dem", axis, str(value), run, budget, full))

    for mu in (0.0, 10.0, 1e3, math.inf):
        add("mu", mu, replace(base, mu=mu), full=mu in (1e3, math.inf))
    add("mu", -0.1, replace(base, mu=-0.1))
    for kappa in (1e1, 1e3, 1e5, 1e7):
        add("kappa", f"{kappa:g}", replace(base, kappa=kappa, prep_rate=0.1 if kappa > 1e4 else 1e-2),
            full=kappa > 1e4, budget=1800.0 if kappa > 1e4 else 240.0)
    add("kappa", "0", replace(base, kappa=0.0))
    for inertial, gamma in ((1e-5, 0.002), (1e-3, 0.05), (1e-1, 0.2)):
        add("I", f"{inertial:g}", replace(base, inertial=inertial), shear_path(gamma, gamma / 4),
            full=inertial < 1e-1, budget=1200.0)
    add("e", "1", replace(base, e=1.0), full=True, budget=900.0)   # slow to relax: only friction dissipates
    # e -> 0 lowers the stable time step (dem.integrator.stable_fraction): 0.015 at e = 1e-3,
    # so the default dt fraction 0.1 is refused (a clear error) and e ~ 0 runs at 0.01
    add("e", "0.001 (dt fraction 0.1)", replace(base, e=1e-3))
    # a FAIL until the servo's proportional term left out the dashpot stress (dem.servo)
    add("e", "0.001 (dt fraction 0.01)", replace(base, e=1e-3, dt_fraction=0.01))
    for e, f in ((0.3, 0.1), (0.1, 0.02), (0.01, 0.01), (1e-3, 0.006)):
        add("e", f"{e:g} (dt fraction {f:g})", replace(base, e=e, dt_fraction=f), full=True)
    add("e", "0", replace(base, e=0.0))
    for w in (0.0, 0.2, 0.5, 0.8):           # wide discs need a sparser gas to be placed
        add("polydispersity W", w, replace(base, radii=f"uniform:{w}", c_gas=0.2),
            full=w in (0.2, 0.5))
    add("polydispersity W", 1.0, replace(base, radii="uniform:1.0"))
    add("packing", "dense (mu_prep 0)", fn=lambda: run_prepare(replace(base, mu_prep=0.0)))
    add("packing", "loose (mu_prep 10)", fn=lambda: run_prepare(replace(base, mu_prep=10.0)))
    for gamma in (2.0, 10.0):
        add("simple shear gamma", gamma, path=shear_path(gamma, 0.1), budget=1800.0,
            full=gamma > 2)
    for strain in (0.7, 3.0):                 # aspect ~ exp(2ε): 4 and 400
        add("cell aspect (pure shear)", f"{math.exp(2 * strain):.0f}",
            path=stretch_path(strain, 0.05), full=False)
    return pts
