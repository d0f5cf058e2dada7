class RotationMixin:
    """Placeholder: the scipy-compatible rotation surface lands here (issue 3)."""
