"""Raw C² rotation spline (scipy's `RotationSpline` maths) on ``(K, *batch, 4)`` keys.

On segment ``i`` the rotation is ``q_i exp(r(t))`` with ``r`` (a rotation
vector relative to the left key) a cubic in ``t - t_i``; ``r(0) = 0`` and
``r(dt_i)`` is the rotation vector of ``q_i* q_{i+1}``.  The angular rates
``w_i`` at the keys are continuous by construction and the angular
accelerations are made continuous at interior keys, which is a nonlinear
block-tridiagonal system in the interior rates (Sola, "Quaternion kinematics
for the error-state Kalman filter", and scipy's `_rotation_spline.py`).  The
end rates are fixed as scipy fixes them: the first equals the first segment's
mean rate, the last the last segment's mean rate.  The nonlinear term is
iterated (at most `MAX_ITER` times, as scipy); each linear solve is a block
cyclic reduction, so no Python loop runs over keys: the loop is over
``log2(K)`` reduction levels, each level vectorised over keys and tracks.

All functions take the key axis first and any batch after it; the last axis
holds components.  float32 stays float32.
"""

from math import prod

import numpy as np

from . import _blocks
from . import _convert
from . import _jacobian
from . import _kernels
from . import _ops
from . import _track
from . import _trig
from ._blocks import soa
from ._trig import tan

MAX_ITER = 10
TOL = {np.dtype(np.float64): 1e-9, np.dtype(np.float32): 4 * float(np.finfo(np.float32).eps)}


def _skew(v):
    s = np.zeros(v.shape[:-1] + (3, 3), v.dtype)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    s[..., 0, 1], s[..., 0, 2] = -z, y
    s[..., 1, 0], s[..., 1, 2] = z, -x
    s[..., 2, 0], s[..., 2, 1] = -y, x
    return s


def _cross(a, b, out=None):
    """``np.cross`` of (..., 3) vectors of one shape, with its operations in its order (the same
    bits) but without its axis handling and input copies, which cost more than the arithmetic
    on the short arrays of the spline's solve."""
    if out is None:
        out = np.empty(np.broadcast_shapes(a.shape, b.shape), np.result_type(a, b))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    tmp = np.empty(out.shape[:-1], out.dtype)
    np.multiply(a2, b1, out=tmp)
    np.multiply(a1, b2, out=out[..., 0])
    out[..., 0] -= tmp
    np.multiply(a2, b0, out=out[..., 1])
    np.multiply(a0, b2, out=tmp)
    out[..., 1] -= tmp
    np.multiply(a0, b1, out=out[..., 2])
    np.multiply(a1, b0, out=tmp)
    out[..., 2] -= tmp
    return out


def rate_to_rotvec_dot(rotvecs):
    """Matrices ``A(r)`` with ``dr/dt = A(r) w``; shape (..., 3, 3)."""
    k = _jacobian.one_minus_half_cot(np.linalg.norm(rotvecs, axis=-1), 2)
    sk = _skew(rotvecs)
    return np.eye(3, dtype=rotvecs.dtype) + 0.5 * sk + k[..., None, None] * (sk @ sk)


def rotvec_dot_to_rate(rotvecs):
    """Matrices ``A(r)^-1`` with ``w = A(r)^-1 dr/dt``; shape (..., 3, 3)."""
    n = np.linalg.norm(rotvecs, axis=-1)
    k1 = _jacobian.one_minus_cos(n, 2)[..., None, None]
    k2 = _jacobian.one_minus_sinc(n, 2)[..., None, None]
    sk = _skew(rotvecs)
    return np.eye(3, dtype=rotvecs.dtype) - k1 * sk + k2 * (sk @ sk)


def acceleration_coefficients(rotvecs):
    """The coefficients of `acceleration_term` that depend on the rotation vectors alone:
    three arrays of shape ``rotvecs.shape[:-1]`` (the spline's iterations change only
    ``dr/dt``, so they compute these once)."""
    n = np.linalg.norm(rotvecs, axis=-1)
    k1, k2 = _jacobian.derivative(n)
    return k1, k2, _jacobian.one_minus_sinc(n, 2)


def acceleration_term(rotvecs, rotvecs_dot, k=None):
    """The part of the angular acceleration quadratic in ``dr/dt``; shape (..., 3).
    `k`: ``acceleration_coefficients(rotvecs)``, if already computed."""
    k1, k2, k3 = acceleration_coefficients(rotvecs) if k is None else k
    dp = np.sum(rotvecs * rotvecs_dot, axis=-1)
    cp = _cross(rotvecs, rotvecs_dot)
    ccp = _cross(rotvecs, cp)
    dccp = _cross(rotvecs_dot, cp)
    return (dp * k1)[..., None] * cp + (dp * k2)[..., None] * ccp + k3[..., None] * dccp


def acceleration_jacobian(rotvecs, rotvecs_dot, k=None):
    """The derivative of `acceleration_term` in ``dr/dt`` (a quadratic form): (..., 3, 3)."""
    k1, k2, k3 = (c[..., None, None] for c in (acceleration_coefficients(rotvecs) if k is None else k))
    dp = np.sum(rotvecs * rotvecs_dot, axis=-1)[..., None, None]
    cp = _cross(rotvecs, rotvecs_dot)
    ccp = _cross(rotvecs, cp)
    sk = _skew(rotvecs)
    outer = (lambda a: a[..., :, None] * rotvecs[..., None, :])
    return (k1 * (outer(cp) + dp * sk) + k2 * (outer(ccp) + dp * (sk @ sk))
            + k3 * (_skew(rotvecs_dot) @ sk - _skew(cp)))


def _mv(m, v):
    return np.einsum("...ij,...j->...i", m, v)


def angular_rate(rotvecs, rotvecs_dot):
    """Angular rate ``A(r)^-1 dr/dt`` from a rotation vector and its time derivative.

    Written with cross products rather than the 3x3 matrix of
    `rotvec_dot_to_rate`, so long query arrays carry no (..., 3, 3) temporaries.
    """
    n = np.linalg.norm(rotvecs, axis=-1)
    k1 = _jacobian.one_minus_cos(n, 2)[..., None]
    k2 = _jacobian.one_minus_sinc(n, 2)[..., None]
    cp = _cross(rotvecs, rotvecs_dot)
    return rotvecs_dot - k1 * cp + k2 * _cross(rotvecs, cp)


def angular_acceleration(rotvecs, rotvecs_dot, rotvecs_ddot):
    """Angular acceleration from a rotation vector and its first two derivatives."""
    return angular_rate(rotvecs, rotvecs_ddot) + acceleration_term(rotvecs, rotvecs_dot)


def inv3(m):
    """Inverses of 3x3 matrices (..., 3, 3) in closed form: the adjugate over the determinant.

    The rows of the adjugate's transpose are cross products of the rows of
    ``m``; no LAPACK call per matrix (``np.linalg.inv`` on stacks of 3x3
    matrices spends its time in per-matrix overhead).
    """
    r0, r1, r2 = m[..., 0, :], m[..., 1, :], m[..., 2, :]
    adj = np.empty(m.shape, m.dtype)
    _cross(r1, r2, adj[..., 0])
    _cross(r2, r0, adj[..., 1])
    _cross(r0, r1, adj[..., 2])
    det = np.sum(r0 * adj[..., :, 0], axis=-1)
    return adj / det[..., None, None]


def block_tridiagonal_factor(lower, diag, upper):
    """Cyclic-reduction factorisation of ``lower_i x_{i-1} + diag_i x_i + upper_i x_{i+1} = rhs_i``.

    ``lower``, ``diag``, ``upper`` have shape (n, *batch, 3, 3) (``lower[0]``
    and ``upper[-1]`` are ignored).  Each level removes the odd rows, so
    there are ``log2(n)`` levels, each vectorised over rows and batch.  The
    matrices are reduced once; `block_tridiagonal_apply` then solves for any
    right-hand side with matrix-vector products only (the spline's
    fixed-point iteration changes only the right-hand side).

    A level keeps, batch first, one (3, 9) matrix per row that the apply's sweeps multiply
    by three consecutive rows ``[y_{i-1}; y_i; y_{i+1}]`` (a window of its vectors):
    ``G_j = [-alpha_j | I | -beta_j]`` makes even row j's right-hand side of the next level
    from rows 2j - 1, 2j, 2j + 1 (``alpha_j = lower_{2j} D_{2j-1}^-1``, ``beta_j = upper_{2j}
    D_{2j+1}^-1``), and ``H_i = [-D^-1 lower | D^-1 | -D^-1 upper]`` (of odd row 2i + 1) its
    unknown from the even rows' solution beside its right-hand side.  A missing neighbour
    (before the first row, after the last) has a zero block.
    """
    levels = []
    dtype, batch = diag.dtype, diag.shape[1:-2]
    rows_first = (len(batch),) + tuple(range(len(batch))) + (-2, -1)   # of a batch-first (..., rows, 3, 9)
    middle = np.zeros((3, 9), dtype)
    middle[:, 3:6] = np.eye(3, dtype=dtype)   # G's I, and the missing neighbours' zero blocks
    while len(diag) > DENSE:
        n = len(diag)
        m, k = (n + 1) // 2, n // 2        # even and odd rows
        j = min(k, m - 1)                  # odd rows with an even row after them
        neg_inv = inv3(diag[1::2])
        np.negative(neg_inv, out=neg_inv)
        G = np.empty(batch + (m, 3, 9), dtype)
        np.copyto(G, middle)
        H = np.empty(batch + (k, 3, 9), dtype)
        g, h = G.transpose(rows_first), H.transpose(rows_first)
        # -(a b) = a (-b) exactly: the blocks land negated, in place
        alpha, beta = g[1:, ..., 0:3], g[:k, ..., 6:9]     # -alpha_j (j >= 1), -beta_j (j < k)
        np.matmul(lower[2::2], neg_inv[:m - 1], out=alpha)
        np.matmul(upper[0:2 * k:2], neg_inv, out=beta)
        np.matmul(neg_inv, lower[1::2], out=h[..., 0:3])
        np.negative(neg_inv, out=h[..., 3:6])
        np.matmul(neg_inv[:j], upper[1:2 * j:2], out=h[:j, ..., 6:9])
        h[j:, ..., 6:9] = 0
        # the even rows' system: diag - alpha upper_{2j-1} - beta lower_{2j+1}, lower
        # -alpha lower_{2j-1}, upper -beta upper_{2j+1} (the ignored ends left 0)
        new_diag = diag[0::2].copy()
        new_diag[1:] += alpha @ upper[1:2 * m - 1:2]
        new_diag[:k] += beta @ lower[1::2]
        new_lower, new_upper = np.empty_like(new_diag), np.empty_like(new_diag)
        new_lower[0] = new_upper[-1] = 0
        np.matmul(alpha, lower[1:2 * m - 1:2], out=new_lower[1:])
        np.matmul(beta[:m - 1], upper[1:2 * m - 2:2], out=new_upper[:-1])
        levels.append((G, H))
        diag, lower, upper = new_diag, new_lower, new_upper
    levels.append(_dense_inverse(lower, diag, upper))
    return levels


#: Block rows at which the cyclic reduction stops: the rest (at most this many rows) is
#: solved by the inverse of its dense matrix, one LAPACK call, instead of log2(DENSE) more
#: levels of small NumPy calls.
DENSE = 16


def _dense_inverse(lower, diag, upper):
    """Inverses (*batch, 3n, 3n) of the dense block-tridiagonal matrices (NaN if singular)."""
    n = len(diag)
    batch = diag.shape[1:-2]
    dense = np.zeros(batch + (n, 3, n, 3), diag.dtype)
    i = np.arange(n)
    # the advanced indices, apart, select (n, *batch, 3, 3): the blocks' own layout
    dense[..., i, :, i, :] = diag
    dense[..., i[1:], :, i[:-1], :] = lower[1:]
    dense[..., i[:-1], :, i[1:], :] = upper[:-1]
    dense = dense.reshape(batch + (3 * n, 3 * n))
    try:
        return np.linalg.inv(dense)
    except np.linalg.LinAlgError:   # as inv3's division by a zero determinant: not finite
        return np.full_like(dense, np.nan)


def _windows(rows, first, count):
    """The (*batch, count, 9) view of rows ``first + 2c - 1, first + 2c, first + 2c + 1``
    (c < count) of `rows`, a contiguous (*batch, n + 2, 3) array padded with a zero row at each
    end (index ``1 + r`` holds row r): three rows are nine consecutive numbers, so each window
    is one, without a copy."""
    step = rows.itemsize
    return np.ndarray(rows.shape[:-2] + (count, 9), rows.dtype, rows, 3 * step * first,
                      rows.strides[:-2] + (6 * step, step))


def block_tridiagonal_apply(levels, rhs):
    """Solution (n, *batch, 3) for ``rhs`` (n, *batch, 3) of a `block_tridiagonal_factor`."""
    n = len(rhs)
    rows = np.zeros(rhs.shape[1:-1] + (n + 2, 3), rhs.dtype)   # batch first, zero-padded
    rows[..., 1:-1, :] = np.moveaxis(rhs, 0, -2)
    return np.moveaxis(_apply(levels, rows), -2, 0)


def _apply(levels, rows, level=0):
    """`block_tridiagonal_apply` on its padded batch-first `rows` from `level` on (the
    rows are overwritten); returns the solution (*batch, n, 3).  Each product sums one
    window's nine terms, so a track's bits do not depend on the batch around it."""
    n = rows.shape[-2] - 2
    if level == len(levels) - 1:
        inv = levels[level]
        x = _mv(inv, rows[..., 1:-1, :].reshape(inv.shape[:-1]))
        return x.reshape(rows.shape[:-2] + (n, 3))
    G, H = levels[level]
    m, k = (n + 1) // 2, n // 2        # even and odd rows
    # forward: the even rows' right-hand sides, into the next level's padded rows
    even = np.zeros(rows.shape[:-2] + (m + 2, 3), rows.dtype)
    np.einsum("...ij,...j->...i", G, _windows(rows, 0, m), out=even[..., 1:-1, :])
    rows[..., 1:-1:2, :] = _apply(levels, even, level + 1)
    # backward: each odd row from its right-hand side between the even rows' solution
    rows[..., 2:-1:2, :] = _mv(H, _windows(rows, 1, k))
    return rows[..., 1:-1, :]


def block_tridiagonal_solve(lower, diag, upper, rhs):
    """Solve ``lower_i x_{i-1} + diag_i x_i + upper_i x_{i+1} = rhs_i`` by cyclic reduction."""
    return block_tridiagonal_apply(block_tridiagonal_factor(lower, diag, upper), rhs)


def relative_rotvecs(keys):
    """Rotation vectors of ``keys[i]* keys[i+1]``, shape (K - 1, *batch, 3).

    The product's vector part is grouped as ``(w_i v_j - w_j v_i) - v_i × v_j``,
    which is exactly 0 for equal keys (the general product's rounding leaves
    about 1e-17 there, which the spline's rates carry over long segments:
    equal keys must give the key itself at every time).
    """
    p, q = keys[:-1], keys[1:]
    if p.dtype == np.float64 and p.size == 4:   # two keys of one track: the formula on floats
        rel = _relative(p.reshape(4).tolist(), q.reshape(4).tolist(), _ops.FLOATS, _ops.FLOAT_STACKS, _ops.NONE)
        return _convert.as_rotvec(np.array(rel).reshape(p.shape))
    rel = np.empty(p.shape, keys.dtype)
    R = soa(rel)
    _relative(soa(p), soa(q), _ops.ARRAYS, _ops.STACKS, (R[0], R[1:], np.empty_like(R[1:])))
    return _convert.as_rotvec(rel)


def _relative(P, Q, op, vec, rows):
    """The components of ``P* Q`` (P, Q: four components, rows or floats), written once;
    rows: the outputs w (one row) and v (three), and three scratch rows (or `_ops.NONE`)."""
    w, v, c = rows[0], rows[1], rows[2]
    t = vec.mul(P[1:], Q[1:], c)                  # summed in component order, as np.sum
    d = op.add(t[0], t[1], None if c is None else c[0])
    d = op.add(d, t[2], d)
    w = op.mul(P[0], Q[0], w)
    w = op.add(w, d, w)
    v = vec.scale(Q[1:], P[0], v)                 # w_i v_j - w_j v_i
    a = vec.scale(P[1:], Q[0], c)
    v = vec.sub(v, a, v)
    # - v_i × v_j, each component as np.cross computes it (a1 b2 - a2 b1, ...)
    x, y, z = P[1], P[2], P[3]
    u0, u1, u2 = Q[1], Q[2], Q[3]
    cr = [(y, u2, z, u1), (z, u0, x, u2), (x, u1, y, u0)]
    out = [None, None, None]
    for k, (a1, b2, a2, b1) in enumerate(cr):
        m = op.mul(a2, b1, None if c is None else c[0])
        ck = op.mul(a1, b2, None if c is None else c[1])
        ck = op.sub(ck, m, ck)
        out[k] = op.sub(v[k], ck, v[k])
    return [w] + out
def _solve_rates(dt, rates, rotvecs):
    """Interior rates (scipy's system) by fixed-point iteration on the quadratic term.

    Each interior equation is scipy's multiplied by the harmonic spacing
    ``g = h k / (h + k)`` of its two segments (h before, k after): the
    diagonal becomes 4, the neighbours' blocks ``2 A k / (h + k)`` and
    ``2 A h / (h + k)``, and every right-hand side term is a rotation vector
    over a spacing (never over its square or cube), so spacings from 1e-300
    to 1e300, and ratios between neighbours as large, neither overflow nor
    lose the diagonal dominance the solve relies on.  The solution is
    scipy's; only the rounding differs.

    Every decision (stop, switch to Newton's method, refactorise) is taken per
    track, so each track of a batch takes the steps it takes alone: its bits do
    not depend on the tracks beside it.
    """
    given = rotvecs.shape
    if rotvecs.ndim > 2:   # one track axis (axis 1), along which tracks leave the iteration
        rotvecs = rotvecs.reshape(len(rotvecs), -1, 3)
        rates = rates.reshape(rotvecs.shape)
        dt = dt.reshape(len(dt), 1)
    dtype = rotvecs.dtype
    first = rates[0].copy()
    a = rate_to_rotvec_dot(rotvecs)
    a_inv = rotvec_dot_to_rate(rotvecs)
    h, k = dt[:-1], dt[1:]
    with np.errstate(over="ignore"):   # h / k = inf: the weight 0
        wh = 1 / (1 + h / k)           # g / h = k / (h + k)
        wk = 1 / (1 + k / h)           # g / k = h / (h + k)
    wh, wk = wh[..., None], wk[..., None]
    dtb = dt[..., None]
    shape = (len(h),) + rotvecs.shape[1:-1] + (3, 3)
    diag = np.broadcast_to(4 * np.eye(3, dtype=dtype), shape).copy()
    lower = np.zeros_like(diag)
    upper = np.zeros_like(diag)
    lower[1:] = 2 * a_inv[1:-1] * wh[1:, ..., None]
    upper[:-1] = 2 * a[1:-1] * wk[:-1, ..., None]
    b0 = 6 * (wh * (rotvecs[:-1] / dtb[:-1]) + wk * (rotvecs[1:] / dtb[1:]))
    b0[0] -= 2 * wh[0] * _mv(a_inv[0], first)
    b0[-1] -= 2 * wk[-1] * _mv(a[-1], rates[-1])
    tol = TOL[np.dtype(dtype)]
    k = acceleration_coefficients(rotvecs[:-1])   # the quadratic term's, of the segment after each key
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):   # a diverging iteration: Newton's below
        newton = _fixed_point(block_tridiagonal_factor(lower, diag, upper), a, wh, dtb, rotvecs, k, b0, rates, tol)
        if newton.all() and newton.size:   # every track (one alone has no track axis to index)
            rates[:-1] = _newton(lower, upper, b0, a, wh, dtb, rotvecs, k, rates[:-1], tol)
        elif newton.any():
            rates[:-1, newton] = _newton(lower[:, newton], upper[:, newton], b0[:, newton], a[:, newton], wh, dtb,
                                         rotvecs[:, newton], _columns(k, newton), rates[:-1, newton], tol)
    rotvecs_dot = _mv(a, rates)
    rates = np.concatenate([first[None], rates[:-1]])
    return rates.reshape(given), rotvecs_dot.reshape(given)


def _columns(arrays, keep):
    """The tracks `keep` (a mask over the track axis, axis 1) of each of `arrays`."""
    return tuple(m[:, keep] for m in arrays)


def _tracks(levels, keep):
    """The `block_tridiagonal_factor` `levels` of the tracks `keep` (a mask over the track
    axis; every level holds the tracks on axis 0)."""
    return [tuple(m[keep] for m in level) for level in levels[:-1]] + [levels[-1][keep]]


def _put_tracks(levels, keep, new):
    """Write the factorisation `new` of the tracks `keep` into `levels`, in place."""
    for level, level_new in zip(levels[:-1], new[:-1]):
        for m, m_new in zip(level, level_new):
            m[keep] = m_new
    levels[-1][keep] = new[-1]


def _fixed_point(levels, a, wh, dtb, rotvecs, k, b0, rates, tol):
    """scipy's fixed-point iteration on the quadratic term, on `rates` (n, tracks, 3) or
    one track's (n, 3), in place.

    Each track iterates until it settles, or until its steps show that the iteration will
    not settle in scipy's `MAX_ITER` steps; those tracks are marked for Newton's method, and
    their rates set to its start: where the iteration got if it was closing in (Newton then
    needs a step or two fewer), else the linear solution.  A track that leaves is dropped
    from the arrays (`levels` is its factorisation), so it takes no step more than alone.
    Returns the mask (tracks,) or () of the tracks for Newton's method.  One track has no
    track axis (its decisions are 0-d; it never leaves alone, so is never indexed).
    """
    newton = np.zeros(rates.shape[1:-1], bool)
    if newton.size == 0:   # an empty batch
        return newton
    track = np.arange(newton.size).reshape(newton.shape)   # the working tracks' places in `rates`
    work, b = rates, b0
    for it in range(1, MAX_ITER + 1):
        # the quadratic term of the rate after each segment, over its spacing: h Q(ṙ) = Q(h ṙ) / h
        rotvecs_dot = _mv(a[:-1], work[:-1]) * dtb[:-1]
        rhs = b - wh * (acceleration_term(rotvecs[:-1], rotvecs_dot, k) / dtb[:-1])
        new = block_tridiagonal_apply(levels, rhs)
        delta = np.abs(new - work[:-1])
        work[:-1] = new
        settled = np.all(delta < tol * (1 + np.abs(new)), axis=(0, -1))
        size = np.max(delta, axis=(0, -1))
        if it == 1:
            first = size
            leave = settled.copy()
        else:
            # the steps shrink by about this ratio each time: where the steps left to scipy's
            # MAX_ITER cannot bring them below the tolerance, or they grow, stop here
            ratio = size / last
            leave = settled | ~((ratio < 1) & (size * ratio ** (MAX_ITER - it) <= tol))
        if it == MAX_ITER:
            leave = np.ones_like(settled)
        if leave.any():
            # where scipy's fixed point does not settle in MAX_ITER steps (large rotations between
            # keys; at uneven spacings it diverges): Newton's method on the same equations, to
            # the spline scipy's iteration would converge to
            failed = leave & ~settled
            linear = failed & ~((size < first) & np.isfinite(work).all(axis=(0, -1)))
            if linear.any():
                np.copyto(work[:-1], block_tridiagonal_apply(levels, b), where=linear[..., None])
            newton.reshape(-1)[track[failed]] = True
            if work is not rates:
                rates[:, track[leave]] = work[:, leave]
            if leave.all():
                break
            keep = ~leave
            track, work, a, rotvecs, b = track[keep], work[:, keep], a[:, keep], rotvecs[:, keep], b[:, keep]
            k = _columns(k, keep)
            levels, first, size = _tracks(levels, keep), first[keep], size[keep]
        last = size
    return newton


NEWTON_ITER = 30


def _newton(lower, upper, b0, a, wh, dtb, rotvecs, k, x, tol):
    """Solve ``lower x₋ + 4 x + upper x₊ + wh Q(r, h A x) / h = b0`` (the scaled rate
    equations of `_solve_rates`; x (n, tracks, 3), or one track's (n, 3)) by Newton's method
    from `x`: the quadratic term's derivative is block diagonal, so each step is one
    block-tridiagonal solve.

    A track's Jacobian is factorised again only when its last step did not shrink to at most
    `REFRESH` of the one before (near the solution the previous factorisation keeps the
    convergence fast, and the factorisation is most of a step's cost); the iteration stops
    on the same test, at the same solution to the tolerance.  Both decisions are the
    track's own, and a track that has converged is dropped from the arrays.

    Raises ValueError if it does not converge (no spline through such keys at such times)."""
    eye4 = 4 * np.eye(3, dtype=x.dtype)
    h, r, av = dtb[:-1], rotvecs[:-1], a[:-1]
    out = track = None   # made when a first track converges before the others
    levels, refresh, last = None, None, np.inf
    for _ in range(NEWTON_ITER):
        d = _mv(av, x) * h
        f = 4 * x + wh * (acceleration_term(r, d, k) / h) - b0
        f[1:] += _mv(lower[1:], x[:-1])
        f[:-1] += _mv(upper[:-1], x[1:])
        if levels is None or refresh.all():
            jac = eye4 + wh[..., None] * (acceleration_jacobian(r, d, k) @ av)
            levels = block_tridiagonal_factor(lower, jac, upper)
        elif refresh.any():
            jac = eye4 + wh[..., None] * (acceleration_jacobian(r[:, refresh], d[:, refresh], _columns(k, refresh))
                                          @ av[:, refresh])
            _put_tracks(levels, refresh, block_tridiagonal_factor(lower[:, refresh], jac, upper[:, refresh]))
        step = block_tridiagonal_apply(levels, f)
        x = x - step
        if not np.isfinite(x).all():   # that track fails alone too: so does the batch
            break
        size = np.abs(step)
        done = np.all(size < tol * (1 + np.abs(x)), axis=(0, -1))
        size = np.max(size, axis=(0, -1))
        refresh = ~(size <= REFRESH * last)
        last = size
        if done.any():
            if out is None:
                if done.all():   # all at once (one track alone always)
                    return x
                out, track = np.empty_like(x), np.arange(x.shape[1])   # track: the places in `out`
            out[:, track[done]] = x[:, done]
            if done.all():
                return out
            keep = ~done
            track, x, r, av, b0, lower, upper = (track[keep], x[:, keep], r[:, keep], av[:, keep], b0[:, keep],
                                                 lower[:, keep], upper[:, keep])
            k = _columns(k, keep)
            levels, refresh, last = _tracks(levels, keep), refresh[keep], last[keep]
    raise ValueError("expected keys and times that a C² rotation spline can join: its rate equations "
                     "have no solution that Newton's method finds (large rotations between keys at very "
                     "uneven time spacings; scipy's iteration diverges there too)")


REFRESH = 0.1


def coefficients(times, keys):
    """Cubic coefficients of the relative rotation vector on every segment.

    Parameters
    ----------
    times : ndarray, shape (K,)
        Strictly increasing key times (K >= 2), in the keys' dtype.
    keys : ndarray, shape (K, *batch, 4)
        Unit scalar-first quaternions.

    Returns
    -------
    ndarray, shape (4, K - 1, *batch, 3)
        ``c[0] u³ + c[1] u² + c[2] u + c[3]`` in the segment's own time
        ``u = (t - times[i]) / (times[i + 1] - times[i])`` in [0, 1]
        (``c[3] = 0``): scipy's ``PPoly`` coefficients times ``dt³``, ``dt²``,
        ``dt``, so that no spacing is cubed (1e-300 or 1e300 would leave
        the float range) and every segment's coefficients are of the size
        of its rotation.

    Raises
    ------
    ValueError
        Where the spacing is so small that a key's rate leaves the float range.
    """
    dtype = keys.dtype
    # solved in float64 whatever the keys' dtype, as scipy does: in float32, Newton's method
    # (uneven spacings) stalls at rounding noise above its tolerance and refused about 2% of
    # random 4-key tracks that float64 solves; the coefficients come back in the keys' dtype
    rotvecs = relative_rotvecs(keys.astype(np.float64, copy=False))
    dt = times[1:] - times[:-1]
    # spacings in a unit of time near their geometric middle (a power of two: exact), so that
    # float32 keys take float64 times of any spacing; the coefficients do not depend on the unit
    _, e = np.frexp(np.sqrt(np.minimum.reduce(dt)) * np.sqrt(np.maximum.reduce(dt)))
    with np.errstate(over="ignore", under="ignore"):   # spacings beyond the keys' range: refused below
        dt = np.ldexp(dt, -e).astype(np.float64).reshape((-1,) + (1,) * (keys.ndim - 2))
        dtb = dt[..., None]
        rates = rotvecs / dtb
    if len(keys) == 2:
        rotvecs_dot = rates
    else:
        rates, rotvecs_dot = _solve_rates(dt, rates, rotvecs)
    coeff = np.zeros((4,) + rotvecs.shape, dtype)
    start, end = dtb * rates, dtb * rotvecs_dot          # the rates in the segment's own time
    with np.errstate(over="ignore"):                     # beyond float32's range: refused below
        coeff[0] = -2 * rotvecs + start + end
        coeff[1] = 3 * rotvecs - 2 * start - end
        coeff[2] = start
    if not np.isfinite(coeff).all():
        raise ValueError("the spline's angular rates at the keys did not come out finite: expected key "
                         "times far enough apart for the rotations between them (times spaced above "
                         f"about {np.finfo(dtype).tiny / np.finfo(dtype).eps:.0e} for a quarter turn), "
                         "or keys that a spline can join (its rate equations diverged)")
    return coeff


_CHECK_BELOW = 8.0
"""Cubics whose terms stay below this (rad) give |q| within about this many ulp of 1 (the
rounding of r(s) relative to its terms, whatever their cancellation): no norm check."""

_UNIT_TOL = {np.dtype(d): 16 * float(np.finfo(d).eps) for d in (np.float32, np.float64)}

ROWS = 25   # key q (4), q (0, c_k) for k = 0, 1, 2 (12), c_0, c_1, c_2 (9)
_TINY = {np.dtype(np.float64): 1e-300, np.dtype(np.float32): 1e-30}
_TINY32 = np.float32(_TINY[np.dtype(np.float32)])


def _tan_float32(x, out=None, rows=None):
    """`_trig.tan` of one float32 scalar (NumPy's, as on float32 rows)."""
    return np.tan(x)


def table(keys, coeff):
    """Per-segment evaluation table (25, K - 1, B), components first, in the keys' dtype.

    With ``r(s) = ((c0 s + c1) s + c2) s`` the spline is ``q exp(r/2)`` =
    ``cos(θ/2) q + sin(θ/2)/θ · q (0, r)`` (θ = |r|), and ``q (0, r)`` is
    the same cubic in s with coefficients ``q (0, c_k)``: those products are
    made here, once per segment, so that a query costs two cubics, one
    tangent and no quaternion product.
    """
    K1 = coeff.shape[1]
    B = prod(keys.shape[1:-1])
    out = np.empty((ROWS, K1, B), keys.dtype)
    q = keys[:-1]
    out[0:4] = soa(q.reshape(K1, B, 4))
    pure = np.zeros((3,) + coeff.shape[1:-1] + (4,), coeff.dtype)   # (0, c_k) for k = 0, 1, 2
    pure[..., 1:] = coeff[:3]
    # one call for the three, on operands of one shape (the product's contiguous path)
    prods = _kernels.multiply(np.repeat(q[None], 3, axis=0), pure).reshape(3, K1, B, 4)
    out[4:16] = prods.transpose(0, 3, 1, 2).reshape(12, K1, B)
    out[16:25] = coeff[:3].reshape(3, K1, B, 3).transpose(0, 3, 1, 2).reshape(9, K1, B)
    return out


def _rotation(G, s, op, vec, tan, tiny, check, renorm, rows):
    """The spline's rotation q exp(r(s)/2), written once, from table rows G (25 rows or
    floats) at the segment's own time s, in `op`'s arithmetic (`_ops` ARRAYS with STACKS,
    or FLOATS with FLOAT_STACKS).  `rows`: nine scratch rows (or `_ops.NONE`); G is
    overwritten.  `check`: the cubics may be large enough for |q| to stray from 1;
    ``renorm(Q, e)`` then divides the elements whose |q|² - 1 = e is off by their norm.
    Returns the four components Q."""
    r, theta, tmp, sq = rows[0:3], rows[3], rows[4], rows[5:9]
    r = vec.scale(G[16:19], s, r)
    r = vec.add(r, G[19:22], r)
    r = vec.scale(r, s, r)
    r = vec.add(r, G[22:25], r)
    r = vec.scale(r, s, r)
    sq3 = vec.mul(r, r, sq[:3])               # the squares in one call, summed in component order
    theta = op.add(sq3[0], sq3[1], theta)
    theta = op.add(theta, sq3[2], theta)
    theta = op.sqrt(theta, theta)
    theta = op.max(theta, tiny, theta)
    tau, d, cos_half = r[0], r[1], r[2]       # r is no longer needed
    tau = op.mul(theta, 0.25, tau)
    tau = tan(tau, out=tau, rows=(d, cos_half, tmp))   # τ = tan(θ/4)
    consts = _COS_SIN_CONSTS[theta.dtype] if op is _ops.ARRAYS else (0.5, 1.0, 2.0)
    cos_half, sin_half = _kernels._cos_sin_of_tangent(tau, op, *consts, cos_half, d, tmp)   # `cos_sin`'s formula;
    tmp = op.div(sin_half, theta, tmp)        # sin(θ/2) / θ                          # sin in tau's row
    V = G[4:8]                                # q (0, r(s)), in place of its first coefficient
    V = vec.scale(V, s, V)
    V = vec.add(V, G[8:12], V)
    V = vec.scale(V, s, V)
    V = vec.add(V, G[12:16], V)
    tmp = op.mul(tmp, s, tmp)                 # the last factor s joins sin(θ/2) / θ
    V = vec.scale(V, tmp, V)
    Q = G[0:4]
    Q = vec.scale(Q, cos_half, Q)
    Q = vec.add(Q, V, Q)
    if check:
        # unit to rounding, except where the cubic's large terms (fast turns between keys, or
        # far extrapolation) cancel in r(s) differently from its products q (0, c_k): only
        # elements off by over 16 eps are divided by their norm (the others keep their bits)
        sq = vec.mul(Q, Q, sq)
        theta = op.add(sq[0], sq[1], theta)
        theta = op.add(theta, sq[2], theta)
        theta = op.add(theta, sq[3], theta)
        theta = op.sub(theta, 1.0, theta)
        Q = renorm(Q, theta)
    return Q


_COS_SIN_CONSTS = {np.dtype(d): tuple(_ops.const(v, d) for v in (0.5, 1.0, 2.0)) for d in (np.float32, np.float64)}
"""0.5, 1 and 2 as operands of rows of each dtype (`_ops.const`), for `_cos_sin_of_tangent`."""


def _renormed(Q, e, op, vec):
    """Q divided by its norm, from ``e = |Q|² - 1`` (`_rotation`'s check), written once, in
    `op`'s arithmetic (`vec` its stacked form)."""
    n = op.sqrt(op.add(e, 1.0, None), None)
    return vec.div(Q, n, None)


def _renorm_rows(Q, e):
    off = _UNIT_TOL[e.dtype]
    if e.size and not (e.max() <= off and e.min() >= -off):
        bad = ~(np.abs(e) <= off)
        Q[:, bad] = _renormed(Q[:, bad], e[bad], _ops.ARRAYS, _ops.STACKS)
    return Q


def _renorm_floats(Q, e):
    if not abs(e) <= _UNIT_TOL[np.dtype(np.float64)]:
        return _renormed(Q, e, _ops.FLOATS, _ops.FLOAT_STACKS)
    return Q


def _rotation_rows(G, s, O, check=True):
    """O (4, m, b) = q exp(r(s)/2) from gathered table rows G (25, m, b) and s (m, 1).

    G is used as scratch (overwritten); O may be a strided view of the output.
    """
    rows = _blocks.scratch().rows(9, O.shape[1:], O.dtype)
    Q = _rotation(G, s, _ops.ARRAYS, _ops.STACKS, tan, _TINY[O.dtype], check, _renorm_rows, rows)
    np.copyto(O, Q)                           # the only write to the (strided) output


def _rate_rows(G, s, order, O):
    """Angular rate (order 1) or acceleration (order 2) (3, m, b) into O."""
    c0, c1, c2 = G[16:19], G[19:22], G[22:25]
    r = ((c0 * s + c1) * s + c2) * s
    r1 = (3 * c0 * s + 2 * c1) * s + c2
    last = (lambda a: np.moveaxis(a, 0, -1))
    if order == 1:
        res = angular_rate(last(r), last(r1))
    else:
        res = angular_acceleration(last(r), last(r1), last(6 * c0 * s + 2 * c1))
    O[...] = np.moveaxis(res, -1, 0)


def coefficient_size(tab):
    """The size of a `table`'s cubic coefficients, for `_rotation_rows`' check (|r| in a
    block is at most this times max(1, |u|)³, u the segment's own time)."""
    return float(np.maximum.reduce(np.abs(tab[16:25]), axis=None, initial=0.0))


def _needs_check(cmax, umax):
    """Whether `_rotation`'s unit check is needed for coefficients of size `cmax` at segment
    times of size up to `umax`: |r| is at most ``cmax * max(1, umax)³`` (coefficients above
    the bound always need it; callers may test that first and skip looking at u)."""
    return cmax > _CHECK_BELOW or not cmax * max(1.0, float(umax)) ** 3 <= _CHECK_BELOW


def evaluate(index, times, tab, t, order, batch, cmax=None):
    """The spline at query times ``t`` (M,): quaternions (order 0), rates (1) or accelerations (2).

    `index` is the `SegmentIndex` of `times` and `tab` the `table`; `cmax` its
    `coefficient_size` if the caller keeps it.  Returns shape (M, *batch, 4)
    for ``order=0`` and (M, *batch, 3) otherwise.  The end segments extend
    beyond the key times, as scipy's ``PPoly``.
    """
    M, K1, B = t.size, tab.shape[1], tab.shape[2]
    dtype = tab.dtype
    width = 4 if order == 0 else 3
    out = np.empty((M, B, width), dtype)

    found = index.find_sorted(t) if M > _blocks.BLOCK else None
    if order == 0 and cmax is None:
        cmax = coefficient_size(tab)
    if order == 0 and M * B == 1 and (dtype == np.float64 or dtype == np.float32):
        # one query of one track: the same formula on Python floats, or on float32 scalars
        i = min(max(int(index.find(t)[0]), 0), K1 - 1)
        t0 = float(times[i])   # (in float64, then the table's dtype)
        s = _track.segment_time(float(t[0]), t0, float(times[i + 1]) - t0, _ops.FLOATS)
        if dtype == np.float64:
            check = _needs_check(cmax, abs(s))
            out[0, 0] = _rotation(tab[:, i, 0].tolist(), s, _ops.FLOATS, _ops.FLOAT_STACKS, _trig.tan_float,
                                  _TINY[dtype], check, _renorm_floats, _ops.NONE)
            return out.reshape(t.shape + tuple(batch) + (width,))
        s = dtype.type(s)
        if not _needs_check(cmax, abs(float(s))):   # (cubics large enough to need the norm check may
            # overflow, which float32 scalars would warn of: the rows' then.)  NumPy's tangent, as on
            # float32 rows, and the floor a float32 scalar (Python's max keeps whichever is larger)
            out[0, 0] = _rotation(tab[:, i, 0], s, _ops.FLOATS32, _ops.FLOAT_STACKS, _tan_float32, _TINY32, False,
                                  None, _ops.NONE)
            return out.reshape(t.shape + tuple(batch) + (width,))

    def block(qt):
        sm, sb = qt
        tb = t[sm]
        i = index.find(tb) if found is None else found[sm].copy()
        np.maximum(i, 0, out=i)
        np.minimum(i, K1 - 1, out=i)
        t0 = times.take(i)
        span = times.take(i + 1) - t0
        # the segment's own time (in float64, then the table's dtype): see `coefficients`
        s = _track.segment_time(tb, t0, span, _ops.ARRAYS).astype(dtype, copy=False)[:, None]
        G = _track.gather(tab, i, sb)
        O = soa(out[sm, sb])
        if order == 0:
            _rotation_rows(G, s, O, check=cmax > _CHECK_BELOW or _needs_check(cmax, np.abs(s).max(initial=0.0)))
        else:
            _rate_rows(G, s, order, O)
            span = span.astype(dtype, copy=False)[:, None]
            O /= span                              # d/dt = d/du / dt (and twice for order 2,
            if order == 2:                         # not by dt², which may leave the range)
                O /= span

    if M * B <= _blocks.BLOCK:   # one block: no split, no pool
        with _blocks.scratch().frame():
            block((slice(None), slice(None)))
    else:
        _blocks.run(block, _track.qt_blocks(M, B), M * B)
    return out.reshape(t.shape + tuple(batch) + (width,))
