"""Tests for quatarray.interpolate: pairwise lerp/nlerp/slerp, unflip, squad and
spherical Bézier (control points and evaluation), Track and the scipy-style Slerp.

squad and Bézier are checked against straightforward loop-based reference
implementations of the formulas (written here, one quaternion at a time, with
the textbook sin/log/exp forms); slerp tracks against scipy's Slerp.
"""

import math
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation as SciRotation
from scipy.spatial.transform import Slerp as SciSlerp

from quatarray import QuatArray, Rotation
from quatarray import _blocks
from quatarray import _interp_kernels as IK
from quatarray._blocks import BLOCK
from quatarray._interp_lookup import SegmentIndex
from quatarray._kernels import multiply as qmul
from quatarray.interpolate import (
    Slerp, Track, bezier, bezier_control_points, lerp, nlerp, slerp, squad,
    squad_control_points, unflip,
)
from quatarray.testing import assert_allclose

from .conftest import random_quats, tol

METHODS = ("linear", "slerp", "squad", "bezier")
SMOOTH = ("squad", "bezier")


# ---------------------------------------------------------------------------
# reference implementations: one quaternion at a time, float64, textbook forms
# ---------------------------------------------------------------------------

def r_mul(p, q):
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def r_conj(q):
    return np.array([q[0], -q[1], -q[2], -q[3]])


def r_log(q):
    """Vector part of the log of a unit quaternion."""
    vn = math.sqrt(q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
    theta = math.atan2(vn, q[0])
    return np.zeros(3) if vn == 0 else np.asarray(q[1:]) * (theta / vn)


def r_exp(v):
    n = math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
    s = 1.0 if n == 0 else math.sin(n) / n
    return np.array([math.cos(n), v[0] * s, v[1] * s, v[2] * s])


def r_slerp(p, q, t):
    """p (p⁻¹ q)^t, following q as given (no flip)."""
    return r_mul(p, r_exp(t * r_log(r_mul(r_conj(p), q))))


def r_double(p, q):
    return 2 * np.dot(p, q) * q - p


def r_bisect(p, q):
    s = p + q
    return s / np.linalg.norm(s)


def r_unflip(keys):
    keys = [np.asarray(k, float) / np.linalg.norm(k) for k in keys]
    for i in range(1, len(keys)):
        if np.dot(keys[i], keys[i - 1]) < 0:
            keys[i] = -keys[i]
    return keys


def r_extend(keys, times):
    """Geodesic reflection at both ends: q_-1 = q0 q1⁻¹ q0 at t0 - (t1 - t0)."""
    first = r_mul(r_mul(keys[0], r_conj(keys[1])), keys[0])
    last = r_mul(r_mul(keys[-1], r_conj(keys[-2])), keys[-1])
    tx = [times[0] - (times[1] - times[0])] + list(times) + [times[-1] + (times[-1] - times[-2])]
    return [first] + list(keys) + [last], tx


def r_squad_controls(keys, times):
    """s_i = q_i exp(-(w_in L+ + w_out L-)/2) (Shoemake's -(L+ + L-)/4 when equally spaced)."""
    ext, tx = r_extend(keys, times)
    out = []
    for i in range(len(keys)):
        q = ext[i + 1]
        lp = r_log(r_mul(r_conj(q), ext[i + 2]))
        lm = r_log(r_mul(r_conj(q), ext[i]))
        din, dout = tx[i + 1] - tx[i], tx[i + 2] - tx[i + 1]
        w_in, w_out = din / (din + dout), dout / (din + dout)
        out.append(r_mul(q, r_exp(-(w_in * lp + w_out * lm) / 2)))
    return out


def r_bezier_controls(keys, times):
    """a_i = slerp(q_i, c_i, 2 w_out / 3), b_i = slerp(q_i, Double(c_i, q_i), 2 w_in / 3),
    c_i = Bisect(Double(q_{i-1}, q_i), q_{i+1}); equal spacing: a_i at 1/3, b_i = Double(a_i, q_i)."""
    ext, tx = r_extend(keys, times)
    a, b = [], []
    for i in range(len(keys)):
        q = ext[i + 1]
        c = r_bisect(r_double(ext[i], q), ext[i + 2])
        din, dout = tx[i + 1] - tx[i], tx[i + 2] - tx[i + 1]
        a.append(r_slerp(q, c, 2 / 3 * dout / (din + dout)))
        b.append(r_slerp(q, r_double(c, q), 2 / 3 * din / (din + dout)))
    return a, b


def r_squad(q0, a, b, q1, u):
    return r_slerp(r_slerp(q0, q1, u), r_slerp(a, b, u), 2 * u * (1 - u))


def r_bezier(q0, a, b, q1, u):
    p = [q0, a, b, q1]
    while len(p) > 1:
        p = [r_slerp(p[j], p[j + 1], u) for j in range(len(p) - 1)]
    return p[0]


def r_track(times, keys, t, method):
    """Reference evaluation of one track (keys (K, 4)) at query times t (M,)."""
    keys = r_unflip(keys)
    times = list(map(float, times))
    if method == "squad":
        s = r_squad_controls(keys, times)
    elif method == "bezier":
        a, b = r_bezier_controls(keys, times)
    out = []
    for tq in t:
        i = min(max(np.searchsorted(times, tq, side="right") - 1, 0), len(times) - 2)
        u = (tq - times[i]) / (times[i + 1] - times[i])
        if method == "slerp":
            out.append(r_slerp(keys[i], keys[i + 1], u))
        elif method == "linear":
            n = (1 - u) * keys[i] + u * keys[i + 1]
            out.append(n / np.linalg.norm(n))
        elif method == "squad":
            out.append(r_squad(keys[i], s[i], s[i + 1], keys[i + 1], u))
        else:
            out.append(r_bezier(keys[i], a[i], b[i + 1], keys[i + 1], u))
    return np.array(out)


def random_track(rng, k, batch=(), unequal=True, step=0.6, dtype=np.float64, flip=True):
    """A smooth-ish random track: neighbouring keys within about `step` rad; random signs."""
    if unequal:
        times = np.cumsum(rng.uniform(0.2, 2.0, k))
    else:
        times = np.arange(k) * 0.7 + 1.0
    keys = np.empty((k,) + tuple(batch) + (4,))
    keys[0] = random_quats(rng, batch)
    for i in range(1, k):
        d = np.concatenate([np.ones(tuple(batch) + (1,)), rng.normal(0, step / 2, tuple(batch) + (3,))], -1)
        keys[i] = r_mul_arr(keys[i - 1], d / np.linalg.norm(d, axis=-1, keepdims=True))
    if flip:
        keys *= rng.choice([-1.0, 1.0], (k,) + tuple(batch) + (1,))
    return times, keys.astype(dtype)


def r_mul_arr(p, q):
    return np.asarray(qmul(np.asarray(p, float), np.asarray(q, float)))


def plain(q):
    return np.asarray(q.ndarray if isinstance(q, QuatArray) else q)


def rotation_angle(q):
    """Rotation angle 2 atan2(|v|, |w|) of (..., 4) quaternions, in [0, pi]."""
    q = plain(q).astype(np.float64)
    return 2 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), np.abs(q[..., 0]))


# ---------------------------------------------------------------------------
# pairwise slerp
# ---------------------------------------------------------------------------

@pytest.fixture(params=["one block", "many blocks"])
def path(request, monkeypatch):
    """Run a pairwise test with the batch in one block and split into blocks of 3
    quaternions (the block engine's splitting, forced here)."""
    if request.param == "many blocks":
        monkeypatch.setattr(_blocks, "BLOCK", 3)
    return request.param


def test_slerp_matches_closed_form(rng, dtype, batch_shape, path):
    q0 = random_quats(rng, batch_shape, dtype)
    q1 = random_quats(rng, batch_shape, dtype)
    t = rng.uniform(-0.5, 1.5, batch_shape).astype(dtype)
    got = slerp(q0, q1, t)
    assert isinstance(got, QuatArray) and got.dtype == dtype and got.shape == batch_shape + (4,)
    a, b, tt = q0.reshape(-1, 4).astype(float), q1.reshape(-1, 4).astype(float), np.ravel(t).astype(float)
    b = b * np.where(np.sum(a * b, -1) < 0, -1, 1)[:, None]
    ref = np.array([r_slerp(x, y, s) for x, y, s in zip(a, b, tt)]).reshape(batch_shape + (4,))
    assert_allclose(got, ref, atol=tol(dtype, 20))


def test_slerp_endpoints_and_shortest_flag(rng, path):
    q0 = random_quats(rng, (50,))
    q1 = random_quats(rng, (50,))
    flip = np.sum(q0 * q1, -1) < 0
    assert flip.any() and not flip.all()
    assert_allclose(slerp(q0, q1, 0.0), q0, atol=tol(np.float64, 2))
    assert_allclose(slerp(q0, q1, 1.0), q1 * np.where(flip, -1, 1)[:, None], atol=tol(np.float64, 4))
    # shortest=False follows the arc to q1 as given: the long way where the dot is negative
    long = slerp(q0, q1, 0.5, shortest=False)
    ref = np.array([r_slerp(a, b, 0.5) for a, b in zip(q0, q1)])
    assert_allclose(long, ref, atol=tol(np.float64, 20))
    assert_allclose(slerp(q0, q1, 1.0, shortest=False), q1, atol=tol(np.float64, 8))
    assert not np.allclose(plain(long)[flip], plain(slerp(q0, q1, 0.5))[flip])


def test_slerp_extrapolates_along_the_great_circle(rng, path):
    q0, q1 = random_quats(rng, (20,)), random_quats(rng, (20,))
    q1 = q1 * np.where(np.sum(q0 * q1, -1) < 0, -1, 1)[:, None]
    for t in (-1.25, 2.0, 3.7):
        ref = np.array([r_slerp(a, b, t) for a, b in zip(q0, q1)])
        assert_allclose(slerp(q0, q1, t), ref, atol=tol(np.float64, 50))


@pytest.mark.parametrize("shortest", [True, False])
def test_slerp_extrapolates_far_without_cancelling(dtype, path, shortest):
    """Far outside [0, 1] the weights of w0 q0 + w1 q1 grow like |t| and cancel: the arc is
    taken from q0 along its tangent instead.  About one axis the closed form is the angle
    a + t (b - a).  The error stays within what the keys' rounding leaves undetermined:
    their angle to about eps (times t) and, a small angle d apart, their circle's tangent to
    about eps / d.  The norm stays unit (the weights' sum drifted by about |t| eps), also
    for equal keys (slerp(q, q, t) = q for any t, not 0) and in squad's outer SLERP."""
    rng = np.random.default_rng(5)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    a = rng.uniform(-3, 3, 8)
    step = np.concatenate([[0.0, 1e-9, -1e-5], rng.uniform(-1.5, 1.5, 5)])   # b - a, |b - a| < π: shortest arcs
    q0 = np.concatenate([np.cos(a / 2)[:, None], np.sin(a / 2)[:, None] * axis], axis=1)
    b = a + step
    q1 = np.concatenate([np.cos(b / 2)[:, None], np.sin(b / 2)[:, None] * axis], axis=1)
    q0, q1 = q0.astype(dtype), q1.astype(dtype)
    eps = np.finfo(dtype).eps
    for t in (-1.5, 2.5, -40.0, 1e3, -1e6, 1e12):
        got = plain(slerp(q0, q1, t, shortest=shortest)).astype(np.float64)
        # the closed form from the keys as rounded to dtype: their angles, then a + t (b - a)
        a0 = 2 * np.arctan2(q0[:, 1:].astype(np.float64) @ axis, q0[:, 0].astype(np.float64))
        a1 = 2 * np.arctan2(q1[:, 1:].astype(np.float64) @ axis, q1[:, 0].astype(np.float64))
        d = np.angle(np.exp(1j * (a1 - a0)))   # in (-π, π]: the shortest arc, as the keys' signs give it
        ang = a0 + t * d
        ref = np.concatenate([np.cos(ang / 2)[:, None], np.sin(ang / 2)[:, None] * axis], axis=1)
        same = np.sign(np.sum(ref * got, axis=1))[:, None]   # (shortest may follow -q1: the same rotations)
        bound = 16 * eps * (1 + abs(t) * (1 + np.abs(d)) + 1 / np.maximum(np.abs(d), eps))[:, None]
        assert np.all(np.abs(got - same * ref) <= bound), (t, np.max(np.abs(got - same * ref) / bound))
        np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1, atol=4 * eps)
        np.testing.assert_array_equal(plain(slerp(q0, q0, t, shortest=shortest)), q0)
    np.testing.assert_array_equal(plain(squad(q0, q0, q0, q0, 1e9)), q0)


def test_slerp_antipodal_is_constant(dtype, path):
    q = random_quats(np.random.default_rng(1), (6,), dtype)
    t = np.linspace(-0.5, 1.5, 6).astype(dtype)
    got = slerp(q, -q, t)
    assert_allclose(got, q, atol=tol(dtype, 2))   # shortest: -q is q, the rotation stays put
    got = plain(slerp(q, -q, t, shortest=False))  # no unique arc: still a constant rotation
    assert np.isfinite(got).all()
    assert_allclose(got, q * np.where(t < 0.5, 1, -1)[:, None], atol=0)


def test_slerp_orthogonal_pair_is_deterministic(dtype, path):
    """q0·q1 = 0 exactly (180° apart as rotations): no flip, the arc to q1 as given."""
    q0 = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0.6, 0.8, 0, 0]], dtype)
    q1 = np.array([[0, 0, 1, 0], [0, 0, 0, -1], [-0.8, 0.6, 0, 0]], dtype)
    assert (np.sum(q0 * q1, -1) == 0).all()
    t = np.array([0.25, 0.5, 0.75], dtype)
    a, b = slerp(q0, q1, t), slerp(q0, q1, t)
    np.testing.assert_array_equal(plain(a), plain(b))
    ref = np.array([r_slerp(x, y, s) for x, y, s in zip(q0.astype(float), q1.astype(float), t)])
    assert_allclose(a, ref, atol=tol(dtype, 8))


def test_slerp_near_identity_closed_form(path):
    """Identity -> 1e-10 rad about an axis, at t = 0.3: 3e-11 rad to 1e-14 relative."""
    axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    theta = 1e-10
    q1 = np.concatenate([[np.cos(theta / 2)], np.sin(theta / 2) * axis])
    got = plain(slerp([1.0, 0, 0, 0], q1, 0.3))
    expected = np.concatenate([[np.cos(0.3 * theta / 2)], np.sin(0.3 * theta / 2) * axis])
    np.testing.assert_allclose(got[1:], expected[1:], rtol=1e-14, atol=0)
    assert got[0] == 1.0
    assert abs(rotation_angle(got) / 3e-11 - 1) < 1e-14


@pytest.mark.parametrize("dtype", [np.float32, np.float64], ids=["f32", "f64"])
def test_slerp_small_angles_keep_relative_accuracy(dtype, path):
    """The angle of slerp(identity, q, t) is t times the angle of q to a few ulp, for
    angles from 1e-12 rad (1e-5 in float32) up to 2 rad: no arccos cancellation."""
    eps = np.finfo(dtype).eps
    lo = -12 if dtype == np.float64 else -5
    theta = np.logspace(lo, np.log10(2.0), 200)
    axis = np.array([0.3, 0.5, -0.8]) / np.linalg.norm([0.3, 0.5, -0.8])
    q1 = np.concatenate([np.cos(theta / 2)[:, None], np.sin(theta / 2)[:, None] * axis], -1).astype(dtype)
    ident = np.array([1, 0, 0, 0], dtype)
    for t in (0.3, 0.5, 0.9, 1.7):
        got = plain(slerp(ident, q1, np.asarray(t, dtype)))
        # angle of the stored q1, then the expected angle t·theta1 (computed in float64)
        th1 = 2 * np.arctan2(np.linalg.norm(q1[:, 1:].astype(float), axis=-1), q1[:, 0].astype(float))
        vn = np.linalg.norm(got[:, 1:].astype(float), axis=-1)
        rel = np.abs(vn / np.sin(float(dtype(t)) * th1 / 2) - 1)
        assert rel.max() < 8 * eps, (t, rel.max())


def test_slerp_broadcasting_and_scalar_parameter(rng, path):
    q0 = random_quats(rng, ())
    q1 = random_quats(rng, (5,))
    t = rng.uniform(0, 1, (3, 1))
    got = slerp(q0, q1, t)
    assert got.shape == (3, 5, 4)
    for i in range(3):
        for j in range(5):
            assert_allclose(got[i, j], slerp(q0, q1[j], float(t[i, 0])), atol=tol(np.float64, 4))
    one = slerp(q0, q1[0], 0.4)
    assert one.shape == (4,) and isinstance(one, QuatArray)
    assert_allclose(one, slerp(q0[None], q1[:1], [0.4])[0], atol=tol(np.float64, 4))


def test_slerp_large_batches_are_blocked(rng):
    """More quaternions than a block, with a broadcast operand (several blocks)."""
    n = BLOCK * 2 + 123
    q0 = random_quats(rng, (2, n))
    q1 = random_quats(rng, (n,))
    t = rng.uniform(0, 1, (2, 1))
    got = plain(slerp(q0, q1, t))
    for i in range(2):
        piece = slice(n - 50, n)
        assert_allclose(got[i, piece], slerp(q0[i, piece], q1[piece], t[i, 0]), atol=tol(np.float64, 4))
        assert_allclose(got[i, :50], slerp(q0[i, :50], q1[:50], t[i, 0]), atol=tol(np.float64, 4))


def test_dtypes_kept_and_promoted(rng, path):
    q32 = random_quats(rng, (4,), np.float32)
    q64 = random_quats(rng, (4,), np.float64)
    for f in (slerp, nlerp, lerp):
        assert f(q32, q32, 0.5).dtype == np.float32
        assert f(q32, q32, np.full(4, 0.5)).dtype == np.float32   # float64 t keeps float32
        assert f(q32, q64, 0.5).dtype == np.float64
        assert f([[1, 0, 0, 0]], [[0, 1, 0, 0]], [0.5]).dtype == np.float64   # ints -> float64
    assert slerp(q32[0], q32[1], 0.5).dtype == np.float32


@given(st.integers(0, 2 ** 32 - 1), st.floats(-1, 2))
def test_slerp_symmetry_and_unit_norm(seed, t):
    rng = np.random.default_rng(seed)
    q0, q1 = random_quats(rng, (3,)), random_quats(rng, (3,))
    a = slerp(q0, q1, t)
    b = slerp(q1, q0, 1 - t)
    assert_allclose(a, b, atol=tol(np.float64, 50), double_cover=True)
    np.testing.assert_allclose(np.linalg.norm(plain(a), axis=-1), 1, atol=tol(np.float64, 10))


# ---------------------------------------------------------------------------
# nearly antipodal pairs and the float32 hemisphere
# ---------------------------------------------------------------------------

def near_antipodal_pairs(rng, n, dtype=np.float64):
    """Unit q0 and unit q1 with |q0 + q1| from about 1e-16 to 1e-1 (float64: 1e-7 to 1e-1
    for float32), q1 not exactly -q0."""
    q0 = random_quats(rng, (n,))
    lo = -16 if dtype == np.float64 else -7
    q1 = -q0 + np.logspace(lo, -1, n)[:, None] * random_quats(rng, (n,))
    q1 /= np.linalg.norm(q1, axis=-1, keepdims=True)
    q0, q1 = q0.astype(dtype), q1.astype(dtype)
    keep = (q0 + q1 != 0).any(axis=-1)
    return q0[keep], q1[keep]


def unit_error(q):
    """max | |q| - 1 | over the batch, in units of the dtype's eps (norm computed in float64)."""
    q = plain(q)
    return np.abs(np.linalg.norm(q.astype(np.float64), axis=-1) - 1).max() / np.finfo(q.dtype).eps


def test_slerp_issue_example_nearly_antipodal_is_unit(path):
    """slerp([0,.6,.8,0], [1e-16,-.6,-.8,0], 0.3, shortest=False) used to be [0.809, 0, 0, 0]."""
    got = plain(slerp([[0, .6, .8, 0]], [[1e-16, -.6, -.8, 0]], [0.3], shortest=False))[0]
    assert abs(np.linalg.norm(got) - 1) < 4 * np.finfo(float).eps
    # the arc leaves q0 towards q0 + q1 = (1e-16, 0, 0, 0): w = sin(0.3 pi)
    np.testing.assert_allclose(got, [np.sin(0.3 * np.pi), .6 * np.cos(0.3 * np.pi), .8 * np.cos(0.3 * np.pi), 0],
                               atol=4e-16)


@pytest.mark.parametrize("dtype", [np.float32, np.float64], ids=["f32", "f64"])
def test_nearly_antipodal_inputs_give_unit_outputs(rng, dtype, path):
    """slerp(shortest=False), pairwise squad and bezier, with q1 ≈ -q0 (not exactly):
    every output is unit to a few eps (the error used to grow like eps / |q0 + q1|)."""
    q0, q1 = near_antipodal_pairs(rng, 60, dtype)
    n = len(q0)
    a, b = random_quats(rng, (n,), dtype), random_quats(rng, (n,), dtype)
    for t in (0.1, 0.3, 0.5, 0.77, 1.0, 1.4):
        tt = np.full(n, t, dtype)
        assert unit_error(slerp(q0, q1, tt, shortest=False)) < 4, t
        assert unit_error(slerp(q0, -q0, tt, shortest=False)) < 4, t
        # squad's inner slerp(q0, q1) and its outer blend, Bézier's de Casteljau levels
        assert unit_error(squad(q0, a, b, q1, tt)) < 8, t
        assert unit_error(squad(q0, q1, q0, q1, tt)) < 8, t
        assert unit_error(bezier(q0, q1, q0, q1, tt)) < 8, t


def test_nearly_antipodal_slerp_follows_the_great_circle(rng, path):
    """The output lies in the plane of q0 and q1 at angle t·Ω from q0 (Ω = angle(q0, q1)),
    checked against 40-digit arithmetic on the float64 inputs as given."""
    mpmath = pytest.importorskip("mpmath")
    mpmath.mp.dps = 40
    q0, q1 = near_antipodal_pairs(rng, 40)
    t = rng.uniform(0, 1, len(q0))
    got = plain(slerp(q0, q1, t, shortest=False))
    for a, b, h, o in zip(q0, q1, t, got):
        A, B, O = (mpmath.matrix([mpmath.mpf(float(x)) for x in v]) for v in (a, b, o))
        A /= mpmath.norm(A)
        B /= mpmath.norm(B)
        omega = 2 * mpmath.atan2(mpmath.norm(B - A), mpmath.norm(B + A))
        P = B - (A.T * B)[0] * A                       # in the plane, perpendicular to A
        P /= mpmath.norm(P)
        O /= mpmath.norm(O)
        # components along A and P give the angle; nothing may stick out of the plane
        ca, cp = (A.T * O)[0], (P.T * O)[0]
        assert mpmath.norm(O - ca * A - cp * P) < 4 * np.finfo(float).eps
        assert abs(mpmath.atan2(cp, ca) - float(h) * omega) < 4 * np.finfo(float).eps


def test_frames_of_nearly_antipodal_keys_are_unit(rng):
    """The great-circle frames Track evaluates: unit outputs along the whole arc."""
    q0, q1 = near_antipodal_pairs(rng, 60)
    F, phi = IK.frames(q0.T.copy(), q1.T.copy())
    for u in (0.1, 0.5, 0.9, 1.0):
        O = np.empty((4, len(q0)))
        IK.frame_core(F.copy(), phi, u, O)
        assert unit_error(O.T) < 4, u


def test_frames_of_one_pair_on_floats_give_the_block_kernels_bits(rng):
    """One float64 pair takes the frame formula on Python floats (Slerp through two keys):
    the same bits as the block kernel, for ordinary, close, coincident, antipodal and wide
    pairs (the last three go to the block kernel)."""
    n = 600
    k0 = random_quats(rng, (n,))
    k1 = random_quats(rng, (n,))
    k1[:100] = k0[:100] + 1e-7 * rng.standard_normal((100, 4))
    k1[100:110] = k0[100:110]
    k1[110:120] = -k0[110:120]
    k1[120:220] = -k0[120:220] + 1e-9 * rng.standard_normal((100, 4))
    k1 /= np.linalg.norm(k1, axis=-1, keepdims=True)
    F, phi = IK.frames(k0.T.copy(), k1.T.copy())      # the block kernel
    for i in range(n):
        Fi, phii = IK.frames(k0[i, :, None].copy(), k1[i, :, None].copy())
        assert np.array_equal(Fi[:, 0], F[:, i]) and np.array_equal(phii[0], phi[i]), i


@pytest.mark.parametrize("rtype", ["slerp", "track"])
def test_float32_hemisphere_from_the_exact_dot(rng, path, rtype):
    """Rotations within 1e-9 rad of π apart (q0·q1 about 5e-10): float32 slerp takes the
    short arc given by the sign of q0·q1 summed in float64 (it used to decide from
    float32 |q1 - q0|² against |q1 + q0|², wrong in 43-46% of the samples)."""
    n = 400
    q0 = random_quats(rng, (n,))
    axis = random_quats(rng, (n,))[:, 1:]
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    delta = rng.uniform(-1e-9, 1e-9, n)          # rotation angle π - delta
    half = (np.pi - delta) / 2
    r = np.concatenate([np.cos(half)[:, None], np.sin(half)[:, None] * axis], -1)
    q1 = r_mul_arr(q0, r)
    a32, b32 = q0.astype(np.float32), q1.astype(np.float32)
    dot = np.sum(a32.astype(np.float64) * b32.astype(np.float64), -1)
    sign = np.where(dot < 0, -1.0, 1.0)
    t = np.float32(0.4)
    if rtype == "slerp":
        got = plain(slerp(a32, b32, t))
    else:
        got = np.array([plain(Track([0.0, 1.0], [a, b])(0.4)) for a, b in zip(a32, b32)])
    assert got.dtype == np.float32
    ref = np.array([r_slerp(a, b * s, 0.4) for a, b, s in zip(a32.astype(float), b32.astype(float), sign)])
    assert np.abs(got - ref).max() < 20 * np.finfo(np.float32).eps


# ---------------------------------------------------------------------------
# lerp, nlerp, unflip
# ---------------------------------------------------------------------------

def test_lerp_and_nlerp(rng, dtype, batch_shape, path):
    q0 = random_quats(rng, batch_shape, dtype)
    q1 = random_quats(rng, batch_shape, dtype)
    t = rng.uniform(-0.5, 1.5, batch_shape).astype(dtype)
    tt = np.asarray(t)[..., None].astype(float)
    ref = (1 - tt) * q0.astype(float) + tt * q1.astype(float)
    assert_allclose(lerp(q0, q1, t), ref, atol=tol(dtype, 8))
    sign = np.where(np.sum(q0.astype(float) * q1, -1) < 0, -1, 1)[..., None]
    n = (1 - tt) * q0.astype(float) + tt * sign * q1.astype(float)
    got = nlerp(q0, q1, t)
    assert got.dtype == dtype
    assert_allclose(got, n / np.linalg.norm(n, axis=-1, keepdims=True), atol=tol(dtype, 40))
    assert_allclose(nlerp(q0, q1, 1.0), q1 * sign, atol=tol(dtype, 8))


def test_nlerp_is_not_constant_speed_but_on_the_slerp_circle(rng, path):
    q0, q1 = random_quats(rng, (10,)), random_quats(rng, (10,))
    t = np.full(10, 0.25)
    a, s = nlerp(q0, q1, t), slerp(q0, q1, t)
    # same great circle: a lies in the plane of q0 and the flipped q1
    assert not np.allclose(plain(a), plain(s))
    assert_allclose(nlerp(q0, q1, 0.5), slerp(q0, q1, 0.5), atol=tol(np.float64, 20))


_SCALES = {np.float64: [1e-300, 1e-160, 1e150, 1e155, 1e300], np.float32: [1e-35, 1e-20, 1e19, 1e20, 1e35]}


@pytest.mark.parametrize("dtype", [np.float32, np.float64], ids=["f32", "f64"])
def test_pairwise_curves_are_homogeneous_at_any_magnitude(rng, dtype, path):
    """Quaternions of one norm r give r times the unit result, for r from about 1e-300 to
    1e300 (float32: 1e-35 to 1e35), where their squares leave the float range; each
    element as it would be alone, mixed with unit ones in one batch, and no warning."""
    q0, a, b, q1 = (random_quats(rng, (6,), dtype) for _ in range(4))
    q1[0] = -q0[0]   # antipodal and orthogonal pairs too
    q1[1] = [-q0[1, 1], q0[1, 0], -q0[1, 3], q0[1, 2]]
    t = rng.uniform(-0.2, 1.2, 6).astype(dtype)
    curves = [(slerp, (q0, q1)), (lambda p, q, h: slerp(p, q, h, shortest=False), (q0, q1)),
              (squad, (q0, a, b, q1)), (bezier, (q0, a, b, q1))]
    if dtype == np.float64:   # nlerp's shortest-path sign is a dot product: in range to 1e±150
        curves.append((nlerp, (q0, q1)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for f, qs in curves:
            unit = np.asarray(f(*qs, t))
            for r in _SCALES[dtype] if f is not nlerp else [1e-150, 1e-100, 1e100, 1e150]:
                r = dtype(r)
                homogeneous = 1 if f is nlerp else r
                scaled = [np.concatenate([q * r, q]) for q in qs]   # scaled and unit rows in one batch
                got = np.asarray(f(*scaled, np.concatenate([t, t])))
                np.testing.assert_allclose(got[:6] / homogeneous, unit, rtol=0, atol=tol(dtype, 20))
                np.testing.assert_array_equal(got[6:], unit)
                alone = np.asarray(f(*(q[2:3] * r for q in qs), t[2:3]))
                np.testing.assert_array_equal(alone[0], got[2])


def test_nlerp_zero_blend_raises(path):
    with pytest.raises(ValueError, match="expected a non-zero blend"):
        nlerp([1, 0, 0, 0], [-1, 0, 0, 0], 0.5, shortest=False)
    assert_allclose(nlerp([1, 0, 0, 0], [-1, 0, 0, 0], 0.5), [1, 0, 0, 0], atol=0)


def test_unflip(rng, dtype):
    q = random_quats(rng, (7, 3), dtype)
    for axis, batch_axis in ((0, 0), (1, 1), (-1, 1), (-2, 0)):   # negative axes count batch axes
        got = plain(unflip(q, axis=axis))
        assert got.dtype == dtype
        moved = np.moveaxis(got, batch_axis, 0)
        assert (np.sum(moved[1:] * moved[:-1], -1) >= 0).all()
        np.testing.assert_array_equal(np.abs(got), np.abs(q))    # only signs change
        np.testing.assert_array_equal(moved[0], np.moveaxis(q, batch_axis, 0)[0])
    # exactly orthogonal neighbours keep their sign (dot = 0 is non-negative)
    np.testing.assert_array_equal(plain(unflip([[1, 0, 0, 0], [0, -1, 0, 0]])), [[1, 0, 0, 0], [0, -1, 0, 0]])
    assert unflip(np.empty((0, 4))).shape == (0, 4)


def test_unflip_equals_the_loop_with_exact_zero_dots(rng):
    """Integer components give exact zero dot products: a zero needs no flip."""
    def loop(q):
        q = q.copy()
        for i in range(1, len(q)):
            if np.dot(q[i], q[i - 1]) < 0:
                q[i] = -q[i]
        return q

    q = rng.integers(-1, 2, (40, 9, 3, 4)).astype(float)
    assert (np.einsum("...i,...i->...", q[:, 1:], q[:, :-1]) == 0).any()
    for k in range(40):
        along0, along1 = plain(unflip(q[k])), plain(unflip(q[k], axis=1))
        for j in range(3):
            np.testing.assert_array_equal(along0[:, j], loop(q[k, :, j]))
        for i in range(9):
            np.testing.assert_array_equal(along1[i], loop(q[k, i]))


def test_unflip_bad_axis():
    with pytest.raises(ValueError, match=r"expected axis in \[-1, 0\].*got 1"):
        unflip([[1, 0, 0, 0]], axis=1)
    with pytest.raises(TypeError, match="expected axis to be an int"):
        unflip([[1, 0, 0, 0]], axis=0.5)
    with pytest.raises(ValueError, match=r"expected q of shape \(\.\.\., 4\), got \(3,\)"):
        unflip([1, 0, 0])


# ---------------------------------------------------------------------------
# inputs: read-only, non-contiguous, empty, never modified; bad input
# ---------------------------------------------------------------------------

def test_inputs_untouched_readonly_noncontiguous_and_empty(rng, path):
    q0 = random_quats(rng, (6, 5))[:, ::2]    # non-contiguous
    q1 = random_quats(rng, (6, 3))
    t = rng.uniform(0, 1, (6, 3))
    for a in (q0, q1, t):
        a.flags.writeable = False
    copies = [a.copy() for a in (q0, q1, t)]
    for f in (slerp, nlerp, lerp):
        got = f(q0, q1, t)
        ref = f(np.ascontiguousarray(q0), q1.copy(), t.copy())
        np.testing.assert_array_equal(plain(got), plain(ref))
    for f in (squad, bezier):
        f(q0, q1, q0, q1, t)
    for a, c in zip((q0, q1, t), copies):
        np.testing.assert_array_equal(a, c)
    for f in (slerp, nlerp, lerp):
        assert f(np.empty((0, 4)), np.empty((0, 4)), np.empty(0)).shape == (0, 4)
        assert f(np.empty((2, 0, 4)), [1, 0, 0, 0], 0.5).shape == (2, 0, 4)
    assert squad(np.empty((0, 4)), [1, 0, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0], 0.5).shape == (0, 4)


@pytest.mark.parametrize("f", [lerp, nlerp, slerp])
def test_pairwise_bad_input(f, path):
    with pytest.raises(ValueError, match=r"expected q0 of shape \(\.\.\., 4\), got \(5, 3\)"):
        f(np.zeros((5, 3)), [1, 0, 0, 0], 0.5)
    with pytest.raises(ValueError, match=r"expected q1 of shape \(\.\.\., 4\), got \(\)"):
        f([1, 0, 0, 0], 1.0, 0.5)
    with pytest.raises(ValueError,
                       match=r"expected broadcastable batch shapes for q0, q1, t, got q0: \(2,\), q1: \(3,\)"):
        f(np.ones((2, 4)), np.ones((3, 4)), 0.5)
    with pytest.raises(TypeError, match="expected q0 of real numbers"):
        f(np.ones(4, complex), [1, 0, 0, 0], 0.5)
    with pytest.raises(TypeError, match="expected t of real numbers"):
        f([1, 0, 0, 0], [1, 0, 0, 0], "a")


# ---------------------------------------------------------------------------
# control points and segment evaluation vs the reference implementation
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("times_kind", [None, "shared", "per_track"])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_squad_controls_inner_only(rng, times_kind, dtype):
    """squad_controls(..., ends=False) gives the inner keys' control points bit for bit as
    the whole call does (the keyframe search asks for two of four)."""
    from quatarray import _interp_curves
    K, n = 6, 5
    keys = rng.standard_normal((K, n, 3, 4))
    keys = (keys / np.linalg.norm(keys, axis=-1, keepdims=True)).astype(dtype)
    steps = rng.uniform(0.2, 2.0, (K, n))
    times = {None: None, "shared": np.cumsum(steps[:, 0]), "per_track": np.cumsum(steps, axis=0)}[times_kind]
    whole = _interp_curves.squad_controls(keys, times)
    inner = _interp_curves.squad_controls(keys, times, ends=False)
    assert inner.dtype == dtype
    np.testing.assert_array_equal(inner, whole[1:-1])


@pytest.mark.parametrize("unequal", [False, True], ids=["equal", "unequal"])
def test_control_points_match_reference(rng, unequal):
    times, keys = random_track(rng, 7, (2,), unequal=unequal)
    s = plain(squad_control_points(keys, times if unequal else None))
    a, b = (plain(x) for x in bezier_control_points(keys, times if unequal else None))
    for j in range(2):
        ks = r_unflip(keys[:, j])
        tt = times if unequal else np.arange(7.0)
        assert_allclose(s[:, j], np.array(r_squad_controls(ks, tt)), atol=tol(np.float64, 20))
        ra, rb = r_bezier_controls(ks, tt)
        assert_allclose(a[:, j], np.array(ra), atol=tol(np.float64, 20))
        assert_allclose(b[:, j], np.array(rb), atol=tol(np.float64, 20))
        if not unequal:   # the paper's b_n = Double(a_n, q_n)
            assert_allclose(b[:, j], np.array([r_double(x, q) for x, q in zip(ra, ks)]), atol=tol(np.float64, 20))
            lp = [r_log(r_mul(r_conj(ks[i]), ks[i + 1])) for i in range(1, 6)]
            lm = [r_log(r_mul(r_conj(ks[i]), ks[i - 1])) for i in range(1, 6)]
            shoemake = [r_mul(ks[i], r_exp(-(lp[i - 1] + lm[i - 1]) / 4)) for i in range(1, 6)]
            assert_allclose(s[1:6, j], np.array(shoemake), atol=tol(np.float64, 20))


def test_control_point_ends_by_reflection(rng):
    times, keys = random_track(rng, 5, unequal=True)
    k = np.array(r_unflip(keys))
    s = squad_control_points(keys, times)
    assert_allclose(s[0], k[0], atol=tol(np.float64, 20))
    assert_allclose(s[-1], k[-1], atol=tol(np.float64, 20))
    a, b = bezier_control_points(keys, times)
    assert_allclose(a[0], r_slerp(k[0], k[1], 1 / 3), atol=tol(np.float64, 20))
    assert_allclose(b[-1], r_slerp(k[-1], k[-2], 1 / 3), atol=tol(np.float64, 20))


def test_pairwise_squad_and_bezier_match_reference(rng, dtype):
    q0, a, b, q1 = (random_quats(rng, (6,), dtype) for _ in range(4))
    u = rng.uniform(0, 1, 6).astype(dtype)
    got_s, got_b = squad(q0, a, b, q1, u), bezier(q0, a, b, q1, u)
    assert got_s.dtype == got_b.dtype == dtype
    f = [x.astype(float) for x in (q0, a, b, q1)]
    ref_s = np.array([r_squad(*(x[i] for x in f), float(u[i])) for i in range(6)])
    ref_b = np.array([r_bezier(*(x[i] for x in f), float(u[i])) for i in range(6)])
    assert_allclose(got_s, ref_s, atol=tol(dtype, 100))
    assert_allclose(got_b, ref_b, atol=tol(dtype, 100))


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("unequal", [False, True], ids=["equal", "unequal"])
def test_track_matches_reference(rng, method, unequal):
    times, keys = random_track(rng, 8, (2,), unequal=unequal)
    t = np.concatenate([rng.uniform(times[0], times[-1], 40), times])
    got = plain(Track(times, keys, method=method)(t))
    for j in range(2):
        ref = r_track(times, keys[:, j], t, method)
        assert_allclose(got[:, j], ref, atol=tol(np.float64, 50))


# ---------------------------------------------------------------------------
# Track and Slerp vs scipy
# ---------------------------------------------------------------------------

@given(st.integers(0, 2 ** 32 - 1), st.integers(2, 12), st.floats(0, 1))
def test_slerp_track_is_pairwise_slerp_between_unflipped_keys(seed, k, frac):
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.uniform(1e-3, 3.0, k)) + rng.uniform(-1e3, 1e3)
    keys = random_quats(rng, (k,)) * rng.uniform(0.5, 2.0, (k, 1))     # not unit: normalised
    t = times[0] + frac * (times[-1] - times[0])
    i = min(np.searchsorted(times, t, side="right") - 1, k - 2)
    u = (t - times[i]) / (times[i + 1] - times[i])
    ku = np.array(r_unflip(keys))
    got = Track(times, keys)(t)
    assert_allclose(got, r_slerp(ku[i], ku[i + 1], u), atol=tol(np.float64, 100))
    np.testing.assert_allclose(np.linalg.norm(plain(got)), 1, atol=tol(np.float64, 10))


@pytest.mark.parametrize("unequal", [False, True], ids=["equal", "unequal"])
def test_slerp_tracks_equal_scipy(rng, unequal):
    times, keys = random_track(rng, 30, unequal=unequal, step=2.0)   # big steps, random signs
    assert (np.sum(keys[1:] * keys[:-1], -1) < 0).any()
    t = np.concatenate([rng.uniform(times[0], times[-1], 300), times])
    ref = SciSlerp(times, SciRotation.from_quat(keys, scalar_first=True))(t).as_quat(scalar_first=True)
    rot = Rotation.from_quat(keys, scalar_first=True)
    for got in (Track(times, keys)(t), Track(times, rot)(t)):
        assert isinstance(got, QuatArray)
        assert_allclose(got, ref, atol=tol(np.float64, 20), double_cover=True)
    for got in (Slerp(times, rot)(t), Slerp(times, Rotation.from_quatarray(QuatArray(keys)))(t),
                Slerp(times, SciRotation.from_quat(keys, scalar_first=True))(t)):
        assert isinstance(got, Rotation)
        assert_allclose(got.as_quat(scalar_first=True), ref, atol=tol(np.float64, 20), double_cover=True)


def test_slerp_class_batches_equal_scipy_per_track(rng):
    times, keys = random_track(rng, 6, (2, 3), step=1.5)
    t = rng.uniform(times[0], times[-1], 25)
    rot = Rotation.from_quat(keys, scalar_first=True)
    with pytest.raises(ValueError, match="more than 1 leading dimension"):
        Slerp(times, rot)   # scipy's rule; batches of tracks are opt-in
    got = Slerp(times, rot, batched=True)(t).as_quat(scalar_first=True)
    assert got.shape == (25, 2, 3, 4)
    for i in range(2):
        for j in range(3):
            ref = SciSlerp(times, SciRotation.from_quat(keys[:, i, j], scalar_first=True))(t)
            assert_allclose(got[:, i, j], ref.as_quat(scalar_first=True), atol=tol(np.float64, 20), double_cover=True)
    one = Slerp(times, rot, batched=True)(t[3])
    assert one.shape == (2, 3)
    assert_allclose(one.as_quat(scalar_first=True), got[3], atol=0)


def test_slerp_class_errors_like_scipy():
    keys = Rotation.from_quat(random_quats(np.random.default_rng(0), (3,)), scalar_first=True)
    with pytest.raises(TypeError, match="must be a `Rotation` instance"):
        Slerp([0, 1, 2], keys.as_quat())
    with pytest.raises(ValueError, match="strictly increasing order"):
        Slerp([0, 1, 1], keys)
    with pytest.raises(ValueError, match="at least 2 rotations"):
        Slerp([0], keys[:1])
    with pytest.raises(ValueError, match="number of rotations to be equal to number of timestamps"):
        Slerp([0, 1], keys)
    with pytest.raises(ValueError, match="1 dimensional array"):
        Slerp([[0, 1, 2]], keys)
    s = Slerp([0, 1, 2], keys)
    with pytest.raises(ValueError, match=r"within the range \[0.0, 2.0\], both inclusive"):
        s([0.5, 2.5])
    with pytest.raises(ValueError, match=r"within the range \[0.0, 2.0\], both inclusive"):
        s(-1e-9)
    with pytest.raises(ValueError, match="at most 1-dimensional"):
        s([[0.5]])
    np.testing.assert_array_equal(s.timedelta, [1, 1])


# ---------------------------------------------------------------------------
# Track properties
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("method", METHODS)
def test_track_passes_through_keys_with_unit_outputs(rng, method):
    times, keys = random_track(rng, 9, (3,), step=1.0)
    track = Track(times, keys, method=method)
    unflipped = np.array([r_unflip(keys[:, j]) for j in range(3)]).transpose(1, 0, 2)
    assert_allclose(track(times), unflipped, atol=tol(np.float64, 2))
    assert_allclose(track.keys, unflipped, atol=tol(np.float64, 2))
    t = rng.uniform(times[0], times[-1], 500)
    np.testing.assert_allclose(np.linalg.norm(plain(track(t)), axis=-1), 1, atol=1e-12)


@pytest.mark.parametrize("method", METHODS)
def test_negating_keys_changes_nothing(rng, method):
    times, keys = random_track(rng, 7, (2,), flip=False)
    t = rng.uniform(times[0], times[-1], 50)
    ref = plain(Track(times, keys, method=method)(t))
    neg = keys.copy()
    neg[[2, 3, 5]] *= -1
    got = plain(Track(times, neg, method=method)(t))
    np.testing.assert_allclose(got, ref, atol=tol(np.float64, 4))
    got = plain(Track(times, -keys, method=method)(t))   # all negated: the sign of key 0 is followed
    np.testing.assert_allclose(got, -ref, atol=tol(np.float64, 4))


def _one_sided_omegas(track, times, frame="world"):
    """Angular velocities just left of, and at, every interior key."""
    inner = times[1:-1]
    left = track.angular_velocity(np.nextafter(inner, -np.inf), frame=frame)
    right = track.angular_velocity(inner, frame=frame)
    return left, right


@pytest.mark.parametrize("unequal", [False, True], ids=["equal", "unequal"])
def test_c1_continuity_at_keys(rng, unequal):
    times, keys = random_track(rng, 10, (2,), unequal=unequal, step=1.0)
    for method in SMOOTH:
        for frame in ("world", "body"):
            left, right = _one_sided_omegas(Track(times, keys, method=method), times, frame)
            scale = np.linalg.norm(right, axis=-1)
            assert (scale > 0.05).all()
            rel = np.linalg.norm(left - right, axis=-1) / scale
            assert rel.max() < 1e-6, (method, frame, rel.max())
    left, right = _one_sided_omegas(Track(times, keys, method="slerp"), times)
    rel = np.linalg.norm(left - right, axis=-1) / np.linalg.norm(right, axis=-1)
    assert rel.min() > 1e-3     # slerp is only C0: the check above could fail


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("frame", ["world", "body"])
def test_angular_velocity_matches_central_difference(rng, method, frame):
    times, keys = random_track(rng, 6, (2,), step=1.0)
    track = Track(times, keys, method=method)
    # stay away from keys, where slerp and linear are not differentiable
    seg = rng.integers(0, 5, 40)
    t = times[seg] + rng.uniform(0.05, 0.95, 40) * np.diff(times)[seg]
    h = 1e-6
    q = plain(track(t))
    dq = (plain(track(t + h)) - plain(track(t - h))) / (2 * h)
    qc = q * np.array([1, -1, -1, -1])
    if frame == "world":
        fd = 2 * qmul(dq, qc)[..., 1:]
    else:
        fd = 2 * qmul(qc, dq)[..., 1:]
    got = track.angular_velocity(t, frame=frame)
    assert got.shape == (40, 2, 3)
    np.testing.assert_allclose(got, fd, atol=1e-7 * np.abs(fd).max())


def test_slerp_angular_velocity_is_the_segment_rotation_vector(rng):
    times, keys = random_track(rng, 5, step=1.0)
    k = np.array(r_unflip(keys))
    track = Track(times, keys)
    t = times[:-1] + 0.3 * np.diff(times)
    expected = np.array([2 * r_log(r_mul(k[i + 1], r_conj(k[i]))) / (times[i + 1] - times[i]) for i in range(4)])
    np.testing.assert_allclose(track.angular_velocity(t), expected, atol=1e-14)
    body = np.array([2 * r_log(r_mul(r_conj(k[i]), k[i + 1])) / (times[i + 1] - times[i]) for i in range(4)])
    np.testing.assert_allclose(track.angular_velocity(t, frame="body"), body, atol=1e-14)


@pytest.mark.parametrize("method", SMOOTH)
def test_uniform_rotation_is_reproduced_with_unequal_spacing(rng, method):
    """Keys of a rotation at constant angular velocity, at unequal times: squad
    and Bézier give back the motion exactly (their tangents are central differences)."""
    omega = np.array([0.4, -0.9, 0.3])
    times = np.cumsum(rng.uniform(0.3, 1.5, 7))
    q0 = random_quats(rng, ())

    def motion(t):
        return np.array([r_mul(r_exp(omega * (s - times[0]) / 2), q0) for s in np.atleast_1d(t)])

    track = Track(times, motion(times), method=method)
    t = rng.uniform(times[0], times[-1], 60)
    assert_allclose(track(t), motion(t), atol=tol(np.float64, 100))
    np.testing.assert_allclose(track.angular_velocity(t), np.broadcast_to(omega, (60, 3)), atol=1e-12)


def test_two_keys_squad_and_bezier_are_slerp(rng):
    times, keys = random_track(rng, 2, (3,), step=1.5)
    t = np.linspace(times[0], times[1], 11)
    ref = plain(Track(times, keys)(t))
    for method in SMOOTH:
        assert_allclose(Track(times, keys, method=method)(t), ref, atol=tol(np.float64, 20))


def test_equal_spacing_tangents_of_squad_and_bezier_agree_closely(rng):
    times, keys = random_track(rng, 8, (4,), unequal=False, step=0.2)
    ws = Track(times, keys, method="squad").angular_velocity(times[1:-1])
    wb = Track(times, keys, method="bezier").angular_velocity(times[1:-1])
    rel = np.linalg.norm(ws - wb, axis=-1) / np.linalg.norm(ws, axis=-1)
    assert rel.max() < 0.05


@pytest.mark.parametrize("batch", [(), (3,), (2, 3)], ids=["batch0", "batch1", "batch2"])
@pytest.mark.parametrize("method", METHODS)
def test_batched_track_equals_separate_tracks(rng, dtype, batch, method):
    times, keys = random_track(rng, 6, batch, dtype=dtype)
    t = rng.uniform(times[0], times[-1], 30)
    track = Track(times, keys, method=method)
    got, w = plain(track(t)), track.angular_velocity(t)
    assert got.dtype == dtype and w.dtype == dtype
    assert got.shape == (30,) + batch + (4,) and w.shape == (30,) + batch + (3,)
    for j in np.ndindex(*batch):
        sep = Track(times, keys[(slice(None),) + j], method=method)
        np.testing.assert_array_equal(got[(slice(None),) + j], plain(sep(t)))
        np.testing.assert_allclose(w[(slice(None),) + j], sep.angular_velocity(t), rtol=0, atol=tol(dtype, 10))
    if dtype == np.float32:
        ref = plain(Track(times, keys.astype(np.float64), method=method)(t))
        np.testing.assert_allclose(got, ref, atol=tol(np.float32, 50))


def test_track_query_shapes(rng):
    times, keys = random_track(rng, 4, (2,))
    track = Track(times, keys, method="squad")
    assert track(times[1]).shape == (2, 4)
    assert track(np.full((2, 3), times[1])).shape == (2, 3, 2, 4)
    assert track(np.empty(0)).shape == (0, 2, 4)
    assert track.angular_velocity(times[1]).shape == (2, 3)
    assert track.angular_velocity(np.empty((0, 5))).shape == (0, 5, 2, 3)
    assert len(track) == 4 and track.batch_shape == (2,) and track.method == "squad"
    assert "squad" in repr(track)
    assert track.control_points.shape == (4, 2, 4)
    assert Track(times, keys).control_points is None
    a, b = Track(times, keys, method="bezier").control_points
    assert a.shape == b.shape == (4, 2, 4)


@pytest.mark.parametrize("method", METHODS)
def test_empty_batch_of_tracks(method):
    track = Track([0, 1, 2], np.zeros((3, 2, 0, 4)), method=method)
    assert track([0.5, 1.5]).shape == (2, 2, 0, 4)
    assert track.angular_velocity(0.5).shape == (2, 0, 3)


def test_many_tracks_and_many_queries_are_blocked(rng):
    """More tracks than a block (split across tracks), and more queries than a block."""
    times, keys = random_track(rng, 3, (BLOCK + 7,), step=0.5)
    track = Track(times, keys, method="squad")
    t = np.array([times[0] + 0.3, times[1] + 0.1])
    got = plain(track(t))
    for j in (0, BLOCK - 1, BLOCK + 6):
        np.testing.assert_array_equal(got[:, j], plain(Track(times, keys[:, j], method="squad")(t)))
    times, keys = random_track(rng, 50)
    t = rng.uniform(times[0], times[-1], 2 * BLOCK + 5)
    for method in METHODS:
        track = Track(times, keys, method=method)
        got = plain(track(t))
        np.testing.assert_array_equal(got[-7:], plain(track(t[-7:])))
        np.testing.assert_array_equal(track.angular_velocity(t)[-7:], track.angular_velocity(t[-7:]))


def test_track_inputs_untouched_readonly_noncontiguous(rng):
    times, keys = random_track(rng, 5, (4,))
    keys_nc = keys[:, ::2]
    times_ro = times.copy()
    for a in (keys, times_ro):
        a.flags.writeable = False
    before = keys.copy()
    track = Track(times_ro, keys_nc, method="bezier")
    t = rng.uniform(times[0], times[-1], 10)
    t.flags.writeable = False
    ref = Track(times, np.ascontiguousarray(keys_nc), method="bezier")
    np.testing.assert_array_equal(plain(track(t)), plain(ref(t)))
    np.testing.assert_array_equal(keys, before)
    assert not track.times.flags.writeable and not track.keys.flags.writeable


def test_extrapolation_modes(rng):
    times, keys = random_track(rng, 5, (2,))
    k = plain(Track(times, keys).keys)
    out_t = np.array([times[0] - 1.0, times[-1] + 2.0])
    for method in METHODS:
        clamp = Track(times, keys, method=method, extrapolate="clamp")
        assert_allclose(clamp(out_t), k[[0, -1]], atol=tol(np.float64, 2))
        assert (clamp.angular_velocity(out_t) == 0).all()
        assert_allclose(clamp([-1e300, 1e300]), k[[0, -1]], atol=tol(np.float64, 2))
        with pytest.raises(ValueError, match="expected finite values in t"):   # the API refuses inf
            clamp([-np.inf, np.inf])
        ext = Track(times, keys, method=method, extrapolate="extend")
        w = ext.angular_velocity(out_t)
        assert np.isfinite(plain(ext(out_t))).all() and (np.abs(w) > 0).any()
    ext = Track(times, keys, extrapolate="extend")
    u = (out_t[1] - times[-2]) / (times[-1] - times[-2])
    assert_allclose(ext(out_t[1]), slerp(k[-2], k[-1], u), atol=tol(np.float64, 20))
    np.testing.assert_allclose(ext.angular_velocity(out_t[1]), ext.angular_velocity(times[-1]), atol=1e-14)
    u = (out_t[0] - times[0]) / (times[1] - times[0])
    assert_allclose(ext(out_t[0]), slerp(k[0], k[1], u), atol=tol(np.float64, 20))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_extended_tracks_of_equal_keys_stay_on_the_key(dtype):
    """Equal keys extended to the limit give the key back with every method: the outer
    SLERP of squad, at 2 u (1 - u) of about -5e7 for u = 5000, used to cancel to 0 in
    float32 and raise."""
    q = np.array([0.5, 0.5, 0.5, 0.5], dtype)
    for method in METHODS:
        ext = Track([0.0, 1.0, 2.0], np.array([q, q, q]), method=method, extrapolate="extend")
        assert_allclose(ext([-5000.0, 1000.0, 5000.0]), np.tile(q, (3, 1)), atol=tol(dtype, 4))


# ---------------------------------------------------------------------------
# segment lookup
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["uniform", "random", "clustered", "two", "tiny_span"])
def test_segment_index_equals_searchsorted(rng, kind):
    times = {
        "uniform": np.arange(100.0) * 0.1,
        "random": np.sort(rng.uniform(-5, 5, 300)),
        "clustered": np.concatenate([np.linspace(0, 1e-6, 500), np.linspace(1, 2, 5)]),
        "two": np.array([3.0, 3.5]),
        "tiny_span": np.array([1.0, np.nextafter(1.0, 2), np.nextafter(np.nextafter(1.0, 2), 2)]),
    }[kind]
    index = SegmentIndex(times, min_keys=2)   # the grid also for few keys
    if kind in ("uniform", "random", "two"):
        assert index.grid is not None
    t = np.concatenate([times, np.nextafter(times, -np.inf), np.nextafter(times, np.inf),
                        rng.uniform(times[0] - 1, times[-1] + 1, 500), [times[0] - 1e300, times[-1] + 1e300]])
    expected = np.searchsorted(times, t, side="right") - 1
    np.testing.assert_array_equal(index.find(t), expected)
    np.testing.assert_array_equal(SegmentIndex(times).find(t), expected)
    order = np.argsort(t, kind="stable")
    np.testing.assert_array_equal(index.find_sorted(t[order]), expected[order])   # sorted: runs per key
    assert index.find_sorted(t) is None                                              # unsorted: refused


@pytest.mark.parametrize("method", ["linear", "slerp", "squad", "bezier"])
def test_track_sorted_queries_take_the_run_lookup_with_the_same_result(rng, method):
    keys = rng.standard_normal((60, 4))
    times = np.cumsum(rng.uniform(0.1, 1, 60))
    track = Track(times, keys, method=method, extrapolate="clamp")
    t = np.sort(np.concatenate([rng.uniform(times[0] - 1, times[-1] + 1, 10_000), times]))
    perm = rng.permutation(t.size)
    np.testing.assert_array_equal(np.asarray(track(t))[perm], np.asarray(track(t[perm])))
    np.testing.assert_array_equal(track.angular_velocity(t)[perm], track.angular_velocity(t[perm]))


# ---------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------

GOOD_T = [0.0, 1.0, 2.5]
GOOD_K = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]

BAD_TRACKS = [
    ("not increasing", ([0, 2, 1], GOOD_K, {}), ValueError,
     r"expected times in strictly increasing order, got times\[2\] = 1.0 after times\[1\] = 2.0"),
    ("repeated time", ([0, 1, 1], GOOD_K, {}), ValueError, "strictly increasing order"),
    ("nan time", ([0, np.nan, 2], GOOD_K, {}), ValueError, "expected finite values in times, got nan or inf"),
    ("inf time", ([0, 1, np.inf], GOOD_K, {}), ValueError, "expected finite values in times"),
    ("one key", ([0.0], GOOD_K[:1], {}), ValueError,
     r"expected keys of shape \(K, \.\.\., 4\) with K >= 2.*got \(1, 4\)"),
    ("mismatched K", ([0, 1], GOOD_K, {}), ValueError, "expected as many times as keys .*got 2 times and 3 keys"),
    ("2-D times", ([[0, 1, 2]], GOOD_K, {}), ValueError, r"expected times of shape \(K,\).*got \(1, 3\)"),
    ("keys not (K, ..., 4)", (GOOD_T, [[1, 0, 0], [0, 1, 0], [0, 0, 1]], {}), ValueError,
     r"expected keys of shape \(K, \.\.\., 4\), got \(3, 3\)"),
    ("single quaternion", (GOOD_T, [1, 0, 0, 0], {}), ValueError,
     r"expected keys of shape \(K, \.\.\., 4\), got \(4,\)"),
    ("zero key", (GOOD_T, [[1, 0, 0, 0], [0, 0, 0, 0], [0, 0, 1, 0]], {}), ValueError,
     "expected non-zero keys, got a zero quaternion"),
    ("nan key", (GOOD_T, [[1, 0, 0, 0], [np.nan, 0, 0, 0], [0, 0, 1, 0]], {}), ValueError,
     "expected finite values in keys"),
    ("complex keys", (GOOD_T, np.ones((3, 4), complex), {}), TypeError, "expected keys of real numbers"),
    ("unknown method", (GOOD_T, GOOD_K, {"method": "cubic"}), ValueError,
     r"expected method in \('linear', 'slerp', 'squad', 'bezier', 'spline'\), got 'cubic'"),
    ("unknown extrapolate", (GOOD_T, GOOD_K, {"extrapolate": "wrap"}), ValueError,
     r"expected extrapolate in \('raise', 'clamp', 'extend'\), got 'wrap'"),
]


@pytest.mark.parametrize("args,exc,match", [c[1:] for c in BAD_TRACKS], ids=[c[0] for c in BAD_TRACKS])
def test_track_bad_input(args, exc, match):
    times, keys, kw = args
    with pytest.raises(exc, match=match):
        Track(times, keys, **kw)


BAD_QUERIES = [
    ("below range", "raise", [-0.1, 1.0],
     r"expected t within the range \[0.0, 2.5\], both inclusive \(extrapolate='raise'\), got -0.1"),
    ("above range", "raise", 2.6, r"expected t within the range \[0.0, 2.5\].*got 2.6"),
    ("nan query", "clamp", [0.5, np.nan], r"expected finite values in t, got nan or inf at index \(1,\)"),
    ("inf query clamp", "clamp", [0.5, -np.inf], r"expected finite values in t, got nan or inf at index \(1,\)"),
    ("nan query raise", "raise", np.nan, "expected finite values in t"),
    ("inf query extend", "extend", [np.inf], r"expected finite values in t, got nan or inf"),
    ("far query extend", "extend", [1e100], r"expected t within 10000 end-segment lengths of the keys, "
     r"i\.e\. in \[-10000\.0, 15002\.5\] \(extrapolate='extend'\), got 1e\+100"),
]


@pytest.mark.parametrize("mode,t,match", [c[1:] for c in BAD_QUERIES], ids=[c[0] for c in BAD_QUERIES])
def test_track_bad_queries(mode, t, match):
    track = Track(GOOD_T, GOOD_K, extrapolate=mode)
    with pytest.raises(ValueError, match=match):
        track(t)
    with pytest.raises(ValueError, match=match):
        track.angular_velocity(t)


def test_track_bad_frame_and_query_type():
    track = Track(GOOD_T, GOOD_K)
    with pytest.raises(ValueError, match=r"expected frame in \('world', 'body'\), got 'local'"):
        track.angular_velocity(1.0, frame="local")
    with pytest.raises(TypeError, match="expected t of real numbers"):
        track("1.0")


def test_control_points_bad_input():
    with pytest.raises(ValueError, match=r"expected keys of shape \(K, \.\.\., 4\) with K >= 2"):
        squad_control_points([[1, 0, 0, 0]])
    with pytest.raises(ValueError, match="strictly increasing order"):
        bezier_control_points(GOOD_K, [0, 0, 1])
    with pytest.raises(ValueError, match="got 2 times and 3 keys"):
        squad_control_points(GOOD_K, [0, 1])


@pytest.mark.parametrize("method", ["linear", "slerp", "squad", "bezier", "spline"])
def test_extend_is_finite_and_unit_up_to_its_limit(method, dtype, rng):
    """extrapolate='extend': every query up to EXTEND_LIMIT end-segment lengths out gives
    unit rotations and finite angular velocities; further out a ValueError names t."""
    from quatarray.interpolate import EXTEND_LIMIT
    keys = random_quats(rng, (5, 3), dtype)
    times = np.array([0.0, 1.0, 2.5, 3.0, 3.5])
    track = Track(times, keys, method=method, extrapolate="extend")
    reach = EXTEND_LIMIT * np.array([-1.0, -0.31, 0.73, 1.0])
    t = np.where(reach < 0, reach * 1.0, 3.5 + reach * 0.5)
    q = track(t).ndarray.astype(np.float64)
    assert np.isfinite(q).all()
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1, atol=tol(dtype, 8))
    assert np.isfinite(track.angular_velocity(t)).all()
    for far in (-EXTEND_LIMIT * 1.001, 3.5 + 0.5 * EXTEND_LIMIT * 1.001, 1e154, -1e300):
        with pytest.raises(ValueError, match="expected t within 10000 end-segment lengths"):
            track(far)
        with pytest.raises(ValueError, match="expected t within 10000 end-segment lengths"):
            track.angular_velocity([0.5, far])


@pytest.mark.parametrize("shortest", [True, False])
def test_one_pair_slerp_equals_the_batch_path(rng, dtype, shortest):
    """One pair at a scalar t runs the batch's kernel: the same bits; near-equal, equal
    and opposite pairs and extrapolation included."""
    n = 1024
    a = random_quats(rng, (n,), np.float64)
    b = random_quats(rng, (n,), np.float64)
    b[:50] = a[:50] + 1e-9 * rng.standard_normal((50, 4))
    b[50:60], b[60:70] = a[50:60], -a[60:70]
    t = rng.uniform(-0.5, 1.5, n)
    a, b, t = a.astype(dtype), b.astype(dtype), t.astype(dtype)
    batch = IK.slerp(a, b, t, shortest)
    one = np.array([IK.slerp(x, y, np.array(h), shortest) for x, y, h in zip(a, b, t)])
    assert one.dtype == dtype
    np.testing.assert_array_equal(one, batch)


# --- keys of a Rotation made with normalize=False ---------------------------------------------------------

def _scaled(rng, keys, low=1e-3, high=1e3):
    """`keys` each times its own positive factor, log-uniform in [low, high] (same rotations)."""
    return keys * np.exp(rng.uniform(np.log(low), np.log(high), keys.shape[:-1] + (1,))).astype(keys.dtype)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_slerp_of_non_unit_rotation_keys_equals_scipy(rng, dtype):
    times, keys = random_track(rng, 12, step=1.5)
    raw = _scaled(rng, keys).astype(dtype)
    t = np.concatenate([rng.uniform(times[0], times[-1], 50), times])
    sci = SciRotation.from_quat(raw.astype(np.float64), scalar_first=True)
    ref = SciSlerp(times, sci)(t).as_quat(scalar_first=True)
    given = raw.copy()
    rot = Rotation(raw, normalize=False, copy=False, scalar_first=True)
    got = Slerp(times, rot)(t).as_quat(scalar_first=True)
    assert got.dtype == dtype
    assert_allclose(got, ref, atol=tol(dtype, 20), double_cover=True)
    track = Track(times, rot)(t)
    assert_allclose(track, ref, atol=tol(dtype, 20), double_cover=True)
    np.testing.assert_array_equal(raw, given)   # the rotation's memory is read, not normalised in place
    np.testing.assert_array_equal(rot.as_quat(scalar_first=True), given)


def test_slerp_of_scipy_issue_keys():
    # scipy 1.17: Slerp([0, 1], Rotation([[0,0,0,1],[0,0,1,1]], normalize=False, copy=False))(0.5) is the unit 45°
    keys = np.array([[0, 0, 0, 1], [0, 0, 1, 1]], dtype=float)
    ref = SciSlerp([0, 1], SciRotation(keys, normalize=False, copy=False))(0.5).as_quat()
    got = Slerp([0, 1], Rotation(keys, normalize=False, copy=False))(0.5).as_quat()
    assert_allclose(got, ref, atol=tol(np.float64, 4))
    assert_allclose(got, [0, 0, np.sin(np.pi / 8), np.cos(np.pi / 8)], atol=tol(np.float64, 4))


def test_slerp_of_non_unit_rotation_keys_batched_equals_per_track(rng):
    times, keys = random_track(rng, 5, (2, 3), step=1.2)
    raw = _scaled(rng, keys)
    t = rng.uniform(times[0], times[-1], 20)
    got = Slerp(times, Rotation(raw, normalize=False, scalar_first=True), batched=True)(t).as_quat(scalar_first=True)
    for i in range(2):
        for j in range(3):
            ref = SciSlerp(times, SciRotation.from_quat(raw[:, i, j], scalar_first=True))(t)
            assert_allclose(got[:, i, j], ref.as_quat(scalar_first=True), atol=tol(np.float64, 20), double_cover=True)


@pytest.mark.parametrize("make, name", [(lambda r: Slerp([0, 1, 2], r), "rotations"),
                                        (lambda r: Track([0, 1, 2], r), "keys")], ids=["Slerp", "Track"])
def test_zero_rotation_key_raises_naming_the_argument(make, name):
    keys = np.array([[0, 0, 0, 1], [0, 0, 0, 0], [0, 0, 1, 1]], dtype=float)
    with pytest.raises(ValueError, match="zero norm quaternions"):   # scipy's answer
        SciSlerp([0, 1, 2], SciRotation(keys, normalize=False))
    with pytest.raises(ValueError, match=rf"zero norm quaternions in `{name}`.*index \(1,\)"):
        make(Rotation(keys, normalize=False))


@pytest.mark.parametrize("scale", [1e200, 1e-200, 1e300])
def test_huge_and_tiny_rotation_keys_slerp_as_their_unit_ones(rng, scale):
    # scipy's squared norm over- or underflows here (it raises "zero norm"); the rotations are
    # the unit ones all the same
    times, keys = random_track(rng, 6, step=1.0)
    t = rng.uniform(times[0], times[-1], 30)
    ref = SciSlerp(times, SciRotation.from_quat(keys, scalar_first=True))(t).as_quat(scalar_first=True)
    rot = Rotation(keys * scale, normalize=False, scalar_first=True)
    for got in (Slerp(times, rot)(t).as_quat(scalar_first=True), np.asarray(Track(times, rot)(t))):
        assert np.isfinite(got).all()
        assert_allclose(got, ref, atol=tol(np.float64, 20), double_cover=True)


def test_every_interpolation_function_takes_rotations(rng):
    """slerp, squad, the control points and the rest take a `Rotation` (quatarray's or scipy's)
    wherever they take quaternions, as `Track` does: the same answer as its scalar-first unit
    quaternions (they raised TypeError, though the README said they take a Rotation as keys)."""
    r = Rotation.from_quat(rng.normal(size=(5, 4)))
    q = r.as_quat(scalar_first=True)
    a, b = r[:4], r[1:]
    qa, qb = q[:4], q[1:]
    t = np.linspace(0, 1, 4)
    for f in (lerp, nlerp, slerp):
        np.testing.assert_array_equal(f(a, b, t).ndarray, f(qa, qb, t).ndarray)
        assert_allclose(f(a.to_scipy(), b, t), f(qa, qb, t), rtol=0, atol=4 * np.finfo(float).eps)
    for f in (squad, bezier):
        np.testing.assert_array_equal(f(a, b, a, b, t).ndarray, f(qa, qb, qa, qb, t).ndarray)
    np.testing.assert_array_equal(unflip(r).ndarray, unflip(q).ndarray)
    times = np.cumsum(rng.uniform(0.5, 2, size=5))
    assert_allclose(squad_control_points(r, times), squad_control_points(q, times), rtol=0,
                    atol=4 * np.finfo(float).eps)
    for got, want in zip(bezier_control_points(r, times), bezier_control_points(q, times)):
        assert_allclose(got, want, rtol=0, atol=4 * np.finfo(float).eps)
    with pytest.raises(ValueError, match="keys"):
        squad_control_points(r[:1])
