"""quatarray.dask equals the in-memory API on chunked data; the Zarr path of the CLI; clear errors."""

import errno
import importlib
import json
import os
import pickle
import re
import sys

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
@pytest.mark.parametrize("scale", [1e-25, 1e-170, 1.0, 1e20])
def test_unflip_of_tiny_or_huge_quaternions_whatever_the_chunks(dtype, scale):
    """The chunked unflip decides every sign with the in-memory unflip's own dot products (float32
    summed in float64): float32 quaternions of 1e-25 had their dots underflow to 0 in the chunk
    summaries, and came back with other signs, chunk by chunk; no warning either."""
    signs = np.array([1, -1, -1, 1, -1, 1, 1, -1, -1, -1])
    q = (np.array([0.6, 0.8, 0, 0]) * signs[:, None] * scale).astype(dtype)
    ref = np.asarray(qi.unflip(q))
    for c in (1, 2, 3, 10):
        got = qd.unflip(da.from_array(q, chunks=(c, 4))).compute(scheduler="synchronous")
        np.testing.assert_array_equal(got, ref)


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


@pytest.mark.parametrize("scale, weights", [(1e160, None), (1e-160, None), (1.0, "huge"), (1.0, "tiny"),
                                            (1.0, "zeros")])
def test_mean_at_extreme_scales_as_rotation_mean(rng, scale, weights):
    """Rotations of any norm and weights of any size give Rotation.mean's answer: the rows are
    normalised as its are (|q|² had overflowed to the identity or underflowed to an eigensolver
    failure) and the weights scaled by the largest of all; zero weights give its identity."""
    q = unit(rng, (30,), np.float64) * 0.4
    w = {None: None, "huge": np.full(30, 1e308), "tiny": np.where(np.arange(30) == 7, 1e-320, 0.0),
         "zeros": np.zeros(30)}[weights]
    ref = quats(Rotation.from_quat(q, scalar_first=True).mean(w))
    got = qd.mean(chunked(q * scale, ((10, 20), (4,))), w).compute()
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-14)
    with pytest.raises(ValueError, match="expected non-zero quaternions"):
        qd.mean(chunked(np.array([[0.0, 0, 0, 0], [1, 0, 0, 0]]), ((1, 1), (4,)))).compute()


def test_rotate_by_a_zero_quaternion_is_refused_as_in_memory():
    """A zero quaternion gives NaN in the rotation formula: refused as QuatArray.rotate refuses
    it (the same function), in the chunk that holds it; the other chunks compute."""
    from quatarray import QuatArray
    q = np.array([[1.0, 0, 0, 0], [0, 0, 0, 0]])
    with pytest.raises(ValueError, match="expected non-zero quaternions to rotate by") as mem:
        QuatArray(q).rotate(np.ones(3))
    lazy = qd.rotate(chunked(q, ((1, 1), (4,))), np.ones(3))
    with pytest.raises(ValueError, match=re.escape(str(mem.value))):
        lazy.compute()
    np.testing.assert_array_equal(lazy[:1].compute(), [[1.0, 1, 1]])


def test_mean_docstring_names_the_mean_it_computes(rng):
    """dask.mean is the chordal mean of Rotation.mean; its docstring pointed at QuatArray.mean, the
    arithmetic mean of the components, which it is not."""
    from quatarray import QuatArray
    doc = qd.mean.__doc__
    assert "QuatArray.mean" not in doc and "`Rotation.mean`" in doc
    q = unit(rng, (50,), np.float64)
    assert not np.allclose(np.asarray(QuatArray(q).mean()), qd.mean(chunked(q, ((25, 25), (4,)))).compute())


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


@pytest.fixture(scope="module")
def s3():
    """An S3-protocol server (moto's server mode, real HTTP) on a free port of 127.0.0.1 only,
    and the storage_options that reach a fresh bucket on it through s3fs."""
    server_mod = pytest.importorskip("moto.server", reason="moto[server] is not installed (the test extra: "
                                                            "pip install -e '.[test]')")
    pytest.importorskip("s3fs", reason="s3fs is not installed (the test extra: pip install -e '.[test]')")
    pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    import logging

    import s3fs
    logging.getLogger("werkzeug").setLevel(logging.ERROR)
    server = server_mod.ThreadedMotoServer(ip_address="127.0.0.1", port=0, verbose=False)
    server.start()
    try:
        host, port = server.get_host_and_port()
        assert host == "127.0.0.1"
        options = {"key": "testing", "secret": "testing", "endpoint_url": f"http://127.0.0.1:{port}",
                   "client_kwargs": {"region_name": "eu-west-1"}}
        s3fs.S3FileSystem(**options).mkdir("quatarray-test")
        yield options
    finally:
        server.stop()


def _s3_objects(options, prefix):
    import s3fs
    fs = s3fs.S3FileSystem(skip_instance_cache=True, **options)
    return sorted(p[len(prefix) + 1:] for p in fs.ls(prefix, detail=False))


def _s3_input(rng, url, options, k=30, batch=(2,)):
    import zarr
    times = np.cumsum(rng.uniform(0.1, 1, k))
    keys = unit(rng, (k,) + batch, np.float32)
    g = zarr.open_group(url, mode="w", storage_options=options)
    g["times"] = times
    g.create_array("keys", data=keys, chunks=(10,) + batch + (4,))
    return times, keys


def test_s3_cli_zarr_path(s3, rng, tmp_path, monkeypatch, capsys):
    """The command line's Zarr path against an S3-protocol server: store in, store out, times from a
    store, an existing output refused without --force, no temporary prefix left behind."""
    import zarr

    from quatarray.formats import zarr as _zarr
    from quatarray.cli import main
    monkeypatch.setattr(_zarr, "CHUNK_QUATS", 2 * 64)     # several chunks (and windows) to write
    monkeypatch.setattr(_zarr, "WINDOW_CHUNKS", 2)
    times, keys = _s3_input(rng, "s3://quatarray-test/cli/in.zarr", s3)
    flags = [arg for k, v in s3.items() for arg in ("--storage-option", f"{k}={json.dumps(v) if isinstance(v, dict) else v}")]
    out = "s3://quatarray-test/cli/out.zarr"
    args = ["resample", "s3://quatarray-test/cli/in.zarr", "-o", out, "--method", "squad", "--quiet", *flags]
    assert main(args + ["--fps", "20"]) == 0, capsys.readouterr().err
    got = zarr.open_group(out, mode="r", storage_options=s3)
    t = got["times"][...]
    np.testing.assert_array_equal(t, quatarray.formats.fps_times(times[0], times[-1], 20))
    np.testing.assert_array_equal(got["keys"][...], np.asarray(Track(times, keys, method="squad")(t)))
    assert _s3_objects(s3, "quatarray-test/cli") == ["in.zarr", "out.zarr"]
    assert main(args + ["--fps", "5"]) == 2
    assert f"{out}: exists; give --force to replace it\n" in capsys.readouterr().err     # the CLI's words
    assert main(args + ["--times", "s3://quatarray-test/cli/out.zarr", "--force"]) == 2
    assert f"{out}: is the times store, which is read chunk by chunk while the output is written" in \
        capsys.readouterr().err
    assert main(["resample", "s3://quatarray-test/cli/out.zarr", "-o", "s3://quatarray-test/cli/again.zarr",
                 "--times", "s3://quatarray-test/cli/in.zarr", "--extrapolate", "clamp", "--quiet", *flags]) == 0
    again = zarr.open_group("s3://quatarray-test/cli/again.zarr", mode="r", storage_options=s3)
    np.testing.assert_array_equal(again["keys"][...], np.asarray(Track(t, got["keys"][...], extrapolate="clamp")(times)))
    assert main(args + ["--fps", "5", "--force"]) == 0
    assert zarr.open_group(out, mode="r", storage_options=s3)["times"].shape == (len(
        quatarray.formats.fps_times(times[0], times[-1], 5)),)
    assert _s3_objects(s3, "quatarray-test/cli") == ["again.zarr", "in.zarr", "out.zarr"]


def test_s3_reduce_and_bad_storage_options_on_the_command_line(s3, rng, tmp_path, capsys):
    """quatarray reduce reads a store on S3 with --storage-option (it had no such option), and an
    option the filesystem does not take is one line naming it, exit status 2, not a traceback."""
    from quatarray.cli import main
    from quatarray.formats import read_csv
    times, keys = _s3_input(rng, "s3://quatarray-test/reduce/in.zarr", s3)
    flags = [arg for k, v in s3.items() for arg in ("--storage-option", f"{k}={json.dumps(v) if isinstance(v, dict) else v}")]
    out = tmp_path / "red.csv"
    assert main(["reduce", "s3://quatarray-test/reduce/in.zarr", "-o", str(out), "--tolerance", "0.5deg", *flags]) == 0
    kept = read_csv(out)
    assert set(kept.times) <= set(times) and kept.times[0] == times[0] and kept.times[-1] == times[-1]
    capsys.readouterr()
    assert main(["resample", "s3://quatarray-test/reduce/in.zarr", "-o", str(tmp_path / "x.csv"), "--fps", "2",
                 *flags, "--storage-option", "bogus_opt=1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("quatarray: error: s3://quatarray-test/reduce/in.zarr: storage options [") and \
        "bogus_opt" in err and err.count("\n") == 1, err


def test_s3_urls_with_empty_segments_are_one_store(s3, rng, monkeypatch):
    """``s3://bkt//x.zarr`` and ``s3://bkt/a//x.zarr`` name the store of the same URL without the
    ``//``: a write that fails leaves no temporary objects (s3fs lists ``bkt//x`` as ``bkt/x``, so
    those under ``/.x.zarr.*.part`` were never found again), a write that succeeds is there, and
    the input is recognised in its ``//`` forms, so it is neither replaced nor written into."""
    import s3fs
    import zarr

    from quatarray.formats import FormatError, read_zarr, resample_zarr
    from quatarray.formats import zarr as _zarr
    monkeypatch.setattr(_zarr, "CHUNK_QUATS", 2 * 4)
    monkeypatch.setattr(_zarr, "MEMORY_KEYS", 0)       # keys read while the output is written
    bucket = "quatarray-test"
    times, keys = _s3_input(rng, f"s3://{bucket}/slashes/in.zarr", s3)

    def objects():
        found = s3fs.S3FileSystem(skip_instance_cache=True, **s3).find(bucket)   # keys with a leading / too
        return sorted(p[len(bucket) + 1:] for p in found if "slashes" in p)

    before = objects()
    for out, plain in ((f"s3://{bucket}//slashes-out.zarr", f"s3://{bucket}/slashes-out.zarr"),
                       (f"s3://{bucket}/slashes//out.zarr/", f"s3://{bucket}/slashes/out.zarr")):
        assert resample_zarr(f"s3://{bucket}/slashes/in.zarr", out, fps=4, progress=False, storage_options=s3)[0] == 30
        np.testing.assert_array_equal(read_zarr(plain, storage_options=s3).times,
                                      quatarray.formats.fps_times(times[0], times[-1], 4, onto=times))
    written = objects()
    assert not [p for p in written if ".part" in p or p.startswith("/") or "//" in p], written
    s3fs.S3FileSystem(skip_instance_cache=True, **s3).pipe(f"{bucket}/slashes/in.zarr/keys/c/2/0/0", b"garbage")
    for out in (f"s3://{bucket}//slashes-bad.zarr", f"s3://{bucket}/slashes//bad.zarr"):
        with pytest.raises(FormatError, match="cannot read array 'keys'"):
            resample_zarr(f"s3://{bucket}/slashes/in.zarr", out, fps=4, progress=False, storage_options=s3)
        assert objects() == written
    for out, message in ((f"s3://{bucket}//slashes//in.zarr", "is the input"),
                         (f"s3://{bucket}/slashes//in.zarr//sub.zarr", "lies inside the input"),
                         (f"s3://{bucket}/slashes//", "lies inside the input")):
        with pytest.raises(FormatError, match=message):
            resample_zarr(f"s3://{bucket}/slashes/in.zarr", out, fps=4, progress=False, force=True, storage_options=s3)
    assert objects() == written
    assert set(before) < set(written)
    np.testing.assert_array_equal(zarr.open_group(f"s3://{bucket}/slashes/in.zarr", mode="r",
                                                  storage_options=s3)["times"][...], times)


def test_s3_quatarray_dask(s3, rng):
    """quatarray.dask on chunks read from and written to an S3-protocol server with dask's
    from_zarr / to_zarr and storage_options."""
    times, keys = _s3_input(rng, "s3://quatarray-test/qd/in.zarr", s3, batch=())
    track = Track(times, keys, method="squad")
    t = da.linspace(times[0], times[-1], 500, chunks=128)
    qd.evaluate(track, t).to_zarr("s3://quatarray-test/qd/out.zarr", component="keys", storage_options=s3)
    back = da.from_zarr("s3://quatarray-test/qd/out.zarr", component="keys", storage_options=s3)
    assert back.chunks[0] == (128, 128, 128, 116)
    np.testing.assert_array_equal(back.compute(), np.asarray(track(t.compute())))
    stored = da.from_zarr("s3://quatarray-test/qd/in.zarr", component="keys", storage_options=s3)
    np.testing.assert_allclose(qd.mean(stored).compute(), quats(Rotation.from_quat(keys, scalar_first=True).mean()),
                               rtol=0, atol=8 * np.finfo(np.float32).eps)


def test_object_store_output_appears_metadata_last(rng, monkeypatch):
    """On an object store (memory:// here) the output is written under a temporary prefix and
    copied under the target chunks first, each array's zarr.json after its chunks, the group's last;
    a failure leaves nothing."""
    import fsspec
    import zarr

    from quatarray.formats import zarr as _zarr
    monkeypatch.setattr(_zarr, "CHUNK_QUATS", 16)
    times, keys = _s3_input(rng, "memory://qa-order/in.zarr", None, batch=())
    fs = fsspec.filesystem("memory")
    copied = []
    real = type(fs).copy

    def copy(self, path1, path2, *args, **kwargs):
        copied.extend([path2] if isinstance(path2, str) else path2)
        return real(self, path1, path2, *args, **kwargs)

    monkeypatch.setattr(type(fs), "copy", copy)
    _zarr.resample_zarr("memory://qa-order/in.zarr", "memory://qa-order/out.zarr", fps=9, progress=False)
    names = [p.split("/out.zarr/", 1)[1] for p in copied]
    assert names[-1] == "zarr.json" and names.index("keys/zarr.json") > max(
        i for i, n in enumerate(names) if n.startswith("keys/c/"))
    assert sorted(fs.ls("/qa-order", detail=False)) == ["/qa-order/in.zarr", "/qa-order/out.zarr"]
    out = zarr.open_group("memory://qa-order/out.zarr", mode="r")
    np.testing.assert_array_equal(out["keys"][...], np.asarray(Track(times, keys)(out["times"][...])))
    fs.pipe("/qa-order/in.zarr/keys/c/1/0", b"garbage")          # fails while writing
    with pytest.raises(ValueError, match="cannot read array 'keys'"):
        _zarr.resample_zarr("memory://qa-order/in.zarr", "memory://qa-order/bad.zarr", fps=9, progress=False)
    assert sorted(fs.ls("/qa-order", detail=False)) == ["/qa-order/in.zarr", "/qa-order/out.zarr"]
    fs.rm("/qa-order", recursive=True)


def test_local_cluster_two_processes_writing_to_s3(rng, s3):
    """Two worker processes, as the hosts of a cluster would: quatarray.dask's tasks, and the
    Zarr path's chunks written by the workers to the S3-protocol server."""
    distributed = pytest.importorskip("distributed", reason="distributed is not installed (the dask extra)")
    import zarr

    from quatarray.formats import resample_zarr
    times = np.cumsum(rng.uniform(0.1, 1, 30))
    keys = unit(rng, (30, 2), np.float64)
    track = Track(times, keys, method="squad")
    t = rng.uniform(times[0], times[-1], 200)
    q = _flippy(rng, 40, 2, np.float64)
    g = zarr.open_group("s3://quatarray-test/cluster/in.zarr", mode="w", storage_options=s3)
    g["times"], g["keys"] = times, keys
    with distributed.LocalCluster(n_workers=2, threads_per_worker=2, processes=True, host="127.0.0.1",
                                  dashboard_address="127.0.0.1:0",
                                  silence_logs=40) as cluster, distributed.Client(cluster) as client:
        lazy = [qd.evaluate(track, da.from_array(t, chunks=30)),
                qd.unflip(da.from_array(q, chunks=(7, 1, 4))),
                qd.mean(da.from_array(q, chunks=(9, 2, 4))),
                qd.slerp(da.from_array(q[:-1], chunks=(6, 2, 4)), q[1:], 0.3),
                da.zeros(8, chunks=2).map_blocks(lambda b: np.full(b.shape, quatarray.get_num_threads()), dtype=int)]
        got = client.compute(lazy, sync=True)
        pids = set(client.run(os.getpid).values())
        assert len(pids) == 2 and os.getpid() not in pids      # two processes, not this one
        # the CLI's Zarr path on the cluster (--scheduler ADDRESS); the workers write the chunks
        assert resample_zarr("s3://quatarray-test/cluster/in.zarr", "s3://quatarray-test/cluster/out.zarr",
                             times=t, method="squad", scheduler=cluster.scheduler_address, progress=False,
                             storage_options=s3) == (30, 200)
        # and the active Client is used when no scheduler is named, with distributed's progress
        assert resample_zarr("s3://quatarray-test/cluster/in.zarr", "s3://quatarray-test/cluster/out2.zarr",
                             times=t, method="squad", progress=True, storage_options=s3) == (30, 200)
        tasks = client.run(lambda dask_worker: len(dask_worker.state.log))
        assert all(n > 0 for n in tasks.values())
    for name in ("out", "out2"):
        stored = zarr.open_group(f"s3://quatarray-test/cluster/{name}.zarr", mode="r", storage_options=s3)
        np.testing.assert_allclose(stored["keys"][...], np.asarray(track(t)), rtol=0, atol=32 * np.finfo(float).eps)
    np.testing.assert_allclose(got[0], np.asarray(track(t)), rtol=0, atol=32 * np.finfo(float).eps)
    np.testing.assert_array_equal(got[1], np.asarray(qi.unflip(q)))
    np.testing.assert_allclose(got[2], quats(Rotation.from_quat(q, scalar_first=True).mean()), rtol=0,
                               atol=100 * np.finfo(float).eps)
    np.testing.assert_allclose(got[3], np.asarray(qi.slerp(q[:-1], q[1:], 0.3)), rtol=0, atol=32 * np.finfo(float).eps)
    assert set(got[4]) == {1}


def test_a_write_failing_on_a_cluster_leaves_no_temporary_store(store, monkeypatch):
    """On a distributed cluster, a chunk that cannot be written ends the resample only once the other
    chunks of the write have finished: one still being written when the error arrived landed after
    the temporary store was removed, and made it again (a .out.zarr.*.part folder left behind)."""
    distributed = pytest.importorskip("distributed", reason="distributed is not installed (the dask extra)")
    import shutil
    import threading

    import zarr

    from quatarray.formats import zarr as _zarr
    tmp, _, _ = store
    monkeypatch.setattr(_zarr, "CHUNK_QUATS", 4 * 3)       # chunks of 4 frames of the 3 tracks
    second_started, removed, second_written = threading.Event(), threading.Event(), threading.Event()
    real_setitem, real_rmtree = zarr.Array.__setitem__, shutil.rmtree

    def setitem(self, key, value):        # the workers are threads of this process
        first = key[0].start if self.basename == "keys" else None
        if first == 0:          # the first chunk fails while the second is being written
            second_started.wait(60)
            raise OSError(errno.ENOSPC, "No space left on device")
        if first == 4:          # the second is written once the temporary store is removed, or after 3 s
            second_started.set()
            removed.wait(3)
            real_setitem(self, key, value)
            second_written.set()
            return
        real_setitem(self, key, value)

    def rmtree(path, *args, **kwargs):
        real_rmtree(path, *args, **kwargs)
        # the removal on the error, not zarr's own when it creates the group (in its I/O thread)
        if os.fspath(path).endswith(".part") and threading.current_thread() is threading.main_thread():
            removed.set()

    monkeypatch.setattr(zarr.Array, "__setitem__", setitem)
    monkeypatch.setattr(shutil, "rmtree", rmtree)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=2, processes=False, dashboard_address="127.0.0.1:0",
                                  silence_logs=40) as cluster, distributed.Client(cluster):
        with pytest.raises(OSError, match="No space left on device") as info:
            _zarr.resample_zarr(str(tmp / "in.zarr"), str(tmp / "out.zarr"), fps=1, progress=False)
        assert second_written.wait(60)
    assert info.value.filename == str(tmp / "out.zarr")
    assert sorted(os.listdir(tmp)) == ["in.zarr"]


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
    with pytest.raises(ValueError, match=r"^Expected last dimension of `angles`.*expected angles of shape "
                                         r"\(\.\.\., 3\) for seq 'xyz', got \(4, 2\)$"):
        qd.from_euler("xyz", da.zeros((4, 2)))


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
    np.testing.assert_array_equal(t, quatarray.formats.fps_times(times[0], times[-1], 7.5, onto=times))
    assert out["keys"].dtype == np.float32 and out["keys"].chunks[0] < len(t)
    want = np.asarray(Track(times, keys, method=method)(t))
    assert quatarray.formats.keys_at_key_times(times, keys, t, want)[0]   # the first frame is a key, as stored
    np.testing.assert_array_equal(out["keys"][...], want)
    # the output store is a valid input store: resampled again at its own times, or at its own rate,
    # it comes back as it is (every frame is a key)
    for args in (["--times", dst], ["--fps", "7.5"]):
        assert main(["resample", dst, "-o", str(tmp / "again.zarr"), *args, "--method", "linear",
                     "--quiet", "--force"]) == 0
        again = zarr.open_group(str(tmp / "again.zarr"), mode="r")
        np.testing.assert_array_equal(again["times"][...], t)
        np.testing.assert_array_equal(again["keys"][...], out["keys"][...])
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
    assert main(["resample", str(tmp / "in.zarr"), "-o", str(dst), "--times", str(tmp / "nothere.zarr")]) == 2
    assert f"{tmp / 'nothere.zarr'}: No such file or directory" in capsys.readouterr().err
    (tmp / "bad.zarr").mkdir()
    (tmp / "bad.zarr" / "zarr.json").write_text("{")
    assert main(["resample", str(tmp / "in.zarr"), "-o", str(dst), "--times", str(tmp / "bad.zarr")]) == 2
    assert "bad.zarr: not a Zarr array or group of times (its metadata (zarr.json) is not valid JSON" in \
        capsys.readouterr().err
    assert sorted(os.listdir(tmp)) == ["bad.zarr", "in.zarr", "t.txt"]


def test_zarr_existing_output_needs_force_and_progress_shows(store, capsys):
    import zarr

    from quatarray.formats import zarr as _zarr
    tmp, times, keys = store
    dst = str(tmp / "out.zarr")
    _zarr.resample_zarr(str(tmp / "in.zarr"), dst, fps=1, progress=False)
    assert capsys.readouterr().err == ""
    with pytest.raises(FileExistsError, match="exists; give force=True to replace it"):
        _zarr.resample_zarr(str(tmp / "in.zarr"), dst, fps=3, progress=False)
    assert zarr.open_group(dst, mode="r")["times"].shape[0] == len(quatarray.formats.fps_times(times[0], times[-1], 1))
    _zarr.resample_zarr(str(tmp / "in.zarr"), dst, fps=3, progress=True, force=True)
    assert "100% Completed" in capsys.readouterr().err
    assert zarr.open_group(dst, mode="r")["times"].shape[0] == len(quatarray.formats.fps_times(times[0], times[-1], 3))
    assert sorted(os.listdir(tmp)) == ["in.zarr", "out.zarr"]


def test_zarr_input_is_never_its_output(store, capsys):
    """Even with --force: a store cannot be replaced atomically while it is read."""
    from quatarray.cli import main
    tmp, times, _ = store
    before = sorted(os.listdir(tmp / "in.zarr"))
    os.symlink(tmp / "in.zarr", tmp / "link.zarr")
    for out, force in [("in.zarr", []), ("in.zarr", ["--force"]), ("in.zarr/", ["--force"]), ("link.zarr", ["--force"])]:
        assert main(["resample", str(tmp / "in.zarr"), "-o", str(tmp / out), "--fps", "10", *force]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"quatarray: error: {tmp / out}: is the input, which is read chunk by chunk while "
                              "the output is written"), err   # the output named once
    assert sorted(os.listdir(tmp / "in.zarr")) == before
    assert sorted(os.listdir(tmp)) == ["in.zarr", "link.zarr"]


@pytest.mark.parametrize("out", ["out.zarr", "out.npz"])
def test_zarr_fps_1e308_is_a_one_line_error(store, capsys, out):
    """--fps 1e308 on a Zarr store raised OverflowError in fps_steps (chunked, or read whole)."""
    from quatarray.cli import main
    tmp, times, _ = store
    assert main(["resample", str(tmp / "in.zarr"), "-o", str(tmp / out), "--fps", "1e308"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"quatarray: error: {tmp / 'in.zarr'}: a rate of 1e+308 fps over ") and \
        "the limit is 1,073,741,824 values" in err and err.count("\n") == 1, err
    assert sorted(os.listdir(tmp)) == ["in.zarr"]


def test_zarr_messages_name_the_users_path(store, capsys):
    """Never a temporary ``.part`` name: a missing folder, a regular file at OUT.zarr."""
    from quatarray.cli import main
    from quatarray.formats import zarr as _zarr
    tmp, times, _ = store
    src = str(tmp / "in.zarr")
    out = tmp / "nodir" / "o8.zarr"
    assert main(["resample", src, "-o", str(out), "--fps", "2"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"quatarray: error: {out}: No such file or directory") and ".part" not in err
    (tmp / "file.zarr").write_text("not a store")
    for force in ([], ["--force"]):     # a file is never replaced by a store
        assert main(["resample", src, "-o", str(tmp / "file.zarr"), "--fps", "2", *force]) == 2
        err = capsys.readouterr().err
        assert err == f"quatarray: error: {tmp / 'file.zarr'}: exists and is not a Zarr store (a directory)\n"
    assert (tmp / "file.zarr").read_text() == "not a store"
    with pytest.raises(FileExistsError, match="exists and is not a Zarr store"):
        _zarr.resample_zarr(src, str(tmp / "file.zarr"), fps=2, force=True)
    assert sorted(os.listdir(tmp)) == ["file.zarr", "in.zarr"]


def test_outputs_inside_the_input_or_holding_it_are_refused(store, capsys):
    """An output inside the input's store, or a store holding the input, is refused even with
    --force (its replacement deleted the input), on local paths and URLs alike; the input and
    the folder are left as they were."""
    from quatarray.cli import main
    from quatarray.formats import FormatError, read_zarr, resample_zarr, write_zarr
    tmp, _, keys = store
    outer = tmp / "outer.zarr"
    for src, out in ((tmp / "in.zarr", tmp / "in.zarr" / "sub.zarr"), (tmp / "in.zarr", tmp / "in.zarr" / "x.csv"),
                     (outer / "in.zarr", outer)):
        if src.parent == outer:
            outer.mkdir(exist_ok=True)
            write_zarr(src, read_zarr(tmp / "in.zarr"), force=True)
        before = sorted(os.listdir(src))
        assert main(["resample", str(src), "-o", str(out), "--fps", "2", "--force"]) == 2
        assert capsys.readouterr().err == f"quatarray: error: {out}: lies inside the input, or holds it: write elsewhere\n"
        assert sorted(os.listdir(src)) == before
        np.testing.assert_array_equal(read_zarr(src).keys, keys)
    write_zarr("memory://nest/in.zarr", read_zarr(tmp / "in.zarr"), force=True)
    with pytest.raises(FormatError, match="lies inside the input, or holds it"):
        resample_zarr("memory://nest/in.zarr", "memory://nest/in.zarr/sub.zarr", fps=2, progress=False, force=True)


def test_an_empty_times_store_is_refused_as_an_empty_times_file(store, capsys):
    """A --times store of no times wrote a store of no frames, which no reader takes back; it is
    refused before anything is written, as an empty file of times is."""
    import zarr
    from quatarray.cli import main
    tmp, _, _ = store
    zarr.open_group(str(tmp / "t.zarr"), mode="w")["times"] = np.zeros(0)
    (tmp / "t.txt").write_text("")
    for times in ("t.zarr", "t.txt"):
        assert main(["resample", str(tmp / "in.zarr"), "-o", str(tmp / "out.zarr"), "--times", str(tmp / times)]) == 2
        assert capsys.readouterr().err == f"quatarray: error: {tmp / times}: no times\n"
    assert sorted(os.listdir(tmp)) == ["in.zarr", "t.txt", "t.zarr"]


def test_an_object_where_a_store_goes_is_never_replaced(store):
    """On an object store as on a disk, a file (an object) at OUT.zarr is not replaced, even with
    force; a store there is."""
    import fsspec
    from quatarray.formats import read_zarr, write_zarr
    tmp, _, keys = store
    kf = read_zarr(tmp / "in.zarr")
    fsspec.filesystem("memory").pipe("/objects/file.zarr", b"data")
    with pytest.raises(FileExistsError, match="exists and is not a Zarr store"):
        write_zarr("memory://objects/file.zarr", kf, force=True)
    assert fsspec.filesystem("memory").cat("/objects/file.zarr") == b"data"
    write_zarr("memory://objects/out.zarr", kf)
    write_zarr("memory://objects/out.zarr", kf, force=True)
    np.testing.assert_array_equal(read_zarr("memory://objects/out.zarr").keys, keys)


def test_a_store_moved_aside_comes_back_when_the_new_one_cannot_take_its_place(store, monkeypatch):
    """Replacing a local store moves it aside, then renames the new one onto it: a failure (or an
    interrupt) between the two puts the old store back, and leaves no temporary folder."""
    from quatarray.formats import read_zarr, write_zarr
    from quatarray.formats import zarr as _zarr
    tmp, _, keys = store
    kf = read_zarr(tmp / "in.zarr")
    out = tmp / "out.zarr"
    write_zarr(out, kf)
    real = os.replace
    calls = []

    def failing(a, b):
        if os.fspath(a).endswith(".part") and os.fspath(b) == str(out):   # the new store onto OUT
            calls.append(a)
            raise KeyboardInterrupt
        return real(a, b)

    monkeypatch.setattr(_zarr.os, "replace", failing)
    with pytest.raises(KeyboardInterrupt):
        write_zarr(out, kf, force=True)
    monkeypatch.setattr(_zarr.os, "replace", real)
    assert len(calls) == 1
    np.testing.assert_array_equal(read_zarr(out).keys, keys)
    assert sorted(os.listdir(tmp)) == ["in.zarr", "out.zarr"]


def test_a_copy_onto_an_object_store_cut_short_keeps_the_new_store(store, monkeypatch):
    """On an object store the old OUT is removed before the new store is copied under it: a copy
    cut short keeps the new store's temporary prefix (the error names it), and a rerun with
    force replaces the incomplete OUT."""
    import fsspec
    from quatarray.formats import read_zarr, write_zarr
    tmp, _, keys = store
    kf = read_zarr(tmp / "in.zarr")
    write_zarr("memory://cut/out.zarr", kf)
    mem = type(fsspec.filesystem("memory"))
    real = mem.copy

    def cut(self, *args, **kwargs):   # the chunks arrive, the metadata does not
        if str(args[0]).endswith("zarr.json"):
            raise KeyboardInterrupt
        return real(self, *args, **kwargs)

    monkeypatch.setattr(mem, "copy", cut)
    with pytest.raises(KeyboardInterrupt) as info:
        write_zarr("memory://cut/out.zarr", kf, force=True)
    monkeypatch.setattr(mem, "copy", real)
    kept = re.search(r"kept at (\S+);", " ".join(info.value.__notes__)).group(1)
    np.testing.assert_array_equal(read_zarr(kept).keys, keys)
    write_zarr("memory://cut/out.zarr", kf, force=True)
    np.testing.assert_array_equal(read_zarr("memory://cut/out.zarr").keys, keys)


@pytest.mark.filterwarnings("ignore:The data type")    # zarr on fixed-length strings
@pytest.mark.parametrize("damage, message", [
    ("complex", "expected 'keys' of real numbers, got dtype complex128"),
    ("strings", "expected 'keys' of real numbers, got dtype"),
    ("group", "expected 'keys' to be an array, got a group"),
    ("no keys", "missing array 'keys' (found arrays: times)"),
    ("group json", "not a Zarr group with arrays 'times' and 'keys' (its metadata (zarr.json) is not valid JSON"),
    ("array json", "cannot open array 'keys': its metadata (zarr.json) is not valid JSON"),
    ("chunk", "cannot read array 'keys' at (slice("),
])
@pytest.mark.parametrize("out", ["out.zarr", "out.npz"])   # chunk by chunk, or read whole
def test_zarr_bad_stores_give_clear_errors(tmp_path, damage, message, out, capsys):
    zarr = pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    from quatarray.cli import main
    src = tmp_path / "in.zarr"
    g = zarr.open_group(str(src), mode="w")
    g["times"] = np.arange(30.0)
    keys = np.tile([1.0, 0, 0, 0], (30, 1))
    if damage == "complex":
        g["keys"] = keys.astype(complex)
    elif damage == "strings":
        g["keys"] = keys.astype(str)
    elif damage == "group":
        g.create_group("keys")
    elif damage != "no keys":
        g.create_array("keys", data=keys, chunks=(10, 4), compressors=zarr.codecs.ZstdCodec())
    if damage == "group json":
        (src / "zarr.json").write_text('{"zarr_format": 3, "node_type": "gro')
    elif damage == "array json":
        (src / "keys" / "zarr.json").write_text("{bad")
    elif damage == "chunk":
        (src / "keys" / "c" / "1" / "0").write_bytes(b"garbage" * 9)
    assert main(["resample", str(src), "-o", str(tmp_path / out), "--fps", "2"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"quatarray: error: {src}: ") and message in err, err
    assert "Traceback" not in err and sorted(os.listdir(tmp_path)) == ["in.zarr"]


def test_zarr_huge_output_is_refused_or_built_window_by_window(store, monkeypatch, capsys):
    """--fps 1e12 is refused before any writing when the disk cannot hold it, and the task graph
    is built a window of chunks at a time: its size does not grow with the number of queries."""
    import zarr
    from dask.callbacks import Callback

    from quatarray.formats import zarr as _zarr
    from quatarray.cli import main
    tmp, times, keys = store
    assert main(["resample", str(tmp / "in.zarr"), "-o", str(tmp / "out.zarr"), "--fps", "1e12"]) == 2
    err = capsys.readouterr().err
    # the output alone is named (it read "quatarray: error: IN: OUT: the output needs ...")
    assert err.startswith(f"quatarray: error: {tmp / 'out.zarr'}: the output needs ") and "GB free" in err
    with pytest.raises(OSError, match="the output needs") as info:
        _zarr.resample_zarr(str(tmp / "in.zarr"), str(tmp / "out.zarr"), fps=1e12, progress=False)
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(tmp / "out.zarr")
    assert sorted(os.listdir(tmp)) == ["in.zarr"]
    monkeypatch.setattr(_zarr, "CHUNK_QUATS", 3 * 8)      # 8 queries x 3 tracks a chunk
    monkeypatch.setattr(_zarr, "WINDOW_CHUNKS", 4)
    largest = {}
    for fps in (8, 64):     # 7 and 49 chunks
        graphs = []
        with Callback(start=lambda dsk: graphs.append(len(dsk))):
            dst = str(tmp / f"out{fps}.zarr")
            _, n = _zarr.resample_zarr(str(tmp / "in.zarr"), dst, fps=fps, progress=False)
        assert len(graphs) == 1 + -(-n // (8 * 4)), graphs       # reading the keys, then one per window
        largest[fps] = max(graphs)
        out = zarr.open_group(dst, mode="r")
        np.testing.assert_array_equal(out["keys"][...], np.asarray(Track(times, keys)(out["times"][...])))
    assert largest[64] == largest[8], largest


def test_zarr_storage_options_need_a_url(store):
    from quatarray.formats import zarr as _zarr
    tmp, _, _ = store
    with pytest.raises(ValueError, match="expected a store URL .* for storage_options"):
        _zarr.resample_zarr(str(tmp / "in.zarr"), str(tmp / "out.zarr"), fps=2, storage_options={"anon": True})


def test_zarr_memory_url_through_the_cli(store, capsys):
    """Any fsspec URL zarr opens: memory:// here (in this process), with --storage-option parsed."""
    import zarr

    from quatarray.cli import main
    tmp, times, keys = store
    src = zarr.open_group("memory://qa-cli/in.zarr", mode="w")
    src["times"], src["keys"] = times, keys
    out = "memory://qa-cli/out.zarr"
    assert main(["resample", "memory://qa-cli/in.zarr", "-o", out, "--fps", "5", "--quiet",
                 "--storage-option", "skip_instance_cache=true"]) == 0
    got = zarr.open_group(out, mode="r")
    np.testing.assert_array_equal(got["keys"][...], np.asarray(Track(times, keys)(got["times"][...])))
    import fsspec
    fs = fsspec.filesystem("memory")
    assert sorted(p.rsplit("/", 1)[-1] for p in fs.ls("/qa-cli", detail=False)) == ["in.zarr", "out.zarr"]   # no .part left
    assert main(["resample", quatarray.formats.example_path("arm.csv"), "-o", str(tmp / "o.csv"), "--fps", "5",
                 "--storage-option", "anon=true"]) == 2
    assert "storage options apply to Zarr stores (.zarr) only" in capsys.readouterr().err
    fs.rm("/qa-cli", recursive=True)


# --------------------------------------------------------------------------- Zarr to and from CSV and NPZ

def _read_any(path):
    from quatarray.formats import read_csv, read_npz, read_zarr
    return {".csv": read_csv, ".npz": read_npz, ".zarr": read_zarr}[os.path.splitext(str(path))[1]](path)


@pytest.mark.parametrize("dtype, chain", [(np.float64, (".csv", ".zarr", ".npz", ".zarr", ".csv")),
                                          (np.float32, (".npz", ".zarr", ".csv", ".zarr"))])
def test_zarr_converts_to_and_from_csv_and_npz(tmp_path, dtype, chain):
    """Each step of CSV -> Zarr -> NPZ -> Zarr -> CSV (and from a float32 NPZ) writes, bit for bit, the
    in-memory resample of what it read (the same computation, resample_keyframes), with the track names;
    float32 stays float32 in NPZ and Zarr (a CSV of it holds 9 digits, the same float32, read as float64)."""
    from quatarray.formats import (Keyframes, example_path, fps_times, read_csv, resample_file, resample_keyframes,
                                   write_npz)
    arm = read_csv(example_path("arm.csv"))
    src = tmp_path / ("step0" + chain[0])
    if chain[0] == ".csv":
        src = example_path("arm.csv")
    else:
        write_npz(src, Keyframes(arm.times, arm.keys.astype(dtype), arm.names))
    steps = zip(chain[1:], (30, 7.5, 12, 50), ("squad", "slerp", "bezier", "linear"))
    for step, (ext, fps, method) in enumerate(steps):
        dst = tmp_path / f"step{step + 1}{ext}"
        read = _read_any(src)
        assert resample_file(src, dst, fps=fps, method=method, progress=False) == (len(read.times), len(
            fps_times(read.times[0], read.times[-1], fps)))
        want = resample_keyframes(read, fps_times(read.times[0], read.times[-1], fps, onto=read.times), method=method)
        got = _read_any(dst)
        np.testing.assert_array_equal(got.times, want.times)
        np.testing.assert_array_equal(got.keys.astype(want.keys.dtype), want.keys)
        assert got.names == arm.names
        if ext != ".csv":
            assert got.keys.dtype == want.keys.dtype == (dtype if step < 2 else np.float64)
        src = dst
    assert sorted(os.listdir(tmp_path)) == sorted(f"step{i}{e}" for i, e in enumerate(chain) if i or e != ".csv")


def test_zarr_to_zarr_stays_chunked_and_keeps_the_names(store, monkeypatch):
    """Zarr -> Zarr goes chunk by chunk (never whole into memory: a store over the in-memory limit still
    resamples), while Zarr -> NPZ needs the whole track and refuses it with the limit, leaving no output;
    the track names travel with the chunked path too."""
    import zarr

    from quatarray.formats import resample_file, text
    from quatarray.formats import zarr as _zarr
    tmp, times, keys = store
    zarr.open_group(str(tmp / "in.zarr"), mode="r+").attrs["names"] = ["a", "b", "c"]
    monkeypatch.setattr(text, "MAX_VALUES", keys.size - 1)
    monkeypatch.setattr(_zarr, "CHUNK_QUATS", 3 * 8)
    assert resample_file(tmp / "in.zarr", tmp / "out.zarr", fps=4, progress=False)[0] == len(times)
    out = zarr.open_group(str(tmp / "out.zarr"), mode="r")
    assert out.attrs["names"] == ["a", "b", "c"] and out["keys"].chunks[0] == 8
    np.testing.assert_array_equal(out["keys"][...], np.asarray(Track(times, keys)(out["times"][...])))
    with pytest.raises(ValueError, match=r"reading the store into memory \(only \.zarr to \.zarr is resampled "
                                         r"chunk by chunk\) asks for 25 frames of 12 values.*the limit is 299 values"):
        resample_file(tmp / "in.zarr", tmp / "out.npz", fps=4)
    assert sorted(os.listdir(tmp)) == ["in.zarr", "out.zarr"]


@pytest.mark.parametrize("pair", [(".csv", ".zarr"), (".zarr", ".npz"), (".zarr", ".csv")])
def test_zarr_conversions_follow_the_overwrite_rule(store, pair):
    """An existing output is refused without force (left as it was) and replaced with it; a file where a
    store should be is never replaced."""
    from quatarray.formats import example_path, resample_file
    tmp, _, _ = store
    src = example_path("arm.csv") if pair[0] == ".csv" else tmp / "in.zarr"
    dst = tmp / ("out" + pair[1])
    if pair[1] == ".zarr":
        dst.mkdir()
        (dst / "precious").write_text("old")
    else:
        dst.write_text("old")
    with pytest.raises(FileExistsError, match="exists; give force=True to replace it") as info:
        resample_file(src, dst, fps=3)
    assert info.value.filename == str(dst)
    assert (dst / "precious" if pair[1] == ".zarr" else dst).read_text() == "old"
    resample_file(src, dst, fps=3, force=True)
    assert _read_any(dst).keys.shape[1:] == _read_any(src).keys.shape[1:]
    if pair[1] == ".zarr":
        assert not (dst / "precious").exists()
        (tmp / "file.zarr").write_text("not a store")
        with pytest.raises(FileExistsError, match="exists and is not a Zarr store"):
            resample_file(src, tmp / "file.zarr", fps=3, force=True)
        assert (tmp / "file.zarr").read_text() == "not a store"
    assert not [f for f in os.listdir(tmp) if f.startswith(".")]     # no temporary left


def test_zarr_conversions_refuse_other_families_and_local_storage_options(store):
    from quatarray.formats import FormatError, example_path, resample_file
    tmp, _, _ = store
    with pytest.raises(FormatError, match=r"cannot write \.zarr from \.bvh input \(BVH files convert into \.bvh "
                                          r"only\)"):
        resample_file(example_path("walk.bvh"), tmp / "out.zarr", fps=3)
    with pytest.raises(FormatError, match=r"cannot write \.glb from \.zarr input \(keyframes files convert into "
                                          r"\.csv, \.npz, \.zarr only\)"):
        resample_file(tmp / "in.zarr", tmp / "out.glb", fps=3)
    with pytest.raises(ValueError, match="expected a store URL .* for storage_options to apply to, got the local "
                                         "paths .*out.zarr"):
        resample_file(example_path("arm.csv"), tmp / "out.zarr", fps=3, storage_options={"anon": True})
    assert sorted(os.listdir(tmp)) == ["in.zarr"]


def test_zarr_url_to_and_from_csv_with_storage_options(tmp_path):
    """CSV -> memory:// store -> NPZ and a memory:// store of times, with storage options: the registry
    hands them to the Zarr reader and writer."""
    import fsspec

    from quatarray.formats import example_path, fps_times, read_csv, read_npz, resample_file, resample_keyframes
    options = {"skip_instance_cache": True}
    arm = read_csv(example_path("arm.csv"))
    url = "memory://qa-convert/arm.zarr"
    assert resample_file(example_path("arm.csv"), url, fps=20, storage_options=options) == (11, 81)
    want = resample_keyframes(arm, fps_times(arm.times[0], arm.times[-1], 20, onto=arm.times))
    assert resample_file(url, tmp_path / "arm.npz", times=url, storage_options=options) == (81, 81)
    got = read_npz(tmp_path / "arm.npz")
    np.testing.assert_array_equal(got.times, want.times)
    np.testing.assert_array_equal(got.keys, want.keys)
    assert fsspec.filesystem("memory").ls("/qa-convert", detail=False) == ["/qa-convert/arm.zarr"]  # no .part
    fsspec.filesystem("memory").rm("/qa-convert", recursive=True)


@pytest.mark.parametrize("damage, message", [
    ("nan", "keys[3, 1]: non-finite quaternion component"),
    ("zero", "keys[3, 1]: zero quaternion (cannot be a rotation)"),
    ("order", "times[3]: time 2.0 does not come after 2.0 (times must be strictly increasing)"),
    ("names", "expected the attribute 'names' to be a list of 2 strings, one per track, got"),
])
def test_read_zarr_checks_the_keys_as_read_npz_does(tmp_path, damage, message):
    import zarr

    from quatarray.formats import FormatError, read_zarr
    times, keys = np.arange(5.0), np.tile([1.0, 0, 0, 0], (5, 2, 1))
    if damage == "nan":
        keys[3, 1, 2] = np.nan
    elif damage == "zero":
        keys[3, 1] = 0
    elif damage == "order":
        times[3] = times[2]
    g = zarr.open_group(str(tmp_path / "in.zarr"), mode="w")
    g["times"], g["keys"] = times, keys
    if damage == "names":
        g.attrs["names"] = ["only one"]
    with pytest.raises(FormatError, match=re.escape(f"{tmp_path / 'in.zarr'}: {message}")):
        read_zarr(tmp_path / "in.zarr")


@pytest.mark.parametrize("t0, t1, fps", [(0.0, 999_999_999.0, 1.0), (0.0, 4.2, 30.0), (0.0, 127 / 30, 30.0),
                                         (1403636579.76, 1403636599.76, 200.0)])
def test_zarr_fps_grid_is_io_fps_times(t0, t1, fps):
    """The Zarr path's lazy --fps grid has io.fps_times' count and values (no extra frame on
    long spans: 0 .. 999999999 at 1 fps is 10⁹ frames, not 10⁹ + 1)."""
    from quatarray.formats import zarr as _zarr
    from quatarray.formats import fps_steps, fps_times

    queries = _zarr._Queries(np.array([t0, t1]), fps, None, None)
    n = queries.size
    assert n == fps_steps(t0, t1, fps) + 1
    if n < 10**6:
        assert np.array_equal(queries.window(0, n, 1 << 20).compute(), fps_times(t0, t1, fps))
        assert np.array_equal(queries.window(5, n, 7).compute(), fps_times(t0, t1, fps)[5:])
    else:
        assert queries.window(n - 2, n, 4).compute()[1] == t1 and queries.window(n - 2, n, 4).compute()[0] < t1


def test_no_zarr_internals_in_the_package():
    """Zarr through its public API only: no private modules or names anywhere in quatarray/."""
    import re
    root = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "quatarray")
    private = re.compile(r"zarr\.core\b|zarr\.\w+\._|\bzarr\._|encode_chunk_key|chunk_key_encoding|\.serializer\b|"
                         r"\bcname\.value\b|\.metadata\.|\bfrom zarr\.(core|abc|api|storage\._|codecs\._)")
    found = []
    for folder, _, files in os.walk(root):
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                for number, line in enumerate(open(path, encoding="utf-8"), 1):
                    if private.search(line):
                        found.append(f"{os.path.relpath(path, root)}:{number}: {line.strip()}")
    assert not found, "\n".join(found)
    assert private.search("from zarr.core.metadata import ArrayV3Metadata")      # the scan can fail
    assert private.search("keys.encode_chunk_key((0, 1))")


def test_readme_dask_example_runs_twice_with_progress(capsys):
    """The README's example writes into a temporary directory (so it runs again), shows progress;
    run here at 10⁵ queries instead of 10⁷."""
    pytest.importorskip("zarr", reason="zarr is not installed (the dask extra)")
    import re
    readme = open(os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "README.md"),
                  encoding="utf-8").read()
    code = re.search(r"## Beyond memory.*?```python\n(.*?)```", readme, re.S).group(1)
    assert "10**7" in code and "TemporaryDirectory" in code and "ProgressBar" in code
    code = code.replace("10**7", "10**5").replace("2**20", "2**14")
    for _ in range(2):
        namespace = {}
        exec(compile(code, "README.md", "exec"), namespace)
        assert "100% Completed" in capsys.readouterr().out
        assert namespace["q"].shape == (10**5, 4) and not os.path.exists(namespace["folder"])
