"""The block engine: splitting, thread controls, identical results for any
thread count, errors from workers, and scratch that stays bounded."""

import os
import subprocess
import sys
import threading
import time
import tracemalloc
import warnings

import numpy as np
import pytest

import quatarray
from quatarray import _blocks
from quatarray import _convert as C
from quatarray import _euler as E
from quatarray import _interp_kernels as IK
from quatarray import _kernels as K
from quatarray._blocks import BLOCK
from quatarray.interpolate import Track

from .conftest import random_quats


@pytest.fixture
def parallel_always(monkeypatch):
    """Every batch goes to the pool, so that small test batches exercise the threads."""
    monkeypatch.setattr(_blocks, "PARALLEL_MIN", 0)


# --- splitting ---------------------------------------------------------------------------

@pytest.mark.parametrize("shape", [(5,), (3, 4), (7, 3, 5), (2, 9), (0, 3), (), (1, 1, 13)])
@pytest.mark.parametrize("block", [1, 4, 6])
def test_split_covers_batch_once_in_bounded_blocks(shape, block):
    seen = np.zeros(shape, int)
    for idx in _blocks.split(shape, block):
        part = seen[idx]
        assert part.size <= max(block, 1) or idx == ()
        seen[idx] += 1
    assert np.all(seen == 1)


def test_part_broadcasts_operands_against_a_block():
    a = np.arange(3 * 4 * 4.0).reshape(3, 4, 4)
    b = np.arange(4.0 * 4).reshape(1, 4, 4)
    for idx in _blocks.split((3, 4), 2):
        np.testing.assert_array_equal(_blocks.part(a, idx, 2), a[idx])
        np.testing.assert_array_equal(np.broadcast_to(_blocks.part(b, idx, 2), a[idx].shape),
                                      np.broadcast_to(b, a.shape)[idx])


# --- thread controls ---------------------------------------------------------------------------

def test_default_is_the_affinity_and_set_num_threads_overrides():
    quatarray.set_num_threads(None)
    try:
        expected = int(os.environ.get("QUATARRAY_NUM_THREADS") or len(os.sched_getaffinity(0)))
        assert quatarray.get_num_threads() == expected
        quatarray.set_num_threads(3)
        assert quatarray.get_num_threads() == 3
    finally:
        quatarray.set_num_threads(None)


def test_context_manager_applies_to_its_thread_and_nests():
    quatarray.set_num_threads(4)
    try:
        with quatarray.num_threads(2):
            assert quatarray.get_num_threads() == 2
            with quatarray.num_threads(1):
                assert quatarray.get_num_threads() == 1
            assert quatarray.get_num_threads() == 2
        assert quatarray.get_num_threads() == 4
    finally:
        quatarray.set_num_threads(None)


def test_other_threads_run_single_threaded_unless_asked():
    got = {}

    def body():
        got["plain"] = quatarray.get_num_threads()
        with quatarray.num_threads(3):
            got["asked"] = quatarray.get_num_threads()

    quatarray.set_num_threads(4)
    try:
        th = threading.Thread(target=body)
        th.start()
        th.join()
    finally:
        quatarray.set_num_threads(None)
    assert got == {"plain": 1, "asked": 3}


def test_no_nested_fan_out_inside_workers(parallel_always):
    """A call made inside a block (on a worker or the caller) runs single-threaded."""
    inner = []

    def fn(i):
        time.sleep(0.002)
        inner.append((threading.get_ident(), quatarray.get_num_threads()))
        return i

    with quatarray.num_threads(3):
        assert _blocks.run(fn, list(range(12)), 12) == list(range(12))
    assert {n for _, n in inner} == {1}
    assert len({ident for ident, _ in inner}) > 1   # the pool did take blocks


@pytest.mark.parametrize("value, expected", [("3", 3), ("1", 1)])
def test_environment_variable_sets_the_default(value, expected):
    code = "import quatarray; print(quatarray.get_num_threads())"
    env = dict(os.environ, QUATARRAY_NUM_THREADS=value)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True, cwd=os.path.dirname(os.path.dirname(__file__)))
    assert int(out.stdout) == expected


def test_bad_environment_variable_warns_and_uses_the_cpus(monkeypatch):
    monkeypatch.setenv("QUATARRAY_NUM_THREADS", "many")
    quatarray.set_num_threads(None)
    try:
        with pytest.warns(RuntimeWarning, match="QUATARRAY_NUM_THREADS"):
            n = quatarray.get_num_threads()
        assert n == len(os.sched_getaffinity(0))
    finally:
        monkeypatch.delenv("QUATARRAY_NUM_THREADS")
        quatarray.set_num_threads(None)


@pytest.mark.parametrize("bad, exc", [(0, ValueError), (-2, ValueError), (1.5, TypeError), (True, TypeError),
                                      ("2", TypeError)])
def test_bad_thread_counts(bad, exc):
    with pytest.raises(exc, match="expected n to be a positive int"):
        quatarray.set_num_threads(bad)
    with pytest.raises(exc, match="expected n to be a positive int"):
        quatarray.num_threads(bad)


# --- same bits for any thread count -------------------------------------------------------------

def _ops(rng, dtype):
    BLOCK = _blocks.block_size(dtype)   # float32 blocks hold twice as many elements
    n = 3 * BLOCK + 77
    p, q = random_quats(rng, (n,), dtype), random_quats(rng, (n,), dtype)
    t = rng.uniform(-0.2, 1.2, n).astype(dtype)
    v = rng.standard_normal((n, 3)).astype(dtype)
    wide = random_quats(rng, (3, BLOCK + 5), dtype)           # blocks along a trailing axis
    times = np.cumsum(rng.uniform(0.5, 1.5, 40))
    keys = random_quats(rng, (40, 3), dtype)
    tq = rng.uniform(times[0], times[-1], BLOCK + 9)
    return {
        "multiply": lambda: K.multiply(p, q),
        "multiply broadcast": lambda: K.multiply(wide, q[:BLOCK + 5]),
        "conjugate": lambda: K.conjugate(p),
        "normalize": lambda: K.normalize(2 * p),
        "normalize strided": lambda: K.normalize(wide[:, ::2]),
        "inverse": lambda: K.inverse(p),
        "exp": lambda: K.exp(p), "log": lambda: K.log(p), "power": lambda: K.power(p, t),
        "rotate": lambda: K.rotate(p, v),
        "as_matrix": lambda: C.as_matrix(p), "from_matrix": lambda: C.from_matrix(C.as_matrix(p)),
        "as_rotvec": lambda: C.as_rotvec(p), "from_rotvec": lambda: C.from_rotvec(v),
        "as_euler": lambda: E.as_euler(p, "zyx"), "from_euler": lambda: E.from_euler("XZX", v),
        "slerp": lambda: IK.slerp(p, q, t), "squad": lambda: IK.squad(p, q, p[::-1], q[::-1], t),
        "bezier": lambda: IK.bezier(p, q, p[::-1], q[::-1], t),
        "track squad": lambda: Track(times, keys, method="squad")(tq),
        "track bezier": lambda: Track(times, keys, method="bezier")(tq),
    }


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_results_are_bit_identical_for_any_thread_count(rng, dtype, parallel_always):
    ops = _ops(rng, dtype)
    with quatarray.num_threads(1):
        want = {k: f().view(np.ndarray) for k, f in ops.items()}
    for threads in (2, 3):
        with quatarray.num_threads(threads):
            for k, f in ops.items():
                np.testing.assert_array_equal(f().view(np.ndarray), want[k], err_msg=f"{k} with {threads} threads")


def test_errors_in_workers_reach_the_caller(rng, parallel_always):
    q = random_quats(rng, (4 * BLOCK,), np.float64)
    q[-1] = 0
    with quatarray.num_threads(2):
        with pytest.raises(ValueError, match="expected non-zero quaternions"):
            K.normalize(q)
        with pytest.raises(ZeroDivisionError, match="expected non-zero"):
            K.inverse(q)


def test_floating_point_state_reaches_the_workers(rng, parallel_always):
    """Zero quaternions rotate to nan quietly, on every thread."""
    q = random_quats(rng, (4 * BLOCK,), np.float64)
    q[::7] = 0
    v = rng.standard_normal((len(q), 3))
    with quatarray.num_threads(2), warnings.catch_warnings():
        warnings.simplefilter("error")
        out = K.rotate(q, v)
    assert np.isnan(out[::7]).all() and np.isfinite(np.delete(out, np.s_[::7], axis=0)).all()


# --- bounded scratch -------------------------------------------------------------------------------

def test_scratch_rows_do_not_overlap_and_frames_give_back():
    work = _blocks.Scratch()
    n = _blocks.SMALL_ROWS   # rows past the small-request size come from the kept buffer
    a = work.rows(2, (n,), np.float64)
    with work.frame():
        b = work.rows(3, (n + 7,), np.float32)
        top = work.top
    c = work.rows(3, (n + 7,), np.float32)
    assert not np.may_share_memory(a, b) and not np.may_share_memory(a, c)
    assert np.may_share_memory(b, c) and work.top == top   # given back, taken again
    small = work.rows(3, (7,), np.float32)   # a fresh array, the kept buffer untouched
    assert small.shape == (3, 7) and small.dtype == np.float32 and work.top == top
    assert not np.may_share_memory(small, work.buf)
    big = work.rows(1, (_blocks.SCRATCH_LIMIT,), np.uint8)  # beyond the bound: not kept
    assert work.nbytes <= _blocks.SCRATCH_LIMIT and not np.may_share_memory(big, work.buf)


def _retained(call):
    """Bytes still allocated after `call()` returns, less its result."""
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        out = call()
        kept = tracemalloc.get_traced_memory()[0] - base - sum(np.asarray(o).nbytes for o in out)
    finally:
        tracemalloc.stop()
    return kept


@pytest.mark.parametrize("threads", [1, 2])
def test_scratch_stays_bounded_whatever_the_batch_shape(rng, threads, parallel_always):
    """Wide batches of tracks leave at most SCRATCH_LIMIT per thread behind (the old pool
    kept scratch proportional to the number of tracks: 8 float64 rows per track, here
    over more tracks than SCRATCH_LIMIT holds rows of)."""
    wide = (_blocks.SCRATCH_LIMIT // (8 * 8 * BLOCK) + 2) * BLOCK
    keys = random_quats(rng, (3, wide), np.float64)
    times = np.array([0.0, 1.0, 2.5])
    bound = threads * _blocks.SCRATCH_LIMIT
    with quatarray.num_threads(threads):
        for method in ("slerp", "squad", "bezier"):
            kept = _retained(lambda: [Track(times, keys, method=method)(np.array([0.3, 2.0]))])
            assert kept <= bound, method
        kept = _retained(lambda: IK.frames(keys[:1].T.reshape(4, 1, -1), keys[1:2].T.reshape(4, 1, -1)))
        assert kept <= bound
        p = random_quats(rng, (2, 5 * BLOCK), np.float64)
        kept = _retained(lambda: [IK.slerp(p, p[::-1], np.full(p.shape[:-1], 0.3))])
        assert kept <= bound


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("where", [None, 0, 1, 2])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_product_and_conjugate_judge_finiteness_block_by_block(rng, threads, where, dtype, parallel_always):
    """`check=True` reports whether the whole result is finite, whichever block holds
    the one non-finite element (the flag is judged per block, while it is in cache)."""
    block = _blocks.block_size(dtype)
    p = random_quats(rng, (3 * block,), dtype)
    q = random_quats(rng, (3 * block,), dtype)
    if where is not None:   # in the first, second or last block
        q[(0, block + 3, 3 * block - 1)[where], 2] = np.inf
    with quatarray.num_threads(threads):
        prod, ok_prod = K.multiply(p, q, check=True)
        conj, ok_conj = K.conjugate(q, check=True)
    np.testing.assert_array_equal(prod, K.multiply(p, q))
    np.testing.assert_array_equal(conj, K.conjugate(q))
    assert ok_prod == bool(np.isfinite(prod).all()) == (where is None)
    assert ok_conj == bool(np.isfinite(conj).all()) == (where is None)
