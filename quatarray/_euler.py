"""Euler and Davenport angles <-> scalar-first quaternions, on raw ndarrays.

All 12 Euler sequences (lower case extrinsic, upper case intrinsic) and
Davenport angles about arbitrary axes, following scipy 1.17's conventions,
angle ranges and gimbal-lock `UserWarning`.  ``from_*`` multiplies the
elementary rotations in closed form; ``as_*`` is the quaternion method of
Bernardes & Viollet (no matrices).  Blocks, dtypes and half angles as in
`_convert`.
"""

import functools
import threading
import warnings

import numpy as np

from . import _blocks, _ops, _scale, _trig
from ._convert import _blockwise
from ._kernels import half_angle as _half_angle
from ._kernels import arctan2, multiply
from ._validate import finite, float_array, quat_array

__all__ = ["check_seq", "check_angles", "from_euler", "as_euler", "check_order", "from_davenport",
           "as_davenport"]

_GIMBAL_EPS = 1e-7
_GIMBAL_MESSAGE = ("Gimbal lock detected. Setting third angle to zero since it is not "
                   "possible to uniquely determine all angles.")


# --- Euler angles ----------------------------------------------------------------------------

def check_seq(seq, n=None):
    """Validate an Euler sequence; return (axis indices, intrinsic).

    Lower case is extrinsic, upper case intrinsic; 1 to 3 axes (exactly `n` if
    given), no axis repeated consecutively.

    >>> from quatarray._euler import check_seq
    >>> check_seq("ZXY")
    ([2, 0, 1], True)
    """
    if not isinstance(seq, str):
        raise TypeError(f"expected seq to be a str such as 'xyz' or 'ZXZ', got {type(seq).__name__}")
    axes, intrinsic = _check_str_seq(seq, n)
    return list(axes), intrinsic


@functools.lru_cache(maxsize=128)
def _check_str_seq(seq, n):
    """`check_seq` for a str, remembered (a single rotation's conversion is a few µs).
    The messages are scipy's (its tests match them); each names what was expected and
    what came."""
    if n is not None and len(seq) != n:
        raise ValueError(f"Expected {n} axes, got {seq}.")
    if not 1 <= len(seq) <= 3:
        raise ValueError(f"Expected axis specification to be a non-empty string of up to 3 "
                         f"characters, got {seq}")
    if not (seq.isupper() or seq.islower()) or set(seq.lower()) - set("xyz"):
        raise ValueError(f"Expected axes from `seq` to be from ['x', 'y', 'z'] or "
                         f"['X', 'Y', 'Z'], got {seq}")
    if any(a == b for a, b in zip(seq, seq[1:])):
        raise ValueError(f"Expected consecutive axes to be different, got {seq}")
    return tuple("xyz".index(a) for a in seq.lower()), seq.isupper()


def check_angles(seq, angles):
    """Validate Euler angles (..., len(seq)) against their sequence; a scalar becomes shape (1,).

    The message starts with scipy's (its tests match it).

    >>> import numpy as np
    >>> from quatarray._euler import check_angles
    >>> check_angles("z", np.array(0.5)).shape
    (1,)
    >>> check_angles("xyz", np.zeros((4, 2)))
    Traceback (most recent call last):
    ...
    ValueError: Expected last dimension of `angles` to match number of sequence axes specified, got 2: expected angles of shape (..., 3) for seq 'xyz', got (4, 2)
    """
    if angles.ndim == 0:
        angles = angles.reshape(1)
    if angles.shape[-1] != len(seq):
        raise ValueError(f"Expected last dimension of `angles` to match number of sequence axes specified, "
                         f"got {angles.shape[-1]}: expected angles of shape (..., {len(seq)}) for seq {seq!r}, "
                         f"got {angles.shape}")
    return angles


def _negate(x):
    """-x in place.  Not ``np.negative(x, out=x)``: NumPy 2.4 reads the wrong elements for
    float32 rows 16 bytes apart (the component rows of an (m, 4) output); the minimal
    reproducer is tests/test_euler.py::test_negate_works_where_numpys_inplace_negative_does_not."""
    return np.multiply(x, -1, out=x)


def _lin(c, a, sign, s, b, op, out=None):
    """c*a + sign*s*b for rows or None (a zero row) in `op`'s arithmetic (`_ops`); None if
    both are zero."""
    if a is None and b is None:
        return None
    if b is None:
        return op.mul(c, a, out)
    sb = op.mul(s, b, out if a is None else None)
    if a is None:
        return sb if sign > 0 else op.mul(sb, -1, sb)   # not np.negative in place: see `_negate`
    ca = op.mul(c, a, out)
    return op.add(ca, sb, ca) if sign > 0 else op.sub(ca, sb, ca)


def _times_axis(p, c, s, k, right, op, out=None):
    """p (c + s e_k) if `right` else (c + s e_k) p, on rows [w, x, y, z] (None = 0)."""
    i, j = (k + 1) % 3, (k + 2) % 3
    w, pk, pi, pj = p[0], p[k + 1], p[i + 1], p[j + 1]
    sg = 1 if right else -1
    o = out if out is not None else [None] * 4
    res = [None] * 4
    res[0] = _lin(c, w, -1, s, pk, op, o[0])
    res[k + 1] = _lin(c, pk, 1, s, w, op, o[k + 1])
    res[i + 1] = _lin(c, pi, sg, s, pj, op, o[i + 1])
    res[j + 1] = _lin(c, pj, -sg, s, pi, op, o[j + 1])
    return res


def _euler_quat(angles, axes, intrinsic, scale, op, q):
    """The product of the elementary quaternions of `angles` (rows, or one rotation's floats)
    in `op`'s arithmetic (`_ops`), the last written into ``q``: [w, x, y, z], None = 0."""
    c, s = _half_angle(angles[0], scale)
    p = [c, None, None, None]
    p[axes[0] + 1] = s
    last = len(axes) - 1
    for n in range(1, len(axes)):
        c, s = _half_angle(angles[n], scale)
        p = _times_axis(p, c, s, axes[n], intrinsic, op, out=q if n == last else None)
    return p


def _k_from_euler(angles, q, axes, intrinsic, scale):
    p = _euler_quat(angles, axes, intrinsic, scale, _ops.ARRAYS, q)
    for row, value in zip(q, p):  # rows not written through `out`
        if value is None:
            row.fill(0)
        elif len(axes) == 1:
            np.copyto(row, value)


def from_euler(seq, angles, degrees=False):
    """Unit quaternions of Euler angles, as scipy's ``Rotation.from_euler``.

    Parameters
    ----------
    seq : str
        1 to 3 axes from ``'xyz'`` (extrinsic: about the fixed frame) or
        ``'XYZ'`` (intrinsic: about the rotating frame), e.g. ``'ZXZ'``.
    angles : array_like, shape (..., len(seq))
        A scalar is accepted for a single axis.
    degrees : bool, default False

    Returns
    -------
    ndarray, shape (..., 4)
        ``from_euler('xyz', [a, b, c])`` is the rotation about x by a, then
        about the fixed y by b, then the fixed z by c.

    Notes
    -----
    The elementary quaternions are multiplied in closed form, skipping their
    zero components: a 3-axis sequence costs 3 tangents and 16 products.
    float64 results are within 5 ulp of the largest component (scipy: 2,
    against 40-digit references): separate sin and cos of each half angle
    would gain about two ulp for twice the transcendental cost.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._euler import from_euler
    >>> np.round(from_euler("z", 90, degrees=True), 6)
    array([0.707107, 0.      , 0.      , 0.707107])
    >>> np.round(from_euler("XY", [[90, 0], [0, 90]], degrees=True), 6)
    array([[0.707107, 0.707107, 0.      , 0.      ],
           [0.707107, 0.      , 0.707107, 0.      ]])
    """
    axes, intrinsic = check_seq(seq)
    a = check_angles(seq, finite(float_array(angles, "angles"), "angles"))
    scale = np.pi / 720.0 if degrees else 0.25
    one, kind = _ops.floats64(a, len(axes)), _ops.F64
    if one is None:
        one, kind = _ops.floats32(a, len(axes))
    if one is not None:   # one float64 or float32 rotation: the same formula on its floats
        p = _euler_quat(one, axes, intrinsic, scale, kind.op, _ops.NONE)
        return _ops.to_array([0.0 if v is None else v for v in p], a.shape[:-1] + (4,), kind.dtype)
    out = np.empty(a.shape[:-1] + (4,), a.dtype)
    _blockwise(_k_from_euler, [a.reshape(-1, len(axes))], [out.reshape(-1, 4)],
               axes=axes, intrinsic=intrinsic, scale=scale)
    return out


_FIRST_THIRD = {True: (0, 2), False: (2, 0)}
"""The rows of arctan2's three arguments, by `extrinsic`, that hold the angle from
``ac + bd`` (first) and the one from ``ac - bd`` (third), in the output's order of angles,
which an intrinsic sequence reverses."""

_ROWS = {"e": (0, 5), "a": (0, 1), "-a": (4, 5), "e04": (0, 4), "e15": (1, 5), "sq": (5, 9),
         "sq01": (5, 7), "sq23": (7, 9), "n": (9, 11), "g": (11, 17), "g0": (11, 13), "g1": (13, 15),
         "g2": (15, 17), "num": (5, 8), "den": (8, 11), "t": (17, 20)}
"""The rows of the Euler angles' work buffer (`_EulerRows`; one rotation's floats take a list
laid out alike): the chain ``e = [a, c, b, d, -a]`` (a, b, c, d as `_abcd` writes them), its
squares (then its products), the norms ``n = [|(a, b)|², |(c, d)|²]``, arctan2's three
(denominator, numerator) pairs ``g0, g1, g2`` in the order of the angles (then, where
`_angles` copies them into rows of their own, in the squares' and norms' rows ``num``,
``den``), and the three arctangents ``t``."""

_ROW_COUNT = 20

_NORMS = (("mul", "a", -1.0, "-a"),       # the chain's end
          ("mul", "e04", "e04", "sq"),    # [a², c², b², d²]
          ("add", "sq01", "sq23", "n"))   # [a² + b², c² + d²]
"""The chain and the norms of Bernardes & Viollet's (a, b) and (c, d), as steps
``(operation, x, y, into)`` on `_ROWS` (`y` a row, a constant or None): each one call on a
block's rows."""

_ARGUMENTS = {first: (("mul", "e04", "e15", "sq"),   # [ac, bc, bd, -ad]: the chain times itself shifted
                      ("sqrt", "n", None, "g1"),      # (u, r) = (|(a, b)|, |(c, d)|)
                      ("add", "sq01", "sq23", f"g{first}"),       # (re₁, im₁) = (ac + bd, bc - ad)
                      ("sub", "sq01", "sq23", f"g{2 - first}"))   # (re₂, im₂) = (ac - bd, bc + ad)
              for first in (0, 2)}
"""arctan2's arguments from the chain and the norms, by the row of the first angle, as
`_NORMS`: ``(a + ib)(c ∓ id) = re + i im``; ``x + (-y)`` is ``x - y`` and ``a·(-d)`` is
``-(a·d)`` to the bit, so ``[ac, bc] ± [bd, -ad]`` are the pairs of both angles."""

_UFUNCS = {"mul": np.multiply, "add": np.add, "sub": np.subtract, "sqrt": np.sqrt}
_NORMS_UFUNCS = tuple((_UFUNCS[name], *rows) for name, *rows in _NORMS)
_ARGUMENTS_UFUNCS = {first: tuple((_UFUNCS[name], *rows) for name, *rows in steps)
                     for first, steps in _ARGUMENTS.items()}
_SLICE = {name: slice(*rows) for name, rows in _ROWS.items()}


def _steps_on_floats(steps, buf, op):
    """`steps` (`_NORMS`, `_ARGUMENTS`) on the list `buf` laid out as `_ROWS`, element by
    element in `op`'s arithmetic (`_ops.FLOATS`, or `_ops.compiled`'s tracer)."""
    for name, x, y, into in steps:
        f = getattr(op, name)
        xs = buf[_SLICE[x]]
        if y is None:
            buf[_SLICE[into]] = [f(a, None) for a in xs]
        elif type(y) is float:
            buf[_SLICE[into]] = [f(a, y, None) for a in xs]
        else:
            buf[_SLICE[into]] = [f(a, b, None) for a, b in zip(xs, buf[_SLICE[y]])]


class _EulerRows:
    """The work rows of `_angles` for blocks of one shape and dtype (`buf`, `_ROW_COUNT` rows),
    laid out as `_ROWS`, with every view its calls use made once (at a few rotations, making
    the views would cost a good part of the calls): `_NORMS` and `_ARGUMENTS` bound to them as
    ``(ufunc, x, y, into)``, `y` a view, a 0-d constant or None."""

    __slots__ = ("nbytes", "e", "abcd", "rows", "norms", "arguments", "num", "den", "num_rows", "den_rows",
                 "t", "t_rows", "tmp", "minus_one", "two")

    def __init__(self, buf):
        self.nbytes = buf.nbytes
        views = {name: buf[where] for name, where in _SLICE.items()}
        self.e = views["e"]
        self.rows = rows = tuple(self.e)             # a, c, b, d, -a
        self.abcd = (rows[0], rows[2], rows[1], rows[3])
        pairs = views["g"].reshape((3, 2) + buf.shape[1:])
        self.den, self.num = pairs[:, 0], pairs[:, 1]
        self.num_rows, self.den_rows = views["num"], views["den"]
        self.t = views["t"]
        self.t_rows = tuple(self.t)
        self.tmp = self.t_rows[0]   # free until the arctangents
        views[-1.0] = self.minus_one = _ops.const(-1.0, buf.dtype)
        self.two = _ops.const(2.0, buf.dtype)
        views[None] = None
        self.norms = tuple((f, views[x], views[y], views[into]) for f, x, y, into in _NORMS_UFUNCS)
        self.arguments = {first: tuple((f, views[x], views[y], views[into]) for f, x, y, into in steps)
                          for first, steps in _ARGUMENTS_UFUNCS.items()}


def _run(steps):
    """Bound steps (`_EulerRows`), one ufunc call each."""
    for f, x, y, into in steps:
        if y is None:
            f(x, out=into)
        else:
            f(x, y, out=into)


_local = threading.local()


_KEEP_BYTES = 1 << 20
"""Bytes of fresh `_EulerRows` a thread keeps between calls (the few sizes a program converts)."""

_KEEP_SCRATCH = 4
"""`_EulerRows` on scratch a thread keeps between calls (a block's rows lie in the same place
of the thread's scratch from call to call)."""


def _euler_rows(shape, dtype):
    """The calling thread's `_EulerRows` for blocks of `shape` (m,) and `dtype`, kept with
    their views (building them costs as much as a dozen small ufunc calls): up to
    `_blocks.FEW` rotations in fresh rows, within `_KEEP_BYTES`; past it on the thread's
    scratch (rows taken for the block as usual), kept by where they lie there."""
    kept = getattr(_local, "rows", None)
    if kept is None:
        kept = _local.rows = {}
    if shape[0] > _blocks.FEW:
        work = _blocks.scratch()
        buf = work.rows(_ROW_COUNT, shape, dtype)
        if buf.base is None:   # a fresh array: past the scratch's limit
            return _EulerRows(buf)
        # (the scratch's buffer is the same object while kept views of it hold it)
        key = (id(work.buf), work.top, shape, dtype)
        rows = kept.get(key)
        if rows is None:
            on_scratch = [k for k in kept if type(k[0]) is int]
            for k in on_scratch:   # views of a buffer the scratch has replaced, or too many
                if k[0] != key[0] or len(on_scratch) >= _KEEP_SCRATCH:
                    del kept[k]
            rows = kept[key] = _EulerRows(buf)
        return rows
    key = (shape, dtype)
    rows = kept.get(key)
    if rows is None:
        fresh = sum(r.nbytes for k, r in kept.items() if type(k[0]) is tuple)
        if fresh + _ROW_COUNT * shape[0] * dtype.itemsize > _KEEP_BYTES:
            kept.clear()
        rows = kept[key] = _EulerRows(np.empty((_ROW_COUNT,) + shape, dtype))
    return rows


def _operands(abcd, op, first):
    """`_NORMS` and `_ARGUMENTS` on floats (`abcd`: ``[a, c, b, d]``, completed by -a into the
    chain; `first` the row of the first angle): arctan2's three numerators and three
    denominators, and |(a, b, c, d)|² (for the range check), seven floats."""
    buf = list(abcd) + [None] * (_ROW_COUNT - 4)
    _steps_on_floats(_NORMS, buf, op)
    _steps_on_floats(_ARGUMENTS[first], buf, op)
    g, n = _ROWS["g"], _ROWS["n"]
    return buf[g[0] + 1:g[1]:2] + buf[g[0]:g[1]:2] + [op.add(*buf[slice(*n)], None)]


_OPERANDS_FLOATS = {extrinsic: _ops.compiled(
    lambda op, stack, *abcd, first=first: _operands(list(abcd), op, first), 4).kinds
    for extrinsic, (first, _) in _FIRST_THIRD.items()}
"""`_operands` compiled for the four floats ``[a, c, b, d]`` of one rotation, by `extrinsic`
and `_ops.Kind` (`_ops.compiled`; the Euler sequences compile theirs from the quaternion,
`_euler_plan`)."""


def _angles_floats(v, extrinsic, symmetric, sign, lamb, kind):
    """`_angles` on one rotation's floats (of `kind`, an `_ops.Kind`), from `_operands`'
    seven: the three angles as a new array (3,) of its dtype, or None where the array kernel
    would rescale or find gimbal lock (its own path, with the warning)."""
    low, high = _BOUNDS[kind]
    if not low <= v[6] <= high:
        return None
    angles = arctan2(v[0:3], v[3:6])   # a new array (3,): the result, as the floats give it
    if kind is _F64:
        mid = m = angles.item(1) * 2.0
    else:   # float32 scalars; the lock tested on the Python float, as the kernel's `_extremes`
        mid = angles[1] * 2.0
        m = float(mid)
    if m <= _GIMBAL_EPS or m >= _PI_LOCK:
        return None
    if not symmetric:
        third = 2 if extrinsic else 0
        value = angles.item(third) if kind is _F64 else angles[third]
        mid, value = _ASYMMETRIC_FLOATS[sign][kind](mid, value, lamb)
        if sign < 0:   # (else the third angle is arctan2's, as it stands)
            angles[third] = value
    angles[1] = mid
    return angles


def _asymmetric(mid, third, sign, k, op, o_mid, o_third):
    """The last step of an asymmetric sequence (i ≠ k), in `op`'s arithmetic (`_ops`): the
    middle angle less λ and the third angle negated for an odd permutation (`sign` < 0);
    ``k = (-1, λ)`` as `op`'s operands; into the rows `o_mid`, `o_third`; returned."""
    if sign < 0:
        third = op.mul(third, k[0], o_third)
    return op.sub(mid, k[1], o_mid), third


_ASYMMETRIC_FLOATS = {sign: _ops.compiled(lambda op, stack, mid, third, lamb, sign=sign: list(
    _asymmetric(mid, third, sign, (-1.0, lamb), op, None, None)), 3).kinds for sign in (-1, 1)}
"""`_asymmetric` on one rotation's floats ``(mid, third, λ)``, by sign and `_ops.Kind`
(`_ops.compiled`)."""


def _angles(w, o, extrinsic, symmetric, sign, lamb, unit=False):
    """Bernardes & Viollet's step 2-3 from a, b, c, d (in the rows ``w.abcd`` of `_euler_rows`'
    `w`; they may be rescaled in place) into o (three rows).  Returns whether any element is
    in gimbal lock.  One rotation's floats take `_operands` and `_angles_floats`: the same
    operations.

    The middle angle is 2 atan2(|(c, d)|, |(a, b)|); the first and third angles are
    half_sum ∓ half_diff with half_sum = arg(a + ib) and half_diff = arg(c + id), each read as
    one argument, of (a + ib)(c ∓ id) = Re + i Im, which lands in [-π, π] without the wrap
    scipy applies to the sum.  The three arctangents (`_kernels.arctan2`) are one call on
    arrays, on the numerators and denominators of `_ARGUMENTS`' pairs in the rows' order of
    `o`.  In gimbal lock (middle angle within 1e-7 of 0 or π) the third angle is set to 0 and
    the first takes the whole turn, as in scipy.  `unit`: a, b, c, d come from finite unit
    quaternions (`Rotation`'s storage), whose squared norms always fit: no range check.

    Each step is one call on several rows (at a few rotations the calls, not the elements,
    take the time): the chain, its squares, their pair sums, the products, the pairs' sums
    and differences, their square roots, the arctangents, their copy into `o`."""
    first, third = _FIRST_THIRD[extrinsic]
    _run(w.norms)
    if not unit:   # the range guard of `_scale`, on |(a, b, c, d)|² (|q|² or 2|q|²)
        u2, r2 = w.norms[-1][3]
        if not _scale.fits(np.add(u2, r2, out=w.tmp)):
            if not np.isfinite(w.e).all():
                raise ValueError(_scale.NONFINITE)
            _scale.rescale(w.e, _scale.outside(w.tmp))   # by powers of two: the angles are unchanged
            _run(w.norms)
            if not np.add(u2, r2, out=w.tmp).all():
                raise ValueError(_scale.ZERO)
    _run(w.arguments[first])
    T = w.t
    t = w.t_rows
    few = len(t[0]) <= _COPY_ALL_MAX
    num, den = w.num, w.den
    if few and not _trig.SIMD_TAN:   # the ratio route (`_kernels.arctan2`) reads y and x three
        np.copyto(w.num_rows, num)   # times: from contiguous rows, as few calls as it has
        np.copyto(w.den_rows, den)
        num, den = w.num_rows, w.den_rows
    # into contiguous rows, finished there, then copied: a transcendental loop's bits may
    # depend on the layout (SIMD for contiguous rows), and o is strided
    arctan2(num, den, out=T, defined=unit)
    mid = np.multiply(t[1], w.two, out=t[1])          # the middle angle, in [0, π]
    lo, hi = _extremes(mid)
    gimbal = lo <= _GIMBAL_EPS or hi >= _PI_LOCK
    if gimbal:
        mid = mid.copy()
    if not symmetric:
        _asymmetric(t[1], t[third], sign, (w.minus_one, _ops.const(lamb, T.dtype)), _ops.ARRAYS, t[1], t[third])
    if few:
        np.copyto(o, T)   # one call (in inner loops of three)
    else:
        for row, angle in zip(o, t):
            np.copyto(row, angle)
    if gimbal:
        _lock(w.abcd, mid, o, extrinsic, third, -1.0 if not symmetric and sign < 0 else 1.0)
    return gimbal


_PI_LOCK = np.pi - _GIMBAL_EPS
_COPY_ALL_MAX = 100
"""Up to this many rotations `_angles` copies its three rows of angles into the strided
output in one call; NumPy walks that copy in inner loops of three elements, so longer rows
are copied one by one."""


def _lock(A, mid, o, extrinsic, third, third_sign):
    """Gimbal lock, as scipy: where the middle angle is within 1e-7 of 0 (or π), the third
    angle is 0 and the first is 2 arg(a + ib) (or ±2 arg(c + id)), wrapped into [-π, π];
    the sign the third angle gets (`third_sign`) applies as it does to the others."""
    case1 = mid <= _GIMBAL_EPS
    at = np.nonzero(case1 | (np.abs(mid - np.pi) <= _GIMBAL_EPS))
    a, b, c, d = A
    lock_angle = np.where(case1[at], 2 * np.arctan2(b[at], a[at]),
                          (-2 if extrinsic else 2) * np.arctan2(d[at], c[at]))
    lock_angle = np.where(lock_angle < -np.pi, lock_angle + 2 * np.pi,
                          np.where(lock_angle > np.pi, lock_angle - 2 * np.pi, lock_angle))
    raw = {0: lock_angle, 2: np.zeros_like(lock_angle)}
    raw[third] = raw[third] * third_sign
    o[0][at] = raw[0]
    o[2][at] = raw[2]


def _extremes(a):
    """(min, max) of `a` (no NaN in it) as Python floats: up to 32 elements by Python's min
    and max (cheaper than two NumPy reductions there)."""
    if a.size <= 32:
        x = a.ravel().tolist()
        return min(x), max(x)
    return float(np.minimum.reduce(a, axis=None)), float(np.maximum.reduce(a, axis=None))


_TINY = {d: float(np.finfo(d).tiny) for d in (np.dtype(np.float32), np.dtype(np.float64))}
_TINY64 = _TINY[np.dtype(np.float64)]


def _abcd(w, qi, qj, qk, symmetric, op, rows):
    """Bernardes & Viollet's a, b, c, d from the components a sequence reads (qk already
    signed), in `op`'s arithmetic (`_ops`), in the chain's order ``[a, c, b, d]`` (`_ROWS`), into the
    four `rows`."""
    if symmetric:
        return [op.copy(w, rows[0]), op.copy(qj, rows[1]), op.copy(qi, rows[2]), op.copy(qk, rows[3])]
    return [op.sub(w, qj, rows[0]), op.add(qj, w, rows[1]), op.add(qi, qk, rows[2]), op.sub(qk, qi, rows[3])]


def _k_as_euler(q, o, i, j, k, symmetric, sign, extrinsic, unit=False):
    w = _euler_rows(q.shape[1:], q.dtype)
    qk = q[k + 1]
    if sign < 0:   # q is only read (views of a Rotation's storage); the chain's last row is free
        qk = np.multiply(qk, _ops.const(-1.0, q.dtype), out=w.rows[4])
    _abcd(q[0], q[i + 1], q[j + 1], qk, symmetric, _ops.ARRAYS, w.rows)
    return _angles(w, o, extrinsic, symmetric, sign, _HALF_PI, unit)


_HALF_PI = np.pi / 2


def _compiled_operands(i, j, k, symmetric, sign, extrinsic):
    """`_abcd` and `_operands` for one Euler sequence's plan, compiled for one rotation's
    four floats (`_ops.compiled`), as `_k_as_euler` and `_angles` run them on rows: the
    functions by `_ops.Kind`."""
    first = _FIRST_THIRD[extrinsic][0]

    def operands(op, stack, *q):
        qk = op.mul(q[k + 1], -1.0, None) if sign < 0 else q[k + 1]
        abcd = _abcd(q[0], q[i + 1], q[j + 1], qk, symmetric, op, _ops.NONE)
        return _operands(abcd, op, first)
    return _ops.compiled(operands, 4).kinds


_BOUNDS = _scale.BOUNDS   # (one lookup fewer a call)
_F64 = _ops.F64
_FLOAT64 = np.dtype(np.float64)


def _warn_gimbal(gimbal, suppress_warnings, stacklevel=4):
    if gimbal and not suppress_warnings:
        warnings.warn(_GIMBAL_MESSAGE, UserWarning, stacklevel=stacklevel)


@functools.lru_cache(maxsize=128)
def _euler_plan(seq):
    """The quaternion components an Euler sequence reads: (i, j, k, symmetric, sign, extrinsic),
    and the sequence's `_compiled_operands`."""
    axes, intrinsic = _check_str_seq(seq, 3)
    i, j, k = axes[::-1] if intrinsic else axes
    symmetric = i == k
    if symmetric:
        k = 3 - i - j
    plan = i, j, k, symmetric, (i - j) * (j - k) * (k - i) // 2, not intrinsic
    return plan + (_compiled_operands(*plan),)


def as_euler(q, seq, degrees=False, suppress_warnings=False, unit=False):
    """Euler angles of quaternions, as scipy's ``Rotation.as_euler``.

    Uses the quaternion method of Bernardes & Viollet (2022) as scipy does,
    with no rotation matrix.

    Parameters
    ----------
    q : ndarray, shape (..., 4)
        Scalar-first quaternions, not necessarily unit.
    seq : str
        3 axes from ``'xyz'`` (extrinsic) or ``'XYZ'`` (intrinsic).
    degrees : bool, default False
    suppress_warnings : bool, default False
        Do not warn about gimbal lock.
    unit : bool, default False
        The caller knows every q is a finite unit quaternion (`Rotation`'s
        storage): the range check of the squared norms is skipped (the same
        bits), and so is the errstate (such input cannot overflow).

    Returns
    -------
    ndarray, shape (..., 3)
        First and third angles in [-π, π]; the second in [0, π] for
        symmetric sequences (``'zxz'``) and in [-π/2, π/2] otherwise.  In
        gimbal lock (second angle within 1e-7 of its ends) the third angle is
        set to 0 and a `UserWarning` is issued.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._euler import from_euler, as_euler
    >>> q = from_euler("zyx", [90, 30, 10], degrees=True)
    >>> np.round(as_euler(q, "zyx", degrees=True), 9)
    array([90., 30., 10.])
    """
    if not isinstance(seq, str):
        check_seq(seq, 3)   # its TypeError
    if not unit:   # (unit: Rotation's own storage, a float array of quaternions)
        q = quat_array(q, "quat")
    plan = _euler_plan(seq)   # which checks seq
    if q.size == 4 and q.dtype is _FLOAT64 and q.ndim <= 2:   # one float64 or float32 rotation: the
        comps, kind = q.tolist() if q.ndim == 1 else q.tolist()[0], _F64   # same formula on its floats,
    else:                                     # as `_k_as_euler` (`_ops.floats64`'s test written out:
        comps, kind = _ops.floats32(q)        # a tenth of the call)
    one = None if comps is None else _angles_floats(plan[6][kind](*comps), plan[5], plan[3], plan[4], _HALF_PI, kind)
    if one is not None:   # (None also where the kernel would rescale or find gimbal lock, with its warning)
        out = one if q.ndim == 1 else one[None]   # (4,) or (1, 4) here
    else:
        i, j, k, symmetric, sign, extrinsic = plan[:6]
        if q.ndim == 2:   # (n, 4), as a Rotation stores them: no reshapes (a small call's cost)
            flat = q
            out = oflat = np.empty((len(q), 3), q.dtype)
        else:
            out = np.empty(q.shape[:-1] + (3,), q.dtype)
            flat, oflat = q.reshape(-1, 4), out.reshape(-1, 3)
        if unit and 0 < len(flat) <= _blocks.VIEWS_MAX:   # a Rotation's few: the kernel at once on
            gimbal = _k_as_euler(flat.T, oflat.T, i, j, k, symmetric, sign, extrinsic, True)   # views
        elif unit:   # up to a block on views too, then blocks on threads
            gimbal = _blocks.on_views(_k_as_euler, flat, oflat, i=i, j=j, k=k, symmetric=symmetric,
                                      sign=sign, extrinsic=extrinsic, unit=True)
        else:
            gimbal = _blockwise(_k_as_euler, [flat], [oflat], read_only=True, i=i, j=j, k=k,
                                symmetric=symmetric, sign=sign, extrinsic=extrinsic, unit=False)
        _warn_gimbal(gimbal, suppress_warnings)
    return np.rad2deg(out, out=out) if degrees else out


# --- Davenport angles ---------------------------------------------------------------------------

def check_order(order, typed=False):
    """True for extrinsic (``'e'``, ``'extrinsic'``), False for intrinsic (``'i'``, ``'intrinsic'``).
    `typed`: an order that is not a str is a TypeError (scipy's from_davenport, whose `order`
    is a typed argument), else a ValueError as any other order (its as_davenport).

    >>> from quatarray._euler import check_order
    >>> check_order("e")
    True
    """
    if order in ("e", "extrinsic"):
        return True
    if order in ("i", "intrinsic"):
        return False
    if typed and not isinstance(order, str):
        raise TypeError(f"expected order to be a str, 'e'/'extrinsic' or 'i'/'intrinsic', got {type(order).__name__}")
    raise ValueError(f"order should be 'e'/'extrinsic' for extrinsic sequences or 'i'/'intrinsic' "
                     f"for intrinsic sequences, got {order!r}")


def _unit_axes(axes, n=None, signed=False):
    """Davenport axes as unit float64 component rows, shape (3, k, ...): x, y and z of the k
    axes of a set, over the sets' batch: () for one set, (3,) or (k, 3); (...) for a set per
    rotation, (..., k, 3).

    Validated as scipy validates them, with its messages: vectors of length 3, 1 to 3 of
    them in a set (exactly `n` if given: as_davenport's 3), consecutive ones orthogonal,
    |cos| <= 1e-7 between them (scipy's from_davenport) or, with `signed`, cos < 1e-7 (its
    as_davenport's test, which lets obtuse axes through); besides, finite and non-zero
    (scipy would return NaN).  Each axis is scaled by the power of two of its largest
    component (exact, and no square can overflow or underflow), then divided by its norm:
    element by element, so a set of axes has the same unit axes alone and in any batch.
    """
    a = float_array(axes, "axes")
    shape = a.shape
    if n is not None and (a.ndim < 2 or shape[-2] != n):
        raise ValueError(f"Expected {n} axes, got {shape}.")
    if a.ndim == 0 or shape[-1] != 3:
        raise ValueError(f"Axes must be vectors of length 3: expected axes of shape (3,), (n, 3) or "
                         f"(..., n, 3), got {shape}")
    if a.ndim > 1 and not 1 <= shape[-2] <= 3:
        raise ValueError(f"Expected up to 3 axes, got {shape[-2]}: expected axes of shape (n, 3) or "
                         f"(..., n, 3) with n from 1 to 3, got {shape}")
    a = finite(a, "axes").astype(np.float64, copy=False)
    if a.ndim == 1:
        a = a[None]
    # the first calls read the strided components, the others contiguous rows (3, k, ...)
    comps = a.transpose((a.ndim - 1, a.ndim - 2) + tuple(range(a.ndim - 2)))
    largest = np.maximum(np.maximum(np.abs(comps[0]), np.abs(comps[1])), np.abs(comps[2]))
    if not largest.all():
        raise ValueError(f"expected non-zero axes, got a zero vector among axes of shape {shape}")
    power = np.negative(np.frexp(largest)[1])
    unit = np.empty((3,) + largest.shape)
    for c in range(3):
        np.ldexp(comps[c], power, out=unit[c])
    np.divide(unit, np.sqrt(_dot(unit, unit)), out=unit)
    cos = _dot(unit[:, 1:], unit[:, :-1])
    bad = cos >= 1e-7 if signed else np.abs(cos) > 1e-7
    if bad.any():
        raise ValueError(f"Consecutive axes must be orthogonal: got cos = "
                         f"{cos[bad][np.argmax(np.abs(cos[bad]))]:.3g} between them")
    return unit


def _dot(u, v):
    """u · v of vectors given as their component rows (x, y, z), summed in that order."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@functools.lru_cache(maxsize=64)
def _shared_axes(axes_bytes, shape, dtype):
    """`_unit_axes` of one set of axes (a float64 array's bytes and shape) as
    `_k_from_davenport` takes them: (k, 1, 3) in `dtype`, read-only; remembered, as the
    same few axes serve many calls and validating them costs more than one rotation."""
    axes = _unit_axes(np.frombuffer(axes_bytes).reshape(shape)).T.astype(dtype)[:, None, :]
    axes.flags.writeable = False
    return axes


def _k_from_davenport(angles, q, axes, extrinsic, scale):
    """One elementary quaternion (cos, sin · axis) per axis, all half angles in one call,
    composed in order with `_kernels.multiply` on (m, 4) rows.  `axes`: (k, 1, 3), one set
    for the block (`_shared_axes`), or (k, m, 3), a set per rotation
    (`_k_from_davenport_rows`): the same products, broadcast."""
    if angles.shape[1] == 1 and angles.dtype == np.float64:
        # one float64 rotation: each half angle's `half_angle` on its float (the same formula)
        cs = [_half_angle(a, scale) for a in angles[:, 0].tolist()]
        turns = np.array([[[c, s * x, s * y, s * z]] for (c, s), (x, y, z) in zip(cs, axes[:, 0].tolist())])
    else:
        c, s = _half_angle(angles, scale)                 # (k, m) each
        turns = np.empty(angles.shape + (4,), q.dtype)    # (k, m, 4): one elementary turn per axis
        turns[..., 0] = c
        np.multiply(s[..., None], axes, out=turns[..., 1:])
    p = turns[0]
    for e in turns[1:]:
        p = multiply(e, p) if extrinsic else multiply(p, e)
    np.copyto(q, p.T)


def _k_from_davenport_rows(angles, axes, q, extrinsic, scale):
    """`_k_from_davenport` with a set of axes per rotation: `axes` (3k, m), `_unit_axes`' rows
    (x of the k axes, then y, then z)."""
    k, m = angles.shape
    _k_from_davenport(angles, q, axes.reshape(3, k, m).transpose(1, 2, 0), extrinsic, scale)


def _angles_mismatch(angles, axes, k):
    return ValueError(f"Expected `angles` to match number of axes, got {angles.shape} angles and "
                      f"{axes.shape} axes: expected angles of shape (..., {k})"
                      + (f" broadcasting with the axes' {axes.shape[:-2]}" if axes.ndim > 2 else ""))


def from_davenport(axes, order, angles, degrees=False):
    """Unit quaternions of Davenport angles (Euler angles about any axes).

    Parameters
    ----------
    axes : array_like, shape (3,), (n, 3) or (..., n, 3), n ≤ 3
        Rotation axes (normalised here); consecutive axes must be orthogonal.
        A batch of sets of axes broadcasts with the angles' batch.
    order : {'e', 'extrinsic', 'i', 'intrinsic'}
    angles : array_like, shape (..., n)
        A scalar is accepted for a single axis.
    degrees : bool, default False

    Returns
    -------
    ndarray, shape (..., 4)
        In the angles' dtype.  A rotation has the same bits whether its axes are
        shared with the batch or its own: the same kernel, the shared axes broadcast.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._euler import from_davenport, from_euler
    >>> ez, ex = [0, 0, 1], [1, 0, 0]
    >>> q = from_davenport([ez, ex], "extrinsic", [90, 45], degrees=True)
    >>> np.allclose(q, from_euler("zx", [90, 45], degrees=True))
    True
    >>> from_davenport([[ez, ex], [ex, ez]], "e", [90, 45], degrees=True).shape
    (2, 4)
    """
    extrinsic = check_order(order, typed=True)
    ax = float_array(axes, "axes")
    a = float_array(angles, "angles")
    if a.ndim == 0:
        a = a.reshape(1)
    scale = np.pi / 720.0 if degrees else 0.25
    if ax.ndim > 2:   # a set per rotation, but maybe one set: the shared path (at half the cost)
        one = _one_set(ax, a.shape[:-1], lambda batch, axes: from_davenport(
            axes, order, np.broadcast_to(a, batch + a.shape[-1:]), degrees))
        if one is not None:
            return one
    if ax.ndim <= 2:   # one set of axes for every rotation
        key = ax.astype(np.float64, copy=False)
        turn_axes = _shared_axes(key.tobytes(), key.shape, a.dtype)
        k = turn_axes.shape[0]
        if a.shape[-1] != k:
            raise _angles_mismatch(a, ax, k)
        finite(a, "angles")
        out = np.empty(a.shape[:-1] + (4,), a.dtype)
        _blockwise(_k_from_davenport, [a.reshape(-1, k)], [out.reshape(-1, 4)],
                   axes=turn_axes, extrinsic=extrinsic, scale=scale, read_only=True)
        return out
    unit = _unit_axes(ax)   # a set of axes per rotation
    k, sets = unit.shape[1], unit.shape[2:]
    if a.shape[-1] != k:
        raise _angles_mismatch(a, ax, k)
    batch = _joint_batch(sets, a.shape[:-1], lambda: _angles_mismatch(a, ax, k))
    finite(a, "angles")
    rows = np.moveaxis(unit.astype(a.dtype, copy=False).reshape((3 * k,) + sets), 0, -1)   # (..., 3k) view
    out = np.empty(batch + (4,), a.dtype)
    _blockwise(_k_from_davenport_rows, [_flat(a, batch), _flat(rows, batch)], [out.reshape(-1, 4)],
               extrinsic=extrinsic, scale=scale, read_only=True)
    return out


def _one_set(ax, batch, shared):
    """Axes given per rotation (`ax`, (..., k, 3)) that are one set: ``shared(joint batch,
    the set (k, 3))``, the shared path broadcast (the same bits); None where they are more
    than one set, or where the shared path refuses the input (invalid axes or angles: the
    per-rotation path then raises with its own checks and messages)."""
    if ax.size == ax.shape[-2] * ax.shape[-1]:
        try:
            return shared(np.broadcast_shapes(ax.shape[:-2], batch), ax.reshape(ax.shape[-2:]))
        except ValueError:
            pass
    return None


def _joint_batch(axes_batch, batch, error):
    """The batch of rotations with a set of axes each: `axes_batch` and `batch` broadcast,
    or ``error()`` raised."""
    try:
        return np.broadcast_shapes(axes_batch, batch)
    except ValueError:
        raise error() from None


def _flat(a, batch):
    """`a` (..., k) broadcast to `batch` (..., k), as (N, k): a view where no axis is broadcast."""
    return np.broadcast_to(a, batch + a.shape[-1:]).reshape(-1, a.shape[-1])


def _davenport_floats(q, lmat, extrinsic, lamb, flip):
    """`_k_davenport_angles` on the floats of one float64 or float32 quaternion, or None (as
    `_angles_floats`)."""
    comps, kind = _ops.floats64(q), _F64
    if comps is None:
        comps, kind = _ops.floats32(q)
    if comps is None:
        return None
    abcd = _davenport_abcd(comps, lmat, kind.op, _ops.NONE, None)
    o = _angles_floats(_OPERANDS_FLOATS[extrinsic][kind](*abcd), extrinsic, False, 1, lamb, kind)
    if o is not None and flip:
        o[1] = -o[1]
    return o


def _davenport_abcd(q, lmat, op, rows, t):
    """(a, c, b, d) = L q (`_davenport_frame`'s L: the chain's order, `_ROWS`), each summed in one order
    (q0 c0 + q1 c1 + q2 c2 + q3 c3, left to right), in `op`'s arithmetic (`_ops`): into the
    first four `rows` with the work row `t` (or `_ops.NONE` and None on floats); returned as
    a list."""
    abcd = []
    for row, coef in zip(rows, lmat):
        row = op.mul(q[0], coef[0], row)
        for k in (1, 2, 3):
            row = op.add(row, op.mul(q[k], coef[k], t), row)
        abcd.append(row)
    return abcd


def _k_davenport_angles(q, o, lmat, extrinsic, lamb, sign):
    """(a, c, b, d) = L q (the chain's order, `_ROWS`) read by `_angles` without its λ step
    (as a symmetric sequence is read), then the middle angle less λ and times `sign`
    (`_davenport_frames`).  `lmat` (4 × 4), `lamb` and `sign` are one set of axes' numbers
    (floats, 0-d arrays of q's dtype; `sign` None for +1) or rows of q's dtype, a set per
    rotation (`_k_davenport_angles_rows`): the same operations, broadcast."""
    w = _euler_rows(q.shape[1:], q.dtype)
    _davenport_abcd(q, lmat, _ops.ARRAYS, w.rows, w.tmp)
    gimbal = _angles(w, o, extrinsic, True, 1, None)
    _asymmetric(o[1], None, 1, (None, lamb), _ops.ARRAYS, o[1], None)   # the middle angle less λ
    if sign is not None:
        np.multiply(o[1], sign, out=o[1])   # (not np.negative in place: see `_negate`)
    return gimbal


def _k_davenport_angles_rows(q, frame, o, extrinsic):
    """`_k_davenport_angles` with a set of axes per rotation: `frame` (18, m), the rows of
    `_davenport_frames`."""
    lmat = tuple(frame[r:r + 4] for r in _CHAIN_L_ROWS)
    return _k_davenport_angles(q, o, lmat, extrinsic, frame[16], frame[17])


_CHAIN_L_ROWS = (0, 8, 4, 12)
"""Where L's rows for a, c, b, d (the chain's order, `_ROWS`) start among `_davenport_frames`'
rows (a, b, c, d)."""


def as_davenport(q, axes, order, degrees=False, suppress_warnings=False):
    """Davenport angles (Euler angles about three given axes) of quaternions.

    The generalisation of Bernardes & Viollet's method that scipy uses: the
    quaternion is first turned by the angle λ between the first and third
    axes, then read like Euler angles.

    Parameters
    ----------
    q : ndarray, shape (..., 4)
    axes : array_like, shape (3, 3) or (..., 3, 3)
        Three axes; the middle one must be orthogonal to the other two.  A
        batch of sets of axes broadcasts with q's batch.
    order : {'e', 'extrinsic', 'i', 'intrinsic'}
    degrees : bool, default False
    suppress_warnings : bool, default False

    Returns
    -------
    ndarray, shape (..., 3)
        First and third angles in [-π, π], the second in a range of width π
        set by λ; gimbal lock warns and sets the third angle to 0.  A rotation
        has the same bits whether its axes are shared with the batch or its own.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray._euler import from_euler, as_davenport
    >>> ez, ex, ey = np.eye(3)[[2, 0, 1]]
    >>> q = from_euler("zxy", [90, 30, 10], degrees=True)
    >>> np.round(as_davenport(q, [ez, ex, ey], "e", degrees=True), 9)
    array([90., 30., 10.])
    >>> np.round(as_davenport(q, [[ez, ex, ey], [ez, ey, ez]], "e", degrees=True), 9)[0]
    array([90., 30., 10.])
    """
    extrinsic = check_order(order)
    q = quat_array(q, "quat")
    ax = float_array(axes, "axes")
    if ax.ndim > 2:   # a set per rotation, but maybe one set: the shared path (a twentieth of the cost)
        one = _one_set(ax, q.shape[:-1], lambda batch, axes: as_davenport(
            np.broadcast_to(q, batch + (4,)), axes, order, degrees, suppress_warnings))
        if one is not None:
            return one
    if ax.ndim <= 2:   # one set of axes for every rotation
        key = ax.astype(np.float64, copy=False)
        lmat, lamb, flip = _davenport_frame(key.tobytes(), key.shape, extrinsic)
        one = _davenport_floats(q, lmat, extrinsic, lamb, flip)
        if one is not None:   # one float64 or float32 rotation away from gimbal lock: the same formula on its floats
            out = one if q.ndim == 1 else one[None]   # (4,) or (1, 4) here
            return np.rad2deg(out, out=out) if degrees else out
        out = np.empty(q.shape[:-1] + (3,), q.dtype)
        gimbal = _blockwise(_k_davenport_angles, [q.reshape(-1, 4)], [out.reshape(-1, 3)], lmat=lmat,
                            extrinsic=extrinsic, lamb=_ops.const(lamb, q.dtype),
                            sign=_ops.const(-1.0, q.dtype) if flip else None)
    else:   # a set of axes per rotation
        frames = np.moveaxis(_davenport_frames(_unit_axes(ax, 3, signed=True), extrinsic).astype(q.dtype, copy=False),
                             0, -1)   # (..., 18) view
        batch = _joint_batch(frames.shape[:-1], q.shape[:-1], lambda: ValueError(
            f"Expected `axes` to match number of rotations, got {ax.shape} axes and {q.shape} rotations: "
            f"expected axes of shape (..., 3, 3) broadcasting with {q.shape[:-1]}"))
        out = np.empty(batch + (3,), q.dtype)
        gimbal = _blockwise(_k_davenport_angles_rows, [_flat(q, batch), _flat(frames, batch)],
                            [out.reshape(-1, 3)], extrinsic=extrinsic, read_only=True)
    _warn_gimbal(gimbal, suppress_warnings)
    return np.rad2deg(out, out=out) if degrees else out


@functools.lru_cache(maxsize=64)
def _davenport_frame(axes_bytes, shape, extrinsic):
    """`_davenport_frames` of one set of axes (a float64 array's bytes and shape) as
    `as_davenport` takes them: (L as nested tuples of floats, its rows in the chain's order
    ``[a, c, b, d]`` (`_ROWS`), λ, flip); remembered, as the same few axes serve many calls
    and building L costs more than one rotation."""
    unit = _unit_axes(np.frombuffer(axes_bytes).reshape(shape), 3, signed=True)
    frame = _davenport_frames(unit[..., None], extrinsic)[:, 0].tolist()   # (a batch of one: the batches' calls)
    return tuple(tuple(frame[r:r + 4]) for r in _CHAIN_L_ROWS), frame[16], frame[17] < 0


def _davenport_frames(unit, extrinsic):
    """What `as_davenport` reads rotations with, per set of unit axes (`_unit_axes`' rows
    (3, 3, ...)): rows (18, ...), the matrix L (16, row by row) that gives Bernardes &
    Viollet's (a, b, c, d) = L q, the angle λ between the first and third axes and the sign
    (±1) of the middle angle.

    As scipy: q is turned by λ about n2, then read along n1, n2 and n1 × n2; where λ < 0, n2
    is reversed instead (λ in [0, π], the middle angle's sign flipped), which keeps the
    angles compatible with `as_euler`.  Element by element, each sum in one order (no matrix
    product): a set of axes gets the same numbers alone and in any batch."""
    n1, n2, n3 = unit[:, 0], unit[:, 1], unit[:, 2]   # component rows (3, ...)
    if not extrinsic:
        n1, n3 = n3, n1
    # row by row (on long batches, (3, 4, ...) stacks of the products would leave the cache)
    ncross = [n1[1] * n2[2] - n1[2] * n2[1], n1[2] * n2[0] - n1[0] * n2[2], n1[0] * n2[1] - n1[1] * n2[0]]
    frames = np.empty((18,) + unit.shape[2:])
    lamb = np.arctan2(_dot(n3, ncross), _dot(n3, n1), out=frames[16])
    sign = frames[17]
    sign[...] = np.where(lamb < 0, -1.0, 1.0)
    n2, ncross = [c * sign for c in n2], [c * sign for c in ncross]
    np.multiply(lamb, sign, out=lamb)
    p0, s = _half_angle(lamb, 0.25)
    x, y, z = s * n2[0], s * n2[1], s * n2[2]
    left = [[p0, -x, -y, -z], [x, p0, -z, y], [y, z, p0, -x], [z, -y, x, p0]]   # q_λ q = left · q
    frames[0:4] = left[0]
    for r, n in enumerate((n1, n2, ncross)):   # L = P · left, P = diag(1, [n1; n2; n1 × n2])
        for j in range(4):
            np.add(n[0] * left[1][j] + n[1] * left[2][j], n[2] * left[3][j], out=frames[4 + 4 * r + j])
    return frames
