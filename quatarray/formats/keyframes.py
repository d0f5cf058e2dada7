"""Keyframes in memory, query times, and resampling them (shared by the CSV, NPZ and Zarr formats)."""

import dataclasses
import os

import numpy as np

from ..interpolate import Track
from .text import MAX_VALUES, FormatError, TextStyle, check_numbers, check_query, check_size, load_table, row_line

__all__ = ["Keyframes", "read_times", "fps_times", "fps_steps", "snap_to_keys", "keys_at_key_times",
           "resample_keyframes", "example_path"]

_TRACK_BLOCK = 1 << 18  # keys interpolated per block of tracks


@dataclasses.dataclass
class Keyframes:
    """Keyframes of one or more quaternion tracks (CSV and NPZ files).

    Attributes
    ----------
    times : ndarray, shape (K,)
        Strictly increasing key times (float64).
    keys : ndarray, shape (K, *batch, 4)
        Scalar-first quaternions; float32 or float64.
    names : tuple of str or None
        Track names, one per flattened batch index (CSV: one per track,
        ``batch == (len(names),)``).
    style : TextStyle or None
        How the CSV file they came from printed its values (decimals, line
        endings, separator); `write_csv` writes the same way.  None: values
        with the shortest text that reads back exactly, ``\\n``, commas.
    copied : ndarray of bool, shape (K,), or None
        Which rows hold keys copied from the file (`resample_keyframes`: a
        query time that is a key time).  Only those rows keep the file's
        decimals; every other row is written with the digits that read back
        exactly, so that an interpolated value is never rounded to the
        input's precision.  None: every row is as read.
    """

    times: np.ndarray
    keys: np.ndarray
    names: tuple = None
    style: TextStyle = None
    copied: np.ndarray = None



# --------------------------------------------------------------------------- query times

def read_times(path):
    """Read query times, one number per line (empty lines ignored).

    Raises `FormatError` naming the line of a non-number, a line with more
    than one value, a non-finite time or a time not after the previous one.

    Examples
    --------
    >>> import os, tempfile
    >>> from quatarray.formats import read_times
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = os.path.join(tmp.name, "t.txt")
    >>> _ = open(path, "w").write("0\\n0.25\\n1e-0\\n")
    >>> read_times(path)
    array([0.  , 0.25, 1.  ])
    """
    t = load_table(path, 0, 1, None, what="time on the line")[:, 0]
    if not len(t):
        raise FormatError("no times", path)
    check_numbers(t, np.ones((len(t), 4)), path, lambda i, j: (row_line(path, 0, i, None), ""))
    return t


def fps_times(t0, t1, fps, per_frame=1, onto=None):
    """Times ``t0 + k / fps`` for k = 0, 1, ... up to `t1` inclusive, within rounding.

    A last sample past `t1` by no more than rounding (a millionth of a frame,
    or the rounding of `t0` and `t1` themselves) is moved onto `t1`, and with
    `onto` (key times, increasing) a sample within that rounding of a key time
    is moved onto it, so that it is that key, not an interpolation one
    rounding away.  More frames than `quatarray.formats.text.MAX_VALUES` / `per_frame`
    (values per output frame) raise ValueError before anything is allocated.

    Examples
    --------
    >>> from quatarray.formats import fps_times
    >>> fps_times(0.0, 0.3, 10)
    array([0. , 0.1, 0.2, 0.3])
    >>> fps_times(1.0, 1.25, 10)
    array([1. , 1.1, 1.2])
    """
    n = fps_steps(t0, t1, fps)
    check_size(n + 1, per_frame, f"a rate of {fps:g} fps over {t1 - t0:g} s")
    t = np.minimum(t0 + np.arange(n + 1) / fps, t1)
    return t if onto is None else snap_to_keys(t, onto, t0, t1, fps)


def snap_to_keys(t, onto, t0, t1, fps):
    """The grid times `t` (of `fps_times`, any part of its grid) with each time within
    rounding of a key time of `onto` (increasing) moved onto it: a copy."""
    t = np.array(t, np.float64)
    if len(onto) and t.size:
        onto = np.asarray(onto, np.float64)
        right = np.minimum(np.searchsorted(onto, t), len(onto) - 1)
        near = np.where(np.abs(onto[right] - t) <= np.abs(onto[right - 1] - t), right, np.maximum(right - 1, 0))
        snap = np.abs(onto[near] - t) <= _rounding(t0, t1, fps) / fps
        t[snap] = onto[near[snap]]
    return t


def _rounding(t0, t1, fps):
    """What "within rounding" allows of a frame time, in frames: a millionth of a frame, plus
    the rounding of the times themselves (absolute clock times such as 1403636579.76 s
    carry 2.4e-7 s each, more than a millionth of a frame at 100 fps)."""
    return 1e-6 + 8 * np.finfo(np.float64).eps * max(abs(t0), abs(t1)) * fps


def fps_steps(t0, t1, fps):
    """The last k of the grid ``t0 + k / fps`` that reaches `t1` within rounding (see `fps_times`).

    Examples
    --------
    >>> from quatarray.formats import fps_steps
    >>> fps_steps(0.0, 0.3, 10), fps_steps(0.0, 999_999_999.0, 1)
    (3, 999999999)
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"expected fps > 0, got {fps}")
    with np.errstate(over="ignore"):
        span = (t1 - t0) * fps
        slack = _rounding(t0, t1, fps) + 1e-12 * span   # (and the rounding of long spans)
        last = np.floor(span + slack)
    if not last < 2.0**62:   # the frame count of --fps 1e308 is no integer numpy can hold
        raise ValueError(f"a rate of {fps:g} fps over {t1 - t0:g} s asks for {float(span):.3g} frames; the limit "
                         f"is {MAX_VALUES:,} values")
    return int(last)

# --------------------------------------------------------------------------- resampling

def resample_keyframes(keyframes, t, *, method="slerp", extrapolate="raise"):
    """Evaluate the keyframes' curves at times `t`; the names and text style are kept.

    At a query time equal to a key time the key itself is returned, as read
    (with the sign the curve has there, which may differ after hemisphere
    alignment), and the row is marked in ``copied``: `write_csv` writes only
    such rows with the input's decimals, so an identity resample gives the
    input's text back, while every interpolated value is written with the
    digits that read back exactly.

    Tracks are independent, so they are interpolated a block of tracks at a
    time (about 2**18 keys per block) into one preallocated output: the
    interpolator's per-key tables then cost a bounded amount of memory on top
    of input and output, however many tracks there are.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.formats import Keyframes, resample_keyframes
    >>> kf = Keyframes(np.array([0.0, 1.0]), np.array([[1.0, 0, 0, 0], [0, 0, 0, 1]]))
    >>> resample_keyframes(kf, np.array([0.5])).keys.round(4)
    array([[0.7071, 0.    , 0.    , 0.7071]])
    """
    t = np.asarray(t, dtype=np.float64)
    times, keys = keyframes.times, keyframes.keys
    check_query(times, t, extrapolate)
    flat = keys.reshape(len(keys), -1, 4)
    check_size(len(t), flat.shape[1] * 4, f"{len(t):,} query times")
    out = np.empty((len(t),) + flat.shape[1:], dtype=keys.dtype)
    step = max(1, _TRACK_BLOCK // len(keys))
    for j in range(0, flat.shape[1], step):
        track = Track(times, flat[:, j:j + step], method=method, extrapolate=extrapolate)
        out[:, j:j + step] = np.asarray(track(t))
    copied = keys_at_key_times(times, flat, t, out)
    return Keyframes(t, out.reshape((len(t),) + keys.shape[1:]), keyframes.names, keyframes.style, copied)


def keys_at_key_times(times, keys, t, out):
    """Where a query time equals a key time, the key itself as read into `out` (the curve's
    value there, rows of `t`), on the curve's side (negated where the curve has the other
    sign): a curve normalises its keys, and a file's keys hold a few decimals, so the curve
    at a key is the key but for about one of its last digits.  `keys` (K, ..., 4); returns the
    mask of the rows replaced.  Every path that writes a resampled file runs it (in memory,
    and on each chunk of queries in `quatarray.formats.zarr`)."""
    at = np.minimum(np.searchsorted(times, t), len(times) - 1)
    copied = times[at] == t
    if copied.any():
        key = keys[at[copied]]
        flip = (np.einsum("...i,...i->...", out[copied], key) < 0)[..., None]
        out[copied] = np.where(flip, -key + 0.0, key)   # + 0.0: a flipped 0 is 0, not -0
    return copied


def example_path(name):
    """Path of an example file shipped in ``quatarray/data`` (``arm.csv``, ``walk.bvh``).

    >>> import os
    >>> from quatarray.formats import example_path
    >>> os.path.basename(example_path("arm.csv"))
    'arm.csv'
    """
    return os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "data", name)
