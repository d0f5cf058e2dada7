"""CSV and NPZ keyframe files, query times, atomic writes (quatarray.formats)."""

import errno
import os
import re
import stat
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from .conftest import random_quats, tol
from quatarray import formats as qio
from quatarray.formats import csv as qcsv, text as _text
from quatarray.formats import (FormatError, Keyframes, fps_times, read_csv, read_npz, read_times,
                           resample_keyframes, write_csv, write_npz)

METHODS = ("slerp", "squad", "bezier", "linear")


def smooth_keys(rng, n, batch=(), dtype=np.float64):
    """Unit keys, each within ~35 degrees of the previous one (same hemisphere)."""
    q = np.empty((n,) + tuple(batch) + (4,))
    q[0] = random_quats(rng, batch)
    for k in range(1, n):
        step = random_quats(rng, batch)
        step[..., 0] = np.abs(step[..., 0]) + 3.0
        q[k] = q[k - 1] + 0.3 * step / np.linalg.norm(step, axis=-1, keepdims=True)
        q[k] /= np.linalg.norm(q[k], axis=-1, keepdims=True)
    return q.astype(dtype)


def uneven_times(rng, n):
    return np.cumsum(rng.uniform(0.05, 1.0, n)) - 0.3


def write_text(path, text):
    with open(path, "w", newline="") as f:
        f.write(text)
    return path


# --------------------------------------------------------------------------- CSV

@pytest.mark.parametrize("scalar_last", [False, True], ids=["wxyz", "xyzw"])
def test_csv_write_read_is_exact(tmp_path, rng, scalar_last):
    kf = Keyframes(uneven_times(rng, 9), smooth_keys(rng, 9, (3,)), ("hip", "left.knee", "b c"))
    path = tmp_path / "k.csv"
    write_csv(path, kf, scalar_last=scalar_last)
    back = read_csv(path, scalar_last=scalar_last)
    assert back.names == kf.names
    np.testing.assert_array_equal(back.times, kf.times)
    np.testing.assert_array_equal(back.keys, kf.keys)


@pytest.mark.parametrize("scalar_last", [False, True], ids=["wxyz", "xyzw"])
def test_csv_layout(tmp_path, scalar_last):
    kf = Keyframes(np.array([0.0, 0.5]), np.array([[[1.0, 2.0, 3.0, 4.0]], [[5.0, 6.0, 7.0, 8.0]]]), ("a",))
    path = tmp_path / "k.csv"
    write_csv(path, kf, scalar_last=scalar_last)
    header, first, _ = path.read_text().split("\n", 2)
    order = "xyzw" if scalar_last else "wxyz"
    assert header.split(",") == ["time"] + [f"a.{c}" for c in order]
    cells = [float(c) for c in first.split(",")]
    assert cells[1:] == [dict(zip("wxyz", kf.keys[0, 0]))[c] for c in order]


def test_csv_names_default_from_batch(tmp_path, rng):
    keys = smooth_keys(rng, 3, (2, 2))
    path = tmp_path / "k.csv"
    write_csv(path, Keyframes(np.arange(3.0), keys))
    back = read_csv(path)
    assert back.names == ("q0", "q1", "q2", "q3")
    np.testing.assert_array_equal(back.keys, keys.reshape(3, 4, 4))


@pytest.mark.parametrize("names, match", [(("Arm", "arm"), "differ other than in case"), (("a", ""), "non-empty"),
                                          (("a", "b\nc"), "no line break"), ((" sp ", "b"), "spaces at either end")])
def test_csv_refuses_names_it_could_not_read_back(tmp_path, rng, names, match):
    path = tmp_path / "k.csv"
    with pytest.raises(ValueError, match=match):
        write_csv(path, Keyframes(np.arange(3.0), smooth_keys(rng, 3, (2,)), names))
    assert not path.exists()
    write_csv(path, Keyframes(np.arange(3.0), smooth_keys(rng, 3, (2,)), ("Arm", "arm.2")))   # these read back
    assert read_csv(path).names == ("Arm", "arm.2")


def test_csv_reads_shipped_example():
    kf = read_csv(qio.example_path("arm.csv"))
    assert kf.keys.shape == (len(kf.times), len(kf.names), 4)
    assert (np.diff(kf.times) > 0).all() and np.ptp(np.diff(kf.times)) > 0  # unequally spaced
    np.testing.assert_allclose(np.linalg.norm(kf.keys, axis=-1), 1, atol=1e-8)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("scalar_last", [False, True], ids=["wxyz", "xyzw"])
def test_csv_resample_at_key_times_reproduces_input(tmp_path, rng, method, scalar_last):
    src, dst = tmp_path / "in.csv", tmp_path / "out.csv"
    write_csv(src, Keyframes(uneven_times(rng, 8), smooth_keys(rng, 8, (3,)), ("a", "b", "c")),
              scalar_last=scalar_last)
    kf = read_csv(src, scalar_last=scalar_last)
    write_csv(dst, resample_keyframes(kf, kf.times, method=method), scalar_last=scalar_last)
    back = read_csv(dst, scalar_last=scalar_last)
    assert back.names == kf.names
    np.testing.assert_array_equal(back.times, kf.times)
    np.testing.assert_allclose(back.keys, kf.keys, rtol=0, atol=1e-12)


def test_csv_tolerates_blank_lines_crlf_and_spaces(tmp_path):
    path = write_text(tmp_path / "k.csv", "time, a.w ,a.x,a.y,a.z\r\n0, 1,0,0,0\r\n\r\n1 ,0,1,0,0\r\n")
    kf = read_csv(path)
    np.testing.assert_array_equal(kf.times, [0, 1])
    np.testing.assert_array_equal(kf.keys[:, 0], [[1, 0, 0, 0], [0, 1, 0, 0]])


HEADER = "time,a.w,a.x,a.y,a.z\n"
CSV_ERRORS = {  # text, line of the problem, message pattern
    "no time": ("t,a.w,a.x,a.y,a.z\n0,1,0,0,0\n", 1, r"no 'time' column, got 't,a.w,a.x,a.y,a.z'"),
    "two times": ("time,a.w,a.x,a.y,a.z,Time\n0,1,0,0,0,0\n", 1, r"columns 1 and 6 are both 'time'"),
    "bad component": ("time,a.w,a.x,a.y,a.q\n0,1,0,0,0\n", 1, r"column 5 is 'a.q', expected 'time' or"),
    "partial track": ("time,a.w,a.x,a.y\n0,1,0,0\n", 1, r"track 'a' has 3 of its 4 columns \(no 'a.z'\)"),
    "split tracks": ("time,a.w,a.x,b.y,b.z\n0,1,0,0,0\n", 1, r"track 'a' has 2 of its 4 columns \(no 'a.y', 'a.z'\)"),
    "no dot": ("time,angle\n0,1\n", 1, r"column 2 is 'angle', expected 'time' or '<track>.w'"),
    "twice": ("time,a.w,a.x,a.y,a.z,A.W\n0,1,0,0,0,1\n", 1, r"column 6 \('A.W'\) repeats column 2 \('a.w'\)"),
    "no tracks": ("time\n0\n", 1, r"no quaternion columns"),
    "empty file": ("", None, r"the file is empty"),
    "non-numeric": (HEADER + "0,1,0,0,0\n1,1,0,abc,0\n", 3, r"non-numeric value 'abc' in column 'a.y'"),
    "empty cell": (HEADER + "0,1,0,0,0\n1,1,0,,0\n", 3, r"non-numeric value '' in column 'a.y'"),
    "short row": (HEADER + "0,1,0,0,0\n\n1,1,0,0,0\n2,1,0,0\n", 5, r"expected 5 values, got 4"),
    "long row": (HEADER + "0,1,0,0,0,7\n", 2, r"expected 5 values, got 6"),
    "short only row": (HEADER + "0,1,0,0\n", 2, r"expected 5 values, got 4"),
    "nan time": (HEADER + "0,1,0,0,0\nnan,1,0,0,0\n", 3, r"non-finite time"),
    "inf key": (HEADER + "0,1,0,0,0\n\n1,1,inf,0,0\n", 4, r"track 'a': non-finite"),
    "repeated time": (HEADER + "0,1,0,0,0\n1,1,0,0,0\n1,0,1,0,0\n", 4, r"time 1.0 does not come after 1.0"),
    "decreasing time": (HEADER + "0,1,0,0,0\n-1,1,0,0,0\n", 3, r"strictly increasing"),
    "zero quaternion": (HEADER + "0,1,0,0,0\n1,0,0,0,0\n", 3, r"track 'a': zero quaternion"),
    "no rows": (HEADER, None, r"no keyframes"),
}


@pytest.mark.parametrize("case", CSV_ERRORS)
def test_csv_errors_name_file_and_line(tmp_path, case):
    text, line, pattern = CSV_ERRORS[case]
    path = write_text(tmp_path / "bad.csv", text)
    with pytest.raises(FormatError, match=pattern) as info:
        read_csv(path)
    assert info.value.path == str(path)
    assert info.value.line == line
    assert str(info.value).startswith(f"{path}:{line}: " if line else f"{path}: ")


def test_csv_columns_are_matched_by_name_in_any_order(tmp_path):
    """time last, tracks interleaved, x, y, z, w, any case: the same keyframes as the plain layout."""
    plain = write_text(tmp_path / "plain.csv", "time,a.w,a.x,a.y,a.z,b.w,b.x,b.y,b.z\n"
                                               "0,1,0,0,0,0.6,0.8,0,0\n1,0,1,0,0,0,0,0.8,0.6\n")
    mixed = write_text(tmp_path / "mixed.csv", "B.Z,a.X,b.x,A.y,b.W,a.z,B.y,a.W,TIME\n"
                                               "0,0,0.8,0,0.6,0,0,1,0\n0.6,1,0,0,0,0,0.8,0,1\n")
    want, got = read_csv(plain), read_csv(mixed)
    assert got.names == ("B", "a")       # in the order of their first column, as first written
    np.testing.assert_array_equal(got.keys[:, ::-1], want.keys)
    np.testing.assert_array_equal(got.times, want.times)
    assert read_csv(mixed, scalar_last=True).keys.tolist() == got.keys.tolist()


def test_csv_scalar_last_files_are_written_back_scalar_last(tmp_path):
    src = write_text(tmp_path / "k.csv", "time,q.x,q.y,q.z,q.w\n0,0,0,0,1\n1,1,0,0,0\n")
    kf = read_csv(src)
    assert kf.style.scalar_last and kf.keys[0, 0].tolist() == [1, 0, 0, 0]
    write_csv(tmp_path / "out.csv", kf)
    assert (tmp_path / "out.csv").read_text() == src.read_text()
    write_csv(tmp_path / "first.csv", kf, scalar_last=False)
    assert (tmp_path / "first.csv").read_text().startswith("time,q.w,q.x,q.y,q.z\n0,1,0,0,0\n")


def test_csv_header_of_250000_tracks_with_a_repeat(tmp_path):
    """The repeated-column check is one pass (it was quadratic: 277 s for 250,000 tracks)."""
    n = 250_000
    header = "time," + ",".join(f"t{j}.{c}" for j in range(n) for c in "wxyz")
    path = write_text(tmp_path / "wide.csv", header + ",T7.W\n")
    with pytest.raises(FormatError, match=rf"column {4 * n + 2} \('T7.W'\) repeats column 30 \('t7.w'\)"):
        read_csv(path)


# --------------------------------------------------------------------------- NPZ

def test_npz_write_read_is_exact(tmp_path, rng, batch_shape, dtype):
    kf = Keyframes(uneven_times(rng, 5), smooth_keys(rng, 5, batch_shape, dtype))
    path = tmp_path / "k.npz"
    write_npz(path, kf)
    back = read_npz(path)
    assert back.keys.dtype == dtype and back.keys.shape == kf.keys.shape
    np.testing.assert_array_equal(back.times, kf.times)
    np.testing.assert_array_equal(back.keys, kf.keys)


@pytest.mark.parametrize("method", METHODS)
def test_npz_resample_at_key_times_reproduces_input(tmp_path, rng, batch_shape, dtype, method):
    src, dst = tmp_path / "in.npz", tmp_path / "out.npz"
    write_npz(src, Keyframes(uneven_times(rng, 6), smooth_keys(rng, 6, batch_shape, dtype)))
    kf = read_npz(src)
    write_npz(dst, resample_keyframes(kf, kf.times, method=method))
    back = read_npz(dst)
    np.testing.assert_array_equal(back.times, kf.times)
    assert back.keys.shape == kf.keys.shape
    atol = 1e-12 if dtype == np.float64 else tol(dtype, 8)
    np.testing.assert_allclose(back.keys, kf.keys, rtol=0, atol=atol)


def test_resample_between_keys_moves_between_them(rng):
    kf = Keyframes(np.array([0.0, 2.0]), smooth_keys(rng, 2, (4,)))
    mid = resample_keyframes(kf, np.array([1.0])).keys[0]
    # slerp midpoint of unit keys: the normalised sum
    expected = kf.keys.sum(axis=0) / np.linalg.norm(kf.keys.sum(axis=0), axis=-1, keepdims=True)
    np.testing.assert_allclose(mid, expected, atol=1e-12)


def test_resample_outside_keys(rng):
    kf = Keyframes(np.array([0.0, 1.0, 2.0]), smooth_keys(rng, 3))
    with pytest.raises(ValueError, match=r"query time 2.5 is outside the key times \[0.0, 2.0\]"):
        resample_keyframes(kf, np.array([0.0, 2.5]))
    clamped = resample_keyframes(kf, np.array([-1.0, 3.0]), extrapolate="clamp").keys
    np.testing.assert_allclose(clamped, kf.keys[[0, 2]], atol=1e-12)


def test_resample_needs_two_keys(rng):
    with pytest.raises(ValueError, match=r"at least 2 keyframes to interpolate, got 1"):
        resample_keyframes(Keyframes(np.array([0.0]), smooth_keys(rng, 1)), np.array([0.0]))


def npz_bytes(tmp_path, **arrays):
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    return path


GOOD = dict(times=np.arange(3.0), keys=np.tile([1.0, 0, 0, 0], (3, 2, 1)))
NPZ_ERRORS = {  # arrays, message pattern
    "missing keys": (dict(times=GOOD["times"]), r"missing array 'keys' \(found times\)"),
    "missing times": (dict(keys=GOOD["keys"], t=GOOD["times"]), r"missing array 'times'"),
    "2-d times": (dict(times=GOOD["times"][:, None], keys=GOOD["keys"]), r"times of shape \(K,\), got \(3, 1\)"),
    "3 components": (dict(times=GOOD["times"], keys=GOOD["keys"][..., :3]), r"keys of shape \(..., 4\), got"),
    "1-d keys": (dict(times=GOOD["times"][:1], keys=GOOD["keys"][0, 0]), r"keys of shape \(1, ..., 4\)"),
    "length": (dict(times=GOOD["times"][:2], keys=GOOD["keys"]), r"keys of shape \(2, ..., 4\) to match"),
    "strings": (dict(times=GOOD["times"], keys=np.full((3, 4), "a")), r"keys of real numbers"),
    "empty": (dict(times=np.zeros(0), keys=np.zeros((0, 4))), r"no keyframes"),
    "nan time": (dict(times=[0.0, np.nan, 2.0], keys=GOOD["keys"]), r"times\[1\]: non-finite time"),
    "inf key": (dict(times=GOOD["times"], keys=np.where(np.arange(4) == 2, np.inf, GOOD["keys"])),
                r"keys\[0, 0\]: non-finite"),
    "not increasing": (dict(times=[0.0, 2.0, 2.0], keys=GOOD["keys"]), r"times\[2\]: time 2.0 does not come after"),
    "zero quaternion": (dict(times=GOOD["times"], keys=GOOD["keys"] * [[[1], [1]], [[1], [0]], [[1], [1]]]),
                        r"keys\[1, 1\]: zero quaternion"),
}


@pytest.mark.parametrize("case", NPZ_ERRORS)
def test_npz_errors_name_file(tmp_path, case):
    arrays, pattern = NPZ_ERRORS[case]
    path = npz_bytes(tmp_path, **arrays)
    with pytest.raises(FormatError, match=pattern) as info:
        read_npz(path)
    assert info.value.path == str(path) and info.value.line is None


def test_npz_and_zarr_data_besides_the_keyframes_is_named(tmp_path, rng, capsys):
    """Arrays (and Zarr attributes) other than the keyframes are not read: a warning names them,
    on the command line one line (an output written from the file lacks them)."""
    from quatarray.cli import main
    keys = smooth_keys(rng, 3, (2,))
    np.savez(tmp_path / "x.npz", times=np.arange(3.0), keys=keys, fps=30, meta=np.arange(3))
    with pytest.warns(qio.NotCarriedWarning, match=r"x.npz: holds arrays besides the keyframes \('fps', 'meta'\)"):
        kf = read_npz(tmp_path / "x.npz")
    np.testing.assert_array_equal(kf.keys, keys)
    assert main(["resample", str(tmp_path / "x.npz"), "-o", str(tmp_path / "y.npz"), "--fps", "2"]) == 0
    err = capsys.readouterr().err
    assert err.count("quatarray: warning:") == 1 and "('fps', 'meta')" in err
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_npz(tmp_path / "y.npz")   # what quatarray writes holds only the keyframes
    zarr = pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    qio.write_zarr(str(tmp_path / "s.zarr"), kf)
    group = zarr.open_group(str(tmp_path / "s.zarr"))
    group.attrs["subject"] = "S1"
    group["extra"] = np.arange(2.0)
    with pytest.warns(qio.NotCarriedWarning) as caught:
        qio.read_zarr(str(tmp_path / "s.zarr"))
    assert sorted(str(w.message).split("(")[1].split(")")[0] for w in caught) == ["'extra'", "'subject'"]


def test_npz_not_an_archive(tmp_path):
    text = write_text(tmp_path / "bad.npz", "time,a.w\n")
    with pytest.raises(FormatError, match=r"not an NPZ archive"):
        read_npz(text)
    single = tmp_path / "one.npz"
    with open(single, "wb") as f:
        np.save(f, np.zeros(3))
    with pytest.raises(FormatError, match=r"not an NPZ archive of arrays \(a single .npy array\)"):
        read_npz(single)


@pytest.mark.parametrize("array", ["keys", "names"])
def test_npz_of_pickled_objects_is_named_without_numpys_pickle_advice(tmp_path, capsys, array):
    """An archive whose array holds Python objects: NumPy's 'allow_pickle=False' advice leaked
    ("unreadable array (Object arrays cannot be loaded when allow_pickle=False)"); the message names
    the array and says what an NPZ of keyframes holds."""
    from quatarray.cli import main
    arrays = {"times": [0.0, 1.0], "keys": [[1.0, 0, 0, 0], [0, 1.0, 0, 0]], "names": ["q"]}
    arrays[array] = np.array([None, None], dtype=object)
    np.savez(tmp_path / "obj.npz", **arrays)
    with pytest.raises(FormatError, match=f"array '{array}' holds pickled Python objects; expected numbers"):
        read_npz(tmp_path / "obj.npz")
    assert main(["resample", str(tmp_path / "obj.npz"), "-o", str(tmp_path / "out.npz"), "--fps", "2"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"quatarray: error: {tmp_path / 'obj.npz'}: array '{array}' holds pickled") and "pickle=" not in err
    assert not (tmp_path / "out.npz").exists()


def test_npz_integer_times_and_keys_become_float(tmp_path):
    path = npz_bytes(tmp_path, times=np.arange(2), keys=np.array([[1, 0, 0, 0], [0, 1, 0, 0]]))
    kf = read_npz(path)
    assert kf.times.dtype == np.float64 and kf.keys.dtype == np.float64


# --------------------------------------------------------------------------- query times

def test_read_times(tmp_path):
    path = write_text(tmp_path / "t.txt", "0\n 0.25\n\n1e-0\n")
    np.testing.assert_array_equal(read_times(path), [0.0, 0.25, 1.0])


@pytest.mark.parametrize("text, line, pattern", [
    ("0\n0.5\nsoon\n", 3, r"non-numeric value 'soon'"),
    ("0\n0.5 0.7\n", 2, r"expected 1 time on the line, got 2"),
    ("0\n0.5\n0.5\n", 3, r"does not come after"),
    ("0\n \t\n0.5\n\n0.5\n", 5, r"does not come after"),  # blank lines still counted
    ("0\ninf\n", 2, r"non-finite time"),
    ("\n", None, r"no times"),
])
def test_read_times_errors(tmp_path, text, line, pattern):
    path = write_text(tmp_path / "t.txt", text)
    with pytest.raises(FormatError, match=pattern) as info:
        read_times(path)
    assert info.value.line == line and info.value.path == str(path)


@pytest.mark.parametrize("t0, t1, fps, n", [
    (0.0, 0.1 * 3, 10, 4),            # 0.30000000000000004: last key kept
    (0.0, 1 - 1e-13, 10, 11),         # short of 1.0 by rounding only: kept, moved onto t1
    (0.0, 0.95, 10, 10),              # really short: 0.9 is the last sample
    (-2.0, 2.0, 0.5, 3),
    (5.0, 5.0 + 1 / 3, 3, 2),
])
def test_fps_times_cases(t0, t1, fps, n):
    t = fps_times(t0, t1, fps)
    assert len(t) == n and t[0] == t0 and t[-1] <= t1
    np.testing.assert_allclose(t, t0 + np.arange(n) / fps, rtol=0, atol=1e-12 * max(1, abs(t1)))


@given(t0=st.floats(-1e3, 1e3), span=st.floats(1e-3, 1e3), fps=st.floats(0.5, 1e3))
def test_fps_times_cover_the_keys(t0, span, fps):
    t1 = t0 + span
    t = fps_times(t0, t1, fps)
    assert t[0] == t0 and t[-1] <= t1
    assert (np.diff(t) > 0).all()
    assert t1 - t[-1] < 1 / fps * (1 + 1e-9)  # no further sample fits
    np.testing.assert_allclose(np.diff(t)[:-1], 1 / fps, rtol=1e-6)


def test_fps_times_rejects_bad_rate():
    with pytest.raises(ValueError, match=r"expected fps > 0, got 0"):
        fps_times(0.0, 1.0, 0)


# --------------------------------------------------------------------------- atomic writes, errors

def test_failed_write_leaves_target_untouched(tmp_path, rng, monkeypatch):
    path = tmp_path / "k.csv"
    path.write_text("precious\n")
    calls = []

    def broken(f, rows, *args, **kwargs):
        f.write("half a row")
        calls.append(1)
        raise RuntimeError("disk full")

    monkeypatch.setattr(qcsv, "write_rows", broken)
    with pytest.raises(RuntimeError, match="disk full"):
        write_csv(path, Keyframes(np.arange(3.0), smooth_keys(rng, 3)))
    assert calls and path.read_text() == "precious\n"
    assert os.listdir(tmp_path) == ["k.csv"]  # no temporary left behind


def test_new_file_has_usual_permissions(tmp_path, rng):
    path = tmp_path / "k.npz"
    write_npz(path, Keyframes(np.arange(3.0), smooth_keys(rng, 3)))
    mask = os.umask(0)
    os.umask(mask)
    assert os.stat(path).st_mode & 0o777 == 0o666 & ~mask
    assert os.listdir(tmp_path) == ["k.npz"]


def test_write_into_missing_folder_names_the_target(tmp_path, rng):
    path = tmp_path / "nowhere" / "k.csv"
    with pytest.raises(FileNotFoundError) as info:
        write_csv(path, Keyframes(np.arange(3.0), smooth_keys(rng, 3)))
    assert info.value.filename == str(path)


@pytest.mark.parametrize("name", ["k" * 251 + ".csv", "x" + "\u00e9" * 125 + ".csv", "\u4e2d" * 83 + "kk.csv"],
                         ids=["ascii", "two-byte", "three-byte"])
def test_longest_file_names_are_written(tmp_path, rng, monkeypatch, name):
    # 255 bytes, the most a file name may have: ".{name}.{random}.part" did not fit from 241 bytes on
    # ("File name too long"); the temporary's name holds the target's cut at a character
    assert len(name.encode("utf-8")) == 255
    temporaries, replace = [], os.replace

    def recording(src, dst):
        temporaries.append(os.path.basename(src))
        replace(src, dst)

    monkeypatch.setattr(os, "replace", recording)
    kf = Keyframes(np.arange(3.0), smooth_keys(rng, 3))
    write_csv(tmp_path / name, kf)
    assert os.listdir(tmp_path) == [name]
    np.testing.assert_array_equal(read_csv(tmp_path / name).times, kf.times)
    (tmp,) = temporaries
    assert len(tmp.encode("utf-8")) <= 255 and tmp.startswith(".") and tmp.endswith(".part")
    kept = tmp[1:-len(".12345678.part")]
    assert name.startswith(kept) and len(kept.encode("utf-8")) >= 235


def test_atomic_writes_reach_the_disk_before_the_rename(tmp_path, monkeypatch):
    """The temporary file is synced before it is renamed, and its folder after: after a crash
    the name holds the old file or the whole new one, never an empty one."""
    from quatarray.formats import atomic
    events = []
    fsync, replace = os.fsync, os.replace
    monkeypatch.setattr(os, "fsync", lambda fd: events.append(("fsync", stat.S_ISDIR(os.fstat(fd).st_mode)))
                        or fsync(fd))
    monkeypatch.setattr(os, "replace", lambda a, b: events.append(("replace", None)) or replace(a, b))
    with atomic.atomic_write(tmp_path / "a.txt") as f:
        f.write("new")
    assert events == [("fsync", False), ("replace", None), ("fsync", True)]
    assert (tmp_path / "a.txt").read_text() == "new"


def test_files_written_together_are_replaced_together(tmp_path, monkeypatch):
    # new.txt does not exist yet, old.txt does; the third rename fails: the first two are undone
    from quatarray.formats.atomic import atomic_files
    (tmp_path / "old.txt").write_text("old")
    os.chmod(tmp_path / "old.txt", 0o640)
    names = ["new.txt", "old.txt", "last.txt"]
    renamed, replace = [], os.replace

    def failing_third(a, b):
        renamed.append(os.path.basename(b))
        if len(renamed) == 3:
            raise PermissionError(errno.EACCES, "Permission denied")
        replace(a, b)

    monkeypatch.setattr(os, "replace", failing_third)
    with pytest.raises(PermissionError) as info, atomic_files() as files:
        for name in names:
            with files.open(tmp_path / name) as f:
                f.write(name * 2)
    assert info.value.filename == str(tmp_path / "last.txt")
    assert renamed == names + ["old.txt"]          # old.txt put back; new.txt removed
    assert os.listdir(tmp_path) == ["old.txt"] and (tmp_path / "old.txt").read_text() == "old"
    assert os.stat(tmp_path / "old.txt").st_mode & 0o777 == 0o640
    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(RuntimeError, match="stop"), atomic_files() as files:   # an error inside: nothing renamed
        with files.open(tmp_path / "new.txt") as f:
            f.write("new")
        raise RuntimeError("stop")
    assert os.listdir(tmp_path) == ["old.txt"]
    with atomic_files() as files:
        for name in names:
            with files.open(tmp_path / name) as f:
                f.write(name * 2)
    assert {name: (tmp_path / name).read_text() for name in os.listdir(tmp_path)} == {n: n * 2 for n in names}
    assert os.stat(tmp_path / "old.txt").st_mode & 0o777 == 0o640


def test_format_error_text():
    assert str(FormatError("bad", "a.csv", 3)) == "a.csv:3: bad"
    assert str(FormatError("bad", "a.csv")) == "a.csv: bad"
    assert str(FormatError("two\nlines")) == "two lines"
    assert isinstance(FormatError("x"), ValueError)


# --------------------------------------------------------------------------- faithful text, separators, names

def test_style_of_shipped_example():
    style = read_csv(qio.example_path("arm.csv")).style
    assert (style.decimals, style.trim, style.newline, style.delimiter) == (9, False, "\n", ",")
    assert (style.time_decimals, style.time_trim) == (2, True)  # 0, 0.3, 0.55


@pytest.mark.parametrize("newline", ["\n", "\r\n"])
@pytest.mark.parametrize("sep", [",", "\t", ";"])
def test_csv_written_back_as_read(tmp_path, newline, sep):
    """Separator, line endings, decimals (trimmed or fixed) and short times all survive read + write."""
    text = (f"Time{sep}a.w{sep}a.x{sep}a.y{sep}a.z\n0{sep}1{sep}0{sep}0{sep}0\n"
            f"0.25{sep}0.5{sep}0.5{sep}0.5{sep}0.5\n1.5{sep}0.70711{sep}0{sep}0.70711{sep}0\n").replace("\n", newline)
    src = tmp_path / "in.csv"
    src.write_bytes(text.encode())
    kf = read_csv(src)
    np.testing.assert_array_equal(kf.keys[:, 0], [[1, 0, 0, 0], [0.5] * 4, [0.70711, 0, 0.70711, 0]])
    assert kf.style.delimiter == sep and kf.style.newline == newline
    out = tmp_path / "out.csv"
    write_csv(out, kf)
    assert out.read_bytes() == text.replace("Time", "time").encode()


def test_csv_time_header_any_case(tmp_path):
    for word in ("Time", "TIME", "time"):
        kf = read_csv(write_text(tmp_path / "k.csv", f"{word},a.w,a.x,a.y,a.z\n0,1,0,0,0\n1,0,1,0,0\n"))
        np.testing.assert_array_equal(kf.times, [0, 1])


def test_csv_other_separator_is_named(tmp_path):
    with pytest.raises(FormatError, match=r"separator must be a comma, a tab or a semicolon"):
        read_csv(write_text(tmp_path / "k.csv", "time|a.w|a.x|a.y|a.z\n0|1|0|0|0\n"))
    with pytest.raises(FormatError, match=r"non-numeric value '0,5' in column 'a.x' \(decimal commas"):
        read_csv(write_text(tmp_path / "k.csv", "time;a.w;a.x;a.y;a.z\n0;1;0,5;0;0\n"))


def test_huge_header_cell_is_one_line_error(tmp_path):
    path = write_text(tmp_path / "k.csv", "time," + "a" * 200_000 + ".w\n0,1\n")
    with pytest.raises(FormatError) as info:
        read_csv(path)
    assert info.value.line == 1 and len(str(info.value)) < 300
    path = write_text(tmp_path / "k.csv", "time,\"" + "a" * 200_000 + "\"\n0,1\n")
    with pytest.raises(FormatError, match=r"bad header: field larger than field limit") as info:
        read_csv(path)
    assert info.value.line == 1


def test_huge_bad_cell_is_cut_in_the_message(tmp_path):
    path = write_text(tmp_path / "k.csv", HEADER + "0,1,0,0,0\n1," + "x" * 1_000_000 + ",0,0,0\n")
    with pytest.raises(FormatError, match=r"non-numeric value '(x+)\.\.\.' \(1000000 characters\)") as info:
        read_csv(path)
    assert len(str(info.value)) < len(str(path)) + 150
    echoed = str(info.value).split("'")[1]
    assert 40 <= len(echoed) <= 60 and echoed.endswith("...")      # cut to about 60 characters


def test_npz_keeps_track_names(tmp_path, rng):
    kf = Keyframes(uneven_times(rng, 4), smooth_keys(rng, 4, (3,)), ("hip", "knee", "a b"))
    write_npz(tmp_path / "k.npz", kf)
    assert read_npz(tmp_path / "k.npz").names == kf.names
    write_npz(tmp_path / "n.npz", Keyframes(kf.times, kf.keys))
    assert read_npz(tmp_path / "n.npz").names is None and "names" not in np.load(tmp_path / "n.npz").files


@pytest.mark.parametrize("names", [np.array(["a", "b"]), np.array([1, 2, 3]), np.array([["a", "b", "c"]])])
def test_npz_bad_names(tmp_path, names):
    path = npz_bytes(tmp_path, times=np.arange(2.0), keys=np.tile([1.0, 0, 0, 0], (2, 3, 1)), names=names)
    with pytest.raises(FormatError, match=r"expected names of shape \(3,\), one string per track"):
        read_npz(path)


def test_size_is_checked_before_allocating():
    with pytest.raises(ValueError, match=r"a rate of 1e\+09 fps over 4 s asks for 4,000,000,001 frames of 13 "
                                         r"values .* the limit is 1,073,741,824 values"):
        fps_times(0.0, 4.0, 1e9, per_frame=13)


def test_extrapolation_error_names_the_option(rng):
    kf = Keyframes(np.array([0.0, 1.0]), smooth_keys(rng, 2))
    with pytest.raises(ValueError, match=r"extrapolate with extrapolate='clamp' or 'extend'$"):
        resample_keyframes(kf, np.array([2.0]))


def test_existing_file_keeps_its_permissions(tmp_path, rng):
    path = tmp_path / "k.csv"
    path.write_text("old\n")
    os.chmod(path, 0o640)
    write_csv(path, Keyframes(np.arange(3.0), smooth_keys(rng, 3)))
    assert os.stat(path).st_mode & 0o777 == 0o640 and read_csv(path).keys.shape == (3, 1, 4)


def test_directory_target_is_named(tmp_path, rng):
    with pytest.raises(IsADirectoryError) as info:
        write_csv(tmp_path, Keyframes(np.arange(3.0), smooth_keys(rng, 3)))
    assert info.value.filename == str(tmp_path)
    assert os.listdir(tmp_path) == []


def test_failed_rename_names_the_target(tmp_path, rng, monkeypatch):
    def refuse(src, dst):
        raise PermissionError(13, "Permission denied", src)

    monkeypatch.setattr(_text.os, "replace", refuse)
    with pytest.raises(PermissionError) as info:
        write_npz(tmp_path / "k.npz", Keyframes(np.arange(3.0), smooth_keys(rng, 3)))
    assert info.value.filename == str(tmp_path / "k.npz") and os.listdir(tmp_path) == []


def test_file_modules_share_public_in_package_names_only():
    """The format modules and cli import no `_private` name from another module; docstrings point at
    quatarray.formats, never at a private module."""
    import ast
    import inspect
    from quatarray import cli, formats
    from quatarray.formats import atomic, bvh, gltf, gltf_read, gltf_sampler, keyframes, npz, registry, zarr
    for module in (formats, qcsv, npz, keyframes, bvh, gltf, gltf_read, gltf_sampler, zarr, registry, atomic, cli,
                   _text):
        source = inspect.getsource(module)
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, ast.ImportFrom) and node.level and node.module:  # `from . import _mod` is a module
                private = [a.name for a in node.names if a.name.startswith("_")]
                assert not private, f"{module.__name__} imports {private} from {node.module}"
        assert not re.search(r"quatarray\._(io|text|bvh|gltf|zarr)", source), module.__name__
    assert set(qio.__all__) >= {"read_csv", "write_csv", "read_npz", "write_npz", "read_bvh", "write_bvh",
                                "resample_motion", "resample_keyframes", "FormatError", "Keyframes", "Motion"}
    assert all(hasattr(qio, name) for name in qio.__all__)


def test_fps_grid_reaches_a_last_key_rounded_at_clock_times():
    """EuRoC-style absolute times: a last key one ulp below t0 + 20 s is still reached at 200 Hz."""
    t0 = 1403636579.7635556
    t1 = np.nextafter(t0 + 20.0, -np.inf)
    assert (t1 - t0) * 200 < 4000
    t = fps_times(t0, t1, 200)
    assert len(t) == 4001 and t[-1] == t1
    assert len(fps_times(t0, t0 + 20.0 - 1 / 400, 200)) == 4000  # half a frame short is really short


def test_fps_grid_lands_on_every_key_at_clock_times():
    """Keys at 100 Hz written with two decimals at absolute times: the own-rate grid lands on
    every key (each grid time is within the times' own rounding of its key, 2.4e-7 s, more
    than a millionth of a frame)."""
    keys = np.round(1403636579.76 + np.arange(200) / 100, 2)
    t = fps_times(keys[0], keys[-1], 100, onto=keys)
    np.testing.assert_array_equal(t, keys)


def test_style_measured_in_blocks_of_lines_is_the_same(tmp_path, monkeypatch, rng):
    """Looking at a file 64 bytes of whole lines at a time finds the same decimals as in one go."""
    rows = ["time,a.w,a.x,a.y,a.z"] + [f"{k / 7:.{k % 3 + 1}f},{w:.6f},0,{x:.3f},1.5e-7"
                                       for k, (w, x) in enumerate(rng.uniform(-1, 1, (50, 2)))]
    path = write_text(tmp_path / "k.csv", "\r\n".join(rows) + "\r\n")
    whole = _text.measure_style(path, 1, 5)
    assert whole == _text.TextStyle(8, True, "\r\n", ",", 3, True)  # 1.5e-7 has 8 decimals
    monkeypatch.setattr(_text, "_MEASURE_BLOCK", 64)
    assert _text.measure_style(path, 1, 5) == whole


# --------------------------------------------------------------------------- precision of what is written

def _written(keys, decimals):
    """`keys` (K, tracks, 4) as the cells of a CSV file with `decimals` decimals; a key that rounds to
    zero becomes the identity (a zero quaternion is refused by the reader)."""
    text = np.char.mod(f"%.{decimals}f", keys)
    zero = (np.abs(np.char.mod(f"%.{decimals}f", keys).astype(float)) == 0).all(axis=-1)
    text[zero] = ["1", "0", "0", "0"]
    return text


@given(seed=st.integers(0, 2**32 - 1), nkeys=st.integers(2, 7), ntracks=st.integers(1, 3),
       decimals=st.integers(0, 9), method=st.sampled_from(METHODS), fps=st.sampled_from([2.0, 3.0, 7.5, 30.0]))
def test_csv_interpolated_values_are_never_rounded_to_the_inputs_decimals(seed, nkeys, ntracks, decimals, method,
                                                                          fps):
    """Random tracks written with 0-9 decimals, resampled by resample_file and read back: every
    interpolated value is within 1e-6 of the value computed from the keys as read, and unit; every
    row at a key time is that key copied, with the input's text (and sign of the curve there)."""
    import tempfile

    from quatarray import Track
    from quatarray.formats import resample_file
    rng = np.random.default_rng(seed)
    times = np.round(np.cumsum(rng.uniform(0.1, 0.6, nkeys)), 2)
    cells = _written(smooth_keys(rng, nkeys, (ntracks,)), decimals)
    header = "time," + ",".join(f"t{j}.{c}" for j in range(ntracks) for c in "wxyz")
    lines = [header] + [f"{t:.2f}," + ",".join(row.ravel()) for t, row in zip(times, cells)]
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = os.path.join(tmp, "in.csv"), os.path.join(tmp, "out.csv")
        write_text(src, "\n".join(lines) + "\n")
        resample_file(src, dst, fps=fps, method=method)
        kf, out = read_csv(src), read_csv(dst)
        out_cells = [line.split(",")[1:] for line in open(dst).read().splitlines()[1:]]
    want = np.asarray(Track(kf.times, kf.keys, method=method)(out.times))
    at_key = np.isin(out.times, kf.times)
    assert at_key[0] and at_key.sum() >= 1
    inner = ~at_key
    np.testing.assert_allclose(out.keys[inner], want[inner], rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(out.keys[inner], axis=-1), 1.0, rtol=0, atol=1e-6)
    for i in np.flatnonzero(at_key):
        k = int(np.searchsorted(kf.times, out.times[i]))
        sign = np.sign(np.einsum("ij,ij->i", kf.keys[k], want[i]))[:, None]
        np.testing.assert_array_equal(out.keys[i], np.where(sign < 0, -kf.keys[k] + 0.0, kf.keys[k]))
        unit = out.keys[i] / np.linalg.norm(out.keys[i], axis=-1, keepdims=True)
        np.testing.assert_allclose(unit, want[i], rtol=0, atol=1e-12)
        expected = [str(c) if s > 0 else c[1:] if c.startswith("-") else "-" + c if float(c) else str(c)
                    for c, s in zip(cells[k].ravel(), np.repeat(sign.ravel(), 4))]
        assert out_cells[i] == expected


def test_integer_keys_are_not_rounded_to_integers(tmp_path):
    """The issue's example: keys written as integers, resampled at 2 fps, gave 0.5,1,1,0,0."""
    from quatarray.formats import resample_file
    src = write_text(tmp_path / "in.csv", "time,q.w,q.x,q.y,q.z\n0,1,0,0,0\n1,0,1,0,0\n")
    resample_file(src, tmp_path / "out.csv", fps=2)
    lines = (tmp_path / "out.csv").read_text().splitlines()
    assert lines[1] == "0,1,0,0,0" and lines[3] == "1,0,1,0,0"
    middle = np.array(lines[2].split(","), float)
    np.testing.assert_allclose(middle, [0.5, np.sqrt(0.5), np.sqrt(0.5), 0, 0], rtol=0, atol=1e-15)


def test_fps_grid_lands_on_key_times_within_rounding():
    """0.7 + 1 / 10 is 0.7999999999999999, not the key at 0.8: within a millionth of a frame it is moved
    onto the key, so that row is the key, not an interpolation one rounding away."""
    keys = np.array([0.7, 0.8, 0.9, 1.0, 1.1, 1.3])
    plain = fps_times(0.7, 1.3, 10)
    assert plain[1] != 0.8 and plain[2] != 0.9
    t = fps_times(0.7, 1.3, 10, onto=keys)
    np.testing.assert_array_equal(t[np.isin(plain.round(9), keys)], keys)
    np.testing.assert_array_equal(t[5], plain[5])      # 1.2: no key there, the grid as computed


@pytest.mark.parametrize("decimals, keys, warns", [
    (0, "1,1,0,0", False),                # 0.7071, 0.7071 written with 0 decimals: explained
    (2, "0.71,0.71,0.00,0.00", False),
    (2, "0.80,0.80,0.00,0.00", True),     # norm 1.13: 2 decimals explain 0.01
    (9, "0.862453391,0.506136493,0.000000000,0.000000000", False),
    (4, "0.5000,0.5000,0.5000,0.5100", True),
    (4, "1,1,0,0", False),                # a key of 0 decimals among keys of 4 (a %g-style file)
])
def test_non_unit_keys_warn_once_per_file(tmp_path, decimals, keys, warns):
    import warnings

    from quatarray.formats import NonUnitKeyWarning
    text = "time,a.w,a.x,a.y,a.z,b.w,b.x,b.y,b.z\n" + "".join(
        f"{t},{keys},{keys}\n" for t in range(3)) + "3,0.5000,0.5000,0.5000,0.5000,1,0,0,0\n"
    path = write_text(tmp_path / "k.csv", text)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        read_csv(path)
    assert len(seen) == (1 if warns else 0)
    if warns:
        assert issubclass(seen[0].category, NonUnitKeyWarning)
        assert str(seen[0].message).startswith(f"{path}:2: track 'a': key of norm ")
        assert "(6 keys in all further from norm 1 than" in str(seen[0].message)


def test_non_unit_npz_keys_warn(tmp_path):
    from quatarray.formats import NonUnitKeyWarning
    np.savez(tmp_path / "k.npz", times=[0.0, 1.0], keys=[[1.0, 0, 0, 0], [0, 2.0, 0, 0]])
    with pytest.warns(NonUnitKeyWarning, match=r"keys\[1\]: key of norm 2 is normalised \(1 key in all"):
        read_npz(tmp_path / "k.npz")


def test_a_full_disk_names_the_file(tmp_path, rng, monkeypatch):
    """Errno 28 while writing names the file asked for (it named none), and leaves nothing behind."""
    import errno

    def full(f, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(qcsv, "write_rows", full)
    with pytest.raises(OSError) as info:
        write_csv(tmp_path / "k.csv", Keyframes(np.arange(3.0), smooth_keys(rng, 3)))
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(tmp_path / "k.csv")
    assert os.listdir(tmp_path) == []
