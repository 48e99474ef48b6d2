"""Constitutive model tiers 0-2 (DESIGN §4): return-mapping kernels behind one interface."""
