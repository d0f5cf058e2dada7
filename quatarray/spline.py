"""`RotationSpline`: scipy 1.17's C² rotation spline, batched over tracks.

Validates, calls the raw maths in `_interp_spline`, and wraps quaternions
as `Rotation`.  Beyond scipy, the keys may hold any batch of tracks
``(K, *batch)`` sharing one time axis, and float32 keys stay float32.
"""

import numpy as np

from . import _interp_spline
from ._array import QuatArray
from ._interp_lookup import SegmentIndex
from ._rotation import Rotation
from ._validate import finite, float_array, in_memory

__all__ = ["RotationSpline", "angular_rate_to_rotvec_dot_matrix", "rotvec_dot_to_angular_rate_matrix",
           "angular_acceleration_nonlinear_term", "block_tridiagonal_banded"]


def _rotvecs(x, name):
    return float_array(x, name, last=3)


def angular_rate_to_rotvec_dot_matrix(rotvecs):
    """Matrices ``A(r)`` (..., 3, 3) with ``dr/dt = A(r) w``: angular rate to rotation-vector rate.

    scipy keeps this private (``_angular_rate_to_rotvec_dot_matrix``); it
    is the Jacobian the spline's rate equations are written with.

    Examples
    --------
    >>> from quatarray.spline import angular_rate_to_rotvec_dot_matrix
    >>> import numpy as np
    >>> r = np.array([0.0, 0, 1.0])
    >>> np.allclose(angular_rate_to_rotvec_dot_matrix(r) @ r, r)   # rate along r: dr/dt = w
    True
    """
    return _interp_spline.rate_to_rotvec_dot(_rotvecs(rotvecs, "rotvecs"))


def rotvec_dot_to_angular_rate_matrix(rotvecs):
    """Matrices ``A(r)⁻¹`` (..., 3, 3) with ``w = A(r)⁻¹ dr/dt`` (closed form, no inversion).

    Examples
    --------
    >>> from quatarray.spline import rotvec_dot_to_angular_rate_matrix, angular_rate_to_rotvec_dot_matrix
    >>> import numpy as np
    >>> r = np.array([0.3, -0.2, 0.9])
    >>> np.allclose(rotvec_dot_to_angular_rate_matrix(r) @ angular_rate_to_rotvec_dot_matrix(r), np.eye(3))
    True
    """
    return _interp_spline.rotvec_dot_to_rate(_rotvecs(rotvecs, "rotvecs"))


def angular_acceleration_nonlinear_term(rotvecs, rotvecs_dot):
    """The part of the angular acceleration quadratic in ``dr/dt`` (..., 3).

    The angular acceleration is ``A(r)⁻¹ d²r/dt² +`` this term (scipy's
    private ``_angular_acceleration_nonlinear_term``); it vanishes when
    ``dr/dt`` is parallel to ``r``.

    Examples
    --------
    >>> from quatarray.spline import angular_acceleration_nonlinear_term
    >>> import numpy as np
    >>> r = np.array([0.1, 0.2, 0.3])
    >>> np.allclose(angular_acceleration_nonlinear_term(r, 2 * r), 0)
    True
    """
    r = _rotvecs(rotvecs, "rotvecs")
    rd = _rotvecs(rotvecs_dot, "rotvecs_dot")
    return _interp_spline.acceleration_term(*np.broadcast_arrays(r, rd))


def block_tridiagonal_banded(A, B, d):
    """The block-tridiagonal matrix of the spline's rate equations in LAPACK banded form.

    Rows of 3x3 blocks ``[A_{k-1}, d_k I, B_k]`` (block row k of n + 1), stored
    as `scipy.linalg.solve_banded` takes them with ``(l, u) = (5, 5)``: element
    ``(i, j)`` at ``[5 + i - j, j]``.  quatarray solves the system by block
    cyclic reduction instead; this gives the same matrix to other solvers
    (scipy keeps it private, as ``_create_block_3_diagonal_matrix``).

    Parameters
    ----------
    A, B : array_like, shape (n, 3, 3)
        Sub- and super-diagonal blocks.
    d : array_like, shape (n + 1,)
        The diagonal blocks are ``d_k`` times the identity.

    Returns
    -------
    ndarray, shape (11, 3 (n + 1))

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.linalg import solve_banded
    >>> from quatarray.spline import block_tridiagonal_banded
    >>> A, B, d = np.full((1, 3, 3), 0.5), np.eye(3)[None], np.array([4.0, 5.0])
    >>> dense = np.block([[4 * np.eye(3), B[0]], [A[0], 5 * np.eye(3)]])
    >>> x = solve_banded((5, 5), block_tridiagonal_banded(A, B, d), np.arange(6.0))
    >>> np.allclose(dense @ x, np.arange(6.0))
    True
    """
    A, B, d = (np.asarray(x, dtype=float) for x in (A, B, d))
    n = len(d) - 1
    if A.shape != (n, 3, 3) or B.shape != (n, 3, 3):
        raise ValueError(f"expected A and B of shape ({n}, 3, 3) for d of shape ({n + 1},), "
                         f"got {A.shape} and {B.shape}")
    out = np.zeros((11, 3 * (n + 1)))
    out[5] = np.repeat(d, 3)
    a, b = np.ogrid[:3, :3]
    col = 3 * np.arange(n)[:, None, None] + b      # block column k of A_k, (n, 1, 3)
    out[8 + a - b, col] = A                          # A_k at block (k + 1, k)
    out[2 + a - b, col + 3] = B                      # B_k at block (k, k + 1)
    return out


def _keys(rotations):
    in_memory(rotations, "rotations")
    if isinstance(rotations, Rotation):
        return rotations._unit_quat("rotations")   # read only: the rotation keeps its unit flag
    if hasattr(rotations, "as_quat") and not isinstance(rotations, QuatArray):
        # a scipy Rotation (or anything with scipy's as_quat): read its quaternions
        q = np.asarray(rotations.as_quat())
        return np.concatenate([q[..., 3:], q[..., :3]], axis=-1)
    if isinstance(rotations, QuatArray):
        return rotations.view(np.ndarray)
    raise TypeError(f"expected rotations to be a Rotation, got {type(rotations).__name__}")


class RotationSpline:
    """Interpolate rotations with continuous angular rate and acceleration.

    Same constructor, evaluation and errors as
    ``scipy.spatial.transform.RotationSpline``: on each segment the rotation
    vector relative to the segment's left key is a cubic in time, and the
    angular rate and acceleration are continuous at the keys.

    Parameters
    ----------
    times : array_like, shape (K,)
        Strictly increasing key times, K >= 2.
    rotations : Rotation, shape (K, *batch)
        Keys; a batch of tracks after the key axis is evaluated in one call.

    Notes
    -----
    Beyond scipy: the rate equations are solved per segment's own time scale,
    so key spacings from 1e-300 to 1e300 (and neighbours that far apart) work,
    and equal keys give the key itself at every time.  Where scipy's
    fixed-point iteration has not settled after `MAX_ITER` steps (large
    rotations between keys; at uneven spacings it diverges), Newton's method
    continues to the solution; where that fails too, `ValueError` is raised
    rather than a non-unit or NaN rotation returned.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import Rotation, RotationSpline
    >>> keys = Rotation.from_euler('z', [[0], [90], [180]], degrees=True)
    >>> spline = RotationSpline([0, 1, 2], keys)
    >>> np.round(spline(0.5).as_euler('zyx', degrees=True), 6)
    array([45.,  0.,  0.])
    >>> np.round(spline([0.5, 1.5], 1), 6)   # angular rate, rad/s
    array([[0.      , 0.      , 1.570796],
           [0.      , 0.      , 1.570796]])
    """

    MAX_ITER = _interp_spline.MAX_ITER
    TOL = _interp_spline.TOL[np.dtype(np.float64)]   # scipy's class attribute (float32 keys iterate to their own)

    def __init__(self, times, rotations):
        keys = _keys(rotations)
        if keys.ndim < 2:
            raise ValueError("`rotations` must be a sequence of rotations.")
        if len(keys) == 1:
            raise ValueError("`rotations` must contain at least 2 rotations.")
        # a copy: the spline's segments index these times, so the caller's array changing
        # later must not move them (as a Slerp's)
        times = np.array(in_memory(times, "times"), dtype=float)
        if times.ndim != 1:
            raise ValueError("`times` must be 1-dimensional.")
        finite(times, "times")   # scipy: "array must not contain infs or NaNs"
        if len(times) != len(keys):
            raise ValueError("Expected number of rotations to be equal to number of timestamps given, "
                             f"got {len(keys)} rotations and {len(times)} timestamps.")
        if (times[1:] <= times[:-1]).any():   # finite times: the same test as np.diff(times) <= 0
            raise ValueError("Values in `times` must be in a strictly increasing order.")
        if keys.dtype not in (np.float32, np.float64):
            keys = keys.astype(np.float64)
        # a Rotation's keys are unit already (normalising them again would move a third of
        # them by an ulp, and equal keys must give the key); others go through `Rotation`'s
        # one normalisation (`_kernels.normalize`), whose result is also the stored keys
        self.times = times
        self.rotations = (rotations if isinstance(rotations, Rotation)
                          else Rotation.from_quat(keys, scalar_first=True))
        keys = keys if isinstance(rotations, Rotation) else self.rotations._q
        self._keys = keys
        self._table = _interp_spline.table(keys, _interp_spline.coefficients(times, keys))
        self._cmax = _interp_spline.coefficient_size(self._table)
        self._index = SegmentIndex(times)

    def __call__(self, times, order=0):
        """Interpolated rotations (order 0), angular rate (1, rad/s) or acceleration (2, rad/s²).

        Parameters
        ----------
        times : float or array_like, shape (M,)
        order : {0, 1, 2}, default 0

        Returns
        -------
        Rotation of shape (M, *batch) or ndarray of shape (M, *batch, 3)
            Without the M axis for a scalar time.
        """
        if order not in (0, 1, 2):
            raise ValueError("`order` must be 0, 1 or 2.")
        t = np.asarray(in_memory(times, "times"), dtype=float)
        if t.ndim > 1:
            raise ValueError("`times` must be at most 1-dimensional.")
        finite(t, "times")   # scipy: "Found zero norm quaternions"
        single = t.ndim == 0
        res = _interp_spline.evaluate(self._index, self.times, self._table, t.reshape(-1) if single else t,
                                      order, self._keys.shape[1:-1], self._cmax)
        if single:
            res = res[0]
        if order:
            return res
        return Rotation._wrap(res)   # unit to rounding (not from a normalising path: unit=False)
