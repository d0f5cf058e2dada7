"""The one block engine: block size, splitting a batch into blocks, per-thread
scratch bounded by the block size, and the thread pool that runs the blocks.

Every kernel that walks a long batch goes through `blockwise` (component-major
copies of the inputs, outputs written in place) or, for the few memory-bound
loops that work on flat views, through `run` with blocks from `split`.

Threads
-------
NumPy releases the GIL inside its ufunc loops, so blocks computed on several
threads run in parallel.  The number of threads is, in order of precedence:

1. inside one of our own worker threads: 1 (a block never fans out again);
2. a ``with quatarray.num_threads(n):`` block active in the calling thread;
3. in a thread other than the main thread: 1 -- threads of another pool
   (a web server, `concurrent.futures`, Dask's threaded workers) already use
   the cores, so quatarray does not multiply them; such code asks for more
   with ``with quatarray.num_threads(n):`` in its own thread;
4. `set_num_threads` (process-wide), else the environment variable
   ``QUATARRAY_NUM_THREADS``, else the number of CPUs this process may run on
   (``len(os.sched_getaffinity(0))``).

Batches below `PARALLEL_MIN` elements stay on the calling thread: handing
work to the pool costs more than it saves there.

Results do not depend on the number of threads: blocks are the same whatever
runs them, every element is computed by the same sequence of ufunc calls,
and results are collected in block order.
"""

import contextvars
import itertools
import os
import threading
import warnings
import weakref
from math import prod

import numpy as np

__all__ = [
    "BLOCK", "FEW", "PARALLEL_MIN", "VIEWS_MAX", "SMALL_ROWS", "SCRATCH_LIMIT",
    "get_num_threads", "set_num_threads", "num_threads",
    "block_size", "split", "part", "soa", "scratch", "scratch_bytes", "run", "blockwise", "on_views",
]

#: float64 elements (quaternions, vectors, matrices) per block (float32 blocks hold
#: twice as many: `block_size`).  Each ufunc call then
#: works on 32768 elements: the call's fixed cost (about 1 µs) and, with several
#: threads, the hand-over of the GIL around it are paid once per 32768 elements.
#: Measured on the AVX2 machine (2 CPUs), 10⁶ elements, against 8192: product
#: 14.5 -> 8.0 ms, from_rotvec 37 -> 21 ms, rotate 52 -> 22 ms with 2 threads
#: (at 8192 two threads were slower than one: GIL hand-overs every few µs).
#: A float64 row is 256 KiB: a short kernel's rows stay in L2, a long one's in L3.
BLOCK = 32768


def block_size(*dtypes):
    """Elements per block for data of these float dtypes: the bytes of `BLOCK`
    float64 elements, so a float32 block holds twice as many (2 vCPUs, AVX2:
    the float32 product 6.2 -> 5.2 ms at 10⁶, float64 unchanged; per-call
    costs are paid per element count, cache space per byte).

    >>> import numpy as np
    >>> from quatarray._blocks import block_size
    >>> block_size(np.float64), block_size(np.float32), block_size(np.float32, np.float64)
    (32768, 65536, 32768)
    """
    factor = _FACTOR.get(dtypes)
    if factor is None:   # first call with these dtypes (a few a process)
        size = max((np.dtype(d).itemsize for d in dtypes if np.dtype(d).kind in "fc"), default=8)
        factor = _FACTOR[dtypes] = 8 // min(size, 8)
    return BLOCK * factor


_FACTOR = {}   # dtypes -> elements per block over BLOCK; a small batch pays a dict lookup


#: A few elements: up to this many, kernels may run their formula straight on fresh
#: component rows (stacked where that saves calls), without the block engine.
FEW = 1024

#: Below this many elements a call runs on the calling thread only.
PARALLEL_MIN = 4 * BLOCK

#: Largest batch of a `Rotation` whose conversion kernels are called straight on views
#: of its storage, without the engine (whose setup costs about a ufunc call's), and
#: whose stacked as_matrix plan runs rather than the block program (past it that plan's
#: strided writes cost more than the copies).  Up to it kernels take no kept scratch rows
#: (`FEW`).  Past it, up to one block, `blockwise`'s ``read_only`` kernels still read
#: views: measured against copies at 600 to 30000 rotations (AVX-512 and emulated
#: AVX2), magnitude, as_rotvec, as_euler and power ran 1.0-1.4x faster on the views.
VIEWS_MAX = 512

#: Requests for scratch rows of at most this many bytes get fresh arrays: small
#: allocations come from the heap without page faults, and cost a fifth of carving
#: a view from the kept buffer (what a small batch pays per row set).
SMALL_ROWS = 32 * 1024

_FEW_ROWS = SMALL_ROWS // 8   # elements of a component-major copy that are always fresh rows
_FEW_QUATS = _FEW_ROWS // 4    # elements of a batch whose copies of up to four components are

#: Bytes of scratch a thread keeps between calls: 24 rows of a float64 block
#: (6 MiB; two threads keep 12 MiB, 0.4 of a 10⁶-quaternion float64 output).
#: The few kernels that need more rows (Bézier, squad) get fresh arrays for the
#: rows beyond it, freed after use.
SCRATCH_LIMIT = 24 * BLOCK * 8

_ENV = "QUATARRAY_NUM_THREADS"


# --------------------------------------------------------------------------- thread controls

_local = threading.local()   # .override (int or None), .worker (bool), .scratch (Scratch)
_setting = None              # set_num_threads value; None: environment / affinity
_default_threads = None      # QUATARRAY_NUM_THREADS or the CPU count, read on first use


def _cpus():
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _check(n, name="n"):
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise TypeError(f"expected {name} to be a positive int, got {type(n).__name__}")
    if n < 1:
        raise ValueError(f"expected {name} to be a positive int, got {n}")
    return int(n)


def _default():
    env = os.environ.get(_ENV, "").strip()
    if env:
        try:
            return _check(int(env), _ENV)
        except (TypeError, ValueError):
            warnings.warn(f"expected {_ENV} to be a positive int, got {env!r}; using the CPU count",
                          RuntimeWarning, stacklevel=3)
    return _cpus()


def get_num_threads():
    """Threads a quatarray call made now from this thread would use.

    >>> from quatarray import get_num_threads
    >>> get_num_threads() >= 1
    True
    """
    if getattr(_local, "worker", False):
        return 1
    override = getattr(_local, "override", None)
    if override is not None:
        return override
    if threading.current_thread() is not threading.main_thread():
        return 1
    if _setting is not None:
        return _setting
    global _default_threads
    if _default_threads is None:
        _default_threads = _default()
    return _default_threads


def set_num_threads(n):
    """Set the number of threads quatarray uses in the main thread, process-wide.

    Parameters
    ----------
    n : int or None
        A positive number of threads; None restores the default
        (``QUATARRAY_NUM_THREADS``, else the CPUs this process may use).

    Examples
    --------
    >>> import quatarray
    >>> quatarray.set_num_threads(1)
    >>> quatarray.get_num_threads()
    1
    >>> quatarray.set_num_threads(None)
    """
    global _setting, _default_threads
    _setting = None if n is None else _check(n)
    _default_threads = None   # the environment is read again


class num_threads:
    """Context manager: quatarray calls from this thread use `n` threads inside the block.

    Applies to the calling thread only (other threads keep their own
    setting), so it is the way to run quatarray single-threaded inside a
    task of another pool, or multi-threaded from a thread that is not the
    main thread.

    Examples
    --------
    >>> import quatarray
    >>> with quatarray.num_threads(1):
    ...     quatarray.get_num_threads()
    1
    """

    def __init__(self, n):
        self.n = _check(n)
        self._saved = []

    def __enter__(self):
        self._saved.append(getattr(_local, "override", None))
        _local.override = self.n
        return self

    def __exit__(self, *exc):
        _local.override = self._saved.pop()
        return False


# --------------------------------------------------------------------------- splitting

def split(shape, block=BLOCK):
    """Index tuples (into the leading axes) of blocks of at most `block` elements.

    The blocks cover the batch `shape` exactly once, in C order; a batch of
    at most `block` elements is one block ``()``.  Trailing axes are kept
    whole while they fit in a block, so blocks are as contiguous as possible.

    >>> from quatarray._blocks import split
    >>> split((5,), block=2)
    [(slice(0, 2, None),), (slice(2, 4, None),), (slice(4, 5, None),)]
    >>> len(split((3, 4), block=4))
    3
    """
    shape = tuple(shape)
    if prod(shape) <= block:
        return [()]
    inner, k = 1, len(shape)
    while k > 0 and inner * shape[k - 1] <= block:
        inner *= shape[k - 1]
        k -= 1
    ax = k - 1
    step = max(block // inner, 1)
    n = shape[ax]
    return [outer + (slice(start, min(start + step, n)),)
            for outer in np.ndindex(*shape[:ax]) for start in range(0, n, step)]


def part(a, idx, batch_ndim, core=1):
    """The part of `a` that broadcasts against block `idx` of a batch of
    `batch_ndim` axes (`a`'s batch is right-aligned; `core` trailing axes
    are not batch axes)."""
    if not idx:
        return a
    offset = batch_ndim - (a.ndim - core)
    sel = []
    for i, ix in enumerate(idx):
        j = i - offset
        if j < 0:
            continue
        if a.shape[j] == 1:
            sel.append(0 if isinstance(ix, int) else slice(None))
        else:
            sel.append(ix)
    return a[tuple(sel)]


def soa(a):
    """Components-first view ``(k, ...)`` of an ``(..., k)`` array (no copy)."""
    if a.ndim == 2:   # the common (N, k): `.T` costs a fifth of a general transpose
        return a.T
    n = a.ndim - 1
    return a.transpose((n,) + tuple(range(n)))


# --------------------------------------------------------------------------- scratch

_DTYPES = {d: np.dtype(d) for d in (np.float32, np.float64, bool)}
_DTYPES.update({d: d for d in list(_DTYPES.values())})   # (a dict lookup: cheaper than np.dtype())


class Scratch:
    """A thread's scratch: a stack of rows carved from one buffer kept between calls.

    ``rows(n, shape, dtype)`` returns a fresh ``(n, *shape)`` view that no
    other live request shares; everything taken while a block runs is given
    back when the block ends (``frame()`` gives back earlier).  The buffer
    grows to the largest need seen, never beyond `SCRATCH_LIMIT` bytes;
    requests that would pass it get a fresh array, freed after use.  Kept
    buffers save the page faults of fresh memory on every call.
    """

    __slots__ = ("buf", "top", "__weakref__")

    def __init__(self):
        self.buf = None
        self.top = 0

    def rows(self, n, shape, dtype):
        shape = (n, *shape)
        dtype = _DTYPES.get(dtype) or np.dtype(dtype)
        nbytes = prod(shape) * dtype.itemsize
        if nbytes <= SMALL_ROWS:   # fresh small memory costs no page faults, and less than a view
            return np.empty(shape, dtype)
        start = -(-self.top // 64) * 64   # 64-byte aligned rows
        end = start + nbytes
        if end > SCRATCH_LIMIT:
            return np.empty(shape, dtype)
        if self.buf is None or end > self.buf.size:
            # views into the old buffer stay valid (they keep it alive)
            size = 0 if self.buf is None else self.buf.size
            self.buf = np.empty(min(SCRATCH_LIMIT, max(end, 2 * size)), np.uint8)
        self.top = end
        return self.buf[start:end].view(dtype).reshape(shape)

    def frame(self):
        """Context manager giving back, on exit, the rows taken inside it."""
        return _Frame(self)

    @property
    def nbytes(self):
        """Bytes held between calls."""
        return 0 if self.buf is None else self.buf.size


class _Frame:
    __slots__ = ("work", "top")

    def __init__(self, work):
        self.work = work

    def __enter__(self):
        self.top = self.work.top
        return self.work

    def __exit__(self, *exc):
        self.work.top = self.top
        return False


_every_scratch = weakref.WeakSet()   # of every live thread


def scratch():
    """The calling thread's `Scratch`."""
    work = getattr(_local, "scratch", None)
    if work is None:
        work = _local.scratch = Scratch()
        _every_scratch.add(work)
    return work


def scratch_bytes():
    """Bytes of scratch kept by all live threads (at most `SCRATCH_LIMIT` each)."""
    return sum(w.nbytes for w in list(_every_scratch))


# --------------------------------------------------------------------------- the pool

_pool = None
_pool_workers = 0            # threads of `_pool` (ThreadPoolExecutor does not say, publicly)
_pool_lock = threading.Lock()


def _mark_worker():
    _local.worker = True


def _executor(workers):
    """The shared pool, with at least `workers` threads."""
    global _pool, _pool_workers
    with _pool_lock:
        if _pool is None or _pool_workers < workers:
            from concurrent.futures import ThreadPoolExecutor
            old = _pool
            _pool = ThreadPoolExecutor(workers, thread_name_prefix="quatarray", initializer=_mark_worker)
            _pool_workers = workers
            if old is not None:
                old.shutdown(wait=False)
        return _pool


def _forget_pool():
    """After fork the pool's threads do not exist in the child: start afresh."""
    global _pool, _pool_workers, _pool_lock
    _pool, _pool_workers, _pool_lock = None, 0, threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool)


def _call(fn, item):
    work = scratch()
    top = work.top
    try:
        return fn(item)
    finally:
        work.top = top


def run(fn, items, size):
    """``[fn(item) for item in items]``, on several threads when `size` (elements) is large.

    Each call's scratch (`scratch()`) is given back when it returns.  The
    first exception (by item order among those raised) is re-raised after
    every thread has stopped.  The caller's context (`np.errstate`) applies
    in the workers too.
    """
    n = len(items)
    threads = min(get_num_threads(), n) if size >= PARALLEL_MIN else 1
    if threads <= 1:
        return [_call(fn, item) for item in items]
    results = [None] * n
    errors = []
    counter = itertools.count()

    def worker():
        was = getattr(_local, "worker", False)
        _local.worker = True
        try:
            while not errors:
                i = next(counter)   # atomic under the GIL
                if i >= n:
                    break
                try:
                    results[i] = _call(fn, items[i])
                except BaseException as exc:  # noqa: BLE001 - re-raised in the caller
                    errors.append((i, exc))
        finally:
            _local.worker = was

    pool = _executor(threads - 1)
    futures = [pool.submit(contextvars.copy_context().run, worker) for _ in range(threads - 1)]
    try:
        worker()
    finally:
        for f in futures:
            f.result()
    if errors:
        raise min(errors, key=lambda e: e[0])[1]
    return results


def blockwise(kernel, ins, outs, batch=None, dtype=None, views=(), read_only=False, **params):
    """Run ``kernel(*ins_block, *views_block, *outs_block, **params)`` over the blocks of a batch.

    Parameters
    ----------
    kernel : callable
        Gets, per block of batch shape ``s``, each input as a contiguous
        components-first scratch copy ``(k, *s)`` (in `dtype`, default the
        input's dtype) and each output as the components-first view
        ``(k, *s)`` of that block of the output, which it must fill.  It may
        take more rows from `scratch()`.
    ins : list of ndarray, shape (..., k)
        Inputs broadcasting against `batch` (any strides, never modified).
    outs : list of ndarray, shape (*batch, k)
        Preallocated outputs (not overlapping the inputs).
    batch : tuple, optional
        Batch shape; default ``outs[0].shape[:-1]``.
    dtype : dtype, optional
        dtype of the input copies.
    views : list of ndarray, shape (...)
        Batch-shaped arrays (no component axis, e.g. interpolation
        parameters) broadcasting against `batch`: the kernel gets each
        block's part as a view (not copied, dtype kept) that broadcasts
        against ``s``.
    read_only : bool, default False
        The kernel never writes into its inputs: a batch of one block gets
        components-first views of inputs of its shape and dtype (no copies;
        the same ufunc calls on strided rows give the same bits).

    Returns
    -------
    bool
        True if any call of `kernel` returned True (e.g. a warning to give
        once); other return values are ignored.
    """
    if batch is None:
        batch = outs[0].shape[:-1]
    batch = tuple(batch)
    if not read_only and not views and len(outs) == 1 and len(batch) == 1 and 1 < batch[0] <= _FEW_QUATS:
        # a few elements in one flat batch of the inputs' own shape: fresh components-first
        # copies at once (the one-block path below makes the same copies through more checks,
        # which cost as much as the kernel's first ufunc calls here)
        a = ins[0]
        if len(ins) == 1 and a.shape[:-1] == batch and a.shape[-1] <= 4 and (dtype is None or a.dtype == dtype):
            iv = [a.T.copy()]   # (one input, as `_few_copies` copies it)
        else:
            iv = _few_copies(ins, batch, dtype)
        if iv is not None:
            work = scratch()
            top = work.top
            try:
                r = kernel(*iv, outs[0].T, **params)
            finally:
                work.top = top
            return r is True or r is np.True_
    if (read_only and not views and len(batch) == 1 and 0 < batch[0] <= BLOCK
            and (ins[0].shape[:-1] == batch and (dtype is None or ins[0].dtype == dtype) if len(ins) == 1
                 else all(a.shape[:-1] == batch and (dtype is None or a.dtype == dtype) for a in ins))):
        # a flat batch of one block read in place: the kernel on the components-first views,
        # at once (the general path below would come to the same call through more checks)
        work = scratch()
        top = work.top
        try:
            r = kernel(*[a.T for a in ins], *[o.T for o in outs], **params)
        finally:
            work.top = top
        return r is True or r is np.True_
    nb = len(batch)
    if 0 in batch:
        return False
    n = prod(batch)
    if n == 1:   # one element (a single quaternion, or a batch of one)
        return _pair_of_one(kernel, ins, outs, dtype, views, params)
    # (up to BLOCK elements it is one block for every dtype: no need to ask `block_size`)
    size = BLOCK if n <= BLOCK else block_size(*([dtype] if dtype is not None else [a.dtype for a in ins]),
                                               *[o.dtype for o in outs])
    if n <= size:
        # one block: the same kernel call, without splitting or the pool
        work = scratch()
        top = work.top
        try:
            iv = []
            for a in ins:   # contiguous components-first copies, broadcast to the batch
                if (read_only and a.shape[:-1] == batch
                        and (dtype is None or a.dtype == dtype)):
                    iv.append(soa(a))
                    continue
                k = a.shape[-1]
                # (a few: fresh rows, as `Scratch.rows` gives them, without its bookkeeping)
                buf = (np.empty((k, *batch), dtype or a.dtype) if n * k <= _FEW_ROWS
                       else work.rows(k, batch, dtype or a.dtype))
                np.copyto(buf, soa(a if a.ndim == nb + 1 else a.reshape((1,) * (nb + 1 - a.ndim) + a.shape)),
                          casting="unsafe")
                iv.append(buf)
            for v in views:
                v = np.asarray(v)
                iv.append(v if v.ndim == nb else v.reshape((1,) * (nb - v.ndim) + v.shape))
            r = kernel(*iv, *[soa(o) for o in outs], **params)
        finally:
            work.top = top
        return r is True or r is np.True_

    def block(idx):
        work = scratch()
        s = outs[0][idx].shape[:-1] if idx else batch
        iv = []
        for a in ins:
            ab = part(a, idx, nb)
            ab = ab.reshape((1,) * (len(s) + 1 - ab.ndim) + ab.shape)
            buf = work.rows(a.shape[-1], s, dtype or a.dtype)
            np.copyto(buf, soa(ab), casting="unsafe")
            iv.append(buf)
        for v in views:
            vb = part(v, idx, nb, core=0)
            iv.append(vb.reshape((1,) * (len(s) - vb.ndim) + vb.shape))
        ov = [soa(o[idx]) for o in outs]
        return kernel(*iv, *ov, **params)

    return any(r is True or r is np.True_ for r in run(block, split(batch, size), n))


def _few_copies(ins, batch, dtype):
    """`blockwise`'s components-first copies of inputs of the batch's own shape, or of one
    element broadcast to it (up to four components each), as its one-block path makes them;
    None for any other input."""
    iv = []
    for a in ins:
        shape = a.shape
        k = shape[-1]
        if k > 4:
            return None
        if shape[:-1] == batch:
            iv.append(a.T.copy() if dtype is None or a.dtype == dtype else a.T.astype(dtype, order="C"))
        elif a.size == k:   # (k,) or (1, k): every column of the copy that element
            buf = np.empty((k, *batch), dtype or a.dtype)
            np.copyto(buf, a.reshape(k, 1), casting="unsafe")
            iv.append(buf)
        else:
            return None
    return iv


def _pair_of_one(kernel, ins, outs, dtype, views, params):
    """`blockwise` for a batch of one element: the kernel on rows of two equal columns, the
    first column copied out.

    NumPy takes its slow iterator for a ufunc that writes over an input of one element
    (its test that the operands are equally iterable counts a one-element array as having
    stride 0, which never "strides ahead" of itself), several times the direct loop's cost
    at this size (benchmarks/README.md), and the kernels work in place on their rows.  Two
    columns take the direct loop.  Each column is computed by the same ufunc calls on the
    same numbers as any element of any batch (every kernel is element by element, and its
    block-wide tests see the same element twice), so the first column has the bits the
    element has anywhere."""
    work = scratch()
    top = work.top
    try:
        iv = []
        for a in ins:
            buf = np.empty((a.shape[-1], 2), dtype or a.dtype)
            buf[...] = a.reshape(-1, 1)   # (k, 1) broadcast to both columns (casting as np.copyto)
            iv.append(buf)
        iv += [np.asarray(v).reshape(1) for v in views]
        ov = []
        for o in outs:   # the output's own values in both columns: a kernel may read an output
            buf = np.empty((o.shape[-1], 2), o.dtype)
            buf[...] = o.reshape(-1, 1)
            ov.append(buf)
        r = kernel(*iv, *ov, **params)
        for o, buf in zip(outs, ov):
            o[...] = buf[:, 0].reshape(o.shape)
    finally:
        work.top = top
    return r is True or r is np.True_


def on_views(kernel, a, out, **params):
    """Run the read-only `kernel` (as for `blockwise`) on a flat batch `a` (n, k) into `out`
    (n, m), given the components-first views of both up to one block (within a scratch
    frame: the rows the kernel takes are given back), and by `blockwise` past it (copies
    of blocks, on threads).  Returns the kernel's result (`blockwise`'s bool past one
    block).  (Up to `VIEWS_MAX` rows, callers call their kernels on the views themselves:
    the kernels take no kept scratch rows there.)"""
    if 0 < len(a) <= BLOCK:
        with scratch().frame():
            return kernel(a.T, out.T, **params)
    return blockwise(kernel, [a], [out], read_only=True, **params)
