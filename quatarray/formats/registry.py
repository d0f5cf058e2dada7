"""The one table of file formats, and `resample_file`, which the command line and the API both use.

Each format registers its extensions, its family (formats of one family
convert into each other), its reader and writer (None where it has none in
memory), the resampler of its family and, where it has one, a resampler from
the format into itself that does not hold the track in memory (Zarr → Zarr,
chunk by chunk).  `resample_file`, the command line's messages and
``quatarray --help`` read this table, so a format added here is everywhere at
once.
"""

import dataclasses
import errno
import os

import numpy as np

from . import bvh, csv, gltf, npz, zarr
from .keyframes import fps_times, read_times, resample_keyframes
from .text import (FormatError, TextStyle, echo, nested, not_a_store, option, read_while_written, refuse_existing,
                   same_file)

__all__ = ["Format", "FORMATS", "format_of", "resample_file"]


@dataclasses.dataclass(frozen=True)
class Request:
    """What `resample_file` was asked for, handed to the format's resampler."""

    fps: float = None
    times: object = None
    method: str = "slerp"
    extrapolate: str = "raise"
    scalar_last: bool = False
    precision: object = None
    force: bool = False
    scheduler: str = None
    progress: bool = None
    storage_options: dict = None

    def grid(self, t0, t1, per_frame, onto=None):
        """The query times: the given ones, or ``t0 + k / fps`` up to `t1` (size checked first; a time
        within a millionth of a frame of a key time in `onto` is that key time)."""
        return fps_times(t0, t1, self.fps, per_frame, onto) if self.times is None else self.times

    def style(self, style):
        """`style` (the input's, or None) with the decimals `precision` asks for."""
        if self.precision is None:
            return style
        return dataclasses.replace(style or TextStyle(), decimals=None if self.precision == "full" else self.precision)


def _read_csv(path, request):
    return csv.read_csv(path, scalar_last=request.scalar_last)


def _write_csv(path, data, request):
    if request.precision is not None:   # every value as asked, interpolated or copied
        data = dataclasses.replace(data, style=request.style(data.style), copied=None)
    csv.write_csv(path, data, scalar_last=request.scalar_last or None)


def _read_npz(path, request):
    return npz.read_npz(path)


def _write_npz(path, data, request):
    npz.write_npz(path, data)


def _read_zarr(path, request):
    return zarr.read_zarr(path, storage_options=request.storage_options)


def _write_zarr(path, data, request):
    zarr.write_zarr(path, data, force=request.force, storage_options=request.storage_options)


def _resample_keyframes(src, dst, kind_in, kind_out, request):
    data = FORMATS[kind_in].read(src, request)
    t = request.grid(data.times[0], data.times[-1], 1 + data.keys[0].size, onto=data.times)
    out = resample_keyframes(data, t, method=request.method, extrapolate=request.extrapolate)
    FORMATS[kind_out].write(dst, out, request)
    return len(data.times), len(t)


def _read_bvh(path, request):
    return bvh.read_bvh(path)


def _write_bvh(path, data, request):
    if request.precision is not None:   # every value as asked, interpolated or copied
        data = dataclasses.replace(data, style=request.style(data.style), copied=None)
    bvh.write_bvh(path, data)


def _resample_bvh(src, dst, kind_in, kind_out, request):
    data = _read_bvh(src, request)
    times = data.times
    t = request.grid(times[0], times[-1], data.frames.shape[1], onto=times)
    out = bvh.resample_motion(data, t, method=request.method, extrapolate=request.extrapolate,
                              frame_time=None if request.fps is None else 1 / request.fps)
    _write_bvh(dst, out, request)
    return len(times), len(t)


def _resample_gltf(src, dst, kind_in, kind_out, request):
    return gltf.resample_gltf(src, dst, fps=request.fps, times=request.times, method=request.method,
                              extrapolate=request.extrapolate, force=request.force)


def _resample_zarr(src, dst, kind_in, kind_out, request):
    return zarr.resample_zarr(src, dst, fps=request.fps, times=request.times, method=request.method or "slerp",
                              extrapolate=request.extrapolate, scheduler=request.scheduler,
                              progress=request.progress, force=request.force,
                              storage_options=request.storage_options)


@dataclasses.dataclass(frozen=True)
class Format:
    """One file format of the registry.

    Attributes
    ----------
    name : str
        As messages name it (``"CSV"``).
    family : str
        Formats of one family convert into each other.
    read, write : callable or None
        ``read(path, request) -> data`` and ``write(path, data, request)``;
        None where the format has none in memory.
    resample : callable
        ``resample(src, dst, ext_in, ext_out, request) -> (keys read,
        frames written)``, the resampler of the family.
    chunked : callable or None
        A resampler (called as `resample`) used instead when input and
        output are both of this format, which resamples chunk by chunk
        beyond memory (Zarr → Zarr): it reads the input while it writes
        the output, so its output is never its input.  None: none.  Every
        other path reads the input whole before the output is renamed into
        place, so there the output may be the input (with ``force``).
    directory : bool
        The format is a directory (a Zarr store), not a file.
    urls : bool
        A file of this format may be a URL (``s3://``, ``memory://``, ...)
        with ``storage_options`` for its filesystem.
    """

    name: str
    family: str
    read: object
    write: object
    resample: object
    chunked: object = None
    directory: bool = False
    urls: bool = False


#: File extension (lower case) -> `Format`.
FORMATS = {
    ".csv": Format("CSV", "keyframes", _read_csv, _write_csv, _resample_keyframes),
    ".npz": Format("NPZ", "keyframes", _read_npz, _write_npz, _resample_keyframes),
    ".bvh": Format("BVH", "BVH", _read_bvh, _write_bvh, _resample_bvh),
    ".gltf": Format("glTF", "glTF", None, None, _resample_gltf),
    ".glb": Format("GLB", "glTF", None, None, _resample_gltf),
    ".zarr": Format("Zarr", "keyframes", _read_zarr, _write_zarr, _resample_keyframes, chunked=_resample_zarr,
                    directory=True, urls=True),
}


def format_of(path):
    """The registry's extension for `path` (lower case), or a `FormatError` that lists the known ones.

    >>> from quatarray.formats import format_of
    >>> format_of("walk.BVH")
    '.bvh'
    """
    ext = os.path.splitext(os.fspath(path).rstrip("/\\"))[1].lower()
    if ext not in FORMATS:
        raise FormatError(f"unknown extension {echo(ext) if ext else '(none)'} (expected {', '.join(FORMATS)})", path)
    return ext


def formats_of(src, dst):
    """The extensions of `src` and `dst`, checked to be of one family (formats that convert into each other)."""
    kind_in, kind_out = format_of(src), format_of(dst)
    family = FORMATS[kind_in].family
    if family != FORMATS[kind_out].family:
        raise FormatError(f"cannot write {kind_out} from {kind_in} input ({family} files convert into "
                          f"{', '.join(e for e, f in FORMATS.items() if f.family == family)} only)", dst)
    return kind_in, kind_out


def check_storage_options(storage_options, kind_in, kind_out, dst):
    """Storage options apply to formats that take URLs (Zarr stores) only."""
    if storage_options and not (FORMATS[kind_in].urls or FORMATS[kind_out].urls):
        urls = ", ".join(f"{f.name} stores ({e})" for e, f in FORMATS.items() if f.urls)
        raise FormatError(f"storage options apply to {urls} only", dst)


def check_output(src, dst, kind_out, force, chunked=False):
    """The overwrite rule, for every command that writes a file: an existing `dst` only with `force`;
    `dst` equal to `src` only with `force`, and never when `chunked` (the input is read chunk by chunk
    while `dst` is written, so it cannot be replaced atomically); never a file where a store (a
    directory) goes, or the reverse, nor `dst` inside the input's store or holding the input (whose
    replacement would delete it)."""
    if nested(src, dst):
        raise FormatError("lies inside the input, or holds it: write elsewhere", dst)
    if os.path.isdir(dst) != FORMATS[kind_out].directory and os.path.exists(dst):
        if FORMATS[kind_out].directory:
            raise not_a_store(dst, FORMATS[kind_out].name)
        raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), os.fspath(dst))
    if same_file(src, dst):
        if chunked:
            raise read_while_written(dst)
        if not force:
            what = "store" if FORMATS[kind_out].directory else "file"
            raise FormatError(f"is the input {what}; give {option('force')} to replace it", dst)
    else:
        refuse_existing(os.path.lexists(dst), dst, force)


def resample_file(src, dst, *, fps=None, times=None, method=None, extrapolate="raise", scalar_last=False,
                  precision=None, force=False, scheduler=None, progress=None, storage_options=None):
    """Read `src`, resample it and write `dst`; formats follow the extensions.

    Parameters
    ----------
    src, dst : str or os.PathLike
        ``.csv``, ``.npz``, ``.bvh``, ``.gltf``, ``.glb`` or ``.zarr``.  CSV,
        NPZ and Zarr convert into each other, and so do glTF and GLB; BVH
        goes to BVH only.  Zarr → Zarr is resampled chunk by chunk, beyond
        memory; a Zarr store converted to or from CSV or NPZ is held in memory
        whole, as those formats need (see `quatarray.formats.read_zarr`).
        `dst` is written atomically.
    fps : float, optional
        Sample at ``t0 + k / fps`` for k = 0, 1, ... up to the last key time.
    times : array_like or str or os.PathLike, optional
        Query times, or a file of one time per line, or a Zarr store (or
        array) holding ``times``.  For BVH they count from
        the first frame and must be evenly spaced.  Give `fps` or `times`.
    method, extrapolate : str
        Passed to `quatarray.Track`.  `method` None is 'slerp',
        except for glTF, where it keeps each sampler's own interpolation
        (see `quatarray.formats.resample_gltf`).
    scalar_last : bool
        CSV output in ``x, y, z, w`` order.  By default a CSV output is
        written in the order of a CSV input (the columns of an input are
        matched by name, so it needs no option), else ``w, x, y, z``.
    precision : int or "full", optional
        Decimals of the values written to CSV or BVH.  By default those of the
        input (for BVH, the most decimals among its frame values); ``"full"``
        writes the shortest text that reads back exactly.  Times are always
        written exactly.
    force : bool
        Replace an existing `dst` (atomically), also when it is `src`, and
        let a ``.gltf`` output's ``.bin`` replace an existing file (never a
        file of the input, unless `dst` is the input itself and the file its
        buffer: the two are rewritten together).  A Zarr store resampled
        into a Zarr store, read chunk by chunk while the output is written,
        is never written over.
    scheduler, progress
        Zarr → Zarr only: see `quatarray.formats.resample_zarr`.
    storage_options : dict, optional
        For Zarr stores given as a URL zarr opens, such as
        ``s3://bucket/run.zarr``, input or output: see
        `quatarray.formats.resample_zarr`.

    Returns
    -------
    tuple of int
        ``(keys read, frames written)``.

    Raises
    ------
    FormatError
        An unknown extension, or an unreadable input or times file (the
        message names the file and line), or `dst` is `src` without
        `force`, or a ``.gltf`` output's ``.bin`` would replace a file of
        the input.
    FileExistsError
        `dst` (or a ``.gltf`` output's ``.bin``) exists, without `force`.
    ValueError
        Query times outside the keys with ``extrapolate="raise"``, a single key,
        an output of more than ``quatarray.formats.text.MAX_VALUES`` values, or
        a Zarr store of more for a CSV or NPZ output (read into memory).
    OSError
        A missing input or an unwritable output.

    Examples
    --------
    >>> from quatarray.formats import example_path, resample_file
    >>> import os, tempfile
    >>> tmp = tempfile.TemporaryDirectory()
    >>> resample_file(example_path("arm.csv"), os.path.join(tmp.name, "arm.npz"), fps=60, method="squad")
    (11, 241)
    """
    kind_in, kind_out = formats_of(src, dst)
    family = FORMATS[kind_in].family
    chunked = FORMATS[kind_in].chunked if kind_in == kind_out else None
    if (fps is None) == (times is None):
        raise ValueError("give exactly one of fps and times")
    if not (precision is None or precision == "full" or (isinstance(precision, int) and 0 <= precision <= 30)):
        raise ValueError(f"expected precision an int from 0 to 30 or 'full', got {precision!r}")
    check_storage_options(storage_options, kind_in, kind_out, dst)
    check_output(src, dst, kind_out, force, chunked=chunked is not None)
    if chunked is None:   # a chunked resampler reads its query times chunk by chunk (Zarr: also from a .zarr store)
        if times is not None and isinstance(times, (str, os.PathLike)):
            times = (zarr.read_times_zarr(times, storage_options=storage_options) if zarr.is_zarr(times)
                     else read_times(times))
        times = None if times is None else np.asarray(times, np.float64)
    if method is None and family != "glTF":
        method = "slerp"
    request = Request(fps, times, method, extrapolate, scalar_last, precision, force, scheduler, progress,
                      storage_options)
    return (chunked or FORMATS[kind_in].resample)(src, dst, kind_in, kind_out, request)
