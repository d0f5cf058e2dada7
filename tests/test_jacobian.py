"""SO(3) Jacobian coefficients (`quatarray._jacobian`) against 50-digit references."""

import mpmath as mp
import numpy as np
import pytest

from quatarray import _jacobian

THETA = np.concatenate([np.logspace(-8, np.log10(3.0), 400), [_jacobian.SMALL * (1 + 1e-12), _jacobian.SMALL,
                                                              _jacobian.DERIVATIVE_SMALL * (1 + 1e-12),
                                                              _jacobian.DERIVATIVE_SMALL]])


def _reference(f):
    mp.mp.dps = 50
    return np.array([float(f(mp.mpf(float(t)))) for t in THETA])


@pytest.mark.parametrize("name, f, tol", [
    ("one_minus_cos", lambda t: (1 - mp.cos(t)) / t**2, 1e-15),
    ("one_minus_sinc", lambda t: (t - mp.sin(t)) / t**3, 2e-9),
    ("one_minus_half_cot", lambda t: (1 - t / 2 * mp.cot(t / 2)) / t**2, 3e-9),
])
def test_jacobian_coefficients_against_mpmath(name, f, tol):
    """Each coefficient (``power=2``) within the bound its module states, on both sides of the
    series' cut-off."""
    got = getattr(_jacobian, name)(THETA, 2)
    np.testing.assert_allclose(got, _reference(f), rtol=tol, atol=0)


def test_acceleration_coefficients_against_mpmath():
    """The spline's acceleration coefficients: the closed forms cancel to 1e-3 and 3e-2 relative
    near 1e-3 (and scipy's to 13 and 2e2 near 1e-4); with the series below 0.3, 2e-13 and 4e-12."""
    k1, k2 = _jacobian.derivative(THETA)
    np.testing.assert_allclose(k1, _reference(lambda t: (2 * (1 - mp.cos(t)) - t * mp.sin(t)) / t**4),
                               rtol=3e-13, atol=0)
    np.testing.assert_allclose(k2, _reference(lambda t: (3 * mp.sin(t) - 2 * t - t * mp.cos(t)) / t**5),
                               rtol=6e-12, atol=0)
