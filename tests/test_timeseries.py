"""Tests of quatarray.timeseries: keyframe reduction with a checked error bound."""

import numpy as np
import pytest

from quatarray import Rotation, Track, reduce_keys
from quatarray.formats import example_path, read_bvh, read_csv

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


def smooth_series(T=400, batch=(), seed=1, span=4.0):
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
    t, q = smooth_series(300, (2, 3))
    tracks, err = check(t, q, 1e-3 if dtype == np.float64 else 3e-3, method, shared, dtype)
    if shared:
        assert tracks.batch_shape == (2, 3) and tracks.dtype == dtype
        assert len(tracks) < 300 // 2
    else:
        assert len(tracks) == 6 and all(tr.batch_shape == () and tr.dtype == dtype for tr in tracks)
        assert all(len(tr) < 300 // 2 for tr in tracks)


def test_order_of_tracks():
    """shared=False: one Track per track in the batch's C order, keys taken from that track."""
    t, q = smooth_series(200, (2, 3))
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


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("rows", [2, 3, 50, 1000])
def test_unit_series_blocked_over_time(dtype, rows, rng, monkeypatch):
    """reduce_keys normalises and unflips its samples over blocks of times: the same bits
    as `unit_keys` of the whole series, in either layout, with sign flips at the block
    edges, exactly orthogonal neighbours (a zero dot product restarts the signs) and
    huge magnitudes."""
    import quatarray
    from quatarray import _blocks, _interp_kernels, timeseries
    T, B = 301, 5
    q = rng.normal(size=(T, B, 4)).astype(dtype)
    q[rng.random((T, B)) < 0.3] *= -1
    q[49:53, 0] = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, 0], [0, 0, 0, 1]]
    q[99:101, 1] = [[1, 0, 0, 0], [0, 2, 0, 0]]
    q[10:20, 2] *= 1e30 if dtype == np.float64 else 1e15
    whole = _interp_kernels.unit_keys(q)
    np.testing.assert_array_equal(timeseries._unit_series(q, "keys", False, rows), whole)
    np.testing.assert_array_equal(timeseries._unit_series(q, "keys", True, rows), whole.transpose(1, 0, 2))
    # groups of tracks on two threads
    monkeypatch.setattr(_blocks, "PARALLEL_MIN", 0)
    with quatarray.num_threads(2):
        np.testing.assert_array_equal(timeseries._unit_series(q, "keys", False, rows), whole)
        np.testing.assert_array_equal(timeseries._unit_series(q, "keys", True, rows), whole.transpose(1, 0, 2))


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
    t, q = smooth_series(200, (2,), seed=3)
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


def _walk(rng, B, T, step, dtype):
    """Track-major unit, unflipped random walks (B, T, 4) as `reduce` searches them."""
    from quatarray._interp_kernels import unit_keys
    q = np.cumsum(rng.normal(0, step, (T, B, 4)), axis=0) + [1.0, 0, 0, 0]
    return np.ascontiguousarray(unit_keys(q.astype(dtype)).transpose(1, 0, 2))


def _geodesic(p, q, u):
    """slerp written out: (sin((1-u)W) p + sin(uW) q) / sin W, q on p's side (float64)."""
    q = np.where(np.sum(p * q, -1, keepdims=True) < 0, -q, q)
    w = angles(p, q)[..., None] / 2
    with np.errstate(invalid="ignore", divide="ignore"):
        out = (np.sin((1 - u) * w) * p + np.sin(u * w) * q) / np.sin(w)
    return np.where(w > 0, out, p)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_segment_errors_against_the_curve(method, dtype, rng):
    """The search's error of a candidate segment (Track's table rows and kernel) is the
    largest angle between the samples inside it and the curve written out independently
    (slerp, NLERP), or squad's pairwise kernel with the same control points."""
    from quatarray import _interp_kernels as IK
    from quatarray import _reduce
    B, T = 3, 200
    Q = _walk(rng, B, T, 0.05, dtype)
    times = np.cumsum(rng.uniform(0.5, 1.5, T))
    s = rng.integers(0, T - 2, 40)
    c = np.minimum(s + rng.integers(1, 40, 40), T - 1)
    b = rng.integers(0, B, 40)
    err, worst = _reduce.segment_errors(method, times, Q, s, c, None, None, b)
    Q64 = Q.astype(np.float64)
    if method == "squad":
        unknown = np.full(len(s), -1)
        qs, qc, a_s, a_c = _reduce._controls(Q, times, unknown, s, c, unknown, b, 0, T - 1)
    atol = 1e3 * np.finfo(dtype).eps
    for j in range(len(s)):
        k = np.arange(s[j] + 1, c[j])
        if k.size == 0:
            assert err[j] == 0 and worst[j] == s[j]
            continue
        u = ((times[k] - times[s[j]]) / (times[c[j]] - times[s[j]]))[:, None]
        p, q = Q64[b[j], s[j]], Q64[b[j], c[j]]
        if method == "slerp":
            curve = _geodesic(p, q, u)
        elif method == "linear":
            curve = unit((1 - u) * p + u * np.where(p @ q < 0, -q, q))
        else:
            curve = IK.squad(qs[j, 0], a_s[j, 0], a_c[j, 0], qc[j, 0], u[:, 0].astype(dtype))
        expected = angles(curve, Q64[b[j], k])
        assert abs(err[j] - expected.max()) <= atol
        assert abs(expected[worst[j] - s[j] - 1] - expected.max()) <= atol


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_chord_is_the_nearer_sign(dtype, rng):
    """The search's squared chord is min(|p - q|², |p + q|²) bit for bit, also where q
    is more than a third of a turn from p (the only place |p + q|² is formed)."""
    from quatarray import _blocks, _reduce
    p = unit(rng.standard_normal((4, 3, 500)).transpose(1, 2, 0)).astype(dtype)
    q = unit(rng.standard_normal((4, 3, 500)).transpose(1, 2, 0)).astype(dtype)
    q[0, :100] = p[0, :100] + 1e-3            # close: |p - q|² small
    q[1, :100] = -p[1, :100]                  # the other sign: |p + q|² = 0
    q = unit(q.astype(np.float64)).astype(dtype)
    P, Qc = np.moveaxis(p, -1, 0), np.moveaxis(q, -1, 0)
    with _blocks.scratch().frame() as work:
        got = _reduce._chord2(P, Qc, work).copy()
    minus = ((p - q) ** 2).astype(dtype)
    plus = ((p + q) ** 2).astype(dtype)
    # the kernel's summation order: ((x0 + x1) + x2) + x3
    expected = np.minimum(((minus[..., 0] + minus[..., 1]) + minus[..., 2]) + minus[..., 3],
                          ((plus[..., 0] + plus[..., 1]) + plus[..., 2]) + plus[..., 3])
    assert (got > 1).any() and (got < 1e-4).any()
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("method", METHODS)
def test_segment_errors_in_groups(method, rng, monkeypatch):
    """Many segments are handled in groups (bounded memory); each segment's error and worst
    sample are the same bits whatever group it falls in, and the errors the same when the
    worst samples are not looked for."""
    from quatarray import _reduce
    Q = _walk(rng, 3, 500, 0.05, np.float64)
    times = np.cumsum(rng.uniform(0.5, 1.5, 500))
    s = rng.integers(0, 480, 300)
    c = np.minimum(s + rng.integers(1, 60, 300), 499)
    p = np.where(rng.random(300) < 0.5, -1, np.maximum(s - 5, 0))
    n = np.where(rng.random(300) < 0.5, -1, np.minimum(c + 7, 499))
    b = rng.integers(0, 3, 300)
    whole = _reduce.segment_errors(method, times, Q, s, c, p, n, b)
    monkeypatch.setattr(_reduce, "SEGMENTS", 37)
    grouped = _reduce.segment_errors(method, times, Q, s, c, p, n, b)
    np.testing.assert_array_equal(grouped[0], whole[0])
    np.testing.assert_array_equal(grouped[1], whole[1])
    # the search's call, without locating the worst samples: the same errors
    err, where = _reduce.segment_errors(method, times, Q, s, c, p, n, b, locate=False)
    np.testing.assert_array_equal(err, whole[0])
    np.testing.assert_array_equal(where, s)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shared", [False, True])
def test_back_controls_are_those_of_the_segment(dtype, shared, rng):
    """squad's search tests [p, s] again with a candidate c's control point at s, taken from
    the candidate's own controls and the lane's control point at p: bit for bit those
    `_controls` computes for [p, s] with neighbours pp and c, also where keys lie in
    opposite hemispheres (the control point negated) and at the track's first key."""
    from quatarray import _reduce
    B, T, m = 3, 400, 300
    Q = _walk(rng, B, T, 0.4, dtype)
    times = np.cumsum(rng.uniform(0.5, 1.5, T))
    p = rng.integers(0, T - 60, m)
    p[:20] = 0
    s = p + rng.integers(1, 20, m)
    c = s + rng.integers(1, 20, m)
    pp = np.where(rng.random(m) < 0.3, -1, np.maximum(p - rng.integers(1, 20, m), 0))
    pp[p == 0] = -1
    b = None if shared else rng.integers(0, B, m)
    if shared:
        Q = np.ascontiguousarray(Q.transpose(1, 0, 2))
    unknown = np.full(m, -1)
    ctl = _reduce._controls(Q, times, p, s, c, unknown, b, 0, T - 1)
    a_p = _reduce._controls(Q, times, pp, p, s, unknown, b, 0, T - 1)[2]
    rows = np.arange(m)
    got = _reduce._back_controls(Q, p, ctl, rows, a_p, b)
    want = _reduce._controls(Q, times, pp, p, s, c, b, 0, T - 1)
    assert (np.sum(got[0] * got[1], -1) < 0).sum() > 5   # keys in opposite hemispheres occur
    for g, w in zip(got, want):
        assert g.dtype == w.dtype
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(_reduce._hemisphere(got[0], got[1]), want[1])
    np.testing.assert_array_equal(got[2], want[2])
    np.testing.assert_array_equal(got[3], want[3])
    # and the segments' errors through either
    e_got = _reduce.segment_errors("squad", times, Q, p, s, b=b, locate=False, controls=got)[0]
    e_want = _reduce.segment_errors("squad", times, Q, p, s, pp, c, b, locate=False)[0]
    np.testing.assert_array_equal(e_got, e_want)


@pytest.mark.parametrize("method", ["linear", "slerp"])
@pytest.mark.parametrize("tol", [1e-3, 1e-2])
def test_search_reaches_farthest(method, tol, rng):
    """linear and slerp segments depend on their two keys only: every segment the search
    keeps is within `tol` and one sample longer it is not (a farthest reach), whatever
    order the search tries lengths in."""
    from quatarray import _reduce
    T = 1500   # one chunk: no forced boundaries
    Q = _walk(rng, 4, T, 0.004, np.float64)
    times = np.cumsum(rng.uniform(0.5, 1.5, T))
    for b, kept in enumerate(_reduce.greedy(method, times, Q, tol, False)):
        s, c = kept[:-1], kept[1:]
        bb = np.full(len(s), b)
        err, _ = _reduce.segment_errors(method, times, Q, s, c, None, None, bb)
        assert (err <= tol).all()
        longer = c < T - 1
        err, _ = _reduce.segment_errors(method, times, Q, s[longer], c[longer] + 1, None, None, bb[longer])
        assert (err > tol).all()


@pytest.mark.parametrize("method", METHODS)
def test_threads_give_the_same_keys(method, monkeypatch):
    """Tracks reduced on their own are searched and checked in groups on several threads:
    the same keys and errors as on one thread."""
    import quatarray
    from quatarray import _blocks
    monkeypatch.setattr(_blocks, "PARALLEL_MIN", 0)
    t, q = smooth_series(400, (5,), seed=11)
    with quatarray.num_threads(1):
        one, err1 = reduce_keys(t, q, 1e-3, method=method)
    with quatarray.num_threads(2):
        two, err2 = reduce_keys(t, q, 1e-3, method=method)
    np.testing.assert_array_equal(err2, err1)
    for a, b in zip(one, two):
        np.testing.assert_array_equal(a.times, b.times)
        np.testing.assert_array_equal(np.asarray(a.keys), np.asarray(b.keys))


def test_degrees_and_rotation_input():
    t, q = smooth_series(200)
    r = Rotation.from_quat(q, scalar_first=True)
    tracks_deg, err_deg = reduce_keys(t, r, 0.1, degrees=True)
    tracks_rad, err_rad = reduce_keys(t, q, np.radians(0.1))
    np.testing.assert_array_equal(tracks_deg[0].times, tracks_rad[0].times)
    np.testing.assert_allclose(err_deg, np.degrees(err_rad))
    assert err_deg <= 0.1


def test_inputs_untouched_and_read_only():
    t, q = smooth_series(100, (2,))
    q = -q                                      # flipped signs: unflipping must not write back
    t.flags.writeable = False
    q.flags.writeable = False
    before = q.copy()
    reduce_keys(t, q[:, ::-1], 1e-3, method="squad")
    np.testing.assert_array_equal(q, before)


def test_empty_batch():
    tracks, err = reduce_keys([0.0, 1.0], np.zeros((2, 0, 4)), 0.1)
    assert tracks == [] and err.shape == (0,)
    track, err = reduce_keys([0.0, 1.0, 2.0], np.zeros((3, 0, 4)), 0.1, shared=True)
    assert track.batch_shape == (0,) and len(track) == 2 and err.shape == (0,)


@pytest.mark.parametrize("method", ["magnus", "constant"])
def test_empty_batches_of_the_series_functions(method):
    """No tracks (or no groups to average) give empty results of the right shape."""
    from quatarray import geodesic_mean, integrate_angular_velocity
    assert integrate_angular_velocity([0.0, 1, 2], np.zeros((3, 0, 3)), method=method).shape == (3, 0)
    assert geodesic_mean(np.zeros((0, 3, 4)), axis=1).shape == (0,)
    assert geodesic_mean(np.zeros((3, 0, 4)), axis=0).shape == (0,)
    assert Rotation.identity(shape=(0, 3)).mean(axis=1).shape == (0,)


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


# ---------------------------------------------------------------------------
# angular velocity <-> orientation
# ---------------------------------------------------------------------------

from quatarray import (angular_velocity, fill_gaps, geodesic_mean, integrate_angular_velocity,  # noqa: E402
                       minimal_rotation, smooth, swing_twist)

NU, BETA = 2.0, 0.3


def coning(t):
    """R(t) = Rz(ν t) Rx(β) Rz(-ν t) and its world angular velocity ν (z - Rz(ν t) Rx(β) z)."""
    spin = Rotation.from_rotvec(np.outer(NU * t, [0, 0, 1]))
    tilt = Rotation.from_rotvec([BETA, 0, 0])
    R = spin * tilt * spin.inv()
    return R, NU * (np.array([0, 0, 1.0]) - (spin * tilt).apply([0, 0, 1.0]))


def rotation_error(a, b):
    return (a * b.inv()).magnitude()


def test_integrate_constant_omega_exact(rng):
    """Piecewise-constant ω (held over each interval) integrates exactly, both frames, any batch."""
    t = np.cumsum(rng.uniform(0.01, 0.1, 40))
    w = rng.normal(size=(40, 2, 3))
    q0 = Rotation.random(2, rng=rng)
    for frame in ("world", "body"):
        r = integrate_angular_velocity(t, w, initial=q0, frame=frame, method="constant")
        assert r.shape == (40, 2)
        # step by step: world steps act on the left, body steps on the right
        ref = [q0]
        for k in range(39):
            step = Rotation.from_rotvec(w[k] * (t[k + 1] - t[k]))
            ref.append(step * ref[-1] if frame == "world" else ref[-1] * step)
        ref = Rotation.concatenate([x[None] for x in ref])
        assert rotation_error(r, ref).max() < 1e-13


def test_integrate_frame_order_pinned():
    """A world-frame z spin after a body tilt: the two frames differ, and each matches q̇ = ½ ω q resp. ½ q ω."""
    t = np.linspace(0, 1, 3)
    tilt = Rotation.from_rotvec([np.pi / 2, 0, 0])
    w = np.tile([0, 0, np.pi / 2], (3, 1))
    world = integrate_angular_velocity(t, w, initial=tilt, frame="world", method="constant")
    body = integrate_angular_velocity(t, w, initial=tilt, frame="body", method="constant")
    spin = Rotation.from_rotvec([0, 0, np.pi / 2])
    assert rotation_error(world[-1], spin * tilt) < 1e-15          # world: the step on the left
    assert rotation_error(body[-1], tilt * spin) < 1e-15           # body: the step on the right
    assert rotation_error(world[-1], body[-1]) > 1                 # and they are not the same


@pytest.mark.parametrize("frame", ["world", "body"])
def test_integrate_coning_closed_form(frame):
    t = np.arange(0, 10 + 1e-9, 0.005)
    R, w = coning(t)
    if frame == "body":
        w = R.inv().apply(w)
    r = integrate_angular_velocity(t, w, initial=R[0], frame=frame)
    assert rotation_error(r, R).max() < 1e-11
    # fourth order: halving the step divides the error by about 16
    errs = []
    for dt in (0.04, 0.02):
        tt = np.arange(0, 10 + 1e-9, dt)
        RR, ww = coning(tt)
        errs.append(rotation_error(integrate_angular_velocity(tt, ww, initial=RR[0]), RR).max())
    assert 10 < errs[0] / errs[1] < 40


def test_integrate_as_accurate_as_numpy_quaternion():
    quaternion = pytest.importorskip("quaternion")
    t = np.arange(0, 10 + 1e-9, 0.005)
    R, w = coning(t)
    ours = rotation_error(integrate_angular_velocity(t, w, initial=R[0]), R)
    R0 = quaternion.from_float_array(R[0].as_quat(scalar_first=True))
    _, Rq = quaternion.integrate_angular_velocity((t, w), t[0], t[-1], R0=R0)
    theirs = rotation_error(Rotation.from_quat(quaternion.as_float_array(Rq), scalar_first=True), R)
    assert ours[-1] <= theirs[-1] and ours.max() <= theirs.max()


@pytest.mark.parametrize("scale", [1e-300, 1e-200, 1e200, 1e300])
def test_integrate_at_extreme_time_scales(scale, rng):
    """ω s over times t / s is the same motion: the coning term h² ω₁ × ω₂ must not overflow
    or underflow where each step's rotation is ordinary (it was 0 × inf at |ω| ≳ 1e154)."""
    t = np.cumsum(rng.uniform(0.05, 0.2, 12))
    w = rng.normal(size=(12, 3))
    for method in ("magnus", "constant"):
        ref = integrate_angular_velocity(t, w, method=method)
        got = integrate_angular_velocity(t / scale, w * scale, method=method)
        assert rotation_error(got, ref).max() < 1e-13


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_integrate_dtype_and_batch(dtype, rng):
    t = np.linspace(0, 1, 20)
    w = rng.normal(size=(20, 2, 3, 3)).astype(dtype)
    r = integrate_angular_velocity(t, w)
    assert r.shape == (20, 2, 3) and r.dtype == dtype
    one = integrate_angular_velocity(t, w[:, 1, 2])
    assert rotation_error(r[:, 1, 2], one).max() < 1e-6 if dtype == np.float32 else 1e-14


def euler_motion():
    t = np.linspace(0, 4, 401)
    a, ad, add = np.sin(1.3 * t) + 0.2 * t, 1.3 * np.cos(1.3 * t) + 0.2, -1.69 * np.sin(1.3 * t)
    b, bd, bdd = 0.7 * np.cos(0.9 * t), -0.63 * np.sin(0.9 * t), -0.567 * np.cos(0.9 * t)
    R = Rotation.from_euler("ZX", np.c_[a, b])                    # Rz(a) Rx(b)
    z, x = np.array([0, 0, 1.0]), np.array([1.0, 0, 0])
    Rz = Rotation.from_rotvec(np.outer(a, z))
    w = np.outer(ad, z) + Rz.apply(np.outer(bd, x))
    alpha = np.outer(add, z) + Rz.apply(np.outer(bdd, x)) + np.cross(np.outer(ad, z), Rz.apply(np.outer(bd, x)))
    return t, R, w, alpha


def test_angular_velocity_closed_form_and_ends():
    t, R, w, alpha = euler_motion()
    got, acc = angular_velocity(t, R, acceleration=True)
    assert np.linalg.norm(got - w, axis=1).max() < 1e-10             # ends included
    assert np.linalg.norm(acc - alpha, axis=1).max() < 1e-7
    body = angular_velocity(t, R, frame="body")
    np.testing.assert_allclose(R.apply(body), got, atol=1e-13)


def test_angular_velocity_within_twice_numpy_quaternion():
    quaternion = pytest.importorskip("quaternion")
    t, R, w, _ = euler_motion()
    ours = np.linalg.norm(angular_velocity(t, R) - w, axis=1)
    theirs = np.linalg.norm(quaternion.angular_velocity(
        quaternion.from_float_array(R.as_quat(scalar_first=True)), t) - w, axis=1)
    assert ours.max() <= 2 * theirs.max()
    assert ours[10:-10].max() <= 2 * theirs[10:-10].max()


@pytest.mark.parametrize("batch", [(), (3,), (2, 2)])
def test_angular_velocity_batch_roundtrip(batch, rng):
    """Differentiating the integral of a smooth ω gives ω back, per track as in a batch."""
    t = np.linspace(0, 2, 201)
    f = rng.uniform(0.5, 1.5, batch + (3,))
    w = np.cos(np.multiply.outer(t, f))
    r = integrate_angular_velocity(t, w, frame="body")
    back = angular_velocity(t, r, frame="body")
    assert back.shape == (201,) + batch + (3,)
    assert np.abs(back - w).max() < 1e-8


def test_minimal_rotation():
    t = np.linspace(0, 2, 201)
    r = Rotation.from_euler("zx", np.c_[3 * t, np.sin(t)])
    m = minimal_rotation(t, r)
    assert np.abs(angular_velocity(t, m, frame="body")[:, 2]).max() < 1e-6
    np.testing.assert_allclose(m.apply([0, 0, 1]), r.apply([0, 0, 1]), atol=1e-12)
    assert rotation_error(m[0], r[0]) < 1e-15


# ---------------------------------------------------------------------------
# swing-twist, geodesic mean
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("batch", [(), (5,), (2, 3)])
def test_swing_twist(batch, rng):
    r = Rotation.random(shape=batch, rng=rng)
    axis = rng.normal(size=batch + (3,))
    swing, twist = swing_twist(r, axis)
    assert swing.shape == twist.shape == batch
    assert rotation_error(swing * twist, r).max() < 1e-14
    a = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    rv = twist.as_rotvec()
    np.testing.assert_allclose(np.cross(rv, a), 0, atol=1e-14)        # the twist turns about the axis
    np.testing.assert_allclose(np.sum(swing.as_rotvec() * a, axis=-1), 0, atol=1e-14)   # the swing across it


def test_swing_twist_undefined_twist():
    swing, twist = swing_twist(Rotation.from_rotvec([np.pi, 0, 0]), [0, 0, 1])
    assert twist.magnitude() == 0 and abs(swing.magnitude() - np.pi) < 1e-15


@pytest.mark.parametrize("tiny", [1e-150, 1e-170, 1e-300])
def test_swing_twist_of_a_tiny_twist(tiny):
    """A half turn about x tipped by a tiny quarter turn about z: the twist about z is that
    quarter turn, however small its components (their squares underflowed to an identity)."""
    q = Rotation.from_quat([tiny, 1, 0, tiny], scalar_first=True)
    swing, twist = swing_twist(q, [0, 0, 1])
    np.testing.assert_allclose(twist.as_rotvec(), [0, 0, np.pi / 2], rtol=1e-15)
    assert rotation_error(swing * twist, q) < 1e-15


def test_geodesic_mean(rng):
    # about one axis the geodesic mean is the weighted mean angle
    ang = rng.uniform(-1, 1, 7)
    wts = rng.uniform(0.1, 1, 7)
    r = Rotation.from_rotvec(np.outer(ang, [0, 1, 0]))
    m = geodesic_mean(r, weights=wts)
    np.testing.assert_allclose(m.as_rotvec(), [0, np.average(ang, weights=wts), 0], atol=1e-13)
    # in general: the weighted sum of the logs at the mean vanishes (first-order condition)
    base = Rotation.random(rng=rng)
    r = base * Rotation.from_rotvec(rng.normal(0, 0.4, (4, 6, 3)))
    m = geodesic_mean(r, axis=1)
    assert m.shape == (4,)
    logs = (m[:, None].inv() * r).as_rotvec()
    assert np.abs(logs.sum(axis=1)).max() < 1e-10
    # it minimises the sum of squared angles: no worse than the chordal mean (its start)
    def cost(mean):
        return np.sum((mean[:, None].inv() * r).magnitude() ** 2, axis=1)
    assert (cost(m) <= cost(r.mean(axis=1))).all()


def test_geodesic_mean_errors():
    r = Rotation.from_rotvec([[0, 0, 0.1], [0, 0, 0.2]])
    with pytest.raises(ValueError, match="tol > 0"):
        geodesic_mean(r, tol=0)
    with pytest.raises(ValueError, match="max_iter"):
        geodesic_mean(r, max_iter=0)
    with pytest.raises(ValueError, match="positive sum"):
        geodesic_mean(r, weights=[0, 0])


# ---------------------------------------------------------------------------
# smoothing and gaps
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_smooth_reduces_error_to_truth(dtype, rng):
    t = np.linspace(0, 4, 401)
    truth = Rotation.from_euler("zx", np.c_[np.sin(t), 0.5 * np.cos(2 * t)])
    noise = Rotation.from_rotvec(rng.normal(0, 0.01, (401, 3)))
    noisy = Rotation.from_quat(((truth * noise).as_quat() * np.where(rng.random((401, 1)) < 0.3, -1, 1))
                               .astype(dtype))
    before = rotation_error(noisy, truth)
    out = smooth(t, noisy, 0.3)
    assert out.dtype == dtype
    after = rotation_error(out, truth)
    assert after.mean() < before.mean() / 3 and after.max() < before.max()
    # the signs of the input are kept (hemisphere)
    assert (np.sum(out.as_quat() * noisy.as_quat(), axis=-1) > 0).all()


def test_fill_gaps():
    t = np.arange(10.0)
    q = Rotation.from_rotvec(np.outer(t / 10, [0, 0, 1])).as_quat(scalar_first=True)
    q = np.stack([q, q], axis=1)
    q[2:4, 0] = np.nan          # a gap of 3 s between valid samples 1 and 4
    q[6, 1] = np.nan            # a gap of 2 s
    q[9, 1] = np.nan            # after the last valid sample
    out = np.asarray(fill_gaps(t, q, 2.5))
    assert np.isnan(out[2:4, 0]).all()                       # too long: left as NaN
    assert not np.isnan(out[6, 1]).any() and np.isnan(out[9, 1]).all()
    ref = Rotation.from_rotvec([0, 0, 0.6]).as_quat(scalar_first=True)
    assert angles(out[6, 1], ref) < 1e-14                    # SLERP of a uniform spin is exact
    out = np.asarray(fill_gaps(t, q, 3.0))
    assert not np.isnan(out[2:4, 0]).any()


def test_nan_refused_elsewhere():
    q = np.tile([1.0, 0, 0, 0], (3, 1))
    q[1, 0] = np.nan
    for call in (lambda: angular_velocity([0, 1, 2], q), lambda: smooth([0, 1, 2], q, 1.0),
                 lambda: reduce_keys([0, 1, 2], q, 0.1)):
        with pytest.raises(ValueError, match="finite values"):
            call()
    with pytest.raises(ValueError, match="finite values"):
        integrate_angular_velocity([0, 1, 2], [[0, 0, 1.0], [np.nan, 0, 0], [0, 0, 0]])


@pytest.mark.parametrize("call, match", [
    (lambda: integrate_angular_velocity([0, 1, 1], np.zeros((3, 3))), "strictly increasing"),
    (lambda: integrate_angular_velocity([0, 1], np.zeros((2, 4))), r"omega of shape \(T, \.\.\., 3\)"),
    (lambda: integrate_angular_velocity([0, 1], np.zeros((2, 3)), frame="space"), "expected frame in"),
    (lambda: integrate_angular_velocity([0, 1], np.zeros((2, 3)), method="rk4"), "expected method in"),
    (lambda: integrate_angular_velocity([0, 1], np.zeros((2, 2, 3)), initial=np.ones((3, 4))), "initial"),
    (lambda: angular_velocity([1, 0], np.tile([1.0, 0, 0, 0], (2, 1))), "strictly increasing"),
    (lambda: angular_velocity([0, 1], np.tile([1.0, 0, 0, 0], (2, 1)), points=1), "points"),
    (lambda: smooth([0, 1, 2], np.tile([1.0, 0, 0, 0], (3, 1)), 0), "window > 0"),
    (lambda: fill_gaps([0, 1, 2], np.tile([1.0, 0, 0, 0], (3, 1)), -1), "max_gap > 0"),
    (lambda: swing_twist(Rotation.identity(), [0, 0, 0]), "non-zero axis"),
    (lambda: minimal_rotation([0, 1], np.tile([1.0, 0, 0, 0], (2, 1)), axis=[0, 0, 0]), "non-zero axis"),
    (lambda: minimal_rotation([0, 1], np.tile([1.0, 0, 0, 0], (2, 1)), axis=np.ones((2, 3))),
     r"axis of shape \(3,\) or one that broadcasts to the rotations' batch shape \(\) \+ \(3,\), got \(2, 3\)"),
    (lambda: minimal_rotation([0, 1], np.tile([1.0, 0, 0, 0], (2, 1)), iterations=-1), "iterations to be an int >= 0"),
])
def test_series_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@pytest.mark.parametrize("call, name", [
    (lambda q: minimal_rotation([0, 1], q, iterations=1.7), "iterations"),
    (lambda q: minimal_rotation([0, 1], q, iterations="2"), "iterations"),
    (lambda q: minimal_rotation([0, 1], q, iterations=None), "iterations"),
    (lambda q: angular_velocity([0, 1], q, points=2.0), "points"),
    (lambda q: geodesic_mean(q, max_iter=True), "max_iter"),
    (lambda q: smooth([0, 1], q, 1.0, order=1.0), "order"),
])
def test_series_counts_must_be_ints(call, name):
    with pytest.raises(TypeError, match=f"expected {name} to be an int >= "):
        call(np.tile([1.0, 0, 0, 0], (2, 1)))


# ---------------------------------------------------------------------------
# property: the bound holds for any track, tolerance and method
# ---------------------------------------------------------------------------

from hypothesis import given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@given(seed=st.integers(0, 2**32 - 1), T=st.integers(2, 120), step=st.floats(0.001, 1.0),
       tol=st.floats(1e-6, 0.5), method=st.sampled_from(METHODS), shared=st.booleans())
def test_bound_property(seed, T, step, tol, method, shared):
    """Random walks with random step sizes (from nearly constant to half turns between
    samples), unequal times: the returned error is at most the tolerance and is the error
    of the returned tracks."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.1, 1.0, T))
    rv = np.cumsum(rng.normal(0, step, (T, 2, 3)), axis=0)
    q = Rotation.from_rotvec(rv.reshape(-1, 3)).as_quat(scalar_first=True).reshape(T, 2, 4)
    check(t, q, tol, method, shared)
