"""Raw coefficients of SO(3)'s left Jacobian, its inverse and its derivative, as functions of the angle.

With ``φ = θ k`` a rotation vector (``k`` its unit axis) and ``[φ]×`` its
cross-product matrix, the left Jacobian and its inverse are

    J(φ)  = I + (1 - cos θ)/θ² [φ]× + (θ - sin θ)/θ³ [φ]×²
    J⁻¹(φ) = I - ½ [φ]× + (1 - θ/2 cot(θ/2))/θ² [φ]×²

The rotation spline multiplies these coefficients by ``[φ]×`` (``power=2``);
rigid transforms multiply them by ``[k]×`` (``power`` one or two lower), which
keeps every coefficient bounded where θ² or θ³ would overflow.  Each coefficient
is written once here, for both.

Near θ = 0 the closed forms cancel (1 - sin θ/θ loses about 2 log10(1/θ) digits),
so below `SMALL` a three-term Taylor series replaces them.  Measured against
mpmath over θ in [1e-8, 1e-1] (float64), the relative error is at most 4e-16
for (1 - cos θ)/θ², 9e-10 for (θ - sin θ)/θ³ and 2e-9 for the inverse's
coefficient; scipy's rotation spline switches at 1e-4 with two terms and
1 - cos θ, which gives 1e-8, 4e-8 and 1e-7 there.
"""

import math

import numpy as np

__all__ = ["SMALL", "DERIVATIVE_SMALL", "one_minus_cos", "one_minus_sinc", "one_minus_half_cot", "derivative"]

#: Angles below this take the Taylor series instead of the closed forms (scipy's RigidTransform's
#: cut-off; with three terms the series is within an ulp up to it).
SMALL = 1e-3


def _piecewise(theta, cut, series, closed, limit=None):
    """``series(θ)`` where θ < `cut`, ``closed(θ)`` elsewhere (`limit` where θ is infinite, if
    given), element by element; `series` and `closed` may return tuples (of as many arrays),
    taken the same way term by term.  Each branch runs only when some element needs it (a
    spline's keys are usually all on one side: half the passes), and where both do, each
    on the angles of the other replaced by a harmless value (0, 1), so that neither warns
    (inf - inf, 0/0) where it is not used; an element's value is its branch's either way."""
    small = theta < cut
    if small.all():
        return series(theta)
    huge = np.isinf(theta) if limit is not None else None
    far = huge is not None and huge.any()
    if not small.any():
        value = closed(np.where(huge, 1.0, theta) if far else theta)
        return _where(huge, limit, value) if far else value
    value = closed(np.where(small | huge if far else small, 1.0, theta))
    if far:
        value = _where(huge, limit, value)
    return _where(small, series(np.where(small, theta, 0.0)), value)


def _where(mask, a, b):
    """``np.where(mask, a, b)``, term by term where `b` is a tuple (`a` then one too, or one
    value for every term)."""
    if type(b) is tuple:
        return tuple(np.where(mask, x, y) for x, y in zip(a if type(a) is tuple else (a,) * len(b), b))
    return np.where(mask, a, b)


def _coefficient(theta, power, c0, d1, d2, closed, limit):
    """``closed(θ) / θ**power`` where `closed` is ``θ² (c0 + θ²/d1 + θ⁴/d2 + ...)``: below
    `SMALL` its three Taylor terms times ``θ**(2 - power)``, `limit` where θ is infinite."""
    def series(ts):
        z = ts * ts
        return (c0 + z / d1 + z * z / d2) * ts ** (2 - power)
    return _piecewise(theta, SMALL, series, lambda th: closed(th) / th ** power, limit)


def one_minus_cos(theta, power):
    """``(1 - cos θ) / θ**power`` for angles ``theta`` (≥ 0, any shape); `power` is 1 or 2.

    Computed as ``2 sin²(θ/2)``, which does not cancel; 0 where θ is infinite.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import _jacobian
    >>> _jacobian.one_minus_cos(np.array([0.0, np.pi]), 2).tolist() == [0.5, 2 / np.pi ** 2]
    True
    """
    return _coefficient(theta, power, 0.5, -24, 720, lambda th: 2 * np.sin(th / 2) ** 2, 0.0)


def one_minus_sinc(theta, power):
    """``(1 - sin θ / θ) / θ**power`` for angles ``theta`` (≥ 0, any shape); `power` is 0 or 2.

    With ``power=2`` this is ``(θ - sin θ)/θ³``.  Where θ is infinite: 1 for ``power=0``, else 0.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import _jacobian
    >>> _jacobian.one_minus_sinc(np.array([0.0, np.inf]), 0).tolist()
    [0.0, 1.0]
    """
    return _coefficient(theta, power, 1 / 6, -120, 5040, lambda th: 1 - np.sin(th) / th, 1.0 if power == 0 else 0.0)


def one_minus_half_cot(theta, power):
    """``(1 - θ/2 cot(θ/2)) / θ**power`` for angles ``theta`` in [0, 2π); `power` is 0 or 2.

    The coefficient of ``[φ]×²`` in the inverse left Jacobian (``power=2``).

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import _jacobian
    >>> _jacobian.one_minus_half_cot(np.array([0.0, np.pi]), 0).tolist()
    [0.0, 1.0]
    """
    return _coefficient(theta, power, 1 / 12, 720, 30240, lambda th: 1 - 0.5 * th / np.tan(0.5 * th), np.nan)


def derivative(theta):
    """The coefficients of the rotation spline's angular acceleration term quadratic in ``dφ/dt``:
    ``(2 (1 - cos θ) - θ sin θ)/θ⁴`` and ``(3 sin θ - 2θ - θ cos θ)/θ⁵``, for finite θ ≥ 0.

    Their numerators are of order θ⁴ and θ⁵ and made of terms of order θ² and θ, so the
    closed forms lose about 130 eps/θ² and 180 eps/θ⁴ relative: below `DERIVATIVE_SMALL`
    (0.3) the Taylor series take over, five terms each.  Against mpmath over [1e-8, 3]
    both are within 2e-13 and 4e-12 relative (the largest just above 0.3).  scipy's closed
    forms down to 1e-4 and two-term series leave relative errors of 13 and 2e2 just above
    1e-4, and its series has 12604 where the coefficient is 1260.

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray import _jacobian
    >>> [c.tolist() for c in _jacobian.derivative(np.array([0.0]))] == [[1 / 12], [-1 / 60]]
    True
    """
    def closed(th):
        sn, cs = np.sin(th), np.cos(th)
        return (-th * sn - 2 * (cs - 1)) / th ** 4, (3 * sn - 2 * th - th * cs) / th ** 5

    def series(ts):
        z = ts * ts
        return _horner(_K1, z), _horner(_K2, z)

    return _piecewise(theta, DERIVATIVE_SMALL, series, closed)


def _horner(coefficients, z):
    """``c0 + c1 z + c2 z² + ...`` by Horner's rule (the highest degree first)."""
    acc = np.full_like(z, coefficients[-1])
    for c in coefficients[-2::-1]:
        acc = acc * z + c
    return acc


#: Below this angle `derivative` takes its series.
DERIVATIVE_SMALL = 0.3

# Taylor coefficients in z = θ²: (-1)^m (2m - 2) / (2m)! for m >= 2, and (-1)^n (2 - 2n) / (2n + 1)!
# for n >= 2 (from the series of sin and cos), five of each
_K1 = [(-1) ** m * (2 * m - 2) / math.factorial(2 * m) for m in range(2, 7)]
_K2 = [(-1) ** n * (2 - 2 * n) / math.factorial(2 * n + 1) for n in range(2, 7)]
