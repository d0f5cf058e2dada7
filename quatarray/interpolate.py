"""Interpolation of rotations: pairwise LERP / NLERP / SLERP, squad and
spherical Bézier curves, and keyframe tracks (`Track`, scipy-style `Slerp`).

Every function accepts `QuatArray` or array_like input of shape (..., 4)
(scalar-first w, x, y, z), broadcasts batch shapes the NumPy way, keeps
float32 as float32, never modifies its inputs and returns a `QuatArray`.
The maths lives in `quatarray._interp_kernels` (blocked SLERP kernels),
`quatarray._interp_curves` (control points, analytic derivatives),
`quatarray._interp_lookup` (segment lookup) and `quatarray._track` (track
tables and their blocked evaluation); this module validates and wraps.

Conventions
-----------
* Quaternions to interpolate are expected to be unit quaternions (the
  SLERP family is homogeneous: two quaternions of the same norm r give r
  times the unit result, for r from about 1e-300 to 1e300, float32 1e-35 to
  1e35; nlerp normalises, and its shortest-path test is a dot product, in
  range for r within 1e±150).  `Track` and `Slerp` normalise their keys.
* ``t`` outside [0, 1] extrapolates along the same curve (no clipping).
* Keyframe curves: keys are unflipped first (`unflip`), so negating any key
  changes nothing; the outputs follow the sign of the first key.
* Angular velocities are in radians per unit time, in the **world**
  (space) frame by default: ω = 2 vec(q̇ q*), so that q̇ = ½ ω q;
  ``frame='body'`` gives ω_b = 2 vec(q* q̇) = q* ω q.
"""


import numpy as np

from . import _interp_curves
from . import _interp_kernels
from . import _interp_spline
from . import _kernels
from . import _track
from ._array import QuatArray
from ._rotation import Rotation, _is_scipy_rotation
from ._validate import batch_axis, choice, finite, float_array, key_times, quat_array

__all__ = [
    "lerp", "nlerp", "slerp", "unflip",
    "squad", "squad_control_points", "bezier", "bezier_control_points",
    "Track", "Slerp",
]

METHODS = ("linear", "slerp", "squad", "bezier", "spline")
EXTRAPOLATE = ("raise", "clamp", "extend")
FRAMES = ("world", "body")
EXTEND_LIMIT = _track.EXTEND_LIMIT



# ---------------------------------------------------------------------------
# argument handling
# ---------------------------------------------------------------------------

def _rotation_quats(x, name):
    """The unit quaternions, scalar-first, of `x` if it is a `Rotation` (or scipy's), else None:
    every interpolation function takes rotations as it takes quaternions."""
    if type(x) is np.ndarray or not (isinstance(x, Rotation) or _is_scipy_rotation(x)):
        return None
    return (x if isinstance(x, Rotation) else Rotation.from_scipy(x))._unit_quat(name)


def _quats(x, name):
    """Quaternions (..., 4) of array_like `x` or of a Rotation (`_rotation_quats`)."""
    q = _rotation_quats(x, name)
    return quat_array(x, name) if q is None else q


def _finite_quat(x, name):
    return finite(_quats(x, name), name)


def _param(t):
    return finite(float_array(t, "t"), "t")


def _broadcast(names, shapes):
    try:
        return np.broadcast_shapes(*shapes)
    except ValueError:
        got = ", ".join(f"{n}: {s}" for n, s in zip(names, shapes))
        raise ValueError(f"expected broadcastable batch shapes for {', '.join(names)}, got {got}") from None


def _pairwise(names, quats, t):
    shape = quats[0].shape
    if (t.ndim == 0 or t.shape == shape[:-1]) and all(q.shape == shape for q in quats):
        return  # nothing to broadcast (the common call: keep it cheap)
    _broadcast(names + ("t",), [q.shape[:-1] for q in quats] + [t.shape])


# ---------------------------------------------------------------------------
# pairwise functions
# ---------------------------------------------------------------------------

def lerp(q0, q1, t):
    """Linear interpolation ``(1 - t) q0 + t q1`` (not normalised).

    Parameters
    ----------
    q0, q1 : array_like, shape (..., 4), or Rotation
        Quaternions; batch shapes broadcast.
    t : array_like
        Interpolation parameter, broadcasting against the batch shape;
        values outside [0, 1] extrapolate.

    Returns
    -------
    QuatArray, shape (broadcast batch, 4)

    Examples
    --------
    >>> from quatarray.interpolate import lerp
    >>> lerp([1, 0, 0, 0], [0, 0, 0, 1], [0, 0.5, 1])
    QuatArray([[1. , 0. , 0. , 0. ],
               [0.5, 0. , 0. , 0.5],
               [0. , 0. , 0. , 1. ]])
    """
    q0, q1, t = _finite_quat(q0, "q0"), _finite_quat(q1, "q1"), _param(t)
    _pairwise(("q0", "q1"), (q0, q1), t)
    return QuatArray._wrap(_interp_kernels.lerp(q0, q1, t))


def nlerp(q0, q1, t, *, shortest=True):
    """Normalised linear interpolation ``n / |n|`` with ``n = (1 - t) q0 + t q1``.

    Cheap, and on the same great circle as SLERP, but not constant-speed.

    Parameters
    ----------
    q0, q1 : array_like, shape (..., 4), or Rotation
        Unit quaternions; batch shapes broadcast.
    t : array_like
        Interpolation parameter, broadcasting against the batch shape.
    shortest : bool, default True
        Replace q1 by -q1 where that is closer to q0 (the same rotation by
        the shorter path); with False the blend follows q1 as given.

    Returns
    -------
    QuatArray, shape (broadcast batch, 4)

    Raises
    ------
    ValueError
        Where the blend is the zero quaternion (q1 = -q0 with
        ``shortest=False`` at t = 1/2, or zero input).

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.interpolate import nlerp
    >>> q = nlerp([1, 0, 0, 0], [0, 0, 0, 1], 0.5)
    >>> np.allclose(q, [np.sqrt(0.5), 0, 0, np.sqrt(0.5)])
    True
    """
    q0, q1, t = _finite_quat(q0, "q0"), _finite_quat(q1, "q1"), _param(t)
    _pairwise(("q0", "q1"), (q0, q1), t)
    with np.errstate(over="ignore"):   # a dot product of huge quaternions: its sign is kept
        return QuatArray._wrap(_interp_kernels.nlerp(q0, q1, t, bool(shortest)))


def slerp(q0, q1, t, *, shortest=True):
    """Spherical linear interpolation: constant angular speed along the great circle.

    ``slerp(q0, q1, t) = q0 (q0⁻¹ q1)^t``.  The angle is computed as
    Ω = 2 atan2(|q1 - q0|, |q1 + q0|) (after the shortest-path sign
    flip), which is accurate for tiny angles where ``arccos(q0·q1)`` is not:
    interpolated rotation angles keep their relative accuracy (a few ulp)
    down to 1e-12 rad and below.

    Parameters
    ----------
    q0, q1 : array_like, shape (..., 4), or Rotation
        Unit quaternions; batch shapes broadcast.
    t : array_like
        Interpolation parameter, broadcasting against the batch shape;
        values outside [0, 1] extrapolate along the same great circle.
    shortest : bool, default True
        Follow the shorter arc: replace q1 by -q1 when |q1 + q0| < |q1 - q0|
        (i.e. q0·q1 < 0; q0·q1 = 0 exactly keeps q1).  q1 = -q0 then gives the
        constant rotation q0.  With False the arc from q0 to q1 as given is
        followed; for q1 = -q0 that arc is not unique and the result is the
        constant rotation (q0 for t < 1/2, q1 from t = 1/2 on).

    Returns
    -------
    QuatArray, shape (broadcast batch, 4)

    See Also
    --------
    nlerp : cheaper, not constant-speed.
    Track : many keys, many tracks.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.interpolate import slerp
    >>> z90 = [np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)]   # 90° about z
    >>> q = slerp([1, 0, 0, 0], z90, [0, 1 / 3, 1])
    >>> np.allclose(q[1], [np.cos(np.pi / 12), 0, 0, np.sin(np.pi / 12)])  # 30°
    True
    >>> slerp([1, 0, 0, 0], [-1, 0, 0, 0], 0.5)    # the same rotation: stays put
    QuatArray([1., 0., 0., 0.])
    """
    q0, q1, t = _quats(q0, "q0"), _quats(q1, "q1"), float_array(t, "t")
    _pairwise(("q0", "q1"), (q0, q1), t)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):   # non-finite input: named below
        res, ok = _interp_kernels.slerp(q0, q1, t, bool(shortest), check=True)
    if not ok:   # finite input gives finite output: one of them is not finite
        for a, name in ((q0, "q0"), (q1, "q1"), (t, "t")):
            finite(a, name)
    return QuatArray._wrap(res)


def unflip(q, axis=0):
    """Flip signs so that consecutive quaternions along `axis` have a non-negative dot product.

    q and -q are the same rotation; interpolating between consecutive keys
    takes the short way round only when their dot product is >= 0.  The
    first quaternion along `axis` keeps its sign.

    Parameters
    ----------
    q : array_like, shape (..., 4), or Rotation
    axis : int, default 0
        A batch axis (the component axis cannot be chosen).

    Returns
    -------
    QuatArray, same shape as `q`

    Examples
    --------
    >>> from quatarray.interpolate import unflip
    >>> unflip([[1, 0, 0, 0], [-1, 0, 0, 0], [0, -1, 0, 0], [0.6, 0.8, 0, 0]])
    QuatArray([[ 1. ,  0. ,  0. ,  0. ],
               [ 1. , -0. , -0. , -0. ],
               [ 0. , -1. ,  0. ,  0. ],
               [-0.6, -0.8, -0. , -0. ]])
    """
    q = _finite_quat(q, "q")
    return QuatArray._wrap(_interp_kernels.unflip(q, batch_axis(axis, q.shape[:-1])))


def squad(q0, a, b, q1, t):
    """Shoemake's spherical quadrangle interpolation of one curve segment.

    ``squad = slerp(slerp(q0, q1, t), slerp(a, b, t), 2 t (1 - t))`` with no
    sign flips (so the curve is continuous in t).  In Shoemake's notation
    q0 = q_i, q1 = q_{i+1}, a = s_i, b = s_{i+1}; see `squad_control_points`.
    The argument order (p, a, b, q) matches `bezier`.

    Parameters
    ----------
    q0, a, b, q1 : array_like, shape (..., 4), or Rotation
        Unit quaternions (segment ends and inner control points); batch
        shapes broadcast.
    t : array_like
        Parameter in [0, 1] along the segment (broadcasting).

    Returns
    -------
    QuatArray, shape (broadcast batch, 4)

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.interpolate import squad, slerp
    >>> q0, q1 = [1, 0, 0, 0], [np.cos(0.3), np.sin(0.3), 0, 0]
    >>> np.allclose(squad(q0, q0, q1, q1, 0.25), slerp(q0, q1, 0.25))
    True
    """
    qs = [_finite_quat(x, n) for x, n in zip((q0, a, b, q1), ("q0", "a", "b", "q1"))]
    t = _param(t)
    _pairwise(("q0", "a", "b", "q1"), qs, t)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):   # huge or tiny: computed again scaled
        return QuatArray._wrap(_interp_kernels.squad(*qs, t))


def bezier(q0, a, b, q1, t):
    """Spherical cubic Bézier segment with control points q0, a, b, q1 (Shoemake).

    Evaluated by de Casteljau's construction with SLERP in place of linear
    interpolation (three levels, no sign flips).  The tangent at t = 0 is
    3 log(q0⁻¹ a) and at t = 1 is 3 log(b⁻¹ q1) (per unit t, body frame).

    Parameters
    ----------
    q0, a, b, q1 : array_like, shape (..., 4), or Rotation
        Unit quaternions; batch shapes broadcast.
    t : array_like
        Parameter in [0, 1] along the segment (broadcasting).

    Returns
    -------
    QuatArray, shape (broadcast batch, 4)

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.interpolate import bezier, slerp
    >>> q0, q1 = [1, 0, 0, 0], [np.cos(0.3), np.sin(0.3), 0, 0]
    >>> a, b = slerp(q0, q1, 1 / 3), slerp(q0, q1, 2 / 3)   # evenly on the arc
    >>> np.allclose(bezier(q0, a, b, q1, 0.4), slerp(q0, q1, 0.4))
    True
    """
    qs = [_finite_quat(x, n) for x, n in zip((q0, a, b, q1), ("q0", "a", "b", "q1"))]
    t = _param(t)
    _pairwise(("q0", "a", "b", "q1"), qs, t)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):   # huge or tiny: computed again scaled
        return QuatArray._wrap(_interp_kernels.bezier(*qs, t))


def _prepared_keys(keys, times, name="keys", times_name="times"):
    """Validated, normalised and unflipped keys (K, ..., 4) and float64 times (or None), from
    array_like keys or a Rotation of shape (K, ...): its unit quaternions (`_rotation_quats`,
    unit already: not normalised again, see `unit_keys`)."""
    q = _rotation_quats(keys, name)
    unit = q is not None
    keys = float_array(keys if q is None else q, name)
    if keys.ndim < 2 or keys.shape[-1] != 4:
        raise ValueError(f"expected {name} of shape (K, ..., 4), got {keys.shape}")
    K = keys.shape[0]
    if K < 2:
        raise ValueError(f"expected {name} of shape (K, ..., 4) with K >= 2 "
                         f"(a sequence of at least 2 rotations), got {keys.shape}")
    finite(keys, name)
    keys = _interp_kernels.unit_keys(keys, name, unit)
    if times is not None:
        times = _check_times(times, K, times_name, name)
    return keys, times


def _check_times(times, K, name="times", keys_name="keys"):
    return key_times(times, K, name, keys_name)


def squad_control_points(keys, times=None):
    """Squad control points s_i, one per key, computed once for a whole track.

    ``s_i = q_i exp(-(w_in L₊ + w_out L₋) / 2)`` with L± = log(q_i⁻¹ q_{i±1}),
    w_in = Δ_{i-1} / (Δ_{i-1} + Δ_i) and w_out = Δ_i / (Δ_{i-1} + Δ_i) for the
    key intervals Δ.  With equal spacing this is Shoemake's
    q_i exp(-(L₊ + L₋) / 4).  With unequal spacing the weights scale the
    neighbouring tangents by the ratio of the adjacent intervals, so that
    the angular velocity at q_i is the central difference
    (L₊ - L₋) / (t_{i+1} - t_{i-1}) from both sides: the curve is C¹ in time.
    (The same single s_i serves the segments on both sides of q_i.)

    Ends: the sequence is extended by geodesic reflection,
    q₋₁ = q₀ q₁⁻¹ q₀ at t₀ - Δ₀ (and likewise after the last key), which
    gives s₀ = q₀ and s_{K-1} = q_{K-1}: the curve leaves the first key and
    reaches the last one with the velocity of the end segment's SLERP.

    Keys are normalised and unflipped along axis 0 first.

    Parameters
    ----------
    keys : array_like, shape (K, ..., 4), or Rotation of shape (K, ...)
        K >= 2 keyframes of any batch of tracks.
    times : array_like, shape (K,), optional
        Strictly increasing key times; equal spacing if omitted.

    Returns
    -------
    QuatArray, shape (K, ..., 4)
        Segment i uses ``squad(q_i, s_i, s_{i+1}, q_{i+1}, u)``.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.interpolate import squad_control_points
    >>> keys = [[1, 0, 0, 0], [np.cos(0.2), np.sin(0.2), 0, 0], [np.cos(0.4), np.sin(0.4), 0, 0]]
    >>> s = squad_control_points(keys)      # constant rotation speed: s_i = q_i
    >>> np.allclose(s, keys)
    True
    """
    keys, times = _prepared_keys(keys, times)
    return QuatArray._wrap(_interp_curves.squad_controls(keys, times))


def bezier_control_points(keys, times=None):
    """Spherical Bézier control points (a_i, b_i) for a whole track (Shoemake's construction).

    With Double(p, q) = 2 (p·q) q - p and Bisect(p, q) = (p + q) / |p + q|,
    c_i = Bisect(Double(q_{i-1}, q_i), q_{i+1}) is the end of the tangent at
    q_i.  Taken as the control point as printed in the paper, the tangent
    would be three times the central difference (the curve overshoots), so
    the control point lies one third of the way along it:
    ``a_i = slerp(q_i, c_i, 1/3)`` and ``b_i = Double(a_i, q_i)``.

    Unequal spacing: the fractions become (2/3) w_out and (2/3) w_in, with
    w_out = Δ_i / (Δ_{i-1} + Δ_i) and w_in = Δ_{i-1} / (Δ_{i-1} + Δ_i), i.e.
    ``a_i = slerp(q_i, c_i, 2 w_out / 3)`` and
    ``b_i = slerp(q_i, Double(c_i, q_i), 2 w_in / 3)``, so the velocity in
    time is continuous across every key (C¹ in time).

    Ends: geodesic reflection (q₋₁ = q₀ q₁⁻¹ q₀ at t₀ - Δ₀, likewise at the
    end), which gives a₀ = slerp(q₀, q₁, 1/3) and b_{K-1} = slerp(q_{K-1},
    q_{K-2}, 1/3): the ends move with the velocity of the end segment's SLERP.

    Keys are normalised and unflipped along axis 0 first.

    Parameters
    ----------
    keys : array_like, shape (K, ..., 4), or Rotation of shape (K, ...)
    times : array_like, shape (K,), optional
        Strictly increasing key times; equal spacing if omitted.

    Returns
    -------
    a, b : QuatArray, shape (K, ..., 4)
        Segment i is ``bezier(q_i, a_i, b_{i+1}, q_{i+1}, u)``.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.interpolate import bezier_control_points, slerp
    >>> keys = [[1, 0, 0, 0], [np.cos(0.2), np.sin(0.2), 0, 0], [np.cos(0.4), np.sin(0.4), 0, 0]]
    >>> a, b = bezier_control_points(keys)
    >>> np.allclose(a[0], slerp(keys[0], keys[1], 1 / 3))
    True
    """
    keys, times = _prepared_keys(keys, times)
    a, b = _interp_curves.bezier_controls(keys, times)
    return QuatArray._wrap(a), QuatArray._wrap(b)


# ---------------------------------------------------------------------------
# keyframe tracks
# ---------------------------------------------------------------------------

class Track:
    """Rotation keyframes of a batch of tracks, interpolated in time.

    Parameters
    ----------
    times : array_like, shape (K,)
        Key times: finite, strictly increasing, K >= 2.
    keys : array_like, shape (K, ..., 4), or Rotation of shape (K, ...)
        K keyframes of any batch of tracks, e.g. ``(K, joints, 4)``.  They
        are normalised and unflipped along the key axis (so negating any key
        changes nothing; outputs follow the sign of the first key).
    method : {'slerp', 'linear', 'squad', 'bezier', 'spline'}, default 'slerp'
        ``'spline'`` is scipy's C² `RotationSpline` curve.
        ``'linear'``: NLERP between neighbouring keys (cheap, not
        constant-speed); ``'slerp'``: piecewise great circles at constant
        speed (continuous, but the angular velocity jumps at keys);
        ``'squad'``: Shoemake's squad through `squad_control_points`;
        ``'bezier'``: spherical cubic Bézier through `bezier_control_points`.
        squad and Bézier are C¹ in time, also for unequal key spacing; both
        extend the keys by geodesic reflection at the ends.
    extrapolate : {'raise', 'clamp', 'extend'}, default 'raise'
        Queries outside [times[0], times[-1]]: ``'raise'`` a ValueError,
        ``'clamp'`` to the end keys (zero angular velocity there), or
        ``'extend'`` the first / last segment's curve, up to `EXTEND_LIMIT`
        (10⁴) lengths of that segment beyond the key range (further out:
        ValueError).

    Notes
    -----
    Control points and per-segment great-circle frames are computed once,
    here.  A call does one segment lookup (a grid-accelerated equivalent of
    ``searchsorted(times, t, 'right') - 1``: a query at a key time starts the
    next segment, so every method passes exactly through its keys) and a
    fixed number of batched kernels per cache-sized block: no Python loop
    over keys, queries or tracks.

    Examples
    --------
    A track of two joints with three keys (K, joints, 4) = (3, 2, 4):

    >>> import numpy as np
    >>> from quatarray import QuatArray
    >>> from quatarray.interpolate import Track
    >>> def rz(deg):   # rotation about z
    ...     h = np.radians(deg) / 2
    ...     return [np.cos(h), 0, 0, np.sin(h)]
    >>> keys = [[rz(0), rz(0)], [rz(90), rz(10)], [rz(180), rz(20)]]
    >>> track = Track([0.0, 1.0, 3.0], keys, method='squad')
    >>> track(np.linspace(0, 3, 7)).shape
    (7, 2, 4)
    >>> np.allclose(track(1.0), [rz(90), rz(10)])
    True
    >>> track.angular_velocity(1.0).round(4)      # rad per unit time, world frame
    array([[0.    , 0.    , 1.0472],
           [0.    , 0.    , 0.1164]])
    """

    def __init__(self, times, keys, *, method="slerp", extrapolate="raise"):
        self._setup(times, keys, method, extrapolate, "times", "keys")

    def _setup(self, times, keys, method, extrapolate, times_name, keys_name, prepared=False):
        """`prepared`: the caller has checked `times` (float64 (K,), finite, strictly
        increasing) and made `keys` unit and unflipped (as `_prepared_keys` would)."""
        self._method = choice(method, "method", METHODS)
        extrapolate = choice(extrapolate, "extrapolate", EXTRAPOLATE)
        if not prepared:
            keys, _ = _prepared_keys(keys, None, keys_name)
            times = _check_times(times, keys.shape[0], times_name, keys_name)
        times = times.copy()
        times.flags.writeable = False
        keys.flags.writeable = False
        self._timeline = _track.Timeline(times, extrapolate)
        self._keys = keys
        self._batch = keys.shape[1:-1]
        self._dtype = keys.dtype
        self._controls = None
        if self._method == "spline":
            # scipy's RotationSpline: its own evaluator, no frame table
            self._spline = _interp_spline.table(keys, _interp_spline.coefficients(times, keys))
            self._table = None
            return
        self._table, controls = _track.rotation_table(self._method, times, keys)
        if isinstance(controls, tuple):
            self._controls = tuple(QuatArray._wrap(c) for c in controls)
        elif controls is not None:
            self._controls = QuatArray._wrap(controls)
        for c in (self._controls if isinstance(self._controls, tuple) else (self._controls,)):
            if c is not None:
                c.flags.writeable = False

    # --- properties ---------------------------------------------------------
    @property
    def times(self):
        """Key times, shape (K,) (read-only float64)."""
        return self._timeline.times

    @property
    def keys(self):
        """Keys as used: normalised and unflipped, shape (K, ..., 4) (read-only)."""
        return QuatArray._wrap(self._keys)

    @property
    def method(self):
        """The interpolation method: 'linear', 'slerp', 'squad' or 'bezier'."""
        return self._method

    @property
    def extrapolate(self):
        """Behaviour outside the key times: 'raise', 'clamp' or 'extend'."""
        return self._timeline.extrapolate

    @property
    def batch_shape(self):
        """Batch shape of the tracks (``keys.shape[1:-1]``)."""
        return self._batch

    @property
    def dtype(self):
        """float32 or float64: the dtype of the keys, and of every output."""
        return self._dtype

    @property
    def control_points(self):
        """None for 'linear' / 'slerp'; s (K, ..., 4) for 'squad'; (a, b) for 'bezier'."""
        return self._controls

    def __len__(self):
        """Number of keys K."""
        return len(self._timeline.times)

    def __repr__(self):
        return (f"{type(self).__name__}(K={len(self)}, batch_shape={self._batch}, "
                f"method={self._method!r}, extrapolate={self.extrapolate!r}, dtype={self._dtype})")

    # --- evaluation ---------------------------------------------------------
    def __call__(self, t):
        """Interpolated rotations at times `t`.

        Parameters
        ----------
        t : array_like
            Query times, scalar or any shape (typically (M,)).

        Returns
        -------
        QuatArray, shape ``t.shape + batch_shape + (4,)``

        Examples
        --------
        >>> from quatarray.interpolate import Track
        >>> track = Track([0, 1], [[1, 0, 0, 0], [0, 1, 0, 0]])     # 180° about x
        >>> track([0.5, 1.0])
        QuatArray([[0.70710678, 0.70710678, 0.        , 0.        ],
                   [0.        , 1.        , 0.        , 0.        ]])
        """
        return self._evaluate(t, "t")

    def _evaluate(self, t, name):
        tshape, flat, _ = self._timeline.queries(t, name)
        if self._method == "spline":
            out = _interp_spline.evaluate(self._timeline.index, self.times, self._spline, flat, 0, self._batch)
        else:
            method = self._method
            out = _track.evaluate(self._timeline, self._table, flat,
                              lambda G, u, O: _track.rotation_block(method, G, u, O), 4)
        if self._timeline.extrapolate == "extend" and flat.size and self._method != "slerp":
            # far out, squad's and Bézier's rounding grows like eps u² off the unit sphere (SLERP's
            # cos and sin of one angle on an orthonormal frame do not: its bits stay `frame_core`'s,
            # as `RigidTrack`'s rotations)
            far = (flat < self.times[0]) | (flat > self.times[-1])
            if far.any():
                rows = out.reshape(flat.size, -1, 4)
                rows[far] = _kernels.normalize(rows[far])
        return QuatArray._wrap(out.reshape(tshape + self._batch + (4,)))

    def angular_velocity(self, t, *, frame="world"):
        """Angular velocity of the interpolated rotation, analytic (no finite differences).

        Parameters
        ----------
        t : array_like
            Query times, scalar or any shape.
        frame : {'world', 'body'}, default 'world'
            ``'world'`` (space frame): ω = 2 vec(q̇ q*), i.e. q̇ = ½ ω q;
            ``'body'``: ω_b = 2 vec(q* q̇) = q* ω q.

        Returns
        -------
        ndarray, shape ``t.shape + batch_shape + (3,)``
            Radians per unit of time.  At a key time the velocity of the
            segment that starts there is returned (of the last segment at
            the last key); SLERP's velocity is constant per segment, squad's
            and Bézier's is continuous.  With ``extrapolate='clamp'`` it is
            zero outside the key range.

        Examples
        --------
        >>> import numpy as np
        >>> from quatarray.interpolate import Track
        >>> keys = [[1, 0, 0, 0], [np.cos(0.5), 0, np.sin(0.5), 0]]   # 1 rad about y
        >>> Track([0, 2], keys).angular_velocity([0.5, 1.5])
        array([[0. , 0.5, 0. ],
               [0. , 0.5, 0. ]])
        """
        frame = choice(frame, "frame", FRAMES)
        tshape, flat, outside = self._timeline.queries(t, "t")
        if self._method == "spline":
            # the spline's rate (scipy's order=1) is in the body frame
            w = _interp_spline.evaluate(self._timeline.index, self.times, self._spline, flat, 1, self._batch)
            if frame == "world":
                w = _kernels.rotate(_interp_spline.evaluate(self._timeline.index, self.times, self._spline, flat, 0, self._batch), w)
            if outside is not None:
                w[outside] = 0
        else:
            w = _track.angular_velocity(self._timeline, self._method, self._table, flat, outside, frame)
        return w.reshape(tshape + self._batch + (3,))


def _scipy_ties(keys):
    """Keys (K, ..., 4) signed so that a pair exactly 90° apart in S³ (a half turn between
    keys, dot product 0) turns the way scipy's Slerp does: the relative rotation
    ``conj(q[k]) q[k+1]`` canonical (first non-zero of its vector part positive).
    Other pairs are left to `unflip` (the same choice as scipy's).  Returns the keys
    and, when they are returned unchanged, their dot products as `unflip` computes
    them (else None)."""
    keys = np.asarray(keys)   # raw array (the kernels' arguments)
    d = _interp_kernels.vdot(keys[1:].astype(np.float64, copy=False), keys[:-1])
    if not (d == 0).any():
        return keys, d
    from ._convert import _flip_mask
    rel = _kernels.multiply(_kernels.conjugate(keys[:-1]), keys[1:])
    x, y, z = rel[..., 1], rel[..., 2], rel[..., 3]
    step = np.where((d < 0) | ((d == 0) & _flip_mask(np.zeros_like(x), x, y, z)), -1, 1)
    sign = np.concatenate([np.ones_like(step[:1]), np.cumprod(step, axis=0)])
    return keys * sign[..., None].astype(keys.dtype), None


class Slerp(Track):
    """scipy's ``Slerp(times, rotations)``: spherical linear interpolation returning `Rotation`.

    Same behaviour, attributes and errors as
    ``scipy.spatial.transform.Slerp``.  A scipy ``Rotation`` is accepted as
    well (converted with `Rotation.from_scipy`).  Beyond scipy,
    ``batched=True`` accepts rotations of shape ``(K, *batch)``: a batch of
    tracks sharing the key times, interpolated in one call.

    Parameters
    ----------
    times : array_like, shape (K,)
        Strictly increasing key times.
    rotations : Rotation, shape (K,) (or (K, *batch) with `batched`)
    batched : bool, default False, keyword only
        Allow more than one leading dimension (scipy refuses them).

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import Rotation, Slerp
    >>> keys = Rotation.from_euler("z", [[0], [90]], degrees=True)
    >>> s = Slerp([0, 2], keys)
    >>> np.round(s([0.5, 1.0]).as_euler("zyx", degrees=True), 9) + 0.0
    array([[22.5,  0. ,  0. ],
           [45. ,  0. ,  0. ]])
    >>> s(3.0)
    Traceback (most recent call last):
    ...
    ValueError: Interpolation times must be within the range [0.0, 2.0], both inclusive.
    >>> tracks = Rotation.from_euler("z", [[[0], [0]], [[90], [180]]], degrees=True)  # (K, 2)
    >>> Slerp([0, 1], tracks, batched=True)(0.5).shape
    (2,)
    """

    def __init__(self, times, rotations, *, batched=False):
        if _is_scipy_rotation(rotations):
            rotations = Rotation.from_scipy(rotations)
        if not isinstance(rotations, Rotation):
            raise TypeError(f"`rotations` must be a `Rotation` instance, got {type(rotations).__name__} "
                            f"(Track interpolates arrays of quaternions)")
        if rotations.single or len(rotations) <= 1:
            raise ValueError(f"`rotations` must be a sequence of at least 2 rotations, got shape "
                             f"{rotations.shape}.")
        if len(rotations.shape) > 1 and not batched:
            raise ValueError(f"Rotations with more than 1 leading dimension are not supported "
                             f"(as in scipy; pass batched=True for a batch of tracks), got shape "
                             f"{rotations.shape}.")
        t = float_array(times, "times", dtype=np.float64)
        if t.ndim != 1:
            raise ValueError(f"Expected times to be specified in a 1 dimensional array, got "
                             f"{t.ndim} dimensions.")
        if t.shape[0] != len(rotations):
            raise ValueError(f"Expected number of rotations to be equal to number of timestamps "
                             f"given, got {len(rotations)} rotations and {t.shape[0]} timestamps.")
        finite(t, "times")
        if (t[1:] <= t[:-1]).any():
            raise ValueError("Times must be in strictly increasing order.")
        # unit quaternions (only unflipped from here on, see `unit_keys`): the stored ones where
        # known unit, else normalised (a Rotation made with normalize=False may hold anything)
        keys = finite(rotations._unit_quat("rotations"), "rotations")
        self._given = keys[:-1].copy()   # `rotations`: as given (the curve runs on unflipped keys)
        keys, dots = _scipy_ties(keys)
        self._setup(t, _interp_kernels.unflip(keys, 0, dots), "slerp", "raise", "times", "rotations",
                    prepared=True)
        self._range = (float(t[0]), float(t[-1]))

    @property
    def timedelta(self):
        """Differences between consecutive key times, shape (K - 1,) (as in scipy)."""
        return np.diff(self.times)

    @property
    def rotations(self):
        """The key rotations but the last, as given, a `Rotation` of shape (K - 1, ...) (scipy's
        attribute)."""
        return Rotation._wrap(self._given.copy())

    @property
    def rotvecs(self):
        """Rotation vectors from each key to the next, shape (K - 1, ..., 3) (scipy's attribute)."""
        keys = Rotation._wrap(self._keys)
        return (keys[:-1].inv() * keys[1:]).as_rotvec()

    def __call__(self, times):
        """Interpolated rotations at `times` (scalar or 1-D), as a `Rotation`.

        Shape ``(M, *batch)`` for M times, ``batch`` (single for 1-D keys) for a scalar.

        >>> from quatarray import Rotation, Slerp
        >>> s = Slerp([0, 1], Rotation.from_rotvec([[0, 0, 0], [0, 0, 1]]))
        >>> s(0.25).as_rotvec()
        array([0.  , 0.  , 0.25])
        """
        t = float_array(times, "times")
        if t.ndim > 1:
            raise ValueError(f"`times` must be at most 1-dimensional. Got shape {t.shape}")
        t0, t1 = self._range
        if not (t0 <= float(t) <= t1 if t.ndim == 0 else t.size == 0 or t0 <= t.min() and t.max() <= t1):
            raise ValueError(f"Interpolation times must be within the range [{t0}, {t1}], both inclusive.")
        return Rotation._wrap(self._evaluate(t, "times").view(np.ndarray))
