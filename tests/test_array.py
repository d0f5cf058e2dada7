"""The QuatArray contract: construction, shape, indexing policy, operators,
ufunc and function registries, copying, pickling and repr."""

import copy
import inspect
import pickle

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from quatarray import QuatArray, _array, _kernels as K
from quatarray.testing import assert_allclose, assert_array_equal

from .conftest import hamilton_reference, random_quats, tol


def qa(rng, shape=(), dtype=np.float64, unit=True):
    return QuatArray(random_quats(rng, shape, dtype, unit))


# --- construction ---------------------------------------------------------------------

@pytest.mark.parametrize("dt", [np.float32, np.float64])
def test_float_dtypes_kept(dt):
    assert QuatArray(np.zeros((2, 4), dt)).dtype == dt


@pytest.mark.parametrize("data", [np.zeros((2, 4), int), np.ones(4, bool), [[1, 0, 0, 0]], np.zeros(4, np.float16)])
def test_int_bool_become_float64(data):
    assert QuatArray(data).dtype == np.float64


@pytest.mark.parametrize("data,dtype_name", [(np.zeros(4, complex), "dtype complex128"),
                                             (np.array([None] * 4), "an object array holding NoneType"),
                                             (np.array([1, 0, 0, 1j], object), "an object array holding complex"),
                                             (np.array(["a"] * 4), "dtype <U1")])
def test_non_real_input_is_a_type_error(data, dtype_name):
    with pytest.raises(TypeError, match=f"expected quat of real numbers.* got {dtype_name}"):
        QuatArray(data)


def test_object_arrays_of_real_numbers_become_float64():
    from decimal import Decimal
    from fractions import Fraction
    q = QuatArray(np.array([Decimal("0.5"), Fraction(1, 2), 0, np.float32(0.5)], object))
    assert q.dtype == np.float64
    np.testing.assert_array_equal(q.ndarray, [0.5, 0.5, 0, 0.5])


@pytest.mark.parametrize("shape", [(5, 3), (3,), (4, 5)])
def test_last_axis_must_be_four(shape):
    with pytest.raises(ValueError, match=rf"expected quat of shape \(\.\.\., 4\), got \({shape[0]}, ?{shape[1] if len(shape) > 1 else ''}\)"):
        QuatArray(np.zeros(shape))


def test_scalar_input_is_a_value_error():
    with pytest.raises(ValueError, match=r"expected quat of shape \(\.\.\., 4\), got \(\)"):
        QuatArray(1.0)


def test_not_normalised_and_input_copied():
    data = np.array([[2.0, 0, 0, 0]])
    q = QuatArray(data)
    assert_array_equal(q, data)  # general quaternions allowed
    q *= 3
    assert data[0, 0] == 2.0  # the input is never modified


def test_explicit_dtype():
    assert QuatArray([1, 0, 0, 0], dtype=np.float32).dtype == np.float32
    with pytest.raises(TypeError, match="expected dtype float32 or float64 for quat, got int64"):
        QuatArray([1, 0, 0, 0], dtype=np.int64)


# --- shape, len, iteration ---------------------------------------------------------------

def test_batch_shape_len_iter(rng, batch_shape, dtype):
    q = qa(rng, batch_shape, dtype)
    assert q.batch_shape == q.shape[:-1] == batch_shape
    if not batch_shape:  # one quaternion: an ordinary 1-D array of its 4 components
        assert len(q) == 4
        assert_array_equal(list(q), q.ndarray)
        return
    assert len(q) == batch_shape[0]
    items = list(q)
    assert len(items) == batch_shape[0]
    for i, item in enumerate(items):
        assert type(item) is QuatArray and item.batch_shape == batch_shape[1:] and item.dtype == dtype
        assert_array_equal(item, q.ndarray[i])


# --- indexing policy ------------------------------------------------------------------------

Q34 = QuatArray(np.arange(48.0).reshape(3, 4, 4))


@pytest.mark.parametrize("key", [0, slice(1, 3), np.array([True, False, True]), [0, 2], (Ellipsis, slice(None)),
                                 (Ellipsis, slice(0, 4)), (0, 1), None, (slice(None), None), ()],
                         ids=["int", "slice", "mask", "list", "ellipsis-colon", "ellipsis-0:4", "two-ints", "newaxis",
                              "newaxis-mid", "empty"])
def test_batch_index_returns_quatarray(key):
    res = Q34[key]
    assert type(res) is QuatArray
    assert_array_equal(res, Q34.ndarray[key])


@pytest.mark.parametrize("key", [(Ellipsis, 0), (slice(None), slice(None), slice(1, None)), (Ellipsis, [0, 2]),
                                 (Ellipsis, None), (0, 1, 2), (Ellipsis, slice(None, None, -1)),
                                 np.ones((3, 4, 4), bool), (slice(None), slice(None), slice(None), None)],
                         ids=["ellipsis-int", "slice-last", "ellipsis-list", "ellipsis-newaxis", "three-ints",
                              "reversed", "full-mask", "trailing-newaxis"])
def test_component_index_returns_plain(key):
    res = Q34[key]
    assert type(res) is not QuatArray
    assert_array_equal(res, Q34.ndarray[key])


def test_index_decided_from_index_not_shape():
    eye = QuatArray(np.eye(4))
    col = eye[:, 0]
    assert type(col) is np.ndarray and col.shape == (4,)  # shape (4,) but not a quaternion
    assert type(eye[0]) is QuatArray


def test_array_finalize_never_raises():
    # a raw ndarray-level index produces a QuatArray view of any shape; finalize must accept it
    v = np.ndarray.__getitem__(Q34, (Ellipsis, 0))
    assert v.shape == (3, 4)
    assert Q34.view(QuatArray).shape == Q34.shape


@pytest.mark.parametrize("op,keeps", [
    (lambda q: q.reshape(-1, 4), True), (lambda q: q.reshape(2, 6, 4), True), (lambda q: q.reshape(12, 4), True),
    (lambda q: q.reshape(-1), False), (lambda q: q.reshape(6, 8), False), (lambda q: q.ravel(), False),
    (lambda q: q.transpose(), False), (lambda q: q.T, False), (lambda q: q.transpose(1, 0, 2), True),
    (lambda q: q.swapaxes(0, -1), False), (lambda q: q.swapaxes(0, 1), True), (lambda q: np.moveaxis(q, -1, 0), False),
    (lambda q: np.moveaxis(q, 0, 1), True), (lambda q: np.reshape(q, (-1, 4)), True), (lambda q: np.ravel(q), False),
    (lambda q: np.transpose(q), False), (lambda q: np.transpose(q, (1, 0, 2)), True), (lambda q: np.swapaxes(q, 1, 2), False),
    (lambda q: q.reshape(-1, 4, order="F"), False), (lambda q: q.flatten(), False),
])
def test_layout_changes(op, keeps):
    res = op(Q34)
    assert (type(res) is QuatArray) == keeps
    assert_array_equal(res, op(Q34.ndarray))


def test_single_quaternion_layout_keeps_class():
    q = QuatArray([1, 2, 3, 4])
    assert type(q.T) is QuatArray and type(q.ravel()) is QuatArray


# --- components ------------------------------------------------------------------------------

def test_components_are_plain_views(rng, batch_shape):
    q = qa(rng, batch_shape)
    raw = q.ndarray
    assert type(raw) is np.ndarray and np.shares_memory(raw, q)
    for i, name in enumerate("wxyz"):
        comp = getattr(q, name)
        assert type(comp) is np.ndarray and comp.shape == batch_shape and np.shares_memory(comp, q)
        assert_array_equal(comp, raw[..., i])
    assert q.vec.shape == batch_shape + (3,) and type(q.vec) is np.ndarray
    assert_array_equal(q.vec, raw[..., 1:])


# --- operators -----------------------------------------------------------------------------------

BROADCAST_PAIRS = [((), ()), ((5,), ()), ((3, 1), (4,)), ((2, 3, 2), (3, 1))]


@pytest.mark.parametrize("sp,sq", BROADCAST_PAIRS)
def test_product_operator(rng, dtype, sp, sq):
    p, q = qa(rng, sp, dtype, False), qa(rng, sq, dtype, False)
    r = p * q
    assert type(r) is QuatArray and r.dtype == dtype and r.batch_shape == np.broadcast_shapes(sp, sq)
    assert_allclose(r, hamilton_reference(p.ndarray, q.ndarray), atol=tol(dtype, 20) * 10)
    assert_array_equal(np.multiply(p, q), r)


def test_scalar_and_batch_array_scale_per_quaternion(rng, dtype):
    q = qa(rng, (3, 2), dtype)
    for s in (2, 2.5, np.float32(2)):
        for r in (q * s, s * q):
            assert type(r) is QuatArray and r.dtype == dtype
            assert_allclose(r, q.ndarray * s, rtol=tol(dtype))
    s = np.array([2.0, -1.0])  # batch-shaped (broadcasts against (3, 2))
    assert_allclose(q * s, q.ndarray * s[:, None], rtol=tol(dtype))
    assert_allclose(q / s, q.ndarray / s[:, None], rtol=tol(dtype))


def test_plain_quaternion_shaped_array_is_not_a_quaternion(rng):
    q = qa(rng, (3,))
    plain = random_quats(rng, (3,))
    with pytest.raises(ValueError):  # taken as a (3, 4) array of scalars: does not broadcast with batch (3,)
        q * plain


def test_division(rng, dtype):
    p, q = qa(rng, (4,), dtype, False), qa(rng, (4,), dtype, False)
    assert_allclose(p / q, p * q.inverse(), atol=tol(dtype, 100))
    assert_allclose((p / q) * q, p, atol=tol(dtype, 100) * 10)
    assert_allclose(1 / q, q.inverse(), atol=tol(dtype))
    assert_allclose(q / 2, q.ndarray / 2, rtol=tol(dtype))


def test_add_subtract_negate(rng, dtype):
    p, q = qa(rng, (3,), dtype), qa(rng, (3,), dtype)
    assert_array_equal(p + q, p.ndarray + q.ndarray)
    assert_array_equal(p - q, p.ndarray - q.ndarray)
    assert_array_equal(-q, -q.ndarray)
    assert_array_equal(+q, q.ndarray)
    assert type(p + q) is type(-q) is QuatArray
    # a real number is the quaternion (s, 0, 0, 0)
    assert_array_equal((q + 1).ndarray, q.ndarray + np.array([1, 0, 0, 0], dtype))
    assert_array_equal((1 - q).ndarray, np.array([1, 0, 0, 0], dtype) - q.ndarray)


def test_power_operator(rng, dtype):
    q = qa(rng, (3, 2), dtype)
    assert_allclose(q ** 0.3, K.exp(0.3 * K.log(q.ndarray)), atol=tol(dtype))
    t = np.array([0.5, 2.0])
    assert_allclose(q ** t, K.exp(t[:, None] * K.log(q.ndarray)), atol=tol(dtype))
    assert_allclose(q ** 2, q * q, atol=tol(dtype))
    assert (q ** 0.5).dtype == dtype
    assert_allclose(np.float_power(q, 0.5), q ** 0.5, atol=tol(dtype))
    assert np.float_power(q, 0.5).dtype == np.float64
    with pytest.raises(TypeError, match="expected a QuatArray raised to a real exponent"):
        q ** q
    # the method: the same values, and its argument named
    np.testing.assert_array_equal(q.power(t).ndarray, (q ** t).ndarray)
    with pytest.raises(TypeError, match="expected a real exponent t .* got a QuatArray"):
        q.power(q)
    with pytest.raises(ValueError, match=r"exponent t broadcastable to the batch shape \(3, 2\), got shape \(3,\)"):
        q.power(np.ones(3))


def test_conjugate_abs_equality(rng):
    q = qa(rng, (3,), unit=False)
    assert_array_equal(~q, q.ndarray * [1, -1, -1, -1])
    a = abs(q)
    assert type(a) is np.ndarray and a.shape == (3,)
    assert_allclose(a, np.linalg.norm(q.ndarray, axis=-1), rtol=1e-15)
    p = q.copy()
    p.ndarray[1, 2] += 1
    assert_array_equal(q == p, [True, False, True])
    assert_array_equal(q != p, [False, True, False])
    assert type(q == p) is np.ndarray
    assert_array_equal(QuatArray([[2, 0, 0, 0], [2, 1, 0, 0]]) == 2, [True, False])


def test_in_place_forms_match_out_of_place(rng, dtype):
    p, q = qa(rng, (5, 3), dtype, False), qa(rng, (3,), dtype, False)
    for op, iop in [(lambda a, b: a * b, "__imul__"), (lambda a, b: a / b, "__itruediv__")]:
        a = p.copy()
        res = getattr(a, iop)(q)
        assert res is a
        assert_array_equal(a, op(p, q))
    a = p.copy()
    a *= 2.0
    assert_array_equal(a, p * 2.0)


# --- ufuncs -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("ufunc,expected", [
    (np.exp, lambda q: K.exp(q)), (np.log, lambda q: K.log(q)), (np.sqrt, lambda q: K.power(q, 0.5)),
    (np.conjugate, lambda q: K.conjugate(q)), (np.negative, lambda q: -q), (np.positive, lambda q: q)])
def test_unary_ufuncs_quaternion_valued(rng, ufunc, expected):
    q = qa(rng, (4,), unit=False)
    res = ufunc(q)
    assert type(res) is QuatArray
    assert_allclose(res, expected(q.ndarray), rtol=1e-14)
    out = QuatArray(np.zeros((4, 4)))
    assert ufunc(q, out=out) is out
    assert_array_equal(out, res)


def test_sqrt_squares_back(rng):
    q = qa(rng, (6,), unit=False)
    assert_allclose(np.sqrt(q) * np.sqrt(q), q, atol=1e-14)


@pytest.mark.parametrize("ufunc", [np.absolute, np.isnan, np.isfinite])
def test_unary_ufuncs_per_quaternion(ufunc):
    q = QuatArray([[1, 0, 0, 0], [np.nan, 0, 0, 0], [0, np.inf, 0, 0]])
    if ufunc is np.absolute:   # non-finite input is refused (the API's policy)
        with pytest.raises(ValueError, match=r"expected finite values in the argument of absolute, got nan or inf at "
                                             r"index \(1, 0\)"):
            ufunc(q)
        q = QuatArray([[1, 0, 0, 0], [0, 3, 0, 4], [0, 0, 0, 0]])
    res = ufunc(q)
    assert type(res) is np.ndarray and res.shape == (3,)
    want = {np.absolute: [1, 5, 0], np.isnan: [False, True, False],
            np.isfinite: [True, False, False]}[ufunc]
    assert_array_equal(res, want)


@pytest.mark.parametrize("ufunc", [np.multiply, np.divide, np.add, np.subtract, np.power, np.equal])
def test_binary_ufuncs_with_out(rng, ufunc):
    p = qa(rng, (3,), unit=False)
    q = qa(rng, (3,), unit=False) if ufunc is not np.power else 0.7
    want = ufunc(p, q)
    out = np.zeros((3,), bool) if ufunc is np.equal else QuatArray(np.zeros((3, 4)))
    assert ufunc(p, q, out=out) is out
    assert_array_equal(out, want)


@pytest.mark.parametrize("ufunc", [np.multiply, np.add, np.power])
def test_binary_ufunc_of_plain_operands_into_a_quatarray_out_raises(rng, ufunc):
    """Only the out is a QuatArray: no quaternion operand, a TypeError naming both operands
    (it was an AttributeError), and the out is left as it was."""
    out = QuatArray(np.ones((3, 4)))
    with pytest.raises(TypeError, match=f"expected a QuatArray operand of {ufunc.__name__}.*ndarray and float"):
        ufunc(np.arange(12.0).reshape(3, 4), 2.0, out=out)
    assert_array_equal(out.ndarray, np.ones((3, 4)))


@pytest.mark.parametrize("ufunc", [np.sin, np.maximum, np.matmul, np.floor, np.arctan2, np.greater])
def test_other_ufuncs_raise(rng, ufunc):
    q = qa(rng, (3,))
    args = (q,) * ufunc.nin
    with pytest.raises(TypeError, match="has no quaternion meaning"):
        ufunc(*args)


def test_multiply_reduce_is_ordered_product(rng, dtype):
    q = qa(rng, (7, 3), dtype)
    want = q[0]
    for k in range(1, 7):
        want = want * q[k]
    got = np.multiply.reduce(q, axis=0)
    assert type(got) is QuatArray and got.batch_shape == (3,)
    assert_allclose(got, want, atol=tol(dtype, 100))
    acc = np.multiply.accumulate(q, axis=0)
    prefix = q[0]
    for k in range(7):
        if k:
            prefix = prefix * q[k]
        assert_allclose(acc[k], prefix, atol=tol(dtype, 100))
    # along the last batch axis, and the empty product
    assert_allclose(np.multiply.reduce(q, axis=-1), q[:, 0] * q[:, 1] * q[:, 2], atol=tol(dtype, 100))
    assert_array_equal(np.multiply.reduce(q[:0], axis=0), np.tile([1, 0, 0, 0], (3, 1)))


def test_add_reduce_over_batch_axes(rng):
    q = qa(rng, (4, 3))
    assert_allclose(q.sum(), q.ndarray.reshape(-1, 4).sum(0))
    assert_allclose(q.sum(axis=-1), q.ndarray.sum(1))
    assert type(q.sum(axis=0)) is QuatArray


# --- NumPy functions ---------------------------------------------------------------------------------------

#: NumPy functions a QuatArray must handle (keep the batch, compare or lay out quaternions).
SUPPORTED_FUNCTIONS = {np.concatenate, np.stack, np.copy, np.broadcast_to, np.where, np.take, np.flip, np.roll,
                       np.expand_dims, np.squeeze, np.zeros_like, np.ones_like, np.empty_like, np.allclose,
                       np.isclose, np.array_equal}


def test_function_registries_complete_and_disjoint():
    regs = [set(_array.BATCH_FUNCTIONS), set(_array.COMPARISON_FUNCTIONS), set(_array.LAYOUT_FUNCTIONS)]
    assert SUPPORTED_FUNCTIONS <= set().union(*regs)
    for i in range(3):
        for j in range(i + 1, 3):
            assert not regs[i] & regs[j]
    # every registered function keeps the class or is a comparison: check by calling each
    assert set(_array.COMPARISON_FUNCTIONS) == {np.allclose, np.isclose, np.array_equal}


def test_batch_functions(rng, dtype):
    p, q = qa(rng, (2, 3), dtype), qa(rng, (2, 3), dtype)
    P, Qr = p.ndarray, q.ndarray
    cases = [
        (np.concatenate([p, q]), np.concatenate([P, Qr])),
        (np.concatenate([p, q], axis=-1), np.concatenate([P, Qr], axis=1)),  # axis -1 = last batch axis
        (np.concatenate([p, q], axis=None), np.concatenate([P.reshape(-1, 4), Qr.reshape(-1, 4)])),
        (np.stack([p, q]), np.stack([P, Qr])),
        (np.stack([p, q], axis=-1), np.stack([P, Qr], axis=2)),
        (np.copy(p), P),
        (np.broadcast_to(p[0], (5, 3)), np.broadcast_to(P[0], (5, 3, 4))),
        (np.where([True, False, True], p, q), np.where(np.array([True, False, True])[:, None], P, Qr)),
        (np.take(p, [0, 2], axis=-1), P[:, [0, 2]]),
        (np.take(p, [5]), P.reshape(-1, 4)[[5]]),
        (np.flip(p), P[::-1, ::-1]),
        (np.flip(p, axis=-1), P[:, ::-1]),
        (np.roll(p, 1), np.roll(P.reshape(-1, 4), 1, axis=0).reshape(P.shape)),
        (np.roll(p, 1, axis=-1), np.roll(P, 1, axis=1)),
        (np.expand_dims(p, -1), P[:, :, None]),
        (np.squeeze(p[:1]), P[0]),
        (np.zeros_like(p), np.zeros_like(P)),
        (np.ones_like(p), np.broadcast_to([1, 0, 0, 0], P.shape)),
    ]
    for got, want in cases:
        assert type(got) is QuatArray and got.dtype == dtype
        assert_array_equal(got, want)
    e = np.empty_like(p)
    assert type(e) is QuatArray and e.shape == p.shape and e.dtype == dtype
    assert np.zeros_like(p, shape=(5,)).shape == (5, 4)
    assert not np.shares_memory(np.copy(p), p)


def test_a_keepdims_operand_broadcasts_over_the_components(rng, dtype):
    """q / np.linalg.norm(q.ndarray, axis=-1, keepdims=True), NumPy's idiom, divides each
    quaternion by its norm, as NumPy divides the (n, 4) components (it made an (n, n) batch);
    a last axis of another length stays a batch axis."""
    q = QuatArray(rng.normal(size=(50, 4)).astype(dtype))
    norms = np.linalg.norm(q.ndarray, axis=-1, keepdims=True)
    for got in (q / norms, q * (1 / norms), (1 / norms) * q):
        assert type(got) is QuatArray and got.shape == (50, 4)
        np.testing.assert_allclose(got.ndarray, q.ndarray / norms, rtol=2 * np.finfo(dtype).eps)
    p = q.copy()
    p /= norms
    np.testing.assert_array_equal(p.ndarray, (q / norms).ndarray)
    with pytest.raises(ValueError, match="broadcastable batch shapes"):   # as NumPy's (50, 4) * (7, 1)
        q * np.ones((7, 1))
    assert (q[:, None] * np.ones((50, 2))).shape == (50, 2, 4)          # a batch-shaped operand, as before


def test_division_by_a_real_zero_raises_as_by_the_zero_quaternion():
    """q / 0 gave inf and NaN with a warning, where q / QuatArray(0) raises: both raise now,
    whatever the dtype, the divisor's shape or the operator's form."""
    q = QuatArray([[1.0, 2, 3, 4], [0, 0, 0, 0]])
    for divisor in (0, 0.0, np.float32(0), np.array([1.0, 0.0]), [0.0, 2.0]):
        with pytest.raises(ZeroDivisionError, match="expected non-zero real divisors, got 0"):
            q / divisor
        with pytest.raises(ZeroDivisionError):
            np.divide(q, divisor)
    p = q.copy()
    with pytest.raises(ZeroDivisionError):
        p /= 0
    np.testing.assert_array_equal(p.ndarray, q.ndarray)   # nothing written
    np.testing.assert_array_equal((q / np.array([2.0, 4.0])).ndarray, q.ndarray / [[2.0], [4.0]])


def test_numpy_scalars_promote_as_numpy_and_empty_reprs_read_back():
    """np.float64 is a strong scalar in NumPy (NEP 50) for every operator, where + and -
    treated it as a Python float; an empty batch's repr keeps its shape and reads back."""
    q32 = QuatArray(np.ones((2, 4), np.float32))
    for op in (np.add, np.subtract, np.multiply, np.divide):
        assert op(q32, np.float64(2)).dtype == op(q32.ndarray, np.float64(2)).dtype == np.float64
        assert op(q32, 2.0).dtype == np.float32 and op(q32, np.float32(2)).dtype == np.float32
    # real operands of other dtypes promote with the quaternions' dtype as NumPy promotes them
    # (float16 and small integers keep float32; int32, int64 and float64 make float64)
    q64 = QuatArray(np.ones((2, 4)))
    for x in (np.float16(2), np.int8(2), np.uint16(3), np.bool_(True), np.int32(2), np.int64(2),
              np.array([2, 3], np.int8), np.array([2, 3], np.float16), np.array([2, 3]), [2, 3]):
        per_quat = x if np.ndim(x) == 0 else np.asarray(x)[:, None]
        for q in (q32, q64):
            for op in (np.add, np.subtract, np.multiply, np.divide):
                want = op(q.ndarray, per_quat)
                got = op(q, x)
                assert got.dtype == want.dtype, (op.__name__, q.dtype, x)
                if op in (np.multiply, np.divide):   # a real scales every component, as NumPy's op
                    np.testing.assert_array_equal(got.ndarray, want)
                else:   # a real is added to w only
                    np.testing.assert_array_equal(got.ndarray[:, 0], want[:, 0])
    for empty in (QuatArray(np.zeros((2, 0, 4))), QuatArray(np.zeros((0, 4), np.float32))):
        back = eval(repr(empty), {"QuatArray": QuatArray, "np": np, "float32": np.float32})
        assert back.shape == empty.shape and back.dtype == empty.dtype


def test_ndarray_methods_follow_the_functions(rng):
    """ndarray's methods of the NumPy functions' names are those functions: whole quaternions
    for take and repeat, TypeError for those without a quaternion meaning (q.sort() sorted the
    components of each quaternion; q.argsort() and q.diagonal() made QuatArrays that are not
    (..., 4)), and a view that is no longer (..., 4) float is a plain ndarray."""
    q = QuatArray(rng.normal(size=(3, 2, 4)))
    np.testing.assert_array_equal(q.take([2, 0], axis=0).ndarray, q.ndarray[[2, 0]])
    np.testing.assert_array_equal(q.take([5]).ndarray, q.ndarray.reshape(-1, 4)[[5]])
    rep = q.repeat(2, axis=1)
    assert type(rep) is QuatArray and rep.shape == (3, 4, 4)
    np.testing.assert_array_equal(rep.ndarray[:, ::2], q.ndarray)
    np.testing.assert_array_equal(q.repeat(2).ndarray, np.repeat(q.ndarray.reshape(-1, 4), 2, axis=0))
    before = q.ndarray.copy()
    for name in ("sort", "argsort", "argmax", "argmin", "max", "min", "diagonal", "cumsum", "cumprod", "nonzero",
                 "searchsorted", "partition", "trace", "compress"):
        args = {"searchsorted": (0.5,), "partition": (1,), "compress": ([True],)}.get(name, ())
        with pytest.raises(TypeError, match="has no quaternion meaning"):
            getattr(q, name)(*args)
    np.testing.assert_array_equal(q.ndarray, before)
    assert type(q.view(np.complex128)) is np.ndarray and type(q[..., :2].view(np.float64)) is np.ndarray
    assert type(q.view(np.ndarray)) is np.ndarray and type(q.ndarray.view(QuatArray)) is QuatArray


def test_comparison_functions(rng):
    p = qa(rng, (3,))
    q = p.copy()
    q.ndarray[1, 3] += 1e-3
    assert_array_equal(np.isclose(p, q), [True, False, True])
    assert np.allclose(p, p) is True and np.allclose(p, q) is False
    assert np.array_equal(p, p.copy()) and not np.array_equal(p, q)


@pytest.mark.parametrize("func", [np.median, np.sin.__call__, np.cumsum, np.linalg.norm, np.trace, np.prod, np.std],
                         ids=lambda f: getattr(f, "__name__", str(f)))
def test_unregistered_function_raises_like_a_ufunc(rng, func):
    """Functions without a quaternion meaning raise TypeError, as ufuncs do (np.sin),
    instead of silently computing on the components."""
    q = qa(rng, (3,))
    with pytest.raises(TypeError, match="has no quaternion meaning for QuatArray; use q.ndarray"):
        func(q)
    func(q.ndarray)   # the plain components are the way to componentwise maths


def test_plain_functions_see_the_components(rng):
    q = qa(rng, (3,))
    assert np.shape(q) == (3, 4) and np.ndim(q) == 2 and np.size(q) == 12
    assert np.shares_memory(q, q.ndarray) and np.result_type(q, np.float32) == np.float64
    assert "QuatArray" not in np.array_repr(q)


@pytest.mark.parametrize("axis", [None, 0, 1, (0, 1), -1])
def test_sum_and_mean_are_over_batch_axes(rng, axis):
    q = qa(rng, (3, 5), unit=False)
    want = np.sum(q.ndarray, axis=(0, 1) if axis is None else (axis if axis != -1 else 1))
    s = np.sum(q, axis=axis)
    assert type(s) is QuatArray and s.shape == want.shape
    assert_allclose(s, want, atol=1e-13)
    n = {None: 15, 0: 3, 1: 5, (0, 1): 15, -1: 5}[axis]
    assert_allclose(np.mean(q, axis=axis), want / n, atol=1e-13)
    assert np.mean(q, axis=axis, keepdims=True).ndim == 3
    with pytest.raises(TypeError, match="supports axis, out and keepdims only"):
        np.sum(q, dtype=np.float32)


@pytest.mark.parametrize("axis", [None, 0, 1, (0, 1), -1])
def test_mean_and_std_methods_agree_with_the_functions(rng, axis):
    """q.mean() is np.mean(q) (it raised TypeError about 'casting' and 'subok' of ufunc 'divide');
    q.std() and q.var() are refused with np.std's message, which says why."""
    q = qa(rng, (3, 5), unit=False)
    got, want = q.mean(axis=axis), np.mean(q, axis=axis)
    assert type(got) is QuatArray and got.shape == want.shape
    assert_array_equal(got, want)
    assert_array_equal(q.mean(axis, keepdims=True), np.mean(q, axis, keepdims=True))
    for name in ("std", "var"):
        with pytest.raises(TypeError, match=f"NumPy function '{name}' has no quaternion meaning for QuatArray; "
                                            "use q.ndarray"):
            getattr(q, name)(axis=axis)


HANDLERS = sorted(((f, h) for table in (_array.BATCH_FUNCTIONS, _array.COMPARISON_FUNCTIONS,
                                        _array.LAYOUT_FUNCTIONS) for f, h in table.items()),
                  key=lambda fh: fh[0].__name__)


@pytest.mark.parametrize("func, handler", HANDLERS, ids=[f.__name__ for f, _ in HANDLERS])
def test_handler_signatures_accept_what_numpy_accepts(func, handler):
    """astropy's check: every argument NumPy's function takes binds to the same
    parameter of the handler, both by position and (where NumPy allows it) by
    keyword, since dispatch passes the caller's arguments on as given."""
    ours, theirs = inspect.signature(handler), inspect.signature(func)
    params = [p for p in theirs.parameters.values() if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
    by_position = [p.name for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    keyword_only = {p.name: p.name for p in params if p.kind is p.KEYWORD_ONLY}
    bound = ours.bind(*by_position, **keyword_only).arguments
    for name in by_position + list(keyword_only):
        assert name in bound.values() or any(name in v for v in bound.values() if isinstance(v, tuple))
    positional_only = [p.name for p in params if p.kind is p.POSITIONAL_ONLY]
    by_keyword = {p.name: p.name for p in params if p.kind is not p.POSITIONAL_ONLY}
    bound = ours.bind(*positional_only, **by_keyword).arguments
    for name in by_keyword:
        assert bound.get(name) == name or name in bound.get("kwargs", {})


def test_registries_are_disjoint():
    tables = [set(t) for t in (_array.BATCH_FUNCTIONS, _array.COMPARISON_FUNCTIONS, _array.LAYOUT_FUNCTIONS,
                               _array.PLAIN_FUNCTIONS)]
    assert sum(len(t) for t in tables) == len(set().union(*tables))


def test_plain_arrays_refused_by_batch_functions(rng):
    with pytest.raises(TypeError, match=r"expected arrays\[1\] to be a QuatArray, got ndarray"):
        np.concatenate([qa(rng, (2,)), np.zeros((2, 4))])


# --- copy, pickle, repr -------------------------------------------------------------------------------------

@pytest.mark.parametrize("clone", [copy.copy, copy.deepcopy, lambda q: pickle.loads(pickle.dumps(q))])
def test_copy_and_pickle_round_trip(rng, dtype, clone):
    q = qa(rng, (2, 3), dtype)
    c = clone(q)
    assert type(c) is QuatArray and c.dtype == dtype and not np.shares_memory(c, q)
    assert_array_equal(c, q)


def test_repr():
    assert repr(QuatArray([[1, 0, 0, 0]])) == "QuatArray([[1., 0., 0., 0.]])"
    assert repr(QuatArray([1, 0, 0, 0], dtype=np.float32)) == "QuatArray([1., 0., 0., 0.], dtype=float32)"
    assert str(QuatArray([1, 0, 0, 0])) == "[1. 0. 0. 0.]"


# --- methods ---------------------------------------------------------------------------------------------------

def test_methods_match_kernels(rng, dtype, batch_shape):
    q = qa(rng, batch_shape, dtype, unit=False)
    raw = q.ndarray
    for name, want in [("conj", K.conjugate(raw)), ("inverse", K.inverse(raw)), ("normalized", K.normalize(raw)),
                       ("exp", K.exp(raw)), ("log", K.log(raw))]:
        res = getattr(q, name)()
        assert type(res) is QuatArray and res.dtype == dtype
        assert_array_equal(res, want)
    assert_array_equal(q.norm(), K.norm(raw))
    assert_array_equal(q.power(1.5), K.power(raw, 1.5))
    assert_allclose(q.dot(q), q.norm() ** 2, rtol=tol(dtype))
    assert_allclose(q.normalized().norm(), 1, atol=tol(dtype))


def test_inverse_of_zero_raises():
    with pytest.raises(ZeroDivisionError, match="expected non-zero quaternions"):
        QuatArray([[1, 0, 0, 0], [0, 0, 0, 0]]).inverse()


def test_rotate(rng, dtype):
    q = qa(rng, (4, 1), dtype, unit=False)
    v = rng.standard_normal((3, 3)).astype(dtype)
    got = q.rotate(v)
    assert type(got) is np.ndarray and got.shape == (4, 3, 3) and got.dtype == dtype
    # rotation preserves length and equals q v q^-1 with two products
    assert_allclose(np.linalg.norm(got, axis=-1), np.broadcast_to(np.linalg.norm(v, axis=-1), (4, 3)), rtol=tol(dtype, 20))
    vq = QuatArray(np.concatenate([np.zeros((3, 1)), v.astype(float)], -1))
    qq = QuatArray(q.ndarray.astype(float))
    assert_allclose(got, (qq * vq * qq.inverse()).vec, atol=tol(dtype, 20) * 10)
    with pytest.raises(ValueError, match=r"expected v of shape \(\.\.\., 3\), got \(4,\)"):
        q.rotate(np.zeros(4))
    with pytest.raises(ValueError, match="expected non-zero quaternions to rotate by"):
        QuatArray(np.zeros(4)).rotate([1, 0, 0])


def test_identity():
    assert QuatArray.identity().shape == (4,)
    assert QuatArray.identity(3).shape == (3, 4)
    i = QuatArray.identity(shape=(2, 5), dtype=np.float32)
    assert i.shape == (2, 5, 4) and i.dtype == np.float32 and type(i) is QuatArray
    assert_array_equal(i.w, 1)
    assert_array_equal(i.vec, 0)
    with pytest.raises(ValueError, match="expected num to be a non-negative int, got -1"):
        QuatArray.identity(-1)


# --- layouts and inputs ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("layout", ["readonly", "noncontiguous", "fortran", "empty"])
def test_unusual_inputs_work_and_are_not_modified(rng, layout):
    raw = random_quats(rng, (6, 5), unit=False)
    if layout == "readonly":
        raw.flags.writeable = False
    elif layout == "noncontiguous":
        raw = np.concatenate([raw, raw], axis=-1)[::2, :, 2:6]
    elif layout == "fortran":
        raw = np.asfortranarray(raw)
    else:
        raw = raw[:0]
    before = raw.copy()
    q = QuatArray(raw, copy=False)
    results = [q * q, q / 2, q ** 0.5, q.conj(), q.normalized() if q.size else q, np.exp(q), q.rotate([1.0, 0, 0])]
    want = hamilton_reference(before, before)
    assert_allclose(results[0], want, atol=1e-13)
    assert_array_equal(raw, before)
    assert all(r.shape[:-1] == raw.shape[:-1] for r in results)


# --- _touches_last against a probe ---------------------------------------------------------

def _probe_keeps_last(key, shape):
    """Ground truth from a probe whose entries hold their component index and
    whose batch axes never have length 4: the last axis stayed whole and last
    iff the result ends in an axis of length 4 reading 0, 1, 2, 3."""
    probe = np.broadcast_to(np.arange(4), shape)
    res = probe[key]
    # an empty result holds no entries to read the components' order from
    assume(not (isinstance(res, np.ndarray) and res.size == 0 and res.ndim >= 1 and res.shape[-1] == 4))
    return isinstance(res, np.ndarray) and res.ndim >= 1 and res.shape[-1] == 4 and bool(
        (res == np.arange(4)).all())


BATCH_DIM = st.sampled_from([1, 2, 3, 5])


@st.composite
def shapes_and_keys(draw):
    batch = tuple(draw(st.lists(BATCH_DIM, min_size=0, max_size=3)))
    shape = batch + (4,)
    key = draw(hnp.basic_indices(shape, min_dims=0, allow_newaxis=True, allow_ellipsis=True))
    if batch and draw(st.booleans()):   # an integer-array index on a batch axis
        axis = draw(st.integers(0, len(batch) - 1))
        idx = draw(hnp.arrays(np.intp, draw(st.integers(0, 3)), elements=st.integers(0, batch[axis] - 1)))
        key = (slice(None),) * axis + (idx,)
    return shape, key


@given(shapes_and_keys())
def test_touches_last_agrees_with_a_probe(case):
    shape, key = case
    assert _array._touches_last(key, shape) == (not _probe_keeps_last(key, shape)), (shape, key)


@pytest.mark.parametrize("call, name", [
    (lambda q: abs(q), "the quaternions"), (lambda q: np.absolute(q), "the argument of absolute"),
    (lambda q: q.norm(), "the quaternions"),
    (lambda q: q.log(), "the quaternions"), (lambda q: np.log(q), "the argument of log"),
    (lambda q: q.normalized(), "the quaternions"), (lambda q: q.inverse(), "the quaternions"),
    (lambda q: q ** 0.5, r"the left operand of \*\*"), (lambda q: q.power(0.5), "the quaternions"),
    (lambda q: np.sqrt(q), "the argument of sqrt"), (lambda q: q.rotate([1, 0, 0]), "the quaternions"),
    (lambda q: q.as_matrix(), "the quaternions"), (lambda q: q.as_rotvec(), "the quaternions"),
    (lambda q: q.as_mrp(), "the quaternions"), (lambda q: q.as_euler("xyz"), "the quaternions"),
    (lambda q: q.as_davenport(np.eye(3), "extrinsic"), "the quaternions"),
    (lambda q: QuatArray(np.ones((3, 4))) / q, "the right operand of /"),
    (lambda q: 2 / q, "the right operand of /"),
])
def test_nan_input_is_named_with_its_index(call, name):
    """Every operation names the argument and the first index holding nan or inf (those whose
    kernels find it by their range test said only 'expected finite quaternions')."""
    q = QuatArray(np.ones((3, 4)))
    q[1, 2] = np.nan   # the quaternion's component (1, 2): the first non-finite element
    with pytest.raises(ValueError, match=rf"expected finite values in {name}, got nan or inf at index \(1, 2\)"):
        call(q)
