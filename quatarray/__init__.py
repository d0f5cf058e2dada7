"""quatarray: vectorised NumPy arrays of quaternions."""

from ._array import QuatArray

Rotation = QuatArray

__all__ = ["QuatArray", "Rotation"]
__version__ = "0.1.0"
