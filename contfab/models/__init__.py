"""Constitutive model tiers behind one update interface (:mod:`contfab.models.tiers`)."""
