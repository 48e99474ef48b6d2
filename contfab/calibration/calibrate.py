"""``contfab calibrate``: the model's parameters from the embedded DEM (docs/theory.md §12).

1. **DEM campaign** (:mod:`contfab.calibration.campaign`): dense and loose biaxial at the fitted κ,
   simple shear at constant normal stress with a reversal, isotropic compression (fitted);
   held-out paths; the stress-probing runs. K seeds each, through an executor
   (:mod:`contfab.executor`), resumable.
2. **Fit** (:mod:`contfab.calibration.fitting`), on the seed-mean DEM curves of the fitted paths:
   tier 1 (φ*, φ', ψ', c*; quantities R/P, c); for tier 2, for *both* fabric laws, first the
   law's coefficients alone on the fabric (A, Bc, Bs) with the cone reduced to tier 1's
   (fabric weight w = 0 and k_d = 0: the fabric then does not feed back on the stress),
   then, at the template's w, the cone's dilatancy slope k_d, the critical anisotropy b_c
   and the law's coefficients together on R/P, c, A, Bc, Bs
   (:func:`contfab.calibration.fitting.tier2_spec`). The law with the smaller error on the
   held-out paths goes into ``[tier2]``; both are written.
   Tier 0 is set to the critical state of tier 1 (φ = φ*, ψ = 0).
3. **Evaluation**: every model on every path (fitted and held out), errors per path and
   quantity (:func:`contfab.calibration.curves.errors`), and stress probing (:mod:`contfab.calibration.probing`):
   DEM per seed, the models from their own state at the same point of the preload path
   (probes 100 times smaller: the model's incremental response; the DEM needs finite
   probes to rise above its noise).
4. **Files** in the output directory: ``params.toml`` (the calibrated parameter file, with
   a ``[provenance]`` table: command, DEM settings, seeds, code version, timing, the fitted
   values with their seed-scatter uncertainty, fit residuals per path and quantity, held-out
   errors, the law choice, probing angles), ``params_tier2_<law>.toml`` for each law,
   ``report/<path>.png`` overlays, ``report/errors.csv`` / ``errors.md``,
   ``report/probing.png``, ``report/curves/<path>.csv`` (DEM seed-mean curves),
   ``report/report.md`` (the summary) and ``report/summary.json``.

The template values of everything not fitted (regularization λ = 1000, ν = 0; tier 1's
clamps; the ``[tier2]`` defaults of :class:`contfab.params.Tier2`, the fabric weight among
them; the initial state = the dense samples' mean prepared state) are in :data:`TEMPLATE`
and :func:`template`.
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, replace
from pathlib import Path as FsPath
from typing import Mapping, Sequence

import numpy as np

from contfab.calibration import fitting
from contfab.calibration.campaign import ROLES, CampaignSettings, Layout, run_campaign
from contfab.calibration.curves import curve_table, dem_curve, read_history
from contfab.executor import make_executor
from contfab.params import Params
from contfab.toml_writer import dumps
from dem.fileio import atomic_path, write_csv, write_json
from dem.paths import load_path
from dem.provenance import code_versions

LAW_NAMES = ("balance", "relaxation")
MODEL_PROBE_SCALE = 0.01
TEMPLATE = {
    "regularization": {"lambda": 1000.0, "p_ref": 1.0, "nu": 0.0},
    "tier1": {"dphi_dc_deg": 200.0, "dpsi_dc_deg": 200.0, "phi_min_deg": 8.0, "phi_max_deg": 60.0},
}
"""Values not taken from the DEM: the regularization, tier 1's clamps (φ_min = 8° keeps tier
2's cone radius sin φ - w b_c positive over the fit's bounds of b_c), and the fit's start
values of φ', ψ'; ``[tier2]`` starts at :class:`contfab.params.Tier2`'s defaults (φ*, c*,
z_crit, B/A and the initial state come from the DEM curves, :func:`template`)."""


# --------------------------------------------------------------------------- DEM curves

def load_targets(cs: CampaignSettings, layout: Layout) -> dict[str, list[fitting.Target]]:
    """{role: [targets]}: seed-mean curves of every run (one target per probe for a probe
    family)."""
    out: dict[str, list[fitting.Target]] = {role: [] for role in ROLES}
    for spec in cs.runs:
        path = load_path(spec.path)
        subs = path.expand()
        for k, sub in enumerate(subs):
            csv = "history.csv" if len(subs) == 1 else f"history_{k}.csv"
            hist = [read_history(layout.run(spec.name, s) / csv) for s in cs.seeds]
            name = spec.name if len(subs) == 1 else f"{spec.name}_{sub.name.rsplit('/', 1)[-1]}"
            origin = {"path": spec.path, "probe": k if len(subs) > 1 else -1, "role": spec.role,
                      "density": spec.density, "kappa": spec.kappa}
            out[spec.role].append(fitting.Target(name, sub, dem_curve(sub, hist), origin))
    return out


def _residual(targets, q, fn=np.nanmean) -> float:
    vals = []
    for t in targets:
        w = t.curve.grid.residual_window()
        vals.append(fn(t.curve.mean[q][w]))
    return float(np.nanmean(vals))


def template(cs: CampaignSettings, targets: Sequence[fitting.Target], tier: int) -> Params:
    """The starting parameter set: :data:`TEMPLATE` plus the DEM's steady R/P, c, z, B/A
    (φ* = asin of the mean residual R/P of the fitted shear paths, c* their mean residual c)
    and the dense samples' prepared state as ``[initial]``."""
    sheared = [t for t in targets if not t.name.startswith("isotropic")] or list(targets)
    rp = _residual(sheared, "RP")
    bound = fitting.TIER1[0]
    phi = min(max(math.degrees(math.asin(min(max(rp, 0.0), 0.9))), bound.lo), bound.hi)
    a_res, b_res = _residual(sheared, "A"), _residual(sheared, "B")
    dense = [t for t in targets if "_dense_" in t.name] or list(targets)
    c0 = float(np.mean([t.curve.start["c"] for t in dense]))
    a0 = float(np.mean([t.curve.start["A"] for t in dense]))
    doc = {
        "tier": tier,
        "regularization": dict(TEMPLATE["regularization"]),
        "tier0": {"phi_deg": phi, "psi_deg": 0.0},
        "tier1": {"phi_star_deg": phi, "c_star": _residual(sheared, "c"), **TEMPLATE["tier1"]},
        "tier2": {"fabric_law": "balance",
                  "z_crit": min(max(math.pi * a_res, 1.6), 3.9),
                  "b_ratio_crit": min(max(b_res / a_res, 0.01), fitting.B_RATIO_CRIT.hi)},
        "initial": {"c0": c0, "A0": a0, "B0": 0.0, "theta_p0_deg": 0.0},
    }
    return Params.from_dict(doc, source="contfab.calibration.calibrate template")


# --------------------------------------------------------------------------- fits

MAX_NFEV = 40
"""Default least-squares evaluations per fit stage (each costs one model run per target;
the forward-difference Jacobian another one per fitted parameter)."""


def fit_tier1(start: Params, targets, progress: bool, max_nfev: int = MAX_NFEV) -> fitting.FitResult:
    res = fitting.fit(start, 1, fitting.TIER1, targets, max_nfev=max_nfev, progress=progress,
                      desc="fit tier 1")
    phi = res.params.tier1.phi_star_deg
    res.params = res.params.replace("tier0", phi_deg=phi, psi_deg=0.0)
    return res


def fit_tier2(tier1: Params, law: str, targets, scale, progress: bool,
              max_nfev: int = MAX_NFEV) -> fitting.FitResult:
    """Law coefficients alone on the fabric (the cone reduced to tier 1's), then the cone's
    and the law's together at the template's fabric weight (module doc)."""
    p = tier1.replace("tier2", fabric_law=float(tier1.tier2.LAWS[law])).with_tier(2)
    coupled = {k: getattr(p.tier2, k) for k in ("fabric_weight", "dilatancy_fabric")}
    first = fitting.fit(p.replace("tier2", fabric_weight=0.0, dilatancy_fabric=0.0), 2,
                        fitting.LAWS[law], targets, quantities=("A", "Bc", "Bs"),
                        scale=scale, max_nfev=max_nfev, progress=progress,
                        desc=f"fit tier 2 {law} (fabric law)")
    return fitting.fit(first.params.replace("tier2", **coupled), 2, fitting.tier2_spec(law),
                       targets, scale=scale, max_nfev=max_nfev, progress=progress,
                       desc=f"fit tier 2 {law} (all)")


def objective(params: Params, tier: int, targets, scale) -> float:
    """½ Σ r² of ``params`` on ``targets`` with the tier's fitted quantities."""
    samples = [fitting.run_model(params, tier, t)[0] for t in targets]
    r = fitting.residuals(samples, [t.curve.mean for t in targets], targets,
                          fitting.TIER_QUANTITIES[tier], scale)
    return 0.5 * float(r @ r)


# --------------------------------------------------------------------------- probing

def dem_probing(cs: CampaignSettings, layout: Layout) -> dict:
    """Per-seed DEM probe analyses and their mean ± sd."""
    from contfab.calibration.probing import analyse, probe_response

    fam = load_path(layout.probes_path)
    n = len(fam.expand())
    per_seed, responses = [], []
    for s in cs.seeds:
        d = layout.run(f"{Layout.PROBES}_loose_k{cs.probe_kappa:g}", s)
        resp = probe_response([read_history(d / f"history_{k}.csv") for k in range(n)])
        responses.append(resp)
        per_seed.append(analyse(resp))
    pre = [read_history(layout.run(f"{Layout.PRELOAD}_loose_k{cs.probe_kappa:g}", s) / "history.csv")
           for s in cs.seeds]
    return {"analyses": per_seed, "responses": responses, "preload": pre,
            "start": {q: float(np.mean([h[q][0] for h in pre])) for q in ("c", "A", "Bc", "Bs")},
            "state": {q: float(np.mean([h[q][-1] for h in pre])) for q in ("RP", "c", "P")}}


def model_probing(params: Params, tier: int, layout: Layout, start: Mapping[str, float]):
    """(response, analysis, preload result) of the model: the preload path from the DEM's
    mean start state, then the probe family (magnitude × MODEL_PROBE_SCALE) from its end."""
    from contfab import material_point as mp
    from contfab.calibration.curves import history_of
    from contfab.calibration.probing import analyse, probe_response

    state0 = {"c": start["c"]} if tier < 2 else dict(start)
    pre = mp.run_path(load_path(layout.preload_path), params, tier, state0=state0)
    fam = load_path(layout.probes_path)
    fam = replace(fam, probes=replace(fam.probes, magnitude=fam.probes.magnitude * MODEL_PROBE_SCALE))
    runs = mp.run_family(fam, params, tier, start=pre)
    resp = probe_response([history_of(r) for r in runs])
    return resp, analyse(resp), pre


# --------------------------------------------------------------------------- the command

def _models(tier: int, fits: Mapping[str, fitting.FitResult]) -> dict[str, tuple[Params, int]]:
    models = {"tier 0": (fits["tier1"].params.with_tier(0), 0),
              "tier 1": (fits["tier1"].params.with_tier(1), 1)}
    if tier == 2:
        for law in LAW_NAMES:
            models[f"tier 2 {law}"] = (fits[law].params, 2)
    return models


def calibrate(out: str | FsPath, tier: int = 2, campaign: CampaignSettings | None = None,
              executor: str = "serial", workers: int | None = None, scheduler: str | None = None,
              progress: bool = True, command: str = "", max_nfev: int = MAX_NFEV
              ) -> dict[str, FsPath]:
    """Run the campaign, fit, evaluate and write the files of the module doc into ``out``;
    returns {what: file}."""
    if tier not in (1, 2):
        raise ValueError(f"--tier {tier!r} out of range; accepted 1 or 2 (tier 2 also fits tier 1, "
                         f"whose c-terms it reads)")
    cs = campaign or CampaignSettings()
    cs.validate()
    out = FsPath(out)
    t0 = time.perf_counter()
    from contfab.calibration.campaign import warm_kernels
    with make_executor(executor, workers, scheduler, warm=warm_kernels) as ex:
        layout = run_campaign(cs, out, ex)
    t_dem = time.perf_counter() - t0
    targets = load_targets(cs, layout)
    fit_t, held = targets["fit"], targets["heldout"]
    start = template(cs, fit_t, tier)
    fits: dict[str, fitting.FitResult] = {"tier1": fit_tier1(start, fit_t, progress, max_nfev)}
    scale = fitting.scales(fit_t)
    choice = None
    heldout_objective = {}
    if tier == 2:
        for law in LAW_NAMES:
            fits[law] = fit_tier2(fits["tier1"].params, law, fit_t, scale, progress, max_nfev)
            heldout_objective[law] = (objective(fits[law].params, 2, held, scale) if held
                                      else math.nan)
        choice = min(LAW_NAMES, key=lambda law: (heldout_objective[law]
                                                 if math.isfinite(heldout_objective[law])
                                                 else fits[law].cost))
    t_fit = time.perf_counter() - t0 - t_dem
    final = (fits[choice].params if tier == 2 else fits["tier1"].params).with_tier(tier)
    models = _models(tier, fits)
    written = _evaluate_and_report(out, cs, layout, targets, models, progress)
    probing = _probing(cs, layout, models, out) if cs.probe else {}
    written.update(probing.pop("files", {}))
    seconds = {"dem": t_dem, "fit": t_fit, "total": time.perf_counter() - t0}
    summary = _summary(cs, tier, fits, choice, heldout_objective, written.pop("rows"), probing,
                       seconds, command, max_nfev)
    header = (f"contfab model parameters, calibrated from the embedded DEM by\n"
              f"  {command or 'contfab calibrate'}\n"
              f"([provenance] records the DEM settings, seeds, code version, fit residuals per\n"
              f"path and quantity; regenerate with the same command). Units: angles in degrees,\n"
              f"stresses in units of p_ref, A = z/pi.")
    doc = {**final.to_dict(), "provenance": summary["provenance"]}
    written["params"] = _write_toml(out / "params.toml", doc, header)
    if tier == 2:
        for law in LAW_NAMES:
            written[f"params_{law}"] = _write_toml(
                out / f"params_tier2_{law}.toml",
                {**fits[law].params.to_dict(), "provenance": summary["provenance"]},
                header + f"\nThis file: tier 2 with the {law} fabric law.")
    written["summary"] = write_json(out / "report" / "summary.json", summary)
    written["report"] = _write_markdown(out / "report" / "report.md", summary)
    return written


def _write_toml(file: FsPath, doc: Mapping, header: str) -> FsPath:
    with atomic_path(file) as tmp:
        tmp.write_text(dumps(doc, header))
    return file


def _evaluate_and_report(out: FsPath, cs, layout, targets, models, progress) -> dict:
    from contfab.calibration.curves import errors
    from contfab.calibration.report import error_rows, overlay_plot, write_tables

    rows, written = [], {}
    every = [(role, t) for role in ROLES for t in targets[role]]
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(every), desc="evaluate and plot", unit="path")
    for role, t in every:
        samples = {}
        for name, (params, tier) in models.items():
            samples[name] = fitting.run_model(params, tier, t)[0]
            rows += error_rows(role, t.name, name, errors(t.curve, samples[name]))
        written[f"plot_{t.name}"] = overlay_plot(t.curve, samples, out / "report" / f"{t.name}.png",
                                                 f"{t.name} ({role}): DEM N = {cs.n}, "
                                                 f"{len(cs.seeds)} seeds, vs models")
        written[f"curve_{t.name}"] = write_csv(out / "report" / "curves" / f"{t.name}.csv",
                                               *curve_table(t.curve))
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    written["errors_csv"], written["errors_md"] = write_tables(rows, out / "report" / "errors")
    written["reference"] = _write_reference(out / "report" / "reference", cs, every, models)
    written["rows"] = rows
    return written


REFERENCE_ROWS = 60


def _write_reference(folder: FsPath, cs, every, models) -> FsPath:
    """Small DEM reference curves (at most REFERENCE_ROWS points each) with an index of
    their runs, start states and the errors of the calibrated models on exactly these
    stored curves: the data of tests/test_material_point_vs_dem.py (copied to
    tests/data/dem_reference)."""
    from contfab.calibration.curves import errors, read_curve

    index = {"generated_by": "contfab calibrate: report/reference of the campaign directory",
             "campaign": {k: v for k, v in cs.to_dict().items() if k != "runs"}, "curves": {}}
    for role, t in every:
        file = write_csv(folder / f"{t.name}.csv", *curve_table(t.curve, REFERENCE_ROWS))
        stored = fitting.Target(t.name, t.path, read_curve(file, t.curve.start), t.origin)
        errs = {name: errors(stored.curve, fitting.run_model(params, tier, stored)[0])
                for name, (params, tier) in models.items()}
        index["curves"][t.name] = {**t.origin, "file": file.name, "start": t.curve.start,
                                   "errors": errs}
    return write_json(folder / "index.json", index)


def _probing(cs, layout, models, out: FsPath) -> dict:
    from contfab.calibration.report import probe_plot

    dem = dem_probing(cs, layout)
    result = {"dem": _mean_sd([a.to_dict() for a in dem["analyses"]]),
              "dem_state": dem["state"], "models": {}}
    responses = {"DEM seed 1": dem["responses"][0]}
    analyses = {"DEM seed 1": dem["analyses"][0]}
    for name, (params, tier) in models.items():
        if tier < 2:        # the isotropic cone's flow direction, whatever the probes do
            result["models"][name] = {"closed_form": _cone_probe(params, tier, dem["state"]["c"])}
        if tier == 0:       # perfectly plastic: a stress probe outward has no solution
            continue
        try:
            resp, ana, pre = model_probing(params, tier, layout, dem["start"])
        except ValueError as exc:           # the model cannot follow the preload or probes
            result["models"][name] = {**result["models"].get(name, {}), "error": str(exc)}
            continue
        result["models"][name] = {**result["models"].get(name, {}), **ana.to_dict(),
                                  "RP": float(pre["RP"][-1]), "c": float(pre["c"][-1])}
        responses[name], analyses[name] = resp, ana
    result["files"] = {"probing_plot": probe_plot(responses, analyses, out / "report" / "probing.png",
                                                  "stress probing: plastic strain directions")}
    return result


def _cone_probe(params: Params, tier: int, c: float) -> dict:
    """Yield normal, flow direction and non-associativity δ (degrees) of the isotropic cone
    at packing fraction ``c`` (:func:`contfab.calibration.probing.cone_angles`): what the probes of a
    tier-0/1 point must find, and its answer where they have none (at zero hardening an
    outward stress probe has no bounded solution)."""
    from contfab.models import cone
    from contfab.calibration.probing import cone_angles

    if tier == 0:
        phi, psi = math.radians(params.tier0.phi_deg), math.radians(params.tier0.psi_deg)
    else:
        phi, psi = cone.tier1_angles(c, params.array(1))[:2]
    normal, flow, delta = cone_angles(math.sin(phi), math.sin(psi))
    return {"normal_deg": normal, "flow_deg": flow, "delta_deg": delta, "c": float(c)}


def _mean_sd(dicts: Sequence[Mapping[str, float]]) -> dict:
    keys = dicts[0].keys()
    return {k: {"mean": float(np.mean([d[k] for d in dicts])),
                "sd": float(np.std([d[k] for d in dicts], ddof=1)) if len(dicts) > 1 else math.nan}
            for k in keys}


def acceptance_rows(rows: Sequence[Mapping], models: Sequence[str]) -> list[dict]:
    """Acceptance 1 per fitted path and model: residual R/P and c errors, and for tier 2
    the relative residual A and B errors, each with its bound and verdict."""
    out = []
    bounds = {"RP": ("residual_error", 0.02), "c": ("residual_error", 0.005),
              "A": ("residual_rel", 0.10), "B": ("residual_rel", 0.10)}
    for r in rows:
        if (r["role"] != "fit" or r["model"] not in models or r["model"] == "tier 0"
                or r["quantity"] not in bounds):
            continue
        if r["quantity"] in ("A", "B") and not r["model"].startswith("tier 2"):
            continue
        key, bound = bounds[r["quantity"]]
        v = r[key]
        out.append({"path": r["path"], "model": r["model"], "quantity": r["quantity"],
                    "measure": key, "value": v, "bound": bound,
                    "dem_scatter": r["dem_scatter"],
                    "pass": bool(math.isfinite(v) and abs(v) <= bound)})
    return out


TRANSIENT_PATHS = ("simple_shear_reversal", "direction_change")


def transient_rows(rows: Sequence[Mapping]) -> list[dict]:
    """Where fabric matters — after the shear reversal and the 90° change of direction —
    each model's RMS error over the transient (:data:`contfab.calibration.curves.TRANSIENT_LENGTH` of
    the last stage) and over the whole path, and its ratio to tier 1's."""
    out = []
    keyed = {(r["path"], r["model"], r["quantity"]): r for r in rows}
    for (path, model, q), r in keyed.items():
        if not path.startswith(TRANSIENT_PATHS) or q not in ("RP", "eps_v", "B", "theta_p"):
            continue
        t1 = keyed.get((path, "tier 1", q))
        ratio = (r["rms_transient"] / t1["rms_transient"]
                 if t1 and t1["rms_transient"] and math.isfinite(t1["rms_transient"]) else math.nan)
        out.append({"path": path, "model": model, "quantity": q, "rms_transient": r["rms_transient"],
                    "rms": r["rms"], "transient_vs_tier1": ratio})
    return out


def _summary(cs, tier, fits, choice, heldout_objective, rows, probing, seconds, command,
             max_nfev) -> dict:
    fit_tables = {name: f.table() for name, f in fits.items()}
    models = [r["model"] for r in rows]
    provenance = {
        "command": command or "contfab calibrate",
        "created": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "versions": code_versions(),
        "seconds": seconds,
        "max_nfev": max_nfev,
        "campaign": {k: v for k, v in cs.to_dict().items() if k != "runs"},
        "runs": {spec.name: asdict(spec) for spec in cs.runs},
        "fabric_law_choice": choice or "",
        "heldout_objective": {k: v for k, v in heldout_objective.items()},
        "fitted": {name: {f"{p['section']}.{p['key']}": {"value": p["value"], "stderr": p["stderr"],
                                                       "single_seed_sd": p["scatter"]}
                          for p in table} for name, table in fit_tables.items()},
        "fit_cost": {name: f.cost for name, f in fits.items()},
        "residuals": {},
    }
    for r in rows:
        if r["role"] == "fit":
            key = r["model"].replace(" ", "_")
            provenance["residuals"].setdefault(r["path"], {}).setdefault(key, {})[r["quantity"]] = {
                "rms": r["rms"], "residual_error": r["residual_error"]}
    if probing:
        provenance["probing_nonassociativity_deg"] = {
            "DEM": probing["dem"]["nonassociativity_deg"]["mean"],
            **{k: v.get("nonassociativity_deg", math.nan) for k, v in probing["models"].items()},
            **{f"{k} closed form": v["closed_form"]["delta_deg"]
               for k, v in probing["models"].items() if "closed_form" in v}}
    return {"provenance": provenance, "acceptance": acceptance_rows(rows, sorted(set(models))),
            "transients": transient_rows(rows),
            "errors": rows, "probing": probing, "fits": fit_tables, "tier": tier,
            "fabric_law_choice": choice, "heldout_objective": heldout_objective,
            "seconds": seconds}


def _write_markdown(file: FsPath, s: Mapping) -> FsPath:
    from contfab.calibration.report import markdown_table

    lines = [f"# Calibration report\n", f"Command: `{s['provenance']['command']}`  ",
             f"Wall time: DEM {s['seconds']['dem']:.0f} s, fit {s['seconds']['fit']:.0f} s, "
             f"total {s['seconds']['total']:.0f} s.\n",
             "## Fitted parameters (± standard error of the seed-mean fit; single-seed sd)\n"]
    for name, table in s["fits"].items():
        lines.append(f"### {name}\n")
        lines.append(markdown_table(table, ("section", "key", "value", "stderr", "scatter",
                                            "lo", "hi", "at_bound")))
    if s["fabric_law_choice"]:
        lines.append(f"Fabric law chosen on the held-out paths: **{s['fabric_law_choice']}** "
                     f"(held-out objective {s['heldout_objective']}).\n")
    lines.append("## Acceptance 1: residuals on the fitted paths\n")
    lines.append(markdown_table(s["acceptance"], ("path", "model", "quantity", "measure", "value",
                                                  "bound", "dem_scatter", "pass")))
    lines.append("## Where fabric matters: transients after the reversal and the change of "
                 "direction (RMS over the first 0.1 of the last stage; ratio to tier 1)\n")
    lines.append(markdown_table(s["transients"], ("path", "model", "quantity", "rms_transient",
                                                  "rms", "transient_vs_tier1")))
    lines.append("## Errors per path, model and quantity (θp in degrees)\n")
    from contfab.calibration.report import ERROR_COLUMNS
    lines.append(markdown_table(s["errors"], ERROR_COLUMNS))
    if s["probing"]:
        p = s["probing"]
        lines.append("## Stress probing (non-associativity angle δ = normal - flow, degrees)\n")
        rows = [{"who": "DEM (mean over seeds)", **{k: v["mean"] for k, v in p["dem"].items()},
                 "sd": p["dem"]["nonassociativity_deg"]["sd"]}]
        for k, v in p["models"].items():
            rows.append({"who": k, **{q: x for q, x in v.items() if q != "closed_form"}})
            if "closed_form" in v:
                cf = v["closed_form"]
                rows.append({"who": f"{k}, closed form at c = {cf['c']:.4f}", "normal_deg": cf["normal_deg"],
                             "flow_deg": cf["flow_deg"], "nonassociativity_deg": cf["delta_deg"]})
        lines.append(markdown_table(rows, ("who", "normal_deg", "flow_deg", "nonassociativity_deg",
                                           "sd", "sin_psi", "fit_r2", "plastic_max")))
        lines.append(f"DEM state probed: {p['dem_state']}\n")
    with atomic_path(file) as tmp:
        tmp.write_text("\n".join(lines))
    return file

