"""`Rotation`: scipy 1.17's ``scipy.spatial.transform.Rotation``, over a `QuatArray`.

A `Rotation` holds unit quaternions, scalar-first ``(w, x, y, z)``, in an
array of shape ``(*shape, 4)`` (`as_quatarray` returns it as a `QuatArray`
without copying), the way scipy's `Rotation` holds ``_quat``.  Every method
validates its arguments, calls a raw-array function from `_convert`,
`_euler` or `_kernels`, and wraps the result; no conversion is written here.
Names, arguments, defaults, angle ranges, warnings, exception types and the
messages scipy's tests match on are scipy's.  Beyond scipy: float32 stays
float32, any batch shape works everywhere, and ``r ** n`` accepts exponents of
the batch shape (one per rotation).
"""

import math
import warnings

import numpy as np

from . import _convert
from . import _euler
from . import _kernels
from . import _rotation_algorithms
from ._array import QuatArray
from ._rotation_groups import group_quats
from ._validate import batch_shape, finite, float_array

__all__ = ["Rotation"]


def _is_scipy_rotation(x):
    t = type(x)
    return t.__name__ == "Rotation" and t.__module__.startswith("scipy.spatial.transform")


def _broadcast(p, q, message):
    try:
        return np.broadcast_shapes(p.shape[:-1], q.shape[:-1])
    except ValueError:
        raise ValueError(message) from None


class Rotation:
    """Rotations in 3 dimensions: scipy 1.17's ``Rotation``, any batch shape.

    Create rotations with the ``from_*`` class methods (`from_quat`,
    `from_matrix`, `from_rotvec`, `from_mrp`, `from_euler`,
    `from_davenport`), `identity`, `random`, `align_vectors`, `concatenate`,
    `create_group`, or from a `QuatArray` (`from_quatarray`) or a scipy
    ``Rotation`` (`from_scipy`).

    Parameters
    ----------
    quat : array_like, shape (..., 4)
        Quaternions, ``(x, y, z, w)``, or ``(w, x, y, z)`` with
        ``scalar_first=True``.  float32 stays float32; other input becomes
        float64.
    normalize : bool, default True
        Divide each quaternion by its norm (a zero quaternion raises
        `ValueError`).  With False the quaternions must already be unit.
    copy : bool, default True
        Only with ``normalize=False``: copy `quat` (scalar-first float input
        is otherwise used as it is).
    scalar_first : bool, default False

    Attributes
    ----------
    shape : tuple
        The batch shape: ``()`` for a single rotation.
    single : bool

    Notes
    -----
    ``*`` composes (``p * q`` applies ``q`` first), broadcasting batch shapes;
    ``r ** t`` turns by ``t`` times the angle about the same axis; ``==``
    compares identity, as in scipy (use `approx_equal`).  Indexing, ``len``,
    iteration, pickling and `copy` behave as in scipy.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import Rotation
    >>> r = Rotation.from_euler("z", [[0], [90]], degrees=True)
    >>> r.shape, len(r), r[1].single
    ((2,), 2, True)
    >>> np.round(r[1].apply([1, 0, 0]), 12) + 0.0
    array([0., 1., 0.])
    >>> np.round((r[1] * r[1]).as_rotvec(degrees=True), 9) + 0.0
    array([  0.,   0., 180.])
    """

    # _unit: every stored quaternion is known to be a unit one (made by a normalising path and
    # never handed out writable), so that `as_matrix` may skip the squared norms; False is
    # always safe (the general path normalises)
    __slots__ = ("_q", "_unit", "__weakref__")

    def __init__(self, quat, normalize=True, copy=True, scalar_first=False):
        if _is_scipy_rotation(quat):
            raise TypeError("expected quat to be an array of quaternions, got a scipy Rotation; "
                            "convert it with quatarray.Rotation.from_scipy")
        q = float_array(quat, "quat")
        if q.ndim == 0 or q.shape[-1] != 4:
            raise ValueError(f"Expected `quat` to have shape (..., 4), got {q.shape}.")
        if normalize:
            q = _convert.from_quat(q, scalar_first=scalar_first)
        elif not scalar_first:
            q = _convert.to_scalar_first(q)
        elif copy and (q is quat or isinstance(quat, np.ndarray) and np.may_share_memory(q, quat)):
            q = q.copy()
        self._q = q
        self._unit = bool(normalize)

    @classmethod
    def _wrap(cls, q, unit=False):
        """A rotation holding the raw unit scalar-first array `q` (no checks, no copy); `unit`:
        `q` was made by a normalising path (see ``_unit``)."""
        r = object.__new__(cls)
        r._q = q
        r._unit = unit
        return r

    # --- the stored quaternions -----------------------------------------------------------
    @property
    def _quat(self):
        """The stored quaternions as a `QuatArray` view (scipy-style private name; scipy's own
        test suite reads it).  The package's readers use `_unit_quat`: these may not be unit."""
        return self._q.view(QuatArray)

    def _unit_quat(self, name="rotations"):
        """The rotations as unit scalar-first quaternions (ndarray, not to be written), for the
        package's readers (interpolants, time series).  Known unit ones (``_unit``) are the
        stored array itself, so the readers' answers keep their bits; others (``normalize=False``,
        or handed out by `as_quatarray`) are normalised into a new array by `_convert.from_quat`
        (`_kernels.normalize`, safe at any magnitude), whose `ValueError` for a zero, NaN or
        infinite quaternion names `name`.  Unlike `as_quatarray` it keeps the unit flag."""
        if self._unit:
            return self._q
        return _convert.from_quat(self._q, scalar_first=True, name=name)

    @classmethod
    def from_quatarray(cls, q):
        """The rotations of a `QuatArray` of unit quaternions, sharing its memory.

        Zero-copy: the rotation holds `q`'s data (later changes to `q` show).
        The quaternions are not normalised or checked; use
        ``Rotation(q.ndarray, scalar_first=True)`` for a normalised copy.

        >>> import numpy as np
        >>> from quatarray import QuatArray, Rotation
        >>> q = QuatArray([[1, 0, 0, 0], [0, 0, 0, 1]])
        >>> r = Rotation.from_quatarray(q)
        >>> r.shape, np.shares_memory(r.as_quatarray(), q)
        ((2,), True)
        """
        if not isinstance(q, QuatArray):
            raise TypeError(f"expected q to be a QuatArray, got {type(q).__name__}")
        return cls._wrap(q.view(np.ndarray))

    def as_quatarray(self):
        """The stored unit quaternions as a `QuatArray` (scalar-first), without copying.

        Writing into the result changes this rotation.

        >>> from quatarray import Rotation
        >>> Rotation.from_euler("x", 0).as_quatarray()
        QuatArray([1., 0., 0., 0.])
        """
        self._unit = False   # the caller may write anything into it
        return self._q.view(QuatArray)

    @classmethod
    def from_scipy(cls, r):
        """A `Rotation` from a ``scipy.spatial.transform.Rotation`` (float64, same shape).

        >>> from scipy.spatial.transform import Rotation as ScipyRotation
        >>> from quatarray import Rotation
        >>> Rotation.from_scipy(ScipyRotation.from_rotvec([0, 0, 1])).as_rotvec()
        array([0., 0., 1.])
        """
        if not _is_scipy_rotation(r):
            raise TypeError(f"expected a scipy.spatial.transform.Rotation, got {type(r).__name__}")
        return cls._wrap(np.asarray(r.as_quat(scalar_first=True), dtype=np.float64))   # may hold normalize=False quaternions

    def to_scipy(self):
        """This rotation as a ``scipy.spatial.transform.Rotation`` (float64).

        >>> from quatarray import Rotation
        >>> Rotation.from_euler("x", 30, degrees=True).to_scipy().as_euler("xyz", degrees=True)
        array([30.,  0.,  0.])
        """
        from scipy.spatial.transform import Rotation as ScipyRotation
        q = _convert.from_quat(self._q.astype(np.float64), scalar_first=True, name="rotations")   # nan: not "zero norm"
        return ScipyRotation.from_quat(q, scalar_first=True)

    # --- quaternions ---------------------------------------------------------------------
    @classmethod
    def from_quat(cls, quat, *, scalar_first=False):
        """Rotations from quaternions ``(x, y, z, w)`` (or ``(w, x, y, z)``), normalised.

        Parameters
        ----------
        quat : array_like, shape (..., 4)
        scalar_first : bool, default False

        Raises
        ------
        ValueError
            For zero, NaN or infinite quaternions, or a last axis other than 4.

        >>> from quatarray import Rotation
        >>> Rotation.from_quat([0, 0, 1, 1]).as_quat()  # 90° about z
        array([0.        , 0.        , 0.70710678, 0.70710678])
        """
        return cls(quat, scalar_first=scalar_first)

    def as_quat(self, canonical=False, *, scalar_first=False):
        """The quaternions, shape (..., 4), ``(x, y, z, w)`` unless `scalar_first` (a new array).

        Parameters
        ----------
        canonical : bool, default False
            The representative with w ≥ 0 (for w = 0, the first non-zero of
            x, y, z positive).
        scalar_first : bool, default False

        >>> from quatarray import Rotation
        >>> r = Rotation.from_quat([0, 0, 0, -1])
        >>> r.as_quat(), r.as_quat(canonical=True), r.as_quat(scalar_first=True)
        (array([ 0.,  0.,  0., -1.]), array([0., 0., 0., 1.]), array([-1.,  0.,  0.,  0.]))
        """
        q = self._q
        q = _convert.canonical(q) if canonical else q
        if scalar_first:
            return q if canonical else q.copy()
        return _convert.to_scalar_last(q)

    # --- matrices, rotation vectors, MRPs ------------------------------------------------
    @classmethod
    def from_matrix(cls, matrix, *, assume_valid=False):
        """Rotations from rotation matrices, shape (..., 3, 3).

        A matrix that is not orthogonal is replaced by the nearest rotation
        matrix, as in scipy; `assume_valid` skips that check.

        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> r = Rotation.from_matrix([[0, -1, 0], [1, 0, 0], [0, 0, 1]])
        >>> np.round(r.as_rotvec(degrees=True), 9)
        array([ 0.,  0., 90.])
        """
        m = float_array(matrix, "matrix")
        if m.ndim < 2 or m.shape[-2:] != (3, 3):
            raise ValueError(f"Expected `matrix` to have shape (3, 3) or (..., 3, 3), got {m.shape}")
        return cls._wrap(_convert.from_matrix(m, assume_valid=assume_valid), unit=True)

    def as_matrix(self):
        """Rotation matrices, shape (..., 3, 3).

        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> np.round(Rotation.from_euler("z", 90, degrees=True).as_matrix(), 12) + 0.0
        array([[ 0., -1.,  0.],
               [ 1.,  0.,  0.],
               [ 0.,  0.,  1.]])
        """
        return _convert.as_matrix(self._q, self._unit)

    @classmethod
    def from_rotvec(cls, rotvec, degrees=False):
        """Rotations from rotation vectors (axis × angle), shape (..., 3).

        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> np.round(Rotation.from_rotvec([0, 0, np.pi / 2]).as_quat(), 6)
        array([0.      , 0.      , 0.707107, 0.707107])
        """
        v = float_array(rotvec, "rotvec")
        if v.ndim == 0 or v.shape[-1] != 3:
            raise ValueError(f"Expected `rot_vec` to have shape (3,) or (..., 3), got {v.shape}")
        return cls._wrap(_convert.from_rotvec(v, degrees=degrees), unit=True)

    def as_rotvec(self, degrees=False):
        """Rotation vectors, shape (..., 3), angle (the norm) in [0, π].

        >>> from quatarray import Rotation
        >>> Rotation.from_euler("x", 1e-9).as_rotvec()
        array([1.e-09, 0.e+00, 0.e+00])
        """
        return _convert.as_rotvec(self._q, degrees=degrees, unit=self._unit)

    @classmethod
    def from_mrp(cls, mrp):
        """Rotations from modified Rodrigues parameters ``axis · tan(angle / 4)``, shape (..., 3).

        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> np.round(Rotation.from_mrp([0, 0, 1]).as_rotvec(), 12)
        array([0.        , 0.        , 3.14159265])
        """
        p = float_array(mrp, "mrp")
        if p.ndim == 0 or p.shape[-1] != 3:
            raise ValueError(f"Expected `mrp` to have shape (3,) or (..., 3), got {p.shape}")
        return cls._wrap(_convert.from_mrp(p), unit=True)

    def as_mrp(self):
        """Modified Rodrigues parameters, shape (..., 3), norm ≤ 1.

        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> np.round(Rotation.from_rotvec([0, 0, np.pi / 2]).as_mrp(), 12)
        array([0.        , 0.        , 0.41421356])
        """
        return _convert.as_mrp(self._q, unit=self._unit)

    # --- Euler and Davenport angles -----------------------------------------------------
    @classmethod
    def from_euler(cls, seq, angles, degrees=False):
        """Rotations from Euler angles.

        Parameters
        ----------
        seq : str
            1 to 3 axes, ``'xyz'`` extrinsic or ``'XYZ'`` intrinsic.
        angles : float or array_like, shape (..., len(seq))
        degrees : bool, default False

        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> r = Rotation.from_euler("zyx", [[90, 0, 0], [0, 45, 0]], degrees=True)
        >>> np.round(r.as_rotvec(degrees=True), 9) + 0.0
        array([[ 0.,  0., 90.],
               [ 0., 45.,  0.]])
        """
        _euler.check_seq(seq)
        a = _euler.check_angles(seq, float_array(angles, "angles"))
        return cls._wrap(_euler.from_euler(seq, a, degrees=degrees), unit=True)

    def as_euler(self, seq, degrees=False, *, suppress_warnings=False):
        """Euler angles, shape (..., 3), in scipy's ranges, with its gimbal-lock warning.

        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> r = Rotation.from_euler("ZXY", [30, 20, 10], degrees=True)
        >>> np.round(r.as_euler("ZXY", degrees=True), 9)
        array([30., 20., 10.])
        """
        return _euler.as_euler(self._q, seq, degrees=degrees, suppress_warnings=suppress_warnings,
                               unit=self._unit)   # which checks seq

    @classmethod
    def from_davenport(cls, axes, order, angles, degrees=False):
        """Rotations from Davenport angles: turns about any 1 to 3 axes, consecutive ones orthogonal.

        Parameters
        ----------
        axes : array_like, shape (3,), (n, 3) or (..., n, 3)
            Batched axes broadcast with the angles' batch shape.
        order : {'e', 'extrinsic', 'i', 'intrinsic'}
        angles : float or array_like, shape (..., n)
        degrees : bool, default False

        >>> from quatarray import Rotation
        >>> r = Rotation.from_davenport([[0, 0, 1], [1, 0, 0]], "e", [90, 45], degrees=True)
        >>> bool(r.approx_equal(Rotation.from_euler("zx", [90, 45], degrees=True)))
        True
        """
        return cls._wrap(_euler.from_davenport(axes, order, angles, degrees=degrees), unit=True)

    def as_davenport(self, axes, order, degrees=False, *, suppress_warnings=False):
        """Davenport angles about three axes (the middle one orthogonal to the others), shape (..., 3).

        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> ez, ex, ey = [0, 0, 1], [1, 0, 0], [0, 1, 0]
        >>> r = Rotation.from_davenport([ez, ex, ey], "e", [90, 30, 10], degrees=True)
        >>> np.round(r.as_davenport([ez, ex, ey], "e", degrees=True), 9)
        array([90., 30., 10.])
        """
        return _euler.as_davenport(self._q, axes, order, degrees=degrees, suppress_warnings=suppress_warnings)

    # --- acting on vectors, composing, inverting, measuring -------------------------------
    def apply(self, vectors, inverse=False):
        """Rotate vectors, shape (..., 3); batch shapes broadcast as in scipy 1.17.

        One rotation and one vector give shape (3,); otherwise the result has
        the broadcast batch shape of rotations and vectors.

        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> r = Rotation.from_euler("z", [[0], [90]], degrees=True)
        >>> np.round(r.apply([1, 0, 0]), 12) + 0.0
        array([[1., 0., 0.],
               [0., 1., 0.]])
        """
        v = finite(float_array(vectors, "vectors"), "vectors")
        if v.ndim == 0 or v.shape[-1] != 3:
            raise ValueError(f"Expected input of shape (..., 3), got {v.shape}.")
        q = self._q
        if (q.ndim > 1 or v.ndim > 1) and q.shape[:-1] != v.shape[:-1]:
            _broadcast(q, v[..., :1], f"Cannot broadcast {q.shape[0]} rotations to {v.shape[0]} vectors."
                       if q.ndim <= 2 and v.ndim <= 2 else  # scipy's two wordings
                       f"Cannot broadcast {q.shape[:-1]} rotations to {v.shape} vectors.")
        return _kernels.rotate(q, v, inverse, unit=self._unit)

    def __mul__(self, other):
        """Composition ``self * other``: apply `other`, then `self` (batch shapes broadcast)."""
        if isinstance(other, Rotation):
            q = other._q
        elif _is_scipy_rotation(other):
            q = Rotation.from_scipy(other)._q
        else:
            return NotImplemented
        p = self._q
        if p.shape != q.shape:
            _broadcast(p, q, f"Cannot broadcast {p.shape[:-1]} rotations in first to "
                             f"{q.shape[:-1]} rotations in second object.")
        pq = _kernels.multiply(p, q)
        return type(self)._wrap(_kernels.normalize(pq, out=pq), unit=True)

    def __rmul__(self, other):
        if _is_scipy_rotation(other):
            return Rotation.from_scipy(other) * self
        return NotImplemented

    def __pow__(self, n, modulus=None):
        """The rotation about the same axis by `n` times the angle (scipy's ``**``).

        ``n = -1`` is `inv`, ``n = 0`` the identity.  `n` is a real number
        (or an array of shape () or (1,)), as in scipy; beyond scipy, an array
        that broadcasts with the batch shape gives one exponent per rotation.
        The angle of ``r ** n`` is ``n · r.magnitude()`` taken modulo 2π
        into [0, π] (so ``(r ** 0.5) ** 2 == r``, but not the other way round).
        Computed in one step as ``(cos(n θ/2), sin(n θ/2) v/|v|)`` with θ/2 the
        canonical half angle (scipy's ``from_rotvec(n * r.as_rotvec())``, without
        the rotation vectors in between); ``|n|`` up to the float maximum over π/2
        (a larger exponent is a ValueError: no angle is left to reduce).

        >>> from quatarray import Rotation
        >>> r = Rotation.from_rotvec([0, 0, 1])
        >>> (r ** 2).as_rotvec(), (r ** 0.5).as_rotvec()
        (array([0., 0., 2.]), array([0. , 0. , 0.5]))
        """
        if modulus is not None:
            raise NotImplementedError("modulus not supported")
        q = self._q
        if isinstance(n, np.ndarray) or not isinstance(n, (int, float, np.number)):
            t = float_array(n, "n")
            if t.shape == (1,):
                t = t[0]
            elif t.ndim != 0:
                if t.ndim > q.ndim - 1 or not _broadcastable(t.shape, q.shape[:-1]):
                    raise ValueError(f"Array exponent must be a scalar, or (an extension of "
                                     f"scipy's) broadcast with the rotations' shape "
                                     f"{q.shape[:-1]}: got shape {t.shape}")
                t = finite(t.astype(np.result_type(t.dtype, q.dtype), copy=False), "the exponent n")
                if t.dtype != q.dtype:
                    q = q.astype(t.dtype)
                return type(self)._wrap(_convert.rotation_power(q, t, unit=self._unit), unit=True)
            n = float(t)
        try:
            finite_n = math.isfinite(n)
        except OverflowError:   # an int beyond the float range
            finite_n = False
        if not finite_n:
            raise ValueError(f"expected a finite exponent n, got {n}")
        if n == 0:
            return type(self).identity(shape=q.shape[:-1], dtype=q.dtype)
        if n == -1:
            return self.inv()
        if n == 1:
            return type(self)._wrap(q.copy())
        return type(self)._wrap(_convert.rotation_power(q, n, unit=self._unit), unit=True)

    def inv(self):
        """The inverse rotations.

        >>> from quatarray import Rotation
        >>> Rotation.from_rotvec([0, 0, 1]).inv().as_rotvec() + 0.0
        array([ 0.,  0., -1.])
        """
        return type(self)._wrap(_kernels.conjugate(self._q), unit=self._unit)

    def magnitude(self):
        """Rotation angles in [0, π], batch shape (a NumPy float for one rotation).

        >>> from quatarray import Rotation
        >>> Rotation.from_rotvec([[0, 0, 1], [0, 4, 0]]).magnitude()
        array([1.        , 2.28318531])
        """
        m = _convert.magnitude(self._q, unit=self._unit)
        return m[()] if m.ndim == 0 else m

    def approx_equal(self, other, atol=None, degrees=False):
        """Whether the angle between each pair of rotations is below `atol` (batch shapes broadcast).

        Parameters
        ----------
        other : Rotation
        atol : float, optional
            Default 1e-8 rad (1e-5 rad when either side is float32).  With
            ``degrees=True`` and no `atol` the default is used and a
            `UserWarning` issued, as in scipy.
        degrees : bool, default False

        Returns
        -------
        ndarray of bool
            Shape (1,) for two single rotations, as in scipy.

        >>> from quatarray import Rotation
        >>> r = Rotation.from_rotvec([[0, 0, 1], [0, 0, 2]])
        >>> r.approx_equal(Rotation.from_rotvec([0, 0, 1 + 1e-10]))
        array([ True, False])
        """
        if not isinstance(other, Rotation):
            if not _is_scipy_rotation(other):
                raise TypeError(f"expected other to be a Rotation, got {type(other).__name__}")
            other = Rotation.from_scipy(other)
        # quaternions held as given (`from_quatarray`) may have any magnitude: their
        # product could overflow, so they are normalised first
        p = self._q if self._unit else _kernels.normalize(self._q)
        q = other._q if other._unit else _kernels.normalize(other._q)
        if atol is None:
            if degrees:
                warnings.warn("atol must be set to use the degrees flag, defaulting to 1e-8 radians.",
                              UserWarning, stacklevel=2)
            atol = 1e-8 if p.dtype == q.dtype == np.float64 else 1e-5
        elif degrees:
            atol = np.deg2rad(atol)
        if (p.ndim > 1 or q.ndim > 1) and p.shape != q.shape:
            _broadcast(p, q, f"Expected broadcastable shapes in both rotations, got {p.shape[:-1]} "
                             f"rotations in first and {q.shape[:-1]} rotations in second object.")
        # the product of two unit quaternions is one (|q p*|² within a few ulp of 1): magnitude's
        # range check would find nothing to rescale
        res = _convert.magnitude(_kernels.multiply(q, _kernels.conjugate(p)), unit=self._unit and other._unit) < atol
        return res.reshape(1) if res.ndim == 0 else res

    # --- averaging and reducing ---------------------------------------------------------
    def mean(self, weights=None, axis=None):
        """Chordal L2 mean: the dominant eigenvector of Σ wᵢ qᵢ qᵢᵀ.

        Parameters
        ----------
        weights : array_like, optional
            Non-negative, broadcastable to the batch shape.
        axis : None, int or tuple of ints, optional
            Batch axes to average over (default: all).

        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> r = Rotation.from_euler("z", [[0], [10], [20]], degrees=True)
        >>> np.round(r.mean().as_euler("zyx", degrees=True), 9) + 0.0
        array([10.,  0.,  0.])
        """
        q = self._q
        if weights is None and axis is None:
            if (q.ndim == 1 or q.shape == (1, 4)) and self._unit:   # one unit rotation: itself
                return type(self)._wrap(_convert.canonical(q.reshape(4)))
            if q.ndim == 2 and len(q):
                return type(self)._wrap(_rotation_algorithms.mean(q, None, (0,), unit=self._unit))
        if q.ndim == 1:
            q = q[None]
        batch = q.shape[:-1]
        axes = _rotation_algorithms.mean_axes(axis, batch, "rotation")
        if any(batch[a] == 0 for a in axes):
            raise ValueError(f"Mean of an empty rotation set is undefined: expected at least one "
                             f"rotation along axis {axes}, got shape {batch}")
        w = None
        if weights is not None:
            w = float_array(weights, "weights").astype(np.float64, copy=False)
            if (w < 0).any():
                raise ValueError("`weights` must be non-negative.")
            if not np.isfinite(w).all():
                raise ValueError("expected finite weights, got nan or inf")
            if not _broadcastable(w.shape, batch) or np.broadcast_shapes(w.shape, batch) != batch:
                raise ValueError(f"Expected `weights` to be broadcastable to rotation shape, got "
                                 f"shape {w.shape} for {batch} rotations.")
        if not axes:   # nothing averaged: each rotation is its own mean, as given (scipy's copy)
            return type(self)._wrap(q.copy(), unit=self._unit)
        return type(self)._wrap(_rotation_algorithms.mean(q, w, axes, unit=self._unit))

    def reduce(self, left=None, right=None, return_indices=False):
        """Reduce each rotation p to the smallest l · p · r over l in `left`, r in `right`.

        Typically `left` and `right` are symmetry groups (`create_group`):
        the result is the representative with the smallest angle.

        Parameters
        ----------
        left, right : Rotation, optional
            Candidate rotations (default: the identity only).
        return_indices : bool, default False
            Also return the chosen indices into `left` and `right` (None for
            a side that was not given).

        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> g = Rotation.create_group("C4")
        >>> r = Rotation.from_euler("z", 100, degrees=True)
        >>> round(float(np.degrees(r.reduce(left=g).magnitude())), 9)
        10.0
        """
        if left is None and right is None:
            reduced = type(self)._wrap(self._q.copy())
            return (reduced, None, None) if return_indices else reduced
        p = self._q
        ls = _coerce(left, "left").reshape(-1, 4) if left is not None else None
        rs = _coerce(right, "right").reshape(-1, 4) if right is not None else None
        reduced, li, ri = _rotation_algorithms.reduce(p, ls, rs)
        rot = type(self)._wrap(reduced)
        if not return_indices:
            return rot
        shape = p.shape[:-1] or (1,)  # scipy: shape (1,) for a single rotation
        return (rot, li.reshape(shape) if left is not None else None,
                ri.reshape(shape) if right is not None else None)

    @classmethod
    def create_group(cls, group, axis="Z"):
        """A 3D rotation group: 'I' (icosahedral), 'O', 'T', 'Cn' (cyclic) or 'Dn' (dicyclic).

        Parameters
        ----------
        group : str
        axis : {'X', 'Y', 'Z'} (or lower case), default 'Z'
            The main axis of 'Cn' and 'Dn'.

        >>> from quatarray import Rotation
        >>> Rotation.create_group("I").shape, Rotation.create_group("D3", "x").shape
        ((60,), (6,))
        """
        if not isinstance(group, str):
            raise ValueError(f"`group` argument must be a string, got {type(group).__name__}")
        permitted = ["x", "y", "z", "X", "Y", "Z"]
        if not isinstance(axis, str) or axis not in permitted:
            raise ValueError("`axis` must be one of " + ", ".join(permitted) + f", got {axis!r}")
        if group in ("I", "O", "T"):
            symbol, order = group, 1
        elif group[:1] in ("C", "D") and group[1:].isdigit():
            symbol, order = group[:1], int(group[1:])
        else:
            raise ValueError(f"`group` must be one of 'I', 'O', 'T', 'Dn', 'Cn', got {group!r}")
        if order < 1:
            raise ValueError(f"Group order must be positive, got {group!r}")
        return cls._wrap(group_quats(symbol, order, "xyz".index(axis.lower())))

    # --- construction of many ---------------------------------------------------------------
    @staticmethod
    def identity(num=None, *, shape=None, dtype=np.float64):
        """Identity rotations: one, ``num`` of them, or a batch of `shape`.

        >>> from quatarray import Rotation
        >>> Rotation.identity().single, Rotation.identity(3).shape, Rotation.identity(shape=(2, 5)).shape
        (True, (3,), (2, 5))
        """
        q = np.zeros(batch_shape(num, shape) + (4,), dtype)
        q[..., 0] = 1
        return Rotation._wrap(q, unit=True)

    @staticmethod
    def random(*args, **kwargs):
        """random(num=None, rng=None, *, shape=None): rotations uniform on SO(3): the same draws as scipy's for the same `rng`.

        Parameters
        ----------
        num : int, optional
            A batch of shape ``(num,)`` (default: one rotation).
        rng : None, int or numpy.random.Generator, optional
            By keyword: passed to `numpy.random.default_rng`.  By position
            (or as the legacy keyword `random_state`), scipy's old meaning: an
            int seeds a `numpy.random.RandomState`, None is NumPy's global
            generator, a Generator or RandomState is used as it is.
        shape : int or tuple of ints, optional
            Batch shape (instead of `num`).

        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> from scipy.spatial.transform import Rotation as ScipyRotation
        >>> ours, theirs = Rotation.random(3, rng=7), ScipyRotation.random(3, rng=7)
        >>> float(np.abs(ours.as_quat() - theirs.as_quat()).max()) < 1e-15  # same draws
        True
        """
        return _random_entry(*args, **kwargs)

    @classmethod
    def concatenate(cls, rotations):
        """Rotations stacked along the first batch axis (a single rotation counts as one).

        >>> from quatarray import Rotation
        >>> Rotation.concatenate([Rotation.identity(), Rotation.random(2, rng=0)]).shape
        (3,)
        """
        if isinstance(rotations, Rotation):
            return cls._wrap(rotations._q.copy(), unit=rotations._unit)
        if _is_scipy_rotation(rotations):
            return cls.from_scipy(rotations)
        rotations = list(rotations)
        for i, r in enumerate(rotations):
            if _is_scipy_rotation(r):
                raise TypeError(f"input must contain Rotation objects only: got a scipy Rotation at "
                                f"position {i}; convert it with quatarray.Rotation.from_scipy")
            if not isinstance(r, Rotation):
                raise TypeError(f"input must contain Rotation objects only, got "
                                f"{type(r).__name__} at position {i}")
        if not rotations:
            raise ValueError("need at least one rotation to concatenate, got an empty sequence")
        return cls._wrap(np.concatenate([np.atleast_2d(r._q) for r in rotations]),
                         unit=all(r._unit for r in rotations))

    @classmethod
    def align_vectors(cls, a, b, weights=None, return_sensitivity=False):
        """The rotation that best maps vectors `b` onto vectors `a` (Kabsch / Wahba), as scipy.

        Parameters
        ----------
        a, b : array_like, shape (3,) or (N, 3)
        weights : array_like, shape (N,), optional
            Non-negative; one infinite weight makes that pair exact.
        return_sensitivity : bool, default False

        Returns
        -------
        rotation : Rotation (single)
        rssd : float
        sensitivity : ndarray, shape (3, 3), only with `return_sensitivity`

        >>> import numpy as np
        >>> from quatarray import Rotation
        >>> r, rssd = Rotation.align_vectors([[0, 1, 0], [-1, 0, 0]], [[1, 0, 0], [0, 1, 0]])
        >>> np.round(r.as_rotvec(degrees=True), 9) + 0.0, round(float(rssd), 9)
        (array([ 0.,  0., 90.]), 0.0)
        """
        q, rssd, sens = _rotation_algorithms.align(a, b, weights, return_sensitivity)
        rot = cls._wrap(q)
        return (rot, rssd, sens) if return_sensitivity else (rot, rssd)

    # --- container behaviour -----------------------------------------------------------------
    @property
    def single(self):
        """True for one rotation (shape ``()``)."""
        return self._q.ndim == 1

    @property
    def shape(self):
        """The batch shape: ``()`` for a single rotation."""
        return self._q.shape[:-1]

    @property
    def dtype(self):
        """float32 or float64: the precision the rotations are kept in (not in scipy, which is float64 only)."""
        return self._q.dtype

    def __bool__(self):
        return True

    def __len__(self):
        if self._q.ndim == 1:
            raise TypeError("Single rotation has no len().")
        return self._q.shape[0]

    def __iter__(self):
        if self._q.ndim == 1:
            raise TypeError("Single rotation is not iterable.")
        cls = type(self)
        return (cls._wrap(q.copy(), unit=self._unit) for q in self._q)   # copies, as scipy's

    def __getitem__(self, indexer):
        if self._q.ndim == 1:
            raise TypeError("Single rotation is not subscriptable.")
        return type(self)._wrap(np.array(self._q[_batch_key(indexer, self.shape)], copy=True), unit=self._unit)

    def __setitem__(self, indexer, value):
        if self._q.ndim == 1:
            raise TypeError("Single rotation is not subscriptable.")
        if _is_scipy_rotation(value):
            value = Rotation.from_scipy(value)
        if not isinstance(value, Rotation):
            raise TypeError(f"value must be a Rotation object, got {type(value).__name__}")
        self._q[_batch_key(indexer, self.shape)] = value._q
        self._unit = self._unit and value._unit

    def __getstate__(self):
        # the unit flag travels with the quaternions: it picks the formulas (as_matrix,
        # as_mrp), so a copy or an unpickled rotation gives the original's bits
        return self._q, self._unit

    def __setstate__(self, state):
        q, unit = state if isinstance(state, tuple) else (state, False)   # an array: older pickles
        self._q = np.array(q, copy=True)
        self._unit = bool(unit)

    def __repr__(self):
        m = repr(self.as_matrix()).splitlines()
        m[1:] = [" " * 21 + line for line in m[1:]]
        return "Rotation.from_matrix(" + "\n".join(m) + ")"


def _random(num=None, rng=None, *, shape=None, legacy=False):
    size = batch_shape(num, shape)
    try:
        if legacy:
            if rng is None:   # NumPy's global RandomState, through its public module functions
                rng = np.random
            elif isinstance(rng, (int, np.integer)):
                rng = np.random.RandomState(rng)
            elif not isinstance(rng, (np.random.RandomState, np.random.Generator)):
                rng = np.random.default_rng(rng)
        else:
            rng = np.random.default_rng(rng)
    except (TypeError, ValueError) as exc:   # NumPy's own message does not say which argument
        raise type(exc)(f"expected rng to be a numpy.random.Generator, a RandomState, None or a "
                        f"non-negative int seed, got {rng!r}") from None
    return Rotation(rng.normal(size=size + (4,)))


# named `random` for Python's own argument errors ("random() takes from 0 to 2 positional
# arguments"), which scipy's tests match
_random.__name__ = _random.__qualname__ = "random"


def _random_entry(*args, **kwargs):
    """scipy's transition rule for the random generator argument (`_transition_to_rng`)."""
    by_old, by_new, by_position = "random_state" in kwargs, "rng" in kwargs, len(args) >= 2
    if by_old + by_new + by_position > 1:
        raise TypeError("random() got multiple values for argument now known as `rng`. "
                        "Specify one of `rng` or `random_state`.")
    if by_old:
        kwargs["rng"] = kwargs.pop("random_state")
    legacy = by_old or by_position or not by_new
    return _random(*args, legacy=legacy, **kwargs)


def _broadcastable(a, b):
    try:
        np.broadcast_shapes(a, b)
    except ValueError:
        return False
    return True


def _batch_key(indexer, shape):
    """An index into the batch axes of a (..., 4) array (the component axis stays whole)."""
    key = indexer if isinstance(indexer, tuple) else (indexer,)
    key = tuple(k._q if isinstance(k, Rotation) else k for k in key)
    used = sum(0 if k is None or k is Ellipsis else
               np.ndim(k) if isinstance(k, (np.ndarray, list)) and np.asarray(k).dtype == bool else 1
               for k in key)
    if used > len(shape):
        raise IndexError(f"too many indices for rotations of shape {shape}: {used} batch axes "
                         f"indexed, {len(shape)} present")
    return key + (slice(None),) if any(k is Ellipsis for k in key) else key + (Ellipsis,)


def _coerce(r, name):
    """Raw quaternions of a Rotation (or a scipy Rotation) argument."""
    if isinstance(r, Rotation):
        return r._q
    if _is_scipy_rotation(r):
        return Rotation.from_scipy(r)._q
    raise TypeError(f"expected {name} to be a Rotation, got {type(r).__name__}")
