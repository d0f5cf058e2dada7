"""NPZ keyframe archives: arrays ``times`` (K,), ``keys`` (K, *batch, 4) scalar-first, optional ``names``."""

import contextlib
import os
import zipfile

import numpy as np

from .._validate import float_array
from .atomic import atomic_write
from .keyframes import Keyframes
from .text import FormatError, check_arrays, not_carried

__all__ = ["read_npz", "write_npz"]

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

    Warns
    -----
    NonUnitKeyWarning
        Once per file, naming the first key whose norm differs from 1 by more
        than ``1e-6`` (what 6 decimals would explain).

    Examples
    --------
    >>> import numpy as np
    >>> import io
    >>> from quatarray.formats import read_npz
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
        except (ValueError, OSError, EOFError, zipfile.BadZipFile):   # numpy's own message would offer pickle
            raise FormatError("not an NPZ archive of arrays (numpy.savez writes them)", name) from None
        if not isinstance(archive, np.lib.npyio.NpzFile):
            raise FormatError("not an NPZ archive of arrays (a single .npy array)", name)
        stack.enter_context(archive)
        missing = [a for a in ("times", "keys") if a not in archive.files]
        if missing:
            raise FormatError(f"missing array {missing[0]!r} (found {', '.join(archive.files) or 'none'})", name)
        not_carried("arrays", set(archive.files) - {"times", "keys", "names"}, name)
        arrays = {}
        for a in ("times", "keys", "names"):
            if a not in archive.files:
                continue
            try:
                arrays[a] = archive[a]
            except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
                if "allow_pickle" in str(exc):   # numpy's message would offer pickle
                    raise FormatError(f"array {a!r} holds pickled Python objects; expected numbers (an NPZ "
                                      "archive of arrays, as numpy.savez writes them)", name) from None
                raise FormatError(f"array {a!r} is unreadable ({exc})", name) from None
        times, keys, names = arrays["times"], arrays["keys"], arrays.get("names")
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
    check_arrays(times, keys, name)
    return Keyframes(times, keys, names)


def write_npz(path, keyframes):
    """Write ``times``, ``keys`` (scalar-first) and the track ``names`` to an NPZ archive, atomically.

    ``names`` is left out when ``keyframes.names`` is None.

    Examples
    --------
    >>> import numpy as np
    >>> import os, tempfile
    >>> from quatarray.formats import Keyframes, read_npz, write_npz
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

