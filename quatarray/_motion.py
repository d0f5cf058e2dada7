"""Raw rigid motions ``x -> R(q) x + t`` stored as unit scalar-first quaternions (..., 4)
and translations (..., 3): apply, compose and invert, broadcasting batch shapes.

Vectors are rotated by `_kernels.rotate`, the one rotation formula, at every
batch size (a vector gets the same bits as from `Rotation.apply`).
"""

import numpy as np

from . import _kernels

__all__ = ["apply", "apply_matrix", "compose", "inverse"]


def apply(q, t, v, inverse=False, unit=False):
    """``R(q) v + t`` (or ``R(q)ᵀ (v - t)`` with `inverse`) for unit q, broadcasting; `unit`:
    q is known to be finite and unit (`_kernels.rotate`'s `unit`)."""
    if v.shape == (3,) and q.shape == (4,) and t.shape == (3,):   # one motion, one vector: no checks
        if inverse:
            return _kernels.rotate(q, v - t, inverse=True, unit=unit)
        return _kernels.rotate(q, v, unit=unit) + t
    if q.shape[:-1] == t.shape[:-1] == v.shape[:-1] and q.dtype == t.dtype == v.dtype:
        dtype, batch = q.dtype, q.shape[:-1]
    else:
        dtype = _kernels.result_dtype(q, t, v)
        batch = np.broadcast_shapes(q.shape[:-1], t.shape[:-1], v.shape[:-1])
    if inverse:
        return _kernels.rotate(q, np.subtract(v, t, dtype=dtype), inverse=True, unit=unit).reshape(batch + (3,))
    if t.shape == batch + (3,) and q.shape[:-1] == v.shape[:-1] == batch and q.dtype == v.dtype == t.dtype:
        return _kernels.rotate(q, v, unit=unit, add=t)   # t added to each block while it is in cache
    out = np.asarray(_kernels.rotate(q, v, unit=unit))
    if out.shape != batch + (3,) or out.dtype != dtype or not out.flags.writeable:
        out = np.broadcast_to(out, batch + (3,)).astype(dtype)
    out += t
    return out


def compose(q1, t1, q2, t2, unit=False):
    """The motion ``(q2, t2)`` then ``(q1, t1)``: ``(q1 q2, R(q1) t2 + t1)``; `unit`: q1 is
    known to be finite and unit."""
    return _kernels.multiply(q1, q2), apply(q1, t1, t2, unit=unit)


def inverse(q, t, unit=False):
    """``(q*, -R(q*) t)``; `unit`: q is known to be finite and unit."""
    qi = _kernels.conjugate(q)
    ti = np.asarray(_kernels.rotate(qi, t, unit=unit))
    return qi, np.negative(ti, out=ti) if ti.flags.writeable else -ti


def apply_matrix(m, v, inverse):
    """``R v + t`` with R, t the blocks of the 4 x 4 matrices `m` as they are (``Rᵀ (v - t)``, scipy's
    inverse of a rigid matrix, with `inverse`), broadcasting: for transforms kept with
    ``normalize=False``, whose R need not be a rotation.  Each sum in column order, element by
    element: the same bits for any batch."""
    r, t = m[..., :3, :3], m[..., :3, 3]
    if inverse:
        r, v = np.swapaxes(r, -1, -2), v - t
    p = r * v[..., None, :].astype(r.dtype, copy=False)
    out = p[..., 0] + p[..., 1]
    out += p[..., 2]
    return out if inverse else out + t


def invert_matrix(m):
    """scipy's inverse of rigid matrices `m` (..., 4, 4) taken as they are: ``[Rᵀ, -Rᵀ t]``, with
    -Rᵀ t as `apply_matrix`'s ``Rᵀ (0 - t)``, so that a kept transform and its inverse agree."""
    out = np.zeros_like(m)
    out[..., :3, :3] = np.swapaxes(m[..., :3, :3], -1, -2)
    out[..., :3, 3] = apply_matrix(m, np.zeros(m.shape[:-2] + (3,), m.dtype), True)
    out[..., 3, 3] = 1
    return out
