"""Interpolation kernels on raw ndarrays (no `QuatArray` here).

Layout.  Inside a block the maths runs on *structure-of-arrays* views: a
block of quaternions of batch shape ``s`` is held as an array of shape
``(4, *s)`` (components first), so every NumPy call streams over long
contiguous rows.  The block engine (`_blocks.blockwise`) copies blocks in
from the caller's ``(..., 4)`` arrays and hands the kernels
``np.moveaxis(out, -1, 0)`` views of a preallocated output; scratch rows
come from the thread's bounded `_blocks.scratch()`, so a call allocates
O(BLOCK) extra memory whatever the size of its input.

SLERP weights.  For quaternions A, B (unit), with a = |B - A|, b = |B + A|,
the angle between them is Omega = 2 atan2(a, b) and rho = a / b =
tan(Omega / 2).  With tau = tan(h Omega / 2) the weights of
``w0 A + w1 B`` are, exactly,

    w1 = sin(h Omega) / sin(Omega) = (tau / rho) (1 + rho^2) / (1 + tau^2)
    w0 = cos(h Omega) - cos(Omega) w1
       = ((1 - tau^2) - (1 - rho^2) tau / rho) / (1 + tau^2)

so one call to arctan and one to tan replace the calls to sin that the
textbook formula needs, and no 1 - cos cancellation appears: for tiny
angles tau / rho -> h with full relative accuracy.  That is the float64
route: float64 sin has no SIMD loop on AVX-512 CPUs, where tan and arctan
are cheap.  float32 takes the textbook sines (w1 = sin(h Omega) /
sin(Omega), Omega from arcsin): float32 sin and arcsin are SIMD loops on
every x86 CPU, tan and arctan are not (costs in benchmarks/README.md).
"""

from math import prod
from types import SimpleNamespace

import numpy as np

from . import _blocks
from . import _ops
from . import _scale
from ._blocks import soa
from ._kernels import _COS_SIN, _cos_sin_of_tangent, cos_sin, normalize, normalize_block, result_dtype
from ._trig import SIMD_TAN, atan_unit32, tan, tan_float
from ._validate import all_finite

__all__ = [
    "vdot", "soa", "sqsum", "slerp_weights", "hemisphere", "arcs", "slerp_core", "squad_param", "squad_blend",
    "frame_core", "frames", "slerp", "lerp", "nlerp", "squad", "bezier", "unflip", "unit_keys",
]


_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))
_TINY = {np.dtype(d): (np.sqrt(np.finfo(d).tiny), 4 * np.finfo(d).tiny) for d in (np.float32, np.float64)}


def _tiny(dtype):
    """Smallest rho = tan(Omega/2) kept as is: its square is still a normal number."""
    return _TINY[np.dtype(dtype)][0]


def _floor(dtype):
    """Floor for b² = |B + A|² (4 · smallest normal): keeps a²/b² finite and quiet."""
    return _TINY[np.dtype(dtype)][1]


def _rows(n, s, dtype):
    return _blocks.scratch().rows(n, s, dtype)


def vdot(p, q, axis=-1):
    """Dot products of real vectors along `axis` (-1: (..., n); 0: components first).

    Summed component by component in a fixed order, so that every element's
    result is the same whatever the size or layout of the batch (a batch of
    tracks gives bit for bit the tracks built one by one; einsum's and
    vecdot's summation order depends on the batch size).
    """
    n = p.shape[axis]
    if axis == 0:
        out = p[0] * q[0]
        for k in range(1, n):
            out += p[k] * q[k]
    elif p.size <= _blocks.BLOCK and p.shape == q.shape:
        # few vectors: all products in one call, then summed in the same order (the same bits)
        pq = p * q
        out = pq[..., 0] + pq[..., 1]
        for k in range(2, n):
            out += pq[..., k]
    else:
        out = p[..., 0] * q[..., 0]
        for k in range(1, n):
            out += p[..., k] * q[..., k]
    return out


def sqsum(T, out):
    """out = T[0]² + ... + T[3]² for a (4, ...) array (T is overwritten), in `_scale.squares`'
    order."""
    return _scale._summed(np.multiply(T, T, out=T), out)


# --------------------------------------------------------------------------
# SLERP between two blocks (angle computed at run time)
# --------------------------------------------------------------------------

def slerp_weights(a2, b2, h, sign=None):
    """The SLERP weights (w0, w1) of ``w0 A + w1 B``, written once for every path.

    a2 = |B - A|², b2 = |B + A|² (arrays of one shape, both overwritten),
    h broadcastable to them.  `sign`: None follows B as given; otherwise an
    array of the sign of A·B (see `hemisphere`), and B counts as -B where it
    is negative (w1 then carries the sign; +0 keeps B).  Accurate for
    A·B >= 0 after the flip (weights at most sqrt(2)); `slerp_core` computes
    the wide arcs (A·B < 0, followed as given) and extrapolation beyond -1 and 2 by
    `arcs` instead.
    Returns views into the thread's scratch: use them before the caller's
    scratch frame ends.
    """
    s = a2.shape
    dtype = a2.dtype
    r2, rho, tau, t2, w0 = _rows(5, s, dtype)
    if sign is not None:
        r2, b2 = _folded(a2, b2, _ops.ARRAYS, r2)
    else:
        np.copyto(r2, a2)
    if dtype == np.float32:
        w0, w1 = _sine_weights(r2, b2, h, w0, tau, t2, rho)
    else:
        w0, w1 = _tangent_weights(r2, b2, h, w0, tau, t2, rho, a2)
    if sign is not None:
        w1 = _signed(w1, sign, _ops.const(1.0, dtype), _ops.ARRAYS, sign)
    return w0, w1


def _folded(a2, b2, op, r2):
    """The chords (r², b²) of the arc followed where B counts as -B for A·B < 0, whose chords
    |B - A| and |B + A| then swap: the shorter first, written once, in `op`'s arithmetic
    (`_ops`), into `r2` and `b2`."""
    return op.min(a2, b2, r2), op.max(a2, b2, b2)


def _signed(w1, d, one, op, sign):
    """w1 for B counted as -B where ``d = b² - a² = 4 A·B`` (`hemisphere`) is negative: times
    ``copysign(1, d)`` (d = +0, as x - x is: ties keep B), written once (`one`: 1 as `op`'s
    operand; `sign` a work row, may be d)."""
    sign = op.copysign(one, d, sign)
    return op.mul(w1, sign, w1)


def _sine_weights(r2, b2, h, w0, th, s2, w1):
    """float32 weights sin((1 - h) Ω) / sin Ω and sin(h Ω) / sin Ω, Ω = 2θ with
    tan θ = sqrt(r2 / b2) <= 1: float32 sin is a SIMD loop, and θ comes from
    `_trig.atan_unit32` (NumPy's float32 arcsin and arctan are scalar loops on
    AVX2; benchmarks/README.md)."""
    dtype = r2.dtype
    return _sine_formula(r2, b2, h, _ops.ARRAYS, lambda x, out: atan_unit32(x, out, r2, b2, w0), _CAST_ROWS.mul,
                         _ops.row(_floor(dtype), dtype, b2.shape), _ops.row(_tiny(dtype), dtype, th.shape),
                         w0, th, s2, w1)


def _sine_formula(r2, b2, h, op, atan, times, floor, tiny, w0, th, s2, w1):
    """`_sine_weights`' formula, written once, in `op`'s arithmetic with the arctangent
    ``atan(x, out)`` of x in [0, 1] (`atan_unit32`'s), ``times(th, h, out)``: th·h rounded
    to th's dtype (h of any float dtype), and the floors `floor`, `tiny` of b² and θ; into
    the rows `w0`, `th`, `s2`, `w1` (r2 and b2 are overwritten).  Returns (w0, w1)."""
    b2 = op.max(b2, floor, b2)
    s2 = op.div(r2, b2, s2)
    s2 = op.sqrt(s2, s2)
    th = atan(s2, th)                         # (rows: r2, b2 and w0 are not needed again)
    th = op.max(th, tiny, th)                 # sin(2hθ) / sin(2θ) -> h at θ = 0
    th = op.mul(th, 2.0, th)                  # Ω
    s2 = op.sin(th, s2)
    s2 = op.div(1.0, s2, s2)                  # 1 / sin Ω
    w1 = times(th, h, w1)
    w0 = op.sub(th, w1, w0)                   # (1 - h) Ω
    w1 = op.sin(w1, w1)
    w0 = op.sin(w0, w0)
    return op.mul(w0, s2, w0), op.mul(w1, s2, w1)


def _tangent_weights(r2, b2, h, w0, tau, t2, rho, a2):
    """float64 weights from rho = tan(Ω/2) and tau = tan(h Ω/2) (module docstring)."""
    dtype = r2.dtype
    return _tangent_formula(r2, b2, h, _ops.ARRAYS, _TANGENT_ROWS, _ops.row(_floor(dtype), dtype, b2.shape),
                            _ops.row(_tiny(dtype), dtype, rho.shape), _ONE64, w0, tau, t2, rho, a2)


def _tangent_formula(r2, b2, h, op, fns, floor, tiny, one, w0, tau, t2, rho, a2):
    """`_tangent_weights`' formula on rows, in `op`'s arithmetic with ``fns = (arctan, tan,
    times)`` (``times(tau, h)``: tau·h, h of any real dtype) and the constants `floor`, `tiny`
    (rows made read-only) and `one` (a 0-d array): `_tangent_angle`, the tangent, then
    `_tangent_blend`.  Returns (w0, w1)."""
    arctan, tan_, times = fns
    r2, rho, tau = _tangent_angle(r2, b2, h, op, arctan, times, floor, tiny, rho, tau)
    tau = tan_(tau, out=tau, rows=(t2, w0, a2))
    return _tangent_blend(tau, r2, rho, op, one, w0, t2, a2)


def _tangent_angle(r2, b2, h, op, arctan, times, floor, tiny, rho, tau):
    """The first half of the weights' formula, written once: (rho², rho, h Ω / 2) from
    a² (`r2`, overwritten) and b², rho = a / b = tan(Ω / 2) (`_tangent_formula`)."""
    # b² = 0 only for zero input (or B = -A followed as given, see `arcs`):
    # a floor keeps the division finite and quiet (no errstate needed)
    b2 = op.max(b2, floor, b2)
    r2 = op.div(r2, b2, r2)
    rho = op.sqrt(r2, rho)
    rho = op.max(rho, tiny, rho)
    return r2, rho, times(arctan(rho, tau), h)


def _tangent_blend(tau, r2, rho, op, one, w0, t2, a2):
    """The second half, written once: (w0, w1) from tau = tan(h Ω / 2), rho² and rho."""
    t2 = op.mul(tau, tau, t2)
    v = op.div(tau, rho, tau)            # tau / rho  (-> h for tiny angles)
    g = op.add(t2, one, rho)
    g = op.div(one, g, g)                # 1 / (1 + tau²)
    w0 = op.sub(one, r2, w0)
    w0 = op.mul(w0, v, w0)
    w0 = op.add(t2, w0, w0)              # tau² + (1 - rho²) v
    w0 = op.sub(one, w0, w0)
    w0 = op.mul(w0, g, w0)
    w1 = op.add(r2, one, a2)
    w1 = op.mul(w1, v, w1)
    w1 = op.mul(w1, g, w1)
    return [w0, w1]


# (0-d arrays: a Python scalar operand costs a conversion per ufunc call)
_ONE64 = _ops.const(1.0, np.float64)
_TANGENT_ROWS = (lambda x, out: np.arctan(x, out=out), tan,
                 lambda tau, h: np.multiply(tau, h, out=tau, casting="unsafe"))


def hemisphere(A, B, a2, b2, out):
    """out = b2 - a2 = 4 A·B (components first), with the sign of A·B summed in float64.

    In float32 the difference of the rounded squares cannot resolve a dot
    product below about 1e-6 (rotations within about 1e-6 rad of π apart);
    there the dot is summed again in float64, where the products of float32
    numbers are exact.
    """
    out = _chord_difference(a2, b2, _ops.ARRAYS, out)
    if out.dtype == np.float32:   # (in scratch rows: four fresh block-sized temporaries cost page faults)
        bound, size = _rows(2, out.shape, out.dtype)
        unsure = np.less_equal(*_doubt32(a2, b2, out, _ops.ARRAYS, size, bound))
        if unsure.any():
            s = out.shape
            at = _where(unsure)
            d = vdot(np.broadcast_to(A, (4,) + s)[at].astype(np.float64),
                     np.broadcast_to(B, (4,) + s)[at].astype(np.float64), 0)
            out[at[1:]] = np.sign(d)      # 0 stays +0: ties keep B
    return out


def _chord_difference(a2, b2, op, out):
    """``b² - a² = |B + A|² - |B - A|² = 4 A·B``, written once, in `op`'s arithmetic."""
    return op.sub(b2, a2, out)


#: |b² - a²| below this times a² + b² leaves the float32 sign of A·B in doubt.
_UNSURE32 = np.float32(64 * np.finfo(np.float32).eps)


def _doubt32(a2, b2, d, op, size, bound):
    """(|d|, (a² + b²) `_UNSURE32`) for d = b² - a² in float32, in `op`'s arithmetic (into
    the rows `size`, `bound`): the sign of A·B is in doubt where the first is at most the
    second (`hemisphere`)."""
    bound = op.add(a2, b2, bound)
    return op.abs(d, size), op.mul(bound, _UNSURE32, bound)


def _where(mask):
    """Index of the True elements of `mask` for (k, *mask.shape) arrays: integer
    indices, since boolean indexing of every component row rescans the mask."""
    return (slice(None),) + np.nonzero(mask)


def arcs(A, B, h, O, where, sign=None):
    """O[:, where] = slerp(A, B, h) as ``cos(h Ω) A + sin(h Ω) P``, the arc from A along P.

    For the pairs the weights of ``w0 A + w1 B`` serve badly: wide arcs (A·B < 0, B
    followed as given), where they grow like 1 / |A + B| near B = -A, and extrapolation
    (h < -1 or h > 2), where they grow like |h| while their sum stays near 1: both
    cancel.  P is the unit vector of ``V - (A·V) A / |A|²``, V the shorter of D = B - A
    and S = B + A (exact for nearly equal or nearly opposite inputs), so P is accurate and
    orthogonal to A, and the output's norm that of A whatever h.  `sign`: ±1 rows (see
    `slerp_weights`), B counting as -B where -1.  B = c A exactly (c ≠ 0) has no unique
    arc: the rotation stays constant, A before the midpoint and B from it on.
    """
    s = O.shape[1:]
    at = _where(where)
    a = np.broadcast_to(A, (4,) + s)[at]
    b = np.broadcast_to(B, (4,) + s)[at]
    if sign is not None:
        b = b * sign[at[1:]]
    hh = np.broadcast_to(h, s)[at[1:]]
    S = a + b
    D = b - a
    a2, d2, s2 = vdot(a, a, 0), vdot(D, D, 0), vdot(S, S, 0)
    V = np.where(d2 <= s2, D, S)
    P = _rejection(V, a, a2)
    pn = np.sqrt(vdot(P, P, 0))
    flat = ~(pn > 0)
    pn[flat] = 1
    ang = np.arctan2(np.sqrt(d2), np.sqrt(s2))
    ang *= 2 * hh
    res = np.cos(ang) * a + (np.sin(ang) * (np.sqrt(a2) / pn)) * P   # P at |A|: homogeneous
    if flat.any():
        res[:, flat] = np.where(hh[flat] < 0.5, a[:, flat], b[:, flat])
    O[at] = res.astype(O.dtype, copy=False)


def _rejection(V, a, a2):
    """``V - (a·V / a²) a``, the part of V orthogonal to a (a² = a·a), components first:
    the tangent `arcs` and `_wide_tangents` follow, written once."""
    return V - (vdot(a, V, 0) / a2) * a


def slerp_core(A, B, h, O, shortest):
    """``O = slerp(A, B, h)`` on components-first arrays.

    A, B : (4, *s) arrays (not modified); h : broadcastable to s;
    O : (4, *s) output, may be a strided view, must not overlap A or B.
    With `shortest`, B is replaced by -B where A·B < 0 (ties keep B).

    Pairs whose squares leave the float range (norms beyond about 2**±458, float32 2**±39)
    are computed again from A and B scaled by 2**-e (e: the exponent of their largest
    component), the result scaled back: SLERP is homogeneous (two quaternions of norm r give
    r times the unit result) and the scaling exact.
    """
    huge_or_tiny = _slerp_rows(A, B, h, O, shortest)
    if huge_or_tiny is not None:
        s = O.shape[1:]
        at = _where(huge_or_tiny)
        a, b = np.broadcast_to(A, (4,) + s)[at], np.broadcast_to(B, (4,) + s)[at]
        e = np.frexp(np.maximum(np.abs(a).max(axis=0), np.abs(b).max(axis=0)))[1]
        part = np.empty(a.shape, O.dtype)
        _slerp_rows(np.ldexp(a, -e).astype(O.dtype, copy=False), np.ldexp(b, -e).astype(O.dtype, copy=False),
                    np.broadcast_to(h, s)[at[1:]], part, shortest)
        O[at] = np.ldexp(part, e)
    return O


def _chords(A, B, vec, T, ab):
    """(a², b²) = (|B - A|², |B + A|²), written once: `vec` is `_ops.STACKS` on rows (T: 8
    rows, ab: 2) or `_ops.FLOAT_STACKS` on floats.  The differences and sums are held
    interleaved (D0, S0, D1, S1, ...), squared together, and both norms summed in one
    order from contiguous pairs of rows (2-D views of rows four apart cost a ufunc call
    about three times a contiguous one's at small sizes)."""
    T = vec.interleave(vec.sub(B, A, T[0::2]), vec.add(B, A, T[1::2]), T)
    T = vec.mul(T, T, T)
    ab = vec.add(T[0:2], T[2:4], ab)
    ab = vec.add(ab, T[4:6], ab)
    return vec.add(ab, T[6:8], ab)


def _blend(A, B, w0, w1, vec, T, O):
    """O = w0 A + w1 B, the blend of SLERP's and (N)LERP's weights, written once (`vec` as in
    `_chords`; T: eight work rows, which O may be part of)."""
    return vec.add(vec.scale(A, w0, T[:4]), vec.scale(B, w1, T[4:]), O)


def _slerp_rows(A, B, h, O, shortest):
    """`slerp_core`'s formula; returns where |A|² + |B|² is out of range (None: nowhere)."""
    s = O.shape[1:]
    with _blocks.scratch().frame() as work:
        T = work.rows(8, s, O.dtype)
        ab = work.rows(3, s, O.dtype)
        _chords(A, B, _ops.STACKS, T, ab[:2])
        a2, b2, sign = ab
        # |B - A|² + |B + A|² = 2 (|A|² + |B|²), in range for every unit pair
        out_of_range = None if _scale.fits(np.add(a2, b2, out=sign)) else _scale.outside(sign)
        wide = None
        if shortest:
            sign = hemisphere(A, B, a2, b2, sign)
        else:
            sign = None
            wide = b2 < a2
        w0, w1 = slerp_weights(a2, b2, h, sign)
        _blend(A, B, w0, w1, _ops.STACKS, T, O)
        if wide is not None and wide.any():
            arcs(A, B, h, O, wide)
        if not _scale.inside(np.asarray(h), 2.0, -1.0):   # extrapolation beyond a segment's length
            far = np.broadcast_to((h < -1) | (h > 2) | (h != h), s)   # (NaN h: NaN out, named by callers)
            if wide is not None:
                far = far & ~wide
            if far.any():
                arcs(A, B, h, O, far, sign)
    return out_of_range


def squad_param(h, out=None, op=None):
    """2 h (1 - h): the parameter of squad's outer SLERP (its derivative is 2 - 4 h), written
    once: on rows (`out`: a row of any float dtype, or None for a new one), or with
    ``op=_ops.FLOATS`` on a float."""
    op = op or _CAST_ROWS
    out = op.sub(1, h, out)
    out = op.mul(out, h, out)
    return op.mul(out, 2, out)


_CAST_ROWS = SimpleNamespace(sub=lambda a, b, out: np.subtract(a, b, out=out, casting="unsafe"),
                             mul=lambda a, b, out: np.multiply(a, b, out=out, casting="unsafe"))
"""`_ops.ARRAYS`' operations into rows of another float dtype than an operand's."""


def _squad_floats(Q0, A, B, Q1, h, kind=_ops.F64):
    """`_squad_block` of one quadruple (lists of four floats of `kind`) at a float `h`, by
    `_SLERP_FLOATS` (the block kernels' formulas on floats), or None where one of its three
    SLERPs needs the block kernel."""
    slerp = _SLERP_FLOATS[kind]
    P = slerp(Q0, Q1, h, False)
    S = None if P is None else slerp(A, B, h, False)
    # (2 h (1 - h) into float32 rows: each step rounded to float32, `_CAST_FLOATS32`)
    hh = squad_param(h, None, _ops.FLOATS if kind is _ops.F64 else _CAST_FLOATS32)
    return None if S is None else slerp(P, S, hh, False)


def squad_blend(P, S, h, O):
    """Squad's outer blend, written once: ``O = slerp(P, S, 2 h (1 - h))`` (no flip),
    with P = slerp(q0, q1, h) and S = slerp(a, b, h) (components first)."""
    with _blocks.scratch().frame() as work:
        hh = squad_param(h, work.rows(1, np.shape(h), O.dtype)[0])
        slerp_core(P, S, hh, O, False)
    return O


# --------------------------------------------------------------------------
# SLERP along a precomputed frame (fixed endpoints, used by Track)
# --------------------------------------------------------------------------

def frames(k0, k1, F=None, phi=None):
    """Great-circle frames for fixed pairs, components first.

    For unit k0, k1 (shape (4, *s)) returns ``(F, phi)``: F (8, *s) stacks k0
    and the unit tangent p ⊥ k0 in the plane of k0, k1, and phi = Omega/2 is
    half the angle between them, so that ``slerp(k0, k1, u) = cos(2 u phi) k0
    + sin(2 u phi) p``.  No sign flip is applied.  p is computed without
    cancellation as ``(2 D + a² k0) / (a b)`` with D = k1 - k0 (a = |D|,
    b = |k1 + k0|); coincident pairs get p = 0 and antipodal pairs p = 0,
    phi = 0 (a constant rotation: the arc is not unique).  `F` and `phi`
    may be given as output arrays (views into a table).

    Runs on the block engine (blocks of the batch s, bounded scratch):
    fresh temporaries of the full size would cost more in page faults than
    the arithmetic.
    """
    shape = k0.shape if k0.shape == k1.shape else np.broadcast_shapes(k0.shape, k1.shape)
    s = shape[1:]
    if F is None:
        F = np.empty((8,) + s, np.result_type(k0, k1))
        phi = np.empty(s, F.dtype)
    if k0.shape != shape:
        k0 = np.broadcast_to(k0, shape)
    if k1.shape != shape:
        k1 = np.broadcast_to(k1, shape)
    n = prod(s)
    if n == 0:
        return F, phi
    one = None
    if n == 1 and F.dtype == np.float64:   # one pair: the same formula on Python floats
        one = _frame_floats(k0.reshape(4).tolist(), k1.reshape(4).tolist())
    elif n == 1 and F.dtype == k0.dtype == k1.dtype == np.float32:   # or on float32 scalars
        (c0, _), (c1, _) = _ops.floats32(k0.reshape(4)), _ops.floats32(k1.reshape(4))
        one = None if c0 is None or c1 is None else _frame_floats(c0, c1, _ops.F32)
    if one is not None:
        at = (slice(None),) + (0,) * len(s)
        F[at], phi[at[1:]] = one
        return F, phi
    if n <= _blocks.BLOCK:   # one block: the same kernel call, without splitting
        with _blocks.scratch().frame():
            _frames_block(k0, k1, F, phi)
        return F, phi

    def block(idx):
        full = (slice(None),) + idx
        _frames_block(k0[full], k1[full], F[full], phi[idx])

    _blocks.run(block, _blocks.split(s), n)
    return F, phi


def _frame(k0, k1, op, vec, atan2, rare, floor, D, S, T, R):
    """The frame formula, written once: (p, phi, 1 / (a b), rare) for components-first k0, k1.

    `op` is an `_ops` namespace for single rows or floats, `vec` its counterpart
    for 4-component stacks (`_ops.STACKS` / `_ops.FLOAT_STACKS`), `atan2` the
    arctangent of the arithmetic, `floor` the dtype's `_floor`.  D (the tangent's
    output), S, T: 4-row stacks; R: 6 rows (or `_ops.NONE`).  ``rare(ab, a2, b2)``
    tells where the pair is coincident, antipodal or wide (see `_frames_block`); on
    floats the caller then takes the block kernel.
    """
    a2, b2, n2, sc, a, b = R[:6]
    D = vec.sub(k1, k0, D)
    S = vec.add(k1, k0, S)
    T = vec.mul(D, D, T)
    S = vec.mul(S, S, S)
    a2 = op.add(T[0], T[1], a2)              # a² = |k1 - k0|², b² = |k1 + k0|², in component order
    a2 = op.add(a2, T[2], a2)
    a2 = op.add(a2, T[3], a2)
    b2 = op.add(S[0], S[1], b2)
    b2 = op.add(b2, S[2], b2)
    b2 = op.add(b2, S[3], b2)
    n2 = op.add(a2, b2, n2)
    n2 = op.mul(n2, 0.5, n2)                 # 2 for unit quaternions
    a = op.sqrt(a2, a)
    b = op.sqrt(b2, b)
    phi = atan2(a, b)
    sc = op.mul(a, b, sc)
    rare = rare(sc, a2, b2)                  # coincident or antipodal (a b = 0), or k0·k1 < 0
    sc = op.max(sc, floor, sc)
    sc = op.div(1.0, sc, sc)
    D = vec.scale(D, n2, D)
    T = vec.scale(k0, a2, T)
    D = vec.add(D, T, D)
    D = vec.scale(D, sc, D)
    return D, phi, sc, rare


def _rare_floats(sc, a2, b2):
    return sc == 0 or a2 > b2


def _rare_rows(sc, a2, b2):
    flags = _rows(2, sc.shape, bool)
    np.equal(sc, 0, out=flags[0])
    np.greater(a2, b2, out=flags[1])
    return flags if flags.any() else None


def _frame_floats(k0, k1, kind=_ops.F64):
    """`_frame` of one pair (lists of 4 floats of `kind`, an `_ops.Kind`) on floats: (F as 8
    floats, phi), or None where the pair is rare (the block kernel handles those)."""
    def atan2(a, b):   # NumPy's arctangent, as the block kernel's
        return float(np.arctan2(a, b)) if kind is _ops.F64 else np.arctan2(a, b)
    p, phi, _, rare = _frame(k0, k1, kind.op, _ops.FLOAT_STACKS, atan2, _rare_floats, _floor(kind.dtype),
                             None, None, None, _ops.NONE)
    if rare:
        return None
    return k0 + p, phi


def _frames_block(k0, k1, F, phi):
    s = phi.shape
    W = _rows(14, s, F.dtype)
    S, T = W[:4], W[4:8]

    def atan2(a, b):
        return np.arctan2(a, b, out=phi)

    _, _, _, flags = _frame(k0, k1, _ops.ARRAYS, _ops.STACKS, atan2, _rare_rows, _floor(F.dtype), F[4:], S, T,
                            W[8:14])
    F[:4] = k0
    if flags is not None:
        zero, wide = flags
        if zero.any():
            F[4:, zero] = 0                  # no tangent: the arc stays at k0 ...
            phi[(W[13] == 0) & zero] = 0     # ... antipodal (b = 0): no unique arc
        if wide.any():
            _wide_tangents(k0, k1, F[4:], phi, wide)


def _wide_tangents(k0, k1, P, phi, wide):
    """P[:, wide] = the unit tangent at k0 towards k1 where k0·k1 < 0.

    ``(2 D + a² k0) / (a b)`` cancels near k1 = -k0 (its error grows like
    1 / b); the component of S = k0 + k1 orthogonal to k0 does not (as in
    `arcs`).  k1 = -c k0 exactly: no unique arc, p = 0 and phi = 0.
    """
    at = _where(wide)
    a = k0[at]
    S = a + k1[at]
    S = _rejection(S, a, vdot(a, a, 0))
    n = np.sqrt(vdot(S, S, 0))
    flat = ~(n > 0)
    n[flat] = np.inf                         # p = 0
    S /= n
    P[at] = S
    if flat.any():
        phi[tuple(i[flat] for i in at[1:])] = 0


def frame_core(F, phi, u, O):
    """``O = cos(2 u phi) k + sin(2 u phi) p`` with F = [k; p] of shape (8, *s).

    `F` is used as scratch (overwritten).  u broadcastable to s.
    cos and sin are `_kernels.cos_sin`'s (in float64 from tau = tan(u phi), its
    `_cos_sin_of_tangent`); u = 0 gives exactly k.  Returns the rows (cos 2u phi,
    sin 2u phi), the thread's scratch (`_track.rigid_block`'s translations use them).
    """
    s = O.shape[1:]
    c, sn, r0, r1 = _rows(4, s, O.dtype)
    np.multiply(phi, u, out=sn, casting="unsafe")
    if O.dtype == np.float32:                # `cos_sin`'s float32 route: SIMD sin and cos of 2 u phi
        sn *= 2
        c, sn = cos_sin(sn, c, sn)
    else:                                    # its float64 formula, from the one tangent of u phi
        t = tan(sn, out=sn, rows=None if SIMD_TAN else (c, r0, r1))   # (NumPy's SIMD tan needs no rows)
        c, sn = _cos_sin_of_tangent(t, _ops.ARRAYS, *_COS_SIN[False], c, r0, r1)
    # (two multiplies of four rows: one on the (2, 4, *s) view broadcasting (2, 1, *s) costs
    # more than both at small sizes, NumPy's iterator on 3-D and 4-D operands)
    np.multiply(F[:4], c, out=F[:4])
    np.multiply(F[4:], sn, out=F[4:])
    np.add(F[:4], F[4:], out=O)
    return c, sn


# --------------------------------------------------------------------------
# Pairwise functions: broadcasting, blocks, preallocated output
# --------------------------------------------------------------------------

def _pairwise(kernel, quats, t, dtype, flagged=False, **params):
    """Run ``kernel(*quats_block, t_block, O, **params)`` on the block engine;
    returns the (batch, 4) output, and with `flagged` also whether any block's
    kernel returned True (`_blocks.blockwise`)."""
    batch = quats[0].shape[:-1]
    if not (t.shape == batch and all(q.shape[:-1] == batch for q in quats[1:])):   # (the common case:
        batch = np.broadcast_shapes(*(q.shape[:-1] for q in quats), t.shape)        # no costly call)
    out = np.empty(batch + (4,), dtype)
    flag = _blocks.blockwise(kernel, list(quats), [out], batch, dtype, views=[t], **params)
    return (out, flag) if flagged else out


def slerp(q0, q1, t, shortest=True, check=False):
    """Pairwise SLERP of raw arrays (see `quatarray.interpolate.slerp`).

    With `check`, returns ``(result, w all finite)``, judged block by block while
    each block is in cache: non-finite input always gives a non-finite w
    (it reaches |B ∓ A|² or the angle, so both weights), so callers check the
    inputs only then.
    """
    dtype = result_dtype(q0, q1)
    one = _slerp_one(q0, q1, t, shortest)
    if one is not None:   # (finite: the float path takes finite input only)
        return (one, True) if check else one
    if not check:
        return _pairwise(slerp_core, (q0, q1), t, dtype, shortest=shortest)
    out, bad = _pairwise(_slerp_checked, (q0, q1), t, dtype, flagged=True, shortest=shortest)
    return out, not bad


def _slerp_floats_of(kind):
    """`_SLERP_FLOATS`' function for `kind`."""
    chords, blend, op = _chords_floats.kinds[kind], _blend_floats.kinds[kind], kind.op
    fold, signed_blend = _fold_floats.kinds[kind], _signed_blend_floats.kinds[kind]
    low, high = _scale.BOUNDS[kind]
    python = kind is _ops.F64

    def slerp_floats(A, B, h, shortest):
        a2, b2 = chords(*A, *B)
        if not (low <= a2 + b2 <= high and -1.0 <= h <= 2.0):
            return None
        if shortest:   # `slerp_weights` and `hemisphere`: B counts as -B where A·B < 0
            d, r2, b2 = fold(a2, b2)
            if not python:
                size, bound = _doubt32(a2, b2, d, op, None, None)
                if size <= bound:
                    return None
        elif b2 < a2:
            return None
        else:
            r2 = a2
        if python:
            r2, rho, tau = _tangent_angle_floats(r2, b2, h)
            w0, w1 = _tangent_blend_floats(tan_float(tau), r2, rho)
        else:   # `slerp_weights`' float32 route, on float32 scalars
            w0, w1 = _sine_floats.float32(r2, b2, h)
        if shortest:
            return signed_blend(*A, *B, w0, w1, d)
        return blend(*A, *B, w0, w1)
    return slerp_floats


def _atan_unit32_float(x, out=None):
    """`atan_unit32` of one float32 scalar: NumPy's arctan where that is the rows' (AVX-512),
    else the rows' code on an array of one."""
    if SIMD_TAN:
        return np.arctan(x)
    return atan_unit32(np.array([x]), *np.empty((4, 1), np.float32))[0]


_FLOOR64, _TINY64 = float(_floor(np.float64)), float(_tiny(np.float64))   # Python floats: float arithmetic

# The formulas on one pair's floats as plain Python statements (`_ops.compiled`: the same
# operations in the same order, without a namespace call per operation)
_chords_floats = _ops.compiled(lambda op, stack, *c: _chords(list(c[:4]), list(c[4:]), stack, _ops.NONE, None), 8)
_tangent_angle_floats = _ops.compiled(
    lambda op, stack, r2, b2, h: _tangent_angle(r2, b2, h, op, op.arctan, lambda x, y: op.mul(x, y, None),
                                                _FLOOR64, _TINY64, None, None), 3)
_sine_floats = _ops.compiled(
    lambda op, stack, r2, b2, h: list(_sine_formula(r2, b2, h, op, op.atan, op.times, _floor(np.float32),
                                                    _tiny(np.float32), None, None, None, None)), 3,
    calls={"atan": (1, None, _atan_unit32_float), "times": (2, None, lambda th, h: _CAST_FLOATS32.mul(th, h, None))})
"""`_sine_formula` on one float32 pair's scalars ``(r², b², h)`` (its ``float32``; no float64 form)."""
_tangent_blend_floats = _ops.compiled(
    lambda op, stack, tau, r2, rho: _tangent_blend(tau, r2, rho, op, 1.0, None, None, None), 3)
_blend_floats = _ops.compiled(
    lambda op, stack, *c: _blend(list(c[:4]), list(c[4:8]), c[8], c[9], stack, _ops.NONE, None), 10)
_fold_floats = _ops.compiled(
    lambda op, stack, a2, b2: [_chord_difference(a2, b2, op, None), *_folded(a2, b2, op, None)], 2)
"""`_chord_difference` and `_folded` on one pair's (a², b²): [d, r², b²]."""
_signed_blend_floats = _ops.compiled(
    lambda op, stack, *c: _blend(list(c[:4]), list(c[4:8]), c[8], _signed(c[9], c[10], 1.0, op, None), stack,
                                 _ops.NONE, None), 11)
"""`_signed` and `_blend` on one pair's floats ``(*A, *B, w0, w1, d)``."""
_SLERP_FLOATS = _ops.by_kind(_slerp_floats_of)
"""`slerp_core` of one pair (lists of four floats) at a float h, by `_ops.Kind`: ``f(A, B, h,
shortest)``, the four floats, or None where the block kernel has more to do (|A|² + |B|²
out of range, a wide arc followed as given, extrapolation beyond -1 and 2, non-finite
input: `arcs` and the rescaled pass; in float32 also a sign of A·B in doubt, which
`hemisphere` sums again in float64)."""


def _floats_of_one(quats, t):
    """The float paths' operands: the four floats of each of `quats`, one float64 or float32
    quaternion each of one shape and kind, one float64 (float32 too for float32
    quaternions) `t` (its shape within theirs) as a Python float, and their `_ops.Kind`;
    or None."""
    first = quats[0]
    shape = first.shape
    if t.size != 1 or t.ndim >= len(shape):
        return None
    c, kind = _ops.floats64(first), _ops.F64
    if c is None:
        c, kind = _ops.floats32(first)
        if c is None or t.dtype is not _F32 and t.dtype is not _F64:
            return None
    elif t.dtype is not _F64:
        return None
    comps = [c]
    floats = _FLOATS_OF[kind]   # (the others of the first one's kind)
    for q in quats[1:]:   # (a loop, not a generator and a comprehension: this is the cost of one call)
        c = floats(q) if q.shape == shape else None
        if c is None:
            return None
        comps.append(c)
    return comps, t.item(0), kind


_F64, _F32 = np.dtype(np.float64), np.dtype(np.float32)
_FLOATS_OF = {_ops.F64: _ops.floats64, _ops.F32: lambda q: _ops.floats32(q)[0]}

_CAST_FLOATS32 = SimpleNamespace(sub=lambda a, b, out: _F32.type(float(a) - float(b)),
                                 mul=lambda a, b, out: _F32.type(float(a) * float(b)))
"""`_CAST_ROWS` on one float32 quaternion's floats: ``a - b`` and ``a * b`` (Python floats,
or float32 or float64 values) rounded to a float32 scalar, as the rows' float64 or float32
operation cast into a float32 row (float64 holds a float32 product exactly, and the
rounding of a difference twice, to float64 and then float32, is the correctly rounded
one)."""


def _slerp_one(q0, q1, t, shortest):
    """`_SLERP_FLOATS` of one float64 or float32 pair at one t (`_floats_of_one`) as an
    array of their shape, or None."""
    one = _floats_of_one((q0, q1), t)
    if one is None:
        return None
    kind = one[2]
    one = _SLERP_FLOATS[kind](*one[0], one[1], shortest)
    return None if one is None else _ops.to_array(one, q0.shape, kind.dtype)


def _slerp_checked(A, B, h, O, shortest):
    """`slerp_core`, returning True when the block's w row is not all finite: a nan or ±inf
    in A, B or h reaches |B ∓ A|² or the angle, hence both weights and every component."""
    slerp_core(A, B, h, O, shortest)
    return not all_finite(O[0])


def lerp(q0, q1, t):
    """(1 - t) q0 + t q1, broadcasting (raw arrays)."""
    return _pairwise(_lerp_block, (q0, q1), t, result_dtype(q0, q1))


def _lerp_block(A, B, h, O):
    s = O.shape[1:]
    w = _rows(1, s, O.dtype)[0]
    np.subtract(1, h, out=w, casting="unsafe")
    _blend(A, B, w, h, _ops.STACKS, _rows(8, s, O.dtype), O)


_ZERO_BLEND = ("nlerp: expected a non-zero blend (1 - t) q0 + t q1 to normalise, "
               "got a zero quaternion (q1 = -q0 with shortest=False, or zero input)")


def nlerp(q0, q1, t, shortest=True):
    """Normalised lerp with an optional shortest-path flip (q0·q1 < 0 flips q1) (raw arrays).

    Raises ValueError where the blend is the zero quaternion (only possible
    for q1 = -q0 followed as given, or zero input)."""
    return _pairwise(_nlerp_block, (q0, q1), t, result_dtype(q0, q1), shortest=shortest)


def _nlerp_block(A, B, h, O, shortest, in_range=False):
    s = O.shape[1:]
    W = _rows(11, s, O.dtype)   # (one request: a scratch call costs as much as a small ufunc's)
    w0, w1, n, T = W[0], W[1], W[2], W[3:]
    np.subtract(1, h, out=w0, casting="unsafe")
    np.copyto(w1, h, casting="unsafe")
    if shortest:
        n = _scale._summed(np.multiply(A, B, out=T[:4]), n)   # A·B, in component order
        n += 0.0                          # -0.0 -> +0.0: a zero dot product keeps q1
        w1 = _signed(w1, n, _ops.const(1.0, O.dtype), _ops.ARRAYS, n)   # q1 counted as -q1 where A·B < 0
    N = _blend(A, B, w0, w1, _ops.STACKS, T, T[:4])
    normalize_block(N, O, _ZERO_BLEND, in_range)   # the package's one q / |q|, safe at any magnitude


def unit_keys(keys, name="keys", unit=False):
    """Finite keyframes (K, ..., 4) unflipped along axis 0, then normalised
    (`_kernels.normalize`, the package's one normalisation).

    The signs follow the dot products of the keys as given: each key is first
    multiplied by a power of two near 1/its largest component (exact: the same
    directions and dot-product signs, and no overflow or underflow at any
    magnitude).  Zero keys raise `ValueError`.
    ``unit=True``: the keys are a Rotation's, unit already, and only
    unflipped (normalising again moves a third of them by an ulp, and an
    interpolant of equal keys must give back the key itself).
    """
    if unit:
        return unflip(keys, 0)
    a = np.abs(keys)
    # the largest of the four, column by column (NumPy's max over a length-4 axis is much slower)
    _, e = np.frexp(np.maximum(np.maximum(a[..., 0], a[..., 1]), np.maximum(a[..., 2], a[..., 3]))[..., None])
    keys = unflip(np.ldexp(keys, -e).astype(keys.dtype, copy=False), 0)
    try:
        return normalize(keys, out=keys)
    except ValueError:
        raise ValueError(f"expected non-zero {name}, got a zero quaternion") from None


def unflip_dots(a, b):
    """The dot products a·b (components last) whose signs `unflip` follows, the one formula of
    every path (the chunked one's too).  float32: summed in float64 (exact products), so that
    rotations close to π apart get the sign of their exact dot product, as `hemisphere` gives
    slerp; in `vdot`'s order, each product cast to float64 as NumPy computes it (no float64
    copy of the quaternions)."""
    if a.dtype != np.float32:
        return vdot(a, b)
    d = np.multiply(a[..., 0], b[..., 0], dtype=np.float64)
    for k in (1, 2, 3):
        d += np.multiply(a[..., k], b[..., k], dtype=np.float64)
    return d


def unflip(q, axis, d=None):
    """Signs flipped so that consecutive quaternions along batch `axis` have
    a non-negative dot product (the first one keeps its sign).

    `d`: the dot products ``q[1:]·q[:-1]`` along `axis` (moved first) if the
    caller has them already, as this function computes them.

    Same result as the loop ``if q[i]·q[i-1] < 0: q[i] = -q[i]`` (with the
    already unflipped q[i-1]): the sign of q[i] is the product of the signs
    of the dot products d_j = q[j]·q[j-1] of the input since the last exact
    zero (a zero dot product needs no flip and restarts the product).
    Vectorised with a cumulative product; no loop over the axis.
    """
    qa = np.moveaxis(q, axis, 0) if axis else q
    dtype = q.dtype if q.dtype in _FLOATS else result_dtype(q)
    n = qa.shape[0]
    if n < 2:
        return q.astype(dtype, copy=True)
    if d is None:
        d = unflip_dots(qa[1:], qa[:-1])
    step = np.ones(qa.shape[:-1], np.int8)
    np.copyto(step[1:], -1, where=d < 0)
    zero = None
    if (d == 0).any():
        zero = np.zeros(qa.shape[:-1], bool)
        np.equal(d, 0, out=zero[1:])
    del d                                                 # (memory: the dot products are done)
    c = np.multiply.accumulate(step, axis=0, dtype=np.int8, out=step)  # sign with no restarts, in place
    if zero is not None:
        idx = np.arange(n).reshape((n,) + (1,) * (qa.ndim - 2))
        last = np.maximum.accumulate(np.where(zero, idx, 0), axis=0)
        c = c * np.take_along_axis(c, last, axis=0)         # restart at the last zero
    out = np.multiply(qa, c[..., None], dtype=dtype)      # the int8 signs cast per block, no copy
    return np.moveaxis(out, 0, axis) if axis else out


# --------------------------------------------------------------------------
# squad and spherical Bézier: pairwise evaluation
# --------------------------------------------------------------------------

def _squad_block(Q0, A, B, Q1, h, O):
    s = O.shape[1:]
    P = _rows(4, s, O.dtype)
    S = _rows(4, s, O.dtype)
    slerp_core(Q0, Q1, h, P, False)
    slerp_core(A, B, h, S, False)
    squad_blend(P, S, h, O)


def squad(q0, a, b, q1, t):
    """Pairwise squad (raw arrays): slerp(slerp(q0, q1, t), slerp(a, b, t), 2t(1-t))."""
    quats = (q0, a, b, q1)
    one = _floats_of_one(quats, t)   # one float64 or float32 quadruple: the same formulas on its floats
    kind = None if one is None else one[2]
    one = None if one is None else _squad_floats(*one[0], one[1], kind)
    if one is not None:
        return _ops.to_array(one, q0.shape, kind.dtype)
    return _pairwise(_squad_block, quats, t, result_dtype(*quats))


def bezier_levels(L, h, O):
    """de Casteljau by SLERP: L (4, n, *s) holds n = 3 or 4 control points along axis 1."""
    s = O.shape[1:]
    while L.shape[1] > 2:
        n = L.shape[1] - 1
        M = _rows(4 * n, s, O.dtype).reshape((4, n) + s)
        slerp_core(L[:, :n], L[:, 1:], h, M, False)
        L = M
    slerp_core(L[:, 0], L[:, 1], h, O, False)


def _bezier_block(Q0, A, B, Q1, h, O):
    s = O.shape[1:]
    L = _rows(16, s, O.dtype).reshape((4, 4) + s)
    for j, X in enumerate((Q0, A, B, Q1)):
        L[:, j] = X
    bezier_levels(L, h, O)


def bezier(q0, a, b, q1, t):
    """Pairwise spherical cubic Bézier (raw arrays), de Casteljau with SLERP."""
    return _pairwise(_bezier_block, (q0, a, b, q1), t, result_dtype(q0, a, b, q1))
