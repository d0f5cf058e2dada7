"""Keyframe files: CSV and NPZ readers and writers, and the machinery shared with BVH.

- **CSV** -- a header line, a ``time`` column, then four columns per track,
  ``<track>.w,<track>.x,<track>.y,<track>.z`` (``x, y, z, w`` with
  ``scalar_last=True``).
- **NPZ** -- arrays ``times`` ``(K,)`` and ``keys`` ``(K, *batch, 4)``,
  scalar-first.

BVH lives in `quatarray._bvh`, on the same machinery.  Bulk numbers are parsed
by NumPy in one pass; lines are looked at one by one only once that parse has
failed, to name the bad one.  Every problem with a file raises `FormatError`
carrying the file name and, where there is one, the line.  Writers write to a
temporary file next to the target and rename it into place only when it is
complete, so a failed write leaves no partial file.
"""

import contextlib
import csv
import dataclasses
import io
import os
import tempfile
import warnings
import zipfile

import numpy as np

from ._validate import float_array
from .interpolate import Track

__all__ = [
    "FormatError", "Keyframes", "read_csv", "write_csv", "read_npz", "write_npz",
    "read_times", "fps_times", "resample_keyframes", "example_path",
]

_ROWS = 4096  # rows formatted per block when writing text
_TRACK_BLOCK = 1 << 18  # keys interpolated per block of tracks


class FormatError(ValueError):
    """A file that cannot be read as the format its extension names.

    ``str(err)`` is one line, ``path:line: message`` (``path: message`` when
    no line applies); the parts are kept as `path`, `line` and `message`.

    >>> str(FormatError("bad header", "a.csv", 1))
    'a.csv:1: bad header'
    """

    def __init__(self, message, path=None, line=None):
        self.message = " ".join(str(message).split("\n"))
        self.path = None if path is None else os.fspath(path)
        self.line = line
        super().__init__(str(self))

    def __str__(self):
        where = "" if self.path is None else self.path + (":" if self.line is None else f":{self.line}:")
        return f"{where} {self.message}" if where else self.message


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
        Track names (CSV: one per track, ``batch == (len(names),)``).
    """

    times: np.ndarray
    keys: np.ndarray
    names: tuple = None


# --------------------------------------------------------------------------- writing

@contextlib.contextmanager
def _atomic(path, binary=False):
    """Open a temporary file beside `path`; rename it to `path` only on success."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{os.path.basename(path)}.", suffix=".part")
    except OSError as exc:  # name the file asked for, not the temporary one
        raise type(exc)(exc.errno, exc.strerror, path) from None
    try:
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)  # mkstemp makes 0600; give the usual mode
        with (os.fdopen(fd, "wb") if binary else
              os.fdopen(fd, "w", encoding="utf-8", errors="surrogateescape", newline="\n")) as f:
            fd = None
            yield f
        os.replace(tmp, path)
    except BaseException:
        if fd is not None:
            os.close(fd)
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _write_rows(f, rows, sep):
    """Write a 2-D float array as text, one line per row, digits that round-trip.

    float64 is written as ``repr`` writes it (the shortest text that reads back
    to the same number), float32 with 9 significant digits.
    """
    line = sep.join(["%r" if rows.dtype == np.float64 else "%.9g"] * rows.shape[1]) + "\n"
    for start in range(0, len(rows), _ROWS):
        f.write("".join(line % tuple(r) for r in rows[start:start + _ROWS].tolist()))


# --------------------------------------------------------------------------- checks

def _check_numbers(times, keys, path, where):
    """Finite values, strictly increasing times, no zero quaternion.

    `where(i, j)` names row `i` (and flat track `j`) for messages; it returns
    ``(line, text)``.
    """
    bad = ~np.isfinite(times)
    if bad.any():
        line, at = where(int(np.argmax(bad)), None)
        raise FormatError(f"{at}non-finite time {float(times[bad][0])!r}", path, line)
    flat = keys.reshape(len(keys), -1, 4)
    bad = ~np.isfinite(flat).all(axis=-1)
    if bad.any():
        i, j = np.unravel_index(np.argmax(bad), bad.shape)
        line, at = where(int(i), int(j))
        raise FormatError(f"{at}non-finite quaternion component", path, line)
    step = np.diff(times)
    bad = ~(step > 0)
    if bad.any():
        i = int(np.argmax(bad)) + 1
        line, at = where(i, None)
        raise FormatError(f"{at}time {float(times[i])!r} does not come after {float(times[i - 1])!r} "
                          "(times must be strictly increasing)", path, line)
    bad = ~(flat != 0).any(axis=-1)
    if bad.any():
        i, j = np.unravel_index(np.argmax(bad), bad.shape)
        line, at = where(int(i), int(j))
        raise FormatError(f"{at}zero quaternion (cannot be a rotation)", path, line)


def _data_lines(path, skip, delimiter):
    """Yield ``(line_number, text)`` of the data lines after the first `skip`.

    As in `numpy.loadtxt`, empty lines are skipped, and so are lines of only
    whitespace when the delimiter is whitespace (`delimiter` None).
    """
    with open(path, encoding="utf-8-sig", errors="surrogateescape") as f:
        for number, text in enumerate(f, 1):
            text = text.rstrip("\r\n")
            if number > skip and (text if delimiter else text.strip()):
                yield number, text


def _row_line(path, skip, row, delimiter):
    """File line number of data row `row` (counted as `_data_lines` does)."""
    for i, (number, _) in enumerate(_data_lines(path, skip, delimiter)):
        if i == row:
            return number
    return None


def _diagnose(path, skip, ncols, delimiter, names=None, what="values"):
    """Find the first line after `skip` with the wrong count or a non-number; raise."""
    for number, text in _data_lines(path, skip, delimiter):
        cells = text.split(delimiter)
        if len(cells) != ncols:
            raise FormatError(f"expected {ncols} {what}, got {len(cells)}", path, number)
        for k, cell in enumerate(cells):
            try:
                float(cell)
            except ValueError:
                col = f" in column {names[k]!r}" if names else f" (value {k + 1})"
                raise FormatError(f"non-numeric value {cell.strip()!r}{col}", path, number) from None


def _load_table(path, skip, ncols, delimiter, names=None, what="values"):
    """Parse the numbers after line `skip` into (rows, ncols) float64, naming bad lines."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            rows = np.loadtxt(path, dtype=np.float64, delimiter=delimiter, skiprows=skip,
                              ndmin=2, comments=None, encoding="utf-8-sig")
    except ValueError as exc:
        error = str(exc)
    else:
        if not rows.size:
            return np.empty((0, ncols))
        if rows.shape[1] == ncols:
            return rows
        error = f"expected {ncols} {what}, got {rows.shape[1]}"
    _diagnose(path, skip, ncols, delimiter, names, what)
    raise FormatError(error, path)


# --------------------------------------------------------------------------- CSV

def _csv_tracks(header, scalar_last, path):
    """Track names from the header cells; raise FormatError naming the bad column."""
    if not header or header[0] != "time":
        raise FormatError(f"bad header: column 1 must be 'time', got {header[0] if header else ''!r}", path, 1)
    order, other = ("xyzw", "wxyz") if scalar_last else ("wxyz", "xyzw")
    names = []
    for start in range(1, len(header), 4):
        group = header[start:start + 4]
        base = group[0].rpartition(".")[0]
        if not base:
            raise FormatError(f"bad header: column {start + 1} is {group[0]!r}, expected '<track>.{order[0]}'",
                              path, 1)
        expected = [f"{base}.{c}" for c in order]
        if len(group) < 4 and group == expected[:len(group)]:
            raise FormatError(f"bad header: track {base!r} has {len(group)} of its 4 columns "
                              f"({', '.join(expected)})", path, 1)
        if group != expected:
            k = next(k for k in range(4) if group[k] != expected[k])
            msg = f"bad header: column {start + k + 1} is {group[k]!r}, expected {expected[k]!r}"
            if group == [f"{base}.{c}" for c in other]:
                msg += (" (the file looks scalar-first: leave out --scalar-last)" if scalar_last
                        else " (the file looks scalar-last: use --scalar-last)")
            raise FormatError(msg, path, 1)
        if base in names:
            raise FormatError(f"bad header: track {base!r} appears twice", path, 1)
        names.append(base)
    if not names:
        raise FormatError("bad header: no quaternion columns after 'time'", path, 1)
    return tuple(names)


def read_csv(path, *, scalar_last=False):
    """Read keyframes from a CSV file.

    Parameters
    ----------
    path : str or os.PathLike
        A header line ``time,<a>.w,<a>.x,<a>.y,<a>.z,<b>.w,...`` then one line
        per key.  Empty lines are ignored.
    scalar_last : bool, optional
        The file's components are ``x, y, z, w`` (header ``<a>.x ... <a>.w``).

    Returns
    -------
    Keyframes
        ``keys`` of shape (K, tracks, 4), scalar-first, float64; ``names``
        the track names.

    Raises
    ------
    FormatError
        Bad header, a row of the wrong length or with a non-number, non-finite
        values, times not strictly increasing or a zero quaternion; the message
        names the line.

    Examples
    --------
    >>> from quatarray._io import read_csv, example_path
    >>> kf = read_csv(example_path("arm.csv"))
    >>> kf.names, kf.keys.shape
    (('shoulder', 'elbow', 'wrist'), (11, 3, 4))
    """
    with open(path, encoding="utf-8-sig", errors="surrogateescape", newline="") as f:
        first = f.readline()
    header = [c.strip() for c in next(csv.reader([first]), [])]
    names = _csv_tracks(header, scalar_last, path)
    ncols = 1 + 4 * len(names)
    rows = _load_table(path, 1, ncols, ",", header)
    if not len(rows):
        raise FormatError("no keyframes after the header", path)
    keys = rows[:, 1:].reshape(len(rows), len(names), 4)
    if scalar_last:
        keys = np.roll(keys, 1, axis=-1)
    times = np.ascontiguousarray(rows[:, 0])

    def where(i, j):
        return _row_line(path, 1, i, ","), ("" if j is None else f"track {names[j]!r}: ")

    _check_numbers(times, keys, path, where)
    return Keyframes(times, np.ascontiguousarray(keys), names)


def write_csv(path, keyframes, *, scalar_last=False):
    """Write keyframes to a CSV file (layout as `read_csv`), atomically.

    ``keys`` of shape (K, *batch, 4) are written as ``prod(batch)`` tracks;
    without ``names`` they are called ``q`` (no batch) or ``q0, q1, ...``
    (flattened batch index).  Numbers are written with the digits that read
    back to the same value.

    Examples
    --------
    >>> import os, tempfile
    >>> from quatarray._io import Keyframes, read_csv, write_csv
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
    dtype = np.float32 if keys.dtype == np.float32 and times.dtype == np.float32 else np.float64
    header = io.StringIO()
    csv.writer(header, lineterminator="").writerow(["time"] + [f"{n}.{c}" for n in names for c in order])
    with _atomic(path) as f:
        f.write(header.getvalue() + "\n")
        for start in range(0, len(times), _ROWS):
            stop = start + _ROWS
            block = np.concatenate([times[start:stop, None].astype(dtype),
                                    flat[start:stop].reshape(-1, 4 * len(names)).astype(dtype)], axis=1)
            _write_rows(f, block, ",")


# --------------------------------------------------------------------------- NPZ

def read_npz(path):
    """Read keyframes from an NPZ archive with arrays ``times`` and ``keys``.

    ``times`` has shape (K,); ``keys`` shape (K, *batch, 4), scalar-first.
    float32 keys stay float32; times become float64.

    Raises
    ------
    FormatError
        Not an NPZ archive, a missing array, wrong shapes or dtypes, non-finite
        values, times not strictly increasing or a zero quaternion (the
        message names the index).

    Examples
    --------
    >>> import io
    >>> from quatarray._io import read_npz
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
        if missing:
            raise FormatError(f"missing array {missing[0]!r} (found {', '.join(archive.files) or 'none'})", name)
        try:
            times = archive["times"]
            keys = archive["keys"]
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

    def where(i, j):
        if j is None:
            return None, f"times[{i}]: "
        return None, "keys[" + ", ".join(map(str, (i,) + np.unravel_index(j, batch))) + "]: "

    _check_numbers(times, keys, name, where)
    return Keyframes(times, keys)


def write_npz(path, keyframes):
    """Write ``times`` and ``keys`` (scalar-first) to an NPZ archive, atomically.

    Examples
    --------
    >>> import os, tempfile
    >>> from quatarray._io import Keyframes, read_npz, write_npz
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = os.path.join(tmp.name, "one.npz")
    >>> write_npz(path, Keyframes(np.array([0.0, 1.0]), np.eye(4)[:2]))
    >>> read_npz(path).times
    array([0., 1.])
    """
    with _atomic(path, binary=True) as f:
        np.savez(f, times=np.asarray(keyframes.times), keys=np.asarray(keyframes.keys))


# --------------------------------------------------------------------------- query times

def read_times(path):
    """Read query times, one number per line (empty lines ignored).

    Raises `FormatError` naming the line of a non-number, a line with more
    than one value, a non-finite time or a time not after the previous one.

    Examples
    --------
    >>> import os, tempfile
    >>> from quatarray._io import read_times
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = os.path.join(tmp.name, "t.txt")
    >>> _ = open(path, "w").write("0\\n0.25\\n1e-0\\n")
    >>> read_times(path)
    array([0.  , 0.25, 1.  ])
    """
    t = _load_table(path, 0, 1, None, what="time on the line")[:, 0]
    if not len(t):
        raise FormatError("no times", path)
    _check_numbers(t, np.ones((len(t), 4)), path, lambda i, j: (_row_line(path, 0, i, None), ""))
    return t


def fps_times(t0, t1, fps):
    """Times ``t0 + k / fps`` for k = 0, 1, ... up to `t1` inclusive, within rounding.

    A last sample past `t1` by no more than rounding is moved onto `t1`.

    Examples
    --------
    >>> from quatarray._io import fps_times
    >>> fps_times(0.0, 0.3, 10)
    array([0. , 0.1, 0.2, 0.3])
    >>> fps_times(1.0, 1.25, 10)
    array([1. , 1.1, 1.2])
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"expected fps > 0, got {fps}")
    span = (t1 - t0) * fps
    n = int(np.floor(span + 1e-9 * max(1.0, span)))
    return np.minimum(t0 + np.arange(n + 1) / fps, t1)


# --------------------------------------------------------------------------- resampling

def _check_query(times, t, extrapolate):
    if len(times) < 2:
        raise ValueError(f"need at least 2 keyframes to interpolate, got {len(times)}")
    if extrapolate == "raise" and len(t) and (t.min() < times[0] or t.max() > times[-1]):
        bad = t[(t < times[0]) | (t > times[-1])][0]
        raise ValueError(f"query time {float(bad)!r} is outside the key times [{float(times[0])!r}, "
                         f"{float(times[-1])!r}] "
                         "and extrapolate is 'raise' (use 'clamp' or 'extend')")


def resample_keyframes(keyframes, t, *, method="slerp", extrapolate="raise"):
    """Evaluate the keyframes' curves at times `t`; the names are kept.

    Tracks are independent, so they are interpolated a block of tracks at a
    time (about 2**18 keys per block) into one preallocated output: the
    interpolator's per-key tables then cost a bounded amount of memory on top
    of input and output, however many tracks there are.

    Examples
    --------
    >>> from quatarray._io import Keyframes, resample_keyframes
    >>> kf = Keyframes(np.array([0.0, 1.0]), np.array([[1.0, 0, 0, 0], [0, 0, 0, 1]]))
    >>> resample_keyframes(kf, np.array([0.5])).keys.round(4)
    array([[0.7071, 0.    , 0.    , 0.7071]])
    """
    t = np.asarray(t, dtype=np.float64)
    times, keys = keyframes.times, keyframes.keys
    _check_query(times, t, extrapolate)
    flat = keys.reshape(len(keys), -1, 4)
    out = np.empty((len(t),) + flat.shape[1:], dtype=keys.dtype)
    step = max(1, _TRACK_BLOCK // len(keys))
    for j in range(0, flat.shape[1], step):
        track = Track(times, flat[:, j:j + step], method=method, extrapolate=extrapolate)
        out[:, j:j + step] = np.asarray(track(t))
    return Keyframes(t, out.reshape((len(t),) + keys.shape[1:]), keyframes.names)


def example_path(name):
    """Path of an example file shipped in ``quatarray/data`` (``arm.csv``, ``walk.bvh``).

    >>> from quatarray._io import example_path
    >>> os.path.basename(example_path("arm.csv"))
    'arm.csv'
    """
    return os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", name)
