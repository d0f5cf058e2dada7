"""Assertions for quaternion arrays.

`numpy.testing` applies componentwise ufuncs (``isinf``, ``abs``, ...) that
`QuatArray` refuses; these helpers compare the plain components instead, and
can compare rotations up to the double cover (q and -q are the same rotation).
"""

import numpy as np

__all__ = ["assert_allclose", "assert_array_equal"]


def _plain(a):
    return np.asarray(a.view(np.ndarray) if isinstance(a, np.ndarray) else a)


def assert_array_equal(actual, desired, err_msg=""):
    """`numpy.testing.assert_array_equal` on the components of quaternion arrays.

    >>> from quatarray.testing import assert_array_equal
    >>> from quatarray import QuatArray
    >>> assert_array_equal(QuatArray([1, 0, 0, 0]), [1, 0, 0, 0])
    """
    np.testing.assert_array_equal(_plain(actual), _plain(desired), err_msg=err_msg)


def assert_allclose(actual, desired, rtol=1e-7, atol=0.0, double_cover=False, err_msg=""):
    """`numpy.testing.assert_allclose` on quaternion components.

    With ``double_cover=True``, each quaternion of `actual` may match either
    the corresponding quaternion of `desired` or its negative (the same rotation).

    >>> from quatarray.testing import assert_allclose
    >>> from quatarray import QuatArray
    >>> assert_allclose(QuatArray([-1.0, 0, 0, 0]), [1, 0, 0, 0], double_cover=True)
    """
    a, d = _plain(actual), _plain(desired)
    if double_cover:
        a, d = np.broadcast_arrays(a, d)
        sign = np.where(np.sum(a * d, axis=-1, keepdims=True) < 0, -1, 1)
        a = a * sign
    np.testing.assert_allclose(a, d, rtol=rtol, atol=atol, err_msg=err_msg)
