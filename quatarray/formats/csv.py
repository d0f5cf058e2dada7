"""CSV keyframe files: a header line, a ``time`` column, four columns per track.

The header is ``time,<track>.w,<track>.x,<track>.y,<track>.z,...`` (``x, y, z,
w`` with ``scalar_last=True``); values are comma-separated, or tab- or
semicolon-separated (detected from the header).  Text is written back the way
it was read: values with the input's number of decimals (`TextStyle`), the
input's line endings and separator.  Every problem with a file raises
`FormatError` carrying the file name and, where there is one, the line.
"""

import csv
import dataclasses
import io

import numpy as np

from .atomic import atomic_write
from .keyframes import Keyframes
from .text import (FormatError, TextStyle, check_numbers, check_unit, echo, load_table, measure_style, row_line,
                   token_decimals, write_rows)

__all__ = ["read_csv", "write_csv"]

def _csv_columns(header, path):
    """``(time column, track names, key columns (tracks, 4) in w, x, y, z order, scalar_last)`` from the
    header cells, matched by name (case-insensitively, in any order); FormatError naming the bad column.

    One pass with a dict: 250,000 tracks take as long as a few.
    """
    lower = [c.lower() for c in header]
    times = [i for i, c in enumerate(lower) if c == "time"]
    if len(times) != 1:
        if times:
            raise FormatError(f"bad header: columns {times[0] + 1} and {times[1] + 1} are both 'time'", path, 1)
        hint = (" (the separator must be a comma, a tab or a semicolon)"
                if len(header) == 1 and lower[0].startswith("time") else "")
        raise FormatError(f"bad header: no 'time' column, got {echo(','.join(header))}{hint}", path, 1)
    tracks, order = {}, []   # casefolded name -> (name as first written, {component: column})
    for i, cell in enumerate(header):
        if i == times[0]:
            continue
        base, dot, comp = cell.rpartition(".")
        comp = comp.lower()
        if not (dot and base and comp in ("w", "x", "y", "z")):
            raise FormatError(f"bad header: column {i + 1} is {echo(cell)}, expected 'time' or '<track>.w', "
                              "'<track>.x', '<track>.y', '<track>.z'", path, 1)
        key = base.casefold()
        if key not in tracks:
            tracks[key] = (base, {})
            order.append(key)
        columns = tracks[key][1]
        if comp in columns:
            raise FormatError(f"bad header: column {i + 1} ({echo(cell)}) repeats column {columns[comp] + 1} "
                              f"({echo(header[columns[comp]])})", path, 1)
        columns[comp] = i
    if not order:
        raise FormatError("bad header: no quaternion columns besides 'time'", path, 1)
    for key in order:
        base, columns = tracks[key]
        if len(columns) < 4:
            missing = [f"{base}.{c}" for c in "wxyz" if c not in columns]
            raise FormatError(f"bad header: track {echo(base)} has {len(columns)} of its 4 columns (no "
                              f"{', '.join(map(echo, missing))})", path, 1)
    names = tuple(tracks[key][0] for key in order)
    cols = np.array([[tracks[key][1][c] for c in "wxyz"] for key in order], dtype=np.intp)
    scalar_last = bool((cols[:, 0] > cols[:, 1:].max(axis=1)).all())   # every track writes w after x, y, z
    return times[0], names, cols, scalar_last


def _check_names(names):
    """Track names that `read_csv` reads back as written: a ValueError for one it could not
    (empty, with a line break or spaces at either end, or equal to another but for case:
    the header is matched case-insensitively)."""
    seen = {}
    for name in names:
        if not isinstance(name, str) or not name or name != name.strip() or "\n" in name or "\r" in name:
            raise ValueError(f"expected track names a CSV header reads back (non-empty, no line break, no "
                             f"spaces at either end), got {name!r}")
        other = seen.setdefault(name.casefold(), name)
        if other is not name:
            raise ValueError(f"expected track names that differ other than in case (a CSV header's are "
                             f"matched case-insensitively), got {other!r} and {name!r}")


def _delimiter(header):
    """The separator of a CSV file from its header line: comma, else tab, else semicolon."""
    return next((d for d in (",", "\t", ";") if d in header), ",")


def read_csv(path, *, scalar_last=False):
    """Read keyframes from a CSV file.

    Parameters
    ----------
    path : str or os.PathLike
        A header line naming a ``time`` column and four columns per track,
        ``<a>.w``, ``<a>.x``, ``<a>.y``, ``<a>.z``, then one line per key.
        Columns are matched by name, case-insensitively and in any order
        (``time`` last, tracks interleaved, ``x, y, z, w``); empty lines are
        ignored; the separator is a comma, or a tab or semicolon when the
        header has no comma.
    scalar_last : bool, optional
        No effect on reading (the columns say which component they hold);
        accepted so that `read_csv` and `write_csv` take the same options.

    Returns
    -------
    Keyframes
        ``keys`` of shape (K, tracks, 4), scalar-first, float64; ``names``
        the track names in the order of their first column (as first
        written); ``style`` the file's decimals, line endings, separator
        and whether its tracks are written ``x, y, z, w``.

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
    time_col, names, cols, file_scalar_last = _csv_columns(header, path)
    ncols = len(header)
    rows = load_table(path, 1, ncols, delimiter, header)
    if not len(rows):
        raise FormatError("no keyframes after the header", path)
    keys = rows[:, cols]   # (K, tracks, 4), scalar-first whatever the file's order
    times = np.ascontiguousarray(rows[:, time_col])

    def where(i, j):
        return row_line(path, 1, i, delimiter), ("" if j is None else f"track {echo(names[j])}: ")

    check_numbers(times, keys, path, where)
    style = measure_style(path, 1, ncols, delimiter, time_col)
    style = dataclasses.replace(style, scalar_last=file_scalar_last)
    check_unit(keys, path, where, style.decimals, lambda: _key_decimals(path, len(rows), ncols, cols))
    return Keyframes(times, keys, names, style)


def _key_decimals(path, nrows, ncols, cols):
    """Decimals of each key of a CSV file (the most of its four values), or None if the file's numbers
    do not line up as (rows, ncols)."""
    with open(path, "rb") as f:
        data = f.read()
    decimals = token_decimals(data[data.find(b"\n") + 1:])
    if decimals.size != nrows * ncols:
        return None
    return decimals.reshape(nrows, ncols)[:, cols].max(axis=-1)


def write_csv(path, keyframes, *, scalar_last=None):
    """Write keyframes to a CSV file (layout as `read_csv`), atomically.

    ``keys`` of shape (K, *batch, 4) are written as ``prod(batch)`` tracks,
    ``time`` first, then each track's ``w, x, y, z`` (``x, y, z, w`` with
    `scalar_last`; None: as ``keyframes.style.scalar_last`` says, that is as
    the file read was written);
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
    _check_names(names)
    style = keyframes.style or TextStyle()
    if scalar_last is None:
        scalar_last = style.scalar_last
    if scalar_last:
        flat = np.roll(flat, -1, axis=-1)
    order = "xyzw" if scalar_last else "wxyz"
    dtype = np.float32 if keys.dtype == np.float32 and times.dtype == np.float32 else np.float64
    header = io.StringIO()
    csv.writer(header, delimiter=style.delimiter, lineterminator="").writerow(
        ["time"] + [f"{n}.{c}" for n in names for c in order])
    with atomic_write(path, newline=style.newline) as f:
        f.write(header.getvalue() + "\n")
        write_rows(f, flat.reshape(len(flat), 4 * len(names)).astype(dtype, copy=False), style,
                   first=times.astype(dtype, copy=False),
                   exact=None if keyframes.copied is None else ~np.asarray(keyframes.copied, bool))

