"""``contfab verify lammps``: the DEM and LAMMPS on the same samples and loading path.

For each seed and kind (dense, loose) one sample is prepared by the DEM
(:func:`dem.job.prepare_sample`: diameters uniform in [0.8, 1.2], μ = 0.5, kt/kn = 0.5,
e = 0.55, κ as given; dense: μ_prep = 0, loose: :data:`dem.job.LOOSE`); its tangential histories are set to zero, and the same state
(positions, velocities, spins, cell) is loaded into both engines
(:mod:`contfab.verify.lammps_engine`). Both then compress it biaxially along y at the
strain rate γ̇ = I (true strain rate) with σxx held at -P0 (the DEM by its servo, LAMMPS
by its barostat), to the axial strain ``strain``. Both are measured at the same
steps by the same code (:func:`contfab.verify.contacts.contact_measures`: contact
stress, R/P, c, z, z*, B/A, sliding fraction).

Summary per run: the peak R/P and its axial strain, and the means over the residual
window (-ε_yy in RESIDUAL_WINDOW, or the last 40 % of a shorter run) of R/P, c, ε_v, z,
z*, B/A and the sliding fraction. Per engine and kind: the seed mean and standard
deviation; per kind the difference of the engines and two standard errors of it,
2 sqrt(sd_dem²/k + sd_lammps²/k) over k seeds.

Files (in ``out``): ``curves.csv`` (every measured row), ``summary.csv`` (one row per
run), ``table.json`` (the seed statistics), ``overlay.png`` (curves of both engines).
"""
from __future__ import annotations

import math
from pathlib import Path as FsPath

import numpy as np

from contfab.verify.contacts import MEASURES, contact_measures
from contfab.verify.lammps_engine import LammpsBiaxial
from dem.fileio import atomic_path, write_csv, write_json
from dem.measure import Contacts

RESIDUAL_WINDOW = (0.20, 0.30)
SUMMARY = ("peak_RP", "peak_strain", "RP", "c", "eps_v", "z", "z_no_rattlers", "BA",
           "sliding_fraction", "sliding_strict")
CURVE_COLUMNS = ("engine", "kind", "seed", "step", "eps_xx", "eps_yy", "eps_v") + MEASURES


def biaxial_path(strain: float, rows: int):
    """One stage: L_yy = -1 (units of γ̇_ref), σxx = -P0, to ε_yy = -strain."""
    from dem.paths import parse_path

    return parse_path({"name": "biaxial_verify", "stage": [{
        "name": "compress", "length": strain, "output_every": strain / rows,
        "L": {"yy": -1.0, "xy": 0.0, "yx": 0.0}, "sigma": {"xx": -1.0}}]})


def sample(kind: str, seed: int, n: int, kappa: float, inertial: float, loose: dict):
    """(state, dynamics) of one prepared sample with zero tangential histories."""
    from dem.job import Settings, prepare_sample

    prep = {"mu_prep": 0.0} if kind == "dense" else loose
    settings = Settings(n=n, seed=seed, kappa=kappa, mu=0.5, e=0.55, kt_ratio=0.5,
                        inertial=inertial, **prep)
    state, dyn, _ = prepare_sample(settings, progress=False)
    state.pair_hist[:, :2] = 0.0
    return state, dyn


def _row(engine, kind, seed, step, exx, eyy, m) -> dict:
    return {"engine": engine, "kind": kind, "seed": seed, "step": int(step), "eps_xx": exx,
            "eps_yy": eyy, "eps_v": exx + eyy, **m}


def dem_curve(state, dyn, kind, seed, strain, rows, timer=None) -> list[dict]:
    """The DEM's rows along the path (measured at each output)."""
    from dem.rve import PathRunner

    out = []
    step0 = [None]

    def measure(run, st):
        c = Contacts(st)
        r = run.rows[-1]
        if step0[0] is None:
            step0[0] = st.step
        out.append(_row("dem", kind, seed, st.step - step0[0], r["eps_xx"], r["eps_yy"],
                        contact_measures(st.s @ st.h.T, st.radius, st.h, c.i, c.j, c.f,
                                         dyn.law.mu)))

    runner = PathRunner(biaxial_path(strain, rows), dyn, dyn.gdot_ref)
    run = runner.start(state)
    measure(run, state)
    runner.run(state, run, on_row=measure)
    return out


def lammps_curve(state, dyn, kind, seed, steps, gamma_t) -> list[dict]:
    """LAMMPS's rows at the DEM's output steps."""
    eng = LammpsBiaxial(state, dyn, dyn.gdot_ref, max(steps), gamma_t)
    try:
        out = []
        for k in steps:
            eng.run_to(k)
            x, h, i, j, f = eng.contacts()
            exx, eyy = eng.strain()
            out.append(_row("lammps", kind, seed, k, exx, eyy,
                            contact_measures(x, state.radius, h, i, j, f, dyn.law.mu)))
        return out
    finally:
        eng.close()


def summarize(rows: list[dict]) -> dict:
    """Peak and residual figures of one run (see the module doc)."""
    ax = np.array([-r["eps_yy"] for r in rows])
    rp = np.array([r["RP"] for r in rows])
    lo, hi = RESIDUAL_WINDOW
    win = (ax >= lo) & (ax <= hi)
    if win.sum() < 3:
        win = ax >= 0.6 * ax[-1]
    k = int(np.argmax(rp))
    out = {"peak_RP": float(rp[k]), "peak_strain": float(ax[k]),
           "window": [float(ax[win].min()), float(ax[win].max())]}
    for q in SUMMARY[2:]:
        out[q] = float(np.mean([r[q] for r, w in zip(rows, win) if w]))
    return out


def seed_table(summaries: list[dict]) -> dict:
    """Per kind: per engine mean and sd over seeds, the difference and 2 se of it."""
    table = {}
    for kind in sorted({s["kind"] for s in summaries}):
        t = {}
        for q in SUMMARY:
            stats = {}
            for eng in ("dem", "lammps"):
                v = np.array([s[q] for s in summaries if s["kind"] == kind and s["engine"] == eng])
                stats[eng] = {"mean": float(v.mean()), "sd": float(v.std(ddof=1)) if v.size > 1
                              else math.nan, "seeds": int(v.size)}
            d, l_ = stats["dem"], stats["lammps"]
            two_se = 2.0 * math.sqrt(d["sd"] ** 2 / d["seeds"] + l_["sd"] ** 2 / l_["seeds"])
            diff = d["mean"] - l_["mean"]
            t[q] = {**stats, "dem_minus_lammps": diff, "two_se": two_se,
                    "within_scatter": bool(abs(diff) <= two_se) if math.isfinite(two_se) else None}
        table[kind] = t
    return table


def overlay_plot(curves: list[dict], file) -> None:
    """R/P, ε_v, c, z, B/A and the sliding fraction against -ε_yy, both engines."""
    from dem.plots import _figure

    plt = _figure()
    panels = (("RP", "R/P"), ("eps_v", "ε_v (dilation > 0)"), ("c", "packing fraction c"),
              ("z", "z (rattlers included)"), ("BA", "B/A"), ("sliding_fraction", "sliding fraction"))
    fig, axes = plt.subplots(2, 3, figsize=(13, 7), sharex=True)
    style = {"dem": "-", "lammps": "--"}
    colour = {"dense": "C0", "loose": "C3"}
    runs = sorted({(r["engine"], r["kind"], r["seed"]) for r in curves})
    for eng, kind, seed in runs:
        rr = [r for r in curves if (r["engine"], r["kind"], r["seed"]) == (eng, kind, seed)]
        ax_strain = [-r["eps_yy"] for r in rr]
        for a, (q, label) in zip(axes.flat, panels):
            a.plot(ax_strain, [r[q] for r in rr], style[eng], color=colour[kind], lw=0.8,
                   label=f"{eng} {kind}" if seed == runs[0][2] else None)
            a.set_ylabel(label)
    for a in axes[1]:
        a.set_xlabel("axial strain -ε_yy")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("biaxial at σxx = -P0: DEM (solid) and LAMMPS gran/hooke/history (dashed)")
    fig.tight_layout()
    with atomic_path(file) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def compare(out, n: int = 1000, seeds=(1, 2, 3), kinds=("dense", "loose"), kappa: float = 1e3,
            strain: float = 0.3, rows: int = 150, inertial: float = 1e-3,
            gamma_t: str = "half", loose: dict | None = None, progress=None) -> dict:
    """Run the comparison (module doc); returns {what: file written} and the table."""
    from contfab.bench.dem_lammps import lammps_class
    from dem.job import LOOSE

    lammps_class()                        # LammpsUnavailable before anything runs
    out = FsPath(out)
    loose = LOOSE if loose is None else loose
    curves, summaries = [], []
    for kind in kinds:
        for seed in seeds:
            state, dyn = sample(kind, seed, n, kappa, inertial, loose)
            ours = dem_curve(state.copy(), dyn, kind, seed, strain, rows)
            theirs = lammps_curve(state, dyn, kind, seed, [r["step"] for r in ours], gamma_t)
            for eng, rr in (("dem", ours), ("lammps", theirs)):
                summaries.append({"engine": eng, "kind": kind, "seed": seed, **summarize(rr)})
            curves += ours + theirs
            if progress is not None:
                progress(kind, seed)
    table = seed_table(summaries)
    written = {
        "curves": write_csv(out / "curves.csv", CURVE_COLUMNS,
                            [[r[c] for c in CURVE_COLUMNS] for r in curves]),
        "summary": write_csv(out / "summary.csv", ("engine", "kind", "seed") + SUMMARY,
                             [[s[c] for c in ("engine", "kind", "seed") + SUMMARY]
                              for s in summaries]),
        "table": write_json(out / "table.json", {
            "settings": {"n": n, "seeds": list(seeds), "kinds": list(kinds), "kappa": kappa,
                         "strain": strain, "inertial": inertial, "gamma_t": gamma_t,
                         "loose": loose, "residual_window": RESIDUAL_WINDOW},
            "runs": summaries, "table": table}),
    }
    overlay_plot(curves, out / "overlay.png")
    written["overlay"] = out / "overlay.png"
    return {"written": written, "table": table, "runs": summaries}


def check_settings(n, seeds, strain, rows) -> None:
    """Refuse bad settings before anything runs (names the value and the range)."""
    if not (isinstance(n, int) and n >= 20):
        raise ValueError(f"n = {n} out of range; accepted integers >= 20")
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds {list(seeds)}: accepted one or more distinct integers")
    if not (0.0 < strain <= 0.5):
        raise ValueError(f"strain = {strain} out of range; accepted (0, 0.5]")
    if not (isinstance(rows, int) and rows >= 5):
        raise ValueError(f"rows = {rows} out of range; accepted integers >= 5")

