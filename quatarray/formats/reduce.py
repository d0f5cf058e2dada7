"""Keyframe files with fewer keys within an angular tolerance (`reduce_file`, ``quatarray reduce``).

Formats come from the registry (`quatarray.formats.FORMATS`): its readers and
writers, and per family the way keys can be dropped:

- **CSV, NPZ, Zarr** (one time column for every track): the tracks keep one shared
  set of key times (`quatarray.reduce_keys` with ``shared=True``); the kept
  rows are written exactly as they were read.
- **BVH** (frames on one uniform grid): keys cannot be dropped one by one.
  The clip is resampled onto the coarsest uniform grid, a whole multiple n
  of the frame time, whose curve, evaluated back at every original frame,
  keeps every joint's rotation within the tolerance (frame time n times the
  old one; a last frame past the end holds the end pose).  Position channels
  are interpolated linearly and are not part of the bound.
- **glTF** (``.gltf``, ``.glb``): each LINEAR rotation sampler is rewritten
  with its own fewer keys (LINEAR is slerp, the only method there); every
  other sampler and everything else in the file is written back as it was.
"""

import dataclasses

import numpy as np

from .. import _euler, _reduce
from ..timeseries import reduce_keys
from .bvh import resample_motion
from .keyframes import Keyframes
from .registry import FORMATS, Request, check_output, check_storage_options, format_of, formats_of
from .text import FormatError

__all__ = ["reduce_file", "parse_tolerance"]


def parse_tolerance(text):
    """An angle given as text, in radians: ``"0.1deg"``, ``"0.002rad"`` or ``"0.002"`` (radians).

    >>> from quatarray.formats.reduce import parse_tolerance
    >>> round(parse_tolerance("0.1deg"), 12), parse_tolerance("0.002")
    (0.001745329252, 0.002)
    """
    s = str(text).strip().lower()
    scale = 1.0
    for unit, factor in (("deg", np.pi / 180), ("°", np.pi / 180), ("rad", 1.0)):
        if s.endswith(unit):
            s, scale = s[:-len(unit)].strip(), factor
            break
    try:
        value = float(s) * scale
    except ValueError:
        value = float("nan")
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"expected tolerance a positive angle such as 0.1deg or 0.002rad, got {text!r}")
    return value


def _reduce_keyframes(src, dst, kind_in, kind_out, tolerance, method, request):
    data = FORMATS[kind_in].read(src, request)
    track, err = reduce_keys(data.times, data.keys, tolerance, method=method, shared=True)
    idx = np.searchsorted(data.times, track.times)
    out = Keyframes(data.times[idx], data.keys[idx], data.names, data.style)
    FORMATS[kind_out].write(dst, out, request)
    names = data.names or tuple(f"q{j}" for j in range(err.size))
    return [(name, len(data.times), len(idx), float(e)) for name, e in zip(names, err.ravel())]


def _motion_quats(motion):
    """Joint rotations (frames, joints, 4) of a BVH clip and the joints' names, in channel order."""
    parts, names = [], []
    rotating = [j for j in motion.joints if j.rotation[0]]
    for seq, cols in motion.rotation_groups().items():
        q = _euler.from_euler(seq, motion.frames[:, cols.ravel()].reshape(-1, 3), degrees=True)
        parts.append(q.reshape(len(motion.frames), -1, 4))
        names += [j.name for j in rotating if j.rotation[0].upper() == seq]
    return np.concatenate(parts, axis=1), names


def _reduce_bvh(src, dst, kind_in, kind_out, tolerance, method, request):
    motion = FORMATS[kind_in].read(src, request)
    times = motion.times
    T = len(times)
    ref, names = _motion_quats(motion)

    def coarse(n):
        m = -(-(T - 1) // n)                     # frames 0, n, ..., m n (the last one may pass the end)
        grid = np.arange(m + 1) * n * motion.frame_time
        out = resample_motion(motion, grid, method=method, extrapolate="clamp", frame_time=n * motion.frame_time)
        back = resample_motion(out, times, method=method, extrapolate="clamp")
        return out, _reduce.angle_between(_motion_quats(back)[0], ref).max(axis=0)

    best = (motion, np.zeros(len(names)), 1)
    lo, hi = 1, max(1, T - 1)                     # n = lo meets the tolerance; find the largest that does
    while lo < hi:
        n = (lo + hi + 1) // 2
        out, err = coarse(n)
        if (err <= tolerance).all():
            lo, best = n, (out, err, n)
        else:
            hi = n - 1
    out, err, n = best
    FORMATS[kind_out].write(dst, out, request)
    return [(name, T, len(out.frames), float(e)) for name, e in zip(names, err)]


def _reduce_gltf(src, dst, kind_in, kind_out, tolerance, method, request):
    from .gltf import check_writable, write_gltf
    from .gltf_read import read_animations, read_gltf
    if method != "slerp":
        raise ValueError(f"glTF rotation samplers interpolate LINEAR, which is slerp: expected method "
                         f"'slerp', got {method!r}")
    gf = read_gltf(src)
    check_writable(gf, dst, request.force)
    nodes = gf.json.get("nodes", [])
    rows, new = [], []
    for a, samplers in enumerate(read_animations(gf)):
        anim = gf.json["animations"][a]
        label = {}
        for channel in anim.get("channels", []):   # a sampler is named after the node it turns
            node = (channel.get("target") or {}).get("node")
            if isinstance(node, int) and 0 <= node < len(nodes) and isinstance(nodes[node].get("name"), str):
                label.setdefault(channel["sampler"], nodes[node]["name"])
        replace = {}
        for i, s in enumerate(samplers):
            if s.path != "rotation" or s.interpolation != "LINEAR" or len(s.times) < 2:
                continue          # translation, scale, weights, STEP and CUBICSPLINE samplers stay as they are
            keys = np.roll(s.values, 1, axis=-1)          # glTF stores x, y, z, w
            tracks, err = reduce_keys(s.times, keys, tolerance, method="slerp")
            idx = np.searchsorted(s.times, tracks[0].times)
            replace[i] = (s.times[idx].astype(np.float32), s.values[idx].astype(np.float32))
            rows.append((label.get(i, f"animation {a} sampler {i}"), len(s.times), len(idx), float(err)))
        new.append(replace or None)
    if not rows:
        raise FormatError("no LINEAR rotation samplers to reduce", src)
    write_gltf(dst, gf, new)
    return rows


_REDUCERS = {"keyframes": _reduce_keyframes, "BVH": _reduce_bvh, "glTF": _reduce_gltf}


def reduce_file(src, dst, tolerance, *, method="slerp", scalar_last=False, force=False, storage_options=None):
    """Write `dst` with fewer keys than `src`, every track within `tolerance` of its keys.

    Parameters
    ----------
    src, dst : str or os.PathLike
        ``.csv``, ``.npz`` or ``.zarr`` (interchangeable), ``.bvh``, or
        ``.gltf`` or ``.glb`` (interchangeable); see the module notes for
        what each format allows.
    tolerance : float or str
        Largest angle between the reduced curve and any original key, in
        radians, or text such as ``"0.1deg"`` (`parse_tolerance`).
    method : {'slerp', 'linear', 'squad'}
        The curve the reader of `dst` will draw through the keys (glTF:
        'slerp' only).
    scalar_last : bool
        CSV components are ``x, y, z, w``.
    force : bool
        Replace an existing `dst`, also when it is `src` (atomically: `src`
        is read whole first, a Zarr store too), and
        let a ``.gltf`` output's ``.bin`` replace an existing file, as
        `resample_file`: without it an existing `dst` or ``.bin`` is refused.
    storage_options : dict, optional
        Options of the filesystems of Zarr stores given as URLs, as `resample_file`.

    Returns
    -------
    list of tuple
        ``(track name, keys before, keys after, max error in radians)`` per track.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> from quatarray.formats import example_path, resample_file
    >>> from quatarray.formats.reduce import reduce_file
    >>> tmp = tempfile.TemporaryDirectory()
    >>> dense = os.path.join(tmp.name, "arm_120.csv")
    >>> _ = resample_file(example_path("arm.csv"), dense, fps=120, method="squad", precision="full")
    >>> rows = reduce_file(dense, os.path.join(tmp.name, "arm_small.csv"), "0.1deg", method="squad")
    >>> [(name, before, after < before // 4, bool(err <= np.radians(0.1))) for name, before, after, err in rows]
    [('shoulder', 481, True, True), ('elbow', 481, True, True), ('wrist', 481, True, True)]
    """
    kind_in, _ = format_of(src), format_of(dst)     # both extensions known before anything else
    family = FORMATS[kind_in].family
    if family not in _REDUCERS:
        raise FormatError(f"reducing {FORMATS[kind_in].name} files is not supported (expected "
                          f"{', '.join(e for e, f in FORMATS.items() if f.family in _REDUCERS)})", src)
    kind_out = formats_of(src, dst)[1]
    tolerance = parse_tolerance(tolerance) if isinstance(tolerance, str) else float(tolerance)
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"expected tolerance > 0, got {tolerance!r}")
    check_storage_options(storage_options, kind_in, kind_out, dst)
    check_output(src, dst, kind_out, force)
    request = dataclasses.replace(Request(), scalar_last=scalar_last, force=force, storage_options=storage_options)
    return _REDUCERS[family](src, dst, kind_in, kind_out, tolerance, method, request)
