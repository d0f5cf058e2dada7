"""Interpolation kernels on raw ndarrays (no `QuatArray` here).

Layout.  Inside a block the maths runs on *structure-of-arrays* views: a
block of quaternions of batch shape ``s`` is held as an array of shape
``(4, *s)`` (components first), so every NumPy call streams over long
contiguous rows.  Blocks are copied in from the caller's ``(..., 4)`` arrays
and written straight into ``np.moveaxis(out, -1, 0)`` of a preallocated
output.  Scratch rows live in a `Work` object, pooled per thread and reused
across blocks and calls, so a call allocates O(BLOCK) extra memory whatever
the size of its input (and fresh pages, which cost ~1.6 µs each to fault
in on this machine, are not touched again on every call).

SLERP weights.  For quaternions A, B (unit), with a = |B - A|, b = |B + A|,
the angle between them is Omega = 2 atan2(a, b) and rho = a / b =
tan(Omega / 2).  With tau = tan(h Omega / 2) the weights of
``w0 A + w1 B`` are, exactly,

    w1 = sin(h Omega) / sin(Omega) = (tau / rho) (1 + rho^2) / (1 + tau^2)
    w0 = cos(h Omega) - cos(Omega) w1
       = ((1 - tau^2) - (1 - rho^2) tau / rho) / (1 + tau^2)

so one call to arctan and one to tan replace the two calls to sin that the
textbook formula needs (on this hardware float64 sin costs ~8-12 ns per
element, tan and arctan ~1.4 ns), and no 1 - cos cancellation appears:
for tiny angles tau / rho -> h with full relative accuracy.
"""

import threading
from math import prod

import numpy as np

from ._kernels import _sub, blocks, result_dtype
from ._validate import CHUNK

__all__ = [
    "BLOCK", "Work", "drive", "soa", "sqsum", "vdot", "slerp_core", "frame_core", "frames",
    "slerp", "lerp", "nlerp", "squad", "bezier", "unflip",
]

#: Quaternions per block for the interpolation kernels (two of the shared
#: CHUNK: the per-call overhead of ~30 NumPy calls per block is then below
#: 2 ns per quaternion while the scratch stays within L2 / fast L3).
BLOCK = 2 * CHUNK


_TINY = {np.dtype(d): (np.sqrt(np.finfo(d).tiny), 4 * np.finfo(d).tiny) for d in (np.float32, np.float64)}


def _tiny(dtype):
    """Smallest rho = tan(Omega/2) kept as is: its square is still a normal number."""
    return _TINY[np.dtype(dtype)][0]


def _floor(dtype):
    """Floor for b² = |B + A|² (4 · smallest normal): keeps a²/b² finite and quiet."""
    return _TINY[np.dtype(dtype)][1]


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
    else:
        out = p[..., 0] * q[..., 0]
        for k in range(1, n):
            out += p[..., k] * q[..., k]
    return out


_POOL = threading.local()


class Work:
    """Scratch rows of one dtype, allocated once per call and reused per block.

    ``rows(key, n, shape)`` returns an ``(n, *shape)`` view of a buffer that
    is kept under `key`; two different keys never share memory.
    """

    def __init__(self, dtype):
        self.dtype = np.dtype(dtype)
        self._bufs = {}
        self.busy = False

    @classmethod
    def acquire(cls, dtype):
        """This thread's pooled scratch for `dtype` (a fresh one if it is in use).

        Fresh scratch costs page faults on first touch: for a call on ~10⁴
        quaternions that is several times the arithmetic, so the buffers are
        kept between calls (a few MB per thread and dtype, bounded by BLOCK).
        Pair with `release`.
        """
        pool = getattr(_POOL, "pool", None)
        if pool is None:
            pool = _POOL.pool = {}
        dtype = np.dtype(dtype)
        work = pool.get(dtype)
        if work is None or work.busy:
            work = cls(dtype)
            pool.setdefault(dtype, work)
        work.busy = True
        return work

    def release(self):
        self.busy = False

    def rows(self, key, n, shape):
        shape = tuple(shape)
        count = prod(shape)
        buf = self._bufs.get(key)
        if buf is None or buf.shape[0] < n or buf.shape[1] < count:
            buf = self._bufs[key] = np.empty((n, max(count, 1)), self.dtype)
        return buf[:n, :count].reshape((n,) + shape)


def soa(out):
    """Components-first view ``(4, ...)`` of an ``(..., 4)`` array (no copy)."""
    n = out.ndim - 1
    return out.transpose((n,) + tuple(range(n)))


def sqsum(T, out):
    """out = T[0]² + ... + T[3]² for a (4, ...) array (T is overwritten)."""
    np.multiply(T, T, out=T)
    np.add(T[0], T[1], out=out)
    out += T[2]
    out += T[3]
    return out


# --------------------------------------------------------------------------
# SLERP between two blocks (angle computed at run time)
# --------------------------------------------------------------------------

def slerp_core(A, B, h, O, shortest, work):
    """``O = slerp(A, B, h)`` on components-first arrays.

    A, B : (4, *s) arrays (not modified); h : broadcastable to s;
    O : (4, *s) output, may be a strided view, must not overlap A or B.
    With `shortest`, B is replaced by -B when |B + A| < |B - A| (ties keep B).
    """
    s = O.shape[1:]
    dtype = work.dtype
    T = work.rows("sl_T", 8, s)
    R = work.rows("sl_R", 7, s)
    a2, b2, r2, rho, tau, t2, w0 = R
    np.subtract(B, A, out=T[:4])
    np.add(B, A, out=T[4:])
    np.multiply(T, T, out=T)
    Tv = T.reshape((2, 4) + s)
    ab = R[:2]
    np.add(Tv[:, 0], Tv[:, 1], out=ab)
    ab += Tv[:, 2]
    ab += Tv[:, 3]
    antipodal = None
    if shortest:
        sgn = T[0]  # scratch row: T is free again
        np.subtract(b2, a2, out=sgn)  # sign of the dot product (b² - a² = 4 A·B)
        np.minimum(a2, b2, out=r2)
        np.maximum(a2, b2, out=b2)
    else:
        sgn = None
        np.copyto(r2, a2)
        zero_b = b2 == 0
        if zero_b.any():
            antipodal = zero_b & (a2 > 0)
    # b² = 0 only for zero input (or B = -A followed as given, fixed below):
    # a floor keeps the division finite and quiet (no errstate needed)
    np.maximum(b2, _floor(dtype), out=b2)
    np.divide(r2, b2, out=r2)
    np.sqrt(r2, out=rho)
    np.maximum(rho, _tiny(dtype), out=rho)
    np.arctan(rho, out=tau)
    np.multiply(tau, h, out=tau, casting="unsafe")
    np.tan(tau, out=tau)
    np.multiply(tau, tau, out=t2)
    v = tau
    np.divide(tau, rho, out=v)           # tau / rho  (-> h for tiny angles)
    g = rho
    np.add(t2, 1, out=g)
    np.divide(1, g, out=g)               # 1 / (1 + tau²)
    np.subtract(1, r2, out=w0)
    w0 *= v
    np.add(t2, w0, out=w0)               # tau² + (1 - rho²) v
    np.subtract(1, w0, out=w0)
    w0 *= g
    w1 = a2
    np.add(r2, 1, out=w1)
    w1 *= v
    w1 *= g
    if sgn is not None:
        np.copysign(1, sgn, out=sgn)     # +1, or -1 to follow -B (x - x is +0: ties keep B)
        w1 *= sgn
    if antipodal is not None and antipodal.any():
        # B = -A followed "as given": no unique arc; keep the rotation constant
        # (A before the midpoint, B from it on), a deterministic choice.
        hb = np.broadcast_to(h, s)
        w0[antipodal] = hb[antipodal] < 0.5
        w1[antipodal] = hb[antipodal] >= 0.5
    np.multiply(A, w0, out=T[:4])
    np.multiply(B, w1, out=T[4:])
    np.add(T[:4], T[4:], out=O)
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

    Runs in blocks along the second axis with pooled scratch: fresh
    temporaries of the full size would cost more in page faults than the
    arithmetic.
    """
    s = np.broadcast_shapes(k0.shape, k1.shape)[1:]
    if F is None:
        F = np.empty((8,) + s, np.result_type(k0, k1))
        phi = np.empty(s, F.dtype)
    k0 = np.broadcast_to(k0, (4,) + s)
    k1 = np.broadcast_to(k1, (4,) + s)
    if not s or 0 in s:
        _frames_block(k0, k1, F, phi, Work(F.dtype))
        return F, phi
    # flatten all but the last axis of s into blocks of about BLOCK frames
    lead = s[:-1]
    per = max(1, BLOCK // max(s[-1], 1))
    work = Work.acquire(F.dtype)
    try:
        for idx in np.ndindex(*lead[:-1]) if len(lead) > 1 else [()]:
            n = lead[-1] if lead else 1
            for start in range(0, n, per):
                sl = idx + ((slice(start, start + per),) if lead else ())
                full = (slice(None),) + sl
                _frames_block(k0[full], k1[full], F[full], phi[sl], work)
    finally:
        work.release()
    return F, phi


def _frames_block(k0, k1, F, phi, work):
    s = phi.shape
    D = F[4:]
    np.subtract(k1, k0, out=D)
    T = work.rows("frT", 4, s)
    R = work.rows("frR", 4, s)
    a2, b2, n2, sc = R
    np.multiply(D, D, out=T)
    np.add(T[0], T[1], out=a2)
    a2 += T[2]
    a2 += T[3]
    np.add(k1, k0, out=T)
    sqsum(T, b2)
    np.add(a2, b2, out=n2)
    n2 *= 0.5                                # 2 for unit quaternions
    a, b = T[0], T[1]
    np.sqrt(a2, out=a)
    np.sqrt(b2, out=b)
    np.arctan2(a, b, out=phi)
    np.multiply(a, b, out=sc)
    zero = sc == 0                           # coincident (a = 0) or antipodal (b = 0)
    np.maximum(sc, _TINY[np.dtype(F.dtype)][1], out=sc)
    np.divide(1, sc, out=sc)
    if zero.any():
        sc[zero] = 0
        phi[b == 0] = 0                      # antipodal: no unique arc; stay at k0
    D *= n2
    np.multiply(k0, a2, out=T)
    D += T
    D *= sc
    F[:4] = k0


def frame_core(F, phi, u, O, work, key="fr"):
    """``O = cos(2 u phi) k + sin(2 u phi) p`` with F = [k; p] of shape (8, *s).

    `F` is used as scratch (overwritten).  u broadcastable to s.
    With tau = tan(u phi): cos = 2/(1 + tau²) - 1, sin = tau · 2/(1 + tau²);
    u = 0 gives exactly k.
    """
    s = O.shape[1:]
    CS = work.rows(key, 2, s)
    c, sn = CS
    np.multiply(phi, u, out=sn, casting="unsafe")
    np.tan(sn, out=sn)                       # tau
    np.multiply(sn, sn, out=c)
    c += 1
    np.divide(2, c, out=c)                   # 2 / (1 + tau²)
    sn *= c                                  # sin
    c -= 1                                   # cos
    Fv = F.reshape((2, 4) + s)
    np.multiply(Fv, CS[:, None], out=Fv)
    np.add(Fv[0], Fv[1], out=O)
    return O


# --------------------------------------------------------------------------
# Pairwise drivers: broadcasting, blocks, preallocated output
# --------------------------------------------------------------------------

def drive(fn, quats, t, dtype, extra=()):
    """Run `fn(blocks_of_quats_soa, t_block, O, work, *extra)` over cache-sized blocks.

    quats: raw (..., 4) arrays broadcasting against each other and t.
    Returns the (batch, 4) output.
    """
    batch = np.broadcast_shapes(*(q.shape[:-1] for q in quats), t.shape)
    if not batch:  # kernels index scratch rows: give them at least one batch axis
        return drive(fn, [q[None] for q in quats], t[None], dtype, extra)[0]
    out = np.empty(batch + (4,), dtype)
    nb = len(batch)
    work = Work.acquire(dtype)
    try:
        for idx in blocks(batch, BLOCK):
            ob = out[idx]
            s = ob.shape[:-1]
            ins = []
            for j, q in enumerate(quats):
                buf = work.rows(("in", j), 4, s)
                qb = _sub(q, idx, nb)
                qb = qb.reshape((1,) * (len(s) + 1 - qb.ndim) + qb.shape)
                np.copyto(buf, soa(qb), casting="unsafe")
                ins.append(buf)
            fn(*ins, _sub(t, idx, nb, lead=0), soa(ob), work, *extra)
    finally:
        work.release()
    return out


#: Up to this many quaternions the pairwise functions use direct (..., 4)
#: expressions: fewer NumPy calls than the blocked kernels, whose per-call
#: overhead dominates below ~10³ quaternions.  Same formulas; the last bit may
#: differ from the blocked path.
SMALL = 512

_VECDOT = getattr(np, "vecdot", None)


def _small(quats, t):
    """The broadcast batch size when it is small enough for the direct path, else None."""
    shape = t.shape
    if any(q.shape[:-1] != shape for q in quats):
        shape = np.broadcast_shapes(*(q.shape[:-1] for q in quats), shape)
    size = prod(shape)
    return size if size <= SMALL else None


def _dot_last(x, y):
    return _VECDOT(x, y) if _VECDOT is not None else np.einsum("...i,...i->...", x, y)


def _sq_last(x):
    return _dot_last(x, x)


def slerp(q0, q1, t, shortest=True):
    """Pairwise SLERP of raw arrays (see `quatarray.interpolate.slerp`)."""
    dtype = result_dtype(q0, q1)
    if q0.shape == q1.shape == (4,) and t.ndim == 0:
        return _slerp_one(q0, q1, float(t), shortest, dtype)
    if _small((q0, q1), t) is not None:
        return _slerp_small(q0, q1, t, shortest, dtype)

    def fn(A, B, h, O, work):
        slerp_core(A, B, h, O, shortest, work)

    return drive(fn, (q0, q1), t, dtype)


def _slerp_small(q0, q1, t, shortest, dtype):
    """`slerp_core`'s weights as direct expressions on (..., 4) arrays (small batches)."""
    A = q0.astype(dtype, copy=False)
    B = q1.astype(dtype, copy=False)
    h = t.astype(dtype, copy=False)
    a2 = _sq_last(B - A)
    b2 = _sq_last(B + A)
    floor = _floor(dtype)
    if shortest:
        sgn = np.copysign(1, b2 - a2)
        r2 = np.minimum(a2, b2) / np.maximum(np.maximum(a2, b2), floor)
    else:
        r2 = a2 / np.maximum(b2, floor)
    rho = np.maximum(np.sqrt(r2), _tiny(dtype))
    tau = np.tan(np.arctan(rho) * h)
    t2 = tau * tau
    g = 1 / (1 + t2)
    v = tau / rho
    w0 = (1 - (t2 + (1 - r2) * v)) * g
    w1 = (1 + r2) * v * g
    if shortest:
        w1 *= sgn
    else:
        anti = (b2 == 0) & (a2 > 0)
        if anti.any():   # B = -A followed as given: constant rotation (as slerp_core)
            hb = np.broadcast_to(h, anti.shape)
            w0 = np.where(anti, hb < 0.5, w0)
            w1 = np.where(anti, hb >= 0.5, w1)
    out = A * w0[..., None].astype(dtype, copy=False)
    out += B * w1[..., None].astype(dtype, copy=False)
    return out


def _slerp_one(q0, q1, h, shortest, dtype):
    """One pair with Python floats (a few µs instead of ~30 NumPy calls)."""
    import math
    a = q0.tolist()
    b = q1.tolist()
    a2 = sum((y - x) ** 2 for x, y in zip(a, b))
    b2 = sum((y + x) ** 2 for x, y in zip(a, b))
    sign = 1.0
    if shortest and a2 > b2:
        a2, b2, sign = b2, a2, -1.0
    if b2 == 0:
        if a2 == 0 or math.isnan(h):
            w0 = w1 = math.nan
        else:  # antipodal, shortest=False
            w0, w1 = float(h < 0.5), float(h >= 0.5)
    elif math.isnan(a2 + b2 + h) or math.isinf(h):
        w0 = w1 = math.nan
    else:
        r2 = a2 / b2
        rho = max(math.sqrt(r2), float(_tiny(dtype)))
        tau = math.tan(h * math.atan(rho))
        t2 = tau * tau
        v = tau / rho
        g = 1 / (1 + t2)
        w0 = ((1 - t2) - (1 - r2) * v) * g
        w1 = sign * v * (1 + r2) * g
    return np.array([w0 * x + w1 * y for x, y in zip(a, b)], dtype)


def lerp(q0, q1, t):
    """(1 - t) q0 + t q1, broadcasting (raw arrays)."""
    dtype = result_dtype(q0, q1)
    if q0.shape == q1.shape == (4,) and t.ndim == 0:
        h = float(t)
        return np.array([(1 - h) * x + h * y for x, y in zip(q0.tolist(), q1.tolist())], dtype)

    if _small((q0, q1), t) is not None:
        h = t.astype(dtype, copy=False)[..., None]
        return ((1 - h) * q0 + h * q1).astype(dtype, copy=False)

    def fn(A, B, h, O, work):
        s = O.shape[1:]
        w = work.rows("lerp_w", 1, s)[0]
        np.subtract(1, h, out=w, casting="unsafe")
        T = work.rows("lerp_T", 8, s)
        np.multiply(A, w, out=T[:4])
        np.multiply(B, h, out=T[4:], casting="unsafe")
        np.add(T[:4], T[4:], out=O)

    return drive(fn, (q0, q1), t, dtype)


_ZERO_BLEND = ("nlerp: expected a non-zero blend (1 - t) q0 + t q1 to normalise, "
               "got a zero quaternion (q1 = -q0 with shortest=False, or zero input)")


def nlerp(q0, q1, t, shortest=True):
    """Normalised lerp with an optional shortest-path flip (q0·q1 < 0 flips q1) (raw arrays).

    Raises ValueError where the blend is the zero quaternion (only possible
    for q1 = -q0 followed as given, or zero input)."""
    dtype = result_dtype(q0, q1)
    if q0.shape == q1.shape == (4,) and t.ndim == 0:
        a, b, h = q0.tolist(), q1.tolist(), float(t)
        w1 = -h if shortest and sum(x * y for x, y in zip(a, b)) < 0 else h
        n = [(1 - h) * x + w1 * y for x, y in zip(a, b)]
        norm = sum(x * x for x in n) ** 0.5
        if not norm > 0:
            raise ValueError(_ZERO_BLEND)
        return np.array([x / norm for x in n], dtype)

    if _small((q0, q1), t) is not None:
        A = q0.astype(dtype, copy=False)
        B = q1.astype(dtype, copy=False)
        h = t.astype(dtype, copy=False)
        w1 = h
        if shortest:
            w1 = np.where(_dot_last(A, B) < 0, -h, h)
        n = (1 - h)[..., None] * A + w1[..., None].astype(dtype, copy=False) * B
        norm = np.sqrt(_sq_last(n))
        if not (norm > 0).all():
            raise ValueError(_ZERO_BLEND)
        n /= norm[..., None]
        return n.astype(dtype, copy=False)

    def fn(A, B, h, O, work):
        s = O.shape[1:]
        w0, w1, n = work.rows("nl_R", 3, s)
        T = work.rows("nl_T", 8, s)
        np.subtract(1, h, out=w0, casting="unsafe")
        np.copyto(w1, h, casting="unsafe")
        if shortest:
            np.multiply(A, B, out=T[:4])
            np.add(T[0], T[1], out=n)
            n += T[2]
            n += T[3]
            n += 0.0                          # -0.0 -> +0.0: a zero dot product keeps q1
            np.copysign(1, n, out=n)
            w1 *= n
        N = T[:4]
        np.multiply(A, w0, out=N)
        np.multiply(B, w1, out=T[4:])
        N += T[4:]
        np.multiply(N, N, out=T[4:])
        np.add(T[4], T[5], out=n)
        n += T[6]
        n += T[7]
        if not (n > 0).all():
            raise ValueError(_ZERO_BLEND)
        np.sqrt(n, out=n)
        np.divide(1, n, out=n)
        np.multiply(N, n, out=O)

    return drive(fn, (q0, q1), t, dtype)


def unflip(q, axis):
    """Signs flipped so that consecutive quaternions along batch `axis` have
    a non-negative dot product (the first one keeps its sign).

    Same result as the loop ``if q[i]·q[i-1] < 0: q[i] = -q[i]`` (with the
    already unflipped q[i-1]): the sign of q[i] is the product of the signs
    of the dot products d_j = q[j]·q[j-1] of the input since the last exact
    zero (a zero dot product needs no flip and restarts the product).
    Vectorised with a cumulative product; no loop over the axis.
    """
    qa = np.moveaxis(q, axis, 0) if axis else q
    dtype = result_dtype(q)
    n = qa.shape[0]
    if n < 2:
        return q.astype(dtype, copy=True)
    d = vdot(qa[1:], qa[:-1])
    step = np.ones(qa.shape[:-1], np.int8)
    step[1:][d < 0] = -1
    c = np.cumprod(step, axis=0, dtype=np.int8)           # sign with no restarts
    zero = np.zeros(qa.shape[:-1], bool)
    zero[1:] = d == 0
    if zero.any():
        idx = np.arange(n).reshape((n,) + (1,) * (qa.ndim - 2))
        last = np.maximum.accumulate(np.where(zero, idx, 0), axis=0)
        c = c * np.take_along_axis(c, last, axis=0)         # restart at the last zero
    out = qa * c[..., None].astype(dtype)
    return np.moveaxis(out, 0, axis) if axis else out


# --------------------------------------------------------------------------
# squad and spherical Bézier: pairwise evaluation
# --------------------------------------------------------------------------

def _squad_block(Q0, A, B, Q1, h, O, work):
    s = O.shape[1:]
    P = work.rows("sq_P", 4, s)
    S = work.rows("sq_S", 4, s)
    slerp_core(Q0, Q1, h, P, False, work)
    slerp_core(A, B, h, S, False, work)
    hh = work.rows("sq_h", 1, s)[0]
    np.subtract(1, h, out=hh, casting="unsafe")
    np.multiply(hh, h, out=hh, casting="unsafe")
    hh *= 2
    slerp_core(P, S, hh, O, False, work)


def squad(q0, a, b, q1, t):
    """Pairwise squad (raw arrays): slerp(slerp(q0, q1, t), slerp(a, b, t), 2t(1-t))."""
    return drive(_squad_block, (q0, a, b, q1), t, result_dtype(q0, a, b, q1))


def _bezier_levels(L, h, O, work):
    """de Casteljau by SLERP: L (4, 4, *s) holds the control points along axis 1."""
    s = O.shape[1:]
    M = work.rows("bz_M", 12, s).reshape((4, 3) + s)
    slerp_core(L[:, :3], L[:, 1:], h, M, False, work)
    N = work.rows("bz_N", 8, s).reshape((4, 2) + s)
    slerp_core(M[:, :2], M[:, 1:], h, N, False, work)
    slerp_core(N[:, 0], N[:, 1], h, O, False, work)


def _bezier_block(Q0, A, B, Q1, h, O, work):
    s = O.shape[1:]
    L = work.rows("bz_L", 16, s).reshape((4, 4) + s)
    for j, X in enumerate((Q0, A, B, Q1)):
        L[:, j] = X
    _bezier_levels(L, h, O, work)


def bezier(q0, a, b, q1, t):
    """Pairwise spherical cubic Bézier (raw arrays), de Casteljau with SLERP."""
    return drive(_bezier_block, (q0, a, b, q1), t, result_dtype(q0, a, b, q1))
