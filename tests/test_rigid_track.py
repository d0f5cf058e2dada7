"""RigidTrack: keyframes of rigid motions interpolated by ScLERP, against the raw dual-quaternion
ScLERP, exact screw motions and the SLERP + linear translation special case."""

import numpy as np
import pytest

from quatarray import RigidTransform, Rotation, Track
from quatarray import _dualquat as D
from quatarray import _kernels as Kn
from quatarray.rigid import RigidTrack

from .conftest import random_quats, tol


def _keys(rng, K, batch, dtype=np.float64):
    q = random_quats(rng, (K,) + batch, dtype)
    t = rng.standard_normal((K,) + batch + (3,)).astype(dtype)
    return q, t


def _transforms(q, t):
    return RigidTransform.from_components(t, Rotation.from_quat(q, scalar_first=True))


def _parts(tf):
    return np.asarray(tf.rotation.as_quat(scalar_first=True)), tf.translation


def _same_rotation(a, b, atol):
    sign = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0, -1, 1)
    return np.allclose(sign * a, b, atol=atol)


def _screw(angle, axis, point, disp):
    """Rotation by `angle` about `axis` through `point`, then `disp` along the axis: (q, t)."""
    angle, disp = np.asarray(angle), np.asarray(disp)
    q = np.concatenate([np.cos(angle / 2)[..., None], np.sin(angle / 2)[..., None] * axis], axis=-1)
    t = disp[..., None] * axis + point - Kn.rotate(q, np.broadcast_to(point, q.shape[:-1] + (3,)))
    return q, np.asarray(t)


@pytest.mark.parametrize("batch", [(), (3,), (2, 3)], ids=lambda b: f"batch{len(b)}")
@pytest.mark.parametrize("extrapolate", ["clamp", "extend"])
def test_equals_sclerp_per_segment(rng, dtype, batch, extrapolate):
    K = 6
    q, t = _keys(rng, K, batch, dtype)
    times = np.cumsum(rng.uniform(0.2, 1.5, K))
    track = RigidTrack(times, _transforms(q, t), extrapolate=extrapolate)
    s = np.concatenate([rng.uniform(times[0] - 1, times[-1] + 1, 40), times])
    got_q, got_t = _parts(track(s))
    assert got_q.dtype == dtype and got_t.dtype == dtype
    assert got_q.shape == s.shape + batch + (4,) and got_t.shape == s.shape + batch + (3,)
    i = np.clip(np.searchsorted(times, s, side="right") - 1, 0, K - 2)
    u = (s - times[i]) / (times[i + 1] - times[i])
    if extrapolate == "clamp":
        u = np.clip(u, 0, 1)
    dq = D.from_rotation_translation(q.astype(np.float64), t.astype(np.float64))
    a = np.moveaxis(dq[i], 0, -2)
    b = np.moveaxis(dq[i + 1], 0, -2)
    ref_q, ref_t = D.as_rotation_translation(D.multiply(a, D.power(D.multiply(D.conjugate(a), b), u)))
    ref_q, ref_t = np.moveaxis(ref_q, -2, 0), np.moveaxis(ref_t, -2, 0)
    scale = 1 + np.abs(ref_t).max()
    assert _same_rotation(got_q, ref_q, tol(dtype, 200))
    assert np.allclose(got_t, ref_t, atol=tol(dtype, 200) * scale)


def test_passes_through_keys_and_clamps(rng):
    q, t = _keys(rng, 5, (4,))
    times = np.array([0.0, 0.5, 2.0, 2.5, 4.0])
    track = RigidTrack(times, _transforms(q, t), extrapolate="clamp")
    got_q, got_t = _parts(track(times))
    assert _same_rotation(got_q, q, 1e-15) and np.allclose(got_t, t, atol=1e-15)
    lo_q, lo_t = _parts(track(-3.0))
    hi_q, hi_t = _parts(track(np.array([4.5, 1e300])))
    assert _same_rotation(lo_q, q[0], 1e-15) and np.array_equal(lo_t, t[0])
    assert _same_rotation(hi_q, q[[-1, -1]], 1e-15) and np.array_equal(hi_t, t[[-1, -1]])


def test_reproduces_constant_screw_motion(rng):
    """Keys sampled from one constant screw motion give that motion at every time, also extended."""
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    point = np.cross(axis, rng.standard_normal(3))
    omega, speed = 0.9, -0.6   # rad and length per unit time
    times = np.array([0.0, 0.7, 1.1, 2.5, 3.0])
    track = RigidTrack(times, _transforms(*_screw(omega * times, axis, point, speed * times)),
                       extrapolate="extend")
    s = np.linspace(-1, 4, 41)
    got_q, got_t = _parts(track(s))
    ref_q, ref_t = _screw(omega * s, axis, point, speed * s)
    assert _same_rotation(got_q, ref_q, 1e-14)
    assert np.allclose(got_t, ref_t, atol=1e-14)


def test_constant_velocity_along_a_segment(rng):
    """The motion over each equal time step of a segment is the same (constant screw velocity)."""
    q, t = _keys(rng, 2, (5,))
    track = RigidTrack([1.0, 3.0], _transforms(q, t))
    pose = track(np.linspace(1, 3, 9))
    steps = pose[1:] * pose[:-1].inv()          # world-frame motion over each step
    sq, st = _parts(steps)
    assert _same_rotation(sq, np.broadcast_to(sq[:1], sq.shape), 1e-14)
    assert np.allclose(st, np.broadcast_to(st[:1], st.shape), atol=1e-14)


def test_axis_through_origin_is_slerp_plus_linear_translation(rng):
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    angles, disps = np.array([0.3, 2.1, -1.0]), np.array([-0.4, 1.7, 0.2])
    q, t = _screw(angles, axis, np.zeros(3), disps)
    times = np.array([0.0, 1.0, 3.0])
    s = np.linspace(0, 3, 13)
    got_q, got_t = _parts(RigidTrack(times, _transforms(q, t))(s))
    assert _same_rotation(got_q, np.asarray(Track(times, q)(s)), 1e-14)
    assert np.allclose(got_t, np.stack([np.interp(s, times, t[:, k]) for k in range(3)], -1), atol=1e-14)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-7])
def test_no_rotation_or_tiny_rotation_translates_linearly(rng, angle):
    """As the rotation between keys vanishes the screw axis runs off to infinity; the
    translation must tend to the linear one without losing accuracy on the way."""
    axis = np.array([0.0, 0.0, 1.0])
    q = np.array([[1.0, 0, 0, 0], [np.cos(angle / 2), 0, 0, np.sin(angle / 2)]])
    t = np.array([[0.0, 0, 0], [1e3, 0, 0]])          # across the axis
    s = np.linspace(0, 1, 11)
    got_q, got_t = _parts(RigidTrack([0, 1], _transforms(q, t))(s))
    assert _same_rotation(got_q, _screw(angle * s, axis, np.zeros(3), 0 * s)[0], 1e-15)
    # the exact screw: the translation bends away from the chord by at most ~ angle * |t| / 8
    assert np.allclose(got_t, s[:, None] * t[1], atol=1e3 * (angle / 4 + 1e-14))
    # and equals the exact screw (axis z through the point p = ½ (t + cot(angle/2) z × t))
    if angle > 0:
        point = 0.5 * (t[1] + np.cross(axis, t[1]) / np.tan(angle / 2))
        ref_t = _screw(angle * s, axis, point, 0 * s)[1]
        assert np.allclose(got_t, ref_t, atol=1e3 * 1e-14 + np.abs(point).max() * 4e-16)


def test_float32_and_read_only_inputs_kept(rng):
    q, t = _keys(rng, 4, (3,), np.float32)
    tf = _transforms(q, t)
    before = tf.as_matrix().copy()
    times = np.array([0.0, 1.0, 2.0, 3.0])
    times.flags.writeable = False
    track = RigidTrack(times, tf, extrapolate="extend")
    pose = track(np.array([0.5, 2.5], np.float32))
    assert pose.translation.dtype == np.float32 and track.dtype == np.float32
    assert np.array_equal(tf.as_matrix(), before)
    assert track(np.empty(0)).shape == (0, 3)
    assert track(1.5).shape == (3,) and not track(1.5).single
    assert RigidTrack([0, 1], _transforms(q[:2, 0], t[:2, 0]))(0.5).single


def test_batch_equals_per_body(rng):
    q, t = _keys(rng, 5, (2, 3))
    times = np.cumsum(rng.uniform(0.1, 1, 5))
    s = rng.uniform(times[0], times[-1], 17)
    whole = RigidTrack(times, _transforms(q, t))(s).as_matrix()
    for j in range(2):
        for k in range(3):
            one = RigidTrack(times, _transforms(q[:, j, k], t[:, j, k]))(s).as_matrix()
            assert np.allclose(whole[:, j, k], one, atol=1e-15)


@pytest.mark.parametrize("call, exc, match", [
    (lambda tf: RigidTrack([0, 1], np.eye(4)[None].repeat(2, 0)), TypeError, "expected transforms to be a RigidTransform"),
    (lambda tf: RigidTrack([0], tf[:1]), ValueError, r"expected transforms of shape \(K, ...\) with K >= 2"),
    (lambda tf: RigidTrack([0], tf[0]), ValueError, "expected transforms .* got a single transform"),
    (lambda tf: RigidTrack([0, 1, 2], tf), ValueError, "expected as many times as transforms"),
    (lambda tf: RigidTrack([1, 0], tf), ValueError, "expected times in strictly increasing order"),
    (lambda tf: RigidTrack([0, 1], tf, extrapolate="wrap"), ValueError, "expected extrapolate in"),
    (lambda tf: RigidTrack([0, 1], tf)(1.5), ValueError, r"expected t within the range \[0.0, 1.0\]"),
    (lambda tf: RigidTrack([0, 1], tf)(np.nan), ValueError, "expected finite values in t, got nan or inf"),
    (lambda tf: RigidTrack([0, 1], tf, extrapolate="extend")(np.inf), ValueError, "expected finite values in t, got nan or inf"),
])
def test_errors(rng, call, exc, match):
    tf = _transforms(*_keys(rng, 2, ()))
    with pytest.raises(exc, match=match):
        call(tf)


@pytest.mark.parametrize("extrapolate", ["clamp", "extend"])
def test_rotations_are_the_slerp_tracks_bits(rng, dtype, extrapolate):
    """A rigid track's rotations are those of the SLERP `Track` of its rotation keys, bit for
    bit, inside the keys and extended beyond them (one formula: `frame_core`)."""
    q, t = _keys(rng, 6, (3,), dtype)
    times = np.cumsum(rng.uniform(0.2, 1.5, 6))
    s = np.concatenate([rng.uniform(times[0] - 5, times[-1] + 5, 300), times])
    tf = _transforms(q, t)
    got = _parts(RigidTrack(times, tf, extrapolate=extrapolate)(s))[0]
    want = np.asarray(Track(times, _parts(tf)[0], method="slerp", extrapolate=extrapolate)(s))
    assert got.dtype == want.dtype == dtype
    np.testing.assert_array_equal(got, want)
