"""BVH motion-capture files: reading, writing and Shoemake resampling.

A BVH file has a skeleton (``HIERARCHY``) whose joints declare channels, and a
``MOTION`` block of one line of numbers per frame.  Rotation channels are Euler
angles in degrees, applied as intrinsic rotations in the declared order:
``Zrotation Xrotation Yrotation`` is ``from_euler("ZXY", [z, x, y],
degrees=True)``.  Resampling converts each joint's angles to quaternions,
interpolates them and converts back in the same channel order; position
channels are interpolated linearly.
"""

import dataclasses

import numpy as np

from . import _euler
from ._io import FormatError, _ROWS, _atomic, _check_query, _load_table, _row_line, _write_rows
from .interpolate import Track

__all__ = ["Joint", "Motion", "read_bvh", "write_bvh", "resample_motion"]

_BLOCK = 1 << 15  # joint rotations converted back to Euler angles per block


@dataclasses.dataclass(frozen=True)
class Joint:
    """A BVH joint: its name, its channels in declared order, and its ``OFFSET``."""

    name: str
    channels: tuple
    offset: tuple


@dataclasses.dataclass
class Motion:
    """A BVH clip.

    Attributes
    ----------
    hierarchy : str
        The file's text from ``HIERARCHY`` up to (not including) ``MOTION``,
        kept verbatim and written back unchanged.
    joints : tuple of Joint
        ``ROOT`` and ``JOINT`` entries in file order (``End Site`` has no
        channels and is not listed).
    frame_time : float
        Seconds between frames.
    frames : ndarray, shape (K, C)
        One row per frame, one column per channel (joints' channels in order).
    """

    hierarchy: str
    joints: tuple
    frame_time: float
    frames: np.ndarray

    @property
    def times(self):
        """Frame times ``k * frame_time``, shape (K,)."""
        return np.arange(len(self.frames)) * self.frame_time

    def rotation_groups(self):
        """Rotation channel columns grouped by Euler sequence.

        Returns
        -------
        dict
            ``{seq: columns}`` with `seq` an upper-case (intrinsic) scipy Euler
            sequence such as ``"ZXY"`` and `columns` an int array of shape
            (J, 3): for each joint with that channel order, the columns of its
            first, second and third rotation channel.
        """
        groups, col = {}, 0
        for joint in self.joints:
            rot = [(col + i, ch[0].upper()) for i, ch in enumerate(joint.channels) if ch[1:].lower() == "rotation"]
            if rot:
                groups.setdefault("".join(a for _, a in rot), []).append([c for c, _ in rot])
            col += len(joint.channels)
        return {seq: np.array(cols, dtype=np.intp) for seq, cols in groups.items()}


_CHANNELS = {f"{a}{k}": f"{a.upper()}{k}" for a in "XYZxyz" for k in ("position", "rotation")}


def _parse_hierarchy(lines, path):
    """Joints from the hierarchy lines (numbered from 1); raise FormatError."""
    joints, stack, pending, seen_root = [], [], None, False
    for number, text in lines:
        tokens = text.split()
        if not tokens:
            continue
        word = tokens[0]
        if not seen_root:
            if word == "HIERARCHY" and len(tokens) == 1:
                seen_root = True
                continue
            raise FormatError(f"expected 'HIERARCHY', got {text.strip()!r}", path, number)
        if pending is not None:
            if word != "{":
                raise FormatError(f"expected '{{' after {pending}, got {word!r}", path, number)
            tokens = tokens[1:]
            pending = None
            if not tokens:
                continue
            word = tokens[0]
        if word in ("ROOT", "JOINT"):
            if (word == "ROOT") != (not stack) or (stack and stack[-1] < 0):
                where = "outside ROOT" if not stack else "inside End Site" if stack[-1] < 0 else "inside a joint"
                raise FormatError(f"{word} {where}", path, number)
            brace = tokens[-1] == "{"
            name = " ".join(tokens[1:-1] if brace else tokens[1:])
            if not name:
                raise FormatError(f"{word} without a name", path, number)
            joints.append({"name": name, "channels": (), "offset": None, "line": number})
            stack.append(len(joints) - 1)
            pending = None if brace else f"{word} {name}"
        elif word == "End" and len(tokens) >= 2 and tokens[1] == "Site":
            if not stack:
                raise FormatError("End Site outside a joint", path, number)
            stack.append(-1)
            pending = None if tokens[-1] == "{" else "End Site"
        elif word == "}":
            if not stack:
                raise FormatError("unbalanced '}'", path, number)
            stack.pop()
        elif word == "OFFSET":
            if not stack:
                raise FormatError("OFFSET outside a joint", path, number)
            try:
                offset = tuple(float(v) for v in tokens[1:])
            except ValueError:
                offset = ()
            if len(offset) != 3:
                raise FormatError(f"expected 3 numbers after OFFSET, got {' '.join(tokens[1:])!r}", path, number)
            if stack[-1] >= 0:
                joints[stack[-1]]["offset"] = offset
        elif word == "CHANNELS":
            if not stack or stack[-1] < 0:
                raise FormatError("CHANNELS outside a joint", path, number)
            joint = joints[stack[-1]]
            if not (len(tokens) >= 2 and tokens[1].isdigit() and int(tokens[1]) == len(tokens) - 2):
                raise FormatError(f"expected 'CHANNELS n' and n channel names, got {text.strip()!r}", path, number)
            for ch in tokens[2:]:
                if ch not in _CHANNELS:
                    raise FormatError(f"unknown channel {ch!r} in joint {joint['name']!r} (expected "
                                      "Xposition, Yposition, Zposition, Xrotation, Yrotation or Zrotation)",
                                      path, number)
            canon = [_CHANNELS[ch] for ch in tokens[2:]]
            if len(set(canon)) != len(canon):
                raise FormatError(f"repeated channel in joint {joint['name']!r}", path, number)
            nrot = sum(ch.endswith("rotation") for ch in canon)
            if nrot not in (0, 3):
                raise FormatError(f"joint {joint['name']!r} has {nrot} rotation channels; "
                                  "only 0 or 3 (a full Euler triple) are supported", path, number)
            joint["channels"] = tuple(tokens[2:])
        else:
            raise FormatError(f"unexpected {word!r} in HIERARCHY", path, number)
    if not seen_root:
        raise FormatError("empty file (expected 'HIERARCHY')", path)
    if not joints:
        raise FormatError("no ROOT in HIERARCHY", path)
    if stack or pending:
        raise FormatError("'{' without its '}' before MOTION", path)
    return tuple(Joint(j["name"], j["channels"], j["offset"] or (0.0, 0.0, 0.0)) for j in joints)


def _header_value(line, key, path, number, kind):
    text = line.strip()
    if not text.startswith(key):
        raise FormatError(f"expected '{key} ...', got {text!r}", path, number)
    try:
        value = kind(text[len(key):].strip())
    except ValueError:
        value = None
    if value is None or not np.isfinite(value) or value < 0 or (kind is float and value == 0):
        raise FormatError(f"bad {key} {text[len(key):].strip()!r} (expected a "
                          f"{'positive number' if kind is float else 'count'})", path, number)
    return value


def read_bvh(path):
    """Read a BVH motion-capture file.

    Returns
    -------
    Motion
        The hierarchy text verbatim, the joints and their channels, the frame
        time and the frames, shape (Frames, channels).

    Raises
    ------
    FormatError
        Malformed hierarchy, an unknown channel, a joint with other than 0 or
        3 rotation channels, a bad ``Frames:`` / ``Frame Time:`` line, a frame
        line with the wrong number of values or a non-number, a frame count
        different from ``Frames:``; the message names the line.

    Examples
    --------
    >>> from quatarray._io import example_path
    >>> from quatarray._bvh import read_bvh
    >>> clip = read_bvh(example_path("walk.bvh"))
    >>> clip.joints[0].name, clip.joints[0].channels[3:]
    ('Hips', ('Zrotation', 'Xrotation', 'Yrotation'))
    >>> clip.frames.shape, clip.frame_time
    ((13, 33), 0.125)
    """
    hierarchy, numbered = [], []
    with open(path, encoding="utf-8-sig", errors="surrogateescape") as f:
        number = 0
        while True:
            text = f.readline()
            if not text:
                raise FormatError("no MOTION section", path)
            number += 1
            if text.strip() == "MOTION":
                break
            hierarchy.append(text)
            numbered.append((number, text))
        joints = _parse_hierarchy(numbered, path)
        head = []
        while len(head) < 2:
            text = f.readline()
            if not text:
                raise FormatError("file ends before 'Frames:' and 'Frame Time:'", path, number)
            number += 1
            if text.strip():
                head.append((number, text))
        frames_line = head[0][0]
        nframes = _header_value(head[0][1], "Frames:", path, frames_line, int)
        frame_time = _header_value(head[1][1], "Frame Time:", path, head[1][0], float)
        skip = number
    nch = sum(len(j.channels) for j in joints)
    names = [f"{j.name}.{c}" for j in joints for c in j.channels]
    frames = _load_table(path, skip, nch, None, names, "values in the frame line")
    if len(frames) != nframes:
        raise FormatError(f"'Frames: {nframes}' but the file has {len(frames)} frame lines", path, frames_line)
    bad = ~np.isfinite(frames)
    if bad.any():
        i, c = np.unravel_index(np.argmax(bad), bad.shape)
        raise FormatError(f"non-finite value in channel {names[c]!r}", path, _row_line(path, skip, int(i), None))
    if not len(frames):
        raise FormatError("no frames ('Frames: 0')", path, frames_line)
    return Motion("".join(hierarchy), joints, frame_time, frames)


def write_bvh(path, motion):
    """Write a BVH file: the hierarchy verbatim, then ``MOTION``, atomically.

    Examples
    --------
    >>> import os, tempfile
    >>> from quatarray._io import example_path
    >>> from quatarray._bvh import read_bvh, write_bvh
    >>> clip = read_bvh(example_path("walk.bvh"))
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = os.path.join(tmp.name, "copy.bvh")
    >>> write_bvh(path, clip)
    >>> again = read_bvh(path)
    >>> again.hierarchy == clip.hierarchy and bool((again.frames == clip.frames).all())
    True
    """
    frames = np.asarray(motion.frames)
    hierarchy = motion.hierarchy if motion.hierarchy.endswith("\n") else motion.hierarchy + "\n"
    with _atomic(path) as f:
        f.write(hierarchy)
        f.write(f"MOTION\nFrames: {len(frames)}\nFrame Time: {float(motion.frame_time)!r}\n")
        _write_rows(f, frames, " ")


# --------------------------------------------------------------------------- resampling

def _lerp_rows(times, values, t, extrapolate):
    """Piecewise-linear interpolation of the rows of `values` (K, C) at `t` (M,)."""
    out = np.empty((len(t), values.shape[1]))
    for start in range(0, len(t), _ROWS):
        tt = t[start:start + _ROWS]
        i = np.clip(np.searchsorted(times, tt, side="right") - 1, 0, len(times) - 2)
        u = (tt - times[i]) / (times[i + 1] - times[i])
        if extrapolate == "clamp":
            u = np.clip(u, 0.0, 1.0)
        block = out[start:start + _ROWS]
        np.multiply(values[i + 1], u[:, None], out=block)
        block += values[i] * (1.0 - u)[:, None]
    return out


def _unflip(q):
    """Flip signs along axis 0 so consecutive quaternions have dot >= 0 (same rotations)."""
    dots = np.einsum("k...i,k...i->k...", q[1:], q[:-1])
    sign = np.cumprod(np.where(dots < 0, -1.0, 1.0), axis=0)
    q[1:] *= sign[..., None]
    return q


def _nearest_euler(angles, ref, proper):
    """The Euler triple equivalent to `angles` (degrees) nearest to `ref`.

    Each rotation has two principal Euler triples, ``(a, b, c)`` and
    ``(a + 180, 180 - b, c + 180)`` (``-b`` for proper sequences), and each
    angle can move by whole turns; choosing the one nearest the linearly
    interpolated input keeps output curves continuous and in the input's
    range (angles beyond +-180 stay so).
    """
    def nearest_turn(a):  # a + 360 k, nearest to ref, in place
        step = ref - a
        step /= 360.0
        np.rint(step, out=step)
        step *= 360.0
        a += step
        return a

    alt = angles + np.array([180.0, 0.0, 180.0])
    alt[..., 1] = -angles[..., 1] if proper else 180.0 - angles[..., 1]
    best, alt = nearest_turn(angles.copy()), nearest_turn(alt)
    dist = np.square(best - ref).sum(axis=-1)
    np.copyto(best, alt, where=(np.square(alt - ref).sum(axis=-1) < dist)[..., None])
    return best


def resample_motion(motion, t, *, method="slerp", extrapolate="raise", frame_time=None):
    """Resample a BVH clip at evenly spaced times `t` (seconds from the first frame).

    Rotation channels go Euler -> quaternion -> interpolate -> Euler in the same
    channel order (Shoemake); among the equivalent Euler triples the one nearest
    the linearly interpolated input angles is written, so curves stay
    continuous.  Position channels are interpolated linearly.  The new frame
    time is `frame_time`, by default the spacing of `t` (the old frame time
    when `t` has one element).

    Examples
    --------
    >>> from quatarray._io import example_path
    >>> from quatarray._bvh import read_bvh, resample_motion
    >>> clip = read_bvh(example_path("walk.bvh"))
    >>> fine = resample_motion(clip, np.arange(91) / 60, method="squad", frame_time=1 / 60)
    >>> fine.frames.shape, fine.frame_time
    ((91, 33), 0.016666666666666666)
    """
    t = np.asarray(t, dtype=np.float64)
    times = motion.times
    _check_query(times, t, extrapolate)
    if len(t) > 1:
        step = np.diff(t)
        spacing = float(t[-1] - t[0]) / (len(t) - 1)
        if not (np.abs(step - spacing) <= 1e-6 * spacing).all():
            raise ValueError("BVH output needs evenly spaced times, got spacing from "
                             f"{float(step.min())!r} to {float(step.max())!r}")
    if frame_time is None:
        frame_time = spacing if len(t) > 1 else motion.frame_time
    frames = _lerp_rows(times, motion.frames, t, extrapolate)  # positions, and reference angles
    for seq, cols in motion.rotation_groups().items():
        quats = _unflip(np.array(_euler.from_euler(seq, motion.frames[:, cols], degrees=True), np.float64))
        track = Track(times, quats, method=method, extrapolate=extrapolate)
        rows = max(1, _BLOCK // len(cols))  # output frames per block: temporaries stay small
        for start in range(0, len(t), rows):
            block = frames[start:start + rows]
            angles = _euler.as_euler(np.asarray(track(t[start:start + rows])), seq, degrees=True,
                                       suppress_warnings=True)
            block[:, cols] = _nearest_euler(angles, block[:, cols], seq[0] == seq[2])
    return Motion(motion.hierarchy, motion.joints, frame_time, frames)
