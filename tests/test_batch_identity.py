"""The same element gives the same bits whatever the batch around it.

For every method of `QuatArray`, `Rotation`, `Slerp`, `RotationSpline`, `RigidTransform`,
the interpolation functions, `Track`, `normalize_dual_quaternion` and `geodesic_mean`, in
float32 and float64: element i of a batch equals, bit for bit, the same element computed alone
(shape ()), as a batch of one, and inside the batch split into blocks of two elements run on
two threads; so does track j of a batch of tracks (control points, `unflip`, `Slerp`, `Track`).  The batches mix
random rotations with near-identity, near-half-turn and gimbal-lock rotations, and (where
the method accepts any magnitude) quaternions scaled by extreme powers of two.  A float64
single rotation or batch of one may run its kernel's formula on Python floats (`quatarray._ops`):
the same code in the same order, so these checks hold it to the same bits.
"""

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import quatarray
from quatarray import (QuatArray, RigidTransform, Rotation, RotationSpline, Slerp, Track, _blocks, _interp_spline,
                       _kernels, bezier, bezier_control_points, geodesic_mean, lerp, nlerp,
                       normalize_dual_quaternion, slerp, squad, squad_control_points, unflip)

KINDS = ("random", "identity", "half turn", "gimbal xyz", "gimbal zyz")


def _rows(seed, kinds, dtype, scale, span=None):
    """Quaternions (n, 4), one per kind; with `scale`, each multiplied by a random power of two
    (up to 2**±900 in float64, 2**±50 in float32, or 2**±`span`)."""
    rng = np.random.default_rng(seed)
    out = []
    for kind in kinds:
        q = rng.standard_normal(4)
        if kind == "identity":
            q = np.array([1.0, *(rng.standard_normal(3) * 10.0 ** rng.uniform(-17, -4))])
        elif kind == "half turn":
            q[0] = rng.standard_normal() * 10.0 ** rng.uniform(-17, -4)
        elif kind.startswith("gimbal"):
            seq = "xyz" if kind.endswith("xyz") else "ZYZ"
            mid = (np.pi / 2 if seq == "xyz" else 0.0) * rng.choice([-1, 1]) + rng.standard_normal() * 1e-9
            q = Rotation.from_euler(seq, [rng.uniform(-3, 3), mid, rng.uniform(-3, 3)]).as_quat(scalar_first=True)
        q = q / np.linalg.norm(q)
        if scale:
            span = span or (900 if dtype == np.float64 else 50)
            q = np.ldexp(q, int(rng.integers(-span, span)))
        out.append(q)
    return np.array(out).astype(dtype)


def batches():
    """(q, i): a batch of 1 to 12 quaternions of mixed kinds and an index into it."""
    return st.tuples(st.integers(0, 2**32 - 1), st.lists(st.sampled_from(KINDS), min_size=1, max_size=12),
                     st.booleans()).flatmap(
        lambda a: st.tuples(st.just(a), st.integers(0, len(a[1]) - 1)))


def _same(got, want, name):
    got, want = np.asarray(got), np.asarray(want)
    assert got.dtype == want.dtype, name
    assert got.shape == want.shape, name
    np.testing.assert_array_equal(got, want, err_msg=name, strict=True)
    if got.dtype.kind == "f":   # the bits: signed zeros too (NaN payloads aside)
        np.testing.assert_array_equal(np.signbit(got), np.signbit(want), err_msg=f"{name}: sign of zero")


def _split(f):
    """`f()` with blocks of two elements, run on two threads."""
    saved = _blocks.BLOCK, _blocks.PARALLEL_MIN
    _blocks.BLOCK, _blocks.PARALLEL_MIN = 2, 1
    try:
        with quatarray.num_threads(2):
            return f()
    finally:
        _blocks.BLOCK, _blocks.PARALLEL_MIN = saved


#: Operations that give a single rotation scipy's shape (1,) result (approx_equal of two single
#: rotations, reduce's indices), where the batch has one element per rotation.
ONE_FOR_SINGLE = {"approx_equal", "reduce indices"}


def check(ops, args, i):
    """For each (name, f): f(*args) at element i equals f on element i alone, as a batch
    of one, and in the split batch.  `args` are arrays whose first axis is the batch."""
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")   # gimbal lock, overflow
        for name, f in ops:
            whole = _raw(f(*args))
            _same(_raw(f(*(a[i:i + 1] for a in args)))[0], whole[i], f"{name}: batch of one")
            alone = _raw(f(*(a[i] for a in args)))
            if name in ONE_FOR_SINGLE:
                alone = alone.reshape(whole[i].shape)
            _same(alone, whole[i], f"{name}: alone")
            _same(_raw(_split(lambda: f(*args))), whole, f"{name}: blocks of 2 on 2 threads")


def _raw(x):
    if isinstance(x, Rotation):
        return x.as_quat(scalar_first=True)
    if isinstance(x, RigidTransform):
        return x.as_matrix()
    return np.asarray(x.view(np.ndarray) if isinstance(x, QuatArray) else x)


DTYPE = pytest.mark.parametrize("dtype", [np.float32, np.float64], ids=["f32", "f64"])


@DTYPE
@given(b=batches())
def test_quatarray_methods(dtype, b):
    (seed, kinds, scale), i = b
    q = _rows(seed, kinds, dtype, scale)
    p = np.roll(_rows(seed + 1, kinds, dtype, False), 1, axis=0)
    rng = np.random.default_rng(seed)
    t = rng.uniform(-2, 2, len(q)).astype(dtype)
    v = rng.standard_normal((len(q), 3)).astype(dtype)
    axes = [[0, 0, 1], [1, 0, 0], [0, 1, 0]]
    Q = QuatArray
    check([("conj", lambda q: Q(q).conj()), ("norm", lambda q: Q(q).norm()),
           ("normalized", lambda q: Q(q).normalized()), ("inverse", lambda q: Q(q).inverse()),
           ("exp", lambda q: Q(q).exp()), ("log", lambda q: Q(q).log()), ("power 0.3", lambda q: Q(q).power(0.3)),
           ("as_matrix", lambda q: Q(q).as_matrix()), ("as_rotvec", lambda q: Q(q).as_rotvec()),
           ("as_mrp", lambda q: Q(q).as_mrp()), ("as_euler xyz", lambda q: Q(q).as_euler("xyz")),
           ("as_euler ZYZ", lambda q: Q(q).as_euler("ZYZ", degrees=True)),
           ("as_davenport", lambda q: Q(q).as_davenport(axes, "e"))], (q,), i)
    check([("np.sqrt", lambda q: np.sqrt(Q(q))), ("np.exp", lambda q: np.exp(Q(q)))], (q,), i)
    check([("power t", lambda q, t: Q(q).power(t)), ("divide by a real", lambda q, t: Q(q) / t)], (q, t), i)
    check([("dot", lambda q, p: Q(q).dot(Q(p))), ("product", lambda q, p: Q(q) * Q(p)),
           ("quotient", lambda q, p: Q(q) / Q(p))], (q, p), i)
    check([("rotate", lambda q, v: Q(q).rotate(v))], (q, v), i)
    m, rv, mrp = Q(q).as_matrix(), Q(q).as_rotvec(), Q(q).as_mrp()
    eu = Q(q).as_euler("xyz", suppress_warnings=True)
    check([("from_matrix", lambda m: Q.from_matrix(m)), ], (m,), i)
    check([("from_rotvec", lambda r: Q.from_rotvec(r))], (rv,), i)
    check([("from_mrp", lambda r: Q.from_mrp(r))], (mrp,), i)
    check([("from_euler", lambda e: Q.from_euler("xyz", e)),
           ("from_davenport", lambda e: Q.from_davenport(axes, "e", e))], (eu,), i)


@DTYPE
@given(b=batches())
def test_rotation_methods(dtype, b):
    (seed, kinds, scale), i = b
    q = _rows(seed, kinds, dtype, scale)
    p = _rows(seed + 1, kinds, dtype, False)
    rng = np.random.default_rng(seed)
    v = rng.standard_normal((len(q), 3)).astype(dtype)
    n = rng.uniform(-3, 3, len(q)).astype(dtype)
    axes = [[0, 0, 1], [1, 0, 0], [0, 1, 0]]
    R = Rotation
    ops = [("from_quat", lambda q: R.from_quat(q)), ("from_quat scalar_first", lambda q: R.from_quat(q, scalar_first=True)),
           ("as_quat", lambda q: R.from_quat(q).as_quat()),
           ("as_quat canonical", lambda q: R.from_quat(q).as_quat(canonical=True)),
           ("as_matrix", lambda q: R.from_quat(q).as_matrix()), ("as_rotvec", lambda q: R.from_quat(q).as_rotvec()),
           ("as_rotvec degrees", lambda q: R.from_quat(q).as_rotvec(degrees=True)),
           ("as_mrp", lambda q: R.from_quat(q).as_mrp()), ("inv", lambda q: R.from_quat(q).inv()),
           ("magnitude", lambda q: R.from_quat(q).magnitude()), ("pow 0.3", lambda q: R.from_quat(q) ** 0.3),
           ("pow -2", lambda q: R.from_quat(q) ** -2)]
    ops += [(f"as_euler {seq}", lambda q, seq=seq: R.from_quat(q).as_euler(seq)) for seq in ("xyz", "ZYZ", "zxy")]
    ops.append(("as_davenport", lambda q: R.from_quat(q).as_davenport(axes, "i")))
    check(ops, (q,), i)
    octahedral, c3 = R.create_group("O"), R.create_group("C3", axis="X")
    check([("reduce", lambda q: R.from_quat(q).reduce(left=octahedral, right=c3)),
           ("reduce left", lambda q: R.from_quat(q).reduce(left=octahedral)),
           ("reduce indices", lambda q: np.stack(R.from_quat(q).reduce(octahedral, c3, return_indices=True)[1:], -1))],
          (q,), i)
    check([("mul", lambda q, p: R.from_quat(q) * R.from_quat(p)),
           ("approx_equal", lambda q, p: R.from_quat(q).approx_equal(R.from_quat(p), atol=1.0))], (q, p), i)
    check([("apply", lambda q, v: R.from_quat(q).apply(v)),
           ("apply inverse", lambda q, v: R.from_quat(q).apply(v, inverse=True))], (q, v), i)
    check([("pow array", lambda q, n: R.from_quat(q) ** n)], (q, n), i)
    r = R.from_quat(q)
    check([("from_matrix", lambda m: R.from_matrix(m))], (r.as_matrix(),), i)
    check([("from_rotvec", lambda x: R.from_rotvec(x))], (r.as_rotvec(),), i)
    check([("from_mrp", lambda x: R.from_mrp(x))], (r.as_mrp(),), i)
    check([("from_euler", lambda x: R.from_euler("xyz", x)),
           ("from_euler degrees", lambda x: R.from_euler("ZYZ", x, degrees=True)),
           ("from_davenport", lambda x: R.from_davenport(axes, "e", x))], (r.as_euler("xyz", suppress_warnings=True),), i)


def _davenport_axes(seed, kinds):
    """A set of Davenport axes for each row of `_rows(seed, kinds, ...)`, (n, 3, 3) float64:
    the gimbal kinds get the axes they lock in extrinsic order ('xyz', z-y-z); the others a
    random orthonormal n1, n2 and n3 turned from n1 about n2 by any angle; each axis of a
    random length."""
    rng = np.random.default_rng(seed + 2)
    sets = []
    for kind in kinds:
        if kind == "gimbal xyz":
            axes = np.eye(3)
        elif kind == "gimbal zyz":
            axes = np.eye(3)[[2, 1, 2]]
        else:
            frame = np.linalg.qr(rng.standard_normal((3, 3)))[0].T
            t = rng.uniform(-np.pi, np.pi)
            axes = np.array([frame[0], frame[1], np.cos(t) * frame[0] + np.sin(t) * frame[2]])
        sets.append(axes * rng.uniform(0.2, 5, (3, 1)))
    return np.array(sets)


@DTYPE
@given(b=batches())
def test_davenport_with_a_set_of_axes_per_rotation(dtype, b):
    """Davenport angles with a set of axes per rotation (..., 3, 3): element i has the bits of
    its rotation alone with its own (3, 3) axes (the shared-axes path), as a batch of one and
    in blocks of two on two threads; the gimbal kinds are in gimbal lock for their axes."""
    (seed, kinds, scale), i = b
    q = _rows(seed, kinds, dtype, scale)
    ax = _davenport_axes(seed, kinds)
    R, Q = Rotation, QuatArray
    check([("as_davenport e", lambda ax, q: R.from_quat(q, scalar_first=True).as_davenport(ax, "e")),
           ("as_davenport i degrees", lambda ax, q: R.from_quat(q, scalar_first=True).as_davenport(ax, "i", degrees=True)),
           ("QuatArray as_davenport", lambda ax, q: Q(q).as_davenport(ax, "e"))], (ax, q), i)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        x = R.from_quat(q, scalar_first=True).as_davenport(ax, "e")   # the lock rows' lock angles
    check([("from_davenport e", lambda ax, x: R.from_davenport(ax, "e", x)),
           ("from_davenport i degrees", lambda ax, x: R.from_davenport(ax, "i", x, degrees=True)),
           ("QuatArray from_davenport", lambda ax, x: Q.from_davenport(ax, "e", x)),
           ("from_davenport, two axes", lambda ax, x: R.from_davenport(ax[..., :2, :], "e", x[..., :2]))], (ax, x), i)
    if dtype == np.float64 and any(kind.startswith("gimbal") for kind in kinds):
        with pytest.warns(UserWarning, match="Gimbal lock"):
            R.from_quat(q, scalar_first=True).as_davenport(ax, "e")


DAVENPORT_AXES = [np.eye(3), np.eye(3)[[2, 1, 2]], [[2.0, 0, 0], [0, 1, 0], [1, 0, 1]],
                  [[1, 1, 0], [0, 0, 3], [1, -0.5, 0]], [[1, 0, 0], [0, 1, 0], [-1, 0, 0.1]]]


@DTYPE
@pytest.mark.parametrize("n", [1, 2, 33, _blocks.VIEWS_MAX + 1, _blocks.BLOCK + 3])
def test_davenport_axes_repeated_per_rotation_give_the_shared_axes_bits(dtype, n):
    """One set of axes given once (3, 3), once per rotation (n, 3, 3) or as a batch of one
    (1, 3, 3) gives the same bits, both ways and in either order (one kernel, the shared axes
    broadcast), up to and past one block; and per rotation along another batch axis
    (n, 1, 3, 3)."""
    kinds = [KINDS[k % len(KINDS)] for k in range(n)]
    r = Rotation.from_quat(_rows(n, kinds, dtype, False), scalar_first=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # gimbal lock
        for axes in map(np.asarray, DAVENPORT_AXES):
            for order in ("e", "i"):
                name = f"{axes.tolist()} {order}"
                shared = r.as_davenport(axes, order)
                assert shared.dtype == dtype
                x = shared
                want = _raw(Rotation.from_davenport(axes, order, x))
                for per in (np.broadcast_to(axes, (n, 3, 3)), axes[None]):
                    _same(r.as_davenport(per, order), shared, f"as_davenport {name} {per.shape}")
                    _same(_raw(Rotation.from_davenport(per, order, x)), want, f"from_davenport {name} {per.shape}")
                _same(_raw(Rotation.from_davenport(np.broadcast_to(axes[:2], (n, 2, 3)), order, x[:, :2])),
                      _raw(Rotation.from_davenport(axes[:2], order, x[:, :2])), f"from_davenport {name} two axes")
                if n <= 33:
                    outer = np.broadcast_to(axes, (n, 1, 3, 3))
                    _same(r.as_davenport(outer, order), np.broadcast_to(shared, (n, n, 3)), f"as_davenport {name} (n, 1)")
                    _same(_raw(Rotation.from_davenport(outer, order, x)), np.broadcast_to(want, (n, n, 4)),
                          f"from_davenport {name} (n, 1)")


@DTYPE
@given(b=batches())
def test_interpolation(dtype, b):
    (seed, kinds, scale), i = b
    q0 = _rows(seed, kinds, dtype, scale)
    q1 = _rows(seed + 1, kinds, dtype, scale)
    a = _rows(seed + 2, kinds, dtype, scale)
    c = _rows(seed + 3, kinds, dtype, scale)
    rng = np.random.default_rng(seed)
    t = rng.uniform(-0.25, 1.25, len(q0)).astype(dtype)
    t[::3] = rng.choice([0.0, 0.5, 1.0])
    check([("lerp", lerp), ("nlerp", nlerp), ("slerp", slerp),
           ("slerp long way", lambda p, q, t: slerp(p, q, t, shortest=False))], (q0, q1, t), i)
    check([("squad", squad), ("bezier", bezier)], (q0, a, c, q1, t), i)
    keys = _rows(seed + 4, ["random", "identity", "half turn", "random", "gimbal xyz"], dtype, scale)
    times = np.array([0.0, 0.5, 1.5, 2.0, 4.0], dtype)
    at = rng.uniform(0, 4, len(q0)).astype(dtype)
    at[::4] = times[rng.integers(0, 5)]
    ops = [("Slerp", lambda x: Slerp(times, Rotation.from_quat(keys, scalar_first=True))(x)),
           ("RotationSpline", lambda x: RotationSpline(times, Rotation.from_quat(keys, scalar_first=True))(x)),
           ("RotationSpline rate", lambda x: RotationSpline(times, Rotation.from_quat(keys, scalar_first=True))(x, 1))]
    ops += [(f"Track {m}", lambda x, m=m: Track(times, keys, method=m)(x))
            for m in ("linear", "slerp", "squad", "bezier", "spline")]
    ops += [(f"Track {m} angular_velocity", lambda x, m=m: Track(times, keys, method=m).angular_velocity(x))
            for m in ("linear", "slerp", "squad", "bezier")]
    check(ops, (at,), i)


def _per_track(f):
    """`f` of keys (K, *tracks, 4), giving results whose track axis is the second last, as a
    function for `check` of keys with the tracks first: (n, K, 4) for a batch of tracks and
    (K, 4) for one track alone; its result has the track axis first."""
    def tracks_first(keys):
        if keys.ndim == 2:
            return _raw(f(keys))
        return np.moveaxis(_raw(f(np.moveaxis(keys, 0, 1))), -2, 0)
    return tracks_first


def _stacked(arrays):
    """Arrays stacked on a new first axis."""
    return np.stack([_raw(a) for a in arrays])


@DTYPE
@settings(max_examples=min(settings().max_examples, 30))   # each example builds 9 interpolants 4 times
@given(b=batches())
def test_batches_of_tracks(dtype, b):
    """Track j of a batch of tracks (keys (K, n, 4), one track per kind, at any magnitude):
    its control points, unflipped keys, Slerp and Track values and angular velocities are
    those of the track alone, as a batch of one and in blocks of two on two threads."""
    (seed, kinds, scale), j = b
    k = 5
    keys = np.stack([_rows(seed + m, kinds, dtype, scale) for m in range(k)], axis=1)   # (n, K, 4)
    keys[:, 2] = -keys[:, 2]   # a flipped key, for unflip and the control points
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.uniform(0.1, 2.0, k)).astype(dtype)
    at = np.concatenate([times, rng.uniform(times[0], times[-1], 4).astype(dtype)])
    ops = [("unflip", unflip), ("squad_control_points", lambda q: squad_control_points(q, times)),
           ("bezier_control_points", lambda q: _stacked(bezier_control_points(q, times))),
           ("Slerp batched", lambda q: Slerp(times, Rotation.from_quat(q, scalar_first=True), batched=True)(at))]
    ops += [(f"Track {m}", lambda q, m=m: Track(times, q, method=m)(at)) for m in ("linear", "slerp", "squad", "bezier")]
    ops += [(f"Track {m} angular_velocity", lambda q, m=m: Track(times, q, method=m).angular_velocity(at))
            for m in ("linear", "slerp", "squad", "bezier")]
    check([(name, _per_track(f)) for name, f in ops], (keys,), j)


@DTYPE
@given(b=batches())
def test_rigid_transforms(dtype, b):
    (seed, kinds, scale), i = b
    q = _rows(seed, kinds, dtype, scale)
    p = _rows(seed + 1, kinds, dtype, False)
    rng = np.random.default_rng(seed)
    tr = (rng.standard_normal((len(q), 3)) * 10.0 ** rng.uniform(-3, 3)).astype(dtype)
    v = rng.standard_normal((len(q), 3)).astype(dtype)

    def tf(q, tr):
        return RigidTransform.from_components(tr, Rotation.from_quat(q, scalar_first=True))

    check([("as_matrix", tf), ("inv", lambda q, tr: tf(q, tr).inv()), ("pow 0.3", lambda q, tr: tf(q, tr) ** 0.3),
           ("as_exp_coords", lambda q, tr: tf(q, tr).as_exp_coords()),
           ("as_dual_quat", lambda q, tr: tf(q, tr).as_dual_quat())], (q, tr), i)
    exp_coords = tf(q, tr).as_exp_coords()
    exp_coords[::2, :3] *= rng.uniform(-4, 4, (len(exp_coords[::2]), 1)).astype(dtype)   # angles past a half turn
    check([("from_exp_coords", lambda e: RigidTransform.from_exp_coords(e))], (exp_coords,), i)
    # dual quaternions of any magnitude, the dual part not orthogonal to the real one
    dual = tf(q, tr).as_dual_quat() * np.ldexp(1.0, rng.integers(-40, 40, (len(q), 1))).astype(dtype)
    dual[:, 4:] += rng.standard_normal((len(q), 4)).astype(dtype)
    check([("from_dual_quat", lambda d: RigidTransform.from_dual_quat(d)),
           ("normalize_dual_quaternion", normalize_dual_quaternion)], (dual,), i)
    check([("apply", lambda q, tr, v: tf(q, tr).apply(v)),
           ("apply inverse", lambda q, tr, v: tf(q, tr).apply(v, inverse=True))], (q, tr, v), i)
    check([("compose", lambda q, tr, p: tf(q, tr) * tf(p, 2 * tr))], (q, tr, p), i)
    m = tf(q, tr).as_matrix()
    check([("from_matrix", lambda m: RigidTransform.from_matrix(m))], (m,), i)


@DTYPE
def test_long_batches_across_real_blocks(dtype):
    """Batches longer than one block (at the engine's own block size, on the default
    threads): the rows at either side of each block boundary, alone, give the batch's bits."""
    n = _blocks.block_size(dtype) + 5
    rng = np.random.default_rng(7)
    q = rng.standard_normal((n, 4)).astype(dtype)
    p = rng.standard_normal((n, 4)).astype(dtype)
    v = rng.standard_normal((n, 3)).astype(dtype)
    t = rng.uniform(0, 1, n).astype(dtype)
    Q, R = QuatArray, Rotation
    cases = [("product", lambda q, p: Q(q) * Q(p), (q, p)), ("normalized", lambda q: Q(q).normalized(), (q,)),
             ("log", lambda q: Q(q).log(), (q,)), ("as_matrix", lambda q: R.from_quat(q).as_matrix(), (q,)),
             ("as_euler", lambda q: R.from_quat(q).as_euler("zyx"), (q,)),
             ("as_mrp", lambda q: R.from_quat(q).as_mrp(), (q,)), ("from_mrp", R.from_mrp, (v,)),
             ("from_rotvec", R.from_rotvec, (v,)),
             ("apply", lambda q, v: R.from_quat(q).apply(v), (q, v)), ("slerp", slerp, (q, p, t)),
             ("rigid apply", lambda q, v: RigidTransform.from_components(v, R.from_quat(q)).apply(v), (q, v))]
    edge = _blocks.block_size(dtype)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, f, args in cases:
            whole = _raw(f(*args))
            for i in (0, edge - 1, edge, n - 1):
                _same(_raw(f(*(a[i] for a in args))), whole[i], f"{name} at {i}")


@DTYPE
def test_dask_chunks_give_the_memory_bits(dtype):
    """Chunked (Dask) evaluation runs the same kernels on each chunk: the in-memory bits."""
    da = pytest.importorskip("dask.array")
    from quatarray import dask as qd
    rng = np.random.default_rng(3)
    q = rng.standard_normal((50, 4)).astype(dtype)
    Q = da.from_array(q, chunks=(7, 4))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, lazy, memory in (("as_euler", qd.as_euler(Q, "xyz"), QuatArray(q).as_euler("xyz")),
                                   ("as_matrix", qd.as_matrix(Q), QuatArray(q).as_matrix()),
                                   ("log", qd.log(Q), QuatArray(q).log()),
                                   ("product", qd.multiply(Q, Q[::-1]), QuatArray(q) * QuatArray(q[::-1]))):
            _same(lazy.compute(scheduler="synchronous"), _raw(memory), name)


@DTYPE
@given(b=batches())
def test_one_normalisation(dtype, b):
    """`Rotation.from_quat` (either component order), `QuatArray.normalized` and the raw
    kernel give the same bits: one normalisation kernel."""
    (seed, kinds, scale), _ = b
    q = _rows(seed, kinds, dtype, scale)
    want = QuatArray(q).normalized().view(np.ndarray)
    _same(Rotation.from_quat(q, scalar_first=True).as_quat(scalar_first=True), want, "from_quat scalar_first")
    _same(Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_quat(scalar_first=True), want, "from_quat scalar last")
    _same(Rotation(q, scalar_first=True).as_quat(scalar_first=True), want, "Rotation()")


@pytest.mark.parametrize("s", [1e-150, 1e-160, 1e-200, 1e-300, 5e-324, 1e-8])
def test_one_rotation_at_the_kernels_branches(s):
    """A float64 rotation whose |v|² underflows, or sits at the edges of the kernels' common
    path, gives the bits of the same row in a batch (a single rotation may run the formula
    on Python floats only where the block kernel takes its common path)."""
    rows = np.array([[s, 0, 0, 1], [0, s, s, 1], [s, 0, 0, 0], [0, 1, 0, 0], [s, -s, 0, -1]])
    r = Rotation.from_quat(rows)
    v = np.array([3.0, -1e-300, 2e300])
    ops = [("as_rotvec", lambda x: x.as_rotvec()), ("magnitude", lambda x: x.magnitude()),
           ("as_matrix", lambda x: x.as_matrix()), ("apply", lambda x: x.apply(v)),
           ("as_euler xyz", lambda x: x.as_euler("xyz")), ("as_euler ZYZ", lambda x: x.as_euler("ZYZ")),
           ("from_rotvec", lambda x: Rotation.from_rotvec(x.as_rotvec()).as_quat()),
           ("from_euler", lambda x: Rotation.from_euler("zyx", x.as_euler("zyx")).as_quat())]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # gimbal lock
        for name, f in ops:
            whole = np.asarray(f(r))
            for i in range(len(rows)):
                _same(f(r[i]), whole[i], f"{name}, row {i}")


def _edge_quaternions():
    """float64 quaternions at the edges of the algebra's one-quaternion float paths: e**w near
    overflow, |q|² and |v|² at and beyond the range, zero and underflowing vectors, negative
    reals, near-identity and unit rows."""
    rng = np.random.default_rng(11)
    q = rng.standard_normal((120, 4)) * rng.choice([1e-3, 1.0, 30.0, 1e10, 1e150, 1e-150, 1e160, 1e-160], (120, 1))
    q[::7, 1:] = 0
    q[1::11, 0] = rng.choice([708.9, 709.0, 709.5, -800.0], len(q[1::11]))
    q[2::13, 2:] = 1e-200
    q[3::17] /= np.linalg.norm(q[3::17], axis=1, keepdims=True)
    q[4::19, 0] = -np.abs(q[4::19, 0])
    q[5::23, 1:] *= 1e-9
    q[6::29] = [1, 0, 0, 0]
    q[7::31] = [-2, 0, 0, 0]
    q[8::37] = [0, 0, 0, 0]
    return q


@pytest.mark.parametrize("t", [0.3, -2.5, 7.0, 250.0, 1e16])
def test_one_quaternion_algebra_at_its_float_paths_edges(t):
    """exp, log, power, norm and inverse of one float64 quaternion run their formulas on Python floats where
    the block kernel takes its common path, and the block kernel elsewhere: either way the
    bits of the same row in a batch, alone and as a batch of one."""
    q = _edge_quaternions()
    Q = QuatArray
    ops = [("exp", lambda x: Q(x).exp()), ("log", lambda x: Q(x).log()), ("power", lambda x: Q(x) ** t),
           ("norm", lambda x: Q(x).norm())]
    nonzero = q[np.any(q != 0, axis=1)]   # (the inverse of a zero quaternion raises)
    ops = [(name, f, q) for name, f in ops] + [("inverse", lambda x: Q(x).inverse(), nonzero)]
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        for name, f, q in ops:
            whole = _raw(f(q))
            for i in range(len(q)):
                _same(_raw(f(q[i])), whole[i], f"{name}, row {i}")
                _same(_raw(f(q[i:i + 1]))[0], whole[i], f"{name}, row {i} as a batch of one")


_FLOAT32_OPS = [
    ("norm", lambda x: QuatArray(x).norm()), ("normalized", lambda x: QuatArray(x).normalized()),
    ("inverse", lambda x: QuatArray(x).inverse()), ("exp", lambda x: QuatArray(x).exp()),
    ("log", lambda x: QuatArray(x).log()), ("power 0.3", lambda x: QuatArray(x) ** 0.3),
    ("power -2.5", lambda x: QuatArray(x) ** -2.5), ("power 7", lambda x: QuatArray(x).power(np.float32(7))),
    ("power 1e16", lambda x: QuatArray(x) ** 1e16),
    ("as_rotvec", lambda x: QuatArray(x).as_rotvec()), ("as_rotvec degrees", lambda x: QuatArray(x).as_rotvec(True)),
    ("as_euler xyz", lambda x: QuatArray(x).as_euler("xyz")),
    ("as_euler ZYZ", lambda x: QuatArray(x).as_euler("ZYZ", degrees=True)),
    ("as_euler zxy", lambda x: QuatArray(x).as_euler("zxy")),
    ("as_davenport", lambda x: QuatArray(x).as_davenport([[0, 0, 1], [1, 0, 0], [0, 1, 0]], "e")),
    ("from_quat", lambda x: Rotation.from_quat(x, scalar_first=True)),
    ("magnitude", lambda x: Rotation.from_quat(x).magnitude()),
    ("Rotation as_rotvec", lambda x: Rotation.from_quat(x).as_rotvec()),
    ("Rotation pow", lambda x: Rotation.from_quat(x) ** 0.37),
    ("Rotation as_euler", lambda x: Rotation.from_quat(x).as_euler("zyx")),
    ("Rotation as_matrix", lambda x: Rotation.from_quat(x).as_matrix()),
    ("Rotation as_mrp", lambda x: Rotation.from_quat(x).as_mrp())]
"""The methods whose one float32 quaternion runs its float path's formula on float32 scalars
(`quatarray._ops.F32`)."""


@given(b=batches(), span=st.sampled_from([20, 40, 59, 62, 75]))
def test_one_float32_element_gives_the_batchs_bits(b, span):
    """One float32 quaternion (shape (4,) or (1, 4)) runs its method's formula on float32
    scalars where the block kernel takes its common path, and the block kernel elsewhere:
    random, near-identity, near-half-turn and gimbal-lock rows scaled by powers of two up to
    2**±span (across float32's ranges: |q|² within 2**±80, components below 2**60) give
    the bits of the same row in the batch."""
    (seed, kinds, _), i = b
    q = _rows(seed, kinds, np.float32, True, span)
    rng = np.random.default_rng(seed)
    v = (rng.standard_normal((len(q), 3)) * 10.0 ** rng.uniform(-30, 30, (len(q), 1))).astype(np.float32)
    check(_FLOAT32_OPS, (q,), i)
    check([("rotate", lambda q, v: QuatArray(q).rotate(v)),
           ("apply", lambda q, v: Rotation.from_quat(q).apply(v)),
           ("apply inverse", lambda q, v: Rotation.from_quat(q).apply(v, inverse=True))], (q, v), i)
    r = Rotation.from_quat(q)
    size = 10.0 ** rng.uniform(-20, 20, (len(q), 1))
    check([("from_rotvec", lambda x: QuatArray.from_rotvec(x)),
           ("from_rotvec degrees", lambda x: Rotation.from_rotvec(x, degrees=True))],
          ((r.as_rotvec() * size).astype(np.float32),), i)
    check([("from_euler", lambda x: QuatArray.from_euler("xyz", x)),
           ("from_euler ZYZ degrees", lambda x: Rotation.from_euler("ZYZ", x, degrees=True))],
          ((r.as_euler("xyz", suppress_warnings=True) * size ** 0.1).astype(np.float32),), i)
    m = r.as_matrix()
    m[::3] *= np.float32(1.00001)   # (within the orthogonality tolerance, or not: the block path's projection)
    m[1::4] *= np.float32(1.01)
    check([("from_matrix", lambda x: QuatArray.from_matrix(x)), ("Rotation from_matrix", lambda x: Rotation.from_matrix(x))],
          (m,), i)


def test_one_float32_quaternion_skips_the_block_engine(monkeypatch):
    """A typical float32 quaternion (and vector) takes the float paths: no block kernel runs."""
    def refuse(*args, **kwargs):
        raise AssertionError("the block engine ran")

    q = np.array([0.7, -0.3, 0.5, 0.4], np.float32)
    v = np.array([1.0, -2.0, 0.5], np.float32)
    for module, name in ((_blocks, "blockwise"), (_blocks, "on_views"), (_kernels, "_normalize_flat"),
                         (_kernels, "_rotate_few")):
        monkeypatch.setattr(module, name, refuse)
    for x in (q, q[None]):
        for name, f in _FLOAT32_OPS:
            # (Rotation's own rows take no engine; tθ = 1e16 θ: the block kernel's)
            if not name.startswith(("Rotation", "magnitude", "from_quat", "power 1e16")):
                f(x)
        QuatArray(x).rotate(v)


@pytest.mark.parametrize("dtype", [np.float32, np.float64], ids=["f32", "f64"])
def test_track_of_one_pair_gives_the_bits_among_others(dtype):
    """A track of one pair of keys builds its frame on the pair's floats (`frames`); the same
    pair among other tracks, on rows: the same bits."""
    rng = np.random.default_rng(15)
    q = rng.standard_normal((40, 2, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    q[::5, 1] = -q[::5, 0]   # (antipodal keys: no unique arc, the block kernel's rows)
    q[1::5, 1] = q[1::5, 0]
    q = q.astype(dtype)
    t = np.linspace(0.0, 1.0, 7)
    for keys in q:
        one = Track([0.0, 1.0], keys)(t)
        among = Track([0.0, 1.0], np.stack([keys, q[0], keys[::-1]], axis=1))(t)
        _same(_raw(one), _raw(among)[:, 0], "track of one pair")


def _edge_quaternions32():
    """float32 quaternions at the edges of the float paths: e**w near float32's overflow,
    |q|² and |v|² at and beyond 2**±80, components at 2**60, zero and underflowing
    vectors, negative reals, w = 0 and tiny, near-identity and unit rows."""
    rng = np.random.default_rng(13)
    q = rng.standard_normal((180, 4)) * rng.choice(
        [1e-3, 1.0, 30.0, 1e10, 1e-10, 1e12, 1e-12, 2.0 ** 59, 2.0 ** 61, 1e-19, 1e-21], (180, 1))
    q[::7, 1:] = 0
    q[1::11, 0] = rng.choice([40.0, 87.9, 88.0, 88.5, -100.0], len(q[1::11]))
    q[2::13, 2:] = rng.choice([1e-20, 1e-30, 2.0 ** -40], (len(q[2::13]), 1))
    q[3::17] /= np.linalg.norm(q[3::17], axis=1, keepdims=True)
    q[4::19, 0] = -np.abs(q[4::19, 0])
    q[5::23, 1:] *= 1e-4
    q[6::29] = [1, 0, 0, 0]
    q[7::31] = [-2, 0, 0, 0]
    q[9::41, 0] = 0
    q[10::43, 0] *= 1e-25
    return q.astype(np.float32)


def test_one_float32_quaternion_at_its_float_paths_edges():
    """The float32 float paths at their edges (`_edge_quaternions32`, zero rows left out:
    the conversions refuse them): alone and as a batch of one, the bits of the same row in
    the batch."""
    q = _edge_quaternions32()
    q = q[np.any(q != 0, axis=1)]
    rng = np.random.default_rng(14)
    v = (rng.standard_normal((len(q), 3)) * rng.choice([1.0, 1e20, 2.0 ** 61, 1e-30], (len(q), 1))).astype(np.float32)
    ops = [(name, lambda x, v, f=f: f(x)) for name, f in _FLOAT32_OPS]
    ops.append(("rotate", lambda x, v: QuatArray(x).rotate(v)))
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        for name, f in ops:
            whole = _raw(f(q, v))
            for i in range(len(q)):
                _same(_raw(f(q[i], v[i])), whole[i], f"{name}, row {i}")
                _same(_raw(f(q[i:i + 1], v[i:i + 1]))[0], whole[i], f"{name}, row {i} as a batch of one")


@pytest.mark.parametrize("shortest", [True, False])
@pytest.mark.parametrize("dtype, t_dtype", [(np.float64, np.float64), (np.float32, np.float64),
                                            (np.float32, np.float32)], ids=["f64", "f32", "f32 t32"])
def test_one_pair_slerp_and_squad_at_their_float_paths_edges(shortest, dtype, t_dtype):
    """slerp of one float64 or float32 pair and squad of one quadruple run the formulas on
    floats only where the block kernel takes its common path (no wide arc followed as
    given, t within [-1, 2], |A|² + |B|² in range, in float32 a sign of A·B not in doubt):
    the batch's bits either way, for t of either float dtype."""
    rng = np.random.default_rng(12)
    n = 160
    q0 = rng.standard_normal((n, 4))
    q0 /= np.linalg.norm(q0, axis=1, keepdims=True)
    q1 = rng.standard_normal((n, 4))
    q1 /= np.linalg.norm(q1, axis=1, keepdims=True)
    q1[::3] = q0[::3] + rng.standard_normal((len(q0[::3]), 4)) * 1e-9
    q1[::5] = -q0[::5]
    q1[::7] = q0[::7]
    r = rng.standard_normal((len(q0[1::9]), 4))   # A·B near 0 (in doubt in float32, `hemisphere`)
    r -= np.sum(r * q0[1::9], axis=1, keepdims=True) * q0[1::9]
    q1[1::9] = r / np.linalg.norm(r, axis=1, keepdims=True) + q0[1::9] * rng.uniform(-1e-5, 1e-5, (len(r), 1))
    scale = rng.choice([1.0, 1e-200, 1e200, 3.0] if dtype == np.float64 else [1.0, 1e-20, 1e20, 3.0, 2.0 ** 61],
                       (n, 1))
    q0, q1 = (q0 * scale).astype(dtype), (q1 * scale).astype(dtype)
    a, b = np.roll(q1, 1, axis=0), np.roll(q0, 2, axis=0)
    t = rng.uniform(-1.5, 2.5, n)
    t[::4] = rng.choice([0.0, 0.5, 1.0, -1.0, 2.0], len(t[::4]))
    t = t.astype(t_dtype)
    ops = [("slerp", lambda p, q, a, b, t: slerp(p, q, t, shortest=shortest)),
           ("squad", lambda p, q, a, b, t: squad(p, a, b, q, t))]
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        for name, f in ops:
            whole = _raw(f(q0, q1, a, b, t))
            for i in range(n):
                _same(_raw(f(q0[i], q1[i], a[i], b[i], t[i])), whole[i], f"{name}, pair {i}")
                one = (x[i:i + 1] for x in (q0, q1, a, b, t))
                _same(_raw(f(*one))[0], whole[i], f"{name}, pair {i} as a batch of one")


@DTYPE
@pytest.mark.parametrize("n", [32, 33, _blocks.VIEWS_MAX, _blocks.VIEWS_MAX + 1, _blocks.FEW, _blocks.FEW + 1,
                               2048, 2049, 4096, 4097])
def test_batches_at_the_engines_size_thresholds(dtype, n):
    """At either side of the size thresholds of the small-batch paths (Python-float range
    checks up to 32 norms or vectors; `_blocks.VIEWS_MAX`: kernels called on views of a
    Rotation's storage without the engine, and as_matrix's stacked plan or its block
    program; `_blocks.FEW`:
    rotations and products on stacked rows; `_blocks.SMALL_ROWS`: fresh scratch rows or the
    kept buffer, at 1024 float64 / 2048 float32 rows of four; squares of 4096 elements
    stacked; `_blocks.FEW` again: the power's moduli far from 1 from every row's power or
    from the far rows gathered), the first, middle and last rows of the
    batch, alone and as a batch of one, give the batch's bits."""
    kinds = [KINDS[k % len(KINDS)] for k in range(n)]
    q = _rows(n, kinds, dtype, False)
    r = Rotation.from_quat(q, scalar_first=True)
    v = np.random.default_rng(n).standard_normal((n, 3)).astype(dtype)
    v[n // 2] *= np.finfo(dtype).max / 4   # one vector past the rescaling bound, mid-batch
    p = _rows(n + 1, kinds, dtype, True)     # any magnitude, for the QuatArray algebra
    Q = QuatArray
    check([("product", lambda q, p, v: Q(q) * Q(p)), ("rotate", lambda q, p, v: Q(p).rotate(v)),
           ("norm", lambda q, p, v: Q(p).norm()), ("normalized", lambda q, p, v: Q(p).normalized()),
           ("log", lambda q, p, v: Q(p).log()), ("as_rotvec", lambda q, p, v: Q(p).as_rotvec()),
           ("as_matrix", lambda q, p, v: Q(p).as_matrix()), ("exp", lambda q, p, v: np.exp(Q(q * 3))),
           ("power", lambda q, p, v: Q(p) ** 0.3), ("power of units", lambda q, p, v: Q(q) ** -1.7),
           ("sqrt", lambda q, p, v: np.sqrt(Q(p)))], (q, p, v), n // 2)
    axes = [[0, 0, 1], [1, 0, 0], [0, 1, 0]]
    R = Rotation
    ops = [("as_matrix", lambda r: r.as_matrix()), ("as_rotvec", lambda r: r.as_rotvec()),
           ("as_mrp", lambda r: r.as_mrp()), ("magnitude", lambda r: r.magnitude()),
           ("as_euler", lambda r: r.as_euler("xyz")), ("as_euler ZYZ", lambda r: r.as_euler("ZYZ")),
           ("as_davenport", lambda r: r.as_davenport(axes, "e")), ("inv", lambda r: r.inv()),
           ("mul", lambda r: r * r), ("pow", lambda r: r ** 0.3),
           ("as_quat canonical", lambda r: r.as_quat(canonical=True))]
    check([(name, lambda q, f=f: f(R.from_quat(q, scalar_first=True))) for name, f in ops], (q,), 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # gimbal lock
        for name, f, args in [("apply", lambda q, v: R.from_quat(q, scalar_first=True).apply(v), (q, v)),
                              ("from_quat", lambda q: R.from_quat(q, scalar_first=True), (q,)),
                              ("from_matrix", R.from_matrix, (r.as_matrix(),)),
                              ("from_rotvec", R.from_rotvec, (r.as_rotvec(),)), ("from_mrp", R.from_mrp, (r.as_mrp(),)),
                              ("from_rotvec, a huge vector", R.from_rotvec, (v,)),
                              ("from_mrp, a huge vector", R.from_mrp, (v,)),
                              ("from_euler", lambda e: R.from_euler("xyz", e), (r.as_euler("xyz"),))] + [
                (name, lambda q, f=f: f(R.from_quat(q, scalar_first=True)), (q,)) for name, f in ops]:
            whole = _raw(f(*args))
            for i in (0, n // 2, n - 1):
                _same(_raw(f(*(a[i] for a in args))), whole[i], f"{name} at {i}: alone")
                _same(_raw(f(*(a[i:i + 1] for a in args)))[0], whole[i], f"{name} at {i}: batch of one")


@DTYPE
@pytest.mark.parametrize("n", [1100, 1101])
def test_one_block_of_views_or_copied_blocks(dtype, n, monkeypatch):
    """Read-only kernels read a Rotation's storage through views up to one block
    (`_blocks.BLOCK`) and copies of its blocks past it: the same bits either side.  The
    block is lowered to 1100 rows (past `_blocks.FEW`, where the squares of
    `_convert._half_turn` take kept scratch rows in the storage's layout) to keep the
    check short."""
    monkeypatch.setattr(_blocks, "BLOCK", 1100)
    test_batches_at_the_engines_size_thresholds(dtype, n)


@DTYPE
@pytest.mark.parametrize("layout", ["strided", "fortran", "reversed", "read-only"])
def test_any_memory_layout_gives_the_contiguous_bits(dtype, layout):
    """Input in any memory layout (strided or reversed views, Fortran order, read-only) gives
    the bits of its contiguous copy, at a small batch (the engine's views) and past one block."""
    for n in (5, _blocks.VIEWS_MAX + 3):
        q = _rows(n, [KINDS[k % len(KINDS)] for k in range(n)], dtype, False)
        if layout == "strided":
            x = np.repeat(q, 2, axis=0)[::2]
        elif layout == "fortran":
            x = np.asfortranarray(q)
        elif layout == "reversed":
            x = q[::-1].copy()[::-1]
        else:
            x = q.copy()
            x.flags.writeable = False
        saved = x.copy()
        Q, R = QuatArray, Rotation
        for name, f in [("normalized", lambda a: Q(a).normalized()), ("log", lambda a: Q(a).log()),
                        ("as_matrix", lambda a: Q(a).as_matrix()), ("as_rotvec", lambda a: Q(a).as_rotvec()),
                        ("as_mrp", lambda a: Q(a).as_mrp()), ("as_euler", lambda a: Q(a).as_euler("zyx")),
                        ("product", lambda a: Q(a) * Q(a)),
                        ("Rotation", lambda a: R.from_quat(a, scalar_first=True)),
                        ("Rotation normalize=False", lambda a: R(a, scalar_first=True, normalize=False).as_matrix()),
                        ("from_matrix", lambda a: R.from_matrix(Q(a).as_matrix())),
                        ("from_rotvec", lambda a: R.from_rotvec(a[:, 1:])), ("from_mrp", lambda a: R.from_mrp(a[:, 1:])),
                        ("slerp", lambda a: slerp(a, a[::-1], np.linspace(0, 1, n, dtype=dtype)))]:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")   # gimbal lock
                _same(_raw(f(x)), _raw(f(q)), f"{name}, {n} rows")
        np.testing.assert_array_equal(x, saved, strict=True)   # never written


@DTYPE
@pytest.mark.parametrize("k", [2, 3, 16, 17, 18, 33])
def test_interpolants_at_their_key_count_thresholds(dtype, k):
    """Slerp and RotationSpline over 2 keys (the Python-float paths of one float64 pair), and
    around the spline solve's dense base case (16 block rows): each query alone and as a batch
    of one gives the batch's bits, at, between and next to the keys; near-identity, half-turn,
    gimbal, equal and antipodal neighbouring keys included."""
    keys = _rows(k, [KINDS[(j + k) % len(KINDS)] for j in range(k)], dtype, False)
    if k > 2:
        keys[2] = keys[1]       # equal neighbours
    if k > 3:
        keys[3] = -keys[2]      # antipodal neighbours (the same rotation)
    rng = np.random.default_rng(k)
    times = np.cumsum(rng.uniform(0.1, 2.0, k))
    at = np.concatenate([times, rng.uniform(times[0], times[-1], 8), (times[:-1] + times[1:]) / 2,
                         np.nextafter(times[1:], -np.inf)])
    r = Rotation.from_quat(keys, scalar_first=True)
    slerp_, spline = Slerp(times, r), RotationSpline(times, r)
    check([("Slerp", slerp_), ("RotationSpline", spline), ("RotationSpline rate", lambda t: spline(t, 1)),
           ("RotationSpline acceleration", lambda t: spline(t, 2))], (at,), len(at) - 1)
    for name, f in [("Slerp", slerp_), ("RotationSpline", spline), ("RotationSpline rate", lambda t: spline(t, 1))]:
        whole = _raw(f(at))
        assert np.isfinite(whole).all(), name
        for i in range(len(at)):
            _same(_raw(f(at[i])), whole[i], f"{name} at {at[i]}: alone")
            _same(_raw(f(at[i:i + 1]))[0], whole[i], f"{name} at {at[i]}: batch of one")


#: Batches of k tracks: the seed of the key times, and for each track (size of the random
#: rotation-vector steps between keys, seed): equal keys (the spline's fixed point settles at
#: its first step), gentle turns (a few steps), larger ones (up to scipy's ten steps) and
#: large turns at uneven spacings (Newton's method, from where the fixed point got or from the
#: linear solution); at 40 keys (past the solve's dense base case) some tracks refactorise
#: Newton's Jacobian at a step where others keep it.  The times' seeds are ones where float32
#: keys too gave other bits in the batch when the batch iterated as one (in float32 the
#: extra steps' changes mostly round away).
SPLINE_TRACKS = {5: (6, [(0.0, 0), (0.02, 0), (0.3, 0), (0.8, 0), (0.8, 1), (1.5, 0), (2.5, 1)]),
                 40: (69, [(0.0, 0), (0.02, 0), (0.3, 0), (0.3, 1), (0.8, 2), (2.5, 0)])}


def _spline_tracks(k):
    """Key times (k,) at uneven spacings and keys (k, tracks, 4) of `SPLINE_TRACKS[k]`."""
    seed_times, tracks = SPLINE_TRACKS[k]
    times = np.cumsum(np.r_[0, 10 ** np.random.default_rng(seed_times).uniform(-1.5, 0.5, k - 1)])
    walks = [np.cumsum(np.random.default_rng(100 * k + seed).normal(scale=scale, size=(k, 3)), axis=0)
             for scale, seed in tracks]
    return times, QuatArray.from_rotvec(np.stack(walks, axis=1)).view(np.ndarray)


def _counting(monkeypatch, module, name):
    """Replace `module.name` by a wrapper counting its calls; returns the count (a list)."""
    calls = []
    real = getattr(module, name)

    def counted(*args, **kwargs):
        calls.append(name)
        return real(*args, **kwargs)
    monkeypatch.setattr(module, name, counted)
    return calls


@DTYPE
@pytest.mark.parametrize("k", sorted(SPLINE_TRACKS))
def test_spline_tracks_iterate_as_alone(dtype, k, monkeypatch):
    """Tracks of one batch whose rate equations take different work (`SPLINE_TRACKS`) give,
    as coefficients, evaluated and as rates, each the bits of the track alone and as a batch
    of one: each track stops its fixed point, switches to Newton's method, stops it and
    refactorises its Jacobian on its own steps, not on the batch's largest."""
    times, keys = _spline_tracks(k)
    keys = keys.astype(dtype)
    n = keys.shape[1]
    newton = _counting(monkeypatch, _interp_spline, "_newton")
    # the premise: the tracks alone take different paths (some Newton's method, some not)
    alone = []
    for j in range(n):
        newton.clear()
        alone.append((_interp_spline.coefficients(times, keys[:, j]), bool(newton)))
    assert not alone[0][1] and not alone[1][1], "equal keys and gentle turns settle in the fixed point"
    assert sum(used for _, used in alone) >= 2, "some tracks need Newton's method"
    batch = (2, 3) if n == 6 else (n,)   # a batch of more than one axis too
    keys_batch = keys.reshape((k,) + batch + (4,))
    coeff = _interp_spline.coefficients(times, keys_batch).reshape(4, k - 1, n, 3)
    for j, (want, _) in enumerate(alone):
        _same(coeff[:, :, j], want, f"coefficients of track {j}")
        _same(_interp_spline.coefficients(times, keys[:, j:j + 1])[:, :, 0], want, f"track {j} as a batch of one")
    at = np.concatenate([times, (times[1:] + times[:-1]) / 2, [times[0] - 0.5, times[-1] + 0.5]])
    track = Track(times, keys_batch, method="spline", extrapolate="extend")
    spline = RotationSpline(times, Rotation.from_quat(keys_batch, scalar_first=True))
    got = [_raw(track(at)).reshape(len(at), n, 4), _raw(track.angular_velocity(at)).reshape(len(at), n, 3),
           _raw(spline(at)).reshape(len(at), n, 4), _raw(spline(at, 1)).reshape(len(at), n, 3)]
    for j in range(n):
        track_j = Track(times, keys[:, j], method="spline", extrapolate="extend")
        spline_j = RotationSpline(times, Rotation.from_quat(keys[:, j], scalar_first=True))
        for name, g, want in zip(["Track", "Track angular_velocity", "RotationSpline", "RotationSpline rate"], got,
                                 [track_j(at), track_j.angular_velocity(at), spline_j(at), spline_j(at, 1)]):
            _same(g[:, j], _raw(want), f"{name}, track {j}")
    if k > _interp_spline.DENSE + 1:   # the premise at 40 keys
        partial = _counting(monkeypatch, _interp_spline, "_put_tracks")
        _interp_spline.coefficients(times, keys_batch)
        assert partial, "some tracks refactorise Newton's Jacobian where others keep it"


def _iterations(q, weights):
    """The fewest iterations with which `geodesic_mean` of q (n, 4) converges."""
    for m in range(1, 101):
        try:
            geodesic_mean(q, weights, max_iter=m)
            return m
        except ValueError:
            pass
    raise AssertionError("did not converge")


@DTYPE
@pytest.mark.parametrize("weighted", [False, True], ids=["unweighted", "weighted"])
@pytest.mark.parametrize("groups_first", [False, True], ids=["groups last", "groups first"])
def test_geodesic_mean_groups_iterate_as_alone(dtype, weighted, groups_first):
    """Groups of `geodesic_mean(axis=...)` whose Karcher iterations take different numbers
    of steps (equal rotations, a tight cluster, wide spreads) give each the bits of the group
    alone and as a batch of one: each stops on its own step, not on the largest of the batch.
    (The means are iterated in float64: a float32 result rounds away the differences, below
    `tol`, that a batch-wide stop made.)"""
    rng = np.random.default_rng(4)
    spreads = np.array([0.0, 1e-3, 0.1, 0.6, 1.2, 0.3])
    n = 25
    rv = rng.normal(size=(n, len(spreads), 3)) * spreads[:, None] + rng.normal(size=(1, len(spreads), 3))
    q = QuatArray.from_rotvec(rv).view(np.ndarray).astype(dtype)
    w = rng.uniform(0.1, 1.0, (n, len(spreads))) if weighted else None
    steps = [_iterations(q[:, j], None if w is None else w[:, j]) for j in range(len(spreads))]
    assert len(set(steps)) >= 3, steps   # the premise: the groups stop at different steps
    if groups_first:   # the groups on axis 0, two axes of them; the averaged axis last
        got = geodesic_mean(q.transpose(1, 0, 2).reshape(2, 3, n, 4), axis=-1,
                            weights=None if w is None else w.T.reshape(2, 3, n))
        got = got.as_quat(scalar_first=True).reshape(len(spreads), 4)
    else:
        got = geodesic_mean(q, w, axis=0).as_quat(scalar_first=True)
    for j in range(len(spreads)):
        wj = None if w is None else w[:, j]
        _same(got[j], geodesic_mean(q[:, j], wj).as_quat(scalar_first=True), f"group {j} alone")
        _same(got[j], geodesic_mean(q[:, j:j + 1], None if w is None else w[:, j:j + 1], axis=0)
              .as_quat(scalar_first=True)[0], f"group {j} as a batch of one")


@DTYPE
@pytest.mark.parametrize("weighted", [False, True], ids=["unweighted", "weighted"])
@pytest.mark.parametrize("rows", [5, 7, 20])
def test_chordal_means_of_groups_are_each_alone(dtype, weighted, rows, monkeypatch):
    """`Rotation.mean` and `RigidTransform.mean` over axes: each group's mean has the bits of
    the group averaged alone, whatever the other groups, the layout (groups first or last,
    two kept or two averaged axes) or the number of slabs its rows are summed in (`ROWS`
    lowered to 7: groups of fewer, as many and more rows than one product takes)."""
    from quatarray import _rotation_algorithms
    monkeypatch.setattr(_rotation_algorithms, "ROWS", 7)
    rng = np.random.default_rng(rows)
    groups = 6
    q = _rows(rows, KINDS * (groups * rows // len(KINDS) + 1), dtype, False)[:groups * rows].reshape(groups, rows, 4)
    t = (rng.standard_normal((groups, rows, 3)) * 10.0 ** rng.uniform(-3, 3, (groups, 1, 1))).astype(dtype)
    w = rng.uniform(0.0, 2.0, (groups, rows)) if weighted else None

    def means(q, t, w, axis):
        r = Rotation.from_quat(q, scalar_first=True)
        return (r.mean(weights=w, axis=axis).as_quat(scalar_first=True),
                RigidTransform.from_components(t, r).mean(weights=w, axis=axis).as_matrix())

    alone = [means(q[g], t[g], None if w is None else w[g], None) for g in range(groups)]
    last = means(q, t, w, 1)                                                     # groups first
    first = means(*(np.ascontiguousarray(a.swapaxes(0, 1)) for a in (q, t)),
                  None if w is None else np.ascontiguousarray(w.T), 0)           # groups last, C order
    two_kept = means(q.reshape(2, 3, rows, 4), t.reshape(2, 3, rows, 3),
                     None if w is None else w.reshape(2, 3, rows), 2)
    split = rows // 5 * 5 == rows and rows > 5   # two averaged axes: the rows as (rows / 5, 5)
    two_averaged = means(q.reshape(groups, rows // 5, 5, 4), t.reshape(groups, rows // 5, 5, 3),
                         None if w is None else w.reshape(groups, rows // 5, 5), (1, 2)) if split else None
    for g, (quat, matrix) in enumerate(alone):
        for name, got in [("groups first", last), ("groups last", first), ("two kept axes", two_kept),
                          ("two averaged axes", two_averaged)]:
            if got is None:
                continue
            gq, gm = got[0].reshape(groups, 4), got[1].reshape(groups, 4, 4)
            _same(gq[g], quat, f"Rotation.mean, group {g}, {name}")
            _same(gm[g], matrix, f"RigidTransform.mean, group {g}, {name}")


def test_chordal_means_of_long_groups_at_the_real_slab_size():
    """Three groups of 40,000 rotations (more than one slab of `ROWS` rows each), averaged
    along either axis of a C-ordered array: each mean has the bits of its group alone (the
    slabs were cut by the number of groups, 10,922 rows here, against 32,768 alone)."""
    from quatarray import _rotation_algorithms
    rng = np.random.default_rng(7)
    n = _rotation_algorithms.ROWS + 7232
    q = rng.standard_normal((3, n, 4))
    got = Rotation.from_quat(q).mean(axis=1).as_quat()
    got_first = Rotation.from_quat(np.ascontiguousarray(q.swapaxes(0, 1))).mean(axis=0).as_quat()
    for g in range(3):
        alone = Rotation.from_quat(q[g]).mean().as_quat()
        _same(got[g], alone, f"group {g}, groups first")
        _same(got_first[g], alone, f"group {g}, groups last")
