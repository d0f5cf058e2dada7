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
  shapes refer to *batch* axes), `COMPARISON_FUNCTIONS` (per quaternion) and
  `LAYOUT_FUNCTIONS` (class kept only when the last axis stays last).  Every
  other function sees plain ndarrays and returns plain results.
"""

import numpy as np

from . import _convert as C
from . import _euler as E
from . import _kernels as K
from ._validate import batch_shape, float_array

__all__ = ["QuatArray", "BATCH_FUNCTIONS", "COMPARISON_FUNCTIONS", "LAYOUT_FUNCTIONS"]


def _raw(x):
    """Plain ndarray view of a QuatArray (no copy)."""
    return x.view(np.ndarray)


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
    float32 (NumPy's weak-scalar rule); everything else becomes a real array.
    """
    if isinstance(x, QuatArray):
        return _raw(x)
    if isinstance(x, (int, float)):
        return x
    return float_array(x, name)


def _per_quat(s):
    """A real scalar or batch-shaped array, lifted to broadcast against (..., 4)."""
    return s[..., None] if isinstance(s, np.ndarray) else s


def _batch_axis(axis, nb, name="axis", extra=0):
    """Normalise a batch-axis index for a batch of `nb` axes (+`extra` new ones)."""
    n = nb + extra
    if not isinstance(axis, (int, np.integer)):
        raise TypeError(f"expected {name} to be an int (a batch axis), got {type(axis).__name__}")
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

    Parameters
    ----------
    data : array_like, shape (..., 4)
        Quaternions; float32 and float64 are kept, integers and bools become
        float64.  Nothing is normalised (general quaternions are allowed).
    dtype : {None, float32, float64}, optional
    copy : bool, default True
        Copy `data` (so that later in-place operations never modify it).

    Examples
    --------
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
        body = np.array2string(_raw(self), separator=", ", prefix="QuatArray(")
        suffix = "" if self.dtype == np.float64 else f", dtype={self.dtype}"
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

    # --- algebra -----------------------------------------------------------------
    def conj(self):
        """Conjugate (w, -x, -y, -z); also ``~q``.

        >>> QuatArray([1, 2, 3, 4]).conj()
        QuatArray([ 1., -2., -3., -4.])
        """
        return self._wrap(K.conjugate(_raw(self)))

    conjugate = conj

    def norm(self):
        """Norm |q| as a plain array of batch shape; also ``abs(q)``.

        >>> QuatArray([[1, 2, 2, 4]]).norm()
        array([5.])
        """
        return K.norm(_raw(self))

    def normalized(self):
        """q / |q|; zero quaternions raise `ValueError`.

        >>> QuatArray([0, 3, 0, 4]).normalized()
        QuatArray([0. , 0.6, 0. , 0.8])
        """
        return self._wrap(K.normalize(_raw(self)))

    def inverse(self):
        """conj(q) / |q|² (general quaternions); a zero quaternion raises `ZeroDivisionError`.

        >>> q = QuatArray([1, 1, 1, 1])
        >>> q * q.inverse()
        QuatArray([1., 0., 0., 0.])
        """
        return self._wrap(K.inverse(_raw(self)))

    def exp(self):
        """Quaternion exponential; also ``np.exp(q)``.

        >>> QuatArray([0, 0, 0, 0]).exp()
        QuatArray([1., 0., 0., 0.])
        """
        return self._wrap(K.exp(_raw(self)))

    def log(self):
        """Principal logarithm (ln|q|, θ v/|v|) with θ in [0, π]; also ``np.log(q)``.

        >>> QuatArray([1, 0, 0, 0]).log()
        QuatArray([0., 0., 0., 0.])
        """
        return self._wrap(K.log(_raw(self)))

    def power(self, t):
        """Quaternion power exp(t log q) for real `t` (scalar or batch-shaped); also ``q ** t``.

        >>> k = QuatArray([0, 0, 0, 1])
        >>> np.allclose(k.power(2), [-1, 0, 0, 0])
        True
        """
        return self._wrap(K.power(_raw(self), _real(t, "t")))

    def dot(self, other):
        """4-D inner product with `other` (a QuatArray), batch shape.

        >>> QuatArray([1, 2, 3, 4]).dot(QuatArray([1, 1, 1, 1]))
        np.float64(10.0)
        """
        return K.dot(_raw(self), _quat(other, "other"))

    def rotate(self, v):
        """Rotate vectors `v` (..., 3) by q/|q|, i.e. q v q⁻¹, broadcasting batch shapes.

        Zero quaternions raise `ValueError`.

        >>> q = QuatArray([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])
        >>> np.round(q.rotate([1, 0, 0]), 12)
        array([0., 1., 0.])
        """
        q = _raw(self)
        v = float_array(v, "v", last=3)
        res = K.rotate(q, v)
        if not np.isfinite(res).all() and np.isfinite(q).all() and np.isfinite(v).all():
            raise ValueError("expected non-zero quaternions to rotate by, got a zero quaternion")
        return res

    @classmethod
    def identity(cls, num=None, *, shape=None, dtype=np.float64):
        """Identity quaternions (1, 0, 0, 0).

        `num` gives a batch of shape ``(num,)`` (scipy's convention), `shape`
        any batch shape; with neither, a single quaternion of shape (4,).

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

        >>> QuatArray([0, 0, 0, 1]).as_matrix() + 0.0
        array([[-1.,  0.,  0.],
               [ 0., -1.,  0.],
               [ 0.,  0.,  1.]])
        """
        return C.as_matrix(_raw(self))

    @classmethod
    def from_matrix(cls, matrix, *, assume_valid=False):
        """Unit quaternions of rotation matrices (..., 3, 3) (non-orthogonal ones projected).

        >>> QuatArray.from_matrix(np.eye(3))
        QuatArray([1., 0., 0., 0.])
        """
        return cls._wrap(C.from_matrix(matrix, assume_valid=assume_valid))

    def as_rotvec(self, degrees=False):
        """Rotation vectors (axis × angle, angle in [0, π]) of q/|q|, shape (..., 3).

        >>> QuatArray([0, 0, 0, 1]).as_rotvec()
        array([0.        , 0.        , 3.14159265])
        """
        return C.as_rotvec(_raw(self), degrees=degrees)

    @classmethod
    def from_rotvec(cls, rotvec, degrees=False):
        """Unit quaternions of rotation vectors (..., 3).

        >>> np.allclose(QuatArray.from_rotvec([0, 0, 180], degrees=True), [0, 0, 0, 1])
        True
        """
        return cls._wrap(C.from_rotvec(rotvec, degrees=degrees))

    def as_mrp(self):
        """Modified Rodrigues parameters ``axis · tan(angle / 4)`` of q/|q|, shape (..., 3).

        >>> QuatArray([0, 0, 0, 1]).as_mrp()
        array([0., 0., 1.])
        """
        return C.as_mrp(_raw(self))

    @classmethod
    def from_mrp(cls, mrp):
        """Unit quaternions of modified Rodrigues parameters (..., 3).

        >>> QuatArray.from_mrp([0, 0, 1])
        QuatArray([0., 0., 0., 1.])
        """
        return cls._wrap(C.from_mrp(mrp))

    def as_euler(self, seq, degrees=False, *, suppress_warnings=False):
        """Euler angles (..., 3) of q/|q|, scipy's conventions ('xyz' extrinsic, 'XYZ' intrinsic).

        >>> QuatArray.from_euler("ZXY", [30, 20, 10], degrees=True).as_euler("ZXY", degrees=True).round(9)
        array([30., 20., 10.])
        """
        return E.as_euler(_raw(self), seq, degrees=degrees, suppress_warnings=suppress_warnings)

    @classmethod
    def from_euler(cls, seq, angles, degrees=False):
        """Unit quaternions of Euler angles (..., len(seq)).

        >>> np.allclose(QuatArray.from_euler("z", 180, degrees=True), [0, 0, 0, 1])
        True
        """
        return cls._wrap(E.from_euler(seq, angles, degrees=degrees))

    def as_davenport(self, axes, order, degrees=False, *, suppress_warnings=False):
        """Davenport angles (..., 3) of q/|q| about three axes (3, 3).

        >>> q = QuatArray.from_euler("zxz", [10, 20, 30], degrees=True)
        >>> q.as_davenport(np.eye(3)[[2, 0, 2]], "e", degrees=True).round(9)
        array([10., 20., 30.])
        """
        return E.as_davenport(_raw(self), axes, order, degrees=degrees, suppress_warnings=suppress_warnings)

    @classmethod
    def from_davenport(cls, axes, order, angles, degrees=False):
        """Unit quaternions of Davenport angles about 1 to 3 axes (n, 3).

        >>> np.allclose(QuatArray.from_davenport([0, 0, 1], "e", 180, degrees=True), [0, 0, 0, 1])
        True
        """
        return cls._wrap(E.from_davenport(axes, order, angles, degrees=degrees))

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
                res = _UNARY[ufunc](_quat(inputs[0], "argument"))
                return _finish_plain(res, out) if ufunc in _PLAIN_UNARY else _finish(res, out)
        elif method in ("reduce", "accumulate") and ufunc in (np.multiply, np.add):
            return _reduce(ufunc, method, *inputs, out=out, **kwargs)
        raise TypeError(
            f"ufunc {ufunc.__name__!r} ({method}) has no quaternion meaning for QuatArray; "
            f"use q.ndarray for componentwise maths on the components")

    def __array_function__(self, func, types, args, kwargs):
        handler = BATCH_FUNCTIONS.get(func) or COMPARISON_FUNCTIONS.get(func) or LAYOUT_FUNCTIONS.get(func)
        if handler is not None:
            return handler(*args, **kwargs)
        return func(*_plain(args), **_plain(kwargs))


# --- operand handling ------------------------------------------------------------

def _quat(x, name):
    """Raw quaternion array of a QuatArray operand; plain arrays are refused."""
    if isinstance(x, QuatArray):
        return _raw(x)
    raise TypeError(f"expected {name} to be a QuatArray, got {type(x).__name__} "
                    f"(wrap plain (..., 4) arrays in QuatArray to use them as quaternions)")


def _finish(res, out):
    """Wrap a raw quaternion result (..., 4), or copy it into `out`."""
    if out is None:
        return res.view(QuatArray)
    if out.shape != res.shape:
        raise ValueError(f"expected out of shape {res.shape}, got {out.shape}")
    out.view(np.ndarray)[...] = res
    return out


def _finish_plain(res, out):
    """Return a non-quaternion result (batch-shaped), or copy it into `out`."""
    if out is None:
        return res
    out[...] = res
    return out


def _lift(s, dtype_like):
    """A real operand as a real quaternion (s, 0, 0, 0) of batch shape."""
    s = np.asarray(s, dtype=np.result_type(dtype_like, s) if isinstance(s, np.ndarray) else dtype_like.dtype)
    q = np.zeros(s.shape + (4,), s.dtype)
    q[..., 0] = s
    return q


def _binary(ufunc, a, b, out=None):
    qa, qb = isinstance(a, QuatArray), isinstance(b, QuatArray)
    name = ufunc.__name__
    A = _raw(a) if qa else _real(a, "left operand of " + name)
    B = _raw(b) if qb else _real(b, "right operand of " + name)
    raw_out = _raw(out) if isinstance(out, QuatArray) else out
    if ufunc is np.multiply:
        if qa and qb:
            if raw_out is not None:
                K.multiply(A, B, out=raw_out)
                return out
            return _finish(K.multiply(A, B), None)
        return _finish(np.multiply(A if qa else _per_quat(A), B if qb else _per_quat(B)), out)
    if ufunc is np.divide:
        if qb:
            Binv = K.inverse(B)
            if qa:
                return _finish(K.multiply(A, Binv), out)
            return _finish(_per_quat(A) * Binv, out)
        return _finish(np.divide(A, _per_quat(B)), out)
    if ufunc in (np.add, np.subtract):
        if not qa:
            A = _lift(A, B)
        if not qb:
            B = _lift(B, A)
        return _finish(ufunc(A, B), out)
    if ufunc in (np.power, np.float_power):
        if qb or not qa:
            raise TypeError(f"expected a QuatArray raised to a real exponent, got {type(a).__name__} ** {type(b).__name__}")
        if ufunc is np.float_power:
            A = A.astype(np.float64)
        return _finish(K.power(A, B), out)
    if ufunc in (np.equal, np.not_equal):
        if not qa:
            A = _lift(A, B)
        if not qb:
            B = _lift(B, A)
        res = np.all(A == B, axis=-1)
        return _finish_plain(res if ufunc is np.equal else ~res, out)
    raise TypeError(f"ufunc {name!r} is not a binary quaternion operation")  # pragma: no cover


_BINARY = {np.multiply, np.divide, np.add, np.subtract, np.power, np.float_power, np.equal, np.not_equal}


_UNARY = {
    np.exp: K.exp,
    np.log: K.log,
    np.sqrt: lambda q: K.power(q, 0.5),
    np.conjugate: K.conjugate,
    np.invert: K.conjugate,  # ~q
    np.negative: np.negative,
    np.positive: np.positive,
    np.absolute: K.norm,
    np.isnan: lambda q: np.isnan(q).any(axis=-1),
    np.isfinite: lambda q: np.isfinite(q).all(axis=-1),
}
"""Unary ufuncs with a quaternion meaning (all others raise `TypeError`)."""

_PLAIN_UNARY = {np.absolute, np.isnan, np.isfinite}
"""The unary ufuncs whose results are per quaternion, not quaternions."""


def _ordered_product(a, axis):
    """Product a[0] a[1] ... a[n-1] along batch `axis` by pairwise halving (log n vectorised steps)."""
    a = np.moveaxis(a, axis, 0)
    if a.shape[0] == 0:
        res = np.zeros(a.shape[1:], a.dtype)
        res[..., 0] = 1
        return res
    while a.shape[0] > 1:
        n = a.shape[0]
        head = K.multiply(a[0:n - 1:2], a[1:n:2])
        a = np.concatenate([head, a[n - 1:]]) if n % 2 else head
    return a[0]


def _ordered_scan(a, axis):
    """Prefix products a[0], a[0]a[1], ... along batch `axis` (Hillis-Steele scan)."""
    res = np.moveaxis(a, axis, 0).astype(a.dtype, copy=True)
    shift = 1
    while shift < res.shape[0]:
        res[shift:] = K.multiply(res[:-shift], res[shift:])
        shift *= 2
    return np.moveaxis(res, 0, axis)


def _reduce(ufunc, method, q, axis=0, dtype=None, out=None, keepdims=False, where=True, **kwargs):
    """`multiply`/`add` `.reduce`/`.accumulate` along batch axes (axis=None: all of them)."""
    bad = sorted(kwargs) + (["dtype"] if dtype is not None else []) + ([] if where is True else ["where"])
    if bad:
        raise TypeError(f"QuatArray {ufunc.__name__}.{method} supports axis, out and keepdims only, got {bad}")
    raw = _quat(q, "argument")
    nb = raw.ndim - 1
    if method == "accumulate":
        ax = _batch_axis(axis, nb)
        res = _ordered_scan(raw, ax) if ufunc is np.multiply else np.add.accumulate(raw, axis=ax)
        return _finish(res, out)
    axes = _batch_axes(axis, nb)
    if ufunc is np.add:
        res = np.add.reduce(raw, axis=axes, keepdims=keepdims)
    else:
        res = raw
        for ax in sorted(axes, reverse=True):  # reduce the last batch axis first: row-major order
            res = _ordered_product(res, ax)
            if keepdims:
                res = np.expand_dims(res, ax)
    return _finish(res, out)


# --- NumPy function registries -------------------------------------------------------

def _quats(seq, name):
    return [_quat(a, f"{name}[{i}]") for i, a in enumerate(seq)]


def _concatenate(arrays, axis=0, out=None, **kwargs):
    raws = _quats(arrays, "arrays")
    if axis is None:
        raws = [r.reshape(-1, 4) for r in raws]
        axis = 0
    nb = raws[0].ndim - 1
    res = np.concatenate(raws, axis=_batch_axis(axis, nb), **kwargs)
    return _finish(res, out)


def _stack(arrays, axis=0, out=None, **kwargs):
    raws = _quats(arrays, "arrays")
    nb = raws[0].ndim - 1
    return _finish(np.stack(raws, axis=_batch_axis(axis, nb, extra=1), **kwargs), out)


def _copy(a, order="K", subok=True):
    return QuatArray._wrap(np.copy(_quat(a, "a"), order=order))


def _broadcast_to(array, shape, subok=True):
    shape = (shape,) if isinstance(shape, (int, np.integer)) else tuple(shape)
    return QuatArray._wrap(np.broadcast_to(_quat(array, "array"), shape + (4,)))


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


def _take(a, indices, axis=None, out=None, mode="raise"):
    raw = _quat(a, "a")
    if axis is None:
        raw, axis = raw.reshape(-1, 4), 0
    res = np.take(raw, _plain(indices), axis=_batch_axis(axis, raw.ndim - 1), mode=mode)
    return _finish(res, out)


def _flip(m, axis=None):
    raw = _quat(m, "m")
    return QuatArray._wrap(np.flip(raw, axis=_batch_axes(axis, raw.ndim - 1)))


def _roll(a, shift, axis=None):
    raw = _quat(a, "a")
    if axis is None:
        return QuatArray._wrap(np.roll(raw.reshape(-1, 4), shift, axis=0).reshape(raw.shape))
    return QuatArray._wrap(np.roll(raw, shift, axis=_batch_axes(axis, raw.ndim - 1)))


def _expand_dims(a, axis):
    raw = _quat(a, "a")
    axes = axis if isinstance(axis, tuple) else (axis,)
    nb_new = raw.ndim - 1 + len(axes)
    axes = tuple(_batch_axis(ax, nb_new) for ax in axes)
    return QuatArray._wrap(np.expand_dims(raw, axes))


def _squeeze(a, axis=None):
    return a.squeeze(axis) if isinstance(a, QuatArray) else np.squeeze(a, axis)


def _like(fill):
    def like(prototype, dtype=None, order="K", subok=True, shape=None, **kwargs):
        raw = _quat(prototype, "prototype")
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


BATCH_FUNCTIONS = {
    np.concatenate: _concatenate,
    np.stack: _stack,
    np.copy: _copy,
    np.broadcast_to: _broadcast_to,
    np.where: _where,
    np.take: _take,
    np.flip: _flip,
    np.roll: _roll,
    np.expand_dims: _expand_dims,
    np.squeeze: _squeeze,
    np.zeros_like: _like(0.0),
    np.ones_like: _like(1.0),  # the quaternion 1 = (1, 0, 0, 0), as numpy-quaternion's ones_like
    np.empty_like: _like(None),
}
"""NumPy functions that keep the class; axes and shapes refer to batch axes."""


def _pair(a, b):
    A = _raw(a) if isinstance(a, QuatArray) else np.asarray(a)
    B = _raw(b) if isinstance(b, QuatArray) else np.asarray(b)
    return A, B


def _isclose(a, b, rtol=1e-05, atol=1e-08, equal_nan=False):
    A, B = _pair(a, b)
    return np.all(np.isclose(A, B, rtol=rtol, atol=atol, equal_nan=equal_nan), axis=-1)


def _allclose(a, b, rtol=1e-05, atol=1e-08, equal_nan=False):
    A, B = _pair(a, b)
    return bool(np.allclose(A, B, rtol=rtol, atol=atol, equal_nan=equal_nan))


def _array_equal(a1, a2, equal_nan=False):
    A, B = _pair(a1, a2)
    return bool(np.array_equal(A, B, equal_nan=equal_nan))


COMPARISON_FUNCTIONS = {
    np.isclose: _isclose,
    np.allclose: _allclose,
    np.array_equal: _array_equal,
}
"""Comparisons per quaternion: `isclose` returns a bool array of batch shape."""


def _last_axis_stays(func, ndim, *args, **kwargs):
    """Apply an axis-permuting `func` to a tiny probe whose only long axis is the
    last one: the last axis stayed last iff the probe's does."""
    probe = func(np.empty((1,) * (ndim - 1) + (2,)), *args, **kwargs)
    return probe.ndim == ndim and probe.shape[-1] == 2


def _permutation(func):
    def apply(a, *args, **kwargs):
        if not isinstance(a, QuatArray):  # pragma: no cover - NumPy dispatches here only for QuatArrays
            return func(_plain(a), *_plain(args), **_plain(kwargs))
        res = func(_raw(a), *args, **kwargs)
        return res.view(QuatArray) if _last_axis_stays(func, a.ndim, *args, **kwargs) else res
    return apply


LAYOUT_FUNCTIONS = {
    np.reshape: lambda a, *args, **kwargs: a.reshape(*args, **kwargs),
    np.ravel: lambda a, order="C": a.ravel(order),
    np.transpose: _permutation(np.transpose),
    np.swapaxes: _permutation(np.swapaxes),
    np.moveaxis: _permutation(np.moveaxis),
    np.rollaxis: _permutation(np.rollaxis),
}
"""Functions that rearrange axes: the class is kept only when the last axis
stays last and whole (a C-order reshape to (..., 4) keeps every quaternion)."""
