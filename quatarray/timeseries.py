"""Orientation time series: fewer keys within a stated error (`reduce_keys`), angular
velocity to orientations and back (`integrate_angular_velocity`, `angular_velocity`),
`minimal_rotation`, `swing_twist`, the geodesic mean (`geodesic_mean`), smoothing
(`smooth`) and bridging NaN gaps (`fill_gaps`).

The maths lives in `quatarray._reduce` and `quatarray._timeseries`; this module
validates, calls and wraps.
Conventions as in `quatarray.interpolate`: quaternions scalar-first (w, x, y, z),
time along axis 0, any batch shape after it, float32 kept as float32.
"""

from math import prod
from typing import NamedTuple

import numpy as np

from . import _blocks
from . import _convert
from . import _interp_kernels
from . import _kernels
from . import _reduce
from . import _timeseries
from ._array import QuatArray
from ._rotation import Rotation
from ._validate import batch_axis, choice, finite, float_array, integer, key_times
from .interpolate import METHODS as TRACK_METHODS
from .interpolate import Track

__all__ = ["ReducedKeys", "reduce_keys", "integrate_angular_velocity", "angular_velocity", "minimal_rotation",
           "swing_twist", "geodesic_mean", "smooth", "fill_gaps"]

FRAMES = ("world", "body")


def _series(keys, name, min_len=2):
    """keys (T, *batch, 4) from a QuatArray, array_like or Rotation: finite, unflipped, unit."""
    return _interp_kernels.unit_keys(_raw_series(keys, name, min_len), name)


def _raw_series(keys, name, min_len=2):
    """keys (T, *batch, 4) from a QuatArray, array_like or Rotation, checked finite (not copied)."""
    if isinstance(keys, Rotation):
        if keys.single:
            raise ValueError(f"expected {name} of shape (T, ...) (a sequence of rotations), got a single rotation")
        keys = keys._unit_quat(name)   # read only: not as_quatarray, which drops the rotation's unit flag
    keys = float_array(keys, name)
    if keys.ndim < 2 or keys.shape[-1] != 4:
        raise ValueError(f"expected {name} of shape (T, ..., 4), got {keys.shape}")
    if keys.shape[0] < min_len:
        raise ValueError(f"expected {name} of shape (T, ..., 4) with T >= {min_len}, got {keys.shape}")
    finite(keys, name)
    return keys


def _unit_series(raw, name, track_major, rows=None):
    """`unit_keys` of raw (T, B, 4): the same values as the whole at once, computed over
    blocks of `rows` times (about `_blocks.BLOCK` samples: every pass stays in cache, no
    temporaries of the whole input), returned (T, B, 4) or track-major (B, T, 4).

    A block starts with the previous block's last raw sample, its sign set as the
    previous block left it: `unit_keys` keeps the first key's sign and unflips the
    others from exact dot products of the keys as given, so the signs continue
    across blocks exactly as in one call.  Tracks are independent: groups of
    them run on the threads of `_blocks.run`.
    """
    T, B = raw.shape[:2]
    out = np.empty((B, T, 4) if track_major else (T, B, 4), raw.dtype)
    item = np.dtype((np.void, 4 * raw.dtype.itemsize))
    out_items = out.view(item)[..., 0]

    def fill(bounds):   # tracks b0:b1 (each track is unflipped on its own: any grouping gives the same bits)
        b0, b1 = bounds
        part = raw[:, b0:b1]
        n = rows or max(2, _blocks.BLOCK // max(b1 - b0, 1))
        sign = None
        for t0 in range(0, T, n):
            t1 = min(t0 + n, T)
            if sign is None:
                unit = _interp_kernels.unit_keys(part[t0:t1], name)
            else:
                block = part[t0 - 1:t1].copy()
                block[0] *= sign
                unit = _interp_kernels.unit_keys(block, name)[1:]
            if track_major:   # whole quaternions as 32- or 16-byte items: a copy per item, not per component
                out_items[b0:b1, t0:t1] = np.ascontiguousarray(unit).view(item)[..., 0].T
            else:
                out[t0:t1, b0:b1] = unit
            # the sign this block gave its last sample: compare the largest raw component
            last = part[t1 - 1]
            k = np.argmax(np.abs(last), axis=-1)[:, None]
            sign = np.where((np.take_along_axis(unit[-1], k, -1) < 0) == (np.take_along_axis(last, k, -1) < 0),
                            1, -1).astype(raw.dtype)

    threads = _blocks.get_num_threads() if T * B >= _blocks.PARALLEL_MIN else 1
    n = max(1, min(B, threads))
    edges = (np.arange(n + 1) * B) // n
    _blocks.run(fill, list(zip(edges[:-1], edges[1:])), T * B)
    return out


def _positive(x, name):
    if isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)):
        raise TypeError(f"expected {name} to be a real number, got {type(x).__name__}")
    x = float(x)
    if not (np.isfinite(x) and x > 0):
        raise ValueError(f"expected {name} > 0 (finite), got {x!r}")
    return x


class ReducedKeys(NamedTuple):
    """What `reduce_keys` returns: ``tracks, max_error = reduce_keys(...)``."""

    #: list of one-track `Track` (``shared=False``, in the batch's C order) or one `Track` (``shared=True``)
    tracks: object
    #: the largest angular error at the original times, per track: ndarray of the batch shape
    max_error: np.ndarray


def reduce_keys(times, keys, tolerance, *, method="slerp", shared=False, degrees=False):
    """Keep few keys of rotation tracks such that the curve through them stays within `tolerance`.

    From every key the next one is the farthest sample for which the chosen
    interpolation, evaluated at every original time in between, stays within
    the tolerance of the samples (a greedy farthest reach, all tracks and
    parts of tracks searched in lock step).  The kept keys are then made into
    `Track` objects, evaluated at every original time and compared with the
    samples; where the error exceeds the tolerance (squad's control points
    depend on neighbours the search had to guess) the worst sample becomes a
    key, until none does.  The error returned is measured on the returned tracks.

    Parameters
    ----------
    times : array_like, shape (T,)
        Sample times: finite, strictly increasing, T >= 2.
    keys : array_like, QuatArray or Rotation, shape (T, *batch, 4) (Rotation: (T, *batch))
        Samples of any batch of tracks (normalised and unflipped along time first).
    tolerance : float
        Largest angle allowed between the curve and any sample, > 0; radians
        unless `degrees`.  Below the dtype's resolution (about 1e-7 rad in
        float32) the check may keep every sample.
    method : {'slerp', 'linear', 'squad'}, default 'slerp'
        Interpolation of the result (`Track` methods; 'linear' is NLERP).
    shared : bool, default False
        False: each track is reduced on its own.  True: all tracks keep one
        common grid of key times (as BVH and CSV need); the error of every
        track stays within the tolerance.
    degrees : bool, default False
        `tolerance` and the returned errors in degrees.

    Returns
    -------
    ReducedKeys
        ``(tracks, max_error)``.  `tracks`: with ``shared=False`` a list of
        one-track `Track` (batch shape ``()``), one per track in the batch's
        C order; with ``shared=True`` one `Track` of batch shape `batch`.
        `max_error`: ndarray of shape `batch`, the largest angle between the
        track and the samples at the original times (<= `tolerance`).

    Raises
    ------
    ValueError
        Unsorted or non-finite times, non-finite or zero keys, T < 2,
        tolerance <= 0, unknown method.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import Rotation, reduce_keys
    >>> t = np.linspace(0, 2, 201)
    >>> r = Rotation.from_euler("zx", np.c_[np.sin(2 * t), 0.3 * t ** 2])
    >>> tracks, err = reduce_keys(t, r, 0.1, method="squad", degrees=True)
    >>> len(tracks), len(tracks[0]) < 201 // 5, float(err) <= 0.1
    (1, True, True)
    """
    method = choice(method, "method", _reduce.METHODS)
    tol = _positive(tolerance, "tolerance")
    raw = _raw_series(keys, "keys")
    times = key_times(times, raw.shape[0], "times", "keys")
    batch = raw.shape[1:-1]
    T, B = raw.shape[0], prod(batch)
    tol_rad = np.radians(tol) if degrees else tol
    Q = _unit_series(raw.reshape(T, B, 4), "keys", not (shared or B == 0))

    def make_track(idx, b):
        k = Q[idx] if b is None else Q[b, idx]
        return Track(times[idx], k.reshape((len(idx),) + (batch if b is None else ()) + (4,)), method=method)

    if B == 0:
        ends = [0, T - 1]   # no track to keep within anything: the two ends make a Track
        return ReducedKeys(Track(times[ends], Q[ends].reshape((2,) + batch + (4,)), method=method) if shared else [],
                           np.zeros(batch, raw.dtype))
    _, tracks, errors = _reduce.reduce(method, times, Q, tol_rad, bool(shared), make_track)
    errors = errors.reshape(batch)
    if degrees:
        errors = np.degrees(errors)
    return ReducedKeys(tracks[0] if shared else tracks, errors.astype(raw.dtype))


# ---------------------------------------------------------------------------
# angular velocity <-> orientation
# ---------------------------------------------------------------------------

def _wrap_rotation(q, dtype):
    return Rotation.from_quat(np.asarray(q, dtype), scalar_first=True)


def _vectors(x, name, T):
    x = float_array(x, name)
    if x.ndim < 1 or x.shape[-1] != 3 or x.ndim < 2:
        raise ValueError(f"expected {name} of shape (T, ..., 3), got {x.shape}")
    if x.shape[0] != T:
        raise ValueError(f"expected as many {name} as times, got {x.shape[0]} {name} and {T} times")
    return finite(x, name)


def integrate_angular_velocity(times, omega, *, initial=None, frame="world", method="magnus"):
    """Orientations from sampled angular velocities.

    Parameters
    ----------
    times : array_like, shape (T,)
        Sample times, finite and strictly increasing, T >= 2.
    omega : array_like, shape (T, ..., 3)
        Angular velocity at each time (radians per unit of time), any batch
        shape after the time axis.
    initial : Rotation or array_like of shape (..., 4), optional
        Orientation at ``times[0]`` (scalar-first quaternions broadcasting
        against the batch shape); the identity by default.
    frame : {'world', 'body'}, default 'world'
        ``'world'``: ω in the fixed frame, q̇ = ½ ω q, each step applied on
        the left, ``q[k+1] = exp(φ_k) q[k]``.  ``'body'``: ω in the rotating
        frame (a gyroscope), q̇ = ½ q ω, each step applied on the right,
        ``q[k+1] = q[k] exp(φ_k)``.
    method : {'magnus', 'constant'}, default 'magnus'
        ``'constant'``: ω[k] held over [t_k, t_{k+1}), φ_k = ω[k] Δt: exact
        for piecewise-constant ω.  ``'magnus'``: for smoothly varying ω, the
        fourth-order Magnus step at the two Gauss points of each interval,
        ω there from the cubic through the four nearest samples, with the
        cross (coning) term ∓ (√3/12) Δt² ω₁ × ω₂; error O(Δt⁴).

    Returns
    -------
    Rotation, shape (T, ...)
        In omega's dtype (computed in float64).

    Examples
    --------
    A constant 1 rad/s about z for π/2 seconds is a quarter turn:

    >>> import numpy as np
    >>> from quatarray import integrate_angular_velocity
    >>> t = np.linspace(0, np.pi / 2, 50)
    >>> r = integrate_angular_velocity(t, np.tile([0.0, 0, 1], (50, 1)))
    >>> np.round(r[-1].as_rotvec(), 12) + 0.0
    array([0.        , 0.        , 1.57079633])
    """
    frame = choice(frame, "frame", FRAMES)
    method = choice(method, "method", ("magnus", "constant"))
    w = float_array(omega, "omega")
    times = key_times(times, w.shape[0] if w.ndim else 0, "times", "omega")
    if len(times) < 2:
        raise ValueError(f"expected at least 2 times, got {len(times)}")
    w = _vectors(w, "omega", len(times))
    batch = w.shape[1:-1]
    if initial is None:
        q0 = np.zeros(batch + (4,))
        q0[..., 0] = 1
    else:
        if isinstance(initial, Rotation):
            initial = initial._unit_quat("initial")
        q0 = float_array(initial, "initial", last=4).astype(np.float64)
        finite(q0, "initial")
        try:
            fits = np.broadcast_shapes(q0.shape[:-1], batch) == batch
        except ValueError:
            fits = False
        if not fits:
            raise ValueError(f"expected initial of shape (..., 4) broadcasting to the batch shape {batch}, "
                             f"got {q0.shape}")
        q0 = _kernels.normalize(np.ascontiguousarray(np.broadcast_to(q0, batch + (4,)).reshape(-1, 4)))
    T, B = len(times), prod(batch)
    q = _timeseries.integrate(times, w.reshape(T, B, 3).astype(np.float64), np.asarray(q0).reshape(B, 4), method, frame)
    return _wrap_rotation(q.reshape((T,) + batch + (4,)), w.dtype)


def _given_quats(rotations):
    """The quaternions as given (signs kept), as an ndarray."""
    return np.asarray(rotations._unit_quat() if isinstance(rotations, Rotation) else rotations)


def _orientations(rotations, name="rotations"):
    """(T, *batch, 4) unit, unflipped float quaternions from a Rotation / QuatArray / array (T >= 2)."""
    return _series(rotations, name)


def angular_velocity(times, rotations, *, frame="world", acceleration=False, points=7):
    """Angular velocity of sampled orientations at their own times.

    The rotation vectors ``log(q_k* q_j)`` of the `points` nearest samples
    seen from each sample k are fitted by their interpolating polynomial in
    time (a 6th-degree one by default), whose first derivative at t_k is the
    body angular velocity and whose second is its derivative: as accurate
    at the ends (a one-sided stencil) as inside, for any batch shape.

    Parameters
    ----------
    times : array_like, shape (T,)
        Strictly increasing, T >= 2.
    rotations : Rotation, shape (T, ...), or quaternions (T, ..., 4)
    frame : {'world', 'body'}, default 'world'
        ω = 2 vec(q̇ q*) (fixed frame) or ω_b = 2 vec(q* q̇) = q* ω q.
    acceleration : bool, default False
        Also return the angular acceleration dω/dt in the same frame.
    points : int, default 7
        Samples per fit (at least 2; fewer when T is smaller): the error
        falls like Δt^(points - 1) for smooth motion.

    Returns
    -------
    ndarray, shape (T, ..., 3), or a tuple (omega, alpha) with `acceleration`
        Radians per unit of time (per unit of time squared), in the
        rotations' dtype.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import Rotation, angular_velocity
    >>> t = np.linspace(0, 1, 11)
    >>> r = Rotation.from_rotvec(np.outer(t ** 2, [0, 0, 1.0]))   # angle t², about z
    >>> np.round(angular_velocity(t, r)[[0, 5, 10]], 9) + 0.0          # 2 t
    array([[0., 0., 0.],
           [0., 0., 1.],
           [0., 0., 2.]])
    """
    frame = choice(frame, "frame", FRAMES)
    points = integer(points, "points", 2)
    Q = _orientations(rotations)
    times = key_times(times, Q.shape[0], "times", "rotations")
    T, batch = Q.shape[0], Q.shape[1:-1]
    q = Q.reshape(T, -1, 4).astype(np.float64)
    derivs = (1, 2) if acceleration and min(points, T) > 2 else (1,)
    out = _timeseries.derivatives(times, q, derivs, int(points))
    if acceleration and len(out) == 1:   # two samples: a straight great circle, no acceleration
        out.append(np.zeros_like(out[0]))
    if frame == "world":
        out = [_kernels.rotate(q, v) for v in out]
    out = [v.reshape((T,) + batch + (3,)).astype(Q.dtype) for v in out]
    return tuple(out) if acceleration else out[0]


def minimal_rotation(times, rotations, axis=(0.0, 0.0, 1.0), *, iterations=2):
    """Remove the twist about a body axis from a series of orientations.

    Returns ``R(t) exp(γ(t) a / 2)``, the same orientations of the axis
    ``a`` (``R a`` is unchanged) with the rotation about it chosen so that
    the body angular velocity has no component along ``a``:
    γ(t) = -∫ ω_b · a dt, from t₀ on (γ(t₀) = 0).  As numpy-quaternion's
    ``minimal_rotation``, the angular velocity comes from the samples and
    is integrated by the trapezoidal rule, `iterations` times.

    Parameters
    ----------
    times : array_like, shape (T,)
    rotations : Rotation, shape (T, ...), or quaternions (T, ..., 4)
    axis : array_like, shape (3,) or (..., 3), default z
        Body axis (normalised), broadcasting against the batch shape.
    iterations : int, default 2

    Returns
    -------
    Rotation, shape (T, ...)

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import Rotation, angular_velocity, minimal_rotation
    >>> t = np.linspace(0, 2, 201)
    >>> r = Rotation.from_euler("zx", np.c_[3 * t, np.sin(t)])     # spins about its z axis
    >>> m = minimal_rotation(t, r)
    >>> w = angular_velocity(t, m, frame="body")
    >>> bool(np.abs(w[:, 2]).max() < 1e-6)
    True
    >>> bool(np.allclose(m.apply([0, 0, 1]), r.apply([0, 0, 1])))      # the axis is kept
    True
    """
    iterations = integer(iterations, "iterations", 0)
    Q = _orientations(rotations)
    times = key_times(times, Q.shape[0], "times", "rotations")
    T, batch = Q.shape[0], Q.shape[1:-1]
    a = float_array(axis, "axis", last=3).astype(np.float64)
    finite(a, "axis")
    n = np.linalg.norm(a, axis=-1, keepdims=True)
    if not (n > 0).all():
        raise ValueError("expected a non-zero axis, got a zero vector")
    try:
        a = np.broadcast_to(a / n, batch + (3,)).reshape(1, -1, 3)
    except ValueError:
        raise ValueError(f"expected axis of shape (3,) or one that broadcasts to the rotations' batch shape "
                         f"{batch} + (3,), got {a.shape}") from None
    q = Q.reshape(T, -1, 4).astype(np.float64)
    for _ in range(iterations):
        wb = _timeseries.derivatives(times, q, (1,))[0]
        along = np.sum(wb * a, axis=-1)
        dt = np.diff(times)[:, None]
        gamma = np.concatenate([np.zeros((1, along.shape[1])),
                                np.cumsum(0.5 * (along[1:] + along[:-1]) * dt, axis=0)])
        q = _kernels.multiply(q, _convert.from_rotvec(-gamma[..., None] * a))
    return _wrap_rotation(q.reshape((T,) + batch + (4,)), Q.dtype)


# ---------------------------------------------------------------------------
# decomposition and averaging
# ---------------------------------------------------------------------------

def swing_twist(rotations, axis):
    """Split rotations into a swing and a twist about `axis`: ``r = swing * twist``.

    The twist is the rotation about `axis` closest to r (the projection of
    r's quaternion vector part on the axis); the swing turns the axis
    itself (its rotation axis is perpendicular to `axis`).  Where the twist
    is undefined (a half turn about an axis perpendicular to `axis`) it is
    the identity.

    Parameters
    ----------
    rotations : Rotation, or quaternions (..., 4)
    axis : array_like, shape (3,) or (..., 3)
        Broadcasting against the batch shape; normalised.

    Returns
    -------
    swing, twist : Rotation
        Of the broadcast batch shape.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import Rotation, swing_twist
    >>> r = Rotation.from_euler("ZX", [40, 30], degrees=True)    # 40° about z, then 30° about x
    >>> swing, twist = swing_twist(r, [0, 0, 1])
    >>> np.round(twist.as_rotvec(degrees=True), 9) + 0.0
    array([ 0.,  0., 40.])
    >>> bool((swing * twist).approx_equal(r))
    True
    """
    if isinstance(rotations, Rotation):
        rotations = rotations._unit_quat()
    q = float_array(rotations, "rotations", last=4)
    finite(q, "rotations")
    a = float_array(axis, "axis", last=3)
    finite(a, "axis")
    n = np.linalg.norm(a, axis=-1, keepdims=True)
    if not (n > 0).all():
        raise ValueError("expected a non-zero axis, got a zero vector")
    batch = np.broadcast_shapes(q.shape[:-1], a.shape[:-1])
    q64 = _kernels.normalize(np.ascontiguousarray(np.broadcast_to(q.astype(np.float64), batch + (4,))))
    swing, twist = _timeseries.swing_twist(q64, np.broadcast_to(a / n, batch + (3,)).astype(np.float64))
    return _wrap_rotation(swing, q.dtype), _wrap_rotation(twist, q.dtype)


def geodesic_mean(rotations, weights=None, axis=None, *, tol=1e-12, max_iter=100):
    """Geodesic (Karcher) mean: the rotation minimising the weighted sum of squared angles.

    Starts from the chordal mean (`Rotation.mean`) and iterates
    ``mu <- mu exp(Σ wᵢ log(mu⁻¹ qᵢ) / Σ w)`` until the step is below `tol`
    radians.  For rotations within a hemisphere of each other (angles up to
    π/2 from the mean) the minimiser is unique and the iteration converges
    to it.

    Parameters
    ----------
    rotations : Rotation, or quaternions (..., 4)
    weights : array_like, optional
        Non-negative, broadcastable to the batch shape, not all zero along
        the averaged axes.
    axis : None, int or tuple of ints, optional
        Batch axes to average over (default: all).
    tol : float, default 1e-12
        Convergence: the angle of the last step, radians.
    max_iter : int, default 100
        `ValueError` if not converged by then.

    Returns
    -------
    Rotation
        The batch shape without the averaged axes.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import Rotation, geodesic_mean
    >>> r = Rotation.from_rotvec([[0, 0, 0.1], [0, 0, 0.5], [0, 0, 0.6]])
    >>> np.round(geodesic_mean(r).as_rotvec(), 12) + 0.0       # about one axis: the mean angle
    array([0. , 0. , 0.4])
    """
    r = rotations if isinstance(rotations, Rotation) else Rotation.from_quat(
        float_array(rotations, "rotations", last=4), scalar_first=True)
    tol = _positive(tol, "tol")
    max_iter = integer(max_iter, "max_iter", 1)
    start = r.mean(weights=weights, axis=axis)   # validates weights and axis as the chordal mean does
    q = np.asarray(r._unit_quat(), np.float64)
    if q.ndim == 1:
        q = q[None]
    batch = q.shape[:-1]
    nb = len(batch)
    axes = tuple(range(nb)) if axis is None else tuple(sorted({
        batch_axis(a, batch, "rotations") for a in ((axis,) if np.ndim(axis) == 0 else axis)}))
    keep = tuple(a for a in range(nb) if a not in axes)
    order = keep + axes
    w = np.ones(batch) if weights is None else np.broadcast_to(np.asarray(weights, np.float64), batch)
    kshape, n = tuple(batch[a] for a in keep), prod(batch[a] for a in axes)   # (n, not -1: kshape may hold a 0)
    qm = q.transpose(order + (nb,)).reshape(kshape + (n, 4))
    # contiguous, one group a row: NumPy sums a strided axis in another order than a
    # contiguous one, so each group's total weight is summed as the group's alone is
    wm = np.ascontiguousarray(w.transpose(order).reshape(kshape + (n,)))
    total = wm.sum(axis=-1, keepdims=True)
    if not (total > 0).all():
        raise ValueError("expected weights with a positive sum along the averaged axes, got a zero sum")
    mu0 = np.asarray(start._unit_quat(), np.float64).reshape(kshape + (4,))
    mu, step = _timeseries.karcher(qm, wm / total, mu0, tol, max_iter)
    if step is not None:
        raise ValueError(f"expected the geodesic mean to converge within max_iter={max_iter} iterations "
                         f"to tol={tol!r}, got a last step of {step!r} rad")
    return _wrap_rotation(_convert.canonical(mu), r.dtype)


# ---------------------------------------------------------------------------
# noisy and gappy logs
# ---------------------------------------------------------------------------

def smooth(times, rotations, window, *, order=2):
    """Smooth a noisy orientation series by local polynomial fits in the log map.

    Each sample is replaced by the value at its time of the least-squares
    polynomial of degree `order` fitted to the rotation vectors
    ``log(c* q_j)`` of the n samples nearest it in index, about a centre c
    re-set to the previous estimate (two passes): a Savitzky-Golay filter on
    the rotation group.  n is the odd number of samples that `window` spans
    at the median spacing of `times` (at least order + 2): for evenly spaced
    samples, those within `window` around each; where the spacing is uneven,
    a fit takes as many samples, however far apart (resample a log with gaps
    onto an even grid first, e.g. with `fill_gaps` and `Track`).  The hemisphere plays no
    part (log takes the short way round), and the output follows the sign
    of the input.  For equally spaced samples and order 2 the half-power
    cutoff is near 0.6 / `window` (Hz for seconds).

    Parameters
    ----------
    times : array_like, shape (T,)
    rotations : Rotation, shape (T, ...), or quaternions (T, ..., 4)
    window : float
        Width of the fit in units of `times` (> 0), as a number of samples at
        the median spacing; at least order + 2 samples.
    order : int, default 2

    Returns
    -------
    Rotation, shape (T, ...)

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import Rotation, smooth
    >>> rng = np.random.default_rng(0)
    >>> t = np.linspace(0, 4, 401)
    >>> truth = Rotation.from_euler("zx", np.c_[np.sin(t), 0.5 * np.cos(2 * t)])
    >>> noisy = truth * Rotation.from_rotvec(rng.normal(0, 0.01, (401, 3)))
    >>> err = lambda r: np.degrees((r * truth.inv()).magnitude()).mean()
    >>> bool(err(smooth(t, noisy, 0.3)) < err(noisy) / 2)
    True
    """
    Q = _orientations(rotations)
    times = key_times(times, Q.shape[0], "times", "rotations")
    window = _positive(window, "window")
    order = integer(order, "order", 0)
    T = Q.shape[0]
    dt = float(np.median(np.diff(times)))
    points = max(order + 2, 2 * int(round(window / (2 * dt))) + 1)
    q = _timeseries.smooth(times, Q.reshape(T, -1, 4).astype(np.float64), points, order)
    given = _given_quats(rotations).reshape(T, -1, 4)
    q = q * np.where(np.sum(q * given, axis=-1, keepdims=True) < 0, -1.0, 1.0)   # the input's signs
    return _wrap_rotation(q.reshape(Q.shape), Q.dtype)


def fill_gaps(times, keys, max_gap, *, method="slerp"):
    """Bridge NaN samples of orientation logs with a `Track` through the valid ones.

    A sample with any NaN component is missing.  Each run of missing samples
    whose valid neighbours are at most `max_gap` apart in time is filled by
    interpolating that track's valid samples with `method`; longer gaps,
    and missing samples before the first or after the last valid one, stay
    NaN.  (Elsewhere in quatarray NaN input is refused: this is the one
    place that accepts it.)

    Parameters
    ----------
    times : array_like, shape (T,)
    keys : array_like, shape (T, ..., 4)
        Quaternions; NaN marks missing samples (infinities are refused).
    max_gap : float
        Longest gap bridged, in units of `times` (> 0).
    method : {'slerp', 'linear', 'squad', 'bezier', 'spline'}, default 'slerp'

    Returns
    -------
    QuatArray, shape (T, ..., 4)
        Valid samples as given, bridged ones interpolated, the rest NaN.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import fill_gaps
    >>> q = np.array([[1.0, 0, 0, 0], [np.nan] * 4, [0, 0, 0, 1], [np.nan] * 4])
    >>> fill_gaps([0, 1, 2, 3], q, max_gap=2.0)
    QuatArray([[1.        , 0.        , 0.        , 0.        ],
               [0.70710678, 0.        , 0.        , 0.70710678],
               [0.        , 0.        , 0.        , 1.        ],
               [       nan,        nan,        nan,        nan]])
    """
    method = choice(method, "method", TRACK_METHODS)
    q = float_array(keys, "keys")
    if q.ndim < 2 or q.shape[-1] != 4:
        raise ValueError(f"expected keys of shape (T, ..., 4), got {q.shape}")
    times = key_times(times, q.shape[0], "times", "keys")
    max_gap = _positive(max_gap, "max_gap")
    if np.isinf(q).any():
        raise ValueError("expected finite values or nan in keys, got inf")
    T = q.shape[0]
    flat = q.reshape(T, -1, 4)
    out = flat.copy()
    missing = np.isnan(flat).any(axis=-1)                      # (T, B)
    for b in np.flatnonzero(missing.any(axis=0)):              # tracks with gaps, not samples
        ok = np.flatnonzero(~missing[:, b])
        if len(ok) < 2:
            continue
        gap = np.diff(times[ok]) <= max_gap                   # per interval between valid samples
        holes = np.flatnonzero(missing[:, b])
        seg = np.searchsorted(ok, holes) - 1                  # valid sample before each hole
        inside = (seg >= 0) & (seg < len(ok) - 1)
        fill = holes[inside][gap[seg[inside]]]
        if fill.size:
            out[fill, b] = np.asarray(Track(times[ok], flat[ok, b], method=method)(times[fill]))
    return QuatArray(out.reshape(q.shape))
