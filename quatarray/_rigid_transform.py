"""scipy-style `RigidTransform`: ``x -> R x + t``.

Stored as a rotation (unit scalar-first quaternion) plus a translation,
not as a unit dual quaternion: `apply` then costs one quaternion rotation
and one addition, `rotation`/`translation` are free, and matrices convert
without the dual part's products.  Dual quaternions are produced on demand
by the raw `_dualquat` conversions, which are exact inverses of each other.
"""

import numpy as np

from . import _dualquat as DQ
from . import _kernels as Kn


def _rotation_cls():
    from . import Rotation
    return Rotation


def _float(a, name, last):
    a = np.asarray(a)
    if a.dtype.kind not in "fiu" or a.shape[-len(last):] != last:
        raise ValueError(f"Expected `{name}` to have shape (..., {', '.join(map(str, last))}), got {a.shape}.")
    return a.astype(np.float32 if a.dtype == np.float32 else np.float64)


class RigidTransform:
    """Rigid transforms (rotation then translation), batched, scipy 1.17 API."""

    def __init__(self, quat, translation, single):
        self._quat = quat
        self._translation = translation
        self._single = single

    @classmethod
    def _make(cls, quat, translation, single):
        batch = np.broadcast_shapes(quat.shape[:-1], translation.shape[:-1])
        dtype = np.result_type(quat.dtype, translation.dtype)
        q = np.array(np.broadcast_to(quat, batch + (4,)), dtype)
        t = np.array(np.broadcast_to(translation, batch + (3,)), dtype)
        return cls(q, t, single)

    # constructors
    @classmethod
    def from_matrix(cls, matrix):
        m = _float(matrix, "matrix", (4, 4))
        if not np.all(m[..., 3, :] == np.array([0, 0, 0, 1], m.dtype)):
            raise ValueError("Expected last row of `matrix` to be [0, 0, 0, 1].")
        rot = _rotation_cls().from_matrix(m[..., :3, :3])
        q = np.asarray(rot.as_quat(scalar_first=True), m.dtype)
        return cls._make(q, m[..., :3, 3], m.ndim == 2)

    @classmethod
    def from_rotation(cls, rotation):
        q = np.asarray(rotation.as_quat(scalar_first=True))
        return cls._make(q, np.zeros(q.shape[:-1] + (3,), q.dtype), q.ndim == 1)

    @classmethod
    def from_translation(cls, translation):
        t = _float(translation, "translation", (3,))
        q = np.zeros(t.shape[:-1] + (4,), t.dtype)
        q[..., 0] = 1
        return cls._make(q, t, t.ndim == 1)

    @classmethod
    def from_components(cls, translation, rotation):
        t = _float(translation, "translation", (3,))
        q = np.asarray(rotation.as_quat(scalar_first=True))
        return cls._make(q, t, t.ndim == 1 and q.ndim == 1)

    @classmethod
    def from_dual_quat(cls, dual_quat, *, scalar_first=False):
        dq = _float(dual_quat, "dual_quat", (8,))
        if not scalar_first:
            dq = dq[..., [3, 0, 1, 2, 7, 4, 5, 6]]
        q, t = DQ.as_rotation_translation(DQ.normalize(dq))
        return cls._make(q, t, dq.ndim == 1)

    @classmethod
    def identity(cls, num=None):
        shape = () if num is None else (num,)
        return cls.from_translation(np.zeros(shape + (3,)))

    # conversions
    def as_components(self):
        return self.translation, self.rotation

    def as_matrix(self):
        m = np.zeros(self._quat.shape[:-1] + (4, 4), self._quat.dtype)
        m[..., :3, :3] = self.rotation.as_matrix()
        m[..., :3, 3] = self._translation
        m[..., 3, 3] = 1
        return m

    def as_dual_quat(self, *, scalar_first=False):
        dq = DQ.from_rotation_translation(self._quat, self._translation)
        return dq if scalar_first else dq[..., [1, 2, 3, 0, 5, 6, 7, 4]]

    # operations
    def apply(self, vector, inverse=False):
        v = _float(vector, "vector", (3,))
        q, t = self._quat, self._translation
        if inverse:
            out = Kn.rotate(q, v - t, inverse=True)
        else:
            out = Kn.rotate(q, v) + t
        out = np.asarray(out)
        return out[0] if self._single and v.ndim == 1 and out.ndim == 2 else out

    def inv(self):
        qi = Kn.conjugate(self._quat)
        return type(self)(np.asarray(qi), -np.asarray(Kn.rotate(qi, self._translation)), self._single)

    def __mul__(self, other):
        if not isinstance(other, RigidTransform):
            if hasattr(other, "as_quat"):
                other = RigidTransform.from_rotation(other)
            else:
                return NotImplemented
        q = np.asarray(Kn.multiply(self._quat, other._quat))
        t = np.asarray(Kn.rotate(self._quat, other._translation)) + self._translation
        return RigidTransform._make(q, t, self._single and other._single)

    def __rmul__(self, other):
        if hasattr(other, "as_quat"):
            return RigidTransform.from_rotation(other) * self
        return NotImplemented

    # container
    @property
    def single(self):
        return self._single

    @property
    def shape(self):
        return self._quat.shape[:-1]

    @property
    def rotation(self):
        return _rotation_cls().from_quat(self._quat, scalar_first=True)

    @property
    def translation(self):
        return self._translation.copy()

    def __len__(self):
        if self._single:
            raise TypeError("Single transform has no len")
        return self._quat.shape[0]

    def __getitem__(self, index):
        if self._single:
            raise TypeError("Single transform is not subscriptable.")
        q = self._quat[index]
        return type(self)(q.copy(), self._translation[index].copy(), q.ndim == 1)

    def __repr__(self):
        return f"RigidTransform.from_matrix({self.as_matrix()!r})"
