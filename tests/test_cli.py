"""The ``quatarray`` command, run as ``python -m quatarray`` in a subprocess (quatarray.cli)."""

import os
import re
import signal
import subprocess
import sys

import numpy as np
import pytest

from quatarray import cli
from quatarray.formats import registry
from quatarray.formats import read_bvh, resample_motion
from quatarray.formats import example_path, fps_times, read_csv, read_npz, resample_keyframes, write_csv, write_npz

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


@pytest.mark.parametrize("flags", [["--scalar-last"], []])
def test_scalar_last(tmp_path, inputs, flags):
    """A scalar-last input is read by its column names and written back scalar-last, with or without
    --scalar-last; from a scalar-first input, --scalar-last writes x, y, z, w."""
    out = tmp_path / "out.csv"
    res = run("resample", inputs["xyzw"], "-o", out, "--fps", 10, *flags)
    assert res.returncode == 0, res.stderr
    assert out.read_text().split("\n", 1)[0].startswith("time,shoulder.x,shoulder.y,shoulder.z,shoulder.w,")
    np.testing.assert_allclose(read_csv(out, scalar_last=True).keys, expected("csv", inputs["csv"], "slerp", 10).keys,
                               rtol=0, atol=0.5e-9 * (1 + 1e-6))  # the input's 9 decimals
    res = run("resample", inputs["csv"], "-o", tmp_path / "xyzw.csv", "--fps", 10, "--scalar-last")
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "xyzw.csv").read_text().split("\n", 1)[0] == out.read_text().split("\n", 1)[0]


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
    assert {"demo_arm.csv", "demo_arm.npz", "demo_walk.bvh", "demo_imu.csv"} <= written
    assert read_csv(tmp_path / "out" / "demo_imu.csv", scalar_last=True).keys.shape == (60, 1, 4)
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


# --------------------------------------------------------------------------- hardened command line

def one_line_error(res):
    assert res.returncode == 2 and res.stdout == "", res
    assert res.stderr.startswith("quatarray: error: ") and res.stderr.count("\n") == 1, res.stderr
    assert "Traceback" not in res.stderr
    return res.stderr


def test_version():
    from quatarray import __version__
    res = run("--version")
    assert res.returncode == 0 and res.stdout == f"quatarray {__version__}\n"


def test_huge_fps_refused_before_allocating(tmp_path):
    err = one_line_error(run("resample", example_path("arm.csv"), "-o", tmp_path / "o.csv", "--fps", "1e9"))
    assert "asks for 4,000,000,001 frames of 13 values" in err and "the limit is 1,073,741,824 values" in err
    assert os.listdir(tmp_path) == []


def test_times_in_microseconds_refused(tmp_path):
    src = tmp_path / "us.csv"
    src.write_text(HEADER + "0,1,0,0,0\n4000000,0,1,0,0\n1e9,1,0,0,0\n")
    err = one_line_error(run("resample", src, "-o", tmp_path / "o.npz", "--fps", "30"))
    assert "asks for 30,000,000,001 frames" in err and "limit" in err


def test_huge_header_cell(tmp_path):
    src = tmp_path / "big.csv"
    src.write_text("time,\"" + "a" * 200_000 + "\"\n0,1\n")
    err = one_line_error(run("resample", src, "-o", tmp_path / "o.csv", "--fps", "30"))
    assert f"{src}:1: bad header" in err and len(err) < 300


def test_huge_bad_cell_is_cut(tmp_path):
    src = tmp_path / "big.csv"
    src.write_text(HEADER + "0,1,0,0,0\n1," + "x" * 1_000_000 + ",0,0,0\n")
    err = one_line_error(run("resample", src, "-o", tmp_path / "o.csv", "--fps", "30"))
    assert "(1000000 characters)" in err and len(err) < len(str(src)) + 150


def test_sigterm_during_write_removes_the_temporary(tmp_path):
    code = ("import sys, time\n"
            "import quatarray.formats.csv as qio\n"
            "from quatarray import cli\n"
            "real = qio.write_rows\n"
            "def slow(f, *args, **kwargs):\n"
            "    real(f, *args, **kwargs)\n"
            "    f.flush()\n"
            "    print('writing', flush=True)\n"
            "    time.sleep(60)\n"
            "qio.write_rows = slow\n"
            "sys.exit(cli.main(sys.argv[1:]))\n")
    _terminate_while_writing(code, [example_path("arm.csv"), "-o", tmp_path / "out.csv", "--fps", "30"], tmp_path)
    assert os.listdir(tmp_path) == []


def _terminate_while_writing(code, args, folder):
    """Run `code` (it prints 'writing' once its output is under way) on `args`; SIGTERM it then."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [ROOT, os.environ.get("PYTHONPATH")])))
    proc = subprocess.Popen([sys.executable, "-c", code, "resample", *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stdout.readline() == "writing\n"
        assert [n for n in os.listdir(folder) if n.endswith(".part")]
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=30) == 128 + signal.SIGTERM
    finally:
        proc.kill()
        proc.communicate()


def test_sigterm_during_a_zarr_write_removes_the_temporary_store(tmp_path):
    zarr = pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    pytest.importorskip("dask", reason="dask is not installed (the dask extra)")
    group = zarr.open_group(str(tmp_path / "in.zarr"), mode="w")
    group["times"] = np.arange(50.0)
    group["keys"] = np.tile([1.0, 0.0, 0.0, 0.0], (50, 1))
    # many small chunks, each written slowly after the first: SIGTERM comes while Dask's threads write
    # (and with writes still under way, a temporary store removed before they end would come back)
    code = ("import sys, time\n"
            "import zarr\n"
            "from quatarray import cli\n"
            "from quatarray.formats import zarr as _zarr\n"
            "_zarr.CHUNK_QUATS = 64\n"
            "said = []\n"
            "def slowed(real):\n"
            "    def slow(self, key, value):\n"
            "        if said:\n"
            "            time.sleep(0.2)\n"
            "        real(self, key, value)\n"
            "        if not said:\n"
            "            said.append(1)\n"
            "            print('writing', flush=True)\n"
            "    return slow\n"
            "zarr.Array.__setitem__ = slowed(zarr.Array.__setitem__)   # every chunk, times and quaternions\n"
            "try:\n"
            "    sys.exit(cli.main(sys.argv[1:]))\n"
            "finally:\n"
            "    time.sleep(0.5)   # a caller that lives on: chunks still being written would land now\n")
    _terminate_while_writing(code, [tmp_path / "in.zarr", "-o", tmp_path / "out.zarr", "--fps", "100"], tmp_path)
    assert os.listdir(tmp_path) == ["in.zarr"]


def test_output_directory_is_named(tmp_path):
    folder = tmp_path / "outdir.csv"
    folder.mkdir()
    err = one_line_error(run("resample", example_path("arm.csv"), "-o", folder, "--fps", "30"))
    assert err == f"quatarray: error: {folder}: Is a directory\n"
    assert os.listdir(folder) == [] and os.listdir(tmp_path) == ["outdir.csv"]


def test_writing_over_the_input_needs_force(tmp_path):
    src = tmp_path / "arm.csv"
    src.write_bytes(open(example_path("arm.csv"), "rb").read())
    before = src.read_bytes()
    err = one_line_error(run("resample", src, "-o", src, "--fps", "30"))
    assert f"{src}: is the input file; give --force" in err and src.read_bytes() == before
    link = tmp_path / "link.csv"
    os.symlink(src, link)
    one_line_error(run("resample", src, "-o", link, "--fps", "30"))
    res = run("resample", src, "-o", src, "--fps", "30", "--force")
    assert res.returncode == 0, res.stderr
    assert len(read_csv(src).times) == len(fps_times(0.0, 4.0, 30))


def test_existing_output_keeps_permissions(tmp_path):
    out = tmp_path / "out.npz"
    out.write_text("old")
    os.chmod(out, 0o604)
    assert cli.main(["resample", example_path("arm.csv"), "-o", str(out), "--fps", "30", "--force"]) == 0
    assert os.stat(out).st_mode & 0o777 == 0o604 and read_npz(out).keys.shape[1:] == (3, 4)


def test_extrapolation_error_names_the_flag(tmp_path):
    times = tmp_path / "t.txt"
    times.write_text("0\n5\n")
    err = one_line_error(run("resample", example_path("arm.csv"), "-o", tmp_path / "o.csv", "--times", times))
    assert "use --extrapolate clamp or extend" in err or "--extrapolate clamp or extend" in err


@pytest.mark.parametrize("sep", ["\t", ";"])
def test_tab_and_semicolon_files(tmp_path, sep):
    src = tmp_path / "in.csv"
    src.write_text(open(example_path("arm.csv")).read().replace(",", sep))
    out = tmp_path / "out.csv"
    assert cli.main(["resample", str(src), "-o", str(out), "--fps", "10"]) == 0
    want = resample_keyframes(read_csv(example_path("arm.csv")), fps_times(0.0, 4.0, 10))
    got = read_csv(out)
    assert out.read_text().split("\n", 1)[0] == open(example_path("arm.csv")).readline().strip().replace(",", sep)
    np.testing.assert_allclose(got.keys, want.keys, rtol=0, atol=0.5e-9 * (1 + 1e-6))


def test_csv_npz_csv_keeps_the_header_and_crlf(tmp_path):
    src = tmp_path / "in.csv"
    src.write_bytes(open(example_path("arm.csv"), "rb").read().replace(b"\n", b"\r\n"))
    times = tmp_path / "t.txt"
    times.write_text("\n".join(line.split(",")[0] for line in open(example_path("arm.csv")).read().split("\n")[1:]))
    assert cli.main(["resample", str(src), "-o", str(tmp_path / "same.csv"), "--times", str(times)]) == 0
    same = (tmp_path / "same.csv").read_bytes()
    assert same.count(b"\r\n") == same.count(b"\n") == 12 and len(same) == len(src.read_bytes())
    assert cli.main(["resample", str(src), "-o", str(tmp_path / "a.npz"), "--fps", "20"]) == 0
    assert read_npz(tmp_path / "a.npz").names == ("shoulder", "elbow", "wrist")
    assert cli.main(["resample", str(tmp_path / "a.npz"), "-o", str(tmp_path / "b.csv"), "--fps", "20"]) == 0
    assert (tmp_path / "b.csv").read_text().split("\n", 1)[0] == open(example_path("arm.csv")).readline().strip()


@pytest.mark.parametrize("precision", ["3", "full"])
def test_csv_precision_option(tmp_path, precision):
    out = tmp_path / "out.csv"
    assert cli.main(["resample", example_path("arm.csv"), "-o", str(out), "--fps", "4", "--precision", precision]) == 0
    want = resample_keyframes(read_csv(example_path("arm.csv")), fps_times(0.0, 4.0, 4))
    rows = [line.split(",")[1:] for line in out.read_text().splitlines()[1:]]
    got = read_csv(out)
    if precision == "full":        # the shortest text that reads back exactly
        np.testing.assert_array_equal(got.keys, want.keys)
        assert all(repr(float(c)) == c for row in rows for c in row)
    else:
        assert {len(c.partition(".")[2]) for row in rows for c in row} == {3}
        np.testing.assert_allclose(got.keys, want.keys, rtol=0, atol=0.5e-3 * (1 + 1e-9))


@pytest.mark.parametrize("argv", [["--precision", "-1"], ["--precision", "two"], ["--precision", "31"]])
def test_precision_usage_errors(argv, capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(["resample", "a.csv", "-o", "b.csv", "--fps", "30", *argv])
    assert info.value.code == 2 and "--precision: expected a number of decimals" in capsys.readouterr().err


# --------------------------------------------------------------------------- README

def readme_section(title):
    text = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()
    start = text.index(f"\n## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start:end if end >= 0 else None]


def test_readme_resample_examples_run_as_written(tmp_path):
    """Every bash block of the README's resample section runs, after `quatarray demo`, in a fresh folder."""
    blocks = re.findall(r"```bash\n(.*?)```", readme_section("Resample a keyframe file"), re.S)
    assert len(blocks) >= 3
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [ROOT, os.environ.get("PYTHONPATH")])))
    script = (f'set -e\nquatarray() {{ "{sys.executable}" -m quatarray "$@"; }}\nquatarray demo >/dev/null\n'
              + "\n".join(blocks))
    res = subprocess.run(["bash", "-c", script], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    commands = [line for block in blocks for line in block.splitlines() if line.startswith("quatarray resample")]
    for line in commands:
        out = line.split(" -o ")[1].split()[0]
        assert (tmp_path / out).exists(), line


def test_readme_says_clone_and_cd_first():
    section = readme_section("Two commands")
    first_pip = section.index("pip install")
    assert "git clone" in section[:first_pip] and "cd quatarray" in section[:first_pip]


def test_readme_documents_the_frame_time_rule_and_gltf_from_the_demo():
    section = readme_section("Resample a keyframe file")
    assert "rule chosen" in section and "Frame Time" in section and "1/n" in section
    demo = section.index("quatarray demo")
    glb = [m.start() for m in re.finditer(r"quatarray resample demo_arm\.glb -o \S+\.(glb|gltf)", section)]
    assert glb and min(glb) > demo and "demo_arm.csv" in section and "demo_imu.csv" in section


def test_out_of_memory_is_one_line(tmp_path, monkeypatch, capsys):
    def exhausted(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(registry, "resample_keyframes", exhausted)
    assert cli.main(["resample", example_path("arm.csv"), "-o", str(tmp_path / "o.csv"), "--fps", "30"]) == 2
    assert capsys.readouterr().err == f"quatarray: error: {example_path('arm.csv')}: out of memory (try a lower " \
                                      "--fps or fewer --times)\n"


@pytest.mark.parametrize("name, flags", [("arm.csv", []), ("imu.csv", ["--scalar-last"])])
def test_identity_resample_gives_the_shipped_examples_back(tmp_path, name, flags):
    """Resampled at their own key times, the shipped examples come back byte for byte (each key is
    copied with its text; before, a key was normalised and 2 lines of each changed in the last digit)."""
    src = example_path(name)
    times = tmp_path / "t.txt"
    times.write_text("\n".join(line.split(",")[0] for line in open(src).read().splitlines()[1:]) + "\n")
    out = tmp_path / name
    assert cli.main(["resample", src, "-o", str(out), "--times", str(times), *flags]) == 0
    assert out.read_bytes() == open(src, "rb").read()


def test_identity_resample_by_fps_on_evenly_spaced_keys(tmp_path):
    """Keys every 0.1 s from 0.7 s, at --fps 10: the grid's 0.7 + k/10 lands on each key within rounding."""
    src = tmp_path / "in.csv"
    rows = [f"{0.7 + k / 10:.1f},{np.cos(k / 5):.4f},{np.sin(k / 5):.4f},0.0000,0.0000" for k in range(9)]
    src.write_text("time,a.w,a.x,a.y,a.z\n" + "\n".join(rows) + "\n")
    assert cli.main(["resample", str(src), "-o", str(tmp_path / "out.csv"), "--fps", "10"]) == 0
    assert (tmp_path / "out.csv").read_text() == src.read_text()


def test_identity_resample_holds_exactly_when_the_guide_says(tmp_path):
    """The guide claimed byte-for-byte identity for 'any file whose header is written as quatarray
    writes it'; a key in the other hemisphere from the key before it comes back negated (the curve's
    sign), and exponent notation or digits past repr come back as plain repr decimals. The guide and
    README now state these conditions; this pins each of them."""
    times = tmp_path / "t.txt"
    times.write_text("0\n1\n2\n")

    def identity(rows):
        src = tmp_path / "in.csv"
        src.write_text("time,q.w,q.x,q.y,q.z\n" + "".join(f"{t},{r}\n" for t, r in enumerate(rows)))
        assert cli.main(["resample", str(src), "-o", str(tmp_path / "out.csv"), "--times", str(times),
                         "--force"]) == 0
        return (tmp_path / "out.csv").read_text().splitlines()[1:]

    plain = ["1,0,0,0", "0.6,0.8,0,0", "0.28,0.96,0,0"]
    assert identity(plain) == [f"{t},{r}" for t, r in enumerate(plain)]
    flipped = ["1,0,0,0", "-0.6,-0.8,0,0", "0.28,0.96,0,0"]       # key 1 in the other hemisphere
    assert identity(flipped) == ["0,1,0,0,0", "1,0.6,0.8,0,0", "2,0.28,0.96,0,0"]
    flipped = ["1,0,0,0", "-0.6,-0.8,0,0", "-0.28,-0.96,0,0"]     # keys 1 and 2 on the curve's other side
    assert identity(flipped) == ["0,1,0,0,0", "1,0.6,0.8,0,0", "2,0.28,0.96,0,0"]
    exponent = ["1e0,0e0,0e0,0e0", "6.0e-01,8.0e-01,0e0,0e0", "0.28,0.96,0,0"]
    got = identity(exponent)
    assert not any("e" in line for line in got)
    assert [[float(v) for v in line.split(",")[1:]] for line in got] == [
        [float(v) for v in row.split(",")] for row in exponent]
    mixed = ["1.000,0.000,0.000,0.000", "0.6,0.8,0,0", "0.28,0.96,0,0"]   # two number styles in one file
    got = identity(mixed)
    assert [[float(v) for v in line.split(",")[1:]] for line in got] == [
        [float(v) for v in row.split(",")] for row in mixed]
    assert got != [f"{t},{r}" for t, r in enumerate(mixed)]            # the same numbers, in one style
    guide = " ".join(open(os.path.join(ROOT, "docs", "guide", "files.rst")).read().split())
    assert "in the same hemisphere as the key before it" in guide and "no exponent notation" in guide
    assert "prints its numbers in one style" in guide and "a file that mixes styles" in guide
    readme = " ".join(open(os.path.join(ROOT, "README.md")).read().split())
    assert "whose keys do not flip hemisphere" in readme


def _zarr_input(path):
    zarr = pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    pytest.importorskip("dask", reason="dask is not installed (the dask extra)")
    group = zarr.open_group(str(path), mode="w")
    group["times"] = np.arange(4.0)
    group["keys"] = np.tile([1.0, 0.0, 0.0, 0.0], (4, 1))
    return path


def test_zarr_converts_to_and_from_csv_and_npz_on_the_command_line(tmp_path):
    """``resample in.csv -o out.zarr`` and ``in.zarr -o out.npz|out.csv``: each output is, bit for bit, the
    in-process resample of what the step read; the CSV header (track names) survives the store."""
    pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    pytest.importorskip("dask", reason="dask is not installed (the dask extra)")
    from quatarray.formats import read_zarr
    arm = read_csv(example_path("arm.csv"))
    res = run("resample", example_path("arm.csv"), "-o", tmp_path / "arm.zarr", "--fps", 30, "--method", "squad")
    assert res.returncode == 0 and res.stderr == "", res.stderr
    assert res.stdout.startswith(f"{example_path('arm.csv')}: 11 keys -> {tmp_path / 'arm.zarr'}: 121 frames (squad")
    store = read_zarr(tmp_path / "arm.zarr")
    want = resample_keyframes(arm, fps_times(arm.times[0], arm.times[-1], 30, onto=arm.times), method="squad")
    np.testing.assert_array_equal(store.keys, want.keys)
    assert store.names == arm.names
    for out in ("arm.npz", "arm.csv"):
        res = run("resample", tmp_path / "arm.zarr", "-o", tmp_path / out, "--fps", 12)
        assert res.returncode == 0 and res.stderr == "", res.stderr
        got = (read_npz if out.endswith(".npz") else read_csv)(tmp_path / out)
        want = resample_keyframes(store, fps_times(store.times[0], store.times[-1], 12, onto=store.times))
        np.testing.assert_array_equal(got.times, want.times)
        np.testing.assert_array_equal(got.keys, want.keys)
        assert got.names == arm.names
    assert open(tmp_path / "arm.csv").readline() == open(example_path("arm.csv")).readline()
    assert sorted(os.listdir(tmp_path)) == ["arm.csv", "arm.npz", "arm.zarr"]


@pytest.mark.parametrize("ext", [".csv", ".npz", ".bvh", ".glb", ".gltf", ".zarr"])
def test_an_existing_output_is_replaced_only_with_force(tmp_path, ext):
    """Every format: an existing output is refused with a message naming it and --force, and left as it
    was; with --force it is replaced."""
    if ext == ".bvh":
        src = example_path("walk.bvh")
    elif ext in (".glb", ".gltf"):
        from quatarray.formats import keyframes_to_gltf
        src = tmp_path / "in.glb"
        keyframes_to_gltf(src, read_csv(example_path("arm.csv")))
    elif ext == ".zarr":
        src = _zarr_input(tmp_path / "in.zarr")
    else:
        src = example_path("arm.csv")
    out = tmp_path / ("out" + ext)
    if ext == ".zarr":
        out.mkdir()
        (out / "precious").write_text("old")
    else:
        out.write_text("old")
    err = one_line_error(run("resample", src, "-o", out, "--fps", "10"))
    assert err == f"quatarray: error: {out}: exists; give --force to replace it\n"
    assert (out / "precious" if ext == ".zarr" else out).read_text() == "old"
    res = run("resample", src, "-o", out, "--fps", "10", "--force")
    assert res.returncode == 0, res.stderr
    assert not (out / "precious").exists() if ext == ".zarr" else out.read_bytes() != b"old"


def test_a_gltf_outputs_existing_buffer_file_needs_force(tmp_path):
    from quatarray.formats import keyframes_to_gltf
    src = tmp_path / "in.glb"            # a .gltf written from a .glb keeps its buffer in a .bin beside it
    keyframes_to_gltf(src, read_csv(example_path("arm.csv")))
    bin_file = tmp_path / "out.bin"
    bin_file.write_text("old")
    err = one_line_error(run("resample", src, "-o", tmp_path / "out.gltf", "--fps", "10"))
    assert f"{bin_file}: exists (the buffer file of the output 'out.gltf'); give --force" in err
    assert bin_file.read_text() == "old" and not (tmp_path / "out.gltf").exists()
    res = run("resample", src, "-o", tmp_path / "out.gltf", "--fps", "10", "--force")
    assert res.returncode == 0 and bin_file.read_bytes() != b"old"


def test_a_zarr_store_is_not_written_over_its_input_even_with_force(tmp_path):
    src = _zarr_input(tmp_path / "in.zarr")
    before = sorted(os.listdir(src))
    err = one_line_error(run("resample", src, "-o", src, "--fps", "10", "--force"))
    assert err == (f"quatarray: error: {src}: is the input, which is read chunk by chunk while the output is "
                   "written, so the output cannot replace it, even with --force: write elsewhere, then rename\n")
    assert sorted(os.listdir(src)) == before and sorted(os.listdir(tmp_path)) == ["in.zarr"]


def test_a_directory_or_a_file_of_the_wrong_kind_is_named(tmp_path):
    _zarr_input(tmp_path / "in.zarr")
    (tmp_path / "out.zarr").write_text("a file")
    err = one_line_error(run("resample", tmp_path / "in.zarr", "-o", tmp_path / "out.zarr", "--fps", "10", "--force"))
    assert err == f"quatarray: error: {tmp_path / 'out.zarr'}: exists and is not a Zarr store (a directory)\n"


def test_messages_name_options_as_the_caller_spells_them(tmp_path):
    """The command line says --extrapolate clamp or extend and --force; Python says extrapolate='clamp'
    and force=True; neither speaks the other's language."""
    from quatarray.formats import resample_file
    times = tmp_path / "t.txt"
    times.write_text("0\n5\n")
    err = one_line_error(run("resample", example_path("arm.csv"), "-o", tmp_path / "o.csv", "--times", times))
    assert err.endswith("extrapolate with --extrapolate clamp or extend\n") and "Python" not in err
    with pytest.raises(ValueError, match=r"extrapolate with extrapolate='clamp' or 'extend'$") as info:
        resample_file(example_path("arm.csv"), tmp_path / "o.csv", times=times)
    assert "--" not in str(info.value)
    (tmp_path / "o.csv").write_text("old")
    with pytest.raises(FileExistsError, match="exists; give force=True to replace it"):
        resample_file(example_path("arm.csv"), tmp_path / "o.csv", fps=2)
    err = one_line_error(run("resample", example_path("arm.csv"), "-o", example_path("arm.csv"), "--fps", "2"))
    assert "give --force to replace it" in err and "force=True" not in err


def test_non_unit_keys_are_a_warning_on_the_command_line(tmp_path):
    src = tmp_path / "in.csv"
    src.write_text("time,q.w,q.x,q.y,q.z\n0,1,0,0,0\n1,0,3,0,0\n2,0,0,1,0\n")
    res = run("resample", src, "-o", tmp_path / "out.csv", "--fps", "2")
    assert res.returncode == 0
    assert res.stderr == f"quatarray: warning: {src}:3: track 'q': key of norm 3 is normalised (1 key in all " \
                         "further from norm 1 than its decimals explain: 1)\n"


@pytest.mark.parametrize("case", ["empty csv", "blank first line", "garbage npz", "missing times file",
                                  "missing input", "fps 1e308", "not utf-8 in a bvh header", "not utf-8 in times"])
def test_messages_say_what_is_wrong_in_one_style(tmp_path, case):
    src, extra, want = example_path("arm.csv"), [], None
    if case == "empty csv":
        src = tmp_path / "empty.csv"
        src.write_text("")
        want = f"{src}: the file is empty (expected a header line 'time,<track>.w,...')"
    elif case == "blank first line":
        src = tmp_path / "blank.csv"
        src.write_text("\n\n")
        want = f"{src}:1: the first line is empty"
    elif case == "garbage npz":
        src = tmp_path / "g.npz"
        src.write_bytes(np.random.default_rng(1).bytes(300))
        want = f"{src}: not an NPZ archive of arrays (numpy.savez writes them)"
    elif case == "missing times file":
        extra = ["--times", tmp_path / "nosuch.txt"]
        want = f"{tmp_path / 'nosuch.txt'}: No such file or directory"
    elif case == "missing input":
        src = tmp_path / "nosuch.csv"
        want = f"{src}: No such file or directory"
    elif case == "fps 1e308":
        extra = ["--fps", "1e308"]
        want = f"{src}: a rate of 1e+308 fps over 4 s asks for inf frames; the limit is 1,073,741,824 values"
    elif case == "not utf-8 in a bvh header":
        lines = open(example_path("walk.bvh"), "rb").read().split(b"\n")
        lines[1] += b" \xff"
        src = tmp_path / "bad.bvh"
        src.write_bytes(b"\n".join(lines))
        res = run("resample", src, "-o", tmp_path / "out.bvh", "--fps", "10")
        assert res.returncode == 0, res.stderr    # the hierarchy is kept as bytes; no number is touched
        assert open(tmp_path / "out.bvh", "rb").read().split(b"\n")[1] == lines[1]
        return
    else:
        (tmp_path / "t.txt").write_bytes(b"0\n0.5\xff\n")
        extra = ["--times", tmp_path / "t.txt"]
        want = f"{tmp_path / 't.txt'}:2: non-numeric value '0.5\\xff' (not UTF-8 text) (value 1)"
    err = one_line_error(run("resample", src, "-o", tmp_path / ("out" + os.path.splitext(str(src))[1]),
                             *(extra or ["--fps", "10"])))
    assert err.startswith(f"quatarray: error: {want}"), err
    assert "pickle" not in err and "not found." not in err and "codec" not in err


def test_summary_line_grammar(tmp_path):
    src = tmp_path / "in.csv"
    src.write_text("time,q.w,q.x,q.y,q.z\n0,1,0,0,0\n1,0,1,0,0\n")
    times = tmp_path / "t.txt"
    times.write_text("0.5\n")
    res = run("resample", src, "-o", tmp_path / "out.csv", "--times", times)
    assert res.returncode == 0 and f"{src}: 2 keys -> {tmp_path / 'out.csv'}: 1 frame (slerp, " in res.stdout


def test_method_spline_on_the_command_line(tmp_path):
    """--method spline is Track(method='spline') (scipy's RotationSpline curve), as in the API."""
    out = tmp_path / "out.npz"
    res = run("resample", example_path("arm.csv"), "-o", out, "--fps", 10, "--method", "spline")
    assert res.returncode == 0, res.stderr
    want = resample_keyframes(read_csv(example_path("arm.csv")), fps_times(0.0, 4.0, 10), method="spline")
    np.testing.assert_array_equal(read_npz(out).keys, want.keys)
    assert "{slerp,linear,squad,bezier,spline}" in run("resample", "--help").stdout


def test_files_the_demo_writes_are_ignored_by_git(tmp_path, capsys):
    """After the README's first command (quatarray demo, in the checkout) git status showed
    demo_arm.glb and demo_imu.csv: every file the demo writes must match a .gitignore pattern."""
    import fnmatch
    path = os.path.join(ROOT, ".gitignore")
    if not os.path.exists(path):
        pytest.skip("not a source checkout (no .gitignore)")
    patterns = [p.strip().rstrip("/") for p in open(path) if p.strip() and not p.startswith("#")]
    cli.demo(str(tmp_path), file=sys.stdout)
    capsys.readouterr()
    written = os.listdir(tmp_path)
    assert {"demo_arm.glb", "demo_imu.csv"} <= set(written)
    assert [n for n in written if not any(fnmatch.fnmatch(n, p.lstrip("/")) for p in patterns)] == []


def test_precision_help_states_the_precision_rule():
    """--help states the rule the files follow: only a key at its own time is written as read, in
    the input's number style (it said 'default: as many as the input has', the old rule that
    rounded interpolated values)."""
    text = " ".join(run("resample", "--help").stdout.split())
    assert "as many as the input has" not in text
    assert "a key at its own time is written as read, in the input's number style" in text
    assert "every interpolated value is written in full" in text


def test_demo_says_why_squad_and_bezier_overlap(tmp_path, capsys):
    """Their printed numbers agree to 2 decimals; the demo says by how much |w| differs, and that is true."""
    cli.demo(str(tmp_path), file=sys.stdout)
    out = capsys.readouterr().out
    said = re.search(r"their \|w\| differs by at most ([0-9.]+) rad/s", out)
    assert said, out
    kf = read_csv(example_path("arm.csv"))
    t = fps_times(kf.times[0], kf.times[-1], 120)
    from quatarray import Track
    speed = {m: np.linalg.norm(np.asarray(Track(kf.times, kf.keys, method=m).angular_velocity(t)), axis=-1)
             for m in ("squad", "bezier")}
    assert float(said.group(1)) == round(float(np.abs(speed["squad"] - speed["bezier"]).max()), 3) > 0


def test_a_full_disk_is_one_line_naming_the_output(tmp_path, monkeypatch, capsys):
    import errno

    from quatarray.formats import csv as qcsv

    def full(f, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(qcsv, "write_rows", full)
    out = tmp_path / "o.csv"
    assert cli.main(["resample", example_path("arm.csv"), "-o", str(out), "--fps", "30"]) == 2
    assert capsys.readouterr().err == f"quatarray: error: {out}: No space left on device\n"
    assert os.listdir(tmp_path) == []


def test_ctrl_c_while_the_command_imports_prints_no_traceback(tmp_path):
    """SIGINT while NumPy is being imported (held there by a finder that waits): no traceback."""
    (tmp_path / "sitecustomize.py").write_text(
        "import sys, time\n"
        "class Wait:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'numpy':\n"
        "            print('importing', flush=True)\n"
        "            time.sleep(30)\n"
        "        return None\n"
        "sys.meta_path.insert(0, Wait())\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), ROOT]))
    proc = subprocess.Popen([sys.executable, "-m", "quatarray", "--version"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stdout.readline() == "importing\n"
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert proc.returncode in (130, -signal.SIGINT)
