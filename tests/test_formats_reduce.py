"""Keyframe files with fewer keys (quatarray.formats.reduce) and the ``quatarray reduce`` command."""

import os

import numpy as np
import pytest

from quatarray import Track
from quatarray.cli import main
from quatarray.formats import (FormatError, example_path, keyframes_to_gltf, read_bvh, read_csv, read_npz,
                               resample_file)
from quatarray.formats.reduce import parse_tolerance, reduce_file


def angles(p, q):
    p, q = np.asarray(p, np.float64), np.asarray(q, np.float64)
    p = p / np.linalg.norm(p, axis=-1, keepdims=True)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    s = np.where(np.sum(p * q, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    return 4 * np.arctan2(np.linalg.norm(p - s * q, axis=-1), np.linalg.norm(p + s * q, axis=-1))


@pytest.fixture
def dense_csv(tmp_path):
    path = tmp_path / "arm_120.csv"
    resample_file(example_path("arm.csv"), path, fps=120, method="squad", precision="full")
    return path


@pytest.mark.parametrize("method", ["slerp", "linear", "squad"])
@pytest.mark.parametrize("ext", [".csv", ".npz"])
def test_keyframes_within_tolerance(dense_csv, tmp_path, method, ext):
    tol = np.radians(0.05)
    out = tmp_path / ("small" + ext)
    rows = reduce_file(dense_csv, out, tol, method=method)
    src = read_csv(dense_csv)
    small = read_csv(out) if ext == ".csv" else read_npz(out)
    assert [r[0] for r in rows] == list(src.names)
    assert all(r[1] == len(src.times) and r[2] == len(small.times) for r in rows)
    assert len(small.times) < len(src.times) // 2
    # the kept rows are the input's rows, and the curve through them stays within the tolerance
    idx = np.searchsorted(src.times, small.times)
    np.testing.assert_array_equal(src.times[idx], small.times)
    np.testing.assert_array_equal(src.keys[idx], small.keys)
    err = angles(np.asarray(Track(small.times, small.keys, method=method)(src.times)), src.keys).max(axis=0)
    assert (err <= tol).all()
    np.testing.assert_allclose(err, [r[3] for r in rows], atol=1e-12)


def _bvh_quats(clip):
    from quatarray._euler import from_euler
    return np.concatenate([from_euler(seq, clip.frames[:, cols.ravel()].reshape(-1, 3), degrees=True)
                           .reshape(len(clip.frames), -1, 4) for seq, cols in clip.rotation_groups().items()], 1)


def test_bvh_uniform_grid_within_tolerance(tmp_path):
    dense = tmp_path / "walk_120.bvh"
    resample_file(example_path("walk.bvh"), dense, fps=120, method="squad", precision="full")
    out = tmp_path / "small.bvh"
    tol = np.radians(0.5)
    rows = reduce_file(dense, out, tol, method="squad")
    src, small = read_bvh(dense), read_bvh(out)
    n = round(small.frame_time / src.frame_time)
    assert n > 2 and abs(small.frame_time - n * src.frame_time) < 1e-6
    assert all(r[2] == len(small.frames) for r in rows)
    # the reduced clip evaluated at the original frame times (the end pose held past the end)
    t_small = np.arange(len(small.frames)) * small.frame_time
    back = []
    q = _bvh_quats(small)
    for j in range(q.shape[1]):
        back.append(np.asarray(Track(t_small, q[:, j], method="squad", extrapolate="clamp")(src.times)))
    err = angles(np.stack(back, 1), _bvh_quats(src)).max(axis=0)
    assert (err <= tol + 1e-9).all()          # the file's printed decimals round the angles (1e-6 degrees)
    assert max(r[3] for r in rows) <= tol


def test_cli_reduce(dense_csv, tmp_path, capsys):
    out = tmp_path / "small.csv"
    assert main(["reduce", str(dense_csv), "-o", str(out), "--tolerance", "0.1deg", "--method", "squad"]) == 0
    text = capsys.readouterr().out
    for name in ("shoulder", "elbow", "wrist"):
        assert name in text
    assert "481 ->" in text and "max error" in text
    assert out.exists()


def test_cli_reduce_errors(dense_csv, tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["reduce", str(dense_csv), "-o", str(tmp_path / "x.csv"), "--tolerance", "abc"])
    assert "expected tolerance a positive angle" in capsys.readouterr().err
    assert main(["reduce", example_path("walk.bvh"), "-o", str(tmp_path / "y.csv"), "--tolerance", "1deg"]) == 2
    assert "cannot write .csv from .bvh input" in capsys.readouterr().err
    assert main(["reduce", str(dense_csv), "-o", str(dense_csv), "--tolerance", "1deg"]) == 2
    assert "--force" in capsys.readouterr().err


@pytest.mark.parametrize("ext", [".csv", ".npz", ".bvh", ".glb"])
def test_reduce_follows_the_overwrite_rule(tmp_path, capsys, ext):
    """quatarray reduce, as resample: an existing output is refused without --force (it was replaced
    without a word), the message names the file and the flag in command-line words (it said
    'give --force (force=True)'), and --force replaces it."""
    src = tmp_path / ("in" + ext)
    if ext == ".bvh":
        resample_file(example_path("walk.bvh"), src, fps=60, method="squad")
    elif ext == ".glb":
        keyframes_to_gltf(src, read_csv(example_path("arm.csv")))
    else:
        resample_file(example_path("arm.csv"), src, fps=60, method="squad")
    out = tmp_path / ("out" + ext)
    out.write_bytes(b"keep me")
    args = ["reduce", str(src), "-o", str(out), "--tolerance", "1deg"]
    assert main(args) == 2
    assert capsys.readouterr().err == f"quatarray: error: {out}: exists; give --force to replace it\n"
    assert out.read_bytes() == b"keep me"
    with pytest.raises(FileExistsError, match="exists; give force=True to replace it"):
        reduce_file(src, out, "1deg")
    before = src.read_bytes()
    assert main(["reduce", str(src), "-o", str(src), "--tolerance", "1deg"]) == 2
    assert capsys.readouterr().err == f"quatarray: error: {src}: is the input file; give --force to replace it\n"
    assert src.read_bytes() == before
    assert main(args + ["--force"]) == 0
    assert out.read_bytes() != b"keep me"
    assert main(["reduce", str(src), "-o", str(src), "--tolerance", "1deg", "--force"]) == 0


@pytest.mark.parametrize("where", ["folder", "memory"])
def test_reduce_replaces_a_zarr_input_with_force_as_a_file(dense_csv, tmp_path, capsys, where):
    """reduce reads a store whole before it writes, so with --force it replaces its own input as it
    does a file (it was refused with resample's reason); without --force it names the flag.  The
    store is replaced atomically: no temporary is left, and the keys kept are the input's rows."""
    pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    from quatarray.formats import read_zarr, write_zarr
    dense = read_csv(dense_csv)
    src = "memory://qa-reduce-in-place/in.zarr" if where == "memory" else str(tmp_path / "in.zarr")
    write_zarr(src, dense, force=True)
    args = ["reduce", src, "-o", src, "--tolerance", "0.5deg"]
    assert main(args) == 2
    what = "exists" if where == "memory" else "is the input store"     # a URL is no path to compare
    assert capsys.readouterr().err == f"quatarray: error: {src}: {what}; give --force to replace it\n"
    np.testing.assert_array_equal(read_zarr(src).keys, dense.keys)
    assert main(args + ["--force"]) == 0, capsys.readouterr().err
    kept = read_zarr(src)
    idx = np.searchsorted(dense.times, kept.times)
    assert 2 <= len(idx) < len(dense.times) // 4 and np.array_equal(dense.times[idx], kept.times)
    np.testing.assert_array_equal(kept.keys, dense.keys[idx])
    assert kept.names == dense.names
    if where == "memory":
        import fsspec
        assert fsspec.filesystem("memory").ls("/qa-reduce-in-place", detail=False) == ["/qa-reduce-in-place/in.zarr"]
        fsspec.filesystem("memory").rm("/qa-reduce-in-place", recursive=True)
    else:
        assert sorted(os.listdir(tmp_path)) == ["arm_120.csv", "in.zarr"]


@pytest.mark.parametrize("text, value", [("0.1deg", np.radians(0.1)), ("2e-3rad", 2e-3), ("0.5", 0.5),
                                         (" 1 deg ", np.radians(1))])
def test_parse_tolerance(text, value):
    assert parse_tolerance(text) == pytest.approx(value, rel=1e-15)


@pytest.mark.parametrize("text", ["0deg", "-1", "nan", "inf", "deg", "1 turn"])
def test_parse_tolerance_errors(text):
    with pytest.raises(ValueError, match="expected tolerance a positive angle"):
        parse_tolerance(text)


def test_unknown_extension(tmp_path):
    with pytest.raises(FormatError, match="unknown extension"):
        reduce_file(example_path("arm.csv"), tmp_path / "x.txt", 0.1)


def test_gltf_rotation_samplers_reduced(tmp_path):
    """Each LINEAR rotation sampler gets its own fewer keys; the rest of the file is as it was."""
    from quatarray.formats.gltf_read import read_animations, read_gltf
    dense = tmp_path / "arm_120.glb"
    keyframes_to_gltf(tmp_path / "arm.glb", read_csv(example_path("arm.csv")))
    resample_file(tmp_path / "arm.glb", dense, fps=120)
    out = tmp_path / "small.gltf"
    tol = np.radians(0.1)
    rows = reduce_file(dense, out, tol)
    before, after = read_gltf(dense), read_gltf(out)
    old, new = read_animations(before)[0], read_animations(after)[0]
    assert len(rows) == sum(s.path == "rotation" for s in old)
    for s_old, s_new in zip(old, new):
        if s_old.path != "rotation":       # other samplers untouched
            np.testing.assert_array_equal(s_old.times, s_new.times)
            np.testing.assert_array_equal(s_old.values, s_new.values)
            continue
        assert len(s_new.times) < len(s_old.times) // 3
        q_new = np.roll(s_new.values, 1, axis=-1)
        curve = np.asarray(Track(s_new.times, q_new)(s_old.times))
        assert angles(curve, np.roll(s_old.values, 1, axis=-1)).max() <= tol + 1e-6   # float32 keys
    assert after.json["nodes"] == before.json["nodes"]
    assert [c["target"] for c in after.json["animations"][0]["channels"]] == \
        [c["target"] for c in before.json["animations"][0]["channels"]]
    with pytest.raises(ValueError, match="expected method 'slerp'"):
        reduce_file(dense, tmp_path / "x.glb", tol, method="squad")


def _gltf_with_buffer_file(tmp_path, name, buffer):
    """The arm example as `name` (.gltf) keeping its buffer in the file `buffer` beside it."""
    keyframes_to_gltf(tmp_path / "arm.glb", read_csv(example_path("arm.csv")))
    resample_file(tmp_path / "arm.glb", tmp_path / buffer.replace(".bin", ".gltf"), fps=60)   # writes the .bin
    os.replace(tmp_path / buffer.replace(".bin", ".gltf"), tmp_path / name)
    os.remove(tmp_path / "arm.glb")
    return tmp_path / name


def test_reduce_gltf_follows_the_buffer_file_rule(tmp_path, capsys):
    """quatarray reduce writes a .gltf's .bin under resample's rule: an existing .bin beside the output,
    or a file of the input, is refused without --force (reduce replaced both without a word)."""
    src = _gltf_with_buffer_file(tmp_path, "scene.gltf", "data.bin")
    buffer = (tmp_path / "data.bin").read_bytes()
    (tmp_path / "out.bin").write_bytes(b"keep me")
    assert main(["reduce", str(src), "-o", str(tmp_path / "out.gltf"), "--tolerance", "1deg"]) == 2
    err = capsys.readouterr().err
    assert err == (f"quatarray: error: {tmp_path / 'out.bin'}: exists (the buffer file of the output 'out.gltf'); "
                   "give --force to replace it\n")
    for force in (False, True):     # the input's buffer: not even with force
        with pytest.raises(FormatError, match="would replace 'data.bin', the buffer file of the input 'scene.gltf'"):
            reduce_file(src, tmp_path / "data.gltf", "1deg", force=force)
    assert (tmp_path / "out.bin").read_bytes() == b"keep me" and (tmp_path / "data.bin").read_bytes() == buffer
    assert sorted(os.listdir(tmp_path)) == ["data.bin", "out.bin", "scene.gltf"]
