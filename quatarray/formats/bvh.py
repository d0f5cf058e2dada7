"""BVH motion-capture files: reading, writing and Shoemake resampling.

A BVH file has a skeleton (``HIERARCHY``) whose joints declare channels, and a
``MOTION`` block of one line of numbers per frame.  Rotation channels are Euler
angles in degrees, applied as intrinsic rotations in the declared order:
``Zrotation Xrotation Yrotation`` is ``from_euler("ZXY", [z, x, y],
degrees=True)``.  Resampling converts each joint's angles to quaternions,
interpolates them and converts back in the same channel order; position
channels are interpolated linearly.

A ``Frame Time`` printed rounded from 1/n s (``0.0333333``, ``.0083333``) is
read as exactly 1/n (see `read_frame_time`), so frame k is at k/n s and a
resample at the file's own rate lands on every frame.  Values are written back
with the input's decimals and line endings.  Use them through `quatarray.formats`.
"""

import dataclasses
import decimal

import numpy as np

from .. import _euler
from .atomic import atomic_write
from .text import (ROWS, FormatError, TextStyle, check_query, check_size, echo, load_table, measure_style, row_line,
                   write_rows)
from ..interpolate import Track

__all__ = ["Joint", "Motion", "read_bvh", "write_bvh", "resample_motion"]

_BLOCK = 1 << 15  # joint rotations converted back to Euler angles per block


@dataclasses.dataclass(frozen=True)
class Joint:
    """A BVH joint: its name, its channels in declared order, and its ``OFFSET``."""

    name: str
    channels: tuple
    offset: tuple

    @property
    def rotation(self):
        """``(seq, positions)``: the Euler sequence of the rotation channels (``"ZXY"``, or ``""``)
        and their positions among the joint's channels."""
        return _split_channels(self.channels)[1:]


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
    style : TextStyle or None
        How the file printed its frame values (decimals) and ended its lines;
        `write_bvh` writes the same way.  None: shortest exact text, ``\\n``.
    frame_time_text : str or None
        ``Frame Time`` as printed in the file read; written back unchanged
        while it still reads as `frame_time`.
    copied : ndarray of bool, shape (K,), or None
        Which frames are copied from the file (`resample_motion`: a frame at
        its own time).  Only those keep the style's decimals; the others are
        written with the digits that read back exactly.  None: every frame
        is as read.
    """

    hierarchy: str
    joints: tuple
    frame_time: float
    frames: np.ndarray
    style: TextStyle = None
    frame_time_text: str = None
    copied: np.ndarray = None

    @property
    def times(self):
        """Frame times, shape (K,): ``k / n`` when `frame_time` is 1/n for a whole n, else ``k * frame_time``."""
        n = round(1 / self.frame_time)
        if n >= 1 and 1 / n == self.frame_time:
            return np.arange(len(self.frames)) / n
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
            seq, positions = joint.rotation
            if seq:
                groups.setdefault(seq, []).append([col + i for i in positions])
            col += len(joint.channels)
        return {seq: np.array(cols, dtype=np.intp) for seq, cols in groups.items()}


_CHANNELS = {f"{a}{k}": f"{a.upper()}{k}" for a in "XYZxyz" for k in ("position", "rotation")}


def _split_channels(channels):
    """The one parser of channel names: ``(canonical names, Euler sequence, rotation positions)``.

    ``("Xposition", "zrotation", "Xrotation", "Yrotation")`` gives
    ``(("Xposition", "Zrotation", ...), "ZXY", [1, 2, 3])``.  An unknown name
    raises KeyError.
    """
    canon = tuple(_CHANNELS[ch] for ch in channels)
    positions = [i for i, ch in enumerate(canon) if ch.endswith("rotation")]
    return canon, "".join(canon[i][0] for i in positions), positions


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
            raise FormatError(f"expected 'HIERARCHY', got {echo(text.strip())}", path, number)
        if pending is not None:
            if word != "{":
                raise FormatError(f"expected '{{' after {pending}, got {echo(word)}", path, number)
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
                raise FormatError(f"expected 3 numbers after OFFSET, got {echo(' '.join(tokens[1:]))}", path, number)
            if stack[-1] >= 0:
                joints[stack[-1]]["offset"] = offset
        elif word == "CHANNELS":
            if not stack or stack[-1] < 0:
                raise FormatError("CHANNELS outside a joint", path, number)
            joint = joints[stack[-1]]
            if not (len(tokens) >= 2 and tokens[1].isdigit() and int(tokens[1]) == len(tokens) - 2):
                raise FormatError(f"expected 'CHANNELS n' and n channel names, got {echo(text.strip())}", path, number)
            for ch in tokens[2:]:
                if ch not in _CHANNELS:
                    raise FormatError(f"unknown channel {echo(ch)} in joint {echo(joint['name'])} (expected "
                                      "Xposition, Yposition, Zposition, Xrotation, Yrotation or Zrotation)",
                                      path, number)
            canon, _, rotations = _split_channels(tokens[2:])
            if len(set(canon)) != len(canon):
                raise FormatError(f"repeated channel in joint {echo(joint['name'])}", path, number)
            nrot = len(rotations)
            if nrot not in (0, 3):
                raise FormatError(f"joint {echo(joint['name'])} has {nrot} rotation channels; "
                                  "only 0 or 3 (a full Euler triple) are supported", path, number)
            joint["channels"] = tuple(tokens[2:])
        else:
            raise FormatError(f"unexpected {echo(word)} in HIERARCHY", path, number)
    if not seen_root:
        raise FormatError("empty file (expected 'HIERARCHY')", path)
    if not joints:
        raise FormatError("no ROOT in HIERARCHY", path)
    if stack or pending:
        raise FormatError("'{' without its '}' before MOTION", path)
    return tuple(Joint(j["name"], j["channels"], j["offset"] or (0.0, 0.0, 0.0)) for j in joints)


def read_frame_time(text):
    """Seconds between frames from a ``Frame Time`` as printed: exactly 1/n when it was 1/n, rounded.

    Exporters print 1/30 s as ``0.0333333``, ``0.033333`` or ``0.03333``, and
    1/120 s as ``.0083333`` or ``0.008333``: slightly below 1/n, so frame k
    would drift to ``k * 0.0333333`` and a resample at 30 fps would miss the
    last frame.  The rule: if exactly one whole n has ``|text - 1/n|`` within
    one unit of the last printed digit (a rounded or truncated print of 1/n),
    the frame time is 1/n; otherwise it is the number as printed.  Needing a
    single n keeps short prints such as ``0.3`` or ``0.04`` as written.

    >>> from quatarray.formats import bvh as _bvh
    >>> _bvh.read_frame_time("0.0333333") == 1 / 30, _bvh.read_frame_time(".0083333") == 1 / 120
    (True, True)
    >>> _bvh.read_frame_time("0.3"), _bvh.read_frame_time("0.03456789")
    (0.3, 0.03456789)
    """
    value = float(text)
    if not (0 < value <= 1):
        return value
    unit = 10.0 ** decimal.Decimal(text.strip()).as_tuple().exponent
    n = round(1 / value)
    near = [k for k in (n - 1, n, n + 1) if k >= 1 and abs(value - 1 / k) <= unit * (1 + 1e-9)]
    return 1 / near[0] if len(near) == 1 else value


def frame_time_text(frame_time, like=None):
    """``Frame Time`` text for `frame_time` s: `like` (as read) while it still reads as `frame_time`.

    Otherwise 1/n for a whole n is printed with the significant digits of
    `like` (at least 6: ``0.0166667``), which `read_frame_time` reads back as
    exactly 1/n; any other frame time as the shortest text that reads back.
    """
    if like is not None and read_frame_time(like) == frame_time:
        return like.strip()
    n = round(1 / frame_time)
    if n >= 1 and 1 / n == frame_time:
        digits = len("".join(c for c in (like or "").lower().partition("e")[0] if c.isdigit()).lstrip("0"))
        text = f"{frame_time:.{max(6, digits)}g}"
        if read_frame_time(text) == frame_time:
            return text
    return repr(float(frame_time))


def _header_value(line, key, path, number, kind):
    text = line.strip()
    if not text.startswith(key):
        raise FormatError(f"expected '{key} ...', got {echo(text)}", path, number)
    try:
        value = kind(text[len(key):].strip())
    except (ValueError, decimal.InvalidOperation):
        value = None
    if value is None or not np.isfinite(value) or value < 0 or (kind is not int and value == 0):
        raise FormatError(f"bad {key} {echo(text[len(key):].strip())} (expected a "
                          f"{'count' if kind is int else 'positive number'})", path, number)
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
    >>> from quatarray.formats import example_path
    >>> from quatarray.formats import read_bvh
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
        frame_time = _header_value(head[1][1], "Frame Time:", path, head[1][0], read_frame_time)
        time_text = head[1][1].strip()[len("Frame Time:"):].strip()
        skip = number
    nch = sum(len(j.channels) for j in joints)
    names = [f"{j.name}.{c}" for j in joints for c in j.channels]
    frames = load_table(path, skip, nch, None, names, "values in the frame line")
    if len(frames) != nframes:
        raise FormatError(f"'Frames: {nframes}' but the file has {len(frames)} frame lines", path, frames_line)
    bad = ~np.isfinite(frames)
    if bad.any():
        i, c = np.unravel_index(np.argmax(bad), bad.shape)
        raise FormatError(f"non-finite value in channel {echo(names[c])}", path, row_line(path, skip, int(i), None))
    if not len(frames):
        raise FormatError("no frames ('Frames: 0')", path, frames_line)
    style = measure_style(path, skip, None, " ")
    return Motion("".join(hierarchy), joints, frame_time, frames, style, time_text)


def write_bvh(path, motion):
    """Write a BVH file: the hierarchy verbatim, then ``MOTION``, atomically.

    Values are written in ``motion.style`` (the decimals and line endings of
    the file read; shortest exact text without one), except frames that
    ``motion.copied`` leaves out (interpolated ones), which are written with
    the digits that read back exactly; ``Frame Time`` as `frame_time_text`
    gives it.

    Examples
    --------
    >>> import os, tempfile
    >>> from quatarray.formats import example_path
    >>> from quatarray.formats import read_bvh, write_bvh
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
    style = motion.style or TextStyle()
    with atomic_write(path, newline=style.newline) as f:
        f.write(hierarchy)
        f.write(f"MOTION\nFrames: {len(frames)}\n"
                f"Frame Time: {frame_time_text(float(motion.frame_time), motion.frame_time_text)}\n")
        write_rows(f, frames, style, sep=" ",
                   exact=None if motion.copied is None else ~np.asarray(motion.copied, bool))


# --------------------------------------------------------------------------- resampling

def _lerp_rows(times, values, t, extrapolate):
    """Piecewise-linear interpolation of the rows of `values` (K, C) at `t` (M,)."""
    out = np.empty((len(t), values.shape[1]))
    for start in range(0, len(t), ROWS):
        tt = t[start:start + ROWS]
        i = np.clip(np.searchsorted(times, tt, side="right") - 1, 0, len(times) - 2)
        u = (tt - times[i]) / (times[i + 1] - times[i])
        if extrapolate == "clamp":
            u = np.clip(u, 0.0, 1.0)
        block = out[start:start + ROWS]
        np.multiply(values[i + 1], u[:, None], out=block)
        block += values[i] * (1.0 - u)[:, None]
        for hit, key in ((u == 0, i), (u == 1, i + 1)):  # on a frame: its values as read, -0.0 included
            block[hit] = values[key[hit]]
    return out


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
    continuous.  Position channels are interpolated linearly.  A frame at its
    own time is copied as read (and marked in ``copied``).  The new frame
    time is `frame_time`, by default the spacing of `t` (the old frame time
    when `t` has one element).

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.formats import example_path
    >>> from quatarray.formats import read_bvh, resample_motion
    >>> clip = read_bvh(example_path("walk.bvh"))
    >>> fine = resample_motion(clip, np.arange(91) / 60, method="squad", frame_time=1 / 60)
    >>> fine.frames.shape, fine.frame_time
    ((91, 33), 0.016666666666666666)
    """
    t = np.asarray(t, dtype=np.float64)
    times = motion.times
    check_query(times, t, extrapolate)
    if len(t) > 1:
        step = np.diff(t)
        spacing = float(t[-1] - t[0]) / (len(t) - 1)
        if not (np.abs(step - spacing) <= 1e-6 * spacing).all():
            raise ValueError("BVH output needs evenly spaced times, got spacing from "
                             f"{float(step.min())!r} to {float(step.max())!r}")
    if frame_time is None:
        frame_time = spacing if len(t) > 1 else motion.frame_time
        n = round(1 / frame_time)
        if n >= 1 and abs(frame_time * n - 1) <= 1e-9:  # k/30 times: 1/30 exactly, not 1/30 + rounding
            frame_time = 1 / n
    check_size(len(t), motion.frames.shape[1], f"{len(t):,} frame times")
    frames = _lerp_rows(times, motion.frames, t, extrapolate)  # positions, and reference angles
    for seq, cols in motion.rotation_groups().items():
        quats = _euler.from_euler(seq, motion.frames[:, cols], degrees=True)
        track = Track(times, quats, method=method, extrapolate=extrapolate)  # Track unflips
        rows = max(1, _BLOCK // len(cols))  # output frames per block: temporaries stay small
        for start in range(0, len(t), rows):
            block = frames[start:start + rows]
            angles = _euler.as_euler(np.asarray(track(t[start:start + rows])), seq, degrees=True,
                                       suppress_warnings=True)
            block[:, cols] = _nearest_euler(angles, block[:, cols], seq[0] == seq[2])
    at = np.minimum(np.searchsorted(times, t), len(times) - 1)
    copied = times[at] == t
    frames[copied] = motion.frames[at[copied]]   # a frame at its own time: as read, not through Euler angles
    return Motion(motion.hierarchy, motion.joints, frame_time, frames, motion.style, motion.frame_time_text, copied)
