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
