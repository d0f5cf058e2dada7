"""Raw orientation time series on (T, B, ...) float64 arrays: integrate and differentiate
angular velocity, minimal rotation, swing-twist, geodesic mean, smoothing.

Quaternions are unit, scalar-first, time along axis 0 and one flattened batch
axis B.  Angular velocities are in the world frame, ω = 2 vec(q̇ q*), or the
body frame, ω_b = 2 vec(q* q̇) = q* ω q (as `Track.angular_velocity`).

Local coordinates.  Around sample k, r_j = log(q_k* q_j) (rotation vectors,
`_convert.as_rotvec`) are smooth functions of time with r(t_k) = 0, and
dr/dt = dexp⁻¹_r(ω_b) = ω_b - ½ r × ω_b + O(r²), so at t_k the first
derivative of r is the body angular velocity and the second its derivative
(the ½ r × ω_b term adds ½ ω_b × ω_b = 0).  Derivatives and smoothing are
then linear combinations of the r_j with weights of a polynomial fit in time
(`poly_weights`), one set per sample and stencil: no loop over samples.

Integration.  Over [t_k, t_{k+1}] of length h the rotation increment is the
exponential of a rotation vector φ: ω_k h for ω held constant (exact for
piecewise-constant ω), or the fourth-order Magnus expansion
φ = h/2 (ω₁ + ω₂) ∓ (√3/12) h² ω₁ × ω₂ at the two Gauss points (ω there from
the cubic through the four nearest samples), whose cross term is the coning
correction.  World frame: q_{k+1} = exp(φ) q_k (minus sign); body frame:
q_{k+1} = q_k exp(φ) (plus sign).  The products of the increments are formed
by a parallel prefix scan (log₂ T batched products, no loop over samples).
"""

import numpy as np

from . import _convert
from . import _kernels
__all__ = ["poly_weights", "stencil", "local_coordinates", "derivatives", "increments", "accumulate",
           "integrate", "swing_twist", "karcher", "smooth"]

_GAUSS = (0.5 - np.sqrt(3) / 6, 0.5 + np.sqrt(3) / 6)


def stencil(T, m):
    """Indices (T, m) of the m samples nearest each sample (shifted inwards at the ends)."""
    m = min(m, T)
    start = np.clip(np.arange(T) - m // 2, 0, T - m)
    return start[:, None] + np.arange(m)


def poly_weights(times, at, idx, order, derivs):
    """Weights (len(at), m, len(derivs)) of the values at times[idx] (len(at), m) giving
    the derivatives `derivs` at `at` of their least-squares polynomial of degree `order`
    (the interpolating polynomial when m = order + 1)."""
    x = times[idx] - at[:, None]
    h = np.maximum(np.abs(x).max(axis=1), np.finfo(np.float64).tiny)   # scale: a well-conditioned fit
    x = x / h[:, None]
    V = x[:, :, None] ** np.arange(order + 1)                             # (n, m, order+1)
    pinv = np.linalg.pinv(V)                                              # (n, order+1, m)
    fact = np.array([float(np.prod(np.arange(1, d + 1))) for d in derivs])
    w = pinv[:, list(derivs), :] * fact[None, :, None] / h[:, None, None] ** np.array(derivs)[None, :, None]
    return np.moveaxis(w, 1, 2)


def local_coordinates(q, idx, j):
    """r = log(q_k* q_idx[k, j]) (T, B, 3): the j-th stencil sample seen from each sample k."""
    return _convert.as_rotvec(_kernels.multiply(_kernels.conjugate(q), q[idx[:, j]]))


def derivatives(times, q, derivs, points=7):
    """Body-frame angular velocity (derivs 1) and acceleration (2) (T, B, 3) each,
    from the polynomial through the `points` nearest samples in local coordinates."""
    T = len(times)
    idx = stencil(T, points)
    m = idx.shape[1]
    w = poly_weights(times, times, idx, m - 1, derivs)
    out = [np.zeros(q.shape[:-1] + (3,)) for _ in derivs]
    for j in range(m):   # the stencil's points, not the samples
        r = local_coordinates(q, idx, j)
        for d in range(len(derivs)):
            out[d] += w[:, j, d, None, None] * r
    return out


def increments(times, omega, method, frame, points=6, substeps=2):
    """Rotation vectors φ (T-1, B, 3) of each step (see the module notes), or with
    `substeps` n > 1 for 'magnus' the n rotation vectors (T-1, n, B, 3) of its parts.
    ω between samples comes from the polynomial through the `points` nearest samples."""
    h = np.diff(times)
    if method == "constant":
        return omega[:-1] * h[:, None, None]
    T = len(times)
    m = min(points, T)
    mid = 0.5 * (times[:-1] + times[1:])
    start = np.clip(np.searchsorted(times, mid) - m // 2, 0, T - m)
    idx = start[:, None] + np.arange(m)                 # the m samples nearest each interval
    hs = h / substeps
    out = np.empty((T - 1, substeps) + omega.shape[1:])
    for j in range(substeps):
        gauss = []
        for g in _GAUSS:
            at = times[:-1] + (j + g) * hs
            w = poly_weights(times, at, idx, m - 1, (0,))[:, :, 0]    # (T-1, m)
            gauss.append(np.einsum("km,kmbc->kbc", w, omega[idx]))
        hh = hs[:, None, None]
        a1, a2 = hh * gauss[0], hh * gauss[1]   # the rotations over the step (no h² ω₁ × ω₂ to overflow)
        coning = (np.sqrt(3) / 12) * np.cross(a1, a2)
        out[:, j] = 0.5 * (a1 + a2) + (coning if frame == "body" else -coning)
    return out


def accumulate(dq, frame):
    """Products (T, B, 4) of the step rotations dq (T-1, B, 4), starting at the identity:
    P_k = dq_{k-1} ... dq_0 (world) or dq_0 ... dq_{k-1} (body), by a prefix scan."""
    P = np.empty((dq.shape[0] + 1,) + dq.shape[1:])
    P[0] = (1, 0, 0, 0)
    P[1:] = dq
    d = 1
    while d < len(P):
        P[d:] = _kernels.multiply(P[d:], P[:-d]) if frame == "world" else _kernels.multiply(P[:-d], P[d:])
        d *= 2
    return P


def integrate(times, omega, initial, method, frame, points=6, substeps=2):
    """Orientations (T, B, 4) from angular velocities omega (T, B, 3) and initial (B, 4)."""
    phi = increments(times, omega, method, frame, points, substeps)
    dq = _convert.from_rotvec(phi)
    if dq.ndim == 4:   # the parts of each step, composed in time order
        n = dq.shape[1]
        P = accumulate(dq.reshape((dq.shape[0] * n,) + dq.shape[2:]), frame)[::n]   # (no -1: B may be 0)
    else:
        P = accumulate(dq, frame)
    q = _kernels.multiply(P, initial[None]) if frame == "world" else _kernels.multiply(initial[None], P)
    return _kernels.normalize(q)


def swing_twist(q, axis):
    """(swing, twist) of unit q (..., 4) about unit `axis` (..., 3): q = swing twist,
    twist a rotation about `axis`; where it is undefined (q a half turn about an axis
    perpendicular to `axis`) the twist is the identity."""
    along = np.sum(q[..., 1:] * axis, axis=-1, keepdims=True)
    twist = np.concatenate([q[..., :1], along * axis], axis=-1)   # q and axis of one batch shape
    # scaled by a power of two near its largest component (exact, the same bits where nothing
    # underflows), so that the squares of a tiny twist do not underflow to a zero norm
    twist = np.ldexp(twist, -np.frexp(np.max(np.abs(twist), axis=-1, keepdims=True))[1]).astype(q.dtype, copy=False)
    n = np.sqrt(np.sum(twist * twist, axis=-1, keepdims=True))
    twist = np.divide(twist, n, out=np.broadcast_to(np.array([1.0, 0, 0, 0], q.dtype), twist.shape).copy(),
                      where=n > 0)
    swing = _kernels.multiply(q, _kernels.conjugate(twist))
    return swing, twist


def karcher(q, w, start, tol, max_iter):
    """Weighted geodesic mean over axis -2 of q (..., n, 4) with weights w (..., n)
    (summing to 1), from `start` (..., 4): mu <- mu exp(Σ w log(mu* q)) until the
    step's angle is below `tol`.  Each mean stops on its own step and is then dropped
    from the arrays, so it takes the steps it takes alone, whatever the others in the
    batch.  Returns (mean, None), or (mean, the largest last step) where a mean did not
    converge within `max_iter` steps."""
    shape = start.shape
    mu, out, group = start, None, None
    if mu.ndim > 1:   # one axis of means, along which they leave the iteration
        mu = mu.reshape(-1, 4)
        q, w = q.reshape(mu.shape[:1] + q.shape[-2:]), w.reshape(mu.shape[:1] + w.shape[-1:])
    for _ in range(max_iter):
        r = _convert.as_rotvec(_kernels.multiply(_kernels.conjugate(mu)[..., None, :], q))
        v = np.sum(w[..., None] * r, axis=-2)
        mu = _kernels.normalize(_kernels.multiply(mu, _convert.from_rotvec(v)))
        step = np.sqrt(np.sum(v * v, axis=-1))
        done = step <= tol
        if done.all() and out is None:   # all at once (one mean alone always)
            return mu.reshape(shape), None
        if done.any():
            if out is None:
                out, group = np.empty_like(mu), np.arange(len(mu))   # group: the means' places in `out`
            out[group[done]] = mu[done]
            if done.all():
                return out.reshape(shape), None
            keep = ~done
            group, mu, q, w = group[keep], mu[keep], q[keep], w[keep]
    if out is not None:
        out[group] = mu
        mu = out
    return mu.reshape(shape), float(step.max())


def smooth(times, q, points, order, passes=2):
    """Local polynomial fit (degree `order`, `points` nearest samples) in local coordinates
    about each sample, evaluated there: q_k exp(Σ_j c_j r_j); `passes` re-centres the
    coordinates on the previous pass's result."""
    T = len(times)
    idx = stencil(T, points)
    c = poly_weights(times, times, idx, min(order, idx.shape[1] - 1), (0,))[:, :, 0]
    centre = q
    for _ in range(passes):
        v = np.zeros(q.shape[:-1] + (3,))
        conj = _kernels.conjugate(centre)
        for j in range(idx.shape[1]):
            v += c[:, j, None, None] * _convert.as_rotvec(_kernels.multiply(conj, q[idx[:, j]]))
        centre = _kernels.normalize(_kernels.multiply(centre, _convert.from_rotvec(v)))
    return centre
