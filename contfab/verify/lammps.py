"""``contfab verify lammps``: the DEM and LAMMPS on the same samples and loading path.

For each seed and kind (dense, loose) one sample is prepared by the DEM
(:func:`dem.job.prepare_sample`: diameters uniform in [0.8, 1.2], μ = 0.5, kt/kn = 0.5,
e = 0.55, κ as given; dense: μ_prep = 0, loose: :data:`dem.job.LOOSE`); its tangential histories are set to zero, and the same state
(positions, velocities, spins, cell) is loaded into both engines
(:mod:`contfab.verify.lammps_engine`). Both then follow one of two paths (``path``):

* ``biaxial``: compression along y at the strain rate γ̇ = I (true strain rate) with σxx
  held at -P0, to the axial strain ``strain`` (the DEM by its servo; LAMMPS, with
  ``remap`` ``v``, by a servo on the x strain rate with whole velocities and
  Lees-Edwards boundaries on both axes, or, with ``x``, by its barostat with affine
  remapping and fluctuation velocities: :class:`contfab.verify.lammps_engine.LammpsBiaxial`);
* ``shear_reversal``: the DEM's standard path ``simple_shear_reversal`` (L_xy = +I to the
  shear strain γ = a, then L_xy = -I to γ = -a, σyy held at -P0, L_xx = L_yx = 0) with
  its lengths, output intervals and stops scaled from a = 1 to the amplitude
  a = ``shear``. LAMMPS reverses at the DEM's reversal step; ``remap`` chooses how its
  discs follow the cell (:class:`contfab.verify.lammps_engine.LammpsShear`: ``v``, whole
  velocities with Lees-Edwards boundaries, or ``x``, affine remapping and fluctuation
  velocities).

LAMMPS's tangential dashpot is ``gamma_t``: ``"zero"`` (the default) is the DEM's default
law, which has none; ``"half"`` is LAMMPS's usual γt = γn/2. The DEM's contact law is of
style ``contact_style`` (:mod:`dem.contact_law`): with ``"hooke/history"`` and ``gamma_t =
"half"`` the two engines run the same force law.

Both are measured at the same steps by the same code
(:func:`contfab.verify.contacts.contact_measures`: contact stress, R/P, τ/σn = σxy/-σyy,
c, z, z*, B/A, sliding fraction).

Summary per biaxial run: the peak R/P and its axial strain, and the means over the
residual window (-ε_yy in RESIDUAL_WINDOW, or the last 40 % of a shorter run) of R/P, c,
ε_v, z, z*, B/A and the sliding fraction. Per shear-reversal run: the means over the
steady window before the reversal (γ in [STEADY_FROM a, a]) of τ/σn, c, ε_v, z, z*, B/A
and the sliding fraction; after the reversal, with Δγ = a - γ the strain since it: the
Δγ at which τ/σn crosses zero (linear between rows), the smallest B/A and its Δγ, and
the Δγ at which B/A regains RECOVERY_FRACTION of its steady value (NaN when the run ends
first). Per engine and kind: the seed mean and standard deviation (over the seeds where
the figure is finite); per kind the difference of the engines and two standard errors
of it, 2 sqrt(sd_dem²/k + sd_lammps²/k) over k seeds.

Files (in ``out``): ``curves.csv`` (every measured row), ``summary.csv`` (one row per
run), ``table.json`` (the seed statistics), ``overlay.png`` (curves of both engines).
"""
from __future__ import annotations

import math
from pathlib import Path as FsPath

import numpy as np

from contfab.verify.contacts import MEASURES, contact_measures
from contfab.verify.lammps_engine import REMAPS, LammpsBiaxial, LammpsShear
from dem.contact_law import STYLES
from dem.fileio import atomic_path, write_csv, write_json
from dem.measure import Contacts

PATHS = ("biaxial", "shear_reversal")
RESIDUAL_WINDOW = (0.20, 0.30)
STEADY_FROM = 0.6
RECOVERY_FRACTION = 0.9
MAX_SHEAR = 1.0
SUMMARY = {
    "biaxial": ("peak_RP", "peak_strain", "RP", "c", "eps_v", "z", "z_no_rattlers", "BA",
                "sliding_fraction", "sliding_strict"),
    "shear_reversal": ("tau_sn", "c", "eps_v", "z", "z_no_rattlers", "BA", "sliding_fraction",
                       "sliding_strict", "zero_cross_strain", "BA_min", "BA_min_strain",
                       "BA_recovery_strain")}
CURVE_COLUMNS = ("engine", "kind", "seed", "step", "stage", "eps_xx", "eps_yy", "eps_v",
                 "gamma", "tau_sn") + MEASURES


def biaxial_path(strain: float, rows: int):
    """One stage: L_yy = -1 (units of γ̇_ref), σxx = -P0, to ε_yy = -strain."""
    from dem.paths import parse_path

    return parse_path({"name": "biaxial_verify", "stage": [{
        "name": "compress", "length": strain, "output_every": strain / rows,
        "L": {"yy": -1.0, "xy": 0.0, "yx": 0.0}, "sigma": {"xx": -1.0}}]})


def shear_reversal_path(amplitude: float, rows: int):
    """The standard ``simple_shear_reversal`` with a = 1 scaled to ``amplitude``, a row
    every 3a/rows."""
    import tomllib

    from dem.paths import STANDARD_DIR, parse_path

    data = tomllib.loads((STANDARD_DIR / "simple_shear_reversal.toml").read_text())
    for st in data["stage"]:
        st["length"] *= amplitude
        st["output_every"] = 3.0 * amplitude / rows
        st["until"] = {q: v * amplitude for q, v in st.get("until", {}).items()}
    return parse_path(data)


def sample(kind: str, seed: int, n: int, kappa: float, inertial: float, loose: dict,
           contact_style: str = STYLES[0]):
    """(state, dynamics) of one prepared sample with zero tangential histories, the DEM's
    contact law of style ``contact_style`` (the sample is the same for every style)."""
    from dem.job import Settings, prepare_sample

    prep = {"mu_prep": 0.0} if kind == "dense" else loose
    settings = Settings(n=n, seed=seed, kappa=kappa, mu=0.5, e=0.55, kt_ratio=0.5,
                        inertial=inertial, contact_style=contact_style, **prep)
    state, dyn, _ = prepare_sample(settings, progress=False)
    state.pair_hist[:, :2] = 0.0
    return state, dyn


def _row(engine, kind, seed, step, stage, exx, eyy, gamma, m) -> dict:
    return {"engine": engine, "kind": kind, "seed": seed, "step": int(step), "stage": int(stage),
            "eps_xx": exx, "eps_yy": eyy, "eps_v": exx + eyy, "gamma": gamma,
            "tau_sn": m["sxy"] / -m["syy"] if m["syy"] < 0 else 0.0, **m}


def dem_curve(state, dyn, kind, seed, path) -> list[dict]:
    """The DEM's rows along ``path`` (measured at each output)."""
    from dem.rve import PathRunner

    out = []
    step0 = [None]

    def measure(run, st):
        c = Contacts(st)
        r = run.rows[-1]
        if step0[0] is None:
            step0[0] = st.step
        out.append(_row("dem", kind, seed, st.step - step0[0], r["stage"], r["eps_xx"],
                        r["eps_yy"], r["gamma"],
                        contact_measures(st.s @ st.h.T, st.radius, st.h, c.i, c.j, c.f,
                                         dyn.law.mu)))

    runner = PathRunner(path, dyn, dyn.gdot_ref)
    run = runner.start(state)
    measure(run, state)
    runner.run(state, run, on_row=measure)
    return out


def lammps_curve(state, dyn, kind, seed, dem_rows, path_name, gamma_t, remap="v") -> list[dict]:
    """LAMMPS's rows at the DEM's output steps; in shear it reverses where the DEM did
    (the step of the DEM's last row of the first stage), its discs remapped by ``remap``."""
    steps = [r["step"] for r in dem_rows]
    if path_name == "shear_reversal":
        eng = LammpsShear(state, dyn, dyn.gdot_ref, max(steps), gamma_t, remap)
    else:
        eng = LammpsBiaxial(state, dyn, dyn.gdot_ref, max(steps), gamma_t, remap)
    try:
        out, stage = [], 0
        for r in dem_rows:
            if r["stage"] != stage:
                eng.reverse()
                stage = r["stage"]
            eng.run_to(r["step"])
            x, h, i, j, f = eng.contacts()
            exx, eyy = eng.strain()
            out.append(_row("lammps", kind, seed, r["step"], stage, exx, eyy,
                            getattr(eng, "gamma", 0.0),
                            contact_measures(x, state.radius, h, i, j, f, dyn.law.mu)))
        return out
    finally:
        eng.close()


def summarize(rows: list[dict]) -> dict:
    """Peak and residual figures of one biaxial run (see the module doc)."""
    ax = np.array([-r["eps_yy"] for r in rows])
    rp = np.array([r["RP"] for r in rows])
    lo, hi = RESIDUAL_WINDOW
    win = (ax >= lo) & (ax <= hi)
    if win.sum() < 3:
        win = ax >= 0.6 * ax[-1]
    k = int(np.argmax(rp))
    out = {"peak_RP": float(rp[k]), "peak_strain": float(ax[k]),
           "window": [float(ax[win].min()), float(ax[win].max())]}
    for q in SUMMARY["biaxial"][2:]:
        out[q] = float(np.mean([r[q] for r, w in zip(rows, win) if w]))
    return out


def _first_crossing(x, y, level: float, start: int) -> float:
    """The x at which y first reaches ``level`` from below or above at index >= start
    (linear between rows), NaN if it never does."""
    for k in range(max(start, 1), len(y)):
        if (y[k - 1] - level) * (y[k] - level) <= 0.0 and y[k] != y[k - 1]:
            return float(x[k - 1] + (level - y[k - 1]) * (x[k] - x[k - 1]) / (y[k] - y[k - 1]))
    return math.nan


def summarize_shear(rows: list[dict]) -> dict:
    """Steady and post-reversal figures of one shear-reversal run (see the module doc)."""
    fwd = [r for r in rows if r["stage"] == 0]
    a = fwd[-1]["gamma"]
    steady = [r for r in fwd if r["gamma"] >= STEADY_FROM * a]
    out = {"reversal_gamma": float(a), "window": [float(steady[0]["gamma"]), float(a)]}
    for q in SUMMARY["shear_reversal"][:8]:
        out[q] = float(np.mean([r[q] for r in steady]))
    back = [fwd[-1]] + [r for r in rows if r["stage"] == 1]
    dg = np.array([a - r["gamma"] for r in back])
    tau = np.array([r["tau_sn"] for r in back])
    ba = np.array([r["BA"] for r in back])
    k = int(np.argmin(ba))
    out.update(zero_cross_strain=_first_crossing(dg, tau, 0.0, 1),
               BA_min=float(ba[k]), BA_min_strain=float(dg[k]),
               BA_recovery_strain=_first_crossing(dg, ba, RECOVERY_FRACTION * out["BA"], k + 1))
    return out


def seed_table(summaries: list[dict], quantities) -> dict:
    """Per kind: per engine mean and sd over the seeds where the figure is finite, the
    difference and 2 se of it (NaN unless both engines have two finite seeds or more; a
    figure a run does not reach, such as a recovery past its end, is NaN)."""
    table = {}
    for kind in sorted({s["kind"] for s in summaries}):
        t = {}
        for q in quantities:
            stats = {}
            for eng in ("dem", "lammps"):
                v = np.array([s[q] for s in summaries if s["kind"] == kind and s["engine"] == eng])
                v = v[np.isfinite(v)]
                stats[eng] = {"mean": float(v.mean()) if v.size else math.nan,
                              "sd": float(v.std(ddof=1)) if v.size > 1 else math.nan,
                              "seeds": int(v.size)}
            d, l_ = stats["dem"], stats["lammps"]
            two_se = (2.0 * math.sqrt(d["sd"] ** 2 / d["seeds"] + l_["sd"] ** 2 / l_["seeds"])
                      if d["seeds"] > 1 and l_["seeds"] > 1 else math.nan)
            diff = d["mean"] - l_["mean"]
            t[q] = {**stats, "dem_minus_lammps": diff, "two_se": two_se,
                    "within_scatter": bool(abs(diff) <= two_se) if math.isfinite(two_se) else None}
        table[kind] = t
    return table


PLOTS = {
    "biaxial": (lambda r: -r["eps_yy"], "axial strain -ε_yy", "RP", "R/P",
                "biaxial at σxx = -P0"),
    "shear_reversal": (lambda r: r["gamma"], "shear strain γ", "tau_sn", "τ/σn = σxy/-σyy",
                       "simple shear reversal at σyy = -P0")}


def overlay_plot(curves: list[dict], path_name: str, file) -> None:
    """The stress ratio (R/P, or τ/σn in shear), ε_v, c, z, B/A and the sliding fraction
    against the path's strain, both engines."""
    from dem.plots import _figure

    plt = _figure()
    strain, xlabel, ratio, ratio_label, title = PLOTS[path_name]
    panels = ((ratio, ratio_label), ("eps_v", "ε_v (dilation > 0)"), ("c", "packing fraction c"),
              ("z", "z (rattlers included)"), ("BA", "B/A"), ("sliding_fraction", "sliding fraction"))
    fig, axes = plt.subplots(2, 3, figsize=(13, 7), sharex=True)
    style = {"dem": "-", "lammps": "--"}
    colour = {"dense": "C0", "loose": "C3"}
    runs = sorted({(r["engine"], r["kind"], r["seed"]) for r in curves})
    for eng, kind, seed in runs:
        rr = [r for r in curves if (r["engine"], r["kind"], r["seed"]) == (eng, kind, seed)]
        ax_strain = [strain(r) for r in rr]
        for a, (q, label) in zip(axes.flat, panels):
            a.plot(ax_strain, [r[q] for r in rr], style[eng], color=colour[kind], lw=0.8,
                   label=f"{eng} {kind}" if seed == runs[0][2] else None)
            a.set_ylabel(label)
    for a in axes[1]:
        a.set_xlabel(xlabel)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(f"{title}: DEM (solid) and LAMMPS gran/hooke/history (dashed)")
    fig.tight_layout()
    with atomic_path(file) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def compare(out, n: int = 1000, seeds=(1, 2, 3), kinds=("dense", "loose"), kappa: float = 1e3,
            strain: float = 0.3, rows: int = 150, inertial: float = 1e-3,
            gamma_t: str = "zero", loose: dict | None = None, path: str = "biaxial",
            shear: float = MAX_SHEAR, remap: str = "v", contact_style: str = STYLES[0],
            progress=None) -> dict:
    """Run the comparison (module doc); returns {what: file written} and the table."""
    from contfab.bench.dem_lammps import lammps_class
    from dem.job import LOOSE

    check_settings(n, seeds, strain, rows, path, shear, remap)
    lammps_class()                        # LammpsUnavailable before anything runs
    out = FsPath(out)
    loose = LOOSE if loose is None else loose
    loading = (shear_reversal_path(shear, rows) if path == "shear_reversal"
               else biaxial_path(strain, rows))
    summary = summarize_shear if path == "shear_reversal" else summarize
    quantities = SUMMARY[path]
    curves, summaries = [], []
    for kind in kinds:
        for seed in seeds:
            state, dyn = sample(kind, seed, n, kappa, inertial, loose, contact_style)
            ours = dem_curve(state.copy(), dyn, kind, seed, loading)
            theirs = lammps_curve(state, dyn, kind, seed, ours, path, gamma_t, remap)
            for eng, rr in (("dem", ours), ("lammps", theirs)):
                summaries.append({"engine": eng, "kind": kind, "seed": seed, **summary(rr)})
            curves += ours + theirs
            if progress is not None:
                progress(kind, seed)
    table = seed_table(summaries, quantities)
    written = {
        "curves": write_csv(out / "curves.csv", CURVE_COLUMNS,
                            [[r[c] for c in CURVE_COLUMNS] for r in curves]),
        "summary": write_csv(out / "summary.csv", ("engine", "kind", "seed") + quantities,
                             [[s[c] for c in ("engine", "kind", "seed") + quantities]
                              for s in summaries]),
        "table": write_json(out / "table.json", {
            "settings": {"n": n, "seeds": list(seeds), "kinds": list(kinds), "kappa": kappa,
                         "path": path, "remap": remap, **({"shear": shear,
                                           "steady_from": STEADY_FROM,
                                           "recovery_fraction": RECOVERY_FRACTION}
                                          if path == "shear_reversal" else
                                          {"strain": strain, "residual_window": RESIDUAL_WINDOW}),
                         "inertial": inertial, "gamma_t": gamma_t,
                         "contact_style": contact_style, "loose": loose},
            "runs": summaries, "table": table}),
    }
    overlay_plot(curves, path, out / "overlay.png")
    written["overlay"] = out / "overlay.png"
    return {"written": written, "table": table, "runs": summaries}


def check_settings(n, seeds, strain, rows, path: str = "biaxial", shear: float = MAX_SHEAR,
                   remap: str = "v") -> None:
    """Refuse bad settings before anything runs (names the value and the range)."""
    if path not in PATHS:
        raise ValueError(f"path {path!r} unknown; accepted {PATHS}")
    if remap not in REMAPS:
        raise ValueError(f"remap {remap!r} unknown; accepted {REMAPS}")
    if not (0.0 < shear <= MAX_SHEAR):
        raise ValueError(f"shear amplitude = {shear} out of range; accepted (0, {MAX_SHEAR:g}]")
    if not (isinstance(n, int) and n >= 20):
        raise ValueError(f"n = {n} out of range; accepted integers >= 20")
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds {list(seeds)}: accepted one or more distinct integers")
    if not (0.0 < strain <= 0.5):
        raise ValueError(f"strain = {strain} out of range; accepted (0, 0.5]")
    if not (isinstance(rows, int) and rows >= 5):
        raise ValueError(f"rows = {rows} out of range; accepted integers >= 5")

