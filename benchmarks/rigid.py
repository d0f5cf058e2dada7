"""RotationSpline and screw interpolation, quatarray against scipy (the only peer with a rotation spline)."""

import numpy as np

from ._common import Skip, rng
from .tracks import make_track

LIBS2 = ["quatarray", "scipy"]


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


class SplineEvaluate:
    """Build a RotationSpline through K keys (``time_build``) and evaluate it at M sorted
    times (the others).  Build and evaluation together cost their sum: a class timing them
    in one call was dropped to keep ``asv run --quick`` under 5 minutes."""

    params = ([10, 10_000], [10, 1_000_000], ["float32", "float64"], LIBS2)
    param_names = ["keys", "queries", "dtype", "lib"]

    def setup(self, k, m, dtype, lib):
        times, keys, t = make_track(k, m, np.dtype(dtype))
        if lib == "quatarray":
            from quatarray import Rotation, RotationSpline
        else:
            from scipy.spatial.transform import Rotation, RotationSpline
        self.rot = Rotation.from_quat(keys, scalar_first=True)
        self.cls, self.times, self.t = RotationSpline, times, t
        self.spline = RotationSpline(times, self.rot)

    def time_build(self, k, m, dtype, lib):
        """Construction only (the interior-rate system); independent of M, so timed at the
        smallest M only."""
        if m != self.params[1][0]:
            raise Skip("construction does not depend on the number of query times")
        self.cls(self.times, self.rot)

    def time_rotations(self, k, m, dtype, lib):
        """Rotations at M times (order 0)."""
        self.spline(self.t)

    def time_angular_rate(self, k, m, dtype, lib):
        """Angular rate at M times (order 1)."""
        self.spline(self.t, 1)

    def time_angular_acceleration(self, k, m, dtype, lib):
        """Angular acceleration at M times (order 2)."""
        self.spline(self.t, 2)


class RigidTransforms:
    """RigidTransform operations on N transforms (N = 1: a single transform)."""

    params = ([1, 10_000, 1_000_000], ["float32", "float64"], LIBS2)   # N = 100 dropped for asv --quick
    param_names = ["n", "dtype", "lib"]

    def setup(self, n, dtype, lib):
        g = rng(71)
        shape = () if n == 1 else (n,)
        q = g.standard_normal(shape + (4,))
        t = g.standard_normal(shape + (3,)).astype(dtype)
        self.v = g.standard_normal(shape + (3,)).astype(dtype)
        if lib == "quatarray":
            from quatarray import RigidTransform, Rotation
        else:
            from scipy.spatial.transform import RigidTransform, Rotation
        self.cls = RigidTransform
        r = Rotation.from_quat(q.astype(dtype))
        if lib == "quatarray":
            self.a = RigidTransform.from_components(t, r)
        else:   # the same matrix as from_components(t, r), which takes scipy 4 s at N = 10⁶
            m = np.zeros(shape + (4, 4), dtype)
            m[..., :3, :3], m[..., :3, 3], m[..., 3, 3] = r.as_matrix(), t, 1
            self.a = RigidTransform(m, normalize=False, copy=False)
        self.b = self.a.inv()
        self.m = self.a.as_matrix()

    def time_apply(self, n, dtype, lib):
        """a.apply(v): one vector per transform."""
        self.a.apply(self.v)

    def time_apply_inverse(self, n, dtype, lib):
        """a.apply(v, inverse=True)."""
        self.a.apply(self.v, inverse=True)

    def time_compose(self, n, dtype, lib):
        """a * b."""
        self.a * self.b

    def time_inv(self, n, dtype, lib):
        """a.inv()."""
        self.a.inv()

    def time_from_matrix(self, n, dtype, lib):
        """RigidTransform.from_matrix (orthonormalising the rotation part)."""
        self.cls.from_matrix(self.m)

    def time_as_matrix(self, n, dtype, lib):
        """a.as_matrix() (a single transform keeps its matrix: later calls copy, as scipy's do)."""
        self.a.as_matrix()

    def time_compose_as_matrix(self, n, dtype, lib):
        """(a * b).as_matrix(): the matrix of a new transform, converted on first use."""
        (self.a * self.b).as_matrix()


class RigidKeyframes:
    """A RigidTrack of K keys over B bodies evaluated at M times (no peer interpolates rigid motions)."""

    params = ([(10_000, 1), (100, 100)], [1_000_000 // 100, 1_000_000], ["float32", "float64"])
    param_names = ["keys, bodies", "queries", "dtype"]

    def setup(self, kb, m, dtype):
        from quatarray import RigidTrack, RigidTransform, Rotation
        k, b = kb
        if m * b > 10_000_000:
            raise NotImplementedError   # asv: skipped (10^8 poses)
        g = rng(73)
        q = g.standard_normal((k, b, 4)).astype(dtype)
        t = g.standard_normal((k, b, 3)).astype(dtype)
        keys = RigidTransform.from_components(t, Rotation.from_quat(q, scalar_first=True))
        self.track = RigidTrack(np.arange(k, dtype=float), keys)
        self.t = np.linspace(0, k - 1, m)

    def time_evaluate(self, kb, m, dtype):
        """Poses (rotation + translation) of every body at M times."""
        self.track(self.t)
