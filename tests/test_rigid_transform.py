"""RigidTransform against scipy 1.17's, in float64 and float32."""

import numpy as np
import pytest

from quatarray import RigidTransform

st = pytest.importorskip("scipy.spatial.transform")


def _pair(dtype, n=7, seed=0):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    t = rng.normal(size=(n, 3))
    ours = RigidTransform.from_components(t.astype(dtype), __import__("quatarray").Rotation.from_quat(q.astype(dtype)))
    ref = st.RigidTransform.from_components(t, st.Rotation.from_quat(q))
    return ours, ref, rng


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_matches_scipy(dtype):
    ours, ref, rng = _pair(dtype)
    tol = 50 * np.finfo(dtype).eps
    v = rng.normal(size=(7, 3))
    np.testing.assert_allclose(ours.as_matrix(), ref.as_matrix(), atol=tol)
    np.testing.assert_allclose(ours.apply(v.astype(dtype)), ref.apply(v), atol=tol * 10)
    np.testing.assert_allclose(ours.apply(v.astype(dtype), inverse=True), ref.apply(v, inverse=True), atol=tol * 10)
    np.testing.assert_allclose(ours.inv().as_matrix(), ref.inv().as_matrix(), atol=tol * 10)
    np.testing.assert_allclose((ours * ours[::-1]).as_matrix(), (ref * ref[::-1]).as_matrix(), atol=tol * 10)
    np.testing.assert_allclose(RigidTransform.from_matrix(ref.as_matrix()).as_matrix(), ref.as_matrix(), atol=1e-12)
    dq = ref.as_dual_quat()
    np.testing.assert_allclose(ours.as_dual_quat(), dq, atol=tol * 10)   # scipy's sign too
    np.testing.assert_allclose(RigidTransform.from_dual_quat(dq).as_matrix(), ref.as_matrix(), atol=1e-12)
    assert ours.as_matrix().dtype == dtype


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_single_transform_matrix_equals_the_batch_row(dtype):
    """The Python-float matrix of one transform gives the block path's numbers (float64:
    the same bits), the translation exactly, and the last row [0, 0, 0, 1]."""
    from quatarray import Rotation
    rng = np.random.default_rng(3)
    q = rng.normal(size=(20, 4))
    q[:5] = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, -1], [0, 1, 1, 0], [-1, 0, 0, 0]]   # identity, half turns
    t = rng.normal(size=(20, 3)) * np.logspace(-30, 30, 20)[:, None]
    many = RigidTransform.from_components(t.astype(dtype), Rotation.from_quat(q.astype(dtype), scalar_first=True))
    whole = many.as_matrix()
    for i, one in enumerate(many):
        m = one.as_matrix()
        assert m.shape == (4, 4) and m.dtype == dtype and one.single
        if dtype == np.float64:
            np.testing.assert_array_equal(m, whole[i])
        else:   # the single path computes in float64, then rounds
            np.testing.assert_allclose(m[:3, :3], whole[i, :3, :3], rtol=0, atol=4 * np.finfo(dtype).eps)
        np.testing.assert_array_equal(m[:3, 3], t[i].astype(dtype))
        np.testing.assert_array_equal(m[3], [0, 0, 0, 1])
    m = one.as_matrix()
    m[0, 0] = 7.0
    assert one.as_matrix()[0, 0] != 7.0   # a new array each time (the kept matrix is not handed out)
    np.testing.assert_array_equal(one.as_matrix(), whole[-1] if dtype == np.float64 else one.as_matrix())
    m = one.as_matrix()   # a new transform has its own matrix
    np.testing.assert_allclose((one * one).as_matrix(), m @ m, rtol=0, atol=1e3 * np.abs(t[-1]).max() * np.finfo(dtype).eps)


def test_container_and_errors():
    ours, ref, _ = _pair(np.float64)
    assert len(ours) == len(ref) and ours.shape == (7,) and not ours.single
    assert ours[2].single and ref[2].single
    np.testing.assert_allclose(ours[2].translation, ref[2].translation)
    with pytest.raises(TypeError):
        len(ours[0])
    with pytest.raises(ValueError, match="matrix"):
        RigidTransform.from_matrix(np.ones((4, 4)))
    np.testing.assert_allclose(RigidTransform.identity(3).as_matrix(), st.RigidTransform.identity(3).as_matrix())


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_exp_coords_pow_mean_concatenate(dtype):
    ours, ref, _ = _pair(dtype, seed=1)
    tol = 100 * np.finfo(dtype).eps
    np.testing.assert_allclose(ours.as_exp_coords(), ref.as_exp_coords(), atol=tol, rtol=tol)
    e = ref.as_exp_coords()
    np.testing.assert_allclose(RigidTransform.from_exp_coords(e.astype(dtype)).as_matrix(),
                               st.RigidTransform.from_exp_coords(e).as_matrix(), atol=tol)
    np.testing.assert_allclose((ours ** 2.5).as_matrix(), (ref ** 2.5).as_matrix(), atol=tol * 10)
    np.testing.assert_allclose(ours.mean().as_matrix(), ref.mean().as_matrix(), atol=tol * 10)
    both = RigidTransform.concatenate([ours, ours[0]])
    assert len(both) == 8
    np.testing.assert_allclose(both[7].as_matrix(), ours[0].as_matrix())
    ours[1] = ours[0]
    np.testing.assert_array_equal(ours[1].as_matrix(), ours[0].as_matrix())


def test_from_dual_quat_zero_real_part_is_identity_like_scipy():
    dq = np.zeros((2, 8))
    np.testing.assert_array_equal(RigidTransform.from_dual_quat(dq).as_matrix(),
                                  st.RigidTransform.from_dual_quat(dq).as_matrix())


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("shapes", [((600,), (600,)), ((2, 300), (2, 300)), ((), (700,)), ((700,), ()),
                                    ((1, 400), (3, 1))], ids=str)
def test_apply_and_compose_long_and_broadcast_match_scipy(dtype, shapes):
    """The fused long-array path and the broadcasting paths of apply and *."""
    tf_shape, v_shape = shapes
    rng = np.random.default_rng(3)
    q = rng.normal(size=tf_shape + (4,))
    t = rng.normal(size=tf_shape + (3,))
    v = rng.normal(size=v_shape + (3,))
    Rot = __import__("quatarray").Rotation
    ours = RigidTransform.from_components(t.astype(dtype), Rot.from_quat(q.astype(dtype)))
    ref = st.RigidTransform.from_components(t, st.Rotation.from_quat(q))
    tol = 100 * np.finfo(dtype).eps * 4
    for inverse in (False, True):
        got = ours.apply(v.astype(dtype), inverse=inverse)
        assert got.dtype == dtype
        np.testing.assert_allclose(got, ref.apply(v, inverse=inverse), atol=tol)
    np.testing.assert_allclose((ours * ours.inv()).as_matrix(), (ref * ref.inv()).as_matrix(), atol=tol)
    np.testing.assert_allclose((ours * ours).as_matrix(), (ref * ref).as_matrix(), atol=tol)


def test_normalize_false_keeps_the_matrix_and_copy_false_shares_it():
    m = np.eye(4)
    m[:3, 3] = [1, 2, 3]
    tf = RigidTransform(m, normalize=False, copy=False)
    m[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]       # 90° about z, written after construction
    np.testing.assert_array_equal(tf.as_matrix(), m)
    np.testing.assert_allclose(tf.apply([1.0, 0, 0]), [1, 3, 3], atol=1e-15)
    np.testing.assert_allclose(tf.rotation.as_matrix(), m[:3, :3], atol=1e-15)
    kept = RigidTransform(m, normalize=False)           # copy=True: later writes are not seen
    m[:3, 3] = 0
    np.testing.assert_array_equal(kept.translation, [1, 2, 3])
    for view in (m.view(type("Sub", (np.ndarray,), {})), m[:, :]):   # a subclass, a view: copied too
        kept = RigidTransform(view, normalize=False)
        view[0, 3] = 7
        np.testing.assert_array_equal(kept.translation, [0, 0, 0])
        m[0, 3] = 0
    many = RigidTransform(np.stack([m, m]), normalize=False, copy=False)
    many[1] = RigidTransform.from_translation([5.0, 0, 0])
    np.testing.assert_array_equal(many.as_matrix()[1, :3, 3], [5, 0, 0])


def test_normalize_false_applies_its_matrix_as_given():
    """A kept matrix whose block is not a rotation acts as that matrix (scipy's ``apply``), in
    float64 and float32, each row as alone, inverse as scipy's ``Rᵀ (v - t)``."""
    rng = np.random.default_rng(4)
    m = np.tile(np.eye(4), (6, 1, 1))
    m[:, :3, :3] += rng.normal(scale=0.05, size=(6, 3, 3))
    m[:, :3, 3] = rng.normal(size=(6, 3))
    v = rng.normal(size=(6, 3))
    for dtype in (np.float64, np.float32):
        tf = RigidTransform(m.astype(dtype), normalize=False)
        got = tf.apply(v.astype(dtype))
        assert got.dtype == dtype
        tol = 8 * np.finfo(dtype).eps
        np.testing.assert_allclose(got, np.einsum("nij,nj->ni", m[:, :3, :3], v) + m[:, :3, 3], atol=tol)
        np.testing.assert_allclose(got, st.RigidTransform(m, normalize=False).apply(v), atol=tol)
        np.testing.assert_allclose(tf.apply(v.astype(dtype), inverse=True),
                                   st.RigidTransform(m, normalize=False).apply(v, inverse=True), atol=10 * tol)
        for i in range(6):
            np.testing.assert_array_equal(RigidTransform(m[i].astype(dtype), normalize=False).apply(v[i].astype(dtype)),
                                          got[i])


def test_normalize_false_operations_as_scipy():
    """A kept matrix whose block is not a rotation goes through scipy's operations as scipy
    takes it: `inv`, ``** -1``, ``** 1``, indexing and `concatenate` keep raw matrices, a
    product is the normalised product of the matrices, `rotation` is the nearest rotation,
    and exp coordinates, dual quaternions, means and other powers use the quaternion derived
    from the block.  A pickled one comes back as it was (scipy's comes back normalised)."""
    import pickle
    rng = np.random.default_rng(11)
    m = np.tile(np.eye(4), (3, 1, 1))
    m[:, :3, :3] = rng.normal(size=(3, 3, 3))
    m[:, :3, 0] *= np.sign(np.linalg.det(m[:, :3, :3]))[:, None]   # proper frames, far from rotations
    m[:, :3, 3] = rng.normal(size=(3, 3))
    other = st.RigidTransform.from_exp_coords(rng.normal(size=(3, 6))).as_matrix()
    for batch in (m, m[0]):
        ours, ref = RigidTransform(batch, normalize=False), st.RigidTransform(batch, normalize=False)
        ours_other = RigidTransform(other[: len(batch)] if batch.ndim == 3 else other[0])
        ref_other = st.RigidTransform(other[: len(batch)] if batch.ndim == 3 else other[0])
        pairs = [(lambda x, y: x.inv().as_matrix()), (lambda x, y: (x ** -1).apply([1.0, 2, 3])),
                 (lambda x, y: (x ** 1).as_matrix()), (lambda x, y: (x * y).as_matrix()),
                 (lambda x, y: (y * x).as_matrix()), (lambda x, y: (x * x.inv()).as_matrix()),
                 (lambda x, y: (x ** 0.5).as_matrix()), (lambda x, y: (x ** 2).as_matrix()),
                 (lambda x, y: x.rotation.as_quat()), (lambda x, y: x.as_exp_coords()),
                 (lambda x, y: x.as_dual_quat()), (lambda x, y: type(x).concatenate([x, y]).inv().as_matrix())]
        if batch.ndim == 3:
            pairs += [(lambda x, y: x.mean().as_matrix()), (lambda x, y: x[1].inv().as_matrix()),
                      (lambda x, y: x[[2, 0]].inv().as_matrix()), (lambda x, y: x[1:].as_matrix())]
        for f in pairs:
            np.testing.assert_allclose(f(ours, ours_other), f(ref, ref_other), atol=1e-12)
        np.testing.assert_array_equal(ours.inv().inv().as_matrix()[..., :3, :3], batch[..., :3, :3])
        np.testing.assert_array_equal(pickle.loads(pickle.dumps(ours)).as_matrix(), batch)


def test_pickle_iteration_and_inputs_unchanged():
    import pickle
    ours, ref, rng = _pair(np.float64)
    back = pickle.loads(pickle.dumps(ours))
    np.testing.assert_array_equal(back.as_matrix(), ours.as_matrix())
    assert back.single == ours.single
    items = list(ours)
    assert len(items) == 7 and all(x.single for x in items)
    np.testing.assert_allclose(items[3].as_matrix(), ref[3].as_matrix(), atol=1e-15)
    v = rng.normal(size=(7, 3))
    v.flags.writeable = False
    before = v.copy()
    ours.apply(v)
    ours.apply(v, inverse=True)
    np.testing.assert_array_equal(v, before)
    with pytest.raises(TypeError, match="not iterable"):
        iter(ours[0])


@pytest.mark.parametrize("shape", [(10,), (10, 2), (10, 3, 3)], ids=str)
def test_powers_equal_repeated_composition(shape):
    """scipy's test_pow without its private-attribute check: integer powers are repeated
    products, fractional ones square to the right power, a single transform stays single."""
    rng = np.random.default_rng(100)
    Rot = __import__("quatarray").Rotation
    p = RigidTransform.from_components(rng.normal(size=shape + (3,)), Rot.from_quat(rng.normal(size=shape + (4,))))
    for n in (-5, -2, -1, 0, 1, 2, 5):
        r = RigidTransform.identity(shape=shape)
        for _ in range(abs(n)):
            r = r * (p if n > 0 else p.inv())
        np.testing.assert_allclose((p ** n).as_matrix(), r.as_matrix(), atol=1e-12)
    for f, whole in ((0.5, 1), (-0.5, -1), (1.5, 3), (-1.5, -3)):
        half = p ** f
        np.testing.assert_allclose((half * half).as_matrix(), (p ** whole).as_matrix(), atol=1e-12)
    assert (RigidTransform.identity() ** 3).as_matrix().shape == (4, 4)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("n", [1, 10, 100, 2000])
def test_known_unit_quaternions_give_the_checked_paths_bits(dtype, n):
    # transforms from normalising constructors skip |q|²'s range checks when rotating; the
    # same quaternions without that knowledge take the checked path: the same bits, also
    # for vectors near the float maximum and non-finite ones, and no new warnings
    import warnings
    from quatarray import Rotation
    rng = np.random.default_rng(n)
    tf = RigidTransform.from_components(rng.normal(size=(n, 3)).astype(dtype),
                                        Rotation.from_quat(rng.normal(size=(n, 4)).astype(dtype)))
    assert tf._unit and (tf * tf).inv()._unit
    plain = RigidTransform._from_parts(tf._quat.copy(), tf._translation.copy(), False)
    assert not plain._unit
    v = rng.normal(size=(n, 3)).astype(dtype)
    v[0, 0] = np.finfo(dtype).max / 1.5
    if n > 1:
        v[1, 1] = np.inf
    results, caught = [], []
    for r in (tf, plain):
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            results.append([r.apply(v), r.apply(v, inverse=True), r.inv().as_matrix(), (r * r[::-1]).as_matrix()])
        caught.append(len(w))
    for a, b in zip(*results):
        np.testing.assert_array_equal(a.view(np.uint8), b.view(np.uint8))
    assert caught[0] <= caught[1]


def test_rotations_not_known_unit_are_not_taken_as_unit():
    from quatarray import Rotation
    q = np.array([[0.0, 0.0, 0.0, 2.0], [1.0, 1.0, 0.0, 0.0]])
    tf = RigidTransform.from_rotation(Rotation(q, normalize=False))
    assert not tf._unit
    ref = st.RigidTransform.from_rotation(st.Rotation.from_quat(q))
    v = np.array([[1.0, 2.0, 3.0], [-1.0, 0.5, 2.0]])
    np.testing.assert_allclose(tf.apply(v), ref.apply(v), atol=1e-14)
    assert RigidTransform.from_rotation(Rotation.from_quat(q))._unit


@pytest.mark.parametrize("n", [1, 5, 5000])   # one, a few, the block path
@pytest.mark.parametrize("dtypes", [("float32", "float64", "float32"), ("float64", "float32", "float64"),
                                    ("float32", "float32", "float64")])
def test_raw_apply_promotes_mixed_dtypes(n, dtypes):
    """`_motion.apply` (q, t, v of different dtypes): the promoted dtype, and the bits of rotating
    in the vectors' own promotion then adding t (the translation is added per block only when
    the three share one dtype)."""
    from quatarray import _kernels, _motion
    rng = np.random.default_rng(16)
    q = rng.standard_normal((n, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    q, t, v = q.astype(dtypes[0]), rng.standard_normal((n, 3)).astype(dtypes[1]), \
        rng.standard_normal((n, 3)).astype(dtypes[2])
    got = _motion.apply(q, t, v, unit=True)
    assert got.dtype == np.float64
    want = _kernels.rotate(q, v, unit=True).astype(np.float64) + t
    np.testing.assert_array_equal(got, want, strict=True)
