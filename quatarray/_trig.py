"""The kernels' own tangent and arctangent, where NumPy's are scalar loops.

NumPy's float64 ``tan`` is a SIMD loop only on CPUs with AVX-512 (SVML);
elsewhere it calls the C library element by element (12-23 ns per element
on the AVX2 machines of benchmarks/README.md, against about 1.4 ns with
AVX-512).  The kernels need it on small arguments: quarter angles of
rotations up to a half turn and SLERP's partial half arcs, all within
[-π/4, π/4].  There Cephes' rational approximation

    tan x = x + x z P(z) / Q(z),   z = x²  (P of degree 2, Q of degree 4)

is within 1 ulp of the correctly rounded tangent (and takes that at ±π/4
itself, the quarter angle of a half turn), and costs 16 ufunc
passes (about 5 ns per element on AVX2).  Larger arguments are first
reduced by multiples of π/2 (within 2 ulp); beyond `REDUCE_LIMIT`, NaN and
infinities go to `np.tan`.  Each element takes the same operations whatever
the rest of its block holds, so its result does not depend on the block.
On CPUs where NumPy's tangent is a SIMD loop, `tan` is `np.tan`.

`atan_unit32` is float32's arctangent on [0, 1] (SLERP's half angles): NumPy's
float32 ``arctan`` and ``arcsin`` are scalar loops on AVX2 too (8-14 ns per
element), Cephes' polynomial after one reduction by π/4 costs 2.4 ns.  Where
NumPy's tangent is a SIMD loop, so is its float32 arctangent (the same SVML
build), and `atan_unit32` is `np.arctan`.
"""

import math

import numpy as np

from . import _ops

__all__ = ["SIMD_TAN", "QUARTER_PI", "TAN_QUARTER_PI", "REDUCE_LIMIT", "tan", "tan_float", "rational", "reduced",
           "atan_unit32"]

# Cephes, tan.c: P with the highest degree first; Q monic (leading 1 implied)
_P0, _P1, _P2 = -1.30936939181383777646e4, 1.15351664838587416140e6, -1.79565251976484877988e7
_Q0, _Q1, _Q2, _Q3 = (1.36812963470692954678e4, -1.32089234440210967447e6,
                      2.50083801823357915839e7, -5.38695755929454629881e7)

#: Arguments up to this magnitude take the rational approximation as they are.
QUARTER_PI = math.pi / 4

#: tan(±QUARTER_PI), correctly rounded: 1 - 2⁻⁵³, where the rational approximation
#: gives 1.  The exact tangent is within 6e-18 of the midpoint between the two, and
#: this one matters: it is the quarter angle of a half turn, whose w = cos(π/2)
#: must keep the sign of the rounded π (as scipy's, and NumPy's tangent, give it).
TAN_QUARTER_PI = 0.9999999999999999

#: Arguments up to this magnitude are reduced by multiples of π/2 first; larger
#: ones go to `np.tan`.
REDUCE_LIMIT = 2.0 ** 20

_TWO_OVER_PI = 2 / math.pi
# Cephes' π/4 in three parts: DP1 and DP2 have few enough bits that their products
# with the even multipliers used here are exact
_DP1, _DP2, _DP3 = 7.853981554508209228515625e-1, 7.94662735614792836714e-9, 3.06161699786838294307e-17

_RATIONAL = _ops.operands(_P0, _P1, _P2, _Q0, _Q1, _Q2, _Q3)
_REDUCTION = _ops.operands(_TWO_OVER_PI, _DP1, _DP2, _DP3, 0.0, 0.5, 1.0)


#: NumPy's float64 tangent is a SIMD loop on this CPU: `tan` is `np.tan`.
SIMD_TAN = _ops.SVML


def rational(x, out, z, p, q, op=_ops.ARRAYS):
    """out = tan x for |x| <= π/4 (out may be x; z, p, q scratch rows overlapping neither),
    in `op`'s arithmetic (`_ops`: rows, or one Python float with the rows ignored; the
    same operations in the same order, so the same bits).

    >>> import numpy as np
    >>> from quatarray._trig import rational
    >>> x = np.array([0.25, -0.5])
    >>> bool(np.allclose(rational(x, np.empty(2), *np.empty((3, 2))), np.tan(x), rtol=2e-16, atol=0))
    True
    """
    p0, p1, p2, q0, q1, q2, q3 = _RATIONAL[op is _ops.FLOATS]
    z = op.mul(x, x, z)
    p = op.mul(z, p0, p)
    p = op.add(p, p1, p)
    p = op.mul(p, z, p)
    p = op.add(p, p2, p)
    q = op.add(z, q0, q)
    q = op.mul(q, z, q)
    q = op.add(q, q1, q)
    q = op.mul(q, z, q)
    q = op.add(q, q2, q)
    q = op.mul(q, z, q)
    q = op.add(q, q3, q)
    p = op.mul(p, z, p)
    p = op.div(p, q, p)
    p = op.mul(p, x, p)
    return op.add(x, p, out)


def reduced(x, out, rows, op=_ops.ARRAYS):
    """out = tan x for |x| <= `REDUCE_LIMIT`: x = z + k π/2 with |z| <= π/4 (π/2 in three
    parts, as in Cephes), tan x = tan z for even k and -1 / tan z for odd k, blended as
    ``(t e - o) / (t o + e)`` (o = 1 - e = k mod 2) without a mask.  For k = 0 every
    step is exact: the bits of `rational`.  In `op`'s arithmetic, as `rational`.

    >>> import numpy as np
    >>> from quatarray._trig import reduced
    >>> x = np.array([1.0, -4.0, 100.0])
    >>> bool(np.allclose(reduced(x, np.empty(3), np.empty((3, 3))), np.tan(x), rtol=5e-16, atol=0))
    True
    """
    k, y, z = rows
    o, p = (np.empty_like(x), np.empty_like(x)) if op is _ops.ARRAYS else (None, None)
    two_over_pi, dp1, dp2, dp3, zero, half, one = _REDUCTION[op is _ops.FLOATS]
    k = op.mul(x, two_over_pi, k)
    k = op.rint(k, k)
    k = op.add(k, zero, k)                       # -0 -> +0: then x - 0 keeps x = -0 (the bits of `rational`)
    y = op.add(k, k, y)                          # multiples of π/4: y·DP1, y·DP2 are exact
    z = op.mul(y, dp1, z)
    z = op.sub(x, z, z)
    p = op.mul(y, dp2, p)
    z = op.sub(z, p, z)
    p = op.mul(y, dp3, p)
    z = op.sub(z, p, z)
    y = op.mul(k, half, y)                       # o = |k - 2 rint(k / 2)|: 1 for odd k
    y = op.rint(y, y)
    y = op.add(y, y, y)
    o = op.sub(k, y, o)
    o = op.abs(o, o)
    t = rational(z, k, y, p, out, op)            # x is not read again: out may be x
    p = op.sub(one, o, p)                        # e
    y = op.mul(t, o, y)
    y = op.add(y, p, y)                          # t o + e
    z = op.mul(t, p, z)
    z = op.sub(z, o, z)                          # t e - o
    return op.div(z, y, out)


def tan_float(x, out=None, rows=None, bounds=None):
    """`tan` of one Python float with the bits of `tan` on an array holding it: NumPy's
    loop where `tan` is `np.tan`, else `rational` or `reduced` on the float (`out`, `rows`,
    `bounds`: ignored, for kernels written for either).

    >>> import numpy as np
    >>> from quatarray._trig import tan, tan_float
    >>> all(tan_float(x) == tan(np.array([x]))[0] for x in (0.3, -0.7853981633974483, 2.0, 1e300))
    True
    """
    if SIMD_TAN or not abs(x) <= REDUCE_LIMIT:   # NaN and huge: NumPy's loop, as `tan` does
        return float(np.tan(x))
    if -QUARTER_PI < x < QUARTER_PI:
        return rational(x, None, None, None, None, _ops.FLOATS)
    if abs(x) == QUARTER_PI:
        return math.copysign(TAN_QUARTER_PI, x)
    return reduced(x, None, _ops.NONE[:3], _ops.FLOATS)


def tan(x, out=None, rows=None, bounds=None):
    """``np.tan(x, out=out)``, within 2 ulp, by the cheaper route on this CPU.

    Parameters
    ----------
    x : ndarray
        Angles in radians (float64 takes the rational approximation where
        ``|x| <= REDUCE_LIMIT``; other dtypes go to `np.tan`).
    out : ndarray, optional
        Output of x's shape and dtype; may be `x` itself.
    rows : sequence of three ndarrays, optional
        Scratch of x's shape and dtype, overlapping neither `x` nor `out`
        (kernels pass rows they hold): then nothing is allocated for
        arguments within [-π/4, π/4].
    bounds : (float, float), optional
        Bounds ``lo <= x <= hi`` the caller knows (float64): then `x` is not
        reduced to find them (two reductions).  Looser bounds give the same
        bits (`reduced` is exact where `rational` applies).

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._trig import tan
    >>> x = np.array([0.0, 0.5, -0.75, 2.0, 1e300])
    >>> bool(np.allclose(tan(x), np.tan(x), rtol=3e-16, atol=0))
    True
    """
    if SIMD_TAN or x.dtype != np.float64 or x.size == 0:
        return np.tan(x, out=out)
    if out is None:
        out = np.empty_like(x)
    if rows is None:
        rows = (np.empty_like(x), np.empty_like(x), np.empty_like(x))
    lo, hi = bounds or (np.minimum.reduce(x, axis=None), np.maximum.reduce(x, axis=None))
    if -QUARTER_PI < lo and hi < QUARTER_PI:     # the common case (NaN fails the test)
        return rational(x, out, *rows)
    quarter = np.abs(x) == QUARTER_PI            # masks, not indices: x may be 0-d
    signs = np.sign(x[quarter])
    if -REDUCE_LIMIT <= lo and hi <= REDUCE_LIMIT:
        reduced(x, out, rows)
    else:
        wide = ~(np.abs(x) <= REDUCE_LIMIT)      # NaN, ±inf, huge: the C library's reduction
        big = x[wide]                            # copied before `out` (maybe x) is written
        reduced(np.where(wide, 0.0, x), out, rows)
        out[wide] = np.tan(big)
    out[quarter] = signs * TAN_QUARTER_PI
    return out


# Cephes, atanf.c: atan x = x + x z (((A0 z + A1) z + A2) z + A3), z = x², |x| <= tan(π/8)
_A = tuple(np.float32(c) for c in (8.05374449538e-2, -1.38776856032e-1, 1.99777106478e-1, -3.33329491539e-1))
_TAN_EIGHTH_PI = np.float32(0.41421356237309503)
# π/4 as a float32 plus the float32 rounding of the rest, added before it
_PIO4_HI = np.float32(math.pi / 4)
_PIO4_LO = np.float32(math.pi / 4 - float(_PIO4_HI))


def atan_unit32(x, out, b, u, z):
    """out = arctan x for float32 x in [0, 1], within 2 ulp (b, u, z: float32 scratch of x's
    shape; none of the four arrays may overlap another).

    Above tan(π/8), atan x = π/4 + atan((x - 1)/(x + 1)); both cases run as one
    blend, ``(x - s) / (s x + 1)`` with s = 0 or 1, without a mask.

    >>> import numpy as np
    >>> from quatarray._trig import atan_unit32
    >>> x = np.array([0.0, 0.25, 0.5, 1.0], np.float32)
    >>> got = atan_unit32(x, *np.empty((4, 4), np.float32))
    >>> bool(np.allclose(got, np.arctan(x), rtol=3e-7, atol=0))
    True
    """
    if SIMD_TAN:   # the AVX-512 builds' SVML loops: NumPy's float32 arctan is SIMD too (0.4 ns, not 1.9)
        return np.arctan(x, out=out)
    np.greater(x, _TAN_EIGHTH_PI, out=b)         # s: 0 or 1
    np.subtract(x, b, out=u)
    np.multiply(b, x, out=z)
    z += 1
    np.divide(u, z, out=u)                       # the reduced argument, |u| <= tan(π/8)
    np.multiply(u, u, out=z)
    np.multiply(z, _A[0], out=out)
    out += _A[1]
    out *= z
    out += _A[2]
    out *= z
    out += _A[3]
    out *= z
    out *= u
    np.multiply(b, _PIO4_LO, out=z)
    out += z
    out += u
    b *= _PIO4_HI
    out += b
    return out
