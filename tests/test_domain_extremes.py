"""The whole float range (issue: an adversarial run of 20,800 cases): valid input of any
magnitude gives finite, unit results (scipy or an mpmath reference as the expected value),
and invalid input a ValueError/TypeError that names what is wrong."""

import numpy as np
import pytest
from scipy.spatial.transform import RigidTransform as ScipyRigidTransform
from scipy.spatial.transform import Rotation as ScipyRotation

from quatarray import QuatArray, RigidTransform, Rotation, Track


# --- errors that name the argument -------------------------------------------------------

def test_random_with_a_tuple_num_is_a_type_error_as_in_scipy():
    with pytest.raises(TypeError) as theirs:
        ScipyRotation.random((3, 2))
    with pytest.raises(TypeError, match=r"Argument 'num' has incorrect type \(expected int, got tuple\)") as ours:
        Rotation.random((3, 2))
    assert str(ours.value) == str(theirs.value)


@pytest.mark.parametrize("n", [np.inf, -np.inf, np.nan])
def test_rotation_power_names_a_non_finite_exponent(n):
    r = Rotation.from_rotvec([[0.1, 0, 0], [0, 0.2, 0]])
    with pytest.raises(ValueError, match="expected a finite exponent n, got"):
        r ** n
    with pytest.raises(ValueError, match="expected a finite exponent n, got"):
        r[0] ** n
    with pytest.raises(ValueError, match="expected finite values in the exponent n"):
        r ** np.array([1.0, n])


@pytest.mark.parametrize("n", [np.inf, np.nan])
def test_rigid_transform_power_names_a_non_finite_exponent(n):
    tf = RigidTransform.from_translation([1.0, 0, 0])
    with pytest.raises(ValueError, match="expected a finite exponent n, got"):
        tf ** n


def test_rigid_transform_mean_with_zero_weights_names_the_weights():
    tf = RigidTransform.from_translation([[1.0, 0, 0], [2.0, 0, 0]])
    with pytest.raises(ZeroDivisionError):   # scipy refuses it too, as a ZeroDivisionError
        ScipyRigidTransform.from_translation([[1.0, 0, 0], [2.0, 0, 0]]).mean(weights=[0, 0])
    with pytest.raises(ValueError, match="expected weights with a positive sum"):
        tf.mean(weights=[0, 0])
    # one zero weight is fine: the other transform's translation
    assert np.array_equal(tf.mean(weights=[0, 1]).translation, [2.0, 0, 0])


def test_track_accepts_scipy_rotation_keys():
    keys = ScipyRotation.from_rotvec([[0, 0, 0], [0.4, 0, 0], [0.4, 0.3, 0]])
    ours = Track([0, 1, 2], keys)(np.array([0.25, 1.5]))
    ref = ScipyRotation.from_quat(np.asarray(ours)[:, [1, 2, 3, 0]])
    expected = Track([0, 1, 2], Rotation.from_scipy(keys))(np.array([0.25, 1.5]))
    assert np.array_equal(np.asarray(ours), np.asarray(expected))
    assert ref.approx_equal(ScipyRotation.from_rotvec([[0.1, 0, 0], [0.4, 0.15, 0]]), atol=0.02).all()


def test_multiply_reduce_of_a_single_quaternion_says_it_has_no_batch_axis():
    with pytest.raises(ValueError, match="at least one batch axis for axis=0, got a single quaternion"):
        np.multiply.reduce(QuatArray([1.0, 0, 0, 0]), axis=0)
    # a batch of one still reduces
    assert np.array_equal(np.asarray(np.multiply.reduce(QuatArray([[1.0, 0, 0, 0]]), axis=0)), [1.0, 0, 0, 0])


# --- big-endian input: accepted wherever scipy accepts it, the same values ---------------

import quatarray as qa  # noqa: E402

RT = RigidTransform
R = Rotation
QA = QuatArray
_rng = np.random.default_rng(0)
q = _rng.standard_normal((5, 4))
v = _rng.standard_normal((5, 3))
m = Rotation.random(5, rng=1).as_matrix()
t = np.linspace(0, 1, 5)
BIG_ENDIAN_CALLS = {
 'from_quat': lambda B: R.from_quat(B(q)).as_quat(),
 'from_rotvec': lambda B: R.from_rotvec(B(v)).as_quat(),
 'from_rotvec1': lambda B: R.from_rotvec(B(v[0])).as_quat(),
 'from_mrp': lambda B: R.from_mrp(B(v)).as_quat(),
 'from_mrp1': lambda B: R.from_mrp(B(v[0])).as_quat(),
 'from_matrix': lambda B: R.from_matrix(B(m)).as_quat(),
 'from_euler': lambda B: R.from_euler('xyz', B(v)).as_quat(),
 'from_davenport': lambda B: R.from_davenport(B(np.eye(3)), 'extrinsic', B(v)).as_quat(),
 'apply': lambda B: R.from_quat(q).apply(B(v)),
 'apply1': lambda B: R.from_quat(q[0]).apply(B(v[0])),
 'pow': lambda B: (R.from_quat(q)**B(np.array(0.3))).as_quat(),
 'mean w': lambda B: R.from_quat(q).mean(weights=B(np.ones(5))).as_quat(),
 'align': lambda B: R.align_vectors(B(v), B(v[::-1]))[0].as_quat(),
 'QA': lambda B: np.asarray(QA(B(q))),
 'QA matrix': lambda B: QA(B(q)).as_matrix(),
 'QA rotvec': lambda B: QA(B(q)).as_rotvec(),
 'QA euler': lambda B: QA(B(q)).as_euler('xyz'),
 'QA mrp': lambda B: QA(B(q)).as_mrp(),
 'QA norm': lambda B: QA(B(q)).norm(),
 'QA normalized': lambda B: np.asarray(QA(B(q)).normalized()),
 'QA mul': lambda B: np.asarray(QA(B(q))*QA(B(q))),
 'QA log': lambda B: np.asarray(QA(B(q)).log()),
 'QA exp': lambda B: np.asarray(QA(B(q)).exp()),
 'QA pow': lambda B: np.asarray(QA(B(q))**0.5),
 'QA rotate': lambda B: QA(B(q)).rotate(B(v)),
 'slerp': lambda B: np.asarray(qa.slerp(QA(B(q[:4])), QA(B(q[1:])), B(t[:4]))),
 'Track': lambda B: np.asarray(qa.Track(B(t), QA(B(q)))(B(t*0.9))),
 'Track sp': lambda B: np.asarray(qa.Track(B(t), QA(B(q)), method='spline')(B(t*0.9))),
 'Spline': lambda B: qa.RotationSpline(B(t), R.from_quat(B(q)))(B(t*0.9)).as_quat(),
 'Slerp': lambda B: qa.Slerp(B(t), R.from_quat(B(q)))(B(t*0.9)).as_quat(),
 'RT comp': lambda B: RT.from_components(B(v), R.from_quat(B(q))).as_matrix(),
 'RT matrix': lambda B: RT.from_matrix(B(RT.from_components(v, R.from_quat(q)).as_matrix())).as_matrix(),
 'RT exp': lambda B: RT.from_exp_coords(B(np.hstack([v,v]))).as_matrix(),
 'RT dq': lambda B: RT.from_dual_quat(B(np.hstack([q,q]))).as_matrix(),
 'RT apply': lambda B: RT.from_translation(v).apply(B(v)),
 'unflip': lambda B: np.asarray(qa.unflip(QA(B(q)))),
 'squad': lambda B: np.asarray(qa.squad(QA(B(q[:2])),QA(B(q[1:3])),QA(B(q[2:4])),QA(B(q[3:5])), B(t[:2]))),
 'nlerp': lambda B: np.asarray(qa.nlerp(QA(B(q[:4])), QA(B(q[1:])), B(t[:4]))),
 'lerp': lambda B: np.asarray(qa.lerp(QA(B(q[:4])), QA(B(q[1:])), B(t[:4]))),
}


@pytest.mark.filterwarnings("ignore::UserWarning")
@pytest.mark.parametrize("dt", ["f8", "f4"])
@pytest.mark.parametrize("name", sorted(BIG_ENDIAN_CALLS))
def test_big_endian_input_gives_the_native_result(name, dt):
    call = BIG_ENDIAN_CALLS[name]
    native = np.asarray(call(lambda a: np.asarray(a).astype("<" + dt)))
    swapped = np.asarray(call(lambda a: np.asarray(a).astype(">" + dt)))
    assert swapped.dtype.isnative and np.array_equal(native, swapped)


def test_big_endian_examples_match_scipy():
    ones = np.ones(3, ">f8")
    assert np.allclose(Rotation.from_rotvec(ones).as_quat(), ScipyRotation.from_rotvec(ones).as_quat(), atol=1e-15)
    assert np.allclose(Rotation.from_mrp(ones).as_quat(), ScipyRotation.from_mrp(ones).as_quat(), atol=1e-15)
    q4 = np.ones((2, 4), ">f8")
    assert np.allclose(QuatArray(q4).as_matrix(), ScipyRotation.from_quat(q4).as_matrix(), atol=1e-15)


# --- vectors near the float maximum ----------------------------------------------------------

def _big_vectors(rng, shape, big, fraction):
    """Vectors of norm `fraction` of the float maximum: random directions, and the axes."""
    v = rng.standard_normal(shape + (3,))
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    flat = v.reshape(-1, 3)
    flat[:6] = np.concatenate([np.eye(3), -np.eye(3)])[:len(flat)]
    return v * (big * fraction)


def _reference_apply(q, v, t=None, inverse=False):
    """scipy's rotation of v scaled down by an exact power of two, scaled back up."""
    k = 2.0 ** 600 if np.dtype(v.dtype) == np.float64 else 2.0 ** 64
    q64, v64 = np.asarray(q, np.float64), np.asarray(v, np.float64) / k
    t64 = None if t is None else np.asarray(t, np.float64) / k
    if t is None:
        res = ScipyRotation.from_quat(q64, scalar_first=True).apply(v64, inverse=inverse)
    else:
        res = ScipyRigidTransform.from_components(t64, ScipyRotation.from_quat(q64, scalar_first=True)).apply(
            v64, inverse=inverse)
    return res * k


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shapes", [((), ()), ((), (7,)), ((7,), ()), ((7,), (7,)), ((300,), (300,))],
                         ids=["one-one", "one-many", "many-one", "many-many", "long"])
@pytest.mark.parametrize("inverse", [False, True])
def test_apply_rotates_vectors_near_the_float_maximum(dtype, shapes, inverse):
    rng = np.random.default_rng(5)
    big = float(np.finfo(dtype).max)
    q = rng.standard_normal(shapes[0] + (4,)).astype(dtype)
    v = _big_vectors(rng, shapes[1], big, 0.97).astype(dtype)
    ours = Rotation.from_quat(q, scalar_first=True).apply(v, inverse=inverse)
    ref = _reference_apply(q, v, inverse=inverse)
    assert ours.dtype == dtype and np.isfinite(ours).all()
    assert np.max(np.abs(ours - ref)) <= 8 * np.finfo(dtype).eps * big
    if not inverse:
        res = QuatArray(q).rotate(v)
        assert np.isfinite(res).all() and np.max(np.abs(res - ref)) <= 8 * np.finfo(dtype).eps * big


def test_apply_issue_example_matches_scipy():
    expected = ScipyRotation.from_quat([0, 0, 1, 0]).apply([1e308, 0, 0])
    assert np.array_equal(Rotation.from_quat([0, 0, 1, 0]).apply([1e308, 0, 0]), expected)
    assert np.array_equal(QuatArray([0.0, 0, 0, 1]).rotate([1e308, 0, 0]), expected)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("n", [None, 5, 600], ids=["one", "short", "fused"])
@pytest.mark.parametrize("inverse", [False, True])
def test_rigid_transform_applies_to_vectors_near_the_float_maximum(dtype, n, inverse):
    rng = np.random.default_rng(6)
    big = float(np.finfo(dtype).max)
    shape = () if n is None else (n,)
    q = rng.standard_normal(shape + (4,)).astype(dtype)
    v = _big_vectors(rng, shape, big, 0.7).astype(dtype)
    t = _big_vectors(rng, shape, big, 0.25).astype(dtype)
    tf = RigidTransform.from_components(t, Rotation.from_quat(q, scalar_first=True))
    ours = tf.apply(v, inverse=inverse)
    ref = _reference_apply(q, v, t, inverse=inverse)
    assert np.isfinite(ours).all()
    assert np.max(np.abs(ours - ref)) <= 8 * np.finfo(dtype).eps * big


# --- tiny angles, tiny quaternions, the zero quaternion --------------------------------------

TINY64 = [1e-150, 1e-158, 1e-160, 1e-200, 1e-300, 1e-310, 5e-324]
TINY32 = [1e-18, 1e-20, 1e-30, 1e-38, 1e-40, 1e-45]


def _tiny_cases():
    return [(np.float64, s) for s in TINY64] + [(np.float32, s) for s in TINY32]


def _mp_rotvec_z(s, w=1.0):
    """mpmath: the rotation vector of the quaternion (w, 0, 0, s), 2 atan2(s, w) about z."""
    import mpmath
    mpmath.mp.dps = 50
    return float(2 * mpmath.atan2(mpmath.mpf(s), mpmath.mpf(w)))


@pytest.mark.parametrize("dtype,s", _tiny_cases())
def test_tiny_rotation_vectors_are_kept(dtype, s):
    s = dtype(s)
    quat = np.array([0, 0, s, 1], dtype)
    expected = _mp_rotvec_z(float(s))
    rtol = 4 * np.finfo(dtype).eps
    for r in (Rotation.from_quat(quat), Rotation.from_quat(np.tile(quat, (3, 1)))):
        got = np.asarray(r.as_rotvec()).reshape(-1, 3)
        assert got.dtype == dtype
        np.testing.assert_allclose(got[:, 2], expected, rtol=rtol, atol=0)
        assert not got[:, :2].any()
        np.testing.assert_allclose(np.asarray(r.magnitude()).reshape(-1), expected, rtol=rtol, atol=0)
    assert np.asarray(QuatArray(np.array([1, 0, 0, s], dtype)).as_rotvec())[2] > 0
    if dtype == np.float64:   # scipy keeps them too
        np.testing.assert_allclose(Rotation.from_quat(quat).as_rotvec(),
                                   ScipyRotation.from_quat(quat).as_rotvec(), rtol=rtol, atol=0)


@pytest.mark.parametrize("dtype,s", [c for c in _tiny_cases() if c[1] > (1e-300 if c[0] == np.float64 else 1e-37)])
@pytest.mark.parametrize("n", [2, 3, 0.5])
def test_powers_of_tiny_rotations_are_not_the_identity(dtype, s, n):
    s = dtype(s)
    quat = np.array([0, 0, s, 1], dtype)
    expected = n * _mp_rotvec_z(float(s))   # the angle times n (well within [0, π])
    for r in (Rotation.from_quat(quat), Rotation.from_quat(np.tile(quat, (3, 1)))):
        got = np.asarray((r ** n).as_rotvec()).reshape(-1, 3)
        np.testing.assert_allclose(got[:, 2], expected, rtol=8 * np.finfo(dtype).eps, atol=0)


@pytest.mark.parametrize("dtype,scales", [(np.float64, [1e-163, 2e-162, 1e-160, 1e-157, 1e-154, 1e-300]),
                                          (np.float32, [1e-22, 1e-21, 1e-20, 1e-19, 1e-37])])
@pytest.mark.parametrize("batched", [False, True])
def test_tiny_quaternions_are_stored_unit(dtype, scales, batched):
    rng = np.random.default_rng(8)
    unit = rng.standard_normal((len(scales), 4))
    unit /= np.linalg.norm(unit, axis=1, keepdims=True)
    quats = (unit * np.array(scales)[:, None]).astype(dtype)
    rs = [Rotation.from_quat(quats)] if batched else [Rotation.from_quat(q) for q in quats]
    got = np.concatenate([np.asarray(r.as_quat()).reshape(-1, 4) for r in rs])
    np.testing.assert_allclose(np.linalg.norm(got.astype(np.float64), axis=1), 1, rtol=0,
                               atol=4 * np.finfo(dtype).eps)
    matrices = np.concatenate([np.asarray(r.as_matrix()).reshape(-1, 3, 3) for r in rs])
    expected = ScipyRotation.from_quat(unit).as_matrix()
    np.testing.assert_allclose(matrices, expected, rtol=0, atol=8 * np.finfo(dtype).eps)


def test_tiny_quaternion_issue_example_is_the_identity():
    np.testing.assert_array_equal(Rotation.from_quat([0, 0, 0, 2e-162]).as_matrix(), np.eye(3))


ZERO_CONVERSIONS = {
    "as_matrix": lambda q: q.as_matrix(),
    "as_rotvec": lambda q: q.as_rotvec(),
    "as_rotvec degrees": lambda q: q.as_rotvec(degrees=True),
    "as_mrp": lambda q: q.as_mrp(),
    "as_euler": lambda q: q.as_euler("xyz"),
    "as_euler zxz": lambda q: q.as_euler("ZXZ"),
    "as_davenport": lambda q: q.as_davenport(np.eye(3), "extrinsic"),
}


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("batch", [None, 1, 5, 70000], ids=["one", "batch1", "batch5", "long"])
@pytest.mark.parametrize("name", sorted(ZERO_CONVERSIONS))
def test_every_conversion_of_the_zero_quaternion_raises_one_clear_error(name, batch, dtype):
    if batch is None:
        q = QuatArray(np.zeros(4, dtype))
    else:
        a = np.tile(np.array([0.5, 0.5, 0.5, 0.5], dtype), (batch, 1))
        a[batch // 2] = 0
        q = QuatArray(a)
    with pytest.raises(ValueError, match=r"^expected non-zero quaternions, got a zero quaternion \(it is no rotation\)$"):
        ZERO_CONVERSIONS[name](q)


@pytest.mark.parametrize("v", [[1.7e308, 1.7e308, 0], [1.7e308, -1.7e308, 1.7e308], [-1e308, 1.6e308, 0]])
@pytest.mark.parametrize("batched", [False, True])
def test_rotation_vectors_whose_norm_overflows(v, batched):
    """|v| beyond the float maximum, |v|/2 within it: the rotation by fl(|v|) about v/|v|, which is
    the square of the rotation by v/2 (an ordinary input; float angles this large carry no digits
    below 2π, so that is the expected value, not the 50-digit one)."""
    v = np.array(v)
    r = Rotation.from_rotvec(np.tile(v, (3, 1)) if batched else v)
    half = Rotation.from_rotvec(v / 2)
    q = np.asarray(r.as_quat()).reshape(-1, 4)
    assert np.isfinite(q).all()
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1, rtol=0, atol=16 * np.finfo(float).eps)
    axis = v * 2.0 ** -600 / np.linalg.norm(v * 2.0 ** -600)
    np.testing.assert_allclose(np.cross(q[:, :3], axis), 0, atol=1e-15)   # the axis of v
    assert np.all((r.inv() * (half * half)).magnitude() < 4e-15)
    for degrees in (False, True):   # in degrees the angle is finite, the ordinary path
        assert np.isfinite(Rotation.from_rotvec(v, degrees=degrees).as_quat()).all()


# --- rigid transforms of extreme size ----------------------------------------------------------

def _mp_power_translation(rotvec, n):
    """50-digit translation of T**n for T = (rotvec, [1, 0, 0]): V(nφ) n V(φ)⁻¹ t."""
    import mpmath as mp
    mp.mp.dps = 50
    phi, t = mp.matrix(rotvec), mp.matrix([1, 0, 0])

    def left_jacobian(p):
        th = mp.norm(p)
        k = mp.matrix([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
        return mp.eye(3) + (1 - mp.cos(th)) / th**2 * k + (th - mp.sin(th)) / th**3 * k * k

    res = left_jacobian(phi * n) * (mp.lu_solve(left_jacobian(phi), t) * n)
    return np.array([float(x) for x in res])


@pytest.mark.parametrize("n", [1e6, -3.5, 0.5, 1e-6])
@pytest.mark.parametrize("size", [1e300, 1e200, 1e-300])
def test_rigid_transform_power_with_extreme_translations(n, size):
    """Against 50 digits (the power is linear in the translation: the reference is for 1, scaled);
    scipy is 2.5e-9 off at n = 1e-6, so it is not the reference here."""
    rotvec = [0.3, 0.2, 0.1]
    ours = RigidTransform.from_components([size, 0, 0], Rotation.from_rotvec(rotvec)) ** n
    ref = _mp_power_translation(rotvec, n)
    assert np.isfinite(ours.translation).all()
    np.testing.assert_allclose(ours.translation / size, ref, rtol=0, atol=4e-15 * np.abs(ref).max())
    assert (ours.rotation.inv() * Rotation.from_rotvec(np.multiply(rotvec, n))).magnitude() < 1e-9


def test_rigid_transform_power_issue_example_matches_scipy():
    rot = [0.3, 0.2, 0.1]
    ours = (RigidTransform.from_components([1e300, 0, 0], Rotation.from_rotvec(rot)) ** 1e6).translation
    theirs = (ScipyRigidTransform.from_components([1e300, 0, 0], ScipyRotation.from_rotvec(rot)) ** 1e6).translation
    np.testing.assert_allclose(ours, theirs, rtol=1e-9)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_exp_coords_round_trip_at_extreme_translations(dtype):
    rng = np.random.default_rng(3)
    big = float(np.finfo(dtype).max)
    sizes = [big / 8, 1e30, 1.0, 1e-30, float(np.finfo(dtype).tiny)]
    t = np.array([s * d for s in sizes for d in np.eye(3)], dtype)
    q = Rotation.random(len(t), rng=rng).as_quat().astype(dtype)
    tf = RigidTransform.from_components(t, Rotation.from_quat(q))
    coords = tf.as_exp_coords()
    back = RigidTransform.from_exp_coords(coords)
    assert np.isfinite(coords).all()
    scale = np.abs(t).max(axis=1, keepdims=True)
    np.testing.assert_allclose(back.translation / scale, t / scale, rtol=0, atol=64 * np.finfo(dtype).eps)


@pytest.mark.parametrize("k", [1e-300, 1e-200, 1e-160, 1e-100, 1e100, 1e200, 1e300])
def test_from_dual_quat_is_invariant_under_scaling(k):
    dq = np.array([0, 0, 0, 1.0, 1.0, 0, 0, 0])   # scalar last: identity rotation, dual x = 1
    expected = ScipyRigidTransform.from_dual_quat(dq).as_matrix()
    for arg in (dq * k, np.tile(dq * k, (3, 1))):
        got = RigidTransform.from_dual_quat(arg).as_matrix()
        np.testing.assert_allclose(got.reshape(-1, 4, 4), np.broadcast_to(expected, got.reshape(-1, 4, 4).shape),
                                   rtol=0, atol=1e-15)


# --- RotationSpline and Track(method="spline") at extreme time spacings ----------------------

from quatarray import RotationSpline  # noqa: E402
from scipy.spatial.transform import RotationSpline as ScipyRotationSpline  # noqa: E402

EXTREME_TIMES = np.array([0, 1e-9, 2e-9, 1e9, 2e9, 3e9])


@pytest.mark.parametrize("dtype,times", [
    (np.float32, EXTREME_TIMES), (np.float64, EXTREME_TIMES), (np.float32, np.arange(5.0)),
    (np.float64, np.arange(5.0)), (np.float32, np.array([0, 1e-30, 2e-30, 1e30])),
    (np.float64, np.array([0, 1e-300, 2e-300, 1e300]))])
def test_identical_keys_give_the_key_exactly_at_every_time(dtype, times):
    key = Rotation.from_rotvec([0.3, 0.2, 0.1]).as_quat().astype(dtype)
    keys = Rotation.from_quat(np.tile(key, (len(times), 1)))
    spline = RotationSpline(times, keys)
    t = np.concatenate([np.linspace(times[0], times[-1], 301), times, [3.9e8, times[1] / 3]])
    q = spline(t).as_quat()
    assert q.dtype == dtype
    np.testing.assert_array_equal(q, np.broadcast_to(keys[0].as_quat(), q.shape))
    assert not spline(t, 1).any() and not spline(t, 2).any()
    inside = t[(t >= times[0]) & (t <= times[-1])]
    track = Track(times, keys, method="spline")
    np.testing.assert_array_equal(np.asarray(track(inside)),
                                  np.broadcast_to(keys[0].as_quat(scalar_first=True), inside.shape + (4,)))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_identical_random_keys_give_the_rotation_s_own_bits(dtype):
    """Any key, not only one whose norm happens to compute to 1: a Rotation's keys are
    not normalised again (that moved about a third of them by an ulp)."""
    rng = np.random.default_rng(27)
    t = np.concatenate([EXTREME_TIMES, rng.uniform(0, 3e9, 40), rng.uniform(0, 2e-9, 20)])
    for q in rng.normal(size=(40, 4)).astype(dtype):
        keys = Rotation.from_quat(np.tile(q, (6, 1)))
        key = keys[0].as_quat()
        got = RotationSpline(EXTREME_TIMES, keys)(t).as_quat()
        np.testing.assert_array_equal(got, np.broadcast_to(key, got.shape))
        got = np.asarray(Track(EXTREME_TIMES, keys, method="spline")(t))
        np.testing.assert_array_equal(got, np.broadcast_to(keys[0].as_quat(scalar_first=True), got.shape))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("c", [1e-300, 1e-150, 1e-9, 1e9, 1e150, 1e300])
def test_spline_is_invariant_under_scaling_of_the_times(dtype, c):
    """Scaling every key time by c scales the spline's time: scipy at spacing 1 is the expected
    value (scipy itself gives NaN at 1e-300)."""
    if dtype == np.float32:   # float32 key times: within its range
        c = min(max(c, 1e-30), 1e30)
    rng = np.random.default_rng(11)
    times = np.cumsum(rng.uniform(0.5, 2.0, 6)) - 0.5
    keys = Rotation.from_rotvec(rng.uniform(-0.8, 0.8, (6, 3))).as_quat()
    ref = ScipyRotationSpline(times, ScipyRotation.from_quat(keys))
    ours = RotationSpline(times * c, Rotation.from_quat(keys.astype(dtype)))
    t = np.linspace(times[0] - 0.2, times[-1] + 0.2, 40)
    q, qr = ours(t * c).as_quat(), ref(t).as_quat()
    eps = np.finfo(dtype).eps
    assert np.isfinite(q).all()
    np.testing.assert_allclose(np.abs(np.sum(q * qr, axis=1)), 1, rtol=0, atol=64 * eps)
    np.testing.assert_allclose(ours(t * c, 1) * dtype(c), ref(t, 1), rtol=0, atol=1e3 * eps)
    if float(np.finfo(dtype).tiny) < c * c < float(np.finfo(dtype).max):   # accelerations ~ 1/c² within the float range
        np.testing.assert_allclose(ours(t * c, 2) * dtype(c) * dtype(c), ref(t, 2), rtol=0, atol=1e4 * eps)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_spline_at_mixed_spacings_follows_a_constant_rotation(dtype):
    """Keys of a constant angular velocity at spacings from 1e-9 to 1e9: the spline is that
    rotation exp(ω t) (a cubic rotation vector with no acceleration solves its equations), so
    its value at every time is known exactly; float32 (whose |q| went from 0.57 to 119 here)
    and float64 both follow it."""
    omega = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5]) * 3e-10
    keys = Rotation.from_rotvec((EXTREME_TIMES[:, None] * omega).astype(dtype))
    t = np.concatenate([np.linspace(0, 3e9, 200), np.linspace(0, 2e-9, 50)])
    q = RotationSpline(EXTREME_TIMES, keys)(t)
    eps = np.finfo(dtype).eps
    np.testing.assert_allclose(np.linalg.norm(q.as_quat().astype(np.float64), axis=1), 1, rtol=0, atol=8 * eps)
    expected = ScipyRotation.from_rotvec(t[:, None] * omega)
    np.testing.assert_allclose(q.as_matrix(), expected.as_matrix(), rtol=0, atol=64 * eps)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_spline_refuses_non_finite_times_as_scipy(bad):
    keys = Rotation.from_rotvec(np.eye(3) * 0.5)
    scipy_keys = ScipyRotation.from_rotvec(np.eye(3) * 0.5)
    if np.isnan(bad):
        with pytest.raises(ValueError):
            ScipyRotationSpline([0, bad, 2], scipy_keys)
    with pytest.raises(ValueError, match="expected finite values in times, got nan or inf at index"):
        RotationSpline([0, bad, 2], keys)
    with pytest.raises(ValueError, match="expected finite values in times"):
        Track([0, bad, 2], keys, method="spline")
    spline = RotationSpline([0, 1, 2], keys)
    with pytest.raises(ValueError):
        ScipyRotationSpline([0, 1, 2], scipy_keys)(bad)
    for order in (0, 1, 2):
        with pytest.raises(ValueError, match=r"expected finite values in times, got nan or inf at index \(1,\)"):
            spline([0.5, bad], order)
        with pytest.raises(ValueError, match="expected finite values in times"):
            spline(bad, order)
    with pytest.raises(ValueError, match="expected finite values in t"):
        Track([0, 1, 2], keys, method="spline", extrapolate="extend")(bad)


def _random_tracks(n, rng):
    """4-key tracks of uniform random rotations at spacings from 1e-3 to 1e3 (where scipy's
    fixed-point iteration diverges for about 1 in 5)."""
    for _ in range(n):
        yield (np.cumsum(np.concatenate([[0], 10 ** rng.uniform(-3, 3, 3)])),
               Rotation.random(4, rng=rng))


def test_spline_of_large_rotations_at_uneven_spacings_is_unit_or_refused():
    rng = np.random.default_rng(0)
    refused = 0
    for times, keys in _random_tracks(300, rng):
        try:
            spline = RotationSpline(times, keys)
        except ValueError as exc:
            assert "expected keys and times that a C² rotation spline can join" in str(exc)
            refused += 1
            continue
        t = np.concatenate([np.linspace(times[0], times[-1], 60), times])
        q = spline(t).as_quat()
        assert np.isfinite(q).all()
        np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1, rtol=0, atol=16 * np.finfo(float).eps)
        # it passes through its keys
        assert (spline(times).inv() * keys).magnitude().max() < 1e-9
        # and its angular acceleration is continuous at the interior keys (C²)
        inner = times[1:-1]
        gap = np.maximum(inner * 1e-12, 1e-12 * np.diff(times).min())
        before, after = spline(inner - gap, 2), spline(inner + gap, 2)
        scale = 1 + np.abs(spline(times, 2)).max()
        assert np.abs(before - after).max() < 1e-4 * scale
    assert refused <= 3


def test_float32_splines_are_refused_only_where_float64_ones_are():
    """float32 keys: the same spline as their float64 values, to float32 rounding, and never
    refused where float64 solves (in float32, Newton's method stalled at rounding noise and
    refused about 2% of these tracks)."""
    rng = np.random.default_rng(3)
    eps = np.finfo(np.float32).eps
    for times, keys in _random_tracks(300, rng):
        keys32 = keys.as_quat().astype(np.float32)
        try:
            ref = RotationSpline(times, Rotation.from_quat(keys32.astype(np.float64)))
        except ValueError:
            continue
        spline = RotationSpline(times, Rotation.from_quat(keys32))
        t = np.linspace(times[0], times[-1], 40)
        q = spline(t).as_quat()
        assert q.dtype == np.float32
        np.testing.assert_allclose(np.linalg.norm(q.astype(np.float64), axis=1), 1, rtol=0, atol=16 * eps)
        # float32 rounds the cubics' terms, which grow with the angle swept in a segment (fast
        # turns between close keys): its bound, the largest rate times the longest spacing
        swept = 1 + np.abs(ref(t, 1)).max() * np.diff(times).max()
        assert (Rotation.from_quat(q.astype(np.float64)).inv() * ref(t)).magnitude().max() < 64 * eps * swept


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_rigid_transform_mean_of_translations_near_the_float_maximum(dtype):
    """The mean of translations near the float maximum is in range (their sum is not): it was
    inf, as scipy's; expected value: scipy's mean of the same translations scaled down by 2**-8."""
    big = np.finfo(dtype).max / 1.1
    rng = np.random.default_rng(5)
    t = (rng.uniform(0.5, 1, (7, 3)) * np.array([1, -1, 1])).astype(dtype) * dtype(big)
    rot = Rotation.from_rotvec(rng.uniform(-1, 1, (7, 3)).astype(dtype))
    w = rng.uniform(0, 1, 7)
    ours = RigidTransform.from_components(t, rot)
    theirs = ScipyRigidTransform.from_components(t.astype(np.float64) / 256, ScipyRotation.from_quat(rot.as_quat()))
    eps = np.finfo(dtype).eps
    for kw in ({}, {"weights": w}):
        got = ours.mean(**kw).translation
        assert got.dtype == dtype and np.isfinite(got).all()
        np.testing.assert_allclose(got / 256, theirs.mean(**kw).translation, rtol=8 * eps)


@pytest.mark.parametrize("scale", [1.5e308, 1e300, 1e-300, 1e-307])
def test_rotation_mean_does_not_depend_on_the_scale_of_the_weights(scale):
    """Weights whose sums of w q qᵀ overflow (or products underflow) give scipy's mean at
    weights of ordinary size (1.5e308 gave the identity, as scipy's does)."""
    rng = np.random.default_rng(6)
    q = rng.standard_normal((9, 4))
    w = rng.uniform(0.5, 1, 9)
    expected = ScipyRotation.from_quat(q).mean(weights=w)
    got = Rotation.from_quat(q).mean(weights=w * scale)
    assert (got.inv() * Rotation.from_quat(expected.as_quat())).magnitude() < 1e-12
    translations = RigidTransform.from_components(rng.standard_normal((9, 3)), Rotation.from_quat(q))
    np.testing.assert_allclose(translations.mean(weights=w * scale).translation,
                               ScipyRigidTransform.from_components(translations.translation,
                                                                   ScipyRotation.from_quat(q)).mean(weights=w).translation,
                               rtol=1e-12, atol=1e-15)


# --- memory: at most 1.5x the output plus a few blocks ------------------------------------------

import tracemalloc  # noqa: E402

from quatarray import _blocks, unflip  # noqa: E402

def _extra_peak(call):
    """Peak memory allocated during `call()` beyond what was allocated before, in bytes."""
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        result = call()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    del result
    return peak - before


@pytest.fixture(scope="module")
def million():
    rng = np.random.default_rng(13)
    q = rng.standard_normal((2_000_000, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_reductions_to_one_rotation_take_a_few_blocks(million, dtype):
    q = million.astype(dtype)
    r = Rotation.from_quat(q, scalar_first=True)
    w = np.linspace(0, 1, len(q))
    budget = 16 * 4 * 8 * _blocks.block_size(np.float64)   # 16 blocks of quaternions: 16 MB
    assert _extra_peak(lambda: r.mean()) < budget
    assert _extra_peak(lambda: r.mean(weights=w)) < budget
    qa_ = QuatArray(q)
    assert _extra_peak(lambda: np.multiply.reduce(qa_, axis=0)) < budget
    # the blocked sums are the same mean as scipy's (random rotations: nearly equal eigenvalues,
    # a gap of about 1/sqrt(n), so the eigenvector moves by about eps sqrt(n) / gap)
    theirs = Rotation.from_quat(ScipyRotation.from_quat(q.astype(np.float64), scalar_first=True).mean().as_quat())
    assert (r.mean().inv() * theirs).magnitude() < {np.float32: 2e-5, np.float64: 1e-9}[dtype]


def _long_calls(q, dtype):
    """The long operations of the memory bullet, on the unit quaternions `q`, and their output bytes."""
    rng = np.random.default_rng(14)
    angles = rng.uniform(-1.5, 1.5, (len(q), 3)).astype(dtype)
    matrices = Rotation.from_quat(q, scalar_first=True).as_matrix()
    spline = RotationSpline(np.arange(64.0), Rotation.from_quat(q[:64], scalar_first=True))
    t = np.linspace(0, 63, len(q))
    qa_ = QuatArray(q)
    return {
        "unflip": lambda: unflip(qa_),
        "from_euler": lambda: Rotation.from_euler("xyz", angles),
        "from_matrix": lambda: Rotation.from_matrix(matrices),
        "spline": lambda: spline(t),
    }


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_long_operations_take_at_most_one_and_a_half_outputs(million, dtype):
    # Extra peak memory grows with N by at most 1.5 output bytes per output byte: measured as the
    # slope between N and 4 N, so the fixed scratch (a few blocks per thread, whatever N is) cancels
    # and a 1.7x temporary cannot hide behind it.
    small, large = million[:500_000].astype(dtype), million.astype(dtype)
    grown = large.nbytes - small.nbytes
    calls_small, calls_large = _long_calls(small, dtype), _long_calls(large, dtype)
    for name in calls_small:
        slope = (_extra_peak(calls_large[name]) - _extra_peak(calls_small[name])) / grown
        assert slope <= 1.5, (name, slope)


# --- the sweep: magnitudes 1e-300..1e300 (float64), 1e-35..1e35 (float32) ------------------------

from hypothesis import given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

EXPONENT = {np.float64: 300.0, np.float32: 35.0}


def _directions(seed, n):
    d = np.random.default_rng(seed).standard_normal((n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _sized_quats(seed, n, exponent):
    """Random rotations as quaternions of norm 10**exponent."""
    q = np.random.default_rng(seed).standard_normal((n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True) * 10.0 ** exponent


def _check_unit(q, dtype):
    q = np.asarray(q, np.float64)
    assert np.isfinite(q).all()
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1, rtol=0, atol=16 * np.finfo(dtype).eps)


def _norms(v):
    """|v| per row, each row scaled by its largest component first (no over- or underflow)."""
    v = np.atleast_2d(np.asarray(v, np.float64))
    m = np.abs(v).max(axis=-1, keepdims=True)
    m[m == 0] = 1
    return np.linalg.norm(v / m, axis=-1) * m[:, 0]


def _check_vectors(got, expected_norms, dtype):
    """Finite, and of the expected norms where they are normal numbers."""
    assert np.isfinite(np.asarray(got)).all()
    norms = _norms(got)
    normal = expected_norms > float(np.finfo(dtype).tiny) / np.finfo(dtype).eps
    np.testing.assert_allclose(norms[normal], expected_norms[normal], rtol=64 * np.finfo(dtype).eps)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@given(seed=st.integers(0, 2**32 - 1), qexp=st.floats(-1, 1), vexp=st.floats(-1, 1),
       n=st.sampled_from([1, 7, 300]))
def test_sweep_apply(dtype, seed, qexp, vexp, n):
    e = EXPONENT[dtype]
    q = _sized_quats(seed, n, qexp * e).astype(dtype)
    # vectors of norm 10**(vexp e), kept below the float maximum (their rotations' norms)
    size = min(10.0 ** (vexp * e), 0.9 * float(np.finfo(dtype).max))
    v = (_directions(seed + 1, n) * size).astype(dtype)
    expected = _norms(v)
    r = Rotation.from_quat(q, scalar_first=True)
    _check_unit(r.as_quat(), dtype)
    for inverse in (False, True):
        _check_vectors(r.apply(v, inverse=inverse), expected, dtype)
        _check_vectors(r[0].apply(v[0], inverse=inverse), expected[:1], dtype)
        _check_vectors(r[0].apply(v, inverse=inverse), expected, dtype)
    _check_vectors(QuatArray(q).rotate(v), expected, dtype)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@given(seed=st.integers(0, 2**32 - 1), texp=st.floats(-1, 1), spread=st.floats(0, 3),
       qexp=st.floats(-1, 1), angle=st.floats(0, 3), k=st.integers(2, 6))
def test_sweep_rotation_spline(dtype, seed, texp, spread, qexp, angle, k):
    """Keys of any magnitude at spacings 10**(texp e) spread over 10**±spread: unit rotations
    and finite rates, or the ValueError that says the spline cannot join these keys."""
    e = EXPONENT[dtype]
    rng = np.random.default_rng(seed)
    dt = 10.0 ** (texp * (e - 4) + rng.uniform(-spread, spread, k - 1))
    times = np.concatenate([[0.0], np.cumsum(dt)])
    rotvecs = _directions(seed + 2, k) * rng.uniform(0, angle, (k, 1))
    unit = Rotation.from_rotvec(rotvecs).as_quat()
    keys = Rotation.from_quat((unit * 10.0 ** (qexp * e)).astype(dtype))
    t = np.concatenate([times, rng.uniform(times[0], times[-1], 20), times[-1] + dt[-1] * rng.uniform(0, 0.5, 3)])
    for build in (lambda: RotationSpline(times, keys), lambda: Track(times, keys, method="spline", extrapolate="extend")):
        try:
            spline = build()
        except ValueError as exc:
            assert "expected keys and times that a C² rotation spline can join" in str(exc)
            return
        q = spline(t)
        _check_unit(q.as_quat() if isinstance(q, Rotation) else q, dtype)
    rates = RotationSpline(times, keys)(t, 1)
    assert rates.dtype == dtype and not np.isnan(rates).any()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@given(seed=st.integers(0, 2**32 - 1), texp=st.floats(-1, 1), qexp=st.floats(-1, 1), vexp=st.floats(-1, 1),
       power=st.sampled_from([0.5, -0.25, 2.0, 3.0, -1.5, 1e-6]), n=st.sampled_from([1, 5, 300]))
def test_sweep_rigid_transform(dtype, seed, texp, qexp, vexp, power, n):
    e = EXPONENT[dtype]
    big = float(np.finfo(dtype).max)
    t = (_directions(seed, n) * min(10.0 ** (texp * e), big / 8)).astype(dtype)
    v = (_directions(seed + 1, n) * min(10.0 ** (vexp * e), big / 8)).astype(dtype)
    q = _sized_quats(seed + 2, n, qexp * e).astype(dtype)
    tf = RigidTransform.from_components(t, Rotation.from_quat(q, scalar_first=True))
    _check_unit(tf.rotation.as_quat(), dtype)
    m = tf.as_matrix()
    assert np.isfinite(m).all()
    for inverse in (False, True):
        assert np.isfinite(tf.apply(v, inverse=inverse)).all()
    dq = tf.as_dual_quat()
    # the same dual quaternions scaled by 10**(qexp e), as far as their largest component allows
    dq_scale = min(10.0 ** (qexp * e), big / 2 / float(np.abs(dq).max()))
    for other in (tf.inv(), tf * tf.inv(), tf ** power,
                  RigidTransform.from_exp_coords(tf.as_exp_coords()),
                  RigidTransform.from_dual_quat(dq), RigidTransform.from_dual_quat(dq * dtype(dq_scale))):
        _check_unit(other.rotation.as_quat(), dtype)
        assert np.isfinite(other.translation).all()
    # the exponential coordinates and the dual quaternion give the transform back
    scale = np.maximum(np.abs(t).max(axis=-1, keepdims=True), float(np.finfo(dtype).tiny)).astype(np.float64)
    back = RigidTransform.from_exp_coords(tf.as_exp_coords()).translation.astype(np.float64)
    assert np.all(np.abs(back - t) <= 1e3 * np.finfo(dtype).eps * scale + 2 * float(np.finfo(dtype).smallest_subnormal))
