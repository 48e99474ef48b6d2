"""How the constitutive kernels are compiled by numba: one set of flags, in one place.

:data:`KERNEL` is for every tier-2 kernel (:mod:`contfab.models.fabric_cone`,
:mod:`contfab.models.fabric_law`) and the small tensor helpers they inline, except those
that allocate (the per-range scratch, the loops over points, ``drive_fabric``):

* ``_nrt=False``: they take arrays and never allocate or return one, so numba's reference
  counting of each array argument at each call — an atomic incref/decref pair, about 5 ns
  per array per call, with tens of calls per point — is dropped (30 % of a tier-2 update,
  outputs bitwise unchanged). An allocation in such a function is a compile error, so the
  flag cannot hide a leak; ``_nrt`` is numba's own (underscored) switch for this.
* ``fastmath={"contract"}``: LLVM may fuse a multiply and an add into one FMA (one
  rounding instead of two). Only ``contract``: ``arcp`` turns d/r into d·(1/r), which is
  NaN for a subnormal deviator radius (R/P = 5e-324), and ``nnan``/``ninf`` would let LLVM
  delete the NaN checks the kernels rely on (it may then assume no value is NaN or
  infinite). Results move by round-off only.
"""
KERNEL = dict(cache=True, error_model="numpy", fastmath={"contract"}, _nrt=False)
"""numba.njit flags of a non-allocating constitutive kernel (module doc)."""
