"""Keyframe curves on raw ndarrays: control points (computed once per track)
and analytic derivatives of the SLERP-built curves (for angular velocity).

Keys are unit, unflipped along axis 0, shape (K, ..., 4), scalar-first.
Construction runs in float64 whatever the key dtype (it is done once).

Ends.  Both curves extend the keys by one geodesic reflection at each end,
q₋₁ = q₀ q₁⁻¹ q₀ at time t₀ - Δ₀ (and q_K = q_{K-1} q_{K-2}⁻¹ q_{K-1} at
t_{K-1} + Δ_{K-2}).  The relative rotation q₋₁⁻¹ q₀ then equals q₀⁻¹ q₁
exactly, which is how it is used below (no reflected quaternion is formed).

Unequal spacing.  The tangent at key i, per unit time, is the central
difference (L₊ - L₋) / (Δ_{i-1} + Δ_i) of the logarithms L± = log(q_i⁻¹ q_{i±1});
each segment's control points scale it by its own interval, i.e. the
uniform-spacing tangents are scaled by 2 Δ_out / (Δ_in + Δ_out) and
2 Δ_in / (Δ_in + Δ_out) ("the ratio of the adjacent intervals").
"""

import numpy as np

from . import _blocks
from . import _kernels
from ._interp_kernels import slerp_core, vdot
from ._kernels import conjugate as _conj
from ._kernels import multiply as _qmul

__all__ = ["squad_controls", "bezier_controls", "slerp_deriv", "frame_deriv", "omega_from"]


# --------------------------------------------------------------------------
# small helpers on (..., 4) float64 arrays
# --------------------------------------------------------------------------

def _dot(p, q):
    return vdot(p, q)


def _log_vec(q):
    """Vector part of the principal log of unit quaternions, theta · v/|v| (`_kernels.log`'s)."""
    return _kernels.log(q)[..., 1:]


def _exp_vec(x):
    """exp of the pure quaternion (0, x), (cos|x|, sin|x| x/|x|) (`_kernels.exp`'s)."""
    p = np.zeros(x.shape[:-1] + (4,), x.dtype)
    p[..., 1:] = x
    return _kernels.exp(p)


def _double(p, q):
    """Shoemake's Double(p, q) = 2 (p·q) q - p: p reflected through q (= q p⁻¹ q for unit quaternions)."""
    return 2 * _dot(p, q)[..., None] * q - p


def _bisect(p, q):
    """Shoemake's Bisect(p, q) = (p + q) / |p + q|; p = -q (no midpoint) gives p."""
    s = p + q
    n = np.sqrt(_dot(s, s))[..., None]
    return np.divide(s, n, out=p.copy(), where=n > 0)


def _interval_weights(times, K, batch_ndim):
    """(w_in, w_out) per key: Δ_{i-1} / (Δ_{i-1} + Δ_i) and Δ_i / (Δ_{i-1} + Δ_i),
    with the mirrored intervals at the ends; shaped (K, 1, ..., 1) (or
    (K, n, 1, ..., 1) for times (K, n)) to broadcast over the batch and a last axis."""
    if times is None:
        w = np.full((K,) + (1,) * (batch_ndim + 1), 0.5)
        return w, w
    # times (K,) shared by every track, or (K, n) per track of the first batch axis
    shape = times.shape + (1,) * (batch_ndim + 2 - times.ndim)
    dt = np.diff(times, axis=0)
    din = np.concatenate([dt[:1], dt])
    dout = np.concatenate([dt, dt[-1:]])
    tot = din + dout
    return (din / tot).reshape(shape), (dout / tot).reshape(shape)


def _slerp_noflip(p, q, h):
    """SLERP (no flip) of (..., 4) float64 arrays; h broadcastable to the batch.

    Always the blocked kernel (pooled scratch, no full-size temporaries), so
    that a batch of tracks gets bit for bit the control points of its tracks."""
    h = np.asarray(h, np.float64)
    batch = np.broadcast_shapes(p.shape[:-1], q.shape[:-1], h.shape)
    out = np.empty(batch + (4,))
    _blocks.blockwise(slerp_core, [p, q], [out], batch, np.float64, views=[h], shortest=False)
    return out


# --------------------------------------------------------------------------
# control points
# --------------------------------------------------------------------------

def squad_controls(keys, times=None, ends=True):
    """Squad control points s_i, one per key: shape of `keys`, dtype of `keys`
    (``ends=False``: those of the inner keys 1..K-2 only, the same bits).

    s_i = q_i exp(-(w_in L₊ + w_out L₋) / 2) with L± = log(q_i⁻¹ q_{i±1}):
    Shoemake's q_i exp(-(L₊ + L₋)/4) for equal spacing.  With squad's
    tangent at u = 0, L₊ + 2 log(q_i⁻¹ s_i) (per unit u, body frame), and at
    u = 1, -L₋ - 2 log(q_i⁻¹ s_i), both equal Δ_out T resp. Δ_in T for the
    central difference T = (L₊ - L₋) / (Δ_in + Δ_out) with the *same* s_i:
    one control point per key makes the curve C¹ in time.  The ends give
    s₀ = q₀, s_{K-1} = q_{K-1} exactly.
    """
    q = keys.astype(np.float64)
    K = q.shape[0]
    L = _log_vec(_qmul(_conj(q[:-1]), q[1:]))           # log(q_j⁻¹ q_{j+1}), j = 0..K-2
    w_in, w_out = _interval_weights(times, K, q.ndim - 2)
    if ends:
        L = np.concatenate([L[:1], L, L[-1:]])           # reflected ends repeat the end rotations
    else:
        q, w_in, w_out = q[1:-1], w_in[1:-1], w_out[1:-1]
    # L₊ = L[i+1], L₋ = -L[i]
    x = (w_out * L[:-1] - w_in * L[1:]) / 2
    return _qmul(q, _exp_vec(x)).astype(keys.dtype, copy=False)


def bezier_controls(keys, times=None):
    """Spherical Bézier control points (a_i, b_i): shapes and dtype of `keys`.

    c_i = Bisect(Double(q_{i-1}, q_i), q_{i+1}); a_i = slerp(q_i, c_i, 2 w_out / 3),
    b_i = slerp(q_i, Double(c_i, q_i), 2 w_in / 3).  Equal spacing: a_i one
    third of the way to c_i and b_i = Double(a_i, q_i) (the paper's
    construction with the tangent shortened to a third).  Ends by reflection:
    Double(q₋₁, q₀) = q₁, so c₀ = q₁; likewise c_{K-1} = Double(q_{K-2}, q_{K-1}).
    """
    q = keys.astype(np.float64)
    K = q.shape[0]
    c = np.empty_like(q)
    c[1:-1] = _bisect(_double(q[:-2], q[1:-1]), q[2:])
    c[0] = q[1]
    c[-1] = _double(q[-2], q[-1])
    w_in, w_out = _interval_weights(times, K, q.ndim - 2)
    ends = np.stack([c, _double(c, q)])                  # (2, K, ..., 4)
    h = (2 / 3) * np.stack([w_out, w_in])[..., 0]        # (2, K, 1, ..., 1)
    ab = _slerp_noflip(q[None], ends, h).astype(keys.dtype, copy=False)
    return ab[0], ab[1]


# --------------------------------------------------------------------------
# derivatives (angular velocity): forward mode through the SLERPs
# --------------------------------------------------------------------------

_SERIES = tuple((-1) ** k / float(np.prod(np.arange(1.0, 2 * k + 2))) for k in range(8, 0, -1))


def _sin_minus_x(x):
    """sin(x) - x without cancellation: for |x| < 0.5 the series
    x³ (-1/3! + x²/5! - ... + x^14/17!) (the next term is < 1e-18 relative)."""
    x2 = x * x
    p = np.zeros_like(x)
    for c in _SERIES:
        p = p * x2 + c
    return np.where(np.abs(x) < 0.5, p * x2 * x, np.sin(x) - x)


def _n_weight(h, om):
    """N(h, Ω) = h cos(hΩ) sin Ω - sin(hΩ) cos Ω = sin²Ω ∂/∂Ω [sin(hΩ)/sin Ω], without
    cancellation: ½[(h - 1) g((1 + h)Ω) + (h + 1) g((1 - h)Ω)] with g(x) = sin x - x."""
    return 0.5 * ((h - 1) * _sin_minus_x((1 + h) * om) + (h + 1) * _sin_minus_x((1 - h) * om))


def slerp_deriv(A, dA, B, dB, h, dh):
    """(q, dq) for q = slerp(A, B, h) (no flip) and its derivative along dA, dB, dh.

    Components-first float64 arrays (4, *s); h, dh broadcastable to s.
    q = w0 A + w1 B with w1 = sin(hΩ)/sin Ω, w0 = sin((1-h)Ω)/sin Ω and
    Ω = 2 atan2(|B - A|, |B + A|), so
    dq = w0 dA + w1 dB + (∂h w0 dh + ∂Ω w0 dΩ) A + (∂h w1 dh + ∂Ω w1 dΩ) B;
    at Ω = 0 the limits w1 = h, ∂h w1 = 1, ∂Ω w1 = 0 are used.
    """
    D = B - A
    S = B + A
    a2 = vdot(D, D, axis=0)
    b2 = vdot(S, S, axis=0)
    a = np.sqrt(a2)
    b = np.sqrt(b2)
    om = 2 * np.arctan2(a, b)
    n2 = a2 + b2
    h = np.broadcast_to(h, om.shape)
    dh = np.broadcast_to(dh, om.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        sin_om = 2 * a * b / n2
        ok = sin_om > 0
        inv = np.where(ok, 1 / sin_om, 0)
        w1 = np.where(ok, np.sin(h * om) * inv, h)
        w0 = np.where(ok, np.sin((1 - h) * om) * inv, 1 - h)
        w1h = np.where(ok, om * np.cos(h * om) * inv, 1)
        w0h = np.where(ok, -om * np.cos((1 - h) * om) * inv, -1)
        w1o = np.where(ok, _n_weight(h, om) * inv * inv, 0)
        w0o = np.where(ok, _n_weight(1 - h, om) * inv * inv, 0)
        da = np.where(a > 0, vdot(D, dB - dA, axis=0) / a, 0)
        db = np.where(b > 0, vdot(S, dB + dA, axis=0) / b, 0)
        dom = np.where(n2 > 0, 2 * (b * da - a * db) / n2, 0)
    q = w0 * A + w1 * B
    dq = w0 * dA + w1 * dB + (w0h * dh + w0o * dom) * A + (w1h * dh + w1o * dom) * B
    return q, dq


def frame_deriv(F, phi, u):
    """(q, dq/du) along a great-circle frame F = [k; p] (8, *s): q = cos(2uφ) k + sin(2uφ) p,
    cos and sin `_kernels.cos_sin`'s (`_interp_kernels.frame_core`'s)."""
    c, s = _kernels.cos_sin(2 * phi * u)
    k, p = F[:4], F[4:]
    q = c * k + s * p
    dq = (2 * phi) * (c * p - s * k)
    return q, dq


def omega_from(q, dq, frame):
    """Angular velocity 2 vec(dq q*) / |q|² (world) or 2 vec(q* dq) / |q|² (body),
    components first: (4, *s) in, (3, *s) out (per unit of the curve parameter)."""
    qw, qv = q[0], q[1:]
    pw, pv = dq[0], dq[1:]
    cross = np.stack([
        pv[1] * qv[2] - pv[2] * qv[1],
        pv[2] * qv[0] - pv[0] * qv[2],
        pv[0] * qv[1] - pv[1] * qv[0],
    ])
    lin = qw * pv - pw * qv
    vec = lin - cross if frame == "world" else lin + cross
    n2 = vdot(q, q, axis=0)
    return vec * (2 / n2)
