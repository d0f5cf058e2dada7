"""scipy-style `RigidTransform`: ``x -> R x + t``, same API, results and errors as scipy 1.17.

Stored as a rotation (unit scalar-first quaternion) plus a translation,
not as a unit dual quaternion: `apply` then costs one quaternion rotation
and one addition, `rotation`/`translation` are free, and matrices convert
without the dual part's products.  Dual quaternions are produced on demand
by the raw `_dualquat` conversions, which are exact inverses of each other.
The price: `as_matrix` converts, where scipy, which stores matrices,
copies; a single transform keeps the matrix of its first `as_matrix` and
copies it on later calls.

The one exception is scipy's ``RigidTransform(matrix, normalize=False)``:
scipy then keeps the matrix exactly as given (with ``copy=False`` sharing
its memory), so such a transform keeps the matrix, applies it as it is (its
block need not be a rotation) and reads its rotation and translation from it
whenever they are needed.  What scipy derives from one without normalising
(`inv`, ``** ±1``, indexing, `concatenate`) keeps a matrix too; a product is
the normalised product of the matrices, as scipy's.

The maths lives in `_motion` (apply, compose, invert), `_convert` and
`_dualquat`; this module validates, wraps and keeps scipy's messages.
"""

import numpy as np

from . import _convert
from . import _dualquat
from . import _jacobian
from . import _motion
from . import _rotation_algorithms
from . import _scale
from ._rotation import Rotation
from ._validate import batch_shape

__all__ = ["RigidTransform"]

_TO_FIRST = [3, 0, 1, 2, 7, 4, 5, 6]
_TO_LAST = [1, 2, 3, 0, 5, 6, 7, 4]


def _promote(x):
    """scipy's promotion: float32 and float64 kept, other real input as float64."""
    a = np.asarray(x)
    if not a.dtype.isnative:   # big-endian input: the same values, native (scipy accepts it)
        a = a.astype(a.dtype.newbyteorder("="))
    if a.dtype == np.float32 or a.dtype == np.float64:
        return a
    if a.dtype.kind not in "biuf":
        raise TypeError(f"expected an array of real numbers, got dtype {a.dtype}")
    return a.astype(np.float64)


def _check_last(a, name, core):
    if a.ndim < 1 or a.shape[-1] != core:
        raise ValueError(f"Expected `{name}` to have shape (..., {core}), got {a.shape}.")


def _is_rotation(x):
    return hasattr(x, "as_quat") and hasattr(type(x), "from_rotvec") and not isinstance(x, RigidTransform)


def _is_unit(q):
    """True when every quaternion of `q` (..., 4) is finite with |q|² within 64 ulp of 1 (a
    normalising path's result): products of such stay far inside `_kernels.rotate`'s range."""
    n2 = np.sum(q * q, axis=-1)
    return bool(n2.size == 0 or np.max(np.abs(n2 - 1)) <= 64 * np.finfo(q.dtype).eps)


def _quat_of(rotation, name="rotation"):
    if not _is_rotation(rotation):
        raise TypeError(f"Expected `{name}` to be a `Rotation` instance, got {type(rotation)}.")
    return np.asarray(rotation.as_quat(scalar_first=True))


def _axis_angle(phi):
    """(θ, k) of rotation vectors (..., 3): θ = |φ| (..., 1) and the unit axis k (0 where θ = 0),
    each vector scaled by a power of two first, so that no square over- or underflows.
    θ is inf where |φ| itself overflows."""
    m = np.max(np.abs(phi), axis=-1, keepdims=True)
    e = np.frexp(m)[1]
    s = np.ldexp(phi, -e)
    n = np.sqrt(np.sum(s * s, axis=-1, keepdims=True))
    with np.errstate(over="ignore"):
        theta = np.ldexp(n, e)
    return theta.astype(phi.dtype, copy=False), (s / np.where(n > 0, n, 1)).astype(phi.dtype, copy=False)


def _shrink(v):
    """Translations (..., 3) whose largest component exceeds `_scale.BIG_VECTOR` scaled by
    2**-e (e their exponent, 0 for the others; None when there are none), so that the
    left Jacobian's sums of up to four such terms cannot overflow: (scaled, e)."""
    m = np.max(np.abs(v), axis=-1, keepdims=True)
    big = m > _scale.BIG_VECTOR[v.dtype]
    if not big.any():
        return v, None
    e = np.where(big, np.frexp(m)[1], 0)
    return np.ldexp(v, -e), e


def _left_jacobian(theta, k, u):
    """V(φ) u = u + (1 - cos θ)/θ k×u + (1 - sin θ/θ) k×(k×u), φ = θ k: the coefficients of
    the unit axis are bounded (no θ² or θ³ to overflow at large angles; where θ overflows
    they take their limits 0 and 1)."""
    ku = np.cross(k, u)
    return u + _jacobian.one_minus_cos(theta, 1) * ku + _jacobian.one_minus_sinc(theta, 0) * np.cross(k, ku)


def _last_row_check(m):
    ok = np.all(m[..., 3, :] == np.array([0, 0, 0, 1], m.dtype), axis=-1)
    if not np.all(ok):
        idx = () if ok.shape == () else tuple(int(i[0]) for i in np.nonzero(~ok))
        raise ValueError(f"Expected last row of transformation matrix {idx} to be "
                         f"exactly [0, 0, 0, 1], got {m[idx + (3, Ellipsis)]}")


class RigidTransform:
    """Rigid transforms ``x -> R x + t`` (rotation, then translation), batched.

    Same constructor, methods, results and errors as scipy 1.17's
    ``scipy.spatial.transform.RigidTransform``; `rotation` is a quatarray
    `Rotation`.  Use the ``from_*`` constructors rather than calling this
    class directly.

    Parameters
    ----------
    matrix : array_like, shape (..., 4, 4)
        Homogeneous transformation matrices.
    normalize : bool, default True
        Replace the rotation part by the nearest rotation matrix.  With
        False the matrix is kept exactly as given (it must be a rigid
        transform).
    copy : bool, default True
        With ``normalize=False``: False keeps (shares) the matrix itself.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import RigidTransform, Rotation
    >>> tf = RigidTransform.from_components([1.0, 0, 0], Rotation.from_rotvec([0, 0, np.pi / 2]))
    >>> np.round(tf.apply([1.0, 0, 0]), 12) + 0.0
    array([1., 1., 0.])
    >>> np.round((tf * tf.inv()).as_matrix(), 12) + 0.0
    array([[1., 0., 0., 0.],
           [0., 1., 0., 0.],
           [0., 0., 1., 0.],
           [0., 0., 0., 1.]])
    """

    # _unit: every stored quaternion is known to be finite with |q|² within rounding of 1 (made
    # by a normalising path, or checked), so that rotating vectors may skip |q|²'s range checks
    # (`_kernels.rotate`'s `unit`: the same bits); False is always safe
    __slots__ = ("_q", "_t", "_m", "_single", "_unit", "_matrix_of_one", "__weakref__")

    def __init__(self, matrix, normalize=True, copy=True):
        self._matrix_of_one = None
        m = _promote(matrix)
        if m.ndim < 2 or m.shape[-2:] != (4, 4):
            raise ValueError(f"Expected `matrix` to have shape (..., 4, 4), got {m.shape}.")
        _last_row_check(m)
        self._single = m.ndim == 2
        self._unit = bool(normalize)
        if normalize:
            self._m = None
            self._q = _convert.from_matrix(m[..., :3, :3])
            self._t = m[..., :3, 3].copy()
        else:
            # copied unless `_promote` made it: np.asarray returns a view of an ndarray
            # subclass (np.matrix, np.memmap) or of another buffer, not just `matrix` itself
            self._m = m.copy() if copy and (m is matrix or m.base is not None) else m
            self._q = self._t = None

    @classmethod
    def _from_parts(cls, quat, translation, single, unit=False):
        """From raw unit scalar-first quaternions (..., 4) and translations (..., 3), not copied;
        `unit`: the quaternions are known to be unit (see ``_unit``)."""
        tf = cls.__new__(cls)
        tf._unit = unit
        tf._q = quat
        tf._t = translation
        tf._m = None
        tf._single = single
        tf._matrix_of_one = None
        return tf

    @classmethod
    def _kept(cls, matrix, single):
        """A transform keeping the matrices (..., 4, 4) as they are, not copied: scipy's raw
        matrix, as ``RigidTransform(matrix, normalize=False)`` and what scipy derives from
        one without normalising (`inv`, ``** ±1``, indexing, `concatenate`)."""
        tf = cls.__new__(cls)
        tf._m, tf._q, tf._t = matrix, None, None
        tf._single, tf._unit, tf._matrix_of_one = single, False, None
        return tf

    @classmethod
    def _make(cls, quat, translation, single):
        """Like `_from_parts`, broadcasting the two and promoting to one dtype."""
        if quat.shape[:-1] != translation.shape[:-1] or quat.dtype != translation.dtype:
            batch = np.broadcast_shapes(quat.shape[:-1], translation.shape[:-1])
            dtype = np.result_type(quat.dtype, translation.dtype)
            quat = np.array(np.broadcast_to(quat, batch + (4,)), dtype)
            translation = np.array(np.broadcast_to(translation, batch + (3,)), dtype)
        return cls._from_parts(quat, translation, single)

    # raw parts (read from the kept matrix for normalize=False transforms: the quaternion derived
    # from its block as it is, normalised, as scipy's exp coordinates, dual quaternions, mean and
    # powers take it; `rotation` is the nearest rotation, as scipy's)
    @property
    def _quat(self):
        if self._m is None:
            return self._q
        return _convert.from_matrix(self._m[..., :3, :3], assume_valid=True)

    @property
    def _batch(self):
        """The stored batch shape (``()`` for a single transform)."""
        return self._q.shape[:-1] if self._m is None else self._m.shape[:-2]

    @property
    def _dtype(self):
        return (self._q if self._m is None else self._m).dtype

    @property
    def _translation(self):
        if self._m is None:
            return self._t
        return self._m[..., :3, 3]

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_matrix(cls, matrix):
        """From homogeneous matrices (..., 4, 4); the rotation part is orthonormalised as in scipy."""
        return cls(matrix, normalize=True, copy=True)

    @classmethod
    def from_rotation(cls, rotation):
        """Pure rotations from a `Rotation` (quatarray's or scipy's)."""
        q = _quat_of(rotation)
        return cls._from_parts(q.copy(), np.zeros(q.shape[:-1] + (3,), q.dtype), q.ndim == 1, _is_unit(q))

    @classmethod
    def from_translation(cls, translation):
        """Pure translations (..., 3)."""
        t = _promote(translation)
        _check_last(t, "translation", 3)
        q = np.zeros(t.shape[:-1] + (4,), t.dtype)
        q[..., 0] = 1
        return cls._from_parts(q, t.copy(), t.ndim == 1, unit=True)

    @classmethod
    def from_components(cls, translation, rotation):
        """Rotation then translation: ``x -> R x + t`` (batches broadcast)."""
        rot = cls.from_rotation(rotation)
        return cls.from_translation(translation) * rot

    @classmethod
    def from_exp_coords(cls, exp_coords):
        """From exponential coordinates (..., 6): rotation vector, then the se(3) translation part."""
        e = _promote(exp_coords)
        _check_last(e, "exp_coords", 6)
        phi, u = e[..., :3], e[..., 3:]
        theta, k = _axis_angle(phi)
        u, scale = _shrink(u)
        t = _left_jacobian(theta, k, u)
        if scale is not None:
            t = np.ldexp(t, scale)
        q = _convert.from_rotvec(phi).astype(e.dtype, copy=False)
        return cls._from_parts(q, t.astype(e.dtype, copy=False), e.ndim == 1, unit=True)

    @classmethod
    def from_dual_quat(cls, dual_quat, *, scalar_first=False):
        """From unit dual quaternions (..., 8) (real part, then dual part); normalised first."""
        dq = _promote(dual_quat)
        _check_last(dq, "dual_quat", 8)
        if not scalar_first:
            dq = dq[..., _TO_FIRST]
        dq = _dualquat.normalize(dq)
        q, t = _dualquat.as_rotation_translation(dq)
        return cls._from_parts(q, t, dq.ndim == 1, unit=True)

    @staticmethod
    def identity(num=None, *, shape=None):
        """Identity transforms: one, `num` of them, or of batch `shape`."""
        shape = batch_shape(num, shape, joined="and")
        q = np.zeros(shape + (4,))
        q[..., 0] = 1
        return RigidTransform._from_parts(q, np.zeros(shape + (3,)), shape == (), unit=True)

    @classmethod
    def concatenate(cls, transforms):
        """Join transforms (single ones count as one) along the first axis."""
        if isinstance(transforms, RigidTransform):
            if transforms._m is not None:
                return cls._kept(transforms.as_matrix(), transforms._single)
            return cls._from_parts(transforms._quat.copy(), transforms._translation.copy(), transforms._single,
                                   transforms._unit)
        if not all(isinstance(x, RigidTransform) for x in transforms):
            raise TypeError("input must contain RigidTransform objects only")
        if any(x._m is not None for x in transforms):   # scipy's raw matrices, joined as they are
            return cls._kept(np.concatenate([x.as_matrix().reshape((-1, 4, 4)) for x in transforms]), False)
        q = np.concatenate([np.atleast_2d(x._quat) for x in transforms])
        t = np.concatenate([np.atleast_2d(x._translation) for x in transforms])
        return cls._from_parts(q, t, False, all(x._unit for x in transforms))

    # ------------------------------------------------------------------ conversions
    def as_matrix(self):
        """Homogeneous matrices (..., 4, 4)."""
        if self._m is not None:
            return self._m.copy()
        q, t = self._q, self._t
        if q.ndim == 1 and self._matrix_of_one is not None:
            # one transform's matrix is kept, as scipy keeps it (a single transform cannot
            # change: no item assignment, and `rotation` and `translation` are copies)
            return self._matrix_of_one.copy()
        m = np.zeros(q.shape[:-1] + (4, 4), q.dtype)
        m[..., :3, :3] = _convert.as_matrix(q)
        m[..., :3, 3] = t
        m[..., 3, 3] = 1
        if q.ndim == 1:
            self._matrix_of_one = m
            return m.copy()
        return m

    def as_components(self):
        """``(translation, rotation)``."""
        return self.translation, self.rotation

    def as_exp_coords(self):
        """Exponential coordinates (..., 6): rotation vector, then the se(3) translation part."""
        q = self._quat
        phi = _convert.as_rotvec(q).astype(q.dtype, copy=False)
        theta, k = _axis_angle(phi)
        # inverse left Jacobian: u = t - θ/2 k×t + (1 - θ/2 cot(θ/2)) k×(k×t), θ in [0, π]
        c = _jacobian.one_minus_half_cot(theta, 0)
        t, scale = _shrink(self._translation)
        kt = np.cross(k, t)
        u = t - (0.5 * theta) * kt + c * np.cross(k, kt)
        if scale is not None:
            u = np.ldexp(u, scale)
        return np.concatenate([phi, u.astype(phi.dtype, copy=False)], axis=-1)

    def as_dual_quat(self, *, scalar_first=False):
        """Unit dual quaternions (..., 8): the real part, then the dual part.

        The real part has scipy's sign, that of its quaternion from the rotation matrix:
        its largest component in magnitude (x, y, z, w: the first of equal ones) is positive."""
        q = self._quat
        if self._m is None:   # (a kept matrix's quaternion comes from its matrix: scipy's sign)
            xyzw = q[..., _TO_LAST[:4]]
            lead = np.take_along_axis(xyzw, np.argmax(xyzw * xyzw, axis=-1)[..., None], axis=-1)
            q = np.where(lead < 0, 0.0 - q, q)   # (0 - q: no -0 where a component is 0)
        dq = _dualquat.from_rotation_translation(q, self._translation)
        return dq if scalar_first else dq[..., _TO_LAST]

    # ------------------------------------------------------------------ operations
    def apply(self, vector, inverse=False):
        """``R v + t`` (or ``Rᵀ (v - t)`` with `inverse`), broadcasting vectors and transforms."""
        v = np.asarray(vector, dtype=self._dtype)
        if v.ndim < 1 or v.shape[-1] != 3:
            raise ValueError(f"Expected vector to have shape (..., 3), got {v.shape}.")
        if self._batch != v.shape[:-1]:
            try:
                np.broadcast_shapes(self._batch, v.shape[:-1])
            except ValueError:
                raise ValueError("operands could not be broadcast together with transforms of shape "
                                 f"{self.shape} and vectors of shape {v.shape}") from None
        q, t = self._q, self._t
        if self._m is not None:   # normalize=False kept the matrix: applied as given, as scipy does
            out = _motion.apply_matrix(self._m, v, inverse)
        else:
            out = _motion.apply(q, t, v, inverse, self._unit)
        if self._single and v.ndim == 1:
            return out
        if self._single and out.ndim == 1:
            out = out[None]
        return out

    def inv(self):
        """The inverse transforms (of a kept matrix: scipy's ``[Rᵀ, -Rᵀ t]``, kept)."""
        if self._m is not None:
            return type(self)._kept(_motion.invert_matrix(self._m), self._single)
        q, t = _motion.inverse(self._quat, self._translation, self._unit)
        return type(self)._from_parts(q, t, self._single, self._unit)

    def __mul__(self, other):
        """Composition: ``(a * b).apply(v) == a.apply(b.apply(v))``; `other` may be a `Rotation`."""
        if not isinstance(other, RigidTransform):
            if _is_rotation(other):
                other = RigidTransform.from_rotation(other)
            else:
                return NotImplemented
        try:
            np.broadcast_shapes(self._batch, other._batch)
        except ValueError:
            raise ValueError(f"Cannot broadcast {self.shape if not self._single else (1,)} transforms in first "
                             f"to {other.shape if not other._single else (1,)} transforms in second object.") from None
        if self._m is not None or other._m is not None:
            # scipy's product of the matrices as they are, then normalised
            return type(self)(np.matmul(self.as_matrix(), other.as_matrix()), normalize=True, copy=False)
        q1, t1, q2, t2 = self._q, self._t, other._q, other._t
        single = self._single and other._single
        if not single:
            q1, t1 = (q1[None], t1[None]) if self._single else (q1, t1)
            q2, t2 = (q2[None], t2[None]) if other._single else (q2, t2)
        q, t = _motion.compose(q1, t1, q2, t2, self._unit)
        return type(self)._from_parts(q, np.asarray(t), single, self._unit and other._unit)

    def __rmul__(self, other):
        if _is_rotation(other):
            return RigidTransform.from_rotation(other) * self
        return NotImplemented

    def __pow__(self, n):
        """Power: ``n`` times the transform (fractional along its screw; scipy's exp coordinates)."""
        if isinstance(n, np.ndarray) or hasattr(n, "shape"):
            n = np.asarray(n)
            if n.shape == (1,):
                n = n[0]
            elif n.ndim != 0:
                raise ValueError("Array exponent must be a scalar")
        if not np.isfinite(n):
            raise ValueError(f"expected a finite exponent n, got {float(n)}")
        if n == 0:
            return RigidTransform.identity(shape=self.shape)
        if n == -1:
            return self.inv()
        if n == 1:
            if self._m is not None:
                return type(self)._kept(self._m.copy(), self._single)
            return type(self)._from_parts(self._quat.copy(), self._translation.copy(), self._single, self._unit)
        res = type(self).from_exp_coords(self.as_exp_coords() * n)
        res._single = self._single
        return res

    def mean(self, weights=None, axis=None):
        """Mean transform: chordal mean rotation and (weighted) mean translation."""
        q, t = self._quat, self._translation
        if self._single:
            q, t = q[None], t[None]
        if q.shape[0] == 0:
            raise ValueError("Mean of an empty rotation set is undefined.")
        axes = _rotation_algorithms.mean_axes(axis, q.shape[:-1], "transform")
        if weights is not None:
            w = _promote(weights)
            if np.any(w < 0):
                raise ValueError("`weights` must be non-negative.")
            if w.shape != q.shape[:-1]:
                raise ValueError(f"Expected `weights` to match transform shape, got shape {w.shape} "
                                 f"for {q.shape[:-1]} transformations.")
        if not axes:   # nothing averaged: each transform is its own mean (scipy's copy)
            return type(self)._from_parts(q.copy(), t.copy(), False, self._unit)
        rot = Rotation(q, normalize=False, copy=False, scalar_first=True)
        qm = np.asarray(rot.mean(weights=weights, axis=axes).as_quat(scalar_first=True), q.dtype)
        tm = _rotation_algorithms.translation_mean(t, None if weights is None else w, axes)
        return type(self)._from_parts(qm.reshape(tm.shape[:-1] + (4,)), tm, tm.ndim == 1)

    # ------------------------------------------------------------------ container
    @property
    def single(self):
        """True for one transform (no batch axes)."""
        return self._single

    @property
    def shape(self):
        """Batch shape (``()`` for a single transform)."""
        return () if self._single else self._batch

    @property
    def rotation(self):
        """The rotations, as a `Rotation` (of a kept matrix: the rotation nearest its block, as scipy's)."""
        if self._m is not None:
            return Rotation.from_matrix(self._m[..., :3, :3])
        return Rotation(self._quat, normalize=False, copy=True, scalar_first=True)

    @property
    def translation(self):
        """The translations (..., 3) (a copy)."""
        return np.array(self._translation)

    def __len__(self):
        if self._single:
            raise TypeError("Single transform has no len")
        return self._batch[0]

    def __iter__(self):
        if self._single:
            raise TypeError("Single transform is not iterable.")
        return (self[i] for i in range(len(self)))

    def __getitem__(self, index):
        if self._single:
            raise TypeError("Single transform is not subscriptable.")
        if isinstance(index, np.ndarray) and index.dtype.kind in "iu" and self._batch[0] == 0:
            raise IndexError("cannot take from an empty array")
        if self._m is not None:   # scipy's rows of the matrices as they are
            m = np.array(self._m[index])
            return type(self)._kept(m, m.ndim == 2)
        q = self._quat[index]
        return type(self)._from_parts(q.copy(), self._translation[index].copy(), q.ndim == 1, self._unit)

    def __setitem__(self, index, value):
        if self._single:
            raise TypeError("Single transform is not subscriptable.")
        if not isinstance(value, RigidTransform):
            raise TypeError("value must be a RigidTransform object")
        if self._m is not None:
            self._m[index] = value.as_matrix()
            return
        self._q[index] = value._quat
        self._t[index] = value._translation
        self._unit = self._unit and value._unit

    def __reduce__(self):
        if self._m is not None:
            return (type(self)._kept, (self._m, self._single))
        return (type(self)._from_parts, (self._quat, self._translation, self._single, self._unit))

    def __repr__(self):
        m = f"{self.as_matrix()!r}".splitlines()
        m[1:] = [" " * 27 + line for line in m[1:]]
        return "RigidTransform.from_matrix(" + "\n".join(m) + ")"

