"""The format registry and resample_file (quatarray.formats.registry): every format round-trips."""

import os
import tempfile

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from quatarray import Rotation, Track
from quatarray.formats import (FORMATS, Keyframes, format_of, keyframes_to_gltf, read_bvh, read_csv, read_npz,
                               resample_file)
from quatarray.formats.gltf_read import read_animations, read_gltf

from .test_io import smooth_keys

BATCHES = ((), (2,), (2, 3))
EXTENSIONS = (".csv", ".npz", ".bvh", ".glb", ".gltf", ".zarr")


def _bvh_text(angles, decimals, frame_time):
    """A chain of one joint per track, each with ZXY rotation channels (the root also positions)."""
    njoints = angles.shape[1]
    lines = ["HIERARCHY"]
    for j in range(njoints):
        pad = "  " * j
        lines += [pad + ("ROOT J0" if j == 0 else f"JOINT J{j}"), pad + "{", pad + "  OFFSET 0 1 0"]
        chans = (["Xposition", "Yposition", "Zposition"] if j == 0 else []) + ["Zrotation", "Xrotation", "Yrotation"]
        lines.append(pad + f"  CHANNELS {len(chans)} " + " ".join(chans))
    pad = "  " * njoints
    lines += [pad + "End Site", pad + "{", pad + "  OFFSET 0 1 0", pad + "}"]
    lines += ["  " * j + "}" for j in reversed(range(njoints))]
    lines += ["MOTION", f"Frames: {len(angles)}", f"Frame Time: {frame_time!r}"]
    cells = np.char.mod(f"%.{decimals}f", angles.reshape(len(angles), -1))
    lines += [" ".join(["0", "0", "0", *row]) for row in cells.tolist()]
    return "\n".join(lines) + "\n"


def _bvh_quats(path):
    """(times, quats (K, joints, 4)) of a file written by `_bvh_text`."""
    clip = read_bvh(path)
    angles = clip.frames[:, 3:].reshape(len(clip.frames), -1, 3)
    return clip.times, Rotation.from_euler("ZXY", angles, degrees=True).as_quat(scalar_first=True)


def _gltf_quats(path):
    """(times, quats (K, nodes, 4)) of the rotation samplers of a file's first animation."""
    samplers = [s for s in read_animations(read_gltf(path))[0] if s.path == "rotation"]
    return samplers[0].times, np.stack([np.roll(s.values, 1, axis=-1) for s in samplers], axis=1)


def _write_input(path, ext, times, keys, decimals):
    rounded = np.round(keys, decimals)
    zero = ~(rounded != 0).any(axis=-1)
    rounded[zero] = [1.0, 0.0, 0.0, 0.0]   # a zero quaternion is refused, and is no rotation
    if ext == ".csv":
        flat = rounded.reshape(len(times), -1)
        header = "time," + ",".join(f"t{j}.{c}" for j in range(flat.shape[1] // 4) for c in "wxyz")
        rows = [f"{t!r}," + ",".join(np.char.mod(f"%.{decimals}f", r)) for t, r in zip(times.tolist(), flat)]
        with open(path, "w") as f:
            f.write(header + "\n" + "\n".join(rows) + "\n")
    elif ext == ".npz":
        np.savez(path, times=times, keys=rounded)
    elif ext == ".zarr":
        zarr = pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
        group = zarr.open_group(path, mode="w")
        group["times"], group["keys"] = times, rounded
    elif ext == ".bvh":
        angles = Rotation.from_quat(keys.reshape(len(times), -1, 4), scalar_first=True).as_euler("ZXY", degrees=True)
        with open(path, "w") as f:
            f.write(_bvh_text(angles, decimals, float(times[1] - times[0])))
    else:
        keyframes_to_gltf(path, Keyframes(times, rounded.reshape(len(times), -1, 4)))


def _read(path, ext):
    """(times, quats (K, tracks, 4)) as written in `path`, in any format."""
    if ext in (".csv", ".npz"):
        kf = read_csv(path) if ext == ".csv" else read_npz(path)
        return kf.times, kf.keys.reshape(len(kf.times), -1, 4)
    if ext == ".zarr":
        import zarr
        group = zarr.open_group(path, mode="r")
        times = group["times"][...]
        return times, group["keys"][...].reshape(len(times), -1, 4)
    if ext == ".bvh":
        return _bvh_quats(path)
    return _gltf_quats(path)


@pytest.mark.filterwarnings("ignore::quatarray.formats.NonUnitKeyWarning")   # keys rounded to 0-9 decimals
@given(seed=st.integers(0, 2**32 - 1), ext=st.sampled_from(EXTENSIONS), batch=st.sampled_from(BATCHES),
       decimals=st.integers(0, 9), nkeys=st.integers(2, 6), method=st.sampled_from(["slerp", "squad", "bezier"]),
       fps=st.sampled_from([3.0, 7.5, 24.0]), convert=st.sampled_from([None, ".csv", ".npz", ".zarr"]))
def test_nothing_written_misrepresents_the_resampled_rotations(seed, ext, batch, decimals, nkeys, method, fps,
                                                                convert):
    """Random tracks (batch shapes, 0-9 decimals) in each format, resampled by resample_file into the same
    format or another of its family (`convert`: CSV, NPZ and Zarr) and read back: every written quaternion
    is, as a rotation, within 1e-6 of the curve through the input as read, and every interpolated one is
    unit within 1e-6 (a key at its own time is copied as the input wrote it)."""
    out = convert if convert and FORMATS[ext].family == FORMATS[convert].family else ext
    if ".zarr" in (ext, out):
        pytest.importorskip("dask", reason="dask is not installed (the dask extra)")
    rng = np.random.default_rng(seed)
    if ext == ".bvh":   # evenly spaced frames, middle angles away from gimbal lock
        times = np.arange(nkeys) / 4.0
        keys = Rotation.from_euler("ZXY", rng.uniform([-170, -70, -170], [170, 70, 170], (nkeys,) + batch + (3,)),
                                   degrees=True).as_quat(scalar_first=True)
    else:
        times = np.round(np.cumsum(rng.uniform(0.1, 0.6, nkeys)), 2)
        keys = smooth_keys(rng, nkeys, batch)
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = os.path.join(tmp, "in" + ext), os.path.join(tmp, "out" + out)
        _write_input(src, ext, times, keys, decimals)
        resample_file(src, dst, fps=fps, method=method, progress=False)
        key_times, key_quats = _read(src, ext)
        t, got = _read(dst, out)
    want = np.asarray(Track(key_times, key_quats, method=method)(t), np.float64)
    got = np.asarray(got, np.float64)
    unit = got / np.linalg.norm(got, axis=-1, keepdims=True)
    dot = np.abs(np.einsum("...i,...i->...", unit, want))
    np.testing.assert_allclose(dot, 1.0, rtol=0, atol=1e-6)
    distance = np.minimum(np.abs(unit - want).max(-1), np.abs(unit + want).max(-1))
    assert distance.max() <= 1e-6
    between = ~np.isin(t, key_times)
    np.testing.assert_allclose(np.linalg.norm(got[between], axis=-1), 1.0, rtol=0, atol=1e-6)


def test_every_format_is_registered_with_its_extension():
    assert set(FORMATS) == set(EXTENSIONS)
    assert all(format_of("a" + ext.upper()) == ext for ext in EXTENSIONS)
    assert format_of("store.zarr/") == ".zarr"


def test_unknown_extension_lists_every_registered_one():
    with pytest.raises(ValueError, match=r"unknown extension '\.txt' \(expected \.csv, \.npz, \.bvh, \.gltf, "
                                         r"\.glb, \.zarr\)"):
        format_of("notes.txt")


def test_help_lists_every_registered_extension(capsys):
    from quatarray import cli
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "(.csv, .npz, .bvh, .gltf, .glb or .zarr)" in out
    with pytest.raises(SystemExit):
        cli.main(["resample", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert ".csv, .npz and .zarr convert into each other. .gltf and .glb convert into each other." in out


def test_formats_of_one_family_convert_into_each_other():
    """CSV, NPZ and Zarr form one family (Zarr -> Zarr with its own chunked resampler); BVH and glTF
    stay apart."""
    families = {}
    for ext, fmt in FORMATS.items():
        families.setdefault(fmt.family, []).append(ext)
    assert sorted(families.values()) == [[".bvh"], [".csv", ".npz", ".zarr"], [".gltf", ".glb"]]
    assert [ext for ext, fmt in FORMATS.items() if fmt.chunked] == [".zarr"]
    assert all(FORMATS[ext].read and FORMATS[ext].write for ext in (".csv", ".npz", ".zarr"))


def test_resample_file_writes_zarr(tmp_path):
    """resample_file goes through the registry for Zarr stores too (it could not write them)."""
    zarr = pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    pytest.importorskip("dask", reason="dask is not installed (the dask extra)")
    group = zarr.open_group(str(tmp_path / "in.zarr"), mode="w")
    group["times"], group["keys"] = np.array([0.0, 1.0]), np.array([[1.0, 0, 0, 0], [0, 0, 0, 1]])
    assert resample_file(tmp_path / "in.zarr", tmp_path / "out.zarr", fps=4, progress=False) == (2, 5)
    got = zarr.open_group(str(tmp_path / "out.zarr"), mode="r")["keys"][...]
    np.testing.assert_allclose(got, np.asarray(Track([0.0, 1.0], group["keys"][...])(np.arange(5) / 4)),
                               rtol=0, atol=1e-15)
