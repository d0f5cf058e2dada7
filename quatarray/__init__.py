"""quatarray: vectorised NumPy arrays of quaternions.

`QuatArray`, an ndarray of scalar-first quaternions ``(..., 4)`` for quaternion
algebra; `Rotation`, scipy 1.17's ``scipy.spatial.transform.Rotation`` over a
`QuatArray` (``r.as_quatarray()`` and ``Rotation.from_quatarray(q)`` convert
without copying); keyframe interpolation (`lerp`, `nlerp`, `slerp`, `squad`,
`bezier`, `Track`, and scipy's `Slerp`, which returns `Rotation`); and
`quatarray.testing` for assertions.
`set_num_threads`, `get_num_threads` and `num_threads` control how many
threads long batches use.
"""

from . import _command  # noqa: F401  (first: a Ctrl-C while the command starts ends it quietly)
from . import testing
from ._array import QuatArray
from ._rotation import Rotation
from ._blocks import get_num_threads, num_threads, set_num_threads
from ._rigid_transform import RigidTransform
from .rigid import RigidTrack, dual_quaternion_blend, normalize_dual_quaternion, sclerp
from .spline import RotationSpline
from .interpolate import Slerp, Track, bezier, bezier_control_points, lerp, nlerp, slerp, squad, squad_control_points, unflip
from .timeseries import (ReducedKeys, angular_velocity, fill_gaps, geodesic_mean, integrate_angular_velocity,
                         minimal_rotation, reduce_keys, smooth, swing_twist)

__all__ = [
    "QuatArray", "Rotation", "Slerp", "Track",
    "lerp", "nlerp", "slerp", "squad", "squad_control_points", "bezier", "bezier_control_points", "unflip",
    "RotationSpline", "RigidTransform", "RigidTrack", "sclerp", "dual_quaternion_blend", "normalize_dual_quaternion",
    "set_num_threads", "get_num_threads", "num_threads",
    "reduce_keys", "ReducedKeys", "integrate_angular_velocity", "angular_velocity", "minimal_rotation",
    "swing_twist", "geodesic_mean", "smooth", "fill_gaps",
    "testing",
]
__version__ = "0.1.0"
