"""Shared fixtures: a seeded rng, random unit quaternions, an edge-case sampler,
and hypothesis profiles (derandomised and small under CI)."""

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

settings.register_profile(
    "ci", max_examples=60, derandomize=True, deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile("dev", max_examples=200, deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

DTYPES = (np.float32, np.float64)
BATCH_SHAPES = ((), (5,), (3, 4), (2, 3, 2))


def tol(dtype, factor=50):
    """Absolute tolerance derived from the dtype's machine epsilon."""
    return factor * np.finfo(dtype).eps


def random_quats(rng, shape=(), dtype=np.float64, unit=True):
    """Random quaternions of batch `shape` (uniform on S^3 when `unit`)."""
    q = rng.standard_normal(tuple(shape) + (4,))
    if unit:
        q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return q.astype(dtype)


def hamilton_reference(p, q):
    """The per-component product formula (independent of the complex-pair kernel)."""
    w1, x1, y1, z1 = np.moveaxis(p, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(q, -1, 0)
    return np.stack([
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ], axis=-1)


def edge_quats(dtype=np.float64):
    """Edge cases: identity, basis elements, their negatives, a 180-degree
    rotation, tiny rotations and a random unit quaternion."""
    e = np.eye(4)
    tiny = np.array([1.0, 1e-9, 0.0, 0.0])
    tiny /= np.linalg.norm(tiny)
    half = np.array([0.0, 1.0, 1.0, 1.0]) / np.sqrt(3)
    rnd = np.array([0.3, -0.5, 0.7, 0.1])
    rnd /= np.linalg.norm(rnd)
    return np.concatenate([e, -e, [tiny, half, rnd]]).astype(dtype)


@pytest.fixture
def rng():
    return np.random.default_rng(20261121)


@pytest.fixture(params=DTYPES, ids=["f32", "f64"])
def dtype(request):
    return request.param


@pytest.fixture(params=BATCH_SHAPES, ids=lambda s: f"batch{len(s)}")
def batch_shape(request):
    return request.param
