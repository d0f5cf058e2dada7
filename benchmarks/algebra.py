"""Quaternion algebra: product, conjugate, inverse, normalize, magnitude, exp, log, power."""

from ._common import DTYPES, LARGE, LIBS, SIZES, Skip, adapter, quats, unit_quats


class Algebra:
    """Element-wise algebra on batches of N quaternions (N = 1: a single quaternion).

    scipy's twins act on rotations: ``inv`` for the conjugate, ``from_quat``
    for normalisation, ``from_rotvec``/``as_rotvec`` for exp/log and ``**``
    for the power.  numpy-quaternion and quaternionic are float64 only: their
    float32 rows are skipped (they would time float64 again).
    """

    params = (SIZES, DTYPES, LIBS)
    param_names = ["n", "dtype", "lib"]

    def setup(self, n, dtype, lib):
        self.lib = L = adapter(lib, dtype)
        self.raw = quats(n, dtype, salt=3)  # non-unit, for normalize / exp / log
        self.p = L.wrap(unit_quats(n, dtype, salt=1))
        self.q = L.wrap(unit_quats(n, dtype, salt=2))
        self.g = self.raw if lib == "scipy" else L.wrap(self.raw)

    def time_product(self, n, dtype, lib):
        """Hamilton product p q (scipy: composition r1 * r2)."""
        self.lib.product(self.p, self.q)

    def peakmem_product(self, n, dtype, lib):
        """Peak memory of the Hamilton product p q (large N only)."""
        if n < LARGE:
            raise Skip("peakmem only for the large case")
        self.lib.product(self.p, self.q)

    def time_conjugate(self, n, dtype, lib):
        """Conjugate (w, -x, -y, -z) (scipy: inv())."""
        self.lib.conjugate(self.q)

    def time_inv(self, n, dtype, lib):
        """Rotation inverse ``inv()`` of unit quaternions."""
        self.lib.inv(self.q)

    def time_magnitude(self, n, dtype, lib):
        """Rotation angle ``magnitude()`` in [0, π]."""
        self.lib.magnitude(self.q)

    def time_normalize(self, n, dtype, lib):
        """q / |q| of non-unit quaternions (scipy: from_quat)."""
        self.lib.normalize(self.g)

    def time_exp(self, n, dtype, lib):
        """Quaternion exponential (scipy: from_rotvec of twice the vector part)."""
        self.lib.exp(self.g)

    def time_log(self, n, dtype, lib):
        """Quaternion logarithm (scipy: as_rotvec of unit quaternions)."""
        self.lib.log(self.q if lib == "scipy" else self.g)

    def time_power(self, n, dtype, lib):
        """Power q ** 0.3 of unit quaternions (scipy: rotation power)."""
        self.lib.power(self.q, 0.3)

    def time_rotation_power(self, n, dtype, lib):
        """Rotation power ``r ** 0.3`` (the angle scaled, scipy's ``**``; quatarray: `Rotation`)."""
        self.lib.rotation_power(self.q, 0.3)
