"""Quaternions of any magnitude: squared norms that stay in range, and the finiteness test.

A quaternion ``r q`` is the rotation ``q`` for every r > 0, but its squared
norm overflows for |r q| above about 1e154 (float64; 1e19 in float32) and
loses its digits to underflow below about 1e-154 (1e-19).  Kernels that
square components therefore check the squared norms they compute anyway,
per block, with two reductions (`fits`); only a block that fails is
rescaled (`rescale`): each quaternion is multiplied by a power of two that
brings its largest component into [1/2, 1).  Multiplying by a power of two
is exact, so a rescaled quaternion gives the same bits as an unscaled one of
ordinary size, and the common path pays two reductions per block.

The same check finds non-finite input for free: a NaN or an infinity makes
the block's largest squared norm NaN or infinite, so `fits` fails and
`guard` looks at the components exactly.

Everything here works on components-first blocks ``(k, *s)`` (the block
engine's scratch copies, which kernels may overwrite).  Only the rows
that need it are rescaled, so a row's bits never depend on its block.
"""

import math

import numpy as np

from . import _blocks, _ops

__all__ = ["NONFINITE", "ZERO", "LOW", "HIGH", "fits", "fits_listed", "sum_squares", "rescale", "guard", "guarded_sqnorm",
           "outside", "unscale", "true_norm", "BIG_VECTOR", "inside", "at_most", "largest", "smallest", "any_zero",
           "shrink_vectors", "small_norms"]

NONFINITE = "expected finite quaternions, got nan or inf"
ZERO = "expected non-zero quaternions, got a zero quaternion (it is no rotation)"
"""The conversions' error for the zero quaternion (`guard` with ``zero=True``)."""

_RANGE = {}
for _d in (np.float32, np.float64):
    _f = np.finfo(_d)
    # squares of components down to |q| eps are still normal numbers above LOW;
    # HIGH leaves room for the few products kernels form with a squared norm
    _RANGE[np.dtype(_d)] = (float(_f.tiny) / float(_f.eps) ** 2, float(_f.eps) ** 2 / float(_f.tiny))

LOW = {d: r[0] for d, r in _RANGE.items()}
"""Smallest squared norm used as it is, per dtype (2**-918 in float64, 2**-80 in float32)."""

HIGH = {d: r[1] for d, r in _RANGE.items()}
"""Largest squared norm used as it is, per dtype (2**918 in float64, 2**80 in float32)."""

BOUNDS = {kind: _RANGE[kind.dtype] for kind in _ops.KINDS}
"""(`LOW`, `HIGH`) of a float path's `_ops.Kind` (one quaternion's float64 or float32 components)."""

BIG_VECTOR = {d: float(np.ldexp(np.finfo(d).max, -4)) for d in _RANGE}
"""Largest |component| of a vector rotated as it is, per dtype: the rotation formulas form
sums of up to five terms of the vector's size (`shrink_vectors`)."""


#: Up to this many squared norms, `fits` compares Python floats (a NumPy reduction
#: costs about 1.5 µs a call, the comparisons about 0.05 µs an element).
_FEW = 32


def fits(n2):
    """True when every squared norm of a block is in [LOW, HIGH] (False for NaN or inf).

    >>> import numpy as np
    >>> from quatarray._scale import fits
    >>> [bool(fits(np.array(n2))) for n2 in ([1.0, 4.0], [1.0, 1e-320], [np.nan], [np.inf])]
    [True, False, False, False]
    """
    lo, hi = _RANGE[n2.dtype]
    if 0 < n2.size <= _FEW:   # `_bounds`, written out (its calls cost as much as the test)
        x = n2.ravel().tolist()
        total = sum(x)
        return total == total and lo <= min(x) and max(x) <= hi   # (a NaN sum: NaN, or +inf and -inf)
    least, most = _bounds(n2, _FEW)
    return lo <= least and most <= hi


def fits_listed(n2):
    """`fits` of a block's squared norms, given as the list of them (Python floats) where they
    are a few (up to `_FEW`, where `fits` lists them anyway) and fit, for callers' further
    tests on them; otherwise True or False.

    >>> import numpy as np
    >>> from quatarray._scale import fits_listed
    >>> fits_listed(np.array([1.0, 4.0])), fits_listed(np.array([1.0, np.nan]))
    ([1.0, 4.0], False)
    """
    if n2.size > _FEW or not n2.size:
        return fits(n2)
    lo, hi = _RANGE[n2.dtype]
    x = n2.ravel().tolist()
    total = sum(x)
    if total == total and lo <= min(x) and max(x) <= hi:   # (a NaN sum: NaN, or +inf and -inf)
        return x
    return False


def at_most(a, bound):
    """True when every element of `a` is at most `bound` (False for NaN; True when empty).

    >>> import numpy as np
    >>> from quatarray._scale import at_most
    >>> at_most(np.array([1.0, 2.0]), 2.0), at_most(np.array([1.0, np.nan]), 2.0)
    (True, False)
    """
    if 0 < a.size <= _FEW_ONE:   # `largest`, written out (its calls cost as much as the test)
        x = a.ravel().tolist()
        total = sum(x)
        return total == total and max(x) <= bound
    return largest(a) <= bound


def largest(a):
    """The largest element of `a` as a Python float (NaN where `a` holds a NaN, -inf when
    empty): one reduction, or Python's max up to `_FEW` elements.

    >>> import numpy as np
    >>> from quatarray._scale import largest
    >>> largest(np.array([1.0, 3.0, 2.0]))
    3.0
    """
    if 0 < a.size <= _FEW_ONE:   # by Python's max and a sum (for NaN): a call costs as much
        x = a.ravel().tolist()
        total = sum(x)
        return max(x) if total == total else math.nan
    return _extreme(a, 1, np.maximum)


def smallest(a):
    """The smallest element of `a` as a Python float (NaN where `a` holds a NaN, inf when
    empty), as `largest`: ``smallest(np.array([1.0, 3.0]))`` is 1.0."""
    if 0 < a.size <= _FEW_ONE:
        x = a.ravel().tolist()
        total = sum(x)
        return min(x) if total == total else math.nan
    return _extreme(a, 0, np.minimum)


def _extreme(a, side, ufunc):
    """`_bounds`' item `side` (0: min, 1: max) of an empty `a` or of more than `_FEW_ONE`
    elements (the reduction by `ufunc`; `largest` and `smallest` take fewer by Python)."""
    if not a.size:
        return (math.inf, -math.inf)[side]
    return float(ufunc.reduce(a, axis=None))


#: One side of the bounds by Python up to this many elements (both sides pay up to `_FEW`;
#: where each beats NumPy's reductions: benchmarks/README.md).
_FEW_ONE = 20


def any_zero(a):
    """True when an element of `a` is zero (``not a.all()``: NaN is not zero): up to `_FEW`
    elements by a Python test on the list of them (cheaper than a NumPy reduction there).

    >>> import numpy as np
    >>> from quatarray._scale import any_zero
    >>> any_zero(np.array([1.0, -0.0])), any_zero(np.array([np.nan, 2.0]))
    (True, False)
    """
    if a.size <= _FEW:
        return 0.0 in a.ravel().tolist()
    return not a.all()


def sum_squares(q, out, start=0, rows=None):
    """``out = q[start]² + ... + q[-1]²`` for a components-first block (q is not modified).

    Squares may overflow (that is what `guard` looks for): callers run under
    ``np.errstate(over="ignore")``, once per call rather than once per block.
    `rows`: free work rows of the caller's (one per component) for a small block,
    instead of the thread's scratch (whose frame costs more than the ufuncs)."""
    comps = q[start:]
    if len(comps) == 1:
        return np.multiply(comps[0], comps[0], out=out)
    if rows is not None and out.size <= _STACK_MAX:
        return _summed(np.multiply(comps, comps, out=rows[:len(comps)]), out)
    if comps.nbytes <= _blocks.SMALL_ROWS:   # fresh rows, as the scratch would give, without its frame
        return _summed(np.multiply(comps, comps), out)
    with _blocks.scratch().frame() as work:   # no temporary allocated per component
        if out.size > _STACK_MAX:   # one work row, reused while it is in cache
            return squares(list(comps), _ops.ARRAYS, out, work.rows(1, out.shape, out.dtype)[0])
        return _summed(np.multiply(comps, comps, out=work.rows(len(comps), out.shape, out.dtype)), out)


def _summed(sq, out):
    """Small blocks: all squares `sq` made in one call (calls cost more than passes), summed
    into `out` in `squares`' order, so the bits are the same."""
    np.add(sq[0], sq[1], out)
    for k in range(2, len(sq)):   # (indexing: a fifth of iterating over the rows' views)
        np.add(out, sq[k], out)
    return out


_STACK_MAX = 4096
"""Elements per component up to which `sum_squares` squares all components in one call
(10 elements: 15 % faster; a 32768-element block: 6 % slower, the squares leaving cache)."""


def squares(comps, op, out, t):
    """``comps[0]² + comps[1]² + ...``, left to right, in `op`'s arithmetic (`_ops`), into
    `out` with the work row `t`; returned."""
    out = op.mul(comps[0], comps[0], out)
    for c in comps[1:]:
        t = op.mul(c, c, t)
        out = op.add(out, t, out)
    return out


def outside(n2):
    """Where squared norms are not in [LOW, HIGH] (NaN included): the rows to rescale.

    >>> import numpy as np
    >>> from quatarray._scale import outside
    >>> outside(np.array([1.0, 1e-320, np.inf, np.nan])).tolist()
    [False, True, True, True]
    """
    lo, hi = _RANGE[n2.dtype]
    return ~((n2 >= lo) & (n2 <= hi))


def rescale(q, only=None):
    """Multiply each quaternion of a components-first block by 2**-e, in place,
    with e the exponent of its largest |component| (so that it lies in [1/2, 1)).

    Zero and non-finite quaternions are left as they are (e = 0), and so are the
    rows where the batch-shaped mask `only` is False: what happens to a row
    then depends on that row alone, never on the rest of its block (the same
    bits for any batch around it).  Returns e (batch shape, int32).

    >>> import numpy as np
    >>> from quatarray._scale import rescale
    >>> q = np.array([[3e300], [4e300], [0.0], [0.0]])
    >>> e = rescale(q); e, np.ldexp(q[:, 0], e) == [3e300, 4e300, 0, 0]
    (array([999], dtype=int32), array([ True,  True,  True,  True]))
    """
    m = np.max(np.abs(q), axis=0)
    _, e = np.frexp(m)
    if only is not None:
        e *= only
    np.ldexp(q, -e, out=q)
    return e


def guard(q, n2, start=0, zero=False):
    """The squared norms `n2` of a block, made safe: if they do not all `fit`,
    rescale `q` in place (`rescale`) and recompute them into `n2`.

    Returns the exponents applied (None when nothing was rescaled: the
    common path).  NaN or infinite components raise
    `ValueError` (the API's policy for non-finite input), found at no cost
    on the common path; so does a zero quaternion with `zero` (True: `ZERO`, the message of
    conversions to rotations; or the message to raise).  `start` = 1 when `n2` holds the squared norms of
    the vector parts only (the whole quaternion is rescaled all the same).
    """
    if fits(n2):
        return None
    if not np.isfinite(q).all():
        raise ValueError(NONFINITE)
    e = rescale(q, outside(n2))
    sum_squares(q, n2, start)
    if zero and not (n2 if start == 0 else np.max(np.abs(q), axis=0)).all():
        raise ValueError(zero if type(zero) is str else ZERO)
    return e


def true_norm(v, out, rows=None):
    """``out = |v|`` for a components-first block `v` (a scratch copy), at its true size even
    where the squares overflow: such a block is rescaled in place by 2**-e first, and the
    norm scaled back.  Returns e (None on the common path), so that callers multiplying the
    rescaled components can undo it.  Underflowing squares are left as they are: callers
    take the norm as an angle, and their limits at 0 hold there.  Squares that overflow are
    rescaled: callers run under ``np.errstate(over="ignore")``, as for `sum_squares` (and
    `rows`: its free work rows)."""
    sum_squares(v, out, rows=rows)
    e = None
    if not at_most(out, HIGH[out.dtype]):
        e = rescale(v, ~(out <= HIGH[out.dtype]))
        sum_squares(v, out, rows=rows)
    np.sqrt(out, out=out)
    if e is not None:
        np.ldexp(out, e, out=out)
    return e


def guarded_sqnorm(q, zero=False):
    """Squared norms of a block's scratch copy `q` (in a row of the thread's
    scratch), rescaling `q` in place where they would over- or underflow
    (`guard`: with `zero`, a zero quaternion raises `ZERO`)."""
    n2 = sum_squares(q, np.empty(q.shape[1:], q.dtype) if q[0].size <= _blocks.FEW
                     else _blocks.scratch().rows(1, q.shape[1:], q.dtype)[0])
    guard(q, n2, zero=zero)
    return n2


def _bounds(a, few=_FEW):
    """(min, max) of `a` as Python floats: NaN for both where `a` holds a NaN (every
    comparison with them fails, the safe answer), (inf, -inf) when empty.  Up to `few`
    elements by Python's min, max and sum, cheaper than two reductions up to about 32
    elements (beyond, Python's cost per element decides: benchmarks/README.md)."""
    if a.size <= few:
        if not a.size:
            return math.inf, -math.inf
        x = a.ravel().tolist()
        total = sum(x)
        return (min(x), max(x)) if total == total else (math.nan, math.nan)
    return float(np.minimum.reduce(a, axis=None)), float(np.maximum.reduce(a, axis=None))


def inside(v, bound, low=None):
    """True when every element of `v` lies in [-bound, bound] (in [low, bound] if `low` is
    given; False for NaN).

    >>> import numpy as np
    >>> from quatarray._scale import inside
    >>> inside(np.array([1.0, -2.0]), 2.0), inside(np.array([1.0, np.nan]), 2.0)
    (True, False)
    """
    lo, hi = _bounds(v)
    return (-bound if low is None else low) <= lo and hi <= bound


def shrink_vectors(v, n2=None):
    """Scale the vectors of a components-first block (a scratch copy) whose largest |component|
    exceeds `BIG_VECTOR` by 2**-e in place, e the exponent of that component, so that the
    rotation formulas' intermediate sums cannot overflow; the others are left as they are
    (so each vector gives the same bits whatever the block around them).

    With `n2`, the squared norms of the quaternions the vectors are rotated by: the test is
    on the vector's largest |component| times max(|q|, 1/|q|), the size of the cross
    products vec × v and of their quotients by |q|² for a quaternion that is not unit; and
    a vector rotated by a quaternion with |q|² outside [1/4, 4] is always scaled (to
    [1/2, 1)), so that those products neither overflow nor leave the normal range below.

    Returns e (batch shape, int32, 0 where not scaled), or None when no vector is that
    large: the common path, two reductions (four with `n2`).  Multiply the result by 2**e
    (`unscale`).

    >>> import numpy as np
    >>> from quatarray._scale import shrink_vectors
    >>> v = np.array([[1e308, 1.0], [0.0, 2.0], [0.0, 3.0]])
    >>> e = shrink_vectors(v); e.tolist(), v[:, 1].tolist()
    ([1024, 0], [1.0, 2.0, 3.0])
    """
    if not v.size:
        return None
    big = BIG_VECTOR[v.dtype]
    grow = 1.0
    if n2 is not None:
        lo, hi = _bounds(n2)
        grow = math.sqrt(max(hi, 1.0 / lo if lo > 0 else math.inf, 1.0)) if hi == hi else math.nan
    vlo, vhi = _bounds(v)
    if grow <= 2.0 and vhi * grow <= big and vlo * grow >= -big:
        return None
    size = np.max(np.abs(v), axis=0)
    scale = size > big
    if n2 is not None:
        with np.errstate(over="ignore", divide="ignore"):
            f = np.sqrt(np.maximum(n2, 1.0 / n2))
        scale |= (f > 2.0) | (size * f > big)
    _, e = np.frexp(size)
    e = np.where(scale, e, 0).astype(np.int32)
    np.ldexp(v, -e, out=v)
    return e


def small_norms(v, n2):
    """Correct `n2` = |v|² in place where it lost its digits to underflow (below `LOW`), for a
    components-first block `v` (not modified), and return ``|v|`` in it: each such vector's
    norm is taken after scaling it by a power of two.  Vectors with ordinary |v|² keep their
    ``sqrt(n2)`` (the same bits whatever the block around them).

    >>> import numpy as np
    >>> from quatarray._scale import small_norms
    >>> v = np.array([[3e-200, 3.0], [4e-200, 4.0]])
    >>> small_norms(v, (v * v).sum(axis=0)).tolist()
    [5e-200, 5.0]
    """
    small = n2 < LOW[n2.dtype] if n2.size and smallest(n2) < LOW[n2.dtype] else None
    np.sqrt(n2, out=n2)
    if small is not None:
        s = v[:, small]
        _, e = np.frexp(np.max(np.abs(s), axis=0))
        np.ldexp(s, -e, out=s)
        n2[small] = np.ldexp(np.sqrt(sum_squares(s, np.empty(s.shape[1:], s.dtype))), e)
    return n2


def unscale(x, e, power=1):
    """``x * 2**(power * e)`` in place for a rescaled block (nothing when e is None)."""
    if e is not None:
        np.ldexp(x, power * e, out=x)
    return x
