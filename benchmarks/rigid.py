"""RotationSpline and screw interpolation, quatarray against scipy (the only peer with a rotation spline)."""

import numpy as np

from ._common import rng
from .tracks import make_track

LIBS2 = ["quatarray", "scipy"]


class Spline:
    """Build a RotationSpline through K keys and evaluate it at M times (construction included)."""

    params = ([10, 10_000], [10, 1_000_000], ["float32", "float64"], LIBS2)
    param_names = ["keys", "queries", "dtype", "lib"]

    def setup(self, k, m, dtype, lib):
        times, keys, t = make_track(k, m, np.dtype(dtype))
        if lib == "quatarray":
            from quatarray import Rotation, RotationSpline
            self.cls, self.rot = RotationSpline, Rotation.from_quat(keys, scalar_first=True)
        else:
            from scipy.spatial.transform import Rotation, RotationSpline
            self.cls, self.rot = RotationSpline, Rotation.from_quat(keys, scalar_first=True)
        self.times, self.t = times, t

    def time_rotations(self, k, m, dtype, lib):
        """Rotations at M times (order 0)."""
        self.cls(self.times, self.rot)(self.t)

    def time_angular_rate(self, k, m, dtype, lib):
        """Angular rate at M times (order 1)."""
        self.cls(self.times, self.rot)(self.t, 1)


class ScrewInterpolation:
    """ScLERP between N pairs of rigid motions at one parameter (no peer offers it)."""

    params = ([1, 1_000_000], ["float32", "float64"])
    param_names = ["n", "dtype"]

    def setup(self, n, dtype):
        from quatarray import sclerp
        g = rng(61)
        q = g.standard_normal((2, n, 8))
        q[..., :4] /= np.linalg.norm(q[..., :4], axis=-1, keepdims=True)
        q[..., 4:] -= np.sum(q[..., :4] * q[..., 4:], axis=-1, keepdims=True) * q[..., :4]
        self.a, self.b = q.astype(dtype)
        self.sclerp = sclerp

    def time_sclerp(self, n, dtype):
        """sclerp(a, b, 0.3) for N pairs."""
        self.sclerp(self.a, self.b, 0.3)
