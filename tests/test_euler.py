"""Euler and Davenport angles (`quatarray._euler`) cross-checked against scipy:
all 24 sequences both ways, ranges, gimbal lock, float32, shapes and bad input."""

import sys
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation as R

from quatarray import Rotation
from quatarray import _euler as E

from .conftest import tol
from .test_convert import ALL_SEQS, SHAPES, angle_diff, assert_same_rotation, sp, sp_quat, unit

# --- Euler angles ------------------------------------------------------------------------------

@pytest.mark.parametrize("seq", ALL_SEQS)
def test_euler_both_ways_match_scipy(rng, seq):
    q = unit(rng, (300,), np.float64)
    got = E.as_euler(q, seq)
    want = sp(q).as_euler(seq)
    assert angle_diff(got, want).max() <= tol(np.float64)
    np.testing.assert_allclose(got, want, atol=tol(np.float64))  # same branch, not just mod 2π
    np.testing.assert_allclose(E.as_euler(q, seq, degrees=True), sp(q).as_euler(seq, degrees=True),
                               atol=tol(np.float64) * 180 / np.pi)
    angles = rng.uniform(-2 * np.pi, 2 * np.pi, (300, 3))
    assert_same_rotation(E.from_euler(seq, angles), sp_quat(R.from_euler(seq, angles)), tol(np.float64))
    deg = np.degrees(angles)
    assert_same_rotation(E.from_euler(seq, deg, degrees=True),
                         sp_quat(R.from_euler(seq, deg, degrees=True)), tol(np.float64))


@pytest.mark.parametrize("seq", ALL_SEQS)
def test_euler_ranges_and_round_trip(rng, seq):
    q = unit(rng, (500,), np.float64)
    a = E.as_euler(q, seq)
    assert (np.abs(a[:, [0, 2]]) <= np.pi).all()
    lo, hi = (0, np.pi) if seq[0].lower() == seq[2].lower() else (-np.pi / 2, np.pi / 2)
    assert ((a[:, 1] >= lo) & (a[:, 1] <= hi)).all()
    assert_same_rotation(E.from_euler(seq, a), q, tol(np.float64))


@pytest.mark.parametrize("seq", ["xyz", "ZXZ", "yxy", "XZY"])
@pytest.mark.parametrize("shape", SHAPES)
def test_euler_float32_and_batch_shapes(rng, seq, shape):
    q = unit(rng, shape, np.float32)
    a = E.as_euler(q, seq)
    assert a.dtype == np.float32 and a.shape == shape + (3,)
    want = sp(q).as_euler(seq)
    # where the middle angle is well away from gimbal lock the angles are well conditioned
    mid = want[..., 1] if seq[0].lower() == seq[2].lower() else want[..., 1] + np.pi / 2
    ok = np.minimum(mid, np.pi - mid) > 0.05
    assert (angle_diff(a, want)[ok] <= 20 * tol(np.float32)).all()
    back = E.from_euler(seq, a)
    assert back.dtype == np.float32
    assert_same_rotation(back, q / np.linalg.norm(q, axis=-1, keepdims=True), 4 * tol(np.float32))
    angles = rng.uniform(-np.pi, np.pi, shape + (3,)).astype(np.float32)
    assert_same_rotation(E.from_euler(seq, angles), sp_quat(R.from_euler(seq, angles.astype(float))),
                         tol(np.float32))


@pytest.mark.parametrize("seq", ALL_SEQS)
def test_gimbal_lock_for_every_sequence(seq):
    symmetric = seq[0].lower() == seq[2].lower()
    locks = [0.0, np.pi] if symmetric else [-np.pi / 2, np.pi / 2]
    angles = np.array([[0.3, m, -0.7] for m in locks] + [[1.2, m, 0.4] for m in locks])
    q = sp_quat(R.from_euler(seq, angles))
    with pytest.warns(UserWarning, match="Gimbal lock detected"):
        got = E.as_euler(q, seq)
    with pytest.warns(UserWarning, match="Gimbal lock detected"):
        want = R.from_quat(q, scalar_first=True).as_euler(seq)
    assert angle_diff(got, want).max() <= 1e-12
    assert (got[:, 2] == 0).all()  # the third angle is set to zero
    assert_same_rotation(E.from_euler(seq, got), q, 1e-12)  # and it is still the same rotation
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_array_equal(E.as_euler(q, seq, suppress_warnings=True), got)


def test_no_gimbal_warning_away_from_lock(rng):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        E.as_euler(E.from_euler("xyz", [0.1, 0.2, 0.3]), "xyz")


def test_euler_of_identity_and_tiny_angles():
    with pytest.warns(UserWarning, match="Gimbal"):  # zxz: the identity is in gimbal lock
        np.testing.assert_array_equal(E.as_euler(np.array([1.0, 0, 0, 0]), "zxz"), [0, 0, 0])
    np.testing.assert_array_equal(E.as_euler(np.array([1.0, 0, 0, 0]), "xyz"), [0, 0, 0])
    a = np.array([1e-9, -2e-9, 3e-9])
    np.testing.assert_allclose(E.as_euler(E.from_euler("xyz", a), "xyz"), a, rtol=1e-6)
    np.testing.assert_allclose(E.from_euler("x", 1e-9), [1, 5e-10, 0, 0], rtol=1e-15)


@pytest.mark.parametrize("seq, angles", [("x", 0.5), ("x", [[0.5], [0.2]]), ("XY", [0.1, 0.2]),
                                         ("zy", [[0.1, 0.2], [0.3, 0.4]]), ("ZYX", [[[0.1, 0.2, 0.3]]])])
def test_from_euler_shapes_like_scipy(seq, angles):
    got = E.from_euler(seq, angles)
    want = sp_quat(R.from_euler(seq, np.reshape(angles, (-1, len(seq))))).reshape(got.shape)
    assert got.shape == np.shape(angles)[:-1] + (4,) if np.ndim(angles) else got.shape == (4,)
    assert_same_rotation(got, want, 1e-15)


@pytest.mark.parametrize("seq, exc, match", [
    ("xxy", ValueError, "Expected consecutive axes to be different, got xxy"),
    ("XYY", ValueError, "consecutive axes"),
    ("xYz", ValueError, r"Expected axes from `seq` to be from \['x', 'y', 'z'\] or \['X', 'Y', 'Z'\], got xYz"),
    ("abc", ValueError, r"from \['x', 'y', 'z'\]"),
    ("xyzx", ValueError, "non-empty string of up to 3 characters, got xyzx"),
    ("", ValueError, "up to 3 characters"),
    (3, TypeError, "expected seq to be a str"),
])
def test_from_euler_bad_sequences(seq, exc, match):
    with pytest.raises(exc, match=match):
        E.from_euler(seq, [0.1, 0.2, 0.3])


@pytest.mark.parametrize("seq, match", [("xy", r"Expected 3 axes, got xy"), ("xyzx", "3 axes"),
                                        ("xyy", "consecutive"), ("Xyz", r"\['X', 'Y', 'Z'\], got Xyz")])
def test_as_euler_bad_sequences(seq, match):
    with pytest.raises(ValueError, match=match):
        E.as_euler(np.array([1.0, 0, 0, 0]), seq)


@pytest.mark.parametrize("seq, angles", [("xyz", [0.1, 0.2]), ("x", [0.1, 0.2, 0.3]), ("xy", 0.3),
                                         ("xyz", np.zeros((4, 2)))])
def test_from_euler_angles_shape_mismatch(seq, angles):
    """The raw function and `Rotation.from_euler` give one message, which starts with scipy's."""
    with pytest.raises(ValueError) as scipy_error:
        R.from_euler(seq, angles)
    scipy_message = str(scipy_error.value).rstrip(".")
    for from_euler in (E.from_euler, Rotation.from_euler):
        with pytest.raises(ValueError, match=rf"expected angles of shape \(\.\.\., {len(seq)}\)") as error:
            from_euler(seq, angles)
        assert str(error.value).startswith(scipy_message + ":"), str(error.value)


# --- Davenport angles ------------------------------------------------------------------------------

def _axes_sets(rng):
    """Axis triples whose middle axis is orthogonal to the other two (some non-unit)."""
    sets = [np.eye(3)[[2, 0, 1]], np.eye(3)[[0, 1, 0]], [[2.0, 0, 0], [0, 1, 0], [1, 0, 1]]]
    for _ in range(3):
        basis = R.random(rng=rng).as_matrix()
        n2 = basis[:, 1]
        n1 = basis[:, 0]
        n3 = np.cos(0.7) * basis[:, 0] + np.sin(0.7) * basis[:, 2]
        sets.append(np.array([n1, n2, n3]))
    return [np.asarray(s, float) for s in sets]


@pytest.mark.parametrize("order", ["e", "extrinsic", "i", "intrinsic"])
def test_davenport_both_ways_match_scipy(rng, order):
    q = unit(rng, (200,), np.float64)
    angles = rng.uniform(-np.pi, np.pi, (200, 3))
    for axes in _axes_sets(rng):
        assert_same_rotation(E.from_davenport(axes, order, angles),
                             sp_quat(R.from_davenport(axes, order, angles)), tol(np.float64))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # random data may touch a lock
            got = E.as_davenport(q, axes, order)
            want = sp(q).as_davenport(axes, order)
        assert angle_diff(got, want).max() <= 1e-12
        assert_same_rotation(E.from_davenport(axes, order, got), q, 1e-12)


def test_davenport_degrees_fewer_axes_and_float32(rng):
    ez, ex = [0, 0, 1], [1, 0, 0]
    a = [[90, 45], [35, 45]]
    assert_same_rotation(E.from_davenport([ez, ex], "e", a, degrees=True),
                         sp_quat(R.from_davenport([ez, ex], "e", a, degrees=True)), 1e-15)
    assert_same_rotation(E.from_davenport(ez, "i", 30, degrees=True), E.from_euler("z", 30, degrees=True), 1e-15)
    q = unit(rng, (50,), np.float32)
    axes = np.eye(3)[[2, 0, 2]]
    got = E.as_davenport(q, axes, "e", degrees=True)
    assert got.dtype == np.float32
    np.testing.assert_allclose(got, E.as_euler(q, "zxz", degrees=True), atol=1e-3)


def test_as_davenport_takes_obtuse_axes_as_scipy(rng):
    """scipy's as_davenport tests cos < 1e-7 between consecutive axes (from_davenport tests
    |cos|): axes at 120° pass, and give scipy's angles."""
    q = unit(rng, (50,), np.float64)
    axes = [[1, 0, 0], [-0.5, 0.75 ** 0.5, 0], [0, 0, 1]]
    for order in ("e", "i"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            np.testing.assert_allclose(E.as_davenport(q, axes, order), sp(q).as_davenport(axes, order), atol=1e-12)
            np.testing.assert_allclose(Rotation.from_quat(q, scalar_first=True).as_davenport(axes, order),
                                       sp(q).as_davenport(axes, order), atol=1e-12)


@pytest.mark.parametrize("scale", [1e-200, 1e200, 1e308])
def test_davenport_axes_of_any_length(rng, scale):
    """The axes' lengths do not matter, also where their squares leave the float range."""
    axes = np.eye(3)[[2, 0, 1]]
    angles = rng.uniform(-np.pi, np.pi, (20, 3))
    want = E.from_davenport(axes, "e", angles)
    assert_same_rotation(E.from_davenport(axes * scale, "e", angles), want, 1e-15)
    np.testing.assert_array_equal(E.as_davenport(want, axes * scale, "e"), E.as_davenport(want, axes, "e"))


def test_davenport_gimbal_lock_warns():
    axes = np.eye(3)[[2, 0, 2]]
    q = E.from_euler("zxz", [0.3, 0.0, 0.2])
    with pytest.warns(UserWarning, match="Gimbal lock"):
        a = E.as_davenport(q, axes, "e")
    assert a[2] == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        E.as_davenport(q, axes, "e", suppress_warnings=True)


def _axes_per_rotation(rng, n):
    """A set of Davenport axes per rotation (n, 3, 3): random orthonormal n1, n2 and the third
    axis turned from n1 about n2 by any angle (obtuse ones too), each of a random length."""
    frames = np.linalg.qr(rng.standard_normal((n, 3, 3)))[0]
    n1, n2, m = frames[..., 0], frames[..., 1], frames[..., 2]
    t = rng.uniform(-np.pi, np.pi, (n, 1))
    return np.stack([n1, n2, np.cos(t) * n1 + np.sin(t) * m], axis=1) * rng.uniform(0.2, 5, (n, 3, 1))


def _lock_angle(axes):
    """The middle angle that puts extrinsic Davenport angles about `axes` (..., 3, 3) in gimbal
    lock: the turn about n2 that takes n1 to n3 (then the first and third turns share an axis)."""
    n1, n2, n3 = (axes[..., k, :] / np.linalg.norm(axes[..., k, :], axis=-1, keepdims=True) for k in range(3))
    return np.arctan2(np.sum(n2 * np.cross(n1, n3), axis=-1), np.sum(n1 * n3, axis=-1))


@pytest.mark.parametrize("order", ["e", "i"])
def test_davenport_with_a_set_of_axes_per_rotation_matches_scipy_row_by_row(rng, dtype, order):
    """as_davenport with a set of axes per rotation gives each row scipy's angles for its own
    axes (scipy 1.17 takes one set of axes per call for (n, 4) quaternions: its Cython
    backend), gimbal lock included, and from_davenport turns them back into the rotations;
    from_davenport matches scipy's batched from_davenport."""
    n = 120
    ax = _axes_per_rotation(rng, n)
    q = unit(rng, (n,), dtype)
    if dtype == np.float64:   # every fourth rotation in gimbal lock, at either end (a float32
        # quaternion's rounding moves the middle angle by about the lock's 1e-7: scipy, reading
        # it in float64, may judge otherwise)
        lock = np.arange(n) % 4 == 0
        ends = _lock_angle(ax[lock] if order == "e" else ax[lock, ::-1]) + np.pi * (np.arange(lock.sum()) % 2)
        lock_angles = np.stack([rng.uniform(-3, 3, len(ends)), ends, rng.uniform(-3, 3, len(ends))], axis=-1)
        q[lock] = E.from_davenport(ax[lock] if order == "e" else ax[lock, ::-1], "e", lock_angles)
        with pytest.warns(UserWarning, match="Gimbal lock"):
            got = E.as_davenport(q, ax, order)
        assert (got[lock, 2] == 0).all()   # (as scipy, for either order)
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            got = E.as_davenport(q, ax, order)
    assert got.dtype == dtype and got.shape == (n, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        want = np.array([sp(q[i]).as_davenport(ax[i], order) for i in range(n)])
    assert angle_diff(got, want).max() <= tol(dtype, 100)
    back = E.from_davenport(ax, order, got)
    assert back.dtype == dtype
    assert_same_rotation(back, q, tol(dtype, 8))
    angles = rng.uniform(-np.pi, np.pi, (n, 3)).astype(dtype)
    assert_same_rotation(E.from_davenport(ax, order, angles),
                         sp_quat(R.from_davenport(ax, order, angles.astype(np.float64))), tol(dtype, 8))
    assert_same_rotation(Rotation.from_davenport(ax[:, :2], order, angles[:, :2]).as_quat(),
                         R.from_davenport(ax[:, :2], order, angles[:, :2].astype(np.float64)).as_quat(), tol(dtype, 8))


@pytest.mark.parametrize("call, match", [
    (lambda: E.from_davenport(np.eye(3), "x", [1, 2, 3]), "order should be 'e'/'extrinsic' .* or 'i'/'intrinsic' .*, got 'x'"),
    (lambda: E.from_davenport([[1, 0, 0], [1, 1, 0], [0, 0, 1]], "e", [1, 2, 3]), "Consecutive axes must be orthogonal"),
    (lambda: E.from_davenport(np.ones((4, 3)), "e", [1, 2, 3, 4]), r"Expected up to 3 axes, got 4: .* got \(4, 3\)"),
    (lambda: E.from_davenport(np.eye(3), "e", [1, 2]),
     r"Expected `angles` to match number of axes, got \(2,\) angles and \(3, 3\) axes: expected angles of shape \(\.\.\., 3\)$"),
    (lambda: E.from_davenport(np.eye(2), "e", [1, 2]), r"Axes must be vectors of length 3: .* got \(2, 2\)"),
    (lambda: E.from_davenport([[0, 0, 0], [0, 1, 0]], "e", [1, 2]), r"non-zero axes, got a zero vector among axes of shape \(2, 3\)"),
    (lambda: E.from_davenport([[np.nan, 0, 0], [0, 1, 0]], "e", [1, 2]), r"finite values in axes, got nan or inf at index \(0, 0\)"),
    (lambda: E.as_davenport(np.array([1.0, 0, 0, 0]), np.eye(3)[:2], "e"), r"Expected 3 axes, got \(2, 3\)\."),
    # a set of axes per rotation: the same validator, element by element
    (lambda: E.from_davenport(np.stack([np.eye(3), [[1, 0, 0], [1, 1, 0], [0, 0, 1]]]), "e", [1, 2, 3]),
     r"Consecutive axes must be orthogonal: got cos = 0\.707"),
    (lambda: E.from_davenport(np.stack([np.eye(3), np.eye(3) * [[1], [0], [1]]]), "e", [1, 2, 3]), "non-zero axes"),
    (lambda: E.from_davenport(np.ones((2, 4, 3)), "e", [1, 2, 3, 4]), r"Expected up to 3 axes, got 4: .* got \(2, 4, 3\)"),
    (lambda: E.from_davenport(np.stack([np.eye(3)] * 2), "e", np.zeros((3, 3))),
     r"got \(3, 3\) angles and \(2, 3, 3\) axes: expected angles of shape \(\.\.\., 3\) broadcasting with the axes' \(2,\)"),
    (lambda: E.as_davenport(np.ones((3, 4)), np.stack([np.eye(3)] * 2), "e"),
     r"Expected `axes` to match number of rotations, got \(2, 3, 3\) axes and \(3, 4\) rotations"),
    (lambda: E.as_davenport(np.ones((2, 4)), np.stack([np.eye(3), [[1, 0, 0], [1, 1, 0], [0, 0, 1]]]), "e"), "orthogonal"),
    (lambda: E.as_davenport(np.ones((2, 4)), np.ones((2, 2, 3)), "e"), r"Expected 3 axes, got \(2, 2, 3\)\."),
    (lambda: E.as_davenport(np.array([1.0, 0, 0, 0]), [[1, 0, 0], [1, 1, 0], [0, 0, 1]], "e"), "orthogonal"),
    (lambda: E.from_davenport([[1, 0, 0], [-1, 1, 0], [0, 0, 1]], "e", [1, 2, 3]), "orthogonal"),
    (lambda: E.as_davenport(np.array([1.0, 0, 0, 0]), np.eye(3), "intrinsic-ish"), "order"),
])
def test_davenport_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_davenport_order_of_another_type_raises_as_scipy():
    """scipy's from_davenport takes `order` as a typed str (TypeError), its as_davenport
    compares it (ValueError)."""
    for cls in (R, Rotation):
        with pytest.raises(TypeError):
            cls.from_davenport(np.eye(3), None, [1, 2, 3])
        with pytest.raises(ValueError):
            cls.identity().as_davenport(np.eye(3), 1)


def test_negate_works_where_numpys_inplace_negative_does_not():
    """The reason for `_euler._negate`: on NumPy 2.4 (AVX-512 and AVX2 builds alike),
    ``np.negative(x, out=x)`` on a float32 row with a 16-byte stride (a component row of
    an (m, 4) array) reads contiguous elements instead of the row's.  The minimal
    reproducer is the first block below; `_negate` must be right either way."""
    a = np.arange(1, 13, dtype=np.float32).reshape(3, 4)
    row = a.T[1]                                   # 2, 6, 10: 16 bytes apart
    want = -row.copy()
    numpy_row = a.copy().T[1]
    np.negative(numpy_row, out=numpy_row)          # NumPy 2.4.6 gives -2, -3, -4
    numpy_is_right = np.array_equal(numpy_row, want)
    E._negate(row)
    np.testing.assert_array_equal(row, want, err_msg=f"numpy's in-place negative right: {numpy_is_right}")


@pytest.mark.parametrize("seq", ["xyz", "ZYX", "zxz", "YXY", "xzy"])
def test_euler_of_quarter_turns_and_signed_zeros_like_scipy_in_any_batch(rng, seq):
    """Quarter and half turns make the arctangents' denominators exactly ±0 (their angles are
    ±π/2 or ±π, signed as scipy's); with signed zero components and random rows, every row
    alone, as a batch of one and in the batch gives the same bits, and scipy's angles."""
    turns = R.from_euler("xyz", [[90, 0, 0], [0, 0, 90], [180, 0, 0], [0, 0, -90], [90, 0, 90],
                                 [-90, 0, 180], [0, 30, 0]], degrees=True).as_quat(scalar_first=True)
    signed = np.array([[0.5, -0.5, 0.5, -0.5], [-0.0, 1.0, -0.0, 0.0], [0.0, -0.0, -1.0, 0.0],
                       [0.5, 0.5, -0.0, np.sqrt(0.5)]])
    signed /= np.linalg.norm(signed, axis=1, keepdims=True)
    batch = np.concatenate([unit(rng, (3,), np.float64), turns, signed])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # the half turns of symmetric sequences are gimbal locks
        want = sp(batch).as_euler(seq)
        for f in (lambda q: E.as_euler(q, seq), lambda q: Rotation.from_quat(q, scalar_first=True).as_euler(seq)):
            whole = f(batch)
            for i in range(len(batch)):
                np.testing.assert_array_equal(f(batch[i]), whole[i])
                np.testing.assert_array_equal(f(batch[i:i + 1])[0], whole[i])
            assert angle_diff(whole, want).max() <= tol(np.float64)


def test_kept_work_rows_give_the_same_angles_in_any_order_of_sizes_and_threads(rng):
    """`_euler._euler_rows` keeps each thread's work rows and their views by block shape and
    dtype (past `_blocks.FEW` rotations, by their place in the thread's scratch): sizes and
    dtypes in any order, and four threads at once, give the bits of the first calls."""
    from concurrent.futures import ThreadPoolExecutor

    qs = [unit(rng, (n,), dtype) for n in (1, 3, 10, 100, 1500, 20000) for dtype in (np.float64, np.float32)]
    calls = [(q, seq) for q in qs for seq in ("xyz", "ZXZ", "yzx")]
    want = [E.as_euler(q, seq) for q, seq in calls]

    def run(order):
        return all(np.array_equal(E.as_euler(*calls[k]), want[k]) for k in order)
    orders = [list(range(len(calls)))[::step] for step in (1, -1, 2, -3)]
    assert run(orders[1])
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)   # threads switch between any two ufunc calls
    try:
        with ThreadPoolExecutor(4) as pool:
            assert all(pool.map(run, orders * 4))
    finally:
        sys.setswitchinterval(interval)
