"""Argument checking shared by every module.

Messages name the argument, what was expected and what came, e.g.
``expected quat of shape (..., 4), got (5, 3)``.
"""

import math
import numbers

import numpy as np

__all__ = ["float_array", "quat_array", "all_finite", "finite", "batch_shape", "in_memory", "batch_axis", "key_times"]

_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))


def in_memory(x, name):
    """Raise `TypeError` for a Dask array (or other Dask collection), which NumPy would compute silently.

    Detected by the type's module, so Dask is never imported here.

    >>> from quatarray._validate import in_memory
    >>> in_memory([1.0], "t")
    [1.0]
    """
    if type(x).__module__.split(".")[0] == "dask":
        raise TypeError(f"expected {name} in memory (array_like), got a Dask {type(x).__name__}; "
                        f"use quatarray.dask for Dask arrays (same names, lazy results)")
    return x


def float_array(x, name, last=None, dtype=None):
    """Return `x` as a float32 or float64 ndarray (never copied if already one).

    float32 and float64 are kept; bool, integer and object input holding real numbers
    (Decimal, Fraction) become float64; complex, string and other input raise `TypeError`.  With `last`,
    the length of the last axis is checked (`ValueError` otherwise).

    Examples
    --------
    >>> from quatarray._validate import float_array
    >>> float_array([[1, 0, 0, 0]], "quat", last=4).dtype
    dtype('float64')
    >>> float_array([1, 2, 3], "quat", last=4)
    Traceback (most recent call last):
    ...
    ValueError: expected quat of shape (..., 4), got (3,)
    """
    if (type(x) is np.ndarray and dtype is None and (x.dtype is _FLOATS[1] or x.dtype is _FLOATS[0])
            and (last is None or x.shape[-1:] == (last,))):
        return x   # the common case at once (`is`: NumPy's native float dtypes), cheaper than the checks below
    if dtype is not None:
        dtype = np.dtype(dtype)
        if dtype not in (np.float32, np.float64):
            raise TypeError(f"expected dtype float32 or float64 for {name}, got {dtype}")
    if isinstance(x, np.ndarray):
        a = x.view(np.ndarray) if type(x) is not np.ndarray else x
    else:
        in_memory(x, name)
        try:
            a = np.asarray(x)
        except (ValueError, TypeError) as exc:
            raise ValueError(f"expected {name} to be array_like of real numbers, got {type(x).__name__} ({exc})") from None
    kind = a.dtype.kind
    if not a.dtype.isnative:   # big-endian input on a little-endian machine: the same values, native
        a = a.astype(a.dtype.newbyteorder("="))
    if kind == "f":
        if a.dtype.itemsize not in (4, 8):
            a = a.astype(np.float64)
    elif kind in "biu":
        a = a.astype(np.float64)
    elif kind == "O":   # Python numbers, Decimal, Fraction (a pandas object column): as float64, as scipy
        odd = next((v for v in a.flat if not _real_number(v)), a)
        if odd is not a:
            raise TypeError(f"expected {name} of real numbers, got an object array holding {type(odd).__name__}")
        a = a.astype(np.float64)
    else:
        raise TypeError(f"expected {name} of real numbers (float, int or bool), got dtype {a.dtype}")
    if dtype is not None and a.dtype != dtype:
        a = a.astype(dtype)
    if last is not None and (a.ndim == 0 or a.shape[-1] != last):
        raise ValueError(f"expected {name} of shape (..., {last}), got {a.shape}")
    return a


def _real_number(v):
    """Whether `v` is a real number: int, float, Fraction, Decimal (registered as a Number
    only), NumPy's scalars and bool; not None, str or complex."""
    return isinstance(v, numbers.Real) or (isinstance(v, numbers.Number) and not isinstance(v, numbers.Complex))


def quat_array(x, name):
    """`float_array` of shape (..., 4): quaternions (any batch shape).

    >>> from quatarray._validate import quat_array
    >>> quat_array([1, 0, 0, 0], "q")
    array([1., 0., 0., 0.])

    A plain float32 / float64 ndarray of that shape is returned at once (what
    `float_array` would return, without its checks: they cost more than the
    maths of one rotation).  Finiteness and magnitude are the callers' kernels'
    business (`_scale.guard`).
    """
    if type(x) is np.ndarray and x.dtype in _FLOATS and x.shape[-1:] == (4,):
        return x
    return float_array(x, name, last=4)


def all_finite(a):
    """True when every element of `a` is finite (no nan, no ±inf), cheaply.

    A few elements (up to 96): a sum of Python floats; small arrays: `np.isfinite`;
    large ones: one sum (a finite sum means finite elements; a sum that is
    not finite is then checked element by element).  A long float32 array is
    summed as rows of `_SUM_ROW` added to each other (NumPy's SIMD add; its
    float32 ``add.reduce`` over the whole array costs about as much per
    element as float64's, twice as much per byte).

    >>> import numpy as np
    >>> from quatarray._validate import all_finite
    >>> all_finite(np.array([1.0, 2.0])), all_finite(np.array([1.0, np.inf]))
    (True, False)
    """
    if not isinstance(a, np.ndarray):
        a = np.asarray(a)
    size = a.size
    if size <= 96:   # a few: one Python sum (a finite sum means finite elements)
        return math.isfinite(sum(a.ravel().tolist())) or bool(np.isfinite(a).all())
    if size <= 4096:
        return bool(np.isfinite(a).all())
    with np.errstate(over="ignore", invalid="ignore"):
        if a.dtype == np.float32 and a.flags.c_contiguous:
            flat = a.reshape(-1)
            whole = size - size % _SUM_ROW
            total = np.add.reduce(flat[:whole].reshape(-1, _SUM_ROW), axis=0).sum() + flat[whole:].sum()
        else:
            total = np.add.reduce(a, axis=None)
    return bool(np.isfinite(total)) or bool(np.isfinite(a).all())


#: Row length of `all_finite`'s float32 sum (a row's partial sums stay in L1).
_SUM_ROW = 1024


def finite(a, name):
    """Raise `ValueError` unless every element of `a` is finite (the API's
    policy for NaN and infinite input); returns `a`.

    Cheap in the common case (`all_finite`); the first offending element
    is looked for only when there is one.

    >>> import numpy as np
    >>> from quatarray._validate import finite
    >>> finite(np.array([[1.0, 2.0], [np.nan, 0.0]]), "times")
    Traceback (most recent call last):
    ...
    ValueError: expected finite values in times, got nan or inf at index (1, 0)
    """
    if all_finite(a):
        return a
    bad = ~np.isfinite(a)
    if bad.any():
        where = np.unravel_index(int(np.argmax(bad)), np.shape(a))
        at = f" at index {tuple(int(i) for i in where)}" if where else ""
        raise ValueError(f"expected finite values in {name}, got nan or inf{at}")
    return a


def batch_shape(num, shape, joined="or"):
    """scipy's `num` / `shape` arguments as a batch shape: ``(num,)``, `shape`, or ``()``.
    `joined`: the word scipy's message joins the two with when both are given (``'or'`` in
    Rotation's, ``'and'`` in RigidTransform's).

    >>> from quatarray._validate import batch_shape
    >>> batch_shape(3, None), batch_shape(None, (2, 5)), batch_shape(None, None)
    ((3,), (2, 5), ())
    """
    if num is not None and shape is not None:
        raise ValueError(f"Only one of `num` {joined} `shape` can be specified: expected num or shape, got both")
    if num is not None:
        if not isinstance(num, (int, np.integer)):
            # scipy's type error (its `num` is a typed int argument), with our wording's what-came
            raise TypeError(f"Argument 'num' has incorrect type (expected int, got {type(num).__name__})")
        if num < 0:
            raise ValueError(f"expected num to be a non-negative int, got {num!r}")
        return (int(num),)
    if shape is None:
        return ()
    if isinstance(shape, (int, np.integer)):
        shape = (shape,)
    if not isinstance(shape, tuple):
        raise ValueError(f"`shape` must be an int or a tuple of ints or None, got {shape!r}")
    if any(isinstance(n, bool) or not isinstance(n, (int, np.integer)) for n in shape):   # as scipy: a type
        raise TypeError(f"expected `shape` a tuple of ints, got {shape!r}")
    if any(n < 0 for n in shape):
        raise ValueError(f"expected `shape` of non-negative ints, got {shape!r}")
    return tuple(int(n) for n in shape)


def batch_axis(axis, batch, name="q"):
    """`axis` as an index into the batch shape `batch` of `name` (negative counts from the end).

    >>> from quatarray._validate import batch_axis
    >>> batch_axis(-1, (5, 3))
    1
    """
    nb = len(batch)
    if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)):
        raise TypeError(f"expected axis to be an int (a batch axis), got {type(axis).__name__}")
    if not -nb <= axis < nb:
        raise ValueError(f"expected axis in [{-nb}, {nb - 1}] (a batch axis of {name} with batch shape "
                         f"{tuple(batch)}), got {axis}")
    return int(axis) % nb


def key_times(times, K, name="times", keys_name="keys"):
    """`times` as float64 of shape (K,), finite and strictly increasing (`ValueError` otherwise).

    >>> from quatarray._validate import key_times
    >>> key_times([0, 2, 1], 3)
    Traceback (most recent call last):
    ...
    ValueError: expected times in strictly increasing order, got times[2] = 1.0 after times[1] = 2.0
    """
    times = float_array(times, name, dtype=np.float64)
    if times.ndim != 1:
        raise ValueError(f"expected {name} of shape (K,) (a 1 dimensional array), got {times.shape}")
    if times.shape[0] != K:
        raise ValueError(f"expected as many {name} as {keys_name} (number of rotations equal to number "
                         f"of timestamps), got {times.shape[0]} {name} and {K} {keys_name}")
    finite(times, name)
    bad = np.flatnonzero(np.diff(times) <= 0)
    if bad.size:
        j = int(bad[0])
        raise ValueError(f"expected {name} in strictly increasing order, got "
                         f"{name}[{j + 1}] = {float(times[j + 1])!r} after {name}[{j}] = {float(times[j])!r}")
    return times


def integer(value, name, least):
    """`value` as an int if it is an integer (not a bool) of at least `least`: a TypeError
    naming `name` for another type, a ValueError for a smaller one.

    >>> from quatarray._validate import integer
    >>> integer(3, "points", 2)
    3
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"expected {name} to be an int >= {least}, got {value!r}")
    if value < least:
        raise ValueError(f"expected {name} to be an int >= {least}, got {value!r}")
    return int(value)


def choice(value, name, options):
    """`value` if it is one of the strings `options`, else a ValueError naming `name`.

    >>> from quatarray._validate import choice
    >>> choice("slerp", "method", ("slerp", "squad"))
    'slerp'
    """
    if not isinstance(value, str) or value not in options:
        raise ValueError(f"expected {name} in {options}, got {value!r}")
    return value
