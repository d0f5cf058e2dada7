"""Conversions between quaternions and matrices, rotation vectors and Euler angles, both ways."""

from ._common import (DTYPES, LARGE, LIBS, SIZES, Skip, adapter, euler_angles, matrices, rotvecs,
                      unit_quats)

#: Libraries whose from_matrix at N = 10⁶ is known to be more than 100x slower than quatarray's.
SLOW_FROM_MATRIX = ("numpy-quaternion", "quaternionic")


class Conversions:
    """scipy's ``as_*`` / ``from_*`` on N rotations (Euler sequence ``'xyz'``).

    numpy-quaternion and quaternionic have matrices and rotation vectors but
    only z-y-z Euler angles, so their Euler benchmarks are skipped.
    """

    params = (SIZES, DTYPES, LIBS)
    param_names = ["n", "dtype", "lib"]

    def setup(self, n, dtype, lib):
        self.lib = L = adapter(lib, dtype)
        self.q = L.wrap(unit_quats(n, dtype, salt=21))
        self.m = matrices(n, dtype, salt=22)
        self.v = rotvecs(n, dtype, salt=23)
        self.a = euler_angles(n, dtype, salt=24)

    def time_as_matrix(self, n, dtype, lib):
        """Rotation matrices (..., 3, 3) from quaternions."""
        self.lib.as_matrix(self.q)

    def time_from_matrix(self, n, dtype, lib):
        """Quaternions from rotation matrices.

        Skipped for numpy-quaternion and quaternionic at N = 10⁶: known to be more
        than 100x slower than quatarray there (23-26 s per call), their N = 10⁴
        rows stand in (as in ``benchmarks.compare``).
        """
        if n >= LARGE and lib in SLOW_FROM_MATRIX:
            raise Skip(f"{lib} from_matrix at N = {n}: more than 100x slower, see N = 10^4")
        self.lib.from_matrix(self.m)

    def time_as_rotvec(self, n, dtype, lib):
        """Rotation vectors (axis × angle) from quaternions."""
        self.lib.as_rotvec(self.q)

    def time_from_rotvec(self, n, dtype, lib):
        """Quaternions from rotation vectors."""
        self.lib.from_rotvec(self.v)

    def time_as_euler(self, n, dtype, lib):
        """Extrinsic 'xyz' Euler angles from quaternions."""
        self.lib.as_euler(self.q)

    def time_from_euler(self, n, dtype, lib):
        """Quaternions from extrinsic 'xyz' Euler angles."""
        self.lib.from_euler(self.a)
