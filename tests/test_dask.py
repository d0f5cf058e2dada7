"""quatarray.dask equals the in-memory API on chunked data; the Zarr path of the CLI; clear errors."""

import importlib
import os
import pickle
import sys
import warnings

import numpy as np
import pytest

da = pytest.importorskip("dask.array", reason="the dask extra is not installed (pip install 'quatarray[dask]')")
import dask  # noqa: E402

import quatarray  # noqa: E402
import quatarray.formats  # noqa: E402,F401
from quatarray import QuatArray, Rotation, RotationSpline  # noqa: E402
from quatarray import dask as qd  # noqa: E402
from quatarray import interpolate as qi  # noqa: E402
from quatarray.interpolate import Track  # noqa: E402

BATCH = (11, 6)
#: one chunk, ragged chunks on both axes, single rows, and chunks of one element
CHUNKS = [(11, 6), (4, 4), (1, 6), (5, 1)]
DTYPES = [np.float32, np.float64]


@pytest.fixture(params=["synchronous", "threads"])
def scheduler(request):
    with dask.config.set(scheduler=request.param):
        yield request.param


def tol(dtype):
    # same kernels on the same values: a few rounding steps at most (single-element fast paths)
    return dict(rtol=32 * np.finfo(dtype).eps, atol=32 * np.finfo(dtype).eps)


def unit(rng, shape, dtype):
    q = rng.normal(size=shape + (4,))
    return (q / np.linalg.norm(q, axis=-1, keepdims=True)).astype(dtype)


def quats(r):
    """Scalar-first quaternions of a scipy-style Rotation."""
    return r.as_quat(scalar_first=True)


def chunked(x, chunks):
    return da.from_array(x, chunks=chunks + x.shape[len(chunks):])


def check(lazy, expected, dtype):
    assert isinstance(lazy, da.Array)
    got = lazy.compute()
    assert type(got) is np.ndarray        # chunks are plain ndarrays
    expected = np.asarray(expected)
    assert got.shape == lazy.shape == expected.shape
    assert got.dtype == lazy.dtype == expected.dtype
    np.testing.assert_allclose(got, expected, **tol(dtype))


# --------------------------------------------------------------------------- algebra and conversions

@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("chunks", CHUNKS)
def test_algebra_equals_memory(rng, scheduler, chunks, dtype):
    p, q = unit(rng, BATCH, dtype), unit(rng, BATCH, dtype)
    q[0, 0] *= 3   # a non-unit quaternion
    t = rng.uniform(-2, 2, BATCH).astype(dtype)
    v = rng.normal(size=BATCH + (3,)).astype(dtype)
    P, Q, T, V = chunked(p, chunks), chunked(q, chunks), chunked(t, chunks), chunked(v, chunks)
    mq = QuatArray(q)
    check(qd.multiply(P, Q), QuatArray(p) * mq, dtype)
    check(qd.multiply(P[:, :1], Q), QuatArray(p[:, :1]) * mq, dtype)      # broadcasting
    check(qd.conjugate(Q), mq.conj(), dtype)
    check(qd.inverse(Q), mq.inverse(), dtype)
    check(qd.normalize(Q), mq.normalized(), dtype)
    check(qd.exp(Q), mq.exp(), dtype)
    check(qd.log(Q), mq.log(), dtype)
    check(qd.power(Q, T), mq.power(t), dtype)
    check(qd.power(Q, 0.5), mq.power(0.5), dtype)
    r = Rotation.from_quat(q, scalar_first=True)
    check(qd.rotate(Q, V), r.apply(v), dtype)
    check(qd.rotate(Q, V, inverse=True), r.apply(v, inverse=True), dtype)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("chunks", CHUNKS)
def test_conversions_equal_memory(rng, scheduler, chunks, dtype):
    # the quaternions a Rotation holds (normalised again), so that both sides read the same bits
    q = Rotation.from_quat(unit(rng, BATCH, dtype), scalar_first=True).as_quat(scalar_first=True)
    Q = chunked(q, chunks)
    r = Rotation.from_quat(q, scalar_first=True)
    m = r.as_matrix()
    check(qd.as_matrix(Q), m, dtype)
    check(qd.from_matrix(chunked(m, chunks)), quats(Rotation.from_matrix(m)), dtype)
    check(qd.as_rotvec(Q), r.as_rotvec(), dtype)
    check(qd.as_rotvec(Q, degrees=True), r.as_rotvec(degrees=True), dtype)
    rv = r.as_rotvec()
    check(qd.from_rotvec(chunked(rv, chunks)), quats(Rotation.from_rotvec(rv)), dtype)
    for seq in ("xyz", "ZXZ"):
        e = r.as_euler(seq, degrees=True)
        check(qd.as_euler(Q, seq, degrees=True), e, dtype)
        check(qd.from_euler(seq, chunked(e, chunks), degrees=True), quats(Rotation.from_euler(seq, e, degrees=True)),
              dtype)
    check(qd.from_euler("y", chunked(rv[..., :1], chunks)), quats(Rotation.from_euler("y", rv[..., :1])), dtype)
    for first in (False, True):
        raw = r.as_quat(scalar_first=first)
        check(qd.as_quat(Q, scalar_first=first), raw, dtype)
        check(qd.as_quat(-Q, canonical=True, scalar_first=first),
              Rotation.from_quat(-q, scalar_first=True).as_quat(canonical=True, scalar_first=first), dtype)
        check(qd.from_quat(chunked(3 * raw, chunks), scalar_first=first),
              quats(Rotation.from_quat(3 * raw, scalar_first=first)), dtype)


# --------------------------------------------------------------------------- interpolation

@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("chunks", CHUNKS)
def test_pairwise_equal_memory(rng, scheduler, chunks, dtype):
    q0, a, b, q1 = (unit(rng, BATCH, dtype) for _ in range(4))
    t = rng.uniform(0, 1, BATCH)
    D = [chunked(x, chunks) for x in (q0, a, b, q1)]
    T = chunked(t, chunks)
    check(qd.lerp(D[0], D[3], T), qi.lerp(q0, q1, t), dtype)
    check(qd.nlerp(D[0], D[3], T), qi.nlerp(q0, q1, t), dtype)
    check(qd.slerp(D[0], D[3], T), qi.slerp(q0, q1, t), dtype)
    check(qd.slerp(D[0], D[3], T, shortest=False), qi.slerp(q0, q1, t, shortest=False), dtype)
    check(qd.squad(*D, T), qi.squad(q0, a, b, q1, t), dtype)
    check(qd.bezier(*D, T), qi.bezier(q0, a, b, q1, t), dtype)
    check(qd.slerp(q0[0, 0], q1[0, 0], T), qi.slerp(q0[0, 0], q1[0, 0], t), dtype)   # one pair, chunked t


def _flippy(rng, n, m, dtype):
    """A smooth walk with random signs, and exact zero dot products (also at chunk borders)."""
    q = unit(rng, (1, m), np.float64) + 0.05 * np.cumsum(rng.normal(size=(n, m, 4)), axis=0)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    q *= rng.choice([-1.0, 1.0], (n, m, 1))
    for i in (3, 4, 9):    # q[i] orthogonal to q[i - 1]: the in-memory rule restarts the sign there
        q[i, :, :] = np.stack([-q[i - 1, :, 1], q[i - 1, :, 0], -q[i - 1, :, 3], q[i - 1, :, 2]], -1)
    return q.astype(dtype)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("chunks", [(23, 3), (4, 2), (1, 3), (5, 1), (9, 3)])
def test_unflip_across_chunk_borders(rng, scheduler, chunks, dtype):
    q = _flippy(rng, 23, 3, dtype)
    assert (np.sum(q[1:] * q[:-1], -1) < 0).any() and (np.sum(q[1:] * q[:-1], -1) == 0).any()
    expected = np.asarray(qi.unflip(q, axis=0))
    lazy = qd.unflip(chunked(q, chunks), axis=0)
    assert lazy.chunks == chunked(q, chunks).chunks
    got = lazy.compute()
    np.testing.assert_array_equal(got, expected)     # signs only: exact
    # along the other axis
    qt = np.ascontiguousarray(q.transpose(1, 0, 2))
    np.testing.assert_array_equal(qd.unflip(chunked(qt, chunks[::-1]), axis=-1).compute(), np.asarray(qi.unflip(qt, axis=1)))


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("chunks", CHUNKS)
def test_mean_reduction_equals_memory(rng, scheduler, chunks, dtype):
    q = unit(rng, BATCH, dtype) * rng.uniform(0.5, 2, BATCH + (1,)).astype(dtype)
    r = Rotation.from_quat(q, scalar_first=True)
    eps = np.finfo(dtype).eps
    lazy = qd.mean(chunked(q, chunks))
    assert lazy.shape == (4,) and lazy.dtype == dtype
    np.testing.assert_allclose(lazy.compute(), quats(r.mean()), rtol=0, atol=100 * eps)
    w = rng.uniform(0, 3, BATCH)
    np.testing.assert_allclose(qd.mean(chunked(q, chunks), chunked(w, chunks)).compute(), quats(r.mean(w)),
                               rtol=0, atol=100 * eps)
    np.testing.assert_allclose(qd.mean(chunked(q, chunks), w[0]).compute(), quats(r.mean(np.broadcast_to(w[0], BATCH))),
                               rtol=0, atol=100 * eps)
    # the graph sums 4x4 blocks: one partial per chunk, nothing of the size of q collected
    parts = [k for k in dict(lazy.__dask_graph__()) if "chordal_sum" in str(k[0] if isinstance(k, tuple) else k)]
    assert len(parts) == np.prod([len(c) for c in chunked(q, chunks).chunks[:-1]])


# --------------------------------------------------------------------------- keyframe tracks

@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("method", ["slerp", "squad", "bezier", "linear"])
def test_track_at_chunked_times(rng, scheduler, method, dtype):
    times = np.cumsum(rng.uniform(0.1, 1, 40))
    keys = unit(rng, (40, 3), dtype)
    track = Track(times, keys, method=method)
    t = rng.uniform(times[0], times[-1], (101,))
    for chunks in [(101,), (17,), (1,)]:
        check(qd.evaluate(track, da.from_array(t, chunks=chunks)), track(t), dtype)
    t2 = t[:100].reshape(10, 10)
    check(qd.evaluate(track, da.from_array(t2, chunks=(3, 4))), track(t2), dtype)
    check(qd.Track(times, keys, method=method)(da.from_array(t, chunks=13)), track(t), dtype)


@pytest.mark.parametrize("dtype", DTYPES)
def test_rotation_spline_and_slerp_at_chunked_times(rng, scheduler, dtype):
    times = np.cumsum(rng.uniform(0.1, 1, 12))
    keys = unit(rng, (12,), dtype)
    t = rng.uniform(times[0], times[-1], 57)
    spline = RotationSpline(times, Rotation.from_quat(keys, scalar_first=True))
    check(qd.evaluate(spline, da.from_array(t, chunks=10)), quats(spline(t)), dtype)
    s = qi.Slerp(times, Rotation.from_quat(keys, scalar_first=True))
    check(qd.evaluate(s, da.from_array(t, chunks=10)), quats(s(t)), dtype)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("kchunks", [(8, 5, 7), (8, 2, 3), (8, 1, 7)])
def test_track_with_dask_keys_chunked_along_batch(rng, scheduler, kchunks, dtype):
    times = np.cumsum(rng.uniform(0.1, 1, 8))
    keys = unit(rng, (8, 5, 7), dtype)
    t = rng.uniform(times[0], times[-1], 23)
    for method in ("slerp", "squad"):
        lazy = qd.Track(times, da.from_array(keys, chunks=kchunks + (4,)), method=method)(da.from_array(t, chunks=10))
        assert lazy.chunks[1:3] == da.from_array(keys, chunks=kchunks + (4,)).chunks[1:3]
        check(lazy, Track(times, keys, method=method)(t), dtype)


def test_extrapolate_raise_errors_when_computed(rng):
    track = Track([0.0, 1.0], unit(rng, (2,), np.float64))
    lazy = qd.evaluate(track, da.from_array(np.array([0.5, 2.0]), chunks=1))
    np.testing.assert_allclose(lazy[0].compute(), np.asarray(track(0.5)))
    with pytest.raises(ValueError, match="within the range"):
        lazy.compute(scheduler="synchronous")


# --------------------------------------------------------------------------- threads and pickling

def test_tasks_run_quatarray_single_threaded():
    x = da.zeros(8, chunks=2)
    seen = x.map_blocks(lambda b: np.full(b.shape, quatarray.get_num_threads()), dtype=int)
    assert set(seen.compute(scheduler="threads")) == {1}


def test_track_and_tasks_pickle_small(rng):
    K = 10_000
    times = np.arange(K, dtype=np.float64)
    keys = unit(rng, (K,), np.float32)
    track = Track(times, keys, method="squad")
    size = len(pickle.dumps(track))
    # 18 float32 table rows (72 B), keys and control points (2 x 16 B), times (8 B) per key;
    # the segment index is rebuilt from the times when unpickled
    assert size < 115 * K, size     # 112 B per key
    assert np.array_equal(pickle.loads(pickle.dumps(track))(times[:50] + 0.5), track(times[:50] + 0.5))
    lazy = qd.evaluate(track, da.linspace(0, K - 1, 10**6, chunks=10**5))
    tasks = sorted(len(pickle.dumps(v)) for v in dict(lazy.__dask_graph__()).values())
    # the track is one task of the graph; every evaluation task only references it
    assert tasks[-1] >= size * 0.9 and tasks[-2] < 4096, tasks[-3:]
    assert len(pickle.dumps(qd.slerp(keys[:4], keys[4:8], da.ones(4, chunks=2)).__dask_graph__())) < 20_000


def test_local_cluster_two_processes(rng, tmp_path):
    distributed = pytest.importorskip("distributed", reason="distributed is not installed (the dask extra)")
    zarr = pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    from quatarray.formats import resample_zarr
    times = np.cumsum(rng.uniform(0.1, 1, 30))
    keys = unit(rng, (30, 2), np.float64)
    track = Track(times, keys, method="squad")
    t = rng.uniform(times[0], times[-1], 200)
    q = _flippy(rng, 40, 2, np.float64)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=2, processes=True, dashboard_address=None,
                                  silence_logs=40) as cluster, distributed.Client(cluster) as client:
        lazy = [qd.evaluate(track, da.from_array(t, chunks=30)),
                qd.unflip(da.from_array(q, chunks=(7, 1, 4))),
                qd.mean(da.from_array(q, chunks=(9, 2, 4))),
                qd.slerp(da.from_array(q[:-1], chunks=(6, 2, 4)), q[1:], 0.3),
                da.zeros(8, chunks=2).map_blocks(lambda b: np.full(b.shape, quatarray.get_num_threads()), dtype=int)]
        got = client.compute(lazy, sync=True)
        assert len(client.scheduler_info()["workers"]) == 2
        # the CLI's Zarr path on the cluster (--scheduler ADDRESS): workers write the chunks
        g = zarr.open_group(str(tmp_path / "in.zarr"), mode="w")
        g["times"], g["keys"] = times, keys
        assert resample_zarr(str(tmp_path / "in.zarr"), str(tmp_path / "out.zarr"), times=t, method="squad",
                             scheduler=cluster.scheduler_address, progress=False) == (30, 200)
    np.testing.assert_allclose(zarr.open_group(str(tmp_path / "out.zarr"), mode="r")["keys"][...],
                               np.asarray(track(t)), rtol=0, atol=32 * np.finfo(float).eps)
    np.testing.assert_allclose(got[0], np.asarray(track(t)), rtol=0, atol=32 * np.finfo(float).eps)
    np.testing.assert_array_equal(got[1], np.asarray(qi.unflip(q)))
    np.testing.assert_allclose(got[2], quats(Rotation.from_quat(q, scalar_first=True).mean()), rtol=0, atol=100 * np.finfo(float).eps)
    np.testing.assert_allclose(got[3], np.asarray(qi.slerp(q[:-1], q[1:], 0.3)), rtol=0, atol=32 * np.finfo(float).eps)
    assert set(got[4]) == {1}


# --------------------------------------------------------------------------- errors

def test_split_component_axis_is_refused(rng):
    q = da.from_array(unit(rng, (6,), np.float64), chunks=(3, 2))
    with pytest.raises(ValueError, match=r"component axis .* one chunk.*rechunk\(\{-1: -1\}\)"):
        qd.conjugate(q)
    m = da.from_array(np.tile(np.eye(3), (4, 1, 1)), chunks=(2, 3, 1))
    with pytest.raises(ValueError, match=r"matrix with its component axis.*rechunk\(\{-2: -1, -1: -1\}\)"):
        qd.from_matrix(m)
    np.testing.assert_allclose(qd.conjugate(q.rechunk({-1: -1})).compute(), np.asarray(QuatArray(q.compute()).conj()))


def test_bad_shapes_and_types(rng):
    with pytest.raises(ValueError, match=r"expected q of shape \(\.\.\., 4\), got \(5, 3\)"):
        qd.normalize(da.zeros((5, 3)))
    with pytest.raises(TypeError, match="expected q of real numbers"):
        qd.normalize(da.zeros((5, 4), dtype=complex))
    with pytest.raises(ValueError, match="broadcastable batch shapes for p, q"):
        qd.multiply(da.zeros((5, 4)), da.zeros((3, 4)))
    with pytest.raises(ValueError, match=r"key axis \(axis 0\) in one chunk.*rechunk\(\{0: -1\}\)"):
        qd.Track([0, 1, 2], da.from_array(unit(rng, (3, 2), np.float64), chunks=(2, 1, 4)))
    with pytest.raises(ValueError, match=r"expected axis in \[-1, 0\]"):
        qd.unflip(da.zeros((5, 4)), axis=1)
    with pytest.raises(ValueError, match="Mean of an empty rotation set"):
        qd.mean(da.zeros((0, 4)))
    with pytest.raises(ValueError, match="weights"):
        qd.mean(da.ones((5, 4)), -np.ones(5)).compute()


@pytest.mark.parametrize("name, call, chunkwise", [
    ("p", lambda q: qd.multiply(q, q[:1]), True),
    ("q", lambda q: qd.multiply(q[:1], q), True),
    ("q0", lambda q: qd.slerp(q, q[:1], 0.3), True),
    ("q1", lambda q: qd.squad(q[:1], q[:1], q[:1], q, 0.3), True),
    ("t", lambda q: qd.slerp(q[:1], q[:1], da.where(da.isnan(q[:, 1]), np.nan, 0.3)), True),
    ("q", lambda q: qd.normalize(q), True),
    ("q", lambda q: qd.as_matrix(q), True),
    ("rotvec", lambda q: qd.from_rotvec(q[:, :3]), True),
    ("q", lambda q: qd.unflip(q), False),         # every chunk's sign depends on the chunks before
    ("q", lambda q: qd.unflip(q.rechunk({0: -1})), False),
    ("q", lambda q: qd.mean(q), False),
], ids=["multiply-p", "multiply-q", "slerp", "squad", "slerp-t", "normalize", "as_matrix", "from_rotvec", "unflip",
        "unflip-1", "mean"])
def test_nan_refused_per_chunk_when_computed(rng, name, call, chunkwise):
    """NaN and inf are refused as by the in-memory API (a ValueError naming the argument) when
    the chunk holding them is computed; building the graph computes nothing."""
    q = unit(rng, (6,), np.float64)
    q[4, 1] = np.nan
    lazy = call(da.from_array(q, chunks=(2, 4)))
    with pytest.raises(ValueError, match=f"expected finite values in {name}, got nan or inf"):
        lazy.compute(scheduler="synchronous")
    if chunkwise:       # the chunks without NaN compute
        assert np.isfinite(lazy[:2].compute(scheduler="synchronous")).all()


def test_unknown_chunk_sizes(rng, scheduler):
    """Boolean indexing leaves chunk sizes unknown (NaN): elementwise functions work on them,
    broadcasting them against known sizes asks for compute_chunk_sizes()."""
    q = rng.normal(size=(20, 4))
    mask = q[:, 0] > 0
    x = da.from_array(q, chunks=(6, 4))
    y = x[x[:, 0] > 0]
    assert np.isnan(y.shape[0])
    sel = QuatArray(q[mask])

    def check(lazy, expected, dtype):     # the shape is known once computed
        np.testing.assert_allclose(lazy.compute(), np.asarray(expected), **tol(dtype))

    check(qd.normalize(y), sel.normalized(), np.float64)
    check(qd.multiply(y, y), sel * sel, np.float64)
    check(qd.multiply(y, np.array([0.0, 0, 0, 1])), sel * QuatArray([0.0, 0, 0, 1]), np.float64)
    check(qd.slerp(qd.normalize(y), np.array([1.0, 0, 0, 0]), 0.25),
          qi.slerp(sel.normalized(), QuatArray([1.0, 0, 0, 0]), 0.25), np.float64)
    np.testing.assert_allclose(qd.mean(y).compute(), quats(Rotation.from_quat(q[mask], scalar_first=True).mean()),
                               rtol=0, atol=64 * np.finfo(float).eps)
    with pytest.raises(ValueError, match=r"expected p with known chunk sizes.*p\.compute_chunk_sizes\(\)"):
        qd.multiply(y, x)
    with pytest.raises(ValueError, match=r"known chunk sizes along axis 0.*q\.compute_chunk_sizes\(\)"):
        qd.unflip(y)
    check(qd.unflip(y.compute_chunk_sizes()), qi.unflip(q[mask]), np.float64)


@pytest.mark.parametrize("call", [
    lambda d: QuatArray(d),
    lambda d: Rotation.from_quat(d),
    lambda d: qi.slerp(d, d, 0.5),
    lambda d: qi.unflip(d),
    lambda d: Track([0, 1, 2], d),
    lambda d: Track([0, 1], np.eye(4)[:2])(d[:, 0]),
    lambda d: RotationSpline([0, 1, 2], Rotation.identity(3))(d[:, 0]),
    lambda d: QuatArray(np.eye(4)[:3]) * d,
], ids=["QuatArray", "from_quat", "slerp", "unflip", "Track-keys", "Track-times", "RotationSpline", "ufunc"])
def test_dask_array_to_memory_api_points_to_quatarray_dask(call):
    computed = []
    d = da.ones((3, 4), chunks=2).map_blocks(lambda b: computed.append(1) or b, meta=np.empty((0, 0)))
    with pytest.raises(TypeError, match=r"got a Dask Array; use quatarray\.dask"):
        call(d)
    assert not computed      # never computed silently


def test_missing_dask_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "dask", None)
    monkeypatch.setitem(sys.modules, "dask.array", None)
    monkeypatch.delitem(sys.modules, "quatarray.dask")
    with pytest.raises(ImportError, match=r"pip install 'quatarray\[dask\]'"):
        importlib.import_module("quatarray.dask")
    from quatarray.cli import main
    monkeypatch.setitem(sys.modules, "zarr", None)
    assert main(["resample", "in.zarr", "-o", "out.zarr", "--fps", "2"]) == 2


def test_import_quatarray_does_not_import_dask():
    import subprocess
    code = "import quatarray, quatarray.cli, sys; print(sorted(m for m in ('dask', 'zarr', 'distributed') if m in sys.modules))"
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root, check=True)
    assert out.stdout.strip() == "[]"


# --------------------------------------------------------------------------- the Zarr path of the CLI

@pytest.fixture
def store(tmp_path, rng):
    zarr = pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    times = np.cumsum(rng.uniform(0.1, 1, 25))
    keys = unit(rng, (25, 3), np.float32)
    g = zarr.open_group(str(tmp_path / "in.zarr"), mode="w")
    g["times"] = times
    g.create_array("keys", data=keys, chunks=(10, 2, 4))
    return tmp_path, times, keys


@pytest.mark.parametrize("method", ["slerp", "squad"])
def test_zarr_cli_round_trip(store, method, capsys, monkeypatch):
    import zarr

    from quatarray.formats import zarr as _zarr
    from quatarray.cli import main
    tmp, times, keys = store
    monkeypatch.setattr(_zarr, "CHUNK_QUATS", 64)      # many chunks, a ragged last one
    src, dst = str(tmp / "in.zarr"), str(tmp / "out.zarr")
    assert main(["resample", src, "-o", dst, "--fps", "7.5", "--method", method]) == 0
    assert "frames" in capsys.readouterr().out
    out = zarr.open_group(dst, mode="r")
    t = out["times"][...]
    np.testing.assert_array_equal(t, quatarray.formats.fps_times(times[0], times[-1], 7.5))
    assert out["keys"].dtype == np.float32 and out["keys"].chunks[0] < len(t)
    np.testing.assert_array_equal(out["keys"][...], np.asarray(Track(times, keys, method=method)(t)))
    # the output store is a valid input store: resample it again at its own times
    assert main(["resample", dst, "-o", str(tmp / "again.zarr"), "--times", dst, "--method", "linear",
                 "--quiet"]) == 0
    again = zarr.open_group(str(tmp / "again.zarr"), mode="r")
    np.testing.assert_allclose(again["keys"][...], out["keys"][...], rtol=0, atol=4 * np.finfo(np.float32).eps)
    assert sorted(os.listdir(tmp)) == ["again.zarr", "in.zarr", "out.zarr"]   # no temporary left


def test_zarr_cli_with_dask_keys(store, monkeypatch):
    import zarr

    from quatarray.formats import zarr as _zarr
    tmp, times, keys = store
    monkeypatch.setattr(_zarr, "MEMORY_KEYS", 0)       # keys stay a Dask array, chunked along the tracks
    assert _zarr.resample_zarr(str(tmp / "in.zarr"), str(tmp / "out.zarr"), times=times[2:9], progress=False) == (25, 7)
    np.testing.assert_array_equal(zarr.open_group(str(tmp / "out.zarr"), mode="r")["keys"][...],
                                  np.asarray(Track(times, keys)(times[2:9])))


def test_zarr_cli_failure_leaves_no_output(store, capsys):
    from quatarray.cli import main
    tmp, times, _ = store
    np.savetxt(tmp / "t.txt", [times[0], times[-1] + 1])
    dst = tmp / "out.zarr"
    assert main(["resample", str(tmp / "in.zarr"), "-o", str(dst), "--times", str(tmp / "t.txt")]) == 2
    assert "outside the key times" in capsys.readouterr().err
    assert sorted(os.listdir(tmp)) == ["in.zarr", "t.txt"]
    assert main(["resample", str(tmp / "in.zarr"), "-o", str(tmp / "out.bvh"), "--fps", "2"]) == 2
    assert "cannot write .bvh from .zarr input" in capsys.readouterr().err
    assert main(["resample", str(tmp / "nothere.zarr"), "-o", str(dst), "--fps", "2"]) == 2
    assert "nothere.zarr" in capsys.readouterr().err


def test_zarr_cli_replaces_existing_store_and_shows_progress(store, monkeypatch, capsys):
    import zarr

    from quatarray.formats import zarr as _zarr
    tmp, times, keys = store
    dst = str(tmp / "out.zarr")
    _zarr.resample_zarr(str(tmp / "in.zarr"), dst, fps=1, progress=False)
    assert capsys.readouterr().err == ""
    _zarr.resample_zarr(str(tmp / "in.zarr"), dst, fps=3, progress=True)
    assert "100% Completed" in capsys.readouterr().err
    assert zarr.open_group(dst, mode="r")["times"].shape[0] == len(quatarray.formats.fps_times(times[0], times[-1], 3))
    assert sorted(os.listdir(tmp)) == ["in.zarr", "out.zarr"]


@pytest.mark.parametrize("t0, t1, fps", [(0.0, 999_999_999.0, 1.0), (0.0, 4.2, 30.0), (0.0, 127 / 30, 30.0),
                                         (1403636579.76, 1403636599.76, 200.0)])
def test_zarr_fps_grid_is_io_fps_times(t0, t1, fps):
    """The Zarr path's lazy --fps grid has io.fps_times' count and values (no extra frame on
    long spans: 0 .. 999999999 at 1 fps is 10⁹ frames, not 10⁹ + 1)."""
    from quatarray.formats import zarr as _zarr
    from quatarray.formats import fps_steps, fps_times

    t, _ = _zarr._query_times(np.array([t0, t1]), fps, None, 1 << 20)
    assert t.shape == (fps_steps(t0, t1, fps) + 1,)
    if t.shape[0] < 10**6:
        assert np.array_equal(t.compute(), fps_times(t0, t1, fps))
    else:
        assert t[-1].compute() == t1 and t[-2].compute() < t1


# --------------------------------------------------------------------------- the Zarr output's chunk writer

def _chunk_files(root):
    return {os.path.relpath(os.path.join(d, f), root): open(os.path.join(d, f), "rb").read()
            for d, _, fs in os.walk(root) for f in fs if f != "zarr.json"}


@pytest.mark.parametrize("blosc", [None, ("lz4", 1, "shuffle"), ("zstd", 3, "bitshuffle")])
@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("shape, chunks", [((1000, 4), (256, 4)),          # 4096-byte multiples (float32), ragged end
                                           ((700, 3, 4), (300, 3, 4)),     # an unaligned tail in every chunk
                                           ((5, 4), (8, 4))])              # one chunk, larger than the array
def test_raw_chunks_are_the_files_zarr_writes(tmp_path, rng, dtype, shape, chunks, blosc):
    zarr = pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    from zarr.codecs import BloscCodec

    from quatarray.formats.zarr import RawChunks
    data = rng.normal(size=shape).astype(dtype)
    data[:len(data) // 2] = np.round(data[:len(data) // 2])   # something for a compressor to find
    compressors = None if blosc is None else BloscCodec(cname=blosc[0], clevel=blosc[1], shuffle=blosc[2])
    made = {}
    for name in ("zarr", "ours"):
        root = str(tmp_path / name)
        a = zarr.open_group(root, mode="w").create_array("keys", shape=shape, chunks=chunks, dtype=dtype,
                                                         compressors=compressors)
        if name == "zarr":
            a[...] = data
        else:
            da.store(da.from_array(data, chunks=chunks), RawChunks(a, root), lock=False, scheduler="threads")
        made[name] = _chunk_files(root)
        np.testing.assert_array_equal(zarr.open_group(root, mode="r")["keys"][...], data)
    assert made["ours"] == made["zarr"] and len(made["ours"]) == -(-shape[0] // chunks[0])


def test_raw_chunks_fall_back_to_plain_writes(tmp_path, rng, monkeypatch):
    """Where O_DIRECT is refused (tmpfs at open; a device's alignment at write), the same bytes
    are written plainly."""
    zarr = pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    import errno

    from quatarray.formats import zarr as _zarr
    data = rng.normal(size=(2048, 4)).astype(np.float32)
    real_open, real_write = os.open, os.write
    direct = getattr(os, "O_DIRECT", 0)
    for refuse in ("open", "write"):
        seen = []

        def fake_open(path, flags, mode=0o777, *args, refuse=refuse, seen=seen, **kw):
            if os.sep + "c" + os.sep in os.fspath(path):   # a chunk file (zarr's own files pass)
                seen.append(flags & direct)
                if refuse == "open" and flags & direct:
                    raise OSError(errno.EINVAL, "Invalid argument")
            return real_open(path, flags, mode, *args, **kw)

        def fake_write(fd, data, refuse=refuse):
            if refuse == "write" and direct and _fcntl_flags(fd) & direct:
                raise OSError(errno.EINVAL, "Invalid argument")
            return real_write(fd, data)

        monkeypatch.setattr(_zarr.os, "open", fake_open)
        monkeypatch.setattr(_zarr.os, "write", fake_write)
        root = str(tmp_path / refuse)
        a = zarr.open_group(root, mode="w").create_array("keys", shape=data.shape, chunks=(1024, 4),
                                                         dtype=np.float32, compressors=None)
        w = _zarr.RawChunks(a, root)
        w[0:1024, 0:4] = data[:1024]
        w[1024:2048, 0:4] = data[1024:]
        monkeypatch.undo()
        np.testing.assert_array_equal(zarr.open_group(root, mode="r")["keys"][...], data)
        if direct:   # O_DIRECT asked for once per chunk (then plainly where refused at open)
            assert sum(1 for f in seen if f) == 2


def _fcntl_flags(fd):
    import fcntl
    return fcntl.fcntl(fd, fcntl.F_GETFL)


def test_raw_chunks_refuse_what_they_cannot_write(tmp_path):
    zarr = pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    from quatarray.formats.zarr import RawChunks
    g = zarr.open_group(str(tmp_path / "s.zarr"), mode="w")
    packed = g.create_array("packed", shape=(10, 4), chunks=(5, 4), dtype=np.float32)   # zstd by default
    with pytest.raises(ValueError, match="expected a Zarr v3 array with codec bytes"):
        RawChunks(packed, str(tmp_path / "s.zarr"))
    raw = g.create_array("raw", shape=(10, 4), chunks=(5, 4), dtype=np.float32, compressors=None)
    w = RawChunks(raw, str(tmp_path / "s.zarr"))
    with pytest.raises(ValueError, match="expected one whole chunk"):
        w[2:7, 0:4] = np.zeros((5, 4))
    # a store removed under a late write is not created again
    import shutil
    shutil.rmtree(tmp_path / "s.zarr")
    with pytest.raises(FileNotFoundError):
        w[0:5, 0:4] = np.zeros((5, 4))
    assert os.listdir(tmp_path) == []
