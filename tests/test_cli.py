"""The ``quatarray`` command, run as ``python -m quatarray`` in a subprocess (quatarray.cli)."""

import os
import re
import subprocess
import sys

import numpy as np
import pytest

from quatarray import cli
from quatarray.io import read_bvh, resample_motion
from quatarray.io import example_path, fps_times, read_csv, read_npz, resample_keyframes, write_csv, write_npz

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
METHODS = ("slerp", "squad", "bezier", "linear")


def run(*args, cwd=None):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [ROOT, env.get("PYTHONPATH")]))
    return subprocess.run([sys.executable, "-m", "quatarray", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=120)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """The shipped examples in each format (NPZ and scalar-last CSV made from the CSV)."""
    folder = tmp_path_factory.mktemp("inputs")
    kf = read_csv(example_path("arm.csv"))
    paths = {"csv": example_path("arm.csv"), "npz": str(folder / "arm.npz"), "bvh": example_path("walk.bvh"),
             "xyzw": str(folder / "arm_xyzw.csv")}
    write_npz(paths["npz"], kf)
    write_csv(paths["xyzw"], kf, scalar_last=True)
    return paths


def expected(fmt, path, method, fps):
    """What the library computes in-process for the same request."""
    if fmt == "bvh":
        clip = read_bvh(path)
        return resample_motion(clip, fps_times(0.0, clip.times[-1], fps), method=method).frames
    kf = read_csv(path) if fmt == "csv" else read_npz(path)
    return resample_keyframes(kf, fps_times(kf.times[0], kf.times[-1], fps), method=method)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("fmt", ["csv", "npz", "bvh"])
def test_resample_each_format_and_method(tmp_path, inputs, fmt, method):
    out = tmp_path / f"out.{fmt}"
    res = run("resample", inputs[fmt], "-o", out, "--fps", 50, "--method", method)
    assert res.returncode == 0, res.stderr
    assert res.stderr == ""
    want = expected(fmt, inputs[fmt], method, 50)
    if fmt == "bvh":
        got = read_bvh(out)
        assert got.frame_time == 1 / 50 and got.hierarchy == read_bvh(inputs[fmt]).hierarchy
        # written with the input's 4 decimals
        np.testing.assert_allclose(got.frames, want, rtol=0, atol=0.5e-4 * (1 + 1e-9))
        frames = len(want)
    else:
        got = read_csv(out) if fmt == "csv" else read_npz(out)
        np.testing.assert_array_equal(got.times, want.times)
        if fmt == "csv":  # written with the input's 9 decimals
            assert read_csv(inputs[fmt]).style.decimals == 9
            np.testing.assert_allclose(got.keys, want.keys, rtol=0, atol=0.5e-9 * (1 + 1e-6))
        else:
            np.testing.assert_array_equal(got.keys, want.keys)
        frames = len(want.times)
    assert f"-> {out}: {frames} frames ({method}" in res.stdout
    assert os.listdir(tmp_path) == [out.name]


def test_methods_give_different_curves(tmp_path, inputs):
    """The --method option reaches the interpolator (in-process, no subprocess needed)."""
    outs = {}
    for method in METHODS:
        out = tmp_path / f"{method}.npz"
        assert cli.main(["resample", inputs["npz"], "-o", str(out), "--fps", "30", "--method", method]) == 0
        outs[method] = read_npz(out).keys
    for a in METHODS:
        for b in METHODS:
            if a < b:
                assert not np.allclose(outs[a], outs[b], atol=1e-6), (a, b)


def test_times_file_and_conversion_csv_to_npz(tmp_path, inputs):
    times = tmp_path / "t.txt"
    times.write_text("0.1\n0.7\n\n2.05\n3.999\n")
    out = tmp_path / "out.npz"
    res = run("resample", inputs["csv"], "-o", out, "--times", times, "--method", "squad")
    assert res.returncode == 0, res.stderr
    got = read_npz(out)
    np.testing.assert_array_equal(got.times, [0.1, 0.7, 2.05, 3.999])
    want = resample_keyframes(read_csv(inputs["csv"]), got.times, method="squad")
    np.testing.assert_array_equal(got.keys, want.keys)


def test_scalar_last(tmp_path, inputs):
    out = tmp_path / "out.csv"
    res = run("resample", inputs["xyzw"], "-o", out, "--fps", 10, "--scalar-last")
    assert res.returncode == 0, res.stderr
    assert out.read_text().split("\n", 1)[0].startswith("time,shoulder.x,shoulder.y,shoulder.z,shoulder.w,")
    np.testing.assert_allclose(read_csv(out, scalar_last=True).keys, expected("csv", inputs["csv"], "slerp", 10).keys,
                               rtol=0, atol=0.5e-9 * (1 + 1e-6))  # the input's 9 decimals


@pytest.mark.parametrize("mode", ["clamp", "extend"])
def test_extrapolate(tmp_path, inputs, mode):
    times = tmp_path / "t.txt"
    times.write_text("-0.5\n0\n4\n4.5\n")
    out = tmp_path / "out.csv"
    assert cli.main(["resample", inputs["csv"], "-o", str(out), "--times", str(times), "--extrapolate", mode]) == 0
    kf, got = read_csv(inputs["csv"]), read_csv(out)
    if mode == "clamp":
        np.testing.assert_allclose(got.keys[[0, 3]], kf.keys[[0, -1]], atol=1e-12)
    else:
        assert not np.allclose(got.keys[[0, 3]], kf.keys[[0, -1]], atol=1e-3)


# --------------------------------------------------------------------------- bad input

HEADER = "time,a.w,a.x,a.y,a.z\n"


def bad_case(tmp_path, case):
    """(arguments, file and line the message must name, message pattern) for one bad input."""
    def text(name, content):
        path = tmp_path / name
        path.write_text(content)
        return str(path)

    bvh = open(example_path("walk.bvh")).read().split("\n")
    if case == "missing file":
        src = str(tmp_path / "nothere.csv")
        return [src], src, "No such file"
    if case == "unknown extension":
        src = text("keys.txt", HEADER + "0,1,0,0,0\n1,1,0,0,0\n")
        return [src], src, r"unknown extension '\.txt'"
    if case == "unknown output extension":
        return [example_path("arm.csv"), "-o", str(tmp_path / "out.json")], str(tmp_path / "out.json"), r"'\.json'"
    if case == "bvh to csv":
        return [example_path("walk.bvh"), "-o", str(tmp_path / "out.csv")], str(tmp_path / "out.csv"), "BVH"
    if case == "bad header":
        return [text("k.csv", "time,a.w,a.x,a.y\n0,1,0,0\n")], "k.csv:1", "bad header"
    if case == "non-numeric cell":
        return [text("k.csv", HEADER + "0,1,0,0,0\n1,1,0,x,0\n")], "k.csv:3", "non-numeric value 'x'"
    if case == "short row":
        return [text("k.csv", HEADER + "0,1,0,0,0\n1,1,0,0\n")], "k.csv:3", "expected 5 values, got 4"
    if case == "times not increasing":
        return [text("k.csv", HEADER + "0,1,0,0,0\n1,1,0,0,0\n0.5,1,0,0,0\n")], "k.csv:4", "strictly increasing"
    if case == "zero quaternion":
        return [text("k.csv", HEADER + "0,1,0,0,0\n1,0,0,0,0\n")], "k.csv:3", "zero quaternion"
    if case == "zero quaternion npz":
        src = str(tmp_path / "k.npz")
        np.savez(src, times=[0.0, 1.0], keys=[[1.0, 0, 0, 0], [0, 0, 0, 0]])
        return [src, "-o", str(tmp_path / "out.npz")], "k.npz", r"keys\[1\]: zero quaternion"
    if case == "bvh unknown channel":
        i = next(i for i, line in enumerate(bvh) if "CHANNELS 3" in line)
        bvh[i] = bvh[i].replace("Xrotation", "Xrotate")
        return [text("c.bvh", "\n".join(bvh)), "-o", str(tmp_path / "out.bvh")], f"c.bvh:{i + 1}", "'Xrotate'"
    if case == "bvh short frame line":
        i = len(bvh) - 4
        bvh[i] = bvh[i].rsplit(" ", 2)[0]
        return [text("c.bvh", "\n".join(bvh)), "-o", str(tmp_path / "out.bvh")], f"c.bvh:{i + 1}", "got 31"
    if case == "times file not increasing":
        times = text("t.txt", "0\n1\n1\n")
        return [example_path("arm.csv"), "--times", times], "t.txt:3", "strictly increasing"
    if case == "times file non-numeric":
        times = text("t.txt", "0\n1\nlater\n")
        return [example_path("arm.csv"), "--times", times], "t.txt:3", "non-numeric value 'later'"
    if case == "outside keys":
        times = text("t.txt", "0\n5\n")
        return [example_path("arm.csv"), "--times", times], "arm.csv", r"query time 5\.0 is outside"
    raise AssertionError(case)


BAD = ["missing file", "unknown extension", "unknown output extension", "bvh to csv", "bad header",
       "non-numeric cell", "short row", "times not increasing", "zero quaternion", "zero quaternion npz",
       "bvh unknown channel", "bvh short frame line", "times file not increasing", "times file non-numeric",
       "outside keys"]


@pytest.mark.parametrize("case", BAD)
def test_bad_input(tmp_path, case):
    args, where, pattern = bad_case(tmp_path, case)
    if "-o" not in args:
        args = args + ["-o", str(tmp_path / "out.csv")]
    if "--fps" not in args and "--times" not in args:
        args = args + ["--fps", "30"]
    before = set(os.listdir(tmp_path))
    res = run("resample", *args)
    assert res.returncode == 2
    assert res.stdout == ""
    assert res.stderr.count("\n") == 1 and res.stderr.startswith("quatarray: error: "), res.stderr
    assert where in res.stderr
    assert re.search(pattern, res.stderr), res.stderr
    assert "Traceback" not in res.stderr
    assert set(os.listdir(tmp_path)) == before  # no output, no temporary


def test_failure_keeps_existing_output(tmp_path):
    src = tmp_path / "k.csv"
    src.write_text(HEADER + "0,1,0,0,0\n0,1,0,0,0\n")
    out = tmp_path / "out.csv"
    out.write_text("earlier result\n")
    assert cli.main(["resample", str(src), "-o", str(out), "--fps", "30"]) == 2
    assert out.read_text() == "earlier result\n"
    assert sorted(os.listdir(tmp_path)) == ["k.csv", "out.csv"]


def test_unwritable_output_folder(tmp_path, capsys):
    out = tmp_path / "no" / "out.csv"
    assert cli.main(["resample", example_path("arm.csv"), "-o", str(out), "--fps", "30"]) == 2
    err = capsys.readouterr().err
    assert err == f"quatarray: error: {out}: No such file or directory\n"


@pytest.mark.parametrize("argv", [
    ["resample", "a.csv", "-o", "b.csv"],                                   # neither --fps nor --times
    ["resample", "a.csv", "-o", "b.csv", "--fps", "30", "--times", "t"],    # both
    ["resample", "a.csv", "-o", "b.csv", "--fps", "0"],
    ["resample", "a.csv", "-o", "b.csv", "--fps", "fast"],
    ["resample", "a.csv", "-o", "b.csv", "--fps", "30", "--method", "cubic"],
    ["resample", "a.csv", "--fps", "30"],                                   # no -o
    [],
])
def test_usage_errors_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(argv)
    assert info.value.code == 2
    assert "usage: quatarray" in capsys.readouterr().err


# --------------------------------------------------------------------------- demo

def have_matplotlib():
    try:
        from matplotlib.figure import Figure
    except ImportError:
        return False
    return Figure is not None


def test_demo(tmp_path):
    res = run("demo", "-o", tmp_path / "out", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    kf = read_csv(example_path("arm.csv"))
    assert f"{len(kf.times)} keys" in res.stdout
    assert f"{len(fps_times(kf.times[0], kf.times[-1], 120))} frames at 120 fps" in res.stdout
    for method in ("slerp", "squad", "bezier"):
        assert f"  {method} " in res.stdout
    assert " ms" in res.stdout
    written = set(os.listdir(tmp_path / "out"))
    assert {"demo_arm.csv", "demo_arm.npz", "demo_walk.bvh"} <= written
    np.testing.assert_array_equal(read_npz(tmp_path / "out" / "demo_arm.npz").keys, kf.keys)
    if not have_matplotlib():
        assert 'pip install "quatarray[plot]"' in res.stdout
        return
    png = tmp_path / "out" / "demo.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"wrote {png}" in res.stdout


def test_demo_without_matplotlib(tmp_path, monkeypatch, capsys):
    for name in ("matplotlib", "matplotlib.figure"):
        monkeypatch.setitem(sys.modules, name, None)  # import fails
    assert cli.main(["demo", "-o", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert 'matplotlib is not installed (pip install "quatarray[plot]")' in out
    assert not (tmp_path / "demo.png").exists()


def test_demo_shows_slerp_jumps_and_smooth_curves(tmp_path, capsys):
    """The printed frame-to-frame change of |w| is largest for slerp (its jumps at keys)."""
    cli.demo(str(tmp_path), file=sys.stdout)
    jumps = {}
    for line in capsys.readouterr().out.splitlines():
        parts = line.split()
        if parts and parts[0] in ("slerp", "squad", "bezier"):
            jumps[parts[0]] = float(parts[-2])
    assert jumps["slerp"] > 2 * max(jumps["squad"], jumps["bezier"])


def test_python_dash_m_and_console_entry_point_agree():
    assert cli.main.__module__ == "quatarray.cli"
    res = run("--help")
    assert res.returncode == 0 and "resample" in res.stdout and "demo" in res.stdout
