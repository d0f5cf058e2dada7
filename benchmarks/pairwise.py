"""Pairwise interpolation: slerp and nlerp between N pairs of quaternions at N parameters."""

from ._common import DTYPES, LARGE, LIBS, SIZES, Skip, adapter, batch, rng, unit_quats


class Pairwise:
    """slerp(q0, q1, t) and nlerp(q0, q1, t), one t per pair (N = 1: single quaternions, scalar t).

    scipy has no pairwise slerp: its twin is q0 · from_rotvec(t · as_rotvec(q0⁻¹ q1)),
    which is what `scipy.spatial.transform.Slerp` evaluates.  numpy-quaternion's
    twin is its fastest slerp, the ufunc behind ``quaternion.slerp``.
    """

    params = (SIZES, DTYPES, LIBS)
    param_names = ["n", "dtype", "lib"]

    def setup(self, n, dtype, lib):
        self.lib = L = adapter(lib, dtype)
        q0, q1 = unit_quats(n, dtype, salt=31), unit_quats(n, dtype, salt=32)
        t = rng(33).uniform(0, 1, batch(n)).astype(dtype)
        self.t = float(t) if n == 1 else t
        self.q0, self.q1 = L.wrap(q0), L.wrap(q1)
        # nlerp twins that take raw arrays
        self.r0, self.r1 = (q0, q1) if lib == "scipy" else (self.q0, self.q1)

    def time_slerp(self, n, dtype, lib):
        """Spherical linear interpolation, pairwise."""
        self.lib.slerp(self.q0, self.q1, self.t)

    def peakmem_slerp(self, n, dtype, lib):
        """Peak memory of pairwise slerp (large N only)."""
        if n < LARGE:
            raise Skip("peakmem only for the large case")
        self.lib.slerp(self.q0, self.q1, self.t)

    def time_nlerp(self, n, dtype, lib):
        """Normalised linear interpolation, pairwise (scipy: from_quat of the lerp)."""
        self.lib.nlerp(self.r0, self.r1, self.t)

