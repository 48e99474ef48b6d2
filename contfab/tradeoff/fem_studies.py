"""FEM studies: the strip footing (:mod:`contfab.scenes.strip_footing`) over element × mesh × load step.

Each point is one footing analysis (tier 0, associated flow, the case's mesh family at
``level``, largest load step ``dt_max`` as a fraction of the push); the error is
|computed / exact - 1| of the bearing capacity factor: N_q against Prandtl–Reissner at the
parameter file's φ (weightless soil with a surcharge), N_γ against Martin's (2005) exact
14.75 at φ = 30° (rough footing). Cost: CPU seconds of the analysis.

The model tier is not a knob here: the exact factors hold for the constant-φ cone (tier 0);
tiers 1 and 2 carry φ(c) and the fabric, for which no closed form exists (their cost per
point is measured by ``contfab bench model``).

The biaxial shear band (:mod:`contfab.scenes.biaxial_shear_band`, dense tier 1, rough platens) over
element × mesh level: two errors, the peak σ1/σ3 against the closed form
(1 + sin φ0)/(1 − sin φ0) at the initial density, and the band angle at its onset (the
peak to a quarter of the post-peak drop, the case's ``onset_angle``) against Arthur's
45° + (φ0 + ψ0)/4 of the same peak state (the middle of the Roscoe–Coulomb range), relative. The post-peak
softening is not an error measure: without an internal length it depends on the mesh.
"""
from __future__ import annotations

import functools
import math

from contfab.scenes.case import load_case
from contfab.params import default_params, default_params_digest
from contfab.tradeoff.study import Clock, Study

CASE_DEFAULT = {"element": "P3", "level": 1, "dt_max": 0.05}
"""The footing case's own defaults (its element study's choice)."""


def run_point(study: Study, point: dict) -> dict:
    """One footing analysis at the point's element, level and load step."""
    case = load_case("strip_footing")
    factor = study.settings["factor"]
    params = default_params()
    _compiled(factor)
    phi = 30.0 if factor == "Ngamma" else params.tier0.phi_deg
    with Clock() as clock:
        r = case.solve(phi, phi, factor, point["element"], point["level"], params, None, False,
                       dt_max=point["dt_max"])
    return {"values": {"computed": r["computed"], "reference": r["reference"], "dofs": r["dofs"],
                       "steps": r["steps"]},
            "wall_s": clock.wall, "cpu_s": clock.cpu, "cost": clock.cpu}


@functools.cache
def _compiled(factor: str) -> None:
    """Compile (or load) the kernels once per process: a coarse P1 push in large steps."""
    params = default_params()
    load_case("strip_footing").solve(params.tier0.phi_deg, params.tier0.phi_deg, factor, "P1", 1,
                                     params, None, False, dt_max=0.5)


def evaluate(study, points, results):
    factor = study.settings["factor"]
    rows = [{"knobs": {k: p[k] for k in study.knobs},
             **{k: r[k] for k in ("wall_s", "cpu_s", "cost")},
             "errors": {factor: abs(r["values"]["computed"] / r["values"]["reference"] - 1.0)}}
            for p, r in zip(points, results)]
    notes = {"reference": results[0]["values"]["reference"],
             "DOFs per point": [r["values"]["dofs"] for r in results],
             "load steps per point": [r["values"]["steps"] for r in results]}
    return rows, notes


def _study(factor: str, fast: bool) -> Study:
    if fast:
        grid = [("P1", 1, 0.05), ("P2", 1, 0.05)]
    else:
        grid = [(e, lv, dt) for e in ("P2", "P3", "Q9") for lv in (1, 2, 3) for dt in (0.05, 0.2)]
    symbol = {"Nq": "N_q (Prandtl–Reissner)", "Ngamma": "N_γ (Martin 2005, φ = 30°)"}[factor]
    return Study(
        name=f"fem_footing_{factor.lower()}", knobs=("element", "level", "dt_max"),
        description=f"strip footing: element × mesh level × load step against {symbol}",
        points=tuple({"element": e, "level": lv, "dt_max": dt} for e, lv, dt in grid),
        run_point=run_point, evaluate=evaluate, default=CASE_DEFAULT, quantities=(factor,),
        cost_unit="CPU s per analysis", error_meaning=f"|{factor} / exact - 1|",
        settings={"factor": factor, "parameters": default_params_digest()})


def footing_nq_study(fast: bool) -> Study:
    return _study("Nq", fast)


def footing_ngamma_study(fast: bool) -> Study:
    return _study("Ngamma", fast)


BAND_DEFAULT = {"element": "P2", "level": 2}
"""The band case's defaults (level 1 puts the band 6° off: docs/fem_validation.md §3)."""


def run_band_point(study: Study, point: dict) -> dict:
    """One biaxial shear-band analysis at the point's element and level (the case's push)."""
    case = load_case("biaxial_shear_band")
    params = default_params()
    _compiled_band()
    with Clock() as clock:
        r = case.solve(params, point["element"], point["level"], 0.03, 0.04, None, False)
    values = {k: float(r[k]) for k in ("peak", "onset_angle", "phi0", "psi0", "end")}
    values["dofs"] = int(r["dofs"])
    return {"values": values, "wall_s": clock.wall, "cpu_s": clock.cpu, "cost": clock.cpu}


@functools.cache
def _compiled_band() -> None:
    load_case("biaxial_shear_band").solve(default_params(), "P1", 1, 0.03, 0.002, None, False)


def evaluate_band(study, points, results):
    rows = []
    for p, r in zip(points, results):
        v = r["values"]
        s = math.sin(math.radians(v["phi0"]))
        arthur = 45.0 + (v["phi0"] + v["psi0"]) / 4.0
        rows.append({"knobs": {k: p[k] for k in study.knobs},
                     **{k: r[k] for k in ("wall_s", "cpu_s", "cost")},
                     "errors": {"peak": abs(v["peak"] * (1 - s) / (1 + s) - 1.0),
                                "angle": abs(v["onset_angle"] / arthur - 1.0)}})
    notes = {"band angles at onset (deg)": [r["values"]["onset_angle"] for r in results],
             "peaks sigma1/sigma3": [r["values"]["peak"] for r in results],
             "DOFs per point": [r["values"]["dofs"] for r in results]}
    return rows, notes


def band_study(fast: bool) -> Study:
    grid = [("P2", 1), ("P2", 2)] if fast else [(e, lv) for e in ("P2", "Q9") for lv in (1, 2, 3)]
    return Study(
        name="fem_band", knobs=("element", "level"),
        description="biaxial shear band (dense tier 1): element × mesh level against the peak "
                    "closed form and Arthur's angle of the band at onset",
        points=tuple({"element": e, "level": lv} for e, lv in grid),
        run_point=run_band_point, evaluate=evaluate_band, default=BAND_DEFAULT,
        quantities=("peak", "angle"), cost_unit="CPU s per analysis",
        error_meaning="|peak / closed form - 1| and |onset angle / Arthur - 1|",
        settings={"dense": 0.03, "strain": 0.04, "angle": "onset",
                  "parameters": default_params_digest()})
