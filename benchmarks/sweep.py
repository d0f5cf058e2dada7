"""Every `Rotation` method, Slerp, RotationSpline and RigidTransform, quatarray against scipy,
at every batch size: a single rotation (shape ()), a batch of one, 10, 100, 10³ ... 10⁶.

`SizeSweep` is the asv class. By default asv times quatarray at `QUICK_SIZES` only, to
keep the whole quick suite under five minutes; with the environment variable
``QUATARRAY_ASV_SWEEP=full`` it times every size in `SIZES`, for quatarray and scipy
(``benchmarks.compare`` also uses the class for its single-rotation rows).
``python -m benchmarks.compare --sweep`` times every size side by side in one process and
prints the ratio table (scipy's time ÷ quatarray's: above 1, quatarray is faster).

Each operation is a function ``make(R, mod, n) -> zero-argument call`` that builds its
seeded data for batch size `n` (None: a single rotation) with the library's own classes
(`R` its ``Rotation``, `mod` its ``scipy.spatial.transform``-like module), so both
libraries run the same calls on the same numbers.
"""

import importlib
import os

import numpy as np

from ._common import SEED

__all__ = ["SIZES", "QUICK_SIZES", "ASV_SIZES", "OPS", "TRANSCENDENTAL", "COPIES", "target", "make", "SizeSweep"]

#: Batch sizes of the sweep; None is a single rotation (shape ()).
SIZES = [None, 1, 10, 100, 1_000, 10_000, 100_000, 1_000_000]
#: The sizes asv times by default (its quick run times each once; the whole quick suite
#: must stay under five minutes).
QUICK_SIZES = ["single", "100", "1000000"]
#: ``QUATARRAY_ASV_SWEEP=full``: asv times every size of the sweep, for both libraries.
FULL = os.environ.get("QUATARRAY_ASV_SWEEP", "") == "full"
#: The sizes asv times: `QUICK_SIZES`, or every size of `SIZES` with ``QUATARRAY_ASV_SWEEP=full``.
ASV_SIZES = ["single", *map(str, SIZES[1:])] if FULL else QUICK_SIZES
#: Left out of asv: building a spline through 10⁶ keys takes 30-40 s, an eighth of the whole
#: quick suite's five minutes (``benchmarks.compare --sweep`` still times it).
ASV_SKIP = {("RotationSpline build", "1000000")}
_MODULES = {"quatarray": "quatarray", "scipy": "scipy.spatial.transform"}


def _data(n, salt=0):
    rng = np.random.default_rng(SEED + salt)
    shape = () if n is None else (n,)
    q = rng.standard_normal(shape + (4,))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return rng, shape, q


def _rot(R, n, salt=0):
    return R.from_quat(_data(n, salt)[2])


def _keys(n):
    """At least two keys (Slerp and RotationSpline need them), n for a batch."""
    return 2 if n is None or n < 2 else n


_AXES = np.eye(3)[[2, 0, 2]]


def _ops():
    ops = {}

    def op(name):
        def register(f):
            ops[name] = f
            return f
        return register

    @op("from_quat")
    def _(R, mod, n):
        q = _data(n)[2]
        return lambda: R.from_quat(q)

    for name in ("as_quat", "as_matrix", "as_rotvec", "as_mrp", "inv", "magnitude"):
        ops[name] = (lambda name: lambda R, mod, n: getattr(_rot(R, n), name))(name)

    @op("as_euler")
    def _(R, mod, n):
        r = _rot(R, n)
        return lambda: r.as_euler("xyz")

    @op("as_davenport")
    def _(R, mod, n):
        r = _rot(R, n)
        return lambda: r.as_davenport(_AXES, "e")

    for name, conv in (("from_matrix", "as_matrix"), ("from_rotvec", "as_rotvec"), ("from_mrp", "as_mrp")):
        ops[name] = (lambda name, conv: lambda R, mod, n: (
            lambda x=getattr(_rot(R, n), conv)(): lambda: getattr(R, name)(x))())(name, conv)

    @op("from_euler")
    def _(R, mod, n):
        e = _rot(R, n).as_euler("xyz")
        return lambda: R.from_euler("xyz", e)

    @op("from_davenport")
    def _(R, mod, n):
        e = _rot(R, n).as_davenport(_AXES, "e")
        return lambda: R.from_davenport(_AXES, "e", e)

    @op("identity")
    def _(R, mod, n):
        return lambda: R.identity(n)

    @op("random")
    def _(R, mod, n):
        return lambda: R.random(n, rng=0)

    @op("apply")
    def _(R, mod, n):
        rng, shape, q = _data(n)
        r, v = R.from_quat(q), rng.standard_normal(shape + (3,))
        return lambda: r.apply(v)

    @op("mul")
    def _(R, mod, n):
        r, s = _rot(R, n), _rot(R, n, 1)
        return lambda: r * s

    @op("pow")
    def _(R, mod, n):
        r = _rot(R, n)
        return lambda: r ** 0.3

    @op("approx_equal")
    def _(R, mod, n):
        r, s = _rot(R, n), _rot(R, n, 1)
        return lambda: r.approx_equal(s)

    @op("mean")
    def _(R, mod, n):
        r = _rot(R, n)
        return lambda: r.mean()

    @op("reduce")
    def _(R, mod, n):
        r, g = _rot(R, n), R.create_group("O")
        return lambda: r.reduce(g)

    @op("align_vectors")
    def _(R, mod, n):
        rng = np.random.default_rng(SEED)
        m = 2 if n is None or n < 2 else n
        a, b = rng.standard_normal((2, m, 3))
        return lambda: R.align_vectors(a, b)

    for cls in ("Slerp", "RotationSpline"):
        def build(R, mod, n, cls=cls):
            k = _keys(n)
            r, times = _rot(R, k), np.arange(k, dtype=float)
            return lambda: getattr(mod, cls)(times, r)

        def call(R, mod, n, cls=cls):
            s = getattr(mod, cls)(np.arange(10.0), _rot(R, 10))
            t = np.random.default_rng(SEED).uniform(0, 9, () if n is None else (n,))
            return lambda: s(t)

        ops[f"{cls} build"], ops[f"{cls} call"] = build, call

    def rigid(mod, n, salt=0):
        rng, shape, q = _data(n, salt)
        return mod.RigidTransform.from_components(rng.standard_normal(shape + (3,)), mod.Rotation.from_quat(q))

    @op("RigidTransform apply")
    def _(R, mod, n):
        tf, v = rigid(mod, n), np.random.default_rng(SEED + 5).standard_normal((() if n is None else (n,)) + (3,))
        return lambda: tf.apply(v)

    @op("RigidTransform compose")
    def _(R, mod, n):
        a, b = rigid(mod, n), rigid(mod, n, 1)
        return lambda: a * b

    @op("RigidTransform inv")
    def _(R, mod, n):
        tf = rigid(mod, n)
        return lambda: tf.inv()

    return ops


#: name -> make(R, mod, n)
OPS = _ops()

#: Methods that evaluate a transcendental function (target at N >= 10³: at least 1).
TRANSCENDENTAL = ("as_euler", "from_euler", "as_rotvec", "from_rotvec", "as_mrp", "from_mrp", "magnitude",
                  "pow", "mean", "as_davenport", "from_davenport", "approx_equal", "Slerp build", "Slerp call",
                  "RotationSpline build", "RotationSpline call")
#: Copies and products (target at N >= 10³: at least 0.5).
COPIES = ("from_quat", "as_quat", "as_matrix", "from_matrix", "inv", "apply", "mul",
          "RigidTransform apply", "RigidTransform compose", "RigidTransform inv")


def target(name, n):
    """Issue 23's target for scipy's time ÷ quatarray's of operation `name` at size `n` (None:
    a single rotation), or None where it sets none: 1 for one rotation and a batch of one,
    0.33 at 10 and 100, and from 10³ on 1 for `TRANSCENDENTAL` and 0.5 for `COPIES` (10⁶ has
    further targets of its own, in ``benchmarks.compare --targets``)."""
    if n is None or n == 1:
        return 1.0
    if n < 1000:
        return 0.33
    return 1.0 if name in TRANSCENDENTAL else 0.5 if name in COPIES else None


def make(lib, name, n):
    """The zero-argument call of operation `name` at size `n` (None: single) for `lib`."""
    mod = importlib.import_module(_MODULES[lib])
    if lib == "scipy" and name.startswith("RigidTransform") and not hasattr(mod, "RigidTransform"):
        raise NotImplementedError("this scipy has no RigidTransform")
    return OPS[name](mod.Rotation, mod, n)


class SizeSweep:
    """Each operation at `ASV_SIZES` (float64): a single rotation, 100 and 10⁶, or every size
    of the sweep with ``QUATARRAY_ASV_SWEEP=full``.

    By default asv times quatarray only (its history is what asv tracks), and scipy too with
    the full sweep; ``benchmarks.compare`` runs this class for both, side by side."""

    params = (list(OPS), ASV_SIZES, list(_MODULES) if FULL else ["quatarray"])
    param_names = ["op", "size", "lib"]
    smoke_params = (list(OPS), ["single", "1"], list(_MODULES))   # tests/test_benchmarks.py, both libraries
    timeout = 120

    def setup(self, op, size, lib):
        if (op, size) in ASV_SKIP:
            raise NotImplementedError(f"{op} at {size} is left to benchmarks.compare --sweep")
        try:
            self.call = make(lib, op, None if size == "single" else int(size))
        except ImportError as exc:
            raise NotImplementedError(f"{lib} is not installed ({exc})") from None

    def time_op(self, op, size, lib):
        """The operation `op` on a batch of `size` rotations."""
        self.call()
