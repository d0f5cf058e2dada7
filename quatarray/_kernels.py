"""Quaternion algebra on raw ndarrays of shape (..., 4), scalar-first (w, x, y, z).

Every function broadcasts batch shapes the NumPy way, keeps float32 as
float32, never modifies its inputs and never imports the `QuatArray` class.
Long inputs are processed in cache-sized blocks by the block engine
(`_blocks`) into a preallocated output.
"""

import math
from math import prod

import numpy as np

from . import _blocks, _ops, _scale, _trig
from ._blocks import soa
from ._validate import all_finite

__all__ = [
    "result_dtype", "ANGLE_FLOOR", "cos_sin", "half_angle", "arctan2",
    "hamilton", "multiply", "multiply_rows", "conjugate", "sqnorm", "norm",
    "normalize", "inverse", "dot", "exp", "log", "power", "rotate", "rotate_nonzero",
]

_COMPLEX = {np.dtype(np.float32): np.complex64, np.dtype(np.float64): np.complex128}


def result_dtype(*arrays):
    """The float dtype of a result: float32 only if every quaternion input is float32.

    >>> import numpy as np
    >>> from quatarray._kernels import result_dtype
    >>> result_dtype(np.zeros(4, np.float32), np.zeros(4))
    dtype('float64')
    """
    dtype = getattr(arrays[0], "dtype", None)
    if dtype in _COMPLEX:   # float arrays of one dtype: theirs, without np.result_type's cost
        if len(arrays) == 1:
            return dtype
        if all(getattr(a, "dtype", None) == dtype for a in arrays[1:]):
            return dtype
    return np.result_type(*arrays, np.float32)


#: A positive floor for angles divided into their sines (exp, from_rotvec): sin(a) / a
#: then comes out exactly 1 at a = 0.
ANGLE_FLOOR = {np.dtype(np.float32): np.float32(1e-30), np.dtype(np.float64): 1e-300}


def cos_sin(angle, c=None, s=None, rows=None, bounds=None):
    """(cos a, sin a) of an array of angles, by the cheaper exact route for its dtype.

    float32: `np.cos` and `np.sin`, SIMD loops on every x86 NumPy build.
    float64: one tangent, ``t = tan(a / 2)``, ``cos a = (1 - t)(1 + t) / (1 + t²)``
    and ``sin a = 2 t / (1 + t²)``: one transcendental call instead of two,
    the cheaper on AVX2 and much the cheaper on AVX-512, where float64 sin
    and cos have no SIMD loop (costs in benchmarks/README.md).  The tangent
    is `_trig.tan`: NumPy's where it is a SIMD loop, a rational one elsewhere.
    ``(1 - t)(1 + t)`` rather than ``1 - t²``: near a = π/2 (t ≈ 1) the
    small cosine is accurate to about one ulp of t.

    Kernels pass output rows `c` and `s` and two scratch rows `rows` of the
    angle's shape (none may overlap `angle`): then nothing is allocated; and
    ``bounds = (lo, hi)`` of the angles where they know them (`_trig.tan`'s).

    >>> import numpy as np
    >>> from quatarray._kernels import cos_sin
    >>> [round(float(x), 12) for x in cos_sin(np.array(np.pi / 4))]
    [0.707106781187, 0.707106781187]
    """
    if type(angle) is float:   # one rotation's float64 angle: the same formula
        return _cos_sin_of_float(angle)
    if type(angle) is np.float32:   # one rotation's float32 angle: NumPy's, as on rows below
        return np.cos(angle), np.sin(angle)
    angle = np.asarray(angle)
    if angle.dtype == np.float32:
        return np.cos(angle, out=c), np.sin(angle, out=s)
    if c is None:
        c, s = np.empty_like(angle, dtype=np.float64), np.empty_like(angle, dtype=np.float64)
        rows = (np.empty_like(c), np.empty_like(c))
    return _cos_sin_tan(angle, _ops.ARRAYS, _trig.tan, c, s, rows, bounds and (bounds[0] * 0.5, bounds[1] * 0.5))


def _cos_sin_tan(angle, op, tan, c, s, rows, bounds=None, consts=None):
    """`cos_sin`'s float64 formula on rows (`_ops.ARRAYS`) with the tangent `tan` (`bounds`: of
    angle / 2, for `tan`; `consts`: 0.5, 1 and 2 as operands, else `op`'s); on a float,
    `cos_sin` takes it compiled (`_cos_sin_of_float`)."""
    u, v = rows[:2]
    half, one, two = consts or _COS_SIN[op is _ops.FLOATS]
    s = op.mul(angle, half, s)
    t = tan(s, out=s, rows=(c, u, v), bounds=bounds)
    return _cos_sin_of_tangent(t, op, half, one, two, c, u, v)


def _cos_sin_of_tangent(t, op, half, one, two, c, u, v):
    """(cos a, sin a) from t = tan(a / 2), `cos_sin`'s formula, in `op`'s arithmetic with the
    constants 0.5, 1 and 2 of its kind, into the rows `c`, `u`, `v` (t's row takes sin a)."""
    c = op.mul(t, t, c)
    c = op.add(c, one, c)
    d = op.div(two, c, c)                   # 2 / (1 + t²)
    u = op.sub(one, t, u)
    v = op.add(t, one, v)
    u = op.mul(u, v, u)
    u = op.mul(u, d, u)
    s = op.mul(t, d, t)                     # sin a = t · 2 / (1 + t²)
    return op.mul(u, half, c), s            # cos a (halving is exact)


_COS_SIN = _ops.operands(0.5, 1.0, 2.0)

_cos_sin_of_float = _ops.compiled(
    lambda op, stack, a: list(_cos_sin_tan(a, op, lambda x, out=None, rows=None, bounds=None: op.tan(x, None),
                                           None, None, _ops.NONE, consts=(0.5, 1.0, 2.0))), 1,
    calls={"tan": (1, _trig.tan_float, np.tan)})
"""`_cos_sin_tan` on one float64 angle, `_trig.tan_float` its tangent (`_ops.compiled`: the
same operations; its float32 form is not used, `cos_sin` takes NumPy's cos and sin there)."""


def half_angle(angle, scale):
    """(cos(a/2), sin(a/2)) of ``a = angle * 4 * scale`` (see `cos_sin`).

    >>> import numpy as np
    >>> from quatarray._kernels import half_angle
    >>> [round(float(x), 12) for x in half_angle(np.array(np.pi / 2), 0.25)]
    [0.707106781187, 0.707106781187]
    """
    return cos_sin(angle * (2 * scale))


def arctan2(y, x, out=None, x_nonneg=False, defined=False):
    """``np.arctan2(y, x)`` where that is a SIMD loop (AVX-512, `_trig.SIMD_TAN`: one call,
    no errstate); elsewhere from one ``arctan`` of the ratio: arctan(y / x), plus
    ±π (the sign of y) where x is negative or -0.0.

    The ratio is rounded once and arctan is well conditioned, so the angle
    is within about 2 ulp of ``np.arctan2``'s, signed zeros included, for a
    fraction of its cost on CPUs without AVX-512 (benchmarks/README.md).
    Differs from `np.arctan2` only where both are infinite (NaN here).
    `x_nonneg`: the caller knows x >= +0 (a norm, an absolute value), so no
    ±π fix is looked for.  `defined`: the caller knows no x, y pair is NaN or both
    zero (the angle of a unit quaternion), so no 0 / 0 ratio is looked for.  `out`
    must not be `x` or `y`.

    >>> import numpy as np
    >>> from quatarray._kernels import arctan2
    >>> y, x = np.array([1.0, 0.0, -0.0, -2.0]), np.array([-0.0, -1.0, -1.0, 0.5])
    >>> np.allclose(arctan2(y, x), np.arctan2(y, x), rtol=4e-16, atol=0)
    True

    On Python floats (one rotation's) it is the same ratio, NumPy's ``arctan`` on it
    (the array loop's bits) and the same ±π fix; x = ±0 and NaN take the array code:

    >>> bool(arctan2(1.0, -2.0) == arctan2(np.array([1.0]), np.array([-2.0]))[0])
    True

    Lists of floats give a new float64 array (one call for a few angles, e.g. one
    rotation's Euler angles, whose result it can be):

    >>> arctan2([1.0, -1.0], [-2.0, 3.0]).tolist() == [arctan2(1.0, -2.0), arctan2(-1.0, 3.0)]
    True
    """
    if type(y) is list:   # a few Python floats (one rotation's angles) in one call
        if _trig.SIMD_TAN:   # one binary ufunc call costs four unary ones on floats
            return np.arctan2(y, x)   # (the lists as float64 arrays, or float32: the arrays' loop and bits)
        if type(y[0]) is not float:   # float32 scalars: as arrays, in the array code below
            return arctan2(np.array(y), np.array(x))
        if len(y) == 3:   # (one rotation's three angles: one call)
            b0, b1, b2 = x
            if (b0 > 0 or b0 < 0) and (b1 > 0 or b1 < 0) and (b2 > 0 or b2 < 0):
                return np.array(_RATIO_ROUTE3[b0 < 0, b1 < 0, b2 < 0](*y, b0, b1, b2))
        angles = []
        for a, b in zip(y, x):   # `_ratio_route` compiled, one float at a time
            if b > 0 or b < 0:
                angles.append(_ratio_route_floats(a, b, b < 0))
            else:   # x = ±0 (or NaN): the array code
                angles.append(float(arctan2(np.array(a), np.array(b), out=np.empty(()), x_nonneg=x_nonneg)))
        return np.array(angles)
    if _trig.SIMD_TAN:   # on Python floats too: NumPy's loop, the arrays' bits
        return float(np.arctan2(y, x)) if type(y) is float else np.arctan2(y, x, out=out)
    if type(y) is float:   # the ratio route on one float: NumPy's arctan (the arrays' bits), the ±π fix
        return arctan2([y], [x], x_nonneg=x_nonneg).item(0)
    neg = None if x_nonneg else np.signbit(x)
    few = neg is not None and neg.size <= _MASKED_MAX
    if not (few or neg is None or neg.any()):
        neg = None   # long rows without a negative x: no turn (a reduction, not the fix's three passes)
    dtype = out.dtype if out is not None else y.dtype if y.dtype == x.dtype else np.result_type(y, x)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        out = _ratio_route(y, x, neg, _ops.const(np.pi, dtype), _ops.ARRAYS, out, None, masked=few)
    # a reduction, no mask, when no ratio is 0 / 0
    if not defined and out.size and np.isnan(np.minimum.reduce(out, axis=None)):
        # 0 / 0: y (±0), and its turn where x = -0.0, gives np.arctan2's signed zeros and ±π
        fix = np.isnan(out) & (x == 0)
        np.copyto(out, y, where=fix)
        if neg is not None:
            np.add(out, np.copysign(np.pi, y, dtype=dtype), out=out, where=fix & neg)
    return out


_MASKED_MAX = 96
"""Up to this many angles `arctan2`'s turn is one masked add, without first testing for a
negative x (at a few elements the test costs as much as the turn); beyond, where some x is
negative, the turn times 0 or 1 (a masked add costs more than arctan on long rows)."""


def _ratio_route(y, x, neg, pi, op, out, turn, masked=False):
    """``arctan(y / x) + copysign(π, y)`` where x is negative or -0.0 (`neg`), `arctan2`'s
    ratio route, written once, in `op`'s arithmetic (`_ops`; into the rows `out` and `turn`;
    `pi` π as its operand).  `neg`: rows of bools, the turn added where True (`masked`: by
    one masked add; else as the turn times `neg`: ±0 with y's sign elsewhere, which adds
    nothing, signed zeros kept); True or False for a formula compiled for a known sign;
    None when x >= +0 (no turn)."""
    a = op.div(y, x, out)
    a = op.arctan(a, a)
    if neg is None or neg is False:
        return a
    turn = op.copysign(pi, y, turn)
    if neg is True:
        return op.add(a, turn, a)
    if masked:
        return op.add_where(a, turn, neg, a)
    turn = op.mul(turn, neg, turn)
    return op.add(a, turn, a)


_ratio_route_floats = _ops.compiled(lambda op, stack, y, x, neg: _ratio_route(y, x, neg, math.pi, op, None, None), 3)
"""`_ratio_route` on one pair of Python floats and whether x < 0 (`_ops.compiled`)."""


class _RatioRoute3(dict):
    """`_ratio_route` on three pairs of floats ``(y0, y1, y2, x0, x1, x2)``, compiled for
    the signs ``(x0 < 0, x1 < 0, x2 < 0)`` (the key) when first asked for."""

    def __missing__(self, negs):
        f = self[negs] = _ops.compiled(lambda op, stack, *a: [
            _ratio_route(a[i], a[3 + i], negs[i], math.pi, op, None, None) for i in range(3)], 6)
        return f


_RATIO_ROUTE3 = _RatioRoute3()


def _contig_last(a, dtype):
    """`a` as `dtype` with a contiguous last axis (needed for complex views) and no negative
    strides (NumPy's complex64 multiply rounds differently on reversed views)."""
    if a.dtype != dtype:
        return a.astype(dtype)
    if a.strides[-1] != a.itemsize or any(s < 0 for s in a.strides):
        return np.ascontiguousarray(a)
    return a


def hamilton(a, b, c, d, o0, o1, t, u):
    """The Hamilton product p q, written once for every path.

    p = a + b j and q = c + d j as pairs of complex numbers (a = w + x i,
    b = y + z i): p q = (a c - b conj(d)) + (a d + b conj(c)) j.  Eight ufunc
    passes into the outputs `o0`, `o1` with scratch `t`, `u`; none of the four
    may overlap the inputs or each other.  Complex arrays only, and no
    multiply writes over its own input: NumPy's complex array multiply gives
    the same bits for every length, stride and broadcast, except a length-1
    multiply in place, scalar (or Python complex) multiplies and complex64
    views with negative strides, which round differently.

    >>> import numpy as np
    >>> from quatarray._kernels import hamilton
    >>> a, b, c, d = (np.array([x]) for x in (1j, 0j, 0j, 1 + 0j))
    >>> o0, o1, t, u = np.empty((4, 1), complex)
    >>> hamilton(a, b, c, d, o0, o1, t, u)   # i j = k: (0 + 0i) + (0 + 1i) j
    (array([0.+0.j]), array([0.+1.j]))
    """
    np.multiply(a, c, o0)
    np.multiply(b, np.conjugate(d, t), u)
    np.subtract(o0, u, o0)
    np.multiply(a, d, o1)
    np.multiply(b, np.conjugate(c, t), u)
    np.add(o1, u, o1)
    return o0, o1


#: Up to this many quaternions, a product runs `_hamilton_stacked` (fewer calls, longer
#: copies); beyond, `hamilton`'s eight passes over the operands in place.
_STACK_MAX = 1024


def _hamilton_stacked(P, Q, O):
    """`hamilton` on complex views (n, 2) of a few quaternions, its operands stacked:
    ``[a, a, b, b] · [c, d, conj d, conj c]`` in one multiply, then the same difference
    and sum.  Element by element these are `hamilton`'s operations (the same bits), in
    six ufunc calls instead of eight and no scratch; on long blocks the stacked copies
    cost more than the calls they save."""
    n = len(O)
    if n == 1 and O.dtype == np.complex128:   # one float64 quaternion: the operands from its
        (a, b), (c, d) = P[0].tolist(), Q[0].tolist()   # Python complex numbers (exact)
        m = (np.array([a, a, b, b]) * np.array([c, d, d.conjugate(), c.conjugate()])).tolist()
        O[0] = _stacked_sum(m, _ops.FLOATS, None, None)   # Python's complex - and + round as NumPy's
        return
    L, R = np.empty((2, 4, n), O.dtype)
    L.reshape(2, 2, n)[...] = P.T[:, None, :]   # a, a, b, b
    R[:2] = Q.T                                 # c, d
    np.conjugate(Q.T[::-1], R[2:])              # conj d, conj c
    np.multiply(L, R, L)   # at least 4 elements: never the length-1 in-place multiply
    _stacked_sum(L, _ops.ARRAYS, O[:, 0], O[:, 1])


def _stacked_sum(m, op, o0, o1):
    """``p q = (a c - b conj(d)) + (a d + b conj(c)) j`` from `_hamilton_stacked`'s products
    ``m = [a c, a d, b conj(d), b conj(c)]`` (rows, or Python complex numbers), written
    once, in `op`'s arithmetic (`_ops`), into `o0`, `o1`."""
    return op.sub(m[0], m[2], o0), op.add(m[1], m[3], o1)


def _mul_views(P, Q, O):
    """O = P Q on complex views (..., 2) of one block."""
    t, u = _blocks.scratch().rows(2, O.shape[:-1], O.dtype)
    hamilton(P[..., 0], P[..., 1], Q[..., 0], Q[..., 1], O[..., 0], O[..., 1], t, u)


def _out(out, shape, dtype, name="out"):
    if out is None:
        return np.empty(shape, dtype)
    if not isinstance(out, np.ndarray) or out.shape != tuple(shape):
        got = getattr(out, "shape", type(out).__name__)
        raise ValueError(f"expected {name} of shape {tuple(shape)}, got {got}")
    if out.dtype != dtype:
        raise TypeError(f"expected {name} of dtype {dtype}, got {out.dtype}")
    return out


@np.errstate(divide="ignore", invalid="ignore", over="ignore")
def _blockwise_quiet(kernel, *args, **kwargs):
    """`_blocks.blockwise` under ``np.errstate(divide="ignore", invalid="ignore", over="ignore")``
    (kernels that repair what those give), set as a decorator: per call a third less than the
    ``with`` statement, which makes an errstate object each time."""
    return _blocks.blockwise(kernel, *args, **kwargs)


@np.errstate(over="ignore")
def _blockwise_over(kernel, *args, **kwargs):
    """`_blocks.blockwise` under ``np.errstate(over="ignore")`` (kernels that rescale squares
    that overflow), as `_blockwise_quiet`."""
    return _blocks.blockwise(kernel, *args, **kwargs)


def multiply(p, q, out=None, check=False):
    """Hamilton product ``p q`` of quaternion arrays, broadcasting batch shapes.

    Parameters
    ----------
    p, q : ndarray, shape (..., 4)
        Scalar-first quaternions (float32 or float64).
    out : ndarray, shape (broadcast batch, 4), optional
    check : bool, default False
        Also return False when p or q holds a nan or ±inf, judged on the
        product's w components block by block while the block is in cache (no
        second pass over the result): each component of p and q enters
        ``w = pw qw - px qx - py qy - pz qz`` through one product, so a nan or
        ±inf anywhere makes w nan or infinite.  (A finite input may still
        overflow in some component; callers then check the inputs, as for any
        False.)

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._kernels import multiply
    >>> i, j = np.array([0., 1, 0, 0]), np.array([0., 0, 1, 0])
    >>> multiply(i, j)
    array([0., 0., 0., 1.])
    """
    if (out is None and p.shape == q.shape and p.dtype == q.dtype and p.dtype in _COMPLEX
            and p.flags.c_contiguous and q.flags.c_contiguous):
        # fast path for the common case: same shape, same float dtype, C order
        res = np.empty(p.shape, p.dtype)
        if p.ndim == 2:
            ok = _mul_flat(p, q, res, check)
        else:
            ok = _mul_flat(p.reshape(-1, 4), q.reshape(-1, 4), res.reshape(-1, 4), check)
        return (res, ok) if check else res
    dtype = result_dtype(p, q)
    batch = np.broadcast_shapes(p.shape[:-1], q.shape[:-1])
    shape = batch + (4,)
    res = _out(out, shape, dtype)
    overlap = np.may_share_memory(res, p) or np.may_share_memory(res, q)
    target = np.empty(shape, dtype) if overlap or not res.flags.c_contiguous else res
    p = _contig_last(p, dtype)
    q = _contig_last(q, dtype)
    if not batch:   # one quaternion: the flat kernel on a batch of one
        p, q = np.ascontiguousarray(p.reshape(1, 4)), np.ascontiguousarray(q.reshape(1, 4))
    if p.size == q.size == target.size and p.flags.c_contiguous and q.flags.c_contiguous:
        _mul_flat(p.reshape(-1, 4), q.reshape(-1, 4), target.reshape(-1, 4))
    elif batch:
        ct = _COMPLEX[dtype]
        P, Q, O = p.view(ct), q.view(ct), target.view(ct)
        nb = len(batch)

        def block(idx):
            _mul_views(_blocks.part(P, idx, nb), _blocks.part(Q, idx, nb), O[idx])

        _blocks.run(block, _blocks.split(batch, _blocks.block_size(dtype)), prod(batch))
    if target is not res:
        res[...] = target
    return _checked(res, check)


def _checked(res, check):
    """`res`, or ``(res, all finite)`` with `check` (for results made in one piece)."""
    return (res, all_finite(res)) if check else res


def _mul_flat(p, q, o, check=True):
    """Blocked product of C-contiguous (N, 4) arrays of one shape (complex views made once).
    Returns whether every w of the product is finite (with `check`, see `multiply`; else True)."""
    ct = _COMPLEX[o.dtype]
    P, Q, O = p.view(ct), q.view(ct), o.view(ct)
    if len(o) <= _STACK_MAX:   # a few: no splitting, no pool, no scratch
        _hamilton_stacked(P, Q, O)
        return not check or all_finite(o[:, 0])

    def block(idx):
        _mul_views(P[idx], Q[idx], O[idx])
        return not check or all_finite(o[idx][:, 0])   # the block is still in cache; its w's (see `multiply`)

    return all(_blocks.run(block, _blocks.split((len(o),), _blocks.block_size(o.dtype)), len(o)))


def multiply_rows(p, q):
    """Hamilton product of quaternions given as component rows [w, x, y, z].

    The rows broadcast against each other; returns the product's rows.

    >>> from quatarray._kernels import multiply_rows
    >>> [float(c) for c in multiply_rows([0., 1, 0, 0], [0., 0, 1, 0])]
    [0.0, 0.0, 0.0, 1.0]
    """
    dtype = result_dtype(*p, *q)
    P = np.stack(np.broadcast_arrays(*p), axis=-1).astype(dtype, copy=False)
    Q = np.stack(np.broadcast_arrays(*q), axis=-1).astype(dtype, copy=False)
    return list(_blocks.soa(multiply(P, Q)))


_SIGNS = {}


def _conj_signs(dtype, n=None):
    """(1, -1, -1, -1) tiled over `n` quaternions (default one block), per dtype (built once)."""
    n = _blocks.block_size(dtype) if n is None else n
    key = (dtype, n)
    signs = _SIGNS.get(key)
    if signs is None:
        signs = _SIGNS[key] = np.tile(np.array([1, -1, -1, -1], dtype), n)
    return signs


def conjugate(q, out=None, check=False):
    """Quaternion conjugate (w, -x, -y, -z).

    A flat multiply by a tiled sign pattern, block by block: long inner loops
    instead of a length-3 one per quaternion.  With `check`, also returns
    whether every element is finite, judged per block while it is in cache.

    >>> import numpy as np
    >>> from quatarray._kernels import conjugate
    >>> conjugate(np.array([1., 2, 3, 4]))
    array([ 1., -2., -3., -4.])
    """
    if out is None and not check and q.size <= 256 and type(q) is np.ndarray and q.dtype in _COMPLEX:
        return np.multiply(q, _conj_signs(q.dtype, 1))   # a few float32/64 quaternions
    dtype = result_dtype(q)
    res = _out(out, q.shape, dtype)
    if q.size <= 256 or not (res.flags.c_contiguous and q.flags.c_contiguous and q.dtype == dtype):
        np.multiply(q, _conj_signs(dtype, 1), out=res)
        return _checked(res, check)
    src, dst = q.reshape(-1), res.reshape(-1)
    signs = _conj_signs(dtype)

    def block(idx):
        sl = idx[0] if idx else slice(None)
        o = dst[sl]
        np.multiply(src[sl], signs[:o.size], out=o)
        return not check or all_finite(o)

    ok = all(_blocks.run(block, _blocks.split((src.size,), signs.size), src.size // 4))
    return (res, ok) if check else res


def sqnorm(q):
    """Squared norm w² + x² + y² + z², batch shape.

    >>> import numpy as np
    >>> from quatarray._kernels import sqnorm
    >>> sqnorm(np.array([1., 2, 2, 4]))
    np.float64(25.0)
    """
    return _summed_last(np.multiply(q, q))


def _k_norm(q, o):
    n = _scale.sum_squares(q, o[0])
    # (read only: a block to rescale is rescaled as a copy)
    e = None if _scale.fits(n) else _scale.guard(q.copy(), n)
    np.sqrt(n, out=n)
    _scale.unscale(n, e)


def norm(q):
    """Norm |q|, batch shape; neither overflows nor underflows before the result does.

    >>> import numpy as np
    >>> from quatarray._kernels import norm
    >>> norm(np.array([[1., 2, 2, 4], [0, 0, 0, 0], [1e300, 0, 0, 0]]))
    array([5.e+000, 0.e+000, 1.e+300])
    """
    q = np.asarray(q)
    one = _sqnorm_of_one(q)
    if one is not None:   # one float64 or float32 quaternion: `_k_norm` on its floats
        n = one[1].sqrt(one[2])
        return np.array(n if q.ndim == 1 else [n])
    dtype = result_dtype(q)
    out = np.empty(q.shape[:-1] + (1,), dtype)
    _blockwise_over(_k_norm, [q], [out], dtype=dtype, read_only=True)   # (squares that overflow are rescaled)
    return out[..., 0]


def dot(p, q):
    """4-D inner product w_p w_q + x_p x_q + y_p y_q + z_p z_q, broadcasting.

    >>> import numpy as np
    >>> from quatarray._kernels import dot
    >>> dot(np.array([1., 2, 3, 4]), np.array([[1., 0, 0, 0], [0, 0, 0, 1]]))
    array([1., 4.])
    """
    return _summed_last(np.multiply(p, q, dtype=result_dtype(p, q)))


def _summed_last(terms):
    """The sums of `terms` (..., 4) over the last axis in component order, `_scale.squares`'
    (einsum's order follows the memory layout: a Fortran-ordered batch got other bits)."""
    out = _scale._summed(np.moveaxis(terms, -1, 0), np.empty(terms.shape[:-1], terms.dtype))
    return out[()] if out.ndim == 0 else out


_ZERO_NORMALIZE = "expected non-zero quaternions to normalize, got a zero quaternion"


def normalize_block(q, o, zero=_ZERO_NORMALIZE, in_range=False):
    """``o = q / |q|`` for a components-first block `q` (a scratch copy: rescaled in place
    where its squares would over- or underflow); a zero quaternion raises ValueError(`zero`).
    `in_range`: the caller knows every |q|² is in `_scale`'s range (blends of unit keys at
    bounded weights): no range test."""
    if in_range:
        n = _scale.sum_squares(q, np.empty(q.shape[1:], q.dtype))
    else:
        n = _scale.guarded_sqnorm(q, zero=zero)   # (in range, hence > 0, unless it raises)
    np.sqrt(n, out=n)
    np.divide(q, n, out=o)


def normalize(q, out=None):
    """q / |q|.  Zero quaternions raise `ValueError` (they have no direction).

    >>> import numpy as np
    >>> from quatarray._kernels import normalize
    >>> normalize(np.array([0., 3, 0, 4]))
    array([0. , 0.6, 0. , 0.8])
    """
    one, kind = _ops.floats64(q), _ops.F64
    if one is None:
        one, kind = _ops.floats32(q)
    if one is not None:   # one float64 or float32 quaternion: the same formula on its floats
        one = _NORMALIZE_FLOATS[kind](one)
        if one is not None:
            if out is None:
                return np.array(one).reshape(q.shape)
            res = _out(out, q.shape, kind.dtype)
            res[...] = one
            return res
    res = _out(out, q.shape, result_dtype(q))
    if (res.flags.c_contiguous and q.flags.c_contiguous and q.dtype == res.dtype
            and (res is q or not np.may_share_memory(q, res))):   # in place is safe: row by row
        with np.errstate(over="ignore"):   # squares that overflow are rescaled
            _normalize_flat(q.reshape(-1, 4), res.reshape(-1, 4))
        return res
    target = np.empty(q.shape, res.dtype)
    _blockwise_over(normalize_block, [q], [target], dtype=res.dtype)
    res[...] = target
    return res


def _divided(comps, n, op, outs):
    """Each component over the norm `n`, in `op`'s arithmetic (`_ops`), into `outs`."""
    return [op.div(c, n, o) for c, o in zip(comps, outs)]


def normalize_floats(comps, kind=_ops.F64):
    """`_normalize_flat`'s q / |q| on the four floats of one quaternion (of `kind`, an
    `_ops.Kind`), or None where its squared norm does not `_scale.fits` (the block kernel's
    case)."""
    return _NORMALIZE_FLOATS[kind](comps)


def _sqnorm_floats_of(kind):
    """`_SQNORM_FLOATS`' function for `kind`."""
    op, squares = kind.op, _scale.squares
    low, high = _scale.BOUNDS[kind]

    def sqnorm_floats(comps):
        n2 = squares(comps, op, None, None)
        return n2 if low <= n2 <= high else None
    return sqnorm_floats


_SQNORM_FLOATS = _ops.by_kind(_sqnorm_floats_of)
"""|q|² of one quaternion's four floats, by `_ops.Kind`, in `_scale.sum_squares`' order, or
None where it does not `_scale.fits` (the block kernels rescale there, or find nan or inf)."""


def _sqnorm_of_one(q):
    """(components, kind, |q|²) of one float64 or float32 quaternion `q` ((4,) or (1, 4)), its
    floats' `_SQNORM_FLOATS`, or None for any other input and where the block kernels would
    rescale or find nan or inf (norm's and inverse's float paths)."""
    one, kind = _ops.floats64(q), _ops.F64
    if one is None:
        one, kind = _ops.floats32(q)
        if one is None:
            return None
    n2 = _SQNORM_FLOATS[kind](one)
    return None if n2 is None else (one, kind, n2)


def _normalize_floats_of(kind):
    """`normalize_floats` for `kind`."""
    sqnorm, sqrt, op = _SQNORM_FLOATS[kind], kind.sqrt, kind.op

    def normalize_floats(comps):
        n2 = sqnorm(comps)
        return None if n2 is None else _divided(comps, sqrt(n2), op, _ops.NONE)
    return normalize_floats


_NORMALIZE_FLOATS = _ops.by_kind(_normalize_floats_of)


def _normalize_flat(q, out):
    """Blocked q / |q| on (N, 4) C-contiguous arrays: the squared norms from one flat
    pass of squares and three strided adds, then the divisions by the norms."""
    def block(idx):
        blk, o = q[idx], out[idx]
        if small:   # one small block: fresh rows cost less than the scratch's bookkeeping
            t, sq = np.empty(len(o), q.dtype), np.empty((len(o), 4), q.dtype)
        else:
            work = _blocks.scratch()
            t = work.rows(1, (len(o),), q.dtype)[0]
            sq = work.rows(len(o), (4,), q.dtype)
        np.multiply(blk, blk, out=sq)        # one flat pass, then three strided adds (half the cost of
        _scale._summed(sq.T, t)              # einsum's length-4 reductions), in `_scale.squares`' order
        if not _scale.fits(t):   # extreme magnitudes, zeros or nan: the general kernel
            normalize_block(soa(blk).copy(), soa(o))
            return
        np.sqrt(t, t)
        if len(o) <= _blocks.FEW:   # a few: every component in one call (inner loops of 4)
            _divided([blk], t[:, None], _ops.ARRAYS, [o])
        else:                       # long blocks: one call per component column (long inner loops)
            _divided([blk[:, c] for c in range(4)], t, _ops.ARRAYS, [o[:, c] for c in range(4)])

    size = _blocks.block_size(q.dtype)
    small = len(q) <= size
    if small:
        block(())
    else:
        _blocks.run(block, _blocks.split((len(q),), size), len(q))


def _k_inverse(q, o):
    n2 = _scale.sum_squares(q, _blocks.scratch().rows(1, q.shape[1:], q.dtype)[0])
    e = _scale.guard(q, n2)
    if not (n2 > 0).all():
        raise ZeroDivisionError("quaternion inverse: expected non-zero quaternions, got a zero quaternion")
    _inverse_formula(q, n2, _ops.ARRAYS, _ops.STACKS, o, _ops.const(0.0, n2.dtype))
    if e is not None:   # q was scaled by 2**-e: its inverse by 2**e
        np.negative(e, out=e)
        _scale.unscale(o, e)


def _inverse_formula(q, n2, op, stack, o, zero):
    """conj(q) / |q|² from the positive squared norm `n2`, in `op`'s arithmetic (`stack` its
    stacked form: the vector's three divisions are one call): w / n2, then x, y, z over
    ``0 - n2`` (-n2 exactly), into the four rows `o` (n2's row takes -n2); returned as w and
    the vector."""
    w = op.div(q[0], n2, o[0])
    m = op.sub(zero, n2, n2)
    return w, stack.div(q[1:], m, o[1:])


_inverse_floats = _ops.compiled(lambda op, stack, w, x, y, z, n2: (lambda w, v: [w, *v])(*_inverse_formula(
    [w, x, y, z], n2, op, stack, _ops.NONE, 0.0)), 5)
"""`_inverse_formula` on one quaternion's floats and |q|² (`_ops.compiled`)."""


def inverse(q):
    """Multiplicative inverse conj(q) / |q|², for general quaternions.

    A zero quaternion has no inverse: `ZeroDivisionError`.

    >>> import numpy as np
    >>> from quatarray._kernels import inverse
    >>> inverse(np.array([0., 2, 0, 0]))
    array([ 0. , -0.5, -0. , -0. ])
    """
    one = _sqnorm_of_one(q)
    if one is not None:   # one float64 or float32 quaternion: `_k_inverse` on its floats
        comps, kind, n2 = one
        return _ops.to_array(_inverse_floats.kinds[kind](*comps, n2), q.shape, kind.dtype)
    res = np.empty(q.shape, result_dtype(q))
    _blockwise_over(_k_inverse, [q], [res], dtype=res.dtype)   # (squares that overflow are rescaled)
    return res


def _k_exp(q, o, check=False):
    vn, ew, c, s, u, v = _blocks.scratch().rows(6, q.shape[1:], q.dtype)   # (given back by blockwise)
    tame = None   # whether every w is finite and e**w cannot overflow (None: not looked at)
    if check:     # (before e**w, which could warn of an overflow elsewhere in the block)
        tame = _scale.inside(q[0], _EXP_MAX_OF[q.dtype], -_FLOAT_MAX[q.dtype])   # False for nan
        if not tame:
            _refuse_nonfinite(q)
    np.exp(q[0], out=ew)   # outside the errstate below: e**w that overflows warns (alone)
    _k_exp_quiet(q, o, vn, ew, c, s, u, v, check, tame)


def _refuse_nonfinite(q):
    """`_scale.NONFINITE`'s `ValueError` where `q` holds nan or inf (the exact test)."""
    if not np.isfinite(q).all():
        raise ValueError(_scale.NONFINITE)


# one errstate for the rest (squares that overflow are rescaled; where e**w overflowed,
# inf · 0 and inf - inf are repaired below), not one per step: each costs a few ufunc calls;
# set as a decorator, a third cheaper than a ``with`` statement
@np.errstate(over="ignore", invalid="ignore", divide="ignore")
def _k_exp_quiet(q, o, vn, ew, c, s, u, v, check, tame):
    """`_k_exp` after e**w (in `ew`), on its rows."""
    e = _scale.true_norm(q[1:], vn)   # |v|; q[1:] scaled by 2**-e where |v|² overflows
    if check and e is not None:       # |v|² beyond the range, or nan (a rescale keeps nan and inf)
        _refuse_nonfinite(q)
    over = not tame and ew.size and _scale.largest(ew) == np.inf   # e**w overflowed somewhere
    if over:
        big = ew == np.inf
    kept = []   # sin|v| / |v| where e**w overflowed, before e**w multiplies it

    def scale(s):
        if over:
            kept.append(s[big])
        s *= ew
        if e is not None:
            np.ldexp(s, e, out=s)
        return s

    _exp_formula(q[1:], vn, _ops.row(ANGLE_FLOOR[vn.dtype], vn.dtype, vn.shape), ew, cos_sin, scale,
                 _ops.ARRAYS, _ops.STACKS, c, s, (u, v), o)
    if over:   # each component there as (x e^(w/2)) e^(w/2): finite where it is (e^710 sin(π))
        sb = kept[0]
        half = np.exp(q[0][big] * 0.5)
        if e is not None:
            sb = np.ldexp(sb, e[big])
        o[0][big] = c[big] * half * half
        for k in (1, 2, 3):   # (zero components stay ±0, not 0 · inf)
            qk = q[k][big] * sb
            o[k][big] = np.where(qk == 0, qk, qk * half * half)


def _exp_formula(v, vn, floor, ew, cos_sin, scale, op, stack, c, s, rows, o):
    """The exponential's formula, written once: ``o = e^w (cos|v|, sin|v| v/|v|)`` from the
    vector part `v` (three rows or floats), |v| in `vn` (overwritten), its positive `floor`,
    e^w in `ew`, in `op`'s arithmetic (`_ops`), with ``cos_sin(vn, c, s, rows)`` (`cos_sin`
    or its float form) and ``scale(s)`` multiplying sin|v| / |v| by e^w (the block kernel
    also keeps, and undoes a rescale of, some rows there); the vector part in `stack`'s
    arithmetic (`_ops.STACKS` on a block's rows: one call).  Returns the real part and the
    vector part (a row and three rows of `o`, or a float and a list of three)."""
    vn = op.max(vn, floor, vn)   # cos|v| and sin|v| / |v| (limit 1 at |v| = 0)
    c, s = cos_sin(vn, c, s, rows)
    s = op.div(s, vn, s)
    s = scale(s)
    return op.mul(c, ew, o[0]), stack.scale(v, s, o[1:])


def _exp_floats_of(kind):
    """`_EXP_FLOATS`' function for `kind`."""
    op, sqrt, squares = kind.op, kind.sqrt, _scale.squares
    high, top, floor = _scale.BOUNDS[kind][1], _EXP_MAX[kind], ANGLE_FLOOR[kind.dtype]
    python = kind is _ops.F64

    def exp_floats(comps):
        w, x, y, z = comps
        vv = squares([x, y, z], op, None, None)   # `sum_squares`' order
        if not vv <= high:
            return None
        if not -math.inf < w < top:   # e**w near or past the float maximum (its warning: the block
            return None                # kernel's), or w = -inf (which the block kernel may refuse)
        ew = np.exp(w)   # NumPy's exp: the array loop's bits
        if python:
            ew = float(ew)
        w, vec = _exp_formula([x, y, z], sqrt(vv), floor, ew, _cos_sin_floats, lambda s: s * ew, op,
                              _ops.FLOAT_STACKS, None, None, None, _ops.NONE)
        return [w, *vec]
    return exp_floats


_EXP_MAX = {_ops.F64: 709.0, _ops.F32: 88.0}
"""Arguments below which e**x and the products with it stay finite, by `_ops.Kind`."""

_EXP_MAX_OF = {kind.dtype: top for kind, top in _EXP_MAX.items()}
"""`_EXP_MAX` by dtype."""

_FLOAT_MAX = {d: float(np.finfo(d).max) for d in _COMPLEX}

_EXP_FLOATS = _ops.by_kind(_exp_floats_of)
"""`_k_exp` on the four floats of one quaternion, by `_ops.Kind`, or None where the block
kernel has more to do (|v|² beyond `_scale.HIGH`, e^w near overflow, non-finite input)."""


def _cos_sin_floats(angle, c, s, rows):
    """`cos_sin` of one angle (a Python float, or a float32 scalar), in the signature of the
    kernels'."""
    return cos_sin(angle)


def exp(q, check=False):
    """Quaternion exponential e^w (cos|v|, sin|v| v/|v|).

    With `check`, nan and inf in `q` raise `ValueError` (`_scale.NONFINITE`, before any
    warning of the computation), found by a range test of w the kernel makes anyway and
    its test of |v|² (without, they give nan, inf or 0).

    >>> import numpy as np
    >>> from quatarray._kernels import exp
    >>> np.allclose(exp(np.array([0., np.pi / 2, 0, 0])), [0, 1, 0, 0])
    True
    """
    q = np.asarray(q)
    one, kind = _ops.floats64(q), _ops.F64
    if one is None:
        one, kind = _ops.floats32(q)
    if one is not None:   # one float64 or float32 quaternion: the same formula on its floats
        one = _EXP_FLOATS[kind](one)
        if one is not None:
            return _ops.to_array(one, q.shape, kind.dtype)
    res = np.empty(q.shape, result_dtype(q))
    _blocks.blockwise(_k_exp, [q], [res], dtype=res.dtype, check=check)   # (the kernel sets its own errstate)
    return res


def _log_parts(q):
    """(ln|q|, angle θ = atan2(|v|, w), |v|, scale θ/|v|, e) for the principal log of
    components-first rows.

    ln|q| is ``log1p(d) / 2`` with d = (w - 1)(w + 1) + |v|², accurate near the
    identity where ``log(|q|)`` keeps only the rounding error of |q| ≈ 1;
    log1p(d) is taken as Kahan's ``log(u) · d / (u - 1)`` (d where u = 1), one
    call to log, with u = w² + |v|² = |q|² itself rather than 1 + d: then u - 1
    is exact near 1, the ratio log(u) / (u - 1) changes by half an ulp of u
    between u and 1 + d, and a small |q|² is not lost to 1 + d's rounding, so
    one formula serves every magnitude.  The scale has its limit 1/w at |v| = 0, w > 0;
    for a negative real quaternion (|v| = 0, w < 0) the axis is taken as x
    (θ = π).  Blocks of extreme magnitude are rescaled in place first by
    2**-e (e None when not): ln|q|, |v| and the scale then refer to the
    rescaled q, which is what the callers multiply.  The sixth item is None, or,
    for a block with vectors that are zero or below the range, the mask of the rows
    whose scale is a limit (`_small_vectors`); the seventh |q|² (of q as rescaled)."""
    n2, vv, d, u, ln, theta, scale = _blocks.scratch().rows(7, q.shape[1:], q.dtype)
    w = q[0]
    one, half = _LOG_CONSTS[q.dtype]
    _scale.sum_squares(q, vv, 1)
    _sqnorm_formula(w, vv, _ops.ARRAYS, n2)
    e = v0 = None
    listed = _scale.fits_listed(n2)       # (a few |q|² that fit: as Python floats, for the tests below)
    if listed is False:                   # extreme magnitudes: the vectors kept, whose axes
        v0 = q[1:].copy()                 # a rescale may lose (`_small_vectors`)
        e = _scale.guard(q, n2)
    if e is not None:                     # q was rescaled: |v|² again
        _scale.sum_squares(q, vv, 1)
        _sqnorm_formula(w, vv, _ops.ARRAYS, n2)
    if type(listed) is list and e is None:   # a few, as they are: whether some |q|² = 1, from the
        ratio = _ln_ratio_unit if 1.0 in listed else _ln_ratio_plain   # list (|q|² - 1 = 0 exactly there),
        least = min(vv.ravel().tolist())   # and the smallest |v|² (no NaN: the |q|² fit; 0.4 µs less than
    else:                                  # `_scale.smallest`'s call and NaN test at N = 20)
        ratio, least = _ln_ratio_rows, None
    _ln_formula(w, vv, n2, _ops.ARRAYS, one, half, ratio, d, u, ln)
    # one reduction instead of a mask and a test when no vector is zero or below the range
    few = (_scale.smallest(vv) if least is None else least) < _scale.LOW[vv.dtype]
    vn = _scale.small_norms(q[1:], vv) if few else np.sqrt(vv, out=vv)
    _angle_formula(vn, w, _ops.ARRAYS, arctan2, theta, scale)
    lim = _small_vectors(q, vn, theta, scale, q[1:] if v0 is None else v0) if few else None
    return ln, theta, vn, scale, e, lim, n2


def _sqnorm_formula(w, vv, op, n2):
    """|q|² = w² + |v|² from |v|² (`_log_parts`' order, in `op`'s arithmetic)."""
    n2 = op.mul(w, w, n2)
    return op.add(n2, vv, n2)


def _ln_formula(w, vv, n2, op, one, half, ratio, d, u, ln):
    """ln|q| = log1p(d) / 2 by Kahan's ``log(u) d / (u - 1)`` (`_log_parts`), written once:
    d = (w - 1)(w + 1) + |v|², u = |q|² `n2`, in `op`'s arithmetic with the constants `one`,
    `half` of the operands' dtype; ``ratio(ln, d, um1, n2)`` is ``ln · d / um1``, d where
    |q|² = 1 (rows: a division and a mask; a float: a test).  Returns ln."""
    d = op.sub(w, one, d)
    u = op.add(w, one, u)
    d = op.mul(d, u, d)
    d = op.add(d, vv, d)                  # |q|² - 1 = (w - 1)(w + 1) + |v|²
    ln = ratio(op.log(n2, ln), d, op.sub(n2, one, u), n2)   # u - 1 exact for |q|² in [1/2, 2]
    return op.mul(ln, half, ln)


def _ln_ratio_rows(ln, d, um1, n2, unit=None):
    """`_ln_formula`'s ratio on rows; `unit`: whether some |q|² is 1 (None: not known yet)."""
    if unit is None:
        unit = _scale.any_zero(um1)       # one reduction instead of a mask when none
    ln = _kahan_ratio(ln, d, um1, _ops.ARRAYS)   # nan or inf where |q|² = 1: fixed below
    if unit:
        np.copyto(ln, d, where=n2 == 1)
    return ln


def _kahan_ratio(ln, d, um1, op):
    """``log(u) · d / (u - 1)`` from ln = log(u), written once (`_ln_formula`'s ratio where
    |q|² ≠ 1), into the rows `ln` and `um1`."""
    return op.mul(ln, op.div(d, um1, um1), ln)


def _ln_ratio_unit(ln, d, um1, n2):
    """`_ln_ratio_rows` where some |q|² is known to be 1."""
    return _ln_ratio_rows(ln, d, um1, n2, True)


def _ln_ratio_plain(ln, d, um1, n2):
    """`_ln_ratio_rows` where no |q|² is known to be 1."""
    return _ln_ratio_rows(ln, d, um1, n2, False)


_LOG_CONSTS = {dtype: (_ops.const(1.0, dtype), _ops.const(0.5, dtype)) for dtype in _COMPLEX}
"""1 and 1/2 of `_log_parts`' dtypes, as `_ops.const` makes them."""


def _sqnorms_formula(op, stack, w, x, y, z):
    """(|v|², |q|²) of one quaternion's floats, in `sum_squares`' and `_log_parts`' order."""
    vv = _scale.squares([x, y, z], op, None, None)
    return [vv, _sqnorm_formula(w, vv, op, None)]


# `_log_parts`' formulas on one quaternion's floats, as plain Python statements (`_ops.compiled`:
# the same operations in the same order); ln|q| in two forms, by the test |q|² = 1 of the rows'
_sqnorms_floats = _ops.compiled(_sqnorms_formula, 4)
_ln_floats = _ops.compiled(lambda op, stack, w, vv, n2: [_ln_formula(
    w, vv, n2, op, 1.0, 0.5, lambda ln, d, um1, n2: _kahan_ratio(ln, d, um1, op), None, None, None)], 3)
_ln_unit_floats = _ops.compiled(lambda op, stack, w, vv, n2: [_ln_formula(
    w, vv, n2, op, 1.0, 0.5, lambda ln, d, um1, n2: d, None, None, None)], 3)


def _angle_formula(vn, w, op, atan2, theta, scale):
    """θ = atan2(|v|, w) and the scale θ / |v| of the log's vector part (`_log_parts`)."""
    theta = atan2(vn, w, out=theta)
    return theta, op.div(theta, vn, scale)


def _log_floats_of(kind):
    """`_LOG_FLOATS`' function for `kind`."""
    sqnorms, ln_ratio, ln_unit = (f.kinds[kind] for f in (_sqnorms_floats, _ln_floats, _ln_unit_floats))
    low, high = _scale.BOUNDS[kind]
    sqrt, op = kind.sqrt, kind.op

    def log_floats(comps):
        w = comps[0]
        vv, n2 = sqnorms(*comps)
        if not (low <= n2 <= high and vv >= low):
            return None
        ln = (ln_unit if n2 == 1.0 else ln_ratio)(w, vv, n2)[0]
        vn = sqrt(vv)
        theta, scale = _angle_formula(vn, w, op, _arctan2_float, None, None)
        return ln, theta, vn, scale, n2
    return log_floats


_LOG_FLOATS = _ops.by_kind(_log_floats_of)
"""`_log_parts` on the four floats of one quaternion, by `_ops.Kind`: (ln|q|, θ, |v|, θ/|v|,
|q|²), or None where the block kernel has more to do (|q|² to rescale, |v|² below the
range, zero vector, non-finite input)."""


def _arctan2_float(y, x, out=None):
    """`arctan2` of one pair of floats (`out` ignored), NumPy's loop at once where it is SIMD;
    elsewhere the ratio route, on float32 scalars as 0-d arrays (`arctan2`'s array code)."""
    if _trig.SIMD_TAN:
        return float(np.arctan2(y, x)) if type(y) is float else np.arctan2(y, x)
    if type(y) is float:
        return arctan2(y, x)
    return arctan2(np.array(y), np.array(x), out=np.empty((), y.dtype))[()]


def _small_vectors(q, vn, theta, scale, v0):
    """`_log_parts`' fixes for a block with vectors that are zero or whose |v|² underflowed
    (their |v| already taken by scaling): returns the mask of the rows whose scale θ/|v|
    takes its limit, 1/w for w > 0 (θ = 0 or below the normal range: v = 0, or |v| / w
    tiny) and 0 for a zero or negative real q (whose callers choose the axis).  Where
    w < 0 and |v|² is below the range (θ = π in the float format), only the axis v/|v|
    matters: v and |v| are replaced in place (q is a scratch copy) by the vector as given,
    `v0` (q's own, or the one before a rescale that may have lost its digits), scaled by a
    power of two to |v| near 1, so that the axis is v0's and θ/|v| and sin(tθ)/|v| do
    not overflow, nor their products with |q|^t."""
    w = q[0]
    axis = (w < 0) & (vn < _scale.LOW[vn.dtype] ** 0.5) & (np.max(np.abs(v0), axis=0) > 0)
    if axis.any():
        v = v0[:, axis]
        _, e = np.frexp(np.max(np.abs(v), axis=0))
        v = np.ldexp(v, -e)
        q[1:, axis] = v
        vn[axis] = np.sqrt(_scale.sum_squares(v, np.empty(v.shape[1:], v.dtype)))
    np.divide(theta, vn, out=scale, where=axis)
    lim = ((vn == 0) | (theta < np.finfo(vn.dtype).tiny)) & ~axis
    scale[lim] = np.where(w > 0, 1.0 / w, 0.0)[lim]
    return lim


def _k_log(q, o):
    ln, theta, vn, scale, e, lim, _ = _log_parts(q)
    _log_vector(q[1:], scale, _ops.STACKS, o[1:])
    np.copyto(o[0], ln)
    if e is not None:   # ln|q| = ln|q 2**-e| + e ln 2
        o[0] += e * np.log(o.dtype.type(2))
    if lim is not None:   # a real quaternion in the block: the negative ones get θ = π about x
        np.copyto(o[1], np.pi, where=(vn == 0) & (q[0] < 0))


def _log_vector(v, scale, stack, out):
    """The log's vector part v θ/|v| from `_log_parts`' scale (a stack of rows, `_ops.STACKS`,
    or floats, `_ops.FLOAT_STACKS`)."""
    return stack.scale(v, scale, out)


def log(q):
    """Principal quaternion logarithm (ln|q|, θ v/|v|), θ = atan2(|v|, w) ∈ [0, π].

    A negative real quaternion -r gives (ln r, π, 0, 0); the zero quaternion
    gives (-inf, 0, 0, 0).

    >>> import numpy as np
    >>> from quatarray._kernels import log
    >>> np.allclose(log(np.array([0., 0, 1, 0])), [0, 0, np.pi / 2, 0])
    True
    """
    q = np.asarray(q)
    one, kind = _ops.floats64(q), _ops.F64
    if one is None:
        one, kind = _ops.floats32(q)
    if one is not None:   # one float64 or float32 quaternion: the same formula on its floats
        parts = _LOG_FLOATS[kind](one)
        if parts is not None:
            return _ops.to_array([parts[0], *_log_vector(one[1:], parts[3], _ops.FLOAT_STACKS, None)], q.shape,
                                 kind.dtype)
    res = np.empty(q.shape, result_dtype(q))
    _blockwise_quiet(_k_log, [q], [res], dtype=res.dtype)
    return res


def _k_power(q, t, o):
    _power_block(q, t[0], o)


def _k_power_scalar(q, o, t):
    """`_k_power` with one exponent `t` for every row, a 0-d array of the block's dtype (each
    operation with t gives the bits it gives with a row of copies of t)."""
    _power_block(q, t, o)


def _power_block(q, t, o):
    """`_k_power` on the rows `q` into `o`, with the exponents `t` (a row, or a 0-d array)."""
    ln, theta, vn, scale, e, lim, n2 = _log_parts(q)
    mag, ang, c, sn = _blocks.scratch().rows(4, q.shape[1:], q.dtype)
    real = zero = None   # (masks only for a block with real quaternions or vectors below the range)
    if lim is not None:
        real = vn == 0
        zero = real & (q[0] == 0)

    def magnitude(mag):
        # |q| beyond [e**-0.5, e**0.5]: exp(t ln|q|) carries ln's rounding times |t ln|q|| (140
        # ulp for 2**1023); (|q|²)^(t/2) only that of |q|², times |t| / 2 (pow rounds correctly).
        # (Of the rows as rescaled, if they were: each row's choice is its own.)
        if ln.size <= _blocks.FEW:   # a few: the mask at once (a range test first costs as much),
            far = np.abs(ln) > 0.5   # and every row's power, kept where far (cheaper than gathering
            if True in far.ravel().tolist():   # and scattering them; the same bits either way)
                half = _ops.const(0.5, t.dtype)   # (t / 2 in every row)
                np.copyto(mag, _far_modulus(n2, t, half, _ops.ARRAYS, np.empty_like(n2)), where=far)
        elif not _scale.inside(ln, 0.5):
            far = np.abs(ln) > 0.5
            mag[far] = _far_modulus(n2[far], np.broadcast_to(t, far.shape)[far], 0.5, _ops.ARRAYS, None)
        if e is not None:   # |q|^t = |q 2**-e|^t 2**(t e): exact powers of two where t e is an integer
            mag *= np.exp2(t * e)
        if zero is not None and zero.any():
            np.copyto(mag, np.where(zero, np.where(t > 0, 0.0, np.where(t == 0, 1.0, np.inf)), mag))
        return mag

    def ratio(sn, f):
        # sin(tθ) / |v|  (the axis is v/|v|); where θ is 0 or below the range its limit t·scale
        if lim is not None:
            return np.copyto(f, np.where(lim, t * scale, sn / np.where(real, 1, vn))) or f
        return np.divide(sn, vn, out=f)

    _, f, ang = _power_formula(t, ln, theta, _ops.ARRAYS, magnitude, ratio, mag, ang, c, sn, o[0])
    if zero is not None and zero.any():  # inf * 0 for 0 ** t, t < 0: the vector part stays 0
        ang[zero] = 0.0
    np.multiply(q[1:], ang, out=o[1:])
    if not all_finite(ang):   # sin(tθ)/|v| · |q|^t overflowed: v's share first (|v_k| <= |v|),
        big = ~np.isfinite(ang)   # and a component lost to 0 × inf stays ±0, not NaN
        for k in (1, 2, 3):
            vk = q[k][big] * f[big]
            ok = np.multiply(vk, mag[big])
            o[k][big] = np.where(np.isnan(ok), np.copysign(0.0, vk) * np.sign(mag[big]), ok)
    if real is not None:
        neg_real = real & (q[0] < 0)
        if neg_real.any():
            np.copyto(o[1], mag * sn, where=neg_real)


def _power_formula(t, ln, theta, op, magnitude, ratio, mag, ang, c, sn, o0):
    """The power's formula, written once: |q|^t = exp(t ln|q|) (``magnitude(mag)`` then
    adjusts it: the rows far from |q| = 1, rescaled or zero), and (the real part |q|^t cos(tθ)
    into `o0`, sin(tθ) / |v|, that times |q|^t): the last two, the factors of the vector part
    (``ratio(sn, f)`` divides sin(tθ) by |v| into `f`, the row of tθ).  In `op`'s
    arithmetic (its exp, cos and sin: NumPy's).  sin and cos, not `cos_sin`: cos(tθ) keeps
    its relative accuracy near tθ = π/2 (principal roots of negative reals)."""
    mag = magnitude(op.exp(op.mul(t, ln, mag), mag))
    ang = op.mul(t, theta, ang)
    c = op.cos(ang, c)
    sn = op.sin(ang, sn)
    w = op.mul(mag, c, o0)
    f = ratio(sn, ang)
    return w, f, op.mul(f, mag, c)   # (c is free: the real part is written)


def _far_modulus(n2, t, half, op, out):
    """|q|^t as ``(|q|²)^(t/2)``, for |q| far from 1 (`_power_formula`'s `magnitude`), written
    once, in `op`'s arithmetic (`half`: 0.5 as its operand), into the row `out`."""
    return op.power(n2, op.mul(t, half, out), out)


def _power_floats_formula(far):
    """`_power_formula` on one quaternion's floats ``(t, ln|q|, θ, |v|, |q|²)``, compiled
    (`_ops.compiled`) for a modulus near 1 (exp(t ln|q|)) or `far` from it ((|q|²)^(t/2))."""
    def formula(op, stack, t, ln, theta, vn, n2):
        def magnitude(mag):
            return _far_modulus(n2, t, 0.5, op, None) if far else mag
        return _power_formula(t, ln, theta, op, magnitude, lambda sn, f: op.div(sn, vn, None),
                              None, None, None, None, None)
    return _ops.compiled(formula, 5)


_POWER_FLOATS = {False: _power_floats_formula(False), True: _power_floats_formula(True)}


def _power_floats_of(kind):
    """`_POWER_FLOATS_OF_KIND`'s function for `kind`."""
    log_floats, top = _LOG_FLOATS[kind], _POWER_EXP[kind]
    near, far = (_POWER_FLOATS[f].kinds[kind] for f in (False, True))
    scale = _ops.FLOAT_STACKS.scale
    cast = None if kind is _ops.F64 else kind.dtype.type   # (t: a float of the quaternion's dtype)

    def power_floats(comps, t):
        parts = log_floats(comps)
        if parts is None:
            return None
        ln, theta, vn, _, n2 = parts
        # (tested in Python floats: float32 scalars would warn where the products overflow)
        if not (abs(t * float(ln)) < top and abs(t * float(theta)) < _POWER_ANGLE):
            return None
        # (abs(ln) > 0.5: `_k_power`'s choice of the modulus' formula, for this quaternion)
        w, _, g = (far if abs(ln) > 0.5 else near)(t if cast is None else cast(t), ln, theta, vn, n2)
        if not abs(g) < math.inf:   # sin(tθ)/|v| · |q|^t overflowed: the block kernel's fix
            return None
        return [w, *scale(comps[1:], g, None)]
    return power_floats


_POWER_ANGLE = 2.0 ** 50   # tθ beyond it: the block kernel (sin and cos keep few digits there anyway)
_POWER_EXP = {_ops.F64: 700.0, _ops.F32: 40.0}
"""Bounds of |t ln|q|| for the float paths, by `_ops.Kind`: exp(t ln|q|) stays finite, and in
float32 so does sin(tθ)/|v| · |q|^t (|v| >= 2**-40 there), whose overflow float32 scalars
would warn of (Python floats do not: the float64 path tests the product afterwards)."""

_POWER_FLOATS_OF_KIND = _ops.by_kind(_power_floats_of)
"""`_k_power` on the four floats of one quaternion and an exponent t (a Python float, of the
quaternion's dtype), by `_ops.Kind`, or None where the block kernel has more to do (as
`_LOG_FLOATS`; |t ln|q|| or tθ too large for exp, cos and sin to stay quiet and finite;
sin(tθ)/|v| · |q|^t overflowing)."""


def power(q, t):
    """Quaternion power exp(t log q) for real `t` (scalar or batch-shaped).

    ``0 ** t`` is 0 for t > 0, 1 for t = 0 and inf for t < 0.

    >>> import numpy as np
    >>> from quatarray._kernels import power
    >>> k = np.array([0., 0, 0, 1])
    >>> np.allclose(power(k, 2), [-1, 0, 0, 0])
    True
    """
    q = np.asarray(q)
    if type(t) is float:   # (the common `q ** 0.5`: no 0-d array to make and ask)
        one, kind = _ops.floats64(q), _ops.F64
        if one is None:
            one, kind = _ops.floats32(q)
        tf = t
    else:
        t = np.asarray(t)
        one, kind = None, None
        if t.size == 1 and t.ndim <= q.ndim - 1:
            one, kind = _ops.floats64(q), _ops.F64
            if one is None:
                one, kind = _ops.floats32(q)
        tf = float(t.item(0)) if one is not None else None
    if one is not None:   # one float64 or float32 quaternion, one exponent: the same formula on floats
        if kind is not _ops.F64:   # the block kernel takes t in the quaternion's dtype
            tf = float(kind.dtype.type(tf))
        one = _POWER_FLOATS_OF_KIND[kind](one, tf)
        if one is not None:
            return _ops.to_array(one, q.shape, kind.dtype)
    t = np.asarray(t)
    dtype = result_dtype(q)
    batch = q.shape[:-1] if not t.ndim else np.broadcast_shapes(q.shape[:-1], t.shape)
    res = np.empty(batch + (4,), dtype)
    if t.ndim:
        _blockwise_quiet(_k_power, [q, t[..., None]], [res], batch, dtype=dtype)
    else:   # one exponent: not copied into every block
        _blockwise_quiet(_k_power_scalar, [q], [res], batch, dtype=dtype, t=np.array(t, dtype))
    return res


def rotate(q, v, inverse=False, unit=False, add=None):
    """Rotate vectors `v` (..., 3) by q/|q|: the vector part of q v q⁻¹.

    Uses the expanded form u' = u + w t + vec × t with t = 2 vec × u / |q|²,
    which is the game-developer formula u + 2w(v×u) + 2 v×(v×u) for unit q.
    Every pair (one quaternion with many vectors too) runs this one formula,
    so a vector gets the same bits whatever else is rotated with it.  With
    `inverse`, rotate by conj(q).  Zero quaternions give nan.  `unit`: the caller knows
    that q holds finite unit quaternions (`Rotation.apply`): |q|² is not range-checked,
    and where the vectors are finite and far from the float maximum no floating-point
    warning can arise and none is silenced (the same bits).  `add`: an array of the
    result's shape and dtype added to the rotated vectors (a rigid motion's translation),
    block by block while each is in cache; the same bits as adding it afterwards.

    >>> import numpy as np
    >>> from quatarray._kernels import rotate
    >>> q = np.array([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])  # 90° about z
    >>> np.allclose(rotate(q, np.array([1., 0, 0])), [0, 1, 0])
    True
    >>> np.allclose(rotate(q, np.array([[1., 0, 0]]), inverse=True), [[0, -1, 0]])
    True
    """
    batch = q.shape[:-1] if q.shape[:-1] == v.shape[:-1] else np.broadcast_shapes(q.shape[:-1], v.shape[:-1])
    if add is not None:
        dtype = result_dtype(q, v)
        if add.shape != batch + (3,) or add.dtype != dtype:
            raise ValueError(f"expected add of shape {batch + (3,)} and dtype {dtype}, got {add.shape} {add.dtype}")
    one = _rotate_floats(q, v, inverse) if len(batch) <= 1 and v.size == 3 else None
    if one is not None:
        res = np.array(one).reshape(batch + (3,))
        return res if add is None else np.add(res, add, out=res)
    dtype = q.dtype if q.dtype == v.dtype and q.dtype in _COMPLEX else result_dtype(q, v)
    res = np.empty(batch + (3,), dtype)
    wsign = -1.0 if inverse else 1.0
    if 0 < res.size <= 3 * _blocks.FEW:   # a few: straight into the rows the formula reads
        rows = np.empty((22,) + (batch or (1,)), dtype)   # rows, not scalars, for one rotation
        if q.ndim == v.ndim == 2:   # flat batches: the transposes broadcast as they are
            rows[:4] = q.T
            rows[6:9] = v.T
        else:
            for a, dst in ((soa(q), rows[:4]), (soa(v), rows[6:9])):   # batches right-aligned
                dst[...] = a.reshape(a.shape[:1] + (1,) * (rows.ndim - a.ndim) + a.shape[1:])
        _rotate_few(rows, soa(res.reshape(rows.shape[1:] + (3,))), wsign, unit)
        return res if add is None else np.add(res, add, out=res)
    # `add` rides along as a second output the kernel only reads: its blocks are the result's
    outs = [res] if add is None else [res, add]
    # (zero quaternions give nan)
    _blockwise_quiet(rotate_block, [q, v], outs, batch, dtype=dtype, wsign=wsign, unit=unit)
    return res


def _rotate_floats(q, v, inverse):
    """`rotate_block`'s formula on the floats of one float64 or float32 pair (both of one
    dtype), or None where the block kernel would rescale (|q|² outside [1/4, 4], a huge
    vector, non-finite input)."""
    c, kind = _ops.floats64(q), _ops.F64
    if c is None:
        c, kind = _ops.floats32(q)
    if c is None or v.dtype is not kind.dtype:
        return None
    return _ROTATE_FLOATS[kind](c, v, inverse)


def _rotate_floats_of(kind):
    """`_ROTATE_FLOATS`' function for `kind`."""
    op, squares, rotated, big = kind.op, _scale.squares, _rotated_floats.kinds[kind], _HALF_BIG[kind.dtype]
    python = kind is _ops.F64

    def rotate_floats(c, v, inverse):
        u = v.reshape(3).tolist() if python else _ops.floats32(v, 3)[0]
        if u is None:   # (a float32 vector of huge components)
            return None
        ux, uy, uz = u
        n2 = squares(c, op, None, None)
        if not (0.25 <= n2 <= 4.0 and -big <= ux <= big and -big <= uy <= big and -big <= uz <= big):
            return None
        w, s = _rotation_terms(c[0], n2, inverse, op, None)
        return rotated(w, c[1], c[2], c[3], ux, uy, uz, s)
    return rotate_floats


_HALF_BIG = {d: 0.5 * big for d, big in _scale.BIG_VECTOR.items()}


def _rotated(w, v1, v2, u, u1, u2, s, op, o, t, m, m2):
    """u' = u + w t + vec × t with t = s vec × u, in `op`'s arithmetic (`_ops`) on rows of
    three: `u` and its cyclic shifts ``u1 = (uy, uz, ux)``, ``u2 = (uz, ux, uy)``, and
    likewise ``v1``, ``v2`` of the vector part (so that a cross product is two products
    and a difference of rows); into `o` (three rows) with the work rows `t` (five: t and
    its two shifts), `m` and `m2` (three each); returned.  `u`'s rows are overwritten (its
    last use holds u + w t: in a block they are contiguous scratch, where `o` is a strided
    view of the output, written once)."""
    t0 = op.mul(op.sub(op.mul(v1, u2, t[:3]), op.mul(v2, u1, m), t[:3]), s, t[:3])   # s vec × u
    t1, t2 = op.shifts(t0, t)
    r = op.add(op.mul(w, t0, m), u, u)                                            # u + w t
    return op.add(r, op.sub(op.mul(v1, t2, m), op.mul(v2, t1, m2), m), o)         # + vec × t


_rotated_floats = _ops.compiled(
    lambda op, rows, w, x, y, z, ux, uy, uz, s: _rotated(w, [y, z, x], [z, x, y], [ux, uy, uz], [uy, uz, ux],
                                                         [uz, ux, uy], s, rows, None, _ops.NONE, None, None), 8)
"""`_rotated` on one pair's floats ``(w, x, y, z, ux, uy, uz, s)`` (`_ops.compiled`)."""

_ROTATE_FLOATS = _ops.by_kind(_rotate_floats_of)
"""`_rotate_floats` once the quaternion's floats ``c`` are read, by `_ops.Kind`: ``f(c, v,
inverse)``."""


def rotate_nonzero(q, v, inverse=False):
    """`rotate`, refusing zero quaternions (their NaN) with the API's `ValueError`: finite q and
    v give finite vectors otherwise."""
    res = rotate(q, v, inverse=inverse)
    if not all_finite(res) and all_finite(q):
        raise ValueError("expected non-zero quaternions to rotate by, got a zero quaternion")
    return res


def rotate_block(q, u, o, add=None, *, wsign, unit=False):
    """`rotate`'s block kernel: components-first scratch copies q (4, *s) and u (3, *s), which
    it overwrites, into o (3, *s); `wsign` -1 rotates by conj(q); `unit` as `rotate`'s (the
    checks `_rotate_few` skips); `add` (3, *s), components-first view like o, is added to
    the result.  Evaluated one component row at a time (`_ops.ARRAY_ROWS`: a row's shifts
    are views, nothing is copied)."""
    # checked as `_rotate_few` does: a unit q and no vector near the float maximum, nothing to rescale
    w, s, e = _rotate_setup(q, u, wsign, unit, checked=unit and _scale.inside(u, _HALF_BIG[u.dtype]))
    x, y, z = q[1:]
    ux, uy, uz = u
    with _blocks.scratch().frame() as work:
        t = list(work.rows(9, q.shape[1:], o.dtype))
        _rotated(w, [y, z, x], [z, x, y], [ux, uy, uz], [uy, uz, ux], [uz, ux, uy], s, _ops.ARRAY_ROWS,
                 list(o), t[:3], t[3:6], t[6:9])
    _scale.unscale(o, e)
    if add is not None:   # the (s, 3) blocks themselves: one contiguous add, not three strided
        np.add(o.T, add.T, out=o.T)


def _rotate_few(rows, o, wsign, unit=False):
    """`rotate_block`'s formula for a few pairs (up to `_blocks.FEW`), on stacked rows of three
    (`_ops.ARRAYS`: a third of the ufunc calls; the same operations per element, the same
    bits).  `rows` (22, *s) holds q in rows 0-3 and u in rows 6-8; the vector part and u
    are extended with their first two rows, so that their cyclic shifts are views."""
    q, u = rows[:4], rows[6:9]
    if unit and _scale.inside(u, _HALF_BIG[u.dtype]):
        # finite unit q, no vector near the float maximum and none non-finite: nothing
        # to rescale, and no operation can warn
        _rotate_rows(rows, o, *_rotate_setup(q, u, wsign, unit, checked=True, work=rows[11:15]))
        return
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # zero quaternions give nan
        _rotate_rows(rows, o, *_rotate_setup(q, u, wsign, unit))


def _rotate_rows(rows, o, w, s, e):
    """`_rotate_few`'s formula once `_rotate_setup` has given w, 2 / |q|² and e."""
    rows[4:6] = rows[1:3]    # x y z x y
    rows[9:11] = rows[6:8]   # ux uy uz ux uy
    _rotated(w, rows[2:5], rows[3:6], rows[6:9], rows[7:10], rows[8:11], s, _ops.ARRAYS, o, rows[11:16],
             rows[16:19], rows[19:22])
    _scale.unscale(o, e)


def _rotate_setup(q, u, wsign, unit=False, checked=False, work=None):
    """(w, 2 / |q|², e) for `rotate`'s formula, rescaling q and u in place where needed.
    `unit` (finite unit q): no q is rescaled, so |q|²'s range check is skipped; `checked`:
    the caller has found every vector below half `_scale.BIG_VECTOR`, so none is rescaled
    either; `work`: four free rows for the squares (`_scale.sum_squares`)."""
    if unit:
        n2 = _scale.sum_squares(q, np.empty(q.shape[1:], q.dtype) if q[0].size <= _blocks.FEW
                                else _blocks.scratch().rows(1, q.shape[1:], q.dtype)[0], rows=work)
    else:
        n2 = _scale.guarded_sqnorm(q)
    w, s = _rotation_terms(q[0], n2, wsign < 0, _ops.ARRAYS, q[0])
    # vectors near the float maximum are scaled down by a power of two, and the result back up
    e = None if checked else _scale.shrink_vectors(u, n2)
    return w, s, e


def _rotation_terms(w, n2, inverse, op, w_out):
    """(w, or -w for the inverse rotation, and ``s = 2 / |q|²``), `_rotated`'s terms besides
    the vectors, written once, in `op`'s arithmetic (into `w_out` and n2's row)."""
    if inverse:
        w = op.mul(w, -1.0, w_out)
    return w, op.div(2.0, n2, n2)
