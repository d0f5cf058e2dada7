"""Tests of quatarray.timeseries: keyframe reduction with a checked error bound."""

import numpy as np
import pytest

from quatarray import Rotation, Track, reduce_keys
from quatarray.io import example_path, read_bvh, read_csv

METHODS = ("linear", "slerp", "squad")


def angles(p, q):
    """Rotation angle between unit quaternions (..., 4), independent of the library:
    2 arccos-free formula 2 atan2(|p - s q|, |p + s q|) with s the sign of p.q."""
    p = np.asarray(p, np.float64)
    q = np.asarray(q, np.float64)
    s = np.where(np.sum(p * q, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    return 4 * np.arctan2(np.linalg.norm(p - s * q, axis=-1), np.linalg.norm(p + s * q, axis=-1))


def unit(q):
    q = np.asarray(q, np.float64)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def measured(tracks, times, keys, shared):
    """Largest angle per track between the returned tracks and the samples (T, B, 4)."""
    T = len(times)
    Q = unit(keys).reshape(T, -1, 4)
    if shared:
        return angles(np.asarray(tracks(times)).reshape(T, -1, 4), Q).max(axis=0)
    return np.array([angles(np.asarray(tr(times)), Q[:, j]).max() for j, tr in enumerate(tracks)])


def smooth(T=400, batch=(), seed=1, span=4.0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, span, T)
    f = rng.uniform(0.1, 0.4, batch + (3,))
    ph = rng.uniform(0, 6, batch + (3,))
    rv = np.sin(2 * np.pi * f * t.reshape((T,) + (1,) * (len(batch) + 1)) + ph)
    return t, Rotation.from_rotvec(rv.reshape(-1, 3)).as_quat(scalar_first=True).reshape((T,) + batch + (4,))


def check(times, keys, tol, method, shared=False, dtype=None):
    if dtype is not None:
        keys = np.asarray(keys).astype(dtype)
    tracks, err = reduce_keys(times, keys, tol, method=method, shared=shared)
    batch = np.shape(keys)[1:-1]
    assert err.shape == batch
    assert (err <= tol).all()
    got = measured(tracks, times, keys, shared)
    # the reported error is the error of the returned tracks (up to the angle's rounding)
    eps = np.finfo(np.asarray(keys).dtype).eps
    np.testing.assert_allclose(got, err.ravel(), rtol=0, atol=64 * eps)
    return tracks, err


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("shared", [False, True])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_bound_smooth(method, shared, dtype):
    t, q = smooth(300, (2, 3))
    tracks, err = check(t, q, 1e-3 if dtype == np.float64 else 3e-3, method, shared, dtype)
    if shared:
        assert tracks.batch_shape == (2, 3) and tracks.dtype == dtype
        assert len(tracks) < 300 // 2
    else:
        assert len(tracks) == 6 and all(tr.batch_shape == () and tr.dtype == dtype for tr in tracks)
        assert all(len(tr) < 300 // 2 for tr in tracks)


def test_order_of_tracks():
    """shared=False: one Track per track in the batch's C order, keys taken from that track."""
    t, q = smooth(200, (2, 3))
    tracks, _ = reduce_keys(t, q, 1e-3)
    flat = unit(q).reshape(200, 6, 4)
    for j, tr in enumerate(tracks):
        idx = np.searchsorted(t, tr.times)
        np.testing.assert_array_equal(t[idx], tr.times)
        assert angles(np.asarray(tr.keys), flat[idx, j]).max() < 1e-12


def _bvh_quats():
    clip = read_bvh(example_path("walk.bvh"))
    parts = [Rotation.from_euler(seq, clip.frames[:, cols.ravel()].reshape(-1, 3), degrees=True)
             .as_quat(scalar_first=True).reshape(len(clip.frames), -1, 4)
             for seq, cols in clip.rotation_groups().items()]
    return clip.times, np.concatenate(parts, axis=1)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("shared", [False, True])
def test_bound_real(method, shared):
    arm = read_csv(example_path("arm.csv"))
    imu = read_csv(example_path("imu.csv"), scalar_last=True)
    for times, keys, tol in [(arm.times, arm.keys, 0.05), (imu.times, imu.keys, 0.01), (*_bvh_quats(), 0.02)]:
        check(times, keys, tol, method, shared)
    # the arm resampled densely (120 Hz) by its own squad curve: a smooth, realistic track
    dense = np.linspace(arm.times[0], arm.times[-1], 481)
    keys = np.asarray(Track(arm.times, arm.keys, method="squad")(dense))
    tracks, _ = check(dense, keys, np.radians(0.1), method, shared)
    kept = len(tracks) if shared else max(len(tr) for tr in tracks)
    assert kept < 481 // 3


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_constant_and_steps(method, dtype):
    q0 = unit([0.3, 0.1, -0.5, 0.8])
    q1 = unit([0.9, 0.4, 0.1, 0.0])
    T = 200
    keys = np.tile(q0, (T, 1))
    t = np.arange(T) * 0.01
    tracks, err = check(t, keys, 1e-4, method, dtype=dtype)
    assert len(tracks[0]) == 2                     # a constant track needs its two ends
    keys[100:] = q1                                # a step between two constant parts
    tracks, err = check(t, keys, 1e-4, method, dtype=dtype)
    assert len(tracks[0]) <= 6


@pytest.mark.parametrize("method", METHODS)
def test_near_antipodal_neighbours(method, rng):
    """Signs flipping between samples (q, -q) and neighbours almost a half turn apart."""
    t, q = smooth(200, (2,), seed=3)
    q = q * np.where(rng.random((200, 2, 1)) < 0.5, -1, 1)      # random signs: the same rotations
    check(t, q, 1e-3, method)
    half = np.array([0.0, 1.0, 0.0, 0.0])
    ident = np.array([1.0, 0.0, 0.0, 0.0])
    eps = np.array([1e-9, 0.0, 1e-9, 0.0])
    keys = np.array([ident, unit(half + eps), ident, unit(half - eps), ident, -ident])
    check(np.arange(6.0), keys, 1e-6, method)


def test_recovers_the_keys_of_its_own_curve(rng):
    """Samples of a piecewise SLERP curve need exactly its keys (greedy farthest reach; SLERP
    at constant speed, so any part of a segment is itself a SLERP segment).  NLERP is not:
    a part of an NLERP segment is not the NLERP of its ends."""
    method = "slerp"
    key_t = np.array([0.0, 1.0, 2.5, 3.0, 5.0])
    keys = unit(rng.standard_normal((5, 4)))
    keys[1:] *= np.sign(np.sum(keys[1:] * keys[:-1], -1))[:, None]
    t = np.linspace(0, 5, 501)
    samples = np.asarray(Track(key_t, keys, method=method)(t))
    tracks, err = reduce_keys(t, samples, 1e-8, method=method)
    np.testing.assert_array_equal(tracks[0].times, key_t)


def test_degrees_and_rotation_input():
    t, q = smooth(200)
    r = Rotation.from_quat(q, scalar_first=True)
    tracks_deg, err_deg = reduce_keys(t, r, 0.1, degrees=True)
    tracks_rad, err_rad = reduce_keys(t, q, np.radians(0.1))
    np.testing.assert_array_equal(tracks_deg[0].times, tracks_rad[0].times)
    np.testing.assert_allclose(err_deg, np.degrees(err_rad))
    assert err_deg <= 0.1


def test_inputs_untouched_and_read_only():
    t, q = smooth(100, (2,))
    q = -q                                      # flipped signs: unflipping must not write back
    t.flags.writeable = False
    q.flags.writeable = False
    before = q.copy()
    reduce_keys(t, q[:, ::-1], 1e-3, method="squad")
    np.testing.assert_array_equal(q, before)


def test_empty_batch():
    tracks, err = reduce_keys([0.0, 1.0], np.zeros((2, 0, 4)), 0.1)
    assert tracks == [] and err.shape == (0,)


@pytest.mark.parametrize("args, kwargs, match", [
    (([0, 2, 1], np.tile([1.0, 0, 0, 0], (3, 1)), 0.1), {}, "times in strictly increasing order"),
    (([0, 1, 1], np.tile([1.0, 0, 0, 0], (3, 1)), 0.1), {}, "times in strictly increasing order"),
    (([0, 1, 2], np.tile([1.0, 0, 0, 0], (3, 1)), 0.0), {}, "tolerance > 0"),
    (([0, 1, 2], np.tile([1.0, 0, 0, 0], (3, 1)), -1.0), {}, "tolerance > 0"),
    (([0, 1, 2], np.tile([1.0, 0, 0, 0], (3, 1)), np.nan), {}, "tolerance > 0"),
    (([0, 1, 2], [[1.0, 0, 0, 0], [np.nan, 0, 0, 0], [1, 0, 0, 0]], 0.1), {}, "finite values in keys"),
    (([0, 1, 2], [[1.0, 0, 0, 0], [0, 0, 0, 0], [1, 0, 0, 0]], 0.1), {}, "non-zero keys"),
    (([0, np.nan, 2], np.tile([1.0, 0, 0, 0], (3, 1)), 0.1), {}, "finite values in times"),
    (([0, 1], np.tile([1.0, 0, 0, 0], (3, 1)), 0.1), {}, "as many times as keys"),
    (([0], [[1.0, 0, 0, 0]], 0.1), {}, r"T >= 2"),
    (([0, 1, 2], np.ones((3, 3)), 0.1), {}, r"keys of shape \(T, \.\.\., 4\)"),
    (([0, 1, 2], np.tile([1.0, 0, 0, 0], (3, 1)), 0.1), {"method": "cubic"}, "expected method in"),
])
def test_errors(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        reduce_keys(*args, **kwargs)


def test_tolerance_type():
    with pytest.raises(TypeError, match="tolerance to be a real number"):
        reduce_keys([0, 1], [[1.0, 0, 0, 0], [1, 0, 0, 0]], "0.1deg")
