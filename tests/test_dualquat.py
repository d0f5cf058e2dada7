"""Raw dual quaternions and ScLERP against scipy's RigidTransform and screw-motion formulas."""

import numpy as np
import pytest
from scipy.spatial.transform import RigidTransform as SRT
from scipy.spatial.transform import Rotation as SR

from quatarray import _dualquat as D
from quatarray import _kernels as Kn
from quatarray.interpolate import slerp

from .conftest import random_quats


def _same_motion(a, b, atol):
    """a and b are equal up to the sign of the whole dual quaternion."""
    sign = np.where(np.sum(a[..., :4] * b[..., :4], axis=-1, keepdims=True) < 0, -1, 1)
    return np.allclose(sign * a, b, atol=atol)


def _motions(rng, shape, dtype=np.float64):
    q = random_quats(rng, shape, dtype)
    t = rng.standard_normal(tuple(shape) + (3,)).astype(dtype)
    return q, t


@pytest.mark.parametrize("shape", [(), (5,), (2, 3)])
def test_conversions_match_scipy(rng, shape):
    q, t = _motions(rng, shape)
    dq = D.from_rotation_translation(q, t)
    ref = SRT.from_components(t, SR.from_quat(q, scalar_first=True)).as_dual_quat(scalar_first=True)
    assert _same_motion(dq, ref, 1e-14)
    q2, t2 = D.as_rotation_translation(dq)
    assert np.allclose(q2, q, atol=1e-15) and np.allclose(t2, t, atol=1e-14)


def test_product_and_inverse_match_scipy(rng):
    (q1, t1), (q2, t2) = _motions(rng, (6,)), _motions(rng, (6,))
    a, b = D.from_rotation_translation(q1, t1), D.from_rotation_translation(q2, t2)
    ta = SRT.from_components(t1, SR.from_quat(q1, scalar_first=True))
    tb = SRT.from_components(t2, SR.from_quat(q2, scalar_first=True))
    assert _same_motion(D.multiply(a, b), (ta * tb).as_dual_quat(scalar_first=True), 1e-14)
    assert _same_motion(D.conjugate(a), ta.inv().as_dual_quat(scalar_first=True), 1e-14)


def test_normalize_gives_unit_dual_quaternion(rng):
    dq = rng.standard_normal((7, 8))
    n = D.normalize(dq)
    assert np.allclose(np.linalg.norm(n[:, :4], axis=-1), 1, atol=1e-15)
    assert np.allclose(np.sum(n[:, :4] * n[:, 4:], axis=-1), 0, atol=1e-15)
    # a unit dual quaternion is unchanged
    q, t = _motions(rng, (7,))
    u = D.from_rotation_translation(q, t)
    assert np.allclose(D.normalize(u), u, atol=1e-15)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_power_composes(rng, dtype):
    q, t = _motions(rng, (8,), dtype)
    dq = D.from_rotation_translation(q, t)
    half = D.power(dq, 0.5)
    assert half.dtype == dtype
    eps = np.finfo(dtype).eps
    assert _same_motion(D.multiply(half, half), dq, 200 * eps)
    assert _same_motion(D.power(dq, 1.0), dq, 200 * eps)


def _screw_motion(angle, axis, point, disp):
    """Rotation by `angle` about `axis` through `point`, then `disp` along the axis."""
    q = np.concatenate([np.cos(angle / 2)[..., None], np.sin(angle / 2)[..., None] * axis], axis=-1)
    t = disp[..., None] * axis + point - Kn.rotate(q, np.broadcast_to(point, q.shape[:-1] + (3,)))
    return D.from_rotation_translation(q, t)


def test_sclerp_reproduces_constant_screw(rng):
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    point = np.cross(axis, rng.standard_normal(3))
    omega, speed = 1.3, -0.7  # rad and length per unit time
    s = np.linspace(0, 1, 11)
    a = _screw_motion(np.array(0.2), axis, point, np.array(0.5))
    b = D.multiply(_screw_motion(np.array(omega), axis, point, np.array(speed)), a)
    expected = D.multiply(_screw_motion(omega * s, axis, point, speed * s), a)
    assert _same_motion(D.sclerp(a, b, s), expected, 1e-13)


def test_sclerp_velocity_constant(rng):
    (q1, t1), (q2, t2) = _motions(rng, (4,)), _motions(rng, (4,))
    a, b = D.from_rotation_translation(q1, t1), D.from_rotation_translation(q2, t2)
    path = D.sclerp(a, b, np.linspace(0, 1, 9))  # (4, 9, 8)
    steps = D.multiply(path[:, 1:], D.conjugate(path[:, :-1]))  # motion over each step, in the world frame
    assert _same_motion(steps, np.broadcast_to(steps[:, :1], steps.shape), 1e-13)


def test_sclerp_axis_through_origin_is_slerp_plus_lerp(rng):
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    angles, disps = np.array([0.3, 2.1]), np.array([-0.4, 1.7])
    q = np.concatenate([np.cos(angles / 2)[:, None], np.sin(angles / 2)[:, None] * axis], axis=-1)
    t = disps[:, None] * axis
    a, b = D.from_rotation_translation(q[0], t[0]), D.from_rotation_translation(q[1], t[1])
    s = np.linspace(0, 1, 7)
    got_q, got_t = D.as_rotation_translation(D.sclerp(a, b, s))
    assert np.allclose(got_q, slerp(q[0], q[1], s), atol=1e-14)
    assert np.allclose(got_t, t[0] + s[:, None] * (t[1] - t[0]), atol=1e-14)


def test_blend_of_one_and_of_equal_motions(rng):
    q, t = _motions(rng, (3,))
    dq = D.from_rotation_translation(q, t)
    same = np.stack([dq, -dq, dq])  # the sign of a dual quaternion does not change the motion
    assert _same_motion(D.blend(same, [0.2, 0.5, 0.3]), dq, 1e-14)
    # DLB of two motions is the normalised weighted sum
    b = D.from_rotation_translation(*_motions(rng, (3,)))
    expected = D.normalize(0.25 * dq + 0.75 * np.where(np.sum(dq[..., :4] * b[..., :4], -1, keepdims=True) < 0, -b, b))
    assert _same_motion(D.blend(np.stack([dq, b]), [0.25, 0.75]), expected, 1e-14)
