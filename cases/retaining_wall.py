"""Smooth rigid wall translating away from / into a cohesionless backfill: K_a and K_p.

The scene is defined in :mod:`contfab.scenes.retaining_wall`; this script runs it as
``contfab case retaining_wall`` does (``python cases/retaining_wall.py --help`` lists its options).
"""
import sys

from contfab.scenes import retaining_wall
from contfab.scenes.case import main

if __name__ == "__main__":
    sys.exit(main(retaining_wall))
