"""Shared pieces of the benchmark suites: parameters, seeded data, library adapters.

Every benchmark class takes ``lib`` as its last parameter.  ``adapter(lib)``
returns an object that knows how to hold that library's quaternions and how
to call each operation; an operation the library lacks raises `Skip`, and a
library that is not installed raises `NotImplementedError` from the class's
``setup`` -- both are asv's way of marking a benchmark as skipped.

Data are made here with NumPy only (seeded), in float64 and then cast, so
that every library gets the same numbers.  Quaternions are scalar-first
``(w, x, y, z)``; for N = 1 a single quaternion of shape (4,) is used (and a
single scipy ``Rotation``), the case where per-call overhead decides.
"""

import functools
import importlib

import numpy as np

try:  # asv >= 0.6 counts this as "skipped" when raised inside a benchmark
    from asv_runner.benchmarks.mark import SkipNotImplemented as Skip
except ImportError:  # pragma: no cover - without asv, any NotImplementedError
    class Skip(NotImplementedError):
        """The library has no such operation (asv shows the benchmark as skipped)."""

__all__ = [
    "SIZES", "DTYPES", "LIBS", "SEED", "Skip", "adapter", "installed", "rng",
    "unit_quats", "quats", "vectors", "rotvecs", "euler_angles", "matrices", "batch",
]

#: Batch sizes of the per-element benchmarks (one element, in cache, beyond cache; no
#: 100: each size is about 200 more benchmark processes in `asv run --quick`).
SIZES = [1, 10_000, 1_000_000]
#: Sizes that also get a ``peakmem_`` twin.
LARGE = 1_000_000
DTYPES = ["float32", "float64"]
LIBS = ["quatarray", "scipy", "numpy-quaternion", "quaternionic"]
SEED = 20261121
#: Euler sequence used by the Euler benchmarks (scipy's default style, extrinsic).
EULER_SEQ = "xyz"

_MODULES = {"quatarray": "quatarray", "scipy": "scipy.spatial.transform",
            "numpy-quaternion": "quaternion", "quaternionic": "quaternionic"}


def _preload():
    """Import every installed library now: asv's forkserver imports the suite once and
    forks a child per benchmark, which then inherits them (the peers' numba imports
    cost seconds each)."""
    for mod in _MODULES.values():
        try:
            importlib.import_module(mod)
        except ImportError:
            pass


_preload()


def installed(lib):
    """True when `lib` (one of `LIBS`) can be imported."""
    try:
        importlib.import_module(_MODULES[lib])
    except ImportError:
        return False
    return True


def rng(salt=0):
    """A fresh seeded generator (same numbers on every run and for every library)."""
    return np.random.default_rng(SEED + salt)


def batch(n):
    """Batch shape for size `n`: ``()`` for a single element, else ``(n,)``."""
    return () if n == 1 else (n,)


@functools.lru_cache(maxsize=4)
def _unit_quats(n, dtype, salt=0):
    """Random unit quaternions, uniform on S³, batch `batch(n)`, scalar-first, w ≥ 0."""
    q = rng(salt).standard_normal(batch(n) + (4,))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    q *= np.where(q[..., :1] < 0, -1.0, 1.0)
    return q.astype(dtype)


@functools.lru_cache(maxsize=4)
def _quats(n, dtype, salt=0):
    """Random non-unit quaternions (norms between about 0.5 and 2)."""
    q = unit_quats(n, np.float64, salt) * rng(salt + 1).uniform(0.5, 2.0, batch(n) + (1,))
    return q.astype(dtype)


@functools.lru_cache(maxsize=4)
def _vectors(n, dtype, salt=0):
    """Random 3-vectors, batch `batch(n)`."""
    return rng(salt).standard_normal(batch(n) + (3,)).astype(dtype)


@functools.lru_cache(maxsize=4)
def _rotvecs(n, dtype, salt=0):
    """Random rotation vectors with angles in [0, π)."""
    v = rng(salt).standard_normal(batch(n) + (3,))
    v *= rng(salt + 1).uniform(0, np.pi, batch(n) + (1,)) / np.linalg.norm(v, axis=-1, keepdims=True)
    return v.astype(dtype)


@functools.lru_cache(maxsize=4)
def _euler_angles(n, dtype, salt=0):
    """Random Tait-Bryan angles (radians) in scipy's ranges: [-π, π], [-π/2, π/2], [-π, π]."""
    g = rng(salt)
    a = np.stack([g.uniform(-np.pi, np.pi, batch(n)), g.uniform(-np.pi / 2, np.pi / 2, batch(n)),
                  g.uniform(-np.pi, np.pi, batch(n))], axis=-1)
    return a.astype(dtype)


@functools.lru_cache(maxsize=4)
def _matrices(n, dtype, salt=0):
    """Rotation matrices of `unit_quats` (computed in float64, then cast)."""
    w, x, y, z = np.moveaxis(unit_quats(n, np.float64, salt), -1, 0)
    m = np.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ], axis=-1)
    return m.reshape(batch(n) + (3, 3)).astype(dtype)


def _copying(make):
    """Public generator: made once per arguments (the comparison sets many libraries up
    on the same data), handed out as a fresh copy."""
    @functools.wraps(make)
    def fresh(*args, **kwargs):
        return make(*args, **kwargs).copy()
    return fresh


unit_quats, quats, vectors = _copying(_unit_quats), _copying(_quats), _copying(_vectors)
rotvecs, euler_angles, matrices = _copying(_rotvecs), _copying(_euler_angles), _copying(_matrices)


# --------------------------------------------------------------------------- adapters

class Lib:
    """Operations on one library's quaternions; every one not overridden raises `Skip`.

    ``wrap(q)`` turns a raw scalar-first array into the library's object
    (done in ``setup``, outside the timings).  The operation methods receive
    wrapped objects (and raw arrays for vectors, matrices, angles, ``t``).
    """

    name = "?"

    def _skip(self, op):
        raise Skip(f"{self.name} has no {op}")

    def wrap(self, q):
        return q

    def __getattr__(self, op):
        if op.startswith("_"):
            raise AttributeError(op)
        return lambda *args, **kwargs: self._skip(op)


class Quatarray(Lib):
    """quatarray: the `QuatArray` class and its scipy-compatible surface."""

    name = "quatarray"

    def __init__(self):
        import quatarray
        self.qa = quatarray
        self.Q = quatarray.QuatArray

    def wrap(self, q):
        return self.Q(q)

    def _method(self, cls_or_obj, name):
        f = getattr(cls_or_obj, name, None)
        if f is None:
            self._skip(name)
        return f

    def _interp(self, name):
        try:
            mod = importlib.import_module("quatarray.interpolate")
        except ImportError:
            self._skip(name)
        return self._method(mod, name)

    # algebra
    def product(self, p, q):
        return p * q

    def conjugate(self, q):
        return q.conj()

    def _rotation(self, q):
        """The scipy-surface `Rotation` of the same quaternions, made once per array as a
        user makes one (``from_quat``, as the scipy adapter does in setup, outside the
        timings)."""
        memo = self.__dict__.setdefault("_rotations", {})
        held = memo.get(id(q))
        if held is None or held[0] is not q:
            held = memo[id(q)] = (q, self.qa.Rotation.from_quat(q.view(np.ndarray), scalar_first=True))
        return held[1]

    def inv(self, q):
        return self._rotation(q).inv()

    def rotation_power(self, q, t):
        return self._rotation(q) ** t

    def magnitude(self, q):
        return self._rotation(q).magnitude()

    def normalize(self, q):
        return q.normalized()

    def exp(self, q):
        return q.exp()

    def log(self, q):
        return q.log()

    def power(self, q, t):
        return q ** t

    # rotating vectors
    def rotate(self, q, v):
        return q.rotate(v)

    def apply(self, q, v):
        return self._rotation(q).apply(v)

    # conversions: scipy's surface, `Rotation` (over the same quaternions, no copy)
    def as_matrix(self, q):
        return self._rotation(q).as_matrix()

    def from_matrix(self, m):
        return self.qa.Rotation.from_matrix(m)

    def as_rotvec(self, q):
        return self._rotation(q).as_rotvec()

    def from_rotvec(self, v):
        return self.qa.Rotation.from_rotvec(v)

    def as_euler(self, q):
        return self._rotation(q).as_euler(EULER_SEQ)

    def from_euler(self, a):
        return self.qa.Rotation.from_euler(EULER_SEQ, a)

    # interpolation
    def slerp(self, q0, q1, t):
        return self._interp("slerp")(q0, q1, t)

    def nlerp(self, q0, q1, t):
        return self._interp("nlerp")(q0, q1, t)

    def track(self, times, keys, t, method):
        return self._interp("Track")(times, keys, method=method)(t)

    def slerp_class(self, times, keys):
        return self._interp("Slerp")(times, self._rotation(keys))


class Scipy(Lib):
    """scipy.spatial.transform: `Rotation` (float64 inside), `Slerp`, `RotationSpline`."""

    name = "scipy"

    def __init__(self):
        from scipy.spatial.transform import Rotation, RotationSpline, Slerp
        self.R, self.Slerp, self.Spline = Rotation, Slerp, RotationSpline

    def wrap(self, q):
        return self.R.from_quat(q, scalar_first=True)

    def product(self, p, q):
        return p * q

    def conjugate(self, q):
        return q.inv()

    inv = conjugate

    def magnitude(self, q):
        return q.magnitude()

    def normalize(self, q):
        """From raw (non-unit) quaternions: `from_quat` normalises."""
        return self.R.from_quat(q, scalar_first=True)

    def exp(self, q):
        """The rotation exp map: `from_rotvec` of twice the vector part."""
        return self.R.from_rotvec(2 * q[..., 1:])

    def log(self, q):
        """The rotation log map: `as_rotvec` (twice the quaternion log)."""
        return q.as_rotvec()

    def power(self, q, t):
        return q ** t

    rotation_power = power

    def rotate(self, q, v):
        return q.apply(v)

    apply = rotate

    def as_matrix(self, q):
        return q.as_matrix()

    def from_matrix(self, m):
        return self.R.from_matrix(m)

    def as_rotvec(self, q):
        return q.as_rotvec()

    def from_rotvec(self, v):
        return self.R.from_rotvec(v)

    def as_euler(self, q):
        return q.as_euler(EULER_SEQ)

    def from_euler(self, a):
        return self.R.from_euler(EULER_SEQ, a)

    def slerp(self, q0, q1, t):
        """Pairwise slerp as a scipy user writes it: q0 · exp(t · log(q0⁻¹ q1))."""
        t = np.asarray(t)
        return q0 * self.R.from_rotvec((q0.inv() * q1).as_rotvec() * t[..., None])

    def nlerp(self, q0, q1, t):
        """Pairwise nlerp on raw arrays: `from_quat` normalises the lerp."""
        t = np.asarray(t)[..., None]
        return self.R.from_quat(q0 + t * (q1 - q0), scalar_first=True)

    def track(self, times, keys, t, method):
        if method == "slerp":
            return self.Slerp(times, keys)(t)
        return self.Spline(times, keys)(t)  # scipy's only smooth interpolant (C² cubic)

    def slerp_class(self, times, keys):
        return self.Slerp(times, keys)


class NumpyQuaternion(Lib):
    """numpy-quaternion (compiled, float64 only): arrays of dtype `quaternion`."""

    name = "numpy-quaternion"

    def __init__(self):
        import quaternion
        self.m = quaternion

    def wrap(self, q):
        return self.m.as_quat_array(np.asarray(q, np.float64))

    def product(self, p, q):
        return p * q

    def conjugate(self, q):
        return np.conjugate(q)

    def inv(self, q):
        return np.reciprocal(q)

    def normalize(self, q):
        return q / np.abs(q)

    def exp(self, q):
        return np.exp(q)

    def log(self, q):
        return np.log(q)

    def power(self, q, t):
        return q ** t

    def rotate(self, q, v):
        """Pairwise q v q̄ (`quaternion.rotate_vectors` is an outer product)."""
        return self.m.as_vector_part(q * self.m.from_vector_part(v) * np.conjugate(q))

    def as_matrix(self, q):
        return self.m.as_rotation_matrix(q)

    def from_matrix(self, m):
        return self.m.from_rotation_matrix(m)

    def as_rotvec(self, q):
        return self.m.as_rotation_vector(q)

    def from_rotvec(self, v):
        return self.m.from_rotation_vector(v)

    def slerp(self, q0, q1, t):
        """The fastest slerp: the ufunc behind `quaternion.slerp` (t1 = 0, t2 = 1)."""
        return np.slerp_vectorized(q0, q1, t)

    def track(self, times, keys, t, method):
        if method != "squad":
            self._skip(f"{method} track")
        return self.m.squad(keys, times, t)


class Quaternionic(Lib):
    """quaternionic (numba-compiled ndarray subclass, float64 only)."""

    name = "quaternionic"

    def __init__(self):
        import quaternionic
        self.m = quaternionic

    def wrap(self, q):
        return self.m.array(np.asarray(q, np.float64))

    def product(self, p, q):
        return p * q

    def conjugate(self, q):
        return q.conjugate()

    def inv(self, q):
        return q.inverse

    def normalize(self, q):
        return q.normalized

    def exp(self, q):
        return np.exp(q)

    def log(self, q):
        return np.log(q)

    def power(self, q, t):
        return q ** t

    def rotate(self, q, v):
        """Pairwise q v q̄ (`array.rotate` is an outer product)."""
        return (q * self.m.array.from_vector_part(v) * q.conjugate()).vector

    def as_matrix(self, q):
        return q.to_rotation_matrix

    def from_matrix(self, m):
        return self.m.array.from_rotation_matrix(m)

    def as_rotvec(self, q):
        return q.to_rotation_vector

    def from_rotvec(self, v):
        return self.m.array.from_rotation_vector(v)

    def slerp(self, q0, q1, t):
        return self.m.slerp(q0, q1, t)

    def track(self, times, keys, t, method):
        if method != "squad":
            self._skip(f"{method} track")
        return self.m.squad(keys, times, t)


_ADAPTERS = {"quatarray": Quatarray, "scipy": Scipy, "numpy-quaternion": NumpyQuaternion,
             "quaternionic": Quaternionic}


#: Peers that compute in float64 only: given float32 data they would time float64 again.
FLOAT64_ONLY = ("numpy-quaternion", "quaternionic")


def adapter(lib, dtype=None):
    """The `Lib` for `lib`; `NotImplementedError` (asv: skipped) when it is not installed,
    and `Skip` for a float64-only peer asked for float32 (checked before importing it:
    each asv benchmark runs in a fresh process, where the peers' numba imports cost
    seconds)."""
    if dtype is not None and np.dtype(dtype) == np.float32 and lib in FLOAT64_ONLY:
        raise Skip(f"{lib} computes in float64 only")
    try:
        return _ADAPTERS[lib]()
    except ImportError as exc:
        raise NotImplementedError(f"{lib} is not installed ({exc})") from None
