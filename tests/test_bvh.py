"""BVH motion-capture files: parsing, writing, Shoemake resampling (quatarray.formats.bvh)."""

import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from quatarray.formats import Motion, read_bvh, resample_motion, write_bvh
from quatarray.formats import FormatError, example_path

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]
METHODS = ("slerp", "squad", "bezier", "linear")


def bvh_text(orders=("ZXY",), frames=None, frame_time=0.04):
    """A skeleton: a ROOT with positions and one rotation order, then a chain
    of joints, one per further order; `frames` (K, C) or zeros."""
    lines = ["HIERARCHY"]
    for depth, order in enumerate(orders):
        pad = "  " * depth
        lines += [pad + ("ROOT Hips" if depth == 0 else f"JOINT J{depth}_{order}"), pad + "{",
                  pad + f"  OFFSET 0.0 {float(depth)} 0.5"]
        chans = [f"{a}rotation" for a in order]
        if depth == 0:
            chans = ["Xposition", "Yposition", "Zposition"] + chans
        lines.append(pad + f"  CHANNELS {len(chans)} " + " ".join(chans))
    pad = "  " * len(orders)
    lines += [pad + "End Site", pad + "{", pad + "  OFFSET 0 1 0", pad + "}"]
    lines += ["  " * d + "}" for d in reversed(range(len(orders)))]
    nch = 3 + 3 * len(orders)
    frames = np.zeros((2, nch)) if frames is None else np.asarray(frames)
    lines += ["MOTION", f"Frames: {len(frames)}", f"Frame Time: {frame_time!r}"]
    lines += [" ".join(map(repr, row)) for row in frames.tolist()]
    return "\n".join(lines) + "\n"


def random_frames(rng, n, orders, span=75.0):
    """Positions and Euler angles (degrees) away from gimbal lock."""
    f = rng.uniform(-span, span, (n, 3 + 3 * len(orders)))
    f[:, 3 + 1::3] = rng.uniform(-70, 70, (n, len(orders)))  # middle angles
    return f


def save(tmp_path, text, name="clip.bvh"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_reads_hierarchy_channels_and_frames(tmp_path, rng):
    frames = random_frames(rng, 5, ORDERS)
    clip = read_bvh(save(tmp_path, bvh_text(ORDERS, frames, 1 / 30)))
    assert [j.name for j in clip.joints] == ["Hips"] + [f"J{d}_{o}" for d, o in enumerate(ORDERS) if d]
    assert clip.joints[0].channels[:3] == ("Xposition", "Yposition", "Zposition")
    assert [j.channels[-3:] for j in clip.joints] == [tuple(f"{a}rotation" for a in o) for o in ORDERS]
    assert clip.joints[2].offset == (0.0, 2.0, 0.5)
    assert clip.frame_time == 1 / 30
    np.testing.assert_array_equal(clip.frames, frames)
    np.testing.assert_array_equal(clip.times, np.arange(5) / 30)
    groups = clip.rotation_groups()
    assert sorted(groups) == sorted(ORDERS)
    for d, order in enumerate(ORDERS):
        np.testing.assert_array_equal(groups[order], [[3 + 3 * d, 4 + 3 * d, 5 + 3 * d]])


def test_reads_shipped_example():
    clip = read_bvh(example_path("walk.bvh"))
    assert len(clip.joints) >= 5 and clip.frames.shape == (len(clip.times), 3 + 3 * len(clip.joints))
    assert len(clip.rotation_groups()) >= 2  # more than one channel order


def test_write_then_read_gives_same_hierarchy_and_motion(tmp_path, rng):
    src = save(tmp_path, bvh_text(ORDERS, random_frames(rng, 7, ORDERS), 0.0083333))
    clip = read_bvh(src)
    out = tmp_path / "copy.bvh"
    write_bvh(out, clip)
    again = read_bvh(out)
    assert again.hierarchy == clip.hierarchy == src.read_text().split("MOTION")[0]
    assert again.joints == clip.joints and again.frame_time == clip.frame_time
    np.testing.assert_array_equal(again.frames, clip.frames)
    assert out.read_text().split("MOTION")[0] == src.read_text().split("MOTION")[0]


@pytest.mark.parametrize("method", METHODS)
def test_resample_at_frame_times_reproduces_input(tmp_path, rng, method):
    frames = random_frames(rng, 9, ORDERS)
    clip = read_bvh(save(tmp_path, bvh_text(ORDERS, frames)))
    again = resample_motion(clip, clip.times, method=method)
    assert again.frame_time == pytest.approx(clip.frame_time, rel=1e-15)
    np.testing.assert_allclose(again.frames, frames, rtol=0, atol=1e-12)
    out = tmp_path / "out.bvh"
    write_bvh(out, again)
    np.testing.assert_allclose(read_bvh(out).frames, frames, rtol=0, atol=1e-12)


@pytest.mark.parametrize("order", ORDERS)
def test_midpoint_matches_scipy_euler_slerp_euler(tmp_path, rng, order):
    """Shoemake's scheme done by hand with scipy: from_euler -> Slerp -> as_euler."""
    frames = random_frames(rng, 2, [order])
    clip = read_bvh(save(tmp_path, bvh_text([order], frames, 0.5)))
    mid = resample_motion(clip, [0.0, 0.25, 0.5], method="slerp").frames[1]
    rots = Rotation.from_euler(order, frames[:, 3:], degrees=True)  # upper case: intrinsic
    expected = Slerp([0.0, 0.5], rots)([0.25]).as_euler(order, degrees=True)[0]
    np.testing.assert_allclose(mid[3:], expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(mid[:3], frames.mean(axis=0)[:3], rtol=0, atol=1e-12)


@pytest.mark.parametrize("method", ("squad", "bezier"))
def test_curves_through_several_orders_agree_as_rotations(tmp_path, rng, method):
    """The same motion stored in two channel orders resamples to the same rotations."""
    rots = Rotation.from_euler("ZXY", random_frames(rng, 6, ["ZXY"])[:, 3:], degrees=True)
    frames = np.zeros((6, 9))
    frames[:, 3:6] = rots.as_euler("ZXY", degrees=True)
    frames[:, 6:9] = rots.as_euler("YZX", degrees=True)  # second joint: same rotations, other order
    clip = read_bvh(save(tmp_path, bvh_text(["ZXY", "YZX"], frames, 0.1)))
    fine = resample_motion(clip, np.arange(26) / 50, method=method).frames
    a = Rotation.from_euler("ZXY", fine[:, 3:6], degrees=True)
    b = Rotation.from_euler("YZX", fine[:, 6:9], degrees=True)
    np.testing.assert_allclose((a.inv() * b).magnitude(), 0, atol=1e-9)


def test_angles_beyond_180_stay_continuous(tmp_path):
    """Keys at yaw 170, 190, 210 (unwrapped): between them 180, not a jump to -180."""
    frames = np.zeros((3, 6))
    frames[:, 3] = [170.0, 190.0, 210.0]  # Z, first of ZXY
    clip = read_bvh(save(tmp_path, bvh_text(["ZXY"], frames, 1.0)))
    out = resample_motion(clip, np.arange(9) / 4).frames
    np.testing.assert_allclose(out[:, 3], 170 + 20 * np.arange(9) / 4, atol=1e-9)
    np.testing.assert_allclose(out[:, 4:6], 0, atol=1e-9)


def test_other_euler_branch_is_kept(tmp_path, rng):
    """A triple with its middle angle past 90 (the second solution) reads back as written."""
    frames = np.zeros((2, 6))
    frames[:, 3:] = [[30.0, 120.0, -20.0], [40.0, 125.0, -10.0]]
    clip = read_bvh(save(tmp_path, bvh_text(["ZXY"], frames, 1.0)))
    np.testing.assert_allclose(resample_motion(clip, [0.0, 1.0]).frames, frames, atol=1e-12)
    mid = resample_motion(clip, [0.0, 0.5, 1.0]).frames[1, 3:]
    assert 120 < mid[1] < 125  # stays on the written branch
    expected = Slerp([0, 1], Rotation.from_euler("ZXY", frames[:, 3:], degrees=True))([0.5])
    got = Rotation.from_euler("ZXY", mid, degrees=True)
    assert (expected.inv() * got).magnitude()[0] < 1e-9


def test_extrapolation(tmp_path, rng):
    frames = random_frames(rng, 3, ["ZXY"])
    clip = read_bvh(save(tmp_path, bvh_text(["ZXY"], frames, 0.5)))
    with pytest.raises(ValueError, match=r"query time 1.5 is outside the key times \[0.0, 1.0\]"):
        resample_motion(clip, [0.0, 0.5, 1.0, 1.5])
    clamped = resample_motion(clip, [-0.5, 0.0, 0.5, 1.0, 1.5], extrapolate="clamp").frames
    np.testing.assert_allclose(clamped[[0, 4]], frames[[0, 2]], atol=1e-12)
    extended = resample_motion(clip, [1.0, 1.5], extrapolate="extend").frames
    np.testing.assert_allclose(extended[1, :3], 2 * frames[2, :3] - frames[1, :3], atol=1e-12)


def test_uneven_times_rejected(tmp_path):
    clip = read_bvh(save(tmp_path, bvh_text()))
    with pytest.raises(ValueError, match=r"evenly spaced times, got spacing from 0.01 to 0.03"):
        resample_motion(clip, [0.0, 0.01, 0.04])


def test_frame_time_follows_spacing_or_argument(tmp_path):
    clip = read_bvh(save(tmp_path, bvh_text(frames=np.zeros((5, 6)), frame_time=0.1)))
    assert resample_motion(clip, [0.0, 0.2, 0.4]).frame_time == pytest.approx(0.2)
    assert resample_motion(clip, [0.1]).frame_time == 0.1
    assert resample_motion(clip, [0.0, 0.25], frame_time=0.25).frame_time == 0.25


def test_motion_is_plain_data(tmp_path):
    clip = read_bvh(save(tmp_path, bvh_text()))
    assert isinstance(clip, Motion) and type(clip.frames) is np.ndarray


# --------------------------------------------------------------------------- errors

GOOD = bvh_text(["ZXY", "XYZ"], np.arange(18.0).reshape(2, 9))


def replace_line(text, old, new):
    """Replace the first line containing `old` by `new`; return (text, its 1-based line)."""
    lines = text.split("\n")
    i = next(i for i, line in enumerate(lines) if old in line)
    lines[i] = new
    return "\n".join(lines), i + 1


def last_frame_line(text):
    return text.rstrip("\n").split("\n")[-1]


def frames_header_line(text):
    return next(i for i, line in enumerate(text.split("\n"), 1) if line.startswith("Frames:"))


def error_cases():
    last = last_frame_line(GOOD)
    cases = {
        "unknown channel": replace_line(GOOD, "CHANNELS 3 Xrotation", "CHANNELS 3 Xrotation Yrotation Wrotation")
        + (r"unknown channel 'Wrotation' in joint 'J1_XYZ'",),
        "channel count": replace_line(GOOD, "CHANNELS 3 Xrotation", "CHANNELS 4 Xrotation Yrotation Zrotation")
        + (r"expected 'CHANNELS n' and n channel names",),
        "two rotations": replace_line(GOOD, "CHANNELS 3 Xrotation", "CHANNELS 2 Xrotation Yrotation")
        + (r"joint 'J1_XYZ' has 2 rotation channels; only 0 or 3",),
        "repeated channel": replace_line(GOOD, "CHANNELS 3 Xrotation", "CHANNELS 3 Xrotation Xrotation Zrotation")
        + (r"repeated channel in joint 'J1_XYZ'",),
        "offset": replace_line(GOOD, "OFFSET 0.0 1.0", "OFFSET 0.0 one 0.5") + (r"expected 3 numbers after OFFSET",),
        "stray word": replace_line(GOOD, "OFFSET 0.0 1.0", "OFSET 0 0 0") + (r"unexpected 'OFSET' in HIERARCHY",),
        "not bvh": replace_line(GOOD, "HIERARCHY", "time,a.w") + (r"expected 'HIERARCHY', got 'time,a.w'",),
        "end site": replace_line(GOOD, "End Site", "End Sight") + (r"unexpected 'End' in HIERARCHY",),
        "root in joint": replace_line(GOOD, "JOINT J1_XYZ", "ROOT J1_XYZ") + (r"ROOT inside a joint",),
        "joint in end site": replace_line(GOOD, "OFFSET 0 1 0", "JOINT Tip") + (r"JOINT inside End Site",),
        "short frame line": replace_line(GOOD, last, last.rsplit(" ", 1)[0])
        + (r"expected 9 values in the frame line, got 8",),
        "long frame line": replace_line(GOOD, last, last + " 1.0") + (r"expected 9 values in the frame line, got 10",),
        "non-numeric value": replace_line(GOOD, last, last.replace("9.0 ", "nine ", 1))
        + (r"non-numeric value 'nine' in column 'Hips.Xposition'",),
        "frames count": replace_line(GOOD, "Frames:", "Frames: 3") + (r"'Frames: 3' but the file has 2 frame lines",),
        "frames word": replace_line(GOOD, "Frames:", "Frames: two") + (r"bad Frames: 'two'",),
        "frame time": replace_line(GOOD, "Frame Time:", "Frame Time: 0") + (r"bad Frame Time: '0'",),
        "frame time missing": replace_line(GOOD, "Frame Time:", "10 11 12") + (r"expected 'Frame Time: ...'",),
        "nan value": replace_line(GOOD, last, last.replace("9.0 ", "nan ", 1)) + (r"non-finite value in channel",),
    }
    no_motion = GOOD.split("MOTION")[0]
    cases["no motion"] = (no_motion, None, r"no MOTION section")
    unclosed = GOOD.replace("}\nMOTION", "MOTION")
    cases["unclosed"] = (unclosed, None, r"'\{' without its '\}' before MOTION")
    extra = GOOD.replace("}\nMOTION", "}\n}\nMOTION")
    cases["extra brace"] = (extra, extra.split("\n").index("MOTION"), r"unbalanced '\}'")
    cases["no frames"] = (replace_line(GOOD.split("Frames:")[0] + "Frames: 0\nFrame Time: 0.1\n",
                                       "Frames:", "Frames: 0")[0], frames_header_line(GOOD), r"no frames")
    return cases


CASES = error_cases()


@pytest.mark.parametrize("case", CASES)
def test_errors_name_file_and_line(tmp_path, case):
    text, line, pattern = CASES[case]
    path = save(tmp_path, text)
    with pytest.raises(FormatError, match=pattern) as info:
        read_bvh(path)
    assert info.value.path == str(path)
    assert info.value.line == line


# --------------------------------------------------------------------------- exact frame grids

ONE_JOINT = ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition "
             "Zrotation Xrotation Yrotation\n  End Site\n  {\n    OFFSET 0 1 0\n  }\n}\n")


def bvh_file(tmp_path, frame_time, rows, name="clip.bvh", newline="\n", final=True):
    """A one-joint BVH with `Frame Time` printed as given and frame lines as given (text), exact bytes."""
    text = ONE_JOINT + f"MOTION\nFrames: {len(rows)}\nFrame Time: {frame_time}\n" + "\n".join(rows)
    text = (text + "\n" if final else text).replace("\n", newline)
    path = tmp_path / name
    path.write_bytes(text.encode())
    return path


def printed(values, decimals, trim=False):
    """Frame lines of `values` (K, C) as a %.Nf (or trimmed, %g-like) exporter prints them."""
    cells = np.char.mod(f"%.{decimals}f", np.round(values, decimals) + 0.0)
    if trim:
        cells = np.char.rstrip(np.char.rstrip(cells, "0"), ".")
    return [" ".join(row) for row in cells.tolist()]


@pytest.mark.parametrize("text, n", [
    ("0.0333333", 30), ("0.033333", 30), ("0.03333", 30), (".0083333", 120), ("0.008333", 120),
    ("0.0166667", 60), ("0.0166666", 60), ("0.00416667", 240), ("8.33333e-03", 120), ("0.125", 8), ("1", 1),
])
def test_frame_time_printed_from_one_over_n_is_exactly_that(text, n):
    from quatarray.formats.bvh import read_frame_time
    assert read_frame_time(text) == 1 / n


def test_frame_time_rule_holds_for_every_rate_and_print():
    """1/n for n up to 500, rounded or truncated to 4-9 significant digits, reads as exactly 1/n."""
    import decimal
    from quatarray.formats.bvh import read_frame_time
    for n in range(1, 501):
        for digits in range(4, 10):
            for rounding in (decimal.ROUND_HALF_EVEN, decimal.ROUND_DOWN):
                text = format(decimal.Context(prec=digits, rounding=rounding).create_decimal(1 / n), "f")
                assert read_frame_time(text) == 1 / n, text


@pytest.mark.parametrize("text", ["0.3", "0.03456789", "0.1234567", "2.5", "0.0101"])
def test_frame_time_not_near_one_over_n_stays_as_printed(text):
    """Short prints near several 1/n (0.3, 0.0101) and values far from any stay as written."""
    from quatarray.formats.bvh import read_frame_time
    assert read_frame_time(text) == float(text)


def test_issue_reproducer_4_frames_at_30_fps(tmp_path):
    """Zrotation 0/10/20/30 with Frame Time 0.0333333, --fps 30: the 4 frames, text unchanged."""
    from quatarray.formats import resample_file
    src = bvh_file(tmp_path, "0.0333333", [f"0 0 0 {z} 0 0" for z in (0, 10, 20, 30)])
    clip = read_bvh(src)
    assert clip.frame_time == 1 / 30
    np.testing.assert_array_equal(clip.times, np.arange(4) / 30)
    assert resample_file(src, tmp_path / "out.bvh", fps=30) == (4, 4)
    assert (tmp_path / "out.bvh").read_text() == src.read_text()


@pytest.mark.parametrize("frames", [7, 128, 1064])
def test_own_rate_reproduces_every_frame_and_the_text(tmp_path, rng, frames):
    from quatarray.formats import resample_file
    values = random_frames(rng, frames, ["ZXY"], span=170.0)
    src = bvh_file(tmp_path, "0.0333333", printed(values, 5))
    out = tmp_path / "out.bvh"
    assert resample_file(src, out, fps=30, method="squad") == (frames, frames)
    np.testing.assert_allclose(read_bvh(out).frames, read_bvh(src).frames, rtol=0, atol=0.5e-5)
    assert out.read_text() == src.read_text()


@pytest.mark.parametrize("frames", [7, 128, 1064])
def test_frame_counts_30_to_60_and_120_to_30(tmp_path, rng, frames):
    from quatarray.formats import resample_file
    values = random_frames(rng, frames, ["ZXY"])
    src30 = bvh_file(tmp_path, "0.0333333", printed(values, 4), "a.bvh")
    assert resample_file(src30, tmp_path / "a60.bvh", fps=60) == (frames, 2 * frames - 1)
    a60 = read_bvh(tmp_path / "a60.bvh")
    assert a60.frame_time == 1 / 60 and "Frame Time: 0.0166667\n" in (tmp_path / "a60.bvh").read_text()
    np.testing.assert_allclose(a60.frames[::2], read_bvh(src30).frames, rtol=0, atol=0.5e-4)  # every key hit
    src120 = bvh_file(tmp_path, ".0083333", printed(values, 4), "b.bvh")
    assert resample_file(src120, tmp_path / "b30.bvh", fps=30) == (frames, (frames - 1) // 4 + 1)
    np.testing.assert_allclose(read_bvh(tmp_path / "b30.bvh").frames, read_bvh(src120).frames[::4], atol=0.5e-4)


@pytest.mark.parametrize("frame_time", ["0.0333333", "0.033333"])
def test_times_at_k_over_30_are_inside_the_clip(tmp_path, rng, frame_time):
    """`quatarray resample --times` at k/30, the last one k = F - 1 on the last frame, is accepted."""
    from quatarray.cli import main
    src = bvh_file(tmp_path, frame_time, printed(random_frames(rng, 10, ["ZXY"]), 4))
    times = tmp_path / "t.txt"
    times.write_text("".join(f"{k / 30!r}\n" for k in range(10)))
    assert 9 / 30 > 9 * float(frame_time)      # beyond the last frame as printed
    assert main(["resample", str(src), "-o", str(tmp_path / "out.bvh"), "--times", str(times)]) == 0
    np.testing.assert_allclose(read_bvh(tmp_path / "out.bvh").frames, read_bvh(src).frames, atol=0.5e-4)


# --------------------------------------------------------------------------- faithful output

def test_g_style_values_crlf_identity_is_byte_identical(tmp_path, rng):
    """%g-style values (0, -5.14473, 12.5) and CRLF: an identity resample gives the same bytes."""
    from quatarray.formats import resample_file
    values = random_frames(rng, 40, ["ZXY"])
    values[::3, 0] = 0.0
    values[1::5, 5] = 12.5
    src = bvh_file(tmp_path, "0.0333333", printed(values, 5, trim=True), newline="\r\n")
    style = read_bvh(src).style
    assert (style.decimals, style.trim, style.newline) == (5, True, "\r\n")
    out = tmp_path / "out.bvh"
    resample_file(src, out, fps=30)
    assert out.read_bytes() == src.read_bytes()
    no_final = bvh_file(tmp_path, "0.0333333", printed(values, 5, trim=True), "nf.bvh", "\r\n", final=False)
    resample_file(no_final, out, fps=30, force=True)
    assert out.read_bytes() == src.read_bytes()  # CRLF kept, a final line end added


def test_identity_of_shipped_example_is_identical_text(tmp_path):
    from quatarray.formats import resample_file
    src = example_path("walk.bvh")
    resample_file(src, tmp_path / "out.bvh", fps=8)
    assert (tmp_path / "out.bvh").read_text() == open(src).read()


@pytest.mark.parametrize("precision", [0, 2, 7, "full"])
def test_precision_option(tmp_path, rng, precision):
    from quatarray.formats import resample_file
    src = bvh_file(tmp_path, "0.0333333", printed(random_frames(rng, 6, ["ZXY"]), 4))
    out = tmp_path / "out.bvh"
    resample_file(src, out, fps=45, precision=precision)
    clip = read_bvh(src)
    want = resample_motion(clip, np.arange(8) / 45, frame_time=1 / 45).frames
    lines = out.read_text().split("\n")
    rows = lines[lines.index("MOTION") + 3:-1]
    if precision == "full":
        np.testing.assert_array_equal(read_bvh(out).frames, want)
    else:
        assert {len(c.partition(".")[2]) for row in rows for c in row.split()} == {precision}
        np.testing.assert_allclose(read_bvh(out).frames, want, rtol=0, atol=0.5 * 10.0 ** -precision * (1 + 1e-9))


def test_spacing_of_k_over_n_times_gives_frame_time_one_over_n(tmp_path, rng):
    clip = read_bvh(bvh_file(tmp_path, "0.0333333", printed(random_frames(rng, 10, ["ZXY"]), 4)))
    t = np.array([k / 30 for k in range(1, 4)])
    assert float(t[-1] - t[0]) / 2 != 1 / 30  # the spacing itself carries rounding
    assert resample_motion(clip, t).frame_time == 1 / 30


def test_channels_parsed_by_one_function(tmp_path):
    """Lower-case channel names give the same Euler sequence to the joint and to rotation_groups."""
    path = tmp_path / "lower.bvh"
    path.write_text(ONE_JOINT.replace("Zrotation", "zrotation") + "MOTION\nFrames: 2\nFrame Time: 0.1\n"
                    "0 0 0 10 20 30\n0 0 0 15 25 35\n")
    clip = read_bvh(path)
    assert clip.joints[0].rotation == ("ZXY", [3, 4, 5])
    np.testing.assert_array_equal(clip.rotation_groups()["ZXY"], [[3, 4, 5]])
