"""Orientation time series: fewer keys within a stated error (`reduce_keys`).

The maths lives in `quatarray._reduce`; this module validates, calls and wraps.
Conventions as in `quatarray.interpolate`: quaternions scalar-first (w, x, y, z),
time along axis 0, any batch shape after it, float32 kept as float32.
"""

from math import prod
from typing import NamedTuple

import numpy as np

from . import _interp_kernels as IK
from . import _reduce
from ._validate import finite, float_array, key_times

__all__ = ["ReducedKeys", "reduce_keys"]


def _choice(value, name, options):
    if not isinstance(value, str) or value not in options:
        raise ValueError(f"expected {name} in {options}, got {value!r}")
    return value


def _series(keys, name, min_len=2):
    """keys (T, *batch, 4) from a QuatArray, array_like or Rotation: finite, unflipped, unit."""
    from ._rotation import Rotation
    if isinstance(keys, Rotation):
        if keys.single:
            raise ValueError(f"expected {name} of shape (T, ...) (a sequence of rotations), got a single rotation")
        keys = keys.as_quatarray()
    keys = float_array(keys, name)
    if keys.ndim < 2 or keys.shape[-1] != 4:
        raise ValueError(f"expected {name} of shape (T, ..., 4), got {keys.shape}")
    if keys.shape[0] < min_len:
        raise ValueError(f"expected {name} of shape (T, ..., 4) with T >= {min_len}, got {keys.shape}")
    finite(keys, name)
    return IK.unit_keys(keys, name)


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
    from .interpolate import Track
    method = _choice(method, "method", _reduce.METHODS)
    tol = _positive(tolerance, "tolerance")
    Q = _series(keys, "keys")
    times = key_times(times, Q.shape[0], "times", "keys")
    batch = Q.shape[1:-1]
    T, B = Q.shape[0], prod(batch)
    tol_rad = np.radians(tol) if degrees else tol
    flat = Q.reshape(T, B, 4)

    def make_track(idx, b):
        k = flat[idx] if b is None else flat[idx, b]
        return Track(times[idx], k.reshape((len(idx),) + (batch if b is None else ()) + (4,)), method=method)

    if B == 0:
        return ReducedKeys(Track(times, Q, method=method) if shared else [], np.zeros(batch, Q.dtype))
    _, tracks, errors = _reduce.reduce(method, times, flat, tol_rad, bool(shared), make_track)
    errors = errors.reshape(batch)
    if degrees:
        errors = np.degrees(errors)
    return ReducedKeys(tracks[0] if shared else tracks, errors.astype(Q.dtype))
