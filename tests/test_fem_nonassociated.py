"""The non-associated footing (ψ = 0, coarse mesh) converges through collapse to 0.3 B."""
import math

import pytest

from contfab.scenes.case import run_case


def test_nonassociated_ngamma_footing_converges_to_a_plateau_at_0p3_b():
    """N_γ at φ = 30°, ψ = 0 on the P2 level-1 mesh with the Duvaut–Lions material
    (τ = 1e-4 of the settlement over B): every step converges to a settlement of 0.3 B
    (the rate-independent Newton fails near 0.06 B, docs/fem_validation.md), and at a
    constant settlement rate a perfectly plastic mechanism carries a constant load: the
    last fifth of the push is a plateau (< 1 % drift)."""
    result = run_case("strip_footing", ["--factor", "Ngamma", "--phi", "30", "--psi", "0",
                                        "--element", "P2", "--level", "1", "--settlement", "0.3",
                                        "--relaxation-time", "1e-4", "--quiet", "--out", "none"])
    head = result.figures[0]
    note = result.notes["N_gamma(phi=30, psi=0)"]
    assert math.isnan(head.reference) and "no published reference" in head.source
    assert note["settlement_over_B"] == pytest.approx(0.3, rel=1e-9)
    assert abs(note["plateau_drift"]) < 0.01
    assert note["davis_phi"] == math.degrees(math.atan(0.5))      # tan φ* = sin 30° cos 0
    assert head.computed == note["computed"] > 0
