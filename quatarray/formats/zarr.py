"""Zarr stores: resampled chunk by chunk with Dask, or read and written whole, through zarr's public API.

A store is a Zarr group holding ``times`` (K,) and ``keys`` (K, *batch, 4),
scalar-first, like the NPZ layout, and optionally the track names in the
group attribute ``names`` (one per flattened batch index).  It may be
anything zarr opens: a local path, or a URL (``memory://``, ``s3://``,
``gs://``, any fsspec protocol) with ``storage_options`` for its filesystem
(credentials, endpoint).  A URL's empty path segments are dropped, as a
local path's are: ``s3://bkt//run.zarr`` is ``s3://bkt/run.zarr``.

`resample_zarr` (Zarr → Zarr) reads the keys into memory when small (one
`Track` for every chunk of queries), else keeps them as a Dask array
chunked along the tracks.  Query times come from ``fps`` (generated
lazily, a frame within rounding of a key time put on it, as `fps_times`
does) or a times file (a Zarr store or array holding ``times``, read
chunk by chunk, or a text file).  With the keys in memory, a query at a
key time gives the key as stored (`keys_at_key_times`), as the in-memory
formats do: a store resampled at its own times comes back as it is.  Keys
kept as a Dask array (beyond `MEMORY_KEYS`) give the curve there, which is
the key normalised (within an ulp of a unit key).

Converting to or from the in-memory formats (CSV, NPZ) goes through
`read_zarr` and `write_zarr`: the whole track is in memory then, as those
formats need it anyway, and a store of more than
``quatarray.formats.text.MAX_VALUES`` values is refused before it is read.
`write_zarr` writes the same chunks, through the same atomic steps, as
`resample_zarr`.

Chunks are read with `zarr.open_group` and `dask.array.from_array` and
written by `dask.array.store` into arrays made by zarr's ``create_array``:
zarr alone knows its byte layout.  The queries are computed a window of
`WINDOW_CHUNKS` chunks at a time, so the task graph (and memory) stays
bounded whatever the number of queries.

The output appears only when complete:

* on a local disk, it is written into a temporary directory beside the
  target and renamed onto it;
* an object store has no rename, so it is written under a temporary
  prefix beside the target, whose objects are then copied (a server-side
  copy on S3 and GCS: no data goes through the client) under the target,
  the chunks first and the ``zarr.json`` metadata last, the group's own
  last of all, and the temporary prefix is removed.  A reader sees no
  group until its metadata arrives, after every chunk.  Copying costs a
  second write on the server; writing the metadata last in place would
  not, but zarr's public API writes an array's metadata when it is
  created, and a half-written array would be readable (as fill values)
  meanwhile.

Replacing an existing store needs ``force`` (a file where the store
should be is never replaced); on an object store the old store is removed
first (its metadata first, so that it never looks half-present).
`resample_zarr` never replaces its input store (or its store of times),
even with ``force``: it reads them chunk by chunk while it writes, and
neither way of replacing is atomic for a store that is still being read.
`write_zarr` takes keyframes in memory, so with ``force`` it may replace
the store they were read from (``quatarray reduce in.zarr -o in.zarr``).
"""

import contextlib
import errno
import os
import shutil
import sys
import tempfile
import uuid
from functools import partial

import numpy as np

from .._validate import float_array
from .keyframes import Keyframes, fps_steps, keys_at_key_times, read_times, snap_to_keys
from .text import (FormatError, check_arrays, check_query, check_size, echo, not_a_store, not_carried,
                   one_below_other, read_while_written, refuse_existing)

__all__ = ["read_zarr", "write_zarr", "resample_zarr", "read_store", "read_times_zarr", "is_zarr"]

#: Quaternions per output chunk: 2**21 of them are 32 MiB in float32.
CHUNK_QUATS = 1 << 21

#: Keys up to this size are read into memory and interpolated by one Track.
MEMORY_KEYS = 64 << 20

#: Output chunks per Dask computation: one window's graph is built, computed and dropped before
#: the next, so memory does not grow with the number of queries (10**12 would be 477,000 chunks).
WINDOW_CHUNKS = 512


def _need():
    """Import the optional dependencies of Zarr stores, or say how to install them."""
    try:
        import dask.array  # noqa: F401
        import fsspec  # noqa: F401
        import zarr  # noqa: F401
    except ImportError as exc:
        raise ImportError(f"Zarr stores need the optional dependencies dask[array] and zarr ({exc}): "
                          "pip install 'quatarray[dask]'") from None


def is_zarr(path):
    """True if `path` names a Zarr store (a ``.zarr`` suffix, local path or URL)."""
    return os.fspath(path).rstrip("/\\").lower().endswith(".zarr")


# --------------------------------------------------------------------------- where a store is

class _Location:
    """A store given by the user: a local path, or a URL and its filesystem's options."""

    def __init__(self, store, storage_options):
        import fsspec
        self.name = os.fspath(store)
        self.url = "://" in self.name or "::" in self.name
        self.options = dict(storage_options or {}) if self.url else None
        if self.url:
            try:
                self.fs, self.path = fsspec.core.url_to_fs(self.name, **self.options)
            except TypeError as exc:   # an option the filesystem does not take
                raise self._bad_options(exc) from None
            self.path = _object_path(self.fs, self.path)
            self.local = "file" in np.atleast_1d(self.fs.protocol)
        else:
            self.fs, self.path, self.local = None, os.path.abspath(self.name), True
        if self.local and self.url:
            self.path = os.path.abspath(self.path)

    def key(self):
        """What two locations of the same store have in common."""
        if self.local:
            return ("file", os.path.realpath(self.path))
        return (tuple(np.atleast_1d(self.fs.protocol)), self.path)

    def exists(self):
        if self.local:
            return os.path.lexists(self.path)
        try:
            return self.fs.exists(self.path)
        except TypeError as exc:   # an option the filesystem takes only when it connects (s3fs)
            raise self._bad_options(exc) from None

    def _bad_options(self, exc):
        return ValueError(f"storage options {sorted(self.options)} do not fit {self.name}'s filesystem ({exc})")

    def nests(self, other):
        """Whether this store and `other` are two places one inside the other (on one filesystem)."""
        (kind, a), (other_kind, b) = self.key(), other.key()
        return kind == other_kind and one_below_other(a, b, os.sep if kind == "file" else "/")

    def is_folder(self):
        """Whether what is at this location is a folder (on an object store: a prefix, not an
        object): what `force` may replace by a store, where a file never is."""
        return os.path.isdir(self.path) if self.local else not self.fs.isfile(self.path)

    def store(self, path=None):
        """Arguments of `zarr.open_group` for this store (or for `path` on its filesystem)."""
        path = self.path if path is None else path
        if self.local:
            return {"store": path}
        return {"store": self.fs.unstrip_protocol(path), "storage_options": self.options}


def _object_path(fs, path):
    """`path` on object store `fs` in one form: no empty segments (``//``) and no trailing ``/``, as a
    local path has none.  Zarr writes the literal keys of ``s3://bkt//out.zarr`` (``/out.zarr/...``),
    but s3fs lists and removes ``bkt//out.zarr`` as ``bkt/out.zarr``
    (https://github.com/fsspec/s3fs/issues/770): the temporary objects of such a store could not be
    found again, and a store checked for, replaced or compared was another one.  Paths that are URLs
    themselves (HTTP) are kept as they are."""
    if "://" in path:
        return path.rstrip("/")
    return fs.root_marker + "/".join(part for part in path.split("/") if part)


def _locations(storage_options, **stores):
    """`_Location` of each named store; `storage_options` must apply to at least one URL."""
    found = {k: _Location(v, storage_options) for k, v in stores.items() if v is not None}
    if storage_options and not any(loc.url for loc in found.values()):
        raise ValueError("expected a store URL (such as s3://bucket/out.zarr or memory://out.zarr) for "
                         f"storage_options to apply to, got the local paths {', '.join(loc.name for loc in found.values())}")
    return found


# --------------------------------------------------------------------------- reading

def _open_group(loc, what):
    import zarr

    try:
        return zarr.open_group(mode="r", **loc.store())
    except Exception as exc:  # noqa: BLE001 - zarr raises several unrelated types
        if not loc.exists():
            raise FileNotFoundError(errno.ENOENT, "No such file or directory", loc.name) from None
        raise FormatError(f"not a Zarr group with {what} ({_reason(exc)})", loc.name) from None


def _reason(exc):
    """Why zarr could not read something, in words."""
    import json
    if isinstance(exc, json.JSONDecodeError):
        return f"its metadata (zarr.json) is not valid JSON: {exc}"
    return f"{type(exc).__name__}: {exc}"


def _node(group, name, loc):
    """Array `name` of `group`, real-valued, or a `FormatError` saying what is there instead."""
    import zarr

    try:
        if name not in group:
            found = ", ".join(sorted(group.array_keys())) or "none"
            raise FormatError(f"missing array {name!r} (found arrays: {found})", loc.name)
        node = group[name]
    except FormatError:
        raise
    except Exception as exc:  # noqa: BLE001 - a corrupt zarr.json below the group
        raise FormatError(f"cannot open array {name!r}: {_reason(exc)}", loc.name) from None
    if not isinstance(node, zarr.Array):
        raise FormatError(f"expected {name!r} to be an array, got a {type(node).__name__.lower()}", loc.name)
    if np.dtype(node.dtype).kind not in "biuf":
        raise FormatError(f"expected {name!r} of real numbers, got dtype {node.dtype}", loc.name)
    return node


class _Chunks:
    """Rows ``start:stop`` of a zarr array, for `dask.array.from_array`; a chunk zarr cannot
    decode raises a `FormatError` naming the store, the array and the rows."""

    def __init__(self, array, name, where, start=0, stop=None):
        self.array, self.name, self.where = array, name, where
        self.start = start
        stop = array.shape[0] if stop is None else stop
        self.shape = (stop - start,) + tuple(array.shape[1:])
        self.dtype = np.dtype(array.dtype)
        self.ndim = len(self.shape)

    def __getitem__(self, key):
        key = key if isinstance(key, tuple) else (key,)
        first = key[0] if key else slice(None)
        if isinstance(first, slice):
            lo, hi, step = first.indices(self.shape[0])
            first = slice(self.start + lo, self.start + hi, step)
        key = (first,) + key[1:]
        try:
            return self.array[key]
        except Exception as exc:  # noqa: BLE001 - codecs raise RuntimeError, ValueError, ...
            raise FormatError(f"cannot read array {self.name!r} at {key}: {type(exc).__name__}: {exc}",
                              self.where) from None


def _dask(array, name, where, chunks=None, start=0, stop=None):
    import dask.array as da
    source = _Chunks(array, name, where, start, stop)
    return da.from_array(source, chunks=chunks or array.chunks, asarray=True, fancy=False, lock=False,
                         meta=np.empty((0,) * source.ndim, source.dtype))


def read_store(path, *, storage_options=None):
    """``(times, keys)`` of a Zarr store: times in memory, keys a Dask array.

    Parameters
    ----------
    path : str or os.PathLike
        A local path or a URL zarr opens (``memory://``, ``s3://``, ...).
    storage_options : dict, optional
        Options of the URL's filesystem (fsspec), e.g. credentials.

    Examples
    --------
    >>> import numpy as np, zarr
    >>> from quatarray.formats.zarr import read_store
    >>> g = zarr.open_group("memory://doc-read.zarr", mode="w")
    >>> g["times"] = np.array([0.0, 1.0]); g["keys"] = np.eye(4)[:2]
    >>> times, keys = read_store("memory://doc-read.zarr")
    >>> times, keys.shape
    (array([0., 1.]), (2, 4))
    """
    _need()
    times, keys, _ = _read(_Location(path, storage_options))
    return times, keys


def _open(loc):
    """``(times in memory, the zarr array of keys, track names or None)`` of the store at `loc`, the
    shapes checked."""
    group = _open_group(loc, "arrays 'times' and 'keys'")
    times = _node(group, "times", loc)
    keys = _node(group, "keys", loc)
    times = np.asarray(_Chunks(times, "times", loc.name)[...], np.float64)
    if times.ndim != 1 or not len(times):
        raise FormatError(f"expected times of shape (K,) with K >= 1, got {times.shape}", loc.name)
    if keys.ndim < 2 or keys.shape[0] != len(times) or keys.shape[-1] != 4:
        raise FormatError(f"expected keys of shape ({len(times)}, ..., 4) to match times, got {keys.shape}",
                          loc.name)
    not_carried("arrays or groups", set(group.keys()) - {"times", "keys"}, loc.name)
    not_carried("attributes", set(group.attrs.keys()) - {"names"}, loc.name)
    names = group.attrs.get("names")
    count = int(np.prod(keys.shape[1:-1]))
    if names is not None:
        if not (isinstance(names, list) and len(names) == count and all(isinstance(n, str) for n in names)):
            raise FormatError(f"expected the attribute 'names' to be a list of {count} strings, one per track, "
                              f"got {echo(names)}", loc.name)
        names = tuple(names)
    return times, keys, names


def _read(loc):
    """``(times, keys as a Dask array, track names or None)`` of the store at `loc`."""
    times, keys, names = _open(loc)
    return times, _dask(keys, "keys", loc.name), names


def read_zarr(path, *, storage_options=None):
    """Read the keyframes of a Zarr store into memory.

    The whole store is read, as the in-memory formats (CSV, NPZ) need it:
    a store of more than ``quatarray.formats.text.MAX_VALUES`` values is
    refused before it is read (`resample_zarr` resamples such a store into
    another store, chunk by chunk).

    Parameters
    ----------
    path : str or os.PathLike
        A local path or a URL zarr opens (``memory://``, ``s3://``, ...),
        holding ``times`` (K,), ``keys`` (K, *batch, 4) scalar-first, and
        optionally the group attribute ``names`` (one per flattened batch
        index).
    storage_options : dict, optional
        Options of the URL's filesystem (fsspec), e.g. credentials.

    Returns
    -------
    Keyframes
        float32 keys stay float32, integer keys become float64; times are
        float64.

    Raises
    ------
    FormatError
        Not a store of keyframes, a chunk zarr cannot decode, non-finite
        values, times not strictly increasing or a zero quaternion (the
        message names the index).
    ValueError
        A store of more than ``MAX_VALUES`` values.

    Warns
    -----
    NonUnitKeyWarning
        Once per store, as `read_npz`.

    Examples
    --------
    >>> import numpy as np, zarr
    >>> from quatarray.formats import read_zarr
    >>> g = zarr.open_group("memory://doc-read-zarr.zarr", mode="w")
    >>> g["times"] = np.array([0.0, 1.0]); g["keys"] = np.eye(4)[:2]
    >>> read_zarr("memory://doc-read-zarr.zarr").keys
    array([[1., 0., 0., 0.],
           [0., 1., 0., 0.]])
    """
    _need()
    loc = _locations(storage_options, src=path)["src"]
    times, keys, names = _open(loc)
    check_size(len(times), 4 * int(np.prod(keys.shape[1:-1])),
               "reading the store into memory (only .zarr to .zarr is resampled chunk by chunk)")
    keys = float_array(_Chunks(keys, "keys", loc.name)[:], "keys", last=4)   # real numbers: checked by _node
    check_arrays(times, keys, loc.name)
    return Keyframes(times, keys, names)


def _times_node(loc):
    """The zarr array of query times at `loc`: a Zarr array, or a group's array ``times``."""
    import zarr
    try:
        node = zarr.open(mode="r", **loc.store())
    except Exception as exc:  # noqa: BLE001 - zarr raises several unrelated types
        if not loc.exists():
            raise FileNotFoundError(errno.ENOENT, "No such file or directory", loc.name) from None
        raise FormatError(f"not a Zarr array or group of times ({_reason(exc)})", loc.name) from None
    array = _node(node, "times", loc) if isinstance(node, zarr.Group) else node
    if array.ndim != 1 or np.dtype(array.dtype).kind not in "biuf":
        raise FormatError(f"expected times of real numbers, shape (N,), got {array.dtype} {array.shape}", loc.name)
    return array


def read_times_zarr(path, *, storage_options=None):
    """Query times from a Zarr store (or array) holding ``times``, into memory (float64).

    `resample_zarr` reads such a store chunk by chunk; the in-memory
    formats take their query times whole.

    Examples
    --------
    >>> import numpy as np, zarr
    >>> from quatarray.formats.zarr import read_times_zarr
    >>> zarr.open_group("memory://doc-times.zarr", mode="w")["times"] = np.array([0.0, 0.5])
    >>> read_times_zarr("memory://doc-times.zarr")
    array([0. , 0.5])
    """
    _need()
    loc = _locations(storage_options, times=path)["times"]
    array = _times_node(loc)
    check_size(array.shape[0], 1, "reading the query times into memory")
    return np.asarray(_Chunks(array, "times", loc.name)[...], np.float64)


class _Queries:
    """The query times, built a window of rows at a time."""

    def __init__(self, key_times, fps, times, loc):
        self.fps, self.array = fps, None
        if fps is not None:
            self.key_times = np.asarray(key_times, np.float64)
            self.t0, self.t1 = float(key_times[0]), float(key_times[-1])
            self.size = fps_steps(self.t0, self.t1, fps) + 1   # the same count and values as fps_times
            return
        if loc is not None:
            self.array, self.where = _times_node(loc), loc.name
            self.size = self.array.shape[0]
            if not self.size:   # (as an empty file of times; a store of no frames reads back as no track)
                raise FormatError("no times", loc.name)
            return
        self.memory = np.asarray(read_times(times) if isinstance(times, (str, os.PathLike)) else times, np.float64)
        self.size = len(self.memory)

    def window(self, start, stop, rows):
        """Query times ``start:stop`` as a Dask array chunked by `rows`."""
        import dask.array as da
        if self.fps is not None:
            k = da.arange(start, stop, chunks=rows, dtype=np.float64)
            # as `fps_times` (the grid in memory): a frame within rounding of a key is the key's time
            return da.minimum(self.t0 + k / self.fps, self.t1).map_blocks(
                snap_to_keys, onto=self.key_times, t0=self.t0, t1=self.t1, fps=self.fps, dtype=np.float64)
        if self.array is not None:
            return _dask(self.array, "times", self.where, (rows,), start, stop).astype(np.float64)
        return da.from_array(self.memory[start:stop], chunks=rows)


# --------------------------------------------------------------------------- writing

@contextlib.contextmanager
def _atomic(loc, force):
    """Yield the `_Location`-style zarr arguments of a temporary store; move it onto `loc` on success,
    remove it on failure.  OS errors name the user's store, never the temporary one."""
    if loc.exists() and not loc.is_folder():   # never replace a file (an object) by a store
        raise not_a_store(loc.name, "Zarr")
    if loc.local:
        context = _atomic_dir(loc.path, loc.name, force)
    else:
        context = _atomic_prefix(loc, force)
    try:
        with context as store:
            yield store
    except OSError as exc:
        if exc.filename is None or ".part" in os.fspath(exc.filename):
            raise type(exc)(exc.errno, exc.strerror or str(exc), loc.name) from None
        raise


@contextlib.contextmanager
def _atomic_dir(path, name, force):
    """A temporary directory beside `path`, renamed onto `path` on success, removed on failure."""
    folder = os.path.dirname(path)
    if not os.path.isdir(folder):
        raise FileNotFoundError(errno.ENOENT, "No such file or directory (its folder does not exist)", name)
    refuse_existing(os.path.lexists(path), name, force)   # (a file there: refused by `_atomic`)
    tmp = tempfile.mkdtemp(dir=folder, prefix=f".{os.path.basename(path)}.", suffix=".part")
    old = None
    try:
        yield {"store": tmp}
        if os.path.lexists(path):   # a store there: move it aside first, then drop it
            old = tempfile.mkdtemp(dir=folder, prefix=f".{os.path.basename(path)}.", suffix=".old")
            os.replace(path, os.path.join(old, "store"))
        os.replace(tmp, path)
    except BaseException:   # (an interrupt too): the old store back where it was, if it was moved
        if old is not None and not os.path.lexists(path) and os.path.lexists(os.path.join(old, "store")):
            os.replace(os.path.join(old, "store"), path)
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    finally:
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


@contextlib.contextmanager
def _atomic_prefix(loc, force):
    """A temporary prefix beside `loc` on its object store, copied under `loc` on success (the
    metadata last) and removed either way."""
    fs = loc.fs
    refuse_existing(fs.exists(loc.path), loc.name, force)
    parent, _, base = loc.path.rpartition("/")
    tmp = f"{parent}/.{base}.{uuid.uuid4().hex[:8]}.part"
    committing = False
    try:
        yield loc.store(tmp)
        objects = sorted(fs.find(tmp))
        committing = True
        if fs.exists(loc.path):
            _remove(fs, loc.path)
        # chunks, then each array's zarr.json, then the group's: readers see all or nothing
        order = sorted(objects, key=lambda p: (p.endswith("zarr.json"), p == f"{tmp}/zarr.json"))
        data = [p for p in order if not p.endswith("zarr.json")]
        if data:
            fs.copy(data, [loc.path + p[len(tmp):] for p in data])
        for p in order[len(data):]:
            fs.copy(p, loc.path + p[len(tmp):])
    except BaseException as exc:
        if committing:   # the old store may be gone: the new one, complete, is kept where it was written
            exc.add_note(f"quatarray: the complete new store is kept at {fs.unstrip_protocol(tmp)}; "
                         f"{loc.name} may be incomplete (rerun with force)")
        else:
            with contextlib.suppress(FileNotFoundError):
                fs.rm(tmp, recursive=True)
        raise
    with contextlib.suppress(FileNotFoundError):
        fs.rm(tmp, recursive=True)


def _remove(fs, path):
    """Remove a store from an object store, its group metadata first."""
    with contextlib.suppress(FileNotFoundError):
        fs.rm(f"{path}/zarr.json")
    fs.rm(path, recursive=True)


def _space_check(loc, nbytes):
    """Refuse an output that the local disk cannot hold, before any writing (an ENOSPC `OSError`
    naming the output, as a disk that fills while writing gives)."""
    if not loc.local:
        return
    folder = os.path.dirname(loc.path)
    if not os.path.isdir(folder):
        return    # reported by _atomic_dir
    free = shutil.disk_usage(folder).free
    if nbytes > free:
        raise OSError(errno.ENOSPC, f"the output needs {nbytes / 1e9:.3g} GB, and its disk has "
                      f"{free / 1e9:.3g} GB free (try a lower --fps or fewer --times)", loc.name)


def _rows(batch):
    """Frames per chunk of a store with tracks `batch`: `CHUNK_QUATS` quaternions."""
    return max(1, CHUNK_QUATS // max(1, int(np.prod(batch))))


def _create(store, n, batch, dtype, names):
    """Create the group of a store of `n` frames in `store` (`_Location.store` arguments): its arrays
    ``times`` and ``keys``, chunked by `_rows`, and its ``names`` attribute (unless None)."""
    import zarr
    from zarr.codecs import BloscCodec

    rows = _rows(batch)
    group = zarr.open_group(mode="w", **store)
    if names is not None:
        group.attrs["names"] = list(names)
    # quaternions are float noise to a compressor (zstd saves ~10% of the bytes and costs
    # ~40% of the throughput): stored raw; times compress well with a byte shuffle, and
    # LZ4 does it at memory speed
    times = group.create_array("times", shape=(n,), chunks=(rows,), dtype=np.float64,
                               compressors=BloscCodec(cname="lz4", clevel=1, shuffle="shuffle"))
    keys = group.create_array("keys", shape=(n,) + batch + (4,), chunks=(rows,) + batch + (4,), dtype=dtype,
                              compressors=None)
    return times, keys


def write_zarr(path, keyframes, *, force=False, storage_options=None):
    """Write keyframes to a Zarr store, atomically.

    The store holds ``times``, ``keys`` (scalar-first, in chunks of about
    2**21 quaternions, as `resample_zarr` writes them) and, unless
    ``keyframes.names`` is None, the group attribute ``names``.  It appears
    only when complete (see the module's notes on local disks and object
    stores).

    Parameters
    ----------
    path : str or os.PathLike
        A local path or a URL zarr opens (``memory://``, ``s3://``, ...).
    keyframes : Keyframes
        ``keys`` of shape (K, *batch, 4), float32 or float64.
    force : bool, default False
        Replace an existing store (a file at `path` is never replaced).
    storage_options : dict, optional
        Options of the URL's filesystem (fsspec), e.g. credentials.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.formats import Keyframes, read_zarr, write_zarr
    >>> kf = Keyframes(np.array([0.0, 1.0]), np.eye(4)[:2, None], names=("hand",))
    >>> write_zarr("memory://doc-write.zarr", kf, force=True)
    >>> read_zarr("memory://doc-write.zarr").names
    ('hand',)
    """
    _need()
    loc = _locations(storage_options, dst=path)["dst"]
    times, keys = np.asarray(keyframes.times, np.float64), np.asarray(keyframes.keys)
    batch = keys.shape[1:-1]
    if keyframes.names is not None and len(keyframes.names) != int(np.prod(batch)):
        raise ValueError(f"expected {int(np.prod(batch))} track names, got {len(keyframes.names)}")
    _space_check(loc, _nbytes(len(times), batch, keys.dtype))
    with _atomic(loc, force) as tmp:
        zt, zk = _create(tmp, len(times), batch, keys.dtype, keyframes.names)
        zt[...] = times
        zk[...] = keys


def _nbytes(n, batch, dtype):
    """Bytes of a store of `n` frames of tracks `batch`, uncompressed."""
    return n * (8 + 4 * np.dtype(dtype).itemsize * int(np.prod(batch)))


def resample_zarr(src, dst, *, fps=None, times=None, method="slerp", extrapolate="raise",
                  scheduler=None, progress=None, force=False, storage_options=None):
    """Resample the keyframes of Zarr store `src` into Zarr store `dst`, chunk by chunk.

    The track names (the group attribute ``names``) are carried over.

    Parameters
    ----------
    src, dst : str or os.PathLike
        Stores zarr opens: local paths or URLs (``memory://``, ``s3://``,
        ``gs://``, any fsspec protocol).  `dst` appears only when complete
        (see the module's notes); an existing `dst` is replaced only with
        `force`, and never when it is `src`.
    fps, times, method, extrapolate
        As `quatarray.formats.resample_file`; `times` may also be a Zarr
        store (or array) of query times, read chunk by chunk.
    scheduler : str, optional
        Address of a running ``distributed`` scheduler.  Default: the
        active ``distributed.Client`` if there is one, else Dask's local
        threads.  The workers must reach `src` and `dst`.  On an error the
        chunks being written are finished before the temporary store is
        removed (on a cluster: every chunk of the current window of
        `WINDOW_CHUNKS`), so that none of them makes it again.
    progress : bool, optional
        Show a progress bar on stderr (Dask's ``ProgressBar``, or
        ``distributed.progress`` on a cluster); default: when stderr is a
        terminal.
    force : bool, default False
        Replace an existing `dst`.
    storage_options : dict, optional
        Options of the URLs' filesystems (credentials, ``endpoint_url``,
        ...), as zarr and fsspec take them; they apply to every store
        given as a URL.

    Returns
    -------
    tuple of int
        ``(keys read, frames written)``.

    Examples
    --------
    >>> import numpy as np, zarr
    >>> from quatarray.formats.zarr import resample_zarr
    >>> g = zarr.open_group("memory://doc-in.zarr", mode="w")
    >>> g["times"] = np.array([0.0, 1.0]); g["keys"] = np.array([[1.0, 0, 0, 0], [0, 0, 0, 1]])
    >>> resample_zarr("memory://doc-in.zarr", "memory://doc-out.zarr", fps=4, progress=False, force=True)
    (2, 5)
    >>> np.round(zarr.open_group("memory://doc-out.zarr", mode="r")["keys"][2], 6)
    array([0.707107, 0.      , 0.      , 0.707107])
    """
    _need()
    import dask.array as da

    from .. import dask
    from ..interpolate import Track
    if (fps is None) == (times is None):
        raise ValueError("give exactly one of fps and times")
    times_store = times if isinstance(times, (str, os.PathLike)) and is_zarr(times) else None
    where = _locations(storage_options, src=src, dst=dst, times=times_store)
    loc_in, loc_out = where["src"], where["dst"]
    for what, loc in (("input", loc_in), ("times store", where.get("times"))):
        if loc is not None and loc.key() == loc_out.key():
            raise read_while_written(loc_out.name, what)
        if loc is not None and loc.nests(loc_out):
            raise FormatError(f"lies inside the {what}, or holds it: write elsewhere", loc_out.name)
    key_times, keys, names = _read(loc_in)
    check_query(key_times, np.empty(0), extrapolate)     # at least 2 keys
    batch = keys.shape[1:-1]
    rows = _rows(batch)
    queries = _Queries(key_times, fps, times, where.get("times"))
    n = queries.size
    window = rows * WINDOW_CHUNKS
    if keys.nbytes <= MEMORY_KEYS:
        kmem = keys.compute()
        track = Track(key_times, kmem, method=method, extrapolate=extrapolate)
        interpolate = partial(dask.evaluate, _CurveAndKeys(track, kmem))
    else:
        interpolate = dask.Track(key_times, keys.rechunk({0: -1, -1: -1}), method=method, extrapolate=extrapolate)
    dtype = interpolate(queries.window(0, min(n, 1), 1)).dtype     # lazy: nothing computed
    _space_check(loc_out, _nbytes(n, batch, dtype))
    if extrapolate == "raise" and fps is None and n:   # one pass over the times before any writing
        low, high = np.inf, -np.inf
        for start in range(0, n, window):
            t = queries.window(start, min(n, start + window), rows)
            low, high = np.minimum(low, t.min()), np.maximum(high, t.max())
        check_query(key_times, np.array(da.compute(low, high)), extrapolate)
    show = sys.stderr.isatty() if progress is None else progress
    with _atomic(loc_out, force) as tmp, _runner(scheduler, show) as run:
        zt, zk = _create(tmp, n, batch, dtype, names)
        for start in range(0, n, window):
            stop = min(n, start + window)
            t = queries.window(start, stop, rows)
            out = interpolate(t).rechunk((rows,) + batch + (4,))
            region = slice(start, stop)
            run(partial(da.store, [t, out], [zt, zk], lock=False, compute=False,
                        regions=[(region,), (region,) + (slice(None),) * (len(batch) + 1)]))
    return len(key_times), n


class _CurveAndKeys:
    """A `Track` whose value at a key time is the key as stored (`keys_at_key_times`), as the
    in-memory resampling gives it: a chunk of queries at a time, with the keys in memory."""

    def __init__(self, track, keys):
        self.track, self.keys = track, keys

    @property
    def times(self):
        """The key times (float64), the track's."""
        return self.track.times

    def __call__(self, t):
        out = np.asarray(self.track(t))
        t = np.asarray(t, np.float64)
        keys_at_key_times(self.times, self.keys, t, out)
        return out


@contextlib.contextmanager
def _runner(scheduler, show):
    """A function that runs a write, given as `dask.array.store` waiting for more of its arguments
    (``compute=False``): on the distributed scheduler at `scheduler`, on the active
    ``distributed.Client``, or on local threads; with a progress bar if `show`.  It returns only
    when no chunk of the write is being written any more, also on an error."""
    client = None
    if scheduler is None and "distributed" in sys.modules:
        from distributed import default_client
        with contextlib.suppress(ValueError):
            client = default_client()
    if scheduler is not None or client is not None:
        from distributed import Client, futures_of, progress, wait
        with contextlib.ExitStack() as stack:
            if client is None:
                client = stack.enter_context(Client(scheduler))

            def run(store):
                # a future for every chunk (each one's result is its target, not its data), all waited
                # for, failed or not, before an error is raised: the chunks still being written on the
                # workers when one fails would otherwise land after the temporary store is removed (a
                # cancelled task runs on, and the scheduler no longer reports it).  On Ctrl-C or SIGTERM
                # too, the window's chunks are waited for; a second interrupt stops waiting.
                futures = futures_of(client.persist(store(return_stored=True, load_stored=False)))
                try:
                    if show:
                        progress(futures)
                    wait(futures)
                except BaseException:
                    wait(futures)
                    raise
                for future in futures:
                    if future.status == "error":
                        future.result()    # raises the chunk's error
            yield run
        return
    # our own pool, so that on an error, Ctrl-C or SIGTERM the chunks being written are finished
    # (and no more started) before the temporary store is removed: a write landing after the
    # removal would create it again
    import dask
    from concurrent.futures import ThreadPoolExecutor
    from dask.system import CPU_COUNT
    workers = dask.config.get("num_workers", None) or CPU_COUNT
    pool = ThreadPoolExecutor(workers)
    try:
        with contextlib.ExitStack() as stack:
            if show:
                from dask.diagnostics import ProgressBar
                stack.enter_context(ProgressBar(out=sys.stderr))

            def run(store):
                dask.compute(store(), scheduler="threads", pool=pool, num_workers=workers)
            yield run
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
