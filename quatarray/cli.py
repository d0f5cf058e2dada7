"""The ``quatarray`` command: resample keyframe files, and a demo.

::

    quatarray resample IN -o OUT (--fps F | --times FILE) [--method slerp|squad|bezier|linear]
                                 [--extrapolate raise|clamp|extend] [--scalar-last]
    quatarray demo [-o DIR]

Formats follow the extensions: ``.csv``, ``.npz`` (interchangeable) and
``.bvh``.  Bad input ends with a one-line message naming the file (and line)
on stderr and exit status 2; the output file is then not created or touched.
"""

import argparse
import os
import sys
import time

import numpy as np

from ._bvh import read_bvh, resample_motion, write_bvh
from ._io import (FormatError, _atomic, example_path, fps_times, read_csv, read_npz, read_times,
                  resample_keyframes, write_csv, write_npz)
from .interpolate import Track

__all__ = ["main", "resample_file", "demo"]

#: File extensions `resample_file` understands, lower case.
FORMATS = (".csv", ".npz", ".bvh")
METHODS = ("slerp", "squad", "bezier", "linear")
EXTRAPOLATE = ("raise", "clamp", "extend")


def _format_of(path):
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext not in FORMATS:
        raise FormatError(f"unknown extension {ext or '(none)'!r} (expected {', '.join(FORMATS)})", path)
    return ext


def resample_file(src, dst, *, fps=None, times=None, method="slerp", extrapolate="raise", scalar_last=False):
    """Read `src`, resample it and write `dst`; formats follow the extensions.

    Parameters
    ----------
    src, dst : str or os.PathLike
        ``.csv``, ``.npz`` or ``.bvh``.  CSV and NPZ convert into each other;
        BVH goes to BVH only.  `dst` is written atomically.
    fps : float, optional
        Sample at ``t0 + k / fps`` for k = 0, 1, ... up to the last key time.
    times : array_like or str or os.PathLike, optional
        Query times, or a file of one time per line.  For BVH they count from
        the first frame and must be evenly spaced.  Give `fps` or `times`.
    method, extrapolate : str
        Passed to `quatarray.interpolate.Track`.
    scalar_last : bool
        CSV input and output have components ``x, y, z, w``.

    Returns
    -------
    tuple of int
        ``(keys read, frames written)``.

    Raises
    ------
    FormatError
        An unknown extension, or an unreadable input or times file (the
        message names the file and line).
    ValueError
        Query times outside the keys with ``extrapolate="raise"``, a single key.
    OSError
        A missing input or an unwritable output.

    Examples
    --------
    >>> import os, tempfile
    >>> from quatarray._io import example_path
    >>> tmp = tempfile.TemporaryDirectory()
    >>> resample_file(example_path("arm.csv"), os.path.join(tmp.name, "arm.npz"), fps=60, method="squad")
    (11, 241)
    """
    kind_in, kind_out = _format_of(src), _format_of(dst)
    if (kind_in == ".bvh") != (kind_out == ".bvh"):
        raise FormatError(f"cannot write {kind_out} from {kind_in} input (BVH converts to BVH only)", dst)
    if (fps is None) == (times is None):
        raise ValueError("give exactly one of fps and times")
    if times is not None and isinstance(times, (str, os.PathLike)):
        times = read_times(times)
    if kind_in == ".bvh":
        data = read_bvh(src)
        key_times = data.times
    elif kind_in == ".csv":
        data = read_csv(src, scalar_last=scalar_last)
        key_times = data.times
    else:
        data = read_npz(src)
        key_times = data.times
    t = fps_times(key_times[0], key_times[-1], fps) if times is None else np.asarray(times, np.float64)
    if kind_in == ".bvh":
        write_bvh(dst, resample_motion(data, t, method=method, extrapolate=extrapolate,
                                       frame_time=None if fps is None else 1 / fps))
    else:
        out = resample_keyframes(data, t, method=method, extrapolate=extrapolate)
        if kind_out == ".csv":
            write_csv(dst, out, scalar_last=scalar_last)
        else:
            write_npz(dst, out)
    return len(key_times), len(t)


# --------------------------------------------------------------------------- demo

def demo(outdir=".", *, fps=120, file=None):
    """Resample the shipped example with slerp, squad and Bezier; plot the angular speed.

    Prints what it did and writes ``demo.png`` (angular speed over time per
    method, when matplotlib is installed) into `outdir`, with copies of the
    example inputs (``demo_arm.csv``, ``demo_arm.npz``, ``demo_walk.bvh``) to
    try ``quatarray resample`` on.  Returns the path of ``demo.png``, or None
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

    inputs = {"demo_arm.csv": lambda p: write_csv(p, kf), "demo_arm.npz": lambda p: write_npz(p, kf),
              "demo_walk.bvh": lambda p: write_bvh(p, walk)}
    for name, write in inputs.items():
        write(os.path.join(outdir, name))
    print(f"example inputs written to {outdir}: {', '.join(inputs)}; try", file=file)
    print(f"  quatarray resample {os.path.join(outdir, 'demo_walk.bvh')} -o walk_60.bvh --fps 60 --method squad",
          file=file)
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
    with _atomic(path, binary=True) as f:
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


def build_parser():
    """The argument parser of the ``quatarray`` command."""
    parser = argparse.ArgumentParser(prog="quatarray", description="Arrays of quaternions: keyframe tools.")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = commands.add_parser(
        "resample", help="resample a keyframe file (.csv, .npz or .bvh) with a chosen curve",
        description="Resample keyframes at a new rate or at given times. Formats follow the extensions: "
                    "CSV (time,<track>.w,<track>.x,<track>.y,<track>.z,...), NPZ (times (K,), keys (K, ..., 4) "
                    "scalar-first) and BVH (Euler channels resampled through quaternions). CSV and NPZ "
                    "convert into each other.")
    p.add_argument("input", metavar="IN", help="keyframe file to read")
    p.add_argument("-o", "--output", metavar="OUT", required=True, help="file to write (replaced atomically)")
    when = p.add_mutually_exclusive_group(required=True)
    when.add_argument("--fps", type=_fps, metavar="F", help="sample at t0 + k/F up to the last key time")
    when.add_argument("--times", metavar="FILE", help="sample at these times (one per line)")
    p.add_argument("--method", choices=METHODS, default="slerp", help="curve through the keys (default: slerp)")
    p.add_argument("--extrapolate", choices=EXTRAPOLATE, default="raise",
                   help="query times outside the keys: raise (default), clamp or extend")
    p.add_argument("--scalar-last", action="store_true", help="CSV components are x, y, z, w (input and output)")
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
        nkeys, nframes = resample_zarr(args.input, args.output, fps=args.fps, times=args.times, method=args.method,
                                       extrapolate=args.extrapolate, scheduler=args.scheduler,
                                       progress=False if args.quiet else None)
    else:
        nkeys, nframes = resample_file(args.input, args.output, fps=args.fps, times=args.times, method=args.method,
                                       extrapolate=args.extrapolate, scalar_last=args.scalar_last)
    print(f"{args.input}: {nkeys} keys -> {args.output}: {nframes} frames "
          f"({args.method}, {time.perf_counter() - start:.2f} s)")
    return 0


def _run_demo(args):
    demo(args.output)
    return 0


def main(argv=None):
    """Run the ``quatarray`` command with `argv` (default ``sys.argv[1:]``); return the exit status.

    >>> main(["resample", "missing.csv", "-o", "out.csv", "--fps", "30"])
    2
    """
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except FormatError as exc:
        message = str(exc)
    except OSError as exc:
        message = f"{exc.filename}: {exc.strerror}" if exc.filename else str(exc)
    except ValueError as exc:
        message = f"{args.input if args.command == 'resample' else args.output}: {exc}"
    except ImportError as exc:   # an optional dependency (Zarr stores need the dask extra)
        message = str(exc)
    except KeyboardInterrupt:
        return 130
    print("quatarray: error: " + " ".join(message.split()), file=sys.stderr)
    return 2
