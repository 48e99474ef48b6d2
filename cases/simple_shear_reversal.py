"""A granular layer sheared to γ = 1 and reversed to γ = -1: tier 1 vs tier 2 vs the DEM.

The scene is defined in :mod:`contfab.scenes.simple_shear_reversal`; this script runs it as
``contfab case simple_shear_reversal`` does (``python cases/simple_shear_reversal.py --help`` lists its options).
"""
import sys

from contfab.scenes import simple_shear_reversal
from contfab.scenes.case import main

if __name__ == "__main__":
    sys.exit(main(simple_shear_reversal))
