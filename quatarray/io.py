"""Keyframe files: readers and writers for CSV, NPZ and BVH, and resampling them.

- **CSV** -- a header line, a ``time`` column (any case), then four columns
  per track, ``<track>.w,<track>.x,<track>.y,<track>.z`` (``x, y, z, w``
  with ``scalar_last=True``); comma-separated, or tab- or semicolon-separated
  (detected from the header).
- **NPZ** -- arrays ``times`` ``(K,)`` and ``keys`` ``(K, *batch, 4)``,
  scalar-first, and optionally ``names``, one track name per flattened batch
  index.
- **BVH** -- motion capture: `read_bvh`, `write_bvh`, `resample_motion`.

Text is written back the way it was read: values with the input's number of
decimals (`TextStyle`), the input's line endings and separator.  Every problem
with a file raises `FormatError` carrying the file name and, where there is
one, the line.  Writers write to a temporary file next to the target and
rename it into place only when it is complete, so a failed write leaves no
partial file.
"""

import csv
import contextlib
import dataclasses
import io
import os
import zipfile

import numpy as np

from ._bvh import Joint, Motion, read_bvh, resample_motion, write_bvh
from ._text import (FormatError, TextStyle, atomic_write, check_numbers, check_query, check_size, echo,
                    load_table, measure_style, row_line, write_rows)
from ._validate import float_array
from .interpolate import Track

__all__ = [
    "FormatError", "TextStyle", "Keyframes", "read_csv", "write_csv", "read_npz", "write_npz",
    "Joint", "Motion", "read_bvh", "write_bvh", "resample_motion",
    "read_times", "fps_times", "fps_steps", "resample_keyframes", "example_path",
]

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
    """

    times: np.ndarray
    keys: np.ndarray
    names: tuple = None
    style: TextStyle = None


# --------------------------------------------------------------------------- CSV

def _csv_tracks(header, scalar_last, path):
    """Track names from the header cells; raise FormatError naming the bad column."""
    if not header or header[0].lower() != "time":
        hint = (" (the separator must be a comma, a tab or a semicolon)"
                if len(header) == 1 and header[0].lower().startswith("time") else "")
        raise FormatError(f"bad header: column 1 must be 'time', got {echo(header[0] if header else '')}{hint}",
                          path, 1)
    order, other = ("xyzw", "wxyz") if scalar_last else ("wxyz", "xyzw")
    names = []
    for start in range(1, len(header), 4):
        group = header[start:start + 4]
        base = group[0].rpartition(".")[0]
        if not base:
            raise FormatError(f"bad header: column {start + 1} is {echo(group[0])}, expected '<track>.{order[0]}'",
                              path, 1)
        expected = [f"{base}.{c}" for c in order]
        if len(group) < 4 and group == expected[:len(group)]:
            raise FormatError(f"bad header: track {echo(base)} has {len(group)} of its 4 columns "
                              f"({', '.join(expected)})", path, 1)
        if group != expected:
            k = next(k for k in range(4) if group[k] != expected[k])
            msg = f"bad header: column {start + k + 1} is {echo(group[k])}, expected {echo(expected[k])}"
            if group == [f"{base}.{c}" for c in other]:
                msg += (" (the file looks scalar-first: leave out --scalar-last)" if scalar_last
                        else " (the file looks scalar-last: use --scalar-last)")
            raise FormatError(msg, path, 1)
        if base in names:
            raise FormatError(f"bad header: track {echo(base)} appears twice", path, 1)
        names.append(base)
    if not names:
        raise FormatError("bad header: no quaternion columns after 'time'", path, 1)
    return tuple(names)


def _delimiter(header):
    """The separator of a CSV file from its header line: comma, else tab, else semicolon."""
    return next((d for d in (",", "\t", ";") if d in header), ",")


def read_csv(path, *, scalar_last=False):
    """Read keyframes from a CSV file.

    Parameters
    ----------
    path : str or os.PathLike
        A header line ``time,<a>.w,<a>.x,<a>.y,<a>.z,<b>.w,...`` then one line
        per key.  Empty lines are ignored.  ``time`` may have any case; the
        separator is a comma, or a tab or semicolon when the header has no
        comma.
    scalar_last : bool, optional
        The file's components are ``x, y, z, w`` (header ``<a>.x ... <a>.w``).

    Returns
    -------
    Keyframes
        ``keys`` of shape (K, tracks, 4), scalar-first, float64; ``names``
        the track names; ``style`` the file's decimals, line endings and
        separator.

    Raises
    ------
    FormatError
        Bad header, a row of the wrong length or with a non-number, non-finite
        values, times not strictly increasing or a zero quaternion; the message
        names the line.

    Examples
    --------
    >>> from quatarray.io import read_csv, example_path
    >>> kf = read_csv(example_path("arm.csv"))
    >>> kf.names, kf.keys.shape
    (('shoulder', 'elbow', 'wrist'), (11, 3, 4))
    """
    with open(path, encoding="utf-8-sig", errors="surrogateescape", newline="") as f:
        first = f.readline()
    delimiter = _delimiter(first)
    try:
        header = [c.strip() for c in next(csv.reader([first], delimiter=delimiter), [])]
    except csv.Error as exc:  # a cell over csv.field_size_limit(), or a stray quote
        raise FormatError(f"bad header: {exc}", path, 1) from None
    names = _csv_tracks(header, scalar_last, path)
    ncols = 1 + 4 * len(names)
    rows = load_table(path, 1, ncols, delimiter, header)
    if not len(rows):
        raise FormatError("no keyframes after the header", path)
    keys = rows[:, 1:].reshape(len(rows), len(names), 4)
    if scalar_last:
        keys = np.roll(keys, 1, axis=-1)
    times = np.ascontiguousarray(rows[:, 0])

    def where(i, j):
        return row_line(path, 1, i, delimiter), ("" if j is None else f"track {echo(names[j])}: ")

    check_numbers(times, keys, path, where)
    style = measure_style(path, 1, ncols, delimiter)
    return Keyframes(times, np.ascontiguousarray(keys), names, style)


def write_csv(path, keyframes, *, scalar_last=False):
    """Write keyframes to a CSV file (layout as `read_csv`), atomically.

    ``keys`` of shape (K, *batch, 4) are written as ``prod(batch)`` tracks;
    without ``names`` they are called ``q`` (no batch) or ``q0, q1, ...``
    (flattened batch index).  Values are written in ``keyframes.style``
    (decimals, line endings, separator), by default with the digits that read
    back to the same value; times always read back to the same value.

    Examples
    --------
    >>> import numpy as np
    >>> import os, tempfile
    >>> from quatarray.io import Keyframes, read_csv, write_csv
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = os.path.join(tmp.name, "one.csv")
    >>> write_csv(path, Keyframes(np.array([0.0, 0.5]), np.array([[1.0, 0, 0, 0], [0, 1, 0, 0]])))
    >>> print(open(path).read())
    time,q.w,q.x,q.y,q.z
    0.0,1.0,0.0,0.0,0.0
    0.5,0.0,1.0,0.0,0.0
    <BLANKLINE>
    """
    times, keys = np.asarray(keyframes.times), np.asarray(keyframes.keys)
    flat = keys.reshape(len(keys), -1, 4)
    names = keyframes.names
    if names is None:
        names = ("q",) if keys.ndim == 2 else tuple(f"q{j}" for j in range(flat.shape[1]))
    if len(names) != flat.shape[1]:
        raise ValueError(f"expected {flat.shape[1]} track names, got {len(names)}")
    if scalar_last:
        flat = np.roll(flat, -1, axis=-1)
    order = "xyzw" if scalar_last else "wxyz"
    style = keyframes.style or TextStyle()
    dtype = np.float32 if keys.dtype == np.float32 and times.dtype == np.float32 else np.float64
    header = io.StringIO()
    csv.writer(header, delimiter=style.delimiter, lineterminator="").writerow(
        ["time"] + [f"{n}.{c}" for n in names for c in order])
    with atomic_write(path, newline=style.newline) as f:
        f.write(header.getvalue() + "\n")
        write_rows(f, flat.reshape(len(flat), 4 * len(names)).astype(dtype, copy=False), style,
                   first=times.astype(dtype, copy=False))


# --------------------------------------------------------------------------- NPZ

def read_npz(path):
    """Read keyframes from an NPZ archive with arrays ``times``, ``keys`` and optionally ``names``.

    ``times`` has shape (K,); ``keys`` shape (K, *batch, 4), scalar-first;
    ``names`` (strings, one per flattened batch index) the track names.
    float32 keys stay float32; times become float64.

    Raises
    ------
    FormatError
        Not an NPZ archive, a missing array, wrong shapes or dtypes, non-finite
        values, times not strictly increasing or a zero quaternion (the
        message names the index).

    Examples
    --------
    >>> import numpy as np
    >>> import io
    >>> from quatarray.io import read_npz
    >>> buf = io.BytesIO()
    >>> np.savez(buf, times=[0.0, 1.0], keys=[[1.0, 0, 0, 0], [0, 0, 0, 1]])
    >>> _ = buf.seek(0)
    >>> read_npz(buf).keys.shape
    (2, 4)
    """
    name = (getattr(path, "name", None) or "<stream>") if hasattr(path, "read") else os.fspath(path)
    with contextlib.ExitStack() as stack:
        f = path if hasattr(path, "read") else stack.enter_context(open(path, "rb"))
        try:
            archive = np.load(f, allow_pickle=False)
        except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
            raise FormatError(f"not an NPZ archive ({exc})", name) from None
        if not isinstance(archive, np.lib.npyio.NpzFile):
            raise FormatError("not an NPZ archive (a single .npy array)", name)
        stack.enter_context(archive)
        missing = [a for a in ("times", "keys") if a not in archive.files]
        names = None
        if missing:
            raise FormatError(f"missing array {missing[0]!r} (found {', '.join(archive.files) or 'none'})", name)
        try:
            times = archive["times"]
            keys = archive["keys"]
            if "names" in archive.files:
                names = archive["names"]
        except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
            raise FormatError(f"unreadable array ({exc})", name) from None
    try:
        times = float_array(times, "times", dtype=np.float64)
        keys = float_array(keys, "keys", last=4)
    except (TypeError, ValueError) as exc:
        raise FormatError(str(exc), name) from None
    if times.ndim != 1:
        raise FormatError(f"expected times of shape (K,), got {times.shape}", name)
    if keys.ndim < 2 or keys.shape[0] != len(times):
        raise FormatError(f"expected keys of shape ({len(times)}, ..., 4) to match times, got {keys.shape}", name)
    if not len(times):
        raise FormatError("no keyframes (times is empty)", name)
    batch = keys.shape[1:-1]
    if names is not None:
        if names.ndim != 1 or names.dtype.kind != "U" or len(names) != int(np.prod(batch)):
            raise FormatError(f"expected names of shape ({int(np.prod(batch))},), one string per track, got "
                              f"{names.dtype} of shape {names.shape}", name)
        names = tuple(str(n) for n in names)

    def where(i, j):
        if j is None:
            return None, f"times[{i}]: "
        return None, "keys[" + ", ".join(map(str, (i,) + np.unravel_index(j, batch))) + "]: "

    check_numbers(times, keys, name, where)
    return Keyframes(times, keys, names)


def write_npz(path, keyframes):
    """Write ``times``, ``keys`` (scalar-first) and the track ``names`` to an NPZ archive, atomically.

    ``names`` is left out when ``keyframes.names`` is None.

    Examples
    --------
    >>> import numpy as np
    >>> import os, tempfile
    >>> from quatarray.io import Keyframes, read_npz, write_npz
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = os.path.join(tmp.name, "one.npz")
    >>> write_npz(path, Keyframes(np.array([0.0, 1.0]), np.eye(4)[:2]))
    >>> read_npz(path).times
    array([0., 1.])
    """
    arrays = dict(times=np.asarray(keyframes.times), keys=np.asarray(keyframes.keys))
    if keyframes.names is not None:
        arrays["names"] = np.array(keyframes.names, dtype=str)
    with atomic_write(path, binary=True) as f:
        np.savez(f, **arrays)


# --------------------------------------------------------------------------- query times

def read_times(path):
    """Read query times, one number per line (empty lines ignored).

    Raises `FormatError` naming the line of a non-number, a line with more
    than one value, a non-finite time or a time not after the previous one.

    Examples
    --------
    >>> import os, tempfile
    >>> from quatarray.io import read_times
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


def fps_times(t0, t1, fps, per_frame=1):
    """Times ``t0 + k / fps`` for k = 0, 1, ... up to `t1` inclusive, within rounding.

    A last sample past `t1` by no more than rounding (a millionth of a frame,
    or the rounding of `t0` and `t1` themselves) is moved onto `t1`.  More frames than `quatarray._text.MAX_VALUES` / `per_frame`
    (values per output frame) raise ValueError before anything is allocated.

    Examples
    --------
    >>> from quatarray.io import fps_times
    >>> fps_times(0.0, 0.3, 10)
    array([0. , 0.1, 0.2, 0.3])
    >>> fps_times(1.0, 1.25, 10)
    array([1. , 1.1, 1.2])
    """
    n = fps_steps(t0, t1, fps)
    check_size(n + 1, per_frame, f"a rate of {fps:g} fps over {t1 - t0:g} s")
    return np.minimum(t0 + np.arange(n + 1) / fps, t1)


def fps_steps(t0, t1, fps):
    """The last k of the grid ``t0 + k / fps`` that reaches `t1` within rounding (see `fps_times`).

    Examples
    --------
    >>> from quatarray.io import fps_steps
    >>> fps_steps(0.0, 0.3, 10), fps_steps(0.0, 999_999_999.0, 1)
    (3, 999999999)
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"expected fps > 0, got {fps}")
    span = (t1 - t0) * fps
    # within rounding: a millionth of a frame, plus the rounding of long spans and of large
    # times (absolute clock times such as 1403636579.76 s carry 2.4e-7 s each)
    slack = 1e-6 + 1e-12 * span + 8 * np.finfo(np.float64).eps * max(abs(t0), abs(t1)) * fps
    return int(np.floor(span + slack))


# --------------------------------------------------------------------------- resampling

def resample_keyframes(keyframes, t, *, method="slerp", extrapolate="raise"):
    """Evaluate the keyframes' curves at times `t`; the names and text style are kept.

    Tracks are independent, so they are interpolated a block of tracks at a
    time (about 2**18 keys per block) into one preallocated output: the
    interpolator's per-key tables then cost a bounded amount of memory on top
    of input and output, however many tracks there are.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.io import Keyframes, resample_keyframes
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
    return Keyframes(t, out.reshape((len(t),) + keys.shape[1:]), keyframes.names, keyframes.style)


def example_path(name):
    """Path of an example file shipped in ``quatarray/data`` (``arm.csv``, ``walk.bvh``).

    >>> import os
    >>> from quatarray.io import example_path
    >>> os.path.basename(example_path("arm.csv"))
    'arm.csv'
    """
    return os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", name)
