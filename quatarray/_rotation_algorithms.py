"""Algorithms on raw rotation arrays behind `Rotation`: the chordal mean, the reduction by
symmetry groups, and `align_vectors` (Kabsch's SVD, and scipy's primary-pair method).

The façade (`_rotation`) validates and wraps; the work is done here, on scalar-first
quaternion arrays ``(..., 4)``, as scipy keeps these in its ``_rotation_xp.py`` backend.
Conversions and products come from `_convert` and `_kernels`; nothing here imports the class.
"""

import warnings
from math import prod

import numpy as np

from . import _blocks, _convert, _kernels
from ._validate import all_finite, float_array

__all__ = ["mean", "mean_axes", "translation_mean", "dominant", "weight_exponents", "chordal_sums", "reduce", "align"]


def mean(q, weights, axes, unit=False):
    """Chordal L2 mean of rotations `q` (..., 4) over batch `axes` (sorted, non-negative),
    with optional non-negative `weights` of the batch shape: the dominant eigenvector of
    Σ wᵢ qᵢ qᵢᵀ, canonical, in `q`'s dtype (computed in float64, `chordal_sums`).  `unit`:
    the rows are known to be unit quaternions (`Rotation`'s storage)."""
    if weights is not None:
        weights = _weights_in_range(np.broadcast_to(weights, q.shape[:-1]), axes)
    return dominant(chordal_sums(q, weights, axes, unit=unit), q.dtype)


def mean_axes(axis, batch, kind):
    """The batch axes a mean averages over, sorted and non-negative, from scipy's `axis`
    (None: all of `batch`; an int; a tuple of ints), with scipy's errors naming `kind`
    ("rotation", "transform")."""
    nb = len(batch)
    if axis is None:
        return tuple(range(nb))
    if isinstance(axis, (int, np.integer)) and not isinstance(axis, bool):
        axis = (int(axis),)
    elif not (isinstance(axis, tuple) and all(isinstance(a, (int, np.integer)) and not isinstance(a, bool)
                                               for a in axis)):
        raise ValueError(f"`axis` must be None, int, or tuple of ints, got {axis!r}")
    if any(not -nb <= a < nb for a in axis):
        raise ValueError(f"axis {axis} is out of bounds for {kind} with shape {batch}.")
    return tuple(sorted({int(a) % nb for a in axis}))


def translation_mean(t, weights, axes):
    """Mean (weighted by `weights` of the batch shape; None: equally) of the vectors `t`
    (..., 3) over batch `axes` (sorted, non-negative), in t's dtype.

    Vectors and weights are scaled per mean by powers of two (exact: the same bits where
    nothing over- or underflows), so that their sums stay in range: translations near the
    float maximum, or weights whose sum or products overflow, gave an infinite or 0 mean.
    Each mean's sums run over its own rows, laid out last and contiguous (`_averaged_last`):
    the same bits alone and among other means, whatever the layout of `t`."""
    tmax = np.max(np.abs(t), axis=axes + (t.ndim - 1,), keepdims=True)
    et = np.frexp(tmax)[1]
    ts = _averaged_last(np.ldexp(t, -et).astype(t.dtype, copy=False), axes)   # (kept, 3, rows)
    if weights is None:
        tm = np.add.reduce(ts, axis=-1) / ts.shape[-1]   # np.mean's sum, then the division by the count
    else:
        wmax = np.max(weights, axis=axes, keepdims=True)
        ws = _averaged_last(np.ldexp(weights, -np.frexp(wmax)[1]).astype(weights.dtype, copy=False)[..., None],
                            axes)                                                      # (kept, 1, rows)
        total = np.add.reduce(ws, axis=-1)
        if not np.all(total > 0):   # scipy: ZeroDivisionError; 0/0 would be a NaN translation
            raise ValueError("expected weights with a positive sum over the averaged axes, "
                             "got weights that sum to zero")
        ws = ws.astype(t.dtype, copy=False)
        tm = np.add.reduce(ts * ws, axis=-1) / total.astype(t.dtype, copy=False)
    return np.ldexp(tm, np.squeeze(et, axis=axes)).astype(t.dtype, copy=False)


def _averaged_last(a, axes):
    """`a` (batch + (k,)) as a C-contiguous ``kept batch + (k, rows)`` array, the averaged
    batch `axes` flattened last: a sum along the last axis then runs over each mean's own
    rows, in an order set by their number only (NumPy's pairwise sum on a contiguous row)."""
    nb = a.ndim - 1
    keep = tuple(i for i in range(nb) if i not in axes)
    moved = np.ascontiguousarray(a.transpose(keep + (nb,) + tuple(axes)))
    return moved.reshape(moved.shape[:len(keep) + 1] + (-1,))


def dominant(k, dtype):
    """The mean rotations of chordal sums `k` (..., 4, 4), (w, x, y, z) order: the dominant
    eigenvectors, canonical, in `dtype`.  The matrix is taken in scipy's (x, y, z, w) order, so
    that ties (all weights zero) resolve as in scipy; both reorderings are one `take` from the
    16 flat entries (a fifth of fancy indexing)."""
    _, vectors = np.linalg.eigh(np.take(k.reshape(k.shape[:-2] + (16,)), _XYZW_ENTRIES, axis=-1))
    last = np.take(vectors.reshape(k.shape[:-2] + (16,)), _WXYZ_LAST, axis=-1)
    return _convert.canonical(last).astype(dtype, copy=False)


_XYZW = np.array([1, 2, 3, 0])
#: Flat indices of a 4x4 matrix's entries in (x, y, z, w) order, and of the last column's
#: entries in (w, x, y, z) order
_XYZW_ENTRIES, _WXYZ_LAST = 4 * _XYZW[:, None] + _XYZW, 4 * np.array([3, 0, 1, 2]) + 3


def _weights_in_range(w, axes):
    """Weights (float64, batch shape) scaled per mean by a power of two where the sums of
    ``w q qᵀ`` could overflow or its products underflow (weights of 1.5e308 gave the identity):
    the mean does not depend on their scale.  Ordinary weights are returned as they are."""
    wmax = np.max(w, axis=axes, keepdims=True)
    e = weight_exponents(wmax, prod(w.shape[a] for a in axes))
    return w if e is None else np.ldexp(w, -e)


def weight_exponents(wmax, n):
    """The powers of two to divide weights by, per mean, from their largest `wmax` over `n`
    rotations: None where every mean's weights are ordinary (0, or within 2**±900 over n)."""
    if np.all((wmax == 0) | ((wmax >= 2.0 ** -900) & (wmax <= 2.0 ** 900 / n))):
        return None
    return np.frexp(wmax)[1]


def chordal_sums(q, weights, axes, name="rotations to average", unit=False):
    """Σ wᵢ qᵢ qᵢᵀ over the batch `axes` (sorted, non-negative) of quaternions `q` (..., 4),
    in float64, (w, x, y, z) order: shape ``kept batch + (4, 4)``.  Rows are normalised
    first (NaN, infinite or zero ones raise `_convert.from_quat`'s `ValueError`, naming
    `name` and the index in the whole batch), unless `unit` says they are unit already
    (`Rotation`'s normalised storage: a pass saved).

    Each mean's rows are summed in slices of `ROWS` rows (one BLAS product each, then added
    in order), whatever the other means of the batch: a mean has the same bits alone and
    among others.  A slab of at most about `ROWS` rows is in float64 at a time, so the extra
    memory is a few blocks whatever the batch (not a float64 copy of it).

    >>> import numpy as np
    >>> from quatarray._rotation_algorithms import chordal_sums
    >>> chordal_sums(np.array([[2.0, 0, 0, 0], [0, 0, 0, 1]]), None, (0,))
    array([[1., 0., 0., 0.],
           [0., 0., 0., 0.],
           [0., 0., 0., 0.],
           [0., 0., 0., 1.]])
    """
    batch = q.shape[:-1]
    nb = len(batch)
    if unit and weights is None and len(axes) == nb and q.size <= 4 * ROWS:
        c = q.reshape(-1, 4).astype(np.float64, copy=False)   # one mean of a few unit rotations:
        return np.matmul(c.T, c)                              # the one product of the slab below
    keep = tuple(a for a in range(nb) if a not in axes)
    kshape = tuple(batch[a] for a in keep)
    groups, rows = prod(kshape), prod(batch[a] for a in axes)
    # (groups, rows, 4): a view where the layout allows (the averaged axes after the kept
    # ones in memory), else one copy in q's dtype
    qg = q.transpose(keep + tuple(axes) + (nb,)).reshape(groups, rows, 4)
    wg = None if weights is None else np.broadcast_to(weights, batch).transpose(keep + tuple(axes)).reshape(groups, rows)
    per = max(1, ROWS // max(min(rows, ROWS), 1))   # means per slab
    acc = np.empty((groups, 4, 4))
    for g in range(0, groups, per):   # a loop over slabs of about `ROWS` rows, as the block engine's
        k = acc[g:g + per]
        for start in range(0, rows, ROWS):
            try:
                c = qg[g:g + per, start:start + ROWS].astype(np.float64, copy=False)
                if not unit:
                    c = _convert.from_quat(c, scalar_first=True, name=name)
            except ValueError:   # the message with the index in the whole batch
                _convert.from_quat(q.astype(np.float64, copy=False), scalar_first=True, name=name)
                raise
            wc = c if wg is None else c * wg[g:g + per, start:start + ROWS, None]
            if start:
                k += np.matmul(np.swapaxes(wc, -1, -2), c)
            else:
                np.matmul(np.swapaxes(wc, -1, -2), c, out=k)
    return acc.reshape(kshape + (4, 4))


ROWS = _blocks.block_size(np.float64)
"""Rows of one mean summed by one product (`chordal_sums`): a block of float64 rows."""


def reduce(p, left, right):
    """Each rotation of `p` (..., 4) reduced to the smallest ``l p r`` over the rows l of
    `left` (L, 4) and r of `right` (R, 4) (None: the identity only); returns the reduced
    quaternions and the chosen indices (flat, one per rotation) into `left` and `right`."""
    eye = np.array([[1.0, 0.0, 0.0, 0.0]], p.dtype)
    ls = eye if left is None else left
    rs = eye if right is None else right
    pf = p.reshape(-1, 4)
    if left is None or right is None:
        # one side: |w| of c p (or p c) is |c · conj(p)|, a matrix product; the largest
        # gives the smallest angle
        score = np.abs((pf * np.array([1, -1, -1, -1], p.dtype)) @ (rs if left is None else ls).T)
        best = score.argmax(axis=1)
        zero = np.zeros_like(best)
        li, ri = (zero, best) if left is None else (best, zero)
    else:
        # |w| of l p r = |(l p) · conj(r)|
        lp = _kernels.multiply(ls[:, None], pf[None])                                 # (L, N, 4)
        score = np.abs(np.einsum("lni,ri->nlr", lp, _kernels.conjugate(rs)))
        best = score.reshape(score.shape[0], -1).argmax(axis=1)
        li, ri = np.divmod(best, rs.shape[0])
    reduced = pf if left is None else _kernels.multiply(ls[li], pf)
    reduced = (reduced if right is None else _kernels.multiply(reduced, rs[ri])).reshape(p.shape)
    return reduced, li, ri


def align(a, b, weights, return_sensitivity):
    """`align_vectors` on float64 arrays; returns (quat scalar-first, rssd, sensitivity or None)."""
    a0 = float_array(a, "a")
    b0 = float_array(b, "b")
    dtype = np.result_type(a0.dtype, b0.dtype)
    a2 = np.atleast_2d(a0).astype(np.float64)
    b2 = np.atleast_2d(b0).astype(np.float64)
    if a2.shape[-1] != 3:
        raise ValueError(f"Expected input `a` to have shape (3,) or (N, 3), got {a0.shape}")
    if b2.shape[-1] != 3:
        raise ValueError(f"Expected input `b` to have shape (3,) or (N, 3), got {b0.shape}")
    if a2.shape != b2.shape:
        raise ValueError(f"Expected inputs `a` and `b` to have same shapes, got {a0.shape} and {b0.shape} respectively")
    if a2.ndim > 2:
        raise ValueError(f"Expected inputs `a` and `b` to have shape (3,) or (N, 3), got {a0.shape} "
                         f"and {b0.shape} respectively")
    n = a2.shape[0]
    if n == 0:
        raise ValueError("expected at least one pair of vectors in a and b, got 0")
    if not (all_finite(a2) and all_finite(b2)):
        raise ValueError("expected finite values in a and b, got nan or inf")
    if weights is None:
        w = None if n > 1 else np.ones(1)
    else:
        w = float_array(weights, "weights").astype(np.float64)
        if w.ndim != 1:
            raise ValueError(f"Expected `weights` to be 1 dimensional, got shape {w.shape}")
        if n > 1 and w.shape[0] != n:
            raise ValueError(f"Expected `weights` to have number of values equal to number of input "
                             f"vectors, got {w.shape[0]} values and {n} vectors")
        if np.isnan(w).any() or (w < 0).any():
            raise ValueError("`weights` may not contain negative values: expected non-negative weights")
    inf = np.array([True]) if n == 1 else None if w is None else w == np.inf
    n_inf = 0 if inf is None else int(np.count_nonzero(inf))
    if n_inf > 1:
        raise ValueError("Only one infinite weight is allowed")
    if n_inf == 1:
        if return_sensitivity:
            raise ValueError("Cannot return sensitivity matrix with an infinite weight or one vector pair")
        q, rssd = _align_primary(a2, b2, w, inf)
        return q.astype(dtype), rssd, None
    big = a2.T @ b2 if w is None else (w[:, None] * a2).T @ b2   # (weights of 1: the same products)
    u, s, vt = np.linalg.svd(big)
    if _convert.det3((u @ vt).ravel().tolist()) < 0:   # Python floats
        s[-1] = -s[-1]
        u[:, -1] = -u[:, -1]
    rot = u @ vt
    s0, s1, s2 = s.tolist()
    if s1 + s2 < 1e-16 * s0:
        warnings.warn("Optimal rotation is not uniquely or poorly defined for the given sets of vectors.",
                      UserWarning, stacklevel=3)
    sq = np.sum(b2 ** 2 + a2 ** 2, axis=1)
    rssd = np.sqrt(max(float(np.sum(sq if w is None else w * sq)) - 2 * (s0 + s1 + s2), 0.0))
    sens = None
    if return_sensitivity:
        w = np.ones(n) if w is None else w
        zeta = (s[0] + s[1]) * (s[1] + s[2]) * (s[2] + s[0])
        kappa = s[0] * s[1] + s[1] * s[2] + s[2] * s[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            sens = np.mean(w) / zeta * (kappa * np.eye(3) + big @ big.T)
    q = _convert.from_matrix(rot)   # checked (U Vᵀ passes): one float64 matrix takes the float formulas
    return q.astype(dtype), rssd, sens


def _align_primary(a, b, w, inf):
    """The infinite-weight (or single-pair) case: align the primary pair exactly,
    then turn about it to fit the others best (scipy's algorithm)."""
    a_pri, b_pri = a[inf][0], b[inf][0]
    na, nb = np.linalg.norm(a_pri), np.linalg.norm(b_pri)
    if na == 0 or nb == 0:
        raise ValueError("Cannot align zero length primary vectors")
    a_pri, b_pri = a_pri / na, b_pri / nb
    # shortest-arc rotation taking b_pri to a_pri (antiparallel: π about any orthogonal axis)
    cross = np.cross(b_pri, a_pri)
    theta = np.arctan2(np.linalg.norm(cross), a_pri @ b_pri)
    if np.linalg.norm(cross) == 0 and theta > np.pi / 2:
        i = int(np.argmin(np.abs(a_pri)))
        axis = np.zeros(3)
        axis[i - 1], axis[i - 2] = a_pri[i - 2], -a_pri[i - 1]
        axis /= np.linalg.norm(axis)
    else:
        norm = np.linalg.norm(cross)
        axis = cross / norm if norm > 0 else np.array([1.0, 0, 0])
    q_pri = _convert.from_rotvec(axis * theta)
    q = q_pri
    if a.shape[0] > 1:
        sec = ~inf
        a_sec, b_sec, w_sec = a[sec], b[sec], w[sec]
        c_sec = _kernels.rotate(q_pri, b_sec)
        sin_term = np.einsum("ij,j->i", np.cross(c_sec, a_sec), a_pri)
        cos_term = np.einsum("ij,ij->i", c_sec, a_sec) - (c_sec @ a_pri) * (a_sec @ a_pri)
        phi = np.arctan2(np.sum(w_sec * sin_term), np.sum(w_sec * cos_term))
        q = _kernels.multiply(_convert.from_rotvec(phi * a_pri), q_pri)
    w_zero = w.copy()
    if a.shape[0] > 1 or np.isposinf(w[0]):
        w_zero[inf] = 0
    est = _kernels.rotate(q, b)
    rssd = np.sqrt(np.sum(w_zero @ (a - est) ** 2))
    return q, rssd
