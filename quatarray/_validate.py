"""Argument checking shared by every module.

Messages name the argument, what was expected and what came, e.g.
``expected quat of shape (..., 4), got (5, 3)``.
"""

import numpy as np

__all__ = ["float_array", "real_array", "finite", "batch_shape", "in_memory", "batch_axis"]


def in_memory(x, name):
    """Raise `TypeError` for a Dask array (or other Dask collection), which NumPy would compute silently.

    Detected by the type's module, so Dask is never imported here.

    >>> in_memory([1.0], "t")
    [1.0]
    """
    if type(x).__module__.split(".")[0] == "dask":
        raise TypeError(f"expected {name} in memory (array_like), got a Dask {type(x).__name__}; "
                        f"use quatarray.dask for Dask arrays (same names, lazy results)")
    return x

def float_array(x, name, last=None, dtype=None):
    """Return `x` as a float32 or float64 ndarray (never copied if already one).

    float32 and float64 are kept; bool and integer input become float64;
    complex, object, string and other input raise `TypeError`.  With `last`,
    the length of the last axis is checked (`ValueError` otherwise).

    Examples
    --------
    >>> float_array([[1, 0, 0, 0]], "quat", last=4).dtype
    dtype('float64')
    >>> float_array([1, 2, 3], "quat", last=4)
    Traceback (most recent call last):
    ...
    ValueError: expected quat of shape (..., 4), got (3,)
    """
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
    if kind == "f":
        if a.dtype.itemsize not in (4, 8):
            a = a.astype(np.float64)
    elif kind in "biu":
        a = a.astype(np.float64)
    else:
        raise TypeError(f"expected {name} of real numbers (float, int or bool), got dtype {a.dtype}")
    if dtype is not None and a.dtype != dtype:
        a = a.astype(dtype)
    if last is not None and (a.ndim == 0 or a.shape[-1] != last):
        raise ValueError(f"expected {name} of shape (..., {last}), got {a.shape}")
    return a


def real_array(x, name):
    """Return `x` as a real ndarray (float32/float64 kept, ints and bools as float64).

    Used for interpolation parameters and exponents.

    >>> real_array(0.5, "t").dtype
    dtype('float64')
    """
    return float_array(x, name)


def finite(a, name):
    """Raise `ValueError` unless every element of `a` is finite.

    >>> finite(np.array([1.0, np.nan]), "times")
    Traceback (most recent call last):
    ...
    ValueError: expected finite values in times, got nan or inf
    """
    if not np.isfinite(a).all():
        raise ValueError(f"expected finite values in {name}, got nan or inf")
    return a


def batch_shape(num, shape):
    """scipy's `num` / `shape` arguments as a batch shape: ``(num,)``, `shape`, or ``()``.

    >>> batch_shape(3, None), batch_shape(None, (2, 5)), batch_shape(None, None)
    ((3,), (2, 5), ())
    """
    if num is not None and shape is not None:
        raise ValueError("Only one of `num` or `shape` can be specified: expected num or shape, got both")
    if num is not None:
        if not isinstance(num, (int, np.integer)) or num < 0:
            raise ValueError(f"expected num to be a non-negative int, got {num!r}")
        return (int(num),)
    if shape is None:
        return ()
    if isinstance(shape, (int, np.integer)):
        shape = (shape,)
    if not isinstance(shape, tuple) or any(not isinstance(n, (int, np.integer)) or n < 0 for n in shape):
        raise ValueError(f"`shape` must be an int or a tuple of ints or None: expected a tuple of "
                         f"non-negative ints, got {shape!r}")
    return tuple(int(n) for n in shape)


def batch_axis(axis, batch, name="q"):
    """`axis` as an index into the batch shape `batch` of `name` (negative counts from the end).

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
