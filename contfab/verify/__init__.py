"""Verification of the DEM against an independent engine (``contfab verify``)."""
