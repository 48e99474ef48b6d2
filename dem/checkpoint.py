"""Checkpoints: the full state of a run in ONE file, written atomically.

A checkpoint is a NumPy ``.npz`` archive holding every array of the
:class:`dem.state.State` (positions, velocities, spins, forces, the cell, the whole pair
list with its tangential histories, the servo integral, the accumulators) except the
per-disc incidence index, which is derived from the pair list and rebuilt on load, the
reference arrays of a :class:`dem.rve.PathRun`, and one JSON document (``meta``) with
the scalars: step, pair count, RNG state, the dynamics (contact law, dt, skin, servo
constants), the run's progress and history rows, and free-form settings.

Because the neighbour list itself is saved, a resumed run rebuilds its lists at exactly
the same steps as an uninterrupted one, sums forces in the same order, and is bitwise
identical to it. Loading the same file several times clones a state, e.g. to probe it
along many paths.
"""
from __future__ import annotations

import json
import os
from dataclasses import fields

import numpy as np

from dem.contact_law import STYLES, ContactLaw
from dem.fileio import atomic_path
from dem.integrator import Dynamics
from dem.neighbours import incidence
from dem.rve import PathRun
from dem.state import HIST, State

FORMAT = "contfab-dem-checkpoint-1"
_RUN_ARRAYS = ("ref_su", "ref_h", "ref_acc")
_DERIVED = ("inc_ptr", "inc")
"""State arrays rebuilt from the pair list on load (:func:`dem.neighbours.incidence`)."""


class CheckpointError(ValueError):
    """Not a readable checkpoint file."""


def dynamics_dict(dyn: Dynamics) -> dict:
    law = dyn.law
    return {"kn": law.kn, "kt_ratio": law.kt_ratio, "e": law.e, "mu": law.mu,
            "mu_roll": law.mu_roll, "style": law.style, "dt": dyn.dt, "skin": dyn.skin,
            "gdot_ref": dyn.gdot_ref, "tau_servo": dyn.tau_servo, "l_max": dyn.l_max}


def dynamics_from(d: dict) -> Dynamics:
    law = ContactLaw(kn=d["kn"], kt_ratio=d["kt_ratio"], e=d["e"], mu=d["mu"],
                     mu_roll=d["mu_roll"],
                     style=d.get("style", STYLES[0]))  # written before the styles: the default
    return Dynamics(law, d["dt"], d["skin"], d["gdot_ref"], d["tau_servo"], d["l_max"])


def save(file: str | os.PathLike, state: State, dyn: Dynamics, run: PathRun | None = None,
         settings: dict | None = None) -> str:
    """Write the checkpoint atomically (temporary name, then rename); returns the path."""
    arrays = {f"state/{k}": v for k, v in state.arrays().items() if k not in _DERIVED}
    meta = {"format": FORMAT, "step": state.step, "n_pairs": state.n_pairs,
            "rebuilds": state.rebuilds, "rng_state": state.rng_state,
            "dynamics": dynamics_dict(dyn), "settings": settings or {}, "run": None}
    if run is not None:
        meta["run"] = {k: v for k, v in run.__dict__.items() if k not in _RUN_ARRAYS}
        for k in _RUN_ARRAYS:
            if getattr(run, k) is not None:
                arrays[f"run/{k}"] = getattr(run, k)
    arrays["meta"] = np.frombuffer(json.dumps(meta, default=_plain).encode(), dtype=np.uint8)
    with atomic_path(file) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
    return os.fspath(file)


def load(file: str | os.PathLike) -> tuple[State, Dynamics, PathRun | None, dict]:
    """(state, dynamics, run or None, settings) from a checkpoint file."""
    try:
        with np.load(file, allow_pickle=False) as z:
            meta = json.loads(bytes(z["meta"]).decode())
            if meta.get("format") != FORMAT:
                raise CheckpointError(f"{file}: not a DEM checkpoint (format {meta.get('format')!r})")
            kw = {f.name: z[f"state/{f.name}"].copy() for f in fields(State)
                  if f"state/{f.name}" in z.files and f.name not in _DERIVED}
            run_arrays = {k: z[f"run/{k}"].copy() for k in _RUN_ARRAYS if f"run/{k}" in z.files}
    except (OSError, KeyError, ValueError) as exc:
        if isinstance(exc, CheckpointError):
            raise
        raise CheckpointError(f"{file}: cannot read checkpoint ({exc})") from exc
    if "stress_contact" not in kw:       # written before the servo held the contact stress
        vol = float(np.linalg.det(kw["h"]))
        mv = kw["mass"][:, None] * kw["v"]
        kin = np.array([mv[:, 0] @ kw["v"][:, 0], mv[:, 1] @ kw["v"][:, 1], mv[:, 0] @ kw["v"][:, 1]])
        kw["stress_contact"] = kw["stress"] + kin / vol
    kw.setdefault("stress_damping", np.zeros(3))  # written before the servo split it off
    hist = kw["pair_hist"]
    if hist.shape[1] < HIST:  # written before the tangential dashpot: its force is 0
        kw["pair_hist"] = np.concatenate([hist, np.zeros((hist.shape[0], HIST - hist.shape[1]))], 1)
    kw["inc_ptr"], kw["inc"] = incidence(kw["pair_ij"], meta["n_pairs"], kw["radius"].shape[0])
    state = State(**kw, n_pairs=meta["n_pairs"], step=meta["step"], rng_state=meta["rng_state"],
                  rebuilds=meta["rebuilds"])
    run = None
    if meta["run"] is not None:
        run = PathRun(**meta["run"], **run_arrays)
    return state, dynamics_from(meta["dynamics"]), run, meta["settings"]


def _plain(obj):
    if hasattr(obj, "tolist"):
        return obj.tolist()
    raise TypeError(f"not JSON serializable: {type(obj).__name__}")
