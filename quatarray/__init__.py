"""quatarray: vectorised NumPy arrays of quaternions.

`QuatArray` (alias `Rotation`, a drop-in for `scipy.spatial.transform.Rotation`),
keyframe interpolation (`lerp`, `nlerp`, `slerp`, `squad`, `bezier`, `Track`,
and scipy's `Slerp`), and `quatarray.testing` for assertions.
"""

from ._array import QuatArray
from .rigid import dual_quaternion_blend, normalize_dual_quaternion, sclerp
from .spline import RotationSpline
from .interpolate import Slerp, Track, bezier, bezier_control_points, lerp, nlerp, slerp, squad, squad_control_points, unflip

Rotation = QuatArray

__all__ = [
    "QuatArray", "Rotation", "Slerp", "Track",
    "lerp", "nlerp", "slerp", "squad", "squad_control_points", "bezier", "bezier_control_points", "unflip",
    "RotationSpline", "sclerp", "dual_quaternion_blend", "normalize_dual_quaternion",
]
__version__ = "0.1.0"
from ._rigid_transform import RigidTransform  # noqa: E402

__all__.append("RigidTransform")
