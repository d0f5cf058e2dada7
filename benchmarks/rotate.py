"""Rotating vectors: q v q⁻¹ for N quaternion-vector pairs."""

from ._common import DTYPES, LARGE, LIBS, SIZES, Skip, adapter, unit_quats, vectors


class RotateVectors:
    """Rotate N vectors by N rotations, pairwise (N = 1: one rotation, one vector).

    numpy-quaternion and quaternionic rotate every vector by every rotation
    in their ``rotate`` functions, so their twins write the pairwise q v q̄.
    """

    params = (SIZES, DTYPES, LIBS)
    param_names = ["n", "dtype", "lib"]

    def setup(self, n, dtype, lib):
        self.lib = L = adapter(lib, dtype)
        self.q = L.wrap(unit_quats(n, dtype, salt=11))
        self.v = vectors(n, dtype, salt=12)

    def time_rotate(self, n, dtype, lib):
        """``q.rotate(v)`` (scipy: ``r.apply(v)``)."""
        self.lib.rotate(self.q, self.v)

    def time_apply(self, n, dtype, lib):
        """scipy's ``apply(v)`` on each library's rotation object."""
        self.lib.apply(self.q, self.v)

    def peakmem_rotate(self, n, dtype, lib):
        """Peak memory of rotating vectors (large N only)."""
        if n < LARGE:
            raise Skip("peakmem only for the large case")
        self.lib.rotate(self.q, self.v)
