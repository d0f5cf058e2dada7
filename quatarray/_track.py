"""Raw keyframe-track machinery: the time line, per-segment tables and their blocked evaluation.

A track of K keys over any batch of B tracks is evaluated from a *table*
of shape ``(R, K, B)`` (components first, in the keys' dtype): R rows per
segment, computed once at construction, plus a phantom segment K-1 that
holds the last key (so a query at the last key time is exact).  A call
finds each query's segment, gathers that segment's rows for a block of
queries and tracks, and runs a fixed number of batched kernels on them: no
Python loop over keys, queries or tracks.

`Timeline` holds the key times, the segment lookup and the extrapolation
policy shared by every kind of track (rotations in `interpolate.Track`,
rigid motions in `rigid.RigidTrack`).  The rows of the rotation methods
are great-circle frames ``[F (8), phi]`` per SLERP piece (`frame_rows`);
a query's rotation is then ``cos(u phi) k0 + sin(u phi) k_perp``.
"""

import math
from math import prod

import numpy as np

from . import _blocks
from . import _interp_curves
from . import _interp_kernels
from . import _kernels
from . import _ops
from . import _scale
from ._blocks import soa
from ._interp_lookup import SegmentIndex
from ._validate import finite, float_array

__all__ = ["EXTEND_LIMIT", "Timeline", "components_first", "qt_blocks", "frame_rows", "rotation_table",
           "gather", "evaluate", "angular_velocity"]


#: How far ``extrapolate='extend'`` reaches: this many lengths of the first
#: (last) segment before the first (after the last) key.  squad, Bézier and
#: spline curves are polynomials in time; further out they overflow, and
#: already here their angle keeps few correct digits (in float32, none).
#: Extrapolated rotations are renormalised, so they stay unit.
EXTEND_LIMIT = 1e4


class Timeline:
    """Key times (K,), their segment lookup and the extrapolation policy."""

    def __init__(self, times, extrapolate):
        self.times = times
        self.extrapolate = extrapolate
        self.index = SegmentIndex(times)
        self.dt = np.empty(len(times))
        np.subtract(times[1:], times[:-1], out=self.dt[:-1])
        self.dt[-1] = np.inf                           # phantom segment after the last key: u = 0

    def __getstate__(self):
        # pickles (e.g. shipped to Dask workers) carry the times; the lookup is rebuilt from them
        return {"times": self.times, "extrapolate": self.extrapolate}

    def __setstate__(self, state):
        self.__init__(state["times"], state["extrapolate"])

    def queries(self, t, name):
        """(shape of t, t as flat float64 (clamped with 'clamp'), mask of clamped queries or None)."""
        t = float_array(t, name)
        flat = np.ravel(t).astype(np.float64, copy=False)
        outside = None
        if flat.size:
            lo, hi = _scale.smallest(flat), _scale.largest(flat)
            if not (math.isfinite(lo) and math.isfinite(hi)):   # the API refuses nan and inf
                finite(flat, name)
            t0, t1 = float(self.times[0]), float(self.times[-1])
            if self.extrapolate == "raise" and (lo < t0 or hi > t1):
                bad = lo if lo < t0 else hi
                raise ValueError(f"expected {name} within the range [{t0!r}, {t1!r}], both inclusive "
                                 f"(extrapolate='raise'), got {bad!r}")
            if self.extrapolate == "clamp" and (lo < t0 or hi > t1):
                outside = (flat < t0) | (flat > t1)
                flat = np.clip(flat, t0, t1)
            if self.extrapolate == "extend":
                first = t0 - EXTEND_LIMIT * (float(self.times[1]) - t0)
                last = t1 + EXTEND_LIMIT * (t1 - float(self.times[-2]))
                if not first <= lo <= hi <= last:
                    bad = lo if not first <= lo else hi
                    raise ValueError(
                        f"expected {name} within {EXTEND_LIMIT:g} end-segment lengths of the keys, i.e. in "
                        f"[{first!r}, {last!r}] (extrapolate='extend'), got {bad!r}")
        return t.shape, flat, outside

    def find_all(self, flat):
        """Segments of all queries at once when they are sorted and many (else None)."""
        return self.index.find_sorted(flat) if flat.size > _blocks.BLOCK else None

    def segments(self, tb, velocity, found=None):
        """Segment index i and parameter u (float64) of the queries tb.

        Without `velocity`, a query at (or, with 'clamp', past) the last key
        gets the phantom segment K-1; with it, the last real segment.
        `found` is this block's part of `find_all`, if any.
        """
        i = self.index.find(tb) if found is None else found.copy()
        K = len(self.times)
        if velocity or self.extrapolate == "extend":
            np.clip(i, 0, K - 2, out=i)
        t0 = np.take(self.times, i, mode="clip")
        return i, segment_time(tb, t0, np.take(self.dt, i, mode="clip"), _ops.ARRAYS, t0)


def segment_time(t, t0, span, op, out=None):
    """A segment's own time ``u = (t - t0) / span`` (span = t1 - t0) of queries `t`, written
    once, in `op`'s arithmetic (`_ops`; into the row `out`, which may be t0)."""
    u = op.sub(t, t0, out)
    return op.div(u, span, u)


def components_first(q, K, B):
    """(K, ..., k) -> C-contiguous float64 (k, K, B): long contiguous rows for the
    construction-time maths (strided views make every NumPy call several times slower)."""
    out = np.empty((q.shape[-1], K, B))
    out[...] = soa(q.reshape(K, B, q.shape[-1]))
    return out


def qt_blocks(M, B, block=None):
    """(query slice, track slice) blocks of at most `block` (default BLOCK) elements each."""
    def as_slice(ix):
        return slice(ix, ix + 1) if isinstance(ix, int) else ix

    return [tuple(as_slice(ix) for ix in idx) + (slice(None),) * (2 - len(idx))
            for idx in _blocks.split((M, B), block or _blocks.BLOCK)]


def frame_rows(pieces, last):
    """Rows [F_1 (8), ..., F_n (8), phi_1, ..., phi_n] of shape (9n, K, B) for the n
    great-circle pieces (k0, k1) ((4, K-1, B) each) of every segment, plus a
    phantom segment K-1 that stays at `last` (4, B) (so t = t_end is exact)."""
    n = len(pieces)
    K1, B = pieces[0][0].shape[1:]
    table = np.empty((9 * n, K1 + 1, B))
    Fv = table[:8 * n].reshape(n, 8, K1 + 1, B)
    if n > 1 and n * K1 * B <= _blocks.BLOCK:   # small: one call on the stacked pieces
        k0 = np.stack([p[0] for p in pieces], 1)
        k1 = np.stack([p[1] for p in pieces], 1)
        _interp_kernels.frames(k0, k1, Fv[:, :, :K1].transpose(1, 0, 2, 3), table[8 * n:, :K1])
    else:                                   # large: piece by piece, no stacked copies
        for j, (k0, k1) in enumerate(pieces):
            _interp_kernels.frames(k0, k1, Fv[j, :, :K1], table[8 * n + j, :K1])
    Fv[:, :4, K1] = last[None]
    Fv[:, 4:, K1] = 0
    table[8 * n:, K1] = 0
    return table


def rotation_table(method, times, keys):
    """Table (R, K, B) in the keys' dtype and control points of a rotation track.

    `keys` (K, ..., 4) are unit and unflipped; `method` is 'linear',
    'slerp', 'squad' or 'bezier'.  The control points are None, s
    (K, ..., 4) for squad, or (a, b) for Bézier.
    """
    K = keys.shape[0]
    B = prod(keys.shape[1:-1])
    Q = components_first(keys, K, B)        # (4, K, B), C-contiguous float64
    controls = None
    if method == "linear":
        table = np.concatenate([Q, np.concatenate([Q[:, 1:], Q[:, -1:]], axis=1)])
    elif method == "slerp":
        table = frame_rows([(Q[:, :-1], Q[:, 1:])], Q[:, -1])
    elif method == "squad":
        s = controls = _interp_curves.squad_controls(keys, times)
        S = components_first(s, K, B)
        table = frame_rows([(Q[:, :-1], Q[:, 1:]), (S[:, :-1], S[:, 1:])], Q[:, -1])
    else:
        a, b = controls = _interp_curves.bezier_controls(keys, times)
        A = components_first(a, K, B)
        Bc = components_first(b, K, B)
        table = frame_rows([(Q[:, :-1], A[:, :-1]), (A[:, :-1], Bc[:, 1:]), (Bc[:, 1:], Q[:, 1:])], Q[:, -1])
    return np.ascontiguousarray(table, dtype=keys.dtype), controls


def gather(table, i, sb):
    """Table rows of segments `i` for tracks `sb`: (R, len(i), b), components first,
    in the calling thread's scratch."""
    R, _, B = table.shape
    work = _blocks.scratch()
    if B == 1:   # 2-D take: one element per row and index (twice as fast)
        G = work.rows(R, (len(i),), table.dtype)
        table[:, :, 0].take(i, axis=1, mode="clip", out=G)
        return G[:, :, None]
    tab = table[:, :, sb]
    G = work.rows(R, (len(i), tab.shape[2]), table.dtype)
    np.take(tab, i, axis=1, mode="clip", out=G)
    return G


def rotation_block(method, G, u, O):
    """Rotations (4, m, b) into `O` from gathered rows `G` and parameters `u` (m, 1)."""
    s = O.shape[1:]
    work = _blocks.scratch()
    if method == "slerp":
        _interp_kernels.frame_core(G[:8], G[8], u, O)
    elif method == "linear":   # NLERP of the segment's unit keys (unflipped: as given), whose blends
        _interp_kernels._nlerp_block(G[:4], G[4:8], u, O, shortest=False, in_range=True)   # are near 1
    elif method == "squad":
        P = work.rows(4, s, O.dtype)
        S = work.rows(4, s, O.dtype)
        _interp_kernels.frame_core(G[:8], G[16], u, P)
        _interp_kernels.frame_core(G[8:16], G[17], u, S)
        _interp_kernels.squad_blend(P, S, u, O)
    else:
        L = work.rows(12, s, O.dtype).reshape((4, 3) + s)
        for j in range(3):
            _interp_kernels.frame_core(G[8 * j:8 * j + 8], G[24 + j], u, L[:, j])
        _interp_kernels.bezier_levels(L, u, O)


def rotation_deriv(method, G, u):
    """(q, dq/du) of the rotation from gathered float64 rows `G` and parameters `u` (m, 1)."""
    if method == "linear":
        k0, k1 = G[:4], G[4:]
        return _interp_kernels._blend(k0, k1, 1 - u, u, _ops.STACKS, np.empty((8,) + k0.shape[1:]), None), k1 - k0
    if method == "slerp":
        return _interp_curves.frame_deriv(G[:8], G[8], u)
    if method == "squad":
        A, dA = _interp_curves.frame_deriv(G[:8], G[16], u)
        S, dS = _interp_curves.frame_deriv(G[8:16], G[17], u)
        return _interp_curves.slerp_deriv(A, dA, S, dS, _interp_kernels.squad_param(u), 2 - 4 * u)
    L = [_interp_curves.frame_deriv(G[8 * j:8 * j + 8], G[24 + j], u) for j in range(3)]
    M = [_interp_curves.slerp_deriv(*L[j], *L[j + 1], u, 1.0) for j in range(2)]
    return _interp_curves.slerp_deriv(*M[0], *M[1], u, 1.0)


def evaluate(timeline, table, flat, block_fn, width):
    """Run ``block_fn(G, u, O)`` over blocks of queries `flat` (M,) and the table's tracks.

    `G` is the gathered rows (R, m, b), `u` the segment parameters (m, 1) in
    the table's dtype and `O` the components-first view (width, m, b) of the
    block of the output (M, B, width), which is returned.
    """
    M, B = flat.size, table.shape[2]
    out = np.empty((M, B, width), table.dtype)
    found = timeline.find_all(flat)

    def block(qt):
        sm, sb = qt
        i, u = timeline.segments(flat[sm], False, None if found is None else found[sm])
        G = gather(table, i, sb)
        uu = u.astype(table.dtype)[:, None]
        block_fn(G, uu, soa(out[sm, sb]))

    if 0 < M * B <= _blocks.BLOCK:   # one block: the same call, without splitting or the pool
        with _blocks.scratch().frame():
            block((slice(None), slice(None)))
    else:
        _blocks.run(block, qt_blocks(M, B), M * B)
    return out


def angular_velocity(timeline, method, table, flat, outside, frame):
    """Angular velocity (M, B, 3) of a rotation track at queries `flat` (M,), in the table's dtype.

    Zero where `outside` (clamped queries) is set; `frame` is 'world' or 'body'.
    """
    M, B = flat.size, table.shape[2]
    out = np.empty((M, B, 3), np.float64)
    found = timeline.find_all(flat)
    for sm, sb in qt_blocks(M, B):
        tb = flat[sm]
        i, u = timeline.segments(tb, True, None if found is None else found[sm])
        tab = table[:, :, sb]
        G = np.take(tab, i, axis=1, mode="clip").astype(np.float64, copy=False)
        uu = u[:, None]
        q, dq = rotation_deriv(method, G, uu)
        w = _interp_curves.omega_from(q, dq, frame) / np.take(timeline.dt, i)[:, None]
        if outside is not None:
            w[:, outside[sm]] = 0
        soa(out[sm, sb])[...] = w
    return out.astype(table.dtype, copy=False)


# --------------------------------------------------------------------------- rigid motions

RIGID_ROWS = 23   # frame (8), phi, t0 (3), D (3), P (3), X (3), cos(2 phi), 1 / sin(2 phi)


def rigid_table(keys, translations):
    """Table (23, K, B) of a track of rigid motions, ScLERP on every segment.

    `keys` (K, ..., 4) are unit, unflipped rotation quaternions and
    `translations` (K, ..., 3) the translations, in the keys' dtype.  On
    segment i the rotation is SLERP (the real part of ScLERP), and with the
    relative rotation ``q_{i+1} q_i*`` = (cos Ω, sin Ω a) (world axis a) and
    ``Δ = t_{i+1} - t_i`` split into D = (a·Δ) a along the axis and
    P = Δ - D across it, the translation along the screw is

        t(u) = t_i + u D + f(u) P + g(u) a × P,
        f = sin(uΩ) cos((1-u)Ω) / sin Ω,   g = -sin(uΩ) sin((1-u)Ω) / sin Ω,

    written without the screw axis' point, which runs off to infinity as
    Ω -> 0 (f -> u, g -> 0: linear translation).
    """
    K = keys.shape[0]
    B = prod(keys.shape[1:-1])
    Q = components_first(keys, K, B)
    T = components_first(translations, K, B)
    table = np.zeros((RIGID_ROWS, K, B))
    table[:9] = frame_rows([(Q[:, :-1], Q[:, 1:])], Q[:, -1])
    rel = _kernels.multiply(np.moveaxis(Q[:, 1:], 0, -1), _kernels.conjugate(np.moveaxis(Q[:, :-1], 0, -1)))
    vec = rel[..., 1:]
    s = np.sqrt(np.sum(vec * vec, axis=-1, keepdims=True))
    axis = np.divide(vec, s, out=np.zeros_like(vec), where=s > 0)
    delta = np.moveaxis(T[:, 1:] - T[:, :-1], 0, -1)
    D = np.sum(axis * delta, axis=-1, keepdims=True) * axis
    P = delta - D
    table[9:12] = T
    table[12:15, :-1] = np.moveaxis(D, -1, 0)
    table[15:18, :-1] = np.moveaxis(P, -1, 0)
    table[18:21, :-1] = np.moveaxis(np.cross(axis, P), -1, 0)
    omega = 2 * table[8, :-1]
    table[21] = 1
    table[21, :-1] = np.cos(omega)
    sin = np.sin(omega)
    table[22, :-1] = np.divide(1, sin, out=np.zeros_like(sin), where=sin > 0)
    return np.ascontiguousarray(table, dtype=keys.dtype)


def rigid_block(G, u, O):
    """Rotations (O[:4]) and translations (O[4:7]) from gathered `rigid_table` rows."""
    s = O.shape[1:]
    c, sn = _interp_kernels.frame_core(G[:8], G[8], u, O[:4])   # the rotation: a slerp track's; cos, sin of u Ω
    rc, w = _blocks.scratch().rows(2, s, O.dtype)
    np.multiply(sn, G[22], out=rc)             # sin(uΩ) / sin Ω ...
    np.copyto(rc, np.broadcast_to(u, s), where=G[22] == 0)   # ... -> u as Ω -> 0
    rc *= G[21]                                # times cos Ω
    Ot = O[4:7]
    np.multiply(G[12:15], u, out=Ot)
    Ot += G[9:12]
    np.multiply(rc, c, out=w)
    w += sn * sn                               # f
    np.multiply(G[15:18], w, out=G[15:18])
    Ot += G[15:18]
    np.subtract(rc, c, out=w)
    w *= sn                                    # g
    np.multiply(G[18:21], w, out=G[18:21])
    Ot += G[18:21]
