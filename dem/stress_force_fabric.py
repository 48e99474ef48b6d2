"""How far the contact and force anisotropies explain the stress ratio of DEM histories.

Conventions (:mod:`dem.conventions`, :func:`dem.measure.force_anisotropy`): tension
positive, angles in radians in (-π/2, π/2]. Per history row:

* θσ, the major compressive principal direction of the stress:
  θσ = ½ atan2(-σxy, -(σxx - σyy)/2).
* The anisotropies a_c = B/A (θp), a_n (θn), a_t (θt) and their projections on the
  stress axes, π_k = a_k cos 2(θk - θσ). The stress–force–fabric relation of Rothenburg &
  Bathurst (1989), to first order in the anisotropies:

      R/P ≈ ½ (π_c + π_n + π_t)                (its contact part ½ π_c, force part ½ (π_n + π_t))

  With all three distributions exactly of second order and a branch length independent of
  the direction, the deviator is exactly that and the pressure carries the product of
  the contact and normal-force harmonics (:func:`sff_ratio`):

      R/P = ½ (π_c + π_n + π_t) / (1 + ½ a_c a_n cos 2(θp - θn))

* γs, the accumulated shear strain ∫ 2 sqrt(((dεxx - dεyy)/2)² + dεxy²) (|Δγ| in simple
  shear, |Δ(ε1 - ε2)| in biaxial tests), counted from the path start and from the start
  of the row's leg (s). A leg is a stretch of one loading: each stage of a path, except
  that the stages of a path in ``ONE_LEG`` (the biaxial test, whose two stages only
  change the output interval) form one.
* θD, the compressive principal direction of the strain increment since the previous row,
  the non-coaxiality θσ - θD (folded into [-π/2, π/2)), and the fabric's alignment with
  the loading α_D = (B/A) cos 2(θp - θD) (in [-1, 1]; > 0 when the contacts crowd along
  the direction that closes; the 2D analogue of the fabric–loading invariant of Li &
  Dafalias 2012).
* The dilatancy d = dε_v/dγs (dilation > 0), the slope of a least-squares line of ε_v
  against γs over a window of ``DILATANCY_WINDOW`` of shear strain inside the leg.

Run ``python -m dem.stress_force_fabric RUN_DIR ... --out DIR`` on directories written by
``contfab dem run`` (their ``history.csv`` and ``history.json``). It writes into DIR:
``rows.csv`` (with ``--rows``: every row with the derived columns), ``correlations.csv`` (per path and
phase: Pearson r of R/P with the contact part, the force part, the first-order sum and the
full relation, the slope of R/P on the sum, and the RMS and mean of R/P minus each form),
``transients.csv`` (per run, :func:`transient_figures`), ``buildup.csv`` (per run,
:func:`buildup_figures`), ``rotation.csv`` (per run, :func:`rotation_figures`),
``seed_means.csv`` (the three per path and density: mean and standard deviation over the
seeds), ``dilatancy.csv`` (:func:`dilatancy_fits`),
``summary.json`` (all tables) and the figures ``paths.png``, ``reversal.png``,
``scatter.png`` and ``dilatancy.png``.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path

import numpy as np

from dem.fileio import atomic_path, write_csv, write_json

DILATANCY_WINDOW = 0.04
"""Shear-strain width of the window of the dilatancy's least-squares slope."""
STEADY_FRACTION = 0.4
"""The steady phase of a leg: its last fraction of shear strain."""
BUILD_UP = 0.3
"""The build-up phase: the first leg's first γs = 0.3 (from isotropy)."""
ONE_LEG = ("biaxial",)
TRANSIENT_PATHS = ("simple_shear_reversal", "direction_change")
TRANSIENT = 0.3
"""The transient phase after a reversal or change of direction: the second leg's
first γs = 0.3."""
DERIVED = ("gamma_s", "s", "theta_sigma", "noncoaxiality", "a_c", "pi_c", "pi_n", "pi_t", "sff", "sff_full", "sff_contact",
           "sff_force", "sff_radius", "theta_D", "alpha_D", "dilatancy")


def read_run(run_dir: str | Path) -> tuple[dict, dict[str, np.ndarray]]:
    """(meta, {column: array}) of a ``contfab dem run`` directory; meta has the path
    name, the density ("dense" when the preparation was frictionless), the seed and κ."""
    run_dir = Path(run_dir)
    info = json.loads((run_dir / "history.json").read_text())
    s = info["settings"]
    meta = {"run": run_dir.name, "path": info["path"]["name"], "seed": int(s["seed"]),
            "kappa": float(s["kappa"]), "n": int(s["n"]),
            "density": "dense" if s.get("mu_prep") == 0.0 else "loose"}
    with open(run_dir / "history.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows or "a_n" not in rows[0]:
        raise ValueError(f"{run_dir}: no history rows with the force anisotropy (a_n); "
                         f"rerun with a DEM that records it")
    h = {k: np.array([float(r[k]) if r[k] != "" else math.nan for r in rows]) for k in rows[0]}
    return meta, h


def _angle(x):
    """An angle difference of axes folded into [-π/2, π/2)."""
    return np.mod(x + 0.5 * np.pi, np.pi) - 0.5 * np.pi


def _shear_increment(dxx, dyy, dxy):
    return 2.0 * np.hypot(0.5 * (dxx - dyy), dxy)


def sff_ratio(a_c, theta_c, a_n, theta_n, a_t, theta_t, theta_sigma):
    """(first order, full): R/P of the stress–force–fabric relation projected on the
    stress axes θσ (module doc); numpy scalars or arrays."""
    first = 0.5 * (a_c * np.cos(2.0 * (theta_c - theta_sigma))
                   + a_n * np.cos(2.0 * (theta_n - theta_sigma))
                   + a_t * np.cos(2.0 * (theta_t - theta_sigma)))
    return first, first / (1.0 + 0.5 * a_c * a_n * np.cos(2.0 * (theta_c - theta_n)))


def legs(meta: dict, h: dict[str, np.ndarray]) -> np.ndarray:
    """The leg of every row (module doc)."""
    stage = h["stage"].astype(int)
    return np.zeros_like(stage) if meta["path"] in ONE_LEG else stage


def derived(h: dict[str, np.ndarray], leg: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The derived columns of the module doc for one history (``leg``: the rows' legs,
    :func:`legs`; by default the stages)."""
    sxx, syy, sxy = h["sxx"], h["syy"], h["sxy"]
    theta_s = 0.5 * np.arctan2(-sxy, -0.5 * (sxx - syy))
    a_c = h["B"] / h["A"]
    proj = {k: a * np.cos(2.0 * (th - theta_s))
            for k, a, th in (("c", a_c, h["theta_p"]), ("n", h["a_n"], h["theta_n"]),
                             ("t", h["a_t"], h["theta_t"]))}
    _, full = sff_ratio(a_c, h["theta_p"], h["a_n"], h["theta_n"], h["a_t"], h["theta_t"], theta_s)
    vec = sum(0.5 * a * np.stack([np.cos(2 * th), np.sin(2 * th)])
              for a, th in ((a_c, h["theta_p"]), (h["a_n"], h["theta_n"]), (h["a_t"], h["theta_t"])))
    de = {k: np.diff(h[k], prepend=h[k][0]) for k in ("eps_xx", "eps_yy", "eps_xy")}
    dg = _shear_increment(de["eps_xx"], de["eps_yy"], de["eps_xy"])
    leg = h["stage"].astype(int) if leg is None else leg
    gamma_s = np.cumsum(dg)
    s = np.empty_like(gamma_s)
    for k in np.unique(leg):
        m = leg == k
        s[m] = np.cumsum(dg[m])      # a leg's first row is one output interval into it
    theta_d = 0.5 * np.arctan2(-de["eps_xy"], -0.5 * (de["eps_xx"] - de["eps_yy"]))
    theta_d[0] = theta_d[1] if len(theta_d) > 1 else 0.0
    return {"leg": leg, "gamma_s": gamma_s, "s": s, "theta_sigma": theta_s, "a_c": a_c,
            "noncoaxiality": _angle(theta_s - theta_d),
            "pi_c": proj["c"], "pi_n": proj["n"], "pi_t": proj["t"],
            "sff": 0.5 * (proj["c"] + proj["n"] + proj["t"]), "sff_full": full,
            "sff_contact": 0.5 * proj["c"],
            "sff_force": 0.5 * (proj["n"] + proj["t"]), "sff_radius": np.hypot(*vec),
            "theta_D": theta_d, "alpha_D": a_c * np.cos(2.0 * (h["theta_p"] - theta_d)),
            "dilatancy": dilatancy(s, h["eps_v"], leg)}


def dilatancy(s: np.ndarray, eps_v: np.ndarray, leg: np.ndarray,
              window: float = DILATANCY_WINDOW) -> np.ndarray:
    """dε_v/dγs: least-squares slope over rows of the same leg within ±window/2 of s
    (NaN where the window holds fewer than 3 rows or no shear)."""
    out = np.full(s.shape, math.nan)
    for i in range(len(s)):
        m = (leg == leg[i]) & (np.abs(s - s[i]) <= 0.5 * window)
        if m.sum() >= 3 and np.ptp(s[m]) > 0.25 * window:
            out[i] = np.polyfit(s[m], eps_v[m], 1)[0]
    return out


def phases(meta: dict, h: dict, d: dict) -> dict[str, np.ndarray]:
    """Boolean row masks of the phases of a path: ``build_up`` (first leg, s <= BUILD_UP,
    on paths that start isotropic), ``steady`` (the last STEADY_FRACTION of each leg),
    ``transient`` (second leg, s <= TRANSIENT, on the reversal and the change of
    direction), ``rotation`` (the rotation stage of the axes rotation), ``all``."""
    leg = d["leg"]
    s = d["s"]
    out = {"all": np.ones(len(s), bool)}
    name = meta["path"]
    if name == "axes_rotation":
        out["rotation"] = h["stage"] == 1
        return out
    out["build_up"] = (leg == 0) & (s <= BUILD_UP)
    steady = np.zeros(len(s), bool)
    for k in np.unique(leg):
        m = leg == k
        steady |= m & (s >= (1.0 - STEADY_FRACTION) * s[m].max())
    out["steady"] = steady
    if name in TRANSIENT_PATHS:
        out["transient"] = (leg == 1) & (s <= TRANSIENT)
    return out


def _stats(rp, parts: dict) -> dict:
    r = {f"r_{k}": float(np.corrcoef(rp, v)[0, 1]) if np.ptp(v) > 0 and np.ptp(rp) > 0
         else math.nan for k, v in parts.items()}
    total = parts["sum"]
    slope = float(np.dot(total - total.mean(), rp - rp.mean()) / np.dot(total - total.mean(),
                                                                          total - total.mean()))
    r.update(slope=slope, rms=float(np.sqrt(np.mean((rp - total) ** 2))),
             rms_full=float(np.sqrt(np.mean((rp - parts["full"]) ** 2))),
             mean_residual_full=float(np.mean(rp - parts["full"])),
             mean_residual=float(np.mean(rp - total)), mean_RP=float(rp.mean()),
             mean_contact=float(parts["contact"].mean()), mean_force=float(parts["force"].mean()))
    return r


def correlations(runs: list[tuple[dict, dict, dict]]) -> list[dict]:
    """One row per (path, density, phase), the seeds pooled: Pearson r of R/P with the
    contact part, the force part and the sum of the relation, the slope of R/P on the
    sum, RMS and mean of R/P - sum, and the phase means."""
    groups: dict[tuple, list] = {}
    for meta, h, d in runs:
        for ph, m in phases(meta, h, d).items():
            groups.setdefault((meta["path"], meta["density"], ph), []).append((h, d, m))
    rows = []
    for (path, dens, ph), items in sorted(groups.items()):
        rp = np.concatenate([h["RP"][m] for h, d, m in items])
        parts = {k: np.concatenate([d[c][m] for h, d, m in items])
                 for k, c in (("contact", "sff_contact"), ("force", "sff_force"), ("sum", "sff"),
                              ("full", "sff_full"))}
        rows.append({"path": path, "density": dens, "phase": ph, "seeds": len(items),
                     "rows": int(rp.size), **_stats(rp, parts)})
    return rows


def _first(mask: np.ndarray, x: np.ndarray) -> float:
    idx = np.flatnonzero(mask)
    return float(x[idx[0]]) if idx.size else math.nan


def _strain_to(frac: float, y: np.ndarray, s: np.ndarray, y_end: float) -> float:
    """First s where y has covered ``frac`` of its way from y[0] to y_end."""
    span = y_end - y[0]
    return _first((y - y[0]) / span >= frac, s) if span != 0.0 else math.nan


def second_leg(h: dict, d: dict):
    """(rows, s, n_comp, n_ext) of the second leg from the last row of the first (s = 0):
    the contact densities along the leg's loading axes (θD1, the median θD of its rows),
    n_comp = A + B cos 2(θp - θD1) (closing) and n_ext = A - B cos 2(θp - θD1) (opening)."""
    idx = np.flatnonzero(d["leg"] == 1)
    idx = np.r_[idx[0] - 1, idx]
    s = np.r_[0.0, d["s"][idx[1:]]]
    theta_d1 = float(np.median(d["theta_D"][idx[1:]]))
    proj = h["B"][idx] * np.cos(2.0 * (h["theta_p"][idx] - theta_d1))
    return idx, s, h["A"][idx] + proj, h["A"][idx] - proj


def transient_figures(meta: dict, h: dict, d: dict) -> dict | None:
    """The second leg of a reversal or change of direction against its shear strain s,
    from the last row of the first leg (s = 0): R/P at the start and its minimum over
    s <= TRANSIENT, where the minimum falls, the contact and force parts and the
    non-coaxiality θσ - θD there, the strain back to 90 % of the leg's steady R/P (the
    mean over its last STEADY_FRACTION); the largest compaction Δc = c - c(0) > 0 and
    where; the fabric's loss and gain along the leg's fixed loading axes (θD1, the
    leg's median θD): contacts per particle per radian along the opening direction
    n_ext = A - B cos 2(θp - θD1) and the closing one n_comp = A + B cos 2(θp - θD1),
    their initial rates per unit s over the first 0.05 (loss_rate = -dn_ext/ds / A(0),
    gain_rate = dn_comp/ds / A(0)) and the strains where each has covered 63 % of its way
    to its steady value; the strain where n_comp = n_ext (the fabric isotropic with
    respect to the loading) and the largest relative drop of A. None for other paths."""
    if meta["path"] not in TRANSIENT_PATHS:
        return None
    idx, s, n_comp, n_ext = second_leg(h, d)
    rp, c, a = h["RP"][idx], h["c"][idx], h["A"][idx]
    proj = 0.5 * (n_comp - n_ext)
    steady = s >= (1.0 - STEADY_FRACTION) * s.max()
    rp_ss = float(rp[steady].mean())
    early = s <= TRANSIENT
    i_min = int(np.argmin(np.where(early & (s > 0), rp, np.inf)))
    k = s <= 0.05
    slope = lambda y: float(np.polyfit(s[k], y[k], 1)[0])  # noqa: E731
    dc = c - c[0]
    return {**meta, "RP_start": float(rp[0]), "RP_steady": rp_ss, "RP_min": float(rp[i_min]),
            "s_min": float(s[i_min]),
            "contact_at_min": float(d["sff_contact"][idx][i_min]),
            "force_at_min": float(d["sff_force"][idx][i_min]),
            "noncoaxiality_at_min_deg": float(np.degrees(d["noncoaxiality"][idx][i_min])),
            "s_90": _first((s > s[i_min]) & (rp >= 0.9 * rp_ss), s),
            "dc_max": float(dc[early].max()), "s_dc_max": float(s[early][np.argmax(dc[early])]),
            "loss_rate": -slope(n_ext) / float(a[0]), "gain_rate": slope(n_comp) / float(a[0]),
            "s63_loss": _strain_to(0.63, n_ext, s, float(n_ext[steady].mean())),
            "s63_gain": _strain_to(0.63, n_comp, s, float(n_comp[steady].mean())),
            "s_isotropic": _first(n_comp >= n_ext, s),
            "dA_rel_min": float(np.min(a[early] / a[0] - 1.0)),
            "B_over_A_start": float(h["B"][idx][0] / a[0]),
            "B_over_A_steady": float(np.mean(proj[steady] / a[steady]))}


def _running_mean(y: np.ndarray, width: int = 5) -> np.ndarray:
    return np.convolve(y, np.ones(width) / width, mode="same")


def buildup_figures(meta: dict, h: dict, d: dict) -> dict | None:
    """The first leg of a path from isotropy (all but the axes rotation), against γs:
    the strains where the running mean over 5 rows of R/P, of α_D (the fabric's alignment
    with the loading) and of the force part ½(π_n + π_t) first reach 90 % of their mean
    over the leg's steady phase (the last STEADY_FRACTION), and those means."""
    if meta["path"] == "axes_rotation":
        return None
    m = d["leg"] == 0
    s = d["s"][m]
    steady = s >= (1.0 - STEADY_FRACTION) * s.max()
    out = dict(meta)
    for name, y in (("RP", h["RP"][m]), ("alpha_D", d["alpha_D"][m]), ("force", d["sff_force"][m])):
        ys = _running_mean(y)
        target = float(y[steady].mean())
        out[f"{name}_steady"] = target
        out[f"s90_{name}"] = _first(ys >= 0.9 * target, s)
    return out


def rotation_figures(meta: dict, h: dict, d: dict) -> dict | None:
    """The rotation stage of the axes rotation: mean lags of the fabric, the normal forces
    and the strain rate behind the stress axes (θσ - θp, θσ - θn, θσ - θD, degrees, folded
    into [-90, 90)), the mean anisotropies B/A and a_n, and the mean contact and force
    parts of R/P. None for other paths."""
    if meta["path"] != "axes_rotation":
        return None
    m = h["stage"] == 1
    lag = lambda th: float(np.degrees(np.mean(_angle(d["theta_sigma"][m] - th[m]))))  # noqa: E731
    return {**meta, "lag_fabric_deg": lag(h["theta_p"]), "lag_forces_deg": lag(h["theta_n"]),
            "noncoaxiality_deg": float(np.degrees(np.mean(d["noncoaxiality"][m]))),
            "B_over_A": float(d["a_c"][m].mean()), "a_n": float(h["a_n"][m].mean()),
            "contact": float(d["sff_contact"][m].mean()), "force": float(d["sff_force"][m].mean()),
            "RP": float(h["RP"][m].mean())}


def dilatancy_fits(runs: list[tuple[dict, dict, dict]], rows_from: str = "all") -> list[dict]:
    """Least squares of the dilatancy d on the stress-ratio gap, pooled over the runs other
    than the axes rotation (rows with a defined d past γs = 0.01; ``rows_from`` "all"
    or "after_change": only the second leg of the reversal and the change of direction),
    without and with the fabric's alignment with the loading:

    * ``rowe``:     d = k (R/P - M)                          (Rowe/Taylor, M fitted)
    * ``alignment``: d = k_f (α_D - α*) + d0                 (the fabric alone)
    * ``fabric``:   d = k (R/P - M) + k_f (α_D - α*)         (α*: the mean α_D of the
      steady phases, the alignment at the critical state)
    * ``state``:    ``fabric`` + k_c (c - c*)                 (c*: the steady phases' mean c)

    Each with its R², the coefficients and their standard errors, and M = -(-kM)/k."""
    x_rp, x_al, x_c, y, steady_al, steady_c = [], [], [], [], [], []
    for meta, h, d in runs:
        if meta["path"] == "axes_rotation":
            continue
        ph = phases(meta, h, d)
        ok = np.isfinite(d["dilatancy"]) & (d["gamma_s"] > 0.01)
        if rows_from == "after_change":
            ok &= (d["leg"] == 1) & (meta["path"] in TRANSIENT_PATHS)
        x_rp.append(h["RP"][ok]), x_al.append(d["alpha_D"][ok]), x_c.append(h["c"][ok])
        y.append(d["dilatancy"][ok])
        steady_al.append(d["alpha_D"][ph["steady"]]), steady_c.append(h["c"][ph["steady"]])
    if not y:
        return []
    rp, al, c, y = (np.concatenate(v) for v in (x_rp, x_al, x_c, y))
    a_star = float(np.concatenate(steady_al).mean())
    c_star = float(np.concatenate(steady_c).mean())
    one = np.ones_like(rp)
    designs = {"rowe": ([rp, one], ("k", "-kM")),
               "alignment": ([al - a_star, one], ("k_f", "d0")),
               "fabric": ([rp, al - a_star, one], ("k", "k_f", "-kM")),
               "state": ([rp, al - a_star, c - c_star, one], ("k", "k_f", "k_c", "-kM"))}
    out = []
    for name, (cols, names) in designs.items():
        x = np.stack(cols, axis=1)
        coef, *_ = np.linalg.lstsq(x, y, rcond=None)
        res = y - x @ coef
        cov = np.linalg.inv(x.T @ x) * float(res @ res) / max(1, y.size - x.shape[1])
        row = {"rows_from": rows_from, "model": name, "rows": int(y.size),
               "R2": float(1.0 - res @ res / np.sum((y - y.mean()) ** 2)),
               "alpha_star": a_star, "c_star": c_star}
        for n_, v, e in zip(names, coef, np.sqrt(np.diag(cov))):
            row[n_], row[n_ + "_se"] = float(v), float(e)
        if "k" in row:
            row["M"] = -row["-kM"] / row["k"]
        out.append(row)
    return out


def seed_means(table: list[dict], kind: str) -> list[dict]:
    """Per (path, density): the mean and the standard deviation over the seeds of every
    numeric figure of ``table`` (one row per figure)."""
    groups: dict[tuple, list] = {}
    for t in table:
        groups.setdefault((t["path"], t["density"]), []).append(t)
    skip = {"seed", "kappa", "n"}
    out = []
    for (path, dens), items in sorted(groups.items()):
        for k, v in items[0].items():
            if k in skip or not isinstance(v, float):
                continue
            x = np.array([it[k] for it in items], float)
            out.append({"kind": kind, "path": path, "density": dens, "figure": k,
                        "seeds": len(items), "mean": float(np.nanmean(x)),
                        "sd": float(np.nanstd(x, ddof=1)) if len(items) > 1 else math.nan})
    return out


def _label(meta):
    return f"{meta['path']} {meta['density']}"


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, file: Path) -> Path:
    with atomic_path(file) as tmp:
        fig.savefig(tmp, dpi=110)
    _plt().close(fig)
    return file


def plot_paths(runs, file: Path) -> Path:
    """R/P and its contact and force parts along every path (one panel per path; all
    seeds, thin)."""
    plt = _plt()
    labels = sorted({_label(m) for m, _, _ in runs})
    fig, axes = plt.subplots(len(labels), 1, figsize=(7, 2.3 * len(labels)), squeeze=False)
    for ax, lab in zip(axes[:, 0], labels):
        for i, (meta, h, d) in enumerate(r for r in runs if _label(r[0]) == lab):
            kw = {"lw": 0.8, "alpha": 0.8}
            ax.plot(d["gamma_s"], h["RP"], "k", label="R/P" if i == 0 else None, **kw)
            ax.plot(d["gamma_s"], d["sff_full"], "C3", label="full relation" if i == 0 else None, **kw)
            ax.plot(d["gamma_s"], d["sff_contact"], "C0", label="½π_c (contacts)" if i == 0 else None, **kw)
            ax.plot(d["gamma_s"], d["sff_force"], "C2", label="½(π_n+π_t) (forces)" if i == 0 else None, **kw)
        ax.axhline(0, color="0.6", lw=0.5)
        ax.set_title(lab, fontsize=9)
        ax.set_ylabel("ratio")
    axes[0, 0].legend(fontsize=7, ncol=4)
    axes[-1, 0].set_xlabel("accumulated shear strain γs")
    fig.tight_layout()
    return _save(fig, file)


def plot_reversal(runs, file: Path) -> Path:
    """The second leg of the reversal and change-of-direction runs against its shear
    strain (:func:`second_leg`): R/P with its parts, the contact densities along the
    closing and opening axes, and c."""
    plt = _plt()
    sel = [r for r in runs if r[0]["path"] in TRANSIENT_PATHS]
    labels = sorted({_label(m) for m, _, _ in sel})
    fig, axes = plt.subplots(3, len(labels), figsize=(4 * len(labels), 8), squeeze=False,
                             sharex=True)
    for j, lab in enumerate(labels):
        for i, (meta, h, d) in enumerate(r for r in sel if _label(r[0]) == lab):
            idx, s, n_comp, n_ext = second_leg(h, d)
            m = s <= 0.6
            idx, s, a0 = idx[m], s[m], h["A"][idx[0]]
            first = i == 0
            axes[0, j].plot(s, h["RP"][idx], "k", lw=0.8, label="R/P" if first else None)
            axes[0, j].plot(s, d["sff_contact"][idx], "C0", lw=0.8, label="½π_c" if first else None)
            axes[0, j].plot(s, d["sff_force"][idx], "C2", lw=0.8, label="½(π_n+π_t)" if first else None)
            axes[1, j].plot(s, n_comp[m] / a0, "C3", lw=0.8,
                            label="n_comp / A(0) (closing)" if first else None)
            axes[1, j].plot(s, n_ext[m] / a0, "C0", lw=0.8,
                            label="n_ext / A(0) (opening)" if first else None)
            axes[2, j].plot(s, h["c"][idx] - h["c"][idx[0]], "k", lw=0.8)
        axes[0, j].set_title(lab, fontsize=9)
        axes[0, j].axhline(0, color="0.6", lw=0.5)
        axes[2, 0].set_ylabel("c - c(start)")
        axes[2, j].set_xlabel("shear strain since the change of loading")
    axes[0, 0].set_ylabel("ratio")
    axes[1, 0].set_ylabel("contact density / A0")
    axes[0, 0].legend(fontsize=7)
    axes[1, 0].legend(fontsize=7)
    fig.tight_layout()
    return _save(fig, file)


def plot_scatter(runs, file: Path) -> Path:
    """R/P against the full relation (:func:`sff_ratio`), every row of every run, coloured
    by path."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5, 5))
    for k, lab in enumerate(sorted({_label(m) for m, _, _ in runs})):
        xs = np.concatenate([d["sff_full"] for m, h, d in runs if _label(m) == lab])
        ys = np.concatenate([h["RP"] for m, h, d in runs if _label(m) == lab])
        ax.plot(xs, ys, ".", ms=2, color=f"C{k}", label=lab)
    lim = [min(ax.get_xlim()[0], ax.get_ylim()[0]), max(ax.get_xlim()[1], ax.get_ylim()[1])]
    ax.plot(lim, lim, "k--", lw=0.7)
    ax.set_xlabel("½(π_c + π_n + π_t) / (1 + ½ a_c a_n cos 2(θp - θn))")
    ax.set_ylabel("R/P")
    ax.legend(fontsize=7, markerscale=4)
    fig.tight_layout()
    return _save(fig, file)


def plot_dilatancy(runs, fits: list[dict], file: Path) -> Path:
    """Dilatancy against the Rowe/Taylor gap R/P - M and against the ``fabric`` fit."""
    plt = _plt()
    fab = next(f for f in fits if f["model"] == "fabric" and f["rows_from"] == "all")
    rowe = next(f for f in fits if f["model"] == "rowe" and f["rows_from"] == "all")
    fig, ax = plt.subplots(1, 2, figsize=(10, 4.5))
    for k, lab in enumerate(sorted({_label(m) for m, _, _ in runs if m["path"] != "axes_rotation"})):
        sel = [(h, d) for m, h, d in runs if _label(m) == lab]
        rp = np.concatenate([h["RP"] for h, d in sel])
        al = np.concatenate([d["alpha_D"] for h, d in sel])
        y = np.concatenate([d["dilatancy"] for h, d in sel])
        ax[0].plot(rp - rowe["M"], y, ".", ms=2, color=f"C{k}", label=lab)
        pred = fab["k"] * rp + fab["k_f"] * (al - fab["alpha_star"]) + fab["-kM"]
        ax[1].plot(pred, y, ".", ms=2, color=f"C{k}")
    ax[0].set_xlabel(f"R/P - M (M = {rowe['M']:.3f})")
    ax[0].set_ylabel("dilatancy dε_v/dγs (dilation > 0)")
    ax[0].set_title(f"Rowe/Taylor: R² = {rowe['R2']:.2f}", fontsize=9)
    ax[1].set_xlabel("k (R/P - M) + k_f (α_D - α*)")
    ax[1].set_title(f"with the fabric's alignment: R² = {fab['R2']:.2f}", fontsize=9)
    for a in ax:
        a.axhline(0, color="0.6", lw=0.5)
        a.axvline(0, color="0.6", lw=0.5)
    lim = ax[1].get_xlim()
    ax[1].plot(lim, lim, "k--", lw=0.7)
    ax[0].legend(fontsize=7, markerscale=4)
    fig.tight_layout()
    return _save(fig, file)


def analyse(run_dirs: list[str | Path], out: str | Path, with_rows: bool = False) -> dict:
    """Everything of the module doc, for the runs in ``run_dirs``, written into ``out``
    (``rows.csv`` only ``with_rows``)."""
    if not run_dirs:
        raise ValueError("no run directories given")
    out = Path(out)
    runs = []
    for r in run_dirs:
        meta, h = read_run(r)
        runs.append((meta, h, derived(h, legs(meta, h))))
    if with_rows:
        cols = list(runs[0][1]) + list(DERIVED)
        rows = []
        for meta, h, d in runs:
            for i in range(len(h["tau"])):
                rows.append([meta["run"], meta["path"], meta["density"], meta["seed"]]
                            + [float(h[c][i]) if c in h else float(d[c][i]) for c in cols])
        write_csv(out / "rows.csv", ["run", "path_name", "density", "seed"] + cols, rows)
    corr = correlations(runs)
    trans = [t for t in (transient_figures(*r) for r in runs) if t is not None]
    build = [t for t in (buildup_figures(*r) for r in runs) if t is not None]
    rot = [t for t in (rotation_figures(*r) for r in runs) if t is not None]
    fits = dilatancy_fits(runs) + dilatancy_fits(runs, "after_change")
    means = (seed_means(trans, "transient") + seed_means(build, "buildup")
             + seed_means(rot, "rotation"))
    for name, table in (("correlations", corr), ("transients", trans), ("buildup", build),
                        ("rotation", rot), ("seed_means", means), ("dilatancy", fits)):
        if table:
            cols = list(dict.fromkeys(k for t in table for k in t))
            write_csv(out / f"{name}.csv", cols, [[t.get(k) for k in cols] for t in table])
    summary = {"runs": [m for m, _, _ in runs], "correlations": corr, "transients": trans,
               "buildup": build, "rotation": rot, "seed_means": means, "dilatancy": fits}
    write_json(out / "summary.json", summary)
    plot_paths(runs, out / "paths.png")
    if trans:
        plot_reversal(runs, out / "reversal.png")
    plot_scatter(runs, out / "scatter.png")
    plot_dilatancy(runs, fits, out / "dilatancy.png")
    return summary


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(prog="python -m dem.stress_force_fabric",
                                 description="Stress-force-fabric analysis of DEM runs "
                                             "(see the module doc); writes CSV, JSON and PNG.")
    ap.add_argument("runs", nargs="+", help="directories written by 'contfab dem run'")
    ap.add_argument("--out", required=True, help="output directory")
    ap.add_argument("--rows", action="store_true",
                    help="also write rows.csv (every history row with the derived columns)")
    args = ap.parse_args(argv)
    analyse(args.runs, args.out, with_rows=args.rows)
    print(f"wrote {args.out}/: {'rows.csv ' if args.rows else ''}correlations.csv transients.csv buildup.csv "
          f"rotation.csv seed_means.csv dilatancy.csv summary.json paths.png reversal.png scatter.png "
          f"dilatancy.png")


if __name__ == "__main__":
    main()
