"""The API's domain: one policy for NaN and infinite input (a ValueError naming the
argument), error messages that name operands and shapes, and NumPy's casting
rule for in-place operations."""

import numpy as np
import pytest

from quatarray import QuatArray, Rotation, RotationSpline, Slerp, Track
from quatarray.interpolate import (
    bezier, bezier_control_points, lerp, nlerp, slerp, squad, squad_control_points, unflip,
)

from .conftest import random_quats

RNG = np.random.default_rng(14)
Q = random_quats(RNG, (3,))
V = RNG.standard_normal((3, 3))
KEYS = random_quats(RNG, (4,))
TIMES = np.array([0.0, 1.0, 2.0, 3.0])


def _spoil(a, bad, index=1):
    """A copy of `a` with one element set to `bad` (nan or inf)."""
    a = np.array(a, dtype=np.float64)
    a.reshape(-1)[index] = bad
    return a


def quat(bad):
    return QuatArray(_spoil(Q, bad))


def rot(bad):
    """A Rotation holding non-finite quaternions (normalize=False skips from_quat's check)."""
    return Rotation(_spoil(Q, bad), scalar_first=True, normalize=False)


GOOD = QuatArray(Q)

# name -> call(bad value); every one must raise ValueError("... finite ...")
NONFINITE = {
    # QuatArray algebra
    "norm": lambda b: quat(b).norm(),
    "abs": lambda b: abs(quat(b)),
    "normalized": lambda b: quat(b).normalized(),
    "inverse": lambda b: quat(b).inverse(),
    "conj": lambda b: quat(b).conj(),
    "~": lambda b: ~quat(b),
    "-q": lambda b: -quat(b),
    "exp": lambda b: quat(b).exp(),
    "np.exp": lambda b: np.exp(quat(b)),
    "log": lambda b: quat(b).log(),
    "np.log": lambda b: np.log(quat(b)),
    "np.sqrt": lambda b: np.sqrt(quat(b)),
    "power q": lambda b: quat(b).power(0.5),
    "power t": lambda b: GOOD.power(b),
    "** q": lambda b: quat(b) ** 2,
    "** t": lambda b: GOOD ** np.array([1.0, b, 2.0]),
    "dot": lambda b: GOOD.dot(quat(b)),
    "rotate q": lambda b: quat(b).rotate(V),
    "rotate v": lambda b: GOOD.rotate(_spoil(V, b)),
    "rotate one": lambda b: quat(b)[0].rotate(V[0]),
    "* left": lambda b: quat(b) * GOOD,
    "* right": lambda b: GOOD * quat(b),
    "* real": lambda b: GOOD * np.array([1.0, b, 2.0]),
    "/ left": lambda b: quat(b) / GOOD,
    "/ right": lambda b: GOOD / quat(b),
    "+": lambda b: GOOD + quat(b),
    "-": lambda b: quat(b) - GOOD,
    "+ real": lambda b: GOOD + b,
    "*=": lambda b: GOOD.copy().__imul__(quat(b)),
    "multiply.reduce": lambda b: np.multiply.reduce(quat(b)),
    "multiply.accumulate": lambda b: np.multiply.accumulate(quat(b)),
    "add.reduce": lambda b: np.add.reduce(quat(b)),
    # Rotation
    "from_quat": lambda b: Rotation.from_quat(_spoil(Q, b)),
    "from_matrix": lambda b: Rotation.from_matrix(_spoil(np.eye(3), b)),
    "from_rotvec": lambda b: Rotation.from_rotvec(_spoil(V, b)),
    "from_mrp": lambda b: Rotation.from_mrp(_spoil(V, b)),
    "from_euler": lambda b: Rotation.from_euler("xyz", _spoil(V, b)),
    "from_davenport": lambda b: Rotation.from_davenport(np.eye(3), "e", _spoil(V, b)),
    "as_matrix": lambda b: quat(b).as_matrix(),
    "as_matrix one": lambda b: quat(b)[0].as_matrix(),
    "as_rotvec": lambda b: quat(b).as_rotvec(),
    "as_mrp": lambda b: quat(b).as_mrp(),
    "as_euler": lambda b: quat(b).as_euler("xyz"),
    "as_davenport": lambda b: quat(b).as_davenport(np.eye(3), "e"),
    "apply q": lambda b: rot(b).apply(V),
    "apply vectors": lambda b: Rotation.from_quat(Q).apply(_spoil(V, b)),
    "magnitude": lambda b: rot(b).magnitude(),
    "magnitude one": lambda b: rot(b)[0].magnitude(),
    "approx_equal": lambda b: Rotation.from_quat(Q).approx_equal(rot(b)),
    "mean": lambda b: rot(b).mean(),
    "to_scipy": lambda b: rot(b).to_scipy(),
    # interpolation
    "lerp": lambda b: lerp(Q[0], _spoil(Q[1], b), 0.5),
    "nlerp q": lambda b: nlerp(_spoil(Q[0], b), Q[1], 0.5),
    "nlerp t": lambda b: nlerp(Q[0], Q[1], b),
    "slerp q": lambda b: slerp(Q, _spoil(Q, b), 0.5),
    "slerp t": lambda b: slerp(Q[0], Q[1], [0.2, b]),
    "squad": lambda b: squad(Q[0], Q[1], _spoil(Q[2], b), Q[0], 0.5),
    "bezier": lambda b: bezier(Q[0], Q[1], Q[2], Q[0], b),
    "unflip": lambda b: unflip(_spoil(Q, b)),
    "squad_control_points": lambda b: squad_control_points(_spoil(KEYS, b)),
    "bezier_control_points": lambda b: bezier_control_points(KEYS, _spoil(TIMES, b)),
    "Track keys": lambda b: Track(TIMES, _spoil(KEYS, b)),
    "Track times": lambda b: Track(_spoil(TIMES, b, 3), KEYS),
    "Track query": lambda b: Track(TIMES, KEYS, extrapolate="extend")([0.5, b]),
    "Track angular_velocity": lambda b: Track(TIMES, KEYS, extrapolate="clamp").angular_velocity(b),
    "Slerp": lambda b: Slerp(TIMES, Rotation(_spoil(KEYS, b), normalize=False)),
    "RotationSpline keys": lambda b: RotationSpline(TIMES, QuatArray(_spoil(KEYS, b))),
}


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf], ids=["nan", "inf", "-inf"])
@pytest.mark.parametrize("name", sorted(NONFINITE))
def test_non_finite_input_is_refused(name, bad):
    with pytest.raises(ValueError, match="finite"):
        NONFINITE[name](bad)


def test_the_refusal_names_the_argument():
    with pytest.raises(ValueError, match=r"expected finite values in the right operand of \*, got nan or inf at index \(0, 1\)"):
        GOOD * quat(np.nan)
    with pytest.raises(ValueError, match="expected finite values in t, got nan or inf"):
        nlerp(Q[0], Q[1], np.nan)   # not "zero quaternion"
    with pytest.raises(ValueError, match=r"expected finite values in v, got nan or inf at index \(0, 1\)"):
        GOOD.rotate(_spoil(V, np.inf))
    with pytest.raises(ValueError, match="expected finite rotations, got nan or inf"):
        rot(np.nan).to_scipy()   # not "zero norm"


def test_overflow_of_finite_input_is_not_refused():
    big = QuatArray([1e200, 0, 0, 0])
    with np.errstate(over="ignore"):
        assert np.isinf((big * big).w)
        assert np.isinf((QuatArray([1e308, 0, 0, 0]) + QuatArray([1e308, 0, 0, 0])).w)


def test_tests_for_nan_accept_nan():
    q = quat(np.nan)
    np.testing.assert_array_equal(np.isnan(q), [True, False, False])
    np.testing.assert_array_equal(q == q, [False, True, True])
    assert q[1:].shape == (2, 4) and np.concatenate([q, q]).shape == (6, 4)


# --- shape mismatches name the operands and their batch shapes ---------------------

A5, B3 = QuatArray(random_quats(RNG, (5,))), QuatArray(random_quats(RNG, (3,)))
MISMATCH = {
    "*": lambda: A5 * B3,
    "/": lambda: A5 / B3,
    "+": lambda: A5 + B3,
    "-": lambda: A5 - B3,
    "==": lambda: A5 == B3,
    "!=": lambda: A5 != B3,
    "**": lambda: A5 ** np.ones(3),
    "* real": lambda: np.ones(3) * A5,
    "np.multiply": lambda: np.multiply(A5, B3),
}


@pytest.mark.parametrize("op", sorted(MISMATCH))
def test_shape_mismatch_names_operands_and_batch_shapes(op):
    symbol = op.split()[0].replace("np.multiply", "*")
    with pytest.raises(ValueError, match=rf"expected operands of {__import__('re').escape(symbol)} with broadcastable "
                                         r"batch shapes, got left .* batch shape \(\d,\) and right .* batch shape \(\d,\)"):
        MISMATCH[op]()


def test_dot_and_rotate_mismatch_messages():
    with pytest.raises(ValueError, match=r"operands of dot .* batch shape \(5,\) .* batch shape \(3,\)"):
        A5.dot(B3)
    with pytest.raises(ValueError, match=r"expected v of a batch shape that broadcasts with the quaternions' "
                                         r"\(5,\), got v of batch shape \(3,\)"):
        A5.rotate(np.ones((3, 3)))


@pytest.mark.parametrize("rng", [-1, "seed", 1.5])
def test_bad_rng_is_named(rng):
    with pytest.raises((ValueError, TypeError), match=r"expected rng to be a numpy.random.Generator.*got " + repr(rng).replace(".", r"\.")):
        Rotation.random(3, rng=rng)


# --- mean ------------------------------------------------------------------------------

@pytest.mark.parametrize("row, match", [
    ([np.nan, 0, 0, 0], "expected finite rotations to average, got nan or inf"),
    ([0, np.inf, 0, 0], "expected finite rotations to average, got nan or inf"),
    ([0, 0, 0, 0], "zero quaternion at index"),
])
def test_mean_refuses_bad_rows(row, match):
    with pytest.raises(ValueError, match=match):
        Rotation([[1, 0, 0, 0], row], scalar_first=True, normalize=False).mean()


@pytest.mark.parametrize("shape", [(4,), (1, 4)], ids=["single", "batch of one"])
@pytest.mark.parametrize("row, match", [
    ([np.nan, 0, 0, 0], "expected finite rotations to average, got nan or inf"),
    ([0, np.inf, 0, 0], "expected finite rotations to average, got nan or inf"),
    ([0, 0, 0, 0], "zero quaternion at index"),
])
def test_mean_of_one_rotation_refuses_a_bad_one(shape, row, match):
    """The mean of one rotation is itself only when it is known unit: one made with
    normalize=False is checked and normalised as in a longer batch."""
    with pytest.raises(ValueError, match=match):
        Rotation(np.reshape(row, shape), scalar_first=True, normalize=False).mean()


@pytest.mark.parametrize("shape", [(4,), (1, 4)], ids=["single", "batch of one"])
@pytest.mark.parametrize("scale", [1e-300, 2.0, 1e300])
def test_mean_of_one_non_unit_rotation_is_unit(shape, scale):
    q = np.reshape([0.6 * scale, 0.8 * scale, 0, 0], shape)
    got = Rotation(q, scalar_first=True, normalize=False).mean().as_quat(scalar_first=True)
    np.testing.assert_allclose(got, [0.6, 0.8, 0, 0], rtol=0, atol=1e-15)


@pytest.mark.parametrize("r", [1e-300, 1e-200, 1e200, 1e300])
def test_mean_at_extreme_magnitudes(r):
    q = np.array([[0.6, 0.8, 0, 0], [0.8, 0.6, 0, 0]])
    want = Rotation(q, scalar_first=True).mean().as_quat()
    for make in (lambda x: Rotation(x, scalar_first=True),
                 lambda x: Rotation(x, scalar_first=True, normalize=False)):
        np.testing.assert_allclose(make(r * q).mean().as_quat(), want, atol=1e-15)
    np.testing.assert_allclose(Rotation([[0.6e300, 0.8e300, 0, 0]], scalar_first=True, normalize=False).mean()
                               .as_quat(scalar_first=True), [0.6, 0.8, 0, 0], atol=1e-15)


# --- casting ----------------------------------------------------------------------------

@pytest.mark.parametrize("op", ["__imul__", "__itruediv__", "__iadd__", "__isub__"])
def test_in_place_operations_cast_as_numpy_does(op, rng):
    p64 = QuatArray(random_quats(rng, (4,)))
    p32 = QuatArray(random_quats(rng, (4,), np.float32))
    want = getattr(operator_of(op), "__call__")(p32.astype(np.float64), p64).ndarray.astype(np.float32)
    target = p32.copy()
    res = getattr(target, op)(p64)
    assert res is target and res.dtype == np.float32
    np.testing.assert_array_equal(res.ndarray, want)   # computed in float64, rounded once
    wide = p64.copy()
    assert getattr(wide, op)(p32).dtype == np.float64


def operator_of(op):
    import operator
    return {"__imul__": operator.mul, "__itruediv__": operator.truediv, "__iadd__": operator.add,
            "__isub__": operator.sub}[op]


# --- docstring examples import what they use ---------------------------------------------

@pytest.mark.parametrize("module", ["quatarray._array", "quatarray._scale", "quatarray._validate",
                                    "quatarray._convert"])
def test_docstring_examples_import_what_they_use(module):
    """Each docstring's examples run in an empty namespace: no NameError (a user can
    copy any one of them on its own)."""
    import doctest
    import importlib

    class Runner(doctest.DocTestRunner):
        def report_unexpected_exception(self, out, test, example, exc_info):
            if issubclass(exc_info[0], NameError):
                missing.append(f"{test.name}: {exc_info[1]}")

    missing = []
    for test in doctest.DocTestFinder().find(importlib.import_module(module)):
        test.globs = {}
        Runner(optionflags=doctest.ELLIPSIS).run(test, out=lambda s: None)
    assert not missing, missing


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("size", [5, 96, 97, 4096, 4097, 3 * 1024 + 5, 70_000])
def test_all_finite_finds_one_bad_element_anywhere(dtype, size):
    """`_validate.all_finite` at each of its sizes (Python sum, isfinite, the sums of long
    arrays, float32's row sums with their tail): one nan or ±inf anywhere, a sum that
    overflows from finite elements, and a strided array."""
    from quatarray._validate import all_finite
    a = np.random.default_rng(size).standard_normal(size).astype(dtype)
    assert all_finite(a) and all_finite(a[::2])
    big = a.copy()
    big[:] = np.finfo(dtype).max   # the sum overflows; every element is finite
    assert all_finite(big)
    for bad in (np.nan, np.inf, -np.inf):
        for at in (0, size // 2, size - 1):
            b = a.copy()
            b[at] = bad
            assert not all_finite(b), (bad, at)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shortest", [True, False])
def test_slerp_names_a_bad_component_anywhere_in_a_long_batch(dtype, shortest, monkeypatch):
    """slerp judges each block on its w row only: a nan or ±inf in any component of q0 or q1,
    or in t, still reaches it (through |q1 ∓ q0|² or the angle) on the block path."""
    from quatarray import _blocks
    monkeypatch.setattr(_blocks, "BLOCK", 1000)
    rng = np.random.default_rng(15)
    n = 3000
    q0, q1 = random_quats(rng, (2, n), dtype)
    t = rng.uniform(0, 1, n).astype(dtype)
    for bad in (np.nan, np.inf, -np.inf):
        for name, k in [("q0", c) for c in range(4)] + [("q1", c) for c in range(4)] + [("t", None)]:
            a, b, h = q0.copy(), q1.copy(), t.copy()
            if name == "t":
                h[2500] = bad
            else:
                (a if name == "q0" else b)[2500, k] = bad
            with pytest.raises(ValueError, match=name):
                slerp(a, b, h, shortest=shortest)
