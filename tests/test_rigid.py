"""Public rigid-motion functions in scipy's dual-quaternion layout."""

import numpy as np
import pytest
from scipy.spatial.transform import RigidTransform as SRT
from scipy.spatial.transform import Rotation as SR
from scipy.spatial.transform._rigid_transform import normalize_dual_quaternion as scipy_normalize

from quatarray import _dualquat as D
from quatarray import dual_quaternion_blend, normalize_dual_quaternion, sclerp


def _transforms(rng, n):
    return SRT.from_components(rng.standard_normal((n, 3)), SR.random(n, rng=rng))


@pytest.mark.parametrize("shape", [(8,), (1, 8), (3, 8), (2, 3, 8)])
def test_normalize_matches_scipy(rng, shape):
    dq = rng.standard_normal(shape)
    assert np.allclose(normalize_dual_quaternion(dq), scipy_normalize(dq), atol=1e-15)
    assert np.allclose(normalize_dual_quaternion(np.zeros(shape)), scipy_normalize(np.zeros(shape)), atol=0)


def test_normalize_scalar_first_and_float32(rng):
    dq = rng.standard_normal((4, 8)).astype(np.float32)
    out = normalize_dual_quaternion(dq, scalar_first=True)
    assert out.dtype == np.float32
    assert np.allclose(out, D.normalize(dq), atol=10 * np.finfo(np.float32).eps)


def test_sclerp_endpoints_and_layout(rng):
    a, b = _transforms(rng, 5), _transforms(rng, 5)
    t = np.array([0.0, 0.4, 1.0])
    got = sclerp(a.as_dual_quat(), b.as_dual_quat(), t)
    assert got.shape == (5, 3, 8)
    ends = SRT.from_dual_quat(got[:, [0, 2]].reshape(-1, 8)).as_matrix().reshape(5, 2, 4, 4)
    assert np.allclose(ends[:, 0], a.as_matrix(), atol=1e-13)
    assert np.allclose(ends[:, 1], b.as_matrix(), atol=1e-13)
    first = sclerp(a.as_dual_quat(scalar_first=True), b.as_dual_quat(scalar_first=True), t, scalar_first=True)
    mid = SRT.from_dual_quat(got[:, 1]).as_matrix()
    assert np.allclose(SRT.from_dual_quat(first[:, 1], scalar_first=True).as_matrix(), mid, atol=1e-13)


def test_sclerp_float32(rng):
    a, b = _transforms(rng, 3), _transforms(rng, 3)
    got = sclerp(a.as_dual_quat().astype(np.float32), b.as_dual_quat().astype(np.float32), np.float32(0.3))
    ref = sclerp(a.as_dual_quat(), b.as_dual_quat(), 0.3)
    assert got.dtype == np.float32
    sign = np.sign(np.sum(got[..., :4] * ref[..., :4], axis=-1, keepdims=True))
    assert np.allclose(sign * got, ref, atol=1e3 * np.finfo(np.float32).eps)


def test_blend_weighted_translation_and_axis(rng):
    tr = rng.standard_normal((4, 2, 3))
    dq = SRT.from_translation(tr.reshape(-1, 3)).as_dual_quat().reshape(4, 2, 8)
    w = np.array([0.1, 0.2, 0.3, 0.4])
    out = dual_quaternion_blend(dq, w)
    assert np.allclose(SRT.from_dual_quat(out).translation, np.einsum("k,kij->ij", w, tr), atol=1e-14)
    along1 = dual_quaternion_blend(np.swapaxes(dq, 0, 1), w, axis=1)
    assert np.allclose(along1, out, atol=1e-15)


@pytest.mark.parametrize("call, match", [
    (lambda: sclerp(np.zeros(7), np.zeros(8), 0.5), "a of shape"),
    (lambda: sclerp(np.eye(8)[0], np.eye(8)[0], np.nan), "finite values in t"),
    (lambda: dual_quaternion_blend(np.eye(8)[:3], [1.0, 2.0]), "weights of shape"),
    (lambda: dual_quaternion_blend(np.eye(8)[0], [1.0]), "dual_quats of shape"),
    (lambda: dual_quaternion_blend(np.eye(8)[:3], [1.0] * 3, axis=1), "axis"),
    (lambda: normalize_dual_quaternion([[1.0] * 8, [np.inf] * 8]), "finite values in dual_quat"),
])
def test_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call()
