"""Peak memory of the operations that once took far more than their output at 10⁷ rotations.

asv's ``peakmem_`` is the process's peak resident memory, setup's inputs included:
``peakmem_inputs`` (which does nothing) is the baseline, and each operation's extra
memory is its peak minus that.  The aim is at most 1.5× the output plus a few blocks
(`quatarray._blocks.block_size` elements per block): a reduction to one rotation
(``Rotation.mean``, ``np.multiply.reduce``) should need a few blocks only.  The same
bounds are checked at 10⁶ with tracemalloc in tests/test_domain_extremes.py.
"""

import numpy as np

from ._common import SEED, Skip

import quatarray as qa


class PeakMemory:
    """Extra memory of reductions, sign fixing, conversions and spline evaluation, quatarray only."""

    params = ([1_000, 10_000_000], ["float32", "float64"])
    param_names = ["n", "dtype"]

    def setup(self, n, dtype):
        g = np.random.default_rng(SEED + 70)
        q = g.standard_normal((n, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        self.q = qa.QuatArray(q.astype(dtype))
        self.r = qa.Rotation.from_quat(self.q.ndarray, scalar_first=True)
        self.angles = g.uniform(-1.5, 1.5, (n, 3)).astype(dtype)
        self.matrices = self.r[: min(n, 1_000_000)].as_matrix()   # 10⁶ matrices (9 columns)
        keys = qa.Rotation.from_quat(q[:64].astype(dtype))
        self.spline = qa.RotationSpline(np.arange(64.0), keys)
        self.t = np.linspace(0, 63, n)

    def peakmem_inputs(self, n, dtype):
        """Baseline: the inputs made in setup, no operation."""

    def peakmem_rotation_mean(self, n, dtype):
        """``Rotation.mean()`` (a 32-byte result: a few blocks)."""
        self.r.mean()

    def peakmem_multiply_reduce(self, n, dtype):
        """``np.multiply.reduce(q, axis=0)`` (one quaternion: a few blocks)."""
        np.multiply.reduce(self.q, axis=0)

    def peakmem_unflip(self, n, dtype):
        """``unflip(q)`` (output: n quaternions)."""
        qa.unflip(self.q)

    def peakmem_from_euler(self, n, dtype):
        """``Rotation.from_euler('xyz', angles)`` (output: n quaternions)."""
        qa.Rotation.from_euler("xyz", self.angles)

    def peakmem_from_matrix(self, n, dtype):
        """``Rotation.from_matrix`` of 10⁶ matrices (n ≥ 10⁶; output: 10⁶ quaternions)."""
        if n < 1_000_000:
            raise Skip("from_matrix at the large size only")
        qa.Rotation.from_matrix(self.matrices)

    def peakmem_spline(self, n, dtype):
        """A 64-key ``RotationSpline`` at n sorted times (output: n quaternions)."""
        self.spline(self.t)
