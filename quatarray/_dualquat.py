"""Raw unit dual quaternions on ``(..., 8)`` arrays: real part then dual part, each scalar-first.

A rigid motion ``x -> R x + t`` is ``real = q`` (the rotation's unit
quaternion) and ``dual = ½ (0, t) q``.  Products compose motions like
matrices (``a b`` applies ``b`` first); the inverse of a unit dual
quaternion is its quaternion conjugate.  ScLERP (screw linear
interpolation) is ``a (a* b)^s``, where the power follows the screw of
``a* b``: rotation by ``s θ`` about a fixed axis and translation by
``s d`` along it, so the motion has constant linear and angular velocity.
"""

import numpy as np

from . import _convert
from . import _kernels
from . import _scale
_TINY_ANGLE = {np.dtype(np.float64): 1e-12, np.dtype(np.float32): 1e-6}


def _parts(dq):
    return dq[..., :4], dq[..., 4:]


def _join(real, dual):
    return np.concatenate([real, dual], axis=-1)


def multiply(a, b):
    """Dual-quaternion product ``a b`` (the motion ``b`` then ``a``), broadcasting."""
    ra, da = _parts(a)
    rb, db = _parts(b)
    return _join(_kernels.multiply(ra, rb), _kernels.multiply(ra, db) + _kernels.multiply(da, rb))


def conjugate(dq):
    """Quaternion conjugate of both parts: the inverse of a unit dual quaternion."""
    r, d = _parts(dq)
    return _join(_kernels.conjugate(r), _kernels.conjugate(d))


def from_rotation_translation(quat, translation):
    """Unit dual quaternions of rotations (unit scalar-first quaternions) then translations."""
    batch = np.broadcast_shapes(quat.shape[:-1], translation.shape[:-1])
    dtype = np.result_type(quat.dtype, translation.dtype)
    t = np.zeros(batch + (4,), dtype)
    t[..., 1:] = translation
    real = np.broadcast_to(quat, batch + (4,)).astype(dtype)
    return _join(real, 0.5 * _kernels.multiply(t, real))


def as_rotation_translation(dq):
    """(unit quaternions, translations) of unit dual quaternions: ``t = 2 vec(dual real*)``."""
    r, d = _parts(dq)
    return r.copy(), 2 * _kernels.multiply(d, _kernels.conjugate(r))[..., 1:]


def normalize(dq):
    """Nearest unit dual quaternion: real part scaled to unit norm, dual part made orthogonal to it.

    A zero real part becomes the identity rotation (the dual part is kept), as in scipy.
    """
    r, d = _parts(dq)
    n = _kernels.norm(r)[..., None]   # |r| also where its square over- or underflows
    zero = n == 0
    if zero.any():
        r = np.where(zero, np.array([1, 0, 0, 0], r.dtype), r)
        n = np.where(zero, 1, n).astype(n.dtype)
    r = r / n
    d = d / n
    d = d - np.sum(r * d, axis=-1, keepdims=True) * r
    return _join(r, d)


def screw(dq):
    """Screw parameters of unit dual quaternions with ``w >= 0``.

    Returns ``(angle, axis, pitch_displacement, point)``: rotation ``angle``
    (in [0, π]) about the unit ``axis`` through ``point`` (perpendicular to
    the axis), and translation ``pitch_displacement`` along the axis.  For
    a pure translation the axis is the translation direction and the point 0.
    """
    r, t = as_rotation_translation(dq)
    vec = r[..., 1:]
    s = np.sqrt(_scale.sum_squares(np.moveaxis(vec, -1, 0), np.empty(vec.shape[:-1], vec.dtype)))   # |v|
    angle = _convert.magnitude(r)   # 2 atan(|v| / |w|): the package's rotation angle
    tiny = s < _TINY_ANGLE[np.dtype(dq.dtype)]
    tn = np.linalg.norm(t, axis=-1)
    axis_rot = vec / np.where(tiny, 1, s)[..., None]
    axis_tr = t / np.where(tn > 0, tn, 1)[..., None]
    axis = np.where(tiny[..., None], axis_tr, axis_rot)
    disp = np.sum(t * axis, axis=-1)
    t_perp = t - disp[..., None] * axis
    cot = r[..., 0] / np.where(tiny, 1, s)   # cot(θ/2) = w / |v|
    point = 0.5 * (t_perp + cot[..., None] * np.cross(axis, t_perp))
    point = np.where(tiny[..., None], 0, point)
    angle = np.where(tiny, 0, angle)
    return angle, axis, disp, point


def power(dq, s):
    """``dq ** s`` along the screw of ``dq`` (shortest: ``dq`` taken with ``w >= 0``)."""
    dq = np.where(dq[..., :1] < 0, -dq, dq)
    angle, axis, disp, point = screw(dq)
    s = np.asarray(s, dq.dtype)
    r = dq[..., :4]   # the rotation's power: `_convert.rotation_power`, Rotation's ** (about the
    real = _convert.rotation_power(r, s)   # screw axis; the identity for none)
    trans = (s * disp)[..., None] * axis + point - _kernels.rotate(real, np.broadcast_to(point, real.shape[:-1] + (3,)))
    return from_rotation_translation(real, trans)


def sclerp(a, b, s):
    """Screw linear interpolation ``a (a* b)^s``, broadcasting ``a``, ``b`` batches and ``s``."""
    s = np.asarray(s)
    rel = multiply(conjugate(a), b)
    rel = rel.reshape(rel.shape[:-1] + (1,) * s.ndim + (8,)) if s.ndim else rel
    return multiply(a.reshape(a.shape[:-1] + (1,) * s.ndim + (8,)) if s.ndim else a, power(rel, s))


def blend(dqs, weights, axis=0):
    """Dual-quaternion linear blending (DLB): the normalised weighted sum along ``axis``.

    Each dual quaternion is first flipped into the hemisphere of the first
    one (``q`` and ``-q`` are the same motion), as skinning does.
    """
    dqs = np.moveaxis(dqs, axis, 0)
    sign = np.where(np.sum(dqs[..., :4] * dqs[:1, ..., :4], axis=-1, keepdims=True) < 0, -1, 1)
    w = np.moveaxis(np.asarray(weights, dqs.dtype), axis, 0) if np.ndim(weights) > 1 else np.asarray(weights, dqs.dtype)
    w = w.reshape(w.shape + (1,) * (dqs.ndim - w.ndim))
    return normalize(np.sum(w * sign * dqs, axis=0))
