"""`quatarray.Rotation`, scipy's Rotation over a `QuatArray`: every
method cross-checked against scipy's Rotation in batch shapes (), (N,), (N, M)
and both dtypes; randomness, averaging and fitting; the bad-input table; the
documented migration differences; and a realistic workflow run with either
import giving the same numbers."""

import copy
import pickle
import warnings

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy import stats
from scipy.spatial.transform import Rotation as SR

import quatarray
from quatarray import QuatArray, Rotation
from quatarray._convert import as_matrix
from quatarray.testing import assert_allclose

from .conftest import random_quats, tol

SHAPES = [(), (6,), (3, 4)]


def scipy_of(r):
    """The scipy Rotation of a Rotation, from its float64 components."""
    return SR.from_quat(r.as_quat(scalar_first=True).astype(np.float64), scalar_first=True)


def pair(rng, shape, dtype):
    """The same random rotations as a Rotation (dtype) and a scipy Rotation."""
    q = random_quats(rng, shape, dtype)
    return Rotation.from_quat(q, scalar_first=True), SR.from_quat(q.astype(np.float64), scalar_first=True)


def assert_same_rotation(got, want, atol):
    """Quaternions equal up to the double cover (q and -q)."""
    assert_allclose(got, want, rtol=0, atol=atol, double_cover=True)

def angle_diff(a, b):
    return np.abs(np.angle(np.exp(1j * (np.asarray(a, np.float64) - np.asarray(b, np.float64)))))


def test_rotation_is_its_own_class_over_a_quatarray(rng):
    r = Rotation.from_rotvec([[0, 0, 1], [1, 0, 0]])
    assert quatarray.Rotation is Rotation and not isinstance(r, (QuatArray, np.ndarray))
    # zero-copy both ways: the QuatArray is the rotation's storage, scalar-first
    q = r.as_quatarray()
    assert type(q) is QuatArray and q.shape == (2, 4)
    assert np.shares_memory(q, r.as_quatarray()) and np.shares_memory(Rotation.from_quatarray(q).as_quatarray(), q)
    np.testing.assert_array_equal(q.ndarray, r.as_quat(scalar_first=True))
    keys = QuatArray(random_quats(rng, (5,)))
    assert np.shares_memory(Rotation.from_quatarray(keys).as_quatarray(), keys)
    with pytest.raises(TypeError, match="expected q to be a QuatArray, got ndarray"):
        Rotation.from_quatarray(keys.ndarray)


# --- quaternions in and out ------------------------------------------------------------------

@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("scalar_first", [False, True])
def test_from_quat_as_quat_match_scipy(rng, dtype, shape, scalar_first):
    q = (3 * random_quats(rng, shape, np.float64, unit=False)).astype(dtype)  # not normalised
    before = q.copy()
    r = Rotation.from_quat(q, scalar_first=scalar_first)
    s = SR.from_quat(q.astype(np.float64), scalar_first=scalar_first)
    assert r.dtype == dtype and r.shape == shape == s.shape
    np.testing.assert_array_equal(q, before)  # input untouched
    for canonical in (False, True):
        for sf in (False, True):
            got = r.as_quat(canonical=canonical, scalar_first=sf)
            want = s.as_quat(canonical=canonical, scalar_first=sf)
            assert type(got) is np.ndarray and got.dtype == dtype
            np.testing.assert_allclose(got, want, rtol=0, atol=tol(dtype))
    # canonical=True: the same sign as scipy's, exactly (away from w = 0)
    np.testing.assert_array_equal(np.sign(r.as_quat(canonical=True))[..., 3],
                                  np.sign(s.as_quat(canonical=True))[..., 3])
    np.testing.assert_allclose(np.linalg.norm(r.as_quat(scalar_first=True), axis=-1), 1, atol=tol(dtype))


def test_as_quat_canonical_zero_w_rule():
    q = np.array([[0, 0, -1, 0], [0, -1, 1, 0], [-1, 0, 0, 0], [0, 0, 0, -1.0]])  # scalar-last
    np.testing.assert_array_equal(Rotation.from_quat(q).as_quat(canonical=True),
                                  SR.from_quat(q).as_quat(canonical=True))


def test_as_quat_is_a_copy(rng):
    r = Rotation.from_quat(random_quats(rng, (3,)))
    a = r.as_quat(scalar_first=True)
    a[:] = 0
    assert np.all(np.linalg.norm(r.as_quat(scalar_first=True), axis=-1) > 0.99)


# --- conversions through the class ----------------------------------------------------------------

@pytest.mark.parametrize("shape", SHAPES)
def test_conversions_match_scipy(rng, dtype, shape):
    r, s = pair(rng, shape, dtype)
    t = tol(dtype)
    np.testing.assert_allclose(r.as_matrix(), s.as_matrix(), rtol=0, atol=t)
    np.testing.assert_allclose(r.as_rotvec(), s.as_rotvec(), rtol=0, atol=t)
    np.testing.assert_allclose(r.as_rotvec(degrees=True), s.as_rotvec(degrees=True), rtol=0, atol=t * 60)
    np.testing.assert_allclose(r.as_mrp(), s.as_mrp(), rtol=0, atol=t)
    np.testing.assert_allclose(r.magnitude(), s.magnitude(), rtol=0, atol=t)
    mat = s.as_matrix().astype(dtype)
    assert_same_rotation(Rotation.from_matrix(mat).as_quat(scalar_first=True), s.as_quat(scalar_first=True), t)
    assert_same_rotation(Rotation.from_rotvec(s.as_rotvec().astype(dtype)).as_quat(scalar_first=True), s.as_quat(scalar_first=True), t)
    assert_same_rotation(Rotation.from_mrp(s.as_mrp().astype(dtype)).as_quat(scalar_first=True), s.as_quat(scalar_first=True), t)
    for res in (r.as_matrix(), r.as_rotvec(), r.as_mrp(), Rotation.from_matrix(mat)):
        assert res.dtype == dtype
    assert Rotation.from_matrix(mat).shape == shape


@pytest.mark.parametrize("seq", ["xyz", "ZYX", "zxz", "YXY", "xzy", "XYZ"])
@pytest.mark.parametrize("shape", SHAPES)
def test_euler_and_davenport_match_scipy(rng, dtype, seq, shape):
    r, s = pair(rng, shape, dtype)
    axes = np.eye(3)[["xyz".index(c) for c in seq.lower()]]
    order = "e" if seq.islower() else "i"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        got, want = r.as_euler(seq), s.as_euler(seq)
        got_deg, want_deg = r.as_euler(seq, degrees=True), s.as_euler(seq, degrees=True)
        dav, sdav = r.as_davenport(axes, order), s.as_davenport(axes, order)
    assert got.dtype == dav.dtype == dtype and got.shape == want.shape
    # angles are ill-conditioned near gimbal lock: compare where the middle angle is clear of it
    mid = want[..., 1] if seq[0].lower() == seq[2].lower() else want[..., 1] + np.pi / 2
    ok = np.minimum(mid, np.pi - mid) > (1e-3 if dtype == np.float64 else 0.05)
    t = 20 * tol(dtype)
    assert (angle_diff(got, want)[ok] <= t).all() and (angle_diff(dav, sdav)[ok] <= t).all()
    assert (angle_diff(np.radians(got_deg), np.radians(want_deg))[ok] <= t).all()
    if dtype == np.float64:
        np.testing.assert_allclose(got, want, atol=1e-12)  # the same branch, not only mod 2π
    angles = rng.uniform(-np.pi, np.pi, shape + (3,)).astype(dtype)
    for ours, theirs in ((Rotation.from_euler(seq, angles), SR.from_euler(seq, angles.astype(float))),
                         (Rotation.from_davenport(axes, order, angles),
                          SR.from_davenport(axes, order, angles.astype(float)))):
        assert ours.dtype == dtype and ours.shape == shape
        assert_same_rotation(ours.as_quat(scalar_first=True), theirs.as_quat(scalar_first=True), tol(dtype))


def test_gimbal_warning_points_at_the_caller():
    r = Rotation.from_euler("zxz", [0.3, 0.0, 0.2])
    with pytest.warns(UserWarning, match="Gimbal lock detected") as caught:
        r.as_euler("zxz")
    assert caught[0].filename == __file__
    with pytest.warns(UserWarning, match="Gimbal lock detected") as caught:
        r.as_davenport(np.eye(3)[[2, 0, 2]], "e")
    assert caught[0].filename == __file__
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r.as_euler("zxz", suppress_warnings=True)


def test_edge_rotations_match_scipy():
    angles = [0.0, 1e-9, -1e-9, np.pi, -np.pi, np.pi - 1e-9, 2 * np.pi]
    rv = np.array([[a, 0, 0] for a in angles] + [[0, a, 0] for a in angles] + [[a, a, a] for a in angles])
    r, s = Rotation.from_rotvec(rv), SR.from_rotvec(rv)
    assert_same_rotation(r.as_quat(scalar_first=True), s.as_quat(scalar_first=True), 1e-15)
    np.testing.assert_allclose(r.as_rotvec(), s.as_rotvec(), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(r.as_matrix(), s.as_matrix(), atol=1e-15)
    np.testing.assert_allclose(r.magnitude(), s.magnitude(), rtol=1e-12, atol=1e-15)
    assert_same_rotation(Rotation.from_matrix(s.as_matrix()).as_quat(scalar_first=True), s.as_quat(scalar_first=True), 1e-15)


# --- apply, inv, magnitude, approx_equal, composition, power ------------------------------------------

@pytest.mark.parametrize("rshape, vshape", [((), ()), ((), (5,)), ((5,), ()), ((5,), (5,)), ((1,), (5,)),
                                            ((), (1,)), ((5, 1, 4), (3, 4)), ((2, 3), (2, 3))])
@pytest.mark.parametrize("inverse", [False, True])
def test_apply_matches_scipy_broadcasting(rng, dtype, rshape, vshape, inverse):
    r, s = pair(rng, rshape, dtype)
    v = rng.standard_normal(vshape + (3,)).astype(dtype)
    got = r.apply(v, inverse=inverse)
    want = s.apply(v.astype(np.float64), inverse=inverse)
    assert type(got) is np.ndarray and got.dtype == dtype
    assert got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=0, atol=4 * tol(dtype))


def test_apply_to_lists_and_noncontiguous_readonly_vectors(rng):
    r, s = pair(rng, (40,), np.float64)
    v = rng.standard_normal((80, 3))[::2]
    v.flags.writeable = False  # scipy 1.17 itself refuses read-only vectors: compare on a copy
    np.testing.assert_allclose(r.apply(v), s.apply(v.copy()), atol=1e-14)
    np.testing.assert_allclose(r.apply([1, 2, 3]), s.apply([1, 2, 3]), atol=1e-14)
    np.testing.assert_allclose(r[0].apply(v), s[0].apply(v.copy()), atol=1e-14)


def test_inv_magnitude_and_composition_match_scipy(rng, dtype, batch_shape):
    r, s = pair(rng, batch_shape, dtype)
    r2, s2 = pair(rng, batch_shape, dtype)
    inv = r.inv()
    assert isinstance(inv, Rotation) and inv.dtype == dtype
    assert_same_rotation(inv.as_quat(scalar_first=True), s.inv().as_quat(scalar_first=True), tol(dtype))
    assert_same_rotation((r * r2).as_quat(scalar_first=True), (s * s2).as_quat(scalar_first=True), tol(dtype))
    assert_same_rotation((r * r.inv()).as_quat(scalar_first=True), [1, 0, 0, 0], tol(dtype))
    m = r.magnitude()
    np.testing.assert_allclose(m, s.magnitude(), rtol=0, atol=tol(dtype))
    if batch_shape == ():
        assert isinstance(m, np.floating) and not isinstance(m, np.ndarray)


def test_power_is_scipys_for_either_sign_of_w(rng):
    # `**` is scipy's rotation power, from_rotvec(t * as_rotvec()): the sign of the stored
    # quaternion does not matter (the QuatArray power exp(t log q) is another operation)
    q = random_quats(rng, (200,))
    for sign in (1, -1):
        r, s = Rotation.from_quat(sign * q, scalar_first=True), SR.from_quat(q, scalar_first=True)
        for t in (0.5, -0.3, 2.0, 3.7, 0, 1, -1, np.array(0.25), np.array([1.5])):
            assert_same_rotation((r ** t).as_quat(scalar_first=True), (s ** t).as_quat(scalar_first=True), 1e-13)
    r = Rotation.from_quat(q, scalar_first=True)
    with pytest.raises(TypeError, match="expected n of real numbers"):
        r ** "2"


def test_power_with_one_exponent_per_rotation_is_an_extension(rng):
    q = random_quats(rng, (4, 3))
    r, t = Rotation.from_quat(q, scalar_first=True), rng.uniform(-2, 2, (4, 3))
    got = (r ** t).as_quat(scalar_first=True)
    for i, j in np.ndindex(4, 3):
        want = (SR.from_quat(q[i, j], scalar_first=True) ** t[i, j]).as_quat(scalar_first=True)
        assert_same_rotation(got[i, j], want, 1e-13)
    assert (r ** t[:, :1]).shape == (4, 3)   # broadcasting
    with pytest.raises(ValueError, match="Array exponent must be a scalar"):
        r ** np.ones(5)
    with pytest.raises(ValueError, match="Array exponent must be a scalar"):
        r[0, 0] ** np.ones(2)   # a single rotation: scipy's rule


def test_approx_equal(rng, dtype):
    r, s = pair(rng, (8,), dtype)
    tiny = Rotation.from_rotvec(np.array([1e-10, 0, 0], dtype))
    near = r * tiny
    far = r * Rotation.from_rotvec(np.array([1e-3, 0, 0], dtype))
    assert r.approx_equal(r).all()
    assert r.approx_equal(near).all()
    assert not r.approx_equal(far).any()
    assert r.approx_equal(far, atol=2e-3).all()
    assert r.approx_equal(far, atol=0.1, degrees=True).all()
    assert not r.approx_equal(far, atol=0.01, degrees=True).any()
    np.testing.assert_array_equal(r.approx_equal(r[0]), s.approx_equal(s[0]))
    single = r[0].approx_equal(near[0])
    assert single.shape == s[0].approx_equal(s[0]).shape == (1,) and single.all()  # scipy's shape
    with pytest.warns(UserWarning, match="atol must be set to use the degrees flag"):
        r.approx_equal(near, degrees=True)


def test_approx_equal_default_atol_is_scipy_in_float64(rng):
    r = Rotation.from_rotvec([0, 0, 1.0])
    assert r.approx_equal(Rotation.from_rotvec([0, 0, 1 + 5e-9]))
    assert not r.approx_equal(Rotation.from_rotvec([0, 0, 1 + 2e-8]))
    s = SR.from_rotvec([0, 0, 1.0])
    assert s.approx_equal(SR.from_rotvec([0, 0, 1 + 5e-9])) and not s.approx_equal(SR.from_rotvec([0, 0, 1 + 2e-8]))


# --- mean ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("shape", [(1,), (7,), (4, 5)])
def test_mean_matches_scipy(rng, dtype, shape):
    r, s = pair(rng, shape, dtype)
    # a cluster, so that the mean is well defined
    r = r * Rotation.from_rotvec(np.array([0.3, -0.2, 0.1], dtype))
    s = s * SR.from_rotvec([0.3, -0.2, 0.1])
    base, sbase = Rotation.from_quat(r.as_quat()[(0,) * len(shape)]), SR.from_quat(s.as_quat()[(0,) * len(shape)])
    noise = rng.normal(scale=0.2, size=shape + (3,))
    r = Rotation.from_rotvec(noise.astype(dtype)) * base
    s = SR.from_rotvec(noise) * sbase
    w = rng.uniform(0.1, 2, shape)
    for kwargs in ({}, {"weights": w}):
        got, want = r.mean(**kwargs), s.mean(**kwargs)
        assert got.single and got.dtype == dtype
        assert got.as_quat(scalar_first=True)[0] >= 0  # canonical sign
        assert_same_rotation(got.as_quat(scalar_first=True), want.as_quat(scalar_first=True), 20 * tol(dtype))
    if len(shape) == 2:
        for axis in (0, 1, -1, (0,), (0, 1)):
            got, want = r.mean(axis=axis), s.mean(axis=axis)
            assert got.shape == want.shape
            assert_same_rotation(got.as_quat(scalar_first=True), want.as_quat(scalar_first=True), 20 * tol(dtype))
        got, want = r.mean(weights=w[0], axis=0), s.mean(weights=w[0], axis=0)
        assert_same_rotation(got.as_quat(scalar_first=True), want.as_quat(scalar_first=True), 20 * tol(dtype))


def test_mean_of_single_rotation_and_zero_weights(rng):
    r = Rotation.random(rng=rng)
    assert_same_rotation(r.mean().as_quat(scalar_first=True), r.as_quat(scalar_first=True), 1e-15)
    many = Rotation.random(3, rng=rng)
    assert_same_rotation(many.mean(weights=[0, 1, 0]).as_quat(scalar_first=True), many[1].as_quat(scalar_first=True), 1e-15)


# --- random, identity, concatenate, single, scipy interop ----------------------------------------

def test_random_is_scipys_random_for_the_same_seed():
    for kwargs in ({}, {"num": 5}, {"shape": (2, 3)}, {"shape": 4}):
        got = Rotation.random(rng=7, **kwargs)
        want = SR.random(rng=7, **kwargs)
        assert got.shape == want.shape and got.dtype == np.float64
        np.testing.assert_allclose(got.as_quat(), want.as_quat(), rtol=0, atol=1e-15)
    gen = np.random.default_rng(3)
    np.testing.assert_allclose(Rotation.random(4, gen).as_quat(),
                               SR.random(4, np.random.default_rng(3)).as_quat(), atol=1e-15)


def test_random_is_uniform_on_so3():
    r = Rotation.random(100_000, rng=12345)
    theta = r.magnitude()
    # rotation angles of the Haar measure: density (1 - cos θ)/π, CDF (θ - sin θ)/π on [0, π]
    edges = np.linspace(0, np.pi, 41)
    counts, _ = np.histogram(theta, edges)
    expected = np.diff((edges - np.sin(edges)) / np.pi) * theta.size
    chi2 = np.sum((counts - expected) ** 2 / expected)
    assert chi2 < stats.chi2.ppf(0.999, df=len(counts) - 1)
    # a biased sampler (uniform axis, uniform angle) fails the same test
    biased = Rotation.from_rotvec(Rotation.random(100_000, rng=1).as_rotvec()
                                  / theta[:, None] * np.linspace(0, np.pi, theta.size)[:, None])
    bc, _ = np.histogram(biased.magnitude(), edges)
    assert np.sum((bc - expected) ** 2 / expected) > stats.chi2.ppf(0.999, df=len(counts) - 1)
    # the mean rotation matrix of a uniform sample is zero
    assert np.abs(r.as_matrix().mean(axis=0)).max() < 0.01


def test_identity_matches_scipy():
    for kwargs in ({}, {"num": 3}, {"shape": (2, 2)}):
        np.testing.assert_array_equal(Rotation.identity(**kwargs).as_quat(), SR.identity(**kwargs).as_quat())


def test_concatenate_matches_scipy(rng):
    parts = [Rotation.random(rng=1), Rotation.random(3, rng=2), Rotation.random(2, rng=3)]
    sparts = [SR.random(rng=1), SR.random(3, rng=2), SR.random(2, rng=3)]
    got, want = Rotation.concatenate(parts), SR.concatenate(sparts)
    assert got.shape == want.shape == (6,)
    np.testing.assert_allclose(got.as_quat(), want.as_quat(), atol=1e-15)
    one = Rotation.concatenate(parts[1])
    np.testing.assert_array_equal(one.as_quat(scalar_first=True), parts[1].as_quat(scalar_first=True))
    assert not np.shares_memory(one.as_quatarray(), parts[1].as_quatarray())
    f32 = [Rotation(p.as_quat().astype(np.float32)) for p in parts[:2]]
    assert Rotation.concatenate(f32).dtype == np.float32
    assert Rotation.concatenate([f32[0], parts[1]]).dtype == np.float64


def test_single_len_shape_and_iteration():
    one, many = Rotation.random(rng=0), Rotation.random(3, rng=0)
    assert one.single and not many.single and not Rotation.random(1, rng=0).single
    assert SR.random(rng=0).single and not SR.random(1, rng=0).single
    with pytest.raises(TypeError):
        len(one)
    with pytest.raises(TypeError, match="Single rotation has no len"):
        len(SR.random(rng=0))
    assert len(many) == 3
    assert many.shape == SR.random(3, rng=0).shape == (3,) and one.shape == SR.random(rng=0).shape == ()
    assert [q.single for q in many] == [True] * 3
    assert bool(one) and bool(Rotation.identity(0))
    with pytest.raises(TypeError, match="Single rotation is not subscriptable"):
        one[0]
    with pytest.raises(TypeError, match="Single rotation is not iterable"):
        iter(one)
    assert many.mean().single


def test_scipy_round_trip(rng, dtype, batch_shape):
    r, s = pair(rng, batch_shape, dtype)
    back = Rotation.from_scipy(r.to_scipy())
    assert isinstance(r.to_scipy(), SR)
    assert r.to_scipy().shape == s.shape
    assert_same_rotation(back.as_quat(scalar_first=True), r.as_quat(scalar_first=True), tol(dtype))
    assert_same_rotation(Rotation.from_scipy(s).as_quat(scalar_first=True), s.as_quat(scalar_first=True), 0)
    assert Rotation.from_scipy(s).shape == s.shape


# --- align_vectors ------------------------------------------------------------------------------------

def test_align_vectors_matches_scipy(rng):
    b = rng.standard_normal((10, 3))
    true = SR.random(rng=rng)
    a = true.apply(b) + 0.01 * rng.standard_normal((10, 3))
    w = rng.uniform(0.5, 2, 10)
    for kwargs in ({}, {"weights": w}):
        r, rssd, sens = Rotation.align_vectors(a, b, return_sensitivity=True, **kwargs)
        s, srssd, ssens = SR.align_vectors(a, b, return_sensitivity=True, **kwargs)
        assert r.single
        assert_same_rotation(r.as_quat(scalar_first=True), s.as_quat(scalar_first=True), 1e-13)
        np.testing.assert_allclose(rssd, srssd, rtol=1e-10)
        np.testing.assert_allclose(sens, ssens, rtol=1e-10)
        assert len(Rotation.align_vectors(a, b, **kwargs)) == 2


def test_align_vectors_keeps_float32(rng):
    b = rng.standard_normal((6, 3))
    a = SR.random(rng=rng).apply(b)
    r, rssd = Rotation.align_vectors(a.astype(np.float32), b.astype(np.float32))
    s, _ = SR.align_vectors(a, b)
    assert r.dtype == np.float32
    assert_same_rotation(r.as_quat(scalar_first=True), s.as_quat(scalar_first=True), tol(np.float32))
    assert Rotation.align_vectors(a.astype(np.float32), b)[0].dtype == np.float64


@pytest.mark.parametrize("case", ["single", "inf", "antiparallel", "parallel", "near_antiparallel"])
def test_align_vectors_primary_cases_match_scipy(rng, case):
    b = rng.standard_normal((4, 3))
    a = SR.random(rng=rng).apply(b)
    w = np.ones(4)
    if case == "single":
        a, b, w = a[:1], b[:1], None
    elif case == "inf":
        w[2] = np.inf
    elif case == "antiparallel":
        a, b, w = np.array([[1.0, 0, 0]]), np.array([[-2.0, 0, 0]]), None
    elif case == "parallel":
        a, b, w = np.array([[0.0, 3, 0]]), np.array([[0.0, 1, 0]]), None
    else:
        a, b, w = np.array([[1.0, 0, 0]]), np.array([[-1.0, 1e-5, 0]]), None
    r, rssd = Rotation.align_vectors(a, b, weights=w)
    s, srssd = SR.align_vectors(a, b, weights=w)
    assert_same_rotation(r.as_quat(scalar_first=True), s.as_quat(scalar_first=True), 1e-12)
    np.testing.assert_allclose(rssd, srssd, atol=1e-12)
    np.testing.assert_allclose(r.apply(b[0] / np.linalg.norm(b[0])), a[0] / np.linalg.norm(a[0]), atol=1e-12)


def test_align_vectors_degenerate_warns_like_scipy():
    a = np.array([[1.0, 0, 0], [2.0, 0, 0]])
    with pytest.warns(UserWarning, match="not uniquely or poorly defined"):
        Rotation.align_vectors(a, a)


# --- inputs: layouts, empties, read-only -------------------------------------------------------------

@pytest.mark.parametrize("make", [
    lambda x: Rotation.from_quat(x["q"]), lambda x: Rotation.from_rotvec(x["v"]),
    lambda x: Rotation.from_mrp(x["v"]), lambda x: Rotation.from_euler("xyz", x["v"]),
    lambda x: Rotation.from_matrix(x["m"]), lambda x: Rotation.from_davenport(np.eye(3), "e", x["v"]),
])
def test_constructors_accept_unusual_layouts_and_do_not_modify_input(rng, make):
    base = {"q": random_quats(rng, (20,)), "v": rng.uniform(-1, 1, (20, 3)),
            "m": SR.random(20, rng=1).as_matrix()}
    want = make(base).as_quat(scalar_first=True)
    odd = {k: np.asfortranarray(np.repeat(a, 2, axis=0)[::2]) for k, a in base.items()}
    for a in odd.values():
        a.flags.writeable = False
    before = {k: a.copy() for k, a in odd.items()}
    got = make(odd)
    np.testing.assert_allclose(got.as_quat(scalar_first=True), want, atol=1e-15)
    for k in odd:
        np.testing.assert_array_equal(odd[k], before[k])
    empty = make({"q": np.zeros((0, 4)), "v": np.zeros((0, 3)), "m": np.zeros((0, 3, 3))})
    assert empty.shape == (0,)
    assert empty.as_matrix().shape == (0, 3, 3) and empty.as_rotvec().shape == (0, 3)
    assert empty.apply(np.zeros((0, 3))).shape == (0, 3)


# --- bad input table ------------------------------------------------------------------------------------

R3 = Rotation.random(3, rng=0)

BAD = [
    (lambda: Rotation.from_quat([0, 0, 0, 0]), ValueError, "zero norm quaternions .* got a zero quaternion"),
    (lambda: Rotation.from_quat([[1, 0, 0, 0], [0, 0, 0, 0]]), ValueError, r"at index \(1,\)"),
    (lambda: Rotation.from_quat([np.nan, 0, 0, 1]), ValueError, "expected finite quat"),
    (lambda: Rotation.from_quat([np.inf, 0, 0, 1]), ValueError, "expected finite quat"),
    (lambda: Rotation.from_quat([1, 2, 3]), ValueError, r"Expected `quat` to have shape \(\.\.\., 4\), got \(3,\)"),
    (lambda: Rotation.from_quat(1.0), ValueError, r"shape \(\.\.\., 4\)"),
    (lambda: Rotation.from_quat(["a", "b", "c", "d"]), TypeError, "real numbers"),
    (lambda: Rotation.from_quat([1j, 0, 0, 1]), TypeError, "real numbers"),
    (lambda: Rotation.from_matrix(-np.eye(3)), ValueError, "Non-positive determinant"),
    (lambda: Rotation.from_matrix(np.zeros((3, 3))), ValueError, "Non-positive determinant"),
    (lambda: Rotation.from_matrix(np.full((3, 3), np.nan)), ValueError, "expected finite values in matrix"),
    (lambda: Rotation.from_matrix(np.eye(4)), ValueError, r"Expected `matrix` to have shape \(3, 3\) or \(\.\.\., 3, 3\), got \(4, 4\)"),
    (lambda: Rotation.from_rotvec([1, 2]), ValueError, r"Expected `rot_vec` to have shape \(3,\) or \(\.\.\., 3\), got \(2,\)"),
    (lambda: Rotation.from_mrp(np.ones((2, 4))), ValueError, r"Expected `mrp` to have shape \(3,\) or \(\.\.\., 3\), got \(2, 4\)"),
    (lambda: Rotation.from_euler("xxy", [1, 2, 3]), ValueError, "consecutive axes"),
    (lambda: Rotation.from_euler("xYz", [1, 2, 3]), ValueError, r"Expected axes from `seq` to be from \['x', 'y', 'z'\] or \['X', 'Y', 'Z'\], got xYz"),
    (lambda: Rotation.from_euler("xyzx", [1, 2, 3, 4]), ValueError, "non-empty string of up to 3 characters, got xyzx"),
    (lambda: Rotation.from_euler("xyz", [1, 2]), ValueError, r"expected angles of shape \(\.\.\., 3\)"),
    (lambda: Rotation.from_euler("x", [1, 2, 3]), ValueError, r"expected angles of shape \(\.\.\., 1\)"),
    (lambda: R3.as_euler("xy"), ValueError, "3 axes"),
    (lambda: R3.as_euler("xxz"), ValueError, "consecutive axes"),
    (lambda: Rotation.from_davenport(np.eye(3), "x", [1, 2, 3]), ValueError, "order"),
    (lambda: Rotation.from_davenport([[1, 0, 0], [1, 1, 0], [0, 0, 1]], "e", [1, 2, 3]), ValueError, "orthogonal"),
    (lambda: R3.as_davenport(np.eye(3)[:2], "e"), ValueError, r"Expected 3 axes, got \(2, 3\)"),
    (lambda: R3.apply(np.ones((3, 2))), ValueError, r"Expected input of shape \(\.\.\., 3\), got \(3, 2\)"),
    (lambda: R3.apply(np.ones((2, 3))), ValueError, r"Cannot broadcast 3 rotations to 2 vectors"),
    (lambda: R3.apply(np.ones((3, 3), complex)), TypeError, "real numbers"),
    (lambda: R3.approx_equal(Rotation.random(2, rng=0)), ValueError, "broadcastable shapes"),
    (lambda: R3.approx_equal(np.ones(4)), TypeError, "expected other to be a Rotation"),
    (lambda: R3.mean(weights=[1, -1, 1]), ValueError, "`weights` must be non-negative"),
    (lambda: R3.mean(weights=[1, np.nan, 1]), ValueError, "expected finite weights"),
    (lambda: R3.mean(weights=[1, 1]), ValueError, "broadcastable to rotation shape"),
    (lambda: R3.mean(weights=np.ones((2, 3))), ValueError, "broadcastable to rotation shape"),
    (lambda: R3.mean(axis=1), ValueError, r"axis \(1,\) is out of bounds for rotation with shape \(3,\)"),
    (lambda: R3.mean(axis=[0]), ValueError, "`axis` must be None, int, or tuple of ints"),
    (lambda: Rotation.from_quat(np.zeros((0, 4))).mean(), ValueError, "Mean of an empty rotation set"),
    (lambda: Rotation.random(3, shape=(3,)), ValueError, "Only one of `num` or `shape`"),
    (lambda: Rotation.random(shape=[3]), ValueError, "`shape` must be an int or a tuple of ints"),
    (lambda: Rotation.random(-1), ValueError, "non-negative int"),
    (lambda: Rotation.concatenate([R3, 1]), TypeError, "Rotation objects only.*int at position 1"),
    (lambda: Rotation.concatenate([]), ValueError, "at least one rotation"),
    (lambda: Rotation.align_vectors(np.zeros((0, 3)), np.zeros((0, 3))), ValueError, "at least one pair"),
    (lambda: Rotation.align_vectors([[1, 0, 0]], [[1, 0, 0], [0, 1, 0]]), ValueError, "same shapes"),
    (lambda: Rotation.align_vectors([1, 0], [1, 0]), ValueError, r"`a` to have shape \(3,\) or \(N, 3\)"),
    (lambda: Rotation.align_vectors(np.ones((2, 2, 3)), np.ones((2, 2, 3))), ValueError, r"\(3,\) or \(N, 3\)"),
    (lambda: Rotation.align_vectors(np.eye(3), np.eye(3), weights=[1, -1, 1]), ValueError, "negative"),
    (lambda: Rotation.align_vectors(np.eye(3), np.eye(3), weights=[1, 1]), ValueError, "number of values"),
    (lambda: Rotation.align_vectors(np.eye(3), np.eye(3), weights=np.ones((3, 1))), ValueError, "1 dimensional"),
    (lambda: Rotation.align_vectors(np.eye(3), np.eye(3), weights=[np.inf, np.inf, 1]), ValueError, "Only one infinite"),
    (lambda: Rotation.align_vectors([[1, 0, 0]], [[1, 0, 0]], return_sensitivity=True), ValueError, "sensitivity"),
    (lambda: Rotation.align_vectors([[0, 0, 0]], [[1, 0, 0]]), ValueError, "zero length primary"),
    (lambda: Rotation.align_vectors([[np.nan, 0, 0]], [[1, 0, 0]]), ValueError, "finite"),
    (lambda: Rotation.from_scipy(np.array([0, 0, 0, 1.0])), TypeError, "scipy.spatial.transform.Rotation"),
]


@pytest.mark.parametrize("call, exc, match", BAD, ids=[str(i) for i in range(len(BAD))])
def test_bad_input(call, exc, match):
    with pytest.raises(exc, match=match):
        call()


@pytest.mark.parametrize("call, exc", [
    (lambda R: R.from_quat([0, 0, 0, 0]), ValueError),
    (lambda R: R.from_quat([1, 2, 3]), ValueError),
    (lambda R: R.from_matrix(-np.eye(3)), ValueError),
    (lambda R: R.from_euler("xxy", [1, 2, 3]), ValueError),
    (lambda R: R.from_euler("xyz", [1, 2]), ValueError),
    (lambda R: R.random(3, rng=0).mean(weights=[1, -1, 1]), ValueError),
    (lambda R: R.random(3, rng=0).apply(np.ones((2, 3))), ValueError),
    (lambda R: R.align_vectors([[1, 0, 0]], [[1, 0, 0], [0, 1, 0]]), ValueError),
    (lambda R: R.concatenate([R.identity(), 1]), TypeError),
])
def test_same_error_types_as_scipy(call, exc):
    for cls in (SR, Rotation):
        with pytest.raises(exc):
            call(cls)


# --- migration: one workflow, two imports ----------------------------------------------------------

def workflow(R, Slerp):
    """A realistic scipy-style pipeline, written once for either import."""
    rng = np.random.default_rng(2024)
    # body orientations from a log of intrinsic yaw-pitch-roll angles, in degrees
    ypr = np.column_stack([rng.uniform(-180, 180, 500), rng.uniform(-80, 80, 500), rng.uniform(-180, 180, 500)])
    body = R.from_euler("ZYX", ypr, degrees=True)
    mount = R.from_rotvec([0.0, 0.1, -0.05])            # sensor mounting offset
    sensor = body * mount                                # compose
    cloud = rng.standard_normal((500, 3))                # one point per pose
    world = sensor.apply(cloud)
    back = sensor.apply(world, inverse=True)
    shared = mount.apply(rng.standard_normal((1000, 3)))  # one rotation, many points
    relative = sensor.inv() * body
    noisy = R.from_rotvec(rng.normal(scale=0.05, size=(200, 3))) * mount
    average = noisy.mean(weights=rng.uniform(0.5, 1.5, 200))
    fitted, rssd = R.align_vectors(world[:20], cloud[:20])
    randoms = R.random(50, rng=11)
    keys = R.from_euler("xyz", rng.uniform(-1, 1, (12, 3)))
    smooth = Slerp(np.linspace(0, 10, 12), keys)(np.linspace(0, 10, 101))
    return {
        "euler": sensor.as_euler("ZYX", degrees=True),
        "euler_ext": sensor.as_euler("xyz"),
        "rotvec": relative.as_rotvec(),
        "matrix": sensor.as_matrix(),
        "quat": sensor.as_quat(canonical=True),
        "mrp": sensor.as_mrp(),
        "world": world,
        "back": back,
        "shared": shared,
        "mean_matrix": average.as_matrix(),
        "mean_euler": average.as_euler("zyx"),
        "magnitude": relative.magnitude(),
        "close": relative.approx_equal(R.from_rotvec(relative.as_rotvec()), atol=1e-9),
        "fitted": fitted.as_matrix(),
        "rssd": np.asarray(rssd),
        "randoms": randoms.as_quat(),
        "from_matrix": R.from_matrix(sensor.as_matrix()).as_quat(canonical=True),
        "from_quat": R.from_quat(sensor.as_quat()).as_rotvec(),
        "concat": R.concatenate([mount, sensor[:3]]).as_rotvec(),
        "slerp": smooth.as_euler("xyz"),
    }


def test_migration_workflow_gives_scipys_numbers():
    from scipy.spatial.transform import Slerp as ScipySlerp

    from quatarray.interpolate import Slerp
    ours, theirs = workflow(Rotation, Slerp), workflow(SR, ScipySlerp)
    assert ours.keys() == theirs.keys()
    for key in ours:
        got, want = np.asarray(ours[key]), np.asarray(theirs[key])
        assert got.shape == want.shape, key
        if got.dtype == bool:
            np.testing.assert_array_equal(got, want, err_msg=key)
        else:
            np.testing.assert_allclose(got, want, rtol=1e-11, atol=1e-11, err_msg=key)


# --- scipy's container behaviour, randomness rules and mixing with scipy -----------------------

def test_repr_pickle_copy_and_setitem_like_scipy(rng):
    q = random_quats(rng, (3,))
    r, s = Rotation.from_quat(q, scalar_first=True), SR.from_quat(q, scalar_first=True)
    assert repr(r) == repr(s) and str(r) == str(s) and repr(r[0]) == repr(s[0])
    for clone in (pickle.loads(pickle.dumps(r)), copy.copy(r), copy.deepcopy(r)):
        np.testing.assert_array_equal(clone.as_quat(), r.as_quat())
        assert not np.shares_memory(clone.as_quatarray(), r.as_quatarray())
    part = r[1:]
    before = r.as_quat()
    part[0] = Rotation.identity()        # a slice is a copy, as in scipy
    np.testing.assert_array_equal(r.as_quat(), before)
    r[1] = Rotation.identity()
    s[1] = SR.identity()
    np.testing.assert_allclose(r.as_quat(), s.as_quat(), atol=1e-15)
    r[0] = s[2]                            # a scipy Rotation is converted
    np.testing.assert_allclose(r[0].as_quat(), s[2].as_quat(), atol=1e-15)
    with pytest.raises(TypeError, match="value must be a Rotation object"):
        r[0] = q[0]
    assert (r == r) and not (r == Rotation.from_quat(r.as_quat())) and r != r.inv()  # identity, as scipy


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("clone", [copy.copy, copy.deepcopy, lambda r: pickle.loads(pickle.dumps(r))],
                         ids=["copy", "deepcopy", "pickle"])
def test_a_copy_or_pickle_gives_the_original_bits(rng, dtype, clone):
    """A copied or unpickled Rotation (a Dask task's, a cached one) answers with the original's
    bits: it keeps knowing its quaternions are unit, so it takes the same formulas."""
    r = Rotation.from_quat(random_quats(rng, (200,)).astype(dtype))
    c = clone(r)
    for name, f in [("as_matrix", lambda x: x.as_matrix()), ("as_mrp", lambda x: x.as_mrp()),
                    ("as_rotvec", lambda x: x.as_rotvec()), ("magnitude", lambda x: x.magnitude()),
                    ("as_euler", lambda x: x.as_euler("xyz")), ("mul", lambda x: (x * x).as_quat()),
                    ("apply", lambda x: x.apply([1.0, 2.0, 3.0]))]:
        np.testing.assert_array_equal(f(c), f(r), err_msg=name, strict=True)
    c.as_quatarray()[0] = [2, 0, 0, 0]   # a clone shares no memory, and no knowledge once written to
    np.testing.assert_allclose(np.linalg.det(clone(c).as_matrix()[0]), 1, rtol=1e-6)
    older = object.__new__(Rotation)   # a pickle from before the flag travelled: the quaternions alone
    older.__setstate__(r.as_quat(scalar_first=True))
    np.testing.assert_allclose(older.as_matrix(), r.as_matrix(), rtol=0, atol=4 * np.finfo(dtype).eps)


def test_iterated_rotations_are_copies(rng):
    """As in scipy, the rotations an iteration yields are independent of the batch: writing
    into one (through as_quatarray) leaves the batch's quaternions and matrices as they were."""
    r = Rotation.from_quat(random_quats(rng, (3,)))
    before = r.as_quat(), r.as_matrix()
    for item in r:
        item.as_quatarray()[:] = [2.0, 0, 0, 0]
    np.testing.assert_array_equal(r.as_quat(), before[0], strict=True)
    np.testing.assert_array_equal(r.as_matrix(), before[1], strict=True)


def _consumers():
    from quatarray import RotationSpline, Slerp, Track, timeseries
    times = np.arange(6.0)
    return [("Slerp", lambda r: Slerp(times, r)), ("RotationSpline", lambda r: RotationSpline(times, r)),
            ("Track", lambda r: Track(times, r)), ("reduce_keys", lambda r: timeseries.reduce_keys(times, r, 0.1)),
            ("integrate initial",
             lambda r: timeseries.integrate_angular_velocity(times, np.zeros((6, 6, 3)), initial=r)),
            ("angular_velocity", lambda r: timeseries.angular_velocity(times, r)),
            ("swing_twist", lambda r: timeseries.swing_twist(r, [0, 0, 1])),
            ("geodesic_mean", lambda r: timeseries.geodesic_mean(r)),
            ("smooth", lambda r: timeseries.smooth(times, r, 3))]


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("name", [name for name, _ in _consumers()])
def test_consumers_leave_a_rotation_as_it_was(rng, dtype, name):
    """Slerp, RotationSpline, Track and the time-series functions read a Rotation's quaternions
    without changing it: afterwards it gives the same bits (it still knows they are unit)."""
    consume = dict(_consumers())[name]
    r = Rotation.from_quat(random_quats(rng, (6,)).astype(dtype))
    before = r.as_quat(), r.as_matrix(), r.as_mrp()
    consume(r)
    for got, want in zip((r.as_quat(), r.as_matrix(), r.as_mrp()), before):
        np.testing.assert_array_equal(got, want, strict=True)


def test_random_legacy_random_state_draws_like_scipy():
    for ours, theirs in ((Rotation.random(4, 5), SR.random(4, 5)),                         # by position
                         (Rotation.random(4, random_state=5), SR.random(4, random_state=5)),
                         (Rotation.random(4, np.random.RandomState(5)), SR.random(4, np.random.RandomState(5)))):
        np.testing.assert_allclose(ours.as_quat(), theirs.as_quat(), rtol=0, atol=1e-15)
    with pytest.raises(TypeError, match="multiple values for argument now known as `rng`"):
        Rotation.random(2, rng=1, random_state=1)
    with pytest.raises(TypeError, match="takes from 0 to 2 positional arguments"):
        Rotation.random(1, 2, 3)


def test_mixing_with_scipy_rotations_works(rng):
    q = random_quats(rng, (4,))
    r, s = Rotation.from_quat(q, scalar_first=True), SR.from_quat(q, scalar_first=True)
    for got in (r * s, s * r):
        assert isinstance(got, Rotation)
        assert_same_rotation(got.as_quat(scalar_first=True), (s * s).as_quat(scalar_first=True), 1e-14)
    assert r.approx_equal(s).all()
    assert Rotation.concatenate(s).shape == (4,)
    with pytest.raises(TypeError, match="from_scipy"):
        Rotation.concatenate([r, s])
    from quatarray import Slerp
    np.testing.assert_allclose(Slerp([0, 1, 2, 3], s)(0.5).as_quat(), Slerp([0, 1, 2, 3], r)(0.5).as_quat())


def test_reduce_and_groups_match_scipy(rng):
    q = random_quats(rng, (20,))
    r, s = Rotation.from_quat(q, scalar_first=True), SR.from_quat(q, scalar_first=True)
    for name in ("I", "O", "T", "D3", "C5"):
        g, sg = Rotation.create_group(name), SR.create_group(name)
        assert g.shape == sg.shape
        # the same group: every scipy element is one of ours
        assert Rotation.from_scipy(sg)[:, None].approx_equal(g[None, :], atol=1e-12).any(axis=1).all()
        for left, right in ((g, None), (None, g), (g, g)):
            got, li, ri = r.reduce(left, right, return_indices=True)
            want = s.reduce(None if left is None else sg, None if right is None else sg)
            np.testing.assert_allclose(got.magnitude(), want.magnitude(), atol=1e-12)
            assert (li is None) == (left is None) and (ri is None) == (right is None)
            one = Rotation.identity() if left is None else g[li]
            two = Rotation.identity() if right is None else g[ri]
            assert (one * r * two).approx_equal(got, atol=1e-12).all()
    assert r[0].reduce(g).single


def test_davenport_with_batched_axes_matches_one_call_per_axes_set(rng):
    axes = np.stack([np.eye(3)[[2, 0, 2]], np.eye(3)[[0, 1, 2]]])     # (2, 3, 3)
    angles = rng.uniform(-1, 1, (2, 3))
    r = Rotation.from_davenport(axes, "e", angles)
    for i in range(2):
        assert_same_rotation(r[i].as_quat(), SR.from_davenport(axes[i], "e", angles[i]).as_quat(), 1e-14)
        np.testing.assert_allclose(r.as_davenport(axes, "e")[i], SR.from_davenport(axes[i], "e", angles[i]).as_davenport(axes[i], "e"), atol=1e-12)


def test_float32_is_kept_where_scipy_promotes():
    q = np.array([[0, 0, 0.6, 0.8]], np.float32)
    r, s = Rotation.from_quat(q), SR.from_quat(q)
    assert r.dtype == np.float32 and s.as_quat().dtype == np.float64
    for out in (r.as_quat(), r.as_matrix(), r.as_rotvec(), r.as_euler("xyz"), r.apply(np.ones(3, np.float32))):
        assert out.dtype == np.float32
    np.testing.assert_allclose(r.as_matrix(), s.as_matrix(), atol=1e-6)


# --- one rotation: the Python-float paths give the batch paths' numbers ----------------------

EULER_SEQS = ["xyz", "xzy", "yxz", "yzx", "zxy", "zyx", "XYZ", "ZYX", "xyx", "zxz", "YZY", "XZX"]
DAV_AXES = np.array([[1, 1, 0], [0, 0, 1], [1, -1, 0]]) / np.array([[2 ** 0.5], [1], [2 ** 0.5]])


def test_single_rotation_paths_equal_batch_paths(rng, dtype):
    q = random_quats(rng, (60,), dtype)
    q[:6] = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, 0], [-1, 0, 0, 0],
                      [0, 0, 0, -1], [np.sqrt(0.5), 0, np.sqrt(0.5), 0]], dtype)   # edges, gimbal lock
    r = Rotation.from_quat(q, scalar_first=True)
    t = 8 * np.finfo(dtype).eps   # float32: the single path computes in float64, then rounds
    batch = {"as_matrix": r.as_matrix(), "as_rotvec": r.as_rotvec(), "as_mrp": r.as_mrp(),
             "as_rotvec_deg": r.as_rotvec(degrees=True) / 180}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        for seq in EULER_SEQS:
            batch[seq] = r.as_euler(seq)
        for order in ("e", "i"):
            batch["dav" + order] = r.as_davenport(DAV_AXES, order)
        for i, one in enumerate(r):
            got = {"as_matrix": one.as_matrix(), "as_rotvec": one.as_rotvec(), "as_mrp": one.as_mrp(),
                   "as_rotvec_deg": one.as_rotvec(degrees=True) / 180}
            for seq in EULER_SEQS:
                got[seq] = one.as_euler(seq)
            for order in ("e", "i"):
                got["dav" + order] = one.as_davenport(DAV_AXES, order)
            for key, value in got.items():
                assert value.dtype == dtype
                np.testing.assert_allclose(value, batch[key][i], rtol=0, atol=t, err_msg=key)
            if dtype == np.float64:   # unit storage: one rotation's matrix is the batch kernel's, bit for bit
                assert one._unit and r._unit
                np.testing.assert_array_equal(got["as_matrix"], batch["as_matrix"][i])
    v = (3 * rng.standard_normal((40, 3))).astype(dtype)
    v[0] = 0
    v64 = v.astype(np.float64)
    for ours, theirs in ((Rotation.from_rotvec, SR.from_rotvec), (Rotation.from_mrp, SR.from_mrp),
                         *(((lambda a, q=seq: Rotation.from_euler(q, a[..., :len(q)])),
                            (lambda a, q=seq: SR.from_euler(q, a[..., :len(q)]))) for seq in ("zxz", "YX", "x")),
                         (lambda a: Rotation.from_davenport(DAV_AXES, "i", a), lambda a: SR.from_davenport(DAV_AXES, "i", a))):
        whole = theirs(v64).as_quat()
        for i in range(len(v)):
            one = ours(v[i])
            assert one.single and one.dtype == dtype
            assert_same_rotation(one.as_quat(), whole[i], 4 * t)


def test_single_rotation_operators_equal_batch_operators(rng):
    r = Rotation.from_quat(random_quats(rng, (20,)), scalar_first=True)
    s = Rotation.from_quat(random_quats(rng, (20,)), scalar_first=True)
    prod, power, close = (r * s).as_quat(), (r ** 0.3).as_quat(), r.approx_equal(s, atol=1.0)
    for i in range(20):
        np.testing.assert_allclose((r[i] * s[i]).as_quat(), prod[i], rtol=0, atol=1e-15)
        np.testing.assert_allclose((r[i] ** 0.3).as_quat(), power[i], rtol=0, atol=1e-15)
        assert r[i].approx_equal(s[i], atol=1.0).tolist() == [close[i]]
    for exponent in (1e308, -1e308):   # n θ/2 still finite: the same finite bits either way
        np.testing.assert_array_equal((r[0] ** exponent).as_quat(), (r[:1] ** exponent).as_quat()[0])
        assert np.isfinite((r[0] ** exponent).as_quat()).all()
    for exponent in (1.5e308, -1.5e308):   # n θ/2 would overflow: the same error either way
        for rotation in (r[0], r[:1]):
            with pytest.raises(ValueError, match="exponent n of magnitude at most"):
                rotation ** exponent


def _held(q):
    """Rotations holding `q` exactly as given (not normalised: any magnitude), and the same as a batch of one."""
    return Rotation.from_quatarray(q.view(QuatArray)), Rotation.from_quatarray(q[None].view(QuatArray))


@given(components=arrays(np.float64, 4, elements=st.floats(-1, 1, allow_nan=False, allow_subnormal=False)),
       exponent=st.integers(-1000, 1000), other=st.sampled_from(range(4)), f32=st.booleans())
def test_single_rotation_methods_equal_the_batch_of_one(components, exponent, other, f32):
    """Every Python-float path of one rotation gives the block path's numbers for the same
    rotation in a batch of one, at any magnitude (the stored quaternion is not normalised)."""
    dtype = np.float32 if f32 else np.float64
    exponent = exponent % 201 - 100 if f32 else exponent
    q = np.ldexp(components, exponent).astype(dtype)
    assume(np.abs(components).max() > 1e-3 and np.isfinite(q).all() and np.abs(q).max() > 0)
    one, batch = _held(q)
    eps = np.finfo(dtype).eps
    for name, atol in (("as_matrix", 4 * eps), ("as_mrp", 4 * eps)):
        got, want = getattr(one, name)(), getattr(batch, name)()[0]
        assert got.dtype == dtype
        np.testing.assert_allclose(got, want, rtol=0, atol=atol, err_msg=name)
    angle = one.magnitude()
    assert type(angle) is dtype
    np.testing.assert_allclose(angle, batch.magnitude()[0], rtol=0, atol=16 * eps)
    for degrees, scale in ((False, 1.0), (True, 180 / np.pi)):
        got, want = one.as_rotvec(degrees), batch.as_rotvec(degrees)[0]
        assert got.dtype == dtype
        if np.pi - angle < 1e-3 and np.dot(got, want) < 0:
            # a half turn less than a few ulp: float32 blocks rescaled into range may lose
            # a w below 2**-149 (then w = 0 and the sign is the canonical one's)
            want = -want
        np.testing.assert_allclose(got, want, rtol=0, atol=16 * eps * scale, err_msg=f"as_rotvec {degrees}")
    for canonical in (False, True):
        for scalar_first in (False, True):
            got = one.as_quat(canonical, scalar_first=scalar_first)
            assert got.dtype == dtype and not np.shares_memory(got, q)
            np.testing.assert_array_equal(got, batch.as_quat(canonical, scalar_first=scalar_first)[0])
    for n in (0.3, -2, 7.5):
        got = (one ** n).as_quat(scalar_first=True)
        assert got.dtype == dtype
        assert_same_rotation(got, (batch ** n).as_quat(scalar_first=True)[0], 64 * eps)
    # approx_equal with a rotation `other` components away, its tolerance clear of the angle between them
    p = np.roll(q, other)
    unit = q.astype(np.float64) / np.abs(q).max()
    unit /= np.linalg.norm(unit)
    gap = 2 * np.arccos(min(1.0, abs(np.dot(unit, np.roll(unit, other)))))   # the angle between p and q
    atol = 0.5
    assume(abs(gap - atol) > 1e-3)
    got = one.approx_equal(_held(p)[0], atol=atol)
    assert got.shape == (1,) and got.dtype == bool
    assert got[0] == (gap < atol)
    if abs(exponent) < (60 if f32 else 500):   # the batch path's product of the two, unscaled, stays normal
        assert batch.approx_equal(_held(p)[1], atol=atol)[0] == got[0]


@pytest.mark.parametrize("seq", EULER_SEQS)
def test_single_rotation_euler_angles_at_edges_equal_the_batch_of_one(dtype, seq):
    """Identity, half turns, gimbal lock (exactly and nearly), degrees: the single-rotation
    Euler path gives the block path's angles, dtype and gimbal-lock warning."""
    sym = seq[0].lower() == seq[2].lower()
    locks = (0.0, np.pi) if sym else (-np.pi / 2, np.pi / 2)
    angles = [[0.3, mid + d, -1.1] for mid in locks for d in (0.0, 1e-9, -1e-9, 1e-6, -1e-6)]
    angles += [[np.pi, 0.5, -np.pi], [2.0, 1.0, 3.0]]
    q = np.concatenate([Rotation.from_euler(seq, angles).as_quat(scalar_first=True),
                        np.eye(4), [[0.0, 1.0, 1.0, 0.0], [0.0, 0.0, -1.0, 1.0]]]).astype(dtype)
    t = 8 * np.finfo(dtype).eps
    for row in q:
        one, batch = _held(row)
        for degrees in (False, True):
            with warnings.catch_warnings(record=True) as caught_one:
                warnings.simplefilter("always")
                got = one.as_euler(seq, degrees=degrees)
            with warnings.catch_warnings(record=True) as caught_batch:
                warnings.simplefilter("always")
                want = batch.as_euler(seq, degrees=degrees)[0]
            assert got.dtype == dtype
            assert [str(w.message) for w in caught_one] == [str(w.message) for w in caught_batch]
            scale = 180 / np.pi if degrees else 1.0
            # modulo 2π: at a half turn float32 blocks may give π where float64 gives -π
            assert angle_diff(got / scale, want / scale).max() <= 2 * t * np.pi, (row, degrees, got, want)
            assert np.abs(got).max() <= np.pi * scale * (1 + t)


def test_gimbal_warning_of_a_single_quatarray_points_at_the_caller():
    with pytest.warns(UserWarning, match="Gimbal lock detected") as caught:
        QuatArray([1.0, 0.0, 0.0, 0.0]).as_euler("zxz")
    assert caught[0].filename == __file__


@pytest.mark.parametrize("seq", ["x", "Z", "yx", "YX", "zy", "XZ", "xyz", "ZXZ"])
def test_from_euler_float32_batches_match_scipy(rng, seq):
    # a NumPy 2.4 bug (in-place negative of float32 rows 16 bytes apart) once broke 2-axis sequences
    angles = rng.uniform(-np.pi, np.pi, (37, len(seq))).astype(np.float32)
    got = Rotation.from_euler(seq, angles)
    assert got.dtype == np.float32
    want = SR.from_euler(seq, angles.astype(np.float64)).as_quat(scalar_first=True)
    assert_same_rotation(got.as_quat(scalar_first=True), want, 1e-6)


def test_tuple_index_of_an_nd_batch_indexes_its_axes_as_numpy_does():
    """Extension (README, Migrating): r[i, j] on a (2, 3) batch is rotation (i, j), as in
    NumPy; scipy 1.17 reads the tuple as an index array along the first axis."""
    from scipy.spatial.transform import Rotation as ScipyRotation

    r = Rotation.random(shape=(2, 3), rng=5)
    s = ScipyRotation.from_quat(r.as_quat())
    assert r[1, 2].single and r[1, 2].approx_equal(r[1][2])
    assert np.allclose(r[1, 2].as_quat(), s[1].as_quat()[2], rtol=0, atol=1e-15)
    assert r[:, 1].shape == (2,) and np.allclose(r[:, 1].as_quat(), s.as_quat()[:, 1], rtol=0, atol=1e-15)
    assert s[1, 0].shape == (2, 3)   # scipy's reading, which we do not copy


def test_as_matrix_of_rotations_known_unit_and_held_as_given(rng, dtype):
    """Rotations made by normalising paths skip the squared norms in `as_matrix` (a few ulp
    from the general path); rotations holding quaternions as given - and any whose storage
    was handed out writable or received such quaternions - still get q/|q|'s matrix."""
    q = random_quats(rng, (50,), dtype)
    eps = np.finfo(dtype).eps
    general = as_matrix(q)
    made = Rotation.from_quat(q, scalar_first=True)
    np.testing.assert_allclose(made.as_matrix(), general, rtol=0, atol=8 * eps)
    for r in (made.inv(), made[3:9], Rotation.concatenate([made, made[:2]]), next(iter(made))):
        np.testing.assert_allclose(r.as_matrix(), as_matrix(r.as_quat(scalar_first=True)), rtol=0, atol=8 * eps)
    scaled = (3 * q).view(QuatArray)
    for held in (Rotation.from_quatarray(scaled), Rotation(3 * q, normalize=False, scalar_first=True)):
        np.testing.assert_allclose(held.as_matrix(), general, rtol=0, atol=8 * eps)
        np.testing.assert_allclose(held.inv().as_matrix(), np.swapaxes(general, -1, -2), rtol=0, atol=8 * eps)
        np.testing.assert_allclose(held[2:5].as_matrix(), general[2:5], rtol=0, atol=8 * eps)
    exposed = Rotation.from_quat(q, scalar_first=True)
    exposed.as_quatarray()[...] *= 5          # written through the zero-copy view
    np.testing.assert_allclose(exposed.as_matrix(), general, rtol=0, atol=8 * eps)
    target = Rotation.from_quat(q, scalar_first=True)
    target[:10] = Rotation.from_quatarray((7 * q[:10]).view(QuatArray))
    np.testing.assert_allclose(target.as_matrix(), general, rtol=0, atol=8 * eps)


@pytest.mark.parametrize("make", [lambda q: Rotation.from_quat(q), lambda q: Rotation.from_quat(q, scalar_first=True),
                                  lambda q: Rotation(q, normalize=False), lambda q: Rotation.from_quat(q[::2])],
                         ids=["from_quat", "scalar_first", "normalize=False", "strided input"])
def test_stored_quaternions_are_c_contiguous(make, rng):
    """Every kernel's fast path wants C order: a reordered copy made by fancy indexing on
    the last axis is not C-contiguous, and made every later call several times slower."""
    q = random_quats(rng, (10, 4))
    r = make(q)
    assert r.as_quatarray().flags.c_contiguous
    np.testing.assert_array_equal(r.as_quat(), r.as_quat(scalar_first=True)[..., [1, 2, 3, 0]])
