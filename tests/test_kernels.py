"""Raw-array quaternion algebra: values against independent formulas and scipy,
algebraic identities (hypothesis), dtypes, layouts and broadcasting."""

import math
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from quatarray import _blocks
from quatarray import _kernels as K

from .conftest import hamilton_reference, random_quats, tol
from .test_convert import R, assert_same_rotation, sp, sp_quat, unit


def cross_rotate_reference(q, v):
    """q v q^-1 computed by two Hamilton products (the definition)."""
    vq = np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], axis=-1)
    qn = q / np.linalg.norm(q, axis=-1, keepdims=True)
    conj = qn * np.array([1, -1, -1, -1])
    return hamilton_reference(hamilton_reference(qn, vq), conj)[..., 1:]


# components in [-10, 10]; magnitudes below 1e-100 flushed to 0 so that norms do not underflow
finite_quat = arrays(np.float64, 4, elements=st.floats(-10, 10).map(lambda c: c if abs(c) > 1e-100 else 0.0))
unit_quat = finite_quat.filter(lambda q: np.linalg.norm(q) > 1e-3).map(lambda q: q / np.linalg.norm(q))
nonzero_quat = finite_quat.filter(lambda q: np.linalg.norm(q) > 1e-2)


# --- the product -----------------------------------------------------------------

@pytest.mark.parametrize("shapes", [((), ()), ((5,), (5,)), ((3, 1), (4,)), ((), (2, 3)),
                                    ((2, 1, 3), (4, 1)), ((20000,), (1,)), ((3, 20000), (20000,)),
                                    ((30001,), (30001,))])
def test_product_matches_component_formula(rng, dtype, shapes):
    sp, sq = shapes
    p = random_quats(rng, sp, dtype, unit=False)
    q = random_quats(rng, sq, dtype, unit=False)
    got = K.multiply(p, q)
    want = hamilton_reference(p.astype(np.float64), q.astype(np.float64))
    assert got.dtype == dtype
    assert got.shape == np.broadcast_shapes(sp, sq) + (4,)
    scale = np.linalg.norm(p, axis=-1)[..., None] * np.linalg.norm(q, axis=-1)[..., None]
    assert np.all(np.abs(got - want) <= 4 * np.finfo(dtype).eps * scale)


def test_product_matches_scipy_composition(rng):
    from scipy.spatial.transform import Rotation as R
    p = random_quats(rng, (10_000,))
    q = random_quats(rng, (10_000,))
    want = (R.from_quat(p, scalar_first=True) * R.from_quat(q, scalar_first=True)).as_quat(scalar_first=True)
    got = K.multiply(p, q)
    # equal up to the double cover: compare the sign-fixed versions
    got *= np.sign(np.sum(got * want, axis=-1))[:, None]
    np.testing.assert_allclose(got, want, atol=tol(np.float64))


def test_product_unit_table():
    one, i, j, k = np.eye(4)
    m = K.multiply
    for u in (i, j, k):
        np.testing.assert_array_equal(m(u, u), -one)
    np.testing.assert_array_equal(m(m(i, j), k), -one)
    np.testing.assert_array_equal(m(i, j), k)
    np.testing.assert_array_equal(m(j, k), i)
    np.testing.assert_array_equal(m(k, i), j)
    np.testing.assert_array_equal(m(j, i), -k)
    np.testing.assert_array_equal(m(k, j), -i)
    np.testing.assert_array_equal(m(i, k), -j)


@pytest.mark.parametrize("layout", ["fortran", "strided", "readonly", "float32+64"])
def test_product_layouts(rng, layout):
    p = random_quats(rng, (7, 5), unit=False)
    q = random_quats(rng, (7, 5), unit=False)
    want = hamilton_reference(p, q)
    if layout == "fortran":
        p, q = np.asfortranarray(p), np.asfortranarray(q)
    elif layout == "strided":
        p = np.repeat(p, 2, axis=0)[::2]
        q = np.concatenate([q, q], axis=-1)[..., :4]
    elif layout == "readonly":
        p.flags.writeable = q.flags.writeable = False
    else:
        p = p.astype(np.float32)
        want = hamilton_reference(p.astype(np.float64), q)
    before = p.copy(), q.copy()
    got = K.multiply(p, q)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-5 if layout == "float32+64" else 1e-14)
    np.testing.assert_array_equal(p, before[0])
    np.testing.assert_array_equal(q, before[1])


def test_product_out_aliasing_input(rng):
    p = random_quats(rng, (40_000,), unit=False)
    q = random_quats(rng, (40_000,), unit=False)
    want = hamilton_reference(p, q)
    K.multiply(p, q, out=p)
    np.testing.assert_allclose(p, want, atol=1e-13)


@pytest.mark.parametrize("n", [1, 2, 7, K._STACK_MAX])
def test_product_stacked_and_in_place_passes_agree(dtype, n):
    """A few quaternions run the product with stacked operands, long blocks with eight
    passes in place: the same operations per element, so the same bits (also for
    inf, nan, signed zeros and subnormals), and a row's bits do not depend on its batch."""
    rng = np.random.default_rng(n)
    fi = np.finfo(dtype)
    special = np.array([np.inf, -np.inf, np.nan, 0.0, -0.0, fi.smallest_subnormal, fi.max, -fi.tiny], dtype)
    p, q = (rng.standard_normal((n, 4)).astype(dtype) for _ in range(2))
    for a in (p, q):   # a fifth of the components special
        mask = rng.random(a.shape) < 0.2
        a[mask] = rng.choice(special, mask.sum())
    ct = np.complex64 if dtype == np.float32 else np.complex128
    stacked, passes = np.empty((2, n, 4), dtype)
    with np.errstate(all="ignore"):
        K._hamilton_stacked(p.view(ct), q.view(ct), stacked.view(ct))
        K._mul_views(p.view(ct), q.view(ct), passes.view(ct))
        long = K.multiply(np.concatenate([p] * (K._STACK_MAX // n + 1)), np.concatenate([q] * (K._STACK_MAX // n + 1)))
    np.testing.assert_array_equal(stacked, passes, strict=True)
    np.testing.assert_array_equal(long[:n], stacked, strict=True)


def test_product_out_errors():
    p = np.zeros((3, 4))
    with pytest.raises(ValueError, match=r"expected out of shape \(3, 4\), got \(2, 4\)"):
        K.multiply(p, p, out=np.zeros((2, 4)))
    with pytest.raises(TypeError, match="expected out of dtype float64, got float32"):
        K.multiply(p, p, out=np.zeros((3, 4), np.float32))


def test_empty_batches():
    e = np.zeros((0, 4))
    assert K.multiply(e, e).shape == (0, 4)
    assert K.rotate(e, np.zeros((0, 3))).shape == (0, 3)
    assert K.exp(e).shape == K.log(e).shape == K.power(e, 2.0).shape == (0, 4)
    assert K.norm(e).shape == (0,)


# --- hypothesis identities ----------------------------------------------------------

@given(finite_quat, finite_quat, finite_quat)
def test_associativity(p, q, r):
    lhs = K.multiply(K.multiply(p, q), r)
    rhs = K.multiply(p, K.multiply(q, r))
    scale = np.linalg.norm(p) * np.linalg.norm(q) * np.linalg.norm(r)
    assert np.all(np.abs(lhs - rhs) <= 16 * np.finfo(float).eps * max(scale, 1e-300))


@given(finite_quat, finite_quat)
def test_norm_is_multiplicative(p, q):
    np.testing.assert_allclose(K.norm(K.multiply(p, q)), K.norm(p) * K.norm(q), rtol=1e-14, atol=1e-300)


@given(finite_quat, finite_quat)
def test_conjugate_reverses_products(p, q):
    lhs = K.conjugate(K.multiply(p, q))
    rhs = K.multiply(K.conjugate(q), K.conjugate(p))
    np.testing.assert_allclose(lhs, rhs, rtol=0, atol=8 * np.finfo(float).eps * (K.norm(p) * K.norm(q) + 1e-300))


@given(nonzero_quat)
def test_inverse(q):
    np.testing.assert_allclose(K.multiply(q, K.inverse(q)), [1, 0, 0, 0], atol=1e-14)
    np.testing.assert_allclose(K.multiply(K.inverse(q), q), [1, 0, 0, 0], atol=1e-14)


@given(arrays(np.float64, 4, elements=st.floats(-3, 3)))
def test_exp_log_roundtrip(q):
    # log(exp q) = q only on the principal branch (|v| < π); exp(log q) = q always
    e = K.exp(q)
    np.testing.assert_allclose(K.exp(K.log(e)), e, rtol=1e-12, atol=1e-12 * K.norm(e))


@given(unit_quat, st.floats(-3, 3), st.floats(-3, 3))
def test_power_adds_exponents(q, a, b):
    lhs = K.multiply(K.power(q, a), K.power(q, b))
    np.testing.assert_allclose(lhs, K.power(q, a + b), atol=1e-12)


@given(finite_quat, st.floats(-3, 3))
def test_power_is_exp_of_scaled_log(q, t):
    q = q + np.array([0.1, 0, 0, 0])  # keep away from the zero quaternion
    np.testing.assert_allclose(K.power(q, t), K.exp(t * K.log(q)), rtol=1e-11, atol=1e-11)


@given(unit_quat, arrays(np.float64, 3, elements=st.floats(-10, 10)))
def test_rotate_matches_two_products(q, v):
    np.testing.assert_allclose(K.rotate(q, v), cross_rotate_reference(q, v), rtol=0,
                               atol=1e-14 * (np.linalg.norm(v) + 1))


# --- accuracy against 40-digit references -----------------------------------------------

def _mp_log(q, mp):
    w, x, y, z = (mp.mpf(float(c)) for c in q)
    vn = mp.sqrt(x * x + y * y + z * z)
    s = mp.atan2(vn, w) / vn if vn else 1 / w
    return [mp.log(w * w + x * x + y * y + z * z) / 2, x * s, y * s, z * s]


def _mp_exp(q, mp):
    w, x, y, z = (mp.mpf(float(c)) for c in q)
    vn = mp.sqrt(x * x + y * y + z * z)
    s = mp.exp(w) * (mp.sin(vn) / vn if vn else 1)
    return [mp.exp(w) * mp.cos(vn), x * s, y * s, z * s]


def _near_identity(rng, n):
    """(1 + δ) (cos θ/2, sin θ/2 axis), θ from 1e-8 to 1e-2 rad, |δ| from 1e-16 to 1e-8 (and 0)."""
    theta = np.logspace(-8, -2, n)
    delta = rng.choice([-1, 1], n) * np.logspace(-16, -8, n)[rng.permutation(n)]
    delta[::7] = 0
    axis = random_quats(rng, (n,))[:, 1:]
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    q = np.concatenate([np.cos(theta / 2)[:, None], np.sin(theta / 2)[:, None] * axis], -1)
    return q * (1 + delta[:, None])


def test_log_scalar_part_near_identity(rng):
    """ln|q| = log1p((w - 1)(w + 1) + |v|²) / 2: near the identity the error is a few eps
    times ln|q| + |v|² (log|q| used to keep the whole rounding error of |q| ≈ 1: up to
    1e7 ulp, as the peers)."""
    mp = pytest.importorskip("mpmath").mp
    mp.dps = 40
    q = _near_identity(rng, 300)
    got = K.log(q)
    eps = np.finfo(float).eps
    for qi, gi in zip(q, got):
        ref = _mp_log(qi, mp)
        scale = abs(float(ref[0])) + float(np.sum(qi[1:] ** 2))
        assert abs(float(gi[0] - ref[0])) <= 2 * eps * scale, (qi, gi[0], ref[0])
        v = np.array([float(r) for r in ref[1:]])
        assert np.abs(gi[1:] - v).max() <= 2 * eps * np.linalg.norm(v)


@pytest.mark.parametrize("func", ["log", "exp"])
def test_log_and_exp_within_a_few_ulp(rng, func):
    """Every component within 3 eps of the output's norm, against 40-digit references, for
    non-unit quaternions, angles up to π (log) and |v| up to 4 (exp)."""
    mp = pytest.importorskip("mpmath").mp
    mp.dps = 40
    q = random_quats(rng, (400,)) * rng.uniform(0.5, 2, (400, 1))
    if func == "exp":
        q = q * rng.uniform(0, 4, (400, 1))
    q = np.concatenate([q, _near_identity(rng, 50)])
    got = getattr(K, func)(q)
    ref = np.array([[float(c) for c in (_mp_log if func == "log" else _mp_exp)(qi, mp)] for qi in q])
    err = np.abs(got - ref).max(axis=-1) / np.linalg.norm(ref, axis=-1)
    assert err.max() <= 3 * np.finfo(float).eps, err.max()


def test_exp_of_huge_vector_parts_and_overflowing_scalars(rng):
    """|v|² beyond float64's range (|v| up to 1e300) still gives a finite exp: the vector
    part is rescaled by a power of two, not squared to inf.  (At such |v| one ulp of |v| is
    many turns, so only what does not depend on the angle can be checked: |exp q| = e^w and
    the vector part along v.)  An overflowing e^w leaves zero components zero, never NaN."""
    q = random_quats(rng, (40,)) * 10.0 ** rng.uniform(150, 300, (40, 1))
    q[:, 0] = rng.uniform(-2, 2, 40)
    q[::5, 2:] = 0
    for got in (K.exp(q), np.array([K.exp(qi) for qi in q])):   # batch, and one at a time
        np.testing.assert_allclose(np.linalg.norm(got, axis=-1), np.exp(q[:, 0]), rtol=4 * np.finfo(float).eps)
        v, gv = q[:, 1:] / np.max(np.abs(q[:, 1:]), axis=-1, keepdims=True), got[:, 1:]
        assert np.abs(np.cross(v, gv)).max() <= 4 * np.finfo(float).eps * np.linalg.norm(v, axis=-1).max() * np.exp(2)
    big = np.array([[800.0, 0, 0, 0], [800.0, 1, 0, 0], [-800.0, 1, 0, 2]])
    with np.errstate(over="ignore"):
        for got in (K.exp(big), np.array([K.exp(b) for b in big])):
            assert not np.isnan(got).any()
            np.testing.assert_array_equal(got[:2, 1:] == 0, big[:2, 1:] == 0)   # e^800: inf, not 0 · inf
            np.testing.assert_array_equal(got[:2, 0], [np.inf, np.inf])
            np.testing.assert_array_equal(got[2], 0.0)                          # e^-800 underflows to 0


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_exp_whose_scale_overflows_keeps_finite_components(dtype):
    """e^w beyond the float range with the other factor small enough: the component is
    finite, e^w times sin|v| v/|v| or cos|v| computed as (x e^(w/2)) e^(w/2); only the
    components that truly overflow are inf.  Independent values: exp and sin of the float
    arguments in float64 (float32) or from e^709 e (float64)."""
    w = {np.float32: 88.8, np.float64: 710.0}[dtype]
    q = np.array([[w, np.pi, 0, 0], [w, 1e-20, 0, 0], [w, 0, np.pi / 2, 0]], dtype)
    with np.errstate(over="ignore"):
        got = K.exp(q).astype(np.float64)
        for i in range(len(q)):
            np.testing.assert_array_equal(K.exp(q[i]), got[i].astype(dtype))   # each row as alone
    wf, v = float(q[0, 0]), [float(q[0, 1]), float(q[1, 1])]
    if dtype == np.float64:   # e^710 sin x as e^709 (e sin x): in range
        np.testing.assert_allclose(got[0, 1], math.exp(709.0) * (math.e * math.sin(v[0])), rtol=4e-16)
        np.testing.assert_allclose(got[1, 1], math.exp(709.0) * (math.e * v[1]), rtol=4e-16)
    else:   # float32's e^88.8 is a float64 number
        np.testing.assert_allclose(got[0, 1], math.exp(wf) * math.sin(v[0]), rtol=4 * np.finfo(np.float32).eps)
        np.testing.assert_allclose(got[1, 1], math.exp(wf) * v[1], rtol=4 * np.finfo(np.float32).eps)
    assert np.isinf(got[:2, 0]).all() and np.isinf(got[2, 2])          # e^w cos|v|, e^w sin(π/2): beyond the range
    np.testing.assert_array_equal(got[:2, 2:], 0)
    assert not np.isnan(got).any()


def test_power_whose_magnitude_overflows_keeps_zero_components(rng):
    """|q|^t beyond the float range gives inf components, and the components of v that are
    zero stay zero (0 × inf would be NaN), with the product's sign; each row as alone."""
    q = np.array([[3.0, 4, 0, 0], [1e200, 0, 0, 0], [0.0, 3, -0.0, 4], [0.6, 0.8, 0, 0], [-1e200, 0, 1e190, 0]])
    t = np.array([1000.0, 2, 1000, 1000, 3])
    with np.errstate(over="ignore"):
        got = K.power(q, t)
        for i in range(len(q)):
            np.testing.assert_array_equal(K.power(q[i], t[i]).view(np.int64), got[i].view(np.int64))
    assert not np.isnan(got).any()
    np.testing.assert_array_equal(got[:, 1:][q[:, 1:] == 0], 0)
    assert np.isinf(got[:3, 0]).all() and np.isinf(got[[0, 2], 1]).all()
    np.testing.assert_array_equal(np.signbit(got[2, 2]), np.signbit(-0.0 * np.sign(got[2, 1])))
    # |q| = 1 does not overflow: the ordinary path
    np.testing.assert_allclose(got[3], K.exp(1000 * K.log(q[3])), atol=1e-12)


def _polar_reference(q, t=None):
    """log q (t None) or q**t from Python's math.hypot and math.atan2: the angle
    θ = atan2(|v|, w) and the axis v / |v| of v scaled by a power of two (exact) to |v|
    near 1, so that neither loses digits however small v is; None for a real q or |q|^t
    out of range."""
    w, *v = (float(c) for c in q)
    if not any(v):
        return None
    e = math.frexp(max(map(abs, v)))[1]
    v = [math.ldexp(c, -e) for c in v]
    h = math.hypot(*v)
    try:
        ws = math.ldexp(w, -e)
    except OverflowError:
        ws = math.copysign(math.inf, w)
    theta, n = math.atan2(h, ws), math.hypot(w, math.ldexp(h, e))
    axis = [c / h for c in v]
    if t is None:   # θ v/|v|; v/w where |v|/w is below double precision (θ/|v| = 1/w)
        vector = ([float(c) / w for c in q[1:]] if w > 0 and h < 2.0 ** -60 * ws
                  else [theta * a for a in axis])
        return np.array([math.log(n)] + vector)
    mag = math.exp(t * math.log(n)) if t * math.log(n) < 709 else math.inf
    if not 0 < mag < 1e300:
        return None
    return np.array([mag * math.cos(t * theta)] + [mag * math.sin(t * theta) * a for a in axis])


def _tiny_vector_quats():
    """Quaternions whose |v|² underflows (or whose rescale to a safe |q|² would lose v):
    w of either sign, from 1e-130 to 1e230, v from 1e-320 to 1e-100."""
    rows = []
    for ew in (-130, -40, 0, 60, 140, 230):
        for ev in (-320, -301, -250, -200, -150, -100):
            q = np.array([7 * 10.0 ** ew, 3 * 10.0 ** ev, -2 * 10.0 ** ev, 10.0 ** ev])
            if math.hypot(*q[1:]) < 10.0 ** ew:
                rows += [q, -q, q[[0, 2, 3, 1]]]
    return np.array(rows)


def test_log_of_tiny_vectors_keeps_their_axis():
    """A vector part whose squares underflow still gives the log its axis: θ v/|v| with
    θ = π for w < 0, not the negative real's x axis; each row as alone."""
    q = _tiny_vector_quats()
    got = K.log(q)
    for i, row in enumerate(q):
        ref = _polar_reference(row)   # (θ below the normal range: a few steps of its grid)
        np.testing.assert_allclose(got[i], ref, rtol=4e-16, atol=4 * np.finfo(float).smallest_subnormal)
        np.testing.assert_array_equal(K.log(row).view(np.int64), got[i].view(np.int64))
    np.testing.assert_allclose(K.log(np.array([-1.0, 0, 1e-200, 0])), [0, 0, np.pi, 0], rtol=4e-16)
    np.testing.assert_allclose(K.log(np.array([-1, 0, 1e-30, 0], np.float32)), [0, 0, np.pi, 0], rtol=1e-7)


def test_power_modulus_rounds_like_pow_away_from_unit_norms():
    """|q|^t for |q| away from 1 comes from (|q|²)^(t/2), correctly rounded: a real
    quaternion whose w² is exact gets the exact power, rounded once (exp(t ln|q|) was 140
    ulp off for 2**1023, and 2**1024 came out finite), and a general one's norm is the exact
    |q|^t (a fraction, for even t) within the |t| / 2 ulp that |q|²'s rounding leaves."""
    from fractions import Fraction
    with np.errstate(over="ignore"):
        for x in (2.0, 3.0, 0.25, 7.25, -5.5, 1 / 1024):
            for t in (1023.0, -60.0, 2.0, 37.0, -3.0, 101.0):
                exact = Fraction(abs(x)) ** int(t)
                if not Fraction(1, 10 ** 300) < exact < 10 ** 300:
                    continue
                got = K.power(np.array([x, 0, 0, 0]), t)
                assert abs(got[0]) == float(exact) and not got[2:].any(), (x, t)
        assert K.power(np.array([2.0, 0, 0, 0]), 1024.0)[0] == np.inf
    rng = np.random.default_rng(9)
    for _ in range(200):
        q = rng.normal(size=4) * 10.0 ** rng.uniform(-3, 3)
        t = int(rng.integers(-30, 31)) * 2
        n2 = sum(Fraction(float(c)) ** 2 for c in q)
        exact = n2 ** (t // 2) if t >= 0 else 1 / n2 ** (-t // 2)
        if not Fraction(1, 10 ** 300) < exact < 10 ** 300:
            continue
        got = K.power(q, float(t))
        norm2 = sum(Fraction(float(c)) ** 2 for c in got)   # |got|² against exact², as fractions
        rel = Fraction((abs(t) / 2 * 2 + 8) * np.finfo(float).eps)
        assert abs(norm2 / exact ** 2 - 1) <= 2 * rel + rel ** 2, (q, t)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_power_and_exp_rows_as_alone_beside_extreme_ones(dtype):
    """A block with one quaternion of extreme magnitude (rescaled) or whose e^w overflows:
    every other row keeps the bits it has alone, signed zeros included (the modulus' choice
    of formula and the overflow's fix-up are each row's own)."""
    big = np.finfo(dtype).max ** 0.75
    rng = np.random.default_rng(12)
    q = (rng.normal(size=(40, 4)) * rng.uniform(0.1, 10, (40, 1))).astype(dtype)
    q[::7, 1] = -0.0
    q[5] = [big, 0, 0, 0]
    q[9] = [{np.float32: 95.0, np.float64: 720.0}[dtype], 0.5, -0.0, 0]
    with np.errstate(over="ignore"):
        for f in (lambda x: K.power(x, 0.3), lambda x: K.power(x, -2.5), K.exp):
            got = f(q)
            for i in range(len(q)):
                np.testing.assert_array_equal(f(q[i]).view(_INT[dtype]), got[i].view(_INT[dtype]))


_INT = {np.float32: np.int32, np.float64: np.int64}


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_product_of_reversed_views_as_alone(dtype):
    """Reversed (negatively strided) operands give each product the bits it has alone: NumPy's
    complex64 multiply rounds differently on such views, so they are copied first."""
    q = np.random.default_rng(13).standard_normal((300, 4)).astype(dtype)
    for p, r in ((q[::-1], q[::-1]), (q[::-1], q), (q, q[::-2][:150].repeat(2, axis=0)), (q[::-1, ::-1], q)):
        got = K.multiply(p, r)
        for i in range(0, len(q), 7):
            np.testing.assert_array_equal(K.multiply(p[i], r[i]).view(_INT[dtype]), got[i].view(_INT[dtype]))


@pytest.mark.parametrize("t", [0.5, -0.5, 2.0, 1.3, 3.7])
def test_power_of_tiny_vectors_keeps_their_axis_and_gives_no_nan(t):
    """q**t for vectors below the range: the axis v/|v| kept (θ = π for w < 0), no
    spurious overflow of sin(tθ)/|v| · |q|^t, and no NaN where |q|^t itself overflows."""
    q = _tiny_vector_quats()
    with np.errstate(over="ignore"):
        got = K.power(q, t)
        for i, row in enumerate(q):
            np.testing.assert_array_equal(K.power(row, t).view(np.int64), got[i].view(np.int64))
    assert not np.isnan(got).any()
    checked = 0
    for row, g in zip(q, got):
        ref = _polar_reference(row, t)
        if ref is not None:   # error relative to the largest component: |q|^t's
            assert np.max(np.abs(g - ref)) <= 1e-13 * np.max(np.abs(ref)), (row, g, ref)
            checked += 1
    assert checked > len(q) // 2
    np.testing.assert_allclose(K.power(np.array([-1.0, 0, 1e-200, 0]), 0.5), [0, 0, 1, 0], atol=1e-16)
    np.testing.assert_allclose(K.power(np.array([-1, 0, 1e-30, 0], np.float32), 0.5), [0, 0, 1, 0], atol=1e-7)


# --- special values -------------------------------------------------------------------

def test_log_special_values():
    np.testing.assert_allclose(K.log(np.array([-2.0, 0, 0, 0])), [np.log(2), np.pi, 0, 0])
    with np.errstate(divide="ignore"):
        assert K.log(np.zeros(4))[0] == -np.inf
    # tiny vector part: accurate angle, no cancellation
    q = np.array([1.0, 1e-200, 0, 0])
    np.testing.assert_allclose(K.log(q), [0, 1e-200, 0, 0], rtol=1e-15)


def test_power_of_zero_and_negative_real():
    z = np.zeros(4)
    np.testing.assert_array_equal(K.power(z, 2.0), z)
    np.testing.assert_array_equal(K.power(z, 0.0), [1, 0, 0, 0])
    assert K.power(z, -1.0)[0] == np.inf
    # (-1)^(1/2) is the principal root i
    np.testing.assert_allclose(K.power(np.array([-1.0, 0, 0, 0]), 0.5), [0, 1, 0, 0], atol=1e-16)


def test_inverse_and_normalize_of_zero_raise():
    with pytest.raises(ZeroDivisionError, match="expected non-zero quaternions"):
        K.inverse(np.zeros((2, 4)))
    with pytest.raises(ValueError, match="expected non-zero quaternions to normalize"):
        K.normalize(np.zeros(4))


@pytest.mark.parametrize("func", [K.exp, K.log, K.conjugate, K.normalize, K.inverse])
def test_unary_keeps_dtype_and_shape(rng, dtype, batch_shape, func):
    q = random_quats(rng, batch_shape, dtype)
    res = func(q)
    assert res.dtype == dtype and res.shape == q.shape


def test_power_batch_shaped_exponent(rng, dtype):
    q = random_quats(rng, (3, 2), dtype)
    t = np.array([0.5, 2.0])
    got = K.power(q, t)
    assert got.dtype == dtype
    for i in range(3):
        for j in range(2):
            np.testing.assert_allclose(got[i, j], K.power(q[i, j], t[j]), atol=tol(dtype))


def test_rotate_broadcasts_and_keeps_dtype(rng, dtype):
    q = random_quats(rng, (4, 1), dtype, unit=False)
    v = rng.standard_normal((3, 3)).astype(dtype)
    got = K.rotate(q, v)
    assert got.shape == (4, 3, 3) and got.dtype == dtype
    want = cross_rotate_reference(q.astype(float), v.astype(float))
    np.testing.assert_allclose(got, want, atol=tol(dtype) * 10)


# --- rotating vectors and the conjugate, against scipy ----------------------------------

def test_conjugate_is_scipy_inverse(rng, dtype, batch_shape):
    q = unit(rng, batch_shape, dtype)
    got = K.conjugate(q)
    assert got.dtype == dtype and got.shape == q.shape
    np.testing.assert_array_equal(got[..., 0], q[..., 0])
    np.testing.assert_array_equal(got[..., 1:], -q[..., 1:])
    assert_same_rotation(got, sp_quat(sp(q).inv()), tol(dtype))


@pytest.mark.parametrize("qshape, vshape", [((), ()), ((), (9,)), ((9,), ()), ((9,), (9,)), ((9,), (1,)),
                                            ((5, 1, 4), (3, 4)), ((2, 3), (3,)), ((1,), (4, 1))])
@pytest.mark.parametrize("inverse", [False, True])
def test_rotate_broadcasts_and_matches_scipy(rng, dtype, qshape, vshape, inverse):
    q = unit(rng, qshape, dtype)
    v = rng.standard_normal(vshape + (3,)).astype(dtype)
    got = K.rotate(q, v, inverse=inverse)
    assert got.dtype == dtype
    assert got.shape == np.broadcast_shapes(qshape, vshape) + (3,)
    qb = np.array(np.broadcast_to(q.astype(float), got.shape[:-1] + (4,)).reshape(-1, 4))
    vb = np.array(np.broadcast_to(v.astype(float), got.shape).reshape(-1, 3))
    want = R.from_quat(qb, scalar_first=True).apply(vb, inverse=inverse).reshape(got.shape)
    np.testing.assert_allclose(got, want, rtol=0, atol=tol(dtype) * 4)


def test_rotate_one_rotation_to_many_vectors_and_zero_quaternion(rng):
    q = unit(rng, (), np.float64)
    v = rng.standard_normal((4, 5, 3))
    got = K.rotate(q[None, None], v, inverse=True)
    assert got.shape == (4, 5, 3)
    np.testing.assert_allclose(got, sp(q).apply(v.reshape(-1, 3), inverse=True).reshape(4, 5, 3), atol=1e-14)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.isnan(K.rotate(np.zeros(4), np.ones(3))).all()
        assert np.isnan(K.rotate(np.zeros((2, 4)), np.ones(3))).all()


@pytest.mark.parametrize("inverse", [False, True])
def test_rotate_stacked_and_component_rows_agree(dtype, inverse):
    """A few pairs run the rotation formula on stacked rows, long blocks one component row
    at a time: the same operations per element, so the same bits, also for quaternions and
    vectors of extreme magnitude (rescaled), zero quaternions (nan) and infinite vectors."""
    rng = np.random.default_rng(5)
    n = 3 * _blocks.FEW   # more than a few: the long path
    q = rng.standard_normal((n, 4)).astype(dtype)
    v = rng.standard_normal((n, 3)).astype(dtype)
    fi = np.finfo(dtype)
    q[::7] *= dtype(2.0) ** rng.integers(-60, 60, (len(q[::7]), 1))
    v[::5] *= fi.max / 4
    q[3] = 0.0
    v[6, 2] = np.inf
    with np.errstate(all="ignore"):
        long = K.rotate(q, v, inverse=inverse)
        for start in range(0, n, 500):   # a few at a time: the stacked path
            few = K.rotate(q[start:start + 500], v[start:start + 500], inverse=inverse)
            np.testing.assert_array_equal(few, long[start:start + 500], strict=True)


def test_rotate_unit_skips_only_checks_whose_outcome_is_known(dtype):
    """`unit=True` (Rotation's finite unit quaternions) skips range checks only where they
    cannot change the result: the same bits as the checked path, for vectors around half
    the vector bound (scaled or not) and in a long batch."""
    from quatarray import _scale
    rng = np.random.default_rng(11)
    q = random_quats(rng, (40,), dtype)
    big = _scale.BIG_VECTOR[np.dtype(dtype)]
    v = rng.standard_normal((40, 3)).astype(dtype)
    v[::3] *= dtype(big / 2)   # components around half the bound: either side
    v[1::3] *= dtype(big)
    for inverse in (False, True):
        np.testing.assert_array_equal(K.rotate(q, v, inverse, unit=True), K.rotate(q, v, inverse), strict=True)


def test_rotate_unit_blocks_skip_only_checks_whose_outcome_is_known(dtype, monkeypatch):
    """The block path's `unit` too: blocks of ordinary vectors skip the checks, a block holding a
    vector near the bound takes them; the same bits as the checked path either way."""
    from quatarray import _scale
    monkeypatch.setattr(_blocks, "BLOCK", 700)   # several blocks, the float32 ones too
    rng = np.random.default_rng(12)
    n = 3 * _blocks.FEW
    q = random_quats(rng, (n,), dtype)
    v = rng.standard_normal((n, 3)).astype(dtype)
    v[-5:] *= dtype(_scale.BIG_VECTOR[np.dtype(dtype)])   # only the last block is near the bound
    for inverse in (False, True):
        np.testing.assert_array_equal(K.rotate(q, v, inverse, unit=True), K.rotate(q, v, inverse), strict=True)


@pytest.mark.parametrize("n", [1, 5, 3 * 1024 + 17])   # one pair, a few, blocks
def test_rotate_add_is_the_sum_after_rotation(dtype, n, monkeypatch):
    """`add` (a rigid motion's translation, added block by block) gives the bits of adding it after."""
    monkeypatch.setattr(_blocks, "BLOCK", 1000)
    rng = np.random.default_rng(13)
    q = random_quats(rng, (n,), dtype)
    v, t = rng.standard_normal((2, n, 3)).astype(dtype)
    for unit in (False, True):
        want = K.rotate(q, v, unit=unit) + t
        np.testing.assert_array_equal(K.rotate(q, v, unit=unit, add=t), want, strict=True)
        assert np.array_equal(np.signbit(K.rotate(q, v, unit=unit, add=t)), np.signbit(want))
    with pytest.raises(ValueError, match="expected add of shape"):
        K.rotate(q, v, add=t[:, :2])


@pytest.mark.parametrize("n", [1, 7, 1500])   # the stacked path and blocks
def test_multiply_check_finds_a_bad_component_anywhere(dtype, n, monkeypatch):
    """`multiply(check=True)` judges the product's w only: a nan or ±inf in any component of
    either operand reaches it, also against zeros (inf · 0 is nan), and finite input passes."""
    monkeypatch.setattr(_blocks, "BLOCK", 512)
    rng = np.random.default_rng(14)
    p, q = random_quats(rng, (2, n), dtype)
    assert K.multiply(p, q, check=True)[1]
    for bad in (np.nan, np.inf, -np.inf):
        for k in range(8):
            a, b = p.copy(), q.copy()
            if n > 1:
                a[n // 2] = b[n // 2] = 0   # the other operand's factor is 0 there
            (a if k < 4 else b)[n // 2, k % 4] = bad
            with np.errstate(invalid="ignore"):
                assert not K.multiply(a, b, check=True)[1], (bad, k)


def test_rotate_mixed_dtypes_promote(rng):
    q = unit(rng, (4,), np.float32)
    v = rng.standard_normal((4, 3))
    assert K.rotate(q, v).dtype == np.float64
    assert K.rotate(q[0], v).dtype == np.float64
    assert K.rotate(q.astype(float), v.astype(np.float32)).dtype == np.float64


def test_rotate_by_non_unit_quaternion_is_a_rotation(rng):
    q = unit(rng, (30,), np.float64) * 3.0
    v = rng.standard_normal((30, 3))
    np.testing.assert_allclose(K.rotate(q, v), K.rotate(q / 3.0, v), atol=1e-14)
    np.testing.assert_allclose(K.rotate(q[0], v), K.rotate(q[0] / 3.0, v), atol=1e-14)


@pytest.fixture(params=["numpy", "ratio"])
def arctan2_route(request, monkeypatch):
    """`K.arctan2`'s route, forced either way: NumPy's loop (taken where it is SIMD) or the
    ratio route (`K._ratio_route`, taken on CPUs without AVX-512)."""
    monkeypatch.setattr(K._trig, "SIMD_TAN", request.param == "numpy")
    return request.param


@pytest.mark.parametrize("dtype", [np.float32, np.float64], ids=["f32", "f64"])
def test_arctan2_from_one_arctan_matches_numpy(rng, dtype, arctan2_route):
    """The arctan-of-the-ratio arctan2 is within 2 ulp of np.arctan2 in every quadrant,
    at signed zeros and at huge and tiny ratios."""
    y = (rng.standard_normal(20000) * 10.0 ** rng.uniform(-30, 30, 20000)).astype(dtype)
    x = (rng.standard_normal(20000) * 10.0 ** rng.uniform(-30, 30, 20000)).astype(dtype)
    z = np.array([0.0, -0.0], dtype)
    y = np.concatenate([y, np.repeat(z, 2), z, z, np.ones(2, dtype), -np.ones(2, dtype), z])
    x = np.concatenate([x, np.tile(z, 2), np.ones(2, dtype), -np.ones(2, dtype), z, z, np.full(2, np.inf, dtype)])
    want = np.arctan2(y, x)
    got = K.arctan2(y, x)
    assert got.dtype == dtype
    np.testing.assert_array_equal(np.signbit(got), np.signbit(want))
    assert (np.abs(got - want) <= 2 * np.spacing(np.abs(want))).all()


def test_arctan2_on_floats_gives_the_array_bits(rng, arctan2_route):
    """On Python floats, one at a time and as lists (one rotation's angles, every sign
    pattern of their x), arctan2 gives the bits of the float64 array path, signed zeros
    included, in every quadrant and at x = ±0 (NumPy's SIMD arctan2 where that is used, else
    the ratio route)."""
    y = (rng.standard_normal(600) * 10.0 ** rng.uniform(-30, 30, 600))
    x = (rng.standard_normal(600) * 10.0 ** rng.uniform(-30, 30, 600))
    y[:48:2] = np.copysign(0.0, y[1:48:2])   # signed zeros over either sign of x
    y = np.concatenate([y, [0.0, -0.0, 0.0, -0.0, 1.0, -1.0, 2.0, -2.0, 0.0, -0.0]])
    x = np.concatenate([x, [0.0, 0.0, -0.0, -0.0, 0.0, -0.0, -3.0, -3.0, 5.0, 5.0]])
    want = K.arctan2(y, x, out=np.empty_like(y))
    listed = np.concatenate([K.arctan2(y[i:i + 3].tolist(), x[i:i + 3].tolist()) for i in range(0, len(y), 3)])
    alone = np.array([K.arctan2(a, b) for a, b in zip(y.tolist(), x.tolist())])
    for got in (listed, alone):
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(np.signbit(got), np.signbit(want))


def _one_vs_batch(func, q, *args):
    """func on one quaternion (the Python-float path) and on a batch of one (the block path)."""
    return func(q, *args), func(q[None], *(np.asarray(a)[None] for a in args))[0]


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_one_quaternion_exp_log_power_equal_the_batch_path(rng, dtype):
    """One quaternion takes Python floats (math.log1p, math.atan2, math.sin and cos): within a
    few eps of the block path's result, relative to its norm, over random, near-identity,
    real, negative-real, zero and extreme-magnitude quaternions; specials agree exactly."""
    eps = float(np.finfo(dtype).eps)
    tiny = 4 * float(np.finfo(dtype).smallest_subnormal)   # results on the subnormal grid
    top = 250 if dtype == np.float64 else 30
    qs = list(random_quats(rng, (60,), np.float64) * 10.0 ** rng.uniform(-top, top, (60, 1)))
    qs += list(_near_identity(rng, 20))
    qs += [np.array(c, float) for c in ([1, 0, 0, 0], [-2, 0, 0, 0], [0, 0, 0, 3], [0.5, 0, 1e-200, 0])]
    def size(x):   # max |component|: a norm that does not underflow at 1e-200
        return float(np.max(np.abs(x)))

    with np.errstate(all="ignore"):
        for q in qs:
            q = q.astype(dtype)
            one, batch = _one_vs_batch(K.log, q)
            assert one.dtype == dtype
            np.testing.assert_allclose(one, batch, rtol=0, atol=4 * eps * size(batch) + tiny)
            if abs(float(q[0])) < 5:
                one, batch = _one_vs_batch(K.exp, q)
                np.testing.assert_allclose(one, batch, rtol=0, atol=6 * eps * size(batch) + tiny)
            ln = abs(float(np.log(np.max(np.abs(q.astype(float))))))
            for t in (0.3, -1.7, 2.0, 0.0):
                one, batch = _one_vs_batch(K.power, q, t)
                assert np.isfinite(one).all() == np.isfinite(batch).all()
                if np.isfinite(batch).all():   # exp(t ln|q|) turns an eps of t ln|q| into as many eps
                    tol = (8 + 2 * abs(t) * ln) * eps * size(batch) + tiny
                    np.testing.assert_allclose(one, batch, rtol=0, atol=tol)
        zero = np.zeros(4, dtype)
        for t in (2.0, 0.0, -1.0):
            np.testing.assert_array_equal(*_one_vs_batch(K.power, zero, t))
        np.testing.assert_array_equal(*_one_vs_batch(K.log, zero))


def test_one_quaternion_normalize_equals_the_batch_path(rng, dtype):
    """One quaternion takes Python floats, the block path's operations in the same order:
    float64 bit for bit at any magnitude, float32 within an eps; zero and non-finite raise."""
    top = 300 if dtype == np.float64 else 30
    qs = (random_quats(rng, (80,), np.float64) * 10.0 ** rng.uniform(-top, top, (80, 1))).astype(dtype)
    batch = K.normalize(qs)
    one = np.array([K.normalize(q) for q in qs])
    assert one.dtype == dtype
    if dtype == np.float64:
        np.testing.assert_array_equal(one, batch)
    else:
        np.testing.assert_allclose(one, batch, rtol=0, atol=np.finfo(dtype).eps)
    for bad, match in (([0, 0, 0, 0], "non-zero"), ([np.nan, 1, 0, 0], "finite"), ([0, np.inf, 0, 0], "finite")):
        with pytest.raises(ValueError, match=match):
            K.normalize(np.array(bad, dtype))


@pytest.mark.parametrize("dtype", [np.float32, np.float64], ids=["f32", "f64"])
def test_dot_and_sqnorm_sum_in_component_order_whatever_the_layout(rng, dtype):
    """dot and sqnorm add the four products in component order (`_scale.squares`' order):
    the same bits for a Fortran-ordered or strided batch, a broadcast operand and one pair."""
    p, q = (rng.standard_normal((3000, 4)) * 10.0 ** rng.uniform(-3, 3, (3000, 1))).astype(dtype), \
        rng.standard_normal((3000, 4)).astype(dtype)
    terms = p * q
    want = ((terms[:, 0] + terms[:, 1]) + terms[:, 2]) + terms[:, 3]
    assert want.dtype == dtype
    np.testing.assert_array_equal(K.dot(p, q), want)
    np.testing.assert_array_equal(K.dot(np.asfortranarray(p), q), want)
    np.testing.assert_array_equal(K.dot(np.repeat(p, 2, axis=0)[::2], q), want)
    np.testing.assert_array_equal(K.dot(p, q[7]), K.dot(p, np.broadcast_to(q[7], p.shape).copy()))
    assert K.dot(p[5], q[5]) == want[5]
    sq = p * p
    np.testing.assert_array_equal(K.sqnorm(np.asfortranarray(p)), ((sq[:, 0] + sq[:, 1]) + sq[:, 2]) + sq[:, 3])
