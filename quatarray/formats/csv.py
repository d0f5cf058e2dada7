"""CSV keyframe files: a header line, a ``time`` column, four columns per track.

The header is ``time,<track>.w,<track>.x,<track>.y,<track>.z,...`` (``x, y, z,
w`` with ``scalar_last=True``); values are comma-separated, or tab- or
semicolon-separated (detected from the header).  Text is written back the way
it was read: values with the input's number of decimals (`TextStyle`), the
input's line endings and separator.  Every problem with a file raises
`FormatError` carrying the file name and, where there is one, the line.
"""

import csv
import io

import numpy as np

from .atomic import atomic_write
from .keyframes import Keyframes
from .text import (FormatError, TextStyle, check_numbers, check_unit, echo, load_table, measure_style, row_line,
                   token_decimals, write_rows)

__all__ = ["read_csv", "write_csv"]

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

    Warns
    -----
    NonUnitKeyWarning
        Once per file, naming the first key whose norm differs from 1 by more
        than the file's decimals explain (``10**-decimals``); keys are
        returned as read and normalised where they are interpolated.

    Examples
    --------
    >>> from quatarray.formats import read_csv, example_path
    >>> kf = read_csv(example_path("arm.csv"))
    >>> kf.names, kf.keys.shape
    (('shoulder', 'elbow', 'wrist'), (11, 3, 4))
    """
    with open(path, encoding="utf-8-sig", errors="surrogateescape", newline="") as f:
        first = f.readline()
    if not first.strip():
        raise FormatError("the file is empty (expected a header line 'time,<track>.w,...')" if not first
                          else "the first line is empty (expected a header line 'time,<track>.w,...')", path,
                          None if not first else 1)
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
    check_unit(keys, path, where, style.decimals, lambda: _key_decimals(path, len(rows), len(names)))
    return Keyframes(times, np.ascontiguousarray(keys), names, style)


def _key_decimals(path, nrows, ntracks):
    """Decimals of each key of a CSV file (the most of its four values), or None if the file's numbers
    do not line up as (rows, 1 + 4 * tracks)."""
    with open(path, "rb") as f:
        data = f.read()
    decimals = token_decimals(data[data.find(b"\n") + 1:])
    if decimals.size != nrows * (1 + 4 * ntracks):
        return None
    return decimals.reshape(nrows, -1)[:, 1:].reshape(nrows, ntracks, 4).max(axis=-1)


def write_csv(path, keyframes, *, scalar_last=False):
    """Write keyframes to a CSV file (layout as `read_csv`), atomically.

    ``keys`` of shape (K, *batch, 4) are written as ``prod(batch)`` tracks;
    without ``names`` they are called ``q`` (no batch) or ``q0, q1, ...``
    (flattened batch index).  Values are written in ``keyframes.style``
    (decimals, line endings, separator), by default with the digits that read
    back to the same value; times always read back to the same value.  When
    ``keyframes.copied`` marks the rows copied from a file (as
    `resample_keyframes` does), only those keep the style's decimals: the
    others are written with the digits that read back to the same value.

    Examples
    --------
    >>> import numpy as np
    >>> import os, tempfile
    >>> from quatarray.formats import Keyframes, read_csv, write_csv
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
                   first=times.astype(dtype, copy=False),
                   exact=None if keyframes.copied is None else ~np.asarray(keyframes.copied, bool))

