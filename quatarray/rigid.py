"""Rigid motions as unit dual quaternions: ScLERP, blending, normalisation.

The public functions take dual quaternions of shape ``(..., 8)`` in scipy's
layout (``RigidTransform.as_dual_quat``): the real quaternion then the dual
quaternion, each scalar-last unless ``scalar_first=True``.  They validate,
reorder to the scalar-first raw layout of `_dualquat`, call it, and reorder
back; float32 stays float32.
"""

import numpy as np

from . import _dualquat
from . import _track
from ._validate import choice, finite, float_array

__all__ = ["sclerp", "dual_quaternion_blend", "normalize_dual_quaternion", "RigidTrack"]

_TO_FIRST = [3, 0, 1, 2, 7, 4, 5, 6]
_TO_LAST = [1, 2, 3, 0, 5, 6, 7, 4]


def _dual(x, name, scalar_first):
    a = finite(float_array(x, name, last=8), name)
    return a if scalar_first else a[..., _TO_FIRST]


def _out(dq, scalar_first):
    return dq if scalar_first else dq[..., _TO_LAST]


def normalize_dual_quaternion(dual_quat, *, scalar_first=False):
    """The nearest unit dual quaternions (scipy's private helper, made public).

    The real part is scaled to unit norm (a zero real part becomes the
    identity) and the dual part is made orthogonal to it.

    Parameters
    ----------
    dual_quat : array_like, shape (..., 8)
    scalar_first : bool, default False

    Returns
    -------
    ndarray, shape (..., 8)

    Examples
    --------
    >>> from quatarray import normalize_dual_quaternion
    >>> normalize_dual_quaternion([0, 0, 0, 2, 0, 0, 0, 1])
    array([0., 0., 0., 1., 0., 0., 0., 0.])
    """
    return _out(_dualquat.normalize(_dual(dual_quat, "dual_quat", scalar_first)), scalar_first)


def sclerp(a, b, t, *, scalar_first=False):
    """Screw linear interpolation of rigid motions (dual-quaternion SLERP).

    The motion from ``a`` to ``b`` is a rotation about one fixed axis with a
    translation along it, traversed at constant angular and linear speed;
    ``t = 0`` gives ``a`` and ``t = 1`` gives ``b``.  Broadcasts like
    `quatarray.slerp`: the batches of ``a`` and ``b`` broadcast together and
    the axes of ``t`` come after them.

    Parameters
    ----------
    a, b : array_like, shape (..., 8)
        Unit dual quaternions (``RigidTransform.as_dual_quat`` layout).
    t : float or array_like
    scalar_first : bool, default False

    Returns
    -------
    ndarray, shape (broadcast batch, *t.shape, 8)

    Examples
    --------
    >>> from quatarray import sclerp
    >>> from scipy.spatial.transform import RigidTransform
    >>> a = RigidTransform.identity().as_dual_quat()
    >>> b = RigidTransform.from_translation([2.0, 0, 0]).as_dual_quat()
    >>> RigidTransform.from_dual_quat(sclerp(a, b, 0.25)).translation
    array([0.5, 0. , 0. ])
    """
    a = _dual(a, "a", scalar_first)
    b = _dual(b, "b", scalar_first)
    t = finite(float_array(t, "t"), "t")
    batch = np.broadcast_shapes(a.shape[:-1], b.shape[:-1])
    a = np.broadcast_to(a, batch + (8,))
    b = np.broadcast_to(b, batch + (8,))
    dtype = np.result_type(a.dtype, b.dtype)
    return _out(_dualquat.sclerp(_dualquat.normalize(a.astype(dtype)), _dualquat.normalize(b.astype(dtype)), t.astype(dtype)), scalar_first)


def dual_quaternion_blend(dual_quats, weights, *, axis=0, scalar_first=False):
    """Dual-quaternion linear blending (DLB), as used for skinning.

    The weighted sum of the dual quaternions along ``axis`` (each first taken
    in the hemisphere of the first one), normalised.  Close to the weighted
    mean motion when the motions are close; never leaves the rigid motions.

    Parameters
    ----------
    dual_quats : array_like, shape (..., 8)
    weights : array_like
        Shape ``(n,)`` for the ``n`` motions along ``axis``.
    axis : int, default 0
    scalar_first : bool, default False

    Returns
    -------
    ndarray, shape (batch without axis, 8)

    Examples
    --------
    >>> from quatarray import dual_quaternion_blend
    >>> from scipy.spatial.transform import RigidTransform
    >>> dq = RigidTransform.from_translation([[0.0, 0, 0], [4, 0, 0]]).as_dual_quat()
    >>> RigidTransform.from_dual_quat(dual_quaternion_blend(dq, [0.75, 0.25])).translation
    array([1., 0., 0.])
    """
    dq = _dual(dual_quats, "dual_quats", scalar_first)
    if dq.ndim < 2:
        raise ValueError(f"expected dual_quats of shape (n, ..., 8), got {dq.shape}")
    axis = int(axis)
    if not -(dq.ndim - 1) <= axis < dq.ndim - 1:
        raise ValueError(f"expected axis in [{-(dq.ndim - 1)}, {dq.ndim - 1}), got {axis}")
    axis %= dq.ndim - 1
    w = finite(float_array(weights, "weights"), "weights")
    if w.shape != (dq.shape[axis],):
        raise ValueError(f"expected weights of shape ({dq.shape[axis]},), got {w.shape}")
    return _out(_dualquat.blend(dq, w.astype(dq.dtype), axis=axis), scalar_first)


class RigidTrack:
    """Keyframes of rigid motions of a batch of bodies, interpolated in time by ScLERP.

    Between neighbouring keys each body moves along the screw from one key
    to the next at constant angular and linear speed (screw linear
    interpolation, `sclerp`): its rotation is the SLERP of the keys'
    rotations and its translation follows the screw, which is linear when
    the rotation does not change.

    Parameters
    ----------
    times : array_like, shape (K,)
        Key times: finite, strictly increasing, K >= 2.
    transforms : RigidTransform, shape (K, *batch)
        The keys, e.g. ``(K, bodies)``; float32 stays float32.
    extrapolate : {'raise', 'clamp', 'extend'}, default 'raise'
        Queries outside [times[0], times[-1]]: ``'raise'`` a ValueError,
        ``'clamp'`` to the end keys, or ``'extend'`` the first / last
        segment's screw motion.

    Notes
    -----
    Built on the same machinery as `quatarray.Track` (`_track`): one table
    of per-segment constants at construction, then per block of queries and
    bodies one segment lookup and a fixed number of batched kernels.

    Examples
    --------
    A body turning a quarter turn about z while moving 2 along z (a screw):

    >>> import numpy as np
    >>> from quatarray import RigidTransform, Rotation
    >>> from quatarray.rigid import RigidTrack
    >>> keys = RigidTransform.from_components([[0, 0, 0], [0, 0, 2.0]],
    ...                                       Rotation.from_euler('z', [[0], [90]], degrees=True))
    >>> track = RigidTrack([0.0, 1.0], keys)
    >>> pose = track(0.5)
    >>> np.round(pose.translation, 6)
    array([0., 0., 1.])
    >>> np.round(pose.rotation.as_euler('zyx', degrees=True), 6)
    array([45.,  0.,  0.])
    """

    def __init__(self, times, transforms, *, extrapolate="raise"):
        from ._rigid_transform import RigidTransform
        from .interpolate import EXTRAPOLATE, _prepared_keys

        if not isinstance(transforms, RigidTransform):
            raise TypeError(f"expected transforms to be a RigidTransform, got {type(transforms).__name__}")
        if transforms.single or len(transforms) < 2:
            got = "a single transform" if transforms.single else f"shape {transforms.shape}"
            raise ValueError(f"expected transforms of shape (K, ...) with K >= 2, got {got}")
        extrapolate = choice(extrapolate, "extrapolate", EXTRAPOLATE)
        # the rotation keys as Track prepares its keys (scaled, unflipped, then normalised)
        q, times = _prepared_keys(transforms.rotation.as_quat(scalar_first=True), times, "transforms")
        times = times.copy()
        times.flags.writeable = False
        t = np.asarray(transforms.translation, q.dtype)
        self._cls = RigidTransform
        self._timeline = _track.Timeline(times, extrapolate)
        self._batch = q.shape[1:-1]
        self._table = _track.rigid_table(q, t)

    @property
    def times(self):
        """Key times, shape (K,) (read-only float64)."""
        return self._timeline.times

    @property
    def extrapolate(self):
        """Behaviour outside the key times: 'raise', 'clamp' or 'extend'."""
        return self._timeline.extrapolate

    @property
    def batch_shape(self):
        """Batch shape of the bodies (the keys' shape after K)."""
        return self._batch

    @property
    def dtype(self):
        """float32 or float64: the dtype of the keys, and of every output."""
        return self._table.dtype

    def __len__(self):
        """Number of keys K."""
        return len(self._timeline.times)

    def __repr__(self):
        return (f"RigidTrack(K={len(self)}, batch_shape={self._batch}, "
                f"extrapolate={self.extrapolate!r}, dtype={self.dtype})")

    def __call__(self, t):
        """Interpolated transforms at times `t`.

        Parameters
        ----------
        t : array_like
            Query times, scalar or any shape.

        Returns
        -------
        RigidTransform, shape ``t.shape + batch_shape``

        Examples
        --------
        >>> import numpy as np
        >>> from quatarray import RigidTransform
        >>> from quatarray.rigid import RigidTrack
        >>> keys = RigidTransform.from_translation([[0, 0, 0], [1.0, 0, 0], [1.0, 2, 0]])
        >>> RigidTrack([0, 1, 2], keys)([0.5, 1.5]).translation
        array([[0.5, 0. , 0. ],
               [1. , 1. , 0. ]])
        """
        tshape, flat, _ = self._timeline.queries(t, "t")
        out = _track.evaluate(self._timeline, self._table, flat, _track.rigid_block, 7)
        shape = tshape + self._batch
        return self._cls._from_parts(out[..., :4].reshape(shape + (4,)), out[..., 4:].reshape(shape + (3,)),
                                     len(shape) == 0)
