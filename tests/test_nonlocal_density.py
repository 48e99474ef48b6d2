"""The nonlocal packing fraction (contfab.fem.nonlocal_density): the averaging operator's
exactness properties, and the local model recovered exactly as the internal length vanishes."""
import numpy as np
import pytest

from contfab.fem import mesh as meshes
from contfab.fem.assembly import Discretization
from contfab.fem.material import TierMaterial
from contfab.fem.nonlocal_density import NonlocalMaterial, averaging_matrix
from contfab.params import ParamError, default_params


def lattice(n: int, a: float) -> np.ndarray:
    """The n × n square lattice of spacing a."""
    x, y = np.meshgrid(np.arange(n) * a, np.arange(n) * a)
    return np.column_stack((x.ravel(), y.ravel()))


def test_averaging_conserves_a_constant_and_reproduces_a_linear_field_in_the_interior():
    """Rows sum to 1: a constant is kept everywhere, also at the sides. A linear field is
    kept exactly at points more than the cutoff from a side: the Gaussian neighbourhood of a
    lattice site is symmetric about it, so its weighted centroid is the site itself (the
    first moment vanishes; a linear field has no higher ones)."""
    a, length, cutoff = 0.1, 0.25, 3.0
    x = lattice(30, a)
    A = averaging_matrix(x, np.full(len(x), a * a), length, cutoff)
    assert np.allclose(A @ np.full(len(x), 0.83), 0.83, rtol=0, atol=1e-14)
    field = 0.8 + 0.3 * x[:, 0] - 0.7 * x[:, 1]
    reach = cutoff * length
    inner = np.all((x > reach + 1e-9) & (x < x.max() - reach - 1e-9), axis=1)
    assert inner.sum() > 50
    assert np.max(np.abs((A @ field - field)[inner])) < 1e-12
    near_side = ~inner                      # there the neighbourhood is one-sided
    assert np.max(np.abs((A @ field - field)[near_side])) > 1e-3


def _disc(h=0.25):
    return Discretization(meshes.delaunay_rectangle(1.0, 1.0, h), "P2")


def _random_field(disc, rng, material):
    n = disc.npoints
    state = material.initial_state(n)
    state[:, material.state_names.index("c")] += rng.uniform(-0.02, 0.02, n)
    stress = np.column_stack((-1 + 0.1 * rng.random(n), -1.5 + 0.1 * rng.random(n),
                              0.05 * rng.standard_normal(n)))
    dstrain = 1e-3 * rng.standard_normal((n, 3))
    return stress, state, dstrain, 1e-4 * rng.standard_normal(n)


def test_vanishing_internal_length_is_the_local_model_exactly():
    """ℓ far below the element size: every element sees only itself, δ = 0 and the update
    (stress, state, tangent) is the local material's bit for bit."""
    params = default_params().with_tier(1)
    disc = _disc()
    local = TierMaterial(params, tier=1)
    nl = NonlocalMaterial(TierMaterial(params, tier=1), disc, length=1e-4, m=2.0)
    args = _random_field(disc, np.random.default_rng(0), local)
    assert np.all(nl.offset(args[1]) == 0.0)
    a, b = local.update(*args), nl.update(*args)
    for k in ("stress", "state", "tangent", "status"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k


def test_uniform_state_has_no_offset_and_a_perturbation_is_spread():
    """A uniform c gives δ = 0 (the local update), also at the sides; a lowered element
    gets a positive offset (its neighbours are denser) and its neighbours a negative one,
    larger with m (δ = m (c̄ − c))."""
    params = default_params().with_tier(1)
    disc = _disc()
    inner = TierMaterial(params, tier=1)
    state = inner.initial_state(disc.npoints)
    nl1 = NonlocalMaterial(inner, disc, length=0.2, m=1.0)
    nl2 = NonlocalMaterial(inner, disc, length=0.2, m=2.0)
    assert np.max(np.abs(nl1.offset(state))) < 1e-14
    centroids = disc.mesh.p[:, disc.mesh.t].mean(axis=1).T
    e = int(np.argmin(np.hypot(*(centroids - 0.5).T)))
    state[e * disc.nq:(e + 1) * disc.nq, 1] -= 0.01
    d1, d2 = nl1.offset(state), nl2.offset(state)
    assert d1[e * disc.nq] > 0.0
    assert d1.min() < 0.0
    assert np.allclose(d2, 2.0 * d1)


def _dense_yielding_field(disc, material, rng):
    """A dense packing (c* + 0.03, scattered by ±0.005 point to point) at the peak stress
    ratio σ1/σ3 = 2.6 under axial compression with lateral expansion: most points load
    plastically and dilate."""
    n = disc.npoints
    col = material.state_names.index("c")
    state = material.initial_state(n)
    state[:, col] = material.params.tier1.c_star + 0.03 + rng.uniform(-0.005, 0.005, n)
    stress = np.column_stack((-np.ones(n), -2.6 * np.ones(n), np.zeros(n)))
    x, y = disc.basis.doflocs              # the location of every DOF; x, y alternate
    u = np.where(np.arange(disc.ndofs) % 2 == 0, 2e-4 * x, -1e-3 * y)
    u += 2e-5 * rng.standard_normal(disc.ndofs)
    return stress, state, u


def test_a_step_weighs_the_points_own_change_by_the_own_weight():
    """Inside a step c_eff = c_eff⁰ + ω (c − c⁰), ω = 1 − m (1 − A_ee) < 0 here: the local
    material started from c_n + δ⁰ + (ω − 1)(c − c_n), with c the wrapper's updated packing
    fraction, returns the wrapper's stress and the same change of c (the fixed point)."""
    params = default_params().with_tier(1)
    disc = _disc(0.1)
    local = TierMaterial(params, tier=1)
    nl = NonlocalMaterial(TierMaterial(params, tier=1), disc, length=0.2, m=1.5)
    stress, state, u = _dense_yielding_field(disc, local, np.random.default_rng(1))
    dstrain, dspin = disc.strain(u)
    res = nl.update(stress, state, dstrain, dspin)
    change = res.state[:, 1] - state[:, 1]
    plastic = res.status == 1
    assert plastic.mean() > 0.5 and np.all(change[plastic] < 0.0)
    assert np.median(change[plastic]) < -1e-4
    omega = 1.0 - 1.5 * (1.0 - np.repeat(nl.matrix.diagonal(), disc.nq))
    assert omega.max() < 0.0
    start = state.copy()
    start[:, 1] += nl.offset(state) + (omega - 1.0) * change
    check = local.update(stress, start, dstrain, dspin)
    assert np.array_equal(check.status, res.status)
    assert np.allclose(check.stress, res.stress, rtol=0, atol=1e-9)
    assert np.allclose(check.state[:, 1] - start[:, 1], change, rtol=0, atol=1e-11)


def test_the_tangent_is_the_derivative_of_the_internal_force():
    """K v (the Newton matrix of the wrapper's tangent and spin tangent) equals the central
    difference of f_int(u ± h v) in a random direction v to 1e-6 (relative), where the
    tangent at a fixed shift (the wrapped material's) is off by more than 1e-3: the chain
    rule through the step's own shift is what makes it consistent."""
    params = default_params().with_tier(1)
    disc = _disc(0.1)
    nl = NonlocalMaterial(TierMaterial(params, tier=1), disc, length=0.2, m=1.5)
    rng = np.random.default_rng(2)
    stress, state, u = _dense_yielding_field(disc, nl, rng)

    def force(u):
        res = nl.update(stress, state, *disc.strain(u))
        return disc.internal_force(res.stress), res

    f0, res = force(u)
    dstrain, dspin = disc.strain(u)
    spin = nl.spin_tangent(stress, state, dstrain, dspin, res)
    v, h = rng.standard_normal(disc.ndofs), 1e-8
    diff = (force(u + h * v)[0] - force(u - h * v)[0]) / (2 * h)
    kv = disc.tangent(res.tangent, spin) @ v
    assert np.linalg.norm(kv - diff) < 1e-6 * np.linalg.norm(diff)
    shifted = state.copy()
    shifted[:, 1] += nl.offset(state)
    fixed = nl.material.update(stress, shifted, dstrain, dspin)   # the kernel at s = 0
    kv_fixed = disc.tangent(fixed.tangent, nl.spin_tangent(stress, state, dstrain, dspin,
                                                           fixed)) @ v
    assert np.linalg.norm(kv_fixed - diff) > 1e-3 * np.linalg.norm(diff)


def test_nonlocal_input_is_checked():
    params = default_params()
    disc = _disc(0.4)
    with pytest.raises(ParamError, match="nonlocal weight m = 0.5 is outside"):
        NonlocalMaterial(TierMaterial(params, tier=1), disc, 0.1, m=0.5)
    with pytest.raises(ParamError, match="internal length = -0.1 is outside"):
        NonlocalMaterial(TierMaterial(params, tier=1), disc, -0.1)
    with pytest.raises(ParamError, match="needs a state column 'c'"):
        NonlocalMaterial(TierMaterial(params, tier=0), disc, 0.1)


def _band(level: int, length: float, weight: float = 1.5) -> dict:
    from contfab.scenes import biaxial_shear_band as band
    return band.solve(default_params(), "P2", level, band.DEFAULT_DENSE, 0.04, None, False,
                      length=length, weight=weight)


@pytest.mark.slow
def test_the_band_width_follows_the_internal_length():
    """On one mesh (level 2, h = 0.0625: ℓ = 0.1 and 0.2 resolved), doubling ℓ doubles the
    band's width to 20 %: the length of the model, not the element, sets it (dimensional
    analysis: w = k ℓ once ℓ is resolved). 15 s."""
    w1, w2 = (_band(2, length, weight=1.25)["band_width"] for length in (0.1, 0.2))
    assert w2 / w1 == pytest.approx(2.0, rel=0.2), (w1, w2)


@pytest.mark.slow
@pytest.mark.parametrize("weight, levels", [(1.25, (2, 3)), (1.5, (1, 2))])
def test_the_post_peak_load_settles_with_the_mesh_under_an_internal_length(weight, levels):
    """σ1/σ3 at 4 % axial strain within 2 % between two mesh levels with ℓ = 0.1 (the plain
    nonlocal m = 1 differs by 3.2 % between levels 1 and 2, the local model by 2.8 %); with
    m = 1.25 between levels 2 and 3 (h = ℓ/1.6 and ℓ/2.4: ℓ resolved), the band width too,
    to 20 %. 1.5 min (m = 1.25) and 1 min (m = 1.5)."""
    runs = [_band(level, 0.1, weight) for level in levels]
    ends = [r["end"] for r in runs]
    assert ends[1] == pytest.approx(ends[0], rel=0.02), ends
    if weight == 1.25:
        widths = [r["band_width"] for r in runs]
        assert widths[1] == pytest.approx(widths[0], rel=0.2), widths
