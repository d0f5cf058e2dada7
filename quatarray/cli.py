"""The ``quatarray`` command: resample keyframe files, and a demo.

::

    quatarray resample IN -o OUT (--fps F | --times FILE) [--method slerp|squad|bezier|linear]
                                 [--extrapolate raise|clamp|extend] [--scalar-last]
                                 [--precision N|full] [--force]
    quatarray demo [-o DIR]
    quatarray --version

Formats follow the extensions: ``.csv``, ``.npz`` (interchangeable),
``.bvh``, and glTF ``.gltf``, ``.glb`` (interchangeable).  Bad input ends
with a one-line message naming the file (and line) on stderr and exit status
2; the output file is then not created or touched (also on Ctrl-C and SIGTERM).
"""

import argparse
import contextlib
import dataclasses
import os
import signal
import sys
import time

import numpy as np

from ._text import FormatError, TextStyle, atomic_write, echo
from .io import (example_path, fps_times, read_bvh, read_csv, read_npz, read_times, resample_keyframes,
                 resample_motion, write_bvh, write_csv, write_npz)
from .interpolate import EXTRAPOLATE, METHODS as _TRACK_METHODS, Track

__all__ = ["main", "resample_file", "demo"]

#: The Track methods the command line offers, default first (every one but 'spline').
METHODS = ("slerp",) + tuple(m for m in _TRACK_METHODS if m not in ("slerp", "spline"))


@dataclasses.dataclass(frozen=True)
class Request:
    """What `resample_file` was asked for, handed to the format's resampler."""

    fps: float = None
    times: np.ndarray = None
    method: str = "slerp"
    extrapolate: str = "raise"
    scalar_last: bool = False
    precision: object = None
    force: bool = False

    def grid(self, t0, t1, per_frame):
        """The query times: the given ones, or ``t0 + k / fps`` up to `t1` (size checked first)."""
        return fps_times(t0, t1, self.fps, per_frame) if self.times is None else self.times

    def style(self, style):
        """`style` (the input's, or None) with the decimals `precision` asks for."""
        if self.precision is None:
            return style
        return dataclasses.replace(style or TextStyle(), decimals=None if self.precision == "full" else self.precision)


def _resample_keyframes(src, dst, kind_in, kind_out, request):
    data = read_csv(src, scalar_last=request.scalar_last) if kind_in == ".csv" else read_npz(src)
    t = request.grid(data.times[0], data.times[-1], 1 + data.keys[0].size)
    out = resample_keyframes(data, t, method=request.method, extrapolate=request.extrapolate)
    if kind_out == ".csv":
        write_csv(dst, dataclasses.replace(out, style=request.style(out.style)), scalar_last=request.scalar_last)
    else:
        write_npz(dst, out)
    return len(data.times), len(t)


def _resample_bvh(src, dst, kind_in, kind_out, request):
    data = read_bvh(src)
    times = data.times
    t = request.grid(times[0], times[-1], data.frames.shape[1])
    out = resample_motion(data, t, method=request.method, extrapolate=request.extrapolate,
                          frame_time=None if request.fps is None else 1 / request.fps)
    write_bvh(dst, dataclasses.replace(out, style=request.style(out.style)))
    return len(times), len(t)


def _resample_gltf(src, dst, kind_in, kind_out, request):
    from ._gltf import resample_gltf

    return resample_gltf(src, dst, fps=request.fps, times=request.times, method=request.method,
                         extrapolate=request.extrapolate, force=request.force)


#: File extension (lower case) -> family; a family converts into its own extensions only.
FORMATS = {".csv": "keyframes", ".npz": "keyframes", ".bvh": "BVH", ".gltf": "glTF", ".glb": "glTF"}
#: Family -> ``resample(src, dst, ext_in, ext_out, request) -> (keys read, frames written)``.
RESAMPLERS = {"keyframes": _resample_keyframes, "BVH": _resample_bvh, "glTF": _resample_gltf}


def _format_of(path):
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext not in FORMATS:
        raise FormatError(f"unknown extension {echo(ext) if ext else '(none)'} (expected {', '.join(FORMATS)})", path)
    return ext


def _same_file(src, dst):
    try:
        return os.path.samefile(src, dst)
    except OSError:
        return False


def resample_file(src, dst, *, fps=None, times=None, method=None, extrapolate="raise", scalar_last=False,
                  precision=None, force=False):
    """Read `src`, resample it and write `dst`; formats follow the extensions.

    Parameters
    ----------
    src, dst : str or os.PathLike
        ``.csv``, ``.npz``, ``.bvh``, ``.gltf`` or ``.glb``.  CSV and NPZ
        convert into each other, and so do glTF and GLB; BVH goes to BVH
        only.  `dst` is written atomically.
    fps : float, optional
        Sample at ``t0 + k / fps`` for k = 0, 1, ... up to the last key time.
    times : array_like or str or os.PathLike, optional
        Query times, or a file of one time per line.  For BVH they count from
        the first frame and must be evenly spaced.  Give `fps` or `times`.
    method, extrapolate : str
        Passed to `quatarray.interpolate.Track`.  `method` None is 'slerp',
        except for glTF, where it keeps each sampler's own interpolation
        (see `quatarray._gltf.resample_gltf`).
    scalar_last : bool
        CSV input and output have components ``x, y, z, w``.
    precision : int or "full", optional
        Decimals of the values written to CSV or BVH.  By default those of the
        input (for BVH, the most decimals among its frame values); ``"full"``
        writes the shortest text that reads back exactly.  Times are always
        written exactly.
    force : bool
        Allow `dst` to be `src` (replaced atomically), and a ``.gltf`` output's
        ``.bin`` to replace a file of a glTF input.

    Returns
    -------
    tuple of int
        ``(keys read, frames written)``.

    Raises
    ------
    FormatError
        An unknown extension, or an unreadable input or times file (the
        message names the file and line), or `dst` is `src` (or a ``.gltf``
        output's ``.bin`` a file of the input) without `force`.
    ValueError
        Query times outside the keys with ``extrapolate="raise"``, a single key,
        an output of more than ``quatarray._text.MAX_VALUES`` values.
    OSError
        A missing input or an unwritable output.

    Examples
    --------
    >>> from quatarray.cli import resample_file
    >>> import os, tempfile
    >>> from quatarray.io import example_path
    >>> tmp = tempfile.TemporaryDirectory()
    >>> resample_file(example_path("arm.csv"), os.path.join(tmp.name, "arm.npz"), fps=60, method="squad")
    (11, 241)
    """
    kind_in, kind_out = _format_of(src), _format_of(dst)
    if FORMATS[kind_in] != FORMATS[kind_out]:
        raise FormatError(f"cannot write {kind_out} from {kind_in} input ({FORMATS[kind_in]} files convert into "
                          f"{', '.join(e for e, f in FORMATS.items() if f == FORMATS[kind_in])} only)", dst)
    if (fps is None) == (times is None):
        raise ValueError("give exactly one of fps and times")
    if not (precision is None or precision == "full" or (isinstance(precision, int) and 0 <= precision <= 30)):
        raise ValueError(f"expected precision an int from 0 to 30 or 'full', got {precision!r}")
    if not force and _same_file(src, dst):
        raise FormatError("is the input file; give --force (force=True) to replace it", dst)
    if times is not None and isinstance(times, (str, os.PathLike)):
        times = read_times(times)
    if method is None and FORMATS[kind_in] != "glTF":
        method = "slerp"
    request = Request(fps, None if times is None else np.asarray(times, np.float64), method, extrapolate,
                      scalar_last, precision, force)
    return RESAMPLERS[FORMATS[kind_in]](src, dst, kind_in, kind_out, request)


# --------------------------------------------------------------------------- demo

def demo(outdir=".", *, fps=120, file=None):
    """Resample the shipped example with slerp, squad and Bezier; plot the angular speed.

    Prints what it did and writes ``demo.png`` (angular speed over time per
    method, when matplotlib is installed) into `outdir`, with copies of the
    example inputs (``demo_arm.csv``, ``demo_arm.npz``, ``demo_walk.bvh``, the
    scalar-last orientation log ``demo_imu.csv``, and ``demo_arm.glb``: the
    arm's tracks as a glTF animation of a joint chain) to try ``quatarray
    resample`` on.  Returns the path of ``demo.png``, or None
    without matplotlib.
    """
    file = sys.stdout if file is None else file
    os.makedirs(outdir, exist_ok=True)
    arm_path = example_path("arm.csv")
    kf = read_csv(arm_path)
    gaps = np.diff(kf.times)
    t = fps_times(kf.times[0], kf.times[-1], fps)
    print(f"example: {len(kf.names)} tracks ({', '.join(kf.names)}), {len(kf.times)} keys over "
          f"{kf.times[0]:g}-{kf.times[-1]:g} s, unequally spaced ({gaps.min():g}-{gaps.max():g} s apart)", file=file)
    print(f"resampled to {len(t)} frames at {fps:g} fps:", file=file)
    speeds = {}
    for method in ("slerp", "squad", "bezier"):
        start = time.perf_counter()
        track = Track(kf.times, kf.keys, method=method)
        track(t)
        omega = np.asarray(track.angular_velocity(t))
        elapsed = time.perf_counter() - start
        speed = np.linalg.norm(omega, axis=-1)  # (frames, tracks)
        speeds[method] = speed
        jump = np.abs(np.diff(speed, axis=0)).max()
        print(f"  {method:<7} {1e3 * elapsed:7.2f} ms   peak |w| {speed.max():5.2f} rad/s   "
              f"largest frame-to-frame change of |w| {jump:5.2f} rad/s", file=file)
    print("  (slerp's angular speed jumps at every key; squad and bezier change it smoothly)", file=file)

    walk = read_bvh(example_path("walk.bvh"))
    start = time.perf_counter()
    fine = resample_motion(walk, fps_times(0.0, walk.times[-1], 60), method="squad", frame_time=1 / 60)
    elapsed = time.perf_counter() - start
    print(f"BVH: {len(walk.joints)} joints, {len(walk.frames)} frames at {1 / walk.frame_time:g} fps -> "
          f"{len(fine.frames)} frames at 60 fps (squad) in {1e3 * elapsed:.2f} ms", file=file)

    from ._gltf import keyframes_to_gltf

    imu = read_csv(example_path("imu.csv"), scalar_last=True)
    inputs = {"demo_arm.csv": lambda p: write_csv(p, kf), "demo_arm.npz": lambda p: write_npz(p, kf),
              "demo_walk.bvh": lambda p: write_bvh(p, walk),
              "demo_imu.csv": lambda p: write_csv(p, imu, scalar_last=True),
              "demo_arm.glb": lambda p: keyframes_to_gltf(p, kf)}
    for name, write in inputs.items():
        write(os.path.join(outdir, name))
    print(f"example inputs written to {outdir}: {', '.join(inputs)}; try", file=file)
    print(f"  quatarray resample {os.path.join(outdir, 'demo_walk.bvh')} -o walk_60.bvh --fps 60 --method squad",
          file=file)
    print(f"  quatarray resample {os.path.join(outdir, 'demo_arm.glb')} -o arm_30.glb --fps 30", file=file)
    try:
        from matplotlib.figure import Figure  # only the demo needs matplotlib
    except ImportError:
        print('demo.png not written: matplotlib is not installed (pip install "quatarray[plot]")', file=file)
        return None
    png = os.path.join(outdir, "demo.png")
    _plot(Figure, png, t, speeds, kf)
    print(f"wrote {png}: angular speed |w(t)| per track for slerp, squad and bezier", file=file)
    return png


def _plot(Figure, path, t, speeds, kf):
    fig = Figure(figsize=(8, 2.2 * len(kf.names) + 0.6), layout="constrained")
    axes = fig.subplots(len(kf.names), 1, sharex=True, squeeze=False)[:, 0]
    styles = {"slerp": dict(color="tab:red", lw=1.2), "squad": dict(color="tab:blue", lw=1.8),
              "bezier": dict(color="tab:green", lw=1.8, ls="--")}
    for j, (ax, name) in enumerate(zip(axes, kf.names)):
        for key in kf.times:
            ax.axvline(key, color="0.8", lw=0.8, zorder=0)
        for method, speed in speeds.items():
            ax.plot(t, speed[:, j], label=method, **styles[method])
        ax.set_ylabel(f"{name}\n|\u03c9| (rad/s)")
    axes[0].legend(loc="upper right", ncol=3, fontsize="small")
    fig.suptitle("Angular speed |\u03c9(t)|: slerp jumps at the keys (grey), squad and B\u00e9zier are smooth")
    axes[-1].set_xlabel("time (s)")
    with atomic_write(path, binary=True) as f:
        fig.savefig(f, format="png", dpi=110)


# --------------------------------------------------------------------------- command line

def _fps(text):
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (np.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _precision(text):
    if text == "full":
        return text
    if not (text.isdigit() and int(text) <= 30):
        raise argparse.ArgumentTypeError(f"expected a number of decimals from 0 to 30 or 'full', got {echo(text)}")
    return int(text)


def build_parser():
    """The argument parser of the ``quatarray`` command."""
    from . import __version__

    parser = argparse.ArgumentParser(prog="quatarray", description="Arrays of quaternions: keyframe tools.")
    parser.add_argument("--version", action="version", version=f"quatarray {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = commands.add_parser(
        "resample", help="resample a keyframe file (.csv, .npz, .bvh, .gltf or .glb) with a chosen curve",
        description="Resample keyframes at a new rate or at given times. Formats follow the extensions: "
                    "CSV (time,<track>.w,<track>.x,<track>.y,<track>.z,...), NPZ (times (K,), keys (K, ..., 4) "
                    "scalar-first), BVH (Euler channels resampled through quaternions) and glTF 2.0 "
                    "(.gltf, .glb: every animation, written back with LINEAR samplers). CSV and NPZ "
                    "convert into each other, and so do .gltf and .glb.")
    p.add_argument("input", metavar="IN", help="keyframe file to read")
    p.add_argument("-o", "--output", metavar="OUT", required=True, help="file to write (replaced atomically)")
    when = p.add_mutually_exclusive_group(required=True)
    when.add_argument("--fps", type=_fps, metavar="F", help="sample at t0 + k/F up to the last key time")
    when.add_argument("--times", metavar="FILE", help="sample at these times (one per line)")
    p.add_argument("--method", choices=METHODS, help="curve through the keys (default: slerp; glTF: each "
                                                     "sampler's own interpolation)")
    p.add_argument("--extrapolate", choices=EXTRAPOLATE, default="raise",
                   help="query times outside the keys: raise (default), clamp or extend")
    p.add_argument("--scalar-last", action="store_true", help="CSV components are x, y, z, w (input and output)")
    p.add_argument("--precision", type=_precision, metavar="N|full",
                   help="decimals of the values written to CSV or BVH (default: as many as the input has; "
                        "'full': the shortest text that reads back exactly)")
    p.add_argument("--force", action="store_true", help="allow OUT to be IN (replaced atomically)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="Zarr stores: run on this distributed scheduler")
    p.add_argument("--quiet", action="store_true", help="Zarr stores: no progress bar")
    p.set_defaults(run=_run_resample)

    p = commands.add_parser("demo", help="resample a shipped example and plot the angular speed (demo.png)",
                            description="Resample a shipped example track with slerp, squad and Bezier, print "
                                        "what was done and plot the angular speed to DIR/demo.png.")
    p.add_argument("-o", "--output", metavar="DIR", default=".", help="folder for demo.png (default: .)")
    p.set_defaults(run=_run_demo)
    return parser


def _run_resample(args):
    start = time.perf_counter()
    from ._zarr import is_zarr, resample_zarr   # Dask and Zarr are imported only for .zarr stores
    if is_zarr(args.input) or is_zarr(args.output):
        if not (is_zarr(args.input) and is_zarr(args.output)):
            raise FormatError("Zarr stores resample to Zarr stores only (both IN and OUT end in .zarr)", args.output)
        nkeys, nframes = resample_zarr(args.input, args.output, fps=args.fps, times=args.times,
                                       method=args.method or "slerp", extrapolate=args.extrapolate,
                                       scheduler=args.scheduler, progress=False if args.quiet else None)
        print(f"{args.input}: {nkeys} keys -> {args.output}: {nframes} frames "
              f"({args.method or 'slerp'}, {time.perf_counter() - start:.2f} s)")
        return 0
    nkeys, nframes = resample_file(args.input, args.output, fps=args.fps, times=args.times, method=args.method,
                                   extrapolate=args.extrapolate, scalar_last=args.scalar_last,
                                   precision=args.precision, force=args.force)
    print(f"{args.input}: {nkeys} keys -> {args.output}: {nframes} frames "
          f"({args.method or ('own' if FORMATS.get(_format_of(args.input)) == 'glTF' else 'slerp')}, "
          f"{time.perf_counter() - start:.2f} s)")
    return 0


def _run_demo(args):
    demo(args.output)
    return 0


def main(argv=None):
    """Run the ``quatarray`` command with `argv` (default ``sys.argv[1:]``); return the exit status.

    >>> from quatarray.cli import main
    >>> main(["resample", "missing.csv", "-o", "out.csv", "--fps", "30"])
    2
    """
    args = build_parser().parse_args(argv)
    where = args.input if args.command == "resample" else args.output
    try:
        with _exit_on_sigterm():
            return args.run(args)
    except FormatError as exc:
        message = str(exc)
    except OSError as exc:
        message = f"{exc.filename}: {exc.strerror}" if exc.filename else str(exc)
    except ValueError as exc:
        message = f"{where}: {exc}"
    except MemoryError:
        message = f"{where}: out of memory (try a lower --fps or fewer --times)"
    except ImportError as exc:   # an optional dependency (Zarr stores need the dask extra)
        message = str(exc)
    except KeyboardInterrupt:
        return 130
    print("quatarray: error: " + " ".join(message.split()), file=sys.stderr)
    return 2


class _Terminated(SystemExit):
    """Raised by the SIGTERM handler so that every ``finally`` runs (temporary files are removed)."""


@contextlib.contextmanager
def _exit_on_sigterm():
    """Turn SIGTERM into `_Terminated` (exit status 143) while the command runs (main thread only)."""
    def handler(signum, frame):
        raise _Terminated(128 + signum)

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
