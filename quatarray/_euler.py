"""Euler and Davenport angles <-> scalar-first quaternions, on raw ndarrays.

All 12 Euler sequences (lower case extrinsic, upper case intrinsic) and
Davenport angles about arbitrary axes, following scipy 1.17's conventions,
angle ranges and gimbal-lock `UserWarning`.  ``from_*`` multiplies the
elementary rotations in closed form; ``as_*`` is the quaternion method of
Bernardes & Viollet (no matrices).  Blocks, dtypes and half angles as in
`_convert`.
"""

import functools
import warnings

import numpy as np

from . import _blocks, _ops, _scale
from ._convert import _blockwise
from ._kernels import cos_sin as _cos_sin
from ._kernels import half_angle as _half_angle
from ._kernels import arctan2, multiply
from ._validate import finite, float_array, quat_array

__all__ = ["check_seq", "from_euler", "as_euler", "check_order", "from_davenport", "as_davenport"]

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
    a = finite(float_array(angles, "angles"), "angles")
    if a.ndim == 0:
        a = a.reshape(1)
    if a.shape[-1] != len(axes):
        raise ValueError(f"expected angles of shape (..., {len(axes)}) for seq {seq!r}, got {a.shape}")
    scale = np.pi / 720.0 if degrees else 0.25
    one = _ops.floats64(a, len(axes))
    if one is not None:   # one float64 rotation: the same formula on its floats
        p = _euler_quat(one, axes, intrinsic, scale, _ops.FLOATS, _ops.NONE)
        return _ops.to_array([0.0 if v is None else v for v in p], a.shape[:-1] + (4,))
    out = np.empty(a.shape[:-1] + (4,), a.dtype)
    _blockwise(_k_from_euler, [a.reshape(-1, len(axes))], [out.reshape(-1, 4)],
               axes=axes, intrinsic=intrinsic, scale=scale)
    return out


def _norms(abcd, op, stack, sq, n):
    """``|(a, b)|², |(c, d)|²`` of Bernardes & Viollet's a, b, c, d (`abcd`: four rows, or
    one rotation's four floats) in `op`'s arithmetic (`_ops`, `stack` its stacked form: the
    four squares are one call, into `sq`, four rows), into the two rows `n`."""
    sq = stack.mul(abcd, abcd, sq)
    return op.add(sq[0], sq[1], n[0]), op.add(sq[2], sq[3], n[1])


_FIRST_THIRD = {True: (0, 2), False: (2, 0)}
"""`_arguments`' `first` and `third` by `extrinsic`: the rows of arctan2's three
arguments that hold the angle from ``ac + bd`` and the one from ``ac - bd`` (rows in the
output's order of angles, which an intrinsic sequence reverses)."""


def _arguments(abcd, u2, r2, op, first, third, yx, work):
    """arctan2's numerators ``[im₁, r, im₂]`` and denominators ``[re₁, u, re₂]``, in the rows'
    order of the angles (`first`, `third`), from a, b, c, d (`abcd`) and `_norms`' ``u2``,
    ``r2``, in `op`'s arithmetic (`_ops`): ``(a + ib)(c ∓ id) = re + i im`` (re₁ = ac + bd,
    re₂ = ac - bd, im₁ = bc - ad, im₂ = bc + ad), ``r = |(c, d)|``, ``u = |(a, b)|``; into the
    six rows `yx` (numerators, then denominators) with the two work rows `work`."""
    a, b, c, d = abcd[0], abcd[1], abcd[2], abcd[3]
    ys, xs = [None] * 3, [None] * 3
    ys[1] = op.sqrt(r2, yx[1])
    xs[1] = op.sqrt(u2, yx[4])
    ac = op.mul(a, c, work[0])
    bd = op.mul(b, d, work[1])
    xs[first] = op.add(ac, bd, yx[3 + first])
    xs[third] = op.sub(ac, bd, yx[3 + third])
    bc = op.mul(b, c, work[0])
    ad = op.mul(a, d, work[1])
    ys[first] = op.sub(bc, ad, yx[first])
    ys[third] = op.add(bc, ad, yx[third])
    return ys, xs


def _operands(abcd, op, stack, first, third):
    """`_norms` and `_arguments` on floats: arctan2's three numerators and three
    denominators, and |(a, b, c, d)|² (for the range check), seven floats."""
    u2, r2 = _norms(abcd, op, stack, None, _ops.NONE)
    ys, xs = _arguments(abcd, u2, r2, op, first, third, _ops.NONE, _ops.NONE)
    return ys + xs + [op.add(u2, r2, None)]


def _angles_floats(v, extrinsic, symmetric, sign, lamb):
    """`_angles` on one rotation's floats, from `_operands`' seven: the three angles as a new
    float64 array (3,), or None where the array kernel would rescale or find gimbal lock
    (its own path, with the warning)."""
    if not _LOW64 <= v[6] <= _HIGH64:
        return None
    angles = arctan2(v[0:3], v[3:6])   # a new array (3,): the result, as the floats give it
    mid = angles.item(1) * 2.0
    if mid <= _GIMBAL_EPS or mid >= _PI_LOCK:
        return None
    if not symmetric:
        third = 2 if extrinsic else 0
        mid, value = _ASYMMETRIC_FLOATS[sign](mid, angles.item(third), lamb)
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
    _asymmetric(mid, third, sign, (-1.0, lamb), op, None, None)), 3) for sign in (-1, 1)}
"""`_asymmetric` on one rotation's floats ``(mid, third, λ)``, by sign (`_ops.compiled`)."""


def _angles(abcd, o, extrinsic, symmetric, sign, lamb, unit=False):
    """Bernardes & Viollet's step 2-3 from a, b, c, d (`abcd`: four rows (4, m), a buffer that
    may be rescaled in place) into o (three rows).  Returns whether any element is in gimbal
    lock.  One rotation's floats take `_operands` and `_angles_floats`: the same operations.

    The middle angle is 2 atan2(|(c, d)|, |(a, b)|); the first and third angles are
    half_sum ∓ half_diff with half_sum = arg(a + ib) and half_diff = arg(c + id), each read as
    one argument, of (a + ib)(c ∓ id) = Re + i Im, which lands in [-π, π] without the wrap
    scipy applies to the sum.  The three arctangents (`_kernels.arctan2`) are one call on
    arrays, numerators and denominators stacked in the rows' order of `o`, written into it.
    In gimbal lock (middle angle within 1e-7 of 0 or π) the third angle is set to 0 and the
    first takes the whole turn, as in scipy.  `unit`: a, b, c, d come from finite unit
    quaternions (`Rotation`'s storage), whose squared norms always fit: no range check."""
    first, third = _FIRST_THIRD[extrinsic]
    op = _ops.ARRAYS
    shape, dtype = abcd.shape[1:], abcd.dtype
    rows = (_blocks.scratch().rows(15, shape, dtype) if abcd.size > 4 * _blocks.FEW
            else np.empty((15,) + shape, dtype))
    # rows 0-3: squares, then products; 4-5: the norms; 6-8 and 9-11: arctan2's numerators
    # and denominators in the rows' order of o; 12-14: the arctangents
    n = (rows[4], rows[5])   # rows by indexing (a fifth of the cost of unpacking an array)
    u2, r2 = _norms(abcd, op, op, rows[0:4], n)   # (on a block's contiguous rows ARRAYS stacks too)
    if not unit:   # the range guard of `_scale`, on |(a, b, c, d)|² (|q|² or 2|q|²)
        n2 = np.add(u2, r2, out=rows[9])
        if not _scale.fits(n2):
            if not np.isfinite(abcd).all():
                raise ValueError(_scale.NONFINITE)
            _scale.rescale(abcd, _scale.outside(n2))   # by powers of two: the angles are unchanged
            u2, r2 = _norms(abcd, op, op, rows[0:4], n)
            if not np.add(u2, r2, out=rows[9]).all():
                raise ValueError(_scale.ZERO)
    _arguments(abcd, u2, r2, _ops.ARRAYS, first, third, (rows[6], rows[7], rows[8], rows[9], rows[10], rows[11]),
               (rows[2], rows[3]))
    T = rows[12:15]
    # into contiguous rows, then copied: a transcendental loop's bits may depend on the
    # layout (SIMD for contiguous rows), and o is strided
    arctan2(rows[6:9], rows[9:12], out=T, defined=unit)
    o0, o1, o2 = o[0], o[1], o[2]
    mid = np.multiply(T[1], _ops.const(2.0, dtype), out=o1)          # the middle angle, in [0, π]
    lo, hi = _extremes(mid)
    gimbal = lo <= _GIMBAL_EPS or hi >= _PI_LOCK
    if gimbal:
        mid = mid.copy()
    angles = [T[0], o1, T[2]]
    angles[first] = op.copy(angles[first], o0 if first == 0 else o2)
    if symmetric or sign > 0:
        angles[third] = op.copy(angles[third], o2 if third == 2 else o0)
    if not symmetric:
        angles[1], angles[third] = _asymmetric(angles[1], angles[third], sign,
                                               (_ops.const(-1.0, dtype), _ops.const(lamb, dtype)), op,
                                               angles[1], o2 if third == 2 else o0)
    if gimbal:
        _lock(abcd, mid, o, extrinsic, third, -1.0 if not symmetric and sign < 0 else 1.0)
    return gimbal


_PI_LOCK = np.pi - _GIMBAL_EPS


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
    signed), in `op`'s arithmetic (`_ops`), into the four `rows`."""
    if symmetric:
        return [op.copy(w, rows[0]), op.copy(qi, rows[1]), op.copy(qj, rows[2]), op.copy(qk, rows[3])]
    return [op.sub(w, qj, rows[0]), op.add(qi, qk, rows[1]), op.add(qj, w, rows[2]), op.sub(qk, qi, rows[3])]


def _k_as_euler(q, o, i, j, k, symmetric, sign, extrinsic, unit=False):
    s = q.shape[1:]
    abcd = _blocks.scratch().rows(5, s, q.dtype) if q.size > 4 * _blocks.FEW else np.empty((5,) + s, q.dtype)
    w, qi, qj, qk = q[0], q[i + 1], q[j + 1], q[k + 1]
    if sign < 0:   # q is only read (views of a Rotation's storage)
        qk = np.multiply(qk, _ops.const(-1.0, q.dtype), out=abcd[4])
    _abcd(w, qi, qj, qk, symmetric, _ops.ARRAYS, abcd)
    return _angles(abcd[:4], o, extrinsic, symmetric, sign, _HALF_PI, unit)


def _euler_floats(q, plan):
    """`_k_as_euler` on the floats of one float64 quaternion, or None where the kernel would
    rescale or find gimbal lock (its own path, with the warning)."""
    comps = _ops.floats64(q)
    if comps is None:
        return None
    return _angles_floats(plan[6](*comps), plan[5], plan[3], plan[4], _HALF_PI)


_HALF_PI = np.pi / 2


def _compiled_operands(i, j, k, symmetric, sign, extrinsic):
    """`_abcd` and `_operands` for one Euler sequence's plan, compiled for one rotation's
    four floats (`_ops.compiled`), as `_k_as_euler` and `_angles` run them on rows."""
    first, third = _FIRST_THIRD[extrinsic]

    def operands(op, stack, *q):
        qk = op.mul(q[k + 1], -1.0, None) if sign < 0 else q[k + 1]
        abcd = _abcd(q[0], q[i + 1], q[j + 1], qk, symmetric, op, _ops.NONE)
        return _operands(abcd, op, stack, first, third)
    return _ops.compiled(operands, 4)


_F64 = np.dtype(np.float64)
_LOW64, _HIGH64 = _scale.LOW[_F64], _scale.HIGH[_F64]


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
    one = _euler_floats(q, plan)
    if one is not None:   # one float64 rotation away from gimbal lock: the same formula on its floats
        out = one if q.ndim == 1 else one[None]   # (4,) or (1, 4) here
    else:
        i, j, k, symmetric, sign, extrinsic = plan[:6]
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
        # one float64 rotation: each half angle's `cos_sin` on its float (the same formula)
        cs = [_cos_sin(a * (2 * scale)) for a in angles[:, 0].tolist()]
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
    """`_k_davenport_angles` on the floats of one float64 quaternion, or None (as
    `_angles_floats`)."""
    comps = _ops.floats64(q)
    if comps is None:
        return None
    first, third = _FIRST_THIRD[extrinsic]
    abcd = _davenport_abcd(comps, lmat, _ops.FLOATS, _ops.NONE, None)
    o = _angles_floats(_operands(abcd, _ops.FLOATS, _ops.FLOAT_STACKS, first, third), extrinsic, False, 1, lamb)
    if o is not None and flip:
        o[1] = -o[1]
    return o


def _davenport_abcd(q, lmat, op, rows, t):
    """(a, b, c, d) = L q, each summed in one order (q0 c0 + q1 c1 + q2 c2 + q3 c3, left to
    right), in `op`'s arithmetic (`_ops`): into the four `rows` with the work row `t` (or
    `_ops.NONE` and None on floats); returned as a list."""
    abcd = []
    for row, coef in zip(rows, lmat):
        row = op.mul(q[0], coef[0], row)
        for k in (1, 2, 3):
            row = op.add(row, op.mul(q[k], coef[k], t), row)
        abcd.append(row)
    return abcd


def _k_davenport_angles(q, o, lmat, extrinsic, lamb, sign):
    """(a, b, c, d) = L q read by `_angles` without its λ step (as a symmetric sequence is
    read), then the middle angle less λ and times `sign` (`_davenport_frames`).  `lmat`
    (4 × 4), `lamb` and `sign` are one set of axes' numbers (floats, 0-d arrays of q's
    dtype; `sign` None for +1) or rows of q's dtype, a set per rotation
    (`_k_davenport_angles_rows`): the same operations, broadcast."""
    with _blocks.scratch().frame() as work:
        A = work.rows(4, q.shape[1:], q.dtype)
        _davenport_abcd(q, lmat, _ops.ARRAYS, A, work.rows(1, q.shape[1:], q.dtype)[0])
        gimbal = _angles(A, o, extrinsic, True, 1, None)
    _asymmetric(o[1], None, 1, (None, lamb), _ops.ARRAYS, o[1], None)   # the middle angle less λ
    if sign is not None:
        np.multiply(o[1], sign, out=o[1])   # (not np.negative in place: see `_negate`)
    return gimbal


def _k_davenport_angles_rows(q, frame, o, extrinsic):
    """`_k_davenport_angles` with a set of axes per rotation: `frame` (18, m), the rows of
    `_davenport_frames`."""
    lmat = (frame[0:4], frame[4:8], frame[8:12], frame[12:16])
    return _k_davenport_angles(q, o, lmat, extrinsic, frame[16], frame[17])


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
    if ax.ndim <= 2:   # one set of axes for every rotation
        key = ax.astype(np.float64, copy=False)
        lmat, lamb, flip = _davenport_frame(key.tobytes(), key.shape, extrinsic)
        one = _davenport_floats(q, lmat, extrinsic, lamb, flip)
        if one is not None:   # one float64 rotation away from gimbal lock: the same formula on its floats
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
    `as_davenport` takes them: (L as nested tuples of floats, λ, flip); remembered, as the
    same few axes serve many calls and building L costs more than one rotation."""
    unit = _unit_axes(np.frombuffer(axes_bytes).reshape(shape), 3, signed=True)
    frame = _davenport_frames(unit[..., None], extrinsic)[:, 0].tolist()   # (a batch of one: the batches' calls)
    return tuple(tuple(frame[r:r + 4]) for r in range(0, 16, 4)), frame[16], frame[17] < 0


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
