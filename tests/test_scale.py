"""Quaternions of extreme magnitude: r q for r from 1e-300 to 1e300 (float64) and
1e-35 to 1e35 (float32) gives what q gives, scaled as the maths says."""

import math

import numpy as np
import pytest

from quatarray import QuatArray, Rotation, RotationSpline, Track
from quatarray import _convert as C
from quatarray import _kernels as K
from quatarray import _scale

from .conftest import random_quats, tol

R64 = [10.0 ** e for e in range(-300, 301, 25)] + [5e-324 * 2 ** 60, 1.7e308 / 4]
R32 = [10.0 ** e for e in range(-35, 36, 5)]

def _rot(q):
    return Rotation.from_quat(q, scalar_first=True)


# functions of the rotation q/|q|: the same for every magnitude of q
SCALE_FREE = {
    "as_matrix": lambda q, v: QuatArray(q).as_matrix(),
    "as_rotvec": lambda q, v: QuatArray(q).as_rotvec(),
    "as_mrp": lambda q, v: QuatArray(q).as_mrp(),
    "as_euler": lambda q, v: QuatArray(q).as_euler("xyz"),
    "as_euler_zxz": lambda q, v: QuatArray(q).as_euler("ZXZ"),
    "as_davenport": lambda q, v: QuatArray(q).as_davenport(np.eye(3)[[2, 0, 1]], "e"),
    "magnitude": lambda q, v: C.magnitude(q),
    "rotate": lambda q, v: QuatArray(q).rotate(v),
    "rotate_inverse": lambda q, v: K.rotate(q, v, inverse=True),
    "normalized": lambda q, v: QuatArray(q).normalized().ndarray,
    "canonical_from_quat": lambda q, v: _rot(q).as_quat(canonical=True),
    "Rotation.apply": lambda q, v: _rot(q).apply(v),
    "Rotation.magnitude": lambda q, v: _rot(q).magnitude(),
    "Rotation.mean": lambda q, v: _rot(q).mean().as_quat(),
    "Rotation.approx_equal": lambda q, v: _rot(q).approx_equal(_rot(QuatArray(q).normalized().ndarray)),
    "Rotation.unnormalized": lambda q, v: Rotation(q, scalar_first=True, normalize=False).as_matrix(),
}


def close(actual, desired, **kw):
    """numpy.testing.assert_allclose on plain arrays (QuatArray's isnan is per quaternion)."""
    plain = [x.ndarray if isinstance(x, QuatArray) else np.asarray(x) for x in (actual, desired)]
    np.testing.assert_allclose(*plain, **kw)


def _ratios(dtype):
    return R64 if dtype == np.float64 else R32


@pytest.mark.parametrize("name", sorted(SCALE_FREE))
@pytest.mark.parametrize("single", [False, True], ids=["batch", "single"])
def test_scale_free_functions_ignore_the_magnitude(name, single, dtype, rng):
    q = random_quats(rng, (7,), np.float64)
    v = rng.standard_normal((7, 3))
    if single:
        q, v = q[0], v[0]
    f = SCALE_FREE[name]
    ref = np.asarray(f(q, v), np.float64)
    for r in _ratios(dtype):
        got = f((r * q).astype(dtype), v.astype(dtype))
        close(np.asarray(got, np.float64), ref, atol=tol(dtype, 200),
                                   err_msg=f"{name} at r = {r:g}")


def test_norm_inverse_log_power_scale_as_the_maths_says(dtype, rng):
    q = random_quats(rng, (5,), np.float64)
    for r in _ratios(dtype):
        rq = QuatArray((r * q).astype(dtype))
        rr = float(dtype(r))
        close(rq.norm(), rr, rtol=tol(dtype, 4), err_msg=f"norm at {r:g}")
        inv = rq.inverse()   # conj(q) / r (finite whenever 1/r is)
        if math.isfinite(1 / rr) and 1 / rr > np.finfo(dtype).tiny:
            close(np.asarray(inv, np.float64) * rr, np.asarray(QuatArray(q).conj()),
                                       atol=tol(dtype, 8), err_msg=f"inverse at {r:g}")
        lg = np.asarray(rq.log(), np.float64)   # (ln r, log(q) vector part)
        close(lg[..., 0], math.log(rr), rtol=tol(dtype, 8), atol=tol(dtype, 8))
        close(lg[..., 1:], np.asarray(QuatArray(q).log())[..., 1:],
                                   atol=tol(dtype, 20), err_msg=f"log at {r:g}")
        half = np.asarray(rq ** 0.5, np.float64) / math.sqrt(rr)
        close(half, np.asarray(QuatArray(q) ** 0.5), atol=tol(dtype, 20), err_msg=f"power at {r:g}")
        close(np.asarray(rq ** 0), QuatArray.identity(5), atol=0)


def test_the_audited_cases():
    big = QuatArray([[0.6e300, 0.8e300, 0, 0]])
    expected = QuatArray([[0.6, 0.8, 0, 0]])
    close(big.as_matrix(), expected.as_matrix(), atol=1e-15)
    close(C.magnitude(big.ndarray), 2 * math.atan2(0.8, 0.6), rtol=1e-15)
    small = QuatArray([0.6e-200, 0.8e-200, 0, 0])
    close(small.log(), [math.log(1e-200), math.atan2(0.8, 0.6), 0, 0], rtol=1e-15)
    close(small ** 0.5, 1e-100 * (QuatArray([0.6, 0.8, 0, 0]) ** 0.5), rtol=1e-14)
    close(QuatArray([1e-310, 0, 0, 0]) ** 0, atol=0, desired= [1, 0, 0, 0])
    track = Track([0, 1], [[1e300, 0, 0, 0], [0.6e300, 0.8e300, 0, 0]])
    close(track(0.5), Track([0, 1], [[1, 0, 0, 0], [0.6, 0.8, 0, 0]])(0.5), atol=1e-15)
    assert QuatArray([1e300, 0, 0, 0]).norm() == 1e300
    tiny = QuatArray([[0.6e-300, 0.8e-300, 0, 0]])
    close(tiny.as_matrix(), expected.as_matrix(), atol=1e-15)
    close(Rotation(tiny.ndarray, scalar_first=True, normalize=False).apply([0, 1, 0]), expected.rotate([0, 1, 0]),
          atol=1e-15)
    close(tiny.normalized(), expected, atol=1e-15)
    close(tiny.inverse(), expected.conj() / 1e-300, rtol=1e-15)
    close(tiny.rotate([0, 1, 0]), expected.rotate([0, 1, 0]), atol=1e-15)


def test_spline_keys_of_extreme_magnitude():
    keys = np.array([[1.0, 0, 0, 0], [0.6, 0.8, 0, 0], [0, 0, 1, 0]])
    ref = RotationSpline([0, 1, 2], QuatArray(keys))([0.3, 1.5]).as_quat()
    for r in (1e-300, 1e300):
        close(RotationSpline([0, 1, 2], QuatArray(r * keys))([0.3, 1.5]).as_quat(), ref, atol=1e-15)


def test_from_matrix_of_scaled_rotations_is_the_rotation():
    # scipy: Rotation.from_matrix(1e103 * np.eye(3)) is the identity
    close(Rotation.from_matrix(1e103 * np.eye(3)).as_quat(scalar_first=True), [1, 0, 0, 0], atol=1e-15)
    m = Rotation.from_euler("xyz", [0.3, -0.2, 1.1]).as_matrix()
    for r in (1e-150, 1e103, 1e150):
        close(Rotation.from_matrix(r * m).as_matrix(), m, atol=1e-14)
    given = 1e103 * np.eye(3)
    Rotation.from_matrix(given)
    np.testing.assert_array_equal(given, 1e103 * np.eye(3))   # not modified
    with pytest.raises(ValueError, match="Non-positive determinant"):
        Rotation.from_matrix(-1e103 * np.eye(3))


@pytest.mark.parametrize("r", [5e-324, 1e-310, 1e-300])
def test_only_the_exact_zero_is_zero(r):
    q = QuatArray([[r, 0, 0, 0], [0, 0, r, 0]])
    close(q.normalized(), [[1, 0, 0, 0], [0, 0, 1, 0]], atol=0, rtol=0)
    close(q.rotate([1, 0, 0]), [[1, 0, 0], [-1, 0, 0]], atol=1e-15)
    zero = QuatArray([0.0, 0, 0, 0])
    with pytest.raises(ValueError, match="zero quaternion"):
        zero.normalized()
    with pytest.raises(ZeroDivisionError, match="zero quaternion"):
        zero.inverse()


def test_guard_leaves_ordinary_blocks_alone():
    q = np.array([[0.5, 1.0], [0.5, 0.0], [0.5, 0.0], [0.5, 0.0]])
    n2 = _scale.sum_squares(q, np.empty(2))
    assert _scale.guard(q, n2) is None
    q[0, 1] = 1e-300
    e = _scale.guard(q, _scale.sum_squares(q, n2))
    np.testing.assert_array_equal(np.ldexp(q, e), [[0.5, 1e-300], [0.5, 0], [0.5, 0], [0.5, 0]])
    q[0, 0] = np.nan
    with pytest.raises(ValueError, match="expected finite quaternions, got nan or inf"):
        _scale.guard(q, _scale.sum_squares(q, n2))
