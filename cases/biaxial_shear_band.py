"""Plane biaxial test of a dense specimen with rough platens: peak, softening, shear band.

The scene is defined in :mod:`contfab.scenes.biaxial_shear_band`; this script runs it as
``contfab case biaxial_shear_band`` does (``python cases/biaxial_shear_band.py --help`` lists its options).
"""
import sys

from contfab.scenes import biaxial_shear_band
from contfab.scenes.case import main

if __name__ == "__main__":
    sys.exit(main(biaxial_shear_band))
