"""Every `Rotation` method on one rotation, quatarray against scipy: the per-call cost.

Both libraries have the same ``Rotation`` API, so each benchmark calls it the
same way on the library's own class; data are made in ``setup``.
"""

import numpy as np

from ._common import LIBS, SEED

_CLASSES = {"quatarray": ("quatarray", "Rotation"), "scipy": ("scipy.spatial.transform", "Rotation")}


class SingleRotation:
    """One rotation (N = 1, float64) through each ``Rotation`` method."""

    params = (LIBS[:2],)
    param_names = ["lib"]

    def setup(self, lib):
        import importlib
        try:
            R = getattr(importlib.import_module(_CLASSES[lib][0]), _CLASSES[lib][1])
        except ImportError as exc:
            raise NotImplementedError(f"{lib} is not installed ({exc})") from None
        rng = np.random.default_rng(SEED)
        q = rng.standard_normal(4)
        self.R = R
        self.quat = q / np.linalg.norm(q)
        self.r = R.from_quat(self.quat)
        self.s = R.from_quat(rng.standard_normal(4))
        self.matrix = self.r.as_matrix()
        self.rotvec = self.r.as_rotvec()
        self.mrp = self.r.as_mrp()
        self.euler = self.r.as_euler("xyz")
        self.axes = np.eye(3)[[2, 0, 2]]
        self.davenport = self.r.as_davenport(self.axes, "e")
        self.vector = rng.standard_normal(3)
        self.a, self.b = rng.standard_normal((2, 3, 3))
        self.group = R.create_group("O")

    def time_from_quat(self, lib):
        """``Rotation.from_quat(q)``."""
        self.R.from_quat(self.quat)

    def time_as_quat(self, lib):
        """``r.as_quat()``."""
        self.r.as_quat()

    def time_from_matrix(self, lib):
        """``Rotation.from_matrix(m)``."""
        self.R.from_matrix(self.matrix)

    def time_as_matrix(self, lib):
        """``r.as_matrix()``."""
        self.r.as_matrix()

    def time_from_rotvec(self, lib):
        """``Rotation.from_rotvec(v)``."""
        self.R.from_rotvec(self.rotvec)

    def time_as_rotvec(self, lib):
        """``r.as_rotvec()``."""
        self.r.as_rotvec()

    def time_from_mrp(self, lib):
        """``Rotation.from_mrp(p)``."""
        self.R.from_mrp(self.mrp)

    def time_as_mrp(self, lib):
        """``r.as_mrp()``."""
        self.r.as_mrp()

    def time_from_euler(self, lib):
        """``Rotation.from_euler('xyz', angles)``."""
        self.R.from_euler("xyz", self.euler)

    def time_as_euler(self, lib):
        """``r.as_euler('xyz')``."""
        self.r.as_euler("xyz")

    def time_from_davenport(self, lib):
        """``Rotation.from_davenport(axes, 'e', angles)``."""
        self.R.from_davenport(self.axes, "e", self.davenport)

    def time_as_davenport(self, lib):
        """``r.as_davenport(axes, 'e')``."""
        self.r.as_davenport(self.axes, "e")

    def time_apply(self, lib):
        """``r.apply(v)`` for one vector."""
        self.r.apply(self.vector)

    def time_mul(self, lib):
        """``r * s``."""
        self.r * self.s

    def time_pow(self, lib):
        """``r ** 0.3``."""
        self.r ** 0.3

    def time_inv(self, lib):
        """``r.inv()``."""
        self.r.inv()

    def time_magnitude(self, lib):
        """``r.magnitude()``."""
        self.r.magnitude()

    def time_approx_equal(self, lib):
        """``r.approx_equal(s)``."""
        self.r.approx_equal(self.s)

    def time_mean(self, lib):
        """``r.mean()``."""
        self.r.mean()

    def time_reduce(self, lib):
        """``r.reduce(group)`` with the octahedral group (24 rotations)."""
        self.r.reduce(self.group)

    def time_identity(self, lib):
        """``Rotation.identity()``."""
        self.R.identity()

    def time_random(self, lib):
        """``Rotation.random(rng=0)``."""
        self.R.random(rng=0)

    def time_align_vectors(self, lib):
        """``Rotation.align_vectors(a, b)`` for three pairs."""
        self.R.align_vectors(self.a, self.b)
