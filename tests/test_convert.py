"""Raw-array conversions (`quatarray._convert`) cross-checked against scipy's
Rotation: every representation both ways, all Euler sequences, edge cases
(identity, π, gimbal lock, tiny angles, non-orthogonal matrices), layouts,
chunking, dtypes and bad input."""

import re
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation as R

from quatarray import Rotation
from quatarray import _blocks
from quatarray import _convert as C
from quatarray import _euler as E
from quatarray import _kernels as K
from quatarray import _scale
from quatarray._blocks import BLOCK as CHUNK
from quatarray.testing import assert_allclose

from .conftest import random_quats, tol

SEQS = ["xyz", "xzy", "yxz", "yzx", "zxy", "zyx", "xyx", "xzx", "yxy", "yzy", "zxz", "zyz"]
ALL_SEQS = SEQS + [s.upper() for s in SEQS]
SHAPES = [(), (7,), (3, 5)]


def sp(q):
    """scipy Rotation of scalar-first quaternions (float64)."""
    return R.from_quat(np.asarray(q, np.float64), scalar_first=True)


def sp_quat(r):
    return r.as_quat(scalar_first=True)


def assert_same_rotation(got, want, atol):
    """Quaternions equal up to the double cover (q and -q)."""
    assert_allclose(got, want, rtol=0, atol=atol, double_cover=True)

def angle_diff(a, b):
    """Differences of angles modulo 2π, in [0, π]."""
    return np.abs(np.angle(np.exp(1j * (np.asarray(a, np.float64) - np.asarray(b, np.float64)))))


def unit(rng, shape, dtype):
    return random_quats(rng, shape, dtype)


# --- quaternions -------------------------------------------------------------------------

def test_from_quat_normalises_in_either_order(rng, dtype, batch_shape):
    q = (5 * random_quats(rng, batch_shape, np.float64, unit=False)).astype(dtype)
    want = R.from_quat(q.astype(float)).as_quat(scalar_first=True)
    got = C.from_quat(q)
    assert got.dtype == dtype and got.shape == q.shape
    np.testing.assert_allclose(got, want, rtol=0, atol=tol(dtype))
    np.testing.assert_allclose(C.from_quat(q, scalar_first=True),
                               R.from_quat(q.astype(float), scalar_first=True).as_quat(scalar_first=True),
                               rtol=0, atol=tol(dtype))


def test_from_quat_with_norms_that_over_or_underflow():
    q = np.array([[1e200, 0, 0, 1e200], [0, 3e-200, 0, 4e-200], [0, 0, 0, 1]])
    np.testing.assert_allclose(C.from_quat(q), [[2 ** -0.5, 2 ** -0.5, 0, 0], [0.8, 0, 0.6, 0], [1, 0, 0, 0]],
                               rtol=1e-15)


@pytest.mark.parametrize("q, match", [
    ([[0, 0, 0, 1], [0, 0, 0, 0]], r"zero quaternion at index \(1,\)"),
    ([[[0, 0, 0, 1]], [[np.nan, 0, 0, 1]]], r"nan or inf in quaternion \(1, 0\)"),
    ([np.inf, 0, 0, 1], r"nan or inf in quaternion \(\)"),
])
def test_from_quat_bad_values(q, match):
    with pytest.raises(ValueError, match=match):
        C.from_quat(q)


# --- matrices ---------------------------------------------------------------------------

@pytest.mark.parametrize("shape", SHAPES)
def test_as_matrix_matches_scipy(rng, dtype, shape):
    q = unit(rng, shape, dtype)
    got = C.as_matrix(q)
    assert got.dtype == dtype and got.shape == shape + (3, 3)
    np.testing.assert_allclose(got, sp(q).as_matrix(), rtol=0, atol=tol(dtype))


@pytest.mark.parametrize("shape", [(), (1,), (1, 1), (7,), (3, 5), (_blocks.VIEWS_MAX + 3,)])
@pytest.mark.parametrize("layout", ["contiguous", "read-only", "strided"])
def test_unit_as_matrix_matches_scipy_and_the_general_path(rng, dtype, shape, layout):
    """`unit=True` (a Rotation's storage): its stacked plan for a few rotations and its
    traced program for blocks agree with scipy and with the general formula, on any layout."""
    q = unit(rng, shape, dtype)
    if layout == "read-only":
        q.flags.writeable = False
    elif layout == "strided":
        q = np.repeat(q, 2, axis=-1)[..., ::2]
    got = C.as_matrix(q, unit=True)
    assert got.dtype == dtype and got.shape == shape + (3, 3) and got.flags.c_contiguous and got.flags.writeable
    np.testing.assert_allclose(got, sp(q).as_matrix(), rtol=0, atol=tol(dtype))
    np.testing.assert_allclose(got, C.as_matrix(q), rtol=0, atol=tol(dtype))


@pytest.mark.parametrize("shape", [(0, 4), (2, 0, 4)])
def test_unit_as_matrix_of_empty_batches(dtype, shape):
    got = C.as_matrix(np.zeros(shape, dtype), unit=True)
    assert got.shape == shape[:-1] + (3, 3) and got.dtype == dtype


def _bits(a):
    return a.view(np.uint64 if a.dtype == np.float64 else np.uint32)


def test_unit_matrix_formula_gives_the_same_bits_on_every_path(dtype):
    """`_unit_matrix` run on floats, its stacked plan (`_unit_rows`) and its straight-line
    program (`_traced_rows`, the blocks) give the same bits, signed zeros included, on
    rows where signs, cancellations and products below the normal range decide them."""
    tiny = np.finfo(dtype).tiny
    rows = np.array([[1, 0, 0, 0], [-1, -0.0, 0, -0.0], [0.5, -0.5, 0.5, -0.5], [0, 1, 0, 0], [-0.0, 0, -1, 0],
                     [np.sqrt(0.5), 0, 0, -np.sqrt(0.5)], [0, np.sqrt(0.5), -np.sqrt(0.5), 0],
                     [1, np.sqrt(tiny), -np.sqrt(tiny), 0], [1, np.sqrt(tiny) / 8, np.sqrt(tiny) * 3, -np.sqrt(tiny)],
                     [1, 2 * tiny, 0, -tiny], [-1, 0, -1e-30, 1e-30]], np.float64)
    rows /= np.linalg.norm(rows, axis=1, keepdims=True)
    rng = np.random.default_rng(7)
    q = np.concatenate([rows, random_quats(rng, (40,))]).astype(dtype)
    qT = np.ascontiguousarray(q.T)
    stacked, program = np.empty((9, len(q)), dtype), np.empty((9, len(q)), dtype)
    C._unit_rows(qT, stacked)
    C._traced_rows(C._UNIT_PROGRAM, qT, program)
    np.testing.assert_array_equal(_bits(stacked), _bits(program))
    np.testing.assert_array_equal(_bits(C.as_matrix(q, unit=True).reshape(-1, 9)), _bits(program.T))
    if dtype == np.float64:
        floats = np.array([C._unit_matrix(*row) for row in q.tolist()])
        np.testing.assert_array_equal(_bits(floats), _bits(program.T))
    for k in range(len(q)):   # alone and as a batch of one (the float path in float64)
        np.testing.assert_array_equal(_bits(C.as_matrix(q[k], unit=True).reshape(9)), _bits(program[:, k]))
        np.testing.assert_array_equal(_bits(C.as_matrix(q[k:k + 1], unit=True).reshape(9)), _bits(program[:, k]))


def test_matrix_plan_needs_two_term_and_four_term_entries():
    with pytest.raises(ValueError, match="sums of products"):
        C._plan(lambda w, x, y, z: [w * x * y] * 9)
    with pytest.raises(ValueError, match="two-term off-diagonal and four-term diagonal"):
        C._plan(lambda w, x, y, z: [w * x + y * z] * 9)


def test_as_matrix_of_non_unit_quaternion_is_the_rotation_by_q_over_norm(rng, dtype):
    q = unit(rng, (50,), dtype)
    scale = np.geomspace(1e-3, 1e3, 50).astype(dtype)[:, None]
    np.testing.assert_allclose(C.as_matrix(q * scale), C.as_matrix(q), rtol=0, atol=tol(dtype))
    for k in (0, -1):  # the single-quaternion path too
        np.testing.assert_allclose(C.as_matrix(q[k] * scale[k]), C.as_matrix(q[k]), rtol=0, atol=tol(dtype))
        np.testing.assert_allclose(C.magnitude(q[k] * scale[k]), C.magnitude(q[k]), rtol=0, atol=tol(dtype))


@pytest.mark.parametrize("shape", [(4,), (3, 4)])
def test_as_matrix_of_zero_quaternion_raises_without_warning(shape):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match="expected non-zero quaternions, got a zero quaternion"):
            C.as_matrix(np.zeros(shape))


@pytest.mark.parametrize("shape", SHAPES)
def test_from_matrix_matches_scipy(rng, dtype, shape):
    m = R.random(int(np.prod(shape)), rng=rng).as_matrix().reshape(shape + (3, 3))
    got = C.from_matrix(m.astype(dtype))
    assert got.dtype == dtype and got.shape == shape + (4,)
    want = R.from_matrix(m.reshape(-1, 3, 3)).as_quat(scalar_first=True).reshape(shape + (4,))
    if dtype == np.float64:  # same branch as scipy, so the same sign
        np.testing.assert_allclose(got, want, rtol=0, atol=tol(dtype))
    assert_same_rotation(got, want, tol(dtype))


def test_from_matrix_every_branch_and_exact_half_turns(dtype):
    # the largest of (m00, m11, m22, trace) picks the branch: cover all four and π turns
    cases = {
        (1.0, 0, 0, 0): np.eye(3),
        (0.0, 1, 0, 0): np.diag([1.0, -1, -1]),
        (0.0, 0, 1, 0): np.diag([-1.0, 1, -1]),
        (0.0, 0, 0, 1): np.diag([-1.0, -1, 1]),
    }
    for q, m in cases.items():
        np.testing.assert_array_equal(C.from_matrix(m.astype(dtype)), np.array(q, dtype))
    qs = np.array([[0.1, 0.9, 0.3, -0.2], [0.2, -0.3, 0.9, 0.1], [0.1, 0.2, -0.3, 0.9], [0.9, 0.1, 0.2, 0.3]])
    qs /= np.linalg.norm(qs, axis=1, keepdims=True)
    got = C.from_matrix(C.as_matrix(qs.astype(dtype)))
    assert_same_rotation(got, qs, tol(dtype))


@pytest.mark.parametrize("noise", [1e-10, 1e-6, 1e-2])
def test_from_matrix_projects_noisy_matrices_like_scipy(rng, noise):
    m = R.random(200, rng=rng).as_matrix() + noise * rng.standard_normal((200, 3, 3))
    got = C.from_matrix(m)
    want = R.from_matrix(m).as_quat(scalar_first=True)
    assert_same_rotation(got, want, 20 * np.finfo(float).eps)


def test_from_matrix_projects_arbitrary_positive_det_matrices_like_scipy(rng):
    m = rng.standard_normal((500, 3, 3))
    m[np.linalg.det(m) < 0] *= -1
    m[0] = 2 * np.eye(3)          # scaled rotation
    m[1] = np.diag([1.0, 2, 3])   # stretch
    m[2] = np.diag([1.0, 1, 1e-8])  # nearly singular, det > 0
    got = C.from_matrix(m)
    want = R.from_matrix(m).as_quat(scalar_first=True)
    assert_same_rotation(got[:2], [[1, 0, 0, 0], [1, 0, 0, 0]], 1e-15)
    assert_same_rotation(got, want, 1e-12)


def test_from_matrix_projection_gives_each_matrix_the_same_bits_alone_and_in_a_batch(rng):
    """The polar projection iterates until a matrix converges, each matrix by itself: a
    matrix that converges early is not iterated further because another in its block is
    slow (which changed its last bits with the batch around it)."""
    m = R.random(60, rng=rng).as_matrix()
    m[::3] += 1e-6 * rng.standard_normal((20, 3, 3))   # a few Newton steps
    m[1::3] = rng.standard_normal((20, 3, 3))           # many
    m[1::3] *= np.sign(np.linalg.det(m[1::3]))[:, None, None]
    whole = C.from_matrix(m)
    for i in range(len(m)):
        np.testing.assert_array_equal(C.from_matrix(m[i]), whole[i], strict=True)
        np.testing.assert_array_equal(C.from_matrix(m[i:i + 1])[0], whole[i], strict=True)


def test_from_matrix_svd_fallback_gives_the_same_rotation(rng, monkeypatch):
    m = rng.standard_normal((50, 3, 3))
    m[np.linalg.det(m) < 0] *= -1
    newton = C.from_matrix(m)
    monkeypatch.setattr(C, "_POLAR_MAXITER", 1)  # Newton cannot converge in one step
    fallback = C.from_matrix(m)
    assert_same_rotation(fallback, newton, 1e-12)


def test_from_matrix_float32_noisy(rng):
    m = R.random(100, rng=rng).as_matrix() + 1e-3 * rng.standard_normal((100, 3, 3))
    got = C.from_matrix(m.astype(np.float32))
    assert got.dtype == np.float32
    assert_same_rotation(got, R.from_matrix(m.astype(np.float32).astype(float)).as_quat(scalar_first=True),
                         tol(np.float32))


def test_from_matrix_assume_valid_skips_checks(rng):
    m = R.random(20, rng=rng).as_matrix()
    np.testing.assert_array_equal(C.from_matrix(m, assume_valid=True), C.from_matrix(m))
    C.from_matrix(-np.eye(3), assume_valid=True)  # no check: no error


@pytest.mark.parametrize("matrix, match", [
    (-np.eye(3), r"Non-positive determinant .* matrix \(\): expected det > 0, got det = -1"),
    (np.zeros((3, 3)), "Non-positive determinant"),
    (np.stack([np.eye(3), np.diag([1.0, 1, -1])]), r"matrix \(1,\)"),
    (np.full((3, 3), np.nan), "expected finite values in matrix"),
    (np.diag([np.inf, 1, 1]), "expected finite values in matrix"),
    (np.eye(4), r"expected matrix of shape \(\.\.\., 3, 3\), got \(4, 4\)"),
    (np.ones(3), r"expected matrix of shape \(\.\.\., 3, 3\), got \(3,\)"),
])
def test_from_matrix_bad_input(matrix, match):
    with pytest.raises(ValueError, match=match):
        C.from_matrix(matrix)


# --- rotation vectors, magnitude, MRPs ------------------------------------------------------

@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("degrees", [False, True])
def test_rotvec_both_ways_match_scipy(rng, dtype, shape, degrees):
    q = unit(rng, shape, dtype)
    got = C.as_rotvec(q, degrees=degrees)
    assert got.dtype == dtype and got.shape == shape + (3,)
    unit_scale = 180 / np.pi if degrees else 1.0
    np.testing.assert_allclose(got, sp(q).as_rotvec(degrees=degrees), rtol=0, atol=tol(dtype) * unit_scale)
    v = (rng.uniform(-4, 4, shape + (3,)) * unit_scale).astype(dtype)  # angles up to 2π and beyond
    q2 = C.from_rotvec(v, degrees=degrees)
    assert q2.dtype == dtype
    np.testing.assert_allclose(q2, sp_quat(R.from_rotvec(v.astype(float), degrees=degrees)),
                               rtol=0, atol=tol(dtype))


@pytest.mark.parametrize("angle", [1e-12, 1e-9, 1e-6, 1e-3, 1.0, np.pi - 1e-6, np.pi - 1e-9])
def test_as_rotvec_accurate_from_tiny_angles_to_pi(rng, angle):
    axis = rng.standard_normal((20, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    q = np.concatenate([np.full((20, 1), np.cos(angle / 2)), np.sin(angle / 2) * axis], axis=1)
    got = C.as_rotvec(q)
    # relative accuracy of a few ulps in every component
    np.testing.assert_allclose(got, angle * axis, rtol=8 * np.finfo(float).eps, atol=0)
    np.testing.assert_allclose(C.magnitude(q), angle, rtol=4 * np.finfo(float).eps, atol=0)


def test_as_rotvec_tiny_angle_float32():
    q = np.array([1.0, 5e-13, 0, 0], np.float32)
    np.testing.assert_allclose(C.as_rotvec(q), [1e-12, 0, 0], rtol=4 * np.finfo(np.float32).eps)


def test_rotvec_exact_half_turn_and_identity():
    for q in np.eye(4)[1:]:
        np.testing.assert_array_equal(C.as_rotvec(q), np.pi * q[1:])
        np.testing.assert_array_equal(C.as_rotvec(-q), np.pi * q[1:])  # canonical sign, as scipy
        np.testing.assert_array_equal(C.as_rotvec(-q), sp(-q).as_rotvec())
    np.testing.assert_array_equal(C.as_rotvec(np.array([1.0, 0, 0, 0])), [0, 0, 0])
    np.testing.assert_array_equal(C.as_rotvec(np.array([-1.0, 0, 0, 0])), [0, 0, 0])
    np.testing.assert_array_equal(C.from_rotvec(np.zeros(3)), [1, 0, 0, 0])
    half = C.from_rotvec([np.pi, 0, 0])
    assert abs(half[0]) < 2e-16 and half[1] == 1.0


@pytest.mark.parametrize("angle", [0.0, 1e-300, 1e-12, 1e-9, 1e-4])
def test_from_rotvec_tiny_angles(angle):
    v = np.array([angle, 0.0, 0.0])
    q = C.from_rotvec(v)
    np.testing.assert_allclose(q, [np.cos(angle / 2), np.sin(angle / 2), 0, 0], rtol=2 * np.finfo(float).eps)


def test_from_rotvec_large_angles_wrap_like_scipy(rng):
    v = rng.standard_normal((100, 3)) * 50
    np.testing.assert_allclose(C.from_rotvec(v), sp_quat(R.from_rotvec(v)), atol=1e-13)


def test_magnitude_matches_scipy_and_range(rng, dtype, batch_shape):
    q = unit(rng, batch_shape, dtype)
    got = C.magnitude(q)
    assert got.dtype == dtype and got.shape == batch_shape
    np.testing.assert_allclose(got, sp(q).magnitude(), rtol=0, atol=tol(dtype))
    assert ((got >= 0) & (got <= np.float32(np.pi))).all()


def test_rotvec_and_magnitude_rows_needing_the_exact_path_keep_their_bits_in_any_batch(rng):
    """w = ±0 (the canonical sign from x, y, z; a floored w² that stays finite), w² below the
    range test, |v|² lost to underflow and the exact identity take `_half_turn`'s exact path;
    the ordinary rows of such a batch keep their bits, and each row is accurate against an
    independent formula (hypot for |v|, np.arctan2)."""
    special = np.array([[0.0, 0.0, -1.0, 0.0], [-0.0, -0.6, 0.8, 0.0], [0.0, 0.0, 0.0, -1.0],
                        [1e-170, 0.6, -0.8, 0.0], [1.0, 1e-200, 0.0, 0.0], [-1.0, 0.0, 3e-170, 0.0],
                        [1.0, 0.0, 0.0, 0.0], [-1.0, -0.0, 0.0, 0.0]])
    plain = random_quats(rng, (6,), np.float64)
    batch = np.concatenate([plain[:3], special, plain[3:]])
    for name, f in (("as_rotvec", lambda q: Rotation.from_quat(q, scalar_first=True).as_rotvec()),
                    ("magnitude", lambda q: Rotation.from_quat(q, scalar_first=True).magnitude()),
                    ("raw as_rotvec", C.as_rotvec), ("raw magnitude", C.magnitude)):
        whole = f(batch)
        for i in range(len(batch)):
            np.testing.assert_array_equal(f(batch[i]), whole[i], err_msg=f"{name} row {i} alone")
            np.testing.assert_array_equal(f(batch[i:i + 1])[0], whole[i], err_msg=f"{name} row {i} of one")
        np.testing.assert_array_equal(f(plain), whole[np.r_[0:3, 11:14]], err_msg=name)
    w, v = batch[:, 0], batch[:, 1:]
    nv = np.hypot(np.hypot(v[:, 0], v[:, 1]), v[:, 2])
    angle = 2 * np.arctan2(nv, np.abs(w))
    np.testing.assert_allclose(C.magnitude(batch), angle, rtol=4 * np.finfo(float).eps, atol=0)
    flip = np.where(C._flip_mask(*batch.T), -1.0, 1.0)[:, None]   # scipy's canonical sign
    expected = v * (flip * angle[:, None] / np.where(nv > 0, nv, 1)[:, None])
    np.testing.assert_allclose(C.as_rotvec(batch), expected, rtol=8 * np.finfo(float).eps, atol=0)
    np.testing.assert_allclose(C.as_rotvec(special[:3]), sp(special[:3]).as_rotvec(), rtol=0, atol=4e-16)


@pytest.mark.parametrize("shape", SHAPES)
def test_mrp_both_ways_match_scipy(rng, dtype, shape):
    q = unit(rng, shape, dtype)
    got = C.as_mrp(q)
    assert got.dtype == dtype and got.shape == shape + (3,)
    np.testing.assert_allclose(got, sp(q).as_mrp(), rtol=0, atol=tol(dtype))
    assert (np.linalg.norm(got, axis=-1) <= 1 + tol(dtype)).all()
    p = rng.uniform(-3, 3, shape + (3,)).astype(dtype)
    np.testing.assert_allclose(C.from_mrp(p), sp_quat(R.from_mrp(p.astype(float))), rtol=0, atol=tol(dtype))


def test_mrp_of_any_quaternion_is_the_unit_formula_with_its_norm(rng, dtype):
    """One formula for MRPs, v / (|q| + |w|) signed as w: where |q| rounds to exactly 1, the
    general path has the bits of `Rotation`'s (|q| taken as 1); scaling q changes nothing
    but rounding (within 2 ulp of the largest component); signed zeros of w as scipy's."""
    q = random_quats(rng, (5000,), dtype)
    q[:50, 0] = 0.0
    q[50:100, 0] = -0.0
    got, unit = C.as_mrp(q), C.as_mrp(q, unit=True)
    one = np.sqrt(_scale.sum_squares(np.ascontiguousarray(q.T), np.empty(len(q), dtype))) == 1   # |q|, the kernel's
    assert one.sum() > len(q) // 4
    np.testing.assert_array_equal(got[one], unit[one])
    for scale in (3.0, 2.0 ** -40, 2.0 ** 40):
        np.testing.assert_allclose(C.as_mrp(q * dtype(scale)), got, rtol=0, atol=2 * np.finfo(dtype).eps)


def test_mrp_of_negative_w_uses_the_short_way():
    q = np.array([-0.5, 0.5, 0.5, 0.5])
    np.testing.assert_allclose(C.as_mrp(q), sp(q).as_mrp(), atol=1e-15)
    np.testing.assert_allclose(C.as_mrp(q), C.as_mrp(-q), atol=1e-15)


# --- canonical form, inverse, applying --------------------------------------------------------------

def test_canonical_matches_scipy_including_zero_w():
    q = np.array([[-1.0, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 0], [0, 0, 0, -1], [0, 0, -1, 1],
                  [0, 1, -1, 0], [-0.5, 0.5, 0.5, 0.5], [0.5, -0.5, -0.5, -0.5]])
    r = sp(q)
    np.testing.assert_array_equal(C.canonical(r.as_quat(scalar_first=True)),
                                  r.as_quat(canonical=True, scalar_first=True))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_canonical_of_one_quaternion_is_the_batch_row(dtype):
    """One quaternion takes a float path (the same `_flip_mask`); its bits, signed zeros
    included, are the batch's row, for every sign pattern of w = ±0, x, y, z in {-1, ±0, 1}."""
    vals = np.array([-1.0, -0.0, 0.0, 1.0], dtype)
    q = np.stack(np.meshgrid(vals[1:3], vals, vals, vals, indexing="ij"), -1).reshape(-1, 4)
    batch = C.canonical(q)
    for i, row in enumerate(q):
        one = C.canonical(row)
        assert one.dtype == dtype and one.shape == (4,)
        np.testing.assert_array_equal(one.view(np.uint8), batch[i].view(np.uint8))


# --- layouts, chunking, empties, dtype rules ---------------------------------------------------------

FUNCS = {
    "as_matrix": (C.as_matrix, 4), "as_rotvec": (C.as_rotvec, 4), "magnitude": (C.magnitude, 4),
    "as_mrp": (C.as_mrp, 4), "inv": (K.conjugate, 4), "canonical": (C.canonical, 4),
    "as_euler": (lambda q: E.as_euler(q, "zxz"), 4),
    "as_davenport": (lambda q: E.as_davenport(q, np.eye(3)[[0, 1, 2]], "i"), 4),
    "from_rotvec": (C.from_rotvec, 3), "from_mrp": (C.from_mrp, 3),
    "from_euler": (lambda a: E.from_euler("XYZ", a), 3),
    "from_davenport": (lambda a: E.from_davenport(np.eye(3), "e", a), 3),
    "from_matrix": (lambda m: C.from_matrix(m.reshape(m.shape[:-1] + (3, 3))), 9),
    "apply": (lambda x: K.rotate(x[..., :4], x[..., 4:]), 7),
}


def _input(rng, k, n):
    if k == 9:
        return R.random(n, rng=rng).as_matrix().reshape(n, 9)
    x = rng.standard_normal((n, k))
    if k in (4, 7):
        x[:, :4] /= np.linalg.norm(x[:, :4], axis=1, keepdims=True)
    return x


@pytest.mark.parametrize("name", sorted(FUNCS))
def test_long_strided_readonly_inputs_are_chunked_and_untouched(rng, name):
    func, k = FUNCS[name]
    n = 2 * CHUNK + 37  # three blocks, the last one short
    base = _input(rng, k, 2 * n)
    contiguous = np.ascontiguousarray(base[::2])
    strided = base[::2]            # non-contiguous rows
    strided.flags.writeable = False
    before = strided.copy()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        want = func(contiguous)
        got = func(strided)
        fortran = func(np.asfortranarray(contiguous))
        small = func(contiguous[:5])
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(fortran, want)
    np.testing.assert_array_equal(small, want[:5])
    np.testing.assert_array_equal(strided, before)


@pytest.mark.parametrize("name", sorted(FUNCS))
def test_empty_inputs(name):
    func, k = FUNCS[name]
    x = np.zeros((0, 2, k))
    out = func(x)
    assert out.shape[:2] == (0, 2)


@pytest.mark.parametrize("name", sorted(FUNCS))
def test_float32_kept_and_ints_become_float64(rng, name):
    func, k = FUNCS[name]
    x = _input(rng, k, 6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        assert func(x.astype(np.float32)).dtype == np.float32
        ints = np.zeros((2, k), int)
        if k in (4, 7):
            ints[:, 0] = 1
        if k == 9:
            ints[:] = np.eye(3).reshape(9)
        assert func(ints).dtype == np.float64


@pytest.mark.parametrize("call, exc, match", [
    (lambda: C.as_matrix(np.ones(3)), ValueError, r"expected quat of shape \(\.\.\., 4\), got \(3,\)"),
    (lambda: C.as_rotvec(np.ones((2, 5))), ValueError, r"expected quat of shape \(\.\.\., 4\), got \(2, 5\)"),
    (lambda: C.from_rotvec([1, 2]), ValueError, r"expected rotvec of shape \(\.\.\., 3\), got \(2,\)"),
    (lambda: C.from_mrp(np.ones((3, 4))), ValueError, r"expected mrp of shape \(\.\.\., 3\)"),
    (lambda: Rotation.identity().apply(np.ones(2)), ValueError, r"Expected input of shape \(\.\.\., 3\), got \(2,\)"),
    (lambda: K.rotate(np.ones((3, 4)), np.ones((2, 3))), ValueError, "shape mismatch|broadcast"),
    (lambda: C.as_matrix(np.ones(4, complex)), TypeError, "real numbers"),
    (lambda: C.from_rotvec(["a", "b", "c"]), TypeError, "real numbers"),
    (lambda: E.from_euler("xyz", [1j, 0, 0]), TypeError, "angles of real numbers"),
])
def test_bad_input(call, exc, match):
    with pytest.raises(exc, match=match):
        call()


# --- identities (hypothesis) -----------------------------------------------------------------------

finite = st.floats(-10, 10, allow_nan=False).map(lambda c: c if abs(c) > 1e-100 else 0.0)
unit_quat = arrays(np.float64, 4, elements=finite).filter(lambda q: np.linalg.norm(q) > 1e-3).map(
    lambda q: q / np.linalg.norm(q))
rotvec = arrays(np.float64, 3, elements=st.floats(-3, 3, allow_nan=False))


@given(unit_quat, unit_quat)
def test_matrix_of_product_is_product_of_matrices(p, q):
    from quatarray import _kernels as K
    np.testing.assert_allclose(C.as_matrix(K.multiply(p, q)), C.as_matrix(p) @ C.as_matrix(q), atol=1e-14)


@given(unit_quat)
def test_round_trips_through_every_representation(q):
    assert_same_rotation(C.from_matrix(C.as_matrix(q)), q, 1e-14)
    assert_same_rotation(C.from_rotvec(C.as_rotvec(q)), q, 1e-14)
    assert_same_rotation(C.from_mrp(C.as_mrp(q)), q, 1e-14)
    for seq in ("zyx", "XZX"):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            angles = E.as_euler(q, seq)
        # in gimbal lock (middle angle within 1e-7 of a lock) the third angle is zeroed, as scipy
        assert_same_rotation(E.from_euler(seq, angles), q, 2e-7 if caught else 1e-12)


@given(rotvec)
def test_rotvec_round_trip_inside_pi(v):
    if np.linalg.norm(v) < np.pi - 1e-6:
        np.testing.assert_allclose(C.as_rotvec(C.from_rotvec(v)), v, atol=1e-14)


@given(unit_quat, arrays(np.float64, 3, elements=st.floats(-10, 10, allow_nan=False)))
def test_apply_is_matrix_times_vector(q, v):
    np.testing.assert_allclose(K.rotate(q, v), C.as_matrix(q) @ v, atol=1e-13)
    np.testing.assert_allclose(K.rotate(q, K.rotate(q, v), inverse=True), v, atol=1e-13)


# --- accuracy against 40-digit references -----------------------------------------------

def _ulp_of_largest(got, ref):
    """|got - ref| per quaternion in ulps of its largest component (sign of ref chosen)."""
    got = got * np.where(np.sum(got * ref, -1) < 0, -1, 1)[:, None]
    return (np.abs(got - ref) / np.spacing(np.abs(ref).max(-1, keepdims=True))).max(-1)


def _mp_axis_quat(mp, angle, k):
    e = [mp.cos(angle / 2), 0, 0, 0]
    e[k + 1] = mp.sin(angle / 2)
    return e


def _mp_mul(p, q):
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return [w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2]


def test_from_rotvec_and_from_euler_ulp_levels(rng):
    """The documented float64 accuracy (the half angles come from one tangent each):
    from_rotvec within 3 ulp, from_euler within 5 ulp of the largest component."""
    mp = pytest.importorskip("mpmath").mp
    mp.dps = 40
    v = rng.standard_normal((300, 3))
    v *= rng.uniform(0, np.pi, (300, 1)) / np.linalg.norm(v, axis=1, keepdims=True)
    ref = []
    for x in v:
        x = [mp.mpf(float(c)) for c in x]
        th = mp.sqrt(sum(c * c for c in x))
        ref.append([float(c) for c in [mp.cos(th / 2)] + [c * mp.sin(th / 2) / th for c in x]])
    assert _ulp_of_largest(C.from_rotvec(v), np.array(ref)).max() <= 3
    a = np.stack([rng.uniform(-np.pi, np.pi, 300), rng.uniform(-np.pi / 2, np.pi / 2, 300),
                  rng.uniform(-np.pi, np.pi, 300)], -1)
    ref = []
    for ang in a:
        qx, qy, qz = (_mp_axis_quat(mp, mp.mpf(float(x)), k) for k, x in enumerate(ang))
        ref.append([float(c) for c in _mp_mul(qz, _mp_mul(qy, qx))])   # extrinsic xyz
    assert _ulp_of_largest(E.from_euler("xyz", a), np.array(ref)).max() <= 5


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_huge_rotation_vectors_and_mrps_give_unit_quaternions(rng, dtype):
    """Rotation vectors and MRPs whose squared norms overflow (mixed in one block with
    ordinary ones) give finite unit quaternions, single and batched (the squares used to
    overflow to inf: NaN out).  MRPs, which have no angle to lose to rounding, are within
    4 eps of a 60-digit reference and the same single or batched; a rotation vector of 1e200
    rad has no meaningful angle left (one ulp is many turns), so only the unit norm is checked."""
    mp = pytest.importorskip("mpmath").mp
    mp.dps = 60
    top = 300 if dtype == np.float64 else 37
    v = rng.standard_normal((60, 3)) * 10.0 ** rng.uniform(-top, top, (60, 1))
    v = v.astype(dtype)
    eps = np.finfo(dtype).eps
    for conv in (C.from_rotvec, C.from_mrp):
        got = conv(v)
        single = np.array([conv(x) for x in v])
        for q in (got, single):
            assert q.dtype == dtype and np.isfinite(q).all()
            np.testing.assert_allclose(np.linalg.norm(q.astype(np.float64), axis=-1), 1, atol=4 * eps)
    # (one float32 MRP is converted in Python floats, then rounded: a few eps apart)
    np.testing.assert_allclose(C.from_mrp(v), np.array([C.from_mrp(x) for x in v]), rtol=0, atol=4 * eps)
    ref = []
    for p in v:
        p = [mp.mpf(float(c)) for c in p]
        n = sum(c * c for c in p)
        ref.append([float((1 - n) / (1 + n))] + [float(2 * c / (1 + n)) for c in p])
    assert np.abs(C.from_mrp(v) - np.array(ref)).max() <= 4 * eps


@pytest.mark.parametrize("n", [None, 1, 7, 5000])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_from_rotvec_refuses_non_finite_vectors_naming_the_first(rng, n, bad):
    """The kernel's norm range check finds them (no separate pass): the message still names
    the first bad element, whatever the batch, including next to huge finite vectors."""
    v = rng.standard_normal((3,) if n is None else (n, 3))
    if n is None:
        v[1], where = bad, "(1,)"
    else:
        v[0] = 1e200   # a huge finite vector in the same block takes the rescaling branch
        v[n - 1, 2] = bad
        where = f"({n - 1}, 2)"
    message = f"expected finite values in rotvec, got nan or inf at index {where}"
    with pytest.raises(ValueError, match=re.escape(message)):
        C.from_rotvec(v)
    with pytest.raises(ValueError, match="expected finite values in rotvec"):
        Rotation.from_rotvec(v)


# --- powers of rotations (`rotation_power`, Rotation ** n) ------------------------------------

POWER_EXPONENTS = [0.0, 1.0, -1.0, 0.5, -0.5, 2.5, -3.0, 1e-9, 1e9]


def _power_cases(rng, dtype):
    """Unit quaternions (n, 4): random, both signs of w, near the identity (tiny |v|), near and at
    the half turn (tiny w, w = ±0 with the canonical sign from x, y, z), the identity itself."""
    eps = float(np.finfo(dtype).eps)
    rnd = random_quats(rng, (12,))
    near_id = np.concatenate([np.ones((4, 1)), rng.standard_normal((4, 3)) * eps * 10.0 ** rng.uniform(-3, 2, (4, 1))], 1)
    near_pi = np.concatenate([rng.standard_normal((4, 1)) * eps * 10.0 ** rng.uniform(-3, 2, (4, 1)),
                              rng.standard_normal((4, 3))], 1)
    half = np.array([[0.0, 0, -1, 1], [-0.0, 0, 1, -1], [0.0, -1, 2, 0], [0.0, 0, 0, -1]])
    ident = np.array([[1.0, 0, 0, 0], [-1.0, 0, 0, 0]])
    q = np.concatenate([rnd, -rnd[:3], near_id, near_pi, half, ident])
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    return q.astype(dtype)


def _power_reference(q, n):
    """``r ** n`` by an independent route: the canonical quaternion (w > 0; at w = 0 the first
    non-zero of x, y, z positive: scipy's rotation vector) raised by `_kernels.power`
    (exp(n log q), its own log and exp) in float64."""
    c = C.canonical(np.asarray(q, np.float64))
    return K.power(c, n)


@pytest.mark.parametrize("n", POWER_EXPONENTS)
def test_rotation_power_against_an_independent_formula(rng, dtype, n):
    q = _power_cases(rng, dtype)
    got = C.rotation_power(q, n, unit=True)
    assert got.dtype == dtype and got.shape == q.shape and np.isfinite(got).all()
    eps = float(np.finfo(dtype).eps)
    # the angle n θ/2 carries n times the rounding of θ/2 (and of q itself): the bound grows with |n|
    atol = 8 * eps * max(1.0, abs(n))
    if atol < 0.1:
        np.testing.assert_allclose(got, _power_reference(q, n), rtol=0, atol=atol)
    np.testing.assert_allclose(np.linalg.norm(got.astype(np.float64), axis=1), 1, rtol=0, atol=4 * eps)


@pytest.mark.parametrize("n", [0.3, -2.0, 2.5, 1e-9])
def test_rotation_power_matches_scipy_signs_included(rng, n):
    q = _power_cases(rng, np.float64)
    want = (sp(q) ** n).as_quat(scalar_first=True)
    for i in range(len(q)):   # scipy's sign of w (cos(n θ/2) may be negative) and its half-turn branch
        np.testing.assert_allclose(Rotation.from_quat(q[i], scalar_first=True).__pow__(n).as_quat(scalar_first=True),
                                   want[i], rtol=0, atol=16 * np.finfo(float).eps * max(1, abs(n)))
    np.testing.assert_allclose(C.rotation_power(q, n), want, rtol=0, atol=16 * np.finfo(float).eps * max(1, abs(n)))


@pytest.mark.parametrize("n", [0.3, -3.0])
def test_rotation_power_same_bits_at_every_size_and_layout(rng, dtype, n):
    """A row alone (one float64 rotation: the float path), within a few (views), within blocks,
    read-only or strided, not unit (the range-guarded path): the same bits."""
    q = _power_cases(rng, dtype)
    big = np.concatenate([q, random_quats(rng, (CHUNK + 7,), dtype)])
    want = C.rotation_power(big, n, unit=True)
    for i in range(len(q)):
        np.testing.assert_array_equal(C.rotation_power(q[i], n, unit=True), want[i])
        np.testing.assert_array_equal(C.rotation_power(q[i:i + 1], n), want[i:i + 1])
    np.testing.assert_array_equal(C.rotation_power(q, n, unit=True), want[:len(q)])
    strided = np.zeros((len(q), 8), dtype)
    strided[:, ::2] = q
    view = strided[:, ::2]
    view.flags.writeable = False
    before = view.copy()
    np.testing.assert_array_equal(C.rotation_power(view, n, unit=True), want[:len(q)])
    np.testing.assert_array_equal(C.rotation_power(view, n), want[:len(q)])
    np.testing.assert_array_equal(view, before)
    each = C.rotation_power(big, np.full(len(big), n, dtype), unit=True)   # one exponent per rotation
    np.testing.assert_array_equal(each, want)


@pytest.mark.parametrize("scale", [2.0 ** -600, 2.0 ** 600])
def test_rotation_power_of_quaternions_of_extreme_norm(rng, scale):
    q = _power_cases(rng, np.float64)
    np.testing.assert_array_equal(C.rotation_power(q * scale, 0.3), C.rotation_power(q, 0.3, unit=True))


@given(unit_quat, st.floats(-20, 20, allow_nan=False))
def test_rotation_power_is_the_scaled_rotation_vector(q, n):
    """scipy's definition, from_rotvec(n as_rotvec(q)), up to the sign of the quaternion."""
    assert_same_rotation(C.rotation_power(q, n), C.from_rotvec(n * C.as_rotvec(q)), 2e-14 * max(1, abs(n)))


def test_rotation_power_rejects_an_exponent_whose_angle_overflows():
    r = Rotation.from_rotvec([0, 0, 1.0])
    assert np.isfinite((r ** 1e308).as_quat()).all()   # n θ/2 still finite
    with pytest.raises(ValueError, match="exponent n of magnitude at most"):
        r ** 1.5e308
    with pytest.raises(ValueError, match="exponents n of magnitude at most"):
        Rotation.from_rotvec(np.ones((2, 3))) ** np.array([1.0, -1.5e308])
    with pytest.raises(ValueError, match="exponent n of magnitude at most"):
        Rotation.from_rotvec(np.ones(3, np.float32)) ** 3e38
    with pytest.raises(ValueError, match="exponent n of magnitude at most"):
        C.rotation_power(np.array([1.0, 0, 0, 0]), -1.5e308)   # the kernel's own check
    with pytest.raises(ValueError, match="exponents n of magnitude at most"):
        C.rotation_power(np.ones((2, 4)), np.array([1.0, 1.5e308]))
