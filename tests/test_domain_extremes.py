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
