"""Conversions between scalar-first quaternions and other rotation representations.

Rotation matrices, rotation vectors and modified Rodrigues parameters, both
ways, and the rotation angle behind `Rotation.magnitude` (Euler and Davenport
angles are in `_euler`; rotating vectors and inverting are `_kernels.rotate`
and `_kernels.conjugate`).  Everything works on raw ndarrays:
quaternions are ``(..., 4)`` scalar-first ``(w, x, y, z)``, any batch shape,
float32 stays float32, inputs are never modified.  A quaternion ``q`` is read
as the rotation by ``q / |q|``, so the ``as_*`` functions accept non-unit
quaternions; the ``from_*`` functions return unit quaternions.

How the work is done
--------------------
Long inputs are processed by the block engine (`_blocks.blockwise`): each
block is copied into component-major scratch (one contiguous row per
component, so that every ufunc runs on contiguous memory) and computed with
whole-row ufuncs that write into the preallocated output.  No per-element
Python, no ``(N, 4, 4)`` temporaries.  Formulas that scale whole rows (MRPs
both ways, `from_rotvec`) read and write the ``(N, 3)`` / ``(N, 4)`` rows in
place instead (`_rowwise`), each component-major view walked by one call.

Half-angle sines and cosines come from `_kernels.cos_sin`: in float64 one
tangent, ``t = tan(a / 4)``, gives ``cos(a / 2) = (1 - t)(1 + t) / (1 + t²)`` and
``sin(a / 2) = 2 t / (1 + t²)`` (one transcendental call instead of two, and
`_trig.tan`'s rational one where NumPy's float64 tangent is not a SIMD loop);
float32 uses its SIMD sin and cos.  Angles come back as one arctan of a ratio (the
rotation angle: 2 atan(sqrt(|v|² / w²)), `_half_turn`), accurate at 0 and at π, never
``arccos``.  The measured
costs behind these choices are in benchmarks/README.md.
"""

import functools
import math

import numpy as np

from . import _blocks, _kernels, _ops, _scale
from ._kernels import ANGLE_FLOOR
from ._kernels import cos_sin as _cos_sin
from ._validate import finite, float_array, quat_array

__all__ = [
    "from_quat", "as_matrix", "from_matrix", "as_rotvec", "from_rotvec",
    "as_mrp", "from_mrp", "canonical", "magnitude", "to_scalar_first", "to_scalar_last",
    "rotation_power", "POWER_MAX",
]

_POLAR_MAXITER = 60
"""Newton steps allowed for the polar factor before falling back to an SVD."""


# --- the block engine, quietly ------------------------------------------------------

def _blockwise(kernel, ins, outs, **params):
    """`_blocks.blockwise` with floating-point warnings off: the kernels handle
    zero, infinite and nan input themselves (nan out, or a status flag)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _blocks.blockwise(kernel, ins, outs, **params)


def _vec3(v, name):
    return float_array(v, name, last=3)


# --- quaternions ---------------------------------------------------------------------

def from_quat(quat, scalar_first=False, name="quat"):
    """Unit scalar-first quaternions from quaternions in either order (scipy's `from_quat`).

    Parameters
    ----------
    quat : array_like, shape (..., 4)
        ``(x, y, z, w)``, or ``(w, x, y, z)`` with ``scalar_first=True``.
    scalar_first : bool, default False
    name : str, default "quat"
        What to call `quat` in error messages.

    Returns
    -------
    ndarray, shape (..., 4)
        ``quat / |quat|``, scalar-first (a new array): `_kernels.normalize`,
        the one normalisation kernel, so the bits are `QuatArray.normalized`'s.

    Raises
    ------
    ValueError
        For a zero quaternion, NaN or infinite components.

    Examples
    --------
    >>> from quatarray._convert import from_quat
    >>> from_quat([0, 0, 3, 4])
    array([0.8, 0. , 0. , 0.6])
    """
    q = quat_array(quat, "quat")
    one, kind = _ops.floats64(q), _ops.F64
    if one is None:
        one, kind = _ops.floats32(q)
    if one is not None:   # one float64 or float32 quaternion: `_kernels.normalize`'s formula on its floats
        one = _kernels.normalize_floats(one if scalar_first else one[3:] + one[:3], kind)
        if one is not None:
            return _ops.to_array(one, q.shape, kind.dtype)
    if scalar_first:
        src = q if q.flags.c_contiguous else np.ascontiguousarray(q)
    else:
        src = to_scalar_first(q)   # a new C-contiguous array, normalised in place
    try:
        with np.errstate(over="ignore", under="ignore"):
            return _kernels.normalize(src, out=None if src is q else src)
    except ValueError:
        pass
    flat = q.reshape(-1, 4)
    finite = np.isfinite(flat).all(axis=1)
    if not finite.all():
        first = int(np.argmin(finite))
        raise ValueError(f"expected finite {name}, got nan or inf in quaternion {_index(first, q.shape[:-1])}")
    first = int(np.argmin(np.abs(flat).max(axis=1) > 0))
    raise ValueError(f"Found zero norm quaternions in `{name}`: expected non-zero quaternions, "
                     f"got a zero quaternion at index {_index(first, q.shape[:-1])}")


#: Up to this many components one `take` of the reordered components (a new C-contiguous
#: array, one call) costs least: a third of the copies' cost at 100 quaternions, the same
#: at 1000, twice at 3000 (AVX-512); above it the shifted contiguous copy (C-contiguous
#: input) or two strided copies.
_TAKE_MAX = 2048
_FIRST = np.array([3, 0, 1, 2])   # (x, y, z, w) -> (w, x, y, z)
_LAST = np.array([1, 2, 3, 0])    # (w, x, y, z) -> (x, y, z, w)


def to_scalar_first(q):
    """``(x, y, z, w)`` -> a new C-contiguous ``(w, x, y, z)`` array (see `to_scalar_last`).

    >>> import numpy as np
    >>> from quatarray._convert import to_scalar_first
    >>> to_scalar_first(np.array([1.0, 2, 3, 4]))
    array([4., 1., 2., 3.])
    """
    if q.size <= _TAKE_MAX:
        return q.take(_FIRST, axis=-1)
    out = np.empty(q.shape, q.dtype)
    if q.flags.c_contiguous:
        out.reshape(-1)[1:] = q.reshape(-1)[:-1]
    else:
        out[..., 1:] = q[..., :3]
    out[..., 0] = q[..., 3]
    return out


def to_scalar_last(q):
    """``(w, x, y, z)`` -> a new C-contiguous ``(x, y, z, w)`` array.

    For C-contiguous input, one contiguous copy shifted by one element (x, y, z land in
    place, each w slot gets the next quaternion's w) and one strided copy of the w's:
    a memcpy and N elements, where two strided copies (or fancy indexing, whose result
    is not even C-contiguous) cost several times as much.  Up to `_TAKE_MAX` components,
    where the calls are the cost, one ``take`` along the last axis.

    >>> import numpy as np
    >>> from quatarray._convert import to_scalar_last
    >>> to_scalar_last(np.array([[4.0, 1, 2, 3]]))
    array([[1., 2., 3., 4.]])
    """
    if q.size <= _TAKE_MAX:
        return q.take(_LAST, axis=-1)
    out = np.empty(q.shape, q.dtype)
    if q.flags.c_contiguous:
        out.reshape(-1)[:-1] = q.reshape(-1)[1:]
    else:
        out[..., :3] = q[..., 1:]
    out[..., 3] = q[..., 0]
    return out


def _index(flat_index, batch):
    """A flat index as a batch index tuple (for messages)."""
    return tuple(int(i) for i in np.unravel_index(flat_index, batch)) if batch else ()


# --- matrices -----------------------------------------------------------------------

_MATRIX_SHAPE = {1: (3, 3), 2: (1, 3, 3)}
"""The shape of one rotation's matrix by its quaternion's ndim: (4,) or (1, 4)."""


def _unit_matrix(w, x, y, z):
    """The nine entries of the rotation matrix of a unit q, row-major, in plain arithmetic:
    scipy's diagonal (w² ∓ z²) ± (x² ∓ y²) (exact zeros where two components are equal in
    magnitude) and the off-diagonal pairs p ∓ r.  Runs as it is on the Python floats of
    one rotation; traced once, it becomes `_UNIT_PLAN` (its operations stacked, for a few
    rotations) and `_UNIT_PROGRAM` (one ufunc call per operation, for blocks)."""
    xs, ys, zs = x + x, y + y, z + z
    ww, xx, yy, zz = w * w, x * x, y * y, z * z
    a, b = ww - zz, xx - yy
    xy, xz, yz, wx, wy, wz = x * ys, x * zs, y * zs, w * xs, w * ys, w * zs
    return [a + b, xy - wz, xz + wy,
            xy + wz, a - b, yz - wx,
            xz - wy, yz + wx, (ww + zz) - (xx + yy)]


class _Traced:
    """A value of a formula traced on symbols: a component (``op`` None, ``args`` its
    index) or an operation on two traced values."""

    __slots__ = ("op", "args")

    def __init__(self, op, *args):
        self.op, self.args = op, args

    def __add__(self, other):
        return _Traced("+", self, other)

    def __sub__(self, other):
        return _Traced("-", self, other)

    def __mul__(self, other):
        return _Traced("*", self, other)


def _signed_terms(v):
    """A traced entry as signed products ``(a, b, c)``, each ``q[a] * (c q[b])``: two terms
    (their sum) or two pairs (the sum of the pairs' sums).  ``c`` is ±1 or ±2: scaling
    by it is exact, so ``q[a] * (-c q[b])`` is exactly ``-(q[a] * (c q[b]))``, ``s + (-t)``
    is exactly ``s - t`` (IEEE subtraction is defined so), and the sum of two products in
    either order rounds alike: the terms, summed pairwise, give the formula's bits."""
    if v.op == "*":
        p, r = v.args
        if p.op is None and r.op is None:
            return (p.args[0], r.args[0], 1)
        if p.op is None and r.op == "+" and r.args[0] is r.args[1] and r.args[0].op is None:
            return (p.args[0], r.args[0].args[0], 2)
    elif v.op in "+-":
        left, right = (_signed_terms(u) for u in v.args)
        if v.op == "-":
            # -(t2 + t3) as (-t2) + (-t3): the same bits unless t2 + t3 cancels to +0 where
            # the other pair is -0; no pair of squares or of scaled products here does
            right = _negated(right)
        if type(left) is type(right):
            return [left, right]
    raise ValueError("the matrix formula must be sums of products q[a] * q[b] or q[a] * (q[b] + q[b])")


def _negated(t):
    return (t[0], t[1], -t[2]) if type(t) is tuple else [_negated(u) for u in t]


def _plan(formula):
    """`formula` (nine entries of q's rotation matrix, e.g. `_unit_matrix`) traced, and laid
    out for stacked rows: (traced entries, gather, scale).  The off-diagonal entries must be
    sums of two products and the diagonal ones sums of two such pairs.  Of the 30 products
    ``P = q.take(gather)[:30] * (q.take(gather)[30:] * scale)``, rows 0-8 hold the first
    term of each entry (the first term of its first pair on the diagonal), rows 12-20 the
    second (the first term of its second pair), and rows 24-29 the diagonal pairs' second
    terms, in the order of ``P[0:24:4]`` = rows 0, 4, 8, 12, 16, 20 (rows 9-11 and 21-23 are
    spare).  So ``P[0:24:4] += P[24:30]`` sums the pairs, and ``P[0:9] + P[12:21]`` is the
    matrix: one NumPy call per stage, each on evenly spaced rows."""
    traced = formula(*(_Traced(None, k) for k in range(4)))
    entries = [_signed_terms(e) for e in traced]
    if not all(type(e[0]) is (list if k in _DIAG else tuple) for k, e in enumerate(entries)):
        raise ValueError("the matrix formula must give two-term off-diagonal and four-term diagonal entries")
    spare = (0, 0, 1)   # a finite product in the rows no stage reads
    terms = [[e[i][0] if k in _DIAG else e[i] for k, e in enumerate(entries)] + [spare] * 3 for i in (0, 1)]
    terms = terms[0] + terms[1] + [entries[k][i][1] for i in (0, 1) for k in _DIAG]
    gather = np.array([t[0] for t in terms] + [t[1] for t in terms])
    return traced, gather, tuple(float(t[2]) for t in terms)


_DIAG = (0, 4, 8)
_UNIT_ENTRIES, *_UNIT_PLAN = _plan(_unit_matrix)


def _unit_rows(q, o):
    """The matrix entries of the unit quaternions whose components are the rows of `q`
    (4, n), as `_unit_matrix` computes them, into `o` (9, n) (any strides), by `_UNIT_PLAN`:
    five ufunc calls (a gather, two products and two sums, the last into `o`), whatever n."""
    n = q.shape[1]
    g = q.take(_UNIT_PLAN[0], axis=0)   # (60, n): the products' factors
    f, d = g[:30], g[30:]
    np.multiply(d, _unit_scale_rows(g.dtype, n), out=d)
    p = np.multiply(f, d, out=f)
    pairs = p[0:24:4]
    np.add(pairs, p[24:], out=pairs)
    np.add(p[0:9], p[12:21], out=o)


def _matrix(w, x, y, z, s, o, t):
    """The nine entries of the rotation matrix of q, row-major, into ``o`` (nine rows) with
    ``s = 2 / |q|²`` (a row) and `t` (three work rows), for any q; each entry is one ufunc
    call into its row on intermediates written with operators."""
    op = _ops.ARRAYS
    o = list(o[:9])
    xs, ys, zs = [op.mul(c, s, r) for c, r in zip((x, y, z), t[:3])]
    xx, yy, zz = x * xs, y * ys, z * zs
    for k, p, r in ((0, yy, zz), (4, xx, zz), (8, xx, yy)):
        o[k] = op.sub(1.0, p + r, o[k])
    # off-diagonal pairs (i, j) = p -/+ r, each output row written once
    for i, j, p1, p2, r1, r2 in ((1, 3, x, ys, w, zs), (6, 2, x, zs, w, ys), (5, 7, y, zs, w, xs)):
        a, b = p1 * p2, r1 * r2
        o[i] = op.sub(a, b, o[i])
        o[j] = op.add(a, b, o[j])
    return o


@functools.lru_cache(maxsize=8)
def _unit_scale_rows(dtype, n):
    """`_UNIT_PLAN`'s scale factors repeated along rows of n, read-only: the scaling is
    then one contiguous loop rather than a broadcast one (a third of its cost at n = 10),
    for the few batch sizes a program uses again and again (at most 8 kept, 1 MiB)."""
    rows = np.repeat(np.array(_UNIT_PLAN[1], dtype)[:, None], n, axis=1)
    rows.flags.writeable = False
    return rows


def _program(entries):
    """The traced formula `entries` as straight-line steps ``(ufunc, a, b, dst, row, free)``
    over numbered values (0-3 the components): ``dst = ufunc(a, b)``, into output `row`
    for an entry (else a temporary), after which the values in `free` are no longer
    needed.  In the formula's own order; intermediates it shares are computed once."""
    order, number = [], {}

    def visit(v):
        if id(v) in number:
            return
        if v.op is None:   # a component: its index
            number[id(v)] = v.args[0]
            return
        for u in v.args:
            visit(u)
        number[id(v)] = 4 + len(order)
        order.append(v)

    for e in entries:
        visit(e)
    last = {}
    for k, v in enumerate(order):
        for u in v.args:
            last[number[id(u)]] = k
    rows = {id(e): k for k, e in enumerate(entries)}
    return [(_UFUNCS[v.op], number[id(v.args[0])], number[id(v.args[1])], 4 + k, rows.get(id(v)),
             tuple(i for i, j in last.items() if j == k and i >= 4))
            for k, v in enumerate(order)]


def _traced_rows(program, q, o):
    """`_program`'s steps on the component rows `q` (4, ...), each entry into its row of
    `o`; a temporary is dropped after its last use, so that a long block's temporaries are
    few and reused rather than fresh pages."""
    values = [*q[:4], *[None] * len(program)]
    for f, a, b, dst, row, free in program:
        values[dst] = f(values[a], values[b]) if row is None else f(values[a], values[b], out=o[row])
        for i in free:
            values[i] = None


_UFUNCS = {"+": np.add, "-": np.subtract, "*": np.multiply}
_UNIT_PROGRAM = _program(_UNIT_ENTRIES)


def _k_as_matrix(q, o, unit=False):
    if unit:
        _traced_rows(_UNIT_PROGRAM, q, o)
        return
    with _blocks.scratch().frame() as work:
        s = np.divide(2.0, _scale.guarded_sqnorm(q, zero=True))
        _matrix(*q, s, o, work.rows(3, q.shape[1:], o.dtype))


def as_matrix(q, unit=False):
    """Rotation matrices of quaternions (the rotation by q/|q|).

    Parameters
    ----------
    q : ndarray, shape (..., 4)
        Scalar-first quaternions, not necessarily unit.
    unit : bool, default False
        The caller knows `q` is an ndarray of finite unit quaternions
        (`Rotation`'s storage): |q|² is taken as 1, saving the squared norms
        and their range check, and the diagonal is scipy's w² ± x² ± y² ± z²
        (exact zeros where two components are equal in magnitude, as scipy's).
        Within a few ulp of the general path for unit q.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ``M @ v`` rotates the column vector ``v``.  A zero quaternion raises `ValueError`.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._convert import as_matrix
    >>> q = np.array([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])  # 90° about z
    >>> np.round(as_matrix(q), 12) + 0.0
    array([[ 0., -1.,  0.],
           [ 1.,  0.,  0.],
           [ 0.,  0.,  1.]])
    """
    if unit and q.size == 4 and q.dtype is _F64 and q.ndim <= 2:
        # one float64 rotation of a Rotation's storage (an ndarray), (4,) or (1, 4): the same
        # formula on its floats (`_ops.floats64`'s test, written out: its call and a splat
        # cost 0.1 µs of scipy's 1.4); np.fromiter and a reshape make the cheapest (3, 3)
        # array of nine floats, 0.5 µs
        ndim = q.ndim
        w, x, y, z = q.tolist() if ndim == 1 else q.tolist()[0]
        return np.fromiter(_unit_matrix(w, x, y, z), _F64, 9).reshape(_MATRIX_SHAPE[ndim])
    if unit and q.size == 4 and q.dtype is _F32 and q.ndim <= 2:   # one float32 rotation: on float32 scalars
        c = _ops.floats32(q)[0]
        if c is not None:
            return np.fromiter(_unit_matrix(*c), _F32, 9).reshape(_MATRIX_SHAPE[q.ndim])
    if unit and q.ndim == 2 and 0 < len(q) <= _blocks.VIEWS_MAX:
        # a Rotation's few (up to where the block engine's copies start to pay, at about the
        # same size as for its other kernels): the plan's calls on the storage, read in place
        out = np.empty((len(q), 3, 3), q.dtype)
        _unit_rows(q.T, out.reshape(-1, 9).T)
        return out
    q = quat_array(q, "quat")
    out = np.empty(q.shape[:-1] + (3, 3), q.dtype)
    flat = q.reshape(-1, 4)
    if unit and 0 < len(flat) <= _blocks.VIEWS_MAX:
        _unit_rows(flat.T, out.reshape(-1, 9).T)
        return out
    _blockwise(_k_as_matrix, [flat], [out.reshape(-1, 9)], unit=unit)
    return out


def _shepperd_k(mat, op, k):
    """tr and the upper triangle of Shepperd's symmetric 4x4 matrix K of a rotation matrix
    `mat` (nine entries, row-major), in `op`'s arithmetic (`_ops`): K's diagonal is
    1 ± m00 ± m11 ± m22 and every column is proportional to the quaternion.  The entries
    (k00, k01, k02, k03, k11, k12, k13, k22, k23, k33) go into the ten rows `k` (or
    `_ops.NONE`) and are returned with tr."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = mat
    tr = op.add(op.add(m00, m11, None), m22, None)
    e = [op.add(1.0, tr, k[0]), op.sub(m21, m12, k[1]), op.sub(m02, m20, k[2]), op.sub(m10, m01, k[3])]
    for mii, row, rest in ((m00, 4, ((m10, m01, 5), (m20, m02, 6))), (m11, 7, ((m21, m12, 8),)), (m22, 9, ())):
        d = op.sub(1.0, tr, k[row])
        e.append(op.add(d, op.mul(2, mii, None), d))
        e += [op.add(a, b, k[r]) for a, b, r in rest]
    return tr, e


#: Where K[i][j] (i, j = column, component) sits in `_shepperd_k`'s upper triangle.
_K_INDEX = [[0, 1, 2, 3], [1, 4, 5, 6], [2, 5, 7, 8], [3, 6, 8, 9]]


def _shepperd(mat, q):
    """Quaternions (4, m) of orthogonal matrices (9, m) by Shepperd's method.

    The column of K (`_shepperd_k`) with the largest diagonal entry is the best
    conditioned.  Ties pick x, then y, z, w, as scipy does (argmax over m00, m11,
    m22, trace).
    """
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = mat
    m = m00.shape[0]
    k = np.empty((4, 4, m), mat.dtype)  # k[column, component]
    tr, _ = _shepperd_k(mat, _ops.ARRAYS, [k[i, j] for i in range(4) for j in range(i, 4)])
    for i in range(4):  # symmetric: fill the lower triangle
        for j in range(i):
            k[i, j] = k[j, i]
    choice = _shepperd_column(m00, m11, m22, tr, _ops.ARRAYS)
    index = choice * (4 * m) + (np.arange(4)[:, None] * m + np.arange(m))
    np.take(k.reshape(-1), index, out=q)
    _unit(q, _ops.ARRAYS, _ops.STACKS, q)


def _shepperd_column(m00, m11, m22, tr, op):
    """The column of K (`_shepperd_k`) to take, written once, in `op`'s arithmetic (`_ops`;
    ARRAYS: integer rows): x (1) if m00 is the largest of (m00, m11, m22, tr), then y (2),
    z (3), w (0); the first wins ties."""
    best, choice = m00, 1
    for col, value in ((2, m11), (3, m22), (0, tr)):
        choice = op.where(value > best, col, choice)
        best = op.max(best, value, None)
    return choice


def _unit(q, op, stack, out):
    """``q / |q|`` (four rows or floats), written once: |q|² summed in component order
    (`_scale.squares`), each component divided by its square root (into `out`)."""
    n = op.sqrt(_scale.squares(q, op, None, None), None)
    return stack.div(q, n, out)


def det3(mat):
    """Determinants of 3x3 matrices given as their nine entries, row-major (rows of a block
    or Python floats), expanded along the first row, written with operators.

    >>> from quatarray._convert import det3
    >>> det3([2.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 4.0])
    24.0
    """
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = mat
    return (m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20)
            + m02 * (m10 * m21 - m11 * m20))


def _orthogonality(mat, op):
    """(det, worst |row·row - 1|, worst |row·row'|) of rotation matrices `mat` (nine entries,
    row-major), written with operators and `op`'s abs and max (`_ops`): scipy's test
    ``isclose(M Mᵀ, I)`` entry by entry, on a block's rows or one matrix's floats."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = mat
    det = det3(mat)
    r0, r1, r2 = (m00, m01, m02), (m10, m11, m12), (m20, m21, m22)
    diag = [op.abs(a[0] * a[0] + a[1] * a[1] + a[2] * a[2] - 1.0, None) for a in (r0, r1, r2)]
    off = [op.abs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2], None) for a, b in ((r0, r1), (r0, r2), (r1, r2))]
    return (det, op.max(op.max(diag[0], diag[1], None), diag[2], None),
            op.max(op.max(off[0], off[1], None), off[2], None))


def _k_from_matrix(mat, q, status, tol_diag, tol_off):
    _shepperd(mat, q)
    det, worst_diag, worst_off = _orthogonality(mat, _ops.ARRAYS)
    orthogonal = (worst_diag <= tol_diag) & (worst_off <= tol_off)
    np.copyto(status[0], 1)
    np.copyto(status[0], 0, where=orthogonal)
    np.copyto(status[0], 2, where=~((det > 0) & (det < np.inf)))


def _from_matrix_floats(m, tol_diag, tol_off, kind):
    """`_k_from_matrix` on the nine floats of one rotation matrix (of `kind`, an `_ops.Kind`),
    where it finds it orthogonal within the tolerances with det > 0 (status 0); else None
    (the block path: projection, rescaling, errors)."""
    det, worst_diag, worst_off = _orthogonality(m, kind.op)
    if not (worst_diag <= tol_diag and worst_off <= tol_off and 0 < det < math.inf):
        return None
    tr, e = _shepperd_k(m, kind.op, _ops.NONE)
    q = [e[i] for i in _K_INDEX[_shepperd_column(m[0], m[4], m[8], tr, kind.op)]]
    return _unit(q, kind.op, _ops.FLOAT_STACKS, None)


def _k_shepperd(mat, q):
    _shepperd(mat, q)


def _k_polar(mat, out, bad, tol, maxiter):
    """Orthogonal polar factor of matrices with det > 0 (9, m) by scaled Newton.

    X ← (γ X + X⁻ᵀ / γ) / 2 with γ = sqrt(|X⁻¹|_F / |X|_F) converges
    quadratically to U Vᵀ (the nearest rotation, scipy's SVD answer).
    X⁻ᵀ = cof(X) / det(X), rows of cof(X) being cross products of rows of X.
    """
    x = mat.copy()
    new = np.empty_like(x)
    # each matrix stops at its own convergence, and every sum runs in one fixed order (no
    # einsum, whose order may follow the strides): a matrix's bits never depend on its block
    active = np.ones(x.shape[1:], bool)
    last = np.full(x.shape[1:], np.inf, x.dtype)
    for _ in range(maxiter):
        r0, r1, r2 = x[0:3], x[3:6], x[6:9]
        cof = np.concatenate([np.cross(r1, r2, axis=0), np.cross(r2, r0, axis=0),
                              np.cross(r0, r1, axis=0)])
        det = r0[0] * cof[0] + r0[1] * cof[1] + r0[2] * cof[2]
        cof2 = _scale.squares(cof, _ops.ARRAYS, None, None)
        x2 = _scale.squares(x, _ops.ARRAYS, None, None)
        gamma = np.sqrt(np.sqrt(cof2 / x2) / np.abs(det))
        np.multiply(x, 0.5 * gamma, out=new)
        new += cof * (0.5 / (gamma * det))
        delta = np.abs(new - x).max(axis=0)
        np.copyto(x, new, where=active)
        np.copyto(last, delta, where=active)
        active &= delta > tol
        if not active.any():
            break
    np.copyto(out, x)
    np.copyto(bad[0], ~(last <= np.sqrt(tol)))


def _svd_polar(mat):
    """Fallback nearest rotation U Vᵀ for (k, 3, 3) matrices (very rarely used)."""
    u, _, vt = np.linalg.svd(mat)
    return u @ vt


def _rescaled_matrices(flat, qflat, status, tol_off):
    """Try again, scaled by a power of two near their largest entry, the finite
    matrices whose determinant over- or underflowed (``1e103 * I`` is the
    identity, as in scipy); updates `qflat` and `status` in place and returns
    the matrices with those rows scaled (a copy; `flat` itself is not modified)."""
    redo = np.flatnonzero(status == 2)
    sub = flat[redo]
    ok = np.isfinite(sub).all(axis=1) & (sub != 0).any(axis=1)
    redo, sub = redo[ok], sub[ok]
    if not redo.size:
        return flat
    _, e = np.frexp(np.abs(sub).max(axis=1))
    sub = np.ldexp(sub, -e[:, None])
    qsub = np.empty((len(sub), 4), flat.dtype)
    ssub = np.empty((len(sub), 1), np.int8)
    _blockwise(_k_from_matrix, [sub], [qsub, ssub], tol_diag=1e-5 + tol_off, tol_off=tol_off)
    qflat[redo] = qsub
    status[redo] = ssub[:, 0]
    flat = flat.copy()
    flat[redo] = sub
    return flat


def from_matrix(matrix, assume_valid=False):
    """Quaternions of rotation matrices, as scipy's ``Rotation.from_matrix``.

    Parameters
    ----------
    matrix : array_like, shape (..., 3, 3)
        Rotation matrices.  A matrix that is not orthogonal is replaced by the
        nearest rotation matrix (its orthogonal polar factor, the SVD answer
        ``U Vᵀ`` that scipy computes), as in scipy: scipy's test
        ``isclose(M Mᵀ, I, atol=1e-12)`` decides which matrices are projected
        (for float32 input the tolerance is ``64 eps``).
    assume_valid : bool, default False
        Skip the determinant and orthogonality checks (faster; the matrices
        must then be rotations).

    Returns
    -------
    ndarray, shape (..., 4)
        Unit scalar-first quaternions, float32 for float32 input.

    Raises
    ------
    ValueError
        For a matrix with determinant ≤ 0 (not a rotation, nor close to one),
        or with NaN or infinite entries, or of the wrong shape.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._convert import from_matrix
    >>> np.round(from_matrix([[0, -1, 0], [1, 0, 0], [0, 0, 1]]), 6)
    array([0.707107, 0.      , 0.      , 0.707107])
    >>> np.round(from_matrix(2 * np.eye(3)), 12)  # projected to the nearest rotation
    array([1., 0., 0., 0.])
    """
    m = float_array(matrix, "matrix")
    if m.ndim < 2 or m.shape[-2:] != (3, 3):
        raise ValueError(f"expected matrix of shape (..., 3, 3), got {m.shape}")
    eps = np.finfo(m.dtype).eps
    tol_off = 1e-12 if m.dtype == np.float64 else 64 * eps
    batch = m.shape[:-2]
    flat = m.reshape(-1, 9)
    n = flat.shape[0]
    one, kind = (None, None) if assume_valid else (_ops.floats64(flat, 9), _ops.F64)
    if one is None and not assume_valid and flat.size == 9 and flat.dtype is _F32:
        # (a float32 entry of magnitude 2 or more fails the orthogonality test anyway: then the
        # block path, without products of three entries that might overflow and warn)
        one, kind = _ops.floats32(flat, 9) if all(-2.0 < v < 2.0 for v in flat.ravel().tolist()) else (None, None)
    if one is not None and all(map(math.isfinite, one)):   # one matrix: the same formulas on its floats
        q = _from_matrix_floats(one, 1e-5 + tol_off, tol_off, kind)
        if q is not None:
            return _ops.to_array(q, batch + (4,), kind.dtype)
    out = np.empty(batch + (4,), m.dtype)
    qflat = out.reshape(-1, 4)
    if assume_valid:
        _blockwise(_k_shepperd, [flat], [qflat])
        return out
    status = np.empty((n, 1), np.int8)
    _blockwise(_k_from_matrix, [flat], [qflat, status], tol_diag=1e-5 + tol_off, tol_off=tol_off)
    status = status[:, 0]
    if n and status.max() == 2:
        given, flat = flat, _rescaled_matrices(flat, qflat, status, tol_off)
    if n and status.max() == 2:
        first = int(np.argmax(status == 2))
        where = _index(first, batch)
        bad = given[first].reshape(3, 3)
        if not np.isfinite(bad).all():
            raise ValueError(f"expected finite values in matrix, got nan or inf in matrix {where}")
        with np.errstate(over="ignore", under="ignore"):
            det = float(np.linalg.det(bad.astype(np.float64)))
        raise ValueError(
            "Non-positive determinant (left-handed or null coordinate frame) in rotation "
            f"matrix {where}: expected det > 0, got det = {det:.6g} for\n{bad}")
    fix = np.flatnonzero(status == 1)
    if fix.size:
        sub = flat[fix]
        ortho = np.empty_like(sub)
        bad = np.empty((fix.size, 1), bool)
        _blockwise(_k_polar, [sub], [ortho, bad], tol=16 * eps, maxiter=_POLAR_MAXITER)
        bad = bad[:, 0]
        if bad.any():
            ortho[bad] = _svd_polar(sub[bad].reshape(-1, 3, 3)).reshape(-1, 9)
        qsub = np.empty((fix.size, 4), m.dtype)
        _blockwise(_k_shepperd, [ortho], [qsub])
        qflat[fix] = qsub
    return out


# --- rotation vectors, angles, MRPs -----------------------------------------------------

def _flip_mask(w, x, y, z):
    """True where q is not canonical: w < 0, or w == 0 and the first non-zero of x, y, z < 0
    (arrays, or the floats of one quaternion: a bool)."""
    flip = w < 0
    zero = w == 0
    if zero if isinstance(zero, bool) else zero.any():
        later = (x < 0) | ((x == 0) & ((y < 0) | ((y == 0) & (z < 0))))
        flip |= zero & later
    return flip


def _half_turn(q, unit=False):
    """(t, exact) for the rotation angle θ of quaternions `q` (four component rows (4, *s):
    views of `Rotation` storage, only read, with `unit`; else a block's scratch copy, rescaled
    in place first where |q|² would over- or underflow): ``t[0] = tan(θ/2) = sqrt(|v|² / w²)``
    (`_tan_half`) and ``t[1] = |v|²`` (`_squares`), two contiguous rows of one array in a
    block, a list of two rows for a few.  `exact`: some row has w² or |v|² below
    `_scale.LOW` (w = 0, or |v|² lost to underflow), which `_tangent_rows` and the kernels
    then handle; only then is w² floored at the dtype's smallest normal number (a unit q
    with w = 0 gives a huge finite ratio, no division by zero).  The common path pays one
    range test of the two rows, by Python's min on up to 32 rotations (a NumPy reduction
    costs more there).

    One multiply squares the four components (their layout kept: contiguous for a block,
    one flat pass for a Rotation's (n, 4) storage)."""
    dtype = q.dtype
    if q.size > 4 * _blocks.FEW:   # a block: scratch rows (the squares in q's layout)
        rows = _blocks.scratch().rows
        sq = rows(q.shape[1], (4,), dtype).T if q.ndim == 2 and q.flags.f_contiguous else rows(4, q.shape[1:], dtype)
        t = rows(2, q.shape[1:], dtype)
        t0, v2 = t[0], t[1]   # rows (indexing: a fifth of unpacking)
    else:   # a few: rows the ufuncs allocate (a fifth cheaper than views of one buffer)
        t = t0 = sq = v2 = None
    w2, v2 = _squares(q, _ops.ARRAYS, _ops.ARRAYS, sq, v2)
    if not unit:   # the range guard on |q|² = w² + |v|²: extreme magnitudes are rescaled
        n2 = np.add(w2, v2, out=t0)
        if not _scale.fits(n2):
            _scale.guard(q, n2, zero=True)
            w2, v2 = _squares(q, _ops.ARRAYS, _ops.ARRAYS, sq, v2)
    low = _LOW[dtype]
    if v2.size <= 32 and v2.ndim == 1:
        exact = min(w2.tolist() + v2.tolist()) < low
    else:   # (two passes: a floor with a 0-d operand runs NumPy's scalar loop, 1.4 ns a row)
        exact = float(np.minimum.reduce(np.minimum(w2, v2, out=t0), axis=None)) < low
    if exact:
        w2 = np.maximum(w2, _ops.const(_TINY[dtype], dtype), out=t0)
    t0 = _tan_half(w2, v2, _ops.ARRAYS, t0)
    return (t if t is not None else [t0, v2]), exact


def _squares(q, op, stack, sq, v2):
    """(w², |v|²) of quaternions `q` (four rows, or the four floats of one), written once, in
    `op`'s arithmetic (`_ops`): the four squares in one call of `stack` (`_ops.ARRAYS` on
    the rows (4, *s), into `sq` or None; element by element on floats), then
    ``|v|² = (x² + y²) + z²`` (into the row `v2`)."""
    sq = stack.mul(q, q, sq)
    v2 = op.add(sq[1], sq[2], v2)
    return sq[0], op.add(v2, sq[3], v2)


def _tan_half(w2, v2, op, out):
    """``tan(θ/2) = sqrt(|v|² / w²)`` from `_squares`, written once, into the row `out`."""
    t = op.div(v2, w2, out)
    return op.sqrt(t, t)


_LOW = _scale.LOW


_TINY = {d: float(np.finfo(d).tiny) for d in (np.dtype(np.float32), np.dtype(np.float64))}


def _tangent_rows(q, t, exact):
    """`_half_turn`'s t as ``[tan(θ/2), |v|]``, where no row is `exact`; else also correcting
    the rows whose |v|² underflowed: their |v| from the vector scaled by a power of two
    (`_scale.small_norms`), tan(θ/2) = |v| / |w| (w ≠ 0 there: |q|² is in range)."""
    small = t[1] < _scale.LOW[q.dtype] if exact else None   # |v|² underflowed
    np.sqrt(t[1], t[1])
    if exact and small.any():
        tan_half, nv = t
        v = q[1:, small]
        nv[small] = _scale.small_norms(v, _scale.sum_squares(v, np.empty(v.shape[1:], v.dtype)))
        tan_half[small] = nv[small] / np.abs(q[0, small])
    return t


def _one_rotation(q):
    """The four floats of one float64 or float32 rotation `q` ((4,) or (1, 4)) and their
    `_ops.Kind` (`_ops.floats64`'s test written out: a tenth of its call), or (None, None)."""
    if q.size == 4 and q.dtype is _F64 and q.ndim <= 2:
        return (q.tolist() if q.ndim == 1 else q.tolist()[0]), _ops.F64
    return _ops.floats32(q)


def _half_turn_floats(consumer, nargs):
    """``consumer(op, stack, w, x, y, z, w², |v|², *extra)`` (`nargs` extra arguments) after
    `_half_turn`'s `_squares` and its range tests, on one rotation's floats, compiled, by
    `_ops.Kind`: each function returns None where the block kernel would rescale or find a
    row `exact` (its own path), or, in float32, where |v|² / w² overflows (float32 scalars
    would warn; the kernel's rows take inf there).  One call: the tests are `op.guard`s."""
    def make(kind):
        low, high = _scale.BOUNDS[kind]

        def formula(op, stack, w, x, y, z, *extra):
            w2, v2 = _squares([w, x, y, z], op, stack, None, None)
            op.guard("{2} <= {0} and {2} <= {1} and {0} + {1} <= {3}", w2, v2, low, high)
            if kind is _ops.F32:   # (Python floats: float32 scalars would warn of the product's overflow)
                op.guard("float({1}) < float({0}) * {2}", w2, v2, 2.0 ** 127)
            return consumer(op, stack, w, x, y, z, w2, v2, *extra)
        return _ops.compiled(formula, 4 + nargs).kinds[kind]
    return _ops.by_kind(make)


_F64, _F32 = np.dtype(np.float64), np.dtype(np.float32)


def _rotvec(w, vec, tan_half, nv, factor, op, stack, o, rows):
    """The rotation vector ``v · factor · atan(tan(θ/2)) / |v|``, signed as w (canonical: -v
    for w < 0), of q with vector part `vec` (x, y, z), |v| = `nv` > 0 and w ≠ 0, in `op`'s
    arithmetic (`_ops`, `stack` its stacked form: the three products are one call), into
    ``o`` (three rows) with the work row `rows[0]`; returned as a list (floats) or `o`."""
    half = op.arctan(tan_half, rows[0])
    scale = op.div(half, nv, half)
    scale = op.copysign(scale, w, scale)
    scale = op.mul(scale, factor, scale)
    return stack.scale(vec, scale, o)


def _signed_tangents(q, unit):
    """`_half_turn` and `_tangent_rows` of the rows `q` for the formulas that sign the half
    angle as w (`_rotvec`, `_powered`): (w, t) with ``t = [tan(θ/2), |v|]``.  Where a row is
    `exact`, w is ±1 by the canonical sign (w = 0: from x, y, z) and |v| is floored at the
    smallest subnormal (|v| = 0: 0 / tiny, the formulas' limits, the zero vector and the
    identity)."""
    t, exact = _half_turn(q, unit)
    _tangent_rows(q, t, exact)
    w = q[0]
    if exact:
        w = np.where(_flip_mask(*q), q.dtype.type(-1), q.dtype.type(1))
        np.maximum(t[1], _DENORM_MIN[q.dtype], out=t[1])
    return w, t


def _k_as_rotvec(q, o, factor, unit=False):
    w, t = _signed_tangents(q, unit)
    _rotvec(w, q[1:4], t[0], t[1], _ops.const(factor, q.dtype), _ops.ARRAYS, _ops.STACKS, o, t)


_DENORM_MIN = {d: np.finfo(d).smallest_subnormal for d in _TINY}


def _blockwise_unit(kernel, q, out, unit, **params):
    """Run a conversion kernel on quaternions `q` (N, 4) into `out` (N, k).  `unit`: they are
    finite unit quaternions (`Rotation`'s storage), which the kernel then only reads and
    which cannot overflow, divide by zero or give NaN: no errstate, and views of them up to
    one block (`_blocks.on_views`)."""
    if unit:
        if 0 < len(q) <= _blocks.VIEWS_MAX:   # a few: the kernel at once on views of them (the
            return kernel(q.T, out.T, unit=True, **params)   # engine's setup costs a ufunc call's)
        return _blocks.on_views(kernel, q, out, unit=True, **params)
    return _blockwise(kernel, [q], [out], **params)


def as_rotvec(q, degrees=False, unit=False):
    """Rotation vectors (axis × angle, angle in [0, π]) of quaternions.

    Accurate for every angle: the angle is ``2 atan2(|v|, |w|)`` and the
    vector ``v · angle / |v|``, with no cancellation near 0 and no ``arccos``
    near π.  At exactly π the sign follows scipy's canonical quaternion.

    Parameters
    ----------
    q : ndarray, shape (..., 4)
        Scalar-first quaternions, not necessarily unit.
    degrees : bool, default False
    unit : bool, default False
        The caller knows every q is a finite unit quaternion (`Rotation`'s
        storage): the range check of |q|² is skipped (the same bits).

    Returns
    -------
    ndarray, shape (..., 3)

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._convert import as_rotvec
    >>> q = np.array([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])
    >>> as_rotvec(q, degrees=True)
    array([ 0.,  0., 90.])
    """
    if not unit:   # (unit: Rotation's own storage, a float array of quaternions)
        q = quat_array(q, "quat")
    c, kind = _one_rotation(q)
    v = None
    if c is not None:
        w, x, y, z = c   # (unpacked: a fifth of splatting with the factor)
        v = _ROTVEC_FLOATS[kind](w, x, y, z, _ROTVEC_FACTOR[True] if degrees else _ROTVEC_FACTOR[False])
    if v is not None:   # one float64 or float32 rotation: the same formula on its floats
        if q.ndim == 1:
            return np.array(v)
        # q is (1, 4): `_ops.to_array`'s batch of one, without its call
        out = np.empty((1, 3)) if kind is _ops.F64 else np.empty((1, 3), _F32)
        out[0, 0], out[0, 1], out[0, 2] = v
        return out
    out = np.empty(q.shape[:-1] + (3,), q.dtype)
    _blockwise_unit(_k_as_rotvec, q if q.ndim == 2 else q.reshape(-1, 4), out if q.ndim == 2 else out.reshape(-1, 3),
                    unit, factor=_ROTVEC_FACTOR[bool(degrees)])
    return out


_ROTVEC_FACTOR = {False: 2.0, True: 2.0 * (180.0 / np.pi)}
"""Rotation vector over half-angle times unit axis, radians and degrees."""

_ROTVEC_FLOATS = _half_turn_floats(
    lambda op, stack, w, x, y, z, w2, v2, factor: _rotvec(w, [x, y, z], _tan_half(w2, v2, op, None),
                                                           op.sqrt(v2, None), factor, op, stack, None, _ops.NONE), 1)
"""`_half_turn_floats` of `_tan_half` and `_rotvec` on one rotation's floats ``(w, x, y, z,
factor)``, by `_ops.Kind`."""


# --- powers of rotations ------------------------------------------------------------------

def _powered(w, tan_half, nv, vec, n, op, stack, o, rows):
    """The unit quaternion of a rotation's power ``r ** n``: r's rotation vector (its half
    angle θ/2 = atan(tan(θ/2)) in [0, π/2] signed as w, the canonical one's sign, about
    v/|v|) times `n`, as ``(cos(n θ/2), sin(n θ/2) v/|v|)``, for r of vector part `vec`
    (x, y, z) with |v| = `nv` > 0.  In `op`'s arithmetic (`_ops`, `stack` its stacked form),
    into ``o`` (four rows) with the work row `rows[0]` (which `tan_half` may be); returned
    as a list.  sin and cos, not `_kernels.cos_sin`'s one tangent: two calls against its
    eleven on a few rotations, cos(n θ/2) keeps its relative accuracy near a quarter turn,
    and NumPy's loops give a Python float the array loop's bits on every CPU."""
    half = op.arctan(tan_half, rows[0])
    half = op.copysign(half, w, half)
    a = op.mul(half, n, half)
    c, s = op.cos(a, o[0]), op.sin(a, a)
    s = op.div(s, nv, s)   # sin(n θ/2) / |v|, with v itself the axis
    return [c, *stack.scale(vec, s, o[1:4])]


_POWERED_FLOATS = _half_turn_floats(
    lambda op, stack, w, x, y, z, w2, v2, n: _powered(w, _tan_half(w2, v2, op, None), op.sqrt(v2, None), [x, y, z],
                                                      n, op, stack, _ops.NONE, _ops.NONE), 1)
"""`_half_turn_floats` of `_tan_half` and `_powered` on one rotation's floats ``(w, x, y, z,
n)``, by `_ops.Kind`."""


def _k_power(q, o, n, unit=False):
    w, t = _signed_tangents(q, unit)
    _powered(w, t[0], t[1], q[1:4], n, _ops.ARRAYS, _ops.STACKS, o, t)


def _k_power_each(q, n, o, unit=False):
    """`_k_power` with one exponent per rotation (the block's view of them)."""
    _k_power(q, o, n, unit)


#: The largest |n| for which n θ/2 (θ/2 <= π/2) stays finite, by dtype.
POWER_MAX = {d: float(np.finfo(d).max) / (0.5 * np.pi) * (1 - 1e-6) for d in _TINY}


def rotation_power(q, n, unit=False):
    """Unit quaternions of the rotations `q` raised to the real power `n` (scipy's ``r ** n``).

    The rotation about the same axis by `n` times the angle: scipy's
    ``from_rotvec(n * as_rotvec(q))`` as one formula, ``(cos(n θ/2), sin(n θ/2) v/|v|)``
    with θ/2 = atan2(|v|, |w|) signed as w (the canonical rotation vector's
    sign, w = 0 included), whose limit at |v| = 0 is the identity.

    Parameters
    ----------
    q : ndarray, shape (..., 4)
        Scalar-first quaternions, not necessarily unit.
    n : float or ndarray
        The exponent, finite with ``|n| <= POWER_MAX[q.dtype]``: a number, or an array of
        q's dtype that broadcasts with the batch shape (one exponent per rotation).  A larger
        exponent raises a `ValueError`.
    unit : bool, default False
        The caller knows every q is a finite unit quaternion (`Rotation`'s storage).

    Returns
    -------
    ndarray, shape (..., 4)
        Unit quaternions; w = cos(n θ/2) may be negative, as scipy's.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._convert import rotation_power
    >>> q = np.array([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])
    >>> np.round(rotation_power(q, 0.5), 6)
    array([0.92388 , 0.      , 0.      , 0.382683])
    """
    if not unit:
        q = quat_array(q, "quat")
    top = POWER_MAX[q.dtype]   # n θ/2 would overflow beyond it: no angle left to reduce
    if type(n) is not np.ndarray or n.ndim == 0:
        n = float(n)
        if abs(n) > top:
            raise ValueError(f"expected an exponent n of magnitude at most {top:.3g}, got {n}")
        c, kind = _one_rotation(q)
        quat = None if c is None else _POWERED_FLOATS[kind](*c, n)
        if quat is not None:   # one float64 or float32 rotation: the same formula on its floats
            return _ops.to_array(quat, q.shape, kind.dtype)
        out = np.empty(q.shape, q.dtype)
        _blockwise_unit(_k_power, _rows(q, 4), _rows(out, 4), unit, n=np.array(n, q.dtype))
        return out
    if n.size and np.abs(n).max() > top:
        raise ValueError(f"expected exponents n of magnitude at most {top:.3g}, got {np.abs(n).max():.3g}")
    batch = np.broadcast_shapes(q.shape[:-1], n.shape)
    q = np.broadcast_to(q, batch + (4,)).reshape(-1, 4)
    n = np.broadcast_to(n.astype(q.dtype, copy=False), batch).reshape(-1)
    out = np.empty(q.shape, q.dtype)
    if unit:
        _blocks.blockwise(_k_power_each, [q], [out], views=[n], read_only=True, unit=True)
    else:
        _blockwise(_k_power_each, [q], [out], views=[n])
    return out.reshape(batch + (4,))


def _rows(a, k):
    """`a` (..., k) as (n, k) rows (a 2-D array as it is: a reshape costs a tenth of a small call)."""
    return a if a.ndim == 2 else a.reshape(-1, k)


def _rowwise(kernel, a, o, k, **params):
    """Run ``kernel(a_block, o_block, rows, **params)`` over blocks of the rows of `a` (n, i)
    into those of `o` (n, j), both read and written in place in their row layout (no
    component-major copies: for formulas that scale whole rows, whose component-major
    views are iterated in C order by one call), with `k` work rows (k, block length):
    fresh ones for a few rows, the thread's scratch for long blocks, which run on the
    block engine's threads."""
    n = len(a)
    if n <= _blocks.FEW:
        kernel(a, o, np.empty((k, n), a.dtype), **params)
        return
    size = _blocks.block_size(a.dtype)

    def block(idx):
        b = a[idx]
        kernel(b, o[idx], _blocks.scratch().rows(k, (len(b),), a.dtype), **params)

    _blocks.run(block, _blocks.split((n,), size), n)


def _k_rotvec_rows(r, o, rows, factor):
    """`from_rotvec` of the rows `r` (n, 3) into `o` (n, 4) with six work rows (6, n): the
    norms from one pass of squares over the rows; blocks where a |r|² leaves the range
    (huge, nan or inf vectors) go to the component-major kernel `_k_from_rotvec`, which
    gives the other rows the same bits."""
    theta = rows[0]
    sq = np.multiply(r, r, out=rows[1:4].reshape(r.shape))   # x², y², z² summed in `squares`' order
    np.add(sq[:, 0], sq[:, 1], out=theta)
    theta += sq[:, 2]
    most = _scale.largest(theta)
    if not most <= _scale.HIGH[theta.dtype]:
        _k_from_rotvec(r.T.copy(), o.T, factor)
        return
    np.sqrt(theta, out=theta)
    _rotvec_quat(r.T, theta, factor, None, _ops.ARRAYS, _ops.STACKS, o.T, rows,
                 math.sqrt(most) if theta.dtype == _F64 and most >= 0.0 else None)   # (-inf: empty)


def _k_from_rotvec(r, q, factor):
    with _blocks.scratch().frame() as work:
        rows = work.rows(6, r.shape[1:], q.dtype)
        e = _scale.true_norm(r, rows[0], rows[1:4])   # |r|; r scaled by 2**-e where |r|² overflows
        if e is not None and not np.isfinite(r).all():   # |r|² in range: finite; else look
            raise ValueError(_scale.NONFINITE)             # (from_rotvec finds the element)
        _rotvec_quat(r, rows[0], factor, e, _ops.ARRAYS, _ops.STACKS, q, rows)
        if e is not None and not np.isfinite(rows[0]).all():
            _huge_rotvecs(r, q, e, ~np.isfinite(rows[0]), factor)


def _rotvec_quat(r, theta, factor, e, op, stack, q, rows, most=None):
    """The unit quaternion of the rotation vector `r` (x, y, z) of norm `theta` (times
    `factor`; `e` the exponents by which a block's x, y, z were scaled down, or None) in
    `op`'s arithmetic (`_ops`, `stack` its stacked form: r as three rows scaled in one call),
    into ``q`` (four rows) with the six work rows `rows`; returned as a list.  `most`: the
    largest float64 norm where the caller knows it: the half angles' bounds follow from it
    by the same roundings (monotone), which spares the tangent its range reductions."""
    q0, qv = q[0], q[1:4]
    _, t, u, v, c, d = rows[:6]
    if factor != 1.0:
        theta = op.mul(theta, factor, theta)
    if type(theta) is np.ndarray:
        floor = _ops.row(ANGLE_FLOOR[theta.dtype], theta.dtype, theta.shape)
    else:   # one rotation's Python float or float32 scalar
        floor = ANGLE_FLOOR[_F64 if type(theta) is float else _F32]
    theta = op.max(theta, floor, theta)
    t = op.mul(theta, 0.5, t)
    bounds = None if most is None else (0.0, math.nextafter(max(most * factor, ANGLE_FLOOR[_F64]) * 0.5, math.inf))
    c, d = _cos_sin(t, c, d, (u, v), bounds)     # cos(θ/2), sin(θ/2)
    q0 = op.copy(c, q0)
    # sin(θ/2) / θ, times the degree factor that converts v itself
    d = op.div(d, theta, d)
    if factor != 1.0:
        d = op.mul(d, factor, d)
    if e is not None:
        np.ldexp(d, e, out=d)
    return [q0, *stack.scale(r, d, qv)]


def _huge_rotvecs(r, q, e, huge, factor):
    """`_k_from_rotvec` where |r| itself overflows (components near the float maximum, the
    angle beyond it) but the half angle |r|/2 does not: from `r` as scaled by 2**-e."""
    rs = r[:, huge]
    ns = np.sqrt(_scale.sum_squares(rs, np.empty(rs.shape[1:], rs.dtype)))
    half = np.ldexp(ns * (0.5 * factor), e[huge])
    q[0, huge] = np.cos(half)
    q[1:, huge] = rs * (np.sin(half) / ns)


def from_rotvec(rotvec, degrees=False):
    """Unit quaternions of rotation vectors (axis × angle).

    Parameters
    ----------
    rotvec : array_like, shape (..., 3)
        Rotation vectors; the angle is the norm (any size, not limited to π).
    degrees : bool, default False

    Returns
    -------
    ndarray, shape (..., 4)
        Scalar-first unit quaternions (w = cos(angle/2) may be negative for
        angles above π, as in scipy).

    Notes
    -----
    float64 results are within 3 ulp of the largest component (scipy: 2.25,
    against 40-digit references): the half angle's sine and cosine come from
    one tangent (`_kernels.cos_sin`); separate sin and cos would gain about
    one ulp for twice the transcendental cost.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._convert import from_rotvec
    >>> np.round(from_rotvec([0, 0, 90], degrees=True), 6)
    array([0.707107, 0.      , 0.      , 0.707107])
    """
    v = _vec3(rotvec, "rotvec")   # finiteness: found by the norms' range check (the kernel's, or n2 here)
    factor = np.pi / 180.0 if degrees else 1.0
    one, kind = _ops.floats64(v, 3), _ops.F64
    if one is None:
        one, kind = _ops.floats32(v, 3)
    n2 = None if one is None else _scale.squares(one, kind.op, None, None)
    if n2 is not None and n2 <= _scale.HIGH[v.dtype]:   # one vector that `true_norm` keeps
        q = _rotvec_quat(one, kind.sqrt(n2), factor, None, kind.op, _ops.FLOAT_STACKS, _ops.NONE, _ops.NONE)
        return _ops.to_array(q, v.shape[:-1] + (4,), kind.dtype)
    out = np.empty(v.shape[:-1] + (4,), v.dtype)
    try:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):   # huge vectors: handled
            _rowwise(_k_rotvec_rows, _rows(v, 3), _rows(out, 4), 6, factor=factor)
    except ValueError:
        finite(v, "rotvec")   # the message with the first non-finite element's index
        raise
    return out


def _k_magnitude(q, o, unit=False):
    """θ of the rows `q` into ``o[0]``, or (`o` None: a few rows, whose rows `_half_turn`'s
    ufuncs allocated) into tan(θ/2)'s own row, returned."""
    t, exact = _half_turn(q, unit)
    tan_half = _tangent_rows(q, t, exact)[0] if exact else t[0]
    if o is None:   # (a row of the thread's scratch, were FEW ever below VIEWS_MAX: a new one)
        o = (tan_half if tan_half.base is None else np.empty_like(tan_half),)
    return _angle(tan_half, _ops.ARRAYS, None, o[0])


def _angle(tan_half, op, stack, o):
    """θ = 2 atan(tan(θ/2)) in `op`'s arithmetic (`_ops`), into the row `o`."""
    half = op.arctan(tan_half, o)
    return op.add(half, half, o)


_ANGLE_FLOATS = _half_turn_floats(
    lambda op, stack, w, x, y, z, w2, v2: _angle(_tan_half(w2, v2, op, None), op, stack, None), 0)
"""`_half_turn_floats` of `_tan_half` and `_angle` on one rotation's floats, by `_ops.Kind`."""


def magnitude(q, unit=False):
    """Rotation angles in [0, π] of quaternions, ``2 atan2(|v|, |w|)``.

    Parameters
    ----------
    q : ndarray, shape (..., 4)
    unit : bool, default False
        The caller knows every q is a finite unit quaternion (`Rotation`'s
        storage): the range check of |q|² is skipped (the same bits).

    Returns
    -------
    ndarray, batch shape

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._convert import magnitude
    >>> magnitude(np.array([[1.0, 0, 0, 0], [0, 1, 0, 0], [-1, 1, 0, 0]]))
    array([0.        , 3.14159265, 1.57079633])
    """
    if not unit:   # (unit: Rotation's own storage, a float array of quaternions)
        q = quat_array(q, "quat")
    elif q.size > 4 and q.ndim == 2 and len(q) <= _blocks.VIEWS_MAX:   # a Rotation's few: the kernel
        return _k_magnitude(q.T, None, unit=True)   # at once on views, into its own fresh row
    c, kind = _one_rotation(q)
    angle = None if c is None else _ANGLE_FLOATS[kind](*c)
    if angle is not None:   # one float64 or float32 rotation: `_k_magnitude` on its floats
        if q.ndim == 1:
            return np.array(angle)   # np.array, not np.full (5x its cost) nor a reshape (2x)
        out = np.empty(1) if kind is _ops.F64 else np.empty(1, _F32)   # q is (1, 4): an element
        out[0] = angle                                                 # assigned costs half of
        return out                                                     # np.array([angle])
    if q.ndim == 2:   # (N, 4): its rows as they are, the output (N,) written as (N, 1)
        out = np.empty(len(q), q.dtype)
        _blockwise_unit(_k_magnitude, q, out[:, None], unit)
        return out
    out = np.empty(q.shape[:-1], q.dtype)
    _blockwise_unit(_k_magnitude, q.reshape(-1, 4), out.reshape(-1, 1), unit)
    return out


def _k_as_mrp(q, o):
    k = _scale.guarded_sqnorm(q, zero=True)   # a scratch row; q may be rescaled in place (MRPs
    np.sqrt(k, out=k)                         # do not change with |q|)
    with _blocks.scratch().frame() as work:
        d = _mrp_denominator(q[0], _ops.ARRAYS, work.rows(1, k.shape, k.dtype)[0], k, _ops.const(0.0, k.dtype), k)
        np.divide(q[1:], d, out=o)            # v / (|q| + |w|), signed as w


def _mrp_denominator(w, op, s, d, zero=0.0, one=1.0):
    """``|q| + |w|``, signed as w (w = -0 counts as positive, as in scipy), written once, in
    `op`'s arithmetic (`_ops`), with the work rows `s`, `d`: MRPs are ``v`` over it (scipy's
    ``v / copysign(1 + |w|, w)`` for unit q).  ``s ± |q|`` (s = w + 0: w with -0 made +0) is
    exactly ``±(|q| + |w|)`` (rounding is symmetric), one call fewer.  `zero`: 0; `one`:
    |q|, 1 for unit q (`Rotation`'s: as scipy, no norm), else the rows of |q| (may be `d`);
    as `_ops.const` arrays on rows."""
    s = op.add(w, zero, s)            # -0 -> +0: only w < 0 flips the sign (and a contiguous row)
    d = op.copysign(one, s, d)
    return op.add(s, d, d)


def _unit_mrp(q):
    """`as_mrp` of finite unit quaternions `q` (..., 4), `Rotation`'s storage: ``v`` over
    `_mrp_denominator`, read in place from the rows of `q`."""
    w = _ops.first64(q)
    if w is not None:   # one float64 rotation: the denominator on its float, v over it in one call
        return np.divide(q[..., 1:], _mrp_denominator_floats(w))
    if q.size == 4 and q.dtype is _F32:   # one float32 rotation: the same on its float32 scalar w
        c = _ops.floats32(q)[0]
        if c is not None:
            return np.divide(q[..., 1:], _mrp_denominator_floats.float32(c[0]))
    if q.ndim == 2:
        n = len(q)
        if n <= _MRP_NEW_ROWS:   # a few rows as stored: into a new array
            return _k_unit_mrp(q, None, _ops.NONE)
        if n <= _blocks.BLOCK:
            # up to a block, the rows as stored and work rows made by the ufuncs: the block
            # engine's setup (split, pool check, scratch) costs more than it saves there,
            # and its threads start at several blocks only
            return _k_unit_mrp(q, np.empty((n, 3), q.dtype), _ops.NONE)
    out = np.empty(q.shape[:-1] + (3,), q.dtype)
    _rowwise(_k_unit_mrp, _rows(q, 4), _rows(out, 3), 2)
    return out


_mrp_denominator_floats = _ops.compiled(lambda op, stack, w: _mrp_denominator(w, op, None, None), 1)
"""`_mrp_denominator` on one rotation's float w (`_ops.compiled`)."""

_MRP_NEW_ROWS = 32
"""Up to this many rows, as_mrp's division makes its own (n, 3) output: its n inner loops
of three (about 9 ns a row) cost less than allocating the output first (0.2-0.3 µs)."""


_ZERO_ONE = {}   # dtype -> `_ops.const` 0 and 1: one lookup by dtype, a third of two `const` calls


def _k_unit_mrp(q, o, rows):
    """`_unit_mrp` of the rows `q` (n, 4) into `o` (n, 3) (None: into a new array, returned)
    with two work rows (2, n), or `_ops.NONE` (new ones)."""
    zero, one = _ZERO_ONE.get(q.dtype) or _ZERO_ONE.setdefault(q.dtype, (_ops.const(0.0, q.dtype),
                                                                         _ops.const(1.0, q.dtype)))
    d = _mrp_denominator(q[:, 0], _ops.ARRAYS, rows[0], rows[1], zero, one)
    if o is None:
        return np.divide(q[:, 1:], d[:, None])
    # x, y, z in one call, iterated in C order over the component-major views: each
    # component is one long (strided) inner loop, not n loops of three
    np.divide(q.T[1:], d, out=o.T, order="C")
    return o


def as_mrp(q, unit=False):
    """Modified Rodrigues parameters ``v / (|q| + |w|)`` (norm ≤ 1, angle ≤ π).

    Parameters
    ----------
    q : ndarray, shape (..., 4)
    unit : bool, default False
        The caller knows `q` is a float32 or float64 ndarray of finite unit
        quaternions (`Rotation`'s storage): it is not checked, and |q| is
        taken as 1, as scipy does (``v / (1 + |w|)``), saving the squared
        norms and their range check.

    Returns
    -------
    ndarray, shape (..., 3)
        ``axis * tan(angle / 4)``; the sign follows scipy (w < 0 is flipped).

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._convert import as_mrp
    >>> np.round(as_mrp(np.array([0.0, 0, 0, 1])), 12)  # 180° about z
    array([0., 0., 1.])
    """
    if unit:   # `Rotation`'s own storage: a float ndarray of shape (..., 4) already
        return _unit_mrp(q)
    q = quat_array(q, "quat")
    out = np.empty(q.shape[:-1] + (3,), q.dtype)
    _blockwise(_k_as_mrp, [q.reshape(-1, 4)], [out.reshape(-1, 3)])
    return out


def _mrp_quat(n, op, e, h, t, w):
    """(w, h) of the unit quaternion ``((1 - n), 2 p) / (1 + n)`` = (w, p / h) of the MRP p
    with n = |p|², in `op`'s arithmetic (`_ops`) into the rows `e`, `h`, `w` (`t` a work
    row): scipy's ``((2 - e) / e, 2 p / e)`` with e = 1 + n (``p / h`` with h = e / 2 is
    ``2 p / e`` exactly: halving is exact), one rounding per component."""
    e = op.add(n, 1.0, e)
    h = op.mul(e, 0.5, h)
    t = op.sub(2.0, e, t)
    return op.div(t, e, w), h


def _k_mrp_rows(p, o, rows):
    """`from_mrp` of the rows `p` (n, 3) into `o` (n, 4) with four work rows (4, n)."""
    sq = np.multiply(p, p, out=rows[1:4].reshape(p.shape))   # x², y², z² in one call, then
    n = _scale._summed(sq.T, rows[0])                       # summed in that order (`_scale.squares`')
    _, h = _mrp_quat(n, _ops.ARRAYS, rows[1], rows[2], rows[3], o[:, 0])
    np.divide(p.T, h, out=o.T[1:], order="C")   # x, y, z in one call (as in `_k_unit_mrp`)
    if not _scale.at_most(n, _scale.HIGH[n.dtype]):   # nan, inf or |p|² overflowing: look
        if not np.isfinite(p).all():
            raise ValueError(_scale.NONFINITE)     # (from_mrp finds the element)
        _huge_mrps(p, o, ~(n <= _scale.HIGH[n.dtype]))


def _huge_mrps(p, o, huge):
    """The rows of `o` where |p|² overflows (|p| past about 1e138, float64): with
    s = 1/|p|² (= |p/m|⁻² / m², m a power of two near max |p_k|, no overflow),
    q = ((s - 1), 2 p s) / (1 + s), the same value as ((1 - |p|²), 2 p) / (1 + |p|²)."""
    ps = p[huge].T.copy()                       # components-first, scaled in place:
    e = _scale.rescale(ps)                      # p 2**-e, exact
    n = _scale.sum_squares(ps, np.empty(ps.shape[1:], ps.dtype))
    s = np.ldexp(1.0 / n, -2 * e)               # 1/|p|², may underflow to 0 (harmless)
    d = 1.0 / (1.0 + s)
    o[huge, 0] = (s - 1.0) * d
    # 2 p / (1 + |p|²) = 2 (p 2**-e) 2**-e / |p 2**-e|² · d
    o[huge, 1:] = (ps * (np.ldexp(2.0 / n, -e) * d)).T


def from_mrp(mrp):
    """Unit quaternions of modified Rodrigues parameters.

    Parameters
    ----------
    mrp : array_like, shape (..., 3)
        ``axis * tan(angle / 4)``.

    Returns
    -------
    ndarray, shape (..., 4)

    Examples
    --------
    >>> from quatarray._convert import from_mrp
    >>> from_mrp([0, 0, 1])
    array([0., 0., 0., 1.])
    """
    p = _vec3(mrp, "mrp")   # finiteness: found by the kernel's range check of |p|² (or n here)
    one = _ops.floats64(p, 3)   # (float32: the rows' kernel on one MRP is as fast, 3 µs)
    if one is not None:
        n = _scale.squares(one, _ops.FLOATS, None, None)   # the kernel's |p|², in its order
        if n <= _scale.HIGH[p.dtype]:   # one float64 MRP: the kernel's formula on its floats
            w, h = _mrp_quat(n, _ops.FLOATS, None, None, None, None)
            return _ops.to_array([w, *_ops.FLOAT_STACKS.div(one, h, None)], p.shape[:-1] + (4,))
    out = np.empty(p.shape[:-1] + (4,), p.dtype)
    try:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            _rowwise(_k_mrp_rows, _rows(p, 3), _rows(out, 4), 4)
    except ValueError:
        finite(p, "mrp")   # the message with the first non-finite element's index
        raise
    return out


# --- canonical form ---------------------------------------------------------------------------

def canonical(q):
    """The representative with w > 0 (for w = 0: first non-zero of x, y, z positive).

    Parameters
    ----------
    q : ndarray, shape (..., 4)

    Returns
    -------
    ndarray, shape (..., 4)
        A new array (the input is not modified).

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._convert import canonical
    >>> canonical(np.array([[-1.0, 0, 0, 0], [0, 0, -1, 1]]))
    array([[ 1.,  0.,  0.,  0.],
           [-0., -0.,  1., -1.]])
    """
    q = quat_array(q, "quat")
    if q.ndim == 1:   # one quaternion: the same test on its floats, then one call
        return -q if _flip_mask(*q.tolist()) else q.copy()
    flip = _flip_mask(q[..., 0], q[..., 1], q[..., 2], q[..., 3])
    return np.where(flip[..., None], -q, q)
