"""The ``quatarray`` command: resample keyframe files, and a demo.

::

    quatarray resample IN -o OUT (--fps F | --times FILE) [--method slerp|linear|squad|bezier|spline]
                                 [--extrapolate raise|clamp|extend] [--scalar-last]
                                 [--precision N|full] [--force]
    quatarray reduce IN -o OUT --tolerance ANGLE [--method slerp|linear|squad] [--scalar-last] [--force]
    quatarray demo [-o DIR]
    quatarray --version

Formats follow the extensions, as registered in `quatarray.formats.FORMATS`:
``.csv``, ``.npz`` and Zarr stores ``.zarr`` (interchangeable), ``.bvh``, glTF
``.gltf``, ``.glb`` (interchangeable).  Bad input ends
with a one-line message naming the file (and line) on stderr and exit status
2; the output file is then not created or touched (also on Ctrl-C and SIGTERM).
"""

import argparse
import contextlib
import json
import os
import signal
import sys
import time
import warnings

import numpy as np

from .formats import (FORMATS, FormatError, NonUnitKeyWarning, NotCarriedWarning, example_path, format_of, fps_times,
                      read_bvh, read_csv, resample_file, resample_motion, write_bvh, write_csv, write_npz)
from .formats.atomic import atomic_write
from .formats.reduce import parse_tolerance, reduce_file
from .formats.text import command_line, echo
from .interpolate import EXTRAPOLATE, METHODS as _TRACK_METHODS, Track

__all__ = ["main", "demo"]

#: The Track methods the command line offers, default first.
METHODS = ("slerp",) + tuple(m for m in _TRACK_METHODS if m != "slerp")
#: The methods of ``quatarray reduce`` (those `quatarray.reduce_keys` offers).
REDUCE_METHODS = ("slerp", "linear", "squad")


# --------------------------------------------------------------------------- demo

def demo(outdir=".", *, fps=120, file=None):
    """Resample the shipped example with slerp, squad and Bezier; plot the angular speed.

    Prints what it did and writes ``demo.png`` (angular speed over time per
    method, when matplotlib is installed) into `outdir`, with copies of the
    example inputs (``demo_arm.csv``, ``demo_arm.npz``, ``demo_walk.bvh``, the
    scalar-last orientation log ``demo_imu.csv``, and ``demo_arm.glb``: the
    arm's tracks as a glTF animation of a joint chain) to try ``quatarray
    resample`` on.  Returns the path of ``demo.png``, or None
    without matplotlib.  These six names are the demo's own: a rerun replaces
    them (each atomically), unlike the outputs of ``resample`` and ``reduce``.
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
    apart = float(np.abs(speeds["squad"] - speeds["bezier"]).max())
    print(f"  (squad and bezier share their tangents at the keys, so on these keys their |w| differs by at most "
          f"{apart:.3f} rad/s: their lines lie on top of each other)", file=file)

    walk = read_bvh(example_path("walk.bvh"))
    start = time.perf_counter()
    fine = resample_motion(walk, fps_times(0.0, walk.times[-1], 60), method="squad", frame_time=1 / 60)
    elapsed = time.perf_counter() - start
    print(f"BVH: {len(walk.joints)} joints, {len(walk.frames)} frames at {1 / walk.frame_time:g} fps -> "
          f"{len(fine.frames)} frames at 60 fps (squad) in {1e3 * elapsed:.2f} ms", file=file)

    from .formats import keyframes_to_gltf

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
    _plot(Figure, png, t, speeds, kf, apart)
    print(f"wrote {png}: angular speed |w(t)| per track for slerp, squad and bezier", file=file)
    return png


def _plot(Figure, path, t, speeds, kf, apart):
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
    fig.suptitle("Angular speed |\u03c9(t)|: slerp jumps at the keys (grey), squad and B\u00e9zier are smooth\n"
                 "(squad and B\u00e9zier share their key tangents: here they differ by at most "
                 f"{apart:.3f} rad/s and overlap)", fontsize="medium")
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


def _families():
    """One sentence per family of the format registry that converts between several extensions."""
    families = {}
    for ext, fmt in FORMATS.items():
        families.setdefault(fmt.family, []).append(ext)
    return [f"{', '.join(exts[:-1])} and {exts[-1]} convert into each other."
            for exts in families.values() if len(exts) > 1]


def _storage_option(text):
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {echo(text)}")
    try:
        value = json.loads(value)
    except ValueError:
        pass
    return key.strip(), value


def build_parser():
    """The argument parser of the ``quatarray`` command."""
    from . import __version__

    parser = argparse.ArgumentParser(prog="quatarray", description="Arrays of quaternions: keyframe tools.")
    parser.add_argument("--version", action="version", version=f"quatarray {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    extensions = list(FORMATS)
    p = commands.add_parser(
        "resample", help=f"resample a keyframe file ({', '.join(extensions[:-1])} or {extensions[-1]}) with a "
                         "chosen curve",
        description="Resample keyframes at a new rate or at given times. Formats follow the extensions: "
                    "CSV (time,<track>.w,<track>.x,<track>.y,<track>.z,...), NPZ (times (K,), keys (K, ..., 4) "
                    "scalar-first), BVH (Euler channels resampled through quaternions), glTF 2.0 "
                    "(.gltf, .glb: every animation, written back with LINEAR samplers) and Zarr stores (.zarr, "
                    "the NPZ layout; .zarr to .zarr is resampled chunk by chunk with Dask, to or from CSV and "
                    "NPZ in memory). "
                    + " ".join(_families()))
    p.add_argument("input", metavar="IN", help="keyframe file to read")
    p.add_argument("-o", "--output", metavar="OUT", required=True,
                   help="file to write (atomically; an existing one only with --force)")
    when = p.add_mutually_exclusive_group(required=True)
    when.add_argument("--fps", type=_fps, metavar="F", help="sample at t0 + k/F up to the last key time")
    when.add_argument("--times", metavar="FILE", help="sample at these times (one per line)")
    p.add_argument("--method", choices=METHODS, help="curve through the keys (default: slerp; glTF: each "
                                                     "sampler's own interpolation)")
    p.add_argument("--extrapolate", choices=EXTRAPOLATE, default="raise",
                   help="query times outside the keys: raise (default), clamp or extend")
    p.add_argument("--scalar-last", action="store_true",
                   help="write CSV components x, y, z, w (default: in the input CSV's order; its columns are "
                        "matched by name, in any order and case)")
    p.add_argument("--precision", type=_precision, metavar="N|full",
                   help="decimals of every value written to CSV or BVH, or 'full': the shortest text that "
                        "reads back exactly (default: a key at its own time is written as read, in the input's "
                        "number style; every interpolated value is written in full)")
    p.add_argument("--force", action="store_true",
                   help="replace an existing OUT, also when it is IN (not .zarr to .zarr, which reads IN "
                        "chunk by chunk while it writes OUT)")
    p.add_argument("--scheduler", metavar="ADDRESS", help=".zarr to .zarr: run on this distributed scheduler")
    _add_storage_option(p)
    p.add_argument("--quiet", action="store_true", help=".zarr to .zarr: no progress bar")
    p.set_defaults(run=_run_resample)

    p = commands.add_parser(
        "reduce", help="keep fewer keys, every track within an angular tolerance (.csv, .npz, .zarr, .bvh, .gltf, "
                       ".glb)",
        description="Drop keys while the curve through the kept ones stays within --tolerance of every "
                    "original key, and print keys before and after and the largest error per track. "
                    "CSV, NPZ and Zarr tracks keep one shared set of key times (the kept rows are the keys as "
                    "read, in the file's number style). "
                    "BVH frames stay on one uniform grid: the clip is resampled at the coarsest whole "
                    "multiple of its frame time that keeps every joint within the tolerance (positions "
                    "linearly, outside the bound). glTF: each LINEAR rotation sampler gets its own fewer keys "
                    "(slerp); everything else in the file is kept as it was.")
    p.add_argument("input", metavar="IN", help="keyframe file to read")
    p.add_argument("-o", "--output", metavar="OUT", required=True,
                   help="file to write (atomically; an existing one only with --force)")
    p.add_argument("--tolerance", type=_tolerance, required=True, metavar="ANGLE",
                   help="largest angle from any original key: 0.1deg, 0.002rad or 0.002 (radians)")
    p.add_argument("--method", choices=REDUCE_METHODS, default="slerp",
                   help="curve the reader draws through the keys (default: slerp)")
    p.add_argument("--scalar-last", action="store_true", help="CSV components are x, y, z, w (input and output)")
    p.add_argument("--force", action="store_true", help="replace an existing OUT, also when it is IN")
    _add_storage_option(p)
    p.set_defaults(run=_run_reduce)

    p = commands.add_parser("demo", help="resample a shipped example and plot the angular speed (demo.png)",
                            description="Resample a shipped example track with slerp, squad and Bezier, print "
                                        "what was done and plot the angular speed to DIR/demo.png, beside the "
                                        "example inputs demo_*; a rerun replaces these files of the demo's own.")
    p.add_argument("-o", "--output", metavar="DIR", default=".", help="folder for demo.png (default: .)")
    p.set_defaults(run=_run_demo)
    return parser


def _add_storage_option(p):
    p.add_argument("--storage-option", metavar="KEY=VALUE", action="append", type=_storage_option, default=[],
                   dest="storage_options",
                   help="Zarr stores given as URLs (s3://..., gs://..., memory://...): an option of their "
                        "filesystem, e.g. endpoint_url=http://127.0.0.1:9000 or anon=true (VALUE is read as "
                        "JSON when it parses, else as text); repeat for several")


def _run_resample(args):
    start = time.perf_counter()
    nkeys, nframes = resample_file(args.input, args.output, fps=args.fps, times=args.times, method=args.method,
                                   extrapolate=args.extrapolate, scalar_last=args.scalar_last,
                                   precision=args.precision, force=args.force, scheduler=args.scheduler,
                                   progress=False if args.quiet else None,
                                   storage_options=dict(args.storage_options) or None)
    own = FORMATS[format_of(args.input)].family == "glTF"
    method = args.method or ("each sampler's own interpolation" if own else "slerp")
    print(f"{args.input}: {_count(nkeys, 'key')} -> {args.output}: {_count(nframes, 'frame')} "
          f"({method}, {time.perf_counter() - start:.2f} s)")
    return 0


def _count(n, noun):
    """``1 frame``, ``2 frames``."""
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _tolerance(text):
    try:
        return parse_tolerance(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _run_reduce(args):
    start = time.perf_counter()
    rows = reduce_file(args.input, args.output, args.tolerance, method=args.method,
                       scalar_last=args.scalar_last, force=args.force,
                       storage_options=dict(args.storage_options) or None)
    width = max(len(r[0]) for r in rows) if rows else 0
    for name, before, after, err in rows:
        print(f"  {name:<{width}}  {before} -> {_count(after, 'key')}   max error {np.degrees(err):.4g} deg")
    total_before = sum(r[1] for r in rows)
    total_after = sum(r[2] for r in rows)
    print(f"{args.input} -> {args.output}: {total_before} -> {_count(total_after, 'key')} over "
          f"{_count(len(rows), 'track')} ({args.method}, tolerance {np.degrees(args.tolerance):.4g} deg, "
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
    where = args.input if args.command in ("resample", "reduce") else args.output
    try:
        with _exit_on_sigterm(), command_line(), warnings.catch_warnings():
            warnings.simplefilter("always", NonUnitKeyWarning)
            warnings.simplefilter("always", NotCarriedWarning)
            warnings.showwarning = _show_warning
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
    except Exception as exc:   # an object store's own errors (no credentials, no endpoint): one line too
        if not type(exc).__module__.split(".")[0] in _STORAGE_PACKAGES:
            raise
        message = f"{where}: {type(exc).__name__}: {exc}"
    print("quatarray: error: " + " ".join(message.split()), file=sys.stderr)
    return 2


_STORAGE_PACKAGES = {"botocore", "aiobotocore", "s3fs", "gcsfs", "adlfs", "fsspec", "aiohttp", "google"}
"""Packages whose exceptions are an object store's answer (credentials, network), not a bug of ours."""


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print("quatarray: warning: " + " ".join(str(message).split()), file=sys.stderr)


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
