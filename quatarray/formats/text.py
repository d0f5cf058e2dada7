"""Machinery shared by the text formats' readers and writers (CSV, BVH, query times) and the command line.

- `FormatError`, the one exception for a file that cannot be read;
- `TextStyle`, `measure_style` and `write_rows`: how a text file printed its
  numbers and ended its lines, so that it can be written back the same way;
- `load_table`, `data_lines`, `row_line`: bulk parsing by NumPy in one pass,
  looking at lines one by one only once that parse has failed, to name the bad
  one;
- `check_numbers`, `check_query`, `check_size`: the checks every format shares;
- `echo`: a value quoted in a message, cut to about 60 characters;
- `option`: an option named as the caller spells it (``--force`` on the
  command line, ``force=True`` in Python; `command_line` switches).
- `refuse_existing`, `read_while_written`, `same_file`, `nested`, `one_below_other`: the overwrite
  rule's wording and its tests of whether an output is the input.

`FormatError` and `TextStyle` are public (`quatarray.formats`); the rest is
shared inside the package.
"""

import contextlib
import contextvars
import dataclasses
import errno
import os
import re
import warnings

import numpy as np

ROWS = 4096  # rows formatted per block when writing text

#: Most values (frames x values per frame) a resample may produce: 8 GiB of float64.
MAX_VALUES = 1 << 30


class FormatError(ValueError):
    """A file that cannot be read as the format its extension names.

    ``str(err)`` is one line, ``path:line: message`` (``path: message`` when
    no line applies); the parts are kept as `path`, `line` and `message`.

    >>> from quatarray.formats import FormatError
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


def echo(value, limit=60):
    """`value` quoted for a message, cut to about `limit` characters.

    >>> from quatarray.formats.text import echo
    >>> echo("abc")
    "'abc'"
    >>> echo("x" * 1000)
    "'xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx...' (1000 characters)"
    >>> print(echo(b"0.5\\xff".decode("utf-8", "surrogateescape")))
    '0.5\\xff' (not UTF-8 text)
    """
    value = str(value)
    if len(value) <= limit:
        text = repr(value)
    else:
        text = repr(value[:limit - 10] + "...") + f" ({len(value)} characters)"
    if not _NOT_UTF8.search(value):
        return text
    # bytes that are not UTF-8 (read with surrogateescape): shown as the bytes they are
    return re.sub(r"\\udc([89a-f][0-9a-f])", r"\\x\1", text) + " (not UTF-8 text)"


_NOT_UTF8 = re.compile("[\udc80-\udcff]")


_COMMAND_LINE = contextvars.ContextVar("quatarray_command_line", default=False)


@contextlib.contextmanager
def command_line():
    """Within this block, `option` names options as the ``quatarray`` command spells them."""
    token = _COMMAND_LINE.set(True)
    try:
        yield
    finally:
        _COMMAND_LINE.reset(token)


def option(name, *values):
    """An option as a message names it: ``--name v1 or v2`` in `command_line`, else ``name=v1 or v2``.

    >>> from quatarray.formats.text import command_line, option
    >>> option("force"), option("extrapolate", "clamp", "extend")
    ('force=True', "extrapolate='clamp' or 'extend'")
    >>> with command_line():
    ...     option("force"), option("extrapolate", "clamp", "extend")
    ('--force', '--extrapolate clamp or extend')
    """
    if _COMMAND_LINE.get():
        return " ".join(["--" + name.replace("_", "-"), " or ".join(map(str, values))]).strip()
    return f"{name}=" + (" or ".join(map(repr, values)) if values else "True")


def refuse_existing(exists, name, force):
    """The overwrite rule, in one wording for every writer: an output that `exists` is replaced
    only with `force`."""
    if exists and not force:
        raise FileExistsError(errno.EEXIST, f"exists; give {option('force')} to replace it", os.fspath(name))


def read_while_written(name, what="input"):
    """The error for an output that is the `what` (``"input"``, ``"times store"``) of a resample that
    reads it chunk by chunk while it writes the output (.zarr to .zarr): never replaced, even with
    force, since the old data is still being read when the new is written."""
    return FormatError(f"is the {what}, which is read chunk by chunk while the output is written, so the output "
                       f"cannot replace it, even with {option('force')}: write elsewhere, then rename", name)


def same_file(a, b):
    """Whether paths `a` and `b` are one existing file (False if either is missing)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def nested(a, b):
    """Whether paths `a` and `b` are two places one inside the other (a file or store within a
    store's folder, or the reverse), links resolved; False for one and the same path.

    >>> from quatarray.formats.text import nested
    >>> nested("in.zarr", "in.zarr/sub.zarr"), nested("in.zarr", "in.zarr"), nested("a.csv", "a.csv.zarr")
    (True, False, False)
    """
    return one_below_other(*(os.path.realpath(os.fspath(x)) for x in (a, b)))


def one_below_other(a, b, sep=os.sep):
    """Whether the resolved paths `a` and `b` differ and one lies below the other (`sep` their
    separator: ``/`` on an object store)."""
    return a != b and (a.startswith(b.rstrip(sep) + sep) or b.startswith(a.rstrip(sep) + sep))


def not_a_store(name, store):
    """The error for a file where a `store` (a directory format such as ``"Zarr"``) is to be written."""
    return FileExistsError(errno.EEXIST, f"exists and is not a {store} store (a directory)", os.fspath(name))


# --------------------------------------------------------------------------- how numbers were printed

@dataclasses.dataclass(frozen=True)
class TextStyle:
    """How a text file printed its values and ended its lines.

    Attributes
    ----------
    decimals : int or None
        Digits after the decimal point; None writes the shortest text that
        reads back to the same number.
    trim : bool
        Trailing zeros are dropped (``0``, ``1.5``, ``-5.14473``, as ``%g``
        writes), rather than every value having `decimals` digits.
    newline : str
        ``"\\n"`` or ``"\\r\\n"``.
    delimiter : str
        Between values on a line (CSV: ``,``, tab or ``;``).
    time_decimals, time_trim : int or None, bool
        The same as `decimals` and `trim` for a time column (CSV), which is
        written so only where that reads back to the same time.
    scalar_last : bool
        Quaternions are written ``x, y, z, w`` (CSV).
    """

    decimals: int = None
    trim: bool = False
    newline: str = "\n"
    delimiter: str = ","
    time_decimals: int = None
    time_trim: bool = False
    scalar_last: bool = False


_NUMBER_BYTE = np.zeros(256, bool)
_NUMBER_BYTE[np.frombuffer(b"0123456789.+-eE", np.uint8)] = True


def token_decimals(data):
    """Digits after the decimal point of each number in `data` (bytes), in order.

    ``1.25`` has 2, ``7`` has 0, ``1.5e-3`` has 4 (what ``%f`` needs to write it).
    """
    b = np.frombuffer(data, np.uint8)
    inside = _NUMBER_BYTE[b]
    before = np.concatenate([[False], inside[:-1]])
    after = np.concatenate([inside[1:], [False]])
    starts = np.flatnonzero(inside & ~before)
    ends = np.flatnonzero(inside & ~after) + 1
    dots = np.flatnonzero(b == ord("."))
    exps = np.flatnonzero((b == ord("e")) | (b == ord("E")))
    decimals = np.zeros(len(starts), np.int64)
    if len(dots):
        i = np.minimum(np.searchsorted(dots, starts), len(dots) - 1)
        has = (dots[i] >= starts) & (dots[i] < ends)
        decimals[has] = ends[has] - dots[i[has]] - 1
    if len(exps):  # rare: a Python loop over the numbers written with an exponent only
        j = np.minimum(np.searchsorted(exps, starts), len(exps) - 1)
        for k in np.flatnonzero((exps[j] >= starts) & (exps[j] < ends)):
            mantissa, _, power = data[starts[k]:ends[k]].decode("ascii").partition(
                "e" if b[exps[j[k]]] == ord("e") else "E")
            try:
                decimals[k] = max(0, len(mantissa.partition(".")[2]) - int(power))
            except ValueError:
                decimals[k] = 0
    return decimals


def measure_style(path, skip, ncols=None, delimiter=",", time_column=0):
    """The `TextStyle` of the numbers after the first `skip` lines of `path`.

    With `ncols`, number `time_column` of every `ncols` numbers (a time
    column) is counted apart.  More than 17 decimals (a tiny value written with an
    exponent) means shortest round-trip text (``decimals=None``).  The file is
    looked at in blocks of whole lines (about 4 MB), so the scratch stays
    small for large files.
    """
    with open(path, "rb") as f:
        data = f.read()
    first = data.find(b"\n")
    newline = "\r\n" if first > 0 and data[first - 1:first] == b"\r" else "\n"
    start = 0
    for _ in range(skip):
        start = data.find(b"\n", start) + 1
        if not start:
            start = len(data)
            break
    ranges = {"values": [], "times": []}  # (fewest, most) decimals per block
    while start < len(data):
        stop = data.find(b"\n", start + _MEASURE_BLOCK)
        stop = len(data) if stop < 0 else stop + 1
        decimals = token_decimals(data[start:stop])
        parts = {"values": decimals}
        if ncols and len(decimals) % ncols == 0:
            table = decimals.reshape(-1, ncols)
            parts = {"values": np.delete(table, time_column, axis=1), "times": table[:, time_column]}
        for kind, part in parts.items():
            if part.size:
                ranges[kind].append((int(part.min()), int(part.max())))
        start = stop
    return TextStyle(*_digits(ranges["values"]), newline, delimiter, *_digits(ranges["times"]))


_MEASURE_BLOCK = 1 << 22


def _digits(ranges):
    """``(decimals, trim)`` for numbers printed with decimals in these (fewest, most) ranges."""
    if not ranges:
        return None, False
    low, top = min(r[0] for r in ranges), max(r[1] for r in ranges)
    if top > 17:
        return None, False
    return top, low != top


def write_rows(f, rows, style=None, sep=None, first=None, exact=None):
    """Write a 2-D float array as text, one line per row.

    Without ``style.decimals``, float64 is written as ``repr`` writes it (the
    shortest text that reads back to the same number) and float32 with 9
    significant digits.  With it, values are written with that many decimals
    (trailing zeros dropped when ``style.trim``), and a value that rounds to
    zero without being zero is written as plain zero, not ``-0.000``.
    `exact`, a boolean mask of rows, writes those rows as without
    ``style.decimals`` (an interpolated value among keys copied from a file).
    `first`, a column written before `rows` (CSV times), is written with
    ``style.time_decimals`` where that reads back to the same number, else
    exactly.
    """
    style = style or TextStyle()
    if exact is not None and style.decimals is not None and np.any(exact):
        exact = np.asarray(exact, bool)
        bounds = np.concatenate([[0], np.flatnonzero(np.diff(exact)) + 1, [len(rows)]])
        plain = dataclasses.replace(style, decimals=None, trim=False)
        for start, stop in zip(bounds[:-1], bounds[1:]):   # runs of rows in one style
            write_rows(f, rows[start:stop], plain if exact[start] else style, sep,
                       None if first is None else first[start:stop])
        return
    sep = style.delimiter if sep is None else sep
    fmt = ("%r" if rows.dtype == np.float64 else "%.9g") if style.decimals is None else f"%.{style.decimals}f"
    line = sep.join([fmt] * rows.shape[1]) + "\n"
    trim = bool(style.decimals and style.trim)
    if trim:  # every value has exactly `decimals` digits after its point: a run of zeros before a
        # separator or line end lies inside them (plain replacements: no per-match Python call)
        zeros = re.compile("0+(?=[" + re.escape(sep) + "\n])")
        point = re.compile("\\.(?=[" + re.escape(sep) + "\n])")
    for start in range(0, len(rows), ROWS):
        block = rows[start:start + ROWS]
        if style.decimals is not None:
            block = np.where((np.abs(block) < 0.5 * 10.0 ** -style.decimals) & (block != 0), 0.0, block)
        text = "".join(line % tuple(r) for r in block.tolist())
        if trim:
            text = point.sub("", zeros.sub("", text))
        if first is not None:  # the time column, in its own style
            text = "".join(f"{t}{sep}{values}\n" for t, values in
                           zip(_time_texts(first[start:start + ROWS], style), text.split("\n")))
        f.write(text)


def _time_texts(times, style):
    """Times as text in the time style, each exactly where the style's decimals cannot hold it."""
    exact = "%r" if times.dtype == np.float64 else "%.9g"
    out = []
    for t in times.tolist():
        text = exact % t
        if style.time_decimals is not None:
            short = f"{t:.{style.time_decimals}f}"
            if style.time_trim and "." in short:
                short = short.rstrip("0").rstrip(".")
            if times.dtype.type(float(short)) == t:
                text = short
        out.append(text)
    return out


# --------------------------------------------------------------------------- checks

def check_numbers(times, keys, path, where):
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


class NotCarriedWarning(UserWarning):
    """A file holds data besides the keyframes (other arrays of an NPZ archive, other arrays or
    attributes of a Zarr store), which quatarray does not read: a file written from it lacks them."""


def not_carried(what, extra, path):
    """Warn (`NotCarriedWarning`) that `extra`, named data of the file at `path` besides the
    keyframes (`what`: 'arrays', 'attributes'), is neither read nor written."""
    if extra:
        warnings.warn(str(FormatError(
            f"holds {what} besides the keyframes ({', '.join(map(repr, sorted(extra)))}), which are not read: "
            "a file written from it does not have them", path)), NotCarriedWarning, stacklevel=3)


class NonUnitKeyWarning(UserWarning):
    """Keys whose norm differs from 1 by more than their written precision explains (they are normalised)."""


def check_unit(keys, path, where, decimals=None, per_key=None):
    """Warn once, naming the first such key, if keys are further from unit norm than their text explains.

    Values written with `decimals` decimals are each within ``0.5 * 10**-decimals``
    of what was meant, so the norm of a unit quaternion so written is within
    ``10**-decimals`` of 1.  Without `decimals` (binary floats, or text that
    reads back exactly) ``1e-6`` is allowed, as for 6 decimals: keys stored
    from such text, or normalised in float32, do not warn.  `per_key`, called
    only when some key is off by more than `decimals` explain, returns the
    decimals of each key (the most of its four values; shape ``keys.shape[:-1]``
    flattened to (K, tracks)), for files whose keys have different precisions.
    `where(i, j)` names row `i`, flat track `j` as for `check_numbers`.
    """
    flat = keys.reshape(len(keys), -1, 4)
    eps = np.finfo(keys.dtype if keys.dtype.kind == "f" else np.float64).eps
    off = np.abs(np.sqrt(np.einsum("...i,...i->...", flat, flat)) - 1)
    allowed = 8 * eps + (1e-6 if decimals is None else 10.0 ** -decimals)
    bad = off > allowed
    if bad.any() and per_key is not None:
        digits = per_key()
        if digits is not None:
            allowed = 8 * eps + 10.0 ** -np.asarray(digits, np.float64)
            bad = off > allowed
    if bad.any():
        i, j = np.unravel_index(np.argmax(bad), bad.shape)
        line, at = where(int(i), int(j))
        count = int(bad.sum())
        limit = float(np.broadcast_to(allowed, bad.shape)[i, j])
        explained = "its decimals explain" if decimals is not None else "is allowed without decimals"
        warnings.warn(str(FormatError(
            f"{at}key of norm {float(np.linalg.norm(flat[i, j])):.9g} is normalised "
            f"({count} key{'s' if count != 1 else ''} in all further from norm 1 than {explained}: {limit:.2g})",
            path, line)), NonUnitKeyWarning, stacklevel=3)


def check_arrays(times, keys, path):
    """`check_numbers` and `check_unit` for keyframes stored as arrays (NPZ, Zarr): messages name the
    index, ``times[3]`` or ``keys[3, 1]``, and the norm allowed is that of binary floats."""
    batch = keys.shape[1:-1]

    def where(i, j):
        if j is None:
            return None, f"times[{i}]: "
        return None, "keys[" + ", ".join(map(str, (i,) + np.unravel_index(j, batch))) + "]: "

    check_numbers(times, keys, path, where)
    check_unit(keys, path, where)


def check_query(times, t, extrapolate):
    """At least two keys, and with ``extrapolate="raise"`` every query time within the keys."""
    if len(times) < 2:
        raise ValueError(f"need at least 2 keyframes to interpolate, got {len(times)}")
    if extrapolate == "raise" and len(t) and (t.min() < times[0] or t.max() > times[-1]):
        bad = t[(t < times[0]) | (t > times[-1])][0]
        raise ValueError(f"query time {float(bad)!r} is outside the key times [{float(times[0])!r}, "
                         f"{float(times[-1])!r}]; to sample there, extrapolate with "
                         f"{option('extrapolate', 'clamp', 'extend')}")


def check_size(frames, per_frame, what):
    """Refuse, before allocating, an output of more than `MAX_VALUES` values."""
    if frames * per_frame > MAX_VALUES:
        raise ValueError(f"{what} asks for {frames:,} frames of {per_frame} values "
                         f"({frames * per_frame * 8 / 2**30:,.1f} GiB as float64); the limit is "
                         f"{MAX_VALUES:,} values ({MAX_VALUES * 8 // 2**30} GiB)")


# --------------------------------------------------------------------------- reading

def data_lines(path, skip, delimiter):
    """Yield ``(line_number, text)`` of the data lines after the first `skip`.

    As in `numpy.loadtxt`, empty lines are skipped, and so are lines of only
    whitespace when the delimiter is whitespace (`delimiter` None).
    """
    with open(path, encoding="utf-8-sig", errors="surrogateescape") as f:
        for number, text in enumerate(f, 1):
            text = text.rstrip("\r\n")
            if number > skip and (text if delimiter else text.strip()):
                yield number, text


def row_line(path, skip, row, delimiter):
    """File line number of data row `row` (counted as `data_lines` does)."""
    for i, (number, _) in enumerate(data_lines(path, skip, delimiter)):
        if i == row:
            return number
    return None


def _diagnose(path, skip, ncols, delimiter, names=None, what="values"):
    """Find the first line after `skip` with the wrong count or a non-number; raise."""
    for number, text in data_lines(path, skip, delimiter):
        cells = text.split(delimiter)
        if len(cells) != ncols:
            raise FormatError(f"expected {ncols} {what}, got {len(cells)}", path, number)
        for k, cell in enumerate(cells):
            try:
                float(cell)
            except ValueError:
                col = f" in column {echo(names[k])}" if names else f" (value {k + 1})"
                hint = " (decimal commas are not supported: write 0.5, not 0,5)" if (
                    delimiter == ";" and "," in cell) else ""
                raise FormatError(f"non-numeric value {echo(cell.strip())}{col}{hint}", path, number) from None


def load_table(path, skip, ncols, delimiter, names=None, what="values"):
    """Parse the numbers after line `skip` into (rows, ncols) float64, naming bad lines."""
    try:
        with warnings.catch_warnings(), contextlib.ExitStack() as stack:
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            try:
                rows = np.loadtxt(path, dtype=np.float64, delimiter=delimiter, skiprows=skip,
                                  ndmin=2, comments=None, encoding="utf-8-sig")
            except UnicodeDecodeError:   # bytes that are not UTF-8: the line with them is named below
                f = stack.enter_context(open(path, encoding="utf-8-sig", errors="surrogateescape"))
                rows = np.loadtxt(f, dtype=np.float64, delimiter=delimiter, skiprows=skip,
                                  ndmin=2, comments=None)
    except FileNotFoundError:   # numpy says "x not found.": the one style, "x: No such file or directory"
        raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), os.fspath(path)) from None
    except ValueError as exc:
        error = str(exc)
    else:
        if not rows.size:
            return np.empty((0, ncols))
        if rows.shape[1] == ncols:
            return rows
        error = f"expected {ncols} {what}, got {rows.shape[1]}"
    _diagnose(path, skip, ncols, delimiter, names, what)
    raise FormatError(error if len(error) <= 200 else error[:190] + "...", path)
