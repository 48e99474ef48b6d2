"""Rigid rough strip footing on a cohesionless cone: N_q and N_γ against exact solutions.

The scene is defined in :mod:`contfab.scenes.strip_footing`; this script runs it as
``contfab case strip_footing`` does (``python cases/strip_footing.py --help`` lists its options).
"""
import sys

from contfab.scenes import strip_footing
from contfab.scenes.case import main

if __name__ == "__main__":
    sys.exit(main(strip_footing))
