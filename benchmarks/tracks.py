"""Keyframe tracks: K keys at unequal times, evaluated at M sorted query times."""

import numpy as np

from ._common import DTYPES, LIBS, Skip, adapter, rng

KEYS = [10, 10_000]
QUERIES = [10, 1_000_000]


def make_track(k, m, dtype, salt=41):
    """(times (K,), keys (K, 4) unflipped, queries (M,)) -- seeded, keys unit."""
    times = np.cumsum(rng(salt).uniform(0.5, 1.5, k)) - 1.0
    times[0] = 0.0
    times = times.astype(np.float32).astype(np.float64)  # float32 queries stay inside [t0, t_end]
    # neighbouring keys within about 60 degrees: a smooth motion, as from a capture
    steps = rng(salt + 2).normal(0, 0.3, (k, 3))
    keys = _integrate(steps)
    t = np.linspace(times[0], times[-1], m)
    return times, keys.astype(dtype), t.astype(dtype)


def _integrate(steps):
    """Unit quaternions q_i = q_{i-1} · exp(step_i / 2), scalar-first (float64)."""
    half = steps / 2
    a = np.linalg.norm(half, axis=-1, keepdims=True)
    d = np.concatenate([np.cos(a), np.sinc(a / np.pi) * half], axis=-1)
    q = np.empty_like(d)
    q[0] = d[0] / np.linalg.norm(d[0])
    for i in range(1, len(d)):  # data preparation only, outside the timings
        w1, x1, y1, z1 = q[i - 1]
        w2, x2, y2, z2 = d[i]
        q[i] = (w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2)
    return q


class Tracks:
    """Build a track through K keys and evaluate it at M times (construction included).

    Twins: scipy ``Slerp`` for slerp and ``RotationSpline`` (its only smooth
    curve) for squad and Bézier; ``quaternion.squad`` and ``quaternionic.squad``
    for squad.
    """

    params = (KEYS, QUERIES, DTYPES, LIBS)
    param_names = ["keys", "queries", "dtype", "lib"]

    def setup(self, k, m, dtype, lib):
        self.lib = L = adapter(lib, dtype)
        times, keys, t = make_track(k, m, dtype)
        self.times, self.keys = times, L.wrap(keys)
        self.t = t if lib in ("quatarray", "scipy") else t.astype(np.float64)

    def time_slerp(self, k, m, dtype, lib):
        """Piecewise slerp track (scipy: Slerp)."""
        self.lib.track(self.times, self.keys, self.t, "slerp")

    def time_squad(self, k, m, dtype, lib):
        """Shoemake squad track (scipy: RotationSpline; peers: their squad)."""
        self.lib.track(self.times, self.keys, self.t, "squad")

    def time_bezier(self, k, m, dtype, lib):
        """Spherical Bézier track (scipy: RotationSpline)."""
        self.lib.track(self.times, self.keys, self.t, "bezier")

    def peakmem_slerp(self, k, m, dtype, lib):
        """Peak memory of the slerp track, 10⁶ queries only."""
        if m < QUERIES[-1]:
            raise Skip("peakmem only for the large case")
        self.lib.track(self.times, self.keys, self.t, "slerp")

    def peakmem_squad(self, k, m, dtype, lib):
        """Peak memory of the squad track, 10⁶ queries only."""
        if m < QUERIES[-1]:
            raise Skip("peakmem only for the large case")
        self.lib.track(self.times, self.keys, self.t, "squad")


class OneQuery:
    """A prebuilt two-key ``Slerp`` evaluated at one time: the per-call overhead (scipy: the same call)."""

    params = (DTYPES, LIBS[:2])
    param_names = ["dtype", "lib"]

    def setup(self, dtype, lib):
        L = adapter(lib, dtype)
        times, keys, _ = make_track(2, 1, dtype)
        self.slerp = L.slerp_class(times, L.wrap(keys))
        self.t = 0.3 * times[-1]

    def time_slerp_call(self, dtype, lib):
        """``Slerp(times, rotations)(t)`` for a single query time t."""
        self.slerp(self.t)
