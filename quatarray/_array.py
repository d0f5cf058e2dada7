"""`QuatArray`: an ndarray subclass of shape (..., 4) holding scalar-first quaternions.

The class is thin: it validates, calls a kernel from `_kernels`, and wraps the
result.  Three policies keep it from surprising a NumPy user:

* **Indexing** is decided from the index, not from the result's shape: an index
  that leaves the last axis whole returns a `QuatArray`, one that touches it
  returns a plain `ndarray`.
* **Ufuncs** go through `_BINARY` and `_UNARY`: each has a quaternion meaning (the Hamilton
  product for `multiply`, ...).  Any other ufunc raises `TypeError` instead of
  applying componentwise maths.
* **NumPy functions** go through `BATCH_FUNCTIONS` (keep the class; axes and
  shapes refer to *batch* axes, e.g. ``np.sum`` and ``np.mean`` of quaternions),
  `COMPARISON_FUNCTIONS` (per quaternion), `LAYOUT_FUNCTIONS` (class kept only
  when the last axis stays last) and `PLAIN_FUNCTIONS` (about the array, not
  its values: ``np.shape``, ``np.shares_memory``, ...).  Any other function
  raises `TypeError`, as a ufunc without a quaternion meaning does; use
  ``q.ndarray`` for componentwise maths.

NaN and infinite input is refused with a `ValueError` naming the argument by
every operation with a quaternion meaning; indexing, layout functions,
comparisons and ``np.isnan`` / ``np.isfinite`` accept it.
"""

import math

import numpy as np

from . import _blocks
from . import _convert
from . import _euler
from . import _kernels
from ._validate import all_finite, batch_shape, finite, float_array

__all__ = ["QuatArray", "BATCH_FUNCTIONS", "COMPARISON_FUNCTIONS", "LAYOUT_FUNCTIONS", "PLAIN_FUNCTIONS"]


def _raw(x):
    """Plain ndarray view of a QuatArray (no copy)."""
    if type(x) is QuatArray:   # ndarray's own method: `QuatArray.view`'s checks would cost as much again
        return _view(x, np.ndarray)
    return x.view(np.ndarray)


_view = np.ndarray.view


def _plain(x):
    """Replace QuatArrays by plain views, recursively through lists/tuples/dicts."""
    if isinstance(x, QuatArray):
        return _raw(x)
    if isinstance(x, (list, tuple)):
        return type(x)(_plain(v) for v in x)
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    return x


def _real(x, name):
    """A real operand that acts as a scalar per quaternion.

    Python numbers are kept as they are, so that float32 quaternions stay
    float32 (NumPy's weak-scalar rule); everything else becomes a real array,
    float32 where NumPy would promote it with float32 to float32 (bool, 8- and
    16-bit integers, float16: ``q32 * np.int8(2)`` stays float32, as in NumPy),
    else float64.
    """
    if isinstance(x, QuatArray):
        return _raw(x)
    if type(x) in (int, float):   # (exactly: a NumPy scalar such as np.float64 is strong, as in NumPy)
        return x
    dtype = getattr(x, "dtype", None)
    if (isinstance(dtype, np.dtype) and dtype.kind in "biuf" and dtype.itemsize < 4
            and np.promote_types(dtype, np.float32) == np.float32):
        return float_array(x, name, dtype=np.float32)
    return float_array(x, name)


def _per_quat(s):
    """A real scalar or batch-shaped array, lifted to broadcast against (..., 4)."""
    return s[..., None] if isinstance(s, np.ndarray) else s


def _batch_axis(axis, nb, name="axis", extra=0):
    """Normalise a batch-axis index for a batch of `nb` axes (+`extra` new ones)."""
    n = nb + extra
    if not isinstance(axis, (int, np.integer)):
        raise TypeError(f"expected {name} to be an int (a batch axis), got {type(axis).__name__}")
    if not n:   # [0, -1] would be an empty range: say what is missing instead
        raise ValueError(f"expected a QuatArray with at least one batch axis for {name}={axis}, got a single "
                         f"quaternion (shape (4,), no batch axis; its only axis holds the components)")
    if not -n <= axis < n:
        raise ValueError(f"expected {name} in [{-n}, {n - 1}] (a batch axis of a batch with {nb} axes), got {axis}")
    return int(axis) % n


def _batch_axes(axis, nb, name="axis"):
    if axis is None:
        return tuple(range(nb))
    if isinstance(axis, tuple):
        return tuple(_batch_axis(a, nb, name) for a in axis)
    return (_batch_axis(axis, nb, name),)


def _touches_last(key, shape):
    """True when indexing with `key` alters or moves the last (component) axis."""
    if not isinstance(key, tuple):
        key = (key,)
    ndim = len(shape)
    counts = []
    for k in key:
        if k is None or k is Ellipsis:
            counts.append(0)
        elif isinstance(k, (bool, np.bool_)):
            counts.append(0)
        elif isinstance(k, (slice, int, np.integer)):
            counts.append(1)
        else:
            a = np.asarray(k)
            counts.append(a.ndim if a.dtype == bool else 1)
    total = sum(counts)
    ell = [i for i, k in enumerate(key) if k is Ellipsis]
    if ell:
        counts[ell[0]] = max(ndim - total, 0)
    elif total < ndim:
        return False  # trailing axes are implicit full slices
    # find the entry that covers the last axis
    pos = 0
    for i, (k, c) in enumerate(zip(key, counts)):
        pos += c
        if pos >= ndim and c:
            if any(e is None or isinstance(e, (bool, np.bool_)) for e in key[i + 1:]):
                return True
            if k is Ellipsis:
                return False
            return not (isinstance(k, slice) and k.indices(shape[-1]) == (0, shape[-1], 1))
    return False


class QuatArray(np.ndarray):
    """Array of quaternions, shape (..., 4), components scalar-first (w, x, y, z).

    Operators: ``p * q`` (Hamilton product), ``p / q`` (p q⁻¹), ``p + q``,
    ``p - q``, ``q ** t``, ``==`` per quaternion, with NumPy broadcasting of
    batch shapes; real operands act as real quaternions.  In-place operators
    follow NumPy's casting rule (``p32 *= p64`` computes in float64 and
    rounds to float32).  See the module docstring for indexing, ufuncs,
    NumPy functions and the refusal of NaN and infinite input.

    Parameters
    ----------
    data : array_like, shape (..., 4)
        Quaternions; float32 and float64 are kept, integers and bools become
        float64.  Nothing is normalised (general quaternions are allowed).
    dtype : {None, float32, float64}, optional
    copy : bool, default True
        Copy `data` (so that later in-place operations never modify it).

    Attributes
    ----------
    batch_shape : tuple
        ``shape[:-1]``.
    w, x, y, z, vec : ndarray
        Plain views of the components (batch shape; ``vec`` is (..., 3)).
    ndarray : ndarray
        Plain view of the whole (..., 4) array.

    Methods
    -------
    conj(), norm(), normalized(), inverse(), exp(), log(), power(t), dot(other)
        Quaternion algebra; also ``~q``, ``abs(q)``, ``np.exp(q)``,
        ``np.log(q)``, ``q ** t``.
    rotate(v)
        Rotate vectors (..., 3) by q/|q|.
    identity(num=None, *, shape=None)
        Identity quaternions.
    as_matrix(), as_rotvec(), as_mrp(), as_euler(seq), as_davenport(axes, order)
        Conversions of the rotation q/|q| (scalar-first; `Rotation` has scipy's API).
    from_matrix, from_rotvec, from_mrp, from_euler, from_davenport
        The inverse conversions (class methods, unit results).

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import QuatArray
    >>> q = QuatArray([[1, 0, 0, 0], [0, 1, 0, 0]])
    >>> q
    QuatArray([[1., 0., 0., 0.],
               [0., 1., 0., 0.]])
    >>> q.batch_shape
    (2,)
    >>> q[1] * q[1]
    QuatArray([-1.,  0.,  0.,  0.])
    """

    def __new__(cls, data, dtype=None, copy=True):
        a = float_array(data, "quat", last=4, dtype=dtype)
        if copy and isinstance(data, np.ndarray) and np.may_share_memory(a, data):
            a = a.copy()
        return a.view(cls)

    @classmethod
    def _wrap(cls, a):
        """View a raw (..., 4) float ndarray as this class (no checks, no copy)."""
        return a.view(cls)

    def __array_finalize__(self, obj):
        # No attributes to carry; must never raise (NumPy calls it on every view).
        pass

    # --- shape ------------------------------------------------------------------
    @property
    def batch_shape(self):
        """Shape of the batch of quaternions: ``shape[:-1]``."""
        return self.shape[:-1]

    @property
    def ndarray(self):
        """Plain ndarray view of the whole array (shape (..., 4))."""
        return _raw(self)

    w = property(lambda self: _raw(self)[..., 0], doc="Scalar parts (plain view, batch shape).")
    x = property(lambda self: _raw(self)[..., 1], doc="i components (plain view, batch shape).")
    y = property(lambda self: _raw(self)[..., 2], doc="j components (plain view, batch shape).")
    z = property(lambda self: _raw(self)[..., 3], doc="k components (plain view, batch shape).")
    vec = property(lambda self: _raw(self)[..., 1:], doc="Vector parts (plain view, shape (..., 3)).")

    def __getitem__(self, key):
        res = _raw(self)[key]
        if not isinstance(res, np.ndarray) or _touches_last(key, self.shape):
            return res
        return res.view(type(self))

    def __repr__(self):
        suffix = "" if self.dtype == np.float64 else f", dtype={self.dtype}"
        if not self.size:   # (``[]`` would lose the shape, and read back as shape (0,))
            return f"QuatArray(np.zeros({self.shape}){suffix})"
        body = np.array2string(_raw(self), separator=", ", prefix="QuatArray(")
        return f"QuatArray({body}{suffix})"

    def __str__(self):
        return str(_raw(self))

    # --- layout methods: the class is kept only when the last axis stays last ---
    def reshape(self, *shape, order="C", **kwargs):
        res = _raw(self).reshape(*shape, order=order, **kwargs)
        c_order = order == "C" or (order == "A" and not self.flags.f_contiguous)
        keep = res.ndim >= 1 and res.shape[-1] == 4 and (c_order or self.ndim == 1 == res.ndim)
        return res.view(type(self)) if keep else res

    def ravel(self, order="C"):
        res = _raw(self).ravel(order)
        return res.view(type(self)) if self.ndim == 1 else res

    def flatten(self, order="C"):
        res = _raw(self).flatten(order)
        return res.view(type(self)) if self.ndim == 1 else res

    def transpose(self, *axes):
        res = _raw(self).transpose(*axes)
        keep = _last_axis_stays(np.ndarray.transpose, self.ndim, *axes)
        return res.view(type(self)) if keep else res

    @property
    def T(self):
        return self.transpose()

    @property
    def mT(self):
        return _raw(self).mT

    def swapaxes(self, axis1, axis2):
        res = _raw(self).swapaxes(axis1, axis2)
        keep = _last_axis_stays(np.swapaxes, self.ndim, axis1, axis2)
        return res.view(type(self)) if keep else res

    def squeeze(self, axis=None):
        """Remove batch axes of length one (the component axis is never removed)."""
        nb = self.ndim - 1
        if axis is None:
            axis = tuple(i for i in range(nb) if self.shape[i] == 1)
        return _raw(self).squeeze(_batch_axes(axis, nb)).view(type(self))

    def astype(self, dtype, *args, **kwargs):
        res = _raw(self).astype(dtype, *args, **kwargs)
        return res.view(type(self)) if res.dtype in (np.float32, np.float64) else res

    def view(self, *args, **kwargs):
        """As ndarray's; a view that is no longer (..., 4) float32 or float64 is a plain ndarray."""
        res = super().view(*args, **kwargs)
        if isinstance(res, QuatArray) and (res.dtype not in (np.float32, np.float64) or res.shape[-1:] != (4,)):
            return res.view(np.ndarray)
        return res

    # --- reductions: the methods are the NumPy functions ----------------------------
    def mean(self, *args, **kwargs):
        """Arithmetic mean over batch axes, exactly ``np.mean(q, ...)`` (not normalised;
        the mean rotation is `Rotation.mean`).

        Examples
        --------
        >>> import numpy as np
        >>> from quatarray import QuatArray
        >>> q = QuatArray([[1.0, 0, 0, 0], [0, 1, 0, 0]])
        >>> q.mean()
        QuatArray([0.5, 0.5, 0. , 0. ])
        """
        return np.mean(self, *args, **kwargs)

    def std(self, *args, **kwargs):
        """Refused as ``np.std(q)`` is: a spread of components has no quaternion meaning
        (use ``q.ndarray.std()`` for the components)."""
        return np.std(self, *args, **kwargs)

    def var(self, *args, **kwargs):
        """Refused as ``np.var(q)`` is: a spread of components has no quaternion meaning
        (use ``q.ndarray.var()`` for the components)."""
        return np.var(self, *args, **kwargs)

    # --- algebra -----------------------------------------------------------------
    def conj(self):
        """Conjugate (w, -x, -y, -z); also ``~q``.

        >>> from quatarray import QuatArray
        >>> QuatArray([1, 2, 3, 4]).conj()
        QuatArray([ 1., -2., -3., -4.])
        """
        q = _raw(self)
        res, ok = _kernels.conjugate(q, check=True)
        if not ok:
            finite(q, "the quaternions")
        return self._wrap(res)

    conjugate = conj

    def norm(self):
        """Norm |q| as a plain array of batch shape; also ``abs(q)``.

        >>> from quatarray import QuatArray
        >>> QuatArray([[1, 2, 2, 4]]).norm()
        array([5.])
        """
        return _checked(_kernels.norm, _raw(self), "the quaternions")

    def normalized(self):
        """q / |q|; zero quaternions raise `ValueError`.

        >>> from quatarray import QuatArray
        >>> QuatArray([0, 3, 0, 4]).normalized()
        QuatArray([0. , 0.6, 0. , 0.8])
        """
        return self._wrap(_checked(_kernels.normalize, _raw(self), "the quaternions"))

    def inverse(self):
        """conj(q) / |q|² (general quaternions); a zero quaternion raises `ZeroDivisionError`.

        >>> from quatarray import QuatArray
        >>> q = QuatArray([1, 1, 1, 1])
        >>> q * q.inverse()
        QuatArray([1., 0., 0., 0.])
        """
        return self._wrap(_checked(_kernels.inverse, _raw(self), "the quaternions"))

    def exp(self):
        """Quaternion exponential; also ``np.exp(q)``.

        >>> from quatarray import QuatArray
        >>> QuatArray([0, 0, 0, 0]).exp()
        QuatArray([1., 0., 0., 0.])
        """
        return self._wrap(_checked(_kernels.exp, _raw(self), "the quaternions", check=True))

    def log(self):
        """Principal logarithm (ln|q|, θ v/|v|) with θ in [0, π]; also ``np.log(q)``.

        >>> from quatarray import QuatArray
        >>> QuatArray([1, 0, 0, 0]).log()
        QuatArray([0., 0., 0., 0.])
        """
        return self._wrap(_checked(_kernels.log, _raw(self), "the quaternions"))

    def power(self, t):
        """Quaternion power exp(t log q) for real `t` (scalar or batch-shaped); also ``q ** t``.

        >>> import numpy as np
        >>> from quatarray import QuatArray
        >>> k = QuatArray([0, 0, 0, 1])
        >>> np.allclose(k.power(2), [-1, 0, 0, 0])
        True
        """
        if isinstance(t, QuatArray):
            raise TypeError("expected a real exponent t (scalar or batch-shaped), got a QuatArray")
        q, t = _raw(self), finite(_real(t, "t"), "t")
        if np.ndim(t) and t.shape != q.shape[:-1]:
            try:
                np.broadcast_shapes(q.shape[:-1], t.shape)
            except ValueError:
                raise ValueError(f"expected an exponent t broadcastable to the batch shape {q.shape[:-1]}, "
                                 f"got shape {t.shape}") from None
        return self._wrap(_checked(_kernels.power, q, "the quaternions", t))

    def dot(self, other):
        """4-D inner product with `other` (a QuatArray), batch shape.

        >>> from quatarray import QuatArray
        >>> QuatArray([1, 2, 3, 4]).dot(QuatArray([1, 1, 1, 1]))
        np.float64(10.0)
        """
        p, q = _raw(self), _operand(other, "other")
        _check_batches("dot", p, True, q, True)
        return _finite_result(_kernels.dot(p, q), ("the quaternions", p), ("other", q))

    def rotate(self, v):
        """Rotate vectors `v` (..., 3) by q/|q|, i.e. q v q⁻¹, broadcasting batch shapes.

        Zero quaternions raise `ValueError`.

        >>> import numpy as np
        >>> from quatarray import QuatArray
        >>> q = QuatArray([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])
        >>> np.round(q.rotate([1, 0, 0]), 12)
        array([0., 1., 0.])
        """
        q = _raw(self)
        v = finite(float_array(v, "v", last=3), "v")
        if q.shape[:-1] != v.shape[:-1]:
            try:
                np.broadcast_shapes(q.shape[:-1], v.shape[:-1])
            except ValueError:
                raise ValueError(f"expected v of a batch shape that broadcasts with the quaternions' "
                                 f"{q.shape[:-1]}, got v of batch shape {v.shape[:-1]}") from None
        return _checked(_kernels.rotate_nonzero, q, "the quaternions", v)

    @classmethod
    def identity(cls, num=None, *, shape=None, dtype=np.float64):
        """Identity quaternions (1, 0, 0, 0).

        `num` gives a batch of shape ``(num,)`` (scipy's convention), `shape`
        any batch shape; with neither, a single quaternion of shape (4,).

        >>> from quatarray import QuatArray
        >>> QuatArray.identity(2)
        QuatArray([[1., 0., 0., 0.],
                   [1., 0., 0., 0.]])
        """
        out = np.zeros(batch_shape(num, shape) + (4,), dtype)
        out[..., 0] = 1
        return cls._wrap(out)

    # --- conversions (scalar-first; `Rotation` has scipy's surface) ------------------
    def as_matrix(self):
        """Rotation matrices of q/|q|, shape (..., 3, 3).

        >>> from quatarray import QuatArray
        >>> QuatArray([0, 0, 0, 1]).as_matrix() + 0.0
        array([[-1.,  0.,  0.],
               [ 0., -1.,  0.],
               [ 0.,  0.,  1.]])
        """
        return _checked(_convert.as_matrix, _raw(self), "the quaternions")

    @classmethod
    def from_matrix(cls, matrix, *, assume_valid=False):
        """Unit quaternions of rotation matrices (..., 3, 3) (non-orthogonal ones projected).

        >>> import numpy as np
        >>> from quatarray import QuatArray
        >>> QuatArray.from_matrix(np.eye(3))
        QuatArray([1., 0., 0., 0.])
        """
        return cls._wrap(_convert.from_matrix(matrix, assume_valid=assume_valid))

    def as_rotvec(self, degrees=False):
        """Rotation vectors (axis × angle, angle in [0, π]) of q/|q|, shape (..., 3).

        >>> from quatarray import QuatArray
        >>> QuatArray([0, 0, 0, 1]).as_rotvec()
        array([0.        , 0.        , 3.14159265])
        """
        return _checked(_convert.as_rotvec, _raw(self), "the quaternions", degrees=degrees)

    @classmethod
    def from_rotvec(cls, rotvec, degrees=False):
        """Unit quaternions of rotation vectors (..., 3).

        >>> import numpy as np
        >>> from quatarray import QuatArray
        >>> np.allclose(QuatArray.from_rotvec([0, 0, 180], degrees=True), [0, 0, 0, 1])
        True
        """
        return cls._wrap(_convert.from_rotvec(rotvec, degrees=degrees))

    def as_mrp(self):
        """Modified Rodrigues parameters ``axis · tan(angle / 4)`` of q/|q|, shape (..., 3).

        >>> from quatarray import QuatArray
        >>> QuatArray([0, 0, 0, 1]).as_mrp()
        array([0., 0., 1.])
        """
        return _checked(_convert.as_mrp, _raw(self), "the quaternions")

    @classmethod
    def from_mrp(cls, mrp):
        """Unit quaternions of modified Rodrigues parameters (..., 3).

        >>> from quatarray import QuatArray
        >>> QuatArray.from_mrp([0, 0, 1])
        QuatArray([0., 0., 0., 1.])
        """
        return cls._wrap(_convert.from_mrp(mrp))

    def as_euler(self, seq, degrees=False, *, suppress_warnings=False):
        """Euler angles (..., 3) of q/|q|, scipy's conventions ('xyz' extrinsic, 'XYZ' intrinsic).

        >>> from quatarray import QuatArray
        >>> QuatArray.from_euler("ZXY", [30, 20, 10], degrees=True).as_euler("ZXY", degrees=True).round(9)
        array([30., 20., 10.])
        """
        q = _raw(self)
        try:   # (not through `_checked`: the gimbal warning points at the caller's frame)
            return _euler.as_euler(q, seq, degrees=degrees, suppress_warnings=suppress_warnings)
        except ValueError:
            finite(q, "the quaternions")
            raise

    @classmethod
    def from_euler(cls, seq, angles, degrees=False):
        """Unit quaternions of Euler angles (..., len(seq)).

        >>> import numpy as np
        >>> from quatarray import QuatArray
        >>> np.allclose(QuatArray.from_euler("z", 180, degrees=True), [0, 0, 0, 1])
        True
        """
        return cls._wrap(_euler.from_euler(seq, angles, degrees=degrees))

    def as_davenport(self, axes, order, degrees=False, *, suppress_warnings=False):
        """Davenport angles (..., 3) of q/|q| about three axes (3, 3), or a set per quaternion (..., 3, 3).

        >>> import numpy as np
        >>> from quatarray import QuatArray
        >>> q = QuatArray.from_euler("zxz", [10, 20, 30], degrees=True)
        >>> q.as_davenport(np.eye(3)[[2, 0, 2]], "e", degrees=True).round(9)
        array([10., 20., 30.])
        """
        q = _raw(self)
        try:   # (as in as_euler)
            return _euler.as_davenport(q, axes, order, degrees=degrees, suppress_warnings=suppress_warnings)
        except ValueError:
            finite(q, "the quaternions")
            raise

    @classmethod
    def from_davenport(cls, axes, order, angles, degrees=False):
        """Unit quaternions of Davenport angles about 1 to 3 axes (n, 3), or a set per rotation (..., n, 3).

        >>> import numpy as np
        >>> from quatarray import QuatArray
        >>> np.allclose(QuatArray.from_davenport([0, 0, 1], "e", 180, degrees=True), [0, 0, 0, 1])
        True
        """
        return cls._wrap(_euler.from_davenport(axes, order, angles, degrees=degrees))

    # --- operators (direct calls: cheaper than the ufunc protocol for small inputs) ---
    def __mul__(self, other):
        return _binary(np.multiply, self, other)

    def __rmul__(self, other):
        return _binary(np.multiply, other, self)

    def __truediv__(self, other):
        return _binary(np.divide, self, other)

    def __rtruediv__(self, other):
        return _binary(np.divide, other, self)

    def __pow__(self, t):
        # ndarray.__pow__ would shortcut t = 2 / 0.5 / -1 to square / sqrt / reciprocal
        return _binary(np.power, self, t)

    def __rpow__(self, base):
        return _binary(np.power, base, self)

    def __ipow__(self, t):
        return _binary(np.power, self, t, out=self)

    def __invert__(self):
        return self.conj()

    def __abs__(self):
        return self.norm()

    def __eq__(self, other):
        try:
            return _binary(np.equal, self, other)
        except TypeError:
            return NotImplemented

    def __ne__(self, other):
        try:
            return _binary(np.not_equal, self, other)
        except TypeError:
            return NotImplemented

    __hash__ = None

    # --- NumPy protocols -----------------------------------------------------
    def __array_ufunc__(self, ufunc, method, *inputs, out=None, **kwargs):
        if out is None and not kwargs and method == "__call__" and len(inputs) == 1:
            named = _GUARDED.get(ufunc)
            if named is not None:   # np.exp(q), np.log(q), np.sqrt(q): the steps below, at once
                return _checked(_UNARY[ufunc], _raw(self), named).view(QuatArray)
        if out is not None:
            out = out[0] if isinstance(out, tuple) and len(out) == 1 else out
            if isinstance(out, tuple):
                raise TypeError(f"expected one out array for ufunc {ufunc.__name__!r}, got {len(out)}")
        if method == "__call__":
            if kwargs:
                raise TypeError(f"QuatArray does not support the keyword(s) {sorted(kwargs)} of ufunc {ufunc.__name__!r}")
            if ufunc in _BINARY and len(inputs) == 2:
                return _binary(ufunc, *inputs, out=out)
            if ufunc in _UNARY and len(inputs) == 1:
                q = _operand(inputs[0], "argument")
                name = f"the argument of {ufunc.__name__}"
                if ufunc in _PLAIN_UNARY:
                    return _finish_plain(_checked(_UNARY[ufunc], q, name), out)
                res = _checked(_UNARY[ufunc], q, name)
                return _finish(res if ufunc in _GUARDED else _finite_result(res, (name, q)), out)
        elif method in ("reduce", "accumulate") and ufunc in (np.multiply, np.add):
            return _reduce(ufunc, method, *inputs, out=out, **kwargs)
        raise TypeError(
            f"ufunc {ufunc.__name__!r} ({method}) has no quaternion meaning for QuatArray; "
            f"use q.ndarray for componentwise maths on the components")

    def __array_function__(self, func, types, args, kwargs):
        return _dispatch(func, args, kwargs)


# --- operand handling ------------------------------------------------------------

def _method_as_function(name):
    """ndarray method `name` as the NumPy function of that name (``q.take(...)`` is ``np.take(q,
    ...)``), so that it follows the function's quaternion meaning or raises its `TypeError`:
    ndarray's own method worked on the components (``q.sort()`` sorted inside each quaternion)."""
    func = getattr(np, name)

    def method(self, *args, **kwargs):
        return func(self, *args, **kwargs)

    method.__name__ = method.__qualname__ = name   # (no docstring: ndarray's API, kept silent in the docs)
    return method


for _name in ("take", "repeat", "sort", "argsort", "partition", "argpartition", "searchsorted", "argmax",
              "argmin", "max", "min", "diagonal", "trace", "compress", "cumsum", "cumprod", "nonzero"):
    setattr(QuatArray, _name, _method_as_function(_name))
del _name


def _operand(x, name):
    """Raw quaternion array of a QuatArray operand; plain arrays are refused."""
    if isinstance(x, QuatArray):
        return _raw(x)
    raise TypeError(f"expected {name} to be a QuatArray, got {type(x).__name__} "
                    f"(wrap plain (..., 4) arrays in QuatArray to use them as quaternions)")


def _finish(res, out):
    """Wrap a raw quaternion result (..., 4), or copy it into `out`.

    The copy follows NumPy's rule for in-place operations: the result is
    computed in the operands' common dtype and cast to `out`'s if that is a
    ``same_kind`` cast (``p32 *= p64`` computes in float64 and rounds to
    float32); other casts raise `TypeError`."""
    if out is None:
        return res.view(QuatArray)
    if out.shape != res.shape:
        raise ValueError(f"expected out of shape {res.shape} (the broadcast result), got {out.shape}")
    np.copyto(out.view(np.ndarray), res, casting="same_kind")
    return out


def _finish_plain(res, out):
    """Return a non-quaternion result (batch-shaped), or copy it into `out`."""
    if out is None:
        return res
    out[...] = res
    return out


def _keepdims(s, q):
    """A real array of the quaternions' ndim whose last axis has length 1 (a reduction over the
    components with ``keepdims=True``, as in ``q / np.linalg.norm(q.ndarray, axis=-1,
    keepdims=True)``): that axis broadcasts over the components, as NumPy's would, instead of
    counting as one more batch axis (which made an (n, n) batch)."""
    return s[..., 0] if isinstance(s, np.ndarray) and 0 < s.ndim == q.ndim and s.shape[-1] == 1 else s


def _lift(s, dtype_like):
    """A real operand as a real quaternion (s, 0, 0, 0) of batch shape."""
    s = np.asarray(s, dtype=np.result_type(dtype_like, s) if isinstance(s, np.ndarray) else dtype_like.dtype)
    q = np.zeros(s.shape + (4,), s.dtype)
    q[..., 0] = s
    return q


_SYMBOLS = {np.multiply: "*", np.divide: "/", np.add: "+", np.subtract: "-", np.power: "**",
            np.float_power: "**", np.equal: "==", np.not_equal: "!="}


def _batch_of(x, is_quat):
    if isinstance(x, np.ndarray):
        shape = x.shape
    elif type(x) in (int, float):   # a Python number (`_real` keeps them): no batch, without np.shape's array
        return ()
    else:
        shape = np.shape(x)
    return shape[:-1] if is_quat else shape


def _check_batches(ufunc, A, qa, B, qb):
    """A ValueError naming the operands and their batch shapes, instead of
    NumPy's message about the (..., 4) arrays."""
    sa, sb = _batch_of(A, qa), _batch_of(B, qb)
    if sa == sb or not sa or not sb:
        return
    try:
        np.broadcast_shapes(sa, sb)
    except ValueError:
        kind = {True: "QuatArray", False: "real"}
        raise ValueError(
            f"expected operands of {_SYMBOLS.get(ufunc, getattr(ufunc, '__name__', ufunc))} with broadcastable batch shapes, got "
            f"left {kind[qa]} operand of batch shape {sa} and right {kind[qb]} operand of batch shape {sb}"
        ) from None


def _checked(kernel, q, name, *args, **kwargs):
    """``kernel(q, *args, **kwargs)``; where the kernel raises `ValueError` (its range test finds
    nan or inf without knowing where, or a zero quaternion), `finite`'s error for nan or inf in
    `q` instead, naming `name` and the first such index; otherwise the kernel's own."""
    try:
        return kernel(q, *args, **kwargs)
    except ValueError:
        finite(q, name)
        raise


def _finite_result(res, *named):
    """The API's non-finite policy for results computed without a guard.

    NaN and infinities in the operands reach the result of these operations,
    so one sum of the result decides the common case; only a result that is
    not finite (non-finite operands, or finite ones that overflowed, which
    is allowed as in NumPy) has its operands looked at one by one."""
    if not all_finite(res):
        for name, x in named:
            finite(x, name)
    return res


def _binary(ufunc, a, b, out=None):
    qa, qb = isinstance(a, QuatArray), isinstance(b, QuatArray)
    if ufunc is _MULTIPLY and qa and qb and out is None and a.shape == b.shape:
        # the product of two arrays of one shape (no batches to check): the steps below, at once
        res, ok = _kernels.multiply(_raw(a), _raw(b), check=True)
        if not ok:
            _finite_operands(ufunc, _raw(a), _raw(b))
        return res.view(QuatArray)
    if ufunc is _POWER and qa and out is None and (type(b) is float or type(b) is int and -_INT_EXP < b < _INT_EXP):
        # q ** t for a Python number t (no batches to check): the steps below, at once; the kernel
        # refuses nan and inf in q, so only a t that is not finite could make the result so
        A = _raw(a)
        try:
            res = _kernels.power(A, b)
        except ValueError:
            _finite_operands(ufunc, A, b)
            raise
        if not math.isfinite(b):
            _finite_operands(ufunc, A, b)
        return res.view(QuatArray)
    name = ufunc.__name__
    if not (qa or qb):   # a QuatArray `out` only: no quaternion among the operands
        raise TypeError(f"expected a QuatArray operand of {name} writing into a QuatArray out, got "
                        f"{type(a).__name__} and {type(b).__name__} (use out.ndarray for componentwise maths)")
    A = _raw(a) if qa else _keepdims(_real(a, "left operand of " + name), _raw(b))
    B = _raw(b) if qb else _keepdims(_real(b, "right operand of " + name), A)
    _check_batches(ufunc, A, qa, B, qb)
    if ufunc in (np.equal, np.not_equal):   # comparisons accept nan (nan != nan)
        if not qa:
            A = _lift(A, B)
        if not qb:
            B = _lift(B, A)
        res = np.all(A == B, axis=-1)
        return _finish_plain(res if ufunc is np.equal else ~res, out)
    if ufunc is np.multiply and qa and qb:   # the product's blocks are judged while in cache
        res, ok = _kernels.multiply(A, B, check=True)
    else:
        try:
            res = _compute(ufunc, A, qa, B, qb, a, b)
        except ValueError:   # a kernel's range test found nan or inf (it cannot say where), or not
            _finite_operands(ufunc, A, B)
            raise
        ok = all_finite(res)
    if not ok:
        _finite_operands(ufunc, A, B)
    return _finish(res, out)


_MULTIPLY, _POWER = np.multiply, np.power   # (`_binary`'s first tests: a name, not an attribute too)

_INT_EXP = 2 ** 53
"""Python integer exponents of `_binary`'s ``q ** t`` path for numbers: those that are floats
exactly (larger ones take the general path, as before)."""


def _finite_operands(ufunc, A, B):
    """`finite`'s error for the first operand of a binary operation holding nan or inf."""
    symbol = _SYMBOLS[ufunc]
    finite(A, f"the left operand of {symbol}")
    finite(B, f"the right operand of {symbol}")


def _compute(ufunc, A, qa, B, qb, a, b):
    """The raw result of a binary operation (the quaternion meaning of `ufunc`)."""
    if ufunc is np.multiply:
        if qa and qb:
            return _kernels.multiply(A, B)
        return np.multiply(A if qa else _per_quat(A), B if qb else _per_quat(B))
    if ufunc is np.divide:
        if qb:
            Binv = _kernels.inverse(B)
            return _kernels.multiply(A, Binv) if qa else _per_quat(A) * Binv
        if not np.all(B):   # as dividing by the zero quaternion (1/0 gave inf, 0/0 NaN)
            raise ZeroDivisionError("quaternion division: expected non-zero real divisors, got 0")
        return np.divide(A, _per_quat(B))
    if ufunc in (np.add, np.subtract):
        if not qa:
            A = _lift(A, B)
        if not qb:
            B = _lift(B, A)
        return ufunc(A, B)
    if ufunc in (np.power, np.float_power):
        if qb or not qa:
            raise TypeError(f"expected a QuatArray raised to a real exponent, got {type(a).__name__} ** {type(b).__name__}")
        if ufunc is np.float_power:
            A = A.astype(np.float64)
        return _kernels.power(A, B)
    if ufunc in (np.equal, np.not_equal):
        if not qa:
            A = _lift(A, B)
        if not qb:
            B = _lift(B, A)
        raise AssertionError("comparisons are handled by _binary")  # pragma: no cover
    raise TypeError(f"ufunc {ufunc.__name__!r} is not a binary quaternion operation")  # pragma: no cover


_BINARY = {np.multiply, np.divide, np.add, np.subtract, np.power, np.float_power, np.equal, np.not_equal}


_UNARY = {
    np.exp: lambda q: _kernels.exp(q, check=True),   # (exp(-inf) is finite: the kernel looks for it)
    np.log: _kernels.log,
    np.sqrt: lambda q: _kernels.power(q, 0.5),
    np.conjugate: _kernels.conjugate,
    np.invert: _kernels.conjugate,  # ~q
    np.negative: np.negative,
    np.positive: np.positive,
    np.absolute: _kernels.norm,
    np.isnan: lambda q: np.isnan(q).any(axis=-1),
    np.isfinite: lambda q: np.isfinite(q).all(axis=-1),
}
"""Unary ufuncs with a quaternion meaning (all others raise `TypeError`)."""

_GUARDED = {ufunc: f"the argument of {ufunc.__name__}" for ufunc in (np.exp, np.log, np.sqrt)}
"""The unary ufuncs whose kernels (or `_UNARY`'s entries) refuse nan and inf in the argument
themselves, so that a result that is not finite (an overflow, ln 0) came from finite input,
which `_finite_result` would look at in vain; each with the name its errors give the
argument."""

_PLAIN_UNARY = {np.absolute, np.isnan, np.isfinite}
"""The unary ufuncs whose results are per quaternion, not quaternions (`absolute`
refuses nan and inf in its kernel; `isnan` and `isfinite` test for them)."""


def _ordered_product(a, axis):
    """Product a[0] a[1] ... a[n-1] along batch `axis` by pairwise halving (log n vectorised steps).

    A long axis is halved in aligned chunks of a power of two (each about one block) and then
    the chunks' products: the same pairs in the same order as halving it whole, with a few
    blocks of extra memory instead of half the input."""
    a = np.moveaxis(a, axis, 0)
    if a.shape[0] == 0:
        res = np.zeros(a.shape[1:], a.dtype)
        res[..., 0] = 1
        return res
    per = max(1, a[0].size // 4)
    chunk = 1 << max(1, (_blocks.block_size(a.dtype) // per).bit_length() - 1)
    if a.shape[0] > chunk:
        a = np.stack([_ordered_product(a[i:i + chunk], 0) for i in range(0, a.shape[0], chunk)])
    while a.shape[0] > 1:
        n = a.shape[0]
        head = _kernels.multiply(a[0:n - 1:2], a[1:n:2])
        a = np.concatenate([head, a[n - 1:]]) if n % 2 else head
    return a[0]


def _ordered_scan(a, axis):
    """Prefix products a[0], a[0]a[1], ... along batch `axis` (Hillis-Steele scan)."""
    res = np.moveaxis(a, axis, 0).astype(a.dtype, copy=True)
    shift = 1
    while shift < res.shape[0]:
        res[shift:] = _kernels.multiply(res[:-shift], res[shift:])
        shift *= 2
    return np.moveaxis(res, 0, axis)


def _reduce(ufunc, method, q, axis=0, dtype=None, out=None, keepdims=False, where=True, **kwargs):
    """`multiply`/`add` `.reduce`/`.accumulate` along batch axes (axis=None: all of them)."""
    bad = sorted(kwargs) + (["dtype"] if dtype is not None else []) + ([] if where is True else ["where"])
    if bad:
        raise TypeError(f"QuatArray {ufunc.__name__}.{method} supports axis, out and keepdims only, got {bad}")
    raw = _operand(q, "argument")
    with np.errstate(invalid="ignore"):   # inf * 0: refused by the check below
        return _reduce_raw(ufunc, method, raw, axis, out, keepdims)


def _reduce_raw(ufunc, method, raw, axis, out, keepdims):
    nb = raw.ndim - 1
    if method == "accumulate":
        ax = _batch_axis(axis, nb)
        res = _ordered_scan(raw, ax) if ufunc is np.multiply else np.add.accumulate(raw, axis=ax)
        return _finish(_finite_result(res, ("the quaternions", raw)), out)
    axes = _batch_axes(axis, nb)
    if ufunc is np.add:
        res = np.add.reduce(raw, axis=axes, keepdims=keepdims)
    else:
        res = raw
        for ax in sorted(axes, reverse=True):  # reduce the last batch axis first: row-major order
            res = _ordered_product(res, ax)
            if keepdims:
                res = np.expand_dims(res, ax)
    return _finish(_finite_result(res, ("the quaternions", raw)), out)


# --- NumPy function registries -------------------------------------------------------
#
# Every NumPy function a QuatArray reaches goes through one of these tables
# (astropy's pattern): a handler is registered next to its code with
# `_implements`, its signature is NumPy's (tests/test_array.py checks it with
# `inspect`), and a function in no table raises `TypeError`, as a ufunc
# without a quaternion meaning does.

BATCH_FUNCTIONS = {}
"""NumPy functions that keep the class; axes and shapes refer to batch axes."""

COMPARISON_FUNCTIONS = {}
"""Comparisons per quaternion: `isclose` returns a bool array of batch shape."""

LAYOUT_FUNCTIONS = {}
"""Functions that rearrange axes: the class is kept only when the last axis
stays last and whole (a C-order reshape to (..., 4) keeps every quaternion)."""

PLAIN_FUNCTIONS = {
    np.shape, np.ndim, np.size, np.result_type, np.shares_memory, np.may_share_memory,
    np.array_repr, np.array_str, np.array2string, np.save, np.savez, np.savez_compressed,
    np.iscomplexobj, np.isrealobj,
}
"""Functions about the array rather than its values (or that store it): they see
the plain (..., 4) components and return what NumPy returns for them."""

_NOVALUE = np._NoValue


def _implements(table, *funcs):
    """Register the decorated handler for `funcs` in `table`."""
    def register(handler):
        for func in funcs:
            table[func] = handler
        return handler
    return register


def _dispatch(func, args, kwargs):
    handler = BATCH_FUNCTIONS.get(func) or COMPARISON_FUNCTIONS.get(func) or LAYOUT_FUNCTIONS.get(func)
    if handler is not None:
        return handler(*args, **kwargs)
    if func in PLAIN_FUNCTIONS:
        return func(*_plain(args), **_plain(kwargs))
    name = getattr(func, "__name__", repr(func))
    raise TypeError(f"NumPy function {name!r} has no quaternion meaning for QuatArray; "
                    f"use q.ndarray for componentwise maths on the components")


def _operands(seq, name):
    return [_operand(a, f"{name}[{i}]") for i, a in enumerate(seq)]


@_implements(BATCH_FUNCTIONS, np.concatenate)
def _concatenate(arrays, axis=0, out=None, *, dtype=None, casting="same_kind"):
    raws = _operands(arrays, "arrays")
    if axis is None:
        raws = [r.reshape(-1, 4) for r in raws]
        axis = 0
    nb = raws[0].ndim - 1
    res = np.concatenate(raws, axis=_batch_axis(axis, nb), dtype=dtype, casting=casting)
    return _finish(res, out)


@_implements(BATCH_FUNCTIONS, np.stack)
def _stack(arrays, axis=0, out=None, *, dtype=None, casting="same_kind"):
    raws = _operands(arrays, "arrays")
    nb = raws[0].ndim - 1
    return _finish(np.stack(raws, axis=_batch_axis(axis, nb, extra=1), dtype=dtype, casting=casting), out)


@_implements(BATCH_FUNCTIONS, np.copy)
def _copy(a, order="K", subok=False):
    return QuatArray._wrap(np.copy(_operand(a, "a"), order=order))


@_implements(BATCH_FUNCTIONS, np.broadcast_to)
def _broadcast_to(array, shape, subok=False):
    shape = (shape,) if isinstance(shape, (int, np.integer)) else tuple(shape)
    return QuatArray._wrap(np.broadcast_to(_operand(array, "array"), shape + (4,)))


@_implements(BATCH_FUNCTIONS, np.where)
def _where(condition, *xy):
    if len(xy) != 2:
        return np.where(_plain(condition))
    x, y = xy
    if not isinstance(x, QuatArray) and not isinstance(y, QuatArray):  # pragma: no cover - NumPy dispatches only with a QuatArray
        return np.where(condition, x, y)
    X = _raw(x) if isinstance(x, QuatArray) else _lift(_real(x, "x"), _raw(y))
    Y = _raw(y) if isinstance(y, QuatArray) else _lift(_real(y, "y"), X)
    cond = np.asarray(_plain(condition), dtype=bool)
    return QuatArray._wrap(np.where(cond[..., None], X, Y))


@_implements(BATCH_FUNCTIONS, np.take)
def _take(a, indices, axis=None, out=None, mode="raise"):
    raw = _operand(a, "a")
    if axis is None:
        raw, axis = raw.reshape(-1, 4), 0
    res = np.take(raw, _plain(indices), axis=_batch_axis(axis, raw.ndim - 1), mode=mode)
    return _finish(res, out)


@_implements(BATCH_FUNCTIONS, np.repeat)
def _repeat(a, repeats, axis=None):
    raw = _operand(a, "a")
    if axis is None:
        raw, axis = raw.reshape(-1, 4), 0
    return QuatArray._wrap(np.repeat(raw, _plain(repeats), axis=_batch_axis(axis, raw.ndim - 1)))


@_implements(BATCH_FUNCTIONS, np.flip)
def _flip(m, axis=None):
    raw = _operand(m, "m")
    return QuatArray._wrap(np.flip(raw, axis=_batch_axes(axis, raw.ndim - 1)))


@_implements(BATCH_FUNCTIONS, np.roll)
def _roll(a, shift, axis=None):
    raw = _operand(a, "a")
    if axis is None:
        return QuatArray._wrap(np.roll(raw.reshape(-1, 4), shift, axis=0).reshape(raw.shape))
    return QuatArray._wrap(np.roll(raw, shift, axis=_batch_axes(axis, raw.ndim - 1)))


@_implements(BATCH_FUNCTIONS, np.expand_dims)
def _expand_dims(a, axis):
    raw = _operand(a, "a")
    axes = axis if isinstance(axis, tuple) else (axis,)
    nb_new = raw.ndim - 1 + len(axes)
    axes = tuple(_batch_axis(ax, nb_new) for ax in axes)
    return QuatArray._wrap(np.expand_dims(raw, axes))


@_implements(BATCH_FUNCTIONS, np.squeeze)
def _squeeze(a, axis=None):
    return a.squeeze(axis) if isinstance(a, QuatArray) else np.squeeze(a, axis)


def _like(fill):
    def like(a, dtype=None, order="K", subok=True, shape=None, *, device=None):
        raw = _operand(a, "a")
        dtype = raw.dtype if dtype is None else np.dtype(dtype)
        if dtype not in (np.float32, np.float64):
            raise TypeError(f"expected dtype float32 or float64 for a QuatArray, got {dtype}")
        full = raw.shape if shape is None else ((shape,) if isinstance(shape, (int, np.integer)) else tuple(shape)) + (4,)
        res = np.empty(full, dtype)
        if fill is not None:
            res[...] = 0
            res[..., 0] = fill
        return QuatArray._wrap(res)
    return like


_implements(BATCH_FUNCTIONS, np.zeros_like)(_like(0.0))
_implements(BATCH_FUNCTIONS, np.ones_like)(_like(1.0))  # the quaternion 1 = (1, 0, 0, 0), as numpy-quaternion's
_implements(BATCH_FUNCTIONS, np.empty_like)(_like(None))


def _no_extras(name, **given):
    extra = sorted(k for k, v in given.items() if v is not None and v is not _NOVALUE)
    if extra:
        raise TypeError(f"np.{name} of a QuatArray supports axis, out and keepdims only, got {extra}")


@_implements(BATCH_FUNCTIONS, np.sum)
def _sum(a, axis=None, dtype=None, out=None, keepdims=_NOVALUE, initial=_NOVALUE, where=_NOVALUE):
    """Sum of quaternions over batch axes (all of them by default)."""
    _no_extras("sum", dtype=dtype, initial=initial, where=where)
    return _reduce(np.add, "reduce", a, axis=axis, out=out, keepdims=keepdims is True)


@_implements(BATCH_FUNCTIONS, np.mean)
def _mean(a, axis=None, dtype=None, out=None, keepdims=_NOVALUE, *, where=_NOVALUE):
    """Arithmetic mean of quaternions over batch axes (not normalised; for the
    mean rotation see `Rotation.mean`)."""
    _no_extras("mean", dtype=dtype, where=where)
    raw = _operand(a, "a")
    count = int(np.prod([raw.shape[ax] for ax in _batch_axes(axis, raw.ndim - 1)]))
    res = _reduce(np.add, "reduce", a, axis=axis, keepdims=keepdims is True)
    return _finish(_raw(res) / count, out)


def _pair(a, b):
    A = _raw(a) if isinstance(a, QuatArray) else np.asarray(a)
    B = _raw(b) if isinstance(b, QuatArray) else np.asarray(b)
    return A, B


@_implements(COMPARISON_FUNCTIONS, np.isclose)
def _isclose(a, b, rtol=1e-05, atol=1e-08, equal_nan=False):
    A, B = _pair(a, b)
    return np.all(np.isclose(A, B, rtol=rtol, atol=atol, equal_nan=equal_nan), axis=-1)


@_implements(COMPARISON_FUNCTIONS, np.allclose)
def _allclose(a, b, rtol=1e-05, atol=1e-08, equal_nan=False):
    A, B = _pair(a, b)
    return bool(np.allclose(A, B, rtol=rtol, atol=atol, equal_nan=equal_nan))


@_implements(COMPARISON_FUNCTIONS, np.array_equal)
def _array_equal(a1, a2, equal_nan=False):
    A, B = _pair(a1, a2)
    return bool(np.array_equal(A, B, equal_nan=equal_nan))


def _last_axis_stays(func, ndim, *args, **kwargs):
    """Apply an axis-permuting `func` to a tiny probe whose only long axis is the
    last one: the last axis stayed last iff the probe's does."""
    probe = func(np.empty((1,) * (ndim - 1) + (2,)), *args, **kwargs)
    return probe.ndim == ndim and probe.shape[-1] == 2


def _permuted(func, a, *args, **kwargs):
    if not isinstance(a, QuatArray):  # pragma: no cover - NumPy dispatches here only for QuatArrays
        return func(_plain(a), *_plain(args), **_plain(kwargs))
    res = func(_raw(a), *args, **kwargs)
    return res.view(QuatArray) if _last_axis_stays(func, a.ndim, *args, **kwargs) else res


@_implements(LAYOUT_FUNCTIONS, np.reshape)
def _reshape(a, /, shape=None, order="C", *, newshape=None, copy=None):
    if shape is None:
        shape = newshape
    if copy is not None:
        return a.reshape(shape, order=order, copy=copy)
    return a.reshape(shape, order=order)


@_implements(LAYOUT_FUNCTIONS, np.ravel)
def _ravel(a, order="C"):
    return a.ravel(order)


@_implements(LAYOUT_FUNCTIONS, np.transpose)
def _transpose(a, axes=None):
    return _permuted(np.transpose, a, axes)


@_implements(LAYOUT_FUNCTIONS, np.swapaxes)
def _swapaxes(a, axis1, axis2):
    return _permuted(np.swapaxes, a, axis1, axis2)


@_implements(LAYOUT_FUNCTIONS, np.moveaxis)
def _moveaxis(a, source, destination):
    return _permuted(np.moveaxis, a, source, destination)


@_implements(LAYOUT_FUNCTIONS, np.rollaxis)
def _rollaxis(a, axis, start=0):
    return _permuted(np.rollaxis, a, axis, start)
