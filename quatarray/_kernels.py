"""Quaternion algebra on raw ndarrays of shape (..., 4), scalar-first (w, x, y, z).

Every function broadcasts batch shapes the NumPy way, keeps float32 as
float32, never modifies its inputs and never imports the `QuatArray` class.
Long inputs are processed in cache-sized blocks (`blocks`) into a
preallocated output.
"""

from math import prod

import numpy as np

from ._validate import CHUNK

__all__ = [
    "blocks", "result_dtype", "multiply", "conjugate", "sqnorm", "norm",
    "normalize", "inverse", "dot", "exp", "log", "power", "rotate",
]

_COMPLEX = {np.dtype(np.float32): np.complex64, np.dtype(np.float64): np.complex128}


def result_dtype(*arrays):
    """The float dtype of a result: float32 only if every quaternion input is float32.

    >>> result_dtype(np.zeros(4, np.float32), np.zeros(4))
    dtype('float64')
    """
    return np.result_type(*arrays, np.float32)


def blocks(shape, chunk=CHUNK):
    """Partition a batch `shape` into blocks of about `chunk` elements.

    Yields index tuples (into the leading axes) that together cover the
    batch exactly once; a batch of at most `chunk` elements is one block
    ``()``.

    >>> list(blocks((5,), chunk=2))
    [(slice(0, 2, None),), (slice(2, 4, None),), (slice(4, 6, None),)]
    >>> len(list(blocks((3, 4), chunk=4)))
    3
    """
    shape = tuple(shape)
    if prod(shape) <= chunk:
        yield ()
        return
    inner, k = 1, len(shape)
    while k > 0 and inner * shape[k - 1] <= chunk:
        inner *= shape[k - 1]
        k -= 1
    ax = k - 1
    step = max(chunk // inner, 1)
    for outer in np.ndindex(*shape[:ax]):
        for start in range(0, shape[ax], step):
            yield outer + (slice(start, start + step),)


def _sub(a, idx, batch_ndim, lead=1):
    """The part of `a` (batch right-aligned to a batch of `batch_ndim` axes,
    with `lead` trailing core axes) that broadcasts against block `idx`."""
    if not idx:
        return a
    offset = batch_ndim - (a.ndim - lead)
    sel = []
    for i, ix in enumerate(idx):
        j = i - offset
        if j < 0:
            continue
        if a.shape[j] == 1:
            sel.append(0 if isinstance(ix, int) else slice(None))
        else:
            sel.append(ix)
    return a[tuple(sel)]


def _contig_last(a, dtype):
    """`a` as `dtype` with a contiguous last axis (needed for complex views)."""
    if a.dtype != dtype:
        return a.astype(dtype)
    if a.strides[-1] != a.itemsize:
        return np.ascontiguousarray(a)
    return a


def _mul_parts(a, b, c, d, o0, o1, t):
    """(o0, o1) = (a c - b conj(d), a d + b conj(c)): the product of p = a + b j
    and q = c + d j as pairs of complex numbers (a = w + x i, b = y + z i).

    Eight ufunc passes with `out` given positionally; `t` is scratch; the
    outputs must not overlap the inputs.
    """
    np.multiply(a, c, o0)
    np.conjugate(d, t)
    np.multiply(b, t, t)
    np.subtract(o0, t, o0)
    np.multiply(a, d, o1)
    np.conjugate(c, t)
    np.multiply(b, t, t)
    np.add(o1, t, o1)


def _mul_block(p, q, o):
    """o = p q (Hamilton) on one block of broadcasting float arrays."""
    ct = _COMPLEX[o.dtype]
    P, Q, O = p.view(ct), q.view(ct), o.view(ct)
    _mul_parts(P[..., 0], P[..., 1], Q[..., 0], Q[..., 1], O[..., 0], O[..., 1], np.empty(O.shape[:-1], ct))


def _mul_flat(p, q, o):
    """Chunked product of C-contiguous (N, 4) arrays of one shape.

    The complex views are made once; each block is a basic slice of them.
    """
    n = len(o)
    ct = _COMPLEX[o.dtype]
    P, Q, O = p.view(ct), q.view(ct), o.view(ct)
    t = np.empty(min(n, CHUNK), ct)
    for s in range(0, n, CHUNK):
        e = min(s + CHUNK, n)
        _mul_parts(P[s:e, 0], P[s:e, 1], Q[s:e, 0], Q[s:e, 1], O[s:e, 0], O[s:e, 1], t[: e - s])


def _mul_scalar(p, q, dtype):
    """Product of two single quaternions with Python floats (a few µs)."""
    w1, x1, y1, z1 = p.tolist()
    w2, x2, y2, z2 = q.tolist()
    return np.array([
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ], dtype)


def _out(out, shape, dtype, name="out"):
    if out is None:
        return np.empty(shape, dtype)
    if not isinstance(out, np.ndarray) or out.shape != tuple(shape):
        got = getattr(out, "shape", type(out).__name__)
        raise ValueError(f"expected {name} of shape {tuple(shape)}, got {got}")
    if out.dtype != dtype:
        raise TypeError(f"expected {name} of dtype {dtype}, got {out.dtype}")
    return out


def multiply(p, q, out=None):
    """Hamilton product ``p q`` of quaternion arrays, broadcasting batch shapes.

    Parameters
    ----------
    p, q : ndarray, shape (..., 4)
        Scalar-first quaternions (float32 or float64).
    out : ndarray, shape (broadcast batch, 4), optional

    Examples
    --------
    >>> i, j = np.array([0., 1, 0, 0]), np.array([0., 0, 1, 0])
    >>> multiply(i, j)
    array([0., 0., 0., 1.])
    """
    if (out is None and p.shape == q.shape and p.dtype == q.dtype and p.dtype in _COMPLEX
            and p.flags.c_contiguous and q.flags.c_contiguous):
        # fast path for the common case: same shape, same float dtype, C order
        if p.shape == (4,):
            return _mul_scalar(p, q, p.dtype)
        res = np.empty(p.shape, p.dtype)
        _mul_flat(p.reshape(-1, 4), q.reshape(-1, 4), res.reshape(-1, 4))
        return res
    dtype = result_dtype(p, q)
    batch = np.broadcast_shapes(p.shape[:-1], q.shape[:-1])
    shape = batch + (4,)
    res = _out(out, shape, dtype)
    overlap = np.may_share_memory(res, p) or np.may_share_memory(res, q)
    target = np.empty(shape, dtype) if overlap or not res.flags.c_contiguous else res
    p = _contig_last(p, dtype)
    q = _contig_last(q, dtype)
    if p.shape == q.shape == shape and p.flags.c_contiguous and q.flags.c_contiguous:
        _mul_flat(p.reshape(-1, 4), q.reshape(-1, 4), target.reshape(-1, 4))
    else:
        nb = len(batch)
        for idx in blocks(batch):
            _mul_block(_sub(p, idx, nb), _sub(q, idx, nb), target[idx])
    if target is not res:
        res[...] = target
    return res


_SIGNS = {}


def _conj_signs(dtype):
    """(1, -1, -1, -1) tiled over one block, per dtype (built once)."""
    dtype = np.dtype(dtype)
    if dtype not in _SIGNS:
        _SIGNS[dtype] = np.tile(np.array([1, -1, -1, -1], dtype), CHUNK)
    return _SIGNS[dtype]


def conjugate(q, out=None):
    """Quaternion conjugate (w, -x, -y, -z).

    A flat multiply by a tiled sign pattern, block by block: long inner loops
    instead of a length-3 one per quaternion.

    >>> conjugate(np.array([1., 2, 3, 4]))
    array([ 1., -2., -3., -4.])
    """
    dtype = result_dtype(q)
    res = _out(out, q.shape, dtype)
    if not (res.flags.c_contiguous and q.flags.c_contiguous and q.dtype == dtype):
        np.multiply(q, _conj_signs(dtype)[:4], out=res)
        return res
    src, dst = q.reshape(-1), res.reshape(-1)
    signs = _conj_signs(dtype)
    step = signs.size
    for start in range(0, src.size, step):
        stop = min(start + step, src.size)
        np.multiply(src[start:stop], signs[:stop - start], out=dst[start:stop])
    return res


def sqnorm(q):
    """Squared norm w² + x² + y² + z², batch shape.

    >>> sqnorm(np.array([1., 2, 2, 4]))
    np.float64(25.0)
    """
    return np.einsum("...i,...i->...", q, q)


def norm(q):
    """Norm |q|, batch shape; overflow-safe like `np.hypot`.

    >>> norm(np.array([[1., 2, 2, 4], [0, 0, 0, 0]]))
    array([5., 0.])
    """
    return np.linalg.norm(q, axis=-1)


def dot(p, q):
    """4-D inner product w_p w_q + x_p x_q + y_p y_q + z_p z_q, broadcasting.

    >>> dot(np.array([1., 2, 3, 4]), np.array([[1., 0, 0, 0], [0, 0, 0, 1]]))
    array([1., 4.])
    """
    dtype = result_dtype(p, q)
    return np.einsum("...i,...i->...", p, q, dtype=dtype)


def normalize(q, out=None):
    """q / |q|.  Zero quaternions raise `ValueError` (they have no direction).

    >>> normalize(np.array([0., 3, 0, 4]))
    array([0. , 0.6, 0. , 0.8])
    """
    res = _out(out, q.shape, result_dtype(q))
    if res.flags.c_contiguous and q.flags.c_contiguous and q.dtype == res.dtype and not np.may_share_memory(q, res):
        _normalize_flat(q.reshape(-1, 4), res.reshape(-1, 4))
        return res
    n = norm(q)
    if not np.all(n > 0):
        raise ValueError(_ZERO_NORMALIZE)
    np.divide(q, n[..., None], out=res)
    return res


_ZERO_NORMALIZE = "expected non-zero quaternions to normalize, got a zero (or nan) quaternion"


def _normalize_flat(q, out):
    """Blocked q / |q| on (N, 4) C-contiguous arrays: one einsum for the squared
    norms, then one division per component column (long inner loops)."""
    n = len(q)
    s = np.empty(min(n, CHUNK), q.dtype)
    for i in range(0, n, CHUNK):
        j = min(i + CHUNK, n)
        blk, o, t = q[i:j], out[i:j], s[: j - i]
        np.einsum("ij,ij->i", blk, blk, out=t)
        np.sqrt(t, t)
        if not (t > 0).all():
            raise ValueError(_ZERO_NORMALIZE)
        for c in range(4):
            np.divide(blk[:, c], t, o[:, c])


def inverse(q):
    """Multiplicative inverse conj(q) / |q|², for general quaternions.

    A zero quaternion has no inverse: `ZeroDivisionError`.

    >>> inverse(np.array([0., 2, 0, 0]))
    array([ 0. , -0.5, -0. , -0. ])
    """
    n2 = sqnorm(q)
    if not np.all(n2 > 0):
        raise ZeroDivisionError("quaternion inverse: expected non-zero quaternions, got a zero quaternion")
    res = conjugate(q)
    res /= n2[..., None]
    return res


def _vec_norm(q):
    v = q[..., 1:]
    return np.sqrt(np.einsum("...i,...i->...", v, v))


def exp(q):
    """Quaternion exponential e^w (cos|v|, sin|v| v/|v|).

    >>> np.allclose(exp(np.array([0., np.pi / 2, 0, 0])), [0, 1, 0, 0])
    True
    """
    q = np.asarray(q)
    vn = _vec_norm(q)
    ew = np.exp(q[..., 0])
    res = np.empty(q.shape, result_dtype(q))
    res[..., 0] = ew * np.cos(vn)
    # sin|v| / |v|, with its limit 1 at |v| = 0
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(vn > 0, np.sin(vn) / vn, 1.0).astype(res.dtype, copy=False)
    np.multiply(q[..., 1:], (ew * s)[..., None], out=res[..., 1:])
    return res


def _log_parts(q):
    """(ln|q|, angle θ = atan2(|v|, w), scale θ/|v|) for the principal log.

    The scale has its limit 1/w at |v| = 0, w > 0; for a negative real
    quaternion (|v| = 0, w < 0) the axis is taken as x (θ = π)."""
    vn = _vec_norm(q)
    w = q[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        ln = np.log(np.hypot(vn, w))
        theta = np.arctan2(vn, w)
        scale = np.where(vn > 0, theta / vn, np.where(w > 0, 1.0 / w, 0.0))
    return ln, theta, vn, scale.astype(q.dtype, copy=False)


def log(q):
    """Principal quaternion logarithm (ln|q|, θ v/|v|), θ = atan2(|v|, w) ∈ [0, π].

    A negative real quaternion -r gives (ln r, π, 0, 0); the zero quaternion
    gives (-inf, 0, 0, 0).

    >>> np.allclose(log(np.array([0., 0, 1, 0])), [0, 0, np.pi / 2, 0])
    True
    """
    q = np.asarray(q)
    ln, theta, vn, scale = _log_parts(q)
    res = np.empty(q.shape, result_dtype(q))
    res[..., 0] = ln
    np.multiply(q[..., 1:], scale[..., None], out=res[..., 1:])
    neg_real = (vn == 0) & (q[..., 0] < 0)
    if neg_real.any():
        res[..., 1][neg_real] = np.pi
    return res


def power(q, t):
    """Quaternion power exp(t log q) for real `t` (scalar or batch-shaped).

    ``0 ** t`` is 0 for t > 0, 1 for t = 0 and inf for t < 0.

    >>> k = np.array([0., 0, 0, 1])
    >>> np.allclose(power(k, 2), [-1, 0, 0, 0])
    True
    """
    q = np.asarray(q)
    t = np.asarray(t)
    dtype = result_dtype(q)
    if t.dtype.kind == "f" and t.dtype.itemsize > np.dtype(dtype).itemsize:
        t = t.astype(dtype)
    ln, theta, vn, scale = _log_parts(q)
    with np.errstate(invalid="ignore", over="ignore"):
        mag = np.exp(t * ln)
        zero = (vn == 0) & (q[..., 0] == 0)
        if zero.any():
            mag = np.where(zero, np.where(t > 0, 0.0, np.where(t == 0, 1.0, np.inf)), mag)
        ang = t * theta
        # sin(tθ) / |v|  (the axis is v/|v|); at |v| = 0 its limit is t·scale
        s = np.where(vn > 0, np.sin(ang) / np.where(vn > 0, vn, 1), t * scale)
        factor = mag * s
        if zero.any():  # inf * 0 for 0 ** t, t < 0: the vector part stays 0
            factor = np.where(zero, 0.0, factor)
    batch = np.broadcast_shapes(q.shape[:-1], np.shape(ang))
    res = np.empty(batch + (4,), dtype)
    res[..., 0] = mag * np.cos(ang)
    np.multiply(q[..., 1:], factor[..., None], out=res[..., 1:])
    neg_real = (vn == 0) & (q[..., 0] < 0)
    if neg_real.any():
        res[..., 1] = np.where(neg_real, mag * np.sin(ang), res[..., 1])
    return res


def rotate(q, v, inverse=False):
    """Rotate vectors `v` (..., 3) by q/|q|: the vector part of q v q⁻¹.

    Uses the expanded form u' = u + w t + vec × t with t = 2 vec × u / |q|²,
    which is the game-developer formula u + 2w(v×u) + 2 v×(v×u) for unit q.
    One quaternion and many vectors use its 3x3 matrix and one matrix product
    (the result is then F-ordered).  With `inverse`, rotate by conj(q).
    Zero quaternions give nan.

    >>> q = np.array([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])  # 90° about z
    >>> np.allclose(rotate(q, np.array([1., 0, 0])), [0, 1, 0])
    True
    >>> np.allclose(rotate(q, np.array([[1., 0, 0]]), inverse=True), [[0, -1, 0]])
    True
    """
    dtype = result_dtype(q, v)
    if q.shape == (4,) and v.shape == (3,):
        return _rotate_scalar(q, v, dtype, inverse)
    batch = np.broadcast_shapes(q.shape[:-1], v.shape[:-1])
    if q.size == 4 and v.size > 3:
        m = _matrix_one(q, dtype)
        res = np.matmul(m.T if inverse else m, v.astype(dtype, copy=False), axes=[(-2, -1), (-1, -2), (-1, -2)])
        return res.reshape(batch + (3,))
    res = np.empty(batch + (3,), dtype)
    nb = len(batch)
    with np.errstate(divide="ignore", invalid="ignore"):  # zero quaternions give nan
        for idx in blocks(batch):
            _rotate_block(_sub(q, idx, nb), _sub(v, idx, nb), res[idx], -1.0 if inverse else 1.0)
    return res


def _matrix_one(q, dtype):
    """The 3x3 rotation matrix of one quaternion q/|q| (nan for zero)."""
    w, x, y, z = q.reshape(4).tolist()
    n2 = w * w + x * x + y * y + z * z
    s = 2.0 / n2 if n2 else float("nan")
    return np.array([
        [1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)],
        [s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)],
        [s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)],
    ], dtype)


def _rotate_scalar(q, u, dtype, inverse=False):
    """`rotate` for one quaternion and one vector, with Python floats (a few µs)."""
    w, x, y, z = q.tolist()
    if inverse:
        w = -w  # conj(q) = (w, -vec): t -> -t, and vec × t keeps its sign
    ux, uy, uz = u.tolist()
    n2 = w * w + x * x + y * y + z * z
    s = 2.0 / n2 if n2 else float("nan")  # zero quaternions give nan, as the array path
    tx, ty, tz = (y * uz - z * uy) * s, (z * ux - x * uz) * s, (x * uy - y * ux) * s
    return np.array([ux + w * tx + (y * tz - z * ty), uy + w * ty + (z * tx - x * tz),
                     uz + w * tz + (x * ty - y * tx)], dtype)


def _rotate_block(q, u, o, wsign):
    w, x, y, z = q[..., 0] * wsign, q[..., 1], q[..., 2], q[..., 3]
    ux, uy, uz = u[..., 0], u[..., 1], u[..., 2]
    s = 2.0 / (w * w + x * x + y * y + z * z)
    tx = (y * uz - z * uy) * s
    ty = (z * ux - x * uz) * s
    tz = (x * uy - y * ux) * s
    o[..., 0] = ux + w * tx + (y * tz - z * ty)
    o[..., 1] = uy + w * ty + (z * tx - x * tz)
    o[..., 2] = uz + w * tz + (x * ty - y * tx)
