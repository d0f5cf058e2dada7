"""Raw rigid motions ``x -> R(q) x + t`` stored as unit scalar-first quaternions (..., 4)
and translations (..., 3): apply, compose and invert, broadcasting batch shapes.

Long arrays of one batch shape take a fused blocked path that reads the
rows in place through complex views (``w + x i``, ``y + z i`` of a
quaternion; ``x i`` and ``y + z i`` of a vector as a pure quaternion) and
rotates with the one Hamilton product of `_kernels`, ``q p q*``: no
components-first copies, whose transposes cost more than the arithmetic.
"""

from math import prod

import numpy as np

from . import _blocks
from . import _kernels as Kn

__all__ = ["apply", "compose", "inverse"]

_COMPLEX = {np.dtype(np.float32): np.complex64, np.dtype(np.float64): np.complex128}
FUSED_MIN = 256   # below this the general path is as fast


def _pair(a, col):
    """Complex view of columns col, col + 1 of a C-contiguous float (N, k) array."""
    return np.ndarray((a.shape[0],), _COMPLEX[a.dtype], buffer=a, offset=col * a.itemsize,
                      strides=(a.strides[0],))


def _rows(a, k, n, dtype):
    return np.ascontiguousarray(a.reshape(n, k), dtype=dtype)


def _apply_block(sl, Q, V, T, O, inverse):
    n = sl.stop - sl.start
    work = _blocks.scratch()
    c, m0, m1, p0, p1, tmp = work.rows(6, (n,), Q.dtype)
    a, b = Q[sl, 0], Q[sl, 1]                 # read in place (strided)
    Vd, Td, Od = _pair(V, 1)[sl], _pair(T, 1)[sl], _pair(O, 1)[sl]
    vx, tx, ox = V[sl, 0], T[sl, 0], O[sl, 0]
    c.real[...] = 0
    if inverse:                               # R* (v - t): rotate by q* = conj(a) - b j
        np.subtract(vx, tx, out=c.imag)
        d = np.subtract(Vd, Td, out=p1)
        a = np.conjugate(a, out=p0)
        b = np.negative(b, out=work.rows(1, (n,), Q.dtype)[0])
    else:
        np.copyto(c.imag, vx)
        d = Vd
    Kn.hamilton(a, b, c, d, m0, m1, tmp)      # m = q p
    np.conjugate(a, out=c)
    d = np.negative(b, out=p1)
    Kn.hamilton(m0, m1, c, d, p0, m0, tmp)    # q p q* (m0 is read before it is overwritten)
    if inverse:
        np.copyto(ox, p0.imag)
        np.copyto(Od, m0)
    else:
        np.add(p0.imag, tx, out=ox)
        np.add(m0, Td, out=Od)


def apply(q, t, v, inverse=False):
    """``R(q) v + t`` (or ``R(q)ᵀ (v - t)`` with `inverse`) for unit q, broadcasting."""
    dtype = Kn.result_dtype(q, t, v)
    batch = np.broadcast_shapes(q.shape[:-1], t.shape[:-1], v.shape[:-1])
    n = prod(batch)
    if n >= FUSED_MIN and q.shape[:-1] == t.shape[:-1] == v.shape[:-1] == batch:
        Q = _rows(q, 4, n, dtype).view(_COMPLEX[np.dtype(dtype)])
        V, T = _rows(v, 3, n, dtype), _rows(t, 3, n, dtype)
        out = np.empty((n, 3), dtype)
        _blocks.run(lambda idx: _apply_block(idx[0] if idx else slice(0, n), Q, V, T, out, inverse),
                    _blocks.split((n,)), n)
        return out.reshape(batch + (3,))
    if inverse:
        return Kn.rotate(q, np.subtract(v, t, dtype=dtype), inverse=True).reshape(batch + (3,))
    out = np.asarray(Kn.rotate(q, v))
    if out.shape != batch + (3,) or out.dtype != dtype or not out.flags.writeable:
        out = np.broadcast_to(out, batch + (3,)).astype(dtype)
    out += t
    return out


def compose(q1, t1, q2, t2):
    """The motion ``(q2, t2)`` then ``(q1, t1)``: ``(q1 q2, R(q1) t2 + t1)``."""
    return Kn.multiply(q1, q2), apply(q1, t1, t2)


def inverse(q, t):
    """``(q*, -R(q*) t)``."""
    qi = Kn.conjugate(q)
    ti = np.asarray(Kn.rotate(qi, t))
    return qi, np.negative(ti, out=ti) if ti.flags.writeable else -ti
