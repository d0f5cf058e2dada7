"""The scipy-compatible rotation surface of `QuatArray` (``quatarray.Rotation``).

`RotationMixin` gives `QuatArray` the names, arguments, defaults, angle
ranges, warnings and error types of ``scipy.spatial.transform.Rotation``
(scipy 1.17): ``from_*`` / ``as_*`` conversions, `apply`, `inv`, `magnitude`,
`approx_equal`, `mean`, `random`, `concatenate`, `align_vectors`, `single`,
and `from_scipy` / `to_scipy`.  Each method validates, calls a raw-array
kernel from `_convert` or `_kernels`, and wraps the result with
``cls._wrap``; the mixin never imports the class itself.

Storage stays scalar-first ``(w, x, y, z)``; the scipy-named methods keep
scipy's scalar-last default for ``from_quat`` / ``as_quat``.  A quaternion is
read as the rotation by ``q / |q|``.
"""

import warnings

import numpy as np

from . import _convert as C
from . import _euler as E
from . import _kernels as K
from ._validate import batch_shape, finite, float_array

__all__ = ["RotationMixin"]


def _raw(x):
    return x.view(np.ndarray)


def _scalar_last(q):
    """(..., 4) scalar-first -> a new scalar-last array."""
    out = np.empty(q.shape, q.dtype)
    out[..., 3] = q[..., 0]
    out[..., :3] = q[..., 1:]
    return out


def _default_atol(*dtypes):
    """1e-8 rad (scipy's default) in float64; 1e-5 rad (about 80 eps) if float32 is involved."""
    return 1e-8 if all(np.dtype(d) == np.float64 for d in dtypes) else 1e-5


class RotationMixin:
    """scipy ``Rotation`` methods for `QuatArray` (see the module docstring)."""

    # --- quaternions -----------------------------------------------------------------
    @classmethod
    def from_quat(cls, quat, *, scalar_first=False):
        """Rotations from quaternions, normalised (scipy's scalar-last default).

        Parameters
        ----------
        quat : array_like, shape (..., 4)
            Quaternions ``(x, y, z, w)``, or ``(w, x, y, z)`` with
            ``scalar_first=True``; float32 stays float32.
        scalar_first : bool, default False

        Returns
        -------
        QuatArray, shape (..., 4)
            Unit quaternions, stored scalar-first.

        Raises
        ------
        ValueError
            For a zero quaternion, NaN or infinite components, or a last axis
            other than 4.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_quat([0, 0, 1, 1])  # (x, y, z, w): 90° about z
        QuatArray([0.70710678, 0.        , 0.        , 0.70710678])
        """
        return cls._wrap(C.from_quat(quat, scalar_first=scalar_first))

    def as_quat(self, canonical=False, *, scalar_first=False):
        """The quaternions as a plain array (scipy's scalar-last default).

        Parameters
        ----------
        canonical : bool, default False
            Return the representative with w ≥ 0 (for w = 0, the first
            non-zero of x, y, z positive).
        scalar_first : bool, default False
            ``(w, x, y, z)`` instead of ``(x, y, z, w)``.

        Returns
        -------
        ndarray, shape (..., 4)
            A new array with the stored components (not renormalised).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_quat([0, 0, 0, -1])
        >>> r.as_quat(), r.as_quat(canonical=True)
        (array([ 0.,  0.,  0., -1.]), array([0., 0., 0., 1.]))
        >>> r.as_quat(scalar_first=True)
        array([-1.,  0.,  0.,  0.])
        """
        q = _raw(self)
        if canonical:
            q = C.canonical(q)
            return q if scalar_first else _scalar_last(q)
        return q.copy() if scalar_first else _scalar_last(q)

    # --- matrices, rotation vectors, MRPs -------------------------------------------------
    @classmethod
    def from_matrix(cls, matrix, *, assume_valid=False):
        """Rotations from rotation matrices (non-orthogonal ones projected to the nearest rotation).

        Parameters
        ----------
        matrix : array_like, shape (..., 3, 3)
        assume_valid : bool, default False
            Skip the determinant and orthogonality checks.

        Returns
        -------
        QuatArray, shape (..., 4)

        Raises
        ------
        ValueError
            For det ≤ 0, NaN or inf, or a wrong shape.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_matrix([[0, -1, 0], [1, 0, 0], [0, 0, 1]])
        >>> np.round(r.as_rotvec(degrees=True), 9)
        array([ 0.,  0., 90.])
        """
        return cls._wrap(C.from_matrix(matrix, assume_valid=assume_valid))

    def as_matrix(self):
        """Rotation matrices, shape (..., 3, 3).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> np.round(Rotation.from_euler("z", 90, degrees=True).as_matrix(), 12) + 0.0
        array([[ 0., -1.,  0.],
               [ 1.,  0.,  0.],
               [ 0.,  0.,  1.]])
        """
        return C.as_matrix(_raw(self))

    @classmethod
    def from_rotvec(cls, rotvec, degrees=False):
        """Rotations from rotation vectors (axis × angle).

        Parameters
        ----------
        rotvec : array_like, shape (..., 3)
        degrees : bool, default False

        Returns
        -------
        QuatArray, shape (..., 4)

        Examples
        --------
        >>> from quatarray import Rotation
        >>> np.round(Rotation.from_rotvec([0, 0, np.pi / 2]).as_quat(), 6)
        array([0.      , 0.      , 0.707107, 0.707107])
        """
        return cls._wrap(C.from_rotvec(rotvec, degrees=degrees))

    def as_rotvec(self, degrees=False):
        """Rotation vectors, shape (..., 3), angle (the norm) in [0, π].

        Accurate for angles down to 1e-12 rad and up to π.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_euler("x", 1e-9).as_rotvec()
        array([1.e-09, 0.e+00, 0.e+00])
        """
        return C.as_rotvec(_raw(self), degrees=degrees)

    @classmethod
    def from_mrp(cls, mrp):
        """Rotations from modified Rodrigues parameters ``axis · tan(angle / 4)``.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> np.round(Rotation.from_mrp([0, 0, 1]).as_rotvec(), 12)
        array([0.        , 0.        , 3.14159265])
        """
        return cls._wrap(C.from_mrp(mrp))

    def as_mrp(self):
        """Modified Rodrigues parameters, shape (..., 3), norm ≤ 1.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> np.round(Rotation.from_rotvec([0, 0, np.pi / 2]).as_mrp(), 12)
        array([0.        , 0.        , 0.41421356])
        """
        return C.as_mrp(_raw(self))

    # --- Euler and Davenport angles ------------------------------------------------------
    @classmethod
    def from_euler(cls, seq, angles, degrees=False):
        """Rotations from Euler angles.

        Parameters
        ----------
        seq : str
            1 to 3 axes: ``'xyz'`` extrinsic (fixed axes) or ``'XYZ'``
            intrinsic (rotating axes); no mixing, no axis twice in a row.
        angles : array_like, shape (..., len(seq))
        degrees : bool, default False

        Returns
        -------
        QuatArray, shape (..., 4)

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_euler("zyx", [[90, 0, 0], [0, 45, 0]], degrees=True)
        >>> np.round(r.as_rotvec(degrees=True), 9) + 0.0
        array([[ 0.,  0., 90.],
               [ 0., 45.,  0.]])
        """
        return cls._wrap(E.from_euler(seq, angles, degrees=degrees))

    def as_euler(self, seq, degrees=False, *, suppress_warnings=False):
        """Euler angles, shape (..., 3), in scipy's ranges and with its gimbal-lock warning.

        Parameters
        ----------
        seq : str
            3 axes, ``'xyz'`` extrinsic or ``'XYZ'`` intrinsic.
        degrees : bool, default False
        suppress_warnings : bool, default False

        Returns
        -------
        ndarray, shape (..., 3)
            First and third angles in [-π, π]; the second in [0, π]
            (symmetric sequences such as ``'zxz'``) or [-π/2, π/2].

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_euler("ZXY", [30, 20, 10], degrees=True)
        >>> np.round(r.as_euler("ZXY", degrees=True), 9)
        array([30., 20., 10.])
        """
        return E.as_euler(_raw(self), seq, degrees=degrees, suppress_warnings=suppress_warnings)

    @classmethod
    def from_davenport(cls, axes, order, angles, degrees=False):
        """Rotations from Davenport angles (Euler angles about any orthogonal-consecutive axes).

        Parameters
        ----------
        axes : array_like, shape (3,) or (n, 3), n ≤ 3
        order : {'e', 'extrinsic', 'i', 'intrinsic'}
        angles : array_like, shape (..., n)
        degrees : bool, default False

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_davenport([[0, 0, 1], [1, 0, 0]], "e", [90, 45], degrees=True)
        >>> bool(r.approx_equal(Rotation.from_euler("zx", [90, 45], degrees=True)))
        True
        """
        return cls._wrap(E.from_davenport(axes, order, angles, degrees=degrees))

    def as_davenport(self, axes, order, degrees=False, *, suppress_warnings=False):
        """Davenport angles about three axes (the middle one orthogonal to the others).

        Parameters
        ----------
        axes : array_like, shape (3, 3)
        order : {'e', 'extrinsic', 'i', 'intrinsic'}
        degrees : bool, default False
        suppress_warnings : bool, default False

        Returns
        -------
        ndarray, shape (..., 3)

        Examples
        --------
        >>> from quatarray import Rotation
        >>> ez, ex, ey = [0, 0, 1], [1, 0, 0], [0, 1, 0]
        >>> r = Rotation.from_davenport([ez, ex, ey], "e", [90, 30, 10], degrees=True)
        >>> np.round(r.as_davenport([ez, ex, ey], "e", degrees=True), 9)
        array([90., 30., 10.])
        """
        return E.as_davenport(_raw(self), axes, order, degrees=degrees,
                              suppress_warnings=suppress_warnings)

    # --- acting on vectors, inverting, measuring -------------------------------------------
    def apply(self, vectors, inverse=False):
        """Rotate vectors, broadcasting batch shapes as scipy 1.17 does.

        Parameters
        ----------
        vectors : array_like, shape (..., 3)
            The rotations' batch shape and the vectors' batch shape broadcast
            (one rotation and many vectors, many rotations and one vector,
            N and N pairwise, or any NumPy broadcast).
        inverse : bool, default False
            Apply the inverse rotations.

        Returns
        -------
        ndarray, shape (broadcast batch, 3)

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_euler("z", [[0], [90]], degrees=True)
        >>> np.round(r.apply([1, 0, 0]), 12) + 0.0
        array([[1., 0., 0.],
               [0., 1., 0.]])
        """
        v = finite(float_array(vectors, "vectors"), "vectors")
        q = _raw(self)
        if v.shape == (3,) and q.shape == (4,):
            return K.rotate(q, v, inverse)
        if v.ndim == 0 or v.shape[-1] != 3:
            raise ValueError(f"Expected input of shape (..., 3): expected vectors of shape (..., 3), got {v.shape}")
        try:
            np.broadcast_shapes(q.shape[:-1], v.shape[:-1])
        except ValueError:
            raise ValueError(f"Cannot broadcast {q.shape[:-1]} rotations to {v.shape[:-1]} vectors: "
                             f"expected batch shapes that broadcast") from None
        return K.rotate(q, v, inverse=inverse)

    def inv(self):
        """Inverse rotations (the conjugates; norms are kept).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_rotvec([0, 0, 1])
        >>> r.inv().as_rotvec() + 0.0
        array([ 0.,  0., -1.])
        """
        return self._wrap(K.conjugate(finite(_raw(self), "rotations")))

    def magnitude(self):
        """Rotation angles in [0, π] (a NumPy scalar for a single rotation).

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.from_rotvec([[0, 0, 1], [0, 4, 0]]).magnitude()
        array([1.        , 2.28318531])
        """
        out = C.magnitude(_raw(self))
        return out[()] if out.ndim == 0 else out

    def approx_equal(self, other, atol=None, degrees=False):
        """Whether the angle between each pair of rotations is below `atol`.

        Parameters
        ----------
        other : QuatArray
            Rotations whose batch shape broadcasts with this one's.
        atol : float, optional
            Default 1e-8 rad (float64; 1e-5 rad when either side is
            float32).  With ``degrees=True`` and no `atol`, the default is
            used and a `UserWarning` issued, as in scipy.
        degrees : bool, default False

        Returns
        -------
        ndarray of bool (batch shape), or a NumPy bool for single rotations

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_rotvec([0, 0, 1])
        >>> r.approx_equal(Rotation.from_rotvec([0, 0, 1 + 1e-10]))
        np.True_
        >>> r.approx_equal(Rotation.from_rotvec([0, 0, 1.1]), atol=5, degrees=True)
        np.False_
        """
        if not isinstance(other, RotationMixin):
            raise TypeError(f"expected other to be a Rotation (QuatArray), got {type(other).__name__}")
        p, q = _raw(self), _raw(other)
        if atol is None:
            if degrees:
                warnings.warn("atol must be set to use the degrees flag, defaulting to 1e-8 radians.",
                              UserWarning, stacklevel=2)
            atol = _default_atol(p.dtype, q.dtype)
        elif degrees:
            atol = np.deg2rad(atol)
        try:
            np.broadcast_shapes(p.shape[:-1], q.shape[:-1])
        except ValueError:
            raise ValueError(f"Expected broadcastable shapes in both rotations, got {p.shape[:-1]} "
                             f"rotations in first and {q.shape[:-1]} rotations in second object") from None
        angle = C.magnitude(K.multiply(q, K.conjugate(p)))
        res = angle < atol
        return res[()] if res.ndim == 0 else res

    # --- averaging, sampling, stacking, fitting ---------------------------------------------
    def mean(self, weights=None, axis=None):
        """Chordal L2 mean: the dominant eigenvector of Σ wᵢ qᵢ qᵢᵀ (one 4x4 eigh per mean).

        Parameters
        ----------
        weights : array_like, optional
            Non-negative, broadcastable to the batch shape.
        axis : None, int or tuple of ints, optional
            Batch axes to average over (default: all).

        Returns
        -------
        QuatArray
            The mean rotations (canonical sign, w ≥ 0); a single rotation
            when every axis is reduced.

        Raises
        ------
        ValueError
            For an empty set, a zero quaternion, NaN or inf in a quaternion,
            negative or non-finite weights, weights that do not broadcast, or
            a bad `axis`.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.from_euler("z", [[0], [10], [20]], degrees=True)
        >>> np.round(r.mean().as_euler("zyx", degrees=True), 9) + 0.0
        array([10.,  0.,  0.])
        """
        q = _raw(self)
        if q.ndim == 1:
            q = q[None]
        batch = q.shape[:-1]
        nb = len(batch)
        if axis is None:
            axes = tuple(range(nb))
        elif isinstance(axis, (int, np.integer)) and not isinstance(axis, bool):
            axes = (int(axis),)
        elif isinstance(axis, tuple) and all(isinstance(a, (int, np.integer)) for a in axis):
            axes = tuple(int(a) for a in axis)
        else:
            raise ValueError(f"`axis` must be None, int, or tuple of ints, got {axis!r}")
        if any(not -nb <= a < nb for a in axes):
            raise ValueError(f"axis {axis} is out of bounds for rotation with shape {batch}")
        axes = tuple(sorted({a % nb for a in axes}))
        if any(batch[a] == 0 for a in axes):
            raise ValueError(f"Mean of an empty rotation set is undefined: expected at least one "
                             f"rotation along axis {axes}, got shape {batch}")
        # Σ w q qᵀ of the rotations q/|q| (normalised at any magnitude; nan, inf and zero refused)
        q64 = C.from_quat(q.astype(np.float64, copy=False), scalar_first=True, name="rotations to average")
        scale = np.ones(batch)
        if weights is not None:
            w = float_array(weights, "weights").astype(np.float64)
            if not np.isfinite(w).all():
                raise ValueError("expected finite weights, got nan or inf")
            if (w < 0).any():
                raise ValueError("`weights` must be non-negative.")
            try:
                if np.broadcast_shapes(w.shape, batch) != batch:
                    raise ValueError
            except ValueError:
                raise ValueError(f"Expected `weights` to be broadcastable to rotation shape: "
                                 f"got weights of shape {w.shape} for rotations of shape {batch}") from None
            scale = scale * w
        wq = q64 * scale[..., None]
        keep = tuple(a for a in range(nb) if a not in axes)
        order = keep + axes + (nb,)
        kshape = tuple(batch[a] for a in keep)
        qm = q64.transpose(order).reshape(kshape + (-1, 4))
        wm = wq.transpose(order).reshape(kshape + (-1, 4))
        k = np.matmul(np.swapaxes(wm, -1, -2), qm)
        _, vectors = np.linalg.eigh(k)
        return self._wrap(C.canonical(vectors[..., -1]).astype(q.dtype))

    @classmethod
    def random(cls, num=None, rng=None, *, shape=None):
        """Rotations uniform on SO(3) (Haar measure): normalised Gaussian 4-vectors.

        With the same `rng` seed, the same rotations as scipy's
        ``Rotation.random``.

        Parameters
        ----------
        num : int, optional
            Number of rotations (a batch of shape ``(num,)``); default one.
        rng : numpy.random.Generator or seed, optional
        shape : int or tuple of ints, optional
            Batch shape (instead of `num`).

        Returns
        -------
        QuatArray, float64

        Examples
        --------
        >>> from quatarray import Rotation
        >>> Rotation.random(3, rng=0).shape
        (3, 4)
        >>> Rotation.random(shape=(2, 5), rng=1).batch_shape
        (2, 5)
        """
        size = batch_shape(num, shape)
        if not isinstance(rng, (np.random.Generator, np.random.RandomState)):
            try:
                rng = np.random.default_rng(rng)
            except (TypeError, ValueError):
                raise ValueError(f"expected rng to be a numpy.random.Generator, a RandomState, None or a "
                                 f"non-negative int seed, got {rng!r}") from None
        return cls.from_quat(rng.normal(size=size + (4,)))

    @classmethod
    def concatenate(cls, rotations):
        """Stack rotations along the first batch axis (single rotations count as one).

        Parameters
        ----------
        rotations : QuatArray or sequence of QuatArray

        Returns
        -------
        QuatArray
            A copy; float32 only if every input is float32.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r = Rotation.concatenate([Rotation.identity(), Rotation.random(2, rng=0)])
        >>> r.batch_shape
        (3,)
        """
        if isinstance(rotations, RotationMixin):
            return cls._wrap(_raw(rotations).copy())
        rotations = list(rotations)
        for i, r in enumerate(rotations):
            if not isinstance(r, RotationMixin):
                raise TypeError(f"input must contain Rotation objects only: expected QuatArray "
                                f"rotations, got {type(r).__name__} at position {i}")
        if not rotations:
            raise ValueError("expected at least one rotation to concatenate, got an empty sequence")
        return cls._wrap(np.concatenate([np.atleast_2d(_raw(r)) for r in rotations]))

    @classmethod
    def align_vectors(cls, a, b, weights=None, return_sensitivity=False):
        """The rotation that best maps vectors `b` onto vectors `a` (Kabsch / Wahba), as scipy.

        Parameters
        ----------
        a, b : array_like, shape (3,) or (N, 3)
        weights : array_like, shape (N,), optional
            Non-negative; one infinite weight makes that pair exact (and
            the others are fitted about it), as in scipy.
        return_sensitivity : bool, default False

        Returns
        -------
        rotation : QuatArray, single
        rssd : float
            Root of the weighted sum of squared distances after alignment.
        sensitivity : ndarray, shape (3, 3)
            Only with ``return_sensitivity=True``.

        Examples
        --------
        >>> from quatarray import Rotation
        >>> r, rssd = Rotation.align_vectors([[0, 1, 0], [-1, 0, 0]], [[1, 0, 0], [0, 1, 0]])
        >>> np.round(r.as_rotvec(degrees=True), 9) + 0.0, round(float(rssd), 9)
        (array([ 0.,  0., 90.]), 0.0)
        """
        q, rssd, sens = _align(a, b, weights, return_sensitivity)
        rot = cls._wrap(q)
        return (rot, rssd, sens) if return_sensitivity else (rot, rssd)

    @property
    def single(self):
        """True for a single rotation (shape (4,)), as scipy's ``single``.

        >>> from quatarray import Rotation
        >>> Rotation.identity().single, Rotation.identity(1).single
        (True, False)
        """
        return self.ndim == 1

    # --- scipy interoperability ---------------------------------------------------------------
    @classmethod
    def from_scipy(cls, r):
        """A `QuatArray` from a ``scipy.spatial.transform.Rotation`` (float64, any shape).

        >>> from scipy.spatial.transform import Rotation as R
        >>> from quatarray import QuatArray
        >>> QuatArray.from_scipy(R.from_rotvec([0, 0, np.pi]))
        QuatArray([6.123234e-17, 0.000000e+00, 0.000000e+00, 1.000000e+00])
        """
        from scipy.spatial.transform import Rotation as ScipyRotation
        if not isinstance(r, ScipyRotation):
            raise TypeError(f"expected a scipy.spatial.transform.Rotation, got {type(r).__name__}")
        return cls._wrap(np.array(r.as_quat(scalar_first=True), dtype=np.float64))

    def to_scipy(self):
        """This rotation as a ``scipy.spatial.transform.Rotation`` (float64, normalised by scipy).

        >>> from quatarray import Rotation
        >>> Rotation.from_euler("x", 30, degrees=True).to_scipy().as_euler("xyz", degrees=True)
        array([30.,  0.,  0.])
        """
        from scipy.spatial.transform import Rotation as ScipyRotation
        q = C.from_quat(_raw(self).astype(np.float64), scalar_first=True, name="rotations")
        return ScipyRotation.from_quat(q, scalar_first=True)


def _align(a, b, weights, return_sensitivity):
    """`align_vectors` on float64 arrays; returns (quat scalar-first, rssd, sensitivity or None)."""
    a0 = float_array(a, "a")
    b0 = float_array(b, "b")
    dtype = np.result_type(a0.dtype, b0.dtype)
    a2 = np.atleast_2d(a0).astype(np.float64)
    b2 = np.atleast_2d(b0).astype(np.float64)
    if a2.ndim != 2 or a2.shape[-1] != 3:
        raise ValueError(f"Expected input `a` to have shape (3,) or (N, 3), got {a0.shape}")
    if b2.ndim != 2 or b2.shape[-1] != 3:
        raise ValueError(f"Expected input `b` to have shape (3,) or (N, 3), got {b0.shape}")
    if a2.shape != b2.shape:
        raise ValueError(f"Expected inputs `a` and `b` to have same shapes, got {a0.shape} and {b0.shape} respectively")
    n = a2.shape[0]
    if n == 0:
        raise ValueError("expected at least one pair of vectors in a and b, got 0")
    if not (np.isfinite(a2).all() and np.isfinite(b2).all()):
        raise ValueError("expected finite values in a and b, got nan or inf")
    if weights is None:
        w = np.ones(n)
    else:
        w = float_array(weights, "weights").astype(np.float64)
        if w.ndim != 1:
            raise ValueError(f"Expected `weights` to be 1 dimensional, got shape {w.shape}")
        if n > 1 and w.shape[0] != n:
            raise ValueError(f"Expected `weights` to have number of values equal to number of input "
                             f"vectors, got {w.shape[0]} values and {n} vectors")
        if np.isnan(w).any() or (w < 0).any():
            raise ValueError("`weights` may not contain negative values: expected non-negative weights")
    inf = np.array([True]) if n == 1 else np.isposinf(w)
    n_inf = int(inf.sum())
    if n_inf > 1:
        raise ValueError("Only one infinite weight is allowed")
    if n_inf == 1:
        if return_sensitivity:
            raise ValueError("Cannot return sensitivity matrix with an infinite weight or one vector pair")
        q, rssd = _align_primary(a2, b2, w, inf)
        return q.astype(dtype), rssd, None
    big = (w[:, None] * a2).T @ b2
    u, s, vt = np.linalg.svd(big)
    if np.linalg.det(u @ vt) < 0:
        s[-1] = -s[-1]
        u[:, -1] = -u[:, -1]
    rot = u @ vt
    if s[1] + s[2] < 1e-16 * s[0]:
        warnings.warn("Optimal rotation is not uniquely or poorly defined for the given sets of vectors.",
                      UserWarning, stacklevel=3)
    rssd = np.sqrt(max(np.sum(w * np.sum(b2 ** 2 + a2 ** 2, axis=1)) - 2 * np.sum(s), 0.0))
    sens = None
    if return_sensitivity:
        zeta = (s[0] + s[1]) * (s[1] + s[2]) * (s[2] + s[0])
        kappa = s[0] * s[1] + s[1] * s[2] + s[2] * s[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            sens = np.mean(w) / zeta * (kappa * np.eye(3) + big @ big.T)
    q = C.from_matrix(rot, assume_valid=True)
    return q.astype(dtype), rssd, sens


def _align_primary(a, b, w, inf):
    """The infinite-weight (or single-pair) case: align the primary pair exactly,
    then turn about it to fit the others best (scipy's algorithm)."""
    a_pri, b_pri = a[inf][0], b[inf][0]
    na, nb = np.linalg.norm(a_pri), np.linalg.norm(b_pri)
    if na == 0 or nb == 0:
        raise ValueError("Cannot align zero length primary vectors")
    a_pri, b_pri = a_pri / na, b_pri / nb
    # shortest-arc rotation taking b_pri to a_pri (antiparallel: π about any orthogonal axis)
    cross = np.cross(b_pri, a_pri)
    theta = np.arctan2(np.linalg.norm(cross), a_pri @ b_pri)
    if np.linalg.norm(cross) == 0 and theta > np.pi / 2:
        i = int(np.argmin(np.abs(a_pri)))
        axis = np.zeros(3)
        axis[i - 1], axis[i - 2] = a_pri[i - 2], -a_pri[i - 1]
        axis /= np.linalg.norm(axis)
    else:
        norm = np.linalg.norm(cross)
        axis = cross / norm if norm > 0 else np.array([1.0, 0, 0])
    q_pri = C.from_rotvec(axis * theta)
    q = q_pri
    if a.shape[0] > 1:
        sec = ~inf
        a_sec, b_sec, w_sec = a[sec], b[sec], w[sec]
        c_sec = K.rotate(q_pri, b_sec)
        sin_term = np.einsum("ij,j->i", np.cross(c_sec, a_sec), a_pri)
        cos_term = np.einsum("ij,ij->i", c_sec, a_sec) - (c_sec @ a_pri) * (a_sec @ a_pri)
        phi = np.arctan2(np.sum(w_sec * sin_term), np.sum(w_sec * cos_term))
        q = K.multiply(C.from_rotvec(phi * a_pri), q_pri)
    w_zero = w.copy()
    if a.shape[0] > 1 or np.isposinf(w[0]):
        w_zero[inf] = 0
    est = K.rotate(q, b)
    rssd = np.sqrt(np.sum(w_zero @ (a - est) ** 2))
    return q, rssd
