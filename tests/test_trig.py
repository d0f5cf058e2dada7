"""The kernels' float64 tangent (`quatarray._trig`): accuracy against 50-digit references,
element-wise results whatever the block holds, the dispatch."""

import mpmath
import numpy as np
import pytest

from quatarray import _trig


@pytest.fixture
def rational_path(monkeypatch):
    """The rational path, whatever this CPU would choose."""
    monkeypatch.setattr(_trig, "SIMD_TAN", False)


def _ulps(got, x):
    """|got - tan x| in ulps of the correctly rounded tan x (50-digit reference)."""
    with mpmath.workdps(50):
        ref = np.array([float(mpmath.tan(mpmath.mpf(float(v)))) for v in x])
    return np.abs(got - ref) / np.spacing(np.abs(ref))


def _samples(rng, lo, hi, n=4000):
    return np.concatenate([rng.uniform(lo, hi, n), np.geomspace(1e-300, 1e-3, 50), -np.geomspace(1e-300, 1e-3, 50)])


def test_within_one_ulp_up_to_a_quarter_turn(rational_path, rng):
    x = np.concatenate([_samples(rng, -np.pi / 4, np.pi / 4),
                        [np.pi / 4, -np.pi / 4, np.nextafter(np.pi / 4, 0), 0.66, 5e-324]])
    assert _ulps(_trig.tan(x), x).max() <= 1


def test_reduced_arguments_within_two_ulp(rational_path, rng):
    k = rng.integers(-1000, 1000, 500)
    near_poles = k * (np.pi / 2) + rng.normal(scale=1e-6, size=500)
    x = np.concatenate([_samples(rng, -20.0, 20.0), rng.uniform(-_trig.REDUCE_LIMIT, _trig.REDUCE_LIMIT, 500),
                        near_poles, [np.pi / 2, -np.pi / 2, np.pi, 3 * np.pi / 4]])
    assert _ulps(_trig.tan(x), x).max() <= 2


def test_signed_zeros_and_tiny_arguments_are_kept(rational_path):
    x = np.array([0.0, -0.0, 1e-320, -1e-320, 1e-200])
    got = _trig.tan(x)
    np.testing.assert_array_equal(got, x)
    np.testing.assert_array_equal(np.signbit(got), np.signbit(x))


def test_signed_zero_beside_reduced_arguments(rational_path):
    """-0 in a block that takes the reduction keeps its sign, as on its own."""
    x = np.array([-0.0, 0.0, 2.0, -5.0])
    got = _trig.tan(x)
    np.testing.assert_array_equal(np.signbit(got[:2]), [True, False])


def test_known_bounds_give_the_bits_of_found_ones(rational_path, rng):
    """Bounds the caller knows (`tan`'s ``bounds``), tight or loose, give the bits of the
    bounds `tan` finds itself: inside a quarter turn, astride it and beyond."""
    for x in (rng.uniform(0, np.pi / 4 * 0.999, 300), rng.uniform(0, 3.0, 300),
              np.array([0.0, np.nextafter(np.pi / 4, 0)])):
        want = _trig.tan(x)
        lo, hi = float(x.min()), float(x.max())
        for bounds in ((lo, hi), (0.0, hi), (-1.0, 10.0)):
            np.testing.assert_array_equal(_trig.tan(x, bounds=bounds), want, strict=True)


def test_from_rotvec_bounds_give_the_bits_of_the_huge_vector_path(rational_path, rng):
    """`from_rotvec`'s row kernel passes the tangent bounds derived from its largest norm;
    the component-major kernel (for a block holding a huge vector) finds them itself: the
    same rows give the same bits either way, in radians and degrees."""
    from quatarray._convert import from_rotvec
    v = rng.standard_normal((50, 3)) * rng.choice([1e-9, 0.5, 3.0, 40.0], (50, 1))
    huge = np.concatenate([v, [[1e200, 0.0, 0.0]]])
    for degrees in (False, True):
        np.testing.assert_array_equal(from_rotvec(v, degrees), from_rotvec(huge, degrees)[:50], strict=True)


@pytest.mark.parametrize("simd", [False, True], ids=["rational", "numpy"])
def test_one_float_has_the_bits_of_the_array_path(monkeypatch, rng, simd):
    """`tan_float` (one rotation's float paths) is `tan` on an array holding the float,
    bit for bit, signed zeros and NumPy's cases included."""
    monkeypatch.setattr(_trig, "SIMD_TAN", simd)
    x = np.concatenate([rng.uniform(-0.8, 0.8, 500), rng.uniform(-30, 30, 500), rng.uniform(-2e6, 2e6, 50),
                        [0.0, -0.0, np.pi / 4, -np.pi / 4, 5e-324, -1e-310, 2.0 ** 20, 1e300, np.inf, np.nan]])
    with np.errstate(invalid="ignore"):
        whole = _trig.tan(x)
        one = np.array([_trig.tan_float(float(v)) for v in x])
    np.testing.assert_array_equal(one.view(np.int64)[:-2], whole.view(np.int64)[:-2])
    assert np.isnan(one[-2:]).all() and np.isnan(whole[-2:]).all()


def test_each_element_is_computed_alone(rational_path, rng):
    """A block holding huge, infinite or NaN arguments (np.tan's) or reduced ones gives every
    other element the bits it gets on its own."""
    x = np.concatenate([rng.uniform(-0.7, 0.7, 64), rng.uniform(-9, 9, 64), [1e300, -1e10, np.inf, np.nan]])
    with np.errstate(invalid="ignore"):
        whole = _trig.tan(x)
        alone = np.array([_trig.tan(x[i:i + 1])[0] for i in range(x.size)])
        ref = np.tan(x[-4:])
    np.testing.assert_array_equal(whole, alone)
    np.testing.assert_array_equal(whole[-4:], ref)   # beyond the reduction: the C library's
    small = x[:64]
    np.testing.assert_array_equal(_trig.tan(small), whole[:64])


def test_out_may_be_the_input_and_rows_are_used(rational_path, rng):
    x = rng.uniform(-3, 3, 1000)
    expected = _trig.tan(x)
    y = x.copy()
    rows = tuple(np.empty_like(x) for _ in range(3))
    assert _trig.tan(y, out=y, rows=rows) is y
    np.testing.assert_array_equal(y, expected)


def test_input_not_modified_and_shapes_kept(rational_path, rng):
    x = rng.uniform(-3, 3, (4, 5, 6))
    x.flags.writeable = False
    got = _trig.tan(x)
    assert got.shape == x.shape
    np.testing.assert_allclose(got, np.tan(x), rtol=5e-16, atol=0)
    assert _trig.tan(np.empty((0, 3))).shape == (0, 3)


def test_simd_cpus_and_float32_use_numpy(monkeypatch, rng):
    x = rng.uniform(-1, 1, 100)
    monkeypatch.setattr(_trig, "SIMD_TAN", True)
    np.testing.assert_array_equal(_trig.tan(x), np.tan(x))
    monkeypatch.setattr(_trig, "SIMD_TAN", False)
    x32 = x.astype(np.float32)
    got = _trig.tan(x32)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, np.tan(x32))


def test_reduction_of_small_arguments_is_exact(rng):
    x = rng.uniform(-np.pi / 4, np.pi / 4, 10_000)
    rows = np.empty((3,) + x.shape)
    np.testing.assert_array_equal(_trig.reduced(x, np.empty_like(x), rows),
                                  _trig.rational(x, np.empty_like(x), *np.empty((3,) + x.shape)))


def test_the_quarter_angle_of_a_half_turn_is_correctly_rounded(rational_path, rng):
    """tan(±fl(π)/4) is 1 - 2⁻⁵³, not 1: a half turn's w = cos(fl(π)/2) keeps its sign."""
    with mpmath.workdps(50):
        assert _trig.TAN_QUARTER_PI == float(mpmath.tan(mpmath.mpf(np.pi / 4)))
    for x in (np.array([np.pi / 4, -np.pi / 4]), np.array([np.pi / 4, -np.pi / 4, 3.0]),
              np.array([np.pi / 4, 1e300])):
        at = np.abs(x) == np.pi / 4
        np.testing.assert_array_equal(_trig.tan(x)[at], np.sign(x[at]) * _trig.TAN_QUARTER_PI)
    one = np.array([np.pi / 4]), np.array(-np.pi / 4)   # alone, as a batch of one and as a 0-d array
    assert _trig.tan(one[0])[0] == _trig.TAN_QUARTER_PI == -_trig.tan(one[1])[()]


@pytest.mark.parametrize("simd", [False, True])
def test_float32_arctangent_on_the_unit_interval(rng, monkeypatch, simd):
    monkeypatch.setattr(_trig, "SIMD_TAN", simd)   # Cephes' polynomial, or NumPy's arctan (SVML on AVX-512)
    edges = np.array([0.0, 1e-38, 1e-30, 1e-8, 0.41421354, 0.41421357, 0.4142136, 0.99999994, 1.0], np.float32)
    x = np.concatenate([rng.uniform(0, 1, 5000).astype(np.float32), edges])
    got = _trig.atan_unit32(x, *np.empty((4,) + x.shape, np.float32))
    assert got.dtype == np.float32
    with mpmath.workdps(30):
        ref = np.array([float(mpmath.atan(mpmath.mpf(float(v)))) for v in x])
    ulps = np.abs(got - ref) / np.spacing(np.abs(ref).astype(np.float32)).astype(np.float64)
    assert ulps.max() <= 2
    assert got[x.size - edges.size] == 0 and not np.signbit(got[x.size - edges.size])
    assert np.all(np.diff(got[np.argsort(x)]) >= 0)   # monotonic across the reduction's edge


@pytest.mark.parametrize("value", [0.3, np.pi / 4, -np.pi / 4, 2.0, -7.5, 1e300])
def test_zero_dimensional_and_strided_arguments(rational_path, value):
    x = np.array(value)
    got = _trig.tan(x)
    assert got.shape == ()
    np.testing.assert_allclose(got, np.tan(x), rtol=5e-16, atol=0)
    assert _trig.tan(x, out=x) is x and x == got
    strided = np.full((6, 4), value)[::2, 1::2]
    np.testing.assert_array_equal(_trig.tan(strided), np.full((3, 2), got))


def test_simd_choice_comes_from_numpys_public_report():
    """`SIMD_TAN` is read from ``numpy.show_config(mode="dicts")`` (no private NumPy names)."""
    found = np.show_config(mode="dicts")["SIMD Extensions"]["found"]
    assert _trig.SIMD_TAN == ("AVX512_SKX" in found or "X86_V4" in found)
