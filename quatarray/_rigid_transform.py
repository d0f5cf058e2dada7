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


def _cross(a, b):
    return np.cross(a, b)


def _left_jacobian_coeffs(theta):
    """(1-cos θ)/θ² and (θ-sin θ)/θ³, by series near zero where the quotients cancel."""
    small = theta < 1e-3
    th = np.where(small, 1.0, theta)
    a = np.where(small, 0.5 - theta**2 / 24, (1 - np.cos(th)) / th**2)
    b = np.where(small, 1 / 6 - theta**2 / 120, (th - np.sin(th)) / th**3)
    return a, b


class RigidTransform:
    """Rigid transforms (rotation then translation), batched, scipy 1.17 API."""

    def __init__(self, quat, translation, single):
        self._quat = quat
        self._translation = translation
        self._single = single

    @classmethod
    def _from_parts(cls, quat, translation, single):
        """From raw unit scalar-first quaternions (..., 4) and translations (..., 3), not copied."""
        return cls(quat, translation, single)

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
        # like scipy, a zero real part (no rotation to normalise) means the identity
        zero = ~np.any(dq[..., :4], axis=-1)
        if np.any(zero):
            dq = np.where(zero[..., None], np.eye(1, 8, dtype=dq.dtype), dq)
        q, t = DQ.as_rotation_translation(DQ.normalize(dq))
        return cls._make(q, t, dq.ndim == 1)

    @classmethod
    def from_exp_coords(cls, exp_coords):
        e = _float(exp_coords, "exp_coords", (6,))
        phi, u = e[..., :3], e[..., 3:]
        theta = np.linalg.norm(phi, axis=-1, keepdims=True)
        a, b = _left_jacobian_coeffs(theta)
        pu = _cross(phi, u)
        t = u + a * pu + b * _cross(phi, pu)
        q = np.asarray(_rotation_cls().from_rotvec(phi).as_quat(scalar_first=True), e.dtype)
        return cls._make(q, t.astype(e.dtype), e.ndim == 1)

    @classmethod
    def concatenate(cls, transforms):
        if isinstance(transforms, RigidTransform):
            return cls(transforms._quat.copy(), transforms._translation.copy(), transforms._single)
        if not all(isinstance(x, RigidTransform) for x in transforms):
            raise TypeError("input must contain RigidTransform objects only")
        q = np.concatenate([np.atleast_2d(x._quat) for x in transforms])
        t = np.concatenate([np.atleast_2d(x._translation) for x in transforms])
        return cls(q, t, False)

    @classmethod
    def identity(cls, num=None, *, shape=None):
        if num is not None and shape is not None:
            raise ValueError("Only one of `num` or `shape` can be specified.")
        shape = (() if num is None else (num,)) if shape is None else tuple(np.atleast_1d(shape))
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

    def as_exp_coords(self):
        phi = np.asarray(self.rotation.as_rotvec(), self._quat.dtype)
        theta = np.linalg.norm(phi, axis=-1, keepdims=True)
        small = theta < 1e-3
        th = np.where(small, 1.0, theta)
        # inverse left Jacobian: u = t - ½ φ×t + c φ×(φ×t)
        c = np.where(small, 1 / 12 + theta**2 / 720,
                     (1 - th * np.sin(th) / (2 * (1 - np.cos(th)))) / th**2)
        t = self._translation
        pt = _cross(phi, t)
        u = t - 0.5 * pt + c * _cross(phi, pt)
        return np.concatenate([phi, u.astype(phi.dtype)], axis=-1)

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

    def __pow__(self, n):
        if n == -1:
            return self.inv()
        if n == 1:
            return type(self)(self._quat.copy(), self._translation.copy(), self._single)
        return type(self).from_exp_coords(self.as_exp_coords() * n)

    def mean(self, weights=None):
        rot = self.rotation.mean(weights) if weights is not None else self.rotation.mean()
        t = np.atleast_2d(self._translation).reshape(-1, 3)
        w = None if weights is None else np.asarray(weights, dtype=float).ravel()
        tm = np.average(t, axis=0, weights=w).astype(self._translation.dtype)
        return RigidTransform.from_components(tm, rot)

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

    def __setitem__(self, index, value):
        if self._single:
            raise TypeError("Single transform is not subscriptable.")
        if not isinstance(value, RigidTransform):
            raise TypeError("value must be a RigidTransform object")
        self._quat[index] = value._quat
        self._translation[index] = value._translation

    def __repr__(self):
        return f"RigidTransform.from_matrix({self.as_matrix()!r})"
